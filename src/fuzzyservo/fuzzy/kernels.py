"""Compiled kernels for two-input Mamdani systems on uniform triangular partitions.

This is the hot path of the fuzzy PI and self-tuning controllers: ``eval_uniform_grid`` is
called inside numba kernels once per controller sample (twice for the self-tuning controller),
so it allocates nothing and visits only the output labels that fired.

Contract (docs/architecture.md, "Fuzzy kernel"):

- inputs ``x1`` (e, columns) and ``x2`` (Δe, rows) are each covered by ``rules.shape[1]`` and
  ``rules.shape[0]`` uniform triangles on ``[lims[0], lims[1]]`` and ``[lims[2], lims[3]]``
  (peaks at ``lo + k (hi - lo) / (n - 1)``, 50 % overlap, the end triangles cut at the universe
  ends); inputs are clipped to the universes; a NaN input gives NaN;
- ``rules[i2, i1]`` is the output label index (0 .. n_out - 1) or -1 for "no rule";
- the output is ``int(lims[6])`` uniform triangles on ``[lims[4], lims[5]]``; min AND, min
  implication, max aggregation, exact centroid over the output universe; ``lims[7]`` is the
  value returned when no rule fires.

Notes
-----
Between two adjacent output peaks p_j and p_j+1 only the falling edge of triangle j and the
rising edge of triangle j+1 are non-zero. With s = (y - p_j) / d in [0, 1] the aggregate there is
g(s) = max(F, R), F = min(a, 1 - s), R = min(b, s), a and b the clip heights of labels j and
j+1. Since max(F, R) = F + R - min(F, R) and min(F, R) = min(m, s, 1 - s) with
m = min(a, b, 1/2) is a trapezoid symmetric about s = 1/2, the area and first moment are

    area   = a - a^2/2 + b - b^2/2 - (m - m^2)
    moment = (a - a^2 + b - (m - m^2)) / 2 + (a^3 - b^3) / 6

(integrals of F: a - a^2/2 and a/2 - a^2/2 + a^3/6; of R: b - b^2/2 and b/2 - b^3/6).
No sampling, no sorting and no branch is involved.
"""

from __future__ import annotations

import numba
import numpy as np

from .._typing import FloatArray, IntArray

__all__ = [
    "LIMS_SIZE",
    "eval_uniform_batch",
    "eval_uniform_checked",
    "eval_uniform_grid",
    "eval_uniform_pair",
    "segment_integrals",
]

#: Length of the ``lims`` vector: lo1, hi1, lo2, hi2, out_lo, out_hi, n_out, default.
LIMS_SIZE = 8
_SIXTH = 1.0 / 6.0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def segment_integrals(a: float, b: float) -> tuple[float, float]:
    """Area and first moment over s in [0, 1] of max(min(a, 1 - s), min(b, s)).

    Parameters
    ----------
    a : float
        Clip height of the falling edge (label j), in [0, 1].
    b : float
        Clip height of the rising edge (label j + 1), in [0, 1].

    Returns
    -------
    area, moment : float
        Integral of g(s) and of s g(s) over [0, 1] (dimensionless).
    """
    # max(F, R) = F + R - min(F, R) with F = min(a, 1 - s), R = min(b, s); min(F, R) is the
    # trapezoid min(m, s, 1 - s), m = min(a, b, 1/2), symmetric about s = 1/2 (area m - m^2)
    m = min(a, b, 0.5)
    tm = m - m * m
    area = a - 0.5 * a * a + b - 0.5 * b * b - tm
    moment = 0.5 * (a - a * a + b - tm) + (a * a * a - b * b * b) * _SIXTH
    return area, moment


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _height(
    j: int, la: int, wa: float, lb: int, wb: float, lc: int, wc: float, ld: int, wd: float
) -> float:
    """Clip height of output label j: the largest strength of the four rules naming it."""
    return max(
        max(wa if la == j else 0.0, wb if lb == j else 0.0),
        max(wc if lc == j else 0.0, wd if ld == j else 0.0),
    )


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _cell(x1: float, x2: float, n1: int, n2: int, lims: FloatArray
          ) -> tuple[int, int, float, float]:
    """Clip the inputs and locate them: grid cell (k1, k2) and fractions (f1, f2) in it."""
    lo1 = lims[0]
    hi1 = lims[1]
    lo2 = lims[2]
    hi2 = lims[3]
    if x1 < lo1:
        x1 = lo1
    elif x1 > hi1:
        x1 = hi1
    if x2 < lo2:
        x2 = lo2
    elif x2 > hi2:
        x2 = hi2
    t1 = (x1 - lo1) / (hi1 - lo1) * (n1 - 1)
    t2 = (x2 - lo2) / (hi2 - lo2) * (n2 - 1)
    k1 = int(t1)
    if k1 > n1 - 2:
        k1 = n1 - 2
    k2 = int(t2)
    if k2 > n2 - 2:
        k2 = n2 - 2
    return k1, k2, t1 - k1, t2 - k2


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _centroid(k1: int, k2: int, f1: float, f2: float, rules: IntArray,
              lims: FloatArray) -> float:
    """Exact centroid of the aggregate of the (at most) four rules of cell (k1, k2)."""
    g1 = 1.0 - f1
    g2 = 1.0 - f2
    # the (at most) four rules that fire, with their min-AND strengths
    la = rules[k2, k1]
    wa = min(g1, g2)
    lb = rules[k2, k1 + 1]
    wb = min(f1, g2)
    lc = rules[k2 + 1, k1]
    wc = min(g1, f2)
    ld = rules[k2 + 1, k1 + 1]
    wd = min(f1, f2)
    if la < 0:
        wa = 0.0
    if lb < 0:
        wb = 0.0
    if lc < 0:
        wc = 0.0
    if ld < 0:
        wd = 0.0
    # the fired labels span lmin .. lmax; visit the segments between adjacent output peaks
    # from lmin - 1 to lmax (each is [p_j, p_j+1]); segments with no fired end are skipped
    n_out = int(lims[6])
    lmin = n_out
    lmax = -1
    if wa > 0.0:
        lmin = min(lmin, la)
        lmax = max(lmax, la)
    if wb > 0.0:
        lmin = min(lmin, lb)
        lmax = max(lmax, lb)
    if wc > 0.0:
        lmin = min(lmin, lc)
        lmax = max(lmax, lc)
    if wd > 0.0:
        lmin = min(lmin, ld)
        lmax = max(lmax, ld)
    area = 0.0
    parea = 0.0
    moment = 0.0
    j = max(lmin - 1, 0)
    jend = min(lmax, n_out - 2)
    ha = _height(j, la, wa, lb, wb, lc, wc, ld, wd)
    while j <= jend:
        hb = _height(j + 1, la, wa, lb, wb, lc, wc, ld, wd)
        if ha > 0.0 or hb > 0.0:
            ar, mo = segment_integrals(ha, hb)
            area += ar
            parea += j * ar
            moment += mo
        ha = hb
        j += 1
    if area <= 0.0:
        return lims[7]
    lo = lims[4]
    # centroid = sum(p_j A_j + d M_j) / sum(A_j), p_j = lo + j d, d = (hi - lo) / (n_out - 1)
    # (the factor d of dy cancels)
    return lo + (lims[5] - lo) * (parea + moment) / (area * (n_out - 1))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def eval_uniform_grid(x1: float, x2: float, rules: IntArray, lims: FloatArray) -> float:
    """Crisp output of a two-input min/min/max/centroid system on uniform triangles.

    Parameters
    ----------
    x1 : float
        First input (e, selects the column of ``rules``); clipped to ``[lims[0], lims[1]]``.
    x2 : float
        Second input (Δe, selects the row of ``rules``); clipped to ``[lims[2], lims[3]]``.
    rules : int64[:, :]
        ``rules[i2, i1]`` = output label index, or -1 for no rule; at least 2 x 2.
    lims : float64[8]
        lo1, hi1, lo2, hi2, output lo, output hi, number of output labels (>= 2), default.

    Returns
    -------
    float
        Exact centroid of the aggregated output over the output universe; ``lims[7]`` when no
        rule fires; NaN when an input is NaN.
    """
    if x1 != x1 or x2 != x2:
        return np.nan
    k1, k2, f1, f2 = _cell(x1, x2, rules.shape[1], rules.shape[0], lims)
    return _centroid(k1, k2, f1, f2, rules, lims)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def eval_uniform_pair(x1: float, x2: float, rules_a: IntArray, lims_a: FloatArray,
                      rules_b: IntArray, lims_b: FloatArray) -> tuple[float, float]:
    """Two systems on the same inputs, e.g. Δu and α of the self-tuning controller.

    Equal to ``(eval_uniform_grid(x1, x2, rules_a, lims_a), eval_uniform_grid(x1, x2,
    rules_b, lims_b))``; when both systems partition the same input universes into the same
    grid (as the paper's two do) the inputs are located once and only the rule look-ups and
    the output integration are done twice.
    """
    if x1 != x1 or x2 != x2:
        return np.nan, np.nan
    k1, k2, f1, f2 = _cell(x1, x2, rules_a.shape[1], rules_a.shape[0], lims_a)
    ya = _centroid(k1, k2, f1, f2, rules_a, lims_a)
    if (rules_b.shape[0] == rules_a.shape[0] and rules_b.shape[1] == rules_a.shape[1]
            and lims_b[0] == lims_a[0] and lims_b[1] == lims_a[1]
            and lims_b[2] == lims_a[2] and lims_b[3] == lims_a[3]):
        return ya, _centroid(k1, k2, f1, f2, rules_b, lims_b)
    k1, k2, f1, f2 = _cell(x1, x2, rules_b.shape[1], rules_b.shape[0], lims_b)
    return ya, _centroid(k1, k2, f1, f2, rules_b, lims_b)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def eval_uniform_checked(x1: float, x2: float, rules: IntArray, lims: FloatArray) -> float:
    """As :func:`eval_uniform_grid`, but NaN whenever an input is not finite (NaN or ±inf).

    The scalar Python API calls this and turns a NaN result into one ``InputError``.
    """
    if not (abs(x1) < np.inf and abs(x2) < np.inf):
        return np.nan
    return eval_uniform_grid(x1, x2, rules, lims)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def eval_uniform_batch(
    x1: FloatArray, x2: FloatArray, rules: IntArray, lims: FloatArray, out: FloatArray
) -> int:
    """Fill ``out[i] = eval_uniform_grid(x1[i], x2[i], rules, lims)`` (1-D, one core).

    Returns
    -------
    int
        Index of the first point with a non-finite input or a NaN output (no rule fired and
        the default is NaN), or -1 if there is none: the caller validates with this number.
    """
    # x - x is 0 for a finite x and NaN otherwise: one running sum flags any bad point
    # without a branch in the loop; only then is the first one searched for
    flag = 0.0
    for i in range(out.shape[0]):
        a = x1[i]
        b = x2[i]
        v = eval_uniform_grid(a, b, rules, lims)
        out[i] = v
        flag += (a - a) + (b - b) + (v - v)
    if flag == 0.0:
        return -1
    for i in range(out.shape[0]):
        if not (abs(x1[i]) < np.inf and abs(x2[i]) < np.inf) or out[i] != out[i]:
            out[i] = np.nan
            return i
    return -1
