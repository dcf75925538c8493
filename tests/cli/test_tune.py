"""``fuzzyservo tune``: gains that meet the overshoot limit when simulated again, one-line
errors with status 2, and an interrupted run that resumes from its checkpoint."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import fuzzyservo.commands.tune as tune_cmd
from fuzzyservo.analysis.autotune import TuningProgress
from fuzzyservo.cli import main
from fuzzyservo.files import checkpoint_path, load_checkpoint, read_gains_toml
from tests.helpers import printed_metrics

FAST = ["--popsize", "4", "--maxiter", "6", "--duration", "5", "--no-polish", "--quiet"]




def test_tuned_pid_meets_the_limit_in_simulate(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "pid.toml"
    assert main(["tune", "--controller", "pid", "--plant", "linear", "--objective", "itae",
                 "--max-overshoot", "10", "--out", str(out), *FAST]) == 0
    summary = capsys.readouterr().out
    assert "feasible=yes" in summary
    tuned = read_gains_toml(out)
    # the gains file as tune wrote it, fed back to simulate with the tuning's setup
    assert main(["simulate", "--plant", "linear", "--gains", str(out),
                 "--reference", "step:0.1", "--duration", "5",
                 "--out", str(tmp_path / "run.csv"), "--metrics"]) == 0
    m = printed_metrics(capsys.readouterr().out)
    assert m["overshoot"] <= 10.0
    assert abs(m["steady_state_error"]) <= 0.002 * 0.1
    # simulate prints 6 significant digits of the same run
    assert m["itae"] == pytest.approx(tuned.metrics["itae"], rel=1e-5)


@pytest.mark.parametrize(
    ("args", "needle"),
    [(["--controller", "lqr"], "lqr"),
     (["--controller", "pid", "--max-overshoot", "-1"], "--max-overshoot"),
     (["--controller", "pid", "--max-sse", "nan"], "--max-sse"),
     (["--controller", "pid", "--plant", "spring"], "spring"),
     (["--controller", "pid", "--objective", "iqe"], "iqe"),
     (["--controller", "pid", "--step", "0"], "step"),
     (["--controller", "pid", "--ts", "1e-9"], "at most 10000000 are allowed"),
     (["--controller", "pid", "--param", "valve.nothing=1"], "nothing"),
     (["--controller", "pid", "--resume"], "partial.npz")],
)
def test_bad_input_is_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                     args: list[str], needle: str) -> None:
    assert main(["tune", *args, "--out", str(tmp_path / "g.toml"), *FAST]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("fuzzyservo") and "error:" in err
    assert needle in err


def test_interrupt_writes_a_checkpoint_and_resume_finishes(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real = tune_cmd.tune_controller

    def interrupted(*a: Any, progress: Any, **kw: Any) -> Any:
        def stop(p: TuningProgress) -> None:
            progress(p)
            if p.generation == 2:
                raise KeyboardInterrupt

        return real(*a, progress=stop, **kw)

    out = tmp_path / "g.toml"
    monkeypatch.setattr(tune_cmd, "tune_controller", interrupted)
    assert main(["tune", "--controller", "pid", "--out", str(out), *FAST]) == 130
    ck = checkpoint_path(out)
    saved = load_checkpoint(ck)
    assert (saved.controller, saved.stage, saved.generation) == ("pid", "search", 2)
    assert not out.exists()
    monkeypatch.setattr(tune_cmd, "tune_controller", real)
    assert main(["tune", "--controller", "pid", "--out", str(out), "--resume", *FAST]) == 0
    assert read_gains_toml(out).controller == "pid"
    assert not ck.exists()
