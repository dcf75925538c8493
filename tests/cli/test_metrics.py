"""``fuzzyservo metrics``: reads a run CSV, prints metrics, fails on one line with status 2."""

from __future__ import annotations

import json
import math
from pathlib import Path

import control as ct
import numpy as np
import pytest

from fuzzyservo.cli import main
from fuzzyservo.sim.stepinfo import METRIC_NAMES


def _write_run(path: Path, *, header: str = "t,r,y,u,alpha", comment: bool = False) -> None:
    sys = ct.tf([4], [1, 1.2, 4])  # underdamped, zeta = 0.3
    t, y = ct.step_response(sys, np.linspace(0.0, 20.0, 2001))
    u = 1.0 - y  # any command signal
    lines = ["# written by a test"] if comment else []
    lines.append(header)
    lines += [
        f"{a!r},1.0,{b!r},{c!r},0.5"
        for a, b, c in zip(t.tolist(), y.tolist(), u.tolist(), strict=True)
    ]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def test_json_matches_python_control(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run.csv"
    _write_run(run, comment=True)
    assert main(["metrics", str(run), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert list(got) == list(METRIC_NAMES)
    t, y = ct.step_response(ct.tf([4], [1, 1.2, 4]), np.linspace(0.0, 20.0, 2001))
    ref = ct.step_info(y, T=t, yfinal=1.0)
    dt = t[1] - t[0]
    assert got["rise_time"] == pytest.approx(ref["RiseTime"], abs=dt)  # one sample
    assert got["settling_time"] == pytest.approx(ref["SettlingTime"], abs=dt)  # one sample
    assert got["peak_time"] == pytest.approx(ref["PeakTime"], abs=dt)  # one sample
    assert got["overshoot"] == pytest.approx(ref["Overshoot"], abs=0.5)  # 0.5 % of amplitude
    # u = 1 - y = r - y: the command's maximum is the initial error, 1 (exact: y[0] = 0)
    assert got["u_max"] == 1.0
    assert got["steady_state_error"] == pytest.approx(1.0 - y[-1], abs=1e-15)  # repr round-trip
    # integral criteria: numpy's trapezoid rule on the same samples (summation-order rounding)
    e = 1.0 - y
    assert got["iae"] == pytest.approx(np.trapezoid(np.abs(e), t), rel=1e-12)
    assert got["ise"] == pytest.approx(np.trapezoid(e**2, t), rel=1e-12)
    assert got["itae"] == pytest.approx(np.trapezoid(t * np.abs(e), t), rel=1e-12)
    assert got["itse"] == pytest.approx(np.trapezoid(t * e**2, t), rel=1e-12)
    assert got["u_sq_integral"] == pytest.approx(np.sum(e[:-1] ** 2 * np.diff(t)), rel=1e-12)


def test_text_output_one_line_per_metric(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run.csv"
    _write_run(run)
    assert main(["metrics", str(run)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == list(METRIC_NAMES)
    assert lines[0].split()[-1] == "s" and lines[3].split()[-1] == "%"


def test_nan_is_null_in_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run.csv"
    t = np.linspace(0.0, 1.0, 11)
    body = "\n".join(f"{a},1.0,{0.5 * a},0.0,1.0" for a in t)  # reaches only 50 %
    run.write_text("t,r,y,u,alpha\n" + body + "\n", encoding="utf-8")
    assert main(["metrics", str(run), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["rise_time"] is None and got["settling_time"] is None
    assert got["steady_state_error"] == pytest.approx(0.5, abs=1e-15)  # 1 - 0.5, exact decimals
    assert not math.isnan(got["iae"])


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (None, "cannot read run CSV"),
        ("", "is empty"),
        ("t,y,alpha\n0,0,1\n1,1,1\n", "lacks column(s) r, u"),
        ("t,r,y,u\n0,1,0,0\n1,1,abc,0\n", "line 3, column 'y': 'abc' is not a number"),
        ("t,r,y,u\n0,1,0,0\n0,1,1,0\n", "strictly increasing"),
        ("t,r,y,u\n0,1,0,0\n1,1,nan,0\n", "not finite"),
    ],
)
def test_bad_files_fail_on_one_line_with_status_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str | None, match: str
) -> None:
    run = tmp_path / "run.csv"
    if content is not None:
        run.write_text(content, encoding="utf-8")
    assert main(["metrics", str(run)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fuzzyservo: error: ")
    assert match in err


def test_regression_sine_reference_reports_no_step(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Review defect 2: a run with --reference sine:0.05:0.5 over 6 s ends with r[-1] one ulp
    # below y[0] = 0.5; metrics printed overshoot 8.15e16 % and rise time 1.2 s.
    t = np.linspace(0.0, 6.0, 6001)
    r = 0.5 + 0.05 * np.sin(np.pi * t)
    y = 0.5 + 0.05 * np.sin(np.pi * t - 0.3) * (1.0 - np.exp(-5.0 * t))
    u = 4.0 * (r - y)
    assert r[-1] != y[0]  # the reported rounding
    cols = (t.tolist(), r.tolist(), y.tolist(), u.tolist())
    rows = [f"{a!r},{b!r},{c!r},{d!r}" for a, b, c, d in zip(*cols, strict=True)]
    run = tmp_path / "run.csv"
    run.write_text("t,r,y,u\n" + "\n".join(rows) + "\n", encoding="utf-8")
    assert main(["metrics", str(run), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    for name in ("rise_time", "settling_time", "settling_time_5", "overshoot", "peak_time"):
        assert got[name] is None, name
    e = r - y
    assert got["iae"] == pytest.approx(np.trapezoid(np.abs(e), t), rel=1e-12)  # rounding
    assert got["u_max"] == pytest.approx(np.max(np.abs(u)), rel=1e-15)  # repr round-trip


def test_regression_error_messages_show_plain_floats(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Review defect 3: "t[2] = np.float64(0.001) <= t[1] = ..." instead of plain numbers
    run = tmp_path / "run.csv"
    run.write_text("t,r,y,u\n0,1,0,0\n0.001,1,0.5,0\n0.001,1,1,0\n", encoding="utf-8")
    assert main(["metrics", str(run)]) == 2
    err = capsys.readouterr().err
    assert "t[2] = 0.001 <= t[1] = 0.001" in err and "np." not in err
