"""Bad input found in review: each is one error line with status 2 (or 1 where noted)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fuzzyservo.cli import main

STFPI = ["simulate", "--plant", "linear", "--controller", "stfpi", "--gains",
         "ke=10,kde=5000,kdu=0.006", "--duration", "1"]


def _err(argv: list[str], capsys: pytest.CaptureFixture[str], status: int = 2) -> str:
    assert main(argv) == status
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


def test_duplicate_gain_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = _err(["simulate", "--plant", "linear", "--controller", "pid", "--gains",
                "kp=1,ki=0.1,kd=0.1,kp=8", "--out", str(tmp_path / "r.csv")], capsys)
    assert "kp is given twice" in err and err.count("\n") == 1


def test_negative_seed_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = _err([*STFPI, "--seed", "-1", "--out", str(tmp_path / "r.csv")], capsys)
    assert "--seed" in err and "-1" in err


def test_run_too_long_for_memory_is_rejected(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    err = _err(["simulate", "--plant", "nonlinear", "--controller", "p", "--gains", "kp=10",
                "--ts", "1e-9", "--duration", "1", "--out", str(tmp_path / "r.csv")], capsys)
    assert "samples" in err and "at most" in err


def test_delay_is_none_unless_asked(tmp_path: Path) -> None:
    """--delay omitted is no delay, whatever the set's delay.transport_delay; --delay hose
    takes delay.transport_delay; an explicit --delay S is S."""
    outs = {}
    for tag, extra in (("default", ["--param", "delay.transport_delay=0.05"]),
                       ("hose", ["--delay", "hose", "--param", "delay.transport_delay=0.05"]),
                       ("explicit", ["--delay", "0.05"]), ("none", ["--delay", "0"])):
        out = tmp_path / f"{tag}.csv"
        assert main([*STFPI, "--out", str(out), *extra]) == 0
        outs[tag] = out.read_text()
    assert outs["default"] == outs["none"] != outs["explicit"] == outs["hose"]


def test_tune_seed_must_be_non_negative(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    err = _err(["tune", "--controller", "pid", "--plant", "linear", "--seed", "-3",
                "--out", str(tmp_path / "g.toml")], capsys)
    assert "seed" in err


def test_tune_that_cannot_meet_its_constraints_says_so(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "g.toml"
    err = _err(["tune", "--controller", "pid", "--plant", "linear", "--max-u", "0",
                "--popsize", "3", "--maxiter", "2", "--no-polish", "--duration", "2",
                "--quiet", "--out", str(out)], capsys, status=1)
    assert "meet the constraints" in err
    assert out.is_file()  # the best found is kept, not lost


def test_reproduce_refuses_runs_too_short_to_judge(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    err = _err(["reproduce", "--out", str(tmp_path / "r"), "--plant", "linear",
                "--duration", "0.01", "--quiet"], capsys)
    assert "--duration" in err and "0.01" in err


def test_reproduce_into_a_path_below_a_file(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "afile"
    f.write_text("x")
    err = _err(["reproduce", "--out", str(f / "sub"), "--plant", "linear", "--duration", "5",
                "--quiet"], capsys)
    assert "cannot write" in err
