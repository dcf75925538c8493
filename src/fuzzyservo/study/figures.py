"""The study's figures of one plant (Figs. 4-8, the delay sweep, the changed plants), rendered
from a :class:`~fuzzyservo.study.paper_study.PlantStudy` into PNG + SVG files."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..plots.study_figures import (
    Curve,
    alpha_figure,
    command_figure,
    delay_sweep_figure,
    save,
    step_figure,
)
from .paper_study import PlantStudy, StudyConfig
from .report import Figure

__all__ = ["study_figures"]


def _curve(study: PlantStudy, key: str, *, label: str | None = None,
           linestyle: str = "-") -> Curve:
    r = study.runs[key]
    lab = label or next(c.label for c in study.cases if c.key == key)
    return Curve(key, lab, r.t, r.y, r.u, r.alpha, r.r, linestyle)


def study_figures(study: PlantStudy, cfg: StudyConfig, out: Path,
                  written: list[Path]) -> list[Figure]:
    """Render every figure of ``study`` into ``out``; append each file written to ``written``
    and return the report's figures (PNG and caption)."""
    p = study.plant
    y0 = float(study.runs["stfpi"].y[0])
    figs: list[Figure] = []

    def put(fig: Any, stem: str, caption: str) -> None:
        paths = save(fig, out / stem)
        written.extend(paths)
        figs.append(Figure(paths[0], caption))

    fig4_keys = ("pid_paper_1", "pid_paper_2", "pid_tuned", "pid2_tuned", "stfpi", "stfpi_10")
    put(step_figure([_curve(study, k) for k in fig4_keys],
                    f"Fig. 4 ({p} plant): step response, PIDs and self-tuning fuzzy PI", y0=y0),
        f"fig4_{p}", f"Fig. 4, {p} plant: {cfg.step * 1e3:g} mm step from mid-stroke.")
    put(command_figure([_curve(study, k) for k in fig4_keys],
                       f"Fig. 5 ({p} plant): control signals"),
        f"fig5_{p}", f"Fig. 5, {p} plant: valve commands of the controllers of Fig. 4.")
    put(alpha_figure([_curve(study, "stfpi")], f"Fig. 6 ({p} plant): self-tuning factor"),
        f"fig6_{p}", f"Fig. 6, {p} plant: alpha_F(t) of the self-tuning fuzzy PI.")
    put(step_figure([_curve(study, "fpi"), _curve(study, "stfpi")],
                    f"Fig. 7 ({p} plant): fuzzy PI without and with self-tuning", y0=y0),
        f"fig7_{p}", f"Fig. 7, {p} plant: fuzzy PI (alpha = 1) and self-tuning fuzzy PI.")
    d = study.delayed
    delayed = Curve("stfpi_delay", f"self-tuning fuzzy PI, {cfg.fig8_delay * 1e3:g} ms delay",
                    d.t, d.y, d.u, d.alpha, d.r, "--")
    put(step_figure([_curve(study, "stfpi", label="self-tuning fuzzy PI, no delay"), delayed],
                    f"Fig. 8 ({p} plant): self-tuning fuzzy PI without and with hose delay",
                    y0=y0),
        f"fig8_{p}", f"Fig. 8, {p} plant: the {cfg.fig8_delay * 1e3:g} ms hose delay.")
    labels = {c.key: c.label for c in study.cases}
    put(delay_sweep_figure(study.delays, {k: v["overshoot"] for k, v in study.sweep.items()},
                           labels, f"Delay sweep ({p} plant): overshoot",
                           ylabel="overshoot [%]", limit=10.0),
        f"fig8_delay_overshoot_{p}",
        f"Delay sweep, {p} plant: overshoot against the transport delay (gains fixed).")
    put(delay_sweep_figure(study.delays,
                           {k: v["settling_time"] for k, v in study.sweep.items()}, labels,
                           f"Delay sweep ({p} plant): 2 % settling time",
                           ylabel="settling time (2 %) [s]"),
        f"fig8_delay_settling_{p}",
        f"Delay sweep, {p} plant: settling time; a missing point never settled in "
        f"{cfg.duration:g} s (failure).")
    curves = [_curve(study, "stfpi", label="nominal")]
    for i, (name, run) in enumerate(study.variant_runs.items()):
        curves.append(Curve(f"variant{i}", name, run.t, run.y, run.u, run.alpha, run.r,
                            ("--", "-.", ":")[i % 3]))
    put(step_figure(curves, f"Changed plant ({p}): self-tuning fuzzy PI, gains fixed", y0=y0),
        f"robustness_{p}", f"Claim C8, {p} plant: the self-tuning fuzzy PI on changed plants.")
    return figs
