"""The compiled uniform-grid kernel the controllers inline equals, bit for bit, the algorithm it
was written as before it was made faster (issue 13): a plain Python transcription kept here.

The faster kernel gathers the clip heights into a buffer (instead of scanning the four rules
for every output label), carries the powers of a height from one segment to the next and counts
the label index as a float; none of that may change a bit of the centroid. Python floats are
IEEE doubles and the compiled code is built without fast-math, so the two must agree exactly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzyservo.fuzzy.engine import pack
from fuzzyservo.fuzzy.kernels import eval_uniform_grid, eval_uniform_pair
from fuzzyservo.paper import alpha_system, du_system

_SIXTH = 1.0 / 6.0


def _segment(a: float, b: float) -> tuple[float, float]:
    m = min(a, b, 0.5)
    tm = m - m * m
    area = a - 0.5 * a * a + b - 0.5 * b * b - tm
    moment = 0.5 * (a - a * a + b - tm) + (a * a * a - b * b * b) * _SIXTH
    return area, moment


def _reference(x1: float, x2: float, rules: np.ndarray, lims: np.ndarray) -> float:
    """fuzzy.kernels.eval_uniform_grid as of the commit before issue 13's changes."""
    if x1 != x1 or x2 != x2:
        return math.nan
    lo1, hi1, lo2, hi2 = (float(v) for v in lims[:4])
    n2, n1 = rules.shape
    x1 = lo1 if x1 < lo1 else (hi1 if x1 > hi1 else x1)
    x2 = lo2 if x2 < lo2 else (hi2 if x2 > hi2 else x2)
    t1 = (x1 - lo1) / (hi1 - lo1) * (n1 - 1)
    t2 = (x2 - lo2) / (hi2 - lo2) * (n2 - 1)
    k1 = min(int(t1), n1 - 2)
    k2 = min(int(t2), n2 - 2)
    f1, f2 = t1 - k1, t2 - k2
    g1, g2 = 1.0 - f1, 1.0 - f2
    fired = [(int(rules[k2, k1]), min(g1, g2)), (int(rules[k2, k1 + 1]), min(f1, g2)),
             (int(rules[k2 + 1, k1]), min(g1, f2)), (int(rules[k2 + 1, k1 + 1]), min(f1, f2))]
    fired = [(lab, w if lab >= 0 else 0.0) for lab, w in fired]
    n_out = int(lims[6])
    labels = [lab for lab, w in fired if w > 0.0]
    lmin, lmax = (min(labels), max(labels)) if labels else (n_out, -1)

    def height(j: int) -> float:
        return max(max(fired[0][1] if fired[0][0] == j else 0.0,
                       fired[1][1] if fired[1][0] == j else 0.0),
                   max(fired[2][1] if fired[2][0] == j else 0.0,
                       fired[3][1] if fired[3][0] == j else 0.0))

    area = parea = moment = 0.0
    j = max(lmin - 1, 0)
    ha = height(j)
    while j <= min(lmax, n_out - 2):
        hb = height(j + 1)
        if ha > 0.0 or hb > 0.0:
            ar, mo = _segment(ha, hb)
            area += ar
            parea += j * ar
            moment += mo
        ha = hb
        j += 1
    if area <= 0.0:
        return float(lims[7])
    lo = float(lims[4])
    return lo + (float(lims[5]) - lo) * (parea + moment) / (area * (n_out - 1))


def _random_table(rng: np.random.Generator, n_out: int) -> tuple[np.ndarray, np.ndarray]:
    n2, n1 = (int(v) for v in rng.integers(2, 10, size=2))
    rules = rng.integers(-1, n_out, size=(n2, n1))
    lo1, lo2 = rng.uniform(-2.0, 0.0, size=2)
    lo_out = float(rng.uniform(-1.0, 0.5))
    lims = np.array([lo1, lo1 + rng.uniform(0.1, 3.0), lo2, lo2 + rng.uniform(0.1, 3.0),
                     lo_out, lo_out + rng.uniform(0.1, 2.0), n_out, rng.choice([0.0, np.nan])])
    return rules, lims


def _inputs(rng: np.random.Generator, lims: np.ndarray, n: int) -> list[tuple[float, float]]:
    """Points inside and outside the universes, on grid lines and at the corners."""
    pts = [(float(a), float(b)) for a, b in zip(
        rng.uniform(lims[0] - 0.5, lims[1] + 0.5, n), rng.uniform(lims[2] - 0.5, lims[3] + 0.5,
                                                                  n), strict=True)]
    pts += [(float(lims[0]), float(lims[2])), (float(lims[1]), float(lims[3])),
            (0.5 * (lims[0] + lims[1]), float(lims[2])), (-0.0, 0.0), (math.nan, 0.0)]
    return pts


@pytest.mark.parametrize("n_out", [2, 3, 7, 9, 14, 15, 16, 17, 40, 90])
def test_kernel_equals_the_previous_algorithm_bit_for_bit(n_out: int) -> None:
    """Random tables (rules -1 .. n_out - 1, so gaps, single labels and wide spans), both the
    gathered heights (n_out < 16) and the scan kept for more labels."""
    rng = np.random.default_rng(1300 + n_out)
    for _ in range(30):
        rules, lims = _random_table(rng, n_out)
        for x1, x2 in _inputs(rng, lims, 60):
            got = eval_uniform_grid(x1, x2, rules, lims)
            ref = _reference(x1, x2, rules, lims)
            assert got == ref or (math.isnan(got) and math.isnan(ref)), (x1, x2, got, ref)


def test_pair_and_strided_tables_equal_the_previous_algorithm() -> None:
    """The paper's two systems through the pair evaluator (shared cell), and a rule table
    that is a strided view (the kernel indexes with the array's strides)."""
    pd, pa = pack(du_system()), pack(alpha_system())
    assert pd.path == pa.path == "uniform grid"
    rd, ld = pd.kernel_args()
    ra, la = pa.kernel_args()
    rng = np.random.default_rng(13)
    for x1, x2 in _inputs(rng, ld, 2000):
        du, alpha = eval_uniform_pair(x1, x2, rd, ld, ra, la)
        assert np.array_equal([du, alpha], [_reference(x1, x2, rd, ld),
                                            _reference(x1, x2, ra, la)], equal_nan=True)
    wide = np.repeat(np.asarray(rd), 2, axis=1)[:, ::2]  # same values, column stride 2
    assert not wide.flags.c_contiguous
    big = np.asarray(ra).T.copy().T  # Fortran order
    for x1, x2 in _inputs(rng, ld, 300):
        assert np.array_equal([eval_uniform_grid(x1, x2, wide, ld),
                               eval_uniform_grid(x1, x2, big, la)],
                              [_reference(x1, x2, rd, ld), _reference(x1, x2, ra, la)],
                              equal_nan=True)
