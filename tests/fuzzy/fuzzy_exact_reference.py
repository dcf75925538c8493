"""Independent exact references for uniform-triangle Mamdani systems (test-only).

``fraction_centroid`` works in exact rational arithmetic (every float is a rational): it
builds the min/min/max aggregate from scratch, with breakpoints at every point where some
clipped triangle can bend or two can cross, and integrates the linear pieces exactly.
``brute_centroid`` samples the aggregate on a grid and applies the trapezoid rule.
"""

from __future__ import annotations

from fractions import Fraction

import numba
import numpy as np

from fuzzyservo._typing import FloatArray, IntArray


def _tri(x: Fraction, peak: Fraction, d: Fraction) -> Fraction:
    return max(Fraction(0), 1 - abs(x - peak) / d)


def fraction_centroid(
    x1: float, x2: float, rules: IntArray, lims: FloatArray
) -> Fraction | None:
    """Exact centroid (None if no rule fires) as a Fraction."""
    n2, n1 = rules.shape
    lo1, hi1, lo2, hi2, lo, hi = (Fraction(float(v)) for v in lims[:6])
    n_out = int(lims[6])
    a = min(max(Fraction(x1), lo1), hi1)
    b = min(max(Fraction(x2), lo2), hi2)
    d1, d2, d = (hi1 - lo1) / (n1 - 1), (hi2 - lo2) / (n2 - 1), (hi - lo) / (n_out - 1)
    mu1 = [_tri(a, lo1 + k * d1, d1) for k in range(n1)]
    mu2 = [_tri(b, lo2 + k * d2, d2) for k in range(n2)]
    heights = [Fraction(0)] * n_out
    for i2 in range(n2):
        for i1 in range(n1):
            j = int(rules[i2, i1])
            if j >= 0:
                heights[j] = max(heights[j], min(mu1[i1], mu2[i2]))
    if not any(heights):
        return None
    peaks = [lo + j * d for j in range(n_out)]
    pts = set(peaks) | {lo, hi}
    for j in range(n_out):
        pts.add(peaks[j] + d / 2)  # adjacent edges cross mid-way
        for h in set(heights):
            pts.update({peaks[j] - d * (1 - h), peaks[j] + d * (1 - h)})
    xs = sorted(p for p in pts if lo <= p <= hi)

    def g(y: Fraction) -> Fraction:
        return max(min(heights[j], _tri(y, peaks[j], d)) for j in range(n_out))

    area = Fraction(0)
    moment = Fraction(0)
    for u, v in zip(xs, xs[1:], strict=False):
        gu, gv = g(u), g(v)
        area += (v - u) * (gu + gv) / 2
        moment += (v - u) * (u * (2 * gu + gv) + v * (gu + 2 * gv)) / 6
    return moment / area


def brute_centroid(
    x1: FloatArray, x2: FloatArray, rules: IntArray, lims: FloatArray, n_samples: int
) -> FloatArray:
    """Sampled centroid (trapezoid rule on ``n_samples`` points), vectorised over points."""
    n2, n1 = rules.shape
    n_out = int(lims[6])
    p1 = np.linspace(lims[0], lims[1], n1)
    p2 = np.linspace(lims[2], lims[3], n2)
    po = np.linspace(lims[4], lims[5], n_out)
    d1, d2, d = p1[1] - p1[0], p2[1] - p2[0], po[1] - po[0]
    a = np.clip(x1, lims[0], lims[1])[:, None]
    b = np.clip(x2, lims[2], lims[3])[:, None]
    mu1 = np.maximum(0.0, 1.0 - np.abs(a - p1) / d1)  # (n, n1)
    mu2 = np.maximum(0.0, 1.0 - np.abs(b - p2) / d2)  # (n, n2)
    h = np.zeros((x1.shape[0], n_out))
    for i2 in range(n2):
        for i1 in range(n1):
            j = rules[i2, i1]
            if j >= 0:
                h[:, j] = np.maximum(h[:, j], np.minimum(mu1[:, i1], mu2[:, i2]))
    y = np.linspace(lims[4], lims[5], n_samples)
    mf = np.maximum(0.0, 1.0 - np.abs(y[None, :] - po[:, None]) / d)  # (n_out, S)
    out = np.empty(x1.shape[0])
    for i in range(x1.shape[0]):
        agg = np.max(np.minimum(h[i][:, None], mf), axis=0)
        out[i] = np.trapezoid(agg * y, y) / np.trapezoid(agg, y)
    return out


@numba.njit(cache=True, parallel=True)
def brute_uniform(
    x1: FloatArray, x2: FloatArray, rules: IntArray, lims: FloatArray, n_samples: int
) -> FloatArray:
    """Brute-force centroid: the aggregate sampled on ``n_samples`` points, trapezoid rule.

    At each sample y only the two output triangles whose peaks bracket y are non-zero, so the
    aggregate there is max(min(h_k, 1 - s), min(h_k+1, s)); every sample is still evaluated.
    """
    n2, n1 = rules.shape
    n_out = int(lims[6])
    out = np.empty(x1.shape[0])
    d1 = (lims[1] - lims[0]) / (n1 - 1)
    d2 = (lims[3] - lims[2]) / (n2 - 1)
    lo, hi = lims[4], lims[5]
    d = (hi - lo) / (n_out - 1)
    step = (hi - lo) / (n_samples - 1)
    for i in numba.prange(x1.shape[0]):
        a = min(max(x1[i], lims[0]), lims[1])
        b = min(max(x2[i], lims[2]), lims[3])
        h = np.zeros(n_out + 1)
        for i2 in range(n2):
            m2 = max(0.0, 1.0 - abs(b - (lims[2] + i2 * d2)) / d2)
            for i1 in range(n1):
                m1 = max(0.0, 1.0 - abs(a - (lims[0] + i1 * d1)) / d1)
                j = rules[i2, i1]
                if j >= 0:
                    h[j] = max(h[j], min(m1, m2))
        area = 0.0
        moment = 0.0
        for s in range(n_samples):
            y = lo + s * step
            t = (y - lo) / d
            k = min(int(t), n_out - 2)
            f = t - k
            g = max(min(h[k], 1.0 - f), min(h[k + 1], f))
            wgt = 0.5 if (s == 0 or s == n_samples - 1) else 1.0
            area += wgt * g
            moment += wgt * g * y
        out[i] = moment / area
    return out


def trapezoid_error_bound(
    exact: FloatArray, rules: IntArray, lims: FloatArray, n_samples: int
) -> FloatArray:
    """Upper bound of the trapezoid-rule centroid error for these aggregates (per point).

    The aggregate f is piecewise linear with slopes in {0, ±1/d}, d the output peak spacing,
    and at most 4 kinks between two adjacent output peaks, so its total slope variation is
    V <= 8 (n_out - 1) / d. With step h, the trapezoid rule errs on the area by at most
    V h^2 / 8 (a kink inside a cell) and on the moment of y f(y) by at most
    (V Y + 2 (hi - lo) / d) h^2 / 8, Y = max |y| (kinks, plus (y f)'' = 2 f' on the pieces).
    The centroid error is then at most (|dM| + |c| |dA|) / (A - |dA|), with A >= A_min the
    smallest area an aggregate can have: here at least one rule fires at >= 1/2, so A is at
    least the area of a half triangle clipped at 1/2, d (1/2 - 1/8) = 3 d / 8.
    """
    n_out = int(lims[6])
    lo, hi = lims[4], lims[5]
    d = (hi - lo) / (n_out - 1)
    h = (hi - lo) / (n_samples - 1)
    v = 8.0 * (n_out - 1) / d
    ymax = max(abs(lo), abs(hi))
    da = v * h * h / 8.0
    dm = (v * ymax + 2.0 * (hi - lo) / d) * h * h / 8.0
    a_min = 3.0 * d / 8.0
    return np.asarray((dm + np.abs(exact) * da) / (a_min - da))
