"""Gains files: the TOML a tuning writes (or a user writes), and controllers built from it.

A gains file holds the controller name (a registry name) and its gains::

    controller = "pid2"
    [gains]
    kp = 10.0
    ki = 10.0
    kd = 0.1
    b = 0.0
    c = 0.0

That is a complete file a user may write by hand. A file ``fuzzyservo tune`` writes adds the
tuning record: the setup that produced the gains (``[tuning]``: plant, parameter set and
overrides, start, step, duration, sample time, delay, objective, constraints, seed,
population, bounds), the step metrics of the tuned run (``[metrics]``), each stage, the
fuzzyservo version and the date (``[result]``). A robust tuning (``tune --robust``) also
records its set of plants (``[tuning.robust]``: the sweep spec, the SHA-256 of the set, the
number of plants and the statistic); its ``[tuning]`` plant is the set's nominal one and its
``[metrics]`` are aggregates over the set (:func:`fuzzyservo.analysis.robust.aggregate`).
:func:`read_gains_file` reads either;
:func:`read_gains_toml` reads a tuning record and names the missing or mistyped key of a bad
one; :func:`load_controller` builds the controller of a file through the registry, at the
file's sample time unless told otherwise (the fuzzy PIs' ``kde`` is per sample).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import tomli_w

from .._io import parse_toml, read_text, write_text_atomic
from ..analysis.autotune import StageRecord, TunedGains, TuningSetup, setup_record
from ..analysis.robust import RobustRecord
from ..analysis.tuning import GainBounds, TuningConstraints
from ..control.fuzzy_pi import KernelSystem
from ..errors import InputError, ParameterError
from ..registry import controller_kind

__all__ = ["FORMAT", "GainsFile", "load_controller", "read_gains_file", "read_gains_toml",
           "write_gains_toml"]

#: Version of the file layout written (2: the stopping rule, convergence, generations and
#: gains on a bound are recorded; a gain may be 0). Layout 1 files are read; their searches
#: are reported as not known to have converged.
FORMAT = 2


def write_gains_toml(path: str | Path, tuned: TunedGains) -> Path:
    """Write ``tuned`` to a TOML file (gains, setup, constraints, metrics, stages, provenance).

    Raises
    ------
    OutputError
        If the file cannot be written; it is written atomically, so the previous file, if
        any, is then left as it was.
    """
    tuning = setup_record(tuned.setup)
    del tuning["controller"]  # the file's top-level key
    doc: dict[str, Any] = {
        "format": FORMAT,
        "controller": tuned.controller,
        "structure": tuned.structure,
        "gains": dict(tuned.gains),
        "tuning": tuning,
        "result": {"objective_value": tuned.objective_value, "cost": tuned.cost,
                   "feasible": tuned.feasible, "converged": tuned.converged,
                   "generations": tuned.generations, "n_evaluations": tuned.n_evaluations,
                   "at_bounds": dict(tuned.at_bounds),
                   "restart_spread": tuned.restart_spread, "elapsed": tuned.elapsed,
                   "fuzzyservo_version": tuned.version, "date": tuned.date},
        "metrics": dict(tuned.metrics),
        "stages": [{"name": st.name, "gains": dict(st.gains), "metrics": dict(st.metrics),
                    "objective_value": st.objective_value, "feasible": st.feasible,
                    "n_evaluations": st.n_evaluations, "generations": st.generations,
                    "converged": st.converged, "at_bounds": dict(st.at_bounds),
                    "restart_spread": st.restart_spread}
                   for st in tuned.stages],
    }
    return write_text_atomic(path, tomli_w.dumps(doc))


class _Reader:
    def __init__(self, path: Path) -> None:
        self.path = path

    def get(self, table: Mapping[str, Any], key: str, kind: type | tuple[type, ...],
            where: str) -> Any:
        name = where + str(key)
        if key not in table:
            raise InputError(f"{str(self.path)!r}: missing key {name!r}")
        v = table[key]
        if kind is float and isinstance(v, int) and not isinstance(v, bool):
            try:
                v = float(v)
            except OverflowError:
                raise InputError(f"{str(self.path)!r}: key {name!r} is an integer too large "
                                 f"for a float ({len(str(abs(v)))} digits)") from None
        if not isinstance(v, kind) or (kind is not bool and isinstance(v, bool)):
            raise InputError(f"{str(self.path)!r}: key {name!r} has the wrong type "
                             f"({type(v).__name__}: {v!r})")
        return v

    def floats(self, table: Mapping[str, Any], where: str) -> dict[str, float]:
        return {str(k): float(self.get(table, k, float, where)) for k in table}


def read_gains_toml(path: str | Path) -> TunedGains:
    """Read a gains file written by :func:`write_gains_toml` (``fuzzyservo tune``).

    The controller must be a registered name and the gains those of its kind (checked by the
    registry: an unknown gain, a missing required one or a bad value is an error naming it).

    Raises
    ------
    InputError
        If the file is missing, not TOML, or lacks a key or has one of the wrong type (the
        message names the key), or its controller or gains are not valid.
    """
    path = Path(path)
    return _tuned_from_doc(path, _load_toml(path))


def _check_layout(rd: _Reader, doc: Mapping[str, Any]) -> int:
    """The file's layout (``format``; a file without one is layout 1), refused if this
    version does not read it."""
    layout = rd.get(doc, "format", int, "") if "format" in doc else 1
    if layout not in (1, FORMAT):
        raise InputError(f"{str(rd.path)!r}: gains file layout {layout} is not one this "
                         f"version reads (1 or {FORMAT})")
    return int(layout)


def _tuned_from_doc(path: Path, doc: Mapping[str, Any]) -> TunedGains:
    """The tuning record of a parsed gains file (see :func:`read_gains_toml`)."""
    rd = _Reader(path)
    layout = _check_layout(rd, doc)
    controller = rd.get(doc, "controller", str, "")
    where = f"{str(path)!r}: "
    try:
        kind = controller_kind(controller)
        raw_gains = rd.floats(rd.get(doc, "gains", dict, ""), "gains.")
        gains = kind.check_gains(raw_gains, where=where)
    except ParameterError as exc:
        msg = str(exc)
        raise InputError(msg if msg.startswith(where) else where + msg) from exc
    tu = rd.get(doc, "tuning", dict, "")
    w = "tuning."
    ct = rd.get(tu, "constraints", dict, w)
    cw = "tuning.constraints."
    bt = tu.get("bounds")
    try:
        constraints = TuningConstraints(
            max_overshoot=rd.get(ct, "max_overshoot", float, cw) if "max_overshoot" in ct
            else None,
            max_steady_state_error=rd.get(ct, "max_steady_state_error", float, cw)
            if "max_steady_state_error" in ct else None,
            max_u=rd.get(ct, "max_u", float, cw) if "max_u" in ct else None,
            require_settled=rd.get(ct, "require_settled", bool, cw))
        bounds = None
        if isinstance(bt, dict) and bt:
            names = tuple(bt)
            rows = [bt[n] for n in names]
            width = 3 if layout == 1 else 4
            if not all(isinstance(r, list) and len(r) == width for r in rows):
                raise InputError(f"{str(path)!r}: tuning.bounds entries must be "
                                 f"[lower, upper, log_scale" + (", may_be_zero]" if width == 4
                                                                else "]"))
            rows = [list(r) + [False] * (4 - len(r)) for r in rows]
            for n, r in zip(names, rows, strict=True):
                b = rd.floats({"lower": r[0], "upper": r[1]}, f"tuning.bounds.{n}.")
                r[0], r[1] = b["lower"], b["upper"]
                rd.get({"log_scale": r[2]}, "log_scale", bool, f"tuning.bounds.{n}.")
                rd.get({"may_be_zero": r[3]}, "may_be_zero", bool, f"tuning.bounds.{n}.")
            bounds = GainBounds(names=names, lower=tuple(float(r[0]) for r in rows),
                                upper=tuple(float(r[1]) for r in rows),
                                log_scale=tuple(bool(r[2]) for r in rows),
                                zero=tuple(bool(r[3]) for r in rows))
        systems = []
        for role, entry in (rd.get(tu, "systems", dict, w) if "systems" in tu else {}).items():
            sw = f"tuning.systems.{role}."
            if not isinstance(entry, dict):
                raise InputError(f"{str(path)!r}: tuning.systems.{role} must be a table with "
                                 f"source and sha256")
            systems.append((str(role), rd.get(entry, "source", str, sw),
                            rd.get(entry, "sha256", str, sw)))
        robust = None
        if "robust" in tu:
            rt = rd.get(tu, "robust", dict, w)
            rw = "tuning.robust."
            robust = RobustRecord(source=rd.get(rt, "spec", str, rw),
                                  digest=rd.get(rt, "set_sha256", str, rw),
                                  points=rd.get(rt, "points", int, rw),
                                  statistic=rd.get(rt, "statistic", str, rw))
        setup = TuningSetup(
            controller=controller, plant=rd.get(tu, "plant", str, w),
            param_set=rd.get(tu, "param_set", str, w),
            overrides=tuple(rd.floats(rd.get(tu, "overrides", dict, w),
                                      "tuning.overrides.").items()),
            start=rd.get(tu, "start", float, w), step=rd.get(tu, "step", float, w),
            duration=rd.get(tu, "duration", float, w), ts=rd.get(tu, "ts", float, w),
            delay=rd.get(tu, "delay", float, w), objective=rd.get(tu, "objective", str, w),
            constraints=constraints, seed=rd.get(tu, "seed", int, w),
            popsize=rd.get(tu, "popsize", int, w), maxiter=rd.get(tu, "maxiter", int, w),
            pid_n=rd.get(tu, "pid_n", float, w), polish=rd.get(tu, "polish", bool, w),
            bounds=bounds, systems=tuple(systems), robust=robust,
            **({"restarts": 1} if layout == 1 else {
                "patience": rd.get(tu, "patience", int, w),
                "rtol": rd.get(tu, "rtol", float, w),
                "spread": rd.get(tu, "spread", float, w),
                "restarts": rd.get(tu, "restarts", int, w)}))
    except ParameterError as exc:
        raise InputError(f"{str(path)!r}: {exc}") from exc
    res = rd.get(doc, "result", dict, "")
    w = "result."
    metrics = rd.floats(rd.get(doc, "metrics", dict, ""), "metrics.")
    stages = []
    for i, st in enumerate(rd.get(doc, "stages", list, "")):
        sw = f"stages[{i}]."
        if not isinstance(st, dict):
            raise InputError(f"{str(path)!r}: stages[{i}] must be a table")
        stages.append(StageRecord(
            name=rd.get(st, "name", str, sw),
            gains=rd.floats(rd.get(st, "gains", dict, sw), sw + "gains."),
            metrics=rd.floats(rd.get(st, "metrics", dict, sw), sw + "metrics."),
            objective_value=rd.get(st, "objective_value", float, sw),
            feasible=rd.get(st, "feasible", bool, sw),
            n_evaluations=rd.get(st, "n_evaluations", int, sw),
            **({"converged": False} if layout == 1 else {
                "generations": rd.get(st, "generations", int, sw),
                "converged": rd.get(st, "converged", bool, sw),
                "at_bounds": _sides(rd, rd.get(st, "at_bounds", dict, sw),
                                    sw + "at_bounds."),
                "restart_spread": rd.get(st, "restart_spread", float, sw)})))
    return TunedGains(
        controller=controller, gains=gains, metrics=metrics,
        objective_value=rd.get(res, "objective_value", float, w),
        cost=rd.get(res, "cost", float, w), feasible=rd.get(res, "feasible", bool, w),
        setup=setup, elapsed=rd.get(res, "elapsed", float, w),
        n_evaluations=rd.get(res, "n_evaluations", int, w), stages=tuple(stages),
        version=rd.get(res, "fuzzyservo_version", str, w), date=rd.get(res, "date", str, w),
        **({"converged": False} if layout == 1 else {
            "converged": rd.get(res, "converged", bool, w),
            "generations": rd.get(res, "generations", int, w),
            "at_bounds": _sides(rd, rd.get(res, "at_bounds", dict, w), "result.at_bounds."),
            "restart_spread": rd.get(res, "restart_spread", float, w)}))


def _sides(rd: _Reader, table: Mapping[str, Any], where: str) -> dict[str, str]:
    """An ``at_bounds`` table: gain name -> "lower" or "upper"."""
    out = {}
    for k in table:
        v = rd.get(table, k, str, where)
        if v not in ("lower", "upper"):
            raise InputError(f"{str(rd.path)!r}: key {where + str(k)!r} must be 'lower' or "
                             f"'upper', got {v!r}")
        out[str(k)] = v
    return out


@dataclass(frozen=True, slots=True, kw_only=True)
class GainsFile:
    """A controller as a file gives it."""

    path: Path  #: the file
    controller: str  #: registered controller name
    gains: dict[str, float]  #: every gain of the kind (defaults filled in) [gain units]
    tuned: TunedGains | None  #: the tuning record of a file ``tune`` wrote, else None

    @property
    def ts(self) -> float | None:
        """Sample time the gains were tuned at [s], or None (no tuning record)."""
        return None if self.tuned is None else self.tuned.setup.ts


def _load_toml(path: Path) -> dict[str, Any]:
    """The parsed TOML of a gains file, read as strict UTF-8 (:func:`fuzzyservo._io.read_text`:
    a bad byte is reported with its offset)."""
    if path.is_dir():
        raise InputError(f"gains file {str(path)!r} is a directory; give a gains file (.toml)")
    return parse_toml(read_text(path, "gains file"), f"gains file {str(path)!r}")


def read_gains_file(path: str | Path) -> GainsFile:
    """Read a gains file: ``controller`` and ``[gains]``, and the tuning record if present
    (then read as :func:`read_gains_toml` reads it).

    Raises
    ------
    InputError
        The file cannot be read, is not TOML, or its controller or gains are not valid (the
        message names the file and the key or gain).
    """
    path = Path(path)
    doc = _load_toml(path)
    if any(k in doc for k in ("tuning", "result", "metrics", "stages")):
        tuned = _tuned_from_doc(path, doc)
        return GainsFile(path=path, controller=tuned.controller, gains=dict(tuned.gains),
                         tuned=tuned)
    rd = _Reader(path)
    _check_layout(rd, doc)
    controller = rd.get(doc, "controller", str, "")
    where = f"{str(path)!r}: "
    unknown = sorted(set(doc) - {"controller", "gains", "format"})
    if unknown:
        raise InputError(f"{where}unknown key '{unknown[0]}'; a gains file has controller, "
                         f"[gains] and, when tune wrote it, [tuning], [result], [metrics], "
                         f"[[stages]]")
    try:
        kind = controller_kind(controller)
        gains = kind.check_gains(rd.floats(rd.get(doc, "gains", dict, ""), "gains."),
                                 where=where)
    except ParameterError as exc:
        msg = str(exc)
        raise InputError(msg if msg.startswith(where) else where + msg) from exc
    return GainsFile(path=path, controller=controller, gains=gains, tuned=None)


def load_controller(path: str | Path, *, dt: float | None = None,
                    systems: Mapping[str, KernelSystem] | None = None,
                    options: Mapping[str, Any] | None = None) -> tuple[Any, GainsFile]:
    """The controller of a gains file, built through the registry, and the file's content.

    Parameters
    ----------
    path : str or Path
        Gains file (``fuzzyservo tune --out``, a committed one, or a hand-written one).
    dt : float, optional
        Sample period [s]; default the file's ``tuning.ts`` (the fuzzy PIs' ``kde`` is per
        sample, so the gains mean what they were tuned for only at that sample time).
        Required for a file without a tuning record.
    systems : mapping, optional
        Fuzzy systems by role; default the paper's.
    options : mapping, optional
        Controller options the kind takes (anti-windup, fuzzy PI conventions, limits).

    Returns
    -------
    (controller, GainsFile)

    Raises
    ------
    InputError
        The file cannot be read or is not a valid gains file.
    ParameterError
        No ``dt`` for a file that records no sample time.
    """
    gf = read_gains_file(path)
    ts = gf.ts if dt is None else dt
    if ts is None:
        raise ParameterError(f"{str(gf.path)!r} records no sample time (no tuning record): "
                             f"give dt")
    ctl = controller_kind(gf.controller).build(gf.gains, dt=ts, systems=systems,
                                               options=options)
    return ctl, gf
