"""The tests' own rules on time (docs/testing.md, "Time"; STYLE.md section 15), checked on the
source of every file under tests/.

1. No assertion depends on the wall clock: an ``assert`` may not contain a clock read
   (``time.time``, ``time.perf_counter``, ``time.monotonic``, ``time.process_time``, their
   ``_ns`` forms, ``datetime.now``/``utcnow``/``today``), nor a name that a clock read was
   assigned to in the same function (followed through assignments). A complexity claim counts
   work instead (tests.helpers.count_lines).
2. Clock reads appear only in the functions of ``CLOCK_ALLOWED``, each with its reason: the
   deadline of a wait for an event, or spreading signals over a write.
3. Every sleep (``time.sleep``, ``asyncio.sleep``, a bare ``sleep`` imported from time) has a
   ``# sleep:`` comment on its line or opening a line of the comment block right above it,
   saying why no event exists to wait on (or that the delay is the test's input).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
CLOCKS = frozenset({"time", "perf_counter", "monotonic", "process_time", "time_ns",
                    "perf_counter_ns", "monotonic_ns", "process_time_ns"})
DATETIME_CLOCKS = frozenset({"now", "utcnow", "today"})
SLEEPS = frozenset({"sleep"})

#: (file relative to tests/, function) -> why a clock is read there. None is an assertion.
CLOCK_ALLOWED: dict[tuple[str, str], str] = {
    ("app/test_browser.py", "settle"): "deadline of the wait, and the page's quiet period "
                                       "(a debounce: 'no more redraws' has no event)",
    ("app/browser.py", "app_server"): "deadline of the wait for the server's address",
    ("app/browser.py", "wait"): "deadline of a wait for a page condition",
    ("sweep/test_run.py", "_kill_when_started"): "deadline of the wait for the child's "
                                                 "first chunk",
    ("sweep/test_run.py", "test_sigkill_while_the_pool_starts_leaves_no_worker"):
        "deadline of the wait for the manifest",
    ("cli/test_interrupts.py", "_kill_and_check"): "the write's duration, to spread the "
                                                   "signals over it",
    ("cli/test_interrupts.py", "handler"): "deadline of the wait for the interruption",
    ("study/test_output_folder.py", "two_runs_timed"): "the writes' duration, to spread "
                                                       "the kills over them",
}


def _is_clock(node: ast.AST) -> bool:
    """A call of a wall-clock read (``time.x()``, ``x()`` of a from-import, ``datetime.now``)."""
    if not isinstance(node, ast.Call):
        return False
    f = node.func
    if isinstance(f, ast.Attribute):
        if isinstance(f.value, ast.Name) and f.value.id == "time" and f.attr in CLOCKS:
            return True
        return f.attr in DATETIME_CLOCKS and isinstance(f.value, ast.Attribute | ast.Name) \
            and (getattr(f.value, "id", None) == "datetime"
                 or getattr(f.value, "attr", None) == "datetime")
    return isinstance(f, ast.Name) and f.id in CLOCKS - {"time"}


def _is_sleep(node: ast.AST) -> bool:
    if not isinstance(node, ast.Call):
        return False
    f = node.func
    if isinstance(f, ast.Attribute):
        return f.attr in SLEEPS and isinstance(f.value, ast.Name) and \
            f.value.id in ("time", "asyncio")
    return isinstance(f, ast.Name) and f.id in SLEEPS


def _functions(tree: ast.AST) -> list[ast.FunctionDef | ast.AsyncFunctionDef | ast.Module]:
    out: list[ast.FunctionDef | ast.AsyncFunctionDef | ast.Module] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Module):
            out.append(node)
    return out


def _own_nodes(scope: ast.AST) -> list[ast.AST]:
    """The nodes of a function (or module) outside its nested functions."""
    out: list[ast.AST] = []
    stack = list(ast.iter_child_nodes(scope))
    while stack:
        node = stack.pop()
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
            continue
        out.append(node)
        stack.extend(ast.iter_child_nodes(node))
    return out


def _tainted(nodes: list[ast.AST]) -> set[str]:
    """Names assigned (directly or through other such names) from a clock read."""
    names: set[str] = set()
    changed = True
    while changed:
        changed = False
        for node in nodes:
            if isinstance(node, ast.Assign | ast.AugAssign | ast.AnnAssign) and \
                    node.value is not None:
                value = node.value
                dirty = any(_is_clock(n) or (isinstance(n, ast.Name) and n.id in names)
                            for n in ast.walk(value))
                if not dirty:
                    continue
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                for t in targets:
                    for n in ast.walk(t):
                        if isinstance(n, ast.Name) and n.id not in names:
                            names.add(n.id)
                            changed = True
    return names


def violations(path: Path, source: str) -> list[str]:
    """Every break of the three rules in one file, as ``file:line: what``."""
    rel = path.relative_to(TESTS).as_posix()
    lines = source.splitlines()
    tree = ast.parse(source, str(path))
    out = []
    for scope in _functions(tree):
        nodes = _own_nodes(scope)
        name = getattr(scope, "name", "<module>")
        tainted = _tainted(nodes)
        for node in nodes:
            if _is_clock(node) and (rel, name) not in CLOCK_ALLOWED:
                out.append(f"{rel}:{node.lineno}: wall-clock read in {name}() (count work, "
                           f"or add the wait's function to CLOCK_ALLOWED with its reason)")
            if isinstance(node, ast.Assert) and any(
                    _is_clock(n) or (isinstance(n, ast.Name) and n.id in tainted)
                    for n in ast.walk(node)):
                out.append(f"{rel}:{node.lineno}: an assertion on the wall clock in {name}()")
            if _is_sleep(node):
                k = node.lineno - 1
                above = []  # the comment lines right above the sleep
                j = k - 1
                while j >= 0 and lines[j].strip().startswith("#"):
                    above.append(lines[j].strip())
                    j -= 1
                if "# sleep:" not in lines[k] and not any(a.startswith("# sleep:")
                                                          for a in above):
                    out.append(f"{rel}:{node.lineno}: a sleep without a '# sleep:' reason")
    return sorted(out, key=lambda m: int(m.split(":")[1]))


def test_tests_keep_the_time_rules() -> None:
    found = []
    for path in sorted(TESTS.rglob("*.py")):
        found += violations(path, path.read_text(encoding="utf-8"))
    assert not found, "\n".join(found)


def test_the_allowed_clocks_exist() -> None:
    """Every CLOCK_ALLOWED entry names a function that still reads a clock (a stale entry
    would allow a new clock read there unseen)."""
    for (rel, name), reason in CLOCK_ALLOWED.items():
        assert reason
        tree = ast.parse((TESTS / rel).read_text(encoding="utf-8"))
        scopes = [s for s in _functions(tree) if getattr(s, "name", None) == name]
        assert scopes, (rel, name)
        assert any(_is_clock(n) for s in scopes for n in _own_nodes(s)), (rel, name)


@pytest.mark.parametrize(("source", "expected"), [
    ("import time\ndef test_a():\n    t0 = time.perf_counter()\n    f()\n"
     "    dt = time.perf_counter() - t0\n    assert dt < 1.0\n",
     ["wall-clock read", "wall-clock read", "assertion on the wall clock"]),
    ("import time\ndef test_a():\n    assert time.monotonic() > 0\n",
     ["wall-clock read", "assertion on the wall clock"]),
    ("from time import process_time\ndef test_a():\n    x = process_time()\n    y = x * 2\n"
     "    assert y\n", ["wall-clock read", "assertion on the wall clock"]),
    ("import datetime\ndef test_a():\n    assert datetime.datetime.now()\n",
     ["wall-clock read", "assertion on the wall clock"]),
    ("import time\ndef test_a():\n    time.sleep(1)\n", ["a sleep without"]),
    ("import asyncio\nasync def test_a():\n    await asyncio.sleep(1)\n", ["a sleep without"]),
    ("import time\ndef test_a():\n    # sleep: nothing to wait on\n    time.sleep(1)\n"
     "    time.sleep(2)  # sleep: nor here\n    # sleep: a reason\n    # on two lines\n"
     "    time.sleep(3)\n", []),
    ("import time\ndef test_a():\n    # sleep: a reason\n    x = 1\n    time.sleep(3)\n",
     ["a sleep without"]),
    ("def test_a():\n    n = count()\n    assert n < 10\n", []),
])
def test_the_rules_find_what_they_forbid(source: str, expected: list[str]) -> None:
    """The checker itself, on small sources: each rule fires on its case and not otherwise."""
    path = TESTS / "scratch_case.py"  # a name under tests/ for the relative path only
    kinds = ("wall-clock read", "assertion on the wall clock", "a sleep without")
    found = violations(path, source)
    assert sorted(k for f in found for k in kinds if k in f) == sorted(expected), found
