"""Independent references for :mod:`fuzzyservo.fuzzy.general` (test-only).

Two references, written from the model's definitions (``fuzzyservo.fuzzy.system``), sharing
no code with the evaluator:

- :func:`exact_outputs`: exact rational arithmetic (``fractions.Fraction``; every float is a
  rational). Memberships, rule strengths and the aggregate are Fractions. For an output with
  piecewise-linear terms and max, bounded-sum or sum aggregation the aggregate is split at every
  term vertex and at every candidate kink (pairwise crossings of the implied lines, of the lines
  with every clip height, with 0 and with 1; then, for bounded sum, where the sum reaches 1);
  between two candidates it is linear, which is checked exactly at a third point, so it is
  integrated exactly. Singleton outputs (COGS) and Sugeno outputs are exact sums.
- :func:`mp_outputs`: mpmath (30 digits, 20 for integrals only) for any system (smooth
  terms, probabilistic-sum aggregation): the aggregate is split at the terms' parameters and
  at the points where an implied set meets its clip height, the largest implied set changes, a
  bounded sum reaches 1 or a dsigmoid's sigmoids cross (a scan of 200 cells per interval of
  parameters, every change in a cell bisected to the working precision), and integrated piece
  by piece by Gauss-Legendre quadrature (``mpmath.quad``; a piece is halved until its error
  estimate is below 1e4 units of the working precision, so a missed bend costs time, not
  accuracy). The bisector: Newton steps on the running integral. The maxima: a dense search
  (60 samples per piece) refined by golden section around every local maximum of the samples;
  values within 1e3 units of the working precision of the largest tie; a run of consecutive
  candidates that all tie is one maximising point (or plateau), taken at the cuts it holds if
  any (a knot: a steep bell's flat top, or a plateau's end, is located exactly only there),
  else at its highest candidate.

Each output's true value is returned as an interval ``(lo, hi)`` (equal ends unless the value is
not unique: a bisector that falls in a gap of zero membership may be any point of the gap), or
None when the output has no value (no rule fires for it, or its aggregate has zero area): the
caller then expects the output's default. Output clamping and defaults are applied by
:func:`expected`.

Conventions (the model's, from ``fuzzyservo.fuzzy.system``):

- vertical edges: a triangle or trapezoid with a == b (or c == d) has its top value at the
  edge; a rectangle is closed; the value of a discrete term at a repeated x is that of the last
  point with that x (callers avoid input points there: the model does not define it);
- the aggregate is taken up to its values at finitely many points: its maximum and maximising
  set are those of its one-sided limits (a zero-width rectangle adds nothing);
- maxima ties: heights within ``TIE`` (relative) of the largest count as the largest. Float rule
  strengths carry rounding errors of about 1e-16, so a finer distinction than rounding is not a
  property of the system; 1e-12 leaves room for that and is far below any real difference in
  the tests' systems;
- mean of maximum: the mean of the maximising set by measure; the mean of its (distinct)
  points when it has measure zero;
- singleton (COGS) outputs: a singleton's implied height is the implication of the rule
  strength with the term's height (min: min(w, height); product: w height), aggregated per
  term, and the centroid is IEC 61131-7's sum over the terms, sum(x h) / sum(h) (two terms at
  the same x count twice, as in IEC's formula).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from decimal import Decimal, localcontext
from fractions import Fraction

import mpmath

from fuzzyservo.fuzzy.system import And, Expr, FuzzySystem, Is, Not, Or, Term, Variable

ZERO = Fraction(0)
ONE = Fraction(1)
#: Relative tie tolerance of the maxima (see the module docstring).
TIE = Fraction(1, 10**12)
PL_SHAPES = ("triangle", "trapezoid", "rectangle", "ramp", "discrete")

Interval = tuple[Fraction, Fraction]


# ---------------------------------------------------------------------------------------------
# memberships in Fractions (piecewise-linear shapes)


def pl_mu(term: Term, x: Fraction) -> Fraction:
    """Exact membership of a piecewise-linear term at x (height applied)."""
    s, p, h = term.shape, term.params, Fraction(term.height)
    if s == "triangle":
        a, b, c = (Fraction(v) for v in p)
        if x < a or x > c:
            return ZERO
        if x == b:
            return h
        return h * (x - a) / (b - a) if x < b else h * (c - x) / (c - b)
    if s == "trapezoid":
        b, c = Fraction(p[1]), Fraction(p[2])
        if b <= x <= c:
            return h
        if x < b:
            if p[0] == -math.inf:
                return h
            a = Fraction(p[0])
            return ZERO if x <= a else h * (x - a) / (b - a)
        if p[3] == math.inf:
            return h
        d = Fraction(p[3])
        return ZERO if x >= d else h * (d - x) / (d - c)
    if s == "rectangle":
        return h if Fraction(p[0]) <= x <= Fraction(p[1]) else ZERO
    if s == "ramp":
        a, b = Fraction(p[0]), Fraction(p[1])
        if a == b:
            return ZERO
        if a < b:
            return ZERO if x <= a else h if x >= b else h * (x - a) / (b - a)
        return ZERO if x >= a else h if x <= b else h * (a - x) / (a - b)
    if s == "discrete":
        xs = [Fraction(v) for v in p[0::2]]
        ys = [Fraction(v) for v in p[1::2]]
        if x < xs[0]:
            return h * ys[0]
        if x > xs[-1]:
            return h * ys[-1]
        i = max(k for k in range(len(xs)) if xs[k] <= x)  # last point at or left of x
        if xs[i] == x:
            return h * ys[i]
        return h * (ys[i] + (ys[i + 1] - ys[i]) * (x - xs[i]) / (xs[i + 1] - xs[i]))
    raise ValueError(f"not a piecewise-linear shape: {s}")


def pl_vertices(term: Term) -> list[Fraction]:
    """The x positions where a piecewise-linear term may bend or jump."""
    s, p = term.shape, term.params
    if s == "discrete":
        return [Fraction(v) for v in p[0::2]]
    if s in PL_SHAPES:
        return [Fraction(v) for v in p if math.isfinite(v)]
    raise ValueError(f"not a piecewise-linear shape: {s}")


# ---------------------------------------------------------------------------------------------
# rule strengths


def _strength(system: FuzzySystem, e: Expr, mu: Callable[[int, int], Fraction]) -> Fraction:
    if isinstance(e, Is):
        v = mu(e.variable, e.term)
        return 1 - v if e.negated else v
    if isinstance(e, Not):
        return 1 - _strength(system, e.operand, mu)
    vals = [_strength(system, op, mu) for op in e.operands]
    acc = vals[0]
    for v in vals[1:]:
        if isinstance(e, And):
            acc = min(acc, v) if system.and_op == "min" else acc * v
        else:
            assert isinstance(e, Or)
            acc = max(acc, v) if system.or_op == "max" else acc + v - acc * v
    return acc


def _clipped_inputs(system: FuzzySystem, x: Sequence[float]) -> list[Fraction]:
    out = []
    for v, xi in zip(system.inputs, x, strict=True):
        q = Fraction(float(xi))
        if v.clip:
            q = min(max(q, Fraction(v.range[0])), Fraction(v.range[1]))
        out.append(q)
    return out


def exact_strengths(system: FuzzySystem, x: Sequence[float]) -> list[Fraction]:
    """Rule strengths (weight applied) in exact arithmetic; piecewise-linear inputs only."""
    xin = _clipped_inputs(system, x)

    def mu(i: int, t: int) -> Fraction:
        return pl_mu(system.inputs[i].terms[t], xin[i])

    return [_strength(system, r.antecedent, mu) * Fraction(r.weight) for r in system.rules]


# ---------------------------------------------------------------------------------------------
# the exact piecewise-linear aggregate

Piece = tuple[Fraction, Fraction, Fraction, Fraction]  # u, v, g(u+), g(v-)


def _implied(impl: str, w: Fraction, m: Fraction) -> Fraction:
    return min(w, m) if impl == "min" else w * m


def _aggregate(agg: str, vals: list[Fraction]) -> Fraction:
    if agg == "max":
        return max(vals, default=ZERO)
    total = sum(vals, ZERO)
    return min(ONE, total) if agg == "bounded_sum" else total


def pl_pieces(var: Variable, items: list[tuple[int, Fraction]], impl: str, agg: str
              ) -> list[Piece]:
    """Exact linear pieces of the aggregate of ``items`` (term index, strength) over the
    variable's range."""
    lo, hi = Fraction(var.range[0]), Fraction(var.range[1])
    terms = [var.terms[j] for j, _ in items]
    ws = [w for _, w in items]
    pts = {lo, hi}
    for t in terms:
        pts.update(v for v in pl_vertices(t) if lo < v < hi)
    xs = sorted(pts)

    def g(y: Fraction) -> Fraction:
        return _aggregate(agg, [_implied(impl, w, pl_mu(t, y)) for t, w in zip(terms, ws,
                                                                              strict=True)])

    def total(y: Fraction) -> Fraction:
        return sum((_implied(impl, w, pl_mu(t, y)) for t, w in zip(terms, ws, strict=True)),
                   ZERO)

    pieces: list[Piece] = []
    for p, q in zip(xs, xs[1:], strict=False):
        # each term is linear on (p, q): its line from two interior points
        y1, y2 = p + (q - p) / 3, p + 2 * (q - p) / 3
        lines: list[tuple[Fraction, Fraction]] = []  # slope, intercept of the functions
        for t, w in zip(terms, ws, strict=True):
            m1, m2 = pl_mu(t, y1), pl_mu(t, y2)
            s = (m2 - m1) / (y2 - y1)
            c = m1 - s * y1
            lines.append((w * s, w * c) if impl == "product" else (s, c))
        consts = {ZERO, ONE, *ws}
        funcs = lines + [(ZERO, k) for k in consts]
        cand = {p, q}
        for i, (s1, c1) in enumerate(funcs):
            for s2, c2 in funcs[i + 1:]:
                if s1 != s2:
                    y = (c2 - c1) / (s1 - s2)
                    if p < y < q:
                        cand.add(y)
        cs = sorted(cand)
        if agg == "bounded_sum":  # where the (linear) sum reaches 1 between two candidates
            more = set(cs)
            for u, v in zip(cs, cs[1:], strict=False):
                a1, a2 = u + (v - u) / 3, u + 2 * (v - u) / 3
                t1, t2 = total(a1), total(a2)
                if t1 != t2:
                    y = a1 + (ONE - t1) * (a2 - a1) / (t2 - t1)
                    if u < y < v:
                        more.add(y)
            cs = sorted(more)
        for u, v in zip(cs, cs[1:], strict=False):
            a1, a2 = u + (v - u) / 3, u + 2 * (v - u) / 3
            g1, g2 = g(a1), g(a2)
            # self-check: linear between candidates (exactly, at a third point)
            mid = (a1 + a2) / 2
            if g(mid) != (g1 + g2) / 2:
                raise AssertionError(f"reference: aggregate not linear on ({u}, {v})")
            slope = (g2 - g1) / (a2 - a1)
            pieces.append((u, v, g1 + slope * (u - a1), g1 + slope * (v - a1)))
    return pieces


def _bisector_from_left(pieces: list[Piece], half: Fraction) -> Fraction:
    """Smallest t with integral(lo..t) >= half, t rounded to about 50 digits."""
    acc = ZERO
    for u, v, gu, gv in pieces:
        seg = (v - u) * (gu + gv) / 2
        if seg > 0 and acc + seg >= half:
            need = half - acc
            s = (gv - gu) / (v - u)
            if s == 0:
                return u + need / gu
            disc = gu * gu + 2 * s * need  # >= 0: need is at most the piece's area
            with localcontext() as ctx:
                ctx.prec = 60
                root = (Decimal(disc.numerator) / Decimal(disc.denominator)).sqrt()
            tau = 2 * need / (gu + Fraction(root))
            return u + min(max(tau, ZERO), v - u)
        acc += seg
    return pieces[-1][1]


def defuzz_pieces(pieces: list[Piece], method: str) -> Interval | None:
    """The defuzzified value of exact linear pieces, as an interval (None: zero area)."""
    area = sum(((v - u) * (gu + gv) / 2 for u, v, gu, gv in pieces), ZERO)
    if area == 0:
        return None
    if method == "centroid":
        mom = sum(((v - u) * (u * (2 * gu + gv) + v * (gu + 2 * gv)) / 6
                   for u, v, gu, gv in pieces), ZERO)
        c = mom / area
        return c, c
    if method == "bisector":
        t1 = _bisector_from_left(pieces, area / 2)
        mirrored = [(-v, -u, gv, gu) for u, v, gu, gv in reversed(pieces)]
        t2 = -_bisector_from_left(mirrored, area / 2)
        return min(t1, t2), max(t1, t2)
    gmax = max(max(gu, gv) for _, _, gu, gv in pieces)
    top = gmax * (1 - TIE)
    plateau = [(u, v) for u, v, gu, gv in pieces if gu >= top and gv >= top and v > u]
    points = sorted({u for u, _, gu, _ in pieces if gu >= top}
                    | {v for _, v, _, gv in pieces if gv >= top})
    if method == "som":
        return points[0], points[0]
    if method == "lom":
        return points[-1], points[-1]
    assert method == "mom"
    length = sum((v - u for u, v in plateau), ZERO)
    if length > 0:
        m = sum(((v * v - u * u) / 2 for u, v in plateau), ZERO) / length
    else:
        m = sum(points, ZERO) / len(points)
    return m, m


def exact_outputs(system: FuzzySystem, x: Sequence[float]) -> list[Interval | None]:
    """Exact value of every output at the point x (before defaults and clamping)."""
    shapes = {t.shape for v in system.inputs for t in v.terms}
    if not shapes <= set(PL_SHAPES):
        raise ValueError("exact_outputs needs piecewise-linear inputs")
    w = exact_strengths(system, x)
    xin = _clipped_inputs(system, x)
    out: list[Interval | None] = []
    for k, var in enumerate(system.outputs):
        items = [(c.term, w[r]) for r, rule in enumerate(system.rules) if w[r] > 0
                 for c in rule.consequents if c.variable == k]
        if system.kind == "sugeno":
            num = den = ZERO
            for j, wr in items:
                t = var.terms[j]
                if t.shape == "constant":
                    z = Fraction(t.params[0])
                else:
                    z = Fraction(t.params[-1]) + sum(
                        (Fraction(cf) * xi for cf, xi in zip(t.params[:-1], xin, strict=True)),
                        ZERO)
                num += wr * z
                den += wr
            if den == 0:
                out.append(None)
            else:
                val = num / den if system.defuzzifier == "wtaver" else num
                out.append((val, val))
            continue
        if not items:
            out.append(None)
            continue
        if all(t.shape == "singleton" for t in var.terms):
            out.append(_singletons(var, items, system))
            continue
        if system.aggregation == "probor" or any(var.terms[j].shape not in PL_SHAPES
                                                 for j, _ in items):
            raise ValueError("exact_outputs: not a piecewise-linear aggregate")
        pieces = pl_pieces(var, items, system.implication, system.aggregation)
        out.append(defuzz_pieces(pieces, system.defuzzifier))
    return out


def _singletons(var: Variable, items: list[tuple[int, Fraction]], system: FuzzySystem
                ) -> Interval | None:
    heights: dict[int, Fraction] = {}  # per term
    for j, w in items:
        t = var.terms[j]
        v = _implied(system.implication, w, Fraction(t.height))
        old = heights.get(j, ZERO)
        if system.aggregation == "max":
            new = max(old, v)
        elif system.aggregation == "bounded_sum":
            new = min(ONE, old + v)
        elif system.aggregation == "sum":
            new = old + v
        else:
            new = old + v - old * v
        heights[j] = new
    den = sum(heights.values(), ZERO)
    if den == 0:
        return None
    pos = {j: Fraction(var.terms[j].params[0]) for j in heights}
    if system.defuzzifier == "centroid":
        c = sum((pos[j] * hgt for j, hgt in heights.items()), ZERO) / den
        return c, c
    gmax = max(heights.values())
    top = sorted({pos[j] for j, hgt in heights.items() if hgt >= gmax * (1 - TIE)})
    m = {"som": top[0], "lom": top[-1], "mom": sum(top, ZERO) / len(top)}[system.defuzzifier]
    return m, m


def expected(system: FuzzySystem, values: Sequence[Interval | None]) -> list[Interval | float]:
    """Apply each output's default (float, may be NaN) and clamping to reference values."""
    res: list[Interval | float] = []
    for var, val in zip(system.outputs, values, strict=True):
        if val is None:
            res.append(var.default)
            continue
        lo, hi = val
        if var.clip:
            r0, r1 = Fraction(var.range[0]), Fraction(var.range[1])
            lo, hi = min(max(lo, r0), r1), min(max(hi, r0), r1)
        res.append((lo, hi))
    return res


def distance(ours: float, ref: Interval | float) -> float:
    """Distance of our value from the reference interval (0 inside); inf if one is NaN / the
    default and the other is not; 0 when both are the same default."""
    if isinstance(ref, float):
        if math.isnan(ref):
            return 0.0 if math.isnan(ours) else math.inf
        return abs(ours - ref) if not math.isnan(ours) else math.inf
    if math.isnan(ours):
        return math.inf
    q = Fraction(ours)
    lo, hi = ref
    return float(max(lo - q, q - hi, ZERO))


# ---------------------------------------------------------------------------------------------
# mpmath reference: any shape, any aggregation

mpf = mpmath.mpf


def _mpq(v: Fraction) -> mpmath.mpf:
    return mpf(v.numerator) / v.denominator


def _sig(x: mpmath.mpf, c: float, a: float) -> mpmath.mpf:
    return 1 / (1 + mpmath.exp(-mpf(a) * (x - mpf(c))))


def _smf(x: mpmath.mpf, a: float, b: float) -> mpmath.mpf:
    fa, fb = mpf(a), mpf(b)
    if x <= fa:
        return mpf(0)
    if x >= fb:
        return mpf(1)
    if x <= (fa + fb) / 2:
        return 2 * ((x - fa) / (fb - fa)) ** 2
    return 1 - 2 * ((x - fb) / (fb - fa)) ** 2


def mp_mu(term: Term, x: mpmath.mpf) -> mpmath.mpf:
    """Membership of any Mamdani term at x in mpmath (height applied)."""
    return mp_term(term)(x)


def mp_term(term: Term) -> Callable[[mpmath.mpf], mpmath.mpf]:
    """The membership function of a term in mpmath, its parameters converted once (at the
    current precision; floats are exact in mpf)."""
    s, h = term.shape, mpf(term.height)
    if s in PL_SHAPES:
        return lambda x: _pl_mu_mp(term, x)
    p = [mpf(v) for v in term.params]
    exp = mpmath.exp

    def sig(x: mpmath.mpf, c: mpmath.mpf, a: mpmath.mpf) -> mpmath.mpf:
        return 1 / (1 + exp(-a * (x - c)))

    def smf(x: mpmath.mpf, a: mpmath.mpf, b: mpmath.mpf) -> mpmath.mpf:
        if x <= a:
            return mpf(0)
        if x >= b:
            return mpf(1)
        if x <= (a + b) / 2:
            return 2 * ((x - a) / (b - a)) ** 2
        return 1 - 2 * ((x - b) / (b - a)) ** 2

    if s == "gaussian":
        return lambda x: h * exp(-((x - p[0]) / p[1]) ** 2 / 2)
    if s == "gaussian2":
        def g2(x: mpmath.mpf) -> mpmath.mpf:
            v = mpf(1)
            if x < p[0]:
                v *= exp(-((x - p[0]) / p[1]) ** 2 / 2)
            if x > p[2]:
                v *= exp(-((x - p[2]) / p[3]) ** 2 / 2)
            return h * v
        return g2
    if s == "bell":
        return lambda x: h / (1 + abs((x - p[0]) / p[1]) ** (2 * p[2]))
    if s == "sigmoid":
        return lambda x: h * sig(x, p[0], p[1])
    if s == "dsigmoid":
        return lambda x: h * abs(sig(x, p[0], p[1]) - sig(x, p[3], p[2]))
    if s == "psigmoid":
        return lambda x: h * sig(x, p[0], p[1]) * sig(x, p[3], p[2])
    if s == "s":
        return lambda x: h * smf(x, p[0], p[1])
    if s == "z":
        return lambda x: h * (1 - smf(x, p[0], p[1]))
    if s == "pi":
        return lambda x: h * smf(x, p[0], p[1]) * (1 - smf(x, p[2], p[3]))
    raise ValueError(f"no mpmath membership for {s}")


def _pl_mu_mp(term: Term, x: mpmath.mpf) -> mpmath.mpf:
    """The piecewise-linear definition in mpf (same branches as pl_mu)."""
    s, p, h = term.shape, term.params, mpf(term.height)
    if s == "triangle":
        a, b, c = (mpf(v) for v in p)
        if x < a or x > c:
            return mpf(0)
        if x == b:
            return h
        return h * (x - a) / (b - a) if x < b else h * (c - x) / (c - b)
    if s == "trapezoid":
        b, c = mpf(p[1]), mpf(p[2])
        if b <= x <= c:
            return h
        if x < b:
            if p[0] == -math.inf:
                return h
            a = mpf(p[0])
            return mpf(0) if x <= a else h * (x - a) / (b - a)
        if p[3] == math.inf:
            return h
        d = mpf(p[3])
        return mpf(0) if x >= d else h * (d - x) / (d - c)
    if s == "rectangle":
        return h if p[0] <= x <= p[1] else mpf(0)
    if s == "ramp":
        a, b = mpf(p[0]), mpf(p[1])
        if a == b:
            return mpf(0)
        if a < b:
            return mpf(0) if x <= a else h if x >= b else h * (x - a) / (b - a)
        return mpf(0) if x >= a else h if x <= b else h * (a - x) / (a - b)
    xs = [mpf(v) for v in p[0::2]]
    ys = [mpf(v) for v in p[1::2]]
    if x < xs[0]:
        return h * ys[0]
    if x > xs[-1]:
        return h * ys[-1]
    i = max(k for k in range(len(xs)) if xs[k] <= x)
    if xs[i] == x:
        return h * ys[i]
    return h * (ys[i] + (ys[i + 1] - ys[i]) * (x - xs[i]) / (xs[i + 1] - xs[i]))


def _knots(term: Term) -> list[float]:
    p = [v for v in term.params if math.isfinite(v)]
    if term.shape in ("s", "z", "pi"):
        p += [(term.params[i] + term.params[i + 1]) / 2 for i in range(0, len(term.params), 2)]
    return p


class MpAggregate:
    """The aggregate of one output in mpmath, with its pieces located."""

    def __init__(self, system: FuzzySystem, var: Variable, items: list[tuple[int, object]],
                 scan: int = 200) -> None:
        self.eps = mpf(10) ** -(mpmath.mp.dps - 2)  # a little above the working precision
        self.impl = system.implication
        self.agg = system.aggregation
        self.terms = [var.terms[j] for j, _ in items]
        self.mus = [mp_term(t) for t in self.terms]
        self.ws = [mpf(w) for _, w in items]
        self.lo, self.hi = mpf(var.range[0]), mpf(var.range[1])
        knots = {self.lo, self.hi}
        for t in self.terms:
            knots.update(mpf(v) for v in _knots(t) if var.range[0] < v < var.range[1])
        ks = sorted(knots)
        cuts = set(ks)
        for p, q in zip(ks, ks[1:], strict=False):
            prev_y = p + (q - p) * self.eps
            prev = self.signature(prev_y)
            for i in range(1, scan + 1):
                y = p + (q - p) * i / scan if i < scan else q - (q - p) * self.eps
                sig = self.signature(y)
                cur, start = prev, prev_y
                while sig != cur:  # every change in the cell: the first, then on from it
                    a, b = start, y
                    while b - a > (self.hi - self.lo) * self.eps:
                        m = (a + b) / 2
                        if self.signature(m) == cur:
                            a = m
                        else:
                            b = m
                    cuts.add((a + b) / 2)
                    cur, start = self.signature(b), b
                prev, prev_y = sig, y
        self.cuts = sorted(cuts)

    def parts(self, y: mpmath.mpf) -> list[mpmath.mpf]:
        return [min(w, mu(y)) if self.impl == "min" else w * mu(y)
                for mu, w in zip(self.mus, self.ws, strict=True)]

    def __call__(self, y: mpmath.mpf) -> mpmath.mpf:
        vals = self.parts(y)
        if self.agg == "max":
            return max(vals)
        if self.agg == "probor":
            acc = mpf(0)
            for v in vals:
                acc = acc + v - acc * v
            return acc
        total = mpmath.fsum(vals)
        return min(mpf(1), total) if self.agg == "bounded_sum" else total

    def signature(self, y: mpmath.mpf) -> tuple[object, ...]:
        mus = [mu(y) for mu in self.mus]
        vals = [min(w, m) if self.impl == "min" else w * m
                for m, w in zip(mus, self.ws, strict=True)]
        clipped = tuple(m >= w for m, w in zip(mus, self.ws, strict=True)) \
            if self.impl == "min" else ()
        arg = max(range(len(vals)), key=lambda i: vals[i]) if self.agg == "max" else -1
        sat = mpmath.fsum(vals) >= 1 if self.agg == "bounded_sum" else False
        # a dsigmoid bends where its two sigmoids cross (the absolute value)
        bends = tuple(_sig(y, t.params[0], t.params[1]) >= _sig(y, t.params[3], t.params[2])
                      for t in self.terms if t.shape == "dsigmoid")
        return clipped, arg, sat, bends

    def _quad(self, f: Callable[[mpmath.mpf], mpmath.mpf], u: mpmath.mpf, v: mpmath.mpf,
              depth: int = 0) -> mpmath.mpf:
        """mpmath.quad on [u, v], halved while its error estimate is above 1e4 eps of the range
        (per unit length, and at least 1e-2 eps: a bend the scan missed ends in a piece small
        enough not to matter); eps is 100 units of the working precision."""
        val, err = mpmath.quad(f, [u, v], error=True, method="gauss-legendre")
        scale = (self.hi - self.lo) * (1 + abs(self.lo) + abs(self.hi))
        if err <= self.eps * 1e4 * scale * ((v - u) / (self.hi - self.lo) + 1e-6):
            return val
        if depth >= 60:
            raise AssertionError(f"reference quadrature inaccurate on [{u}, {v}]: {err}")
        m = (u + v) / 2
        return self._quad(f, u, m, depth + 1) + self._quad(f, m, v, depth + 1)

    def integrals(self) -> tuple[mpmath.mpf, mpmath.mpf]:
        """(area, first moment), piece by piece."""
        area = mpf(0)
        mom = mpf(0)
        for u, v in zip(self.cuts, self.cuts[1:], strict=False):
            area += self._quad(self, u, v)
            mom += self._quad(lambda y: y * self(y), u, v)
        return area, mom

    def bisector(self, area: mpmath.mpf) -> mpmath.mpf:
        """The t with integral(lo..t) = area / 2: safeguarded Newton inside the piece where
        the running integral crosses half the area (the aggregate is smooth there), the
        running integral carried forward by the integrals over the steps."""
        half = area / 2
        acc = mpf(0)
        tol = (self.hi - self.lo) * self.eps * 1e4
        for u, v in zip(self.cuts, self.cuts[1:], strict=False):
            seg = self._quad(self, u, v)
            if seg > 0 and acc + seg >= half:
                a, b = u, v
                t, ft = u, acc  # ft = integral(lo..t)
                for _ in range(200):
                    r = ft - half
                    if r == 0:
                        return t
                    if r < 0:
                        a = t
                    else:
                        b = t
                    gt = self(t)
                    nt = t - r / gt if gt > 0 else (a + b) / 2
                    if not a < nt < b:
                        nt = (a + b) / 2
                    ft += self._quad(self, t, nt) if nt > t else -self._quad(self, nt, t)
                    if abs(nt - t) < tol:
                        return nt
                    t = nt
                raise AssertionError("reference bisector did not converge")
            acc += seg
        return self.cuts[-1]

    def maxima(self, method: str, dense: int = 60) -> mpmath.mpf:
        """Mean, smallest or largest of maximum: a dense search in every piece refined by
        golden section around every local maximum of the samples, plateaus by exact
        equality."""
        invphi = (mpmath.sqrt(5) - 1) / 2
        samples: dict[mpmath.mpf, mpmath.mpf] = {}
        for u, v in zip(self.cuts, self.cuts[1:], strict=False):
            for i in range(dense + 1):
                y = u + (v - u) * i / dense
                samples[y] = self(y)
        ys = sorted(samples)
        gs = [samples[y] for y in ys]
        cand = list(zip(ys, gs, strict=True))
        # golden section around every local maximum of the samples (ends included)
        for i in range(len(ys)):
            left = gs[i - 1] if i > 0 else mpf(-1)
            right = gs[i + 1] if i + 1 < len(ys) else mpf(-1)
            if gs[i] >= left and gs[i] >= right and not left == gs[i] == right:
                a, b = ys[max(i - 1, 0)], ys[min(i + 1, len(ys) - 1)]
                for _ in range(160):
                    x1 = b - invphi * (b - a)
                    x2 = a + invphi * (b - a)
                    if self(x1) < self(x2):
                        a = x1
                    else:
                        b = x2
                m = (a + b) / 2
                cand.append((m, self(m)))
        gmax = max(g for _, g in cand)
        top = gmax * (1 - self.eps * 1e3)  # ties at the working precision
        # plateaus: pieces whose samples all reach the maximum
        plen = mpf(0)
        pmom = mpf(0)
        for u, v in zip(self.cuts, self.cuts[1:], strict=False):
            ys = [u + (v - u) * i / 8 for i in range(9)]
            if all(self(y) >= top for y in ys):
                plen += v - u
                pmom += (v * v - u * u) / 2
        # maximising points: a run of candidates (in order, the dense samples among them)
        # that all reach the maximum is one point, or the plateau between its first and
        # last cut: at a cut if the run holds one (a knot: the flat top of a steep bell, or a
        # plateau's end, is known to be there only), else at its highest candidate
        cuts = set(self.cuts)
        runs: list[list[tuple[mpmath.mpf, mpmath.mpf]]] = [[]]
        for y, g in sorted(cand):
            if g >= top:
                runs[-1].append((y, g))
            elif runs[-1]:
                runs.append([])
        runs = [r for r in runs if r]
        firsts, lasts = [], []
        for r in runs:
            at_cut = [y for y, _ in r if y in cuts]
            best = max(r, key=lambda c: c[1])[0]
            firsts.append(min(at_cut) if at_cut else best)
            lasts.append(max(at_cut) if at_cut else best)
        pts = [firsts[0], lasts[-1]] if method != "mom" else [
            (f + la) / 2 for f, la in zip(firsts, lasts, strict=True)]
        if method == "som":
            return pts[0]
        if method == "lom":
            return pts[-1]
        return pmom / plen if plen > 0 else mpmath.fsum(pts) / len(pts)


def mp_fraction(v: mpmath.mpf) -> Fraction:
    """The exact value of an mpf."""
    sign, man, exp, _ = mpf(v)._mpf_
    q = Fraction(int(man)) * Fraction(2) ** int(exp)
    return -q if sign else q


def mp_outputs(system: FuzzySystem, x: Sequence[float], dps: int = 30
               ) -> list[Interval | None]:
    """Every output at x by mpmath (Mamdani systems with area terms)."""
    with mpmath.workdps(dps):
        xin = []
        for v, xi in zip(system.inputs, x, strict=True):
            q = mpf(float(xi))
            if v.clip:
                q = min(max(q, mpf(v.range[0])), mpf(v.range[1]))
            xin.append(q)

        def mu(i: int, t: int) -> mpmath.mpf:
            return mp_mu(system.inputs[i].terms[t], xin[i])

        w = [_strength(system, r.antecedent, mu) * mpf(r.weight)  # type: ignore[arg-type]
             for r in system.rules]
        out: list[Interval | None] = []
        for k, var in enumerate(system.outputs):
            items: list[tuple[int, object]] = [
                (c.term, w[r]) for r, rule in enumerate(system.rules) if w[r] > 0
                for c in rule.consequents if c.variable == k]
            if not items:
                out.append(None)
                continue
            g = MpAggregate(system, var, items)
            area, mom = g.integrals()
            if not area > 0:
                out.append(None)
                continue
            if system.defuzzifier == "centroid":
                val = mom / area
            elif system.defuzzifier == "bisector":
                val = g.bisector(area)
            else:
                val = g.maxima(system.defuzzifier)
            q = mp_fraction(val)
            out.append((q, q))
        return out
