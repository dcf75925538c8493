"""``simulate --load-force``: the forms it takes, the same run from a CSV file as from the
same points inline, and bad input as one line with status 2 (tests/cli/test_bad_input.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fuzzyservo.cli import main
from fuzzyservo.run import RunSpec

PI = ["simulate", "--plant", "linear", "--controller", "pi", "--gains", "kp=10,ki=2",
      "--duration", "0.5"]


def _err(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    return err


@pytest.mark.parametrize(("value", "words"), [
    ("step:nan:0.1", ["step F", "finite", "nan"]),
    ("step:100:-0.5", ["step time T", ">= 0", "-0.5"]),
    ("pwl:0:0,0.3:5,0.2:1", ["increase strictly", "0.3", "0.2"]),
    ("ramp:5", ["unknown --load-force", "'ramp:5'", "step:F[:T]", "pwl:", "FILE.csv"]),
])
def test_bad_load_force_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                    value: str, words: list[str]) -> None:
    err = _err([*PI, f"--load-force={value}", "--out", str(tmp_path / "r.csv")], capsys)
    for w in words:
        assert w in err, (w, err)


def test_bad_csv_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "f.csv"
    bad.write_text("t,F\n0,1\n0.1,oops\n", encoding="utf-8")
    err = _err([*PI, "--load-force", str(bad), "--out", str(tmp_path / "r.csv")], capsys)
    assert "load-force CSV" in err and "'oops' is not a number" in err and "line 3" in err


def test_open_loop_refuses_a_load_force(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    err = _err(["simulate", "--open-loop", "--command", "0.1", "--load-force", "step:5",
                "--out", str(tmp_path / "r.csv")], capsys)
    assert "--load-force" in err and "closed loop" in err


@pytest.mark.parametrize("plant", ["linear", "small-signal", "nonlinear"])
def test_csv_profile_is_the_inline_points(tmp_path: Path, plant: str) -> None:
    """A CSV profile and the same points as pwl give the same bytes; a force changes y."""
    f = tmp_path / "load.csv"
    f.write_text("t,F\n0.1,0\n0.2,800\n0.4,-300\n", encoding="utf-8")
    base = [*PI[:2], plant, *PI[3:]]
    outs = {}
    for tag, extra in (("csv", ["--load-force", str(f)]),
                       ("pwl", ["--load-force", "pwl:0.1:0,0.2:800,0.4:-300"]),
                       ("none", [])):
        out = tmp_path / f"{tag}.csv"
        assert main([*base, "--out", str(out), *extra]) == 0
        outs[tag] = out.read_bytes()
    assert outs["csv"] == outs["pwl"] != outs["none"]


def test_command_line_of_a_run_with_a_load_force_replays_it(
        capsys: pytest.CaptureFixture[str]) -> None:
    spec = RunSpec(controller="pi", gains=(("kp", 10.0), ("ki", 2.0)), plant="small-signal",
                   duration=0.5, load_force="step:-400:0.2")
    assert "--load-force=step:-400:0.2" in spec.to_argv()
    assert RunSpec.from_argv(spec.to_argv()) == spec
    result = spec.run()
    assert main(["simulate", *spec.to_argv(), "--metrics"]) == 0
    shown = dict(ln.split()[:2] for ln in capsys.readouterr().out.splitlines())
    assert shown == {k: f"{v:.6g}" for k, v in result.metrics().as_dict().items()}


def test_help_names_the_flag_and_its_sign(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "--load-force SPEC" in out and "opposing extension" in out
