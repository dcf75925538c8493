"""``python -m fuzzyservo`` runs the command-line interface."""

from __future__ import annotations

from .cli import console

console()
