"""The set of plants of a robust tuning, from a sweep spec (``fuzzyservo tune --robust``).

A robust tuning (:mod:`fuzzyservo.analysis.robust`) runs every candidate on a fixed set of
plants. Here that set is every point of a sweep spec: the plants, delays and sensor noise a
sweep of the spec runs (:class:`fuzzyservo.sweep.run.PointRuns`, so each plant of the set is
the very run ``fuzzyservo sweep`` makes of that point), and the spec's nominal plant, step,
duration, sample time, start and delay become the tuning's recorded setup (what
``fuzzyservo simulate --gains`` runs). The spec's ``[[controllers]]`` are not tuned; they are
what a sweep of the same spec compares.

Limits: at most :data:`MAX_ROBUST_POINTS` points (each generation runs popsize x gains x
points closed loops); the reference must be one step from t = 0 (the tuner's objective and
constraints are normalised by it), so ``amplitude`` may not vary; every point must be valid.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

from ..analysis.autotune import TuningSetup, params_digest
from ..analysis.robust import MAX_ROBUST_POINTS, RobustRecord, RobustSet, parse_statistic
from ..errors import ParameterError
from ..sim.closed_loop import time_grid
from ..sim.references import Step, parse_reference
from .run import PointRuns
from .sampling import Points, points
from .spec import SweepSpec

__all__ = ["MAX_ROBUST_POINTS", "robust_set", "robust_setup", "set_digest"]

def set_digest(spec: SweepSpec) -> str:
    """SHA-256 of what defines the spec's set of plants, and nothing else: the plant kind,
    every nominal parameter value (whatever set and overrides gave it), start, sample time,
    duration, RK4 substep, reference, nominal delay and noise, and every point's drawn values
    and noise seed. Not the spec's title, chunking or controllers (adding a design to compare
    keeps the record of a design tuned on the set true), nor how the spec's text or canonical
    record is laid out; a change of how points are drawn changes it.

    Raises
    ------
    ParameterError
        More than :data:`MAX_ROBUST_POINTS` points.
    """
    _check_size(spec)
    return _digest(spec, points(spec, 0, spec.n_points))


def _digest(spec: SweepSpec, pts: Points) -> str:
    rec = {"plant": spec.plant, "params": params_digest(spec.nominal), "start": spec.start,
           "ts": spec.ts, "duration": spec.duration, "substep": spec.substep,
           "reference": spec.reference, "delay": spec.delay, "noise_std": spec.noise_std,
           "points": {name: [repr(float(x)) for x in vals] for name, vals in pts.values.items()},
           "noise_seeds": [int(x) for x in pts.noise_seed]}
    text = json.dumps(rec, sort_keys=True, allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def _check_size(spec: SweepSpec) -> None:
    n = spec.n_points
    if n > MAX_ROBUST_POINTS:
        raise ParameterError(f"the robust set has {n} points (grid cells x samples); at most "
                             f"{MAX_ROBUST_POINTS} are allowed, since every generation runs "
                             f"each candidate on every point: lower samples or the grid")


def _step(spec: SweepSpec) -> float:
    ref = parse_reference(spec.reference)
    if not isinstance(ref, Step) or ref.time != 0.0:
        raise ParameterError(f"a robust tuning needs a step reference from t = 0 "
                             f"(reference.spec = \"step:0.1\"), the spec has "
                             f"{spec.reference!r}")
    if spec.load_force:
        raise ParameterError(f"a robust tuning runs without a load-force disturbance: drop "
                             f"[sweep] load_force ({spec.load_force!r})")
    if any(v.name == "amplitude" for v in spec.vary):
        raise ParameterError("a robust tuning runs one step on every plant (its objective and "
                             "constraints are normalised by it): the spec must not vary "
                             "amplitude")
    return float(ref.amplitude)


def robust_set(spec: SweepSpec, *, source: str, statistic: str
               ) -> tuple[RobustSet, RobustRecord]:
    """Every point of ``spec`` as a robust set, and its record.

    Parameters
    ----------
    spec : SweepSpec
        The sweep spec whose points are the set.
    source : str
        Where the spec came from (recorded; its path as given).
    statistic : str
        ``mean``, ``worst`` or ``pNN`` (:func:`fuzzyservo.analysis.robust.parse_statistic`).

    Returns
    -------
    (RobustSet, RobustRecord)

    Raises
    ------
    ParameterError
        More than :data:`MAX_ROBUST_POINTS` points, a reference that is not a step from
        t = 0 or a varied amplitude, an invalid point (named, with the reason), a bad
        statistic.
    """
    stat = parse_statistic(statistic)
    _check_size(spec)
    n = spec.n_points
    _step(spec)
    pts = points(spec, 0, n)
    t = time_grid(spec.duration, spec.ts)
    runs = PointRuns(spec, pts, t)
    for j, err in enumerate(runs.error):
        if err is not None:
            raise ParameterError(f"point {int(pts.index[j])} of the robust set is invalid "
                                 f"({err}); every point must run")
    rset = RobustSet(plants=tuple(runs.plants), delays=runs.delay, noise=runs.noise,
                     labels=tuple(int(i) for i in pts.index))
    record = RobustRecord(source=source, digest=_digest(spec, pts), points=n, statistic=stat)
    return rset, record


def robust_setup(spec: SweepSpec, setup: TuningSetup, record: RobustRecord) -> TuningSetup:
    """``setup`` with the spec's nominal plant, parameter set and overrides, start, step,
    duration, sample time and delay, and the robust set's ``record``."""
    return replace(setup, plant=spec.plant, param_set=spec.param_set,
                   overrides=tuple(spec.overrides), start=spec.start, step=_step(spec),
                   duration=spec.duration, ts=spec.ts, delay=spec.delay, robust=record)
