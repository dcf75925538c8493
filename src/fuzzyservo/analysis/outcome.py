"""How a step response ends: the one rule that classifies a run, and its thresholds.

The study's claims C6 and C8 (:func:`fuzzyservo.study.claims.response_outcome`, one run with
the sentence of evidence) and the sweep (:func:`fuzzyservo.sweep.run.compute_chunk`, every
run of a chunk) both call :func:`classify`. Outcomes (:data:`OUTCOMES`), the first that
applies from the bottom of this list up:

``settles``      settles within the limit: the run is *robust*
``overshoots``   settles, but overshoots more than :data:`MAX_OVERSHOOT_PCT`
``not settled``  never inside the 2 % band for good (the settling time is NaN)
``limit cycle``  the tail (last :data:`TAIL_FRACTION` of the run) swings at least
                 :data:`LIMIT_CYCLE_MIN_SWINGS` times, peak to peak at least
                 :data:`LIMIT_CYCLE_MIN_PP` of the step, and does not die out (second half's
                 peak-to-peak at least :data:`LIMIT_CYCLE_MIN_SUSTAIN` of the first half's)
``diverged``     the state became non-finite
``invalid``      (a sweep's point) no valid plant to run: a drawn parameter out of its range,
                 no equilibrium, a delay longer than the run, a reference out of the stroke

The tail's measures are :func:`tail_oscillation`'s for one run, and ``BatchResult.tail``'s
for a batch: both are :func:`fuzzyservo.sim.stepinfo.tail_oscillation_core`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray
from ..sim.stepinfo import N_TAIL, tail_oscillation_core

__all__ = [
    "LIMIT_CYCLE_MIN_PP",
    "LIMIT_CYCLE_MIN_SUSTAIN",
    "LIMIT_CYCLE_MIN_SWINGS",
    "MAX_OVERSHOOT_PCT",
    "OUTCOMES",
    "TAIL_FRACTION",
    "TailOscillation",
    "classify",
    "tail_oscillation",
]

#: Outcomes of a run, from best to worst.
OUTCOMES: tuple[str, ...] = ("settles", "overshoots", "not settled", "limit cycle", "diverged",
                             "invalid")

#: The paper's design condition for its PID (overshoot <= 10 %), also the constraint every
#: tuned design of the study meets; a run that exceeds it is not "robust" (C6, C8) [%].
MAX_OVERSHOOT_PCT = 10.0
#: Fraction of the run, at its end, over which a response is examined for a limit cycle, and
#: α_F for being constant (C4) [-].
TAIL_FRACTION = 0.25
#: A limit cycle is an oscillation of at least this peak-to-peak size [fraction of the step]:
#: +-0.5 % of the step, the resolution the study reads into the paper's plots (as for "no
#: overshoot"); smaller wiggles are not something the paper could show or mean.
LIMIT_CYCLE_MIN_PP = 0.01
#: ... that swings across its mean (with a hysteresis of a quarter of its peak-to-peak) at
#: least this many times in the tail: two full periods, the least that shows a repetition [-].
LIMIT_CYCLE_MIN_SWINGS = 4
#: ... and is sustained: its peak-to-peak over the second half of the tail is at least this
#: fraction of that over the first half (a decaying oscillation loses more) [-].
LIMIT_CYCLE_MIN_SUSTAIN = 0.5


@dataclass(frozen=True, slots=True)
class TailOscillation:
    """How y moves over the last part of a run (see :func:`tail_oscillation`)."""

    peak_to_peak: float  #: max - min of y over the tail [m]
    swings: int  #: alternations across mean +- peak_to_peak/4 (half periods) [-]
    period: float  #: mean period of the swings, NaN with fewer than 3 [s]
    sustain: float  #: peak-to-peak of the tail's second half over its first half's [-]
    window: float  #: length of the tail [s]


def tail_oscillation(t: FloatArray, y: FloatArray, *,
                     tail: float = TAIL_FRACTION) -> TailOscillation:
    """Measure the oscillation of ``y`` over the last ``tail`` fraction of the run.

    A swing is counted each time y passes from below its tail mean minus a quarter of its
    tail peak-to-peak to above the mean plus that quarter, or back (a hysteresis relative to
    the oscillation itself, so that tiny wiggles at the mean are not counted). The measures
    are :func:`fuzzyservo.sim.stepinfo.tail_oscillation_core`'s, the function the batch
    simulator fills ``BatchResult.tail`` with (``t`` non-decreasing [s], ``y`` [m]).
    """
    tc = np.ascontiguousarray(t, dtype=np.float64)
    yc = np.ascontiguousarray(y, dtype=np.float64)
    if tc.ndim != 1 or tc.shape != yc.shape:
        raise ValueError(f"t and y need the same 1-D shape, got {tc.shape} and {yc.shape}")
    out = np.empty(N_TAIL + 1)
    tail_oscillation_core(tc, yc, float(tail), out)
    return TailOscillation(float(out[0]), int(out[1]), float(out[2]), float(out[3]),
                           float(out[N_TAIL]))


def classify(metrics: Mapping[str, FloatArray], step: FloatArray, diverged: np.ndarray,
             invalid: np.ndarray | None = None) -> np.ndarray:
    """The outcome of each run (see the module docstring), as an array of str.

    Parameters
    ----------
    metrics : mapping
        Per run: ``overshoot`` [%], ``settling_time`` [s] (NaN: not settled) and the tail
        oscillation, ``tail_peak_to_peak`` [m], ``tail_swings`` [-] and ``tail_sustain`` [-]
        (NaN where the tail was not measured: no limit cycle).
    step : array
        The move a limit cycle is measured against, per run [m].
    diverged : array of bool
        The state became non-finite.
    invalid : array of bool, optional
        The run has no valid plant (a sweep's point); None: none is invalid.
    """
    n = diverged.shape[0]
    out = np.full(n, "settles", dtype=object)
    os_ = metrics["overshoot"]
    settle = metrics["settling_time"]
    with np.errstate(invalid="ignore"):
        out[os_ > MAX_OVERSHOOT_PCT] = "overshoots"
        out[np.isnan(settle)] = "not settled"
        cycle = ((metrics["tail_peak_to_peak"] >= LIMIT_CYCLE_MIN_PP * np.abs(step))
                 & (metrics["tail_swings"] >= LIMIT_CYCLE_MIN_SWINGS)
                 & (metrics["tail_sustain"] >= LIMIT_CYCLE_MIN_SUSTAIN))
    out[cycle] = "limit cycle"
    out[diverged] = "diverged"
    if invalid is not None:
        out[invalid] = "invalid"
    return out
