"""The study's figures of one plant (Figs. 4-8, the delay sweep, the changed plants), rendered
from a :class:`~fuzzyservo.study.paper_study.PlantStudy` into PNG + SVG files.

Every figure, its file name and its caption are planned from the study first
(:func:`figure_plan`); drawing is the last step and can be skipped: ``study_figures(...,
reuse=True)`` lists the files a previous run drew from the same inputs (the runner checks
them, ``study.reuse.reusable``) and returns the same captions, without loading matplotlib.
Captions are plain text (the report escapes them): symbols in Unicode, never a literal
underscore.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._typing import FloatArray
from ..files.html import Figure
from ..plots.study_figures import (
    Curve,
    alpha_figure,
    coinciding,
    command_figure,
    delay_figure,
    delay_sweep_figure,
    first_saturation,
    save,
    step_figure,
    tracking_figure,
)
from .frequency import FrequencyStudy
from .paper_study import DESIGN_COLOURS, PlantStudy, StudyConfig

if TYPE_CHECKING:
    from matplotlib.figure import Figure as Drawing

    from ..fuzzy import FuzzySystem, Variable

__all__ = ["FIGURE_STEMS", "FREQUENCY_STEMS", "NEAR_FRACTION", "OVERSHOOT_LIMIT_PCT",
           "TRACKING_STEMS", "PlannedFigure", "fig3_captions", "figure_files", "figure_plan",
           "study_figures"]

#: The figures of one plant, without the ``_{plant}`` suffix, in the report's order.
FIGURE_STEMS: tuple[str, ...] = ("fig4", "fig5", "fig6", "fig7", "fig8",
                                 "fig8_delay_overshoot", "fig8_delay_settling", "robustness")
#: The tracking study's figures of one plant (when it runs), after :data:`FIGURE_STEMS`.
TRACKING_STEMS: tuple[str, ...] = ("tracking_sine", "tracking_move", "tracking_load")
#: The frequency responses' figure of one plant (when they run), last.
FREQUENCY_STEMS: tuple[str, ...] = ("bode",)

#: Curves of Figs. 4 and 7 closer than this fraction of the step over the whole run are
#: marked as coinciding (2 %: the settling band; closer than that they look like one line).
NEAR_FRACTION = 0.02

#: The overshoot limit of claims C6 and C8 [%] (``study.claims``), drawn in the sweep.
OVERSHOOT_LIMIT_PCT = 10.0

#: Controllers of Figs. 4 and 5, in legend order.
FIG4_KEYS: tuple[str, ...] = ("pid_paper_1", "pid_paper_2", "pid_tuned", "pid2_tuned",
                              "stfpi", "stfpi_10")


#: Line styles of the changed plants, each its own.
_VARIANT_STYLES: tuple[str | tuple[float, tuple[float, ...]], ...] = (
    "--", "-.", ":", (0, (6, 2, 1, 2, 1, 2)), (0, (1, 1.5)), (0, (8, 3)))


@dataclass(frozen=True, slots=True)
class PlannedFigure:
    """A figure of the study: file stem (no suffix), caption, and how to draw it."""

    stem: str
    caption: str
    draw: Callable[[], Drawing]


#: Names of the fuzzy systems' variables in captions (Unicode; the figures use mathtext).
_CAPTION_NAMES = {"e": "eₙ", "de": "Δeₙ", "du": "Δuₙ", "alpha": "α"}

#: The defuzzifiers in words.
_DEFUZZ_WORDS = {"centroid": "centroid", "bisector": "bisector of area",
                 "mom": "mean of maxima", "som": "smallest of maxima",
                 "lom": "largest of maxima", "wtaver": "weighted average",
                 "wtsum": "weighted sum"}


def fig3_captions(du: FuzzySystem, alpha: FuzzySystem) -> dict[str, str]:
    """The report's caption of each file stem of Fig. 3 (``plots.figures.FIG3_STEMS``): what
    it shows, read from the two systems (terms, universes, rules, operators)."""
    def name(v: Variable) -> str:
        return _CAPTION_NAMES.get(v.name, v.name)

    def terms(v: Variable) -> str:
        lo, hi = v.range
        return f"{', '.join(t.name for t in v.terms)} on [{lo:g}, {hi:g}]"

    def rules(system: FuzzySystem, fig: str) -> str:
        col, row = system.inputs
        out = system.outputs[0]
        return (f"Fig. {fig}: the {len(system.rules)} rules for {name(out)}, "
                f"laid out as the paper's table: row {name(row)}, column {name(col)}, cell "
                f"the term of {name(out)} (AND {system.and_op}, implication "
                f"{system.implication}, aggregation {system.aggregation.replace('_', ' ')}).")

    def surface(system: FuzzySystem, fig: str, what: str) -> str:
        col, row = system.inputs
        how = _DEFUZZ_WORDS[system.defuzzifier]
        return (f"Fig. {fig}: {what} {name(system.outputs[0])}({name(col)}, {name(row)}) of "
                f"these rules, defuzzified by the {how}: left as a surface, right as "
                f"contours.")

    du_vars = [*du.inputs, du.outputs[0]]
    if len({terms(v) for v in du_vars}) == 1:
        du_terms = f"each with the terms {terms(du.outputs[0])}"
    else:
        du_terms = "; ".join(f"{name(v)}: {terms(v)}" for v in du_vars)
    e, de = du.inputs
    same = ("Its inputs are those of Fig. 3a." if alpha.inputs == du.inputs else
            "Its inputs: " + "; ".join(f"{name(v)}: {terms(v)}" for v in alpha.inputs) + ".")
    return {
        "fig3a_memberships": (
            f"Fig. 3a: membership functions of the fuzzy PI's inputs, the normalised error "
            f"{name(e)} and its change {name(de)}, and of its output, the normalised change "
            f"of the command {name(du.outputs[0])}; {du_terms}."),
        "fig3a_rules_du": rules(du, "3a"),
        "fig3a_surface_du": surface(du, "3a", "the control surface"),
        "fig3b_memberships": (
            f"Fig. 3b: membership functions of the gain updating factor {name(alpha.outputs[0])} "
            f"of the self-tuning fuzzy PI (the paper's α with subscript F): the terms "
            f"{terms(alpha.outputs[0])}. {same}"),
        "fig3b_rules_alpha": rules(alpha, "3b"),
        "fig3b_surface_alpha": surface(alpha, "3b", "the gain updating factor"),
    }


def figure_files(plant: str, out: Path, *, tracking: bool = False,
                 frequency: bool = False) -> list[Path]:
    """Every file :func:`study_figures` writes for ``plant`` into ``out``, in order (with
    the tracking study's and the frequency responses' when they ran)."""
    stems = (FIGURE_STEMS + (TRACKING_STEMS if tracking else ())
             + (FREQUENCY_STEMS if frequency else ()))
    return [Path(out) / f"{s}_{plant}.{fmt}" for s in stems for fmt in ("png", "svg")]


def _curve(study: PlantStudy, key: str, *, label: str | None = None) -> Curve:
    r = study.runs[key]
    case = next(c for c in study.cases if c.key == key)
    return Curve(key, label or case.label, r.t, r.y, r.u, r.alpha, r.r, colour=case.colour)


def _mm(x: float) -> str:
    return f"{x * 1e3:.2g} mm"


def figure_plan(study: PlantStudy, cfg: StudyConfig) -> list[PlannedFigure]:
    """The figures of ``study``, in :data:`FIGURE_STEMS` order, with their captions (computed
    from the study: what coincides, what saturates, what does not settle)."""
    p = study.plant
    y0 = float(study.runs["stfpi"].y[0])
    step = cfg.step
    near = NEAR_FRACTION * step
    plan: list[PlannedFigure] = []

    def add(stem: str, caption: str, draw: Callable[[], Drawing]) -> None:
        plan.append(PlannedFigure(f"{stem}_{p}", caption, draw))

    # Fig. 4 and 7: step responses, coinciding curves marked
    def coincide_text(curves: list[Curve]) -> str:
        return "".join(
            f" {curves[c.later].label} stays within {_mm(c.max_diff)} of "
            f"{curves[c.earlier].label} over the whole run "
            f"({100 * c.max_diff / step:.2g} % of the step): drawn dashed over it."
            for c in coinciding(curves, near))

    fig4 = [_curve(study, k) for k in FIG4_KEYS]
    add("fig4", f"Fig. 4, {p} plant: {step * 1e3:g} mm step from mid-stroke; right, the first "
        f"4 s.{coincide_text(fig4)}",
        lambda: step_figure(fig4, f"Fig. 4 ({p} plant): step response, PIDs and self-tuning "
                                  f"fuzzy PI", y0=y0, near=near))

    kicks = []
    for c in fig4:
        sat = first_saturation(c.t, c.u)
        if sat is not None and sat[0] < 0.2:
            kicks.append(f"{c.label} from {sat[0] * 1e3:.3g} to {sat[1] * 1e3:.3g} ms")
    kick_text = (" At the start the command is at its limit |u| = 100 %: "
                 + "; ".join(kicks) + "." if kicks else "")
    add("fig5", f"Fig. 5, {p} plant: valve commands of the controllers of Fig. 4; right, the "
        f"first 0.2 s.{kick_text}",
        lambda: command_figure(fig4, f"Fig. 5 ({p} plant): control signals"))

    st = _curve(study, "stfpi")
    add("fig6", f"Fig. 6, {p} plant: the gain updating factor α of the self-tuning fuzzy PI "
        f"(the paper's α with subscript F).",
        lambda: alpha_figure([st], f"Fig. 6 ({p} plant): self-tuning factor"))

    fig7 = [_curve(study, "fpi"), st]
    add("fig7", f"Fig. 7, {p} plant: fuzzy PI (α = 1) and self-tuning fuzzy PI; right, the "
        f"first 4 s.{coincide_text(fig7)}",
        lambda: step_figure(fig7, f"Fig. 7 ({p} plant): fuzzy PI without and with "
                                  f"self-tuning", y0=y0, near=near))

    d = study.delayed
    ms = cfg.fig8_delay * 1e3
    nominal = _curve(study, "stfpi", label="self-tuning fuzzy PI, no delay")
    delayed = Curve("stfpi_delay", f"self-tuning fuzzy PI, {ms:g} ms delay", d.t, d.y, d.u,
                    d.alpha, d.r, colour=DESIGN_COLOURS["stfpi_delay"])
    diff = float(np.max(np.abs(np.interp(nominal.t, d.t, d.y) - nominal.y)))
    add("fig8", f"Fig. 8, {p} plant: the self-tuning fuzzy PI without and with the {ms:g} ms "
        f"hose delay; below, the difference (with delay minus without), at most "
        f"{_mm(diff)}.",
        lambda: delay_figure(nominal, delayed, f"Fig. 8 ({p} plant): self-tuning fuzzy PI "
                                               f"without and with hose delay", y0=y0))

    labels = {c.key: c.label for c in study.cases}
    colours = {c.key: c.colour for c in study.cases}
    failed = {k: np.isin(study.delays, np.asarray(study.delay_failures[k], dtype=np.float64))
              for k in study.sweep}
    axis_text = ("Delay axis linear to 10 ms, logarithmic above. A cross in the strip below: "
                 f"the controller fails at that delay (no 2 % settling within the "
                 f"{cfg.duration:g} s run, or diverged).")
    sweep_title = f"Delay sweep ({p} plant, gains fixed)"
    mark = (cfg.fig8_delay, f"hose delay of Fig. 8 ({ms:g} ms)")
    add("fig8_delay_overshoot",
        f"Delay sweep, {p} plant: overshoot against the transport delay, gains fixed. "
        f"{axis_text} Hollow markers: the overshoot of a run that fails. Dashed line: the "
        f"{OVERSHOOT_LIMIT_PCT:g} % overshoot limit of claims C6 and C8 (not the failure "
        f"rule). Overshoot axis linear to {OVERSHOOT_LIMIT_PCT:g} %, logarithmic above.",
        lambda: delay_sweep_figure(
            study.delays, {k: v["overshoot"] for k, v in study.sweep.items()}, labels,
            f"{sweep_title}: overshoot", ylabel="overshoot [%]", failed=failed,
            run_length=cfg.duration, colours=colours, show_failed=True,
            limit=OVERSHOOT_LIMIT_PCT,
            limit_label=f"overshoot limit of claims C6, C8 ({OVERSHOOT_LIMIT_PCT:g} %)",
            mark=mark, log_y=True))
    never = [labels[k] for k in study.sweep if bool(np.all(failed[k]))]
    add("fig8_delay_settling",
        f"Delay sweep, {p} plant: 2 % settling time of the runs that settle. {axis_text}"
        + (f" Never settles at any delay: {', '.join(never)}." if never else ""),
        lambda: delay_sweep_figure(
            study.delays, {k: v["settling_time"] for k, v in study.sweep.items()}, labels,
            f"{sweep_title}: 2 % settling time", ylabel="settling time (2 %) [s]",
            failed=failed, run_length=cfg.duration, colours=colours, mark=mark))

    curves = [_curve(study, "stfpi", label="nominal plant")]
    unsettled = []
    for i, (name, run) in enumerate(study.variant_runs.items()):
        settles = not math.isnan(study.variant_metrics[name]["stfpi"]["settling_time"])
        label = name
        if not settles:
            tail = run.y[int(0.75 * run.y.size):]
            amp = 0.5 * float(np.max(tail) - np.min(tail))
            label += f": does not settle (last quarter ±{amp * 1e3:.2g} mm; band = min/max)"
            unsettled.append(name)
        curves.append(Curve(f"variant{i}", label, run.t, run.y, run.u, run.alpha, run.r,
                            _VARIANT_STYLES[i % len(_VARIANT_STYLES)],
                            envelope=not settles))
    add("robustness",
        f"Claim C8, {p} plant: the self-tuning fuzzy PI on changed plants, gains fixed; right, "
        f"the first 4 s."
        + (f" Does not settle within {cfg.duration:g} s (drawn as its min/max band over the "
           f"whole run): {', '.join(unsettled)}." if unsettled else ""),
        lambda: step_figure(curves, f"Changed plants ({p}): self-tuning fuzzy PI, gains fixed",
                            y0=y0))
    if study.tracking is not None:
        plan.extend(_tracking_plan(study, cfg))
    if study.frequency is not None:
        plan.append(_bode_plan(study))
    return plan


def _bode_plan(study: PlantStudy) -> PlannedFigure:
    """The frequency responses' figure: every design's analytic |T| and ∠T, and on the
    nonlinear plant the measured points."""
    from ..plots.frequency import BodeCurve, bode_figure

    fq = study.frequency
    assert fq is not None
    p = study.plant
    cases = {c.key: c for c in study.tracking_cases}
    empty = np.empty(0)
    curves = []
    for key in fq.keys:
        has_m = key in fq.measured_db
        curves.append(BodeCurve(
            label=cases[key].label, colour=cases[key].colour, frequency=fq.frequency,
            magnitude_db=fq.magnitude_db[key], phase_deg=fq.phase_deg[key],
            measured_frequency=fq.measured_frequency if has_m else empty,
            measured_db=fq.measured_db[key] if has_m else empty,
            measured_phase_deg=_near_phase(fq, key) if has_m else empty,
            bandwidth=fq.margins[key]["bandwidth"]))
    unstable = [cases[k].label for k in fq.keys if fq.margins[k]["stable"] == 0.0]
    model = ("eq. (8), the plant itself" if fq.analytic_plant == "linear"
             else "the small-signal model of the nonlinear plant at mid-stroke")
    text = (f"Closed-loop frequency response, {p} plant: |T| and ∠T from the reference to the "
            f"position, lines analytic (each controller linearised at rest, its feed-forward "
            f"included, on {model}; the loop the simulator runs, sampling and hold included)")
    if fq.measured_frequency.size:
        text += (f"; markers measured on the nonlinear plant with sines of "
                 f"{fq.amplitude * 1e3:g} mm (where they leave the lines the small-signal "
                 f"model no longer describes the loop)")
    text += "."
    if unstable:
        text += (f" Unstable in the small-signal limit (the loop's linearisation has a pole "
                 f"outside the unit circle; at larger amplitude a limit cycle): "
                 f"{', '.join(unstable)}.")
    return PlannedFigure(f"bode_{p}", text, lambda: bode_figure(
        curves, f"Closed-loop frequency response ({p} plant)"))


def _near_phase(fq: FrequencyStudy, key: str) -> FloatArray:
    """Measured phases shifted by whole turns to lie nearest the analytic curve."""
    f = fq.frequency
    ph = fq.phase_deg[key]
    mf = fq.measured_frequency
    mph = fq.measured_phase_deg[key]
    if not np.all(np.isfinite(ph)):
        return np.asarray(mph)
    near = np.interp(np.log(mf), np.log(f), ph)
    return np.asarray(mph + 360.0 * np.round((near - mph) / 360.0))


def _tracking_plan(study: PlantStudy, cfg: StudyConfig) -> list[PlannedFigure]:
    """The tracking study's figures (:data:`TRACKING_STEMS`)."""
    tr = study.tracking
    tc = cfg.tracking
    assert tr is not None and tc is not None
    p = study.plant
    cases = {c.key: c for c in study.tracking_cases}

    def curves(experiment: str) -> list[Curve]:
        out = []
        for key in tr.keys:
            r = tr.runs.get(f"{key}/{experiment}")
            if r is not None:
                c = cases[key]
                out.append(Curve(key, c.label, r.t, r.y, r.u, r.alpha, r.r, colour=c.colour))
        return out

    def missing(experiment: str) -> str:
        gone = [cases[k].label for k in tr.keys if f"{k}/{experiment}" not in tr.runs]
        return f" Diverged (not drawn): {', '.join(gone)}." if gone else ""

    plan: list[PlannedFigure] = []
    # the fastest sine the valve can follow (claim C9 judges it), else the slowest
    f_sine = tc.figure_frequency(cfg.params.velocity_gain)
    sine = curves(f"sine_{f_sine:g}")
    speed = tc.sine_amplitude * 2 * math.pi * f_sine
    sat = (f" Its peak speed {speed:.3g} m/s is beyond the valve's {cfg.params.velocity_gain:.3g}"
           f" m/s at the full command, so every design saturates." if speed >
           cfg.params.velocity_gain else "")
    plan.append(PlannedFigure(
        f"tracking_sine_{p}",
        f"Tracking, {p} plant: a sine of {tc.sine_amplitude * 1e3:g} mm at {f_sine:g} Hz from "
        f"mid-stroke, every design with the gains of the step study; below, the tracking "
        f"error.{sat}{missing(f'sine_{f_sine:g}')}",
        lambda: tracking_figure(sine, f"Sine tracking, {tc.sine_amplitude * 1e3:g} mm at "
                                      f"{f_sine:g} Hz ({p} plant)")))
    mv = tc.move
    t_end = mv.time + mv.duration
    move = curves("move")
    plan.append(PlannedFigure(
        f"tracking_move_{p}",
        f"Jerk-limited move, {p} plant: {mv.distance * 1e3:g} mm with at most "
        f"{mv.v_max:g} m/s, {mv.a_max:g} m/s² and {mv.j_max:g} m/s³ from {mv.time:g} s; "
        f"the move ends at {t_end:.3g} s (dotted). Below, the following error.{missing('move')}",
        lambda: tracking_figure(move, f"S-curve move of {mv.distance * 1e3:g} mm ({p} plant)",
                                mark=t_end, mark_label="end of the move")))
    load = curves("load")
    plan.append(PlannedFigure(
        f"tracking_load_{p}",
        f"Load-force step, {p} plant: {tr.load_force / 1e3:.3g} kN ({tc.load_fraction:.0%} of "
        f"the force at supply pressure on the piston area) opposing extension at "
        f"{tc.load_time:g} s, the reference at rest. Below, the deviation from the position "
        f"at the step.{missing('load')}",
        lambda: tracking_figure(load, f"Load-force step of {tr.load_force / 1e3:.3g} kN "
                                      f"({p} plant)", what="deviation", mark=tc.load_time,
                                mark_label="load step")))
    return plan


def study_figures(study: PlantStudy, cfg: StudyConfig, out: Path, written: list[Path], *,
                  reuse: bool = False) -> list[Figure]:
    """Render every figure of ``study`` into ``out`` (or, with ``reuse``, take the files a
    previous run drew from the same inputs, drawing nothing); append each file to
    ``written`` and return the report's figures (PNG and caption)."""
    figs: list[Figure] = []
    for planned in figure_plan(study, cfg):
        if reuse:
            paths = [out / f"{planned.stem}.png", out / f"{planned.stem}.svg"]
        else:
            paths = save(planned.draw(), out / planned.stem)
        written.extend(paths)
        figs.append(Figure(paths[0], planned.caption))
    return figs
