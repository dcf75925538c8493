"""``fuzzyservo tune``: gains that meet the overshoot limit when simulated again, one-line
errors with status 2, and an interrupted run that resumes from its checkpoint."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import fuzzyservo.commands.tune as tune_cmd
from fuzzyservo.analysis.autotune import TuningProgress
from fuzzyservo.cli import main
from fuzzyservo.errors import InputError
from fuzzyservo.files import checkpoint_path, load_checkpoint, read_gains_toml, save_checkpoint
from tests.helpers import printed_metrics

REAL_TUNE = tune_cmd.tune_controller
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


def _interrupting(monkeypatch: pytest.MonkeyPatch, stage: str, generation: int,
                  restart: int = 0) -> None:
    """Make the next ``tune`` raise Ctrl-C right after search ``restart`` of ``stage``
    reports ``generation``."""
    real = tune_cmd.tune_controller

    def interrupted(*a: Any, progress: Any, **kw: Any) -> Any:
        def stop(p: TuningProgress) -> None:
            progress(p)
            if (p.stage, p.restart, p.generation) == (stage, restart, generation):
                raise KeyboardInterrupt

        return real(*a, progress=stop, **kw)

    monkeypatch.setattr(tune_cmd, "tune_controller", interrupted)


def _without_times(path: Path) -> str:
    """The gains file with the wall time and the date removed (the only fields that may
    differ between two runs of the same tuning)."""
    return "\n".join(line for line in path.read_text().splitlines()
                     if not line.startswith(("elapsed = ", "date = ")))


def test_interrupt_writes_a_checkpoint_and_resume_finishes(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "g.toml"
    _interrupting(monkeypatch, "search", 2)
    assert main(["tune", "--controller", "pid", "--out", str(out), *FAST]) == 130
    ck = checkpoint_path(out)
    saved = load_checkpoint(ck)
    assert (saved.setup["controller"], saved.stage, saved.generation) == ("pid", "search", 2)
    assert not out.exists()
    monkeypatch.setattr(tune_cmd, "tune_controller", REAL_TUNE)
    assert main(["tune", "--controller", "pid", "--out", str(out), "--resume", *FAST]) == 0
    assert read_gains_toml(out).controller == "pid"
    assert not ck.exists()



#: A self-tuning fuzzy PI tuning small enough for a test (its three stages, the polish and
#: the stopping rule all run): 2 s runs of a 20 mm step.
STFPI = ["--controller", "stfpi", "--plant", "linear", "--step", "0.02", "--duration", "2",
         "--popsize", "4", "--patience", "8", "--restarts", "2", "--quiet"]


@pytest.mark.slow
def test_interrupted_and_resumed_tuning_equals_the_uninterrupted_one(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Acceptance: Ctrl-C at three points, then --resume: the gains file is the
    uninterrupted run's, byte for byte but for the date and the wall time, generations
    counted on."""
    ref = tmp_path / "ref.toml"
    code = main(["tune", *STFPI, "--out", str(ref)])  # 1 if the short runs are infeasible
    assert code in (0, 1)
    tuned = read_gains_toml(ref)
    fpi, refine = tuned.stage("fpi"), tuned.stage("refine")
    assert fpi.generations > 8 and refine.generations > 8  # two searches each
    points = [("fpi", 0, 3),        # early in step 1's first search
              ("fpi", 1, 0),        # step 1's second search, just after its initial population
              ("refine", 1, 5)]     # step 3's second search (step 1's result is replayed)
    for stage, restart, gen in points:
        out = tmp_path / f"{stage}-{restart}-{gen}.toml"
        _interrupting(monkeypatch, stage, gen, restart)
        assert main(["tune", *STFPI, "--out", str(out)]) == 130
        ck = load_checkpoint(checkpoint_path(out))
        assert (ck.stage, ck.restart, ck.generation) == (stage, restart, gen)
        seen: list[tuple[str, int, int]] = []

        def watch(*a: Any, progress: Any, seen: list[tuple[str, int, int]] = seen,
                  **kw: Any) -> Any:
            def note(p: TuningProgress) -> None:
                seen.append((p.stage, p.restart, p.generation))
                progress(p)
            return REAL_TUNE(*a, progress=note, **kw)

        monkeypatch.setattr(tune_cmd, "tune_controller", watch)
        assert main(["tune", *STFPI, "--out", str(out), "--resume"]) == code
        assert seen[0] == (stage, restart, gen + 1)  # generations counted on
        assert _without_times(out) == _without_times(ref)
        assert not checkpoint_path(out).exists()
    capsys.readouterr()


@pytest.mark.parametrize(("change", "needle"), [
    (["--step", "0.03"], "step (--step) = 0.02, this run has 0.03"),
    (["--set", "stiff-oil"], "param_set (--set) = 'paper', this run has 'stiff-oil'"),
    (["--seed", "4"], "seed (--seed) = 0, this run has 4"),
    (["--popsize", "5"], "popsize (--popsize) = 4, this run has 5"),
    (["--max-overshoot", "5"], "constraints"),
    (["--delay", "0.006"], "delay (--delay) = 0.0, this run has 0.006"),
    (["--param", "load.mass=20000"], "overrides"),
    (["--plant", "nonlinear"], "plant (--plant) = 'linear', this run has 'nonlinear'"),
    (["--restarts", "3"], "restarts (--restarts) = 2, this run has 3"),
])
def test_a_resume_with_another_setting_is_refused_naming_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        change: list[str], needle: str) -> None:
    out = tmp_path / "g.toml"
    _interrupting(monkeypatch, "fpi", 1)
    assert main(["tune", *STFPI, "--out", str(out)]) == 130
    monkeypatch.setattr(tune_cmd, "tune_controller", REAL_TUNE)
    capsys.readouterr()
    assert main(["tune", *STFPI, *change, "--out", str(out), "--resume"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err and "partial.npz" in err
    assert checkpoint_path(out).exists() and not out.exists()


def _tamper(ck: Any, kind: str) -> Any:
    st = ck.state
    if kind == "population":
        return dataclasses.replace(ck, state=dataclasses.replace(
            st, population=st.population[:2]))
    if kind == "range":
        return dataclasses.replace(ck, state=dataclasses.replace(
            st, population=st.population * 3.0))
    if kind == "costs":
        return dataclasses.replace(ck, state=dataclasses.replace(
            st, costs=np.full_like(st.costs, np.nan)))
    if kind == "history":
        return dataclasses.replace(ck, state=dataclasses.replace(st, history=st.history[:-1]))
    if kind == "generation":
        return dataclasses.replace(ck, state=dataclasses.replace(st, generation=-5))
    if kind == "stage":
        return dataclasses.replace(ck, stage="polish")
    if kind == "restart":
        return dataclasses.replace(ck, restart=7)
    raise AssertionError(kind)


@pytest.mark.parametrize(("kind", "needle"), [
    ("population", "must hold"), ("range", "in [0, 1]"), ("costs", "finite numbers"),
    ("history", "history"), ("generation", "generation -5"), ("stage", "'polish'"),
    ("restart", "restart 7"),
])
def test_a_damaged_checkpoint_is_one_line_not_a_traceback(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        kind: str, needle: str) -> None:
    """Found in review: a population of two members was a traceback, and a NaN cost, a short
    history or a negative generation count were accepted and gave wrong counts."""
    out = tmp_path / "g.toml"
    _interrupting(monkeypatch, "search", 3)
    assert main(["tune", "--controller", "pid", "--out", str(out), *FAST]) == 130
    monkeypatch.setattr(tune_cmd, "tune_controller", REAL_TUNE)
    ck = checkpoint_path(out)
    save_checkpoint(ck, _tamper(load_checkpoint(ck), kind))
    capsys.readouterr()
    assert main(["tune", "--controller", "pid", "--out", str(out), "--resume", *FAST]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err and "without --resume" in err
    assert not out.exists()


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_a_checkpoint_that_is_not_a_regular_file_is_refused_without_reading_it(
        tmp_path: Path, kind: str) -> None:
    """A FIFO would block the read for ever and /dev/zero would fill memory: refused in one
    line, before any read."""
    ck = tmp_path / "g.toml.partial.npz"
    if kind == "fifo":
        os.mkfifo(ck)
    else:
        ck.symlink_to("/dev/zero")
    with pytest.raises(InputError, match="not a regular file.*run without --resume"):
        load_checkpoint(ck)
