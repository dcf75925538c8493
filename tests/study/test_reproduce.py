"""The reproduction end to end: outputs, computed verdicts, agreement with `simulate`."""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
from html import escape
from pathlib import Path

import pytest

from fuzzyservo.cli import main
from fuzzyservo.paper import PAPER_PIDS, named_set
from fuzzyservo.sim import DEFAULT_DELAY
from fuzzyservo.study.paper_study import TUNED_DESIGNS, Design, StudyConfig, run_plant_study
from fuzzyservo.study.runner import default_gains_dir, load_tuned
from tests.helpers import printed_metrics

SHORT = dict(duration=6.0, delay_sweep=(0.0, 0.006, 0.05, 0.2))
COLUMNS = ("rise_time", "settling_time", "overshoot", "steady_state_error", "iae", "itae",
           "u_max")


def _designs(plant: str) -> dict[str, Design]:
    return {k: (v.controller, dict(v.gains))
            for k, v in load_tuned(plant, default_gains_dir()).items()}




PLANTS = ("linear", "nonlinear")


def test_reproduce_writes_every_output(reproduced: Path) -> None:
    out = reproduced
    for plant in PLANTS:
        for stem in ("fig4", "fig5", "fig6", "fig7", "fig8", "fig8_delay_overshoot",
                     "robustness", "tracking_sine", "tracking_move", "tracking_load", "bode"):
            assert (out / f"{stem}_{plant}.png").stat().st_size > 10_000, (stem, plant)
            assert (out / f"{stem}_{plant}.svg").is_file(), (stem, plant)
    assert (out / "fig3a_surface_du.png").stat().st_size > 10_000
    claims = json.loads((out / "claims.json").read_text())
    assert [(c["plant"], c["id"]) for c in claims] == [
        (p, f"C{i}") for p in PLANTS for i in range(1, 10)]
    for c in claims:
        assert set(c) == {"id", "claim", "verdict", "evidence", "plant", "rule", "thresholds",
                          "data"}
        assert c["verdict"] in ("holds", "does not hold", "holds under stated conditions")
        assert c["evidence"]
    html = (out / "report.html").read_text()
    # offline: nothing fetched (the embedded PNGs' base64 may spell "http" by chance)
    text = re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]*", "", html)
    assert "data:image/png;base64," in html and "http" not in text.replace("http-equiv", "")
    for needle in ("Departures from the paper", "Parameter set", "Controller gains",
                   "load.mass", "Tracking and load disturbances on the nonlinear plant",
                   "Frequency response on the linear plant", "Jerk-limited move"):
        assert needle in html
    # the tracking study: every design of the study and the baselines, in each experiment
    with (out / "tracking.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    keys = {(r["plant"], r["controller"], r["experiment"]) for r in rows}
    from fuzzyservo.study.paper_study import TRACKING_KEYS

    assert keys == {(p, k, e) for p in PLANTS for k in TRACKING_KEYS
                    for e in ("sine 0.5 Hz", "sine 1 Hz", "sine 2 Hz", "move", "load step")}
    with (out / "frequency.csv").open() as fh:
        margins = list(csv.DictReader(fh))
    assert {(r["plant"], r["controller"]) for r in margins} == {
        (p, k) for p in PLANTS for k in TRACKING_KEYS}
    for plant in PLANTS:
        assert len(list((out / "traces").glob(f"{plant}_*.csv"))) >= 8


def test_second_run_reuses_the_cache(reproduced: Path, tmp_path: Path) -> None:
    again = tmp_path / "results"
    shutil.copytree(reproduced, again)  # the shared reproduction stays as it is
    before = {p: p.stat().st_mtime_ns for p in (again / ".cache").iterdir()}
    assert len(before) == 2  # one entry per plant
    assert main(["reproduce", "--out", str(again), "--plant", "linear", "--quiet"]) == 0
    after = {p: p.stat().st_mtime_ns for p in (again / ".cache").iterdir()}
    assert before == after  # nothing recomputed


def _simulate_args(key: str, plant: str) -> list[str]:
    """How a user reruns a study controller: its committed gains file, or the paper's
    gains as printed; nothing else than the plant, reference and duration."""
    if key in PAPER_PIDS:
        g = PAPER_PIDS[key]
        return ["--controller", "pid", "--gains", f"kp={g.kp},ki={g.ki},kd={g.kd}"]
    name = TUNED_DESIGNS[key][0]
    return ["--gains", str(default_gains_dir() / f"{plant}-{name}.toml")]


@pytest.mark.parametrize("plant", PLANTS)
def test_simulate_reproduces_every_metrics_row_with_no_extra_flag(
        reproduced: Path, capsys: pytest.CaptureFixture[str], plant: str) -> None:
    """Issue 8's acceptance: ``fuzzyservo simulate --gains FILE --plant linear --reference
    step:0.1 --duration 20 --metrics`` prints the row of metrics.csv: the study's nominal
    runs and simulate use the same default delay (none). Every row, both plants."""
    assert StudyConfig(params=named_set("paper")).delay == DEFAULT_DELAY == 0.0
    with (reproduced / "metrics.csv").open() as fh:
        rows = {r["controller"]: r for r in csv.DictReader(fh)
                if r["plant"] == plant and float(r["delay [s]"]) == 0.0}  # the nominal runs
    assert set(rows) == set(PAPER_PIDS) | set(TUNED_DESIGNS)
    html = (reproduced / "report.html").read_text()
    start = html.index(f"Results on the {plant} plant")
    for key, row in rows.items():
        capsys.readouterr()
        assert main(["simulate", *_simulate_args(key, plant), "--plant", plant, "--reference",
                     "step:0.1", "--duration", "20", "--metrics"]) == 0, key
        printed = printed_metrics(capsys.readouterr().out)
        row_start = html.index(f"<td>{escape(row['label'])}</td>", start)
        cells = re.findall(r'<td class="num">([^<]*)</td>',
                           html[row_start:html.index("</tr>", row_start)])
        for i, col in enumerate(COLUMNS):
            value = float(next(v for k, v in row.items() if k.startswith(col + " ")))
            if math.isnan(value):  # e.g. never settled in the run: both say so
                assert math.isnan(printed[col]) and cells[i] == "n/a", (key, col)
                continue
            # the same run through the same code; simulate prints 6 significant digits
            assert value == pytest.approx(printed[col], rel=5e-6, abs=1e-12), (key, col)
            # the report shows 4 significant digits of the same number
            assert float(cells[i]) == pytest.approx(printed[col], rel=6e-4, abs=1e-12), col


def test_changing_a_gain_changes_verdicts_or_evidence() -> None:
    cfg = StudyConfig(params=named_set("paper"), **SHORT)  # type: ignore[arg-type]
    designs = _designs("linear")
    base = run_plant_study("linear", cfg, designs)
    kind, gains = designs["stfpi-os0"]
    designs["stfpi-os0"] = (kind, {**gains, "kdu": 4.0 * gains["kdu"]})
    changed = run_plant_study("linear", cfg, designs)
    a = [(c.verdict, c.evidence) for c in base.claims]
    b = [(c.verdict, c.evidence) for c in changed.claims]
    assert a != b
    assert base.claims[0].evidence != changed.claims[0].evidence  # C1 quotes the overshoot
