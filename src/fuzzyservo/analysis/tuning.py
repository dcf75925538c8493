"""Automatic step-response tuning: the paper's own method, made systematic.

The paper tunes by "repeatedly performing the step response ... the program evaluated the
performance error, altered the gains and repeated the step response test until the best
performing gains were determined" (Sec. III). Here the step response is the batched closed-loop
simulator, the performance error is IAE, ITAE or ISE, the constraints are penalties on
overshoot, steady-state error and max |u|, and the search is differential evolution
(best/1/bin with dither, as scipy's default), evaluating a whole population per call, until a
stated stopping rule says it has converged, followed by a bounded Nelder-Mead polish.

The search is our own short loop rather than scipy's ``differential_evolution`` so that its
whole state (population, costs, random generator, history of the best cost) is a value,
:class:`SearchState`: a run interrupted after any generation and resumed from that state
gives the same result, bit for bit, as the run that was not interrupted.

This module is independent of the simulator: it takes a function that maps a population of
gain vectors to step metrics. It does no I/O; progress and checkpoints go through callbacks.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from scipy.optimize import minimize

from .._typing import FloatArray
from ..errors import ParameterError

__all__ = [
    "DEFAULT_PATIENCE",
    "DEFAULT_RTOL",
    "DEFAULT_SPREAD",
    "FINAL_ERROR",
    "INFEASIBLE_STEP",
    "OBJECTIVES",
    "ZERO_DECADES",
    "GainBounds",
    "SearchState",
    "StopRule",
    "TuningConstraints",
    "TuningResult",
    "constraint_violation",
    "penalised_cost",
    "tune",
]

Objective = Literal["iae", "itae", "ise"]
#: Objectives the tuner accepts; each is a column of the metrics returned by the evaluator.
OBJECTIVES: tuple[str, ...] = ("iae", "itae", "ise")

#: Metric an evaluator may return besides the step metrics: the largest |r - y| over the last
#: 10 % of the run (``SETTLE_HOLD_FRACTION``) [unit of y]. When present, the steady-state
#: error constraint uses it instead of the error at the last sample, which for a response
#: with a small sustained oscillation depends on the oscillation's phase at the last sample
#: and makes the cost jump between neighbouring gains (docs/model.md, "Tuning").
FINAL_ERROR = "final_error_max"

#: Cost given to a run whose metrics are not finite (diverged, never settled).
_INFEASIBLE = 1.0e6
#: Weight of one unit of normalised constraint violation, in units of the normalised objective.
_PENALTY = 100.0
#: Cost added to any violation, however small [units of the normalised objective]: with the
#: L1 penalty alone the optimum sits on a constraint's boundary and the search could end a
#: hair on its infeasible side (an overshoot of 0.50000001 % against a 0.5 % limit); the step
#: makes every feasible neighbour cheaper.
INFEASIBLE_STEP = 1e-3

#: Width of the "zero" region of a gain that may be 0 [decades of its log scale]: the search
#: coordinate extends this far below log10(lower), and every value there means the gain is 0.
ZERO_DECADES = 1.0

#: An evaluator maps gains (n, k) to a mapping metric name -> values (n,).
Evaluator = Callable[[FloatArray], Mapping[str, FloatArray]]


@dataclass(frozen=True, slots=True, kw_only=True)
class GainBounds:
    """Search box for the gains.

    Parameters
    ----------
    names : tuple of str
        Gain names in the order the evaluator expects them (e.g. ``("kp", "ki", "kd")``).
    lower, upper : tuple of float
        Bounds of each gain, in the gain's own unit (the controller's documentation gives it).
    log_scale : tuple of bool
        Search this gain on a logarithmic scale (bounds must then be positive).
    zero : tuple of bool
        The gain may also be exactly 0 (log-scale gains only): the search coordinate extends
        :data:`ZERO_DECADES` below log10(``lower``) and every value there is the gain 0, so
        a search can switch a term off (a PID's ki or kd) instead of stopping at its smallest
        positive value.
    """

    names: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    log_scale: tuple[bool, ...] = ()
    zero: tuple[bool, ...] = ()

    def __post_init__(self) -> None:
        k = len(self.names)
        if k == 0:
            raise ParameterError("GainBounds needs at least one gain name")
        log = self.log_scale or (False,) * k
        object.__setattr__(self, "log_scale", tuple(bool(v) for v in log))
        object.__setattr__(self, "zero", tuple(bool(v) for v in (self.zero or (False,) * k)))
        for label, seq in (("lower", self.lower), ("upper", self.upper),
                           ("log_scale", self.log_scale), ("zero", self.zero)):
            if len(seq) != k:
                raise ParameterError(
                    f"GainBounds.{label} has {len(seq)} entries for {k} gain names {self.names}")
        for name, lo, hi, lg in zip(self.names, self.lower, self.upper, self.log_scale,
                                    strict=True):
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ParameterError(
                    f"bounds of gain {name!r} must be finite with lower < upper, got [{lo}, {hi}]")
            if lo < 0.0:
                raise ParameterError(f"lower bound of gain {name!r} must be >= 0, got {lo}")
            if lg and lo <= 0.0:
                raise ParameterError(
                    f"gain {name!r} is searched on a log scale, so its lower bound must be > 0,"
                    f" got {lo}")
        for name, lg, zr in zip(self.names, self.log_scale, self.zero, strict=True):
            if zr and not lg:
                raise ParameterError(f"gain {name!r} may be 0 only on a log scale (a linear "
                                     f"scale reaches 0 with lower = 0)")

    def _ends(self) -> tuple[FloatArray, FloatArray]:
        """Search coordinates of the box's ends (log10 where ``log_scale``; the zero region
        below the lower end where ``zero``)."""
        lo = np.array(self.lower, dtype=np.float64)
        hi = np.array(self.upper, dtype=np.float64)
        log = np.asarray(self.log_scale)
        zlo = np.where(log, np.log10(np.where(log, lo, 1.0)), lo)
        zhi = np.where(log, np.log10(np.where(log, hi, 1.0)), hi)
        return zlo - np.where(np.asarray(self.zero), ZERO_DECADES, 0.0), zhi

    def to_unit(self, gains: FloatArray) -> FloatArray:
        """Map gains (..., k) into the unit cube the search runs in (a gain of 0 that may be
        0 maps to the middle of its zero region); values outside the box are clipped."""
        z = self.to_search(gains)
        zero = np.asarray(self.zero) & (np.asarray(gains, dtype=np.float64) <= 0.0)
        zlo, zhi = self._ends()
        z = np.where(zero, zlo + 0.5 * ZERO_DECADES, z)
        return np.clip((z - zlo) / (zhi - zlo), 0.0, 1.0)

    def from_unit(self, u: FloatArray) -> FloatArray:
        """Map unit-cube points (..., k) to gains (0 in a zero region)."""
        zlo, zhi = self._ends()
        z = zlo + np.asarray(u, dtype=np.float64) * (zhi - zlo)
        g = self.from_search(z)
        off = np.asarray(self.zero) & (z < zlo + ZERO_DECADES)
        return np.where(off, 0.0, g)

    def at_bounds(self, gains: FloatArray, rel: float = 1e-3) -> dict[str, str]:
        """Gains of one vector that end on a bound: ``{name: "lower"|"upper"}``; on a bound
        means within ``rel`` of the search range of that end (or exactly 0 for a gain that
        may be 0: its lower bound)."""
        g = np.asarray(gains, dtype=np.float64).reshape(-1)
        zlo, zhi = self._ends()
        zlo = zlo + np.where(np.asarray(self.zero), ZERO_DECADES, 0.0)
        z = self.to_search(g)
        out: dict[str, str] = {}
        for i, name in enumerate(self.names):
            span = zhi[i] - zlo[i]
            if self.zero[i] and g[i] <= 0.0:
                out[name] = "lower"
            elif z[i] <= zlo[i] + rel * span and not self.zero[i]:
                out[name] = "lower"
            elif z[i] >= zhi[i] - rel * span:
                out[name] = "upper"
        return out

    def lowest(self) -> tuple[float, ...]:
        """The smallest value of each gain: 0 where the gain may be 0, else ``lower``."""
        return tuple(0.0 if z else lo for z, lo in zip(self.zero, self.lower, strict=True))

    def to_search(self, gains: FloatArray) -> FloatArray:
        """Map gains (..., k) to the search coordinates (log10 where ``log_scale``)."""
        g = np.asarray(gains, dtype=np.float64)
        return np.where(np.asarray(self.log_scale), np.log10(np.maximum(g, 1e-300)), g)

    def from_search(self, z: FloatArray) -> FloatArray:
        """Map search coordinates (..., k) back to gains."""
        z = np.asarray(z, dtype=np.float64)
        return np.where(np.asarray(self.log_scale), 10.0 ** z, z)

    def search_bounds(self) -> list[tuple[float, float]]:
        """Bounds in search coordinates, as scipy expects them."""
        lo = self.to_search(np.asarray(self.lower))
        hi = self.to_search(np.asarray(self.upper))
        return [(float(a), float(b)) for a, b in zip(lo, hi, strict=True)]


@dataclass(frozen=True, slots=True, kw_only=True)
class TuningConstraints:
    """Constraints on the step response; ``None`` switches one off.

    Parameters
    ----------
    max_overshoot : float or None
        Largest allowed overshoot [%].
    max_steady_state_error : float or None
        Largest allowed |steady-state error| as a fraction of the step size [-].
    max_u : float or None
        Largest allowed max |u| [unit command].
    require_settled : bool
        Whether the response must settle in the 2 % band within the horizon.
    """

    max_overshoot: float | None = 10.0
    max_steady_state_error: float | None = 0.002
    max_u: float | None = None
    require_settled: bool = True

    def __post_init__(self) -> None:
        for name in ("max_overshoot", "max_steady_state_error", "max_u"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v >= 0.0):
                raise ParameterError(f"TuningConstraints.{name} must be >= 0, got {v}")

    @classmethod
    def from_limits(cls, *, max_overshoot: float | None, max_sse_percent: float | None,
                    max_u: float | None) -> TuningConstraints:
        """The constraints as ``fuzzyservo tune`` and the browser page take them: overshoot
        [%], |steady-state error| in percent of the step [%], max |u| [-]; each checked
        with the message naming its command-line flag.

        Raises
        ------
        ParameterError
            A limit that is not a finite number >= 0.
        """
        for name, value in (("--max-overshoot", max_overshoot), ("--max-sse", max_sse_percent),
                            ("--max-u", max_u)):
            if value is not None and not (math.isfinite(value) and value >= 0.0):
                raise ParameterError(f"{name} must be a finite number >= 0, got {value!r}")
        return cls(max_overshoot=max_overshoot,
                   max_steady_state_error=(None if max_sse_percent is None
                                           else max_sse_percent / 100.0),
                   max_u=max_u)


#: Default stopping rule: generations without a relative improvement above DEFAULT_RTOL.
DEFAULT_PATIENCE = 30
DEFAULT_RTOL = 1e-4
DEFAULT_SPREAD = 0.01


@dataclass(frozen=True, slots=True, kw_only=True)
class StopRule:
    """When a differential-evolution search has converged (docs/model.md, "Tuning").

    The search stops at generation g >= ``patience`` when the best cost improved by no more
    than ``rtol`` (relative) over the last ``patience`` generations,
    ``best[g - patience] - best[g] <= rtol * max(|best[g]|, 1e-12)``, and the population has
    gathered: its median cost is within ``spread`` (relative) of the best
    (a best that stalls while half the population is still far from it is a search stuck
    on a rough landscape, not a converged one); it then runs the polish. A search that
    reaches its generation limit first is reported as not converged.

    Parameters
    ----------
    patience : int
        Generations without a significant improvement before stopping (>= 1).
    rtol : float
        Relative improvement below which a generation does not count [-].
    spread : float
        Largest relative distance of the population's median cost from the best [-].
    """

    patience: int = DEFAULT_PATIENCE
    rtol: float = DEFAULT_RTOL
    spread: float = DEFAULT_SPREAD

    def __post_init__(self) -> None:
        if not (isinstance(self.patience, int) and self.patience >= 1):
            raise ParameterError(f"StopRule.patience must be an integer >= 1, got "
                                 f"{self.patience!r}")
        if not (math.isfinite(self.rtol) and 0.0 <= self.rtol < 1.0):
            raise ParameterError(f"StopRule.rtol must be in [0, 1), got {self.rtol!r}")
        if not (math.isfinite(self.spread) and self.spread >= 0.0):
            raise ParameterError(f"StopRule.spread must be finite and >= 0, got "
                                 f"{self.spread!r}")

    def converged(self, history: tuple[float, ...], costs: FloatArray) -> bool:
        """Whether a search whose best cost after each generation (index 0: the initial
        population) is ``history`` and whose members cost ``costs`` has converged."""
        g = len(history) - 1
        if g < self.patience:
            return False
        best, before = history[-1], history[-1 - self.patience]
        scale = max(abs(best), 1e-12)
        if before - best > self.rtol * scale:
            return False
        return float(np.median(costs)) - best <= self.spread * scale


@dataclass(frozen=True, slots=True, kw_only=True)
class SearchState:
    """Everything a differential-evolution search needs to go on, after a generation.

    A search resumed from a state gives the result the uninterrupted search gives, bit for
    bit (the population is kept in the search's own unit-cube coordinates, not in gains).

    Attributes
    ----------
    generation : int
        Generations completed (0: the initial population has been evaluated).
    population : ndarray (m, k)
        Members in unit-cube coordinates (:meth:`GainBounds.to_unit`).
    costs : ndarray (m,)
        Their penalised costs [-].
    rng_state : dict
        State of the search's numpy random generator (``bit_generator.state``).
    history : tuple of float
        Best cost after each generation, index 0 the initial population [-].
    n_evaluations : int
        Closed-loop runs so far.
    """

    generation: int
    population: FloatArray
    costs: FloatArray
    rng_state: dict[str, Any]
    history: tuple[float, ...]
    n_evaluations: int

    @property
    def best_cost(self) -> float:
        """The best cost so far [-]."""
        return float(self.history[-1])


@dataclass(frozen=True, slots=True, kw_only=True)
class TuningResult:
    """Outcome of :func:`tune`.

    Attributes
    ----------
    gains : dict
        Best gains found, by name.
    cost : float
        Penalised, normalised cost of ``gains`` (equal to the normalised objective when feasible).
    objective : str
        The objective minimised.
    objective_value : float
        Its raw value for ``gains`` (e.g. IAE [m s]).
    feasible : bool
        Whether ``gains`` meet every constraint.
    metrics : dict
        All metrics of the best run.
    n_evaluations : int
        Closed-loop runs evaluated.
    generations : int
        Differential-evolution generations completed.
    converged : bool
        Whether the stopping rule stopped the search (not the generation limit).
    at_bounds : dict
        Gains that end on a bound of the box, ``{name: "lower"|"upper"}``.
    history : tuple of float
        Best cost after each generation (index 0: the initial population).
    """

    gains: dict[str, float]
    cost: float
    objective: str
    objective_value: float
    feasible: bool
    metrics: dict[str, float]
    n_evaluations: int
    generations: int
    converged: bool = False
    at_bounds: dict[str, str] = field(default_factory=dict)
    history: tuple[float, ...] = field(default=())


def constraint_violation(metrics: Mapping[str, FloatArray], constraints: TuningConstraints,
                         step_size: float) -> FloatArray:
    """Normalised total violation of the constraints, 0 where all hold.

    Overshoot excess is counted in units of 10 %-points, the steady-state error excess in units
    of its limit (or of 0.1 % of the step), and the max |u| excess in units of its limit.
    Non-finite metrics a constraint needs count as a violation of 1 each.
    """
    n = np.asarray(next(iter(metrics.values()))).shape[0]
    v = np.zeros(n)
    if constraints.max_overshoot is not None:
        os_ = np.asarray(metrics["overshoot"], dtype=np.float64)
        os_ = np.where(np.isfinite(os_), os_, 0.0)  # never overshooting is not a violation
        v += np.maximum(os_ - constraints.max_overshoot, 0.0) / 10.0
    if constraints.max_steady_state_error is not None:
        err = metrics[FINAL_ERROR] if FINAL_ERROR in metrics else metrics["steady_state_error"]
        sse = np.abs(np.asarray(err, dtype=np.float64)) / step_size
        lim = max(constraints.max_steady_state_error, 1e-3)
        v += np.where(np.isfinite(sse),
                      np.maximum(sse - constraints.max_steady_state_error, 0.0) / lim, 1.0)
    if constraints.max_u is not None:
        um = np.asarray(metrics["u_max"], dtype=np.float64)
        v += np.where(np.isfinite(um), np.maximum(um - constraints.max_u, 0.0)
                      / max(constraints.max_u, 1e-9), 1.0)
    if constraints.require_settled:
        ts = np.asarray(metrics["settling_time"], dtype=np.float64)
        v += np.where(np.isfinite(ts), 0.0, 1.0)
    return v


def penalised_cost(metrics: Mapping[str, FloatArray], objective: str,
                   constraints: TuningConstraints, step_size: float) -> FloatArray:
    """Objective normalised by the step size, plus a penalty per unit of constraint violation.

    Normalising by |step| makes IAE a time [s], ITAE a time squared [s^2] and ISE a time times
    the step [s], so one penalty weight works across step sizes.
    """
    if objective not in OBJECTIVES:
        raise ParameterError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    j = np.asarray(metrics[objective], dtype=np.float64)
    j = j / (step_size ** 2 if objective == "ise" else step_size)
    v = constraint_violation(metrics, constraints, step_size)
    cost = j + _PENALTY * v + np.where(v > 0.0, INFEASIBLE_STEP, 0.0)
    return np.where(np.isfinite(cost), cost, _INFEASIBLE)


#: Differential-evolution constants (scipy's defaults): dithered mutation factor drawn per
#: generation from this range, and crossover probability.
MUTATION: tuple[float, float] = (0.5, 1.0)
RECOMBINATION = 0.7


def _latin_hypercube(rng: np.random.Generator, m: int, k: int) -> FloatArray:
    """m points in [0, 1)^k, one per stratum of each coordinate."""
    u = (rng.random((m, k)) + np.arange(m)[:, None]) / m
    for j in range(k):
        u[:, j] = u[rng.permutation(m), j]
    return u


def _generation(rng: np.random.Generator, pop: FloatArray, costs: FloatArray) -> FloatArray:
    """Trial vectors of one best/1/bin generation (dithered F, binomial crossover with one
    forced coordinate); a coordinate leaving [0, 1] is redrawn uniformly, as scipy does."""
    m, k = pop.shape
    f = rng.uniform(*MUTATION)
    best = pop[int(np.argmin(costs))]
    r = np.empty((m, 2), dtype=np.int64)
    for i in range(m):
        pick = rng.choice(m - 1, 2, replace=False)
        r[i] = pick + (pick >= i)
    mutant = best + f * (pop[r[:, 0]] - pop[r[:, 1]])
    cross = rng.random((m, k)) < RECOMBINATION
    cross[np.arange(m), rng.integers(0, k, size=m)] = True
    trial = np.where(cross, mutant, pop)
    bad = (trial < 0.0) | (trial > 1.0)
    if np.any(bad):
        trial[bad] = rng.random(int(np.count_nonzero(bad)))
    return trial


def tune(evaluate: Evaluator, bounds: GainBounds, *, objective: str = "itae",
         constraints: TuningConstraints | None = None, step_size: float,
         seed: int = 0, popsize: int = 10, maxiter: int = 400,
         stop: StopRule | None = None, polish: bool = True, init: FloatArray | None = None,
         resume: SearchState | None = None,
         on_generation: Callable[[SearchState], None] | None = None,
         ) -> TuningResult:
    """Minimise a step-response objective under constraints by differential evolution.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(gains)`` with ``gains`` of shape (n, k) returns a mapping from metric name to
        an array (n,), with at least the objective, ``overshoot``, ``steady_state_error``,
        ``settling_time`` and ``u_max``. It is called once per generation with the whole
        population (the batched simulator runs it in parallel).
    bounds : GainBounds
        Names and search box of the gains.
    objective : {"iae", "itae", "ise"}
        Integral criterion to minimise.
    constraints : TuningConstraints, optional
        Defaults to at most 10 % overshoot, 0.2 % steady-state error, settled within the run.
    step_size : float
        Size of the reference step, used to normalise the objective [m].
    seed : int
        Seed of the search's random generator (recorded with the result for reproducibility).
    popsize : int
        Population multiplier: ``max(5, popsize * k)`` members.
    maxiter : int
        Generation limit; the search normally stops earlier, by ``stop``.
    stop : StopRule, optional
        Convergence rule (default ``StopRule()``: no relative improvement above 1e-4 of the
        best cost over 30 generations).
    polish : bool
        Refine the best member with a bounded Nelder-Mead search afterwards.
    init : array (m, k), optional
        Initial population in gain units (m >= 5), instead of a Latin hypercube.
    resume : SearchState, optional
        Go on from this state (an interrupted run's last ``on_generation``): the result equals
        the uninterrupted run's bit for bit.
    on_generation : callable, optional
        ``on_generation(state)`` after the initial population (generation 0) and after every
        generation, for progress display and checkpoints.

    Returns
    -------
    TuningResult
    """
    constraints = constraints or TuningConstraints()
    stop = stop or StopRule()
    if not (math.isfinite(step_size) and step_size > 0.0):
        raise ParameterError(f"step_size must be a positive number of metres, got {step_size}")
    if objective not in OBJECTIVES:
        raise ParameterError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    k = len(bounds.names)

    def cost_of(u: FloatArray) -> FloatArray:
        metrics = evaluate(bounds.from_unit(np.atleast_2d(u)))
        return penalised_cost(metrics, objective, constraints, step_size)

    if resume is not None:
        if resume.population.ndim != 2 or resume.population.shape[1] != k:
            raise ParameterError(f"a search state for {k} gains needs a population with {k} "
                                 f"columns, got shape {resume.population.shape}")
        rng = np.random.default_rng(seed)
        rng.bit_generator.state = resume.rng_state
        state = resume
    else:
        rng = np.random.default_rng(seed)
        if init is not None:
            pop = bounds.to_unit(np.atleast_2d(np.asarray(init, dtype=np.float64)))
            if pop.shape[0] < 5:
                raise ParameterError(
                    f"an initial population needs at least 5 members, got {pop.shape[0]}")
        else:
            pop = _latin_hypercube(rng, max(5, popsize * k), k)
        costs = cost_of(pop)
        state = SearchState(generation=0, population=pop, costs=costs,
                            rng_state=dict(rng.bit_generator.state),
                            history=(float(np.min(costs)),), n_evaluations=pop.shape[0])
        if on_generation is not None:
            on_generation(state)
    while state.generation < maxiter and not stop.converged(state.history, state.costs):
        trial = _generation(rng, state.population, state.costs)
        tc = cost_of(trial)
        keep = tc <= state.costs
        pop = np.where(keep[:, None], trial, state.population)
        costs = np.where(keep, tc, state.costs)
        state = SearchState(generation=state.generation + 1, population=pop, costs=costs,
                            rng_state=dict(rng.bit_generator.state),
                            history=state.history + (float(np.min(costs)),),
                            n_evaluations=state.n_evaluations + trial.shape[0])
        if on_generation is not None:
            on_generation(state)
    converged = stop.converged(state.history, state.costs)
    n_eval = state.n_evaluations
    ib = int(np.argmin(state.costs))
    u_best, f_best = state.population[ib].copy(), float(state.costs[ib])
    if polish:
        count = [0]

        def scalar(u: FloatArray) -> float:
            count[0] += 1
            return float(cost_of(u)[0])

        pol = minimize(scalar, u_best, method="Nelder-Mead", bounds=[(0.0, 1.0)] * k,
                       options={"xatol": 1e-5, "fatol": 1e-6 * max(f_best, 1e-9),
                                "maxfev": 100 * k})
        n_eval += count[0]
        if float(pol.fun) < f_best:
            u_best, f_best = np.asarray(pol.x, dtype=np.float64), float(pol.fun)
    # parsimony: a term that may be 0 and whose removal costs no more than the stopping
    # rule's tolerance is switched off (ki = 1e-3 next to kp = 8.5 is a P controller)
    # (kept only if it stays feasible when the best was; its own cost is then reported)
    zlo, zhi = bounds._ends()
    best_feasible: bool | None = None
    for j in range(k):
        g_j = float(bounds.from_unit(u_best[None, :])[0, j])
        if bounds.zero[j] and g_j > 0.0:
            if best_feasible is None:
                m_best = evaluate(bounds.from_unit(u_best[None, :]))
                n_eval += 1
                best_feasible = bool(
                    constraint_violation(m_best, constraints, step_size)[0] == 0.0)
            u_off = u_best.copy()
            u_off[j] = 0.5 * ZERO_DECADES / (zhi[j] - zlo[j])  # middle of the zero region
            m_off = evaluate(bounds.from_unit(u_off[None, :]))
            n_eval += 1
            f_off = float(penalised_cost(m_off, objective, constraints, step_size)[0])
            stays = (not best_feasible
                     or float(constraint_violation(m_off, constraints, step_size)[0]) == 0.0)
            if stays and f_off <= f_best + stop.rtol * max(abs(f_best), 1e-12):
                u_best, f_best = u_off, f_off
    gains = bounds.from_unit(u_best[None, :])
    metrics = evaluate(gains)
    n_eval += 1
    feasible = bool(constraint_violation(metrics, constraints, step_size)[0] == 0.0)
    return TuningResult(
        gains={n: float(g) for n, g in zip(bounds.names, gains[0], strict=True)},
        cost=f_best, objective=objective,
        objective_value=float(np.asarray(metrics[objective])[0]), feasible=feasible,
        metrics={m: float(np.asarray(v)[0]) for m, v in metrics.items()},
        n_evaluations=int(n_eval), generations=int(state.generation), converged=converged,
        at_bounds=bounds.at_bounds(gains[0]), history=state.history,
    )
