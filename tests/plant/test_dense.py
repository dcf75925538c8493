"""plant.dense: products, solves and eigenvalues in plain IEEE arithmetic, against numpy's
LAPACK, analytic eigenvalues and exact rational arithmetic."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from fuzzyservo.errors import ParameterError
from fuzzyservo.paper.published import named_set
from fuzzyservo.plant import linearize
from fuzzyservo.plant.dense import balance, dot, eigvals, matmul, solve


def _matched_error(got: np.ndarray, want: np.ndarray) -> float:
    """Largest distance from an eigenvalue of ``got`` to its nearest in ``want``, both ways,
    relative to the largest modulus."""
    scale = max(float(np.max(np.abs(want))), 1e-300)
    there = max(float(np.min(np.abs(want - g))) for g in got)
    back = max(float(np.min(np.abs(got - w))) for w in want)
    return max(there, back) / scale


def test_matmul_sums_each_entry_in_index_order_exactly() -> None:
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((5, 7)), rng.standard_normal((7, 3))
    c = matmul(a, b)
    for i in range(5):
        for j in range(3):
            s = 0.0
            for t in range(7):
                s += float(a[i, t]) * float(b[t, j])
            assert c[i, j] == s  # the documented order, bit for bit
    assert np.allclose(c, a @ b, rtol=1e-13, atol=1e-13)
    v = matmul(a, b[:, 0])
    assert v.shape == (5,) and np.array_equal(v, c[:, 0])
    assert dot(a[0], b[:, 0]) == c[0, 0]


def test_solve_is_exact_on_a_rational_system_and_agrees_with_lapack() -> None:
    # pivots and multipliers powers of two: every elimination step is exact
    a = np.array([[4.0, 2.0, 1.0], [2.0, 2.0, 1.0], [1.0, 1.0, 1.0]])
    assert solve(a, a @ np.array([1.0, -2.0, 3.0])).tolist() == [1.0, -2.0, 3.0]
    rng = np.random.default_rng(1)
    for n in (1, 2, 5, 8):
        m = rng.standard_normal((n, n)) + n * np.eye(n)
        b = rng.standard_normal((n, 4))
        x = solve(m, b)
        # residual against exact rational arithmetic of the doubles given
        for j in range(4):
            for i in range(n):
                r = sum(Fraction(float(m[i, t])) * Fraction(float(x[t, j]))
                        for t in range(n)) - Fraction(float(b[i, j]))
                assert abs(float(r)) <= 1e-13 * (1.0 + float(np.abs(b).max()))
        assert np.allclose(x, np.linalg.solve(m, b), rtol=1e-12, atol=1e-13)


def test_solve_refuses_a_singular_or_misshapen_matrix() -> None:
    with pytest.raises(ParameterError, match="singular"):
        solve(np.array([[1.0, 2.0], [2.0, 4.0]]), np.array([1.0, 1.0]))
    with pytest.raises(ParameterError, match="square"):
        solve(np.ones((2, 3)), np.ones(2))
    with pytest.raises(ParameterError, match="rows"):
        solve(np.eye(2), np.ones(3))


def test_eigvals_of_matrices_with_known_spectra() -> None:
    # companion matrix of (x - 1)(x - 2)...(x - 6): eigenvalues 1..6
    coeffs = np.poly(np.arange(1.0, 7.0))
    comp = np.zeros((6, 6))
    comp[0, :] = -coeffs[1:]
    comp[1:, :-1] = np.eye(5)
    lam = eigvals(comp)
    assert np.allclose(np.sort(lam.real), np.arange(1.0, 7.0), rtol=1e-9)
    assert np.max(np.abs(lam.imag)) <= 1e-9
    # a damped oscillator pair and a real pole: -ζω ± iω√(1-ζ²), -p
    w, z, p = 19.6, 0.1, 350.0
    a = np.array([[0.0, 1.0, 0.0], [-w * w, -2 * z * w, 1.0], [0.0, 0.0, -p]])
    lam = eigvals(a)
    want = np.array([complex(-z * w, w * np.sqrt(1 - z * z)),
                     complex(-z * w, -w * np.sqrt(1 - z * z)), -p])
    assert _matched_error(lam, want) <= 1e-14
    assert lam[0].imag > 0.0 and lam[0] == np.conj(lam[1])  # the positive part first
    assert eigvals(np.zeros((0, 0))).shape == (0,)
    assert eigvals(np.array([[3.0]])).tolist() == [3.0]


@pytest.mark.parametrize("n", [2, 3, 5, 7, 9])
def test_eigvals_agree_with_lapack_on_badly_scaled_random_matrices(n: int) -> None:
    rng = np.random.default_rng(n)
    for _ in range(40):
        a = rng.standard_normal((n, n)) * np.exp(rng.uniform(-6.0, 6.0, (n, n)))
        assert _matched_error(eigvals(a), np.linalg.eigvals(a)) <= 1e-12


@pytest.mark.parametrize("name", ["paper", "stiff-oil"])
def test_eigvals_of_the_linearisations_agree_with_lapack(name: str) -> None:
    p = named_set(name)
    for s in (0.05, 0.3, 0.5, 0.95):
        lin = linearize(p, s * p.cylinder.stroke)
        assert _matched_error(lin.eigenvalues, np.linalg.eigvals(lin.a)) <= 1e-12


def test_balance_is_an_exact_similarity_by_powers_of_two() -> None:
    a = np.array([[1.0, 1e6, 0.0], [1e-6, 2.0, 3e5], [0.0, 1e-5, 3.0]])
    b, d = balance(a)
    assert np.all(np.frexp(d)[0] == 0.5)  # powers of two: the scaling rounds nothing
    assert np.array_equal(b, a * d[None, :] / d[:, None])
    assert np.max(np.abs(b)) < np.max(np.abs(a)) / 100.0


def test_eigvals_refuses_bad_matrices() -> None:
    with pytest.raises(ParameterError, match="square"):
        eigvals(np.ones((2, 3)))
    with pytest.raises(ParameterError, match="finite"):
        eigvals(np.array([[1.0, np.nan], [0.0, 1.0]]))
