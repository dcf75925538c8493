"""Write the study's outputs: figures (PNG + SVG), trace CSVs, metrics.csv, claims.json and
the offline report.html. Nothing is simulated here; everything comes from the records."""

from __future__ import annotations

import csv
import math
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path

from .._io import atomic_write, strict_json, write_text_atomic
from ..files.html import Details, Figure, Section, Table, Verdict, write_html
from ..paper import alpha_system, du_system
from ..paper.departures import DEPARTURES
from ..plant import linearize, to_dict
from .claims import CLAIM_SHORT, HOLDS, NOT_HOLDS, PARTLY, Claim, summarize
from .figures import fig3_captions, study_figures
from .frequency import MARGIN_FIELDS
from .paper_study import TUNED_AS, PlantStudy, StudyConfig, design_name

__all__ = ["METRIC_COLUMNS", "TRACKING_COLUMNS", "trace_files", "write_outputs"]

#: Columns of metrics.csv and of the report's metrics tables, with units. ``u_max_after`` is
#: the peak |u| after C3's initial transient, ``u_rms`` the RMS of u over the run (C3;
#: docs/model.md, "How a verdict is reached").
METRIC_COLUMNS: tuple[tuple[str, str], ...] = (
    ("rise_time", "s"), ("settling_time", "s"), ("overshoot", "%"),
    ("steady_state_error", "m"), ("iae", "m s"), ("itae", "m s^2"), ("u_max", "-"),
    ("u_max_after", "-"), ("u_rms", "-"),
)

#: The tracking study's metrics by experiment, with units (tracking.csv, the report).
TRACKING_COLUMNS: dict[str, tuple[tuple[str, str], ...]] = {
    "sine": (("rms_error", "m"), ("max_error", "m"), ("amplitude_ratio", "-"),
             ("phase_lag", "deg")),
    "move": (("max_following_error", "m"), ("overshoot", "%"), ("settling_time", "s"),
             ("final_error", "m")),
    "load": (("max_deviation", "m"), ("recovery_time", "s"), ("remaining", "m")),
}

#: The verdict grid's short forms.
_SHORT_VERDICT = {HOLDS: "holds", NOT_HOLDS: "does not hold", PARTLY: "partly"}


def _anchor(c: Claim) -> str:
    return f"claim-{c.plant}-{c.id}"


def _cell(v: object) -> object:
    """A value of a claim's data as a table cell (a list of delays in ms, as text)."""
    if isinstance(v, list):
        return ", ".join(f"{x * 1e3:.3g}" for x in v) or "none"
    return "" if v is None else v


def _data_tables(c: Claim) -> list[Table]:
    """A claim's data as tables: entities (controllers, changed plants) that share their
    fields as rows of one table; an entity with fields of its own as a table of its own,
    one row a field."""
    groups: dict[tuple[str, ...], list[str]] = {}
    for name, d in c.data.items():
        groups.setdefault(tuple(f for f in d if f != "label"), []).append(name)
    tables = []
    for fields, names in groups.items():
        if len(names) == 1 and len(fields) > 1:
            d = c.data[names[0]]
            tables.append(Table([str(d.get("label", names[0])), "value"],
                                [[f, _cell(d[f])] for f in fields]))
        else:
            tables.append(Table(["", *fields], [
                [c.data[n].get("label", n)] + [_cell(c.data[n].get(f)) for f in fields]
                for n in names]))
    return tables


def _claim_sections(claims: Sequence[Claim]) -> list[Section]:
    """The verdict grid (claims x plants) and the evidence, one collapsible block a claim."""
    plants = list(dict.fromkeys(c.plant for c in claims))
    by = {(c.id, c.plant): c for c in claims}
    ids = list(dict.fromkeys(c.id for c in claims))
    def cell(c: Claim | None) -> object:
        if c is None:
            return ""
        return Verdict(c.verdict, _SHORT_VERDICT.get(c.verdict, c.verdict), _anchor(c))

    grid: list[list[object]] = [[i, CLAIM_SHORT.get(i, "")]
                                + [cell(by.get((i, p))) for p in plants] for i in ids]
    details = [Details(
        _anchor(c), [f"{c.id}, {c.plant} plant: ", Verdict(c.verdict), f" - {c.claim}"],
        paragraphs=[("Rule:", c.rule), ("Evidence:", c.evidence)],
        tables=_data_tables(c))
        for i in ids for p in plants if (c := by.get((i, p))) is not None]
    return [
        Section("Verdicts", tables=[Table(["id", "claim", *plants], grid)], paragraphs=[
            "Claims as rows, plants as columns; 'partly' is 'holds under stated "
            "conditions'. Each cell links to its evidence below."]),
        Section("Evidence per claim", details=details, paragraphs=[
            "Each verdict is computed from the simulations of this run; open a claim for "
            "the rule, the evidence and the numbers behind it (also in claims.json; SI "
            "units, delays in lists in ms)."]),
    ]


def _metrics_caption(s: PlantStudy) -> str:
    after = next((c.thresholds.get("window_start_s") for c in s.claims if c.id == "C3"), None)
    return ("Step metrics (4 significant digits; metrics.csv has every digit); u_max_after: "
            "peak |u| " + (f"from {after:g} s " if after is not None else "")
            + "after the step, past the PIDs' derivative kick; u_rms: RMS of u over the run")


def _summary(studies: Sequence[PlantStudy]) -> str:
    comparisons = {}
    for s in studies:
        tuned = {design_name(c): s.metrics[c.key] for c in s.cases if c.key in TUNED_AS}
        # at equal terms: the self-tuning design tuned like the PIDs (<= 10 %, ITAE)
        comparisons[s.plant] = (s.metrics["stfpi_10"], tuned)
    return " ".join(summarize([c for s in studies for c in s.claims], comparisons))


def _fmt_gains(g: Mapping[str, float], *, exact: bool = False) -> str:
    """Gains as text: rounded for reading, or exact (``repr``) for the CSV record."""
    return ", ".join(f"{k} = {v!r}" if exact else f"{k} = {v:.5g}" for k, v in g.items())


def trace_files(study: PlantStudy, out: Path) -> list[Path]:
    """Every file :func:`write_outputs` writes into ``out/traces`` for ``study``, in order:
    one CSV a run (the designs, the hose-delay run, the changed plants), then the sweep."""
    p = study.plant
    names = [f"{p}_{key}.csv" for key in study.runs]
    names.append(f"{p}_stfpi_delay.csv")
    names.extend(f"{p}_stfpi_variant{i}.csv" for i in range(len(study.variant_runs)))
    names.append(f"{p}_delay_sweep.csv")
    return [Path(out) / "traces" / n for n in names]


def _write_traces(study: PlantStudy, files: Sequence[Path]) -> None:
    """Write the trace CSVs of ``study`` to ``files`` (:func:`trace_files`' order)."""
    runs = [*study.runs.values(), study.delayed, *study.variant_runs.values()]
    for run, path in zip(runs, files[:-1], strict=True):
        run.to_csv(path)
    with atomic_write(files[-1]) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["controller", "delay", "overshoot", "settling_time", "iae", "u_max",
                    "diverged"])
        for key, sw in study.sweep.items():
            for j, dly in enumerate(study.delays):
                w.writerow([key, repr(float(dly))] + [repr(float(sw[c][j])) for c in
                           ("overshoot", "settling_time", "iae", "u_max", "diverged")])


def write_outputs(out: Path, cfg: StudyConfig, studies: Sequence[PlantStudy],
                  fig3: Sequence[Path], tuning_notes: Mapping[str, str],
                  meta: Mapping[str, str], *, written: list[Path] | None = None,
                  notices: Sequence[str] = (),
                  figures_reused: Collection[str] = (),
                  traces_reused: Collection[str] = ()) -> dict[str, Path]:
    """Write every output of the study into ``out`` and return the main paths.

    Every file is written atomically; ``written`` (if given) receives each path, the report
    last. ``notices`` are shown at the top of the report (the overrides in force, ...).
    ``figures_reused`` names the plants whose figure files a previous run drew from the same
    inputs: they are listed, not drawn again (``study.figures.study_figures``).
    ``traces_reused`` names the plants whose trace CSVs (:func:`trace_files`) a previous run
    wrote from the same study: they are listed, not written again.
    """
    if written is None:
        written = []
    out.mkdir(parents=True, exist_ok=True)
    (out / "traces").mkdir(exist_ok=True)
    for s in studies:
        files = trace_files(s, out)
        if s.plant not in traces_reused:
            _write_traces(s, files)
        written.extend(files)

    metrics_csv = out / "metrics.csv"
    with atomic_write(metrics_csv) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["plant", "controller", "label", "gains", "delay [s]"]
                   + [f"{n} [{u}]" for n, u in METRIC_COLUMNS])
        for s in studies:
            for c in s.cases:
                m = s.metrics[c.key]
                w.writerow([s.plant, c.key, c.label, _fmt_gains(c.gains, exact=True),
                            repr(float(s.runs[c.key].delay))]
                           + [repr(float(m[n])) for n, _ in METRIC_COLUMNS])
            st = next(c for c in s.cases if c.key == "stfpi")  # Fig. 8 and claim C6
            w.writerow([s.plant, st.key, f"{st.label}, {s.delayed.delay * 1e3:g} ms hose delay",
                        _fmt_gains(st.gains, exact=True), repr(float(s.delayed.delay))]
                       + [repr(float(s.delayed_metrics[n])) for n, _ in METRIC_COLUMNS])
    written.append(metrics_csv)
    if any(s.tracking is not None for s in studies):
        written.append(_write_tracking_csv(out / "tracking.csv", studies))
    if any(s.frequency is not None for s in studies):
        written.append(_write_frequency_csv(out / "frequency.csv", studies))

    claims = [c.as_dict() for s in studies for c in s.claims]
    claims_json = write_text_atomic(out / "claims.json", strict_json(claims, indent=2) + "\n")
    written.append(claims_json)
    written.extend(fig3)

    sections: list[Section] = [Section("Summary", summary=_summary(studies))]
    if notices:
        sections.append(Section("Conditions of this run", items=list(notices)))
    sections.extend(_claim_sections([c for s in studies for c in s.claims]))
    for s in studies:
        rows = [[c.label] + [s.metrics[c.key][n] for n, _ in METRIC_COLUMNS]
                for c in s.cases]
        rows.append([f"self-tuning fuzzy PI, {s.delayed.delay * 1e3:g} ms hose delay"]
                    + [s.delayed_metrics[n] for n, _ in METRIC_COLUMNS])
        margin_rows = [[c.label, s.delay_margins[c.key] * 1e3 if not
                        math.isnan(s.delay_margins[c.key]) else "fails without delay",
                        ", ".join(f"{d * 1e3:.3g}" for d in s.delay_failures[c.key]) or "none"]
                       for c in s.cases]
        figs = study_figures(s, cfg, out, written, reuse=s.plant in figures_reused)
        sections.append(Section(
            f"Results on the {s.plant} plant",
            paragraphs=[f"Step of {cfg.step * 1e3:g} mm from mid-stroke, {cfg.duration:g} s, "
                        f"controller sample time {cfg.ts * 1e3:g} ms, no delay unless stated."],
            tables=[Table(["controller"] + [f"{n} [{u}]" for n, u in METRIC_COLUMNS], rows,
                          caption=_metrics_caption(s)),
                    Table(["controller", "settles at every delay up to [ms]",
                           "fails (no 2 % settling in the run) at [ms]"], margin_rows,
                          caption="Delay sweep, gains fixed")],
            figures=[f for f in figs if not f.png.name.startswith(("tracking_", "bode_"))]))
        if s.tracking is not None:
            sections.append(_tracking_section(
                s, cfg, [f for f in figs if f.png.name.startswith("tracking_")]))
        if s.frequency is not None:
            sections.append(_frequency_section(
                s, [f for f in figs if f.png.name.startswith("bode_")]))
    captions = fig3_captions(du_system(), alpha_system())
    sections.append(Section(
        "Fig. 3: membership functions, rule tables and control surfaces",
        figures=[Figure(p, captions[p.stem]) for p in fig3 if p.suffix == ".png"]))
    gain_rows = [[s.plant, c.label, _fmt_gains(c.gains),
                  tuning_notes.get(f"{s.plant}:{c.key}", "given by the paper")]
                 for s in studies for c in s.cases]
    sections.append(Section("Controller gains", tables=[
        Table(["plant", "controller", "gains", "origin"], gain_rows)],
        paragraphs=["Gain units: kp [1/m], ki [1/(m s)], kd [s/m], n [1/s], b and c [-]; "
                    "ke [1/m], kde [1/m per sample], kdu [-]. The command is a fraction of "
                    "the rated valve input."]))
    lin = linearize(cfg.params, 0.5 * cfg.params.cylinder.stroke)
    prm_rows = [[f"{g}.{k}", v] for g, d in to_dict(cfg.params).items() for k, v in d.items()]
    sections.append(Section(
        f"Parameter set '{cfg.set_name}'",
        paragraphs=[f"Linearised at mid-stroke: omega_0 = {lin.omega_0:.4g} rad/s, "
                    f"delta = {lin.damping:.4g}, "
                    f"K_o = {cfg.params.velocity_gain:.4g} m/s per unit "
                    "command."],
        tables=[Table(["parameter (SI units)", "value"], prm_rows)]))
    sections.append(Section("Departures from the paper", tables=[Table(
        ["topic", "paper", "fuzzyservo", "reason"],
        [[d.topic, d.paper, d.ours, d.reason] for d in DEPARTURES])]))
    report = write_html(out / "report.html",
                        "fuzzyservo: reproduction of Aly et al. (2012)", sections, meta)
    written.append(report)
    return {"report": report, "metrics": metrics_csv, "claims": claims_json}



def _tracking_rows(s: PlantStudy) -> list[tuple[str, str, str, str, str, float]]:
    """(controller key, label, experiment, metric, unit, value) of a plant's tracking study:
    NaN for a run that diverged (and for metrics a run never reached)."""
    tr = s.tracking
    assert tr is not None
    labels = {c.key: c.label for c in s.tracking_cases}
    rows = []
    for key in tr.keys:
        blocks = [(f"sine {f} Hz", "sine", m) for f, m in tr.sine[key].items()]
        blocks += [("move", "move", tr.move[key]), ("load step", "load", tr.load[key])]
        for experiment, kind, m in blocks:
            for name, unit in TRACKING_COLUMNS[kind]:
                rows.append((key, labels[key], experiment, name, unit,
                             float(m.get(name, math.nan))))
    return rows


def _write_tracking_csv(path: Path, studies: Sequence[PlantStudy]) -> Path:
    """tracking.csv: one row a metric of a design in an experiment on a plant (long format:
    its experiments have different metrics), every digit."""
    with atomic_write(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["plant", "controller", "label", "experiment", "metric", "unit", "value",
                    "gains"])
        for s in studies:
            if s.tracking is None:
                continue
            gains = {c.key: _fmt_gains(c.gains, exact=True) for c in s.tracking_cases}
            for key, label, experiment, name, unit, v in _tracking_rows(s):
                w.writerow([s.plant, key, label, experiment, name, unit, repr(v), gains[key]])
    return path


def _tracking_section(s: PlantStudy, cfg: StudyConfig, figures: list[Figure]) -> Section:
    """The report's section of a plant's tracking study: one table per experiment, and its
    ``figures``."""
    tr = s.tracking
    tc = cfg.tracking
    assert tr is not None and tc is not None
    labels = {c.key: c.label for c in s.tracking_cases}

    def val(m: Mapping[str, float], name: str, scale: float = 1.0) -> object:
        if m.get("diverged"):
            return "diverged"
        v = m.get(name, math.nan)
        return "never" if math.isnan(v) else v * scale

    sine_head = ["controller"]
    for f in tc.sine_frequencies:
        sine_head += [f"{f:g} Hz: RMS error [mm]", f"{f:g} Hz: max error [mm]",
                      f"{f:g} Hz: amplitude ratio [-]", f"{f:g} Hz: phase lag [deg]"]
    sine_rows = []
    for key in tr.keys:
        row: list[object] = [labels[key]]
        for f in tc.sine_frequencies:
            m = tr.sine[key][f"{f:g}"]
            row += [val(m, "rms_error", 1e3), val(m, "max_error", 1e3),
                    val(m, "amplitude_ratio"), val(m, "phase_lag")]
        sine_rows.append(row)
    move_rows = [[labels[k], val(tr.move[k], "max_following_error", 1e3),
                  val(tr.move[k], "overshoot"), val(tr.move[k], "settling_time"),
                  val(tr.move[k], "final_error", 1e3)] for k in tr.keys]
    load_rows = [[labels[k], val(tr.load[k], "max_deviation", 1e3),
                  val(tr.load[k], "recovery_time"), val(tr.load[k], "remaining", 1e3)]
                 for k in tr.keys]
    mv = tc.move
    speed = [f"{f:g} Hz: {tc.sine_amplitude * 2 * math.pi * f:.3g} m/s"
             for f in tc.sine_frequencies]
    return Section(
        f"Tracking and load disturbances on the {s.plant} plant",
        paragraphs=[
            f"Every design of the study with its step-study gains, and the baselines tuned "
            f"like the PIDs (ITAE on the {cfg.step * 1e3:g} mm step, <= 10 % overshoot), from "
            f"rest at mid-stroke. Sines of {tc.sine_amplitude * 1e3:g} mm, measured over their "
            f"last {tc.sine_periods} periods; their peak speeds ({'; '.join(speed)}) against "
            f"the valve's {cfg.params.velocity_gain:.3g} m/s at the full command. Amplitude "
            f"ratio and lag are those of the first harmonics of y and r.",
            f"The S-curve move: {mv.distance * 1e3:g} mm, at most {mv.v_max:g} m/s, "
            f"{mv.a_max:g} m/s², {mv.j_max:g} m/s³, from {mv.time:g} s to "
            f"{mv.time + mv.duration:.4g} s; settling into ±{tc.band:.0%} of the move after "
            f"its end. The load step: {tr.load_force / 1e3:.4g} kN opposing extension at "
            f"{tc.load_time:g} s; recovery into {tc.band:.0%} of the largest deviation; "
            f"remaining: the mean deviation over the last 0.5 s. tracking.csv has every "
            f"digit; docs/model.md, \"Tracking and load disturbances\", says why these "
            f"experiments."],
        tables=[Table(sine_head, sine_rows, caption="Sine tracking"),
                Table(["controller", "max following error [mm]", "overshoot [%]",
                       "settling after the move [s]", "final error [mm]"], move_rows,
                      caption="Jerk-limited move"),
                Table(["controller", "largest deviation [mm]", "recovery time [s]",
                       "remaining deviation [mm]"], load_rows,
                      caption="Load-force step at rest")],
        figures=figures)


def _write_frequency_csv(path: Path, studies: Sequence[PlantStudy]) -> Path:
    """frequency.csv: per plant and design, the analytic loop's margins and closed-loop
    figures (:data:`~fuzzyservo.study.frequency.MARGIN_FIELDS`), every digit."""
    with atomic_write(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["plant", "controller", "label", "analytic model"]
                   + [f"{n} [{u}]" for n, u in MARGIN_FIELDS])
        for s in studies:
            fq = s.frequency
            if fq is None:
                continue
            labels = {c.key: c.label for c in s.tracking_cases}
            for key in fq.keys:
                w.writerow([s.plant, key, labels[key], fq.analytic_plant]
                           + [repr(float(fq.margins[key][n])) for n, _ in MARGIN_FIELDS])
    return path


def _frequency_section(s: PlantStudy, figures: list[Figure]) -> Section:
    """The report's section of a plant's frequency responses: the margins table and the
    Bode figure."""
    fq = s.frequency
    assert fq is not None
    labels = {c.key: c.label for c in s.tracking_cases}

    def cell(v: float, scale: float = 1.0) -> object:
        return "none" if math.isinf(v) else ("n/a" if math.isnan(v) else v * scale)

    rows = []
    for key in fq.keys:
        m = fq.margins[key]
        rows.append([labels[key], "yes" if m["stable"] == 1.0 else (
            "n/a" if math.isnan(m["stable"]) else "no"), cell(m["gain_margin"]),
            cell(m["phase_crossover"]), cell(m["phase_margin_deg"]),
            cell(m["gain_crossover"]), cell(m["modulus_margin"]), cell(m["bandwidth"]),
            cell(m["peak_db"])])
    model = ("eq. (8) itself" if fq.analytic_plant == "linear"
             else "the small-signal model of the nonlinear plant at mid-stroke")
    paras = [f"Each design linearised at rest (feed-forward included) on {model}, in the "
             f"sampled loop the simulator runs (docs/frequency.md). The loop L is broken at "
             f"the plant input; gain margin 1/|L| at ∠L = -180°, phase margin at |L| = 1, "
             f"modulus margin min |1 + L|; bandwidth: where |T| first falls 3 dB below its "
             f"low-frequency value; peak: the largest |T|. frequency.csv has every digit."]
    if fq.measured_frequency.size:
        paras.append(f"On the nonlinear plant the figure also shows |T| and ∠T measured by "
                     f"simulation with sines of {fq.amplitude * 1e3:g} mm at "
                     f"{', '.join(f'{f:g}' for f in fq.measured_frequency)} Hz.")
    return Section(
        f"Frequency response on the {s.plant} plant", paragraphs=paras,
        tables=[Table(["controller", "stable", "gain margin [-]", "phase crossover [Hz]",
                       "phase margin [deg]", "gain crossover [Hz]", "modulus margin [-]",
                       "bandwidth (-3 dB) [Hz]", "peak |T| [dB]"], rows,
                      caption="Margins of the linearised loops")],
        figures=figures)
