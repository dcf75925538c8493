"""Small helpers shared by the tests."""

from __future__ import annotations

import shlex
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
