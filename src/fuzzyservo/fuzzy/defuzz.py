"""Defuzzification of general Mamdani systems: exact, sampled, bisector, mean of maxima.

For piecewise-linear output sets (triangles, trapezoids, shoulders) the aggregated output under
min or product implication and max or bounded-sum aggregation is piecewise linear. The kernel
below builds it exactly, point by point: between consecutive vertices of the output MFs every
MF is one line; the aggregate can only bend where two of the lines {MF_j, height_j} cross (or,
for the bounded sum, where the sum reaches 1), so those crossings are added as breakpoints and
each piece is integrated exactly (area and first moment of a linear piece). The bisector and
the mean of maxima are read off the same exact pieces. Gaussian or bell outputs are integrated
by ``scipy.integrate.quad`` to the spec's ``quad_tol``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .._jit import kernel
from .._typing import FloatArray, IntArray
from ..errors import ParameterError

if TYPE_CHECKING:
    from .mamdani import MamdaniSystem
    from .rulebase import LinguisticVariable

__all__ = ["centroid_sampled", "check_output", "evaluate_general", "pl_tables"]

_IMPL = {"min": 0, "product": 1}
_AGG = {"max": 0, "bounded_sum": 1}
_DEF = {"exact_centroid": 0, "bisector": 1, "mean_of_maxima": 2}


def check_output(output: LinguisticVariable) -> None:
    """Raise ``ParameterError`` if an output term has no support on the output universe."""
    lo, hi = output.universe
    y = np.linspace(lo, hi, 100_001)
    for label, mf in output.terms:
        if float(np.max(mf(y))) <= 0.0:
            raise ParameterError(
                f"output term {label!r} is zero on the output universe ({lo!r}, {hi!r})"
            )


def pl_tables(output: LinguisticVariable) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Breakpoints and per-interval lines of piecewise-linear output MFs on the universe.

    Returns
    -------
    bp : ndarray (K + 1,)
        Sorted breakpoints from lo to hi [unit of the output].
    slope, icpt : ndarray (K, n_terms)
        MF j equals ``icpt[k, j] + slope[k, j] * y`` on the open interval (bp[k], bp[k+1]).
    """
    lo, hi = output.universe
    pts = {lo, hi}
    for _, mf in output.terms:
        verts = mf.vertices
        if verts is None:
            raise ParameterError("pl_tables needs piecewise-linear output terms")
        pts.update(x for x, _ in verts if lo < x < hi)
    # merge breakpoints closer than rounding (e.g. -1 + 3 * (2/3) and 1): an interval that
    # thin has no room for a line of its own
    tol = 1e-12 * (hi - lo)
    merged: list[float] = []
    for x in sorted(pts):
        if merged and x - merged[-1] <= tol:
            merged[-1] = hi if x == hi else merged[-1]
            continue
        merged.append(x)
    merged[0] = lo
    bp = np.array(merged, dtype=np.float64)
    k = bp.shape[0] - 1
    n = len(output.terms)
    slope = np.empty((k, n))
    icpt = np.empty((k, n))
    y1 = bp[:-1] + (bp[1:] - bp[:-1]) / 3.0
    y2 = bp[:-1] + 2.0 * (bp[1:] - bp[:-1]) / 3.0
    for j, (_, mf) in enumerate(output.terms):
        f1, f2 = mf(y1), mf(y2)
        slope[:, j] = (f2 - f1) / (y2 - y1)
        icpt[:, j] = f1 - slope[:, j] * y1
    return bp, slope, icpt


@kernel
def _agg_at(y: float, n: int, c: FloatArray, m: FloatArray, h: FloatArray,
            impl: int, agg: int) -> tuple[float, float]:
    """(aggregate, unclamped sum) at y of the n active lines c + m y with heights h."""
    best = 0.0
    total = 0.0
    for i in range(n):
        line = c[i] + m[i] * y
        if line < 0.0:
            line = 0.0
        f = min(h[i], line) if impl == 0 else h[i] * line
        total += f
        if f > best:
            best = f
    if agg == 0:
        return best, best
    return min(1.0, total), total


@kernel
def _insort(buf: FloatArray, n: int, y: float) -> int:
    """Insert y into the sorted buf[:n]; return the new length."""
    i = n
    while i > 0 and buf[i - 1] > y:
        buf[i] = buf[i - 1]
        i -= 1
    buf[i] = y
    return n + 1


@kernel
def _pl_point(w: FloatArray, rule_out: IntArray, bp: FloatArray, slope: FloatArray,
              icpt: FloatArray, impl: int, agg: int, mode: int,
              hts: FloatArray, lab: IntArray, c: FloatArray, m: FloatArray, h: FloatArray,
              cand: FloatArray, su: FloatArray, sv: FloatArray, gu: FloatArray,
              gv: FloatArray) -> float:
    """Defuzzified output of one point (NaN if the aggregate is empty)."""
    n_terms = slope.shape[1]
    # the items whose sets are aggregated: one per label (max) or one per rule (bounded sum)
    n_items = 0
    if agg == 0:
        for j in range(n_terms):
            hts[j] = 0.0
        for r in range(w.shape[0]):
            if w[r] > hts[rule_out[r]]:
                hts[rule_out[r]] = w[r]
        for j in range(n_terms):
            if hts[j] > 0.0:
                lab[n_items] = j
                h[n_items] = hts[j]
                n_items += 1
    else:
        for r in range(w.shape[0]):
            if w[r] > 0.0:
                lab[n_items] = rule_out[r]
                h[n_items] = w[r]
                n_items += 1
    n_seg = 0
    for k in range(bp.shape[0] - 1):
        p = bp[k]
        q = bp[k + 1]
        na = 0
        for i in range(n_items):
            j = lab[i]
            mm = slope[k, j]
            cc = icpt[k, j]
            if mm == 0.0 and cc <= 0.0:
                continue
            c[na] = cc
            m[na] = mm
            h[n_items + na] = h[i]
            na += 1
        if na == 0:
            continue
        hh = h[n_items:n_items + na]
        nc = 0
        cand[0] = p
        cand[1] = q
        nc = 2
        for i in range(na):
            # where line i meets 0, its own height, and (max) the other lines and heights
            if m[i] != 0.0:
                for level in (0.0, hh[i]):
                    y = (level - c[i]) / m[i]
                    if p < y < q:
                        nc = _insort(cand, nc, y)
            if agg == 0:
                for jj in range(na):
                    if jj == i:
                        continue
                    if impl == 0:
                        if m[i] != 0.0:
                            y = (hh[jj] - c[i]) / m[i]
                            if p < y < q:
                                nc = _insort(cand, nc, y)
                        if jj > i and m[i] != m[jj]:
                            y = (c[jj] - c[i]) / (m[i] - m[jj])
                            if p < y < q:
                                nc = _insort(cand, nc, y)
                    elif jj > i:
                        di = hh[i] * m[i] - hh[jj] * m[jj]
                        if di != 0.0:
                            y = (hh[jj] * c[jj] - hh[i] * c[i]) / di
                            if p < y < q:
                                nc = _insort(cand, nc, y)
        for t in range(nc - 1):
            u = cand[t]
            v = cand[t + 1]
            if v <= u:
                continue
            # one-sided values from the lines of this interval (exact at vertical MF edges)
            au, tu = _agg_at(u, na, c, m, hh, impl, agg)
            av, tv = _agg_at(v, na, c, m, hh, impl, agg)
            if agg == 1 and (tu - 1.0) * (tv - 1.0) < 0.0:
                ys = u + (1.0 - tu) * (v - u) / (tv - tu)
                su[n_seg] = u
                sv[n_seg] = ys
                gu[n_seg] = au
                gv[n_seg] = 1.0
                n_seg += 1
                su[n_seg] = ys
                sv[n_seg] = v
                gu[n_seg] = 1.0
                gv[n_seg] = av
                n_seg += 1
            else:
                su[n_seg] = u
                sv[n_seg] = v
                gu[n_seg] = au
                gv[n_seg] = av
                n_seg += 1
    area = 0.0
    moment = 0.0
    gmax = 0.0
    for s in range(n_seg):
        u = su[s]
        v = sv[s]
        area += 0.5 * (v - u) * (gu[s] + gv[s])
        moment += (v - u) * (u * (2.0 * gu[s] + gv[s]) + v * (gu[s] + 2.0 * gv[s])) / 6.0
        gmax = max(gmax, gu[s], gv[s])
    if area <= 0.0:
        return np.nan
    if mode == 0:
        return moment / area
    if mode == 1:
        half = 0.5 * area
        acc = 0.0
        for s in range(n_seg):
            u = su[s]
            v = sv[s]
            a = gu[s]
            b = gv[s]
            seg = 0.5 * (v - u) * (a + b)
            if acc + seg >= half and seg > 0.0:
                need = half - acc
                length = v - u
                slope_s = (b - a) / length
                # a t + slope t^2 / 2 = need
                if abs(slope_s) * length < 1e-14 * max(a, 1e-300):
                    return u + need / a
                disc = a * a + 2.0 * slope_s * need
                t_root = (-a + math.sqrt(max(disc, 0.0))) / slope_s
                return u + min(max(t_root, 0.0), length)
            acc += seg
        return sv[n_seg - 1]
    # mean of maxima: plateaus at gmax weighted by length, else mean of the maximal vertices
    tol = 1e-12
    plen = 0.0
    pmom = 0.0
    for s in range(n_seg):
        if gu[s] >= gmax - tol and gv[s] >= gmax - tol:
            plen += sv[s] - su[s]
            pmom += 0.5 * (sv[s] * sv[s] - su[s] * su[s])
    if plen > 0.0:
        return pmom / plen
    # no plateau: the mean of the distinct points where the maximum is reached
    cnt = 0
    tot = 0.0
    last = -np.inf
    for s in range(n_seg):
        if gu[s] >= gmax - tol and su[s] > last:
            cnt += 1
            tot += su[s]
            last = su[s]
        if gv[s] >= gmax - tol and sv[s] > last:
            cnt += 1
            tot += sv[s]
            last = sv[s]
    return tot / cnt


@kernel
def _pl_batch(w: FloatArray, rule_out: IntArray, bp: FloatArray, slope: FloatArray,
              icpt: FloatArray, impl: int, agg: int, mode: int, out: FloatArray) -> None:
    """out[i] = defuzzified exact piecewise-linear aggregate for the strengths w[i, :]."""
    n_terms = slope.shape[1]
    n_items = max(n_terms, w.shape[1])
    n_cand = 2 + 2 * n_items + 3 * n_items * n_items
    n_seg = 2 * (bp.shape[0] - 1) * n_cand
    hts = np.empty(n_terms)
    lab = np.empty(n_items, dtype=np.int64)
    c = np.empty(n_items)
    m = np.empty(n_items)
    h = np.empty(2 * n_items)
    cand = np.empty(n_cand)
    su = np.empty(n_seg)
    sv = np.empty(n_seg)
    gu = np.empty(n_seg)
    gv = np.empty(n_seg)
    for i in range(w.shape[0]):
        out[i] = _pl_point(w[i], rule_out, bp, slope, icpt, impl, agg, mode,
                           hts, lab, c, m, h, cand, su, sv, gu, gv)


@kernel
def _sampled_batch(w: FloatArray, rule_out: IntArray, grid: FloatArray, mf: FloatArray,
                   impl: int, agg: int, mode: int, out: FloatArray) -> None:
    """Sampled aggregate on ``grid``: centroid by the trapezoid rule (mode 0), bisector (1),
    mean of the maximal samples (2); NaN if empty."""
    ns = grid.shape[0]
    g = np.empty(ns)
    for i in range(w.shape[0]):
        for s in range(ns):
            g[s] = 0.0
        for r in range(w.shape[1]):
            wr = w[i, r]
            if wr <= 0.0:
                continue
            j = rule_out[r]
            for s in range(ns):
                f = min(wr, mf[j, s]) if impl == 0 else wr * mf[j, s]
                if agg == 0:
                    if f > g[s]:
                        g[s] = f
                else:
                    g[s] = min(1.0, g[s] + f)
        area = 0.0
        moment = 0.0
        gmax = 0.0
        for s in range(ns - 1):
            dy = grid[s + 1] - grid[s]
            area += 0.5 * dy * (g[s] + g[s + 1])
            moment += 0.5 * dy * (g[s] * grid[s] + g[s + 1] * grid[s + 1])
        for s in range(ns):
            gmax = max(gmax, g[s])
        if area <= 0.0:
            out[i] = np.nan
        elif mode == 0:
            out[i] = moment / area
        elif mode == 1:
            acc = 0.0
            res = grid[ns - 1]
            for s in range(ns - 1):
                seg = 0.5 * (grid[s + 1] - grid[s]) * (g[s] + g[s + 1])
                if acc + seg >= 0.5 * area and seg > 0.0:
                    res = grid[s] + (0.5 * area - acc) / seg * (grid[s + 1] - grid[s])
                    break
                acc += seg
            out[i] = res
        else:
            tot = 0.0
            cnt = 0
            for s in range(ns):
                if g[s] >= gmax:
                    tot += grid[s]
                    cnt += 1
            out[i] = tot / cnt


def centroid_sampled(universe: FloatArray, mu: FloatArray) -> FloatArray:
    """Centroid along the last axis by the trapezoid rule; universe (n,), mu (..., n) -> (...).

    Returns NaN where the area is zero (the caller decides: default output or error).
    """
    area = np.trapezoid(mu, universe, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        res = np.asarray(np.trapezoid(mu * universe, universe, axis=-1) / area)
    return np.where(area > 0.0, res, np.nan)


def _quad_centroid(system: MamdaniSystem, w: FloatArray) -> float:
    """Centroid of a smooth (Gaussian / bell) aggregate by adaptive quadrature.

    The aggregate is smooth except where the active piece changes (which set is largest,
    whether it is clipped, whether a bounded sum saturates). Those points are located on a
    2001-point scan and refined by bisection to rounding, and ``quad`` integrates each smooth
    piece to the spec's ``quad_tol``.
    """
    from scipy import integrate  # only for Gaussian / bell outputs: it takes 0.5 s to import

    out = system.output
    lo, hi = out.universe
    spec = system.spec
    rule_out = system.rule_outputs
    mfs = [mf for _, mf in out.terms]
    active = [(float(w[r]), mfs[int(rule_out[r])]) for r in range(w.shape[0]) if w[r] > 0.0]
    if not active:
        return math.nan
    hs = np.array([h for h, _ in active])
    clip = spec.implication == "min"

    def parts(y: FloatArray) -> tuple[FloatArray, FloatArray]:
        f = np.stack([mf(y) for _, mf in active])  # (n_active, len(y))
        return (np.minimum(hs[:, None], f) if clip else hs[:, None] * f), f

    def g(y: FloatArray) -> FloatArray:
        imp, _ = parts(y)
        if spec.aggregation == "max":
            return np.max(imp, axis=0)
        return np.minimum(1.0, np.sum(imp, axis=0))

    def piece(y: FloatArray) -> IntArray:
        imp, f = parts(y)
        code = (f >= hs[:, None]).astype(np.int64) if clip else np.zeros(imp.shape, np.int64)
        key = np.sum(code * (2 ** np.arange(len(active)))[:, None], axis=0)
        if spec.aggregation == "max":
            return np.asarray(key * (len(active) + 1) + np.argmax(imp, axis=0))
        return np.asarray(key * 2 + (np.sum(imp, axis=0) >= 1.0))

    grid = np.linspace(lo, hi, 2001)
    ids = piece(grid)
    cuts = [lo]
    for k in np.flatnonzero(ids[1:] != ids[:-1]):
        a, b = float(grid[k]), float(grid[k + 1])
        ia = ids[k]
        for _ in range(60):
            mid = 0.5 * (a + b)
            if mid in (a, b):
                break
            if piece(np.array([mid]))[0] == ia:
                a = mid
            else:
                b = mid
        cuts.append(0.5 * (a + b))
    cuts.append(hi)
    tol = spec.quad_tol
    area = 0.0
    mom = 0.0
    for a, b in zip(cuts, cuts[1:], strict=False):
        if b <= a:
            continue
        area += integrate.quad(lambda y: float(g(np.array([y]))[0]), a, b,
                               epsabs=tol, epsrel=tol, limit=200)[0]
        mom += integrate.quad(lambda y: y * float(g(np.array([y]))[0]), a, b,
                              epsabs=tol, epsrel=tol, limit=200)[0]
    return mom / area if area > 0.0 else math.nan


def evaluate_general(system: MamdaniSystem, e: FloatArray, de: FloatArray,
                     out: FloatArray) -> None:
    """Fill ``out`` for finite 1-D inputs ``e``, ``de``; NaN where empty and no default."""
    (v1, v2), output = system.inputs, system.output
    x1 = np.clip(e, *v1.universe)
    x2 = np.clip(de, *v2.universe)
    w = np.ascontiguousarray(system.rule_strengths(x1, x2))
    spec = system.spec
    rule_out = system.rule_outputs
    impl = _IMPL[spec.implication]
    agg = _AGG[spec.aggregation]
    pl = all(mf.vertices is not None for _, mf in output.terms)
    if spec.defuzz != "sampled_centroid" and pl:
        bp, slope, icpt = pl_tables(output)
        _pl_batch(w, rule_out, bp, slope, icpt, impl, agg, _DEF[spec.defuzz], out)
    elif spec.defuzz == "exact_centroid":
        for i in range(w.shape[0]):
            out[i] = _quad_centroid(system, w[i])
    else:
        grid = np.linspace(*output.universe, spec.samples)
        mf = np.stack([mf(grid) for _, mf in output.terms])
        mode = {"sampled_centroid": 0, "bisector": 1, "mean_of_maxima": 2}[spec.defuzz]
        _sampled_batch(w, rule_out, grid, mf, impl, agg, mode, out)
    if spec.default is not None:
        out[np.isnan(out)] = spec.default
