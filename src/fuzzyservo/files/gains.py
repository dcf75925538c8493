"""Gains files: the TOML a tuning writes, and controllers built from it.

A gains file holds the controller name (a registry name) and its gains, the tuning setup that
produced them (plant, parameter set and overrides, start, step, duration, sample time, delay,
objective, constraints, seed, population, bounds), the step metrics of the tuned run, each
stage, the fuzzyservo version and the date. :func:`read_gains_toml` names the missing or
mistyped key of a bad file; :func:`load_controller` builds the controller of a file through
the registry, at the file's sample time unless told otherwise (``kde`` is per sample).
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import tomli_w

from ..analysis.autotune import StageRecord, TunedGains, TuningSetup
from ..analysis.tuning import GainBounds, TuningConstraints
from ..control.fuzzy_pi import KernelSystem
from ..errors import InputError, ParameterError
from ..registry import controller_kind

__all__ = ["FORMAT", "load_controller", "read_gains_toml", "write_gains_toml"]

#: Version of the file layout written.
FORMAT = 1


def _constraints_table(c: TuningConstraints) -> dict[str, Any]:
    out: dict[str, Any] = {"require_settled": c.require_settled}
    for name in ("max_overshoot", "max_steady_state_error", "max_u"):
        v = getattr(c, name)
        if v is not None:
            out[name] = float(v)
    return out


def write_gains_toml(path: str | Path, tuned: TunedGains) -> Path:
    """Write ``tuned`` to a TOML file (gains, setup, constraints, metrics, stages, provenance).

    Raises
    ------
    InputError
        If the file cannot be written.
    """
    s = tuned.setup
    b = s.search_bounds()
    doc: dict[str, Any] = {
        "format": FORMAT,
        "controller": tuned.controller,
        "gains": dict(tuned.gains),
        "tuning": {
            "plant": s.plant, "param_set": s.param_set,
            "overrides": {k: float(v) for k, v in s.overrides},
            "start": s.start, "step": s.step, "duration": s.duration, "ts": s.ts,
            "delay": s.delay, "objective": s.objective, "seed": s.seed,
            "popsize": s.popsize, "maxiter": s.maxiter, "pid_n": s.pid_n, "polish": s.polish,
            "constraints": _constraints_table(s.constraints),
            "bounds": {n: [lo, hi, lg] for n, lo, hi, lg in
                       zip(b.names, b.lower, b.upper, b.log_scale, strict=True)},
        },
        "result": {"objective_value": tuned.objective_value, "cost": tuned.cost,
                   "feasible": tuned.feasible, "elapsed": tuned.elapsed,
                   "n_evaluations": tuned.n_evaluations,
                   "fuzzyservo_version": tuned.version, "date": tuned.date},
        "metrics": dict(tuned.metrics),
        "stages": [{"name": st.name, "gains": dict(st.gains), "metrics": dict(st.metrics),
                    "objective_value": st.objective_value, "feasible": st.feasible,
                    "n_evaluations": st.n_evaluations} for st in tuned.stages],
    }
    path = Path(path)
    try:
        path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot write {str(path)!r}: {exc.strerror}") from exc
    return path


class _Reader:
    def __init__(self, path: Path) -> None:
        self.path = path

    def get(self, table: Mapping[str, Any], key: str, kind: type | tuple[type, ...],
            where: str) -> Any:
        if key not in table:
            raise InputError(f"{str(self.path)!r}: missing key '{where}{key}'")
        v = table[key]
        if kind is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        if not isinstance(v, kind) or (kind is not bool and isinstance(v, bool)):
            raise InputError(f"{str(self.path)!r}: key '{where}{key}' has the wrong type "
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
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read gains file {str(path)!r}: {exc.strerror}") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{str(path)!r} is not valid TOML: {exc}") from exc
    rd = _Reader(path)
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
            if not all(isinstance(r, list) and len(r) == 3 for r in rows):
                raise InputError(f"{str(path)!r}: tuning.bounds entries must be "
                                 f"[lower, upper, log_scale]")
            bounds = GainBounds(names=names, lower=tuple(float(r[0]) for r in rows),
                                upper=tuple(float(r[1]) for r in rows),
                                log_scale=tuple(bool(r[2]) for r in rows))
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
            bounds=bounds)
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
            n_evaluations=rd.get(st, "n_evaluations", int, sw)))
    return TunedGains(
        controller=controller, gains=gains, metrics=metrics,
        objective_value=rd.get(res, "objective_value", float, w),
        cost=rd.get(res, "cost", float, w), feasible=rd.get(res, "feasible", bool, w),
        setup=setup, elapsed=rd.get(res, "elapsed", float, w),
        n_evaluations=rd.get(res, "n_evaluations", int, w), stages=tuple(stages),
        version=rd.get(res, "fuzzyservo_version", str, w), date=rd.get(res, "date", str, w))


def load_controller(path: str | Path, *, dt: float | None = None,
                    systems: Mapping[str, KernelSystem] | None = None,
                    options: Mapping[str, Any] | None = None) -> tuple[Any, TunedGains]:
    """The controller of a gains file, built through the registry, and the file's record.

    Parameters
    ----------
    path : str or Path
        Gains file (``fuzzyservo tune --out``, or a committed one).
    dt : float, optional
        Sample period [s]; default the file's ``tuning.ts`` (the fuzzy PIs' ``kde`` is per
        sample, so the gains mean what they were tuned for only at that sample time).
    systems : mapping, optional
        Fuzzy systems by role; default the paper's.
    options : mapping, optional
        Controller options the kind takes (anti-windup, fuzzy PI conventions, limits).

    Returns
    -------
    (controller, TunedGains)

    Raises
    ------
    InputError
        The file cannot be read or is not a valid gains file.
    """
    tuned = read_gains_toml(path)
    ctl = controller_kind(tuned.controller).build(
        tuned.gains, dt=tuned.setup.ts if dt is None else dt, systems=systems,
        options=options)
    return ctl, tuned
