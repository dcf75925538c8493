"""The compiled uniform-grid kernel against exact rational arithmetic and quadrature."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from fuzzyservo.fuzzy.engine import pack
from fuzzyservo.fuzzy.kernels import (
    eval_uniform_batch,
    eval_uniform_checked,
    eval_uniform_grid,
    segment_integrals,
)
from fuzzyservo.paper import alpha_system, du_system
from tests.fuzzy.fuzzy_exact_reference import fraction_centroid


def _grid(make) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """``(rules, lims)`` of a paper system, which packs for the uniform grid."""
    packed = pack(make())
    assert packed.path == "uniform grid"
    return packed.kernel_args()


@pytest.mark.parametrize("seed", range(3))
def test_segment_integrals_match_quadrature(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for a, b in [*rng.uniform(0, 1, (50, 2)), (0.0, 0.0), (1.0, 1.0), (0.0, 0.7), (0.3, 0.3)]:
        def g(s: float, a: float = a, b: float = b) -> float:
            return max(min(a, 1 - s), min(b, s))

        brk = sorted({0.5, a, 1 - a, b, 1 - b} & {x for x in (0.5, a, 1 - a, b, 1 - b)
                                                  if 0 < x < 1})
        area = integrate.quad(g, 0, 1, points=brk, epsabs=1e-14, epsrel=1e-14)[0]
        mom = integrate.quad(lambda s: s * g(s), 0, 1, points=brk, epsabs=1e-14,
                             epsrel=1e-14)[0]
        got_area, got_mom = segment_integrals(a, b)
        assert got_area == pytest.approx(area, abs=1e-13)  # quad on a piecewise-linear g
        assert got_mom == pytest.approx(mom, abs=1e-13)  # quad on a piecewise-linear g


@pytest.mark.parametrize("system", [du_system, alpha_system], ids=["du", "alpha"])
def test_kernel_matches_exact_rational_centroid(system) -> None:  # type: ignore[no-untyped-def]
    rules, lims = _grid(system)
    rng = np.random.default_rng(7)
    pts = rng.uniform(-1.2, 1.2, (300, 2))
    # include grid nodes, label midpoints and the universe ends, where branches switch
    nodes = np.array([-1, -2 / 3, -0.5, -1 / 3, -1 / 6, 0, 1 / 6, 1 / 3, 0.5, 2 / 3, 1])
    pts = np.vstack([pts, np.array(np.meshgrid(nodes, nodes)).reshape(2, -1).T])
    worst = 0.0
    for x1, x2 in pts:
        exact = fraction_centroid(float(x1), float(x2), rules, lims)
        assert exact is not None
        worst = max(worst, abs(eval_uniform_grid(x1, x2, rules, lims) - float(exact)))
    assert worst <= 1e-12  # acceptance: exact path to 1e-12 against exact arithmetic


def test_kernel_clips_inputs_to_the_universe() -> None:
    rules, lims = _grid(du_system)
    assert eval_uniform_grid(5.0, -7.0, rules, lims) == eval_uniform_grid(1.0, -1.0, rules, lims)
    assert eval_uniform_grid(math.inf, 0.2, rules, lims) == eval_uniform_grid(1.0, 0.2, rules,
                                                                              lims)


def test_kernel_nan_and_checked_variant() -> None:
    rules, lims = _grid(du_system)
    assert math.isnan(eval_uniform_grid(math.nan, 0.0, rules, lims))
    assert math.isnan(eval_uniform_checked(math.inf, 0.0, rules, lims))
    assert math.isnan(eval_uniform_checked(0.0, -math.inf, rules, lims))
    assert eval_uniform_checked(0.2, 0.1, rules, lims) == eval_uniform_grid(0.2, 0.1, rules, lims)


def test_kernel_default_when_no_rule_fires() -> None:
    rules, lims = _grid(du_system)
    rules[:] = -1
    rules[0, 0] = 3  # only (NB, NB) -> ZO
    lims[7] = 0.25
    assert eval_uniform_grid(0.5, 0.5, rules, lims) == 0.25
    assert eval_uniform_grid(-1.0, -1.0, rules, lims) == pytest.approx(0.0, abs=1e-15)  # ZO


def test_batch_equals_scalar_kernel_bitwise() -> None:
    rules, lims = _grid(alpha_system)
    rng = np.random.default_rng(3)
    x1, x2 = rng.uniform(-1.2, 1.2, (2, 1000))
    out = np.empty(1000)
    eval_uniform_batch(x1, x2, rules, lims, out)
    want = [eval_uniform_grid(a, b, rules, lims) for a, b in zip(x1, x2, strict=True)]
    np.testing.assert_array_equal(out, want)  # the same njit function: identical bits


def test_batch_flags_the_first_non_finite_point() -> None:
    rules, lims = _grid(du_system)
    x1 = np.array([0.1, 0.2, np.inf, np.nan, 0.3])
    x2 = np.zeros(5)
    out = np.empty(5)
    assert eval_uniform_batch(x1, x2, rules, lims, out) == 2
    assert math.isnan(out[2])
    assert eval_uniform_batch(x1[:2], x2[:2], rules, lims, out[:2]) == -1
    assert eval_uniform_batch(x1[3:], x2[3:], rules, lims, out[3:]) == 0


def test_pair_equals_two_single_evaluations() -> None:
    """The self-tuning controller's shared-fuzzification path is the same maths, bit for bit."""
    import numpy as np

    from fuzzyservo.fuzzy.kernels import eval_uniform_grid, eval_uniform_pair
    from fuzzyservo.paper import alpha_system, du_system

    du = _grid(du_system)
    al = _grid(alpha_system)
    # a 5 x 4 grid on other universes: the pair must locate the inputs separately
    other_rules = np.array([[0, 1, 2, 3, 4], [1, 2, 3, 4, 4], [2, 3, 4, 4, 4],
                            [-1, 0, 1, 2, 3]], dtype=np.int64)
    other_lims = np.array([-2.0, 2.0, -0.5, 0.5, 0.0, 10.0, 5.0, 0.0])
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1.3, 1.3, size=(5000, 2))
    pts = np.vstack([pts, [[np.nan, 0.0], [1.0, 1.0], [-1.0, -1.0], [0.0, 0.0]]])
    for (ra, la), (rb, lb) in (((du[0], du[1]), (al[0], al[1])),
                               ((du[0], du[1]), (other_rules, other_lims))):
        for x1, x2 in pts:
            ya, yb = eval_uniform_pair(x1, x2, ra, la, rb, lb)
            ea, eb = eval_uniform_grid(x1, x2, ra, la), eval_uniform_grid(x1, x2, rb, lb)
            assert (ya == ea or (np.isnan(ya) and np.isnan(ea)))
            assert (yb == eb or (np.isnan(yb) and np.isnan(eb)))
