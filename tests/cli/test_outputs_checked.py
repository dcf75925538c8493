"""Outputs checked before any work, overrides recorded, library noise kept off stderr
(issue 9, rows 14, 15, 20 and the one-line rule for errors raised inside libraries)."""

from __future__ import annotations

import argparse
import errno
import tomllib
from pathlib import Path

import pytest

import fuzzyservo.cli as cli
from fuzzyservo.cli import main
from fuzzyservo.errors import InputError

PID = ["simulate", "--plant", "linear", "--controller", "pid", "--gains", "kp=20,ki=2,kd=0.1",
       "--duration", "0.2"]
FAST_TUNE = ["tune", "--controller", "p", "--plant", "linear", "--popsize", "4", "--maxiter",
             "2", "--duration", "2", "--no-polish", "--quiet"]


def _one_line(capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    for n in needles:
        assert n in err, err
    return err


@pytest.mark.parametrize("argv", [
    [*PID, "--params", "in.toml", "--out", "in.toml"],
    [*PID, "--params", "in.toml", "--plot", "in.toml"],
    [*FAST_TUNE, "--params", "in.toml", "--out", "in.toml"],
], ids=["simulate-out", "simulate-plot", "tune-out"])
def test_an_output_that_is_an_input_is_refused_and_the_input_kept(
        argv: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Row 15: ``simulate ... --params in.toml --out in.toml`` overwrote the input."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in.toml").write_text("[supply]\npressure = 7.5e6\n")
    assert main(argv) == 2
    err = _one_line(capsys, "'in.toml'")
    assert "input" in err or ".png" in err  # --plot in.toml: refused by its suffix first
    assert (tmp_path / "in.toml").read_text() == "[supply]\npressure = 7.5e6\n"


def test_a_gains_file_is_an_input_too(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    text = 'controller = "p"\n[gains]\nkp = 5.0\n'
    (tmp_path / "g.toml").write_text(text)
    assert main(["simulate", "--plant", "linear", "--gains", "g.toml", "--duration", "0.2",
                 "--out", "./g.toml"]) == 2
    _one_line(capsys, "also an input")
    assert (tmp_path / "g.toml").read_text() == text


def test_plot_refuses_to_overwrite_a_run_it_reads(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run.svg"  # an odd name, but a run CSV all the same
    assert main([*PID, "--out", str(tmp_path / "r.csv")]) == 0
    run.write_bytes((tmp_path / "r.csv").read_bytes())
    capsys.readouterr()
    assert main(["plot", str(run), "--out", str(run)]) == 2
    _one_line(capsys, "also an input")
    assert run.read_bytes() == (tmp_path / "r.csv").read_bytes()


@pytest.mark.parametrize("out", ["adir", "nodir/x.csv"])
def test_a_folder_or_a_missing_folder_is_refused_before_the_run(
        out: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "adir").mkdir()
    assert main([*PID, "--out", out]) == 2
    _one_line(capsys, repr(out))


def test_tune_records_the_overrides_of_a_params_file(tmp_path: Path) -> None:
    """Row 14: the TOML of ``tune --params sp.toml`` listed no override."""
    sp = tmp_path / "sp.toml"
    sp.write_text("[supply]\npressure = 7.5e6\n[load]\nmass = 500.0\n")
    out = tmp_path / "g.toml"
    # status 1: this short search meets no constraint; the best gains are written all the same
    assert main([*FAST_TUNE, "--params", str(sp), "--param", "load.mass=600",
                 "--out", str(out)]) in (0, 1)
    doc = tomllib.loads(out.read_text())
    over = doc["tuning"]["overrides"]
    assert over == {"supply.pressure": 7.5e6, "load.mass": 600.0}  # --param wins


def test_numpy_warnings_do_not_reach_stderr(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """Row 20: ``--gains kp=1e308,...`` printed numpy RuntimeWarnings before its error."""
    assert main(["simulate", "--plant", "linear", "--controller", "pid", "--gains",
                 "kp=1e308,ki=1e308,kd=1e308", "--duration", "1",
                 "--out", str(tmp_path / "x.csv")]) == 2
    _one_line(capsys, "diverged")


def _handler_raising(exc: BaseException) -> argparse.ArgumentParser:
    def handler(args: argparse.Namespace) -> int:
        raise exc

    p = argparse.ArgumentParser()
    p.set_defaults(handler=handler)
    return p


def test_our_error_wrapped_by_a_library_is_printed_as_itself(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """scipy's optimiser and integrators re-raise errors of a callback inside their own."""
    try:
        try:
            raise InputError("--ts must be at least 1e-06 s, got 1e-09")
        except InputError as inner:
            raise RuntimeError("The map-like callable must be of the form f(func, iterable)"
                               ) from inner
    except RuntimeError as wrapped:
        exc = wrapped
    monkeypatch.setattr(cli, "build_parser", lambda **_: _handler_raising(exc))
    assert main([]) == 2
    assert capsys.readouterr().err == ("fuzzyservo: error: --ts must be at least 1e-06 s, "
                                       "got 1e-09\n")


def test_running_out_of_memory_is_one_line(monkeypatch: pytest.MonkeyPatch,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(cli, "build_parser", lambda **_: _handler_raising(MemoryError()))
    assert main([]) == 2
    _one_line(capsys, "out of memory")


def test_a_bug_still_shows_its_traceback(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only our own errors are turned into one line; a bug is not hidden."""
    monkeypatch.setattr(cli, "build_parser", lambda **_: _handler_raising(ZeroDivisionError()))
    with pytest.raises(ZeroDivisionError):
        main([])


@pytest.mark.parametrize("extra", [[], ["--open-loop", "--command", "0.1"]])
def test_a_substep_that_would_run_for_hours_is_refused(
        extra: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--substep 1e-12`` asked for 1e10 RK4 steps in a compiled loop that neither Ctrl-C
    nor a Python SIGTERM handler can stop (found by the fuzz script)."""
    argv = ["simulate", "--plant", "nonlinear", "--substep", "1e-12", "--duration", "0.01",
            "--out", str(tmp_path / "x.csv"), *extra]
    if not extra:
        argv += ["--controller", "p", "--gains", "kp=10"]
    assert main(argv) == 2
    _one_line(capsys, "1.1e+10 RK4 steps", "at most 1e+08")


def test_out_and_plot_naming_one_file_are_refused(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*PID, "--out", str(tmp_path / "a.svg"), "--plot", str(tmp_path / "a.svg")]) == 2
    _one_line(capsys, "--out and --plot name the same file")
    assert not (tmp_path / "a.svg").exists()


def test_review_messages(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Messages found misleading in review: a group that is not a table is not 'unknown';
    a reference just beyond the stroke is printed exactly, not rounded onto it."""
    bad = tmp_path / "bad.toml"
    bad.write_text("supply = 3\n")
    assert main(["linearize", "--params", str(bad)]) == 2
    _one_line(capsys, "'supply'", "must be a table ([supply]")
    assert main([*PID, "--start", "0.5", "--reference", "step:0.5000001",
                 "--out", str(tmp_path / "x.csv")]) == 2
    _one_line(capsys, "reaches 1.0000001 m")


def test_max_evaluations_takes_1e6(tmp_path: Path) -> None:
    assert main(["simulate", "--open-loop", "--command", "0.1", "--plant", "nonlinear",
                 "--method", "solve_ivp", "--duration", "0.01", "--max-evaluations", "1e6",
                 "--out", str(tmp_path / "x.csv")]) == 0


def test_an_os_error_wrapping_ours_is_printed_as_itself(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """An OSError from a library, with one of our errors as its cause, is ours: one line
    (the full-disk clause before the generic one must not take it)."""
    try:
        try:
            raise InputError("--ts must be at least 1e-06 s, got 1e-09")
        except InputError as inner:
            raise OSError(errno.EIO, "callback failed") from inner
    except OSError as wrapped:
        exc = wrapped
    monkeypatch.setattr(cli, "build_parser", lambda **_: _handler_raising(exc))
    assert main([]) == 2
    _one_line(capsys, "--ts must be at least 1e-06 s")


def test_no_room_for_a_temporary_file_does_not_blame_standard_output(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """ENOSPC from a write without a file name while standard output is fine: a temporary
    file's disk, said so; standard output stays usable."""
    exc = OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(cli, "build_parser", lambda **_: _handler_raising(exc))
    assert main([]) == 2
    _one_line(capsys, "cannot write a temporary file: No space left on device")


def test_another_os_error_is_not_hidden(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cli, "build_parser",
                        lambda **_: _handler_raising(OSError(errno.EIO, "I/O error")))
    with pytest.raises(OSError, match="I/O error"):
        main([])
