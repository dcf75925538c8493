"""Step-response metrics of a sampled response: rise, settling, overshoot, integral criteria.

The maths is the compiled :func:`fuzzyservo.sim.stepinfo.step_metrics_core`, which the batched
closed-loop kernel also calls; this module validates the input once and wraps the result in a
frozen :class:`StepMetrics`. Definitions (``docs/model.md``, "Step metrics") follow
python-control's ``step_info``: crossings and band exits are taken at samples, without
interpolation, so a time metric is exact to one sample period.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..errors import InputError, ParameterError
from ..sim.stepinfo import METRIC_NAMES, N_METRICS, step_metrics_core

__all__ = ["StepMetrics", "step_metrics"]


@dataclass(frozen=True, slots=True, kw_only=True)
class StepMetrics:
    """Metrics of one step response; NaN where the data cannot define a metric.

    Times are measured from the first sample ``t[0]``; "the span" is ``final_value -
    initial_value``. See ``docs/model.md`` ("Step metrics") for the exact definitions.
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
        return asdict(self)


def _signal(name: str, value: ArrayLike, n: int | None) -> FloatArray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be an array of numbers, got {value!r:.60}") from exc
    if arr.ndim != 1:
        raise InputError(f"{name} must be one-dimensional, got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise InputError(f"{name} has {arr.shape[0]} samples but t has {n}; they must match")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        k = int(bad[0])
        raise InputError(
            f"{name}[{k}] = {float(arr[k])} is not finite; every sample must be finite"
        )
    return np.ascontiguousarray(arr)


def _finite(name: str, value: float) -> float:
    # Messages show float(value), not repr(value): a numpy scalar would read "np.float64(nan)".
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a finite number, got {value!r:.60}") from exc
    if not math.isfinite(v):
        raise InputError(f"{name} must be a finite number, got {v}")
    return v


def _option(name: str, value: object) -> float:
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be a number, got {value!r:.60}") from exc


def step_metrics(
    t: ArrayLike,
    y: ArrayLike,
    *,
    u: ArrayLike | None = None,
    r: ArrayLike | float | None = None,
    final_value: float | None = None,
    initial_value: float | None = None,
    rise: tuple[float, float] = (0.1, 0.9),
    settle_band: float = 0.02,
    settle_band2: float = 0.05,
) -> StepMetrics:
    """Compute the step-response metrics of a sampled response.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times, finite and strictly increasing, ``n >= 2`` [s].
    y : array_like, shape (n,)
        Output samples [unit of y].
    u : array_like, shape (n,), optional
        Command samples, each held over ``[t[k], t[k+1])``; without it the ``u_*`` metrics
        are NaN [unit of u].
    r : array_like, shape (n,), or float, optional
        Reference; the error is ``e = r - y``. Default: ``final_value`` at every sample
        [unit of y].
    final_value : float, optional
        Target of the step, from which overshoot and the settling bands are measured.
        Default: ``r[-1]`` if ``r`` is given, else ``y[-1]`` (python-control's convention for
        response data) [unit of y].
    initial_value : float, optional
        Value the step starts from. Default: ``y[0]`` [unit of y].
    rise : tuple of float
        Rise-time thresholds as fractions of the span, ``0 <= lo < hi <= 1`` [1].
    settle_band : float
        Half-width of the band that defines ``settling_time``, as a fraction of ``|span|``,
        in ``(0, 1)`` [1].
    settle_band2 : float
        Half-width of the band that defines ``settling_time_5``, in ``(0, 1)`` [1].

    Returns
    -------
    StepMetrics
        The metrics; NaN where undefined (see Notes).

    Raises
    ------
    InputError
        ``t``, ``y``, ``u`` or ``r`` is not one-dimensional, has a different length from ``t``,
        fewer than two samples or a non-finite value; ``t`` is not strictly increasing.
    ParameterError
        ``rise``, ``settle_band`` or ``settle_band2`` is outside the allowed range.

    Notes
    -----
    NaN means: rise time, settling times, overshoot and peak time when there is no step to
    measure, i.e. ``|final_value - initial_value| <= NO_STEP_RTOL * max(1, |initial_value|,
    |final_value|, max(y) - min(y))`` (:data:`fuzzyservo.sim.stepinfo.NO_STEP_RTOL` = 1e-9,
    so rounding of a reference that ends where it started is not a step; the integral
    criteria and ``u_*`` metrics are still computed); rise time when ``y`` never reaches
    ``rise[1]`` of the span; a settling time when ``y`` is outside its band at any sample
    after ``t[0] + 0.9 (t[-1] - t[0])`` (not shown to settle within the record: it must stay
    in the band for the last :data:`~fuzzyservo.sim.stepinfo.SETTLE_HOLD_FRACTION` = 10 % of
    it, so a limit cycle that happens to be in the band at the end is not "settled"); the
    steady-state error when neither ``r`` nor ``final_value`` is given (no reference: it
    would be zero by construction); the ``u_*`` metrics without ``u``.

    Times are measured from ``t[0]``, not from the start of a delayed step (python-control's
    convention): ``peak_time`` and the settling times of a step applied at ``t[0] + d``
    include the wait ``d``; ``rise_time``, a difference of two crossing times, does not. Pass
    the record from the step onwards to measure from the step.

    With ``initial_value = 0`` and ``final_value`` equal to the steady-state value,
    ``rise_time``, ``settling_time``, ``overshoot`` and ``peak_time`` follow python-control's
    ``step_info`` (``RiseTime``, ``SettlingTime``, ``Overshoot``, ``PeakTime``) and
    ``abs(peak)`` is its ``Peak``.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0.0, 10.0, 10001)
    >>> m = step_metrics(t, 1.0 - np.exp(-t), final_value=1.0)
    >>> round(m.rise_time, 3), round(m.iae, 4)
    (2.197, 1.0)
    """
    tt = _signal("t", t, None)
    n = tt.shape[0]
    if n < 2:
        raise InputError(f"t has {n} sample(s); at least 2 are needed")
    steps = np.diff(tt)
    if not np.all(steps > 0.0):
        k = int(np.flatnonzero(steps <= 0.0)[0])
        raise InputError(
            f"t must be strictly increasing, but t[{k + 1}] = {float(tt[k + 1])} "
            f"<= t[{k}] = {float(tt[k])}"
        )
    yy = _signal("y", y, n)
    if np.ndim(rise) != 1 or len(rise) != 2:
        raise ParameterError(f"rise must be a pair (lo, hi) of fractions, got {rise!r:.60}")
    lo, hi = _option("rise[0]", rise[0]), _option("rise[1]", rise[1])
    if not 0.0 <= lo < hi <= 1.0:
        raise ParameterError(f"rise must satisfy 0 <= lo < hi <= 1, got ({lo}, {hi})")
    band1 = _option("settle_band", settle_band)
    band2 = _option("settle_band2", settle_band2)
    for name, band in (("settle_band", band1), ("settle_band2", band2)):
        if not 0.0 < band < 1.0:
            raise ParameterError(f"{name} must be in (0, 1), got {band}")

    rr: FloatArray | None = None
    if r is not None:
        rr = (
            np.full(n, _finite("r", r))  # type: ignore[arg-type]
            if np.ndim(r) == 0
            else _signal("r", r, n)
        )
    if final_value is not None:
        yf = _finite("final_value", final_value)
    elif rr is not None:
        yf = float(rr[-1])
    else:
        yf = float(yy[-1])
    y0 = float(yy[0]) if initial_value is None else _finite("initial_value", initial_value)
    uu = np.empty(0) if u is None else _signal("u", u, n)

    out = np.empty(N_METRICS)
    step_metrics_core(
        tt, yy, uu, np.full(n, yf) if rr is None else rr, y0, yf, lo, hi, band1, band2, out,
    )  # fmt: skip
    if r is None and final_value is None:
        out[METRIC_NAMES.index("steady_state_error")] = math.nan
    return StepMetrics(**dict(zip(METRIC_NAMES, out.tolist(), strict=True)))
