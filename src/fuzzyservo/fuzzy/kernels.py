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

from collections.abc import Callable
from typing import Any, cast

import numba
import numba.extending
import numpy as np
from numba.core import cgutils

from .._jit import data_pointer, kernel
from .._typing import FloatArray, IntArray

__all__ = [
    "LIMS_SIZE",
    "GridTable",
    "data_pointer",
    "eval_uniform_batch",
    "eval_uniform_checked",
    "eval_uniform_grid",
    "eval_uniform_pair",
    "grid_eval",
    "grid_pair",
    "grid_table",
    "insort",
    "segment_integrals",
]

#: Length of the ``lims`` vector: lo1, hi1, lo2, hi2, out_lo, out_hi, n_out, default.
LIMS_SIZE = 8
_SIXTH = 1.0 / 6.0

#: A rule table in the form the inlined kernels take (:func:`grid_table`): the rules' data
#: pointer, shape and strides, then the eight ``lims`` (``n_out`` as an int).
GridTable = tuple[Any, int, int, int, int, float, float, float, float, float, float, int, float]


@kernel(inline=True)
def insort(buf: FloatArray, n: int, y: float) -> int:
    """Insert y into the sorted buf[:n] (room for one more); return n + 1 (the exact
    evaluators' breakpoint lists, a handful of values each)."""
    i = n
    while i > 0 and buf[i - 1] > y:
        buf[i] = buf[i - 1]
        i -= 1
    buf[i] = y
    return n + 1


@kernel(inline=True, error_model="numpy")
def _edge_terms(a: float) -> tuple[float, float, float]:
    """The powers of a clip height the segment integrals use: ``(0.5 a) a``, ``a a`` and
    ``(a a) a`` (computed once per height: adjacent segments share their common end's)."""
    aa = a * a
    return 0.5 * a * a, aa, aa * a


@kernel(inline=True, error_model="numpy")
def _segment(a: float, pa: float, qa: float, ca: float, b: float, pb: float, cb: float
             ) -> tuple[float, float]:
    """:func:`segment_integrals` from the heights and their :func:`_edge_terms`."""
    # max(F, R) = F + R - min(F, R) with F = min(a, 1 - s), R = min(b, s); min(F, R) is the
    # trapezoid min(m, s, 1 - s), m = min(a, b, 1/2), symmetric about s = 1/2 (area m - m^2)
    m = min(a, b, 0.5)
    tm = m - m * m
    area = a - pa + b - pb - tm
    moment = 0.5 * (a - qa + b - tm) + (ca - cb) * _SIXTH
    return area, moment


@kernel(inline=True, error_model="numpy")
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
        Integral of g(s) and of s g(s) over [0, 1] (dimensionless):
        ``a - a²/2 + b - b²/2 - (m - m²)`` and ``(a - a² + b - (m - m²))/2 + (a³ - b³)/6``,
        m = min(a, b, 1/2).
    """
    pa, qa, ca = _edge_terms(a)
    pb, _, cb = _edge_terms(b)
    return _segment(a, pa, qa, ca, b, pb, cb)


#: Output labels up to which the clip heights are gathered in a stack buffer (more: found by
#: scanning the four rules for each label, as before).
_HEIGHTS_CAP = 16


@numba.extending.intrinsic
def _height_buffer_intrinsic(typingctx: Any) -> Any:
    """A buffer of ``_HEIGHTS_CAP`` floats on the stack of the compiled function it is inlined
    into (allocated once per call of that function, in its entry block)."""
    sig = numba.types.CPointer(numba.types.float64)()  # type: ignore[no-untyped-call]

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return cgutils.alloca_once(  # type: ignore[no-untyped-call]
            builder, context.get_value_type(numba.types.float64), size=_HEIGHTS_CAP)

    return sig, codegen


#: The intrinsics as plain callables for the type checker (numba sees the same objects).
_height_buffer = cast(Callable[[], Any], _height_buffer_intrinsic)


@kernel(inline=True)
def grid_table(rules: IntArray, lims: FloatArray) -> GridTable:
    """A rule table and its ``lims`` as one value the inlined kernels take: ``(rules pointer,
    n2, n1, row stride, column stride, lo1, hi1, lo2, hi2, out_lo, out_hi, n_out, default)``
    (strides in elements; ``n_out = int(lims[6])``). The arrays must outlive it."""
    return (data_pointer(rules), rules.shape[0], rules.shape[1],
            rules.strides[0] // rules.itemsize, rules.strides[1] // rules.itemsize,
            lims[0], lims[1], lims[2], lims[3], lims[4], lims[5], int(lims[6]), lims[7])


@kernel(inline=True, error_model="numpy")
def _cell(x1: float, x2: float, tab: GridTable) -> tuple[int, int, float, float]:
    """Clip the inputs and locate them: grid cell (k1, k2) and fractions (f1, f2) in it."""
    n2 = tab[1]
    n1 = tab[2]
    lo1 = tab[5]
    hi1 = tab[6]
    lo2 = tab[7]
    hi2 = tab[8]
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


@kernel(inline=True, error_model="numpy")
def _height(
    j: int, la: int, wa: float, lb: int, wb: float, lc: int, wc: float, ld: int, wd: float
) -> float:
    """Clip height of output label j: the largest strength of the four rules naming it."""
    return max(
        max(wa if la == j else 0.0, wb if lb == j else 0.0),
        max(wc if lc == j else 0.0, wd if ld == j else 0.0),
    )


@kernel(inline=True, error_model="numpy")
def _accumulate(ha: float, pa: float, qa: float, ca: float, hb: float, fj: float, area: float,
                parea: float, moment: float
                ) -> tuple[float, float, float, float, float, float]:
    """Add segment j (clip heights ``ha``, ``hb``; ``ha``'s :func:`_edge_terms`) to the
    sums of the centroid, unless both heights are 0; returns ``hb``'s terms and the sums."""
    if hb > 0.0:
        pb, qb, cb = _edge_terms(hb)
        if ha > 0.0:
            ar, mo = _segment(ha, pa, qa, ca, hb, pb, cb)  # segment_integrals(ha, hb)
        else:
            # _segment with a = 0 (m = tm = pa = qa = ca = 0, and adding or subtracting a
            # zero changes none of the non-zero partial results; 0 - cb is -cb exactly): the
            # same bits, fewer operations
            ar = hb - pb
            mo = 0.5 * hb - cb * _SIXTH
        area += ar
        parea += fj * ar
        moment += mo
    else:
        pb = 0.0  # a zero height's terms (never used: the next segment starts at 0)
        qb = 0.0
        cb = 0.0
        if ha > 0.0:
            # _segment with b = 0 (likewise)
            ar = ha - pa
            mo = 0.5 * (ha - qa) + ca * _SIXTH
            area += ar
            parea += fj * ar
            moment += mo
    return pb, qb, cb, area, parea, moment


@kernel(inline=True, error_model="numpy")
def _centroid(k1: int, k2: int, f1: float, f2: float, tab: GridTable) -> float:
    """Exact centroid of the aggregate of the (at most) four rules of cell (k1, k2)."""
    rp = tab[0]
    rs = tab[3]
    cs = tab[4]
    g1 = 1.0 - f1
    g2 = 1.0 - f2
    # the (at most) four rules that fire, with their min-AND strengths
    i00 = k2 * rs + k1 * cs
    la = rp[i00]
    wa = min(g1, g2)
    lb = rp[i00 + cs]
    wb = min(f1, g2)
    lc = rp[i00 + rs]
    wc = min(g1, f2)
    ld = rp[i00 + rs + cs]
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
    n_out = tab[11]
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
    j = max(lmin - 1, 0)
    jend = min(lmax, n_out - 2)
    area = 0.0
    parea = 0.0
    moment = 0.0
    fj = float(j)  # j as a float, counted alongside (exact): no conversion per segment
    if n_out < _HEIGHTS_CAP:
        # the clip heights of all labels gathered once into a buffer (four stores) rather
        # than by scanning the four rules for every label: the same maxima
        h = _height_buffer()
        for i in range(_HEIGHTS_CAP):  # a fixed count: stores in line, not a call to memset
            h[i] = 0.0
        if wa > 0.0:
            h[la] = wa
        if wb > 0.0:
            h[lb] = max(h[lb], wb)
        if wc > 0.0:
            h[lc] = max(h[lc], wc)
        if wd > 0.0:
            h[ld] = max(h[ld], wd)
        ha = h[j]
        pa, qa, ca = _edge_terms(ha)
        while j <= jend:
            hb = h[j + 1]
            pa, qa, ca, area, parea, moment = _accumulate(ha, pa, qa, ca, hb, fj, area,
                                                          parea, moment)
            ha = hb
            j += 1
            fj += 1.0
    else:
        ha = _height(j, la, wa, lb, wb, lc, wc, ld, wd)
        pa, qa, ca = _edge_terms(ha)
        while j <= jend:
            hb = _height(j + 1, la, wa, lb, wb, lc, wc, ld, wd)
            pa, qa, ca, area, parea, moment = _accumulate(ha, pa, qa, ca, hb, fj, area,
                                                          parea, moment)
            ha = hb
            j += 1
            fj += 1.0
    if area <= 0.0:
        return tab[12]
    lo = tab[9]
    # centroid = sum(p_j A_j + d M_j) / sum(A_j), p_j = lo + j d, d = (hi - lo) / (n_out - 1)
    # (the factor d of dy cancels)
    return lo + (tab[10] - lo) * (parea + moment) / (area * (n_out - 1))


@kernel(inline=True, error_model="numpy")
def grid_eval(x1: float, x2: float, tab: GridTable) -> float:
    """:func:`eval_uniform_grid` on a :func:`grid_table` (inlined by the compiled loops)."""
    if x1 != x1 or x2 != x2:
        return np.nan
    k1, k2, f1, f2 = _cell(x1, x2, tab)
    return _centroid(k1, k2, f1, f2, tab)


@kernel(inline=True, error_model="numpy")
def grid_pair(x1: float, x2: float, tab_a: GridTable, tab_b: GridTable) -> tuple[float, float]:
    """:func:`eval_uniform_pair` on two :func:`grid_table` values (inlined by the loops)."""
    if x1 != x1 or x2 != x2:
        return np.nan, np.nan
    k1, k2, f1, f2 = _cell(x1, x2, tab_a)
    ya = _centroid(k1, k2, f1, f2, tab_a)
    if (tab_b[1] == tab_a[1] and tab_b[2] == tab_a[2] and tab_b[5] == tab_a[5]
            and tab_b[6] == tab_a[6] and tab_b[7] == tab_a[7] and tab_b[8] == tab_a[8]):
        return ya, _centroid(k1, k2, f1, f2, tab_b)
    k1, k2, f1, f2 = _cell(x1, x2, tab_b)
    return ya, _centroid(k1, k2, f1, f2, tab_b)


@kernel(error_model="numpy")
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
    return grid_eval(x1, x2, grid_table(rules, lims))


@kernel(error_model="numpy")
def eval_uniform_pair(x1: float, x2: float, rules_a: IntArray, lims_a: FloatArray,
                      rules_b: IntArray, lims_b: FloatArray) -> tuple[float, float]:
    """Two systems on the same inputs, e.g. Δu and α of the self-tuning controller.

    Equal to ``(eval_uniform_grid(x1, x2, rules_a, lims_a), eval_uniform_grid(x1, x2,
    rules_b, lims_b))``; when both systems partition the same input universes into the same
    grid (as the paper's two do) the inputs are located once and only the rule look-ups and
    the output integration are done twice.
    """
    return grid_pair(x1, x2, grid_table(rules_a, lims_a), grid_table(rules_b, lims_b))


@kernel(error_model="numpy")
def eval_uniform_checked(x1: float, x2: float, rules: IntArray, lims: FloatArray) -> float:
    """As :func:`eval_uniform_grid`, but NaN whenever an input is not finite (NaN or ±inf).

    The scalar Python API calls this and turns a NaN result into one ``InputError``.
    """
    if not (abs(x1) < np.inf and abs(x2) < np.inf):
        return np.nan
    return eval_uniform_grid(x1, x2, rules, lims)


@kernel(error_model="numpy")
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
