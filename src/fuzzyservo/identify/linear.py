"""Eq. (8) fitted directly: K_o, ω_h, ζ_h (and a delay) from data, and what they imply.

The paper's linear model (eq. 8, :class:`fuzzyservo.plant.LinearServo`) from the valve
command u (fraction of rated input) to the piston position x [m]::

    X(s)/U(s) = K_o e^{-s τ} / [s (s²/ω_h² + 2 ζ_h s/ω_h + 1)(s²/ω_v² + 2 ζ_v s/ω_v + 1)]

(with the valve's first-order stage τ_v of the parameter set when it has one). Its
coefficients are fitted by bounded least squares
(:func:`fuzzyservo.identify.lsq.levenberg_marquardt`) from

- **time data** (:func:`fit_linear_time`): an open-loop record of the command and the
  position. The model is the package's own: :meth:`LinearPlant.from_servo` simulated by
  :func:`fuzzyservo.sim.simulate_open_loop` (exact ZOH, fractional delays exact), driven
  by u - u_rest from rest; its output is compared with y less the position at rest (fitted
  too). Residuals are in metres;
- **frequency-response data** (:func:`read_frequency_response`,
  :func:`fit_linear_frequency`): x/u measured at frequencies ω, integrator included (gain in
  m per unit command per rad/s). The residual at each frequency is the complex logarithm of
  model over data, ln|H_m/H| and the wrapped phase difference [rad], weighted evenly.

Positive coefficients are fitted as logarithms (so they stay positive and the search is
scale-free), the delay in samples (time data) or in units of the shortest period (frequency
data); each fit starts from a grid of ω_h, ζ_h (and delay) screened with the gain K_o that
fits best for each (the output is linear in K_o), then refines the best few.

Standard errors are s² (JᵀJ)⁻¹ with J the central-difference Jacobian of the residuals at
the estimate and s² the residual variance (sum of squares over samples less parameters),
carried back to SI units by the delta method. They assume independent residuals of equal
variance (white measurement noise); coloured noise or a model error makes them optimistic.

No BLAS or LAPACK and no numpy vector transcendental is on the path from the data to a
fit (docs/architecture.md, "Machine-independent results"): sums are sequential
(:func:`~fuzzyservo.identify.lsq.total`, :func:`~fuzzyservo.identify.lsq.sum_of_squares`),
the search and the covariance are :mod:`fuzzyservo.identify.lsq`'s, the implied
parameters' propagation uses :mod:`fuzzyservo.plant.dense`, and the frequency residuals
are written out per frequency in real arithmetic, so that a fit gives the same bits
whatever BLAS kernel or vector unit runs it.

:func:`implied_parameters` turns a fit into the physical parameters it determines given the
others (valve.rated_flow from K_o; load.mass or fluid.oil_bulk_modulus from ω_h;
valve.null_leakage or load.viscous_damping from ζ_h), solved with the package's own
:func:`fuzzyservo.plant.linearize` so that they agree with the model.
"""

from __future__ import annotations

import cmath
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from .._io import read_csv_columns
from .._typing import ArrayLike, FloatArray
from ..errors import InputError, ParameterError, SimulationDivergedError
from ..plant import LinearServo, ServoParams, linearize, with_overrides
from ..plant.dense import matmul, solve
from ..sim import LinearPlant, simulate_open_loop
from .lsq import LsqResult, covariance, levenberg_marquardt, sum_of_squares, total

__all__ = [
    "DEFAULT_FIT",
    "LINEAR_NAMES",
    "LINEAR_UNITS",
    "ImpliedParameter",
    "LinearFit",
    "describe",
    "eq8_response",
    "fit_linear_frequency",
    "fit_linear_time",
    "implied_estimates",
    "implied_parameters",
    "read_frequency_response",
    "to_record",
]

ComplexArray = npt.NDArray[np.complex128]

#: The coefficients of eq. (8) a fit may estimate, in this order.
LINEAR_NAMES: tuple[str, ...] = ("K_o", "omega_h", "zeta_h", "delay", "omega_v", "zeta_v")

#: What :func:`fit_linear_time` and :func:`fit_linear_frequency` fit unless told.
DEFAULT_FIT: tuple[str, ...] = ("K_o", "omega_h", "zeta_h", "delay")

#: Unit of each coefficient (SI).
LINEAR_UNITS: dict[str, str] = {
    "K_o": "m/s per unit command", "omega_h": "rad/s", "zeta_h": "1", "delay": "s",
    "omega_v": "rad/s", "zeta_v": "1",
}

#: Search box of the positive coefficients [SI]: wide, so that the data decide; an estimate
#: on an edge is reported as not determined.
_BOUNDS: dict[str, tuple[float, float]] = {
    "K_o": (1e-12, 1e6), "omega_h": (1e-3, 1e6), "zeta_h": (1e-4, 10.0),
    "omega_v": (1e-2, 1e7), "zeta_v": (1e-4, 10.0),
}

#: |correlation| above which two estimates are reported as poorly separated.
_HIGH_CORRELATION = 0.95

#: Starts refined by least squares after the grid screening.
_N_REFINE = 3

#: Units of the parameter fields :func:`implied_parameters` reports.
_FIELD_UNITS: dict[str, str] = {
    "valve.rated_flow": "m³/s", "load.mass": "kg", "fluid.oil_bulk_modulus": "Pa",
    "valve.null_leakage": "m³/(s·Pa)", "load.viscous_damping": "N·s/m",
    "delay.transport_delay": "s", "valve.omega_v": "rad/s", "valve.zeta_v": "1",
}


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class LinearFit:
    """Eq. (8) fitted to data: the estimates, their uncertainty and the fitted model."""

    names: tuple[str, ...]  #: the coefficients fitted, in :data:`LINEAR_NAMES` order
    estimate: FloatArray  #: estimates (len(names),) [SI: m/s per unit command, rad/s, 1, s]
    std_error: FloatArray  #: standard errors (len(names),) [same units]; inf: not determined
    correlation: FloatArray  #: correlation matrix of the estimates (len(names),)*2 [1]
    servo: LinearServo  #: the fitted eq. (8); the coefficients not fitted as held
    delay: float  #: transport delay of the fitted model, fitted or held [s]
    residual_rms: float  #: rms residual: time data [m]; frequency data, |H_m/H - 1| [1]
    source: str  #: "time" or "frequency"
    n_data: int  #: samples (time) or frequencies used in the fit
    #: time data: the position at rest, fitted with the coefficients (the model's output is
    #: y - y_rest); nan for frequency data [m]
    y_rest: float
    notes: tuple[str, ...]  #: what the data do not decide, held values, warnings

    def value(self, name: str) -> float:
        """The fitted model's coefficient ``name`` (one of :data:`LINEAR_NAMES`), fitted or
        held [SI]."""
        s = self.servo
        values = {"K_o": s.K_o, "omega_h": s.omega_0, "zeta_h": s.damping,
                  "delay": self.delay, "omega_v": s.omega_v, "zeta_v": s.zeta_v}
        if name not in values:
            raise ParameterError(f"unknown eq. (8) coefficient {name!r}; one of "
                                 f"{', '.join(LINEAR_NAMES)}")
        return float(values[name])

    def covariance(self) -> FloatArray:
        """Covariance matrix of the estimates [SI units squared]."""
        se = np.where(np.isfinite(self.std_error), self.std_error, np.nan)
        out: FloatArray = self.correlation * np.outer(se, se)
        return out


@dataclass(frozen=True, slots=True, kw_only=True)
class ImpliedParameter:
    """A physical parameter a fit determines given the others."""

    name: str  #: ``group.field`` of :class:`~fuzzyservo.plant.ServoParams`
    value: float  #: the value that reproduces the fit; nan when not determined [SI]
    std_error: float  #: its standard error, propagated from the fit; nan if not determined
    unit: str  #: unit of ``value``
    how: str  #: how it is determined (what is held), or why it is not


# -- the coefficient vector ----------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Space:
    """The fitted coefficients as a search vector θ: logarithms of the positive ones, the
    delay divided by ``delay_scale``; the others held."""

    names: tuple[str, ...]
    held: Mapping[str, float]
    delay_scale: float
    delay_max: float

    def values(self, theta: FloatArray) -> dict[str, float]:
        out = dict(self.held)
        for name, th in zip(self.names, theta.tolist(), strict=True):
            out[name] = th * self.delay_scale if name == "delay" else math.exp(th)
        return out

    def theta(self, values: Mapping[str, float]) -> FloatArray:
        return np.array([values[n] / self.delay_scale if n == "delay" else math.log(values[n])
                         for n in self.names])

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        lo = [0.0 if n == "delay" else math.log(_BOUNDS[n][0]) for n in self.names]
        hi = [self.delay_max / self.delay_scale if n == "delay" else math.log(_BOUNDS[n][1])
              for n in self.names]
        return np.array(lo), np.array(hi)

    def si_slope(self, theta: FloatArray) -> FloatArray:
        """d(SI value)/dθ for each fitted coefficient (the delta method's factors)."""
        return np.array([self.delay_scale if n == "delay" else math.exp(th)
                         for n, th in zip(self.names, theta.tolist(), strict=True)])


def _check_names(fit: Sequence[str]) -> tuple[str, ...]:
    if isinstance(fit, str):
        fit = [part.strip() for part in fit.split(",") if part.strip()]
    names = list(fit)
    unknown = [n for n in names if n not in LINEAR_NAMES]
    if unknown:
        raise ParameterError(f"cannot fit {', '.join(map(repr, unknown))}: eq. (8)'s "
                             f"coefficients are {', '.join(LINEAR_NAMES)}")
    if not names:
        raise ParameterError(f"nothing to fit: name one or more of {', '.join(LINEAR_NAMES)}")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ParameterError(f"{', '.join(twice)} named twice in the coefficients to fit")
    return tuple(n for n in LINEAR_NAMES if n in names)


def _held(params: ServoParams, position: float, delay: float) -> dict[str, float]:
    """Eq. (8) of the parameter set at ``position``: K_o = Q_rated/A_f, ω_h and ζ_h of its
    linearisation, the valve's ω_v and ζ_v, and ``delay``."""
    if not isinstance(params, ServoParams):
        raise ParameterError(f"params must be a ServoParams, got {type(params).__name__}")
    lin = linearize(params, position)
    return {"K_o": params.velocity_gain, "omega_h": lin.omega_0, "zeta_h": lin.damping,
            "delay": delay, "omega_v": params.valve.omega_v, "zeta_v": params.valve.zeta_v}


def _servo(values: Mapping[str, float], tau_v: float) -> LinearServo:
    return LinearServo(K_o=values["K_o"], omega_0=values["omega_h"], damping=values["zeta_h"],
                       omega_v=values["omega_v"], zeta_v=values["zeta_v"], tau_v=tau_v)


# -- the least-squares machinery shared by both fits ---------------------------------------


def _jacobian(fun: Callable[[FloatArray], FloatArray | None], theta: FloatArray,
              lo: FloatArray, hi: FloatArray) -> FloatArray:
    """Central differences of ``fun`` at ``theta`` (one-sided at a bound, or where ``fun``
    cannot be evaluated on one side: None)."""
    r0 = fun(theta)
    if r0 is None:
        raise InputError("the eq. (8) model cannot be simulated at the estimate")
    jac = np.empty((r0.size, theta.size))
    for j in range(theta.size):
        h = 1e-6 * max(1.0, abs(float(theta[j])))
        up, down = theta.copy(), theta.copy()
        up[j] = min(theta[j] + h, hi[j])
        down[j] = max(theta[j] - h, lo[j])
        r_up, r_down = fun(up), fun(down)
        if r_up is None:
            up, r_up = theta, r0
        if r_down is None:
            down, r_down = theta, r0
        span = float(up[j] - down[j])
        if span <= 0.0:
            jac[:, j] = 0.0
            continue
        jac[:, j] = (r_up - r_down) / span
    return jac


class _Guarded:
    """``residual`` for :func:`~fuzzyservo.identify.lsq.levenberg_marquardt`: None (for the
    Jacobian) or infinite residuals (a step the search refuses) where the model cannot be
    simulated; the last evaluation kept, since the search asks for the Jacobian at the
    point it evaluated last."""

    def __init__(self, residual: Callable[[FloatArray], FloatArray]) -> None:
        self.residual = residual
        self.size = -1
        self._last: tuple[bytes, FloatArray | None] | None = None

    def __call__(self, theta: FloatArray) -> FloatArray | None:
        key = np.asarray(theta, dtype=np.float64).tobytes()
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        try:
            r: FloatArray | None = self.residual(theta)
        except (ParameterError, SimulationDivergedError):
            r = None
        if r is not None:
            self.size = r.size
        self._last = (key, r)
        return r

    def values(self, theta: FloatArray) -> FloatArray:
        r = self(theta)
        return np.full(max(self.size, 1), math.inf) if r is None else r


def _solve(space: _Space, residual: Callable[[FloatArray], FloatArray],
           starts: list[FloatArray], nuisance: int = 0
           ) -> tuple[FloatArray, FloatArray, list[str]]:
    """Refine the starts by bounded least squares; the best estimate θ, its covariance (in θ)
    and notes. ``nuisance``: linear parameters ``residual`` projects out (Golub and Pereyra's
    variable projection: the projected Jacobian gives θ's covariance; they cost degrees of
    freedom).

    The search (:func:`~fuzzyservo.identify.lsq.levenberg_marquardt`, central-difference
    Jacobian) and the covariance (:func:`~fuzzyservo.identify.lsq.covariance`) use no BLAS
    or LAPACK: the same bits on every machine."""
    lo, hi = space.bounds()
    guarded = _Guarded(residual)

    def jac(theta: FloatArray) -> FloatArray:
        return _jacobian(guarded, theta, lo, hi)

    best: LsqResult | None = None
    for start in starts:
        x0 = np.minimum(np.maximum(start, lo), hi)
        if guarded(x0) is None:
            continue  # a start whose model cannot be simulated: try the next
        res = levenberg_marquardt(guarded.values, jac, x0, lo, hi,
                                  max_nfev=200 * (len(space.names) + 1), ftol=1e-13,
                                  xtol=1e-13)
        if best is None or res.cost < best.cost:
            best = res
    if best is None:
        raise InputError("the fit failed from every start: no eq. (8) model could be "
                         "simulated for these data")
    theta = np.asarray(best.x, dtype=np.float64)
    r = guarded.values(theta)
    dof = r.size - theta.size - nuisance
    cov, _, null = covariance(jac(theta), r, dof)
    notes: list[str] = []
    if null.shape[0] or not np.all(np.isfinite(cov)):
        cov = np.full((theta.size, theta.size), np.inf)
        notes.append("the data do not determine every coefficient together (the Jacobian is "
                     "singular): standard errors are infinite; fit fewer coefficients")
    for j, name in enumerate(space.names):
        span = hi[j] - lo[j]
        if theta[j] - lo[j] <= 1e-6 * span or hi[j] - theta[j] <= 1e-6 * span:
            if name == "delay" and theta[j] - lo[j] <= 1e-6 * span:
                continue  # no delay is a legitimate answer
            notes.append(f"{name} ended on the edge of its search box: not determined by "
                         f"the data")
    return theta, cov, notes


def _summarise(space: _Space, theta: FloatArray, cov_theta: FloatArray
               ) -> tuple[FloatArray, FloatArray, FloatArray, list[str]]:
    """SI estimates, standard errors, correlation matrix and correlation notes."""
    values = space.values(theta)
    estimate = np.array([values[n] for n in space.names])
    slope = space.si_slope(theta)
    if np.all(np.isfinite(cov_theta)):
        cov = cov_theta * np.outer(slope, slope)
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = cov / np.outer(se, se)
        corr = np.where(np.isfinite(corr), corr, 0.0)
        np.fill_diagonal(corr, 1.0)
    else:
        se = np.full(len(space.names), np.inf)
        corr = np.full((len(space.names),) * 2, np.nan)
        np.fill_diagonal(corr, 1.0)
    notes = []
    for i in range(len(space.names)):
        for j in range(i + 1, len(space.names)):
            if abs(corr[i, j]) > _HIGH_CORRELATION:
                notes.append(f"{space.names[i]} and {space.names[j]} are correlated "
                             f"(r = {corr[i, j]:+.3f}): the data barely separate them")
    return estimate, se, corr, notes


def _unit(unit: str) -> str:
    """A unit as written after a number: none for a ratio."""
    return "" if unit == "1" else " " + unit


def _held_notes(space: _Space, params_desc: str) -> list[str]:
    held = [n for n in LINEAR_NAMES if n not in space.names]
    if not held:
        return []
    parts = [f"{n} = {space.held[n]:.6g}{_unit(LINEAR_UNITS[n])}" for n in held]
    return [f"held ({params_desc}): {', '.join(parts)}"]


def _grid_starts(space: _Space, cost: Callable[[dict[str, float]], tuple[float, float]],
                 omega_grid: Sequence[float], delay_grid: Sequence[float]
                 ) -> list[FloatArray]:
    """Screen the grid (K_o at its best for each point); the best few as θ starts."""
    zetas = (0.05, 0.3, 1.0) if "zeta_h" in space.names else (space.held["zeta_h"],)
    omegas = omega_grid if "omega_h" in space.names else (space.held["omega_h"],)
    delays = delay_grid if "delay" in space.names else (space.held["delay"],)
    scored: list[tuple[float, FloatArray]] = []
    for w in omegas:
        for z in zetas:
            for d in delays:
                values = dict(space.held)
                values.update(omega_h=float(w), zeta_h=float(z), delay=float(d))
                try:
                    c, k_best = cost(values)
                except (ParameterError, SimulationDivergedError):
                    continue
                if "K_o" in space.names:
                    values["K_o"] = min(max(k_best, _BOUNDS["K_o"][0]), _BOUNDS["K_o"][1])
                scored.append((c, space.theta(values)))
    if not scored:
        raise InputError("no starting model of the grid could be simulated for these data")
    scored.sort(key=lambda item: item[0])
    return [theta for _, theta in scored[:_N_REFINE]]


# -- time data -----------------------------------------------------------------------------


def _float_array(values: ArrayLike, what: str) -> FloatArray:
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be an array of numbers") from None
    if arr.ndim != 1:
        raise InputError(f"{what} must be one-dimensional, got shape {arr.shape}")
    return arr


def _first_bad(ok: npt.NDArray[np.bool_]) -> int:
    """Index of the first False, or -1."""
    return int(np.argmin(ok)) if not np.all(ok) else -1


def _mean(x: FloatArray) -> float:
    """The mean, summed in order (:func:`~fuzzyservo.identify.lsq.total`)."""
    return total(x) / x.size


def _geomspace(a: float, b: float, n: int) -> list[float]:
    """``n`` points from ``a`` to ``b`` > 0 evenly spaced in logarithm, by ``math.exp``
    (numpy's vector ``power``, behind ``np.geomspace``, rounds differently on processors
    with AVX-512)."""
    la, lb = math.log(a), math.log(b)
    inner = [math.exp(la + (lb - la) * k / (n - 1)) for k in range(1, n - 1)]
    return [a, *inner, b]


def fit_linear_time(t: ArrayLike, u: ArrayLike, y: ArrayLike, *, params: ServoParams,
                    position: float, dt: float, fit: Sequence[str] = DEFAULT_FIT,
                    delay: float = 0.0, flagged: ArrayLike | None = None,
                    u_rest: float | None = None) -> LinearFit:
    """Fit eq. (8) to an open-loop record of the command and the position.

    Parameters
    ----------
    t : array (N,)
        Sample times, uniform with step ``dt`` [s].
    u : array (N,)
        Valve command logged at t_k and held to t_{k+1}, fraction of rated input [-].
    y : array (N,)
        Piston position at t_k [m]; NaN allowed where ``flagged``.
    params : ServoParams
        Base parameters: the coefficients not fitted (and the valve's τ_v) come from eq. (8)
        of this set at ``position`` (K_o = Q_rated/A_f, ω_h and ζ_h of its linearisation,
        ω_v, ζ_v of the valve); its linearisation also centres the search grid.
    position : float
        Piston position at rest, where the record starts [m].
    dt : float
        Sample time [s].
    fit : sequence of str
        The coefficients to fit, from :data:`LINEAR_NAMES` (a comma-separated string also
        works); default :data:`DEFAULT_FIT`.
    delay : float
        Transport delay between the logged command and the valve when ``delay`` is not
        fitted [s]; default 0.
    flagged : array of bool (N,), optional
        Samples left out of the residual (outliers, drop-outs, end-stop contact).
    u_rest : float, optional
        The command that holds the piston at rest [-]; default ``u[0]``. The model is
        driven by u - u_rest.

    Returns
    -------
    LinearFit
        ``source`` "time"; ``residual_rms`` in metres.

    Raises
    ------
    InputError
        Arrays of different lengths, fewer samples than 4 plus the coefficients, a
        non-finite value, a time grid that is not uniform with step ``dt``, a command that
        never leaves ``u_rest``, or a position that moves against the command.
    ParameterError
        An unknown coefficient name, a bad ``dt``, ``delay`` or ``position``.

    Notes
    -----
    The position at rest is fitted with the coefficients (a linear parameter projected out
    of the residual, its degree of freedom counted): taking it from y[0], or from a lead-in's
    mean, leaves its noise as an offset that biases K_o beyond its standard error.
    """
    names = _check_names(fit)
    if isinstance(dt, bool) or not isinstance(dt, int | float) or not (
            math.isfinite(dt) and dt > 0.0):
        raise ParameterError(f"dt must be a finite number > 0 s, got {dt!r}")
    if not (isinstance(delay, int | float) and math.isfinite(delay) and delay >= 0.0):
        raise ParameterError(f"delay must be a finite number >= 0 s, got {delay!r}")
    tt, uu, yy = (_float_array(v, w) for v, w in ((t, "t"), (u, "u"), (y, "y")))
    n = tt.size
    if uu.size != n or yy.size != n:
        raise InputError(f"t, u and y need one value per sample, got {tt.size}, {uu.size} "
                         f"and {yy.size}")
    skip = np.zeros(n, dtype=bool) if flagged is None else np.asarray(flagged, dtype=bool)
    if skip.shape != (n,):
        raise InputError(f"flagged needs one value per sample ({n}), got shape {skip.shape}")
    used = int(np.count_nonzero(~skip))
    if used < len(names) + 4:
        raise InputError(f"{used} usable samples; fitting {len(names)} coefficient(s) needs "
                         f"at least {len(names) + 4}")
    for arr, what, unit in ((tt, "t", "s"), (uu, "u", "")):
        k = _first_bad(np.isfinite(arr))
        if k >= 0:
            raise InputError(f"{what} at sample {k} is {arr[k]!r}{unit and ' ' + unit}; "
                             f"every value must be finite")
    k = _first_bad(np.isfinite(yy) | skip)
    if k >= 0:
        raise InputError(f"y at sample {k} (t = {tt[k]:.6g} s) is {yy[k]!r}; every unflagged "
                         f"position must be finite")
    steps = np.diff(tt)
    bad = np.abs(steps - dt) > 1e-3 * dt
    if np.any(bad):
        k = int(np.argmax(bad))
        raise InputError(f"t steps by {steps[k]!r} s after sample {k} (t = {tt[k]:.6g} s); "
                         f"the fit needs a uniform grid of dt = {dt!r} s (resample first)")
    rest = float(uu[0]) if u_rest is None else float(u_rest)
    if not math.isfinite(rest):
        raise ParameterError(f"u_rest must be finite, got {u_rest!r}")
    drive = uu[:-1] - rest
    moved = np.flatnonzero(drive != 0.0)
    if moved.size == 0:
        raise InputError(f"the command never leaves its rest value {rest!r}: the record "
                         f"excites nothing to fit")
    # the output cannot move before the sample after the first change: those are at rest
    lead = np.arange(n) <= moved[0]
    at_rest = lead & ~skip
    y_ref = _mean(yy[at_rest]) if np.any(at_rest) else float(yy[np.argmin(skip)])
    target = np.where(skip, 0.0, yy - y_ref)
    keep = ~skip
    scale = max(1.0, float(np.max(np.abs(drive))))  # linear: run |u| <= 1 and scale back
    command = drive / scale
    duration = (n - 1) * dt
    held = _held(params, position, float(delay))
    stroke = params.cylinder.stroke
    tau_v = params.valve.tau_v
    space = _Space(names, held, delay_scale=dt, delay_max=0.25 * duration)

    def simulate(values: Mapping[str, float]) -> FloatArray:
        plant = LinearPlant.from_servo(_servo(values, tau_v), position, stroke=stroke)
        res = simulate_open_loop(plant, command, duration=duration, dt=dt,
                                 delay=values["delay"])
        out: FloatArray = (res.y - position) * scale
        return out

    def raw(theta: FloatArray) -> FloatArray:
        out: FloatArray = (simulate(space.values(theta)) - target)[keep]
        return out

    def residual(theta: FloatArray) -> FloatArray:
        r = raw(theta)
        out: FloatArray = r - _mean(r)  # the rest position at its best (projected out)
        return out

    z = target[keep] - _mean(target[keep])

    def cost(values: dict[str, float]) -> tuple[float, float]:
        if "K_o" not in space.names:
            r = (simulate(values) - target)[keep]
            r = r - _mean(r)
            return sum_of_squares(r), values["K_o"]
        m = simulate(dict(values, K_o=1.0))[keep]
        m = m - _mean(m)
        mm = sum_of_squares(m)
        k_best = total(m * z) / mm if mm > 0.0 else 0.0
        r = k_best * m - z
        return sum_of_squares(r), k_best

    if "K_o" in names:
        # the slowest reading of the gain: y ≈ K_o ∫(u - u_rest) dt
        ramp = np.concatenate([[0.0], np.cumsum(drive) * dt])[keep]
        ramp = ramp - _mean(ramp)
        gain = total(ramp * z) / max(sum_of_squares(ramp), 1e-300)
        if gain <= 0.0:
            raise InputError("the position moves against the command (the gain of y against "
                             "the integral of u - u_rest is negative): check the signs of "
                             "the command and of the position, and u_rest")
    nyquist = math.pi / dt
    base_w = held["omega_h"]
    grid_w = sorted({*(base_w * f for f in (0.5, 1.0, 2.0)),
                     *_geomspace(20.0 / duration, 0.3 * nyquist, 8)})
    grid_w = [w for w in grid_w if 0.0 < w < 0.5 * nyquist] or [base_w]
    grid_d = sorted(d for d in {0.0, float(delay), 5 * dt, 20 * dt} if d <= space.delay_max)
    starts = _grid_starts(space, cost, grid_w, grid_d)
    theta, cov_theta, notes = _solve(space, residual, starts, nuisance=1)
    estimate, se, corr, corr_notes = _summarise(space, theta, cov_theta)
    values = space.values(theta)
    r = residual(theta)
    y_rest = y_ref - _mean(raw(theta))
    notes = _held_notes(space, "eq. (8) of the base parameters") + notes + corr_notes
    if "omega_h" in names and values["omega_h"] > nyquist:
        notes.append(f"omega_h = {values['omega_h']:.4g} rad/s is above the Nyquist "
                     f"frequency {nyquist:.4g} rad/s of the data")
    return LinearFit(names=names, estimate=estimate, std_error=se, correlation=corr,
                     servo=_servo(values, tau_v), delay=values["delay"],
                     residual_rms=math.sqrt(sum_of_squares(r) / r.size), source="time",
                     n_data=int(r.size), y_rest=y_rest, notes=tuple(notes))


# -- frequency data ------------------------------------------------------------------------


def eq8_response(w: ArrayLike, servo: LinearServo, delay: float = 0.0) -> ComplexArray:
    """Eq. (8)'s frequency response x/u at ``w`` [rad/s] with a transport ``delay`` [s]:
    complex, in m per unit command per (rad/s) (the integrator included).

    Computed per frequency as e^{ln H} from the logarithm the frequency fit compares (Python
    floats and the C library): the same bits on every machine, which numpy's complex loops
    are not on processors with AVX-512.

    Raises
    ------
    ParameterError
        A frequency that is not finite and > 0.
    """
    ww = np.asarray(w, dtype=np.float64)
    flat = ww.reshape(-1).tolist()
    bad = [x for x in flat if not (math.isfinite(x) and x > 0.0)]
    if bad:
        raise ParameterError(f"eq8_response needs frequencies finite and > 0 rad/s, got "
                             f"{bad[0]!r}")
    re, im = _log_eq8(flat, servo, delay)
    out: ComplexArray = np.array([cmath.rect(math.exp(a), b)
                                  for a, b in zip(re.tolist(), im.tolist(), strict=True)],
                                 dtype=np.complex128).reshape(ww.shape)
    return out


_TWO_PI = 2.0 * math.pi


def _log_eq8(w: Sequence[float], servo: LinearServo, delay: float
             ) -> tuple[FloatArray, FloatArray]:
    """ln of eq. (8)'s response at ``w`` [rad/s], its real part (ln of the gain) and an
    imaginary part (the phase, not wrapped) [rad], each factor's logarithm written out in
    real arithmetic per frequency (Python floats and the C library's ``log``, ``atan2``):
    numpy's complex and vector loops round differently on processors with AVX-512, and
    the fit's residuals must not depend on the machine."""
    k, wh, zh, wv, zv, tv = (servo.K_o, servo.omega_0, servo.damping, servo.omega_v,
                             servo.zeta_v, servo.tau_v)
    lk = math.log(k)
    re: list[float] = []
    im: list[float] = []
    for x in w:
        a, b = x / wh, x / wv
        hr, hi = 1.0 - a * a, 2.0 * zh * a  # s²/ω_h² + 2ζ_h s/ω_h + 1 at s = jx
        vr, vi = 1.0 - b * b, 2.0 * zv * b
        gain = lk - math.log(x) - math.log(math.hypot(hr, hi)) - math.log(math.hypot(vr, vi))
        phase = -x * delay - 0.5 * math.pi - math.atan2(hi, hr) - math.atan2(vi, vr)
        if tv > 0.0:
            gain -= math.log(math.hypot(1.0, tv * x))
            phase -= math.atan(tv * x)
        re.append(gain)
        im.append(phase)
    return np.array(re), np.array(im)


def _wrap(phase: FloatArray) -> FloatArray:
    """Phases wrapped into [-π, π] (an exact remainder)."""
    return np.array([math.remainder(v, _TWO_PI) for v in phase.tolist()])


def _check_frf(w: FloatArray, h: ComplexArray, what: str, unit: str = "rad/s",
               factor: float = 1.0) -> None:
    """Frequencies finite, > 0, increasing; responses finite and non-zero; >= 4 points."""
    if w.size < 4:
        raise InputError(f"{what} has {w.size} frequencies; at least 4 are needed")
    for k in range(w.size):
        f = float(w[k]) / factor
        if not math.isfinite(f):
            raise InputError(f"{what}: frequency {k + 1} is {f!r}; every frequency must be "
                             f"a finite number")
        if f <= 0.0:
            raise InputError(f"{what}: frequency {k + 1} is {f!r} {unit}; frequencies must "
                             f"be > 0")
        if k and not w[k] > w[k - 1]:
            raise InputError(f"{what}: frequency {k + 1} ({f!r} {unit}) does not follow "
                             f"frequency {k} ({float(w[k - 1]) / factor!r} {unit}); list "
                             f"frequencies once each, in increasing order")
        if not np.isfinite(h[k]):
            raise InputError(f"{what}: the response at frequency {k + 1} ({f!r} {unit}) is "
                             f"{complex(h[k])!r}; gain and phase must be finite")
        if h[k] == 0.0:
            raise InputError(f"{what}: the gain at frequency {k + 1} ({f!r} {unit}) is 0; a "
                             f"gain must be > 0")


_ROLES: dict[str, tuple[str, ...]] = {
    "frequency": ("f", "freq", "frequency"),
    "gain": ("gain", "mag", "magnitude", "amplitude"),
    "phase": ("phase",),
}
_ROLE_UNITS: dict[str, dict[str, str]] = {
    "frequency": {"hz": "Hz", "rad/s": "rad/s"},
    "gain": {"db": "dB", "abs": "abs"},
    "phase": {"deg": "deg", "degree": "deg", "degrees": "deg", "°": "deg", "rad": "rad"},
}
_HEADER = re.compile(r"^\s*([A-Za-z_ ]*?)\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?\s*$")


def read_frequency_response(path: str | Path, *,
                            frequency_unit: Literal["Hz", "rad/s"] | None = None,
                            gain: Literal["abs", "dB"] | None = None,
                            phase: Literal["deg", "rad"] | None = None
                            ) -> tuple[FloatArray, ComplexArray]:
    """A measured frequency response x/u from a CSV of frequency, gain and phase.

    Column names (case-insensitive): ``f``, ``freq`` or ``frequency``; ``gain``, ``mag``,
    ``magnitude`` or ``amplitude``; ``phase``; each may carry its unit in brackets
    (``frequency [Hz]``, ``gain [dB]``, ``phase [deg]``). Other columns are ignored. The
    gain is that of x/u, integrator included: m per unit command per (rad/s) as a ratio
    (``abs``), or 20 log10 of it (``dB``).

    Parameters
    ----------
    path : str or Path
        The CSV file (header row, ``#`` comment lines ignored).
    frequency_unit : {"Hz", "rad/s"}, optional
        Unit of the frequency column; default the header's, else Hz [-].
    gain : {"abs", "dB"}, optional
        Scale of the gain column; default the header's, else ``abs`` [-].
    phase : {"deg", "rad"}, optional
        Unit of the phase column; default the header's, else degrees [-].

    Returns
    -------
    w : ndarray (n,)
        Angular frequencies [rad/s], increasing.
    H : ndarray (n,), complex
        gain · e^{j phase} [m per unit command per (rad/s)].

    Raises
    ------
    InputError
        The file cannot be read, lacks a column or names one twice, a unit in the header
        that is not allowed or contradicts the argument, fewer than 4 rows, a frequency
        that is not finite, not > 0 or not increasing, or a gain or phase that is not a
        finite number (a gain of 0 too). The message names the value.
    ParameterError
        An argument that is not one of its choices.
    """
    given = {"frequency": frequency_unit, "gain": gain, "phase": phase}
    for role, value in given.items():
        allowed = sorted(set(_ROLE_UNITS[role].values()))
        if value is not None and value not in allowed:
            raise ParameterError(f"{role} unit must be one of {', '.join(allowed)}, got "
                                 f"{value!r}")
    what = "frequency-response file"
    shown = f"{what} {str(path)!r}"
    columns = read_csv_columns(path, (), what=what, min_rows=1)
    found: dict[str, tuple[str, str | None]] = {}
    for header in columns:
        m = _HEADER.match(header)
        if m is None:
            continue
        name = m.group(1).strip().lower()
        for role, aliases in _ROLES.items():
            if name in aliases:
                if role in found:
                    raise InputError(f"{shown} has two {role} columns, {found[role][0]!r} "
                                     f"and {header!r}; keep one")
                unit = m.group(2)
                if unit is not None:
                    key = unit.strip().lower()
                    if key not in _ROLE_UNITS[role]:
                        takes = ", ".join(f"[{u}]" for u in
                                          sorted(set(_ROLE_UNITS[role].values())))
                        raise InputError(f"{shown}: column {header!r} has the unit "
                                         f"{unit!r}; a {role} column takes {takes}")
                    unit = _ROLE_UNITS[role][key]
                found[role] = (header, unit)
    missing = [role for role in _ROLES if role not in found]
    if missing:
        raise InputError(
            f"{shown} lacks a numeric {' and '.join(missing)} column (names: "
            + "; ".join(f"{r}: {', '.join(_ROLES[r])}" for r in missing)
            + f"); numeric columns found: {', '.join(map(repr, columns)) or 'none'} (a "
              f"column with an empty or text cell is not numeric)")
    units: dict[str, str] = {}
    for role, default in (("frequency", "Hz"), ("gain", "abs"), ("phase", "deg")):
        header_unit = found[role][1]
        arg = given[role]
        if header_unit is not None and arg is not None and header_unit != arg:
            raise InputError(f"{shown}: column {found[role][0]!r} says {header_unit}, the "
                             f"argument says {arg}; make them agree")
        units[role] = header_unit or arg or default
    f = np.array(columns[found["frequency"][0]], dtype=np.float64)
    g = np.array(columns[found["gain"][0]], dtype=np.float64)
    p = np.array(columns[found["phase"][0]], dtype=np.float64)
    factor = 2.0 * math.pi if units["frequency"] == "Hz" else 1.0
    for k in range(f.size):
        for arr, col in ((g, "gain"), (p, "phase")):
            if not math.isfinite(float(arr[k])):
                raise InputError(f"{shown}: {col} in data row {k + 1} is {float(arr[k])!r}; "
                                 f"every {col} must be a finite number")
        if units["gain"] == "abs" and not g[k] > 0.0:
            raise InputError(f"{shown}: gain in data row {k + 1} is {float(g[k])!r}; a gain "
                             f"must be > 0 (or give it in dB)")
    # per value with the C library (numpy's vector power rounds otherwise on AVX-512)
    mag = (np.array([math.pow(10.0, v / 20.0) for v in g.tolist()]) if units["gain"] == "dB"
           else g)
    ph = np.deg2rad(p) if units["phase"] == "deg" else p
    w = f * factor
    h = np.array([complex(m * math.cos(a), m * math.sin(a))
                  for m, a in zip(mag.tolist(), ph.tolist(), strict=True)],
                 dtype=np.complex128)
    _check_frf(w, h, shown, units["frequency"], factor)
    return w, h


def fit_linear_frequency(w: ArrayLike, H: ArrayLike, *, params: ServoParams,  # noqa: N803
                         position: float | None = None, fit: Sequence[str] = DEFAULT_FIT,
                         delay: float = 0.0) -> LinearFit:
    """Fit eq. (8) to a measured frequency response x/u.

    Parameters
    ----------
    w : array (n,)
        Angular frequencies, > 0 and increasing [rad/s].
    H : array (n,), complex
        Measured x/u at ``w`` [m per unit command per (rad/s)].
    params : ServoParams
        Base parameters: the coefficients not fitted (and τ_v) come from its eq. (8) at
        ``position``; its linearisation also centres the search grid.
    position : float, optional
        Piston position the response was measured about [m]; default mid-stroke.
    fit : sequence of str
        The coefficients to fit, from :data:`LINEAR_NAMES`; default :data:`DEFAULT_FIT`.
    delay : float
        Transport delay held when ``delay`` is not fitted [s]; default 0.

    Returns
    -------
    LinearFit
        ``source`` "frequency"; ``residual_rms`` the rms of |H_model/H - 1| [1].

    Raises
    ------
    InputError
        Fewer than 4 frequencies or fewer than the coefficients allow, a frequency not
        finite, not > 0 or not increasing, a response that is not finite or is zero.
    ParameterError
        An unknown coefficient name, a bad ``delay`` or ``position``.
    """
    names = _check_names(fit)
    if not (isinstance(delay, int | float) and math.isfinite(delay) and delay >= 0.0):
        raise ParameterError(f"delay must be a finite number >= 0 s, got {delay!r}")
    ww = _float_array(w, "w")
    try:
        hh = np.asarray(H, dtype=np.complex128)
    except (TypeError, ValueError):
        raise InputError("H must be an array of complex numbers") from None
    if hh.shape != ww.shape:
        raise InputError(f"w and H need one value per frequency, got {ww.shape} and "
                         f"{hh.shape}")
    _check_frf(ww, hh, "frequency response")
    if 2 * ww.size <= len(names):
        raise InputError(f"{ww.size} frequencies cannot determine {len(names)} coefficients")
    pos = params.cylinder.stroke / 2.0 if position is None else position
    held = _held(params, pos, float(delay))
    tau_v = params.valve.tau_v
    space = _Space(names, held, delay_scale=1.0 / float(ww[-1]),
                   delay_max=2.0 * math.pi / float(ww[0]))
    freqs = ww.tolist()
    # ln H of the data: ln|H| and arg H, per frequency
    log_h_re = np.array([math.log(math.hypot(h.real, h.imag)) for h in hh.tolist()])
    log_h_im = np.array([math.atan2(h.imag, h.real) for h in hh.tolist()])

    def log_ratio(values: Mapping[str, float]) -> tuple[FloatArray, FloatArray]:
        """ln(H_model/H): gain [-] and phase difference wrapped into [-π, π] [rad]."""
        re, im = _log_eq8(freqs, _servo(values, tau_v), values["delay"])
        return re - log_h_re, _wrap(im - log_h_im)

    def residual(theta: FloatArray) -> FloatArray:
        out: FloatArray = np.concatenate(log_ratio(space.values(theta)))
        return out

    def cost(values: dict[str, float]) -> tuple[float, float]:
        k_best = values["K_o"]
        if "K_o" in space.names:
            z0, _ = log_ratio(dict(values, K_o=1.0))
            k_best = math.exp(-_mean(z0))
        gain, phase = log_ratio(dict(values, K_o=k_best))
        return sum_of_squares(gain) + sum_of_squares(phase), k_best

    def delay_guess(wh: float, zh: float) -> float:
        """The slope of the phase that eq. (8) without delay leaves unexplained."""
        base = dict(held, omega_h=wh, zeta_h=zh, delay=0.0)
        phi = np.unwrap(-log_ratio(base)[1])
        phi = phi - _TWO_PI * round(float(phi[0]) / _TWO_PI)
        tau = -total(ww * phi) / sum_of_squares(ww)
        return min(max(tau, 0.0), space.delay_max)

    base_w = held["omega_h"]
    grid_w = sorted({*(base_w * f for f in (0.5, 1.0, 2.0)),
                     *_geomspace(float(ww[0]), float(ww[-1]), 8)})
    if "delay" in names:
        grid_d = sorted({0.0, float(delay), *(delay_guess(wh, zh) for wh in grid_w
                                               for zh in (0.05, 0.3, 1.0))})
    else:
        grid_d = [float(delay)]
    starts = _grid_starts(space, cost, grid_w, grid_d)
    theta, cov_theta, notes = _solve(space, residual, starts)
    estimate, se, corr, corr_notes = _summarise(space, theta, cov_theta)
    values = space.values(theta)
    # |H_model/H - 1| = |e^z - 1| with z = ln(H_model/H)
    gain, phase = log_ratio(values)
    mag = np.array([math.exp(v) for v in gain.tolist()])
    miss = np.concatenate([mag * np.array([math.cos(v) for v in phase.tolist()]) - 1.0,
                           mag * np.array([math.sin(v) for v in phase.tolist()])])
    notes = _held_notes(space, "eq. (8) of the base parameters") + notes + corr_notes
    for name in ("omega_h", "omega_v"):
        if name in names and not ww[0] / 3.0 <= values[name] <= 3.0 * ww[-1]:
            notes.append(f"{name} = {values[name]:.4g} rad/s is far outside the measured band "
                         f"{ww[0]:.4g} to {ww[-1]:.4g} rad/s")
    return LinearFit(names=names, estimate=estimate, std_error=se, correlation=corr,
                     servo=_servo(values, tau_v), delay=values["delay"],
                     residual_rms=math.sqrt(sum_of_squares(miss) / ww.size),
                     source="frequency", n_data=int(ww.size), y_rest=math.nan,
                     notes=tuple(notes))


# -- the physical parameters a fit implies -------------------------------------------------

_SOLVE_FOR = ("load.mass", "fluid.oil_bulk_modulus")
_DAMPING_BY = ("valve.null_leakage", "load.viscous_damping")
_DIRECT = {"delay": "delay.transport_delay", "omega_v": "valve.omega_v",
           "zeta_v": "valve.zeta_v"}


def _field(params: ServoParams, name: str) -> float:
    group, field = name.split(".")
    return float(getattr(getattr(params, group), field))


def _root(f: Callable[[float], float], x0: float, nonnegative: bool) -> float | None:
    """The root of a monotone ``f`` near ``x0`` > 0, by widening brackets then Brent's
    method; None when there is none (or the model fails on the way)."""
    from scipy.optimize import brentq

    def safe(x: float) -> float:
        try:
            return f(x)
        except (ParameterError, SimulationDivergedError):
            return math.nan

    f0 = safe(x0)
    if not math.isfinite(f0):
        return None
    if f0 == 0.0:
        return x0
    below, above = (x0, f0), (x0, f0)
    go_down = go_up = True
    ratio = 1.1
    bracket: tuple[float, float] | None = None
    while bracket is None and (go_down or go_up) and ratio < 1e13:
        if go_down:
            lo = x0 / ratio
            flo = safe(lo)
            if not math.isfinite(flo):
                go_down = False
            elif flo * below[1] <= 0.0:
                bracket = (lo, below[0])
            else:
                below = (lo, flo)
        if bracket is None and go_up:
            hi = x0 * ratio
            fhi = safe(hi)
            if not math.isfinite(fhi):
                go_up = False
            elif fhi * above[1] <= 0.0:
                bracket = (above[0], hi)
            else:
                above = (hi, fhi)
        ratio = ratio * ratio
    if bracket is None and nonnegative:
        fz = safe(0.0)
        if math.isfinite(fz) and fz * below[1] <= 0.0:
            bracket = (0.0, below[0])
    if bracket is None:
        return None
    return float(brentq(f, bracket[0], bracket[1], xtol=1e-300, rtol=1e-13, maxiter=200))


def _start_value(params: ServoParams, field: str, fit: LinearFit) -> float:
    """A scale to search from for a field whose base value is 0."""
    value = _field(params, field)
    if value > 0.0:
        return value
    if field == "load.viscous_damping":  # B = 2 ζ ω M, the damping of the mass alone
        return 2.0 * fit.value("zeta_h") * fit.value("omega_h") * params.load.mass
    if field == "valve.null_leakage":  # a leakage flow of 1 % of rated at the supply
        return 0.01 * params.valve.rated_flow / params.supply.pressure
    return 1.0


def implied_estimates(fit: LinearFit, params: ServoParams, position: float, *,
                      solve_for: Literal["load.mass", "fluid.oil_bulk_modulus"] = "load.mass",
                      damping_by: Literal["valve.null_leakage",
                                          "load.viscous_damping"] = "valve.null_leakage",
                      gain: Literal["eq8", "small-signal"] = "eq8"
                      ) -> list[ImpliedParameter]:
    """The physical parameters a fit determines given the others, with standard errors.

    - ``valve.rated_flow`` from K_o: with ``gain="eq8"`` K_o = Q_rated/A_f (eq. 8, the
      bore held); with ``gain="small-signal"`` K_o read as the small-signal velocity gain
      of :func:`fuzzyservo.plant.linearize` at ``position`` (what small open-loop motions
      of the real servo measure).
    - ``solve_for`` (``load.mass``, holding the bulk moduli and volumes, or
      ``fluid.oil_bulk_modulus``, holding the mass) from ω_h = linearize(...).omega_0.
    - ``damping_by`` (``valve.null_leakage``, holding ``load.viscous_damping``, or the
      reverse) from ζ_h = linearize(...).damping.
    - ``delay.transport_delay``, ``valve.omega_v``, ``valve.zeta_v``: the fitted values
      (the latter two only when fitted).

    The unknowns are solved together (ω₀ and δ of the linearisation each depend on mass,
    modulus, leakage and damping) by sweeps of one-dimensional Brent solves until they
    settle, so that ``linearize(with_overrides(params, implied), position)`` reproduces the
    fitted ω_h and ζ_h. Standard errors follow from the fit's covariance through the
    inverse of the Jacobian of (K_o, ω₀, δ) in the unknowns (implicit-function theorem).

    Parameters
    ----------
    fit : LinearFit
        The fit.
    params : ServoParams
        The parameters held (those the fit does not determine) and the starting values.
    position : float
        Piston position the data were taken about [m].
    solve_for : {"load.mass", "fluid.oil_bulk_modulus"}
        Which of the two ω_h determines; the other is held [-].
    damping_by : {"valve.null_leakage", "load.viscous_damping"}
        Which of the two ζ_h determines; the other is held [-].
    gain : {"eq8", "small-signal"}
        How K_o is read (above) [-].

    Returns
    -------
    list of ImpliedParameter
        One per parameter; ``value`` nan and ``how`` saying why where the data cannot
        decide (a coefficient not fitted, or no value reproduces the fit).

    Raises
    ------
    ParameterError
        A choice not among those allowed, or a position outside the stroke.
    """
    if solve_for not in _SOLVE_FOR:
        raise ParameterError(f"solve_for must be one of {', '.join(_SOLVE_FOR)}, got "
                             f"{solve_for!r}")
    if damping_by not in _DAMPING_BY:
        raise ParameterError(f"damping_by must be one of {', '.join(_DAMPING_BY)}, got "
                             f"{damping_by!r}")
    if gain not in ("eq8", "small-signal"):
        raise ParameterError(f"gain must be 'eq8' or 'small-signal', got {gain!r}")
    est = {n: float(v) for n, v in zip(fit.names, fit.estimate.tolist(), strict=True)}
    cov_fit = fit.covariance()
    index = {n: i for i, n in enumerate(fit.names)}
    direct = {_DIRECT[n]: est[n] for n in ("omega_v", "zeta_v") if n in est}
    base = with_overrides(params, direct) if direct else params
    linearize(base, position)  # the position checked (ParameterError) before any solve
    held_mass = solve_for != "load.mass"
    other_w = "load.mass" if held_mass else "fluid.oil_bulk_modulus"
    other_z = _DAMPING_BY[1 - _DAMPING_BY.index(damping_by)]
    at = f"linearize at x = {position:g} m"

    def lin_of(p: ServoParams) -> Any:
        return linearize(p, position)

    measures: dict[str, Callable[[ServoParams], float]] = {
        "K_o": ((lambda p: p.velocity_gain) if gain == "eq8"
                else (lambda p: float(lin_of(p).velocity_gain))),
        "omega_h": lambda p: float(lin_of(p).omega_0),
        "zeta_h": lambda p: float(lin_of(p).damping),
    }
    fields = {"K_o": "valve.rated_flow", "omega_h": solve_for, "zeta_h": damping_by}
    hows = {
        "K_o": (f"K_o = Q_rated/A_f (eq. 8) with cylinder.bore = "
                f"{params.cylinder.bore:g} m" if gain == "eq8" else
                f"K_o read as the small-signal velocity gain ({at})"),
        "omega_h": (f"omega_h = omega_0 ({at}), holding {other_w} = "
                    f"{_field(params, other_w):.6g}{_unit(_FIELD_UNITS[other_w])}"
                    + ("" if held_mass else " and the volumes")),
        "zeta_h": (f"zeta_h = damping ({at}), holding {other_z} = "
                   f"{_field(params, other_z):.6g}{_unit(_FIELD_UNITS[other_z])}"),
    }
    active = [q for q in ("K_o", "omega_h", "zeta_h") if q in est]
    value = {q: _start_value(base, fields[q], fit) for q in active}
    failed: dict[str, str] = {}

    def current(skip: str | None = None, **extra: float) -> ServoParams:
        over = {fields[q]: v for q, v in value.items() if q != skip and q not in failed}
        over.update({fields[q]: v for q, v in extra.items()})
        return with_overrides(base, over) if over else base

    for _sweep in range(60):
        moved = 0.0
        for q in active:
            if q in failed:
                continue
            target = est[q]

            def residual(v: float, q: str = q, target: float = target) -> float:
                return measures[q](current(skip=q, **{q: v})) - target

            root = _root(residual, value[q], nonnegative=q == "zeta_h")
            if root is None:
                failed[q] = (f"not determined: no {fields[q]} >= 0 reproduces {q} = "
                             f"{target:.6g}{_unit(LINEAR_UNITS[q])} with the others held")
                continue
            moved = max(moved, abs(root - value[q]) / max(abs(root), 1e-300))
            value[q] = root
        if moved < 1e-11:
            break
    solved = [q for q in active if q not in failed]
    se_of = dict.fromkeys(solved, math.nan)
    if solved:
        p0 = current()
        jac = np.empty((len(solved), len(solved)))
        for j, q in enumerate(solved):
            v = value[q]
            h = 1e-5 * v if v > 0.0 else 1e-5 * _start_value(params, fields[q], fit)
            lo = max(v - h, 0.0)
            up_p = with_overrides(p0, {fields[q]: v + h})
            dn_p = with_overrides(p0, {fields[q]: lo})
            for i, qi in enumerate(solved):
                jac[i, j] = (measures[qi](up_p) - measures[qi](dn_p)) / (v + h - lo)
        sub = np.array([[cov_fit[index[a], index[b]] for b in solved] for a in solved])
        try:  # plant.dense: no BLAS or LAPACK (2x2 or 3x3)
            g = solve(jac, np.eye(len(solved)))
            cov = matmul(matmul(g, sub), g.T)
            se_of = {q: float(math.sqrt(max(cov[i, i], 0.0))) if math.isfinite(cov[i, i])
                     else math.inf for i, q in enumerate(solved)}
        except ParameterError:  # a singular Jacobian
            pass
    out: list[ImpliedParameter] = []
    for q in ("K_o", "omega_h", "zeta_h"):
        name = fields[q]
        unit = _FIELD_UNITS[name]
        if q not in est:
            out.append(ImpliedParameter(name=name, value=math.nan, std_error=math.nan,
                                        unit=unit, how=f"not determined: {q} not fitted"))
        elif q in failed:
            out.append(ImpliedParameter(name=name, value=math.nan, std_error=math.nan,
                                        unit=unit, how=failed[q]))
        else:
            together = [fields[o] for o in solved if o != q
                        and (gain == "small-signal" or "K_o" not in (o, q))]
            how = hows[q] + (f"; solved with {', '.join(together)}" if together else "")
            out.append(ImpliedParameter(name=name, value=value[q], std_error=se_of[q],
                                        unit=unit, how=how))
    for d in ("delay", "omega_v", "zeta_v"):
        name = _DIRECT[d]
        if d in est:
            se = float(fit.std_error[index[d]])
            out.append(ImpliedParameter(name=name, value=est[d], std_error=se,
                                        unit=_FIELD_UNITS[name], how=f"the fitted {d}"))
        elif d == "delay":
            out.append(ImpliedParameter(name=name, value=math.nan, std_error=math.nan,
                                        unit=_FIELD_UNITS[name],
                                        how="not determined: delay not fitted"))
    return out


def implied_parameters(fit: LinearFit, params: ServoParams, position: float, *,
                       solve_for: Literal["load.mass", "fluid.oil_bulk_modulus"] = "load.mass",
                       damping_by: Literal["valve.null_leakage",
                                           "load.viscous_damping"] = "valve.null_leakage",
                       gain: Literal["eq8", "small-signal"] = "eq8"
                       ) -> list[tuple[str, float, str]]:
    """:func:`implied_estimates` as ``(group.field, value [SI], how)`` rows, the standard
    error written into ``how``; the parameters as there.

    Parameters
    ----------
    fit : LinearFit
        The fit.
    params : ServoParams
        The parameters held and the starting values.
    position : float
        Piston position the data were taken about [m].
    solve_for : {"load.mass", "fluid.oil_bulk_modulus"}
        Which of the two ω_h determines [-].
    damping_by : {"valve.null_leakage", "load.viscous_damping"}
        Which of the two ζ_h determines [-].
    gain : {"eq8", "small-signal"}
        How K_o is read [-].
    """
    rows = implied_estimates(fit, params, position, solve_for=solve_for,
                             damping_by=damping_by, gain=gain)
    out = []
    for r in rows:
        how = r.how
        if math.isfinite(r.value):
            how += f"; ± {r.std_error:.2g}{_unit(r.unit)} (1 s.e.)"
        out.append((r.name, r.value, how))
    return out


# -- terminal lines and the output file ----------------------------------------------------


def _with_error(value: float, se: float, unit: str) -> str:
    unit = _unit(unit)
    if not math.isfinite(value):
        return "not determined"
    if not math.isfinite(se):
        return f"{value:.6g}{unit} (standard error not determined)"
    return f"{value:.6g} ± {se:.2g}{unit}"


def describe(fit: LinearFit, implied: Sequence[ImpliedParameter] | Sequence[
        tuple[str, float, str]] = ()) -> list[str]:
    """Lines for the terminal: the estimates with their standard errors, the correlations,
    the notes, then the implied parameters (from :func:`implied_estimates` or
    :func:`implied_parameters`)."""
    what = "time data" if fit.source == "time" else "a frequency response"
    count = "samples" if fit.source == "time" else "frequencies"
    rms = (f"{fit.residual_rms:.3g} m" if fit.source == "time"
           else f"{fit.residual_rms:.3g} (|H_model/H - 1|)")
    lines = [f"eq. (8) fitted to {what} ({fit.n_data} {count}): residual rms {rms}"
             + (f", position at rest {fit.y_rest:.6g} m" if fit.source == "time" else "")]
    width = max(len(n) for n in fit.names)
    for n, v, se in zip(fit.names, fit.estimate.tolist(), fit.std_error.tolist(), strict=True):
        lines.append(f"  {n:<{width}} = {_with_error(v, se, LINEAR_UNITS[n])}")
    if len(fit.names) > 1:
        lines.append("  correlation:")
        for i, n in enumerate(fit.names):
            row = " ".join(f"{c:+.3f}" if math.isfinite(c) else "   nan"
                           for c in fit.correlation[i].tolist())
            lines.append(f"    {n:<{width}} {row}")
    lines += [f"  note: {note}" for note in fit.notes]
    if implied:
        lines.append("implied parameters:")
        for item in implied:
            if isinstance(item, ImpliedParameter):
                text = (_with_error(item.value, item.std_error, item.unit) + "  ("
                        + item.how + ")") if math.isfinite(item.value) else item.how
                lines.append(f"  {item.name} = {text}" if math.isfinite(item.value)
                             else f"  {item.name}: {text}")
            else:
                name, value, how = item
                lines.append(f"  {name} = {value:.6g}  ({how})" if math.isfinite(value)
                             else f"  {name}: {how}")
    return lines


def to_record(fit: LinearFit, implied: Sequence[ImpliedParameter] = ()) -> dict[str, Any]:
    """The fit as TOML-ready data (numbers, strings, lists, tables; nan and inf where not
    determined), with the implied parameters when given."""
    s = fit.servo
    doc: dict[str, Any] = {
        "model": "eq. (8)",
        "source": fit.source,
        "n_data": fit.n_data,
        "residual_rms": fit.residual_rms,
        "residual_unit": "m" if fit.source == "time" else "1",
        "y_rest": fit.y_rest,
        "fitted": {n: {"value": v, "std_error": se, "unit": LINEAR_UNITS[n]}
                   for n, v, se in zip(fit.names, fit.estimate.tolist(),
                                       fit.std_error.tolist(), strict=True)},
        "correlation": {"names": list(fit.names),
                        "matrix": [list(map(float, row)) for row in fit.correlation.tolist()]},
        "servo": {"K_o": s.K_o, "omega_h": s.omega_0, "zeta_h": s.damping,
                  "omega_v": s.omega_v, "zeta_v": s.zeta_v, "tau_v": s.tau_v,
                  "delay": fit.delay},
        "notes": list(fit.notes),
    }
    if implied:
        doc["implied"] = {r.name: {"value": r.value, "std_error": r.std_error,
                                   "unit": r.unit, "how": r.how} for r in implied}
    return doc
