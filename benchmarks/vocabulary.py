"""Where the package names its vocabulary: lines of code, and the places outside the registry
and the shape table that name a controller kind or a membership shape (issue 24's figures).

A *place* is a line of code (not a docstring) holding a string literal equal to a registered
controller name, or to a shape of ``fuzzy.shapes.SHAPE_TABLE``. Words that are such a name by
accident are not counted: a shape family (``singleton``, ``sugeno``), the unit ``s``, the
plant ``linear``, FMI's variabilities (``discrete``, ``constant``), the reference shapes of
``sim.references`` and the page (``ramp``, ``trapezoid``), the PID law's own name ``pid``, the
percentile prefix ``p`` and the shape ``pi`` where a controller is meant (and the other way
round). The study's places are counted apart: the paper's designs are named by the study.

    python benchmarks/vocabulary.py [--tree DIR] [--list]
"""

from __future__ import annotations

import argparse
import ast
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
KINDS = {"p", "pi", "pid", "pid2", "fpi", "stfpi"}
SHAPES = {"triangle", "trapezoid", "rectangle", "ramp", "discrete", "singleton", "gaussian",
          "gaussian2", "bell", "sigmoid", "dsigmoid", "psigmoid", "s", "z", "pi", "constant",
          "linear"}
#: (file prefix, word) pairs that are not the vocabulary (see the module's doc)
NOT_KINDS = {("analysis/robust.py", "p"), ("control/pid.py", "pid"), ("fuzzy/", "pi"),
             ("formats/", "pi"), ("plots/systems.py", "pi")}
NOT_SHAPES = {("export/fmu.py", "discrete"), ("export/fmu.py", "constant"),
              ("app/page.py", "ramp"), ("app/page.py", "trapezoid"),
              ("sim/references.py", "ramp"), ("sim/references.py", "trapezoid"),
              ("registry/controllers.py", "pi"), ("app/settings.py", "pi")}


def _literals(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every string constant of ``path`` that is not a docstring, nor a
    comparison with a shape family."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr) \
                and isinstance(body[0].value, ast.Constant):
            skip.add(id(body[0].value))
        if isinstance(node, ast.Compare) and any(
                isinstance(n, ast.Attribute) and n.attr == "family"
                or isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)
                and n.func.attr == "family" for n in ast.walk(node.left)):
            skip.update(id(n) for n in ast.walk(node))
    for node in ast.walk(tree):  # shape(x).family in ("singleton", "sugeno")
        if isinstance(node, ast.Compare) and isinstance(node.left, ast.Attribute) \
                and node.left.attr == "family":
            skip.update(id(n) for n in ast.walk(node))
    return [(n.lineno, n.value) for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in skip]


def places(src: Path, words: set[str], exclude: set[tuple[str, str]], skip: str,
           ignore: set[str]) -> list[tuple[str, int]]:
    """(file, line) of each place naming one of ``words`` outside ``skip``."""
    out = set()
    for path in sorted(src.rglob("*.py")):
        rel = path.relative_to(src).as_posix()
        if rel.startswith(skip):
            continue
        for line, text in _literals(path):
            if text in words and text not in ignore \
                    and not any(rel.startswith(f) and text == w for f, w in exclude):
                out.add((rel, line))
    return sorted(out)


def lines(paths: list[Path]) -> int:
    return sum(len(p.read_text(encoding="utf-8").splitlines()) for p in paths)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", type=Path, default=HERE.parent, help="a checkout")
    parser.add_argument("--list", action="store_true", help="list every place")
    args = parser.parse_args()
    src = args.tree / "src" / "fuzzyservo"
    kinds = places(src, KINDS, NOT_KINDS, "registry/", set())
    shapes = places(src, SHAPES, NOT_SHAPES, "fuzzy/shapes.py", {"s", "linear"})
    study = [p for p in kinds if p[0].startswith("study/")]
    fuzzy = lines(list((src / "fuzzy").glob("*.py")))
    print(f"lines of .py in src/fuzzyservo/fuzzy/: {fuzzy:,d}")
    print(f"lines of .py in src/: {lines(list(src.rglob('*.py'))):,d}")
    for what, found in (("controller kind, outside registry/ and study/",
                         [p for p in kinds if p not in study]),
                        ("controller kind, in study/ (the paper's designs)", study),
                        ("membership shape, outside fuzzy/shapes.py", shapes)):
        files = Counter(f for f, _ in found)
        print(f"places naming a {what}: {len(found)} in {len(files)} files"
              + "".join(f"\n  {n:4d} {f}" for f, n in files.most_common()))
        if args.list:
            print("".join(f"    {f}:{ln}\n" for f, ln in found), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
