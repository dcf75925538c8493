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
import hashlib
import json
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .._args import seed as check_seed
from .._typing import FloatArray
from ..control.fuzzy_pi import KernelSystem
from ..errors import FuzzyServoError, ParameterError
from ..plant import ServoParams, to_dict
from ..plant.zoh import check_delay
from ..registry import (
    DEFAULT_SUBSTEP,
    ControllerKind,
    controller_kind,
    default_systems,
    plant_kind,
)
from ..run import BatchRun, RunSpec, run_default
from ..sim import Plant, Step, parse_reference
from ..sim.closed_loop import plant_limits, time_grid
from ..sim.references import check_reference_samples
from ..sim.result import BatchResult
from ..sim.stepinfo import METRIC_NAMES, SETTLE_HOLD_FRACTION
from .robust import RobustRecord, RobustSet, aggregate
from .tuning import (
    DEFAULT_PATIENCE,
    DEFAULT_RTOL,
    DEFAULT_SPREAD,
    FINAL_ERROR,
    OBJECTIVES,
    GainBounds,
    SearchState,
    StopRule,
    TuningConstraints,
    TuningResult,
    constraint_violation,
    penalised_cost,
    tune,
)

__all__ = [
    "DEFAULT_MAXITER",
    "DEFAULT_RESTARTS",
    "MAX_RESTARTS",
    "RESTART_TOLERANCE",
    "MAX_MAXITER",
    "MAX_POPSIZE",
    "Checkpoint",
    "DoneStage",
    "StageRecord",
    "TunedGains",
    "TuningProgress",
    "TuningSetup",
    "check_run",
    "default_bounds",
    "full_gains",
    "make_evaluator",
    "params_digest",
    "setup_record",
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
#: Largest generation limit: 10 times the default; the stopping rule ends a search long before.
MAX_MAXITER = 5000
#: Default generation limit of a search stage: a budget the default searches of the study's
#: designs stay well below (they converge in 40-330 generations, benchmarks/tuning_seeds.py).
DEFAULT_MAXITER = 500
#: Default number of independent searches per stage: the self-tuning fuzzy PI's cost has
#: several basins and one converged search can end in the worse one (docs/model.md).
DEFAULT_RESTARTS = 3
#: Largest number of restarts.
MAX_RESTARTS = 20
#: Relative disagreement of a stage's restarts above which the tuning warns that the best may
#: not be the global optimum [-].
RESTART_TOLERANCE = 0.01


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
        limit (1 to :data:`MAX_MAXITER`) of each search stage; the limit is a budget, the
        stopping rule normally ends the search first.
    restarts : int
        Independent searches per stage (1 to :data:`MAX_RESTARTS`), each from its own
        initial population; the best is kept and their disagreement recorded.
    patience, rtol, spread : int, float, float
        Stopping rule (:class:`fuzzyservo.analysis.tuning.StopRule`): converged when the best
        cost improved by no more than ``rtol`` (relative) over ``patience`` generations and
        the population's median cost is within ``spread`` (relative) of the best.
    pid_n : float
        Derivative filter coefficient n held while tuning a kind with that gain [1/s].
    polish : bool
        Finish each search stage with a bounded Nelder-Mead polish (serial runs).
    bounds : GainBounds or None
        Search box; None uses :func:`default_bounds`.
    systems : tuple of (str, str, str)
        Fuzzy systems read from files, as (role, source, SHA-256 of the system's values)
        (recorded; the caller passes the systems themselves to :func:`tune_controller`);
        empty: the paper's.
    robust : RobustRecord or None
        A robust tuning: the set of plants it runs on and the statistic of the objective over
        them (recorded; the caller passes the set itself to :func:`tune_controller`). The
        plant, parameter set, overrides, start, step, duration, ts and delay above are then
        the set's nominal ones (what ``fuzzyservo simulate --gains`` runs). None: the one
        plant above.
    """

    controller: str
    plant: str = "linear"
    param_set: str = "paper"
    overrides: tuple[tuple[str, float], ...] = ()
    start: float = run_default("start")
    step: float = 0.1
    duration: float = 10.0
    ts: float = run_default("ts")
    delay: float = run_default("delay")
    objective: str = "itae"
    constraints: TuningConstraints = field(default_factory=TuningConstraints)
    seed: int = 0
    popsize: int = 10
    maxiter: int = DEFAULT_MAXITER
    patience: int = DEFAULT_PATIENCE
    rtol: float = DEFAULT_RTOL
    spread: float = DEFAULT_SPREAD
    restarts: int = DEFAULT_RESTARTS
    pid_n: float = 100.0
    polish: bool = True
    bounds: GainBounds | None = None
    systems: tuple[tuple[str, str, str], ...] = ()
    robust: RobustRecord | None = None

    def __post_init__(self) -> None:
        kind = controller_kind(self.controller)
        if self.robust is not None and not isinstance(self.robust, RobustRecord):
            raise ParameterError(f"TuningSetup.robust must be a RobustRecord or None, got "
                                 f"{type(self.robust).__name__}")
        for item in self.systems:
            if len(item) != 3 or item[0] not in kind.systems:
                raise ParameterError(f"systems entries are (role, source, sha256) with a role "
                                     f"of {self.controller} ({', '.join(kind.systems) or 'none'})"
                                     f", got {item!r}")
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
        check_seed(self.seed, "seed")
        if not 2 <= self.popsize <= MAX_POPSIZE:
            raise ParameterError(f"popsize must be between 2 and {MAX_POPSIZE}, got "
                                 f"{self.popsize!r}")
        if not 1 <= self.maxiter <= MAX_MAXITER:
            raise ParameterError(f"maxiter must be between 1 and {MAX_MAXITER}, got "
                                 f"{self.maxiter!r}")
        StopRule(patience=self.patience, rtol=self.rtol, spread=self.spread)  # checks them
        if not (isinstance(self.restarts, int) and 1 <= self.restarts <= MAX_RESTARTS):
            raise ParameterError(f"restarts must be an integer from 1 to {MAX_RESTARTS}, got "
                                 f"{self.restarts!r}")
        b = self.bounds
        if b is not None and b.names != default_bounds(self.controller, self.step).names:
            raise ParameterError(
                f"bounds for {self.controller} must name "
                f"{default_bounds(self.controller, self.step).names}, got {b.names}")

    @classmethod
    def for_run(cls, run: RunSpec, *, systems: tuple[tuple[str, str, str], ...] = (),
                **search: Any) -> TuningSetup:
        """The tuning of ``run``'s controller on ``run``: its plant, parameter set and
        overrides, start, duration, sample time and delay; its reference must be a step
        from t = 0 (``step:A``: the tuning's step). ``systems`` records the fuzzy systems
        of ``run.systems`` as read, (role, source, SHA-256); ``search`` sets the other
        fields (objective, constraints, seed, ...). The run's gains are what is tuned.

        Raises
        ------
        ParameterError
            Another reference, controller options or measurement noise (the tuner runs
            neither), or a field the setup refuses.
        """
        ref = parse_reference(run.reference)
        if not isinstance(ref, Step) or ref.time != 0.0:
            raise ParameterError(f"the tuner tunes a step response from t = 0: choose the "
                                 f"reference step:A, not {run.reference!r}")
        if run.options:
            raise ParameterError(f"the tuner tunes without controller options: drop "
                                 f"{', '.join(name for name, _ in run.options)}")
        if run.noise_std != 0.0:
            raise ParameterError("the tuner tunes without measurement noise: set the noise "
                                 "to 0 (a robust tuning takes noise from its sweep spec)")
        if run.load_force:
            raise ParameterError(f"the tuner tunes without a load-force disturbance: clear "
                                 f"the load force ({run.load_force!r})")
        if run.substep != DEFAULT_SUBSTEP:
            raise ParameterError(f"the tuner runs the nonlinear plant at the default RK4 step "
                                 f"bound ({DEFAULT_SUBSTEP:g} s): drop the substep "
                                 f"{run.substep!r}")
        files = dict(run.systems)
        if any(files.get(role) != source for role, source, _ in systems):
            raise ParameterError("TuningSetup.for_run: systems must record fuzzy systems of "
                                 "the run's files, (role, file, sha256)")
        return cls(controller=run.controller, plant=run.plant, param_set=run.param_set,
                   overrides=run.overrides, start=run.start, step=float(ref.amplitude),
                   duration=run.duration, ts=run.ts, delay=run.delay, systems=systems,
                   **search)

    def run_spec(self, controller: str | None = None,
                 gains: Mapping[str, float] | None = None) -> RunSpec:
        """The run each candidate of the tuning is (of ``controller``, default
        :attr:`controller`; a stage of the paper's steps tunes another kind): a step of
        :attr:`step` from rest at :attr:`start`, on the nominal plant of a robust tuning;
        the fuzzy systems by the files they were read from. With ``gains``, the run of those
        gains: what ``fuzzyservo simulate`` with its ``to_argv()`` makes. (A value where no
        rule fires given with the files is not a setting of the tuning: its systems are
        recorded by the digest of what was read; add ``no_rule_value`` to replay such a
        run.)"""
        kind = controller_kind(self.controller if controller is None else controller)
        return RunSpec(controller=kind.name, gains=tuple((gains or {}).items()),
                       systems=tuple((r, src) for r, src, _ in self.systems
                                     if r in kind.systems),
                       plant=self.plant, param_set=self.param_set, overrides=self.overrides,
                       reference=f"step:{self.step!r}", duration=self.duration, ts=self.ts,
                       delay=self.delay, start=self.start)

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

    @property
    def stop(self) -> StopRule:
        """The stopping rule of every search stage."""
        return StopRule(patience=self.patience, rtol=self.rtol, spread=self.spread)


def setup_record(setup: TuningSetup) -> dict[str, Any]:
    """Every setting of ``setup`` as plain values (TOML/JSON), in a fixed order: what a gains
    file's ``[tuning]`` table and a checkpoint record (a resume is refused unless it is
    equal, :func:`tune_controller`)."""
    b = setup.search_bounds()
    c = setup.constraints
    cons: dict[str, Any] = {"require_settled": c.require_settled}
    for name in ("max_overshoot", "max_steady_state_error", "max_u"):
        v = getattr(c, name)
        if v is not None:
            cons[name] = float(v)
    return {
        "controller": setup.controller, "plant": setup.plant, "param_set": setup.param_set,
        "overrides": {k: float(v) for k, v in setup.overrides},
        "start": setup.start, "step": setup.step, "duration": setup.duration,
        "ts": setup.ts, "delay": setup.delay, "objective": setup.objective,
        "seed": setup.seed, "popsize": setup.popsize, "maxiter": setup.maxiter,
        "patience": setup.patience, "rtol": setup.rtol, "spread": setup.spread,
        "restarts": setup.restarts, "pid_n": setup.pid_n,
        "polish": setup.polish, "constraints": cons,
        "bounds": {n: [lo, hi, lg, zr] for n, lo, hi, lg, zr in
                   zip(b.names, b.lower, b.upper, b.log_scale, b.zero, strict=True)},
    } | ({"systems": {role: {"source": src, "sha256": digest}
                      for role, src, digest in setup.systems}} if setup.systems else {}) \
      | ({"robust": setup.robust.record()} if setup.robust is not None else {})


#: The command-line option of each setting, for the message refusing a resume.
_OPTION = {"controller": "--controller", "plant": "--plant", "param_set": "--set",
           "overrides": "--param/--params", "start": "--start", "step": "--step",
           "duration": "--duration", "ts": "--ts", "delay": "--delay",
           "objective": "--objective", "seed": "--seed", "popsize": "--popsize",
           "maxiter": "--maxiter", "constraints": "--max-overshoot/--max-sse/--max-u",
           "polish": "--no-polish", "patience": "--patience", "rtol": "--rtol",
           "spread": "--spread", "restarts": "--restarts",
           "systems": "--du-system/--alpha-system", "robust": "--robust/--statistic"}


def params_digest(params: ServoParams) -> str:
    """SHA-256 of every parameter value (``repr``): a checkpoint's parameters, compared on
    resume whatever set them (named set, ``--param``, ``--params`` file)."""
    blob = json.dumps(to_dict(params), sort_keys=True, default=repr)
    return hashlib.sha256(blob.encode()).hexdigest()


def default_bounds(controller: str, step: float = 0.1) -> GainBounds:
    """The registry's search box of ``controller`` for a step of ``step`` [m].

    See :class:`fuzzyservo.registry.GainSpec`: PID gains on log scales (kp 0.01-100 1/m,
    ki 0 or 1e-3-1000 1/(m s), kd 0 or 1e-4-10 s/m), pid2's b in [0, 1] linear; the fuzzy PIs'
    ke in [0.1, 100]/step 1/m, kde in [10, 1e6] per sample, kdu in [1e-5, 1] (docs/model.md,
    "Tuning").
    """
    box = controller_kind(controller).search_box(step)
    return GainBounds(names=tuple(b[0] for b in box), lower=tuple(b[1] for b in box),
                      upper=tuple(b[2] for b in box), log_scale=tuple(b[3] for b in box),
                      zero=tuple(b[4] for b in box))


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
    plant: Plant = setup.run_spec().plant_of(params)
    return plant


Evaluator = Callable[[FloatArray], dict[str, FloatArray]]

#: Samples of trace kept per batch of the evaluator (runs x samples), so that a population of
#: long runs is simulated in parts instead of holding every trace at once (40 MB per signal).
TRACE_SAMPLES = 5_000_000


def _batch(setup: TuningSetup, kind: ControllerKind, params: ServoParams,
           systems: Mapping[str, KernelSystem] | None) -> BatchRun:
    """The batch form of the run of ``kind``'s candidates, with the fuzzy systems given (None:
    the paper's; the setup records the files by digest, the caller passes what it read)."""
    given = default_systems() if systems is None else systems
    return setup.run_spec(kind.name).build_batch(params=params, systems=given)


def _evaluator(setup: TuningSetup, kind: ControllerKind, params: ServoParams,
               systems: Mapping[str, KernelSystem] | None) -> Evaluator:
    batch = _batch(setup, kind, params, systems)
    n_samples = time_grid(setup.duration, setup.ts).size
    per_batch = max(1, TRACE_SAMPLES // n_samples)

    def evaluate(gains: FloatArray) -> dict[str, FloatArray]:
        rows = full_gains(setup, gains, kind)
        parts = [_batch_metrics(batch.simulate(rows[i:i + per_batch], keep_traces=True))
                 for i in range(0, rows.shape[0], per_batch)]
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}

    return evaluate


def _batch_metrics(res: BatchResult) -> dict[str, FloatArray]:
    """Every metric the tuner reads of a batch kept with its traces: ``METRIC_NAMES`` and
    :data:`~fuzzyservo.analysis.tuning.FINAL_ERROR` (the largest |r - y| over the last
    ``SETTLE_HOLD_FRACTION`` of the run; NaN for a diverged run)."""
    part = {name: res.metric(name) for name in METRIC_NAMES}
    assert res.y is not None
    t = res.t
    tail = t >= t[0] + (1.0 - SETTLE_HOLD_FRACTION) * (t[-1] - t[0])
    e = res.y0[:, None] + res.r[None, tail] - res.y[:, tail]
    with np.errstate(invalid="ignore"):
        part[FINAL_ERROR] = np.where(res.diverged, np.nan, np.max(np.abs(e), axis=1))
    return part


def _robust_evaluator(setup: TuningSetup, kind: ControllerKind, params: ServoParams,
                      robust: RobustSet, systems: Mapping[str, KernelSystem] | None
                      ) -> Evaluator:
    """Candidates (n, k) -> metrics aggregated over the plants of ``robust``
    (:func:`fuzzyservo.analysis.robust.aggregate`): n x plants closed loops per call, in
    batches of at most :data:`TRACE_SAMPLES` samples of trace."""
    assert setup.robust is not None
    statistic = setup.robust.statistic
    # the template and the step of the run; the plants, delays and noise are the set's
    batch = _batch(setup, kind, params, systems)
    m = len(robust)
    n_samples = time_grid(setup.duration, setup.ts).size
    per_batch = max(1, TRACE_SAMPLES // n_samples)
    plants = list(robust.plants)

    def evaluate(gains: FloatArray) -> dict[str, FloatArray]:
        rows = full_gains(setup, gains, kind)
        n_runs = rows.shape[0] * m
        parts = []
        failed = []
        for lo in range(0, n_runs, per_batch):
            run = np.arange(lo, min(n_runs, lo + per_batch))
            j = run % m  # candidate-major: run = candidate * m + plant
            res = batch.simulate(rows[run // m], plant=[plants[i] for i in j],
                                 delay=robust.delays[j],
                                 noise=None if robust.noise is None else robust.noise[j],
                                 keep_traces=True)
            parts.append(_batch_metrics(res))
            failed.append(res.diverged)
        per_plant = {k: np.concatenate([p[k] for p in parts]).reshape(-1, m) for k in parts[0]}
        return aggregate(per_plant, np.concatenate(failed).reshape(-1, m), setup.objective,
                         statistic)

    return evaluate


def make_evaluator(setup: TuningSetup, params: ServoParams, *,
                   systems: Mapping[str, KernelSystem] | None = None,
                   robust: RobustSet | None = None) -> Evaluator:
    """Function mapping searched gains (n, k) to step metrics, one batched simulation per call.

    Parameters
    ----------
    setup : TuningSetup
        Controller, plant, step, horizon, sample time and delay.
    params : ServoParams
        Servo parameters (the set ``setup.param_set`` with ``setup.overrides`` applied).
    systems : mapping, optional
        Fuzzy systems by role (``du``, ``alpha``); default the paper's (Fig. 3).
    robust : RobustSet, optional
        The set of plants of a robust tuning (``setup.robust`` records it); then each
        candidate runs on every plant and its metrics are aggregated over them
        (:func:`fuzzyservo.analysis.robust.aggregate`: the objective's statistic, every
        other metric's worst case).

    Returns
    -------
    callable
        ``evaluate(gains)`` with gains (n, k) in the order of ``setup.search_bounds().names``
        returns ``{metric: array (n,)}`` for every name of ``METRIC_NAMES``; diverged runs
        have NaN metrics.

    Raises
    ------
    ParameterError
        ``robust`` given without ``setup.robust`` or the other way round, or a set of another
        size than recorded.
    """
    _check_robust(setup, robust)
    return _evaluator_of(setup, setup.kind, params, systems, robust)


def _evaluator_of(setup: TuningSetup, kind: ControllerKind, params: ServoParams,
                  systems: Mapping[str, KernelSystem] | None,
                  robust: RobustSet | None) -> Evaluator:
    """The evaluator of ``kind``: on the set ``robust`` if given, else on ``setup``'s plant."""
    if robust is not None:
        return _robust_evaluator(setup, kind, params, robust, systems)
    return _evaluator(setup, kind, params, systems)


def _check_robust(setup: TuningSetup, robust: RobustSet | None) -> None:
    if (setup.robust is None) != (robust is None):
        raise ParameterError("a robust tuning needs both TuningSetup.robust (its record) and "
                             "the set of plants itself; a nominal tuning neither")
    if robust is not None and setup.robust is not None and len(robust) != setup.robust.points:
        raise ParameterError(f"the robust set has {len(robust)} plants, its record says "
                             f"{setup.robust.points}")


@dataclass(frozen=True, slots=True, kw_only=True)
class DoneStage:
    """A completed stage, as a checkpoint keeps it.

    Attributes
    ----------
    gains : tuple of float
        Its searched gains (order of the search box) [gain units].
    n_evaluations, generations : int
        Closed-loop runs and generations it used.
    converged : bool
        Whether its search met the stopping rule (True for a stage that is not a search).
    cost : float
        Its penalised cost (to pick the best of a stage's restarts) [-].
    restart_spread : float
        Relative disagreement of the stage's restarts, (worst - best) / best [-].
    """

    gains: tuple[float, ...]
    n_evaluations: int
    generations: int = 0
    converged: bool = True
    cost: float = 0.0
    restart_spread: float = 0.0


@dataclass(frozen=True, slots=True, kw_only=True)
class Checkpoint:
    """State of a tuning after a generation, enough to resume it exactly.

    Attributes
    ----------
    setup : dict
        :func:`setup_record` of the tuning (a resume with another setting is refused).
    params : str
        :func:`params_digest` of its parameters.
    version : str
        fuzzyservo version that wrote it.
    stage : str
        Stage that was running.
    restart : int
        Which of the stage's independent searches (0-based).
    state : SearchState
        That search's state after its last completed generation.
    done : dict
        Completed stages by name, and completed restarts as ``"NAME#R"``.
    """

    setup: dict[str, Any]
    params: str
    version: str
    stage: str
    state: SearchState
    done: dict[str, DoneStage] = field(default_factory=dict)
    restart: int = 0

    @property
    def generation(self) -> int:
        """Generations completed in :attr:`stage`."""
        return self.state.generation


@dataclass(frozen=True, slots=True, kw_only=True)
class TuningProgress:
    """One generation of a search stage, for progress bars and checkpoints.

    Attributes
    ----------
    stage : str
        ``search`` (p, pi, pid, pid2, fpi), or ``fpi``, ``refine`` (stfpi steps 1 and 3).
    generation, max_generations : int
        Generations done (0: the initial population) and the limit of this stage.
    best_cost : float
        Best penalised cost so far [-].
    n_evaluations : int
        Closed-loop runs so far in this stage.
    checkpoint : Checkpoint
        Everything needed to resume from here.
    restart, restarts : int
        Which independent search of the stage this is (0-based), of how many.
    """

    stage: str
    generation: int
    max_generations: int
    best_cost: float
    n_evaluations: int
    checkpoint: Checkpoint
    restart: int = 0
    restarts: int = 1


@dataclass(frozen=True, slots=True, kw_only=True)
class StageRecord:
    """Result of one stage.

    Attributes
    ----------
    name : str
        Stage name (see :class:`TuningProgress`; ``rise`` for stfpi's step 2).
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
    generations : int
        Generations of its search (0 for a stage that is not a search).
    converged : bool
        Whether its search met the stopping rule (True for a stage that is not a search).
    at_bounds : dict
        Searched gains that ended on a bound of the stage's box, ``{name: "lower"|"upper"}``.
    restart_spread : float
        Relative disagreement of the stage's independent searches, (worst - best) / best of
        their penalised costs (0 for one search or a stage that is not a search) [-].
    """

    name: str
    gains: dict[str, float]
    metrics: dict[str, float]
    objective_value: float
    feasible: bool
    n_evaluations: int
    generations: int = 0
    converged: bool = True
    at_bounds: dict[str, str] = field(default_factory=dict)
    restart_spread: float = 0.0


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
    converged : bool
        Whether every search stage met the stopping rule.
    generations : int
        Generations of all search stages.
    at_bounds : dict
        Searched gains of the result that end on a bound of the default box,
        ``{name: "lower"|"upper"}`` (a PID's ki or kd at 0 is on its lower bound).
    restart_spread : float
        Largest disagreement of a search stage's independent searches [-]; above
        :data:`RESTART_TOLERANCE` the cost has several optima the searches ended in, and the
        best found may not be the global one.
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
    converged: bool = True
    generations: int = 0
    at_bounds: dict[str, str] = field(default_factory=dict)
    restart_spread: float = 0.0

    def stage(self, name: str) -> StageRecord:
        """The record of stage ``name``."""
        for s in self.stages:
            if s.name == name:
                return s
        raise ParameterError(f"no stage {name!r}; stages: {[s.name for s in self.stages]}")

    @property
    def structure(self) -> str:
        """What the design is (:meth:`fuzzyservo.registry.ControllerKind.structure`: a
        tuned PID with ki = kd = 0 is a "P")."""
        return controller_kind(self.controller).structure(self.gains)


# ---------------------------------------------------------------------------- tuning


def _record(name: str, setup: TuningSetup, kind: ControllerKind, searched: FloatArray,
            metrics: Mapping[str, Any], n_eval: int, *, generations: int = 0,
            converged: bool = True, at_bounds: Mapping[str, str] | None = None,
            restart_spread: float = 0.0) -> StageRecord:
    m = {k: float(np.asarray(v).reshape(-1)[0]) for k, v in metrics.items()}
    feasible = bool(constraint_violation({k: np.array([v]) for k, v in m.items()},
                                         setup.constraints, setup.step)[0] == 0.0)
    gains = _kind_gains(kind, setup, setup.search_bounds().names, np.atleast_2d(searched)[0])
    return StageRecord(name=name, gains=gains, metrics=m,
                       objective_value=m[setup.objective], feasible=feasible,
                       n_evaluations=n_eval, generations=generations, converged=converged,
                       at_bounds=dict(at_bounds or {}), restart_spread=restart_spread)


def restart_seed(seed: int, restart: int) -> int:
    """Seed of restart ``restart`` of a search seeded ``seed`` (restart 0 is ``seed``)."""
    if restart == 0:
        return seed
    return int(np.random.SeedSequence([seed, restart]).generate_state(1)[0])


def _search(setup: TuningSetup, evaluate: Evaluator, bounds: GainBounds, stage: str, *,
            popsize: int, init: FloatArray | None, resume: SearchState | None,
            restart: int, snapshot: Callable[[str, int, SearchState], Checkpoint],
            progress: Callable[[TuningProgress], None] | None) -> TuningResult:
    def on_gen(state: SearchState) -> None:
        if progress is not None:
            progress(TuningProgress(stage=stage, generation=state.generation,
                                    max_generations=setup.maxiter,
                                    best_cost=state.best_cost,
                                    n_evaluations=state.n_evaluations,
                                    checkpoint=snapshot(stage, restart, state),
                                    restart=restart, restarts=setup.restarts))

    try:
        return tune(evaluate, bounds, objective=setup.objective,
                    constraints=setup.constraints, step_size=setup.step,
                    seed=restart_seed(setup.seed, restart),
                    popsize=popsize, maxiter=setup.maxiter, stop=setup.stop,
                    polish=setup.polish, init=init, resume=resume, on_generation=on_gen)
    except Exception as exc:
        # an error of ours raised inside a library call: surface it, one line, as itself
        own = _own_error(exc)
        if own is None or own is exc:
            raise
        raise own from None


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


def _check_resume(resume: Checkpoint, setup: TuningSetup, params: ServoParams,
                  bounds: GainBounds) -> None:
    """Refuse a checkpoint of any other setting, parameters or version, naming the first."""
    mine = setup_record(setup)
    if "systems" in resume.setup and "systems" not in mine:
        raise ParameterError(f"the checkpoint was made with fuzzy systems from files "
                             f"({_show(resume.setup['systems'])}), this run has the paper's: "
                             f"resume with the same --du-system/--alpha-system, or run without "
                             f"--resume")
    theirs_robust = resume.setup.get("robust")
    if (theirs_robust is None) != (setup.robust is None):
        if theirs_robust is None:
            was = "a tuning on one plant"
        elif isinstance(theirs_robust, dict) and "spec" in theirs_robust:
            was = f"a robust tuning (--robust {_show(theirs_robust['spec'])})"
        else:
            was = "a robust tuning"
        now = "on one plant" if setup.robust is None else "a robust tuning"
        raise ParameterError(f"the checkpoint was made by {was}, this run is {now}: resume "
                             f"with the same options, or run without --resume")
    for key, value in mine.items():
        theirs = resume.setup.get(key, "(not recorded)")
        if theirs != value:
            opt = f" ({_OPTION[key]})" if key in _OPTION else ""
            raise ParameterError(
                f"the checkpoint was made with {key}{opt} = {_show(theirs)}, this run has "
                f"{_show(value)}: resume with the same settings, or run without --resume")
    extra = sorted(set(resume.setup) - set(mine))
    if extra:
        raise ParameterError(f"the checkpoint records a setting {extra[0]!r} this version "
                             f"does not have: run without --resume")
    if resume.params != params_digest(params):
        raise ParameterError("the checkpoint was made with other parameter values (--set, "
                             "--param or --params): resume with the same parameters, or run "
                             "without --resume")
    if resume.version != _version():
        raise ParameterError(f"the checkpoint was made by fuzzyservo {resume.version}, this "
                             f"is {_version()}: run without --resume")
    k = len(bounds.names)
    st = resume.state
    pop = st.population
    stages = (("search",) if setup.kind.tuning == "search" else
              (str(setup.kind.stage_kind), "refine"))

    def bad(what: str) -> ParameterError:
        return ParameterError(f"the checkpoint is damaged: {what}; delete it or run without "
                              f"--resume")

    m = max(5, setup.popsize * k)  # every search stage, the refinement too
    if resume.stage not in stages:
        raise bad(f"stage {resume.stage!r} is not one of {', '.join(stages)}")
    if not (isinstance(resume.restart, int) and 0 <= resume.restart < setup.restarts):
        raise bad(f"restart {resume.restart!r} is not in 0..{setup.restarts - 1}")
    if (pop.ndim != 2 or pop.shape[1] != k or pop.shape[0] != m
            or not np.all(np.isfinite(pop)) or np.any(pop < 0.0) or np.any(pop > 1.0)):
        raise ParameterError(f"the checkpoint population must hold {m} members with {k} columns "
                             f"({', '.join(bounds.names)}) in [0, 1], got shape {pop.shape}; "
                             f"delete the checkpoint or run without --resume")
    costs = st.costs
    if costs.shape != (pop.shape[0],) or not np.all(np.isfinite(costs)):
        raise bad(f"its costs must be {pop.shape[0]} finite numbers, got shape {costs.shape}")
    if not (isinstance(st.generation, int) and 0 <= st.generation <= setup.maxiter):
        raise bad(f"generation {st.generation!r} is not in 0..{setup.maxiter}")
    if (len(st.history) != st.generation + 1
            or not all(math.isfinite(h) for h in st.history)):
        raise bad(f"its history must hold {st.generation + 1} finite costs, got "
                  f"{len(st.history)}")
    if st.n_evaluations < pop.shape[0] * (st.generation + 1):
        raise bad(f"{st.n_evaluations} runs is fewer than its generations need")
    names = {f"{s}#{r}" for s in stages for r in range(setup.restarts)} | set(stages) | {"rise"}
    for name in resume.done:
        if name not in names:
            raise bad(f"completed stage {name!r} is not one of this tuning's")
        if not math.isfinite(resume.done[name].cost):
            raise bad(f"completed stage {name!r} has a cost that is not finite")
    for name, d in resume.done.items():
        if len(d.gains) != k or not all(math.isfinite(x) for x in d.gains):
            raise ParameterError(f"the checkpoint stage {name!r} must hold {k} finite gains, got "
                                 f"{len(d.gains)}; delete the checkpoint or run without "
                                 f"--resume")


def _show(v: Any) -> str:
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_show(x)}" for k, x in v.items()) + "}" if v else "none"
    return repr(v) if isinstance(v, str) else f"{v}"


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
                    resume: Checkpoint | None = None,
                    robust: RobustSet | None = None) -> TunedGains:
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
        Called with a :class:`TuningProgress` (holding a :class:`Checkpoint`) after the
        initial population and each generation of each search stage.
    resume : Checkpoint, optional
        Continue an interrupted run from its last checkpoint: the result (gains, metrics,
        objective, run and generation counts) equals the uninterrupted run's, bit for bit.
    robust : RobustSet, optional
        Tune on this set of plants instead of the one of ``setup`` (which ``setup.robust``
        records): every candidate runs on every plant, the objective is
        ``setup.robust.statistic`` over them and the constraints must hold on each
        (:func:`fuzzyservo.analysis.robust.aggregate`). The result's metrics are those
        aggregates: the worst case of each metric over the set, the objective's statistic,
        and the objective's worst case (``itae_worst``). ``params`` are then the set's
        nominal parameters.

    Returns
    -------
    TunedGains

    Raises
    ------
    ParameterError
        A missing fuzzy system, or a checkpoint of another setting (named), other
        parameters, another fuzzyservo version, or of the wrong shape; ``robust`` without
        ``setup.robust`` or the other way round.
    InputError
        The step leaves the stroke, or the transducer resolution is coarser than the step
        (:func:`check_run`).

    Notes
    -----
    Every search stage is a differential evolution that stops by ``setup.stop`` (or at
    ``setup.maxiter`` generations, then reported as not converged), plus a polish. The
    ``"paper-steps"`` procedure is the paper's Sec. III A, steps 1-3; step 2's rise-time
    match is a batched bracketing of the output gain (kdu) on a log grid followed by
    bisection to the smallest value >= step 1's whose 10-90 % rise time does not exceed step
    1's; step 3 is a search over the whole box, its initial population holding steps 1 and 2.
    Every search stage runs ``setup.restarts`` independent searches and keeps the best.
    """
    t0 = time.perf_counter()
    kind = setup.kind
    bounds = setup.search_bounds()
    _check_robust(setup, robust)
    if resume is not None:
        _check_resume(resume, setup, params, bounds)
    check_run(setup, params)
    done: dict[str, DoneStage] = dict(resume.done) if resume else {}
    record = setup_record(setup)
    digest = params_digest(params)
    version = _version()

    def snapshot(stage: str, restart: int, state: SearchState) -> Checkpoint:
        return Checkpoint(setup=record, params=digest, version=version, stage=stage,
                          state=state, done=dict(done), restart=restart)

    def resumed(stage: str, restart: int) -> SearchState | None:
        if resume is not None and (resume.stage, resume.restart) == (stage, restart):
            return resume.state
        return None

    def search(name: str, evaluate: Evaluator, box: GainBounds, popsize: int,
               init: Callable[[int], FloatArray | None]) -> tuple[FloatArray, StageRecord]:
        for r in range(setup.restarts):
            key = f"{name}#{r}"
            if key in done:
                continue
            res = _search(setup, evaluate, box, name, popsize=popsize, init=init(r),
                          resume=resumed(name, r), restart=r, snapshot=snapshot,
                          progress=progress)
            done[key] = DoneStage(gains=tuple(float(res.gains[n]) for n in box.names),
                                  n_evaluations=res.n_evaluations,
                                  generations=res.generations, converged=res.converged,
                                  cost=res.cost)
        runs = [done.pop(f"{name}#{r}") for r in range(setup.restarts)]
        costs = [d.cost for d in runs]
        best = runs[int(np.argmin(costs))]  # the first of equal ones
        low = min(costs)
        spread = (max(costs) - low) / max(abs(low), 1e-12)
        done[name] = DoneStage(gains=best.gains,
                               n_evaluations=sum(d.n_evaluations for d in runs),
                               generations=sum(d.generations for d in runs),
                               converged=all(d.converged for d in runs), cost=best.cost,
                               restart_spread=spread)
        return replay(name, evaluate)

    def replay(name: str, evaluate: Evaluator) -> tuple[FloatArray, StageRecord]:
        d = done[name]
        g = np.array([d.gains])
        return g, _record(name, setup, kind_of[name], g, evaluate(g), d.n_evaluations,
                          generations=d.generations, converged=d.converged,
                          at_bounds=bounds.at_bounds(g[0]), restart_spread=d.restart_spread)

    def evaluator_of(k: ControllerKind) -> Evaluator:
        return _evaluator_of(setup, k, params, systems, robust)

    stages: list[StageRecord] = []
    if kind.tuning == "search":
        kind_of = {"search": kind}
        evaluate = evaluator_of(kind)
        _, rec = (replay("search", evaluate) if "search" in done else
                  search("search", evaluate, bounds, setup.popsize, lambda r: None))
        stages.append(rec)
    else:
        assert kind.stage_kind is not None and kind.rise_gain is not None
        first = controller_kind(kind.stage_kind)
        if first.searched != kind.searched:
            raise ParameterError(f"{kind.name}: its step-1 kind {first.name} must search the "
                                 f"same gains")
        kind_of = {first.name: first, "rise": kind, "refine": kind}
        col = bounds.names.index(kind.rise_gain)
        ev1 = evaluator_of(first)
        ev = evaluator_of(kind)
        # step 1: the stage kind (the fuzzy PI, alpha = 1)
        g1, rec1 = (replay(first.name, ev1) if first.name in done else
                    search(first.name, ev1, bounds, setup.popsize, lambda r: None))
        stages.append(rec1)
        # step 2: the other gains kept; raise the output gain until the rise time is back
        if "rise" in done:
            g2, rec2 = replay("rise", ev)
        else:
            target = rec1.metrics["rise_time"]
            value, n2 = _rise_match(setup, ev, g1[0].copy(), col,
                                    target if math.isfinite(target) else math.inf,
                                    bounds.upper[col])
            g2 = g1.copy()
            g2[0, col] = value
            m2 = ev(g2)
            done["rise"] = DoneStage(gains=tuple(float(v) for v in g2[0]),
                                     n_evaluations=n2 + 1)
            rec2 = _record("rise", setup, kind, g2, m2, n2 + 1,
                           at_bounds=bounds.at_bounds(g2[0]))
        stages.append(rec2)
        # step 3: refine every searched gain, from a population seeded with steps 1 and 2
        if "refine" in done:
            _, rec3 = replay("refine", ev)
        else:
            m = max(5, setup.popsize * len(bounds.names))

            def init3(r: int) -> FloatArray:
                rng = np.random.default_rng(restart_seed(setup.seed, r))
                u = rng.random((m - 2, len(bounds.names)))
                return np.vstack([g2, g1, bounds.from_unit(u)])

            _, rec3 = search("refine", ev, bounds, setup.popsize, init3)
        stages.append(rec3)
    final = stages[-1]
    best_metrics = {k: np.array([v]) for k, v in final.metrics.items()}
    cost = float(penalised_cost(best_metrics, setup.objective, setup.constraints,
                                setup.step)[0])
    searches = [s for s in stages if s.name != "rise"]
    return TunedGains(
        controller=setup.controller, gains=dict(final.gains), metrics=dict(final.metrics),
        objective_value=final.objective_value, cost=cost, feasible=final.feasible,
        setup=setup, elapsed=time.perf_counter() - t0,
        n_evaluations=sum(s.n_evaluations for s in stages), stages=tuple(stages),
        version=version, date=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        converged=all(s.converged for s in searches),
        generations=sum(s.generations for s in searches),
        at_bounds=dict(final.at_bounds),
        restart_spread=max((s.restart_spread for s in searches), default=0.0))


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
                   n_evaluations=s.n_evaluations, stages=(s,), cost=cost,
                   converged=s.converged, generations=s.generations,
                   at_bounds=dict(s.at_bounds), restart_spread=s.restart_spread)
