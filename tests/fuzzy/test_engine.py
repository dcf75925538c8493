"""The one engine (fuzzyservo.fuzzy.engine): ``evaluate`` is the controllers' compiled code,
``pack`` chooses the uniform grid exactly for the form it takes, and the two exact paths agree.

1. For every two-input system the tests know (the paper's two, the six shipped files, the
   general evaluator's fixed systems, the table-system file's, every file under
   tests/formats/data and fuzzylite's installed examples that read, random systems),
   ``evaluate(system, x)[:, 0]`` equals, bit for bit, a numba loop calling
   ``eval_system(x1, x2, system_table(rules, lims))`` on ``pack(system).kernel_args()``: what
   the controllers' loops run.
2. ``pack`` takes the uniform grid for the paper's systems and their shipped files, and not
   for a system whose triangles are moved by one ulp, or whose operators, clipping, weights
   or heights differ.
3. On the paper's systems the grid path and the general evaluator (``grid=False``) agree
   within 1e-12 of the output range (both exact) on a dense grid.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzyservo.errors import FormatError, ParameterError
from fuzzyservo.formats import read_system
from fuzzyservo.fuzzy import FuzzySystem, Term, Variable, evaluate, pack
from fuzzyservo.fuzzy.engine import eval_system, grid_form, system_table
from fuzzyservo.paper import SYSTEM_FILES, alpha_system, du_system, system_file
from tests.formats.fuzzylite_oracle import EXAMPLES
from tests.formats.strategies import systems as random_systems
from tests.fuzzy.test_general import FIXED, SMOOTH, SUGENO, pl_system, table_system
from tests.fuzzy.test_table_systems import _system as rule_list_system
from tests.fuzzy.test_table_systems import _table as rule_table_system

FORMAT_FILES = Path(__file__).resolve().parents[1] / "formats" / "data"
PAPER = {"du": du_system, "alpha": alpha_system}


@numba.njit
def _loop(x: np.ndarray, rules: np.ndarray, lims: np.ndarray) -> np.ndarray:
    """What the controllers' compiled loops do per sample: eval_system on the packed tables."""
    tab = system_table(rules, lims)
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = eval_system(x[i, 0], x[i, 1], tab)
    return out


def _known() -> Iterator[tuple[str, FuzzySystem]]:
    """Every fixed two-input system the tests know (files that the readers refuse skipped)."""
    for role, make in PAPER.items():
        yield f"paper {role}", make()
    for name in SYSTEM_FILES:
        role, fmt = name.split("-")[1].split(".")
        yield name, read_system(system_file(role, fmt))
    yield "general FIXED", FIXED
    for d in ("bisector", "mom", "som", "lom"):
        yield f"general FIXED {d}", dataclasses.replace(FIXED, defuzzifier=d)
    yield "general SMOOTH", SMOOTH
    yield "general SUGENO", SUGENO
    for agg in ("max", "bounded_sum", "sum", "probor"):
        yield f"rule list {agg}", rule_list_system(default=0.5, aggregation=agg)
        yield f"rule table {agg}", rule_table_system(aggregation=agg)
    for d in ("bisector", "mom"):
        yield f"rule table {d}", rule_table_system(defuzzifier=d)
    for label, root in (("formats", FORMAT_FILES), ("fuzzylite", EXAMPLES)):
        for p in sorted(p for ext in ("fis", "fcl", "fll") for p in root.rglob(f"*.{ext}")):
            try:
                s = read_system(p)
            except (FormatError, ParameterError):
                continue  # refused by the reader (tests/formats checks which and why)
            yield f"{label} {p.relative_to(root)}", s


KNOWN = [(name, s) for name, s in _known() if len(s.inputs) == 2]


def _points(s: FuzzySystem, rng: np.random.Generator, n: int = 400) -> np.ndarray:
    """Random points over and beyond the input ranges, the ranges' ends and every finite
    term parameter of the inputs (vertices, peaks), crossed."""
    lo = np.array([v.range[0] for v in s.inputs])
    hi = np.array([v.range[1] for v in s.inputs])
    span = hi - lo
    pts = [rng.uniform(lo - 0.2 * span, hi + 0.2 * span, (n, 2))]
    marks = [sorted({float(p) for t in v.terms for p in t.params if math.isfinite(p)}
                    | set(v.range))[:25] for v in s.inputs]
    pts.append(np.array([[a, b] for a in marks[0] for b in marks[1]]))
    return np.ascontiguousarray(np.vstack(pts))


def _assert_same_code(s: FuzzySystem, x: np.ndarray) -> None:
    packed = pack(s)
    rules, lims = packed.kernel_args()
    np.testing.assert_array_equal(evaluate(packed, x)[:, 0], _loop(x, rules, lims))
    np.testing.assert_array_equal(evaluate(s, x)[:, 0], _loop(x, rules, lims))


def test_the_systems_are_found() -> None:
    names = [n for n, _ in KNOWN]
    assert sum(n.startswith("paper") for n in names) == 8
    assert sum(n.startswith("formats ") for n in names) >= 8  # tests/formats/data
    assert sum(n.startswith("fuzzylite ") for n in names) >= 16  # installed by make oracles
    # both paths are among them
    paths = {pack(s).path for _, s in KNOWN}
    assert {"uniform grid", "partition", "piecewise linear", "smooth", "sugeno"} <= paths


@pytest.mark.parametrize("name_system", KNOWN, ids=[n for n, _ in KNOWN])
def test_evaluate_is_the_loops_code_bit_for_bit(name_system: tuple[str, FuzzySystem]) -> None:
    name, s = name_system
    _assert_same_code(s, _points(s, np.random.default_rng(abs(hash(name)) % 2**32)))


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.filter_too_much, HealthCheck.large_base_example])
@given(st.data())
def test_random_two_input_systems_are_the_loops_code(data: st.DataObject) -> None:
    which = data.draw(st.sampled_from(["formats", "pl", "table"]))
    maker = {"formats": random_systems, "pl": pl_system, "table": table_system}[which]
    s = data.draw(maker().filter(lambda s: len(s.inputs) == 2))
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    x = _points(s, rng, n=40)
    x = x[np.all(np.isfinite(x), axis=1)]
    _assert_same_code(s, x)


# ---------------------------------------------------------------------------------------------
# 2. the uniform grid is taken exactly for its form


@pytest.mark.parametrize("name", [*PAPER, *SYSTEM_FILES])
def test_the_paper_systems_and_their_files_take_the_uniform_grid(name: str) -> None:
    if name in PAPER:
        s = PAPER[name]()
    else:
        role, fmt = name.split("-")[1].split(".")
        s = read_system(system_file(role, fmt))
    packed = pack(s)
    assert packed.path == "uniform grid" and packed.compiled is None
    assert packed.rules.shape == (7, 7) and packed.lims.shape == (8,)
    np.testing.assert_array_equal(packed.rules, s.rule_table())
    assert grid_form(s) is not None
    general = pack(s, grid=False)
    assert general.path == "partition" and general.compiled is not None
    assert general.rules.shape[0] == 1


def _moved(s: FuzzySystem, where: str, term: int, param: int, direction: float
           ) -> FuzzySystem:
    """``s`` with one parameter of one triangle moved by one ulp."""
    def move(v: Variable) -> Variable:
        t = v.terms[term]
        p = list(t.params)
        p[param] = float(np.nextafter(p[param], direction))
        terms = list(v.terms)
        terms[term] = Term(t.name, t.shape, tuple(p), t.height)
        return dataclasses.replace(v, terms=tuple(terms))

    if where == "output":
        return dataclasses.replace(s, outputs=(move(s.outputs[0]),))
    i = 0 if where == "e" else 1
    inputs = list(s.inputs)
    inputs[i] = move(inputs[i])
    return dataclasses.replace(s, inputs=tuple(inputs))


ULP_MOVES = [("e", 3, 1, math.inf), ("e", 0, 0, -math.inf), ("e", 6, 2, math.inf),
             ("de", 2, 1, -math.inf), ("de", 4, 0, math.inf), ("output", 1, 1, math.inf),
             ("output", 6, 0, -math.inf), ("output", 0, 2, math.inf)]


@pytest.mark.parametrize("role", PAPER)
@pytest.mark.parametrize("move", ULP_MOVES, ids=lambda m: "-".join(map(str, m[:3])))
def test_a_triangle_moved_by_one_ulp_takes_the_general_evaluator(
        role: str, move: tuple[str, int, int, float]) -> None:
    s = _moved(PAPER[role](), *move)
    assert grid_form(s) is None
    packed = pack(s)
    assert packed.path != "uniform grid" and packed.compiled is not None
    # still the same surface to rounding (both paths exact)
    x = np.random.default_rng(1).uniform(-1.2, 1.2, (500, 2))
    np.testing.assert_allclose(evaluate(packed, x), evaluate(PAPER[role](), x), rtol=0,
                               atol=1e-12)


def _weighted(s: FuzzySystem) -> FuzzySystem:
    r = s.rules[5]
    return dataclasses.replace(s, rules=(*s.rules[:5], dataclasses.replace(r, weight=0.5),
                                         *s.rules[6:]))


def _height(s: FuzzySystem) -> FuzzySystem:
    v = s.inputs[0]
    t = v.terms[2]
    terms = (*v.terms[:2], Term(t.name, t.shape, t.params, 0.75), *v.terms[3:])
    return dataclasses.replace(s, inputs=(dataclasses.replace(v, terms=terms), s.inputs[1]))


OTHER_FORMS: dict[str, Any] = {
    "and product": lambda s: dataclasses.replace(s, and_op="product"),
    "implication product": lambda s: dataclasses.replace(s, implication="product"),
    "aggregation sum": lambda s: dataclasses.replace(s, aggregation="sum"),
    "aggregation bounded_sum": lambda s: dataclasses.replace(s, aggregation="bounded_sum"),
    "aggregation probor": lambda s: dataclasses.replace(s, aggregation="probor"),
    "bisector": lambda s: dataclasses.replace(s, defuzzifier="bisector"),
    "mom": lambda s: dataclasses.replace(s, defuzzifier="mom"),
    "unclipped input": lambda s: dataclasses.replace(
        s, inputs=(s.inputs[0], dataclasses.replace(s.inputs[1], clip=False))),
    "a weighted rule": _weighted,
    "a term of height 0.75": _height,
    "two rules on a cell": lambda s: dataclasses.replace(s, rules=(*s.rules, s.rules[0])),
}


@pytest.mark.parametrize("role", PAPER)
@pytest.mark.parametrize("change", sorted(OTHER_FORMS))
def test_other_operators_or_forms_take_the_general_evaluator(role: str, change: str) -> None:
    s = OTHER_FORMS[change](PAPER[role]())
    assert grid_form(s) is None
    assert pack(s).path != "uniform grid"
    # or_op is never used by a rule table of ANDs: it does not matter for the grid
    assert pack(dataclasses.replace(PAPER[role](), or_op="probor")).path == "uniform grid"


# ---------------------------------------------------------------------------------------------
# 3. the two exact paths agree


@pytest.mark.parametrize("role", PAPER)
def test_grid_and_general_paths_agree_on_a_dense_grid(role: str) -> None:
    s = PAPER[role]()
    grid, general = pack(s), pack(s, grid=False)
    assert grid.path == "uniform grid" and general.path == "partition"
    g = np.linspace(-1.1, 1.1, 441)  # step 1/200: every node k/6 of the partitions is on it
    x = np.column_stack([a.ravel() for a in np.meshgrid(g, g)])
    a, b = evaluate(grid, x)[:, 0], evaluate(general, x)[:, 0]
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(b))
    lo, hi = s.outputs[0].range
    assert np.max(np.abs(a - b)) <= 1e-12 * (hi - lo)  # both exact: rounding only
