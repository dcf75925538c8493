"""Shared fixtures. The costly ``make reproduce`` (its recipe, ``fuzzyservo reproduce --out
results/paper``: both plants, default settings) runs once per test session: under
pytest-xdist the workers share one output folder, the first to need it computes it under a
file lock and the others wait and reuse it (pytest-xdist's recipe for session fixtures that
must run once; ``--dist loadgroup`` would do it too, but it does not group with pytest 9.2,
pytest-xdist issue #1386)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fuzzyservo.cli import main
from tests.helpers import make_recipe, run_once


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
    def build(folder: Path) -> None:
        assert main(reproduce_argv(folder / "results" / "paper")) == 0

    return run_once(tmp_path_factory, worker_id, "reproduced", build) / "results" / "paper"
