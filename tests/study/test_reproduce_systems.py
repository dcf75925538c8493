"""``fuzzyservo reproduce --du-system FILE``: the study's fuzzy controllers run the file's
system, its rows equal ``simulate`` with the same gains and file, the report names it."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from fuzzyservo.cli import main
from fuzzyservo.formats import write_system
from tests.cli.test_systems_in_loop import GAINS, _five_by_five
from tests.helpers import printed_metrics


@pytest.mark.slow
def test_reproduce_with_a_du_system_file(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    five = tmp_path / "five.fll"
    write_system(_five_by_five(), five)
    out = tmp_path / "study"
    assert main(["reproduce", "--plant", "linear", "--duration", "5", "--du-system", str(five),
                 "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "were tuned with the paper's fuzzy systems" in err and "--retune" in err
    report = (out / "report.html").read_text()
    assert "fuzzy systems" in report and str(five) in report
    with (out / "metrics.csv").open() as fh:
        rows = {(r["controller"], r["delay [s]"]): r for r in csv.DictReader(fh)}
    row = rows[("stfpi_10", "0.0")]
    assert main(["simulate", "--gains", str(GAINS / "linear-stfpi.toml"), "--du-system",
                 str(five), "--duration", "5", "--metrics", "--out",
                 str(tmp_path / "run.csv")]) == 0
    m = printed_metrics(capsys.readouterr().out)
    # the same loop through the same registry: equal up to the printed 6 digits of --metrics
    assert float(row["overshoot [%]"]) == pytest.approx(m["overshoot"], rel=1e-5)
    assert float(row["itae [m s^2]"]) == pytest.approx(m["itae"], rel=1e-5)
    # and the file's system changed the result (the paper's Δu system gives another ITAE)
    assert main(["simulate", "--gains", str(GAINS / "linear-stfpi.toml"), "--duration", "5",
                 "--metrics", "--out", str(tmp_path / "run2.csv")]) == 0
    paper = printed_metrics(capsys.readouterr().out)
    assert abs(paper["itae"] - m["itae"]) > 1e-3 * paper["itae"]
