"""The points of a sweep: grids, distributions, and independence from chunking.

References: itertools.product for the grid, scipy.stats (truncnorm, lognorm, uniform,
loguniform) for the inverse CDFs and a Kolmogorov-Smirnov test of the drawn values.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import stats

from fuzzyservo.sweep import parse_spec, points
from fuzzyservo.sweep.sampling import counter_uniform, noise_seeds, transform
from fuzzyservo.sweep.spec import Variation

CTL = [{"controller": "pi", "gains": {"kp": 1.0, "ki": 0.5}}]


def _spec(vary: list[dict], samples: int = 1, **sweep: object) -> object:
    return parse_spec({"sweep": {"samples": samples, "seed": 7, **sweep}, "controllers": CTL,
                       "vary": vary})


def test_grid_is_the_full_factorial_first_slowest() -> None:
    spec = _spec([{"name": "load.mass", "grid": [1.0, 2.0, 3.0]},
                  {"name": "delay", "grid": [0.0, 0.01]},
                  {"name": "amplitude", "grid": [0.05, 0.1]}], samples=2, noise_std=1e-6)
    pts = points(spec, 0, spec.n_points)
    expect = [c for c in itertools.product([1.0, 2.0, 3.0], [0.0, 0.01], [0.05, 0.1])
              for _ in range(2)]
    got = list(zip(*(pts.values[n].tolist() for n in ("load.mass", "delay", "amplitude")),
                   strict=True))
    assert got == expect
    assert pts.sample.tolist() == [0, 1] * 12
    assert pts.cell.tolist() == [i // 2 for i in range(24)]


def test_points_do_not_depend_on_the_chunking() -> None:
    spec = _spec([{"name": "load.mass", "grid": [1.0, 2.0]},
                  {"name": "supply.pressure", "relative": True, "distribution": "normal",
                   "mean": 1.0, "std": 0.05, "low": 0.9, "high": 1.1},
                  {"name": "noise_std", "distribution": "log-uniform", "low": 1e-6,
                   "high": 1e-4}], samples=50)
    whole = points(spec, 0, spec.n_points)
    for lo, hi in ((0, 1), (17, 63), (99, 100), (40, 100)):
        part = points(spec, lo, hi)
        for name in whole.values:
            assert np.array_equal(part.values[name], whole.values[name][lo:hi])
        assert np.array_equal(part.noise_seed, whole.noise_seed[lo:hi])


def test_seed_and_variation_give_independent_streams() -> None:
    idx = np.arange(10_000)
    a, b, c = (counter_uniform(1, 1, idx), counter_uniform(1, 2, idx),
               counter_uniform(2, 1, idx))
    assert np.all((a > 0.0) & (a < 1.0))
    for x, y in ((a, b), (a, c)):
        assert abs(np.corrcoef(x, y)[0, 1]) < 0.05
    assert stats.kstest(a, "uniform").pvalue > 1e-3
    seeds = noise_seeds(1, idx)
    assert seeds.min() >= 0 and np.unique(seeds).size == seeds.size


@pytest.mark.parametrize(("dist", "args", "ref"), [
    ("uniform", {"low": 2.0, "high": 5.0}, stats.uniform(2.0, 3.0)),
    ("log-uniform", {"low": 0.5, "high": 2.0}, stats.loguniform(0.5, 2.0)),
    ("normal", {"mean": 1.0, "std": 0.1, "low": 0.85, "high": 1.3},
     stats.truncnorm(-1.5, 3.0, loc=1.0, scale=0.1)),
    ("normal", {"mean": -3.0, "std": 2.0}, stats.norm(-3.0, 2.0)),
    ("log-normal", {"median": 1e-5, "sigma": 0.5}, stats.lognorm(0.5, scale=1e-5)),
    # far in a tail, where Φ rounds to 1 (or 0): the truncation must not collapse on a bound
    ("normal", {"mean": 1.0, "std": 0.01, "low": 1.09, "high": 1.2},
     stats.truncnorm(9.0, 20.0, loc=1.0, scale=0.01)),
    ("normal", {"mean": 0.0, "std": 1.0, "low": -40.0, "high": -7.0},
     stats.truncnorm(-40.0, -7.0)),
    ("log-normal", {"median": 1.0, "sigma": 0.1, "low": 2.5, "high": 4.0},
     stats.truncnorm(np.log(2.5) / 0.1, np.log(4.0) / 0.1)),
])
def test_inverse_cdf_matches_scipy(dist: str, args: dict, ref: object) -> None:
    var = Variation(name="delay", distribution=dist, args=tuple(args.items()))
    u = np.linspace(1e-6, 1.0 - 1e-6, 2001)
    got = transform(var, u)
    if dist == "log-normal" and "low" in args:  # the reference is of ln(x / median) / sigma
        got = np.log(got) / 0.1
    np.testing.assert_allclose(got, ref.ppf(u), rtol=1e-9, atol=0.0)
    assert np.unique(got).size == u.size  # strictly increasing: no draw piles on a bound


def test_truncated_log_normal_stays_in_its_bounds_and_follows_its_law() -> None:
    spec = _spec([{"name": "noise_std", "distribution": "log-normal", "median": 1e-5,
                   "sigma": 0.5, "high": 2e-5}], samples=4000)
    x = points(spec, 0, spec.n_points).values["noise_std"]
    assert x.max() <= 2e-5 and x.min() > 0.0
    b = math.log(2.0) / 0.5
    ref = stats.truncnorm(-np.inf, b)
    assert stats.kstest(np.log(x / 1e-5) / 0.5, ref.cdf).pvalue > 1e-3


def test_relative_values_multiply_the_nominal() -> None:
    spec = _spec([{"name": "load.mass", "relative": True, "grid": [0.5, 2.0]}])
    pts = points(spec, 0, 2)
    m0 = spec.nominal.load.mass
    assert pts.values["load.mass"].tolist() == [0.5 * m0, 2.0 * m0]


def test_fewer_samples_draw_the_first_plants_of_each_cell() -> None:
    vary = [{"name": "delay", "grid": [0.0, 0.01, 0.02]},
            {"name": "load.mass", "relative": True, "distribution": "log-uniform",
             "low": 0.5, "high": 2.0}]
    full, reduced = _spec(vary, samples=40), _spec(vary, samples=7)
    a = points(full, 0, full.n_points)
    b = points(reduced, 0, reduced.n_points)
    for cell in range(3):
        sel_a = (a.cell == cell) & (a.sample < 7)
        sel_b = b.cell == cell
        assert np.array_equal(a.values["load.mass"][sel_a], b.values["load.mass"][sel_b])
        assert np.array_equal(a.noise_seed[sel_a], b.noise_seed[sel_b])


# ---- the generator itself, against an independent implementation: this pins sampling
# scheme 1 (spec.SAMPLING_SCHEME). A change that makes these fail changes every sweep's
# points, and must come with a new scheme number, so that no folder is resumed across it.

_MASK = 2**64 - 1
_GOLDEN = 0x9E3779B97F4A7C15


def _splitmix64(state: int) -> int:
    """SplitMix64 (Steele, Lea & Flood 2014; Vigna's reference C): the output for ``state``
    before its increment, in Python integers."""
    z = (state + _GOLDEN) & _MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK
    return z ^ (z >> 31)


def test_generator_is_splitmix64_as_documented() -> None:
    # the reference generator's first outputs from seed 0 (its published test vector)
    assert [_splitmix64(k * _GOLDEN & _MASK) for k in range(3)] == [
        0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, 0x06C45D188009454F]
    # a draw: key = mix(mix(seed) ^ stream); bits = mix(key ^ mix(counter)); the top 53 bits
    # plus half an ulp; counter = cell * 2**32 + sample (sampling.py's docstring)
    seed, stream = 8, 3
    counters = np.array([0, 1, 2**32 + 5, 7 * 2**32 + 3333, 2**40 - 1], dtype=np.int64)
    key = _splitmix64(_splitmix64(seed) ^ stream)
    bits = [_splitmix64(key ^ _splitmix64(int(c))) for c in counters]
    expected = [((b >> 11) + 0.5) * 2.0 ** -53 for b in bits]
    assert counter_uniform(seed, stream, counters).tolist() == expected
    assert noise_seeds(seed, counters).tolist() == [
        _splitmix64(_splitmix64(_splitmix64(seed) ^ 0) ^ _splitmix64(int(c))) >> 1
        for c in counters]
