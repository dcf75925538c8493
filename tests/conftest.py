"""Shared fixtures. The costly ``make reproduce`` (its recipe, ``fuzzyservo reproduce --out
results/paper``: both plants, default settings) runs once per test session: under
pytest-xdist the workers share one output folder, the first to need it computes it under a
file lock and the others wait and reuse it (pytest-xdist's recipe for session fixtures that
must run once; ``--dist loadgroup`` would do it too, but it does not group with pytest 9.2,
pytest-xdist issue #1386)."""

from __future__ import annotations

import fcntl
from pathlib import Path

import pytest

from fuzzyservo.cli import main
from tests.helpers import make_recipe


def reproduce_argv(out: Path) -> list[str]:
    """``make reproduce``'s command with its output folder replaced by ``out``, quiet."""
    argv = make_recipe("reproduce")
    argv[argv.index("--out") + 1] = str(out)
    return [*argv, "--quiet"]


@pytest.fixture(scope="session")
def reproduced(tmp_path_factory: pytest.TempPathFactory, worker_id: str) -> Path:
    """Output folder of ``make reproduce``'s command, run in a scratch folder.

    Shared, read-only: a test that writes into a reproduction copies it first.
    """
    if worker_id == "master":  # not distributed: a folder of this session
        root = tmp_path_factory.mktemp("reproduce")
    else:  # the session's base folder, common to its workers
        root = tmp_path_factory.getbasetemp().parent
    out = root / "reproduced" / "results" / "paper"
    done = root / "reproduced" / "complete"
    with (root / "reproduced.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not done.is_file():
                assert main(reproduce_argv(out)) == 0
                done.write_text("ok\n")
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    return out
