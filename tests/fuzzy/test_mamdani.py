"""General Mamdani systems: every operator and defuzzifier against independent references."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzyservo.errors import EmptyFuzzySetError, InputError, ParameterError
from fuzzyservo.fuzzy import (
    Gaussian,
    LeftShoulder,
    LinguisticVariable,
    MamdaniSpec,
    MamdaniSystem,
    RightShoulder,
    RuleBase,
    Trapezoid,
    Triangle,
)
from fuzzyservo.paper import du_system

E = LinguisticVariable(name="e", universe=(-1.0, 1.0), terms=(
    ("N", LeftShoulder(a=-0.6, b=0.1)),
    ("Z", Triangle(a=-0.5, b=0.0, c=0.4)),
    ("P", RightShoulder(a=-0.1, b=0.7)),
))
DE = LinguisticVariable(name="de", universe=(-2.0, 2.0), terms=(
    ("N", Trapezoid(a=-3.0, b=-2.0, c=-1.0, d=0.2)),
    ("Z", Triangle(a=-1.0, b=0.0, c=1.0)),
    ("P", Trapezoid(a=-0.2, b=0.9, c=2.0, d=3.0)),
))
PL_OUT = LinguisticVariable(name="u", universe=(-2.0, 3.0), terms=(
    ("LO", Trapezoid(a=-2.5, b=-2.0, c=-1.2, d=-0.3)),
    ("MID", Triangle(a=-1.0, b=-1.0, c=1.1)),  # vertical left edge
    ("HI", Triangle(a=0.2, b=1.9, c=3.4)),  # cut by the universe
))
RULES = """
if e is N and de is N then u is LO
if e is N and de is Z then u is LO
if e is Z and de is Z then u is MID
if e is Z and de is P then u is HI
if e is P then u is HI
if de is N and e is P then u is MID
"""


def _brute(system: MamdaniSystem, e: np.ndarray, de: np.ndarray, n: int) -> np.ndarray:
    """Independent dense-sampling reference (numpy).

    ``sampled_centroid``: trapezoid rule on n points, as the spec defines it. Otherwise the
    midpoint rule on n cells, which stays second-order at the vertical MF edge placed on a
    cell boundary (the trapezoid rule would smear that jump over one cell: first order).
    """
    spec = system.spec
    (v1, v2), out = system.inputs, system.output
    lo, hi = out.universe
    if spec.defuzz == "sampled_centroid":
        y = np.linspace(lo, hi, n)
    else:
        step = (hi - lo) / n
        y = lo + step * (np.arange(n) + 0.5)
    res = np.empty(e.shape)
    for k, (a, b) in enumerate(zip(np.clip(e, *v1.universe), np.clip(de, *v2.universe),
                                   strict=True)):
        agg = np.zeros(y.shape)
        for rule in system.rules.rules:
            ms = [float(var.terms[i][1](x)) for var, i, x in zip((v1, v2), rule.antecedent,
                                                                (a, b), strict=True) if i >= 0]
            w = min(ms) if spec.and_op == "min" else math.prod(ms)
            f = out.terms[rule.consequent][1](y)
            imp = np.minimum(w, f) if spec.implication == "min" else w * f
            agg = np.maximum(agg, imp) if spec.aggregation == "max" else np.minimum(1, agg + imp)
        if agg.max() <= 0:
            res[k] = np.nan
        elif spec.defuzz == "sampled_centroid":
            res[k] = np.trapezoid(agg * y, y) / np.trapezoid(agg, y)
        elif spec.defuzz == "exact_centroid":
            res[k] = np.sum(agg * y) / np.sum(agg)
        elif spec.defuzz == "bisector":
            cum = np.concatenate([[0.0], np.cumsum(agg)])
            edges = np.linspace(lo, hi, n + 1)
            res[k] = np.interp(0.5 * cum[-1], cum, edges)
        else:
            top = agg >= agg.max() - 1e-12
            # a sampled mean of maxima is only meaningful on a plateau (isolated peaks are
            # missed by the samples): -inf marks the points to skip
            res[k] = y[top].mean() if top.sum() > 10 else -np.inf
    return res


def _system(**spec: Any) -> MamdaniSystem:
    rb = RuleBase.from_text(RULES, inputs=(E, DE), output=PL_OUT)
    return MamdaniSystem(rules=rb, spec=MamdaniSpec(**spec))


POINTS = np.random.default_rng(11).uniform(-2.5, 2.5, (2, 60))


@pytest.mark.parametrize("and_op", ["min", "product"])
@pytest.mark.parametrize("implication", ["min", "product"])
@pytest.mark.parametrize("aggregation", ["max", "bounded_sum"])
def test_exact_centroid_all_operators(and_op: str, implication: str, aggregation: str) -> None:
    system = _system(and_op=and_op, implication=implication, aggregation=aggregation,
                     default=0.5)
    e, de = POINTS
    ours = system.evaluate(e, de)
    ref = _brute(system, e, de, 200_000)
    ref = np.where(np.isnan(ref), 0.5, ref)
    # midpoint rule with step 2.5e-5 on a piecewise-linear aggregate (slopes <= 10, the
    # vertical edge at -1 on a cell boundary): error <= a few 1e-9
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-8)


@pytest.mark.parametrize("defuzz", ["bisector", "mean_of_maxima", "sampled_centroid"])
@pytest.mark.parametrize("aggregation", ["max", "bounded_sum"])
def test_other_defuzzifiers(defuzz: str, aggregation: str) -> None:
    system = _system(defuzz=defuzz, aggregation=aggregation, default=0.0, samples=4001)
    e, de = POINTS
    ours = system.evaluate(e, de)
    n = 4001 if defuzz == "sampled_centroid" else 200_000
    ref = _brute(system, e, de, n)
    ref = np.where(np.isnan(ref), 0.0, ref)  # the spec's default where no rule fires
    keep = np.isfinite(ref)
    assert keep.sum() >= 20  # enough plateau points are compared
    ours, ref = ours[keep], ref[keep]
    if defuzz == "sampled_centroid":
        # the same samples and the same rule: rounding only
        np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-12)
    else:
        # sampled reference resolves positions to its step, 2.5e-5 (plateau ends, bisector)
        np.testing.assert_allclose(ours, ref, rtol=0, atol=5e-5)


def test_mean_of_maxima_of_isolated_peaks() -> None:
    # e beyond P, de in N: rules "e is P -> HI" and "de is N and e is P -> MID" fire at 1;
    # the maxima are the peaks -1 (MID's vertical edge) and 1.9 (HI): their mean is 0.45
    system = _system(defuzz="mean_of_maxima")
    assert system.evaluate(2.0, -1.5) == pytest.approx(0.45, abs=1e-15)  # (-1 + 1.9) / 2


def test_general_path_equals_uniform_kernel() -> None:
    du = du_system()
    # the same triangles written as degenerate trapezoids take the general exact path
    out = LinguisticVariable(name="du", universe=(-1.0, 1.0), terms=tuple(
        (lab, Trapezoid(a=mf.a, b=mf.b, c=mf.b, d=mf.c))  # type: ignore[attr-defined]
        for lab, mf in du.output.terms))
    table = [[du.output.labels[j] for j in row] for row in du.uniform_kernel_args()[0]]
    general = MamdaniSystem(rules=RuleBase.from_table(table, columns=du.inputs[0],
                                                      rows=du.inputs[1], output=out))
    with pytest.raises(ParameterError):
        general.uniform_kernel_args()
    e, de = np.random.default_rng(4).uniform(-1.2, 1.2, (2, 3000))
    # two exact methods, different arithmetic: rounding only
    np.testing.assert_allclose(general.evaluate(e, de), du.evaluate(e, de), rtol=0, atol=1e-12)


def test_gaussian_output_by_quadrature() -> None:
    out = LinguisticVariable(name="u", universe=(-2.0, 3.0), terms=(
        ("LO", Gaussian(mean=-1.5, sigma=0.4)),
        ("MID", Gaussian(mean=0.0, sigma=0.5)),
        ("HI", Gaussian(mean=2.0, sigma=0.6)),
    ))
    rb = RuleBase.from_text(RULES, inputs=(E, DE), output=out)
    system = MamdaniSystem(rules=rb, spec=MamdaniSpec(default=0.0, quad_tol=1e-11))
    e, de = POINTS[:, :25]
    ref = np.nan_to_num(_brute(system, e, de, 200_000), nan=0.0)
    # quad to 1e-11 vs trapezoid rule on kinks of a smooth-pieced aggregate: ~1e-9
    np.testing.assert_allclose(system.evaluate(e, de), ref, rtol=0, atol=1e-8)


def test_default_output_and_empty_set() -> None:
    rb = RuleBase.from_text("if e is N and de is N then u is LO", inputs=(E, DE), output=PL_OUT)
    with_default = MamdaniSystem(rules=rb, spec=MamdaniSpec(default=0.25))
    assert with_default.evaluate(0.9, 1.5) == 0.25
    assert with_default.evaluate(np.array([0.9, 0.8]), 1.5).tolist() == [0.25, 0.25]
    strict = MamdaniSystem(rules=rb)
    with pytest.raises(EmptyFuzzySetError, match=r"no rule fires at \(e=0.9, de=1.5\)"):
        strict.evaluate(0.9, 1.5)
    with pytest.raises(EmptyFuzzySetError, match="declares no default"):
        strict.evaluate(np.array([-0.9, 0.9]), np.array([-1.5, 1.5]))


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_inputs_raise(bad: float) -> None:
    for system in (du_system(), _system()):
        with pytest.raises(InputError, match="inputs must be finite"):
            system.evaluate(bad, 0.0)
        with pytest.raises(InputError, match="inputs must be finite"):
            system.evaluate(np.array([0.0, bad]), 0.0)
        with pytest.raises(InputError, match="inputs must be finite"):
            system.evaluate_scalar(0.0, bad)


def test_inputs_must_broadcast() -> None:
    with pytest.raises(InputError, match="broadcast"):
        du_system().evaluate(np.zeros(3), np.zeros(4))
    with pytest.raises(InputError, match="numeric"):
        du_system().evaluate(np.array(["a"]), 0.0)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("and_op", "MIN", r"and_op must be one of 'min', 'product', got 'MIN'"),
        ("implication", "minimum", "implication must be one of"),
        ("aggregation", "sum", "aggregation must be one of 'max', 'bounded_sum'"),
        ("defuzz", "centroid", "defuzz must be one of"),
        ("samples", 1, "samples must be an integer >= 2"),
        ("default", math.nan, "default must be finite"),
        ("quad_tol", 0.0, "quad_tol must be finite and > 0"),
    ],
)
def test_spec_rejects_unknown_choices(field: str, value: object, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        MamdaniSpec(**{field: value})  # type: ignore[arg-type]


def test_output_shape_and_dtype() -> None:
    du = du_system()
    out = du.evaluate(np.zeros((3, 1), dtype=np.float32), np.zeros(4, dtype=np.int64))
    assert out.shape == (3, 4) and out.dtype == np.float64
    assert isinstance(du.evaluate(0.1, 0.2), float)
    assert du.evaluate_scalar(0.1, 0.2) == float(du.evaluate(np.array([0.1]), 0.2)[0])


@settings(max_examples=60, deadline=None)
@given(e=st.floats(-5, 5), de=st.floats(-5, 5))
def test_crisp_output_inside_universe(e: float, de: float) -> None:
    for spec in ({}, {"aggregation": "bounded_sum", "implication": "product"},
                 {"defuzz": "bisector"}, {"defuzz": "mean_of_maxima"}):
        v = _system(default=0.0, **spec).evaluate(e, de)
        assert -2.0 <= v <= 3.0


@settings(max_examples=40, deadline=None)
@given(e=st.floats(-1.5, 1.5), de=st.floats(-1.5, 1.5))
def test_mirror_symmetric_rules_give_an_odd_surface(e: float, de: float) -> None:
    du = du_system()
    spec = MamdaniSpec(and_op="product", implication="product", aggregation="bounded_sum")
    system = MamdaniSystem(rules=du.rules, spec=spec)
    # mirrored inputs select mirrored memberships: equal up to rounding
    assert system.evaluate(-e, -de) == pytest.approx(-system.evaluate(e, de), abs=1e-12)
