"""Fit fields of the servo's parameter set to a logged experiment (weighted least squares).

The model is any plant of the registry (``nonlinear``, ``small-signal``, ``linear``), built
from the parameter set with the fitted fields replaced, at rest at the logged start position,
and driven as the axis was: by the logged command (open loop) or by a controller and the logged
reference (closed loop). Its position, and its chamber pressures where the data have them and
the model has them, are compared with the logged ones sample by sample. The simulations are
the compiled loops of :mod:`fuzzyservo.sim` (one run: a few milliseconds for 10 s at 1 kHz);
the Jacobian is taken by central finite differences, its 2p runs at once on a pool of threads
(the compiled loops release the GIL).

The fit (docs/identify.md):

1. Coordinates: a field whose lower bound is > 0 is fitted as log(value); others (a friction
   that may be 0) linearly, scaled by their upper bound.
2. Weights: each channel c is divided by its noise level sigma_c, first estimated from the data
   (the median absolute second difference: a smooth motion sampled fast has second differences
   far below the noise), then, after a first fit, by the channel's residual RMS
   (iteratively re-weighted least squares, so a channel the model cannot follow as well does
   not dominate).
3. Starts: the parameter set's values, then ``starts - 1`` seeded draws inside the bounds
   (log-uniform); a bounded Levenberg-Marquardt search from each
   (:mod:`fuzzyservo.identify.lsq`: no BLAS or LAPACK, so the estimates are the same bits on
   every machine), the best kept and the spread of the others reported.
4. Uncertainty: the covariance s^2 (J^T J)^-1 at the optimum (s^2 the reduced chi-square),
   standard errors mapped back to SI by the delta method, the correlation matrix; with
   ``bootstrap = N``, percentile intervals from N refits to the fitted traces plus moving
   blocks of the residuals (which keeps their correlation in time).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..control.command import CommandSchedule
from ..errors import FuzzyServoError, InputError, ParameterError
from ..plant import ServoParams, linearize, with_overrides
from ..plant.params import allowed_names, field_unit
from ..registry import build_plant, plant_kind
from ..sim.closed_loop import run_loop
from ..sim.references import reference_rates as rates_of
from .lsq import covariance, levenberg_marquardt, sum_of_squares, total

__all__ = [
    "FIT_CHANNELS",
    "DEFAULT_STARTS",
    "FitSettings",
    "Identification",
    "ModelRunner",
    "check_names",
    "default_bounds",
    "identify",
    "noise_level",
]

#: The signals compared, in order, with their units.
FIT_CHANNELS: dict[str, str] = {"y": "m", "p_f": "Pa", "p_n": "Pa"}

#: Starts of the local search by default: the parameter set's values and two seeded draws.
DEFAULT_STARTS = 3

#: Relative step of the central differences in the fitted coordinates (log: 1e-5 relative).
_FD_STEP = 1.0e-5

#: Fewest hydraulic periods (2 pi / omega_0 of the parameter set) the excited part must last.
MIN_PERIODS = 3.0


@dataclass(frozen=True, slots=True, kw_only=True)
class FitSettings:
    """How the least-squares search runs.

    Parameters
    ----------
    starts : int
        Local searches: the set's values, then seeded draws inside the bounds (>= 1).
    seed : int
        Seed of the starts and of the bootstrap's resampling.
    bootstrap : int
        Refits to resampled residual blocks for percentile intervals (0: none).
    block : int or None
        Length of the bootstrap's residual blocks [samples]; None: two hydraulic periods.
    level : float
        Coverage of the bootstrap's percentile intervals, in (0, 1) [1].
    max_nfev : int
        Most evaluations of the residuals per search.
    reweight : bool
        Re-weight the channels by their residual RMS and refit (step 2 of the module's list).
    workers : int or None
        Threads that run the model; None: the processor count.
    """

    starts: int = DEFAULT_STARTS
    seed: int = 0
    bootstrap: int = 0
    block: int | None = None
    level: float = 0.95
    max_nfev: int = 200
    reweight: bool = True
    workers: int | None = None

    def __post_init__(self) -> None:
        for name, low in (("starts", 1), ("bootstrap", 0), ("max_nfev", 2)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise ParameterError(f"{name} (--{name.replace('_', '-')}) must be an integer "
                                     f">= {low}, got {v!r}")
        if self.block is not None and (isinstance(self.block, bool)
                                       or not isinstance(self.block, int) or self.block < 1):
            raise ParameterError(f"block (--block) must be an integer >= 1 sample, got "
                                 f"{self.block!r}")
        if not (isinstance(self.level, float | int) and 0.0 < self.level < 1.0):
            raise ParameterError(f"level (--level) must be in (0, 1), got {self.level!r}")
        if self.workers is not None and (isinstance(self.workers, bool)
                                         or not isinstance(self.workers, int)
                                         or self.workers < 1):
            raise ParameterError(f"workers must be an integer >= 1, got {self.workers!r}")


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class Identification:
    """The result of :func:`identify`: estimates, their uncertainty and the traces."""

    names: tuple[str, ...]  #: fitted fields, ``group.field``
    units: tuple[str, ...]  #: their units (from the parameter classes' docs)
    initial: FloatArray  #: the parameter set's values of the fields [SI]
    estimate: FloatArray  #: the estimates [SI]
    std_error: FloatArray  #: standard errors (delta method; inf: not determined) [SI]
    correlation: FloatArray  #: correlation matrix of the estimates (p, p) [1]
    bounds: FloatArray  #: (p, 2) bounds of the search [SI]
    interval: FloatArray | None  #: (p, 2) bootstrap percentile interval [SI], or None
    level: float  #: coverage of ``interval`` [1]
    bootstrap: FloatArray | None  #: (N, p) bootstrap estimates [SI], or None
    params: ServoParams  #: the identified parameter set
    base: ServoParams  #: the parameter set the fit started from
    plant: str  #: the plant model fitted
    mode: str  #: "open loop" or "closed loop"
    position: float  #: start position of the model [m]
    t: FloatArray  #: sample times [s]
    channels: tuple[str, ...]  #: signals compared (``FIT_CHANNELS`` names)
    measured: dict[str, FloatArray]  #: each channel's logged trace [SI]
    fitted: dict[str, FloatArray]  #: each channel's trace of the identified model [SI]
    start_fit: dict[str, FloatArray]  #: each channel's trace of the starting model [SI]
    used: FloatArray  #: (n,) bool, samples that enter the fit (not flagged)
    sigma: dict[str, float]  #: each channel's weight 1/sigma: sigma [SI]
    residual_rms: dict[str, float]  #: each channel's residual RMS over the used samples [SI]
    chi2: float  #: reduced chi-square of the final weighted fit [1]
    start_costs: FloatArray  #: final cost of each start (weighted sum of squares / 2)
    start_spread: float  #: widest relative distance from the best of starts at its cost [1]
    n_runs: int  #: model runs made (fit, Jacobians, bootstrap)
    warnings: tuple[str, ...]  #: identifiability warnings, one line each
    notes: tuple[str, ...] = field(default=())  #: what the fit did, one line each

    def value(self, name: str) -> float:
        """The estimate of ``name`` [SI]."""
        if name not in self.names:
            raise ParameterError(f"{name!r} was not fitted; fitted: {', '.join(self.names)}")
        return float(self.estimate[self.names.index(name)])

    def error(self, name: str) -> float:
        """The standard error of ``name`` [SI]."""
        if name not in self.names:
            raise ParameterError(f"{name!r} was not fitted; fitted: {', '.join(self.names)}")
        return float(self.std_error[self.names.index(name)])


def noise_level(x: FloatArray) -> float:
    """A robust estimate of the white measurement noise of a trace sampled fast [its unit]:
    1.4826 median|Δ²x| / sqrt(6) (the second difference of white noise of variance σ² has
    variance 6σ²; a smooth motion's second differences are far smaller)."""
    if x.size < 5:
        return 0.0
    d2 = np.diff(x, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def excited_band(x: FloatArray, dt: float, share: float = 0.99) -> float:
    """The frequency below which ``share`` of the excitation's power lies [Hz] (the signal
    less its mean; a periodogram, its cumulative sum in order)."""
    if x.size < 4:
        return 0.0
    spec = np.abs(np.fft.rfft(x - total(x) / x.size)) ** 2
    cum = np.cumsum(spec)
    if cum[-1] <= 0.0:
        return 0.0
    k = int(np.searchsorted(cum, share * cum[-1]))
    return float(k / (x.size * dt))


def check_names(names: Sequence[str]) -> tuple[str, ...]:
    """The fitted field names, checked: known, each once, at least one."""
    allowed = allowed_names()
    out = tuple(n.strip() for n in names)
    if not out:
        raise ParameterError("--fit names no parameter; give one or more group.field names, "
                             "e.g. load.mass,fluid.oil_bulk_modulus")
    for n in out:
        if n not in allowed:
            raise ParameterError(f"cannot fit unknown parameter {n!r}; allowed: "
                                 f"{', '.join(allowed)}")
        if out.count(n) > 1:
            raise ParameterError(f"--fit names {n!r} twice; name each parameter once")
    return out


def default_bounds(name: str, value: float) -> tuple[float, float]:
    """The search interval of a field with no ``--bounds``: [value/10, 10 value] [SI].

    Raises
    ------
    ParameterError
        When the set's value is 0 or negative (no scale to search around: give bounds).
    """
    if not (math.isfinite(value) and value > 0.0):
        raise ParameterError(f"{name} is {value!r} in the parameter set, so it has no default "
                             f"search interval; give one with --bounds {name}=LO:HI")
    return value / 10.0, value * 10.0


class ModelRunner:
    """The model of one experiment: parameter vectors in, channel traces out.

    Parameters
    ----------
    measurement : Measurement
        The logged experiment (:func:`fuzzyservo.identify.read_measurement`).
    plant : str
        Registered plant name.
    base : ServoParams
        The parameter set whose ``names`` fields are replaced.
    names : sequence of str
        Fitted fields.
    controller : LawController or None
        None: open loop (driven by the logged command ``u``); else closed loop, the
        controller driven by the logged reference ``r``.
    substep : float
        RK4 step bound of the nonlinear plant [s].
    command_offset : {"rest", "none"}
        Open loop: ``rest`` drives the model with u - u_rest + u_hold (the logged command's
        value at rest replaced by the model's own holding command, so a valve's null offset
        does not read as a drift); ``none``: the logged command as it is.
    workers : int or None
        Threads running the model.
    reference_rates : {"auto", "difference", "zero"}
        Closed loop: the reference's velocity and acceleration the feed-forward laws (ffpd,
        smc) get: differences of the logged samples, or zero (a step's exact rates: a
        difference turns each jump into a spike the real controller never saw); ``auto``:
        zero when the reference is piecewise constant (it changes on at most 1 % of the
        samples), else differences.
    """

    def __init__(self, measurement: Any, plant: str, base: ServoParams, names: Sequence[str],
                 *, controller: Any = None, substep: float = 5.0e-4,
                 command_offset: str = "rest", workers: int | None = None,
                 reference_rates: str = "auto") -> None:
        plant_kind(plant)
        if not (isinstance(substep, float | int) and math.isfinite(substep) and substep > 0.0):
            raise ParameterError(f"substep must be finite and > 0 s, got {substep!r}")
        if reference_rates not in ("auto", "difference", "zero"):
            raise ParameterError(f"reference_rates must be 'auto', 'difference' or 'zero', "
                                 f"got {reference_rates!r}")
        if command_offset not in ("rest", "none"):
            raise ParameterError(f"command_offset must be 'rest' or 'none', got "
                                 f"{command_offset!r}")
        self.m = measurement
        self.plant = plant
        self.base = base
        self.names = tuple(names)
        self.controller = controller
        self.substep = float(substep)
        self.command_offset = command_offset
        # writable copies: a read-only array (a Measurement's are) is another type to the
        # compiled loops, which would compile a second time for it
        self.t = np.array(measurement.t, dtype=np.float64)
        self.dt = float(measurement.dt)
        rest = max(1, int(getattr(measurement, "rest", 1)))
        self.position = total(np.asarray(measurement.y[:rest], dtype=np.float64)) / rest
        stroke = base.cylinder.stroke
        if not 0.0 < self.position < stroke:
            raise InputError(
                f"the logged position at rest, {self.position:.6g} m, is outside the stroke "
                f"(0, {stroke:g}) m of the model: positions are measured from the retracted "
                f"end; give the offset (--position-offset M)")
        if controller is None:
            if measurement.u is None:
                raise InputError("open-loop identification needs the logged command (a column "
                                 "u); for closed-loop data name the controller (--controller, "
                                 "--gains) and log the reference r")
            self.u_rest = total(np.asarray(measurement.u[:rest], dtype=np.float64)) / rest
        else:
            if measurement.r is None:
                raise InputError("closed-loop identification needs the logged reference (a "
                                 "column r)")
            if abs(float(controller.dt) - self.dt) > 1e-9 * self.dt:
                raise ParameterError(f"the controller's sample time {controller.dt!r} s differs "
                                     f"from the data's {self.dt!r} s")
            self.u_rest = 0.0
            r = np.array(measurement.r, dtype=np.float64)
            self.r = r
            self.rates_rule = reference_rates
            if reference_rates == "auto":  # steps (piecewise constant): the exact rates, 0
                moving = int(np.count_nonzero(np.diff(r)))
                self.rates_rule = "zero" if moving <= max(1, r.size // 100) else "difference"
            self.rates = (rates_of(r, self.t) if self.rates_rule == "difference"
                          else (np.zeros(r.size), np.zeros(r.size)))
        self.workers = workers or max(1, os.cpu_count() or 1)
        self.n_runs = 0
        self._pool: ThreadPoolExecutor | None = None

    def params_at(self, theta: FloatArray) -> ServoParams:
        """The parameter set with the fitted fields at ``theta`` [SI] (may raise
        ParameterError)."""
        return with_overrides(self.base, {n: float(v) for n, v in
                                          zip(self.names, theta, strict=True)})

    def channels_of(self) -> tuple[str, ...]:
        """The signals this model has among the ones logged."""
        out = ["y"]
        has_p = self.plant != "linear"
        for c in ("p_f", "p_n"):
            if has_p and getattr(self.m, c, None) is not None:
                out.append(c)
        return tuple(out)

    def run(self, theta: FloatArray) -> dict[str, FloatArray] | None:
        """The traces of the model at ``theta`` [SI], or None when it cannot be run (invalid
        parameters, no equilibrium at the start position, divergence)."""
        try:
            params = self.params_at(theta)
            plant = build_plant(self.plant, params, self.position, substep=self.substep)
            delay = params.delay.transport_delay
            if self.controller is None:
                u = np.asarray(self.m.u, dtype=np.float64)
                if self.command_offset == "rest":
                    u = u - self.u_rest + plant.u0
                sched = np.clip(u, -1.0, 1.0)
                raw = run_loop(CommandSchedule(dt=self.dt), plant, np.ascontiguousarray(sched),
                               delay=delay, disturbance=None, noise=np.empty(0), t=self.t,
                               what="open loop")
            else:
                raw = run_loop(self.controller, plant,
                               self.r, delay=delay,
                               disturbance=None, noise=np.empty(0), t=self.t,
                               rates=self.rates)
        except (FuzzyServoError, ValueError, ArithmeticError):
            return None
        finally:
            self.n_runs += 1
        names = plant.state_names
        out = {"y": raw.y}
        for c in ("p_f", "p_n"):
            if c in names:
                out[c] = raw.x[:, names.index(c)]
        if not all(np.all(np.isfinite(v)) for v in out.values()):
            return None
        return out

    def run_many(self, thetas: Sequence[FloatArray]) -> list[dict[str, FloatArray] | None]:
        """:meth:`run` of each vector, on the thread pool."""
        if len(thetas) == 1 or self.workers == 1:
            return [self.run(th) for th in thetas]
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=self.workers)
        return list(self._pool.map(self.run, thetas))

    def close(self) -> None:
        """Stop the thread pool."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None


class _Problem:
    """Weighted residuals in the fitted coordinates z, with a batched Jacobian."""

    def __init__(self, runner: ModelRunner, lo: FloatArray, hi: FloatArray,
                 channels: tuple[str, ...], data: dict[str, FloatArray], used: FloatArray,
                 sigma: dict[str, float]) -> None:
        self.runner = runner
        #: open loop: compare the position up to a constant (see :func:`identify`)
        self.offset = runner.controller is None
        self.log = lo > 0.0
        self.scale = np.where(self.log, 1.0, np.maximum(np.abs(hi), 1e-300))
        self.channels = channels
        self.data = data
        self.used = used
        self.sigma = sigma
        #: a trace farther than this from the data is a run gone off (a failure) [SI]
        self.far = {c: 1e6 * max(float(np.max(np.abs(data[c][used]))), 1e-300)
                    for c in channels}
        self._cache: tuple[bytes, FloatArray] | None = None
        self.tick: Callable[[float], None] | None = None  #: told each new cost
        self.zlo = self.to_z(lo)
        self.zhi = self.to_z(hi)

    # element by element with the C library's log and exp, as the compiled kernels use them
    # (numpy's vector exp and log round differently on AVX-512 processors)
    def to_z(self, theta: FloatArray) -> FloatArray:
        return np.array([math.log(max(float(v), 1e-300)) if lg else float(v) / float(sc)
                         for v, lg, sc in zip(theta, self.log, self.scale, strict=True)])

    def to_theta(self, z: FloatArray) -> FloatArray:
        return np.array([math.exp(float(v)) if lg else float(v) * float(sc)
                         for v, lg, sc in zip(z, self.log, self.scale, strict=True)])

    def dtheta_dz(self, z: FloatArray) -> FloatArray:
        return np.array([math.exp(float(v)) if lg else float(sc)
                         for v, lg, sc in zip(z, self.log, self.scale, strict=True)])

    def weighted(self, traces: dict[str, FloatArray] | None) -> FloatArray | None:
        """The weighted residuals of a run, or None for a run that failed or went far off
        the data (the search refuses such a point: its cost is infinite)."""
        if traces is None:
            return None
        parts = []
        for c in self.channels:
            res = traces[c][self.used] - self.data[c][self.used]
            if not bool(np.all(np.abs(res) <= self.far[c])):
                return None
            if c == "y" and self.offset:  # the start position's error, profiled out
                res = res - total(res) / res.size
            parts.append(res / self.sigma[c])
        return np.concatenate(parts)

    def residuals(self, z: FloatArray) -> FloatArray:
        key = np.asarray(z, dtype=np.float64).tobytes()
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        got = self.weighted(self.runner.run(self.to_theta(z)))
        m = int(np.count_nonzero(self.used)) * len(self.channels)
        res = np.full(m, np.inf) if got is None else got
        self._cache = (key, res)
        if self.tick is not None:
            self.tick(0.5 * sum_of_squares(res))
        return res

    def jacobian(self, z: FloatArray) -> FloatArray:
        z = np.asarray(z, dtype=np.float64)
        p = z.size
        h = np.full(p, _FD_STEP)
        zs: list[FloatArray] = []
        for i in range(p):
            for sgn in (1.0, -1.0):
                zz = z.copy()
                zz[i] += sgn * h[i]
                zs.append(zz)
        runs = self.runner.run_many([self.to_theta(zz) for zz in zs])
        f0 = self.residuals(z)
        jac = np.empty((f0.size, p))
        for i in range(p):
            a, b = self.weighted(runs[2 * i]), self.weighted(runs[2 * i + 1])
            if a is not None and b is not None:
                jac[:, i] = (a - b) / (2.0 * h[i])
            elif a is not None:  # one-sided where the other side cannot be run
                jac[:, i] = (a - f0) / h[i]
            elif b is not None:
                jac[:, i] = (f0 - b) / h[i]
            else:
                jac[:, i] = 0.0
        return jac


def _solve(problem: _Problem, z0: FloatArray, max_nfev: int) -> tuple[FloatArray, float, str]:
    """One bounded search from ``z0`` (:func:`fuzzyservo.identify.lsq.levenberg_marquardt`:
    no BLAS or LAPACK, the same bits on every machine): the end point, its cost and why the
    search stopped."""
    z0 = np.clip(z0, problem.zlo, problem.zhi)
    sol = levenberg_marquardt(problem.residuals, problem.jacobian, z0, problem.zlo,
                              problem.zhi, max_nfev=max_nfev, ftol=1e-10, xtol=1e-10)
    return np.asarray(sol.x, dtype=np.float64), float(sol.cost), sol.status


def _covariance(problem: _Problem, z: FloatArray) -> tuple[FloatArray, float, FloatArray]:
    """Covariance of z, s² (JᵀJ)⁺, the reduced chi-square s², and the unit vectors of the
    directions the data do not determine (rows): along them the variance is unbounded
    (:func:`fuzzyservo.identify.lsq.covariance`)."""
    f = problem.residuals(z)
    jac = problem.jacobian(z)
    m, p = jac.shape
    dof = max(1, m - p - (1 if problem.offset and "y" in problem.channels else 0))
    return covariance(jac, f, dof)


def identify(
    measurement: Any,
    *,
    plant: str,
    params: ServoParams,
    fit: Sequence[str],
    bounds: Mapping[str, tuple[float, float]] | None = None,
    controller: Any = None,
    substep: float = 5.0e-4,
    command_offset: str = "rest",
    reference_rates: str = "auto",
    channels: Sequence[str] | None = None,
    settings: FitSettings | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    resume: FloatArray | None = None,
    checkpoint: Callable[[FloatArray], None] | None = None,
) -> Identification:
    """Fit the named fields of ``params`` to a logged experiment.

    Parameters
    ----------
    measurement : Measurement
        The experiment (:func:`fuzzyservo.identify.read_measurement` or
        :func:`~fuzzyservo.identify.measurement_from_arrays`): position ``y`` [m] from the
        retracted end, command ``u`` [-] (open loop) or reference ``r`` [m] (closed loop),
        chamber pressures ``p_f``, ``p_n`` [Pa] when logged.
    plant : str
        The model: ``nonlinear``, ``small-signal`` or ``linear`` (registry name).
    params : ServoParams
        The parameter set: the starting values of the fitted fields and every other field.
    fit : sequence of str
        Fields to fit, ``group.field`` (``load.mass``, ``fluid.oil_bulk_modulus``, ...).
    bounds : mapping, optional
        ``{name: (lo, hi)}`` search interval of a field [SI]; default
        :func:`default_bounds` (a decade either side of the set's value).
    controller : LawController, optional
        Closed loop: the controller that ran the axis (its ``dt`` the data's sample time).
    substep : float
        RK4 step bound of the nonlinear plant [s].
    command_offset : {"rest", "none"}
        See :class:`ModelRunner`.
    reference_rates : {"auto", "difference", "zero"}
        Closed loop: the reference's rates for feed-forward laws; see :class:`ModelRunner`.
    channels : sequence of str, optional
        Signals to compare (``y``, ``p_f``, ``p_n``); default every one logged that the model
        has.
    settings : FitSettings, optional
        Starts, seed, bootstrap, threads.
    progress : callable, optional
        ``progress(stage, done, total)``: called as starts and bootstrap refits finish
        (``stage`` "starts" or "bootstrap"), and with ``total`` 0 at every new cost of the
        search (``stage`` names the search and the cost, ``done`` counts the model runs).
    resume : array (k, p), optional
        The first k bootstrap estimates of an interrupted run with the same data and
        settings [SI]: they are kept and the bootstrap goes on from refit k (each refit draws
        from its own generator, so the result is the uninterrupted run's, bit for bit).
    checkpoint : callable, optional
        ``checkpoint(done)`` with the bootstrap estimates so far (k, p), after each refit:
        where the caller saves them for ``resume``.

    Returns
    -------
    Identification

    Raises
    ------
    ParameterError
        Unknown or repeated names or channels, bad bounds, a bad substep or option, bad
        settings. (A starting value outside its bounds is moved onto the nearer bound.)
    InputError
        Data that cannot identify anything: no command or reference, a start position
        outside the stroke, too short for the model's dynamics, or a model that cannot be
        run at the starting values.
    """
    cfg = settings or FitSettings()
    names = check_names(fit)
    runner = ModelRunner(measurement, plant, params, names, controller=controller,
                         substep=substep, command_offset=command_offset, workers=cfg.workers,
                         reference_rates=reference_rates)
    try:
        return _identify(measurement, runner, params, names, bounds or {}, channels, cfg,
                         progress, resume, checkpoint)
    finally:
        runner.close()


def _bounds(names: tuple[str, ...], theta0: FloatArray,
            given: Mapping[str, tuple[float, float]]) -> tuple[FloatArray, FloatArray]:
    for key in given:
        if key not in names:
            raise ParameterError(f"--bounds names {key!r}, which is not fitted; fitted: "
                                 f"{', '.join(names)}")
    lo = np.empty(len(names))
    hi = np.empty(len(names))
    for i, n in enumerate(names):
        if n in given:
            a, b = (float(v) for v in given[n])
            if not (math.isfinite(a) and math.isfinite(b) and a < b):
                raise ParameterError(f"bounds of {n} must be finite with LO < HI, got "
                                     f"{a!r}:{b!r}")
        else:
            a, b = default_bounds(n, float(theta0[i]))
        lo[i], hi[i] = a, b
    return lo, hi


def _identify(m: Any, runner: ModelRunner, params: ServoParams, names: tuple[str, ...],
              given_bounds: Mapping[str, tuple[float, float]],
              channels: Sequence[str] | None, cfg: FitSettings,
              progress: Callable[[str, int, int], None] | None,
              resume: FloatArray | None = None,
              checkpoint: Callable[[FloatArray], None] | None = None) -> Identification:
    flat = {n: float(getattr(getattr(params, n.split(".")[0]), n.split(".")[1])) for n in names}
    theta0 = np.array([flat[n] for n in names])
    lo, hi = _bounds(names, theta0, given_bounds)
    have = runner.channels_of()
    if channels is None:
        chans = have
    else:
        chans = tuple(channels)
        if not chans:
            raise ParameterError(f"channels names no signal; give one or more of "
                                 f"{', '.join(have)}")
        for c in chans:
            if chans.count(c) > 1:
                raise ParameterError(f"channels names {c!r} twice (it would count twice); "
                                     f"name each signal once")
            if c not in have:
                raise InputError(f"cannot fit channel {c!r}: the data and the {runner.plant} "
                                 f"model have {', '.join(have)}")
    notes: list[str] = []
    if runner.controller is not None and runner.controller.law.feedforward:
        notes.append(f"the reference's rates for the feed-forward: {runner.rates_rule} "
                     f"(--reference-rates)")
    if runner.plant == "linear" and any(getattr(m, c, None) is not None for c in ("p_f", "p_n")):
        notes.append("the linear plant (eq. 8) has no chamber pressures: fitted on the position "
                     "only (use --plant small-signal or nonlinear to use them)")
    lin = linearize(params, runner.position)
    period = 2.0 * math.pi / lin.omega_0
    rest = max(1, int(getattr(m, "rest", 1)))
    excited = float(m.t[-1] - m.t[min(rest, m.t.size - 1)])
    if excited < MIN_PERIODS * period:
        raise InputError(
            f"the data are too short for the fitted dynamics: {excited:.4g} s of excitation, "
            f"at least {MIN_PERIODS:g} hydraulic periods (2 pi/omega_0 = {period:.4g} s at "
            f"the start position) = {MIN_PERIODS * period:.4g} s needed")
    data = {c: np.ascontiguousarray(getattr(m, c), dtype=np.float64) for c in chans}
    flagged = getattr(m, "flagged", None)
    used = np.ones(m.t.size, dtype=bool) if flagged is None else ~np.asarray(flagged, bool)
    if not float(np.ptp(np.asarray(m.y, dtype=np.float64)[used])) > 0.0:
        raise InputError(f"the logged position never moves (always {float(m.y[0]):.6g} m) "
                         f"while the {'command' if runner.controller is None else 'reference'}"
                         f" does: a dead sensor or the wrong column (--columns y=NAME); "
                         f"nothing to fit")
    sigma: dict[str, float] = {}
    for c in chans:
        rng_c = float(np.ptp(data[c][used])) or 1.0
        sigma[c] = max(noise_level(data[c][used]), 1e-9 * rng_c)
    theta_start = np.clip(theta0, lo, hi)
    start_traces = runner.run(theta_start)
    if start_traces is None:
        shown = ", ".join(f"{n} = {v:.6g}" for n, v in zip(names, theta_start, strict=True))
        raise InputError(f"the {runner.plant} model cannot be run with the starting values "
                         f"({shown}): "
                         f"no equilibrium at {runner.position:.6g} m or a divergence; check "
                         f"the parameter set and the data's position")
    prob = _Problem(runner, lo, hi, chans, data, used, sigma)
    stage = ["start 1"]

    def tick(cost: float) -> None:
        if progress is not None:
            progress(f"{stage[0]}: cost {cost:.6g}", runner.n_runs, 0)

    prob.tick = tick
    rng = np.random.default_rng([cfg.seed, 27])
    z_starts = [prob.to_z(theta_start)]
    for _ in range(cfg.starts - 1):
        z_starts.append(prob.zlo + rng.random(len(names)) * (prob.zhi - prob.zlo))
    results = []
    for i, z0 in enumerate(z_starts):
        stage[0] = f"start {i + 1}/{len(z_starts)}"
        results.append(_solve(prob, z0, cfg.max_nfev))
        if progress is not None:
            progress("starts", i + 1, len(z_starts))
    costs = np.array([c for _, c, _ in results])
    best = int(np.argmin(costs))
    z_best = results[best][0]
    th_best = prob.to_theta(z_best)
    spread = 0.0  # over the starts that reached the best cost (to 1e-3): how flat it is
    worse = short = 0
    for z, cost_i, status in results:
        if cost_i > costs[best] * (1.0 + 1e-3) + 1e-300:
            if status == "max_nfev":
                short += 1
            else:
                worse += 1
            continue
        spread = max(spread, float(np.max(np.abs(prob.to_theta(z) - th_best)
                                          / np.maximum(np.abs(th_best), 1e-300))))
    if worse:
        notes.append(f"{worse} of {len(results)} starts ended in a worse local minimum; the "
                     f"best was kept")
    if short:
        notes.append(f"{short} of {len(results)} starts had not converged after "
                     f"{cfg.max_nfev} evaluations (max_nfev) and ended above the best")
    if results[best][2] == "max_nfev":
        notes.append(f"the best search had not converged after {cfg.max_nfev} evaluations: "
                     f"raise max_nfev, or start nearer (--params)")
    if cfg.reweight:
        fitted = runner.run(th_best)
        if fitted is not None:
            for c in chans:
                res = fitted[c][used] - data[c][used]
                if c == "y" and prob.offset:
                    res = res - total(res) / res.size
                sigma[c] = max(math.sqrt(sum_of_squares(res) / res.size), 1e-12 * sigma[c],
                               1e-300)
            prob = _Problem(runner, lo, hi, chans, data, used, sigma)
            stage[0] = "re-weighted"
            prob.tick = tick
            z_best, _, _ = _solve(prob, z_best, cfg.max_nfev)
            th_best = prob.to_theta(z_best)
    cov_z, s2, null = _covariance(prob, z_best)
    d = prob.dtheta_dz(z_best)
    cov = cov_z * np.outer(d, d)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    for vec in null:  # undetermined along vec: unbounded errors, moving together along it
        on = np.abs(vec) > 1e-6
        se[on] = np.inf
        both = np.outer(on, on)
        corr = np.where(both, np.sign(np.outer(vec, vec)), corr)
    np.fill_diagonal(corr, 1.0)
    fitted = runner.run(th_best)
    if fitted is None:  # the optimum was run above; a failure here would be a bug
        raise InputError("the identified model cannot be run")
    offset = 0.0
    if prob.offset and "y" in chans:
        offset = total(data["y"][used] - fitted["y"][used]) / int(used.sum())
        fitted = dict(fitted, y=fitted["y"] + offset)
        start_traces = dict(start_traces, y=start_traces["y"] + total(
            data["y"][used] - start_traces["y"][used]) / int(used.sum()))
        notes.append(f"the logged position is compared up to a constant, fitted with the "
                     f"parameters: {offset * 1e6:+.3g} µm (the start position taken from the "
                     f"noisy rest samples)")
    at_bound = [n for n, v, a, b in zip(names, th_best, lo, hi, strict=True)
                if v <= a + 1e-6 * (b - a) or v >= b - 1e-6 * (b - a)]
    undetermined_names = {names[k] for vec in null for k in np.flatnonzero(np.abs(vec) > 1e-6)}
    for n in at_bound:
        if n in undetermined_names:
            continue  # its warning says it: the data do not move it
        notes.append(f"{n} ended on a bound of its search interval: widen --bounds {n}=LO:HI "
                     f"or check the model")
    interval = None
    boot = None
    if cfg.bootstrap > 0:
        boot = _bootstrap(prob, runner, fitted, z_best, cfg, period, progress, resume,
                          checkpoint)
        ok = np.all(np.isfinite(boot), axis=1)
        a = (1.0 - cfg.level) / 2.0
        interval = np.quantile(boot[ok], [a, 1.0 - a], axis=0).T if np.any(ok) else None
        if cfg.bootstrap < 20:
            notes.append(f"the {100 * cfg.level:g} % intervals are percentiles of only "
                         f"{cfg.bootstrap} refits, close to their extremes: take 200 or more "
                         f"(--bootstrap) for intervals to rely on")
        if not np.all(ok):
            notes.append(f"{int(np.count_nonzero(~ok))} of {cfg.bootstrap} bootstrap refits "
                         f"failed and were left out")
    rms = {c: math.sqrt(sum_of_squares(fitted[c][used] - data[c][used]) / int(used.sum()))
           for c in chans}
    from .advice import identifiability_warnings

    identified = runner.params_at(th_best)
    try:  # the advice speaks of the identified axis's frequencies
        omega_0 = linearize(identified, runner.position).omega_0
    except (FuzzyServoError, ValueError, ArithmeticError):
        omega_0 = lin.omega_0
    excitation = m.u if runner.controller is None else m.r
    warns = identifiability_warnings(
        names, th_best, se, corr, channels=chans, omega_0=omega_0,
        omega_v=identified.valve.omega_v,
        excited=excited_band(np.asarray(excitation, dtype=np.float64), runner.dt),
        undetermined=[tuple(int(k) for k in np.flatnonzero(np.abs(vec) > 1e-6))
                      for vec in null])
    return Identification(
        names=names, units=tuple(field_unit(n) for n in names), initial=theta0,
        estimate=th_best, std_error=se, correlation=corr, bounds=np.column_stack([lo, hi]),
        interval=interval, level=float(cfg.level), bootstrap=boot,
        params=runner.params_at(th_best), base=params, plant=runner.plant,
        mode="open loop" if runner.controller is None else "closed loop",
        position=runner.position, t=np.asarray(m.t, dtype=np.float64), channels=chans,
        measured=data, fitted={c: fitted[c] for c in chans},
        start_fit={c: start_traces[c] for c in chans}, used=used, sigma=dict(sigma),
        residual_rms=rms, chi2=s2, start_costs=costs, start_spread=spread,
        n_runs=runner.n_runs, warnings=tuple(warns), notes=tuple(notes))


def _bootstrap(prob: _Problem, runner: ModelRunner, fitted: dict[str, FloatArray],
               z_best: FloatArray, cfg: FitSettings, period: float,
               progress: Callable[[str, int, int], None] | None,
               resume: FloatArray | None = None,
               checkpoint: Callable[[FloatArray], None] | None = None) -> FloatArray:
    """Refits to the fitted traces plus moving blocks of the residuals (the same blocks for
    every channel), each from the estimate; replicate i draws from its own generator
    (seed, i), so the result does not depend on the order the refits run in, and a run
    resumed from its first k estimates (``resume``) equals the uninterrupted one."""
    used = prob.used
    idx_used = np.flatnonzero(used)
    m = idx_used.size
    block = cfg.block or max(10, int(round(2.0 * period / runner.dt)))
    block = min(block, m)
    res = {c: prob.data[c] - fitted[c] for c in prob.channels}
    out = np.full((cfg.bootstrap, z_best.size), np.nan)
    first = 0
    if resume is not None and resume.size:
        prev = np.asarray(resume, dtype=np.float64)
        if prev.ndim != 2 or prev.shape[1] != z_best.size or prev.shape[0] > cfg.bootstrap:
            raise InputError(f"cannot resume the bootstrap: the saved estimates have shape "
                             f"{prev.shape}, this run needs at most ({cfg.bootstrap}, "
                             f"{z_best.size})")
        first = prev.shape[0]
        out[:first] = prev
        if progress is not None:
            progress("bootstrap", first, cfg.bootstrap)
    for i in range(first, cfg.bootstrap):
        g = np.random.default_rng([cfg.seed, 2700, i])
        n_blocks = -(-m // block)
        starts = g.integers(0, m - block + 1, size=n_blocks)
        take = (starts[:, None] + np.arange(block)[None, :]).ravel()[:m]
        data_b = {}
        for c in prob.channels:
            d = prob.data[c].copy()
            d[idx_used] = fitted[c][idx_used] + res[c][idx_used][take]
            data_b[c] = d
        pb = _Problem(runner, prob.to_theta(prob.zlo), prob.to_theta(prob.zhi), prob.channels,
                      data_b, used, prob.sigma)
        try:
            z, _, _ = _solve(pb, z_best, cfg.max_nfev)
            out[i] = pb.to_theta(z)
        except (ValueError, ArithmeticError):
            pass
        if checkpoint is not None:
            checkpoint(out[:i + 1].copy())
        if progress is not None:
            progress("bootstrap", i + 1, cfg.bootstrap)
    return out
