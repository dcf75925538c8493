"""Acceptance: the paper's systems against brute force, scikit-fuzzy and exact arithmetic.

The full-size brute force (10^5 points x 10^6 samples, ~1e11 samples) lives in
benchmarks/fuzzy_accuracy.py; here all 10^5 points meet a 10^4-sample brute force and 1000 of
them the full 10^6-sample one, each within that brute force's proven error bound
(``trapezoid_error_bound``, documented in fuzzy_exact_reference.py).
"""

from __future__ import annotations

import numpy as np
import pytest

from fuzzyservo.fuzzy import FuzzySystem, evaluate, pack
from fuzzyservo.paper import alpha_system, du_system
from tests.fuzzy.fuzzy_exact_reference import brute_uniform, trapezoid_error_bound

SYSTEMS = {"du": du_system, "alpha": alpha_system}


def _grid(system: FuzzySystem) -> tuple[np.ndarray, np.ndarray]:
    packed = pack(system)
    assert packed.path == "uniform grid"
    return packed.kernel_args()


def _eval(system: FuzzySystem, e: np.ndarray, de: np.ndarray) -> np.ndarray:
    return evaluate(system, np.column_stack([e, de]))[:, 0]


@pytest.mark.slow
@pytest.mark.parametrize("name", SYSTEMS)
@pytest.mark.parametrize(("n_points", "n_samples"), [(100_000, 10_000), (1_000, 1_000_000)])
def test_exact_centroid_within_brute_force_error(name: str, n_points: int, n_samples: int) -> None:
    system = SYSTEMS[name]()
    rules, lims = _grid(system)
    rng = np.random.default_rng(2012)
    e, de = rng.uniform(-1.2, 1.2, (2, n_points))
    exact = _eval(system, e, de)
    brute = brute_uniform(e, de, rules, lims, n_samples)
    bound = trapezoid_error_bound(exact, rules, lims, n_samples)
    assert np.all(np.abs(exact - brute) <= bound)  # the brute force's own error bound


@pytest.mark.parametrize("name", SYSTEMS)
def test_exact_centroid_against_scikit_fuzzy(name: str) -> None:
    skfuzzy = pytest.importorskip("skfuzzy")
    system = SYSTEMS[name]()
    rules, lims = _grid(system)
    n_grid = 2001
    lo, hi = system.outputs[0].range
    y = np.linspace(lo, hi, n_grid)
    xin = np.linspace(-1.0, 1.0, 2001)
    peaks_in = np.linspace(-1, 1, 7)
    peaks_out = np.linspace(lo, hi, 7)
    d_in, d_out = peaks_in[1] - peaks_in[0], peaks_out[1] - peaks_out[0]
    mf_in = [skfuzzy.trimf(xin, [p - d_in, p, p + d_in]) for p in peaks_in]
    mf_out = [skfuzzy.trimf(y, [p - d_out, p, p + d_out]) for p in peaks_out]
    rng = np.random.default_rng(5)
    e, de = rng.uniform(-1.2, 1.2, (2, 300))
    ours = _eval(system, e, de)
    theirs = np.empty_like(ours)
    for k, (a, b) in enumerate(zip(np.clip(e, -1, 1), np.clip(de, -1, 1), strict=True)):
        mu_e = [skfuzzy.interp_membership(xin, m, a) for m in mf_in]
        mu_de = [skfuzzy.interp_membership(xin, m, b) for m in mf_in]
        agg = np.zeros_like(y)
        for i2 in range(7):
            for i1 in range(7):
                w = min(mu_e[i1], mu_de[i2])
                agg = np.fmax(agg, np.fmin(w, mf_out[rules[i2, i1]]))
        theirs[k] = skfuzzy.defuzz(y, agg, "centroid")
    # scikit-fuzzy integrates the aggregate sampled on its universe: the same bound applies,
    # plus the interpolation of the input memberships on a 2001-point grid (exact for
    # triangles whose vertices are grid points, as here)
    bound = trapezoid_error_bound(ours, rules, lims, n_grid)
    assert np.all(np.abs(ours - theirs) <= bound)
    assert np.abs(ours - theirs).max() > 0.0  # they do sample: the comparison is not vacuous
