"""Two-input Mamdani systems (FuzzySystem.from_table and rule lists) through ``evaluate``:
every operator and defuzzifier against an independent dense-sampling reference."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzyservo.errors import InputError, ParameterError
from fuzzyservo.fuzzy import (
    And,
    Consequent,
    FuzzySystem,
    Is,
    Rule,
    Term,
    Variable,
    evaluate,
    pack,
)
from fuzzyservo.fuzzy.engine import grid_form
from fuzzyservo.paper import du_system
from fuzzyservo.paper.rulebases import DU_TABLE

INF = math.inf

E = Variable("e", (-1.0, 1.0), (
    Term("N", "trapezoid", (-INF, -0.6, -0.6, 0.1)),  # left shoulder: 1 up to -0.6, 0 at 0.1
    Term("Z", "triangle", (-0.5, 0.0, 0.4)),
    Term("P", "trapezoid", (-0.1, 0.7, 0.7, INF)),  # right shoulder: 0 at -0.1, 1 from 0.7
))
DE = Variable("de", (-2.0, 2.0), (
    Term("N", "trapezoid", (-3.0, -2.0, -1.0, 0.2)),
    Term("Z", "triangle", (-1.0, 0.0, 1.0)),
    Term("P", "trapezoid", (-0.2, 0.9, 2.0, 3.0)),
))
PL_OUT = Variable("u", (-2.0, 3.0), (
    Term("LO", "trapezoid", (-2.5, -2.0, -1.2, -0.3)),
    Term("MID", "triangle", (-1.0, -1.0, 1.1)),  # vertical left edge
    Term("HI", "triangle", (0.2, 1.9, 3.4)),  # cut by the universe
))
#: The rules (inputs e, de; output u), as the former text form read them:
#:   if e is N and de is N then u is LO;  if e is N and de is Z then u is LO
#:   if e is Z and de is Z then u is MID; if e is Z and de is P then u is HI
#:   if e is P then u is HI;              if de is N and e is P then u is MID
RULES = (
    Rule(And((Is(0, 0), Is(1, 0))), (Consequent(0, 0),)),
    Rule(And((Is(0, 0), Is(1, 1))), (Consequent(0, 0),)),
    Rule(And((Is(0, 1), Is(1, 1))), (Consequent(0, 1),)),
    Rule(And((Is(0, 1), Is(1, 2))), (Consequent(0, 2),)),
    Rule(Is(0, 2), (Consequent(0, 2),)),
    Rule(And((Is(1, 0), Is(0, 2))), (Consequent(0, 1),)),
)
#: A rule table over the same variables (rows de, columns e), two empty cells.
TABLE = (
    ("LO", "LO", None),   # de = N
    ("LO", "MID", "HI"),  # de = Z
    ("-", "HI", "MID"),   # de = P
)


def _mu(t: Term, x: np.ndarray) -> np.ndarray:
    """Independent numpy membership of the shapes used here (height 1)."""
    p = t.params
    with np.errstate(invalid="ignore", divide="ignore"):
        if t.shape == "gaussian":
            return np.exp(-0.5 * ((x - p[0]) / p[1]) ** 2)
        a, b, c, d = p if t.shape == "trapezoid" else (p[0], p[1], p[1], p[2])
        rise = (np.where(x >= a, 1.0, 0.0) if (b == a or a == -INF)
                else np.clip((x - a) / (b - a), 0.0, 1.0))
        fall = (np.where(x <= d, 1.0, 0.0) if (d == c or d == INF)
                else np.clip((d - x) / (d - c), 0.0, 1.0))
        return np.minimum(rise, fall)


def _clauses(rule: Rule) -> list[Is]:
    a = rule.antecedent
    return [a] if isinstance(a, Is) else list(a.operands)  # type: ignore[union-attr,arg-type]


def _brute(system: FuzzySystem, e: np.ndarray, de: np.ndarray, n: int) -> np.ndarray:
    """Independent dense-sampling reference (numpy): the midpoint rule on n cells of the
    output range, which stays second-order at the vertical MF edge placed on a cell boundary
    (the trapezoid rule would smear that jump over one cell: first order). NaN where no rule
    fires (the caller substitutes the output's default); -inf where a maximum method has no
    plateau the samples resolve (isolated peaks are missed by the samples)."""
    v1, v2 = system.inputs
    out = system.outputs[0]
    lo, hi = out.range
    step = (hi - lo) / n
    y = lo + step * (np.arange(n) + 0.5)
    terms = [_mu(t, y) for t in out.terms]
    res = np.empty(e.shape)
    for k, (a, b) in enumerate(zip(np.clip(e, *v1.range), np.clip(de, *v2.range),
                                   strict=True)):
        agg = np.zeros(y.shape)
        x = (np.array([a]), np.array([b]))
        for rule in system.rules:
            ms = [float(_mu(system.inputs[c.variable].terms[c.term], x[c.variable])[0])
                  for c in _clauses(rule)]
            w = min(ms) if system.and_op == "min" else math.prod(ms)
            f = terms[rule.consequents[0].term]
            imp = np.minimum(w, f) if system.implication == "min" else w * f
            if system.aggregation == "max":
                agg = np.maximum(agg, imp)
            elif system.aggregation == "bounded_sum":
                agg = np.minimum(1.0, agg + imp)
            elif system.aggregation == "sum":
                agg = agg + imp
            else:  # probor
                agg = agg + imp - agg * imp
        d = system.defuzzifier
        if agg.max() <= 0:
            res[k] = np.nan
        elif d == "centroid":
            res[k] = np.sum(agg * y) / np.sum(agg)
        elif d == "bisector":
            cum = np.concatenate([[0.0], np.cumsum(agg)])
            edges = np.linspace(lo, hi, n + 1)
            res[k] = np.interp(0.5 * cum[-1], cum, edges)
        else:
            top = agg >= agg.max() - 1e-12
            if top.sum() <= 10:
                res[k] = -np.inf
            else:
                res[k] = {"mom": y[top].mean(), "som": y[top].min() - 0.5 * step,
                          "lom": y[top].max() + 0.5 * step}[d]
    return res


def _with_default(v: Variable, default: float) -> Variable:
    return dataclasses.replace(v, default=default)


def _system(default: float = math.nan, output: Variable = PL_OUT, **ops: Any) -> FuzzySystem:
    """The rule-list system (a rule on one input, a rule with the clauses swapped)."""
    return FuzzySystem(name="rules", inputs=(E, DE), outputs=(_with_default(output, default),),
                       rules=RULES, **ops)


def _table(default: float = math.nan, **ops: Any) -> FuzzySystem:
    """The rule-table system over the same variables."""
    return FuzzySystem.from_table(TABLE, columns=E, rows=DE,
                                  output=_with_default(PL_OUT, default), name="table", **ops)


BUILDERS = {"rules": _system, "table": _table}
POINTS = np.random.default_rng(11).uniform(-2.5, 2.5, (2, 60))


def _eval(system: FuzzySystem, e: Any, de: Any) -> np.ndarray:
    return evaluate(system, np.column_stack([np.ravel(e), np.ravel(de)]))[:, 0]


def test_the_table_builds_its_cells() -> None:
    s = _table()
    assert s.rule_table() == [[0, 0, -1], [0, 1, 2], [-1, 2, 1]]
    assert len(s.rules) == 7
    with pytest.raises(ParameterError, match="not a cell of a rule table"):
        _system().rule_table()


@pytest.mark.parametrize("build", sorted(BUILDERS))
@pytest.mark.parametrize("and_op", ["min", "product"])
@pytest.mark.parametrize("implication", ["min", "product"])
@pytest.mark.parametrize("aggregation", ["max", "bounded_sum", "sum", "probor"])
def test_exact_centroid_all_operators(build: str, and_op: str, implication: str,
                                      aggregation: str) -> None:
    system = BUILDERS[build](default=0.5, and_op=and_op, implication=implication,
                             aggregation=aggregation)
    e, de = POINTS
    ours = _eval(system, e, de)
    ref = _brute(system, e, de, 200_000)
    ref = np.where(np.isnan(ref), 0.5, ref)
    # midpoint rule with step 2.5e-5 on a piecewise-linear aggregate (slopes <= 10, the
    # vertical edge at -1 on a cell boundary): error <= a few 1e-9
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-8)


@pytest.mark.parametrize("build", sorted(BUILDERS))
@pytest.mark.parametrize("defuzz", ["bisector", "mom", "som", "lom"])
@pytest.mark.parametrize("aggregation", ["max", "bounded_sum"])
def test_other_defuzzifiers(build: str, defuzz: str, aggregation: str) -> None:
    system = BUILDERS[build](defuzzifier=defuzz, aggregation=aggregation, default=0.0)
    e, de = POINTS
    ours = _eval(system, e, de)
    ref = _brute(system, e, de, 200_000)
    ref = np.where(np.isnan(ref), 0.0, ref)  # the output's default where no rule fires
    keep = np.isfinite(ref)
    assert keep.sum() >= 20  # enough plateau points are compared
    ours, ref = ours[keep], ref[keep]
    # sampled reference resolves positions to its step, 2.5e-5 (plateau ends, bisector)
    np.testing.assert_allclose(ours, ref, rtol=0, atol=5e-5)


def test_mean_of_maxima_of_isolated_peaks() -> None:
    # e beyond P, de in N: rules "e is P -> HI" and "de is N and e is P -> MID" fire at 1;
    # the maxima are the peaks -1 (MID's vertical edge) and 1.9 (HI): their mean is 0.45
    system = _system(defuzzifier="mom")
    assert evaluate(system, [2.0, -1.5])[0] == pytest.approx(0.45, abs=1e-15)  # (-1 + 1.9)/2


def test_general_path_equals_uniform_kernel() -> None:
    du = du_system()
    # the same triangles written as degenerate trapezoids take the general exact path
    out = du.outputs[0]
    trap = Variable(out.name, out.range, tuple(
        Term(t.name, "trapezoid", (t.params[0], t.params[1], t.params[1], t.params[2]))
        for t in out.terms))
    general = FuzzySystem.from_table(DU_TABLE, columns=du.inputs[0], rows=du.inputs[1],
                                     output=trap)
    assert general.rule_table() == du.rule_table()
    assert grid_form(general) is None and pack(general).path != "uniform grid"
    assert pack(du).path == "uniform grid"
    e, de = np.random.default_rng(4).uniform(-1.2, 1.2, (2, 3000))
    # two exact methods, different arithmetic: rounding only
    np.testing.assert_allclose(_eval(general, e, de), _eval(du, e, de), rtol=0, atol=1e-12)


def test_gaussian_output_by_quadrature() -> None:
    out = Variable("u", (-2.0, 3.0), (
        Term("LO", "gaussian", (-1.5, 0.4)),
        Term("MID", "gaussian", (0.0, 0.5)),
        Term("HI", "gaussian", (2.0, 0.6)),
    ))
    system = _system(default=0.0, output=out)
    assert pack(system).path == "smooth"
    e, de = POINTS[:, :25]
    ref = np.nan_to_num(_brute(system, e, de, 200_000), nan=0.0)
    # adaptive quadrature to 1e-12 vs the midpoint rule on kinks of a smooth-pieced
    # aggregate: ~1e-9
    np.testing.assert_allclose(_eval(system, e, de), ref, rtol=0, atol=1e-8)


@pytest.mark.parametrize("build", sorted(BUILDERS))
def test_default_output_and_no_rule(build: str) -> None:
    one = (Rule(And((Is(0, 0), Is(1, 0))), (Consequent(0, 0),)),)
    with_default = dataclasses.replace(BUILDERS[build](default=0.25), rules=one)
    assert evaluate(with_default, [0.9, 1.5])[0] == 0.25
    assert _eval(with_default, [0.9, 0.8], [1.5, 1.5]).tolist() == [0.25, 0.25]
    # no default (NaN): no value where no rule fires (the former EmptyFuzzySetError)
    strict = dataclasses.replace(BUILDERS[build](), rules=one)
    assert math.isnan(evaluate(strict, [0.9, 1.5])[0])
    got = _eval(strict, [-0.9, 0.9], [-1.5, 1.5])
    assert math.isfinite(got[0]) and math.isnan(got[1])


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_inputs_raise(bad: float) -> None:
    for system in (du_system(), _system(), _table()):
        packed = pack(system)
        with pytest.raises(InputError, match="input 'e' must be finite"):
            evaluate(packed, [bad, 0.0])
        with pytest.raises(InputError, match="input 'de' must be finite.* at row 1"):
            evaluate(packed, [[0.0, 0.0], [0.0, bad]])


def test_inputs_must_have_the_systems_columns() -> None:
    with pytest.raises(InputError, match=r"inputs need shape \(n, 2\)"):
        evaluate(du_system(), np.zeros((3, 3)))
    with pytest.raises(InputError, match=r"inputs need shape \(n, 2\)"):
        evaluate(du_system(), np.zeros(3))
    with pytest.raises(InputError, match="numeric"):
        evaluate(du_system(), np.array([["a", "b"]], dtype=object))


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("and_op", "MIN", r"and_op must be one of 'min', 'product', got 'MIN'"),
        ("implication", "minimum", "implication must be one of"),
        ("aggregation", "einstein",
         "aggregation must be one of 'max', 'bounded_sum', 'sum', 'probor'"),
        ("defuzzifier", "exact_centroid", "defuzzifier must be one of"),
        ("defuzzifier", "wtaver", "a mamdani system defuzzifies by centroid"),
    ],
)
def test_systems_reject_unknown_choices(field: str, value: object, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        _table(**{field: value})
    with pytest.raises(ParameterError, match=match):
        _system(**{field: value})


def test_an_infinite_default_is_refused() -> None:
    with pytest.raises(ParameterError, match="default must be finite or NaN"):
        _table(default=math.inf)


def test_output_shape_and_dtype() -> None:
    du = du_system()
    out = evaluate(du, np.zeros((3, 2), dtype=np.float32))
    assert out.shape == (3, 1) and out.dtype == np.float64
    one = evaluate(du, [0.1, 0.2])
    assert one.shape == (1,) and one.dtype == np.float64
    assert one[0] == evaluate(du, np.array([[0.1, 0.2]]))[0, 0]
    assert evaluate(du, np.zeros((0, 2))).shape == (0, 1)


@settings(max_examples=60, deadline=None)
@given(e=st.floats(-5, 5), de=st.floats(-5, 5))
def test_crisp_output_inside_universe(e: float, de: float) -> None:
    for spec in ({}, {"aggregation": "bounded_sum", "implication": "product"},
                 {"aggregation": "sum"}, {"defuzzifier": "bisector"},
                 {"defuzzifier": "mom"}, {"defuzzifier": "som"}, {"defuzzifier": "lom"}):
        for build in BUILDERS.values():
            v = evaluate(build(default=0.0, **spec), [e, de])[0]
            assert -2.0 <= v <= 3.0


MIRRORED = FuzzySystem.from_table(DU_TABLE, columns=du_system().inputs[0],
                                  rows=du_system().inputs[1], output=du_system().outputs[0],
                                  and_op="product", implication="product",
                                  aggregation="bounded_sum")


@settings(max_examples=40, deadline=None)
@given(e=st.floats(-1.5, 1.5), de=st.floats(-1.5, 1.5))
def test_mirror_symmetric_rules_give_an_odd_surface(e: float, de: float) -> None:
    v = evaluate(MIRRORED, [[e, de], [-e, -de]])[:, 0]
    # mirrored inputs select mirrored memberships: equal up to rounding
    assert v[1] == pytest.approx(-v[0], abs=1e-12)
