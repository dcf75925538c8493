"""Imports between subpackages point one way (STYLE.md section 1)."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "fuzzyservo"

# subpackage -> internal subpackages it may import (errors/_typing/_io/_jit always allowed)
ALLOWED: dict[str, set[str]] = {
    "fuzzy": set(),
    "plant": set(),
    "formats": {"fuzzy"},
    "control": {"fuzzy"},
    "sim": {"control", "plant", "fuzzy"},
    "paper": {"fuzzy", "formats", "plant", "control"},
    "registry": {"fuzzy", "formats", "plant", "control", "sim", "paper"},
    "analysis": {"registry", "sim", "control", "plant", "fuzzy", "formats"},
    "files": {"analysis", "registry", "sim", "control", "plant", "fuzzy", "formats"},
    "plots": {"analysis", "sim", "control", "plant", "fuzzy", "formats", "paper"},
    "export": {"registry", "control", "fuzzy", "formats", "plant", "sim", "paper"},
    "sweep": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "analysis",
              "files", "plots"},
    # the study runs the shipped C8 sweeps (study/c8.py); the sweep knows nothing of the study
    "study": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "analysis",
              "files", "plots", "sweep"},
    # the browser page is a front end like the CLI: it builds its runs through the commands
    "app": {"fuzzyservo", "fuzzy", "formats", "plant", "control", "sim", "paper", "registry",
            "analysis", "files", "plots", "export", "commands", "cli"},
}
# _jit: the compiled core's decorator, cache and notice (numba only), free for every layer
ALWAYS = {"errors", "_typing", "_io", "_jit", "__version__"}


def _internal_targets(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    rel = path.relative_to(SRC).parts
    targets: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level == 0:
                mod = node.module or ""
                if mod.startswith("fuzzyservo."):
                    targets.add(mod.split(".")[1])
                continue
            # relative import: resolve against the file's package
            base = list(rel[:-1])[: len(rel) - node.level]
            parts = base + (node.module.split(".") if node.module else [])
            if parts:
                targets.add(parts[0])
            else:
                targets.update(alias.name for alias in node.names)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("fuzzyservo."):
                    targets.add(alias.name.split(".")[1])
    return targets


def test_subpackages_import_one_way() -> None:
    bad: list[str] = []
    for sub, allowed in ALLOWED.items():
        for path in (SRC / sub).rglob("*.py"):
            for target in _internal_targets(path) - {sub} - ALWAYS:
                if target not in allowed:
                    bad.append(f"{path.relative_to(SRC)} imports {target}")
    assert not bad, "imports against the layout:\n" + "\n".join(bad)
