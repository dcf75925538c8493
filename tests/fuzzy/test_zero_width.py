"""Zero-width terms in the exact evaluator (issue 29; docs/fuzzy-files.md, "Zero-width terms"):
analytic values on small systems, both output paths (piecewise linear and smooth), every
aggregation's value at the point. The exported C evaluator's agreement on these systems is
tests/export/test_fuzzy_c.py (``zero_width_systems`` among its regression cases); the
comparison with fuzzylite is tests/formats/test_zero_width.py."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fuzzyservo.fuzzy import evaluate, membership
from fuzzyservo.fuzzy.system import Consequent, FuzzySystem, Is, Rule, Term, Variable

#: A maximum that is a vertex or a point: rounding only.
EXACT = 1e-15


def test_a_point_is_its_height_there_and_zero_elsewhere() -> None:
    x0 = 0.4
    x = np.array([x0, np.nextafter(x0, 1.0), np.nextafter(x0, 0.0), 0.0, 1.0, math.nan])
    for shape, params in (("triangle", (x0,) * 3), ("trapezoid", (x0,) * 4),
                          ("rectangle", (x0,) * 2)):
        np.testing.assert_array_equal(membership(shape, params, x, 0.5),
                                      [0.5, 0, 0, 0, 0, math.nan])


def _system(point: Term, other: Term, aggregation: str = "max",
            defuzzifier: str = "mom") -> FuzzySystem:
    """Input a in [0, 1] fires the point (rule 1: 'lo' = 1 - a) and the other term (rule 2:
    'hi' = a); input b fires the point at strength 1 when b = 0.5 exactly (rule 3)."""
    ins = (Variable("a", (0.0, 1.0), (Term("lo", "triangle", (0.0, 0.0, 1.0)),
                                      Term("hi", "triangle", (0.0, 1.0, 1.0)))),
           Variable("b", (0.0, 1.0), (Term("at", "triangle", (0.5, 0.5, 0.5)),)))
    out = Variable("y", (-1.0, 1.0), (point, other))
    rules = (Rule(Is(0, 0), (Consequent(0, 0),)), Rule(Is(0, 1), (Consequent(0, 1),)),
             Rule(Is(1, 0), (Consequent(0, 0),)))
    return FuzzySystem(inputs=ins, outputs=(out,), rules=rules, aggregation=aggregation,
                       defuzzifier=defuzzifier)


POINT = Term("z", "triangle", (0.5, 0.5, 0.5))
OTHERS = {  # the other output term, on the piecewise-linear and on the smooth path
    "piecewise linear": Term("p", "trapezoid", (-1.0, -0.8, -0.2, 0.0)),
    "smooth": Term("p", "gaussian", (-0.5, 0.1)),
}


@pytest.mark.parametrize("path", sorted(OTHERS))
def test_a_point_above_the_rest_is_the_maximum(path: str) -> None:
    for d in ("mom", "som", "lom"):
        s = _system(POINT, OTHERS[path], defuzzifier=d)
        # a = 0.2: the point at 0.8 beats the other term's 0.2; b = 0 fires nothing more
        assert evaluate(s, [[0.2, 0.0]])[0, 0] == 0.5
        # only the point fires (a = 0): no area, but a maximum
        assert evaluate(s, [[0.0, 0.0]])[0, 0] == 0.5


@pytest.mark.parametrize("path", sorted(OTHERS))
def test_a_point_below_the_rest_is_ignored(path: str) -> None:
    without = dataclasses.replace(_system(POINT, OTHERS[path]), rules=(
        Rule(Is(0, 1), (Consequent(0, 1),)),))
    for d in ("mom", "som", "lom", "centroid", "bisector"):
        s = dataclasses.replace(_system(POINT, OTHERS[path]), defuzzifier=d)
        w = dataclasses.replace(without, defuzzifier=d)
        x = [[0.7, 0.0]]  # the point at 0.3 under the other term's 0.7
        # the same maxima; a centroid's pieces split at the point: rounding (smooth:
        # the quadrature's documented 1e-12 of the range)
        tol = EXACT if path == "piecewise linear" or d in ("som", "lom") else 1e-12 * 2
        assert evaluate(s, x)[0, 0] == pytest.approx(evaluate(w, x)[0, 0], abs=tol)


def test_centroid_and_bisector_of_points_alone_are_the_default() -> None:
    for d in ("centroid", "bisector"):
        s = _system(POINT, OTHERS["piecewise linear"], defuzzifier=d)
        out = dataclasses.replace(s.outputs[0], default=0.125)
        s = dataclasses.replace(s, outputs=(out,))
        assert evaluate(s, [[0.0, 0.0]])[0, 0] == 0.125  # only the point fired: no area
        # a = 0.2 fires the trapezoid at 0.2 (symmetric about -0.5): the point adds nothing
        assert evaluate(s, [[0.2, 0.0]])[0, 0] == pytest.approx(-0.5, abs=EXACT)


def test_a_point_level_with_a_plateau() -> None:
    """a = 0.5: the point and the trapezoid's plateau [-0.8, -0.2] both at 0.5."""
    s = _system(POINT, OTHERS["piecewise linear"])
    x = [[0.5, 0.0]]
    got = {d: evaluate(dataclasses.replace(s, defuzzifier=d), x)[0, 0]
           for d in ("mom", "som", "lom")}
    # mom: the plateau (it has length, the point none); som: the plateau's start; lom: the point
    assert got["mom"] == pytest.approx(-0.5, abs=EXACT)
    assert got["som"] == pytest.approx(-0.9, abs=EXACT)  # -1 + 0.2 * 0.5: clipped edge
    assert got["lom"] == 0.5


def test_two_points_alone_average_for_mom() -> None:
    s = _system(POINT, Term("q", "trapezoid", (-0.25,) * 4))
    x = [[0.5, 0.0]]  # both points at 0.5
    got = [evaluate(dataclasses.replace(s, defuzzifier=d), x)[0, 0]
           for d in ("mom", "som", "lom")]
    assert got == [0.125, -0.25, 0.5]


@pytest.mark.parametrize(("aggregation", "som", "lom"), [
    ("max", 0.14, 0.86),  # max(0.3, 0.7) = 0.7: level with the plateau, which has length
    ("sum", 0.5, 0.5),  # 0.3 + 0.7 = 1 above the plateau's 0.7: the point is the maximum
    ("bounded_sum", 0.5, 0.5),  # min(1, 0.3 + 0.7) = 1, the same
])
def test_the_aggregate_at_a_point_is_every_fired_term_there(aggregation: str, som: float,
                                                           lom: float) -> None:
    """a = 0.7: the point at 0.3 inside the other term's plateau at 0.7 ([0.2, 0.8] clipped:
    [0.14, 0.86]); the aggregate at the point aggregates both terms there."""
    plateau = Term("p", "trapezoid", (0.0, 0.2, 0.8, 1.0))
    s = _system(POINT, plateau, aggregation=aggregation, defuzzifier="som")
    x = [[0.7, 0.0]]
    assert evaluate(s, x)[0, 0] == pytest.approx(som, abs=EXACT)
    assert evaluate(dataclasses.replace(s, defuzzifier="lom"), x)[0, 0] == \
        pytest.approx(lom, abs=EXACT)


def zero_width_systems() -> list[tuple[str, FuzzySystem, list[list[float]]]]:
    """The systems above under every defuzzifier and aggregation, with the inputs that fire
    the point alone, above, level with and below the other term (for the C evaluator's
    comparison in tests/export/test_fuzzy_c.py)."""
    points = [[0.0, 0.0], [0.2, 0.0], [0.5, 0.0], [0.7, 0.0], [1.0, 0.5], [0.3, 0.5]]
    # the smooth term narrower than OTHERS': the C comparison in float (bound 1e-5 of the
    # range) meets two limits of the float smooth path that hold with or without a point:
    # a Gaussian's top is located to about sigma sqrt(2 eps) (1.2e-5 of the range measured at
    # sigma = 0.1), and a clipped plateau's ends are missed when the flank there is steep
    # (a plateau end 0.012 off at sigma = 0.02). sigma = 0.05 sits between them.
    others = dict(OTHERS, smooth=Term("p", "gaussian", (-0.5, 0.05)),
                  plateau=Term("p", "trapezoid", (0.0, 0.2, 0.8, 1.0)),
                  point=Term("q", "trapezoid", (-0.25,) * 4))
    out = []
    for name, other in sorted(others.items()):
        for agg in ("max", "sum", "bounded_sum", "probor"):
            for d in ("centroid", "bisector", "mom", "som", "lom"):
                out.append((f"zero width {name} {agg} {d}",
                            _system(POINT, other, aggregation=agg, defuzzifier=d), points))
    return out


def test_every_case_of_the_c_comparison_fires_a_point() -> None:
    """The comparison's systems really hold a point that fires: at a = 0 only the point
    has strength (so a maxima method gives 0.5, a centroid the default)."""
    for name, s, _ in zero_width_systems():
        got = evaluate(s, [[0.0, 0.0]])[0, 0]
        if s.defuzzifier in ("mom", "som", "lom"):
            assert got == 0.5, name
        else:
            assert math.isnan(got) and math.isnan(s.outputs[0].default), name
