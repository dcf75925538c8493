"""Imports between subpackages point one way (STYLE.md section 1)."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "fuzzyservo"

# subpackage (or top-level module) -> internal subpackages it may import
# (errors/_typing/_io/_jit always allowed)
ALLOWED: dict[str, set[str]] = {
    "fuzzy": set(),
    "plant": set(),
    "formats": {"fuzzy"},
    "control": {"fuzzy"},
    "sim": {"control", "plant", "fuzzy"},
    "paper": {"fuzzy", "formats", "plant", "control"},
    "registry": {"fuzzy", "formats", "plant", "control", "sim", "paper"},
    # one description of a run (RunSpec), for every front end below
    "run": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry"},
    "analysis": {"registry", "sim", "control", "plant", "fuzzy", "formats"},
    "files": {"analysis", "registry", "sim", "control", "plant", "fuzzy", "formats"},
    "plots": {"analysis", "sim", "control", "plant", "fuzzy", "formats", "paper"},
    "export": {"registry", "control", "fuzzy", "formats", "plant", "sim", "paper"},
    "study": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "run",
              "analysis", "files", "plots"},
    "sweep": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "run",
              "analysis", "files", "plots", "study"},
    # the browser page is a front end beside the CLI: it describes its runs as RunSpecs and
    # imports neither the command line nor its commands
    "app": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "run",
            "analysis", "files", "plots", "export"},
    # the commands sit on every library layer (``app`` serves the page)
    "commands": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "run",
                 "analysis", "files", "plots", "export", "study", "sweep", "app"},
    "cli": {"commands"},
    "_entry": {"cli"},
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


def _files(sub: str) -> list[Path]:
    module = SRC / f"{sub}.py"
    return [module] if module.is_file() else sorted((SRC / sub).rglob("*.py"))


def test_the_table_has_no_cycle() -> None:
    done: set[str] = set()

    def visit(node: str, path: tuple[str, ...]) -> None:
        assert node not in path, f"cycle: {' -> '.join((*path, node))}"
        if node in done:
            return
        for nxt in ALLOWED.get(node, set()):
            visit(nxt, (*path, node))
        done.add(node)

    for sub in ALLOWED:
        visit(sub, ())


def test_every_subpackage_is_in_the_table() -> None:
    subs = {p.name for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").is_file()}
    assert subs <= set(ALLOWED) | {"data"}, sorted(subs - set(ALLOWED))


def test_subpackages_import_one_way() -> None:
    bad: list[str] = []
    for sub, allowed in ALLOWED.items():
        for path in _files(sub):
            for target in _internal_targets(path) - {sub} - ALWAYS:
                if target not in allowed:
                    bad.append(f"{path.relative_to(SRC)} imports {target}")
    assert not bad, "imports against the layout:\n" + "\n".join(bad)
