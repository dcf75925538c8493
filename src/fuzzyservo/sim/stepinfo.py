"""Compiled cores of the step-response metrics and of the tail oscillation, shared by the batch
kernel and the analysis and study APIs.

:func:`step_metrics_core` fills a float64 buffer in the order of :data:`METRIC_NAMES` without
allocating, so the batched closed-loop kernel can call it once per run on a reused per-thread
buffer; :func:`fuzzyservo.analysis.step_metrics` validates its input, calls the same function and
wraps the buffer in a frozen ``StepMetrics``. The definitions are those of python-control's
``step_info`` (threshold crossings and band exits taken at samples, no interpolation), measured
between an initial value ``y0`` and a target ``y_final``; ``docs/model.md`` ("Step metrics")
defines each metric and says when it is NaN.

:func:`tail_oscillation_core` measures how a response moves over the last part of the run (its
peak-to-peak, swings across its mean, their period and whether they are sustained): the batch
kernel fills ``BatchResult.tail`` with it and :func:`fuzzyservo.analysis.outcome.tail_oscillation`
(one run's, for the limit-cycle test of the outcome rule) wraps it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._jit import kernel
from .._typing import FloatArray
from ..errors import ParameterError

__all__ = [
    "METRIC_NAMES",
    "NO_STEP_RTOL",
    "N_METRICS",
    "N_TAIL",
    "SETTLE_HOLD_FRACTION",
    "StepMetrics",
    "TAIL_NAMES",
    "TAIL_WORK",
    "metric_options",
    "metrics_of",
    "step_metrics_core",
    "tail_oscillation_core",
    "tail_oscillation_work",
]

#: Names of the metrics, in the order :func:`step_metrics_core` writes them.
METRIC_NAMES: tuple[str, ...] = (
    "rise_time",
    "settling_time",
    "settling_time_5",
    "overshoot",
    "peak",
    "peak_time",
    "steady_state_error",
    "iae",
    "ise",
    "itae",
    "itse",
    "u_max",
    "u_sq_integral",
    "u_total_variation",
)

#: Number of metrics; ``out`` must hold at least this many values.
N_METRICS: int = len(METRIC_NAMES)

#: Names of the tail-oscillation measures, in the order :func:`tail_oscillation_core` writes
#: them (its ``out[N_TAIL]`` is the length of the tail window, not a measure of the response).
TAIL_NAMES: tuple[str, ...] = (
    "tail_peak_to_peak",
    "tail_swings",
    "tail_period",
    "tail_sustain",
)

#: Number of tail measures; ``tail_oscillation_core``'s ``out`` holds ``N_TAIL + 1`` values.
N_TAIL: int = len(TAIL_NAMES)

#: Fraction of the record (``t[-1] - t[0]``) at its end that a response must spend inside a
#: settling band to count as settled: a settling time is NaN unless the last sample outside
#: the band is at or before ``t[0] + (1 - SETTLE_HOLD_FRACTION) (t[-1] - t[0])``. Without it a
#: sustained oscillation (limit cycle) that happens to be inside the band at the last few
#: samples would be reported as settled just before the end of the run [1].
SETTLE_HOLD_FRACTION: float = 0.1

#: Relative tolerance below which ``y_final - y0`` counts as no step: the span is zero when
#: ``|y_final - y0| <= NO_STEP_RTOL * max(1, |y0|, |y_final|, max(y) - min(y))``. Rounding
#: (e.g. a sine reference ending at ``0.5 + 0.05 sin(6 pi)`` instead of 0.5) must not turn a
#: run with no step into one whose overshoot is divided by 1e-17 [1].
NO_STEP_RTOL: float = 1e-9

_RISE, _SETTLE, _SETTLE2, _OS, _PEAK, _TPEAK, _ESS = 0, 1, 2, 3, 4, 5, 6
_IAE, _ISE, _ITAE, _ITSE, _UMAX, _USQ, _UTV = 7, 8, 9, 10, 11, 12, 13


@kernel
def step_metrics_core(
    t: FloatArray,
    y: FloatArray,
    u: FloatArray,
    r: FloatArray,
    y0: float,
    y_final: float,
    rise_lo: float,
    rise_hi: float,
    band: float,
    band2: float,
    out: FloatArray,
) -> None:
    """Write the step metrics of one response into ``out[:N_METRICS]``, allocating nothing.

    Parameters
    ----------
    t : float64[:]
        Sample times, strictly increasing; times are measured from ``t[0]`` [s].
    y : float64[:]
        Output samples, same length as ``t`` [unit of y].
    u : float64[:]
        Command samples, each held over ``[t[k], t[k+1])`` (zero-order hold); an array whose
        length differs from ``len(t)`` (e.g. empty) means "no command": the three ``u_*``
        metrics are then NaN [unit of u].
    r : float64[:]
        Reference samples, same length as ``t``; the error is ``e = r - y`` [unit of y].
    y0 : float
        Initial value the step starts from [unit of y].
    y_final : float
        Target of the step; rise, overshoot and settling are measured between ``y0`` and it
        [unit of y].
    rise_lo, rise_hi : float
        Rise-time thresholds as fractions of ``y_final - y0``, ``0 <= rise_lo < rise_hi`` [1].
    band, band2 : float
        Half-widths of the settling bands around ``y_final`` as fractions of
        ``|y_final - y0|`` (0.02 and 0.05 for ``settling_time`` and ``settling_time_5``) [1].
    out : float64[:]
        Output buffer of length at least ``N_METRICS``, filled in the order of
        ``METRIC_NAMES`` [mixed units].

    Notes
    -----
    The kernel assumes valid input (finite values, strictly increasing ``t``, ``len(t) >= 1``);
    the analysis API validates. A metric the data cannot define is NaN: rise time, both
    settling times, overshoot and peak time when there is no step (``|y_final - y0|`` within
    :data:`NO_STEP_RTOL` of the signal's scale); rise time when ``y`` never reaches
    ``rise_hi``; a settling time when ``y`` leaves its band during the last
    :data:`SETTLE_HOLD_FRACTION` of the record (not shown to settle within the record).
    """
    n = t.shape[0]
    for i in range(N_METRICS):
        out[i] = np.nan
    if n == 0:
        return
    t0 = t[0]

    # Peak: largest excursion from y0 (first sample attaining it); y's range for the no-step
    # test; in the same pass the largest excursion beyond y_final in the step's direction.
    span = y_final - y0
    s = 1.0 if span > 0.0 else -1.0
    k_pk = 0
    d_max = -1.0
    y_min = y[0]
    y_max = y[0]
    os_max = 0.0
    for k in range(n):
        d = abs(y[k] - y0)
        if d > d_max:
            d_max = d
            k_pk = k
        y_min = min(y_min, y[k])
        y_max = max(y_max, y[k])
        d = s * (y[k] - y_final)
        if d > os_max:
            os_max = d
    out[_PEAK] = y[k_pk]

    scale = max(1.0, abs(y0), abs(y_final), y_max - y_min)
    if abs(span) > NO_STEP_RTOL * scale and math.isfinite(span):
        out[_TPEAK] = t[k_pk] - t0
        # Rise time: first samples at or beyond the two thresholds (python-control's rule).
        lvl_lo = y0 + rise_lo * span
        lvl_hi = y0 + rise_hi * span
        k_lo = -1
        for k in range(n):
            if k_lo < 0 and s * (y[k] - lvl_lo) >= 0.0:
                k_lo = k
            if s * (y[k] - lvl_hi) >= 0.0:
                out[_RISE] = t[k] - t[k_lo]
                break
        # Settling: the sample after the last one outside the band (|y - y_final| >= band).
        half1 = band * abs(span)
        half2 = band2 * abs(span)
        last1 = -2
        last2 = -2
        for k in range(n - 1, -1, -1):
            dev = abs(y[k] - y_final)
            if last1 == -2 and dev >= half1:
                last1 = k
            if last2 == -2 and dev >= half2:
                last2 = k
            if last1 != -2 and last2 != -2:
                break
        # Settled only if the last exit is no later than the start of the record's final
        # SETTLE_HOLD_FRACTION (a limit cycle may be inside the band at its last samples).
        # A last exit within 1e-9 of the record of that instant counts as on time, so rounding
        # of shifted time stamps cannot flip a sample that lies on it (samples are far apart).
        t_hold = (1.0 - SETTLE_HOLD_FRACTION + 1e-9) * (t[n - 1] - t0)
        if last1 == -2:
            out[_SETTLE] = 0.0
        elif last1 < n - 1 and t[last1] - t0 <= t_hold:
            out[_SETTLE] = t[last1 + 1] - t0
        if last2 == -2:
            out[_SETTLE2] = 0.0
        elif last2 < n - 1 and t[last2] - t0 <= t_hold:
            out[_SETTLE2] = t[last2 + 1] - t0
        # Overshoot: largest excursion beyond the target in the step's direction [%].
        out[_OS] = 100.0 * os_max / abs(span)

    out[_ESS] = r[n - 1] - y[n - 1]

    # Integral criteria of e = r - y, trapezoid on the samples, time from t[0].
    iae = 0.0
    ise = 0.0
    itae = 0.0
    itse = 0.0
    for k in range(n - 1):
        h = t[k + 1] - t[k]
        ea = r[k] - y[k]
        eb = r[k + 1] - y[k + 1]
        ta = t[k] - t0
        tb = t[k + 1] - t0
        iae += 0.5 * h * (abs(ea) + abs(eb))
        ise += 0.5 * h * (ea * ea + eb * eb)
        itae += 0.5 * h * (ta * abs(ea) + tb * abs(eb))
        itse += 0.5 * h * (ta * ea * ea + tb * eb * eb)
    out[_IAE] = iae
    out[_ISE] = ise
    out[_ITAE] = itae
    out[_ITSE] = itse

    # Command metrics: u is zero-order held, so its integral is the exact left sum.
    if u.shape[0] == n:
        u_max = 0.0
        u_sq = 0.0
        u_tv = 0.0
        for k in range(n - 1):
            a = abs(u[k])
            if a > u_max:
                u_max = a
            u_sq += u[k] * u[k] * (t[k + 1] - t[k])
            u_tv += abs(u[k + 1] - u[k])
        a = abs(u[n - 1])
        if a > u_max:
            u_max = a
        out[_UMAX] = u_max
        out[_USQ] = u_sq
        out[_UTV] = u_tv


# Tail oscillation. The sums are numpy's pairwise summation (numpy's ``pairwise_sum``: eight
# interleaved partial sums in blocks of at most 128 values, the two halves of a larger range
# summed separately and added), so the tail's mean and the mean swing period are bit for bit
# those of ``np.mean``. The values are drawn in order from a stream (the tail's samples, or
# the times between its swings), so nothing is stored; the halves are walked with an explicit
# stack in a caller's work array (a recursive njit function cannot be cached: numba #6061).
_PW_BLOCK = 128
#: Rows of the work array of :func:`tail_oscillation_work` (the depth of the pairwise tree).
TAIL_WORK = 64


@kernel(inline=True)
def _stream_next(mode: int, t: FloatArray, y: FloatArray, k: int, side: int, t_last: float,
                 mean: float, h: float) -> tuple[float, int, int, float]:
    """Next value of a stream and the stream's new state ``(k, side, t_last)``.

    Mode 0: the sample ``y[k]``. Mode 1: the time from the last swing (at ``t_last``, to
    ``side``) to the next one at or after ``k``: the next sample whose deviation from ``mean``
    is beyond ``h`` on the other side.
    """
    if mode == 0:
        return y[k], k + 1, side, t_last
    while True:
        dev = y[k] - mean
        s = 1 if dev > h else (-1 if dev < -h else 0)
        if s != 0 and s != side:
            return t[k] - t_last, k + 1, s, t[k]
        k += 1


@kernel(inline=True)
def _block_stream(mode: int, n: int, t: FloatArray, y: FloatArray, k: int, side: int,
                  t_last: float, mean: float, h: float) -> tuple[float, int, int, float]:
    """numpy's sum of a block of ``n <= 128`` stream values; the sum and the new state."""
    if n < 8:
        res = 0.0
        for _ in range(n):
            v, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
            res += v
        return res, k, side, t_last
    r0, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
    r1, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
    r2, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
    r3, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
    r4, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
    r5, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
    r6, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
    r7, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
    i = 8
    while i < n - n % 8:
        v, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
        r0 += v
        v, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
        r1 += v
        v, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
        r2 += v
        v, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
        r3 += v
        v, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
        r4 += v
        v, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
        r5 += v
        v, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
        r6 += v
        v, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
        r7 += v
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        v, k, side, t_last = _stream_next(mode, t, y, k, side, t_last, mean, h)
        res += v
        i += 1
    return res, k, side, t_last


@kernel(inline=True)
def _pairwise_stream(mode: int, n: int, t: FloatArray, y: FloatArray, k: int, side: int,
                     t_last: float, mean: float, h: float, work: FloatArray) -> float:
    """Sum of the next ``n`` values of a stream (:func:`_stream_next`) in numpy's pairwise
    order. ``work`` (TAIL_WORK, 3) is the stack of the ranges split in two: the size of the
    right half, the left half's sum, whether the left half is done."""
    d = 0
    size = n
    while True:
        while size > _PW_BLOCK:
            n2 = size // 2
            n2 -= n2 % 8
            work[d, 0] = size - n2
            work[d, 2] = 0.0
            d += 1
            size = n2
        v, k, side, t_last = _block_stream(mode, size, t, y, k, side, t_last, mean, h)
        while d > 0 and work[d - 1, 2] == 1.0:
            d -= 1
            v = work[d, 1] + v
        if d == 0:
            return v
        work[d - 1, 1] = v
        work[d - 1, 2] = 1.0
        size = int(work[d - 1, 0])


@kernel
def tail_oscillation_core(t: FloatArray, y: FloatArray, tail_fraction: float,
                          out: FloatArray) -> None:
    """:func:`tail_oscillation_work` with its own work array (one small allocation)."""
    tail_oscillation_work(t, y, tail_fraction, out, np.empty((TAIL_WORK, 3)))


@kernel
def tail_oscillation_work(t: FloatArray, y: FloatArray, tail_fraction: float,
                          out: FloatArray, work: FloatArray) -> None:
    """Write how ``y`` moves over the last ``tail_fraction`` of the record into ``out``,
    allocating nothing (scratch in ``work``): ``out[:N_TAIL]`` in the order of
    :data:`TAIL_NAMES`, ``out[N_TAIL]`` the length of the window.

    Parameters
    ----------
    t : float64[:]
        Sample times, non-decreasing [s].
    y : float64[:]
        Samples, same length as ``t`` [unit of y].
    tail_fraction : float
        The window is ``t >= t[0] + (1 - tail_fraction) (t[-1] - t[0])`` [1].
    out : float64[:]
        At least ``N_TAIL + 1`` values: the peak-to-peak of y over the window (max - min)
        [unit of y]; the swings, the number of times y passes from below the window's mean
        minus a quarter of that peak-to-peak to above the mean plus that quarter, or back
        (a hysteresis relative to the oscillation itself, so tiny wiggles at the mean do not
        count) [1]; the period, twice the mean time between consecutive swings (NaN with
        fewer than 3 swings) [s]; the sustain, the peak-to-peak over the second half of the
        window (in time) over that over its first half (NaN when the first half's is 0) [1];
        the window's length ``t[-1] - start`` [s].
    work : float64[TAIL_WORK, 3]
        Scratch space (the batch kernel reuses one per thread).

    Notes
    -----
    With fewer than 2 samples in the window every measure is NaN except the swings (0). A NaN
    in the window makes the peak-to-peak NaN and the swings 0, as numpy's ``ptp`` and
    comparisons do. The mean and the mean period are summed in numpy's pairwise order, so
    the results equal those of the numpy formulation bit for bit (tests/study/test_claims.py
    keeps it as an independent reference).
    """
    n = t.shape[0]
    for i in range(N_TAIL + 1):
        out[i] = np.nan
    if n == 0:
        out[1] = 0.0
        return
    start = t[0] + (1.0 - tail_fraction) * (t[n - 1] - t[0])
    out[N_TAIL] = t[n - 1] - start
    k0 = n
    while k0 > 0 and t[k0 - 1] >= start:
        k0 -= 1
    m = n - k0
    out[1] = 0.0
    if m < 2:
        return
    # peak-to-peak over the window and over its two halves in time (NaN propagates, as ptp)
    mid = t[k0] + 0.5 * (t[n - 1] - t[k0])
    lo = y[k0]
    hi = y[k0]
    lo1 = np.inf
    hi1 = -np.inf
    lo2 = np.inf
    hi2 = -np.inf
    n1 = 0
    n2 = 0
    nan_all = False
    nan1 = False
    nan2 = False
    for k in range(k0, n):
        v = y[k]
        if v != v:
            nan_all = True
            if t[k] < mid:
                nan1 = True
                n1 += 1
            else:
                nan2 = True
                n2 += 1
            continue
        lo = min(lo, v)
        hi = max(hi, v)
        if t[k] < mid:
            lo1 = min(lo1, v)
            hi1 = max(hi1, v)
            n1 += 1
        else:
            lo2 = min(lo2, v)
            hi2 = max(hi2, v)
            n2 += 1
    pp = np.nan if nan_all else float(hi - lo)
    p1 = (np.nan if nan1 else hi1 - lo1) if n1 > 0 else 0.0
    p2 = (np.nan if nan2 else hi2 - lo2) if n2 > 0 else 0.0
    out[0] = pp
    out[3] = p2 / p1 if p1 > 0.0 else np.nan
    # swings across mean +- pp/4
    total = _pairwise_stream(0, m, t, y, k0, 0, 0.0, 0.0, 0.0, work)
    mean = total / m
    h = pp / 4.0
    swings = 0
    side = 0
    k_first = -1
    for k in range(k0, n):
        dev = y[k] - mean
        s = 1 if dev > h else (-1 if dev < -h else 0)
        if s != 0:
            if side != 0 and s != side:
                swings += 1
                if k_first < 0:
                    k_first = k
            side = s
    out[1] = float(swings)
    if swings >= 3:
        side = 1 if y[k_first] - mean > h else -1
        total = _pairwise_stream(1, swings - 1, t, y, k_first + 1, side, t[k_first], mean,
                                 h, work)
        out[2] = 2.0 * (total / (swings - 1))


@dataclass(frozen=True, slots=True, kw_only=True)
class StepMetrics:
    """Metrics of one step response; NaN where the data cannot define a metric.

    Times are measured from the first sample ``t[0]``; "the span" is ``final_value -
    initial_value``. See ``docs/model.md`` ("Step metrics") for the exact definitions. The
    fields are :data:`METRIC_NAMES`, in order.
    """

    rise_time: float  #: first sample at 90 % of the span minus first sample at 10 % [s]
    settling_time: float  #: time from t[0] after which y stays within ±2 % of the span [s]
    settling_time_5: float  #: as settling_time with a ±5 % band [s]
    overshoot: float  #: largest excursion beyond final_value, in % of |span| [%]
    peak: float  #: y at its largest excursion from initial_value [unit of y]
    peak_time: float  #: time of that excursion from t[0] (first if repeated) [s]
    steady_state_error: float  #: r - y at the last sample [unit of y]
    iae: float  #: integral of |e|, e = r - y, trapezoid rule [unit of y · s]
    ise: float  #: integral of e² [unit of y² · s]
    itae: float  #: integral of (t - t[0]) |e| [unit of y · s²]
    itse: float  #: integral of (t - t[0]) e² [unit of y² · s²]
    u_max: float  #: largest |u| [unit of u]
    u_sq_integral: float  #: integral of u², u zero-order held [unit of u² · s]
    u_total_variation: float  #: sum of |u[k+1] - u[k]| [unit of u]

    def as_dict(self) -> dict[str, float]:
        """Return the metrics as ``{name: value}`` in the order of ``METRIC_NAMES``."""
        return {n: float(getattr(self, n)) for n in METRIC_NAMES}

    def __getitem__(self, name: str) -> float:
        """One metric by its name in :data:`METRIC_NAMES`."""
        if name not in METRIC_NAMES:
            raise KeyError(f"no metric {name!r}; metrics: {', '.join(METRIC_NAMES)}")
        return float(getattr(self, name))


def _number(name: str, value: object) -> float:
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be a number, got {value!r:.60}") from exc


def metric_options(rise: tuple[float, float], settle_band: float,
                   settle_band2: float) -> tuple[float, float, float, float]:
    """Validate the metric options: ``(rise_lo, rise_hi, band, band2)`` as floats.

    Raises
    ------
    ParameterError
        ``rise`` is not a pair with 0 <= lo < hi <= 1, or a band is outside (0, 1).
    """
    if np.ndim(rise) != 1 or len(rise) != 2:
        raise ParameterError(f"rise must be a pair (lo, hi) of fractions, got {rise!r:.60}")
    lo, hi = _number("rise[0]", rise[0]), _number("rise[1]", rise[1])
    if not 0.0 <= lo < hi <= 1.0:
        raise ParameterError(f"rise must satisfy 0 <= lo < hi <= 1, got ({lo}, {hi})")
    band1 = _number("settle_band", settle_band)
    band2 = _number("settle_band2", settle_band2)
    for name, band in (("settle_band", band1), ("settle_band2", band2)):
        if not 0.0 < band < 1.0:
            raise ParameterError(f"{name} must be in (0, 1), got {band}")
    return lo, hi, band1, band2


def metrics_of(t: FloatArray, y: FloatArray, u: FloatArray, r: FloatArray, *, y0: float,
               y_final: float, options: tuple[float, float, float, float]) -> StepMetrics:
    """:func:`step_metrics_core` on validated arrays (``u`` may be empty), as
    :class:`StepMetrics`; ``options`` from :func:`metric_options`."""
    out = np.empty(N_METRICS)
    step_metrics_core(t, y, u, r, y0, y_final, options[0], options[1], options[2],
                      options[3], out)
    return StepMetrics(**dict(zip(METRIC_NAMES, out.tolist(), strict=True)))
