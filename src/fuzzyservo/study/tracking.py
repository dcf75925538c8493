"""The tracking and disturbance study: beyond the step (docs/model.md, "Tracking and load
disturbances").

Every design of the paper's study and the baselines industry and research put beside a fuzzy
PI (:data:`BASELINE_DESIGNS`, tuned by the same tuner and constraints as the study's PIDs),
on each plant, from rest at mid-stroke, gains fixed:

- sine tracking, ``sine_amplitude`` at each of ``sine_frequencies``: RMS and largest error,
  amplitude ratio and phase lag over the last ``sine_periods`` whole periods
  (:func:`fuzzyservo.analysis.tracking.sine_metrics`);
- a jerk-limited (S-curve) point-to-point move: largest following error, overshoot and
  settling after the end of the move (:func:`~fuzzyservo.analysis.tracking.move_metrics`);
- a load-force step at rest, ``load_fraction`` of the force at supply pressure on the piston
  area (p_s A_A), opposing extension: largest deviation, recovery time to 2 % of it and the
  remaining deviation (:func:`~fuzzyservo.analysis.tracking.disturbance_metrics`).

Each run is a :class:`~fuzzyservo.run.RunSpec`, so ``fuzzyservo simulate`` with its
``to_argv()`` makes the same run. Claim C9 (the paper's "tracking ability") is judged from
these numbers by the rule in docs/model.md (:func:`tracking_claim`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from ..analysis.tracking import disturbance_metrics, move_metrics, sine_metrics
from ..errors import ParameterError
from ..run import RunSpec
from ..sim import SCurve, SimResult
from .claims import (
    CLAIM_RULES,
    CLAIM_TEXTS,
    HOLDS,
    NOT_HOLDS,
    PARTLY,
    TRACK_LAG_MAX_DEG,
    TRACK_RATIO_MAX,
    TRACK_RATIO_MIN,
    TRACK_RMS_VS_BEST,
    Claim,
    Value,
)

__all__ = [
    "BASELINE_DESIGNS",
    "TrackingConfig",
    "TrackingStudy",
    "run_tracking_study",
    "tracking_claim",
]

#: The baselines beside the paper's designs: study key -> (gain-file name, legend label).
#: Tuned like the study's PIDs (ITAE on the 0.1 m step, <= 10 % overshoot, no steady-state
#: error), by the same tuner (study.runner.study_jobs).
BASELINE_DESIGNS: dict[str, tuple[str, str]] = {
    "ffpd": ("ffpd", "position control with feed-forward (industrial axis)"),
    "smc": ("smc", "sliding-mode control"),
    "wfpi": ("wfpi", "self-tuning fuzzy PI (Woo et al. 2000)"),
}


@dataclass(frozen=True, slots=True, kw_only=True)
class TrackingConfig:
    """The experiments of the tracking study (docs/model.md, "Tracking and load
    disturbances", says why each value).

    Parameters
    ----------
    sine_amplitude : float
        Amplitude of the sines [m].
    sine_frequencies : tuple of float
        Their frequencies [Hz].
    sine_periods : int
        Whole periods at the end of each sine run the metrics are measured over.
    sine_duration : float
        Shortest sine run [s]; a run lasts at least ``sine_periods + 2`` periods.
    move_distance, move_v_max, move_a_max, move_j_max : float
        The S-curve move: distance [m], speed [m/s], acceleration [m/s²] and jerk [m/s³]
        limits.
    move_start : float
        When the move starts [s].
    move_settle : float
        Run time after the end of the move [s].
    load_fraction : float
        Load-force step as a fraction of p_s A_A [-].
    load_time : float
        When the force steps [s].
    load_duration : float
        Length of the load-step run [s].
    band : float
        Settling and recovery band, a fraction of the move or of the largest deviation [-].
    """

    sine_amplitude: float = 0.05
    sine_frequencies: tuple[float, ...] = (0.5, 1.0, 2.0)
    sine_periods: int = 2
    sine_duration: float = 4.0
    move_distance: float = 0.2
    move_v_max: float = 0.15
    move_a_max: float = 0.5
    move_j_max: float = 2.0
    move_start: float = 0.2
    move_settle: float = 3.0
    load_fraction: float = 0.1
    load_time: float = 0.5
    load_duration: float = 4.0
    band: float = 0.02

    def __post_init__(self) -> None:
        for name in ("sine_amplitude", "sine_duration", "move_distance", "move_v_max",
                     "move_a_max", "move_j_max", "move_settle", "load_fraction",
                     "load_duration", "band"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ParameterError(f"TrackingConfig.{name} must be > 0, got {v!r}")
        if not self.sine_frequencies or not all(
                math.isfinite(f) and f > 0.0 for f in self.sine_frequencies):
            raise ParameterError(f"TrackingConfig.sine_frequencies must be > 0 Hz, got "
                                 f"{self.sine_frequencies!r}")

    @property
    def move(self) -> SCurve:
        """The S-curve move."""
        return SCurve(self.move_distance, self.move_v_max, self.move_a_max, self.move_j_max,
                      self.move_start)

    def judged(self, capacity: float) -> tuple[float, ...]:
        """The sine frequencies whose peak speed A 2π f is within ``capacity``, the valve's
        no-load speed at the full command [m/s]: those claim C9 judges."""
        return tuple(f for f in self.sine_frequencies
                     if self.sine_amplitude * 2.0 * math.pi * f <= capacity)

    def figure_frequency(self, capacity: float) -> float:
        """The sine the figure draws: the fastest one judged, else the slowest [Hz]."""
        within = self.judged(capacity)
        return max(within) if within else min(self.sine_frequencies)

    def sine_run_duration(self, f: float) -> float:
        """Length of the run of the sine at ``f`` [s]."""
        return max(self.sine_duration, (self.sine_periods + 2) / f)


@dataclass(frozen=True, slots=True, kw_only=True)
class TrackingStudy:
    """What the tracking study computed on one plant."""

    plant: str
    keys: tuple[str, ...]  #: the designs, in legend order (the plant study's case keys)
    sine: dict[str, dict[str, dict[str, float]]]  #: key -> f"{Hz:g}" -> metric -> value
    move: dict[str, dict[str, float]]  #: key -> metric -> value
    load: dict[str, dict[str, float]]  #: key -> metric -> value
    load_force: float  #: the force step [N]
    runs: dict[str, SimResult] = field(default_factory=dict)  #: f"{key}/{experiment}" -> run


def _failed() -> dict[str, float]:
    """The record of a run that diverged: no metric."""
    return {"diverged": 1.0}


def run_tracking_study(kind: str, base: Callable[[str], RunSpec], keys: Sequence[str],
                       tcfg: TrackingConfig, *, params: Any, systems: Any = None,
                       keep: Sequence[str] = ("sine_0.5", "move", "load"),
                       tick: Callable[[str], None] | None = None) -> TrackingStudy:
    """Run the tracking study on plant ``kind``: ``base(key)`` is the step run of design
    ``key`` (its controller, gains, plant and sample time; the study's ``run_spec``), whose
    reference, duration and load force each experiment replaces. Runs named in ``keep``
    (``sine_<f>``, ``move``, ``load``) are kept for the figures."""
    from ..errors import SimulationDivergedError

    force = tcfg.load_fraction * params.supply.pressure * params.cylinder.piston_area
    sine: dict[str, dict[str, dict[str, float]]] = {}
    move: dict[str, dict[str, float]] = {}
    load: dict[str, dict[str, float]] = {}
    runs: dict[str, SimResult] = {}
    mv = tcfg.move
    t_end = mv.time + mv.duration

    def run(spec: RunSpec) -> SimResult:
        return spec.build(params=params, systems=systems).simulate()

    for key in keys:
        spec = base(key)
        sine[key] = {}
        for f in tcfg.sine_frequencies:
            name = f"sine_{f:g}"
            s = replace(spec, reference=f"sine:{tcfg.sine_amplitude!r}:{f!r}",
                        duration=tcfg.sine_run_duration(f))
            try:
                res = run(s)
            except SimulationDivergedError:
                sine[key][f"{f:g}"] = _failed()
                continue
            m = sine_metrics(res.t, res.r, res.y, f, periods=tcfg.sine_periods)
            sine[key][f"{f:g}"] = {"rms_error": m.rms_error, "max_error": m.max_error,
                                   "amplitude_ratio": m.amplitude_ratio,
                                   "phase_lag": m.phase_lag, "diverged": 0.0}
            if name in keep:
                runs[f"{key}/{name}"] = res
        s = replace(spec, reference=(f"scurve:{mv.distance!r}:{mv.v_max!r}:{mv.a_max!r}:"
                                     f"{mv.j_max!r}:{mv.time!r}"),
                    duration=t_end + tcfg.move_settle)
        try:
            res = run(s)
        except SimulationDivergedError:
            move[key] = _failed()
        else:
            mm = move_metrics(res.t, res.r, res.y, distance=mv.distance, t_end=t_end,
                              band=tcfg.band)
            move[key] = {"max_following_error": mm.max_following_error,
                         "overshoot": mm.overshoot, "settling_time": mm.settling_time,
                         "final_error": mm.final_error, "diverged": 0.0}
            if "move" in keep:
                runs[f"{key}/move"] = res
        s = replace(spec, reference="step:0.0", duration=tcfg.load_duration,
                    load_force=f"step:{force!r}:{tcfg.load_time!r}")
        try:
            res = run(s)
        except SimulationDivergedError:
            load[key] = _failed()
        else:
            dm = disturbance_metrics(res.t, res.y, t_step=tcfg.load_time, band=tcfg.band)
            load[key] = {"max_deviation": dm.max_deviation, "recovery_time": dm.recovery_time,
                         "remaining": dm.remaining, "diverged": 0.0}
            if "load" in keep:
                runs[f"{key}/load"] = res
        if tick is not None:
            tick(f"{kind}: tracking, {key}")
    return TrackingStudy(plant=kind, keys=tuple(keys), sine=sine, move=move, load=load,
                         load_force=force, runs=runs)


def tracking_claim(study: TrackingStudy, labels: Mapping[str, str], *, subject: str,
                   capacity: float, tcfg: TrackingConfig) -> Claim:
    """Claim C9, the paper's "tracking ability" of the self-tuning fuzzy PI (``subject``),
    judged by the rule of docs/model.md (``claims.CLAIM_RULES["C9"]``); ``capacity`` is
    the valve's no-load speed at the full command, K_o [m/s]."""
    within = tcfg.judged(capacity)
    thresholds = {"amplitude_ratio_min": TRACK_RATIO_MIN,
                  "amplitude_ratio_max": TRACK_RATIO_MAX,
                  "phase_lag_max_deg": TRACK_LAG_MAX_DEG, "rms_vs_best": TRACK_RMS_VS_BEST,
                  "valve_speed_m_s": capacity, "sine_amplitude_m": tcfg.sine_amplitude}
    data: dict[str, dict[str, Value]] = {}
    ok: list[tuple[float, bool, bool]] = []
    for f in within:
        fk = f"{f:g}"
        sm = study.sine[subject].get(fk, {"diverged": 1.0})
        live = [k for k in study.keys if not study.sine[k][fk].get("diverged")]
        best_key = min(live, key=lambda k: study.sine[k][fk]["rms_error"]) if live else None
        best = study.sine[best_key][fk]["rms_error"] if best_key else math.nan
        alive = not sm.get("diverged")
        follows = bool(alive and TRACK_RATIO_MIN <= sm["amplitude_ratio"] <= TRACK_RATIO_MAX
                       and sm["phase_lag"] <= TRACK_LAG_MAX_DEG)
        competitive = bool(alive and sm["rms_error"] <= TRACK_RMS_VS_BEST * best)
        ok.append((f, follows, competitive))
        data[f"sine {fk} Hz"] = {
            "amplitude_ratio": sm.get("amplitude_ratio", math.nan),
            "phase_lag_deg": sm.get("phase_lag", math.nan),
            "rms_error_mm": sm.get("rms_error", math.nan) * 1e3,
            "best_rms_error_mm": best * 1e3,
            "best": labels.get(best_key, best_key) if best_key else None,
            "follows": follows, "competitive": competitive}
    name = labels.get(subject, subject)
    beyond = [f"{f:g} Hz" for f in tcfg.sine_frequencies if f not in within]
    if not within:
        verdict = NOT_HOLDS
        evidence = (f"No sine of {tcfg.sine_amplitude * 1e3:g} mm is within the valve's "
                    f"speed ({capacity:.3g} m/s): nothing to judge tracking by.")
    else:
        if all(a and b for _, a, b in ok):
            verdict = HOLDS
        elif not any(a for _, a, _ in ok):
            verdict = NOT_HOLDS
        else:
            verdict = PARTLY
        parts = []
        for f, follows, competitive in ok:
            d = data[f"sine {f:g} Hz"]
            parts.append(
                f"at {f:g} Hz amplitude ratio {float(d['amplitude_ratio']):.3f}, lag "  # type: ignore[arg-type]
                f"{float(d['phase_lag_deg']):.1f}°, RMS error "  # type: ignore[arg-type]
                f"{float(d['rms_error_mm']):.3g} mm against the best "  # type: ignore[arg-type]
                f"{float(d['best_rms_error_mm']):.3g} mm ({d['best']})"  # type: ignore[arg-type]
                + ("" if follows else ": does not follow")
                + ("" if competitive or not follows else ": not competitive"))
        evidence = f"{name}: " + "; ".join(parts) + "."
    if beyond:
        evidence += (f" Not judged (peak speed beyond the valve's {capacity:.3g} m/s, so "
                     f"every design saturates): {', '.join(beyond)}.")
    return Claim("C9", CLAIM_TEXTS["C9"], verdict, evidence, study.plant, CLAIM_RULES["C9"],
                 thresholds, data)
