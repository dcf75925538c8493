"""Measured rig data, read as it comes: a CSV (or arrays) made into a checked, SI, uniform record.

:func:`read_measurement` reads a CSV with a header row; :func:`measurement_from_arrays` does the
same checks and processing on arrays already in memory. Both return a :class:`Measurement`:
the logged signals in SI units on a uniform sample grid starting at 0, the samples to leave out
of a fit (``flagged``), the length of the rest segment before the excitation moves, and one
note for each thing that was done to the data (units converted, stamps resampled, offsets
added, samples flagged). Nothing is printed; the caller shows the notes.

Columns
    Found by name, case-insensitively, unless ``columns`` maps a signal to the file's name:
    ``t``: t, time; ``y``: y, x, position; ``u``: u, command; ``r``: r, reference, setpoint;
    ``p_f``: p_f, pa, p_a, p_cap; ``p_n``: p_n, pb, p_b, p_rod. Other columns are ignored.
Units
    In the header (``position [mm]``, ``p_f (bar)``, ``t[ms]``) or given by ``units``
    (``{"y": "mm"}``, which wins over the header); SI when neither says. See :data:`UNITS`.
Time
    Finite and strictly increasing. Stamps that are not uniform (one step differs from the
    median step by more than :data:`JITTER` of it, or the stamps drift from a uniform grid by
    more than :data:`DRIFT` of a step), or a ``dt`` that differs from the stamps' step, are
    resampled by linear interpolation onto a uniform grid at the median step (or ``dt``). A
    step longer than :data:`MAX_GAP` median steps is a hole in the data and refused. Uniform
    data are kept as logged, bit for bit.
Rest and flags
    ``rest`` counts the leading samples before the excitation (``u`` in open loop, ``r`` in
    closed loop) leaves its first value by more than :data:`MOVE_TOLERANCE` of its range; an
    excitation that never moves is refused (a log must begin at rest). A position or pressure
    that sits at its column's extreme value for :data:`CLIP_SAMPLES` or more samples while
    the excitation moves is flagged (a clipped sensor or an end stop): the run must begin
    after the rest segment (the rest value held through the dead time is no clip), and the
    excitation must change during it, or, for the position in open loop, the valve be away
    from its rest opening (a steady value after a step is no clip). A command at or beyond
    the rated input (``|u| >= 1``) is noted, not flagged: the model's valve saturates too.
Offsets
    The time starts at 0; ``position_offset`` is added to the position and the reference
    (one frame), ``pressure_offset`` to both pressures.
Non-finite values
    In the time, the position or a needed signal: refused, naming the column and the time.
    In another signal: that signal is left out, with a note.

Every array of a :class:`Measurement` is finite and read-only.
"""

from __future__ import annotations

import csv
import hashlib
import math
import numbers
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._args import given, real
from .._io import MAX_LINE_BYTES, open_input, read_csv_columns
from .._typing import BoolArray, FloatArray
from ..errors import InputError, ParameterError

__all__ = [
    "ALIASES",
    "CHANNELS",
    "CLIP_SAMPLES",
    "DRIFT",
    "JITTER",
    "MAX_GAP",
    "MOVE_TOLERANCE",
    "UNITS",
    "Measurement",
    "measurement_from_arrays",
    "parse_mapping",
    "read_measurement",
]

#: The logged signals a measurement may hold, besides the time ``t``.
CHANNELS: tuple[str, ...] = ("y", "u", "r", "p_f", "p_n")

#: The column names each signal is found by (compared case-insensitively, units stripped).
ALIASES: dict[str, tuple[str, ...]] = {
    "t": ("t", "time"),
    "y": ("y", "x", "position"),
    "u": ("u", "command"),
    "r": ("r", "reference", "setpoint"),
    "p_f": ("p_f", "pa", "p_a", "p_cap"),
    "p_n": ("p_n", "pb", "p_b", "p_rod"),
}

#: What each signal measures (the key into :data:`UNITS`).
_QUANTITY: dict[str, str] = {"t": "time", "y": "position", "r": "position", "u": "command",
                             "p_f": "pressure", "p_n": "pressure"}

#: What each signal is, in messages.
_DESCRIBE: dict[str, str] = {"t": "time", "y": "position", "u": "valve command",
                             "r": "position reference", "p_f": "full-bore pressure",
                             "p_n": "annulus pressure"}

#: The units allowed for each quantity, as (multiplier, divisor) to SI: a value v in the unit
#: is v * multiplier / divisor in SI (a division by 1000 rather than a multiplication by 1e-3,
#: so that a millimetre value comes out as the correctly rounded metre value). The first unit
#: of each is SI. Unit names are matched case-insensitively; ``µ`` may stand for ``u``.
UNITS: dict[str, dict[str, tuple[float, float]]] = {
    "time": {"s": (1.0, 1.0), "ms": (1.0, 1e3), "us": (1.0, 1e6)},
    "position": {"m": (1.0, 1.0), "mm": (1.0, 1e3), "um": (1.0, 1e6)},
    "pressure": {"Pa": (1.0, 1.0), "kPa": (1e3, 1.0), "bar": (1e5, 1.0), "MPa": (1e6, 1.0),
                 # the international avoirdupois pound-force per square inch, exactly:
                 # 0.45359237 kg * 9.80665 m/s^2 / (0.0254 m)^2
                 "psi": (0.45359237 * 9.80665, 0.0254**2)},
    "command": {"1": (1.0, 1.0), "%": (1.0, 100.0)},
}

#: The SI unit of each quantity, in notes.
_SI = {"time": "s", "position": "m", "pressure": "Pa", "command": "a fraction of rated input"}

#: Largest deviation of one time step from the median step, as a fraction of it, for the
#: stamps to count as uniform [-].
JITTER = 1e-3
#: Largest distance of a stamp from the uniform grid ``t_0 + k dt``, as a fraction of ``dt``,
#: for the stamps to count as uniform [-]: steps each within :data:`JITTER` can still add up
#: to a grid that is samples away at the end of a long record.
DRIFT = 0.01
#: Longest time step, in median steps, before the record counts as having a hole [-].
MAX_GAP = 5.0
#: The excitation moves when it leaves its first value by more than this fraction of its
#: range [-].
MOVE_TOLERANCE = 1e-6
#: Consecutive samples at a column's extreme value that make a clip [-].
CLIP_SAMPLES = 3

_UNIT_IN_NAME = re.compile(r"^(.*?)\s*(?:\[([^\]]*)\]|\(([^)]*)\))\s*$")


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class Measurement:
    """A logged experiment on a uniform sample grid, SI units.

    Every array has the length of ``t``, is finite and read-only.
    """

    t: FloatArray  #: sample times from 0, uniform [s]
    dt: float  #: sample time [s]
    y: FloatArray  #: piston position, offset as the options say [m]
    u: FloatArray | None  #: valve command, fraction of rated input [-]
    r: FloatArray | None  #: position reference (closed loop), offset as ``y`` [m]
    p_f: FloatArray | None  #: full-bore (cap side) chamber pressure [Pa]
    p_n: FloatArray | None  #: annulus (rod side) chamber pressure [Pa]
    flagged: BoolArray  #: samples to leave out of a fit: a clipped position or pressure
    source: str  #: the path as given, or what the arrays were called
    digest: str  #: ``"sha256:<hex>"`` of the file's bytes (of the arrays, for arrays)
    notes: tuple[str, ...]  #: what was done to the data, one line each
    rest: int  #: samples before the excitation first moves (>= 1)

    def channels(self) -> tuple[str, ...]:
        """The names of the logged signals among ``y, u, r, p_f, p_n``, in that order."""
        return tuple(name for name in CHANNELS if getattr(self, name) is not None)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])


# ------------------------------------------------------------------------- option values


def parse_mapping(text: str, what: str) -> dict[str, str]:
    """An option value ``"a=b,c=d"`` as ``{"a": "b", "c": "d"}`` (spaces around names and
    values removed; a value may hold ``=`` but not ``,``).

    Parameters
    ----------
    text : str
        The option's value.
    what : str
        The option, for messages (``"--columns"``).

    Raises
    ------
    InputError
        An item without ``=``, an empty name or value, or a name given twice.
    """
    out: dict[str, str] = {}
    for item in text.split(","):
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not key or not value:
            raise InputError(f"{what} {text!r}: {item.strip()!r} is not NAME=VALUE; give "
                             f"comma-separated pairs such as y=pos_mm,u=cmd")
        if key in out:
            raise InputError(f"{what} {text!r} gives {key!r} twice; give each name once")
        out[key] = value
    return out


# ------------------------------------------------------------------------- units and names


def _split_unit(name: str) -> tuple[str, str | None]:
    """``"position [mm]"`` -> ``("position", "mm")``; a name without a unit -> (name, None)."""
    m = _UNIT_IN_NAME.match(name)
    if m is None or not m.group(1):
        return name.strip(), None
    unit = m.group(2) if m.group(2) is not None else m.group(3)
    return m.group(1).strip(), unit.strip()


def _unit_factor(signal: str, unit: str, column: str) -> tuple[str, float, float]:
    """(canonical unit name, multiplier, divisor) of ``unit`` for ``signal``."""
    table = UNITS[_QUANTITY[signal]]
    key = unit.strip().replace("\u00b5", "u").replace("\u03bc", "u").lower()
    for name, (mul, div) in table.items():
        if name.lower() == key:
            return name, mul, div
    raise InputError(f"column {column!r} ({_DESCRIBE[signal]}): unit {unit!r} is not known; "
                     f"allowed: {', '.join(table)}")


def _unit_name(signal: str, unit: str) -> str | None:
    """The canonical name of ``unit`` for ``signal``, or None if it is not known."""
    try:
        return _unit_factor(signal, unit, signal)[0]
    except InputError:
        return None


def _check_keys(mapping: Mapping[str, str] | None, what: str) -> dict[str, str]:
    if mapping is None:
        return {}
    if not isinstance(mapping, Mapping):
        raise ParameterError(f"{what} must be a mapping of signal names to strings, got "
                             f"{given(mapping)}")
    allowed = ("t", *CHANNELS)
    out: dict[str, str] = {}
    for key, value in mapping.items():
        if key not in allowed:
            raise InputError(f"{what}: {key!r} is not a signal; allowed: "
                             f"{', '.join(allowed)}")
        if not isinstance(value, str) or not value.strip():
            raise InputError(f"{what}: {key}={value!r} must name a column or unit")
        out[key] = value.strip()
    return out


def _resolve(header: list[str], columns: dict[str, str], source: str,
             notes: list[str]) -> dict[str, str]:
    """Signal -> the header's column name, by ``columns`` first, then by :data:`ALIASES`."""
    found = ", ".join(repr(h) for h in header) or "none"
    base = {h: _split_unit(h)[0].lower() for h in header}
    out: dict[str, str] = {}
    for signal, wanted in columns.items():
        hits = [h for h in header if h == wanted] or \
            [h for h in header if h.lower() == wanted.lower()] or \
            [h for h in header if base[h] == wanted.lower()]
        if not hits:
            raise InputError(f"{source!r} has no column {wanted!r} (given for {signal}); "
                             f"found {found}")
        if len(hits) > 1:
            raise InputError(f"{source!r}: column {wanted!r} (given for {signal}) matches "
                             f"{', '.join(repr(h) for h in hits)}; name one exactly")
        out[signal] = hits[0]
    taken = set(out.values())
    for signal, names in ALIASES.items():
        if signal in out:
            continue
        hits = [h for h in header if h not in taken and base[h] in names]
        own = [h for h in hits if base[h] == signal]
        if len(hits) > 1 and len(own) == 1:  # the signal's own name wins over its aliases
            notes.append(f"column {own[0]!r} read as {signal}; "
                         f"{', '.join(repr(h) for h in hits if h != own[0])} not used "
                         f"(choose with columns {signal}=NAME)")
            hits = own
        if len(hits) > 1:
            raise InputError(f"{source!r}: columns {', '.join(repr(h) for h in hits)} could "
                             f"each be the {_DESCRIBE[signal]} ({signal}); say which with "
                             f"columns ({signal}=NAME)")
        if hits:
            out[signal] = hits[0]
            taken.add(hits[0])
    return out


def _header(path: Path, what: str) -> list[str] | None:
    """The header row of a CSV (``#`` and blank lines skipped), or None for an empty file.

    Only the lines up to the header are read, each bounded; the full read
    (:func:`read_csv_columns`) checks the encoding strictly."""
    with open_input(path, what) as fh:
        first = True
        for raw in iter(lambda: fh.readline(MAX_LINE_BYTES + 1), b""):
            if first and raw.startswith(b"\xef\xbb\xbf"):
                raw = raw[3:]
            first = False
            row = next(csv.reader([raw.decode("utf-8", errors="replace")]), [])
            if not row or row[0].lstrip().startswith("#"):
                continue
            return [name.strip() for name in row]
    return None


# ------------------------------------------------------------------------------- reading


def read_measurement(path: str | Path, *, columns: Mapping[str, str] | None = None,
                     units: Mapping[str, str] | None = None, dt: float | None = None,
                     position_offset: float | None = None, pressure_offset: float = 0.0,
                     need: tuple[str, ...] = ("u",), min_samples: int = 200) -> Measurement:
    """Read a logged experiment from a CSV with a header row.

    Parameters
    ----------
    path : str or Path
        The CSV: a header row, then one row per sample; lines starting with ``#`` are
        ignored (strict UTF-8, read as a stream: :func:`fuzzyservo._io.read_csv_columns`).
    columns : mapping of str to str, optional
        Signal (``t``, ``y``, ``u``, ``r``, ``p_f``, ``p_n``) -> the file's column name, for
        columns not found by their usual names (:data:`ALIASES`).
    units : mapping of str to str, optional
        Signal -> unit (:data:`UNITS`); wins over a unit in the header.
    dt : float, optional
        Sample time to put the data on [s]; by default the stamps' median step. Without a
        time column the rows are taken as samples ``dt`` apart.
    position_offset : float, optional
        Added to the position and the reference [m] (the model measures the position from
        the retracted end, 0 to the stroke); None leaves them as logged.
    pressure_offset : float
        Added to both pressures [Pa] (101325 turns gauge into absolute pressure).
    need : tuple of str
        The signals the caller requires besides ``y`` (``("u",)`` in open loop, ``("r",)``
        in closed loop); ``r`` in it makes the reference the excitation.
    min_samples : int
        Fewest samples accepted [-].

    Returns
    -------
    Measurement

    Raises
    ------
    InputError
        The file cannot be read or is not a CSV of numbers (:func:`read_csv_columns`), a
        needed column is missing or holds a non-number, NaN or infinity, a unit is not
        known, the time is not finite and increasing or has a hole, there are fewer than
        ``min_samples`` samples, the excitation never moves, more than half the samples are
        flagged, or the file changed while it was read.
    ParameterError
        An argument of the wrong type or range.
    """
    what = "measurement CSV"
    p = Path(path)
    source = str(path)
    columns_ = _check_keys(columns, "columns")
    units_ = _check_keys(units, "units")
    args = _Args.check(dt, position_offset, pressure_offset, need, min_samples)
    before = _stat(p)
    header = _header(p, what)
    if header is None:
        raise InputError(f"{what} {source!r} is empty; expected a header row naming its "
                         f"columns (t, y, u, ...)")
    notes: list[str] = []
    names = _resolve(header, columns_, source, notes)
    tcol = names.get("t")
    cols = read_csv_columns(p, (tcol,) if tcol is not None else (), what=what, min_rows=1,
                            keep=names.values())  # the other columns: skipped unparsed
    _check_same(p, before, what)
    digest = "sha256:" + _sha256(p)
    _check_same(p, before, what)
    required = {"t", "y", *args.need}
    raw: dict[str, FloatArray] = {}
    labels: dict[str, str] = {}
    for signal, name in names.items():
        if name not in cols:  # read_csv_columns leaves out a column holding text
            if signal in required:
                read_csv_columns(p, (name,), what=what)  # raises, naming the line
                raise InputError(f"{what} {source!r}: column {name!r} is not all numbers")
            notes.append(f"column {name!r} ({signal}) holds text, not numbers: left out")
            continue
        raw[signal] = cols[name]
        labels[signal] = f"column {name!r} ({signal})"
    unit_of = {signal: _split_unit(names[signal])[1] for signal in raw}
    for signal in units_:
        if signal not in raw:
            notes.append(f"units gives {signal}={units_[signal]}, but the file has no "
                         f"{signal} column: not used")
    for signal in list(raw):
        flag, head = units_.get(signal), unit_of[signal]
        unit = flag if flag is not None else head
        if unit is None:
            continue
        canon, mul, div = _unit_factor(signal, unit, names[signal])
        if flag is not None and head is not None and _unit_name(signal, head) != canon:
            notes.append(f"{labels[signal]}: unit {canon} given, the header says {head!r}; "
                         f"read as {canon}")
        raw[signal] = _to_si(raw[signal], mul, div)
        if (mul, div) != (1.0, 1.0):
            notes.append(f"{labels[signal]} converted from {canon} to "
                         f"{_SI[_QUANTITY[signal]]}")
    return _build(raw, args, labels=labels, found=header, source=source, digest=digest,
                  notes=notes, rows="data row")


def measurement_from_arrays(t: Any, y: Any, *, u: Any = None, r: Any = None,
                            p_f: Any = None, p_n: Any = None, source: str = "arrays",
                            units: Mapping[str, str] | None = None, dt: float | None = None,
                            position_offset: float | None = None,
                            pressure_offset: float = 0.0, need: tuple[str, ...] = ("u",),
                            min_samples: int = 200) -> Measurement:
    """A :class:`Measurement` from arrays, with the checks and processing of
    :func:`read_measurement`.

    Parameters
    ----------
    t : array_like
        Sample times, finite and increasing [s] (or in ``units["t"]``); None with ``dt``
        given takes the samples as ``dt`` apart.
    y : array_like
        Piston position [m] (or in ``units["y"]``).
    u, r, p_f, p_n : array_like, optional
        Valve command [-], position reference [m], full-bore and annulus pressures [Pa]
        (or in ``units``), each the length of ``t``.
    source : str
        What the arrays are, for messages and the record.
    units, dt, position_offset, pressure_offset, need, min_samples
        As :func:`read_measurement`; ``dt`` [s], ``position_offset`` [m],
        ``pressure_offset`` [Pa].

    Returns
    -------
    Measurement
        Its ``digest`` is the SHA-256 of the arrays given (each as float64 bytes after its
        name), before any conversion.

    Raises
    ------
    InputError
        As :func:`read_measurement`, or arrays that are not 1-D or not of one length.
    ParameterError
        An argument of the wrong type or range.
    """
    units_ = _check_keys(units, "units")
    args = _Args.check(dt, position_offset, pressure_offset, need, min_samples)
    given_ = {"t": t, "y": y, "u": u, "r": r, "p_f": p_f, "p_n": p_n}
    raw: dict[str, FloatArray] = {}
    h = hashlib.sha256()
    for signal, value in given_.items():
        if value is None:
            continue
        try:
            a = np.array(value, dtype=np.float64, copy=True)
        except (TypeError, ValueError):
            raise InputError(f"{source}: {signal} must be an array of numbers, got "
                             f"{given(value)}") from None
        if a.ndim != 1:
            raise InputError(f"{source}: {signal} must be one-dimensional, got shape "
                             f"{a.shape}")
        h.update(signal.encode() + b"\0" + a.astype("<f8").tobytes())
        raw[signal] = a
    lengths = {s: a.shape[0] for s, a in raw.items()}
    if len(set(lengths.values())) > 1:
        raise InputError(f"{source}: the arrays differ in length ("
                         + ", ".join(f"{s}: {n}" for s, n in lengths.items()) + ")")
    notes: list[str] = []
    for signal, unit in units_.items():
        if signal not in raw:
            notes.append(f"units gives {signal}={unit}, but there is no {signal}: not used")
            continue
        canon, mul, div = _unit_factor(signal, unit, signal)
        raw[signal] = _to_si(raw[signal], mul, div)
        if (mul, div) != (1.0, 1.0):
            notes.append(f"{signal} converted from {canon} to {_SI[_QUANTITY[signal]]}")
    return _build(raw, args, labels={s: s for s in raw}, found=list(raw), source=source,
                  digest="sha256:" + h.hexdigest(), notes=notes, rows="sample")


# ---------------------------------------------------------------------------- processing


@dataclass(frozen=True, slots=True)
class _Args:
    """The processing options, checked before any file is read."""

    dt: float | None  #: sample time asked for [s]
    position_offset: float | None  #: added to y and r [m]
    pressure_offset: float  #: added to the pressures [Pa]
    need: tuple[str, ...]  #: signals required besides y
    min_samples: int  #: fewest samples accepted

    @staticmethod
    def check(dt: Any, position_offset: Any, pressure_offset: Any, need: Any,
              min_samples: Any) -> _Args:
        if isinstance(min_samples, bool) or not isinstance(min_samples, numbers.Integral) \
                or min_samples < 2:
            raise ParameterError(f"min_samples must be an integer >= 2, got "
                                 f"{given(min_samples)}")
        if isinstance(need, str) or not isinstance(need, tuple | list) or \
                any(s not in CHANNELS for s in need):
            raise ParameterError(f"need must be a tuple of signal names among "
                                 f"{', '.join(CHANNELS)}, got {given(need)}")
        return _Args(
            dt=None if dt is None else real(dt, "dt", "s", positive=True),
            position_offset=None if position_offset is None
            else real(position_offset, "position_offset", "m"),
            pressure_offset=real(pressure_offset, "pressure_offset", "Pa"),
            need=tuple(need), min_samples=int(min_samples))


def _build(raw: dict[str, FloatArray], args: _Args, *, labels: dict[str, str],
           found: list[str], source: str, digest: str, notes: list[str],
           rows: str) -> Measurement:
    """The checks and processing both readers share (see the module's docstring)."""
    dt_, y_off, p_off = args.dt, args.position_offset, args.pressure_offset
    need, min_samples = args.need, args.min_samples
    looked = "; ".join(f"{s}: {', '.join(ALIASES[s])}" for s in ("t", "y", *need))
    shown = ", ".join(repr(f) for f in found) or "none"
    for signal in ("y", *need):
        if signal not in raw:
            raise InputError(f"{source!r} has no {_DESCRIBE[signal]} ({signal}) column; found "
                             f"{shown} (looked for {looked}; name it with columns "
                             f"{signal}=NAME)")
    if "u" not in raw and "r" not in raw:
        raise InputError(f"{source!r} has neither a valve command (u) nor a reference (r) "
                         f"to drive the model; found {shown}")
    n = raw["y"].shape[0]
    if n < min_samples:
        raise InputError(f"{source!r} has {n} samples; at least {min_samples} are needed")
    if "t" in raw:
        t = raw.pop("t")
        t_label = labels.get("t", "t")
    elif dt_ is not None:
        t = np.arange(n, dtype=np.float64) * dt_
        t_label = "t"
        notes.append(f"no time column: samples taken as dt = {dt_:.6g} s apart")
    else:
        raise InputError(f"{source!r} has no time (t) column; found {shown} (name it with "
                         f"columns t=NAME, or give dt)")
    _check_time(t, t_label, source, rows)
    channels: dict[str, FloatArray] = {}
    for signal in CHANNELS:
        if signal not in raw:
            continue
        a = raw[signal]
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            k = int(bad[0])
            where = (f"{labels[signal]} is {float(a[k])!r} at t = {t[k]:.6g} s "
                     f"({rows} {k + 1})")
            if signal in ("y", *need):
                raise InputError(f"{source!r}: {where}; every value of the "
                                 f"{_DESCRIBE[signal]} must be a number")
            notes.append(f"{where} and at {bad.size - 1} more sample(s): {signal} left out")
            continue
        channels[signal] = a
    t = t - t[0]
    t, dt_out, channels = _uniform(t, channels, dt_, source, notes)
    n = t.shape[0]
    if n < min_samples:
        raise InputError(f"{source!r} has {n} samples after resampling; at least "
                         f"{min_samples} are needed")
    if y_off is not None:
        for signal in ("y", "r"):
            if signal in channels:
                channels[signal] = channels[signal] + y_off
        notes.append(f"position offset {y_off:+.6g} m added to "
                     + " and ".join(s for s in ("y", "r") if s in channels))
    pressures = [s for s in ("p_f", "p_n") if s in channels]
    if p_off != 0.0:
        for signal in pressures:
            channels[signal] = channels[signal] + p_off
        notes.append(f"pressure offset {p_off:+.6g} Pa added to {' and '.join(pressures)}"
                     if pressures else f"pressure offset {p_off:+.6g} Pa not used: no "
                     f"pressure logged")
    for signal in pressures:
        low = float(np.min(channels[signal]))
        if low < 0.0:
            notes.append(f"{signal} goes down to {low:.6g} Pa, below 0: a gauge pressure? "
                         f"the model's pressures are absolute (give a pressure offset)")
    excitation = "r" if ("r" in need or "u" not in channels) else "u"
    e = channels[excitation]
    span = float(np.max(e) - np.min(e))
    if not span > 0.0:
        late = (f"; it differs from the position {float(channels['y'][0]):.6g} m at the "
                f"first sample: the step came before the log began"
                if excitation == "r" and abs(float(e[0] - channels["y"][0])) > 0.0 else "")
        raise InputError(f"{source!r}: the {_DESCRIBE[excitation]} ({excitation}) never moves "
                         f"(always {float(e[0]):.6g}): nothing to identify (a log must begin "
                         f"at rest, before the excitation starts){late}")
    tol = MOVE_TOLERANCE * span
    rest = int(np.argmax(np.abs(e - e[0]) > tol))
    changed = _moving(e, tol)
    opened = np.abs(e - e[0]) > tol if excitation == "u" else None
    flagged = np.zeros(n, dtype=np.bool_)
    for signal in ("y", "p_f", "p_n"):
        if signal in channels:
            flagged |= _clipped(channels[signal], signal, t, rest, changed,
                                opened if signal == "y" else None, notes)
    if "u" in channels:
        sat = np.flatnonzero(np.abs(channels["u"]) >= 1.0)
        if sat.size:
            notes.append(f"u at or beyond the valve's rated input (|u| >= 1) at {sat.size} "
                         f"sample(s), t = {t[sat[0]]:.6g} .. {t[sat[-1]]:.6g} s: kept (the "
                         f"model's valve saturates too)")
    count = int(np.count_nonzero(flagged))
    if 2 * count > n:
        raise InputError(f"{source!r}: {count} of {n} samples are clipped or at an end stop "
                         f"(more than half); nothing left to fit")
    arrays = {s: channels.get(s) for s in CHANNELS}
    frozen: list[np.ndarray | None] = [t, flagged, *arrays.values()]
    for arr in frozen:
        if arr is not None:
            arr.flags.writeable = False
    return Measurement(t=t, dt=dt_out, y=channels["y"], u=arrays["u"], r=arrays["r"],
                       p_f=arrays["p_f"], p_n=arrays["p_n"], flagged=flagged, source=source,
                       digest=digest, notes=tuple(notes), rest=rest)


def _to_si(a: FloatArray, mul: float, div: float) -> FloatArray:
    out = a
    if mul != 1.0:
        out = out * mul
    if div != 1.0:
        out = out / div
    return out


def _check_time(t: FloatArray, label: str, source: str, rows: str) -> None:
    """Finite and strictly increasing, else the first bad sample."""
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        k = int(bad[0])
        raise InputError(f"{source!r}: the time, {label}, is {float(t[k])!r} at {rows} {k + 1}; "
                         f"every time must be a number")
    step = np.diff(t)
    back = np.flatnonzero(~(step > 0.0))
    if back.size:
        k = int(back[0])
        raise InputError(f"{source!r}: the time, {label}, does not increase at {rows} "
                         f"{k + 2}: {float(t[k])!r} then {float(t[k + 1])!r}; the time must "
                         f"increase strictly")


def _uniform(t: FloatArray, channels: dict[str, FloatArray], dt: float | None, source: str,
             notes: list[str]) -> tuple[FloatArray, float, dict[str, FloatArray]]:
    """The samples on a uniform grid: as logged if the stamps are uniform (and ``dt``, if
    given, agrees), else linearly interpolated onto one; ``t`` starts at 0."""
    n = t.shape[0]
    steps = np.diff(t)
    med = float(np.median(steps))
    gaps = np.flatnonzero(steps > MAX_GAP * med)
    if gaps.size:
        k = int(gaps[0])
        raise InputError(f"{source!r}: the data has holes: the time jumps by {steps[k]:.6g} s "
                         f"({steps[k] / med:.1f} sample times of {med:.6g} s) after t = "
                         f"{t[k]:.6g} s ({gaps.size} such gap(s)); at most {MAX_GAP:g} sample "
                         f"times are bridged")
    jitter = float(np.max(np.abs(steps - med)))
    jitter_ok = jitter <= JITTER * med
    agrees = dt is None or abs(dt - med) <= JITTER * med
    if dt is not None and dt < med * (1.0 - JITTER):
        raise InputError(f"{source!r}: dt = {dt:.6g} s is finer than the logged step "
                         f"{med:.6g} s: interpolating between samples makes neighbouring "
                         f"samples' noise correlated, and a fit's standard errors wrong; "
                         f"choose dt >= {med:.6g} s")
    step = dt if dt is not None else (float(t[-1]) / (n - 1) if jitter_ok else med)
    if dt is None and jitter_ok:  # the decimal step the log was written with
        decimal = float(f"{step:.12g}")
        if abs(decimal - step) <= 1e-9 * step:
            step = decimal
    drift = float(np.max(np.abs(t - np.arange(n) * step)))
    if jitter_ok and agrees and drift <= DRIFT * step:
        notes.append(f"uniform time stamps, kept as logged: dt = {step:.6g} s, {n} samples")
        return t, step, channels
    m = int(math.floor(float(t[-1]) / step * (1.0 + 1e-12))) + 1
    grid = np.arange(m, dtype=np.float64) * step
    why = (f"dt = {dt:.6g} s given, the stamps' median step is {med:.6g} s" if not agrees
           else f"time stamps not uniform: steps {float(np.min(steps)):.6g} .. "
                f"{float(np.max(steps)):.6g} s, up to {100 * jitter / med:.3g} % from the "
                f"median {med:.6g} s, up to {100 * drift / step:.3g} % of a step from a "
                f"uniform grid")
    down = (": downsampled without an anti-alias filter"
            if dt is not None and dt > 1.5 * med else "")
    notes.append(f"{why}; resampled onto a uniform grid at dt = {step:.6g} s by linear "
                 f"interpolation ({n} -> {m} samples){down}")
    return grid, step, {s: np.interp(grid, t, a) for s, a in channels.items()}


def _moving(e: FloatArray, tol: float) -> BoolArray:
    """Sample k (k >= 1) where the excitation has changed since sample k - 1."""
    out = np.zeros(e.shape[0], dtype=np.bool_)
    out[1:] = np.abs(np.diff(e)) > tol
    return out


def _clipped(x: FloatArray, signal: str, t: FloatArray, rest: int, changed: BoolArray,
             opened: BoolArray | None, notes: list[str]) -> BoolArray:
    """Runs of :data:`CLIP_SAMPLES` or more samples at the column's maximum or minimum
    while the excitation moves, flagged; a note says where.

    A run counts when it begins after the rest segment (one that begins in it is the rest
    value held through the plant's dead time) and the excitation changes while the signal
    sits still (a steady value after a step is not a clip); ``opened`` (the position in open
    loop: the valve away from its rest opening) also counts, since an open valve moves the
    piston unless it is at an end stop."""
    n = x.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    for which, value in (("maximum", float(np.max(x))), ("minimum", float(np.min(x)))):
        at = np.concatenate(([False], x == value, [False]))
        edges = np.flatnonzero(np.diff(at.astype(np.int8)))
        starts, stops = edges[0::2], edges[1::2]
        hits = np.zeros(n, dtype=np.bool_)
        runs = 0
        for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
            moves = bool(changed[a + 1:b].any()) or (
                opened is not None and bool(opened[a:b].any()))
            if b - a >= CLIP_SAMPLES and a >= rest and moves:
                hits[a:b] = True
                runs += 1
        if runs:
            k = np.flatnonzero(hits)
            unit = "Pa" if signal.startswith("p_") else "m"
            notes.append(f"{signal} sits at its {which} {value:.6g} {unit} for "
                         f"{k.size} sample(s) in {runs} run(s), t = {t[k[0]]:.6g} .. "
                         f"{t[k[-1]]:.6g} s, while the excitation moves: clipped sensor or "
                         f"end stop, flagged (left out of the fit)")
            out |= hits
    return out


# ------------------------------------------------------------------------ file identity


def _stat(p: Path) -> tuple[int, int, int] | None:
    try:
        st = os.stat(p)
    except OSError:
        return None  # open_input names the reason
    return st.st_ino, st.st_size, st.st_mtime_ns


def _check_same(p: Path, before: tuple[int, int, int] | None, what: str) -> None:
    if before is not None and _stat(p) != before:
        raise InputError(f"{what} {str(p)!r} changed while it was read; read it again when "
                         f"the logger has finished writing it")


def _sha256(p: Path) -> str:
    h = hashlib.sha256()
    with open_input(p, "measurement CSV") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()
