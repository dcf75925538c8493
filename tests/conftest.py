"""Shared fixtures. The costly ``fuzzyservo reproduce`` runs once per test session (and, under
pytest-xdist, on one worker: its users carry ``@pytest.mark.xdist_group("reproduce")`` and
``make test`` distributes with ``--dist loadgroup``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fuzzyservo.cli import main

#: Arguments of the session's reproduction: the linear plant, the default 20 s runs.
REPRODUCE_ARGS: tuple[str, ...] = ("--plant", "linear", "--quiet")


@pytest.fixture(scope="session")
def reproduce_args() -> tuple[str, ...]:
    """The ``reproduce`` options of :func:`reproduced` (to run the same reproduction again)."""
    return REPRODUCE_ARGS


@pytest.fixture(scope="session")
def reproduced(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Output folder of ``fuzzyservo reproduce --plant linear`` (default settings)."""
    out = tmp_path_factory.mktemp("reproduce") / "results"
    assert main(["reproduce", "--out", str(out), *REPRODUCE_ARGS]) == 0
    return out

