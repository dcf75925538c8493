"""Small helpers shared by the tests."""

from __future__ import annotations

import fcntl
import shlex
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType
from typing import Any, TypeVar

T = TypeVar("T")

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
        # sleep: polling the folder (the stdlib has no file-creation event to wait on)
        time.sleep(0.002)
    return False


class WorkExceeded(AssertionError):
    """More Python lines ran than a :func:`count_lines` budget allows."""


def count_lines(fn: Callable[..., T], *args: Any, limit: int | None = None) -> tuple[T, int]:
    """``fn(*args)`` and the number of Python lines it executed (``sys.settrace`` line events
    in every frame it runs, the standard library's included).

    The count is the work done, the same on any machine and under any load: tests compare
    counts, never wall-clock times (docs/testing.md). Lines of C (``list.index``, a regular
    expression's scan) are not counted; a loop written in Python is, once per iteration.
    With ``limit``, :class:`WorkExceeded` is raised as soon as more than ``limit`` lines ran
    (a runaway reader stops there instead of running on). A tracer already installed (a
    coverage run's) is put back afterwards."""
    count = 0

    def local(frame: FrameType, event: str, arg: object) -> Any:
        nonlocal count
        if event == "line":
            count += 1
            if limit is not None and count > limit:
                raise WorkExceeded(f"more than {limit} Python lines ran")
        return local

    def calls(frame: FrameType, event: str, arg: object) -> Any:
        return local

    previous = sys.gettrace()
    sys.settrace(calls)
    try:
        result = fn(*args)
    finally:
        sys.settrace(previous)
    return result, count


def run_once(tmp_path_factory: Any, worker_id: str, name: str,
             build: Callable[[Path], None]) -> Path:
    """The folder ``name`` that ``build(folder)`` makes, once per test session: under
    pytest-xdist the first worker to need it builds it under a file lock, the others wait
    and reuse it. Shared, read-only: a test that writes into it copies it first."""
    if worker_id == "master":  # not distributed: a folder of this session
        root = tmp_path_factory.mktemp(name)
    else:  # the session's base folder, common to its workers
        root = tmp_path_factory.getbasetemp().parent
    folder = root / name
    done = root / f"{name}.complete"
    with (root / f"{name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not done.is_file():
                build(folder)
                done.write_text("ok\n")
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    return folder
