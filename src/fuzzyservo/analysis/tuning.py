"""Automatic step-response tuning: the paper's own method, made systematic.

The paper tunes by "repeatedly performing the step response ... the program evaluated the
performance error, altered the gains and repeated the step response test until the best
performing gains were determined" (Sec. III). Here the step response is the batched closed-loop
simulator, the performance error is IAE, ITAE or ISE, the constraints are penalties on
overshoot, steady-state error and max |u|, and the search is scipy's differential evolution,
evaluating a whole population per call, followed by a bounded Nelder-Mead polish.

This module is independent of the simulator: it takes a function that maps a population of
gain vectors to step metrics. It does no I/O; progress and checkpoints go through callbacks.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy.optimize import differential_evolution, minimize

from .._typing import FloatArray
from ..errors import ParameterError

__all__ = [
    "OBJECTIVES",
    "GainBounds",
    "TuningConstraints",
    "TuningResult",
    "constraint_violation",
    "penalised_cost",
    "tune",
]

Objective = Literal["iae", "itae", "ise"]
#: Objectives the tuner accepts; each is a column of the metrics returned by the evaluator.
OBJECTIVES: tuple[str, ...] = ("iae", "itae", "ise")

#: Cost given to a run whose metrics are not finite (diverged, never settled).
_INFEASIBLE = 1.0e6
#: Weight of one unit of normalised constraint violation, in units of the normalised objective.
_PENALTY = 100.0

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
    """

    names: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    log_scale: tuple[bool, ...] = ()

    def __post_init__(self) -> None:
        k = len(self.names)
        if k == 0:
            raise ParameterError("GainBounds needs at least one gain name")
        log = self.log_scale or (False,) * k
        object.__setattr__(self, "log_scale", tuple(bool(v) for v in log))
        for label, seq in (("lower", self.lower), ("upper", self.upper),
                           ("log_scale", self.log_scale)):
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
    """

    gains: dict[str, float]
    cost: float
    objective: str
    objective_value: float
    feasible: bool
    metrics: dict[str, float]
    n_evaluations: int
    generations: int
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
        sse = np.abs(np.asarray(metrics["steady_state_error"], dtype=np.float64)) / step_size
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
    cost = j + _PENALTY * constraint_violation(metrics, constraints, step_size)
    return np.where(np.isfinite(cost), cost, _INFEASIBLE)


def tune(evaluate: Evaluator, bounds: GainBounds, *, objective: str = "itae",
         constraints: TuningConstraints | None = None, step_size: float,
         seed: int = 0, popsize: int = 12, maxiter: int = 60, tol: float = 1e-4,
         polish: bool = True, init: FloatArray | None = None,
         on_generation: Callable[[int, float, FloatArray, FloatArray], None] | None = None,
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
    popsize, maxiter, tol : int, int, float
        Differential-evolution population multiplier, generation limit and relative tolerance.
    polish : bool
        Refine the best member with a bounded Nelder-Mead search afterwards.
    init : array (m, k), optional
        Initial population in gain units (e.g. a checkpoint of an interrupted run).
    on_generation : callable, optional
        ``on_generation(generation, best_cost, population, costs)`` after every generation with
        the population in gain units, for progress display and checkpoints.

    Returns
    -------
    TuningResult
    """
    constraints = constraints or TuningConstraints()
    if not (math.isfinite(step_size) and step_size > 0.0):
        raise ParameterError(f"step_size must be a positive number of metres, got {step_size}")
    if objective not in OBJECTIVES:
        raise ParameterError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    state = {"evals": 0, "gen": 0}
    history: list[float] = []
    last: dict[str, FloatArray] = {}

    def cost_of(z: FloatArray) -> FloatArray:
        gains = bounds.from_search(np.atleast_2d(z))
        metrics = evaluate(gains)
        state["evals"] += gains.shape[0]
        c = penalised_cost(metrics, objective, constraints, step_size)
        last["pop"], last["cost"] = gains, c
        return c

    def vectorised(zt: FloatArray) -> FloatArray:  # scipy passes (k, S)
        return cost_of(np.asarray(zt).T)

    def callback(intermediate_result: object) -> None:
        state["gen"] += 1
        best = float(getattr(intermediate_result, "fun", np.nan))
        history.append(best)
        if on_generation is not None and "pop" in last:
            on_generation(state["gen"], best, last["pop"], last["cost"])

    de_init: str | FloatArray = "latinhypercube"
    if init is not None:
        z0 = bounds.to_search(np.asarray(init, dtype=np.float64))
        lo = np.array([b[0] for b in bounds.search_bounds()])
        hi = np.array([b[1] for b in bounds.search_bounds()])
        de_init = np.clip(np.atleast_2d(z0), lo, hi)
        if de_init.shape[0] < 5:
            raise ParameterError(
                f"an initial population needs at least 5 members, got {de_init.shape[0]}")
    res = differential_evolution(
        vectorised, bounds.search_bounds(), vectorized=True, updating="deferred",
        popsize=popsize, maxiter=maxiter, tol=tol, rng=np.random.default_rng(seed),
        init=de_init, polish=False, callback=callback,
    )
    z_best = np.asarray(res.x, dtype=np.float64)
    f_best = float(res.fun)
    if polish:
        sb = bounds.search_bounds()
        pol = minimize(lambda z: float(cost_of(z)[0]), z_best, method="Nelder-Mead",
                       bounds=sb, options={"xatol": 1e-4, "fatol": 1e-6 * max(f_best, 1e-9),
                                           "maxfev": 60 * len(sb)})
        if float(pol.fun) < f_best:
            z_best, f_best = np.asarray(pol.x, dtype=np.float64), float(pol.fun)
    gains = bounds.from_search(z_best[None, :])
    metrics = evaluate(gains)
    state["evals"] += 1
    feasible = bool(constraint_violation(metrics, constraints, step_size)[0] == 0.0)
    return TuningResult(
        gains={n: float(g) for n, g in zip(bounds.names, gains[0], strict=True)},
        cost=f_best, objective=objective,
        objective_value=float(np.asarray(metrics[objective])[0]), feasible=feasible,
        metrics={k: float(np.asarray(v)[0]) for k, v in metrics.items()},
        n_evaluations=int(state["evals"]), generations=int(state["gen"]),
        history=tuple(history),
    )
