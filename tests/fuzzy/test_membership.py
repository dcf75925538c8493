"""Membership functions: values, non-finite inputs, parameter validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzzyservo.errors import ParameterError
from fuzzyservo.fuzzy import (
    Bell,
    Gaussian,
    LeftShoulder,
    RightShoulder,
    Trapezoid,
    Triangle,
    gauss,
    gbell,
    shoulder_left,
    shoulder_right,
    trap,
    tri,
)


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


def test_smooth_functions_against_formulas() -> None:
    x = np.linspace(-3, 3, 13)
    # a few ulp: exp of a differently rounded argument
    np.testing.assert_allclose(gauss(x, 0.5, 0.7), np.exp(-((x - 0.5) ** 2) / 0.98), rtol=1e-13)
    np.testing.assert_allclose(gbell(x, 1.0, 2.0, 0.5), 1 / (1 + np.abs(x - 0.5) ** 4),
                               rtol=1e-13)  # pow vs repeated product: a few ulp


@pytest.mark.parametrize(
    ("mf", "at_minus_inf", "at_plus_inf"),
    [
        (Triangle(a=-1, b=0, c=1), 0.0, 0.0),
        (Triangle(a=0, b=0, c=1), 0.0, 0.0),
        (Trapezoid(a=-1, b=0, c=1, d=2), 0.0, 0.0),
        (LeftShoulder(a=0, b=1), 1.0, 0.0),
        (RightShoulder(a=0, b=1), 0.0, 1.0),
        (Gaussian(mean=0, sigma=1), 0.0, 0.0),
        (Bell(a=1, b=2, c=0), 0.0, 0.0),
    ],
)
def test_non_finite_inputs(mf: object, at_minus_inf: float, at_plus_inf: float) -> None:
    out = mf(np.array([-np.inf, np.nan, np.inf]))  # type: ignore[operator]
    assert out[0] == at_minus_inf and out[2] == at_plus_inf
    assert math.isnan(out[1])


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: Triangle(a=1, b=0, c=2), "triangle needs"),
        (lambda: Triangle(a=0, b=0, c=0), "triangle needs"),
        (lambda: Triangle(a=0, b=2, c=1), "triangle needs"),
        (lambda: Triangle(a=0, b=math.nan, c=1), "must be finite"),
        (lambda: Trapezoid(a=0, b=2, c=1, d=3), "trapezoid needs"),
        (lambda: LeftShoulder(a=1, b=1), "left shoulder needs"),
        (lambda: RightShoulder(a=2, b=1), "right shoulder needs"),
        (lambda: Gaussian(mean=0, sigma=0), "sigma must be > 0"),
        (lambda: Bell(a=-1, b=1, c=0), "bell needs"),
    ],
)
def test_bad_parameters_raise(build: object, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        build()  # type: ignore[operator]


def test_error_names_the_values() -> None:
    with pytest.raises(ValueError, match=r"a=1, b=0, c=2"):
        tri(0.0, 1, 0, 2)


finite = st.floats(min_value=-1e6, max_value=1e6)


@given(x=finite, p=st.lists(finite, min_size=4, max_size=4, unique=True))
def test_memberships_lie_in_unit_interval(x: float, p: list[float]) -> None:
    a, b, c, d = sorted(p)
    for v in (tri(x, a, b, c), trap(x, a, b, c, d), shoulder_left(x, a, b),
              shoulder_right(x, c, d), gauss(x, a, d - a), gbell(x, d - a, 1.5, b)):
        assert 0.0 <= float(v) <= 1.0
