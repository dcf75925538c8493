"""Fast exact path of the general evaluator for rule tables over fuzzy partitions.

Most controllers' systems have one shape: a complete rule table (every rule an AND of one plain
clause per input), continuous piecewise-linear input terms, and piecewise-linear output terms
of which at most two are non-zero anywhere (a fuzzy partition: the paper's 7 x 7 tables, the
usual 3 x 3, 5 x 5 and 7 x 7 controllers, with triangles or trapezoids, even or uneven), min or
product AND and implication, max aggregation and centroid defuzzification. For these,
:func:`fuzzyservo.fuzzy.general.compile_system` adds the tables built here, and
:func:`eval_partition` replaces the general algorithm (same result to rounding: the same exact
integration, fewer steps):

- each input is located by bisection among its terms' vertices; on that interval only the terms
  not zero there are evaluated, from their line (exact at the vertices);
- the rules that can fire are the cells of the table at the non-zero terms' combinations;
- on each interval between the output terms' vertices at most two implied sets,
  min(a, F) and min(b, R) (or a F and b R), are non-zero, F and R linear; their maximum bends
  only where F = a, R = b, F = R, F = b or R = a (a F = b R for the product): at most five
  points, each piece linear and integrated in closed form.

Tables (``pi`` integers, ``pf`` floats; offsets relative to the start of each):

    pi: [n_in, n_out, grid_off, in_off[n_in], out_off[n_out]]
    input i at in_off:  [n_bp, xb_off(pf), n_regions, region (start, count) ..., entries term ...]
                        entry floats in pf: slope, intercept (at entry_f_off + 2 k)
    output o at out_off:[n_int, bp_off(pf), n_terms, line_off(pf), pair (j1, j2) per interval,
                         support (k0, k1) per term]
                        lines in pf: (slope, intercept) of j1 then of j2 per interval
    grid at grid_off:   [stride per input, (start, count) per cell, rule ... ]
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from .._typing import FloatArray, IntArray
from .kernels import insort, segment_integrals
from .system import And, FuzzySystem, Is, Term

__all__ = ["eval_partition", "partition_tables"]

#: Most cells of the rule table the fast path indexes.
MAX_CELLS = 1 << 16


def _continuous_pl(t: Term) -> bool:
    """A piecewise-linear term without a jump (so that one line per interval is exact at its
    ends too)."""
    s, p = t.shape, t.params
    if s == "triangle":
        return p[0] < p[1] < p[2]
    if s == "trapezoid":
        return (p[0] < p[1] or p[0] == -math.inf) and (p[2] < p[3] or p[3] == math.inf)
    if s == "ramp":
        return p[0] != p[1]
    if s == "discrete":
        xs = p[0::2]
        return all(b > a for a, b in zip(xs, xs[1:], strict=False))
    return False


def _value(t: Term, x: float) -> float:
    """Exact value of a continuous piecewise-linear term at x (from its vertices)."""
    v = t.vertices
    assert v is not None
    xs = [a for a, _ in v]
    ys = [b for _, b in v]
    if x <= xs[0]:
        return ys[0]
    if x >= xs[-1]:
        return ys[-1]
    for i in range(len(xs) - 1):
        if xs[i] <= x <= xs[i + 1]:
            if x == xs[i]:
                return ys[i]
            if x == xs[i + 1]:
                return ys[i + 1]
            return ys[i] + (ys[i + 1] - ys[i]) * (x - xs[i]) / (xs[i + 1] - xs[i])
    return ys[-1]


def _regions(terms: tuple[Term, ...]) -> tuple[list[float], list[list[tuple[int, float, float]]]]:
    """Vertices and, per region (left of the first, between consecutive, right of the last),
    the (term, slope, intercept) of every term not identically zero there."""
    xb = sorted({x for t in terms for x, _ in (t.vertices or ()) if math.isfinite(x)})
    regions: list[list[tuple[int, float, float]]] = []
    edges = [-math.inf, *xb, math.inf]
    for r in range(len(edges) - 1):
        p, q = edges[r], edges[r + 1]
        entries = []
        for j, t in enumerate(terms):
            if math.isinf(p) or math.isinf(q):
                x0 = q if math.isinf(p) else p
                v = _value(t, x0)
                if v > 0.0:
                    entries.append((j, 0.0, v))
                continue
            v0, v1 = _value(t, p), _value(t, q)
            if v0 <= 0.0 and v1 <= 0.0:
                continue
            m = (v1 - v0) / (q - p)
            entries.append((j, m, v0 - m * p))
        regions.append(entries)
    return xb, regions


def partition_tables(system: FuzzySystem, out_lines: list[tuple[np.ndarray, np.ndarray,
                                                                 np.ndarray]]
                     ) -> tuple[list[int], list[float]] | None:
    """The fast path's tables for ``system``, or None when it does not have the form.

    ``out_lines`` are the general evaluator's per-output (breakpoints, slope, intercept)
    tables (``general._pl_tables``), reused so that both paths integrate the same lines.
    Offsets inside the tables are relative to their own start.
    """
    if (system.kind != "mamdani" or system.aggregation != "max"
            or system.defuzzifier != "centroid" or not system.rules):
        return None
    n_in, n_out = len(system.inputs), len(system.outputs)
    for v in system.inputs:
        if not all(_continuous_pl(t) for t in v.terms):
            return None
    cells = 1
    strides = []
    for v in system.inputs:
        strides.append(cells)
        cells *= len(v.terms)
    if cells > MAX_CELLS:
        return None
    lists: list[list[int]] = [[] for _ in range(cells)]
    for r, rule in enumerate(system.rules):
        a = rule.antecedent
        clauses = [a] if isinstance(a, Is) else list(a.operands) if isinstance(a, And) else []
        if len(clauses) != n_in or not all(isinstance(c, Is) and not c.negated
                                           for c in clauses):
            return None
        if len({c.variable for c in clauses if isinstance(c, Is)}) != n_in:
            return None
        if len({c.variable for c in rule.consequents}) != len(rule.consequents):
            return None
        cell = sum(strides[c.variable] * c.term for c in clauses if isinstance(c, Is))
        lists[cell].append(r)
    pi: list[int] = [n_in, n_out, 0, 0 if system.and_op == "min" else 1,
                     0 if system.implication == "min" else 1, len(system.rules), 0, 0]
    pi += [0] * (n_in + n_out)
    pf: list[float] = [r.weight for r in system.rules]
    pi[7] = 0  # weights at pf[0:n_rules]
    pi[6] = len(pi)  # rule_out[r * n_out + o]: term of output o named by rule r, or -1
    for rule in system.rules:
        row = [-1] * n_out
        for c in rule.consequents:
            row[c.variable] = c.term
        pi += row
    for i, v in enumerate(system.inputs):
        xb, regions = _regions(v.terms)
        pi[8 + i] = len(pi)
        n_entries = sum(len(e) for e in regions)
        head = len(pi)
        xb_off = len(pf)
        pf += xb
        # equally spaced vertices (the usual partition): the region from one multiplication
        d = (xb[-1] - xb[0]) / (len(xb) - 1) if len(xb) > 1 else 0.0
        uniform = len(xb) > 1 and d > 0.0 and all(
            x == xb[0] + k * d for k, x in enumerate(xb))
        inv_off = len(pf)
        pf += [1.0 / d if uniform else 0.0]
        ent_f = len(pf)
        pi += [len(xb), xb_off, len(regions), ent_f, head + 6 + 2 * len(regions), inv_off]
        pi += [0] * (2 * len(regions))
        terms_at = len(pi)
        pi += [0] * n_entries
        k = 0
        for r, entries in enumerate(regions):
            pi[head + 6 + 2 * r] = k
            pi[head + 6 + 2 * r + 1] = len(entries)
            for j, m, icp in entries:
                pi[terms_at + k] = j
                pf += [m, icp]
                k += 1
    for o, v in enumerate(system.outputs):
        if not all(t.vertices is not None for t in v.terms):
            return None
        bp, slope, icpt = out_lines[o]
        n_int = bp.shape[0] - 1
        nz = (slope != 0.0) | (icpt > 0.0)
        if np.any(nz.sum(axis=1) > 2):
            return None
        pi[8 + n_in + o] = len(pi)
        bp_off = len(pf)
        pf += bp.tolist()
        line_off = len(pf)
        pairs: list[int] = []
        for k in range(n_int):
            js = [int(j) for j in np.flatnonzero(nz[k])] + [-1, -1]
            j1, j2 = js[0], js[1]
            p, q = float(bp[k]), float(bp[k + 1])
            # a unit pair: one term falls exactly from 1 to 0 across the interval and the
            # other rises from 0 to 1 (a partition's edges meeting at shared vertices): then
            # the closed form of fuzzy.kernels.segment_integrals applies
            unit = 0
            if j1 >= 0 and j2 >= 0:
                t1, t2 = v.terms[j1], v.terms[j2]
                ends = (_value(t1, p), _value(t1, q), _value(t2, p), _value(t2, q))
                if ends == (1.0, 0.0, 0.0, 1.0):
                    unit = 1
                elif ends == (0.0, 1.0, 1.0, 0.0):
                    unit = 1
                    j1, j2 = j2, j1
            pairs += [j1, j2, unit]
            for j in (j1, j2):
                pf += [float(slope[k, j]), float(icpt[k, j])] if j >= 0 else [0.0, 0.0]
        sup: list[int] = []
        for j in range(len(v.terms)):
            ks = np.flatnonzero(nz[:, j])
            sup += [int(ks[0]), int(ks[-1])] if ks.size else [1, 0]
        pi += [n_int, bp_off, len(v.terms), line_off, *pairs, *sup]
    pi[2] = len(pi)
    pi += strides
    start = len(pi) + 2 * cells
    idx: list[int] = []
    for lst in lists:
        pi += [start + len(idx), len(lst)]
        idx += lst
    pi += idx
    return pi, pf


def scratch_sizes(system: FuzzySystem) -> tuple[int, int]:
    """(floats, ints) of scratch :func:`eval_partition` needs."""
    n_in = len(system.inputs)
    t_in = sum(len(v.terms) for v in system.inputs)
    t_out = sum(len(v.terms) for v in system.outputs)
    return n_in + t_in + t_out + 8, 2 * n_in + t_in


@kernel(inline=True)
def _g2(y: float, m1: float, c1: float, a: float, m2: float, c2: float, b: float,
        impl: int) -> float:
    f1 = c1 + m1 * y
    f2 = c2 + m2 * y
    if f1 < 0.0:
        f1 = 0.0
    if f2 < 0.0:
        f2 = 0.0
    if impl == 0:
        # at a clip crossing c + m y is the clip height up to its rounding (eps |c|, a large
        # relative error for a weakly fired rule): take the height, so the plateau stays flat
        if abs(f1 - a) <= 1e-15 * (abs(c1) + abs(m1 * y)):
            f1 = a
        if abs(f2 - b) <= 1e-15 * (abs(c2) + abs(m2 * y)):
            f2 = b
        f1 = min(a, f1)
        f2 = min(b, f2)
    else:
        f1 = a * f1
        f2 = b * f2
    return f1 if f1 > f2 else f2


@kernel(inline=True)
def _interval(p: float, q: float, m1: float, c1: float, a: float, m2: float, c2: float,
              b: float, impl: int, ref: float, scale: float, cand: FloatArray
              ) -> tuple[float, float]:
    """Area and first moment of max(impl(a, F), impl(b, R)) on [p, q]; the moment of
    (y - ref) ``scale`` (1 / the range: no overflow for abscissae past 1e154)."""
    cand[0] = p
    n = 1
    if impl == 0:
        if m1 != 0.0:
            for level in (a, b):
                y = (level - c1) / m1
                if p < y < q:
                    n = insort(cand, n, y)
        if m2 != 0.0:
            for level in (a, b):
                y = (level - c2) / m2
                if p < y < q:
                    n = insort(cand, n, y)
        if m1 != m2 and a > 0.0 and b > 0.0:
            y = (c2 - c1) / (m1 - m2)
            if p < y < q:
                n = insort(cand, n, y)
    else:
        d = a * m1 - b * m2
        if d != 0.0 and a > 0.0 and b > 0.0:
            y = (b * c2 - a * c1) / d
            if p < y < q:
                n = insort(cand, n, y)
    cand[n] = q
    n += 1
    area = 0.0
    mom = 0.0
    u = cand[0]
    gu = _g2(u, m1, c1, a, m2, c2, b, impl)
    for k in range(1, n):
        v = cand[k]
        gv = _g2(v, m1, c1, a, m2, c2, b, impl)
        w = v - u
        if w > 0.0 and (gu > 0.0 or gv > 0.0):
            uu = (u - ref) * scale
            vv = (v - ref) * scale
            area += 0.5 * w * (gu + gv)
            mom += w * (uu * (2.0 * gu + gv) + vv * (gu + 2.0 * gv)) / 6.0
        u = v
        gu = gv
    return area, mom


@kernel
def eval_partition(x: FloatArray, pi: IntArray, pf: FloatArray, out: FloatArray,
                   work: FloatArray, iw: IntArray) -> None:
    """Centroid of every output at the (clipped) inputs ``x``; NaN where no rule fires.

    ``work`` and ``iw`` are scratch of :func:`scratch_sizes`."""
    n_in = pi[0]
    n_out = pi[1]
    gt = pi[2]
    and_op = pi[3]
    impl = pi[4]
    ro = pi[6]
    # the non-zero terms of each input: iw[i] of them, local indices at iw[pos...], values at
    # work[pos...]
    pos = n_in
    for i in range(n_in):
        base = pi[8 + i]
        n_bp = pi[base]
        xb_off = pi[base + 1]
        ent_f = pi[base + 3]
        terms_at = pi[base + 4]
        xv = x[i]
        inv = pf[pi[base + 5]]
        # region = number of vertices <= x (on a vertex: the interval right of it)
        if inv > 0.0:
            t = (xv - pf[xb_off]) * inv
            # compare before converting: int() of t >= 2**63 (an unclipped input of 1e19,
            # or inf) is undefined and crashed the process
            if t >= n_bp:
                lo = n_bp
            elif t >= 0.0:
                lo = int(t) + 1
                if lo > n_bp:
                    lo = n_bp
            else:
                lo = 0
            # t rounded near a vertex: settle on the exact comparison
            while lo > 0 and pf[xb_off + lo - 1] > xv:
                lo -= 1
            while lo < n_bp and pf[xb_off + lo] <= xv:
                lo += 1
        else:
            lo = 0
            hi = n_bp
            while lo < hi:
                mid = (lo + hi) >> 1
                if pf[xb_off + mid] <= xv:
                    lo = mid + 1
                else:
                    hi = mid
        k0 = pi[base + 6 + 2 * lo]
        cnt = 0
        for k in range(k0, k0 + pi[base + 6 + 2 * lo + 1]):
            mval = pf[ent_f + 2 * k] * xv + pf[ent_f + 2 * k + 1]
            if mval > 0.0:
                iw[pos + cnt] = pi[terms_at + k]
                work[pos + cnt] = mval
                cnt += 1
        if cnt == 0:
            for o in range(n_out):
                out[o] = np.nan
            return
        iw[i] = cnt
        pos += cnt
    # heights of the output terms: the largest strength of the fired rules naming each
    hoff = pos
    nh = 0
    for o in range(n_out):
        nh += pi[pi[8 + n_in + o] + 2]
    for k in range(nh):
        work[hoff + k] = 0.0
    dig = pos
    for i in range(n_in):
        iw[dig + i] = 0
    total = 1
    for i in range(n_in):
        total *= iw[i]
    for _ in range(total):
        cell = 0
        acc = 1.0
        p0 = n_in
        for i in range(n_in):
            d = iw[dig + i]
            cell += pi[gt + i] * iw[p0 + d]
            v = work[p0 + d]
            if and_op == 0:
                if v < acc:
                    acc = v
            else:
                acc *= v
            p0 += iw[i]
        ce = gt + n_in + 2 * cell
        st = pi[ce]
        for q in range(pi[ce + 1]):
            rr = pi[st + q]
            wr = acc * pf[rr]
            if wr > 0.0:
                ho = hoff
                for o in range(n_out):
                    j = pi[ro + rr * n_out + o]
                    if j >= 0 and wr > work[ho + j]:
                        work[ho + j] = wr
                    ho += pi[pi[8 + n_in + o] + 2]
        for i in range(n_in):  # next combination (odometer)
            iw[dig + i] += 1
            if iw[dig + i] < iw[i]:
                break
            iw[dig + i] = 0
    cand = work[hoff + nh:hoff + nh + 8]
    ho = hoff
    for o in range(n_out):
        ob = pi[8 + n_in + o]
        n_int = pi[ob]
        bp_off = pi[ob + 1]
        n_t = pi[ob + 2]
        line_off = pi[ob + 3]
        pairs = ob + 4
        sup = pairs + 3 * n_int
        k0 = n_int
        k1 = -1
        for j in range(n_t):
            if work[ho + j] > 0.0:
                k0 = min(k0, pi[sup + 2 * j])
                k1 = max(k1, pi[sup + 2 * j + 1])
        area = 0.0
        mom = 0.0
        ref = pf[bp_off]
        span = pf[bp_off + n_int] - ref
        scale = 1.0 / span
        for k in range(k0, k1 + 1):
            j1 = pi[pairs + 3 * k]
            j2 = pi[pairs + 3 * k + 1]
            a = work[ho + j1] if j1 >= 0 else 0.0
            b = work[ho + j2] if j2 >= 0 else 0.0
            if a <= 0.0 and b <= 0.0:
                continue
            if impl == 0 and pi[pairs + 3 * k + 2] == 1:
                p = pf[bp_off + k]
                w = pf[bp_off + k + 1] - p
                ar, mo = segment_integrals(a, b)
                area += w * ar
                mom += w * ((p - ref) * scale * ar + (w * scale) * mo)
                continue
            lo4 = line_off + 4 * k
            ar, mo = _interval(pf[bp_off + k], pf[bp_off + k + 1], pf[lo4], pf[lo4 + 1], a,
                               pf[lo4 + 2], pf[lo4 + 3], b, impl, ref, scale, cand)
            area += ar
            mom += mo
        out[o] = ref + span * (mom / area) if area > 0.0 else np.nan
        ho += n_t
