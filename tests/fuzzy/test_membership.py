"""Membership functions (``fuzzyservo.fuzzy.membership``, the compiled values the evaluator
uses): values against their formulas, non-finite inputs, parameter validation (Term)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzzyservo.errors import ParameterError
from fuzzyservo.fuzzy import Term, membership
from fuzzyservo.fuzzy.shapes import PIECEWISE_LINEAR, SHAPES, SMOOTH, vertices

INF = math.inf


def tri(x: object, a: float, b: float, c: float) -> np.ndarray:
    return membership("triangle", (a, b, c), x)


def trap(x: object, a: float, b: float, c: float, d: float) -> np.ndarray:
    return membership("trapezoid", (a, b, c, d), x)


def shoulder_left(x: object, a: float, b: float) -> np.ndarray:
    """1 for x <= a, falling linearly to 0 at b: the trapezoid open to the left."""
    return membership("trapezoid", (-INF, a, a, b), x)


def shoulder_right(x: object, a: float, b: float) -> np.ndarray:
    """0 for x <= a, rising linearly to 1 at b and 1 beyond: the trapezoid open to the right."""
    return membership("trapezoid", (a, b, b, INF), x)


def gauss(x: object, mean: float, sigma: float) -> np.ndarray:
    return membership("gaussian", (mean, sigma), x)


def gbell(x: object, width: float, slope: float, center: float) -> np.ndarray:
    return membership("bell", (center, width, slope), x)


def test_triangle_values() -> None:
    x = np.array([-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 3.0])
    # exact: vertices at -1, 0, 1 and slopes 1, so values are exact binary fractions
    np.testing.assert_array_equal(tri(x, -1.0, 0.0, 1.0), [0, 0, 0.5, 1, 0.5, 0, 0])


def test_triangle_with_vertical_edge() -> None:
    assert tri(0.0, 0.0, 0.0, 1.0) == 1.0
    assert tri(-1e-300, 0.0, 0.0, 1.0) == 0.0
    assert tri(0.25, 0.0, 0.0, 1.0) == 0.75


def test_trapezoid_and_shoulders() -> None:
    x = np.array([-1.0, 0.0, 0.5, 1.5, 2.5, 3.0, 4.0])
    np.testing.assert_array_equal(trap(x, 0.0, 1.0, 2.0, 3.0), [0, 0, 0.5, 1, 0.5, 0, 0])
    np.testing.assert_array_equal(shoulder_left(x, 0.0, 1.0), [1, 1, 0.5, 0, 0, 0, 0])
    np.testing.assert_array_equal(shoulder_right(x, 0.0, 1.0), [0, 0, 0.5, 1, 1, 1, 1])


def test_shapes_keep_the_input_shape_and_apply_the_height() -> None:
    x = np.array([[-0.5, 0.0], [0.5, 2.0]])
    got = membership("triangle", (-1.0, 0.0, 1.0), x, height=0.5)
    assert got.shape == (2, 2) and got.dtype == np.float64
    np.testing.assert_array_equal(got, [[0.25, 0.5], [0.25, 0.0]])


def test_smooth_functions_against_formulas() -> None:
    x = np.linspace(-3, 3, 13)
    # a few ulp: exp of a differently rounded argument
    np.testing.assert_allclose(gauss(x, 0.5, 0.7), np.exp(-((x - 0.5) ** 2) / 0.98), rtol=1e-13)
    np.testing.assert_allclose(gbell(x, 1.0, 2.0, 0.5), 1 / (1 + np.abs(x - 0.5) ** 4),
                               rtol=1e-13)  # pow vs repeated product: a few ulp


@pytest.mark.parametrize(
    ("shape", "params", "at_minus_inf", "at_plus_inf"),
    [
        ("triangle", (-1, 0, 1), 0.0, 0.0),
        ("triangle", (0, 0, 1), 0.0, 0.0),
        ("trapezoid", (-1, 0, 1, 2), 0.0, 0.0),
        ("trapezoid", (-INF, 0, 0, 1), 1.0, 0.0),  # left shoulder
        ("trapezoid", (0, 1, 1, INF), 0.0, 1.0),  # right shoulder
        ("gaussian", (0, 1), 0.0, 0.0),
        ("bell", (0, 1, 2), 0.0, 0.0),
    ],
)
def test_non_finite_inputs(shape: str, params: tuple[float, ...], at_minus_inf: float,
                           at_plus_inf: float) -> None:
    out = membership(shape, params, np.array([-np.inf, np.nan, np.inf]))
    assert out[0] == at_minus_inf and out[2] == at_plus_inf
    assert math.isnan(out[1])


@pytest.mark.parametrize(
    ("shape", "params", "match"),
    [
        ("triangle", (1, 0, 2), "triangle needs"),
        ("triangle", (0, 0, -1), "triangle needs"),  # a = b > c ((0, 0, 0) is a point)
        ("triangle", (0, 2, 1), "triangle needs"),
        ("triangle", (0, math.nan, 1), "must be finite"),
        ("triangle", (0, 0.5, INF), "must be finite"),
        ("trapezoid", (0, 2, 1, 3), "trapezoid needs"),
        ("trapezoid", (-INF, 2, 1, 3), "trapezoid needs"),  # a left shoulder with b > c
        ("trapezoid", (-INF, 0, 1, INF), "a finite or d finite"),
        ("trapezoid", (2, 1, 1, INF), "trapezoid needs"),  # a right shoulder with a > b
        ("gaussian", (0, 0), "sigma > 0"),
        ("bell", (0, 0, 1), "bell needs"),
        ("bell", (0, 1, -1), "bell needs"),
    ],
)
def test_bad_parameters_raise(shape: str, params: tuple[float, ...], match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        Term("t", shape, params)


def test_error_names_the_values() -> None:
    with pytest.raises(ValueError, match=r"got \[1\.0, 0\.0, 2\.0\]"):
        Term("t", "triangle", (1, 0, 2))


def test_the_shape_table() -> None:
    assert SHAPES["triangle"] == ("a", "b", "c") and SHAPES["bell"] == (
        "center", "width", "slope")
    assert {"triangle", "trapezoid"} <= PIECEWISE_LINEAR and "gaussian" in SMOOTH
    assert not PIECEWISE_LINEAR & SMOOTH
    assert vertices("trapezoid", (-INF, 0.0, 0.0, 1.0)) == ((0.0, 1.0), (0.0, 1.0), (1.0, 0.0))
    assert vertices("triangle", (0.0, 1.0, 2.0), 0.5) == ((0.0, 0.0), (1.0, 0.5), (2.0, 0.0))
    assert vertices("gaussian", (0.0, 1.0)) is None


finite = st.floats(min_value=-1e6, max_value=1e6)


@given(x=finite, p=st.lists(finite, min_size=4, max_size=4, unique=True))
def test_memberships_lie_in_unit_interval(x: float, p: list[float]) -> None:
    a, b, c, d = sorted(p)
    for v in (tri(x, a, b, c), trap(x, a, b, c, d), shoulder_left(x, a, b),
              shoulder_right(x, c, d), gauss(x, a, d - a), gbell(x, d - a, 1.5, b)):
        assert 0.0 <= v.item() <= 1.0
