"""The paper's study (Figs. 4-8 and its claims), run on the linear and the nonlinear plant.

The study computes first and renders second: :func:`run_plant_study` simulates every experiment
of one plant and returns a :class:`PlantStudy` record (traces, metrics, sweeps, claims);
``fuzzyservo.study.outputs`` writes figures, CSV, JSON and the HTML report from it.

Experiments per plant (all from rest at mid-stroke, a step of ``step`` metres, gains fixed):

- nominal step responses of PID (1.2, 1, 0.75), PID (0.8, 0.55, 0.5), the PIDs tuned to the
  paper's constraint (1-DOF and 2-DOF), the fuzzy PI and the self-tuning fuzzy PI (Figs. 4-7);
- the self-tuning fuzzy PI with the hose delay (Fig. 8) and a sweep of the delay for every
  controller, up to where it fails (no 2 % settling within the run, or divergence);
- every controller on changed plants (load mass x0.5 and x2, oil bulk modulus x0.5, supply
  pressure -500 kPa, and on the nonlinear plant a +-500 kPa supply ripple), gains fixed (C8);
  the self-tuning fuzzy PI's runs there are kept, to tell a limit cycle from a slow response.

A tuned PID-family design is named for the terms its gains use (``ControllerKind.structure``):
a "1-DOF PID" whose tuned ki and kd are 0 is a P controller and is labelled so.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..errors import ParameterError
from ..paper import PAPER_PIDS
from ..plant import ServoParams, with_overrides
from ..registry import controller_colour, controller_kind, plant_kind
from ..run import RunSpec, overrides_of
from ..sim import DEFAULT_DELAY, SimResult
from .claims import (
    Claim,
    Trace,
    command_amplitude,
    evaluate_claims,
    transient_window,
)
from .frequency import FrequencyConfig, FrequencyStudy, run_frequency_study
from .tracking import (
    BASELINE_DESIGNS,
    TrackingConfig,
    TrackingStudy,
    run_tracking_study,
    tracking_claim,
)

__all__ = [
    "CONTROLLER_KEYS",
    "DESIGN_COLOURS",
    "ControllerCase",
    "PlantStudy",
    "StudyConfig",
    "TRACKING_KEYS",
    "TUNED_AS",
    "TUNED_DESIGNS",
    "design_name",
    "run_plant_study",
    "study_cases",
    "variants",
]

#: The study's controllers, in legend order.
CONTROLLER_KEYS: tuple[str, ...] = (
    "pid_paper_1", "pid_paper_2", "pid_tuned", "pid2_tuned", "fpi", "stfpi", "stfpi_10")

#: The designs of the tracking study, in legend order: the study's, then the baselines.
TRACKING_KEYS: tuple[str, ...] = (*CONTROLLER_KEYS, *BASELINE_DESIGNS)

#: Tuned designs the study loads: study key -> (gain-file name, legend label).
#: The fuzzy PI and the self-tuning fuzzy PI of Figs. 4-8 are tuned for the behaviour the
#: paper reports for them (no overshoot, read as <= 0.5 %), following its steps 1-3; the
#: self-tuning fuzzy PI is also tuned like the PIDs (<= 10 % overshoot), to compare at equal
#: constraints.
TUNED_DESIGNS: dict[str, tuple[str, str]] = {
    "pid_tuned": ("pid", "PID tuned, 1-DOF (<= 10 %)"),
    "pid2_tuned": ("pid2", "PID tuned, 2-DOF (<= 10 %)"),
    "fpi": ("fpi-os0", "fuzzy PI (no overshoot design)"),
    "stfpi": ("stfpi-os0", "self-tuning fuzzy PI (no overshoot design)"),
    "stfpi_10": ("stfpi", "self-tuning fuzzy PI (<= 10 %, like the PIDs)"),
}

#: Colours of the designs that share their kind with another design of the study (each
#: other design is drawn in its kind's colour, ``registry.controller_colour``: tuned PID
#: brown, 2-DOF PID purple, fuzzy PI green, self-tuning fuzzy PI blue): the paper's PIDs red
#: and orange, the self-tuning fuzzy PI tuned like the PIDs pink, and Fig. 8's delayed run
#: vermillion beside the blue of the undelayed one.
DESIGN_COLOURS: dict[str, str] = {
    "pid_paper_1": "#d62728",
    "pid_paper_2": "#ff7f0e",
    "stfpi_10": "#e377c2",
    "stfpi_delay": "#d55e00",
}

#: What the tuned PID-family designs were tuned as: study key -> the design's full name.
#: A design whose gains leave out a term is named for what it is ("P (tuned as a 1-DOF PID,
#: <= 10 %)"): see :func:`design_name`.
TUNED_AS: dict[str, str] = {"pid_tuned": "1-DOF PID", "pid2_tuned": "2-DOF PID"}

#: A tuned design as the study takes it: (registered controller name, its gains).
Design = tuple[str, Mapping[str, float]]


@dataclass(frozen=True, slots=True, kw_only=True)
class StudyConfig:
    """Settings of the study; each is recorded in the report.

    Parameters
    ----------
    params : ServoParams
        The plant parameter set.
    set_name : str
        Its name (for the report).
    step : float
        Reference step from mid-stroke [m].
    duration : float
        Length of each run [s].
    ts : float
        Controller sample time [s].
    delay : float
        Transport delay of every run but Fig. 8's and the sweep's [s]: the package's one
        default, ``DEFAULT_DELAY`` (none, as the paper's Figs. 4-7), so that a metrics row is
        what ``fuzzyservo simulate`` prints with no extra flag.
    hose_delay : float or None
        Hose delay of Fig. 8 [s]; None takes the parameter set's ``delay.transport_delay``
        (Table A.1's 6 ms for the paper set).
    delay_sweep : tuple of float
        Delays of the sweep [s].
    pid_filter : float
        Derivative filter coefficient N of the paper's PIDs [1/s] (Simulink's default, 100).
    systems : tuple of (str, LoopSystem)
        Fuzzy systems from files by role (``du``, ``alpha``) in place of the paper's Fig. 3
        for every fuzzy controller of the study (``reproduce --du-system``); empty: the
        paper's.
    no_rule_value : float or None
        The value those systems were read with where no rule fires (``reproduce
        --no-rule-value``; recorded in each run's :class:`~fuzzyservo.run.RunSpec`); None:
        each file's own.
    tracking : TrackingConfig or None
        The tracking and disturbance study (claim C9) with these experiments; None: not run
        (``fuzzyservo reproduce`` runs it with the defaults of :class:`TrackingConfig`).
    frequency : FrequencyConfig or None
        The closed loops' frequency responses of the tracking study's designs; None: not run
        (``fuzzyservo reproduce`` runs them with the defaults of :class:`FrequencyConfig`).
    """

    params: ServoParams
    set_name: str = "paper"
    step: float = 0.1
    duration: float = 20.0
    ts: float = 0.001
    delay: float = DEFAULT_DELAY
    hose_delay: float | None = None
    delay_sweep: tuple[float, ...] = (0.0, 0.006, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.08,
                                      0.1, 0.125, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.8,
                                      1.0)
    pid_filter: float = 100.0
    systems: tuple[tuple[str, Any], ...] = ()
    no_rule_value: float | None = None
    tracking: TrackingConfig | None = None
    frequency: FrequencyConfig | None = None

    def __post_init__(self) -> None:
        for role, _ in self.systems:
            if role not in ("du", "alpha"):
                raise ParameterError(f"StudyConfig.systems roles are du and alpha, got {role!r}")
        for name in ("step", "duration", "ts"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ParameterError(f"StudyConfig.{name} must be > 0, got {v!r}")
        if not (math.isfinite(self.delay) and self.delay >= 0.0):
            raise ParameterError(f"StudyConfig.delay must be >= 0 s, got {self.delay!r}")
        if self.duration < 10 * self.ts:
            raise ParameterError(
                f"StudyConfig.duration must cover at least 10 samples, got {self.duration!r} s")

    def system_map(self) -> dict[str, Any] | None:
        """The fuzzy systems by role for the registry (the paper's where not given), or None
        for the paper's."""
        if not self.systems:
            return None
        from ..registry import default_systems

        given = dict(self.systems)
        return {**default_systems(tuple(r for r in ("du", "alpha") if r not in given)),
                **given}

    def run_spec(self, plant: str, case: ControllerCase, *,
                 params: ServoParams | None = None) -> RunSpec:
        """The run of ``case`` on ``plant`` (on ``params``, default :attr:`params`): a step
        of :attr:`step` from rest at mid-stroke, :attr:`duration`, :attr:`ts` and
        :attr:`delay`; the parameters as the set with the overrides that make them, the
        fuzzy systems by their files. ``fuzzyservo simulate`` with its
        :meth:`~fuzzyservo.run.RunSpec.to_argv` makes the same run."""
        p = self.params if params is None else params
        return RunSpec(controller=case.kind, gains=tuple(case.gains.items()),
                       systems=tuple((role, s.source) for role, s in self.systems),
                       no_rule_value=self.no_rule_value if self.systems else None,
                       plant=plant, param_set=self.set_name,
                       overrides=overrides_of(p, self.set_name),
                       reference=f"step:{self.step!r}", duration=self.duration, ts=self.ts,
                       delay=self.delay, start=0.5)

    @property
    def fig8_delay(self) -> float:
        """The hose delay of Fig. 8 [s]: ``hose_delay``, or the parameter set's."""
        if self.hose_delay is None:
            return float(self.params.delay.transport_delay)
        return float(self.hose_delay)


@dataclass(frozen=True, slots=True)
class ControllerCase:
    """A controller of the study: key, legend label, registered controller name and gains."""

    key: str
    label: str
    kind: str
    gains: dict[str, float]

    @property
    def colour(self) -> str:
        """The design's colour in every figure: its own (:data:`DESIGN_COLOURS`), else its
        kind's (the registry's, as the page draws the kind's runs)."""
        return DESIGN_COLOURS.get(self.key) or controller_colour(self.kind)


def study_cases(tuned: Mapping[str, Design], pid_filter: float = 100.0, *,
                paper: Mapping[str, Design] | None = None) -> list[ControllerCase]:
    """The study's controllers: the paper's PIDs and the tuned designs.

    ``tuned`` maps each gain-file name of :data:`TUNED_DESIGNS` ("pid", "pid2", "fpi-os0",
    "stfpi-os0", "stfpi") to its design: the registered controller name and its gains. The
    paper's PIDs are the registry's ``pid`` with the derivative filter ``pid_filter`` [1/s],
    unless ``paper`` gives them (key of :data:`~fuzzyservo.paper.PAPER_PIDS` -> design; e.g.
    a ``pid2`` with c = 0, which has no derivative kick). A tuned PID-family design whose
    gains leave out a term is labelled by its structure (:func:`design_name`).
    """
    cases = []
    for key, g in PAPER_PIDS.items():
        if paper is not None and key in paper:
            kind, gains = paper[key]
            full = controller_kind(kind).check_gains(gains, where=f"paper design {key}: ")
            label = f"PID ({full['kp']:g}, {full['ki']:g}, {full['kd']:g})"
            if "c" in full:  # a setpoint-weighted PID says its weights
                label += f", b = {full['b']:g}, c = {full['c']:g}"
            cases.append(ControllerCase(key, label, kind, full))
            continue
        cases.append(ControllerCase(key, f"PID ({g.kp:g}, {g.ki:g}, {g.kd:g})", "pid",
                                    {"kp": g.kp, "ki": g.ki, "kd": g.kd, "n": pid_filter}))
    for key, (name, label) in TUNED_DESIGNS.items():
        if name not in tuned:
            raise ParameterError(f"tuned gains for {name!r} are missing")
        kind, gains = tuned[name]
        full = controller_kind(kind).check_gains(gains, where=f"tuned design {name}: ")
        structure = controller_kind(kind).structure(full)
        if key in TUNED_AS and structure != "PID":
            label = f"{structure} (tuned as a {TUNED_AS[key]}, <= 10 %)"
        cases.append(ControllerCase(key, label, kind, full))
    return cases


def design_name(case: ControllerCase) -> str:
    """A tuned PID-family design named by the terms its gains use: "2-DOF PID" when all
    three are in use, else e.g. "P (1-DOF PID with ki = kd = 0)"; other cases: their label."""
    if case.key not in TUNED_AS:
        return case.label
    structure = controller_kind(case.kind).structure(case.gains)
    if structure == "PID":
        return TUNED_AS[case.key]
    zero = [g for g in ("ki", "kd") if case.gains.get(g, 0.0) == 0.0]
    return f"{structure} ({TUNED_AS[case.key]} with {' = '.join(zero)} = 0)"


def variants(kind: str, params: ServoParams) -> dict[str, ServoParams]:
    """The changed plants of claim C8 (gains fixed)."""
    out = {
        "load mass x0.5": with_overrides(params, {"load.mass": 0.5 * params.load.mass}),
        "load mass x2": with_overrides(params, {"load.mass": 2.0 * params.load.mass}),
        "oil bulk modulus x0.5": with_overrides(
            params, {"fluid.oil_bulk_modulus": 0.5 * params.fluid.oil_bulk_modulus}),
        "supply pressure -500 kPa": with_overrides(
            params, {"supply.pressure": params.supply.pressure - 5.0e5}),
    }
    if plant_kind(kind).supply_ripple:  # only a model with the supply in it feels a ripple
        out["supply ripple +-500 kPa"] = with_overrides(
            params, {"supply.ripple_amplitude": 5.0e5})
    return out


def metrics_dict(res: SimResult, step: float) -> dict[str, float]:
    """Step metrics of a run (the same call ``fuzzyservo simulate --metrics`` makes)."""
    m = res.metrics().as_dict()
    m["steady_state_error_fraction"] = m["steady_state_error"] / step
    return m


def _batch_metrics(names: Sequence[str], row: FloatArray, step: float,
                   diverged: bool) -> dict[str, float]:
    m = {n: float(v) for n, v in zip(names, row, strict=True)}
    m["steady_state_error_fraction"] = m["steady_state_error"] / step
    m["diverged"] = float(diverged)
    return m


def _trace(res: SimResult) -> Trace:
    return res.t, res.y, res.r


@dataclass(frozen=True, slots=True, kw_only=True)
class PlantStudy:
    """Everything the study computed for one plant."""

    plant: str
    cases: tuple[ControllerCase, ...]
    runs: dict[str, SimResult]
    metrics: dict[str, dict[str, float]]
    delayed: SimResult
    delayed_metrics: dict[str, float]
    delays: FloatArray
    sweep: dict[str, dict[str, FloatArray]]  # key -> metric -> (n_delays,)
    delay_margins: dict[str, float]
    delay_failures: dict[str, list[float]]
    variant_metrics: dict[str, dict[str, dict[str, float]]]
    variant_runs: dict[str, SimResult]  # self-tuning fuzzy PI on each changed plant
    claims: list[Claim] = field(default_factory=list)
    tracking: TrackingStudy | None = None  # the tracking and disturbance study, if run
    tracking_cases: tuple[ControllerCase, ...] = ()  # its designs: cases, then baselines
    frequency: FrequencyStudy | None = None  # the frequency responses, if run


def _failed(settling: float, diverged: bool) -> bool:
    return diverged or math.isnan(settling)


def run_plant_study(kind: str, cfg: StudyConfig, tuned: Mapping[str, Design],
                    *, tick: Callable[[str], None] | None = None,
                    stfpi_overshoot_limit: float | None = None,
                    changed_plants: Mapping[str, ServoParams] | None = None,
                    paper: Mapping[str, Design] | None = None) -> PlantStudy:
    """Run every experiment of the study on one plant ("linear" or "nonlinear").

    ``tick(stage)`` is called after each stage, for a progress display;
    ``stfpi_overshoot_limit`` [%] is the constraint the self-tuning design was tuned under
    (it qualifies claim C1); ``changed_plants`` (name -> parameters) replaces the changed
    plants of C8 (default :func:`variants`); ``paper`` replaces designs of the paper's PIDs
    (see :func:`study_cases`).
    """
    def done(stage: str) -> None:
        if tick is not None:
            tick(stage)

    cases = study_cases(tuned, cfg.pid_filter, paper=paper)
    paper_keys = tuple(PAPER_PIDS)
    # C3's window: ten time constants of the slowest derivative filter of the paper's PIDs
    after = max(transient_window(float(c.gains.get("n", math.inf)), cfg.ts)
                for c in cases if c.key in paper_keys)
    systems = cfg.system_map()
    specs = {case.key: cfg.run_spec(kind, case) for case in cases}
    runs: dict[str, SimResult] = {}
    metrics: dict[str, dict[str, float]] = {}
    for case in cases:
        runs[case.key] = specs[case.key].build(params=cfg.params, systems=systems).simulate()
        metrics[case.key] = metrics_dict(runs[case.key], cfg.step)
        metrics[case.key].update(command_amplitude(runs[case.key].t, runs[case.key].u,
                                                   after=after))
    done(f"{kind}: nominal runs")

    st_spec = replace(specs["stfpi"], delay=cfg.fig8_delay)
    delayed = st_spec.build(params=cfg.params, systems=systems).simulate()
    delayed_metrics = metrics_dict(delayed, cfg.step)
    delayed_metrics.update(command_amplitude(delayed.t, delayed.u, after=after))

    delays = np.asarray(cfg.delay_sweep, dtype=np.float64)
    sweep: dict[str, dict[str, FloatArray]] = {}
    margins: dict[str, float] = {}
    failures: dict[str, list[float]] = {}
    batches = {case.key: specs[case.key].build_batch(params=cfg.params, systems=systems)
               for case in cases}
    for case in cases:
        batch = batches[case.key]
        b = batch.simulate(np.tile(batch.row(case.gains), (delays.size, 1)), delay=delays)
        sweep[case.key] = {n: b.metric(n).copy() for n in ("overshoot", "settling_time",
                                                           "iae", "u_max")}
        sweep[case.key]["diverged"] = b.diverged.astype(np.float64)
        failed = [_failed(float(ts_), bool(dv))
                  for ts_, dv in zip(b.metric("settling_time"), b.diverged, strict=True)]
        failures[case.key] = [float(d) for d, f in zip(delays, failed, strict=True) if f]
        first = failed.index(True) if any(failed) else len(failed)
        margins[case.key] = float(delays[first - 1]) if first > 0 else math.nan
    done(f"{kind}: delay sweep")

    var_params = dict(variants(kind, cfg.params) if changed_plants is None
                      else changed_plants)
    # each changed plant is the run's plant on its parameters (a RunSpec of its own below)
    var_plants = [specs["stfpi"].plant_of(p) for p in var_params.values()]
    var_metrics: dict[str, dict[str, dict[str, float]]] = {v: {} for v in var_params}
    var_runs: dict[str, SimResult] = {}
    for case in (cases if var_plants else ()):
        batch = batches[case.key]
        b = batch.simulate(np.tile(batch.row(case.gains), (len(var_plants), 1)),
                           plant=var_plants)
        for i, name in enumerate(var_params):
            var_metrics[name][case.key] = _batch_metrics(b.metric_names, b.metrics[i],
                                                         cfg.step, bool(b.diverged[i]))
    st_case = next(c for c in cases if c.key == "stfpi")
    for name, p in var_params.items():
        if var_metrics[name]["stfpi"]["diverged"]:
            continue  # no trace to keep; the claim reads the batch's divergence flag
        var_runs[name] = cfg.run_spec(kind, st_case, params=p).build(
            params=p, systems=systems).simulate()
    done(f"{kind}: changed plants")

    labels = {c.key: c.label for c in cases}
    claims = evaluate_claims(
        kind, metrics, labels, stfpi="stfpi", fpi="fpi",
        paper_pids=paper_keys, tuned_pids=("pid_tuned", "pid2_tuned"),
        alpha_trace=(runs["stfpi"].t, runs["stfpi"].alpha), delayed=delayed_metrics,
        delay=cfg.fig8_delay, delay_margins=margins, variants=var_metrics,
        duration=cfg.duration, amplitude_after=after,
        stfpi_equal="stfpi_10", delay_failures=failures,
        stfpi_overshoot_limit=stfpi_overshoot_limit, delay_sweep=tuple(delays),
        delayed_trace=_trace(delayed),
        variant_traces={name: _trace(r) for name, r in var_runs.items()})
    tracking: TrackingStudy | None = None
    t_cases: list[ControllerCase] = []
    if cfg.tracking is not None or cfg.frequency is not None:
        t_cases = [*cases, *baseline_cases(tuned)]
    by_key = {c.key: c for c in t_cases}
    if cfg.tracking is not None:
        tracking = run_tracking_study(
            kind, lambda key: cfg.run_spec(kind, by_key[key]), [c.key for c in t_cases],
            cfg.tracking, params=cfg.params, systems=systems, tick=tick,
            keep=(f"sine_{cfg.tracking.figure_frequency(cfg.params.velocity_gain):g}", "move",
                  "load"))
        claims.append(tracking_claim(tracking, {c.key: c.label for c in t_cases},
                                     subject="stfpi", capacity=cfg.params.velocity_gain,
                                     tcfg=cfg.tracking))
    frequency: FrequencyStudy | None = None
    if cfg.frequency is not None:
        frequency = run_frequency_study(
            kind, lambda key: cfg.run_spec(kind, by_key[key]), [c.key for c in t_cases],
            cfg.frequency, params=cfg.params, systems=systems, tick=tick)
    return PlantStudy(plant=kind, cases=tuple(cases), runs=runs, metrics=metrics,
                      delayed=delayed, delayed_metrics=delayed_metrics, delays=delays,
                      sweep=sweep, delay_margins=margins, delay_failures=failures,
                      variant_metrics=var_metrics,
                      variant_runs=var_runs, claims=claims, tracking=tracking,
                      tracking_cases=tuple(t_cases), frequency=frequency)


def baseline_cases(tuned: Mapping[str, Design]) -> list[ControllerCase]:
    """The baselines of the tracking study (:data:`~fuzzyservo.study.tracking.BASELINE_DESIGNS`)
    from their tuned designs in ``tuned`` (by gain-file name).

    Raises
    ------
    ParameterError
        A baseline's tuned gains are missing.
    """
    out = []
    for key, (name, label) in BASELINE_DESIGNS.items():
        if name not in tuned:
            raise ParameterError(f"tuned gains for the baseline {name!r} are missing (the "
                                 f"tracking study compares every baseline)")
        kind, gains = tuned[name]
        full = controller_kind(kind).check_gains(gains, where=f"tuned design {name}: ")
        out.append(ControllerCase(key, label, kind, full))
    return out
