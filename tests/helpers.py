"""Small helpers shared by the tests."""

from __future__ import annotations

import shlex
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def make_recipe(target: str) -> list[str]:
    """The fuzzyservo arguments of a Makefile target's recipe (``$(BIN)/fuzzyservo ...``)."""
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    body = text.split(f"\n{target}:", 1)[1].split("\n\n", 1)[0]
    recipe = next(ln.strip() for ln in body.splitlines() if "fuzzyservo " in ln)
    return shlex.split(recipe.split("fuzzyservo", 1)[1])


def printed_metrics(text: str) -> dict[str, float]:
    """``name value unit`` lines (``simulate --metrics``, ``fuzzyservo metrics``) as a dict."""
    out = {}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) >= 2:
            try:
                out[parts[0]] = float(parts[1])
            except ValueError:
                continue
    return out


def default_sigint() -> None:
    """``preexec_fn`` of a child that reacts to Ctrl-C as in a terminal: background jobs and
    pytest-xdist's workers ignore SIGINT, and a child inherits that."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start_fuzzyservo(argv: Sequence[str], cwd: Path | None = None) -> subprocess.Popen[str]:
    """``python -m fuzzyservo ARGV`` as a child that Ctrl-C (SIGINT) interrupts."""
    return subprocess.Popen([sys.executable, "-m", "fuzzyservo", *argv], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=default_sigint)


def wait_for_temporary(folder: Path, pattern: str, proc: subprocess.Popen[str]) -> bool:
    """Wait until ``proc`` starts a write (a temporary file ``pattern`` appears in
    ``folder``, see fuzzyservo._io.atomic_write); False if it ended first."""
    while proc.poll() is None:
        if any(folder.glob(pattern)):
            return True
        time.sleep(0.002)
    return False
