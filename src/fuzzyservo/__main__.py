"""``python -m fuzzyservo`` runs the command-line interface."""

from __future__ import annotations

from ._entry import run

run()
