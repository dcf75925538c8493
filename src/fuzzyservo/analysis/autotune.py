"""Step-response tuning of any registered controller on the servo, through the batched simulator.

:func:`fuzzyservo.analysis.tuning.tune` is the generic search (differential evolution over a
population, then a Nelder-Mead polish). This module gives it a closed loop: a
:class:`TuningSetup` names the controller and the plant (any name of
:mod:`fuzzyservo.registry`), the step, horizon, sample time, objective and constraints;
:func:`make_evaluator` turns it into a function that runs a whole population of gain vectors
through :func:`fuzzyservo.sim.simulate_batch` in one call, and :func:`tune_controller` runs the
search. What is searched, in which box, and what is held comes from the registry entry of the
controller (:class:`fuzzyservo.registry.ControllerKind`): its searched gains and their boxes,
its held gains (``pid2``: c = 0; the PIDs: n = :attr:`TuningSetup.pid_n`) and its procedure:

``"search"``
    One search over the searched gains (p, pi, pid, pid2, fpi).
``"paper-steps"``
    The paper's steps (Sec. III A; stfpi): (1) tune the stage kind (the fuzzy PI);
    (2) keep its other gains and raise the output gain until the rise time matches step 1's;
    (3) refine every searched gain by a small differential evolution around step 2 plus a
    polish. The paper's step 3 retunes the α rules; we keep the published rules (Fig. 3b).

This module computes and returns records; it reads and writes no files (gains files and
checkpoints: :mod:`fuzzyservo.files`)::

    from fuzzyservo.paper import named_set
    setup = TuningSetup(controller="stfpi", plant="linear")
    tuned = tune_controller(setup, named_set(setup.param_set))
"""

from __future__ import annotations

import datetime as _dt
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from .._typing import FloatArray
from ..control.fuzzy_pi import KernelSystem
from ..errors import FuzzyServoError, ParameterError
from ..plant import ServoParams
from ..plant.zoh import check_delay
from ..registry import ControllerKind, build_plant, controller_kind, plant_kind
from ..sim import DEFAULT_DELAY, Plant, Step, simulate_batch
from ..sim.closed_loop import plant_limits, time_grid
from ..sim.references import check_reference_samples
from ..sim.stepinfo import METRIC_NAMES
from .tuning import (
    OBJECTIVES,
    GainBounds,
    TuningConstraints,
    constraint_violation,
    penalised_cost,
    tune,
)

__all__ = [
    "MAX_MAXITER",
    "MAX_POPSIZE",
    "Checkpoint",
    "StageRecord",
    "TunedGains",
    "TuningProgress",
    "TuningSetup",
    "check_run",
    "default_bounds",
    "full_gains",
    "make_evaluator",
    "stage_as_tuned",
    "tune_controller",
]


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("fuzzyservo")
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "unknown"


#: Largest population multiplier: 10 times the default; with k searched gains a generation is
#: popsize * k closed-loop runs (300 for a PID at the cap, some 10 s of CPU per generation for
#: 10 s runs on the linear plant). Storn and Price advise 5-10 members per searched gain.
MAX_POPSIZE = 100
#: Largest generation limit: 25 times the default (40); the search usually converges well
#: before the default, so more only spends time.
MAX_MAXITER = 1000


@dataclass(frozen=True, slots=True, kw_only=True)
class TuningSetup:
    """What to tune, on what, and how (everything but the parameter values themselves).

    Parameters
    ----------
    controller : str
        Registered controller name (``fuzzyservo.registry.controller_names()``).
    plant : str
        Registered plant name: ``linear`` (eq. (8) at the start position), ``small-signal``
        or ``nonlinear``.
    param_set : str
        Name of the parameter set the caller resolves (recorded; e.g. ``"paper"``).
    overrides : tuple of (str, float)
        ``group.field`` overrides the caller applied to the set (recorded) [SI].
    start : float
        Start position as a fraction of the stroke [-].
    step : float
        Reference step from the start position [m].
    duration : float
        Simulated time per run [s].
    ts : float
        Controller sample period [s].
    delay : float
        Transport delay on the command [s], at most ``duration``; default ``DEFAULT_DELAY``
        (none), as the paper tunes and as every other entry point runs.
    objective : {"iae", "itae", "ise"}
        Integral criterion minimised.
    constraints : TuningConstraints
        Overshoot [%], |steady-state error| as a fraction of the step [-], max |u| [-].
    seed : int
        Seed of the search.
    popsize, maxiter : int
        Differential-evolution population multiplier (2 to :data:`MAX_POPSIZE`) and generation
        limit (1 to :data:`MAX_MAXITER`) (stage 1 for stfpi).
    pid_n : float
        Derivative filter coefficient n held while tuning a kind with that gain [1/s].
    polish : bool
        Finish each search stage with a bounded Nelder-Mead polish (serial runs).
    bounds : GainBounds or None
        Search box; None uses :func:`default_bounds`.
    """

    controller: str
    plant: str = "linear"
    param_set: str = "paper"
    overrides: tuple[tuple[str, float], ...] = ()
    start: float = 0.5
    step: float = 0.1
    duration: float = 10.0
    ts: float = 0.001
    delay: float = DEFAULT_DELAY
    objective: str = "itae"
    constraints: TuningConstraints = field(default_factory=TuningConstraints)
    seed: int = 0
    popsize: int = 10
    maxiter: int = 40
    pid_n: float = 100.0
    polish: bool = True
    bounds: GainBounds | None = None

    def __post_init__(self) -> None:
        kind = controller_kind(self.controller)
        plant_kind(self.plant)
        if not kind.searched:
            raise ParameterError(f"controller {self.controller} has no gain to search")
        if self.objective not in OBJECTIVES:
            raise ParameterError(f"unknown objective {self.objective!r}; allowed: "
                                 f"{', '.join(OBJECTIVES)}")
        for name in ("step", "duration", "ts", "pid_n"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ParameterError(f"TuningSetup.{name} must be finite and > 0, got {v!r}")
        if not (math.isfinite(self.delay) and self.delay >= 0.0):
            raise ParameterError(f"TuningSetup.delay must be finite and >= 0 s, got "
                                 f"{self.delay!r}")
        check_delay(self.delay, duration=self.duration)
        if not 0.0 < self.start < 1.0:
            raise ParameterError(f"TuningSetup.start must be a fraction of the stroke in "
                                 f"(0, 1), got {self.start!r}")
        if self.duration < 10.0 * self.ts:
            raise ParameterError(f"TuningSetup.duration {self.duration!r} s must span at least "
                                 f"10 samples of ts = {self.ts!r} s")
        time_grid(self.duration, self.ts)  # at most MAX_SAMPLES samples per run
        if not (isinstance(self.seed, int) and self.seed >= 0):
            raise ParameterError(f"seed must be a non-negative integer, got {self.seed!r}")
        if not 2 <= self.popsize <= MAX_POPSIZE:
            raise ParameterError(f"popsize must be between 2 and {MAX_POPSIZE}, got "
                                 f"{self.popsize!r}")
        if not 1 <= self.maxiter <= MAX_MAXITER:
            raise ParameterError(f"maxiter must be between 1 and {MAX_MAXITER}, got "
                                 f"{self.maxiter!r}")
        b = self.bounds
        if b is not None and b.names != default_bounds(self.controller, self.step).names:
            raise ParameterError(
                f"bounds for {self.controller} must name "
                f"{default_bounds(self.controller, self.step).names}, got {b.names}")

    @property
    def kind(self) -> ControllerKind:
        """The registry entry of :attr:`controller`."""
        return controller_kind(self.controller)

    def search_bounds(self) -> GainBounds:
        """The search box in use."""
        return self.bounds or default_bounds(self.controller, self.step)

    def held(self) -> dict[str, float]:
        """Values of the gains not searched (registry values; n = :attr:`pid_n`)."""
        return self.kind.held({"n": self.pid_n})


def default_bounds(controller: str, step: float = 0.1) -> GainBounds:
    """The registry's search box of ``controller`` for a step of ``step`` [m].

    See :class:`fuzzyservo.registry.GainSpec`: PID gains on log scales (kp 0.01-100 1/m,
    ki 1e-3-100 1/(m s), kd 1e-4-10 s/m), pid2's b in [0, 1] linear; the fuzzy PIs' ke in
    [1, 10]/step 1/m, kde in [10, 1e6] per sample, kdu in [1e-5, 1] (docs/model.md, "Tuning").
    """
    box = controller_kind(controller).search_box(step)
    return GainBounds(names=tuple(b[0] for b in box), lower=tuple(b[1] for b in box),
                      upper=tuple(b[2] for b in box), log_scale=tuple(b[3] for b in box))


def _kind_gains(kind: ControllerKind, setup: TuningSetup, names: tuple[str, ...],
                row: FloatArray) -> dict[str, float]:
    """Every gain of ``kind``: the searched ``row`` (columns ``names``) plus the held ones."""
    g = {**kind.held({"n": setup.pid_n}), **dict(zip(names, row.tolist(), strict=True))}
    return {n: float(g[n]) for n in kind.gain_names}


def full_gains(setup: TuningSetup, searched: FloatArray, kind: ControllerKind | None = None
               ) -> FloatArray:
    """Searched gains (n, k) -> rows of the controller class's gains (n, len(cls.gain_names)),
    the held gains filled in (what :func:`fuzzyservo.sim.simulate_batch` takes)."""
    k = kind or setup.kind
    names = setup.search_bounds().names
    g = np.atleast_2d(np.asarray(searched, dtype=np.float64))
    return np.vstack([k.class_row(_kind_gains(k, setup, names, row)) for row in g])


def _plant(setup: TuningSetup, params: ServoParams) -> Plant:
    return build_plant(setup.plant, params, setup.start * params.cylinder.stroke)


Evaluator = Callable[[FloatArray], dict[str, FloatArray]]


def _evaluator(setup: TuningSetup, kind: ControllerKind, params: ServoParams,
               systems: Mapping[str, KernelSystem] | None) -> Evaluator:
    plant = _plant(setup, params)
    ctl = kind.template(dt=setup.ts, systems=systems)
    ref = Step(setup.step)

    def evaluate(gains: FloatArray) -> dict[str, FloatArray]:
        res = simulate_batch(ctl, full_gains(setup, gains, kind), plant=plant, reference=ref,
                             duration=setup.duration, delay=setup.delay)
        return {name: res.metric(name) for name in METRIC_NAMES}

    return evaluate


def make_evaluator(setup: TuningSetup, params: ServoParams, *,
                   systems: Mapping[str, KernelSystem] | None = None) -> Evaluator:
    """Function mapping searched gains (n, k) to step metrics, one batched simulation per call.

    Parameters
    ----------
    setup : TuningSetup
        Controller, plant, step, horizon, sample time and delay.
    params : ServoParams
        Servo parameters (the set ``setup.param_set`` with ``setup.overrides`` applied).
    systems : mapping, optional
        Fuzzy systems by role (``du``, ``alpha``); default the paper's (Fig. 3).

    Returns
    -------
    callable
        ``evaluate(gains)`` with gains (n, k) in the order of ``setup.search_bounds().names``
        returns ``{metric: array (n,)}`` for every name of ``METRIC_NAMES``; diverged runs
        have NaN metrics.
    """
    return _evaluator(setup, setup.kind, params, systems)


@dataclass(frozen=True, slots=True, kw_only=True)
class TuningProgress:
    """One generation of a search stage, for progress bars and checkpoints.

    Attributes
    ----------
    stage : str
        ``search`` (pid, pid2, fpi), or ``fpi``, ``rise``, ``refine`` (stfpi steps 1-3).
    generation, max_generations : int
        Generations done and the limit of this stage.
    best_cost : float
        Best penalised cost so far [-].
    population : ndarray (m, k)
        Current population in gain units (searched gains).
    n_evaluations : int
        Closed-loop runs so far in this stage.
    done : dict
        Searched gains of the completed stages, by stage name.
    """

    stage: str
    generation: int
    max_generations: int
    best_cost: float
    population: FloatArray
    n_evaluations: int
    done: dict[str, tuple[float, ...]]


@dataclass(frozen=True, slots=True, kw_only=True)
class StageRecord:
    """Result of one stage.

    Attributes
    ----------
    name : str
        Stage name (see :class:`TuningProgress`).
    gains : dict
        Every gain of the stage's controller (``fpi`` stage: the fuzzy PI's) [gain units].
    metrics : dict
        Step metrics of the stage's result (``METRIC_NAMES``, SI units).
    objective_value : float
        The objective of that run (IAE [m s], ITAE [m s²] or ISE [m² s]).
    feasible : bool
        Whether it meets the constraints.
    n_evaluations : int
        Closed-loop runs the stage used.
    """

    name: str
    gains: dict[str, float]
    metrics: dict[str, float]
    objective_value: float
    feasible: bool
    n_evaluations: int


@dataclass(frozen=True, slots=True, kw_only=True)
class TunedGains:
    """Outcome of :func:`tune_controller` (or read back by :func:`read_gains_toml`).

    Attributes
    ----------
    controller : str
        Controller kind.
    gains : dict
        Every gain the controller needs, fixed ones included (PID: kp, ki, kd, n, b, c).
    metrics : dict
        Step metrics of the tuned run.
    objective_value : float
        Objective of the tuned run [see :class:`StageRecord`].
    cost : float
        Penalised, step-normalised cost [-].
    feasible : bool
        Whether the tuned run meets every constraint.
    setup : TuningSetup
        The setup echoed.
    elapsed : float
        Wall time of the tuning [s].
    n_evaluations : int
        Closed-loop runs simulated.
    stages : tuple of StageRecord
        One record per stage (one for pid/pid2/fpi, three for stfpi).
    version : str
        fuzzyservo version that tuned.
    date : str
        ISO date and time (UTC) of the tuning.
    """

    controller: str
    gains: dict[str, float]
    metrics: dict[str, float]
    objective_value: float
    cost: float
    feasible: bool
    setup: TuningSetup
    elapsed: float
    n_evaluations: int
    stages: tuple[StageRecord, ...] = ()
    version: str = ""
    date: str = ""

    def stage(self, name: str) -> StageRecord:
        """The record of stage ``name``."""
        for s in self.stages:
            if s.name == name:
                return s
        raise ParameterError(f"no stage {name!r}; stages: {[s.name for s in self.stages]}")


@dataclass(frozen=True, slots=True, kw_only=True)
class Checkpoint:
    """State of an interrupted tuning, enough to resume it.

    Attributes
    ----------
    controller, plant, objective : str
        Identify the setup (resuming another setup is refused).
    seed : int
        Seed of the interrupted search.
    stage : str
        Stage that was running.
    generation : int
        Generations it had completed.
    population : ndarray (m, k)
        Its population in gain units.
    done : dict
        Searched gains of the completed stages.
    """

    controller: str
    plant: str
    objective: str
    seed: int
    stage: str
    generation: int
    population: FloatArray
    done: dict[str, tuple[float, ...]] = field(default_factory=dict)

    @classmethod
    def from_progress(cls, setup: TuningSetup, p: TuningProgress) -> Checkpoint:
        """Checkpoint of ``setup`` at progress report ``p``."""
        return cls(controller=setup.controller, plant=setup.plant, objective=setup.objective,
                   seed=setup.seed, stage=p.stage, generation=p.generation,
                   population=np.array(p.population, dtype=np.float64), done=dict(p.done))


# ---------------------------------------------------------------------------- tuning


def _record(name: str, setup: TuningSetup, kind: ControllerKind, searched: FloatArray,
            metrics: Mapping[str, FloatArray], n_eval: int) -> StageRecord:
    m = {k: float(np.asarray(v)[0]) for k, v in metrics.items()}
    feasible = bool(constraint_violation(metrics, setup.constraints, setup.step)[0] == 0.0)
    gains = _kind_gains(kind, setup, setup.search_bounds().names, np.atleast_2d(searched)[0])
    return StageRecord(name=name, gains=gains, metrics=m,
                       objective_value=m[setup.objective], feasible=feasible,
                       n_evaluations=n_eval)


def _search(setup: TuningSetup, evaluate: Evaluator, bounds: GainBounds, stage: str, *,
            popsize: int, maxiter: int, init: FloatArray | None, seed: int,
            done: dict[str, tuple[float, ...]],
            progress: Callable[[TuningProgress], None] | None) -> tuple[FloatArray, int]:
    count = {"n": 0}

    def counted(g: FloatArray) -> dict[str, FloatArray]:
        count["n"] += np.atleast_2d(g).shape[0]
        return evaluate(g)

    def on_gen(gen: int, best: float, pop: FloatArray, costs: FloatArray) -> None:
        del costs
        if progress is not None:
            progress(TuningProgress(stage=stage, generation=gen, max_generations=maxiter,
                                    best_cost=best, population=pop,
                                    n_evaluations=count["n"], done=dict(done)))

    try:
        res = tune(counted, bounds, objective=setup.objective, constraints=setup.constraints,
                   step_size=setup.step, seed=seed, popsize=popsize, maxiter=maxiter,
                   init=init, polish=setup.polish, on_generation=on_gen)
    except Exception as exc:
        # scipy's differential evolution re-raises a ValueError of the objective as a
        # RuntimeError "from" it: surface our own error, one line, as itself
        own = _own_error(exc)
        if own is None or own is exc:
            raise
        raise own from None
    return np.array([[res.gains[n] for n in bounds.names]]), count["n"]


def _own_error(exc: BaseException) -> FuzzyServoError | None:
    """The first :class:`FuzzyServoError` in the ``raise ... from`` chain of ``exc``, or None."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, FuzzyServoError):
            return e
        seen.add(id(e))
        e = e.__cause__
    return None


def check_run(setup: TuningSetup, params: ServoParams) -> None:
    """Check the tuning's step against the plant before any search: start + step within the
    stroke, the transducer resolution no coarser than the step.

    Raises
    ------
    InputError
        Otherwise (:func:`fuzzyservo.sim.references.check_reference_samples`).
    ParameterError
        No equilibrium at the start position.
    """
    stroke, resolution = plant_limits(_plant(setup, params))
    start = setup.start * params.cylinder.stroke
    check_reference_samples(np.array([start + setup.step]), np.array([0.0]),
                            start=start, stroke=stroke if stroke is not None else
                            params.cylinder.stroke, resolution=resolution)


def _check_resume(resume: Checkpoint, bounds: GainBounds) -> None:
    pop = resume.population
    k = len(bounds.names)
    if pop.ndim != 2 or pop.shape[1] != k or not np.all(np.isfinite(pop)):
        raise ParameterError(f"checkpoint population must be finite with {k} columns "
                             f"({', '.join(bounds.names)}), got shape {pop.shape}; delete the "
                             f"checkpoint or run without --resume")
    for name, v in resume.done.items():
        if len(v) != k or not all(math.isfinite(x) for x in v):
            raise ParameterError(f"checkpoint stage {name!r} must hold {k} finite gains, got "
                                 f"{len(v)}; delete the checkpoint or run without --resume")


def _rise_match(setup: TuningSetup, evaluate: Evaluator, base: FloatArray, col: int,
                target: float, upper: float) -> tuple[float, int]:
    """Smallest value >= ``base[col]`` of the output gain (column ``col`` of the searched
    row ``base``) whose rise time is <= ``target``, by batched bracketing and bisection
    (15 points per round, one batch each).

    Where the rise time is continuous in the gain the bracket ends agree to within a sample.
    It jumps where the first overshoot hump crosses the 90 % line; then the end of the final
    bracket whose rise time is nearer the target is returned. If no value in the box reaches
    the target, the fastest evaluated one is returned.
    """
    n_eval = 0

    def rise(values: FloatArray) -> FloatArray:
        nonlocal n_eval
        g = np.tile(base, (values.size, 1))
        g[:, col] = values
        n_eval += values.size
        tr = evaluate(g)["rise_time"]
        return np.where(np.isfinite(tr), tr, np.inf)

    lo = float(base[col])
    tr_lo = float(rise(np.array([lo]))[0])
    if tr_lo <= target:
        return lo, n_eval
    grid = lo * np.geomspace(1.0, 1e3, 16)[1:]
    grid = grid[grid <= upper] if np.any(grid <= upper) else np.array([upper])
    tr = rise(grid)
    ok = np.nonzero(tr <= target)[0]
    if ok.size == 0:
        return float(grid[int(np.argmin(tr))]), n_eval
    i = int(ok[0])
    hi, tr_hi = float(grid[i]), float(tr[i])
    if i > 0:
        lo, tr_lo = float(grid[i - 1]), float(tr[i - 1])
    for _ in range(8):  # each round divides the log-bracket by 15
        if hi / lo - 1.0 < 1e-7 or tr_lo - target <= setup.ts:
            break
        pts = np.geomspace(lo, hi, 17)[1:-1]
        tr = rise(pts)
        ok = np.nonzero(tr <= target)[0]
        j = int(ok[0]) if ok.size else pts.size
        if j < pts.size:
            hi, tr_hi = float(pts[j]), float(tr[j])
        if j > 0:
            lo, tr_lo = float(pts[j - 1]), float(tr[j - 1])
    return (lo if tr_lo - target < target - tr_hi else hi), n_eval


def tune_controller(setup: TuningSetup, params: ServoParams, *,
                    systems: Mapping[str, KernelSystem] | None = None,
                    progress: Callable[[TuningProgress], None] | None = None,
                    resume: Checkpoint | None = None) -> TunedGains:
    """Tune ``setup.controller`` on the servo by step-response search.

    Parameters
    ----------
    setup : TuningSetup
        What to tune and how.
    params : ServoParams
        Servo parameters (``setup.param_set`` with ``setup.overrides`` applied).
    systems : mapping, optional
        Fuzzy systems by role (``du``, ``alpha``); default the paper's (Fig. 3).
    progress : callable, optional
        Called with a :class:`TuningProgress` after each generation of each stage.
    resume : Checkpoint, optional
        Continue an interrupted run: its population seeds the stage it was in, completed
        stages are not repeated.

    Returns
    -------
    TunedGains

    Raises
    ------
    ParameterError
        A missing fuzzy system, or a checkpoint of another setup or of the wrong shape.
    InputError
        The step leaves the stroke, or the transducer resolution is coarser than the step
        (:func:`check_run`).

    Notes
    -----
    The ``"paper-steps"`` procedure is the paper's Sec. III A, steps 1-3; step 2's rise-time
    match is a batched bracketing of the output gain (kdu) on a log grid followed by
    bisection to the smallest value >= step 1's whose 10-90 % rise time does not exceed step
    1's; step 3 is a differential evolution (``popsize`` 5, ``maxiter // 2`` generations) in
    the box spanning steps 1 and 2 widened by a factor 3, its population seeded with both,
    plus a polish.
    """
    if resume is not None and (resume.controller, resume.plant, resume.objective) != (
            setup.controller, setup.plant, setup.objective):
        raise ParameterError(
            f"checkpoint is for {resume.controller} on the {resume.plant} plant with "
            f"{resume.objective}, not {setup.controller} on the {setup.plant} plant with "
            f"{setup.objective}")
    t0 = time.perf_counter()
    kind = setup.kind
    bounds = setup.search_bounds()
    if resume is not None:
        _check_resume(resume, bounds)
    check_run(setup, params)
    done: dict[str, tuple[float, ...]] = dict(resume.done) if resume else {}

    def init_for(stage: str) -> FloatArray | None:
        if resume is not None and resume.stage == stage and resume.population.shape[0] >= 5:
            return resume.population
        return None

    stages: list[StageRecord] = []
    total = 0
    if kind.tuning == "search":
        evaluate = _evaluator(setup, kind, params, systems)
        best, n = _search(setup, evaluate, bounds, "search", popsize=setup.popsize,
                          maxiter=setup.maxiter, init=init_for("search"), seed=setup.seed,
                          done=done, progress=progress)
        total += n + 1
        stages.append(_record("search", setup, kind, best, evaluate(best), n + 1))
    else:
        assert kind.stage_kind is not None and kind.rise_gain is not None
        first = controller_kind(kind.stage_kind)
        if first.searched != kind.searched:
            raise ParameterError(f"{kind.name}: its step-1 kind {first.name} must search the "
                                 f"same gains")
        col = bounds.names.index(kind.rise_gain)
        ev1 = _evaluator(setup, first, params, systems)
        ev = _evaluator(setup, kind, params, systems)
        # step 1: the stage kind (the fuzzy PI, alpha = 1)
        if first.name in done:
            g1 = np.array([done[first.name]])
            n1 = 0
        else:
            g1, n1 = _search(setup, ev1, bounds, first.name, popsize=setup.popsize,
                             maxiter=setup.maxiter, init=init_for(first.name),
                             seed=setup.seed, done=done, progress=progress)
            done[first.name] = tuple(float(v) for v in g1[0])
        m1 = ev1(g1)
        stages.append(_record(first.name, setup, first, g1, m1, n1 + 1))
        # step 2: the other gains kept; raise the output gain until the rise time is back
        if "rise" in done:
            g2 = np.array([done["rise"]])
            n2 = 0
        else:
            target = float(m1["rise_time"][0])
            value, n2 = _rise_match(setup, ev, g1[0].copy(), col,
                                    target if math.isfinite(target) else math.inf,
                                    bounds.upper[col])
            g2 = g1.copy()
            g2[0, col] = value
            done["rise"] = tuple(float(v) for v in g2[0])
        stages.append(_record("rise", setup, kind, g2, ev(g2), n2 + 1))
        # step 3: refine every searched gain around step 2
        lo = np.maximum(np.asarray(bounds.lower), np.minimum(g1[0], g2[0]) / 3.0)
        hi = np.minimum(np.asarray(bounds.upper), np.maximum(g1[0], g2[0]) * 3.0)
        local = GainBounds(names=bounds.names, lower=tuple(lo), upper=tuple(hi),
                           log_scale=bounds.log_scale)
        init3 = init_for("refine")
        if init3 is None:
            rng = np.random.default_rng(setup.seed)
            z = rng.uniform(local.to_search(lo), local.to_search(hi), size=(13, lo.size))
            init3 = np.vstack([g2, g1, local.from_search(z)])
        g3, n3 = _search(setup, ev, local, "refine", popsize=5,
                         maxiter=max(setup.maxiter // 2, 1), init=init3, seed=setup.seed,
                         done=done, progress=progress)
        stages.append(_record("refine", setup, kind, g3, ev(g3), n3 + 1))
        total += n1 + n2 + n3 + 4
    final = stages[-1]
    best_metrics = {k: np.array([v]) for k, v in final.metrics.items()}
    cost = float(penalised_cost(best_metrics, setup.objective, setup.constraints,
                                setup.step)[0])
    return TunedGains(
        controller=setup.controller, gains=dict(final.gains), metrics=dict(final.metrics),
        objective_value=final.objective_value, cost=cost, feasible=final.feasible,
        setup=setup, elapsed=time.perf_counter() - t0, n_evaluations=total,
        stages=tuple(stages), version=_version(),
        date=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"))


def stage_as_tuned(tuned: TunedGains, stage: str) -> TunedGains:
    """One stage of a multi-stage tuning as a result of its own.

    Stage ``"fpi"`` of a self-tuning fuzzy PI tuning is the plain fuzzy PI of the paper's
    step 1, so it can be written as that controller's gain file.
    """
    s = tuned.stage(stage)
    cost = float(penalised_cost({k: np.array([v]) for k, v in s.metrics.items()},
                                tuned.setup.objective, tuned.setup.constraints,
                                tuned.setup.step)[0])
    return replace(tuned, controller=s.name, gains=dict(s.gains), metrics=dict(s.metrics),
                   objective_value=s.objective_value, feasible=s.feasible,
                   setup=replace(tuned.setup, controller=s.name),
                   n_evaluations=s.n_evaluations, stages=(s,), cost=cost)
