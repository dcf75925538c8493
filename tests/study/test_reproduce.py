"""The reproduction end to end: outputs, computed verdicts, agreement with `simulate`."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import pytest

from fuzzyservo.cli import main
from fuzzyservo.paper import named_set
from fuzzyservo.study.paper_study import StudyConfig, run_plant_study
from fuzzyservo.study.runner import default_gains_dir, load_tuned

SHORT = dict(duration=6.0, delay_sweep=(0.0, 0.006, 0.05, 0.2))


def _gains(plant: str) -> dict[str, dict[str, float]]:
    return {k: dict(v.gains) for k, v in load_tuned(plant, default_gains_dir()).items()}


@pytest.fixture(scope="module")
def linear_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("repro")
    status = main(["reproduce", "--out", str(out), "--plant", "linear", "--duration", "6",
                   "--quiet"])
    assert status == 0
    return out


def test_reproduce_writes_every_output(linear_run: Path) -> None:
    out = linear_run
    for stem in ("fig4_linear", "fig5_linear", "fig6_linear", "fig7_linear", "fig8_linear",
                 "fig8_delay_overshoot_linear", "robustness_linear", "fig3a_surface_du"):
        assert (out / f"{stem}.png").stat().st_size > 10_000, stem
        assert (out / f"{stem}.svg").is_file(), stem
    claims = json.loads((out / "claims.json").read_text())
    assert [c["id"] for c in claims] == [f"C{i}" for i in range(1, 9)]
    for c in claims:
        assert set(c) == {"id", "claim", "verdict", "evidence", "plant"}
        assert c["verdict"] in ("holds", "does not hold", "holds under stated conditions")
        assert c["plant"] == "linear" and c["evidence"]
    html = (out / "report.html").read_text()
    assert "data:image/png;base64," in html and "http" not in html.replace(
        "http-equiv", "")  # offline: nothing fetched
    for needle in ("Departures from the paper", "Parameter set", "Controller gains",
                   "load.mass"):
        assert needle in html
    assert len(list((out / "traces").glob("linear_*.csv"))) >= 8


def test_second_run_reuses_the_cache(linear_run: Path, capsys: pytest.CaptureFixture[str]
                                     ) -> None:
    before = {p: p.stat().st_mtime_ns for p in (linear_run / ".cache").iterdir()}
    assert main(["reproduce", "--out", str(linear_run), "--plant", "linear", "--duration", "6",
                 "--quiet"]) == 0
    after = {p: p.stat().st_mtime_ns for p in (linear_run / ".cache").iterdir()}
    assert before == after  # nothing recomputed


def test_report_numbers_equal_simulate_metrics(linear_run: Path, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    with (linear_run / "metrics.csv").open() as fh:
        rows = {r["controller"]: r for r in csv.DictReader(fh) if r["plant"] == "linear"}
    row = rows["stfpi"]
    gains = row["gains"].replace(" = ", "=").replace(", ", ",")
    capsys.readouterr()
    assert main(["simulate", "--plant", "linear", "--controller", "stfpi", "--gains", gains,
                 "--reference", "step:0.1", "--duration", "6", "--ts", "0.001", "--delay", "0",
                 "--out", str(tmp_path / "run.csv"), "--metrics"]) == 0
    printed = {}
    for line in capsys.readouterr().out.splitlines():
        parts = line.split()
        if len(parts) >= 2:
            printed[parts[0]] = float(parts[1])
    html = (linear_run / "report.html").read_text()
    start = html.index("Results on the linear plant")
    row_start = html.index(f"<td>{row['label']}</td>", start)
    cells = re.findall(r'<td class="num">([^<]*)</td>',
                       html[row_start:html.index("</tr>", row_start)])
    for i, col in enumerate(("rise_time", "settling_time", "overshoot", "steady_state_error",
                             "iae", "itae", "u_max")):
        key = next(k for k in row if k.startswith(col + " "))
        # the same run through the same code; simulate prints 6 significant digits
        assert float(row[key]) == pytest.approx(printed[col], rel=5e-6, abs=1e-12), col
        # the report shows 4 significant digits of the same number
        assert float(cells[i]) == pytest.approx(printed[col], rel=6e-4, abs=1e-12), col


def test_changing_a_gain_changes_verdicts_or_evidence() -> None:
    cfg = StudyConfig(params=named_set("paper"), **SHORT)  # type: ignore[arg-type]
    gains = _gains("linear")
    base = run_plant_study("linear", cfg, gains)
    gains["stfpi-os0"]["kdu"] *= 4.0
    changed = run_plant_study("linear", cfg, gains)
    a = [(c.verdict, c.evidence) for c in base.claims]
    b = [(c.verdict, c.evidence) for c in changed.claims]
    assert a != b
    assert base.claims[0].evidence != changed.claims[0].evidence  # C1 quotes the overshoot
