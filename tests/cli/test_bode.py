"""``fuzzyservo bode``: margins on one table, the response as CSV, JSON and a figure, and bad
input on one line with status 2."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from fuzzyservo.cli import main

PID = ["--controller", "pid2", "--gains", "kp=6,ki=3,kd=0.05,b=0.7,c=0.5"]


def test_margins_table_and_measured_csv(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                        ) -> None:
    out = tmp_path / "bode.csv"
    assert main(["bode", "--plant", "linear", *PID, "--freq", "0.5:50:4", "--measured",
                 "--cycles", "2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    for row in ("gain margin", "phase margin", "modulus margin", "bandwidth", "peak",
                "stable          yes", "measured"):
        assert row in text
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 4
    for r in rows:  # measured on the linear plant: the analytic response (settling: 1e-7)
        assert 10 ** (float(r["measured_db"]) / 20) == pytest.approx(
            10 ** (float(r["magnitude_db"]) / 20), rel=1e-5, abs=1e-7)


def test_json_and_figure(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fig = tmp_path / "bode.png"
    assert main(["bode", "--plant", "linear", *PID, "--freq", "0.5:50:5", "--json",
                 "--out", str(fig)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["margins"]["stable"] is True
    assert len(doc["magnitude_db"]) == 5
    assert fig.stat().st_size > 0


@pytest.mark.parametrize("argv, message", [
    (["--freq", "1:2"], "--freq must be LO:HI:N"),
    (["--freq", "10:1:5"], "0 < LO < HI"),
    (["--freq", "1:600:5"], "Nyquist"),
    (["--amplitude", "-1"], "--amplitude"),
    (["--out", "x.txt"], ".csv, .png or .svg"),
])
def test_bad_input_is_one_line(argv: list[str], message: str,
                               capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bode", "--plant", "linear", *PID, *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
