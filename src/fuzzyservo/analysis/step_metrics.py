"""Step-response metrics of a sampled response: rise, settling, overshoot, integral criteria.

The maths is the compiled :func:`fuzzyservo.sim.stepinfo.step_metrics_core`, which the batched
closed-loop kernel also calls; this module validates the input once and wraps the result in a
frozen :class:`StepMetrics`. Definitions (``docs/model.md``, "Step metrics") follow
python-control's ``step_info``: crossings and band exits are taken at samples, without
interpolation, so a time metric is exact to one sample period.
"""

from __future__ import annotations

import math
from typing import Protocol, cast

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..errors import InputError
from ..sim.stepinfo import StepMetrics, metric_options, metrics_of

__all__ = ["METRIC_UNITS", "Run", "StepMetrics", "step_metrics"]

#: Units of each metric of a run (position in m, command as a fraction of rated input).
METRIC_UNITS: dict[str, str] = {
    "rise_time": "s",
    "settling_time": "s",
    "settling_time_5": "s",
    "overshoot": "%",
    "peak": "m",
    "peak_time": "s",
    "steady_state_error": "m",
    "iae": "m*s",
    "ise": "m^2*s",
    "itae": "m*s^2",
    "itse": "m^2*s^2",
    "u_max": "1",
    "u_sq_integral": "s",
    "u_total_variation": "1",
}


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


class Run(Protocol):
    """A single run with samples ``t``, ``y``, ``u``, ``r`` (a :class:`~fuzzyservo.sim.SimResult`,
    an :class:`~fuzzyservo.sim.OpenLoopResult` (``r`` None) or a run CSV read by
    :func:`fuzzyservo.files.read_run_csv`)."""

    @property
    def t(self) -> FloatArray:
        """Sample times [s]."""

    @property
    def y(self) -> FloatArray:
        """Output [m]."""

    @property
    def u(self) -> FloatArray:
        """Command [-]."""

    @property
    def r(self) -> FloatArray | None:
        """Reference [m] (None: none)."""


def step_metrics(
    t: ArrayLike | Run,
    y: ArrayLike | None = None,
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

    ``step_metrics(result)`` takes a single-run result (a ``SimResult``, or a run CSV read by
    :func:`fuzzyservo.files.read_run_csv`) and uses its ``t``, ``y``, ``u`` and ``r``.

    Parameters
    ----------
    t : array_like, shape (n,), or a run
        Sample times, finite and strictly increasing, ``n >= 2`` [s]; or a result with
        ``t, y, u, r`` (then ``y``, ``u``, ``r`` must not be given).
    y : array_like, shape (n,)
        Output samples [unit of y]; required unless ``t`` is a run.
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
    if hasattr(t, "t") and hasattr(t, "y"):
        if y is not None or u is not None or r is not None:
            raise InputError("step_metrics(result) takes y, u and r from the result; "
                             "do not pass them too")
        run = cast(Run, t)
        if run.r is None:
            raise InputError("step_metrics(result) needs a closed-loop run: an open-loop run "
                             "has no reference to measure the step against (call "
                             "step_metrics(t, y, final_value=...) for a bare response)")
        return step_metrics(run.t, run.y, u=run.u, r=run.r, final_value=final_value,
                            initial_value=initial_value, rise=rise, settle_band=settle_band,
                            settle_band2=settle_band2)
    if y is None:
        raise InputError("step_metrics needs y (or a result with t, y, u, r)")
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
    options = metric_options(rise, settle_band, settle_band2)

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

    m = metrics_of(tt, yy, uu, np.full(n, yf) if rr is None else rr, y0=y0, y_final=yf,
                   options=options)
    if r is None and final_value is None:
        return StepMetrics(**{**m.as_dict(), "steady_state_error": math.nan})
    return m
