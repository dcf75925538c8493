"""``fuzzyservo`` itself: ``--version``, and a reader that closes the pipe early ends the command
quietly with status 141 (128 + SIGPIPE, documented in cli.py), as ``| head -1`` does."""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys

import pytest

import fuzzyservo
from fuzzyservo.cli import main

#: sys.executable is the venv's python when the tests run under the venv
PYTHON = sys.executable


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--version"]) == 0
    out, err = capsys.readouterr()
    assert out == f"fuzzyservo {fuzzyservo.__version__}\n" and err == ""
    # and it is the installed distribution's version (pyproject.toml), not a stale copy
    assert fuzzyservo.__version__ == importlib.metadata.version("fuzzyservo")


def _cli(args: list[str]) -> list[str]:
    return [PYTHON, "-c", f"from fuzzyservo.cli import main; raise SystemExit(main({args!r}))"]


def test_linearize_into_a_closed_pipe_is_quiet() -> None:
    # linearize prints ~500 bytes in one go: reading one line and then closing would race
    # with that single write (it usually lands in the pipe before the reader closes). So
    # the reader is gone before the command starts: its first write meets a closed pipe.
    r, w = os.pipe()
    os.close(r)
    try:
        proc = subprocess.Popen(_cli(["linearize"]), stdout=w, stderr=subprocess.PIPE)
    finally:
        os.close(w)
    _, err = proc.communicate(timeout=120)
    assert err == b""  # no traceback, no "Exception ignored ... BrokenPipeError"
    assert proc.returncode == 141  # 128 + SIGPIPE, cli.py


def test_linearize_read_in_full_is_status_zero() -> None:
    # the control: with a reader that stays, the same command succeeds and prints its lines
    proc = subprocess.run(_cli(["linearize"]), capture_output=True, timeout=120, check=False)
    assert proc.returncode == 0 and proc.stderr == b""
    assert proc.stdout.decode().splitlines()[0].startswith("position")


def test_simulate_to_stdout_piped_into_head() -> None:
    # 50 s at 1 ms: ~50 001 CSV lines, megabytes, far more than a pipe buffer holds, so
    # writes are still pending when the reader closes after the first line
    proc = subprocess.Popen(
        _cli(["simulate", "--plant", "linear", "--controller", "p", "--gains", "kp=4",
              "--duration", "50", "--out", "-"]),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    first = proc.stdout.readline()
    proc.stdout.close()
    err = proc.stderr.read()
    proc.stderr.close()
    assert proc.wait(timeout=120) == 141  # 128 + SIGPIPE, cli.py
    assert first.decode().startswith("t,r,y,u")
    assert err == b""  # no traceback, no "Exception ignored ... BrokenPipeError"
