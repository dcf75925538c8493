"""Load-force disturbances: a force on the piston that follows a profile in time.

Each profile is a frozen dataclass with ``values(t) -> F`` (t [s] -> F [N], numpy arrays), the
force *added* to the parameter set's constant ``load.external_force`` (the force the plant is
trimmed against at rest). Sign: a positive F opposes extension, as ``LoadParams.external_force``
does (it enters the piston's force balance as -F, plant/nonlinear.py ``rhs``): a positive step
pushes the piston back, towards smaller x.

A run samples the profile at its sample instants t_k = k T_s and holds F(t_k) over
[t_k, t_k + T_s) (zero-order hold, as the command is held): the nonlinear loop writes it into
the plant's parameters each sample, the linear plants take the same held samples through their
force input (:meth:`fuzzyservo.sim.closed_loop.LinearPlant.force_response`). A piecewise-linear
profile is therefore seen as a staircase of its values at the sample instants.

:func:`parse_load_force` reads the command line's ``--load-force`` (docs/cli.md):
``step:F[:T]`` (F [N] from T [s] on, 0 before; T default 0), ``pwl:T0:F0,T1:F1,...``
(piecewise linear between the points, held before the first and after the last) or a CSV file
``FILE.csv`` with columns ``t`` [s] and ``F`` [N] under a header, read as a ``pwl``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from .._io import read_csv_columns
from .._typing import FloatArray
from ..errors import InputError

__all__ = [
    "LOAD_FORCE_FORMS",
    "LoadForce",
    "LoadPoints",
    "LoadStep",
    "load_force_samples",
    "parse_load_force",
]

#: The forms ``--load-force`` takes, as error messages and help texts list them.
LOAD_FORCE_FORMS = "step:F[:T], pwl:T0:F0,T1:F1,... or FILE.csv (columns t, F)"


class LoadForce(Protocol):
    """A load-force profile F(t) [N], added to ``load.external_force``; > 0 opposes
    extension."""

    def values(self, t: FloatArray) -> FloatArray:
        """Return F [N] at the times ``t`` [s]."""
        ...


def _force(what: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"load force {what} must be a finite number of newtons, got "
                         f"{value!r}")
    return v


def _time(what: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v >= 0.0):
        raise InputError(f"load force {what} must be a finite time >= 0 s (the run starts at "
                         f"t = 0), got {value!r}")
    return v


@dataclass(frozen=True, slots=True)
class LoadStep:
    """A step of ``force`` [N] at ``time`` [s]: 0 before, ``force`` from ``time`` on."""

    force: float  #: step height F, > 0 opposes extension [N]
    time: float = 0.0  #: step instant T [s]

    def __post_init__(self) -> None:
        _force("step F", self.force)
        _time("step time T", self.time)

    def values(self, t: FloatArray) -> FloatArray:
        """F(t) [N]."""
        return np.where(np.asarray(t, dtype=np.float64) >= self.time, float(self.force), 0.0)

    def text(self) -> str:
        """The command-line form (``step:F:T``, numbers as their shortest repr)."""
        return f"step:{float(self.force)!r}:{float(self.time)!r}"


@dataclass(frozen=True, slots=True, eq=False)
class LoadPoints:
    """Piecewise-linear force through ``(times [s], forces [N])``, held before the first
    point and after the last."""

    times: FloatArray  #: instants, strictly increasing, >= 0 [s]
    forces: FloatArray  #: force at each instant, > 0 opposes extension [N]
    source: str = ""  #: the file the points were read from, "" when given inline

    def __post_init__(self) -> None:
        t = np.array(self.times, dtype=np.float64)
        f = np.array(self.forces, dtype=np.float64)
        if t.ndim != 1 or t.shape != f.shape or t.size == 0:
            raise InputError(f"load force points need as many times as forces (at least "
                             f"one), got {t.size} and {f.size}")
        for v in f.tolist():
            _force("point F", v)
        for v in t.tolist():
            _time("point time", v)
        bad = np.nonzero(np.diff(t) <= 0.0)[0]
        if bad.size:
            i = int(bad[0])
            raise InputError(f"load force point times must increase strictly, got "
                             f"{t[i]!r} s then {t[i + 1]!r} s")
        t.flags.writeable = False
        f.flags.writeable = False
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "forces", f)

    def values(self, t: FloatArray) -> FloatArray:
        """F(t) [N]."""
        return np.interp(np.asarray(t, dtype=np.float64), self.times, self.forces)


def _number(spec: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(f"--load-force {spec!r}: {text.strip()!r} is not a number; "
                         f"allowed: {LOAD_FORCE_FORMS}") from None


def parse_load_force(spec: str) -> LoadForce | None:
    """The load-force profile of ``--load-force`` (None for ``""``: no load force).

    ``step:F[:T]``, ``pwl:T0:F0,T1:F1,...``, or a CSV file (a name ending in ``.csv``) with
    columns ``t`` [s] and ``F`` [N] under a header, read by the package's CSV reader
    (:func:`fuzzyservo._io.read_csv_columns`: strict UTF-8, every value finite).

    Raises
    ------
    InputError
        An unknown form, a value that is not a number, a non-finite force, a negative time,
        point times that do not increase, an unreadable or malformed file (one line naming
        the value and what is allowed).
    """
    text = spec.strip()
    if not text:
        return None
    kind, sep, body = text.partition(":")
    kind = kind.strip().lower()
    if sep and kind == "step":
        parts = body.split(":")
        if not 1 <= len(parts) <= 2:
            raise InputError(f"--load-force {spec!r}: a step is step:F[:T] (F [N], T [s]), "
                             f"got {len(parts)} numbers")
        return LoadStep(*(_number(spec, p) for p in parts))
    if sep and kind == "pwl":
        times: list[float] = []
        forces: list[float] = []
        for item in body.split(","):
            t_text, colon, f_text = item.partition(":")
            if not colon:
                raise InputError(f"--load-force {spec!r}: a point is T:F (T [s], F [N]), "
                                 f"got {item!r}")
            times.append(_number(spec, t_text))
            forces.append(_number(spec, f_text))
        return LoadPoints(np.array(times), np.array(forces))
    if text.lower().endswith(".csv"):
        cols = read_csv_columns(Path(text), ("t", "F"), what="load-force CSV")
        try:
            return LoadPoints(cols["t"], cols["F"], source=text)
        except InputError as exc:
            raise InputError(f"load-force CSV {text!r}: {exc}") from None
    raise InputError(f"unknown --load-force {spec!r}; allowed: {LOAD_FORCE_FORMS}")


def load_force_samples(load: LoadForce, t: FloatArray, base: float = 0.0) -> FloatArray:
    """The total external force per sample [N]: ``base`` (the parameter set's
    ``load.external_force``) plus the profile at each sample instant ``t`` [s], each held over
    its sample by the loops."""
    f = np.asarray(load.values(np.asarray(t, dtype=np.float64)), dtype=np.float64)
    if f.shape != np.shape(t):
        raise InputError(f"a load-force profile gave {f.shape} values for {np.shape(t)} "
                         f"sample times")
    return np.ascontiguousarray(f + float(base)) if base != 0.0 else np.ascontiguousarray(f)
