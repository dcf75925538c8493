"""Imports point one way (STYLE.md section 1), and no module imports itself round a cycle.

Every import counts: at module level, inside functions and under ``TYPE_CHECKING``. An
import inside a function is still a dependency; it only postpones the cycle to run time.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "fuzzyservo"

# unit (subpackage, or top-level module) -> internal units it may import
# (the units of ALWAYS are free for every layer)
ALLOWED: dict[str, set[str]] = {
    "fuzzy": set(),
    "plant": set(),
    "formats": {"fuzzy"},
    "control": {"fuzzy"},
    "sim": {"control", "plant", "fuzzy"},
    "paper": {"fuzzy", "formats", "plant", "control"},
    "registry": {"fuzzy", "formats", "plant", "control", "sim", "paper"},
    # one description of a run (RunSpec), for every front end above
    "run": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry"},
    "analysis": {"run", "registry", "sim", "control", "plant", "fuzzy", "formats"},
    "files": {"analysis", "registry", "sim", "control", "plant", "fuzzy", "formats"},
    "plots": {"analysis", "sim", "control", "plant", "fuzzy", "formats", "paper"},
    "export": {"registry", "control", "fuzzy", "formats", "plant", "sim", "paper"},
    # the study runs claim C8 as a sweep (study/c8.py)
    "study": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "run",
              "analysis", "files", "plots", "sweep"},
    "sweep": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "run",
              "analysis", "files", "plots"},
    # identification of a user's axis from measured data: fits through the registry's plants
    # and the compiled loops; its figures from plots
    "identify": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "run",
                 "analysis", "files", "plots"},
    # the browser page is a front end beside the command line, built on the library: it
    # imports neither the commands nor the CLI (the `app` command starts it)
    "app": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "run",
            "analysis", "files", "plots", "export"},
    # the commands: the command line's handlers, over everything below them
    "commands": {"fuzzy", "formats", "plant", "control", "sim", "paper", "registry", "run",
                 "analysis", "files", "plots", "export", "study", "sweep", "app", "identify"},
    "cli": {"commands"},
    "_entry": {"cli"},  # the entry point: catches Ctrl-C while the CLI is imported
    "__main__": {"_entry"},
}
# free for every layer: errors and typing, atomic I/O, the public API's argument checks, the
# compiled core's decorator, cache and notice (numba only), the version; the package's
# __init__ (its public names)
ALWAYS = {"errors", "_typing", "_io", "_args", "_jit", "__version__", "__init__"}


def _units() -> set[str]:
    """Every subpackage and top-level module of the package."""
    out = {p.name for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    out |= {p.stem for p in SRC.glob("*.py")}
    return out


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in SRC.rglob("*.py")}


def _imports(path: Path, modules: dict[str, Path]) -> set[str]:
    """The package's modules that ``path`` imports (``from X import name`` counts as an
    import of ``X.name`` when that is a module, else of ``X``)."""
    me = _module_name(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:
                full = f"{target}.{alias.name}"
                out.add(full if full in modules else target)
        elif isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
    return {m for m in out if m in modules and m != me}


def _unit(module: str) -> str:
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    found.append(sorted(comp))
    return found


def test_every_unit_is_in_the_table() -> None:
    missing = sorted(_units() - set(ALLOWED) - ALWAYS)
    assert not missing, f"not in the import-direction table: {missing}"


def test_the_table_has_no_cycle() -> None:
    assert _cycles(ALLOWED) == []


def test_units_import_one_way() -> None:
    modules = _modules()
    bad: list[str] = []
    for module, path in sorted(modules.items()):
        unit = _unit(module)
        if unit in ALWAYS:
            continue
        for target in sorted(_imports(path, modules)):
            t = _unit(target)
            if t != unit and t not in ALWAYS and t not in ALLOWED[unit]:
                bad.append(f"{path.relative_to(SRC)} imports {target}")
    assert not bad, "imports against the layout:\n" + "\n".join(bad)


def test_no_module_imports_itself_round_a_cycle() -> None:
    modules = _modules()
    graph = {m: _imports(p, modules) for m, p in modules.items()}
    assert _cycles(graph) == [], "import cycles (module-level or inside functions)"


def test_the_cycle_finder_finds_cycles() -> None:
    """The checks above can fail: a cycle and a back edge are found."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []
    assert _unit("fuzzyservo.sweep.spec") == "sweep" and _unit("fuzzyservo") == "__init__"
    assert _module_name(SRC / "sweep" / "__init__.py") == "fuzzyservo.sweep"
    modules = _modules()
    # a function-level import is seen (cli imports each command's module by name at run
    # time, and the package's own modules directly)
    assert "fuzzyservo._entry" in _imports(SRC / "__main__.py", modules)
    assert "fuzzyservo.fuzzy.engine" in _imports(SRC / "fuzzy" / "loop.py", modules)
