"""Step-response tuning of the package's controllers on the servo, through the batched simulator.

:func:`fuzzyservo.analysis.tuning.tune` is the generic search (differential evolution over a
population, then a Nelder-Mead polish). This module gives it a closed loop: a
:class:`TuningSetup` names the controller (``pid``, ``pid2``, ``fpi``, ``stfpi``), the plant
(``linear`` eq. (8) or ``nonlinear``), the step, horizon, sample time, objective and
constraints; :func:`make_evaluator` turns it into a function that runs a whole population of
gain vectors through :func:`fuzzyservo.sim.simulate_batch` in one call, and
:func:`tune_controller` runs the search (for ``stfpi`` the paper's steps 1-3, Sec. III A).
:func:`write_gains_toml` / :func:`read_gains_toml` store the result with everything needed to
reproduce it.

The analysis layer does not import :mod:`fuzzyservo.paper`, so the servo parameters and the
fuzzy systems are passed in::

    from fuzzyservo.paper import alpha_system, du_system, named_set
    setup = TuningSetup(controller="stfpi", plant="linear")
    tuned = tune_controller(setup, named_set(setup.param_set), du_system=du_system(),
                            alpha_system=alpha_system())

Controllers and what is searched
--------------------------------
``pid``
    1-DOF parallel PID, ``kp, ki, kd`` searched (log scale), ``b = c = 1``, derivative filter
    ``n = 100`` 1/s fixed (Simulink's default; :attr:`TuningSetup.pid_n`).
``pid2``
    2-DOF PID, ``kp, ki, kd, b`` searched, ``c = 0`` (derivative on the measurement: no
    derivative kick at the step, and ``c`` does not enter ∫e = kp (1 - b)/ki, the quantity
    that lets a PID avoid overshoot on this integrating plant, model-notes §5.1).
``fpi``
    Fuzzy PI (α = 1), ``ke, kde, kdu`` searched on log scales.
``stfpi``
    Self-tuning fuzzy PI by the paper's steps: (1) tune the fuzzy PI; (2) keep ``ke, kde`` and
    raise ``kdu`` until the self-tuning controller's rise time matches step 1's; (3) refine
    ``ke, kde, kdu`` by a small differential evolution around step 2 plus a polish. The paper's
    step 3 retunes the α rules; we keep the published rules (Fig. 3b) and refine the gains.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import time
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from .._typing import FloatArray
from ..control import FuzzyPIController, PIDController, SelfTuningFuzzyPIController
from ..control.fuzzy_pi import KernelSystem
from ..errors import InputError, ParameterError
from ..plant import ServoParams
from ..sim import LinearPlant, NonlinearPlant, Step, make_plant, simulate_batch
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
    "CONTROLLER_KINDS",
    "PLANT_KINDS",
    "Checkpoint",
    "StageRecord",
    "TunedGains",
    "TuningProgress",
    "TuningSetup",
    "default_bounds",
    "full_gains",
    "load_checkpoint",
    "make_evaluator",
    "read_gains_toml",
    "save_checkpoint",
    "stage_as_tuned",
    "tune_controller",
    "write_gains_toml",
]

#: Controllers :func:`tune_controller` tunes.
CONTROLLER_KINDS: tuple[str, ...] = ("pid", "pid2", "fpi", "stfpi")
#: Plants it tunes them on.
PLANT_KINDS: tuple[str, ...] = ("linear", "nonlinear")
_FORMAT = 1


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("fuzzyservo")
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "unknown"


@dataclass(frozen=True, slots=True, kw_only=True)
class TuningSetup:
    """What to tune, on what, and how (everything but the parameter values themselves).

    Parameters
    ----------
    controller : {"pid", "pid2", "fpi", "stfpi"}
        Controller kind (module docstring: what each searches).
    plant : {"linear", "nonlinear"}
        Eq. (8) linearised at the start position, or the nonlinear two-chamber model.
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
        Transport delay on the command [s]; the paper tunes without the hose delay.
    objective : {"iae", "itae", "ise"}
        Integral criterion minimised.
    constraints : TuningConstraints
        Overshoot [%], |steady-state error| as a fraction of the step [-], max |u| [-].
    seed : int
        Seed of the search.
    popsize, maxiter : int
        Differential-evolution population multiplier and generation limit (stage 1 for stfpi).
    pid_n : float
        Derivative filter coefficient of the PIDs [1/s].
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
    delay: float = 0.0
    objective: str = "itae"
    constraints: TuningConstraints = field(default_factory=TuningConstraints)
    seed: int = 0
    popsize: int = 10
    maxiter: int = 40
    pid_n: float = 100.0
    polish: bool = True
    bounds: GainBounds | None = None

    def __post_init__(self) -> None:
        if self.controller not in CONTROLLER_KINDS:
            raise ParameterError(f"unknown controller {self.controller!r}; allowed: "
                                 f"{', '.join(CONTROLLER_KINDS)}")
        if self.plant not in PLANT_KINDS:
            raise ParameterError(f"unknown plant {self.plant!r}; allowed: "
                                 f"{', '.join(PLANT_KINDS)}")
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
        if not 0.0 < self.start < 1.0:
            raise ParameterError(f"TuningSetup.start must be a fraction of the stroke in "
                                 f"(0, 1), got {self.start!r}")
        if self.duration < 10.0 * self.ts:
            raise ParameterError(f"TuningSetup.duration {self.duration!r} s must span at least "
                                 f"10 samples of ts = {self.ts!r} s")
        if not (isinstance(self.seed, int) and self.seed >= 0):
            raise ParameterError(f"seed must be a non-negative integer, got {self.seed!r}")
        if self.popsize < 2 or self.maxiter < 1:
            raise ParameterError(f"need popsize >= 2 and maxiter >= 1, got {self.popsize}, "
                                 f"{self.maxiter}")
        b = self.bounds
        if b is not None and b.names != default_bounds(self.controller, self.step).names:
            raise ParameterError(
                f"bounds for {self.controller} must name "
                f"{default_bounds(self.controller, self.step).names}, got {b.names}")

    def search_bounds(self) -> GainBounds:
        """The search box in use."""
        return self.bounds or default_bounds(self.controller, self.step)


def default_bounds(controller: str, step: float = 0.1) -> GainBounds:
    """Default search box of ``controller`` for a step of ``step`` [m].

    PID gains (u is a fraction of the rated command, e in metres): kp in [0.01, 100] 1/m,
    ki in [1e-3, 100] 1/(m s), kd in [1e-4, 10] s/m, all log scale (they span decades; the
    paper's PIDs, 0.5-1.2, sit inside), b in [0, 1] linear. Fuzzy PI (model-notes §5.3):
    ke in [1, 10]/step 1/m (the paper's step 1 picks ke so that the expected error fills
    [-1, 1]: e_n = 1 at the step for ke = 1/step; up to 10/step saturates large errors and
    sharpens the response near the target; below 1/step the rule base is under-used),
    kde in [10, 1e6] per sample (a 0.26 m/s slew is 2.6e-4 m
    per 1 ms sample, kde ~ 4e3 normalises it; two decades margin each side), kdu in
    [1e-5, 1] (the effective loop gain kdu kde K_v must stay below ~4 1/s).
    """
    if controller in ("pid", "pid2"):
        names: tuple[str, ...] = ("kp", "ki", "kd")
        lo: tuple[float, ...] = (0.01, 1e-3, 1e-4)
        hi: tuple[float, ...] = (100.0, 100.0, 10.0)
        lg: tuple[bool, ...] = (True, True, True)
        if controller == "pid2":
            names, lo, hi, lg = names + ("b",), lo + (0.0,), hi + (1.0,), lg + (False,)
        return GainBounds(names=names, lower=lo, upper=hi, log_scale=lg)
    if controller in ("fpi", "stfpi"):
        return GainBounds(names=("ke", "kde", "kdu"), lower=(1.0 / step, 10.0, 1e-5),
                          upper=(10.0 / step, 1e6, 1.0), log_scale=(True, True, True))
    raise ParameterError(f"unknown controller {controller!r}; allowed: "
                         f"{', '.join(CONTROLLER_KINDS)}")


def full_gains(setup: TuningSetup, searched: FloatArray) -> FloatArray:
    """Searched gains (n, k) -> every gain of the controller (n, len(gain_names)).

    PIDs get ``n = setup.pid_n`` and ``b = c = 1`` (pid) or ``c = 0`` (pid2).
    """
    g = np.atleast_2d(np.asarray(searched, dtype=np.float64))
    if setup.controller in ("fpi", "stfpi"):
        return g
    n = g.shape[0]
    b = np.ones(n) if setup.controller == "pid" else g[:, 3]
    c = np.ones(n) if setup.controller == "pid" else np.zeros(n)
    return np.column_stack([g[:, 0], g[:, 1], g[:, 2], np.full(n, setup.pid_n), b, c])


def _gain_dict(setup: TuningSetup, searched: FloatArray) -> dict[str, float]:
    row = full_gains(setup, searched)[0]
    names = PIDController.gain_names if setup.controller in ("pid", "pid2") \
        else FuzzyPIController.gain_names
    return {n: float(v) for n, v in zip(names, row, strict=True)}


def _plant(setup: TuningSetup, params: ServoParams) -> LinearPlant | NonlinearPlant:
    return make_plant(setup.plant, params, setup.start * params.cylinder.stroke)


def _template(setup: TuningSetup, kind: str, du_system: KernelSystem | None,
              alpha_system: KernelSystem | None) -> Any:
    if kind in ("pid", "pid2"):
        return PIDController(dt=setup.ts, n=setup.pid_n)
    if du_system is None or (kind == "stfpi" and alpha_system is None):
        raise ParameterError(f"controller {kind} needs du_system"
                             f"{' and alpha_system' if kind == 'stfpi' else ''} "
                             f"(fuzzyservo.paper.du_system(), alpha_system())")
    if kind == "stfpi":
        return SelfTuningFuzzyPIController.from_systems(du_system, alpha_system, dt=setup.ts,
                                                        ke=1.0, kde=1.0, kdu=1.0)
    return FuzzyPIController.from_systems(du_system, None, dt=setup.ts, ke=1.0, kde=1.0,
                                          kdu=1.0)


Evaluator = Callable[[FloatArray], dict[str, FloatArray]]


def _evaluator(setup: TuningSetup, kind: str, params: ServoParams,
               du_system: KernelSystem | None, alpha_system: KernelSystem | None
               ) -> Evaluator:
    plant = _plant(setup, params)
    ctl = _template(setup, kind, du_system, alpha_system)
    ref = Step(setup.step)

    def evaluate(gains: FloatArray) -> dict[str, FloatArray]:
        res = simulate_batch(ctl, full_gains(setup, gains), plant=plant, reference=ref,
                             duration=setup.duration, delay=setup.delay)
        return {name: res.metric(name) for name in METRIC_NAMES}

    return evaluate


def make_evaluator(setup: TuningSetup, params: ServoParams, *,
                   du_system: KernelSystem | None = None,
                   alpha_system: KernelSystem | None = None) -> Evaluator:
    """Function mapping searched gains (n, k) to step metrics, one batched simulation per call.

    Parameters
    ----------
    setup : TuningSetup
        Controller, plant, step, horizon, sample time and delay.
    params : ServoParams
        Servo parameters (the set ``setup.param_set`` with ``setup.overrides`` applied).
    du_system, alpha_system : MamdaniSystem, optional
        The Δu and α systems (Fig. 3); required for fpi (Δu) and stfpi (both).

    Returns
    -------
    callable
        ``evaluate(gains)`` with gains (n, k) in the order of ``setup.search_bounds().names``
        returns ``{metric: array (n,)}`` for every name of ``METRIC_NAMES``; diverged runs
        have NaN metrics.
    """
    return _evaluator(setup, setup.controller, params, du_system, alpha_system)


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


def save_checkpoint(path: str | Path, ckpt: Checkpoint) -> Path:
    """Write ``ckpt`` as an ``.npz`` file (population array plus a JSON header)."""
    path = Path(path)
    header = json.dumps({"controller": ckpt.controller, "plant": ckpt.plant,
                         "objective": ckpt.objective, "seed": ckpt.seed, "stage": ckpt.stage,
                         "generation": ckpt.generation,
                         "done": {k: list(v) for k, v in ckpt.done.items()}})
    try:
        with path.open("wb") as fh:
            np.savez(fh, population=np.asarray(ckpt.population, dtype=np.float64),
                     header=np.array(header))
    except OSError as exc:
        raise InputError(f"cannot write checkpoint {str(path)!r}: {exc.strerror}") from exc
    return path


def load_checkpoint(path: str | Path) -> Checkpoint:
    """Read a checkpoint written by :func:`save_checkpoint`.

    Raises
    ------
    InputError
        If the file is missing or not a checkpoint.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            pop = np.asarray(z["population"], dtype=np.float64)
            h = json.loads(str(z["header"]))
        return Checkpoint(controller=str(h["controller"]), plant=str(h["plant"]),
                          objective=str(h["objective"]), seed=int(h["seed"]),
                          stage=str(h["stage"]), generation=int(h["generation"]),
                          population=np.atleast_2d(pop),
                          done={str(k): tuple(float(x) for x in v)
                                for k, v in dict(h["done"]).items()})
    except OSError as exc:
        raise InputError(f"cannot read checkpoint {str(path)!r}: {exc.strerror or exc}"
                         ) from exc
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{str(path)!r} is not a tuning checkpoint ({exc})") from exc


# ---------------------------------------------------------------------------- tuning


def _record(name: str, setup: TuningSetup, kind_setup: TuningSetup, searched: FloatArray,
            metrics: Mapping[str, FloatArray], n_eval: int) -> StageRecord:
    m = {k: float(np.asarray(v)[0]) for k, v in metrics.items()}
    feasible = bool(constraint_violation(metrics, setup.constraints, setup.step)[0] == 0.0)
    return StageRecord(name=name, gains=_gain_dict(kind_setup, searched), metrics=m,
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

    res = tune(counted, bounds, objective=setup.objective, constraints=setup.constraints,
               step_size=setup.step, seed=seed, popsize=popsize, maxiter=maxiter,
               init=init, polish=setup.polish, on_generation=on_gen)
    return np.array([[res.gains[n] for n in bounds.names]]), count["n"]


def _rise_match(setup: TuningSetup, evaluate: Evaluator, ke: float, kde: float, kdu1: float,
                target: float, upper: float) -> tuple[float, int]:
    """Smallest kdu >= kdu1 whose rise time is <= ``target``, by batched bracketing and
    bisection (15 points per round, one batch each).

    Where the rise time is continuous in kdu the bracket ends agree to within a sample. It
    jumps where the first overshoot hump crosses the 90 % line; then the end of the final
    bracket whose rise time is nearer the target is returned. If no kdu in the box reaches the
    target, the fastest evaluated kdu is returned.
    """
    n_eval = 0

    def rise(kdus: FloatArray) -> FloatArray:
        nonlocal n_eval
        g = np.column_stack([np.full(kdus.size, ke), np.full(kdus.size, kde), kdus])
        n_eval += kdus.size
        tr = evaluate(g)["rise_time"]
        return np.where(np.isfinite(tr), tr, np.inf)

    lo = kdu1
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
                    du_system: KernelSystem | None = None,
                    alpha_system: KernelSystem | None = None,
                    progress: Callable[[TuningProgress], None] | None = None,
                    resume: Checkpoint | None = None) -> TunedGains:
    """Tune ``setup.controller`` on the servo by step-response search.

    Parameters
    ----------
    setup : TuningSetup
        What to tune and how.
    params : ServoParams
        Servo parameters (``setup.param_set`` with ``setup.overrides`` applied).
    du_system, alpha_system : MamdaniSystem, optional
        The Δu and α systems (fpi needs Δu, stfpi both).
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
        A missing fuzzy system, or a checkpoint of another setup.

    Notes
    -----
    The stfpi procedure is the paper's Sec. III A, steps 1-3; step 2's rise-time match is a
    batched bracketing of kdu on a log grid followed by bisection to the smallest kdu >= step
    1's whose 10-90 % rise time does not exceed step 1's; step 3 is a differential evolution
    (``popsize`` 5, ``maxiter // 2`` generations) in the box spanning steps 1 and 2 widened by
    a factor 3, its population seeded with both, plus a polish.
    """
    if resume is not None and (resume.controller, resume.plant, resume.objective) != (
            setup.controller, setup.plant, setup.objective):
        raise ParameterError(
            f"checkpoint is for {resume.controller} on the {resume.plant} plant with "
            f"{resume.objective}, not {setup.controller} on the {setup.plant} plant with "
            f"{setup.objective}")
    t0 = time.perf_counter()
    bounds = setup.search_bounds()
    done: dict[str, tuple[float, ...]] = dict(resume.done) if resume else {}

    def init_for(stage: str) -> FloatArray | None:
        if resume is not None and resume.stage == stage and resume.population.shape[0] >= 5:
            return resume.population
        return None

    stages: list[StageRecord] = []
    total = 0
    if setup.controller != "stfpi":
        evaluate = make_evaluator(setup, params, du_system=du_system,
                                  alpha_system=alpha_system)
        best, n = _search(setup, evaluate, bounds, "search", popsize=setup.popsize,
                          maxiter=setup.maxiter, init=init_for("search"), seed=setup.seed,
                          done=done, progress=progress)
        total += n + 1
        stages.append(_record("search", setup, setup, best, evaluate(best), n + 1))
    else:
        fsetup = replace(setup, controller="fpi")
        ev1 = _evaluator(setup, "fpi", params, du_system, alpha_system)
        ev = _evaluator(setup, "stfpi", params, du_system, alpha_system)
        # step 1: fuzzy PI, alpha = 1
        if "fpi" in done:
            g1 = np.array([done["fpi"]])
            n1 = 0
        else:
            g1, n1 = _search(setup, ev1, bounds, "fpi", popsize=setup.popsize,
                             maxiter=setup.maxiter, init=init_for("fpi"), seed=setup.seed,
                             done=done, progress=progress)
            done["fpi"] = tuple(float(v) for v in g1[0])
        m1 = ev1(g1)
        stages.append(_record("fpi", setup, fsetup, g1, m1, n1 + 1))
        # step 2: same ke, kde; raise kdu until the rise time is back
        if "rise" in done:
            g2 = np.array([done["rise"]])
            n2 = 0
        else:
            target = float(m1["rise_time"][0])
            kdu2, n2 = _rise_match(setup, ev, float(g1[0, 0]), float(g1[0, 1]),
                                   float(g1[0, 2]), target if math.isfinite(target)
                                   else math.inf, bounds.upper[2])
            g2 = np.array([[g1[0, 0], g1[0, 1], kdu2]])
            done["rise"] = tuple(float(v) for v in g2[0])
        stages.append(_record("rise", setup, setup, g2, ev(g2), n2 + 1))
        # step 3: refine the three gains around step 2
        lo = np.maximum(np.asarray(bounds.lower), np.minimum(g1[0], g2[0]) / 3.0)
        hi = np.minimum(np.asarray(bounds.upper), np.maximum(g1[0], g2[0]) * 3.0)
        local = GainBounds(names=bounds.names, lower=tuple(lo), upper=tuple(hi),
                           log_scale=bounds.log_scale)
        init3 = init_for("refine")
        if init3 is None:
            rng = np.random.default_rng(setup.seed)
            z = rng.uniform(np.log10(lo), np.log10(hi), size=(13, 3))
            init3 = np.vstack([g2, g1, 10.0 ** z])
        g3, n3 = _search(setup, ev, local, "refine", popsize=5,
                         maxiter=max(setup.maxiter // 2, 1), init=init3, seed=setup.seed,
                         done=done, progress=progress)
        stages.append(_record("refine", setup, setup, g3, ev(g3), n3 + 1))
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


# ---------------------------------------------------------------------------- TOML


def _constraints_table(c: TuningConstraints) -> dict[str, Any]:
    out: dict[str, Any] = {"require_settled": c.require_settled}
    for name in ("max_overshoot", "max_steady_state_error", "max_u"):
        v = getattr(c, name)
        if v is not None:
            out[name] = float(v)
    return out


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


def write_gains_toml(path: str | Path, tuned: TunedGains) -> Path:
    """Write ``tuned`` to a TOML file (gains, setup, constraints, metrics, stages, provenance).

    Raises
    ------
    InputError
        If the file cannot be written.
    """
    s = tuned.setup
    b = s.search_bounds()
    doc: dict[str, Any] = {
        "format": _FORMAT,
        "controller": tuned.controller,
        "gains": dict(tuned.gains),
        "tuning": {
            "plant": s.plant, "param_set": s.param_set,
            "overrides": {k: float(v) for k, v in s.overrides},
            "start": s.start, "step": s.step, "duration": s.duration, "ts": s.ts,
            "delay": s.delay, "objective": s.objective, "seed": s.seed,
            "popsize": s.popsize, "maxiter": s.maxiter, "pid_n": s.pid_n, "polish": s.polish,
            "constraints": _constraints_table(s.constraints),
            "bounds": {n: [lo, hi, lg] for n, lo, hi, lg in
                       zip(b.names, b.lower, b.upper, b.log_scale, strict=True)},
        },
        "result": {"objective_value": tuned.objective_value, "cost": tuned.cost,
                   "feasible": tuned.feasible, "elapsed": tuned.elapsed,
                   "n_evaluations": tuned.n_evaluations,
                   "fuzzyservo_version": tuned.version, "date": tuned.date},
        "metrics": dict(tuned.metrics),
        "stages": [{"name": st.name, "gains": dict(st.gains), "metrics": dict(st.metrics),
                    "objective_value": st.objective_value, "feasible": st.feasible,
                    "n_evaluations": st.n_evaluations} for st in tuned.stages],
    }
    path = Path(path)
    try:
        path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot write {str(path)!r}: {exc.strerror}") from exc
    return path


class _Reader:
    def __init__(self, path: Path) -> None:
        self.path = path

    def get(self, table: Mapping[str, Any], key: str, kind: type | tuple[type, ...],
            where: str) -> Any:
        if key not in table:
            raise InputError(f"{str(self.path)!r}: missing key '{where}{key}'")
        v = table[key]
        if kind is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        if not isinstance(v, kind) or (kind is not bool and isinstance(v, bool)):
            raise InputError(f"{str(self.path)!r}: key '{where}{key}' has the wrong type "
                             f"({type(v).__name__}: {v!r})")
        return v

    def floats(self, table: Mapping[str, Any], where: str) -> dict[str, float]:
        return {str(k): float(self.get(table, k, float, where)) for k in table}


def read_gains_toml(path: str | Path) -> TunedGains:
    """Read a file written by :func:`write_gains_toml`.

    Raises
    ------
    InputError
        If the file is missing, not TOML, or lacks a key or has one of the wrong type (the
        message names the key).
    """
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read gains file {str(path)!r}: {exc.strerror}") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{str(path)!r} is not valid TOML: {exc}") from exc
    rd = _Reader(path)
    controller = rd.get(doc, "controller", str, "")
    gains = rd.floats(rd.get(doc, "gains", dict, ""), "gains.")
    tu = rd.get(doc, "tuning", dict, "")
    w = "tuning."
    ct = rd.get(tu, "constraints", dict, w)
    cw = "tuning.constraints."
    bt = tu.get("bounds")
    try:
        constraints = TuningConstraints(
            max_overshoot=rd.get(ct, "max_overshoot", float, cw) if "max_overshoot" in ct
            else None,
            max_steady_state_error=rd.get(ct, "max_steady_state_error", float, cw)
            if "max_steady_state_error" in ct else None,
            max_u=rd.get(ct, "max_u", float, cw) if "max_u" in ct else None,
            require_settled=rd.get(ct, "require_settled", bool, cw))
        bounds = None
        if isinstance(bt, dict) and bt:
            names = tuple(bt)
            rows = [bt[n] for n in names]
            if not all(isinstance(r, list) and len(r) == 3 for r in rows):
                raise InputError(f"{str(path)!r}: tuning.bounds entries must be "
                                 f"[lower, upper, log_scale]")
            bounds = GainBounds(names=names, lower=tuple(float(r[0]) for r in rows),
                                upper=tuple(float(r[1]) for r in rows),
                                log_scale=tuple(bool(r[2]) for r in rows))
        setup = TuningSetup(
            controller=controller, plant=rd.get(tu, "plant", str, w),
            param_set=rd.get(tu, "param_set", str, w),
            overrides=tuple(rd.floats(rd.get(tu, "overrides", dict, w),
                                      "tuning.overrides.").items()),
            start=rd.get(tu, "start", float, w), step=rd.get(tu, "step", float, w),
            duration=rd.get(tu, "duration", float, w), ts=rd.get(tu, "ts", float, w),
            delay=rd.get(tu, "delay", float, w), objective=rd.get(tu, "objective", str, w),
            constraints=constraints, seed=rd.get(tu, "seed", int, w),
            popsize=rd.get(tu, "popsize", int, w), maxiter=rd.get(tu, "maxiter", int, w),
            pid_n=rd.get(tu, "pid_n", float, w), polish=rd.get(tu, "polish", bool, w),
            bounds=bounds)
    except ParameterError as exc:
        raise InputError(f"{str(path)!r}: {exc}") from exc
    needed = PIDController.gain_names if controller in ("pid", "pid2") \
        else FuzzyPIController.gain_names
    missing = [n for n in needed if n not in gains]
    if missing:
        raise InputError(f"{str(path)!r}: missing key 'gains.{missing[0]}' "
                         f"({controller} needs {', '.join(needed)})")
    res = rd.get(doc, "result", dict, "")
    w = "result."
    metrics = rd.floats(rd.get(doc, "metrics", dict, ""), "metrics.")
    stages = []
    for i, st in enumerate(rd.get(doc, "stages", list, "")):
        sw = f"stages[{i}]."
        if not isinstance(st, dict):
            raise InputError(f"{str(path)!r}: stages[{i}] must be a table")
        stages.append(StageRecord(
            name=rd.get(st, "name", str, sw),
            gains=rd.floats(rd.get(st, "gains", dict, sw), sw + "gains."),
            metrics=rd.floats(rd.get(st, "metrics", dict, sw), sw + "metrics."),
            objective_value=rd.get(st, "objective_value", float, sw),
            feasible=rd.get(st, "feasible", bool, sw),
            n_evaluations=rd.get(st, "n_evaluations", int, sw)))
    return TunedGains(
        controller=controller, gains=gains, metrics=metrics,
        objective_value=rd.get(res, "objective_value", float, w),
        cost=rd.get(res, "cost", float, w), feasible=rd.get(res, "feasible", bool, w),
        setup=setup, elapsed=rd.get(res, "elapsed", float, w),
        n_evaluations=rd.get(res, "n_evaluations", int, w), stages=tuple(stages),
        version=rd.get(res, "fuzzyservo_version", str, w), date=rd.get(res, "date", str, w))
