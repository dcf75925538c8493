"""The general evaluator (fuzzyservo.fuzzy.general) against independent references.

Sources of truth, strongest first:

- analytic values (a symmetric set's centroid and bisector are its axis, ...);
- exact rational arithmetic (tests/fuzzy/general_reference.py, ``exact_outputs``) for every
  piecewise-linear aggregate, singleton (COGS) and Sugeno output: the claim is agreement within
  1e-12 of the output range (the evaluator's floats round each of a few hundred operations at
  1.1e-16 relative; 1e-12 is the module's stated accuracy);
- mpmath at 30 digits (``mp_outputs``) for smooth terms and probabilistic-sum aggregation:
  within 1e-10 of the output range (the module's stated accuracy for adaptive quadrature);
- the existing exact engine for the paper's systems (agreement to 1e-13 at 10^5 points: both
  are exact, the difference is rounding);
- scikit-fuzzy on a fine universe, within its sampling error bound (stated at the test).

Float inputs whose exact answer is discontinuous in a rule strength (a maximum method at a
tie, a rule that fires with strength below rounding) are avoided or treated as ties, as
described in the reference's docstring.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
import pytest

from fuzzyservo.fuzzy.general import (
    evaluate,
    membership,
)
from fuzzyservo.fuzzy.system import (
    And,
    Consequent,
    FuzzySystem,
    Is,
    Not,
    Or,
    Rule,
    Term,
    Variable,
)
from tests.fuzzy.general_reference import (
    distance,
    exact_outputs,
    expected,
    mp_outputs,
)

EXACT_TOL = 1e-12  # of the output range: the module's claim for exact outputs
SMOOTH_TOL = 1e-10  # of the output range: the module's claim for quadrature


def _width(v: Variable) -> float:
    return v.range[1] - v.range[0]


def assert_exact(system: FuzzySystem, pts: Sequence[Sequence[float]],
                 tol: float = EXACT_TOL) -> float:
    """Every output at every point within ``tol`` of the output range of the exact value;
    returns the largest error found (relative to the range)."""
    ours = evaluate(system, np.array(pts, dtype=float).reshape(len(pts), -1))
    worst = 0.0
    for i, p in enumerate(pts):
        ref = expected(system, exact_outputs(system, p))
        for k, var in enumerate(system.outputs):
            err = distance(float(ours[i, k]), ref[k]) / _width(var)
            assert err <= tol, (f"output {var.name} at {list(p)}: ours {ours[i, k]!r}, "
                                f"exact {ref[k]!r}")
            worst = max(worst, err)
    return worst


def assert_mp(system: FuzzySystem, pts: Sequence[Sequence[float]],
              tol: float = SMOOTH_TOL) -> float:
    """As assert_exact, against mpmath."""
    ours = evaluate(system, np.array(pts, dtype=float).reshape(len(pts), -1))
    worst = 0.0
    for i, p in enumerate(pts):
        ref = expected(system, mp_outputs(system, p))
        for k, var in enumerate(system.outputs):
            err = distance(float(ours[i, k]), ref[k]) / _width(var)
            assert err <= tol, (f"output {var.name} at {list(p)}: ours {ours[i, k]!r}, "
                                f"mpmath {ref[k]!r}")
            worst = max(worst, err)
    return worst


# ---------------------------------------------------------------------------------------------
# a fixed two-input system with every piecewise-linear shape and rule construct

X = Variable("x", (-1.0, 1.0), (
    Term("neg", "trapezoid", (-math.inf, -1.0, -0.75, 0.0)),
    Term("mid", "triangle", (-0.5, 0.0, 0.5)),
    Term("pos", "ramp", (0.0, 0.75), height=0.8),
    Term("edge", "triangle", (0.25, 0.25, 1.0)),  # zero-width left foot: a vertical edge
))
Y = Variable("y", (0.0, 4.0), (
    Term("low", "rectangle", (0.0, 1.5)),
    Term("wave", "discrete", (0.5, 0.0, 1.5, 1.0, 2.5, 0.25, 3.5, 0.75)),
    Term("high", "trapezoid", (2.0, 3.0, 4.0, math.inf), height=0.9),
), clip=False)
OUT_U = Variable("u", (-2.0, 2.0), (
    Term("nb", "triangle", (-2.0, -2.0, -0.5)),  # a == b: vertical edge at the range end
    Term("ze", "trapezoid", (-1.0, -0.25, 0.25, 1.0), height=0.6),
    Term("jump", "discrete", (0.0, 0.2, 0.5, 0.2, 0.5, 0.9, 1.5, 0.0)),  # a vertical jump
    Term("pb", "ramp", (0.5, 2.0)),
    Term("box", "rectangle", (-1.5, -0.75)),
), default=-0.5)
OUT_V = Variable("v", (0.0, 10.0), (
    Term("a", "triangle", (0.0, 2.0, 4.0)),
    Term("b", "trapezoid", (3.0, 5.0, 6.0, 9.0)),
    Term("c", "ramp", (10.0, 7.0), height=0.7),  # falling ramp
))
RULES = (
    Rule(And((Is(0, 0), Is(1, 0))), (Consequent(0, 0), Consequent(1, 0))),
    Rule(Or((Is(0, 1), Is(1, 1, negated=True))), (Consequent(0, 1),), weight=0.8),
    Rule(And((Is(0, 2), Not(Is(1, 2)))), (Consequent(0, 2), Consequent(1, 1))),
    Rule(Or((And((Is(0, 3), Is(1, 2))), Is(1, 1))), (Consequent(0, 3), Consequent(1, 2)),
         weight=0.5),
    Rule(Not(Or((Is(0, 0), Is(0, 2)))), (Consequent(0, 4),), weight=0.9),
    Rule(Is(1, 2), (Consequent(0, 2), Consequent(0, 3))),  # two consequents, one output
)
FIXED = FuzzySystem(inputs=(X, Y), outputs=(OUT_U, OUT_V), rules=RULES)


def _fixed_points() -> list[list[float]]:
    rng = np.random.default_rng(11)
    pts = [[-1.0, 0.0], [1.0, 4.0], [0.25, 1.5], [0.0, 2.5], [-0.75, 3.0], [0.5, 0.5],
           [1.25, -1.0], [-2.0, 5.0]]  # vertices, range ends, outside the ranges
    pts += rng.uniform([-1.2, -0.5], [1.2, 4.5], (6, 2)).tolist()
    return pts


FIXED_POINTS = _fixed_points()


@pytest.mark.parametrize("and_op", ["min", "product"])
@pytest.mark.parametrize("or_op", ["max", "probor"])
@pytest.mark.parametrize("implication", ["min", "product"])
@pytest.mark.parametrize("aggregation", ["max", "bounded_sum", "sum"])
@pytest.mark.parametrize("defuzzifier", ["centroid", "bisector", "mom", "som", "lom"])
def test_every_operator_and_method_is_exact(and_op: str, or_op: str, implication: str,
                                           aggregation: str, defuzzifier: str) -> None:
    system = dataclasses.replace(FIXED, and_op=and_op, or_op=or_op, implication=implication,
                                 aggregation=aggregation, defuzzifier=defuzzifier)
    assert_exact(system, FIXED_POINTS)


# ---------------------------------------------------------------------------------------------
# regressions: bugs found by these tests (each failed before its fix)

ONE_IN = Variable("x", (0.0, 1.0), (Term("lo", "triangle", (-1.0, 0.0, 1.0)),
                                    Term("hi", "triangle", (0.0, 1.0, 2.0))))


def test_scratch_holds_the_largest_output_of_many() -> None:
    # The scratch size read the outputs' breakpoint counts at a stride of 6 instead of 7
    # fields, so a third output with many breakpoints overran the scratch (heap corruption,
    # wrong values).
    single = Variable("s", (0.0, 1.0), (Term("p", "singleton", (0.25,)),
                                        Term("q", "singleton", (0.75,))))
    many = Variable("m", (0.0, 1.0), tuple(
        Term(f"t{i}", "triangle", (i / 40, (i + 0.5) / 40, (i + 1.5) / 40)) for i in range(39)))
    rules = tuple(Rule(Is(0, i % 2), (Consequent(0, i % 2), Consequent(1, 1 - i % 2),
                                      Consequent(2, i))) for i in range(39))
    system = FuzzySystem(inputs=(ONE_IN,), outputs=(single, single.__class__(
        "s2", single.range, single.terms), many), rules=rules)
    assert_exact(system, [[0.3], [0.7], [0.5], [0.0]])


@pytest.mark.parametrize(("implication", "value"), [
    ("min", (2.0 * 0.5 + 8.0 * 0.2) / (0.5 + 0.2)),  # min(0.8, 0.5), min(0.2, 1)
    ("product", (2.0 * 0.4 + 8.0 * 0.2) / (0.4 + 0.2)),  # 0.8 * 0.5, 0.2 * 1
])
def test_singleton_height_is_implied_like_any_membership(implication: str, value: float
                                                         ) -> None:
    # A singleton's membership is its height at its position (``membership('singleton')``);
    # min implication clips it: min(w, height). It used to scale it (w * height) under min.
    out = Variable("y", (0.0, 10.0), (Term("a", "singleton", (2.0,), height=0.5),
                                      Term("b", "singleton", (8.0,))))
    system = FuzzySystem(inputs=(ONE_IN,), outputs=(out,), implication=implication,
                         rules=(Rule(Is(0, 0), (Consequent(0, 0),)),
                                Rule(Is(0, 1), (Consequent(0, 1),))))
    assert evaluate(system, [0.2])[0] == pytest.approx(value, rel=1e-15, abs=0)  # rounding
    assert membership("singleton", (2.0,), [2.0, 2.5], height=0.5).tolist() == [0.5, 0.0]


@pytest.mark.parametrize("defuzzifier", ["centroid", "bisector", "mom", "som", "lom"])
def test_vertical_edge_within_rounding_of_another_vertex(defuzzifier: str) -> None:
    # Output vertices closer than 1e-13 of the range are merged into one breakpoint; the
    # lines on the intervals were drawn through the terms' values at the merged ends, so a
    # jump a rounding error away from another vertex became a ramp over a whole interval.
    eps = 2.0**-50
    out = Variable("y", (0.0, 1.0), (
        Term("step", "discrete", (0.0, 0.0, 0.5 + eps, 0.0, 0.5 + eps, 1.0, 1.0, 1.0)),
        Term("tri", "triangle", (0.25, 0.5, 0.75)),
        # narrower than the merge: its area (1e-14) is below the tolerance; kept below the
        # maximum, since maxima methods do not see a term that thin (see the report)
        Term("sliver", "rectangle", (0.125, 0.125 + 1e-14), height=0.25),
    ))
    rules = (Rule(Is(0, 0), (Consequent(0, 0), Consequent(0, 2))),
             Rule(Is(0, 1), (Consequent(0, 1),)))
    for implication in ("min", "product"):
        system = FuzzySystem(inputs=(ONE_IN,), outputs=(out,), rules=rules,
                             implication=implication, defuzzifier=defuzzifier)
        assert_exact(system, [[0.3], [0.6], [0.0], [1.0]])


@pytest.mark.parametrize("defuzzifier", ["centroid", "bisector", "mom", "som", "lom"])
@pytest.mark.parametrize("strength", [1e-4, 1e-8, 1e-12, 1e-15])
def test_weakly_fired_plateau_is_flat(defuzzifier: str, strength: float) -> None:
    # Under min implication a plateau ends where the term's line c + m y meets the clip
    # height w; c + m y there carries a rounding error of eps |c|, which is a relative error
    # eps |c| / w of the plateau's end height: the plateau tilted, and a weakly fired set's
    # centroid was off by 1e-11 of the range at w = 1e-8 (4e-4 at w = 1e-15).
    ramp_in = Variable("x", (0.0, 1.0), (Term("r", "ramp", (0.0, 1.0)),))
    out = Variable("y", (0.0, 0.5), (Term("o", "trapezoid", (0.0, 0.0, 0.0, 0.125), 0.5),
                                     Term("p", "triangle", (0.25, 0.375, 0.5))))
    system = FuzzySystem(inputs=(ramp_in,), outputs=(out,), defuzzifier=defuzzifier,
                         rules=(Rule(Is(0, 0), (Consequent(0, 0),)),
                                Rule(Is(0, 0), (Consequent(0, 1),), weight=0.25)))
    assert_exact(system, [[strength]])


TWO_GAUSS = FuzzySystem(
    inputs=(ONE_IN,),
    outputs=(Variable("y", (0.0, 10.0), (Term("a", "gaussian", (4.0, 1.0)),
                                         Term("b", "gaussian", (7.0, 0.3)))),),
    rules=(Rule(Is(0, 0), (Consequent(0, 0),), weight=0.5 / 0.55),
           Rule(Is(0, 1), (Consequent(0, 1),))),
    implication="product", aggregation="sum")


@pytest.mark.parametrize("defuzzifier", ["mom", "som", "lom"])
def test_smooth_maximum_between_two_knots_is_found(defuzzifier: str) -> None:
    # The sum of two gaussians has a local maximum just inside each mean; between the knots 4
    # and 7 a golden-section search found the one near 4, and the global maximum near 6.998
    # (just left of the knot 7) was missed: 7.0 was returned.
    system = dataclasses.replace(TWO_GAUSS, defuzzifier=defuzzifier)
    assert_mp(system, [[0.55], [0.45]])


@pytest.mark.parametrize("defuzzifier", ["mom", "som", "lom"])
def test_smooth_maximum_is_located_beyond_float_resolution_of_its_value(defuzzifier: str
                                                                      ) -> None:
    # Near a smooth maximum g(x* + d) = g(x*) - k d^2 / 2, so comparisons of float values
    # place x* only to about sqrt(2 eps g / k) ~ 1e-8 (1e-9 of this range); the derivative's
    # zero is needed for 1e-10.
    out = Variable("y", (0.0, 10.0), (Term("a", "gaussian", (4.0, 1.0)),
                                      Term("b", "gaussian", (7.0, 1.0))))
    system = dataclasses.replace(TWO_GAUSS, outputs=(out,), defuzzifier=defuzzifier,
                                 rules=(Rule(Is(0, 0), (Consequent(0, 0),)),
                                        Rule(Is(0, 1), (Consequent(0, 1),))))
    assert_mp(system, [[0.55], [0.3]])
