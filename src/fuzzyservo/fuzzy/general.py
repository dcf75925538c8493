"""Exact evaluation of general fuzzy systems (:class:`~fuzzyservo.fuzzy.system.FuzzySystem`).

One implementation serves every caller: :func:`compile_system` packs a system once into two
flat arrays (``ints``, ``floats``), and the compiled functions below evaluate them: point by
point, in batches (:func:`fuzzyservo.fuzzy.engine.evaluate`, which also chooses this
evaluator or the uniform grid) and inside the controllers' compiled loops (:func:`eval_first2`,
through :func:`fuzzyservo.fuzzy.engine.eval_system`).

How each output is defuzzified (docs/fuzzy-files.md, "Exactness"):

- **Piecewise-linear terms** (triangle, trapezoid, rectangle, ramp, discrete) under min or
  product implication and max, bounded-sum or sum aggregation: the aggregate is piecewise
  linear. It is built exactly between the terms' vertices and the points where lines cross each
  other, their clip heights, zero, or (bounded sum) 1; each linear piece is integrated in closed
  form. Centroid, bisector and the maxima are read off these pieces; the result is exact up to
  floating-point rounding (tested to 1e-12 of the range against exact rational arithmetic).
- **Singleton terms** (IEC 61131-7 COGS): the centroid is sum(h x) / sum(h) over the aggregated
  heights; the maxima methods use the singletons of largest height.
- **Everything else** (smooth shapes, s/z/pi, probabilistic-sum aggregation, mixtures): the
  aggregate is split at every term's knots, at the points where an implied set reaches its clip
  height and where the largest implied set changes (located on a scan of 32 cells per knot
  interval and refined by bisection to rounding), and each piece is integrated by adaptive
  Gauss-Kronrod (G7, K15). A subinterval is accepted when |K15 - G7| <= 1e-12 A len / range,
  A the area estimated first: on a piece where the aggregate is smooth the K15 error is far
  below that estimate, so the relative error of the area and the first moment is below 1e-12
  and the centroid within about 1e-12 of the range; a kink the scan missed is caught by the
  same test (the aggregate is continuous inside a piece), at the price of more subdivision.
  Tested against mpmath quadrature at 1e-10 of the range.

When no rule fires for an output (zero aggregate; zero total weight for Sugeno) the output is
its ``default`` (NaN: no value, fuzzylite's convention). Inputs are clipped to their range when
the variable says so; a NaN input gives NaN outputs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from .._jit import kernel
from .._typing import ArrayLike, FloatArray, IntArray
from ..errors import ParameterError
from .kernels import insort
from .partition import eval_partition, partition_tables, scratch_sizes
from .shapes import SHAPE_TABLE, shape
from .system import And, Expr, FuzzySystem, Is, Not, Or

__all__ = [
    "CompiledSystem",
    "compile_system",
    "eval_batch",
    "eval_first2",
    "eval_parallel",
    "membership",
]

SHAPE_CODE: dict[str, int] = {s.name: s.code for s in SHAPE_TABLE}
# the codes the compiled functions switch on (each shape's own formula), read from the table
(_TRI, _TRAP, _RECT, _RAMP, _DISC, _SING, _GAUSS, _GAUSS2, _BELL, _SIG, _DSIG, _PSIG, _S, _Z,
 _PI, _CONST, _LIN) = (SHAPE_CODE[name] for name in (
    "triangle", "trapezoid", "rectangle", "ramp", "discrete", "singleton", "gaussian",
    "gaussian2", "bell", "sigmoid", "dsigmoid", "psigmoid", "s", "z", "pi", "constant",
    "linear"))

# header of ``ints``
(H_MAGIC, H_NIN, H_NOUT, H_NTERMS, H_NRULES, H_KIND, H_AND, H_OR, H_IMPL, H_AGG, H_DEFUZZ,
 H_VARS, H_TERMS, H_RULES, H_PROG, H_CONS, H_OUTS, H_WORK, H_STACK, H_FVARS, H_FLAT,
 H_FLATOFF, H_MAXITEMS, H_FWEIGHT, H_PIVOT, H_IWORK, H_GRID, H_PART, H_PARTF) = range(29)
_HEADER = 29
#: Largest number of cells of the dense rule index (product of the inputs' term counts).
GRID_MAX_CELLS = 1 << 16
MAGIC = 20261130
# output modes
_M_PL, _M_SING, _M_SMOOTH, _M_SUGENO = range(4)
_OUT_FIELDS = 7  # mode, bp_off, n_bp, slope_off, icpt_off, n_terms, support_off
# program ops
_OP_IS, _OP_NOT, _OP_AND, _OP_OR = range(4)

_DEFUZZ = {"centroid": 0, "bisector": 1, "mom": 2, "som": 3, "lom": 4, "wtaver": 5, "wtsum": 6}
_AGG = {"max": 0, "bounded_sum": 1, "sum": 2, "probor": 3}

#: Scan cells per knot interval when locating the pieces of a smooth aggregate.
SCAN_CELLS = 32
#: Most changes of the piece signature located inside one scan cell.
CELL_CHANGES = 8
#: Acceptance of a Gauss-Kronrod subinterval: |K15 - G7| <= QUAD_RTOL * A * len / range.
QUAD_RTOL = 1e-12
#: Most subintervals per piece before the adaptive quadrature gives up refining.
QUAD_MAX_SUB = 4000

# Gauss-Kronrod 7-15 nodes and weights on [-1, 1] (QUADPACK's qk15)
_XGK = np.array([0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
                 0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
                 0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
                 0.207784955007898467600689403773245, 0.000000000000000000000000000000000])
_WGK = np.array([0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
                 0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
                 0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
                 0.204432940075298892414161999234649, 0.209482141084727828012999174891714])
_WG = np.array([0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
                0.381830050505118944950369775488975, 0.417959183673469387755102040816327])


# ---------------------------------------------------------------------------------------------
# membership functions (one implementation; numpy callers go through ``membership``)


@kernel(error_model="numpy")
def _sigmoid(x: float, c: float, a: float) -> float:
    return 1.0 / (1.0 + math.exp(-a * (x - c)))


@kernel(error_model="numpy")
def _smf(x: float, a: float, b: float) -> float:
    if x <= a:
        return 0.0
    if x >= b:
        return 1.0
    m = 0.5 * (a + b)
    if x <= m:
        t = (x - a) / (b - a)
        return 2.0 * t * t
    t = (x - b) / (b - a)
    return 1.0 - 2.0 * t * t


@kernel(inline=True, error_model="numpy")
def mf_value(code: int, f: FloatArray, off: int, n: int, x: float) -> float:
    """Membership (height applied) of term ``code`` with parameters f[off:off+n], height
    f[off+n], at x. Shapes and conventions: fuzzyservo.fuzzy.system."""
    h = f[off + n]
    if x != x:
        return np.nan
    if code == _TRI:
        a = f[off]
        b = f[off + 1]
        c = f[off + 2]
        if x < a or x > c:
            return 0.0
        if x == b:
            return h
        if x < b:
            return (x - a) * f[off + n + 1]
        return (c - x) * f[off + n + 2]
    if code == _TRAP:
        a = f[off]
        b = f[off + 1]
        c = f[off + 2]
        d = f[off + 3]
        if x < a or x > d:
            return 0.0
        if x < b:
            return h if a == -np.inf else (x - a) * f[off + n + 1]
        if x <= c:
            return h
        if x < d:
            return h if d == np.inf else (d - x) * f[off + n + 2]
        return h if d == np.inf else 0.0
    if code == _RECT:
        return h if f[off] <= x <= f[off + 1] else 0.0
    if code == _RAMP:
        a = f[off]
        b = f[off + 1]
        if a == b:
            return 0.0
        if a < b:
            if x <= a:
                return 0.0
            if x >= b:
                return h
            return h * (x - a) / (b - a)
        if x >= a:
            return 0.0
        if x <= b:
            return h
        return h * (a - x) / (a - b)
    if code == _DISC:
        m = n // 2
        if x <= f[off]:
            return h * f[off + 1]
        if x >= f[off + 2 * (m - 1)]:
            return h * f[off + 2 * m - 1]
        lo = 0
        hi = m - 1
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if f[off + 2 * mid] <= x:
                lo = mid
            else:
                hi = mid
        x0 = f[off + 2 * lo]
        x1 = f[off + 2 * hi]
        y0 = f[off + 2 * lo + 1]
        y1 = f[off + 2 * hi + 1]
        if x1 == x0:
            return h * y1
        return h * (y0 + (y1 - y0) * (x - x0) / (x1 - x0))
    if code == _SING:
        return h if x == f[off] else 0.0
    if code == _GAUSS:
        t = (x - f[off]) / f[off + 1]
        return h * math.exp(-0.5 * t * t)
    if code == _GAUSS2:
        v = 1.0
        if x < f[off]:
            t = (x - f[off]) / f[off + 1]
            v *= math.exp(-0.5 * t * t)
        if x > f[off + 2]:
            t = (x - f[off + 2]) / f[off + 3]
            v *= math.exp(-0.5 * t * t)
        return h * v
    if code == _BELL:
        t = abs((x - f[off]) / f[off + 1])
        return h / (1.0 + t ** (2.0 * f[off + 2]))
    if code == _SIG:
        return h * _sigmoid(x, f[off], f[off + 1])
    if code == _DSIG:
        return h * abs(_sigmoid(x, f[off], f[off + 1]) - _sigmoid(x, f[off + 3], f[off + 2]))
    if code == _PSIG:
        return h * _sigmoid(x, f[off], f[off + 1]) * _sigmoid(x, f[off + 3], f[off + 2])
    if code == _S:
        return h * _smf(x, f[off], f[off + 1])
    if code == _Z:
        return h * (1.0 - _smf(x, f[off], f[off + 1]))
    if code == _PI:
        return h * _smf(x, f[off], f[off + 1]) * (1.0 - _smf(x, f[off + 2], f[off + 3]))
    return np.nan


@kernel
def _mf_array(code: int, f: FloatArray, off: int, n: int, x: FloatArray, out: FloatArray
              ) -> None:
    for i in range(x.shape[0]):
        out[i] = mf_value(code, f, off, n, x[i])


def _term_floats(shape: str, params: tuple[float, ...], height: float) -> list[float]:
    """A term's floats: its parameters, its height, then two precomputed slopes (height over
    the widths of the rising and falling edges of a triangle or trapezoid, 0 if unused)."""
    s1 = s2 = 0.0
    if shape == "triangle":
        a, b, c = params
        s1 = height / (b - a) if b > a else 0.0
        s2 = height / (c - b) if c > b else 0.0
    elif shape == "trapezoid":
        a, b, c, d = params
        s1 = height / (b - a) if math.isfinite(a) and b > a else 0.0
        s2 = height / (d - c) if math.isfinite(d) and d > c else 0.0
    return [*params, height, s1, s2]


def membership(shape: str, params: tuple[float, ...], x: ArrayLike, height: float = 1.0
               ) -> FloatArray:
    """Membership of a term (shape and parameters as :class:`~fuzzyservo.fuzzy.system.Term`)
    at ``x``: the compiled function the evaluator uses, over a numpy array."""
    f = np.array(_term_floats(shape, tuple(params), height), dtype=np.float64)
    xa = np.asarray(x, dtype=np.float64)
    flat = np.ascontiguousarray(xa.ravel())
    out = np.empty(flat.shape[0])
    _mf_array(SHAPE_CODE[shape], f, 0, len(params), flat, out)
    return out.reshape(xa.shape)


# ---------------------------------------------------------------------------------------------
# packing


@dataclass(frozen=True, slots=True, eq=False)
class CompiledSystem:
    """A fuzzy system packed for the compiled evaluator.

    Attributes
    ----------
    system : FuzzySystem
        The system.
    ints : int64 ndarray
        Header, variable, term, rule, program and output tables.
    floats : float64 ndarray
        Ranges, defaults, term parameters and heights, piecewise-linear output tables.
    """

    system: FuzzySystem  #: the packed system
    ints: IntArray  #: integer tables
    floats: FloatArray  #: float tables


def _program(e: Expr, out: list[int], depth: int = 1) -> int:
    """Append postfix ops of ``e``; return the stack depth it needs."""
    if isinstance(e, Is):
        out += [_OP_IS, e.variable, e.term, 1 if e.negated else 0]
        return depth
    if isinstance(e, Not):
        d = _program(e.operand, out, depth)
        out += [_OP_NOT]
        return d
    need = depth
    for k, op in enumerate(e.operands):
        need = max(need, _program(op, out, depth + k))
    out += [_OP_AND if isinstance(e, And) else _OP_OR, len(e.operands)]
    return need


def _flat(system: FuzzySystem) -> int:
    """1 if every rule is a flat AND (or a single clause) of distinct inputs, 2 for flat OR,
    0 otherwise (general programs)."""
    kinds = set()
    for r in system.rules:
        a = r.antecedent
        if isinstance(a, Is):
            continue
        if not isinstance(a, And | Or) or not all(isinstance(o, Is) for o in a.operands):
            return 0
        vars_ = [o.variable for o in a.operands if isinstance(o, Is)]
        if len(set(vars_)) != len(vars_):
            return 0
        kinds.add(1 if isinstance(a, And) else 2)
    if len(kinds) > 1:
        return 0
    return kinds.pop() if kinds else 1


def _output_mode(system: FuzzySystem, k: int) -> int:
    if system.kind == "sugeno":
        return _M_SUGENO
    families = {shape(t.shape).family for t in system.outputs[k].terms}
    if families == {"singleton"}:
        return _M_SING
    if families <= {"piecewise linear"} and system.aggregation != "probor":
        return _M_PL
    return _M_SMOOTH


def _pl_tables(system: FuzzySystem, k: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Breakpoints and per-interval lines of the piecewise-linear terms of output k."""
    var = system.outputs[k]
    lo, hi = var.range
    pts = {lo, hi}
    for t in var.terms:
        v = t.vertices
        assert v is not None
        pts.update(x for x, _ in v if lo < x < hi)
    # breakpoints closer than rounding (-1 + 3 (2/3) and 1) are merged: an interval that thin
    # has no room for a line of its own (the merge moves a vertex by at most 1e-13 of the range)
    tol = 1e-13 * (hi - lo)
    merged: list[float] = []
    for x in sorted(pts):
        if merged and x - merged[-1] <= tol:
            merged[-1] = hi if x == hi else merged[-1]
            continue
        merged.append(x)
    merged[0] = lo
    bp = np.array(merged, dtype=np.float64)
    n_int = bp.shape[0] - 1
    n = len(var.terms)
    slope = np.empty((n_int, n))
    icpt = np.empty((n_int, n))
    for j, t in enumerate(var.terms):
        for i in range(n_int):
            p, q = float(bp[i]), float(bp[i + 1])
            # the line the term follows inside (p, q): a vertex merged into p or q above lies
            # outside the piece, so its jump (if any) stays within rounding of the end
            v0, v1 = _interval_line(t, p, q)
            slope[i, j] = (v1 - v0) / (q - p)
            icpt[i, j] = v0 - slope[i, j] * p
    return bp, slope, icpt


def _interval_line(t: object, p: float, q: float) -> tuple[float, float]:
    """Values at p and q of the line a piecewise-linear term follows inside (p, q): its piece
    that contains the middle of the interval, from its vertices (exact where p and q are
    vertices of that piece)."""
    verts = t.vertices  # type: ignore[attr-defined]
    xs = [x for x, _ in verts]
    ys = [y for _, y in verts]
    mid = 0.5 * (p + q)
    if mid <= xs[0]:
        return float(ys[0]), float(ys[0])
    if mid >= xs[-1]:
        return float(ys[-1]), float(ys[-1])
    for i in range(len(xs) - 1):
        a, b = xs[i], xs[i + 1]
        if a <= mid < b:
            y0, y1 = ys[i], ys[i + 1]
            v0 = y0 if p == a else y0 + (y1 - y0) * (p - a) / (b - a)
            v1 = y1 if q == b else y0 + (y1 - y0) * (q - a) / (b - a)
            return float(v0), float(v1)
    raise AssertionError("unreachable: the vertices cover the middle of the interval")


def compile_system(system: FuzzySystem) -> CompiledSystem:
    """Pack ``system`` for the compiled evaluator (done once per system).

    Raises
    ------
    ParameterError
        If ``system`` is not a FuzzySystem.
    """
    if not isinstance(system, FuzzySystem):
        raise ParameterError(f"expected a FuzzySystem, got {type(system).__name__}")
    n_in, n_out = len(system.inputs), len(system.outputs)
    variables = system.inputs + system.outputs
    fl: list[float] = [r.weight for r in system.rules]
    fvars = len(fl)
    for v in variables:
        fl += [v.range[0], v.range[1], v.default, 1.0 if v.clip else 0.0]
    var_tab: list[int] = []
    term_tab: list[int] = []
    n_terms = 0
    for v in variables:
        var_tab += [n_terms, len(v.terms)]
        for t in v.terms:
            term_tab += [SHAPE_CODE[t.shape], len(fl), len(t.params)]
            fl += _term_floats(t.shape, t.params, t.height)
            n_terms += 1
    # rules: postfix programs (clause terms as global term indices) and consequents
    prog: list[int] = []
    cons: list[int] = []
    rule_tab: list[int] = []
    stack = 1
    for r in system.rules:
        start = len(prog)
        stack = max(stack, _program(r.antecedent, prog))
        c0 = len(cons)
        for c in r.consequents:
            cons += [c.variable, c.term]
        rule_tab += [start, len(prog) - start, c0, len(r.consequents)]
    # clause term indices -> global term index (input variable's first term + local index)
    k = 0
    while k < len(prog):
        op = prog[k]
        if op == _OP_IS:
            prog[k + 2] = var_tab[2 * prog[k + 1]] + prog[k + 2]
            k += 4
        elif op == _OP_NOT:
            k += 1
        else:
            k += 2
    flat = _flat(system)
    flat_tab: list[int] = []
    if flat:
        for r in system.rules:
            row = [-1] * n_in
            neg = [0] * n_in
            clauses = [r.antecedent] if isinstance(r.antecedent, Is) else \
                r.antecedent.operands  # type: ignore[union-attr]
            for cl in clauses:
                assert isinstance(cl, Is)
                row[cl.variable] = var_tab[2 * cl.variable] + cl.term
                neg[cl.variable] = 1 if cl.negated else 0
            flat_tab += row + neg
    out_tab: list[int] = []
    out_lines: list[tuple[FloatArray, FloatArray, FloatArray]] = []
    sup_lists: list[tuple[int, list[int]]] = []
    max_items = 1
    n_cons = max(1, len(cons) // 2)
    for k in range(n_out):
        mode = _output_mode(system, k)
        n_t = len(system.outputs[k].terms)
        items = n_t if system.aggregation == "max" else n_cons
        max_items = max(max_items, items, n_t)
        if mode == _M_PL:
            bp, slope, icpt = _pl_tables(system, k)
            bp_off = len(fl)
            fl += bp.tolist()
            s_off = len(fl)
            fl += slope.ravel().tolist()
            i_off = len(fl)
            fl += icpt.ravel().tolist()
            sup: list[int] = []
            for j in range(n_t):
                nz = np.flatnonzero((slope[:, j] != 0.0) | (icpt[:, j] > 0.0))
                sup += [int(nz[0]), int(nz[-1])] if nz.size else [1, 0]
            out_tab += [mode, bp_off, bp.shape[0], s_off, i_off, n_t, -1]
            out_lines.append((bp, slope, icpt))
            sup_lists.append((len(out_tab) - 1, sup))
        else:
            out_tab += [mode, 0, 0, 0, 0, n_t, -1]
    # scratch sizes (see _work_layout)
    max_bp = max([out_tab[_OUT_FIELDS * k + 2] for k in range(n_out)] + [2])
    ints = [0] * _HEADER
    ints[H_MAGIC] = MAGIC
    ints[H_NIN] = n_in
    ints[H_NOUT] = n_out
    ints[H_NTERMS] = n_terms
    ints[H_NRULES] = len(system.rules)
    ints[H_KIND] = 0 if system.kind == "mamdani" else 1
    ints[H_AND] = 0 if system.and_op == "min" else 1
    ints[H_OR] = 0 if system.or_op == "max" else 1
    ints[H_IMPL] = 0 if system.implication == "min" else 1
    ints[H_AGG] = _AGG[system.aggregation]
    ints[H_DEFUZZ] = _DEFUZZ[system.defuzzifier]
    ints[H_STACK] = stack + 1
    ints[H_FVARS] = fvars
    ints[H_FLAT] = flat
    ints[H_MAXITEMS] = max_items
    ints[H_FWEIGHT] = 0
    ints[H_IWORK] = max_items + len(system.rules) + n_terms + n_in
    pivot = _pivot_table(system, flat, var_tab)
    grid = _grid_table(system, flat)
    body: list[int] = []
    for key, tab in ((H_VARS, var_tab), (H_TERMS, term_tab), (H_RULES, rule_tab),
                     (H_PROG, prog), (H_CONS, cons), (H_OUTS, out_tab), (H_FLATOFF, flat_tab),
                     (H_PIVOT, pivot), (H_GRID, grid)):
        ints[key] = _HEADER + len(body)
        body += tab
    if not pivot:
        ints[H_PIVOT] = -1
    if not grid:
        ints[H_GRID] = -1
    # the fast path of rule tables over fuzzy partitions (fuzzy/partition.py), when it applies
    part = partition_tables(system, out_lines) if len(out_lines) == n_out else None
    ints[H_PART] = ints[H_PARTF] = -1
    if part is not None:
        ints[H_PART] = _HEADER + len(body)
        body += part[0]
        ints[H_PARTF] = len(fl)
        fl += part[1]
    for pos, sup in sup_lists:
        body[ints[H_OUTS] - _HEADER + pos] = _HEADER + len(body)
        body += sup
    n_cand = 2 + 2 * max_items + 3 * max_items * max_items
    ints[H_WORK] = _work_size(n_in, n_terms, len(system.rules), stack + 1, max_items, max_bp,
                              n_cand)
    if part is not None:
        pw, piw = scratch_sizes(system)
        ints[H_WORK] += pw  # partition scratch after the general layout (rest)
        ints[H_IWORK] = max(ints[H_IWORK], piw)
    return CompiledSystem(system=system, ints=np.array(ints + body, dtype=np.int64),
                          floats=np.array(fl, dtype=np.float64))


def _pivot_table(system: FuzzySystem, flat: int, var_tab: list[int]) -> list[int]:
    """For a flat-AND rule base in which every rule names one input p: [p, n_terms_p, then
    (start, count) per term of p, then the rule indices naming each term]. The strengths
    then visit only the rules of p's non-zero terms. Empty if there is no such input."""
    if flat != 1 or not system.rules:
        return []
    for p in range(len(system.inputs)):
        lists: list[list[int]] = [[] for _ in system.inputs[p].terms]
        ok = True
        for r, rule in enumerate(system.rules):
            a = rule.antecedent
            clauses = [a] if isinstance(a, Is) else list(a.operands)  # type: ignore[union-attr]
            hit = [c for c in clauses if isinstance(c, Is) and c.variable == p]
            if len(hit) != 1 or hit[0].negated:
                ok = False
                break
            lists[hit[0].term].append(r)
        if ok:
            n_t = len(lists)
            tab = [p, n_t]
            start = 2 + 2 * n_t
            idx: list[int] = []
            for lst in lists:
                tab += [start + len(idx), len(lst)]
                idx += lst
            return tab + idx
    return []


def _grid_table(system: FuzzySystem, flat: int) -> list[int]:
    """Dense rule index for a flat-AND rule base whose every rule names every input (a rule
    table): [n_cells, stride per input, (start, count) per cell, rule indices]. The strengths
    then visit only the cells of the inputs' non-zero terms. Empty if not applicable."""
    if flat != 1 or not system.rules:
        return []
    n_in = len(system.inputs)
    strides = []
    cells = 1
    for v in system.inputs:
        strides.append(cells)
        cells *= len(v.terms)
        if cells > GRID_MAX_CELLS:
            return []
    lists: list[list[int]] = [[] for _ in range(cells)]
    for r, rule in enumerate(system.rules):
        a = rule.antecedent
        clauses = [a] if isinstance(a, Is) else list(a.operands)  # type: ignore[union-attr]
        if len(clauses) != n_in or any(not isinstance(c, Is) or c.negated for c in clauses):
            return []
        cell = sum(strides[c.variable] * c.term for c in clauses if isinstance(c, Is))
        lists[cell].append(r)
    tab = [cells, *strides]
    start = 1 + n_in + 2 * cells
    idx: list[int] = []
    for lst in lists:
        tab += [start + len(idx), len(lst)]
        idx += lst
    return tab + idx


def _work_size(n_in: int, n_terms: int, n_rules: int, stack: int, items: int, n_bp: int,
               n_cand: int) -> int:
    n_seg = 2 * max(n_bp - 1, 1) * n_cand
    # eval_point: xin, mu, w, stack, hts, h, then lines c, m, hh (3 items), candidates, pieces
    return (n_in + n_terms + n_rules + stack + 5 * items + n_cand + 4 * n_seg + 64)


# ---------------------------------------------------------------------------------------------
# rule strengths


@kernel(inline=True, error_model="numpy")
def _strengths(ints: IntArray, f: FloatArray, xin: FloatArray, mu: FloatArray,
               w: FloatArray, stk: FloatArray, fired: IntArray, nz: IntArray) -> int:
    """Input memberships mu (global term index), rule strengths w (weight applied) and the
    list of rules that fired (w > 0); returns their number. w is valid for fired rules."""
    n_in = ints[H_NIN]
    vt = ints[H_VARS]
    tt = ints[H_TERMS]
    for i in range(n_in):
        first = ints[vt + 2 * i]
        for t in range(first, first + ints[vt + 2 * i + 1]):
            mu[t] = mf_value(ints[tt + 3 * t], f, ints[tt + 3 * t + 1], ints[tt + 3 * t + 2],
                             xin[i])
    n_rules = ints[H_NRULES]
    rt = ints[H_RULES]
    and_op = ints[H_AND]
    or_op = ints[H_OR]
    flat = ints[H_FLAT]
    nf = 0
    gt = ints[H_GRID]
    if gt >= 0:
        # a rule table: visit the cells of the non-zero terms (odometer over the inputs)
        # nz[0:n_in] = number of non-zero terms per input, then their local indices
        pos = n_in
        for i in range(n_in):
            first = ints[vt + 2 * i]
            cnt = 0
            for tl in range(ints[vt + 2 * i + 1]):
                if mu[first + tl] > 0.0:
                    nz[pos + cnt] = tl
                    cnt += 1
            if cnt == 0:
                return 0
            nz[i] = cnt
            pos += cnt
        # every combination of non-zero terms, as a mixed-radix counter
        total = 1
        for i in range(n_in):
            total *= nz[i]
        for combo in range(total):
            rem = combo
            pos = n_in
            cell = 0
            acc = 1.0
            for i in range(n_in):
                d = rem % nz[i]
                rem //= nz[i]
                tl = nz[pos + d]
                pos += nz[i]
                cell += ints[gt + 1 + i] * tl
                v = mu[ints[vt + 2 * i] + tl]
                if and_op == 0:
                    if v < acc:
                        acc = v
                else:
                    acc *= v
            ce = gt + 1 + n_in + 2 * cell
            st = gt + ints[ce]
            for q in range(ints[ce + 1]):
                r = ints[st + q]
                wr = acc * f[ints[H_FWEIGHT] + r]
                if wr > 0.0:
                    w[r] = wr
                    fired[nf] = r
                    nf += 1
        return nf
    pv = ints[H_PIVOT]
    if pv >= 0:
        # flat AND with a pivot input named by every rule: only its non-zero terms' rules
        fo = ints[H_FLATOFF]
        p = ints[pv]
        first_p = ints[vt + 2 * p]
        for tl in range(ints[pv + 1]):
            if mu[first_p + tl] <= 0.0:
                continue
            st = pv + ints[pv + 2 + 2 * tl]
            for q in range(ints[pv + 3 + 2 * tl]):
                r = ints[st + q]
                row = fo + 2 * n_in * r
                acc = 1.0
                for i in range(n_in):
                    t = ints[row + i]
                    if t < 0:
                        continue
                    v = mu[t]
                    if ints[row + n_in + i] != 0:
                        v = 1.0 - v
                    if and_op == 0:
                        if v < acc:
                            acc = v
                    else:
                        acc *= v
                    if acc <= 0.0:
                        break
                if acc > 0.0:
                    acc *= f[ints[H_FWEIGHT] + r]
                    if acc > 0.0:
                        w[r] = acc
                        fired[nf] = r
                        nf += 1
        return nf
    if flat != 0:
        fo = ints[H_FLATOFF]
        for r in range(n_rules):
            row = fo + 2 * n_in * r
            if flat == 1:
                acc = 1.0
                for i in range(n_in):
                    t = ints[row + i]
                    if t < 0:
                        continue
                    v = mu[t]
                    if ints[row + n_in + i] != 0:
                        v = 1.0 - v
                    if and_op == 0:
                        if v < acc:
                            acc = v
                    else:
                        acc *= v
                    if acc <= 0.0:
                        acc = 0.0
                        break
            else:
                acc = 0.0
                for i in range(n_in):
                    t = ints[row + i]
                    if t < 0:
                        continue
                    v = mu[t]
                    if ints[row + n_in + i] != 0:
                        v = 1.0 - v
                    if or_op == 0:
                        if v > acc:
                            acc = v
                    else:
                        acc = _probor(acc, v)
            w[r] = acc * f_weight(ints, f, r)
            if w[r] > 0.0:
                fired[nf] = r
                nf += 1
        return nf
    pg = ints[H_PROG]
    for r in range(n_rules):
        start = pg + ints[rt + 4 * r]
        end = start + ints[rt + 4 * r + 1]
        sp = 0
        k = start
        while k < end:
            op = ints[k]
            if op == _OP_IS:
                v = mu[ints[k + 2]]
                if ints[k + 3] != 0:
                    v = 1.0 - v
                stk[sp] = v
                sp += 1
                k += 4
            elif op == _OP_NOT:
                stk[sp - 1] = 1.0 - stk[sp - 1]
                k += 1
            else:
                cnt = ints[k + 1]
                base = sp - cnt
                acc = stk[base]
                for j in range(base + 1, sp):
                    v = stk[j]
                    if op == _OP_AND:
                        acc = min(acc, v) if and_op == 0 else acc * v
                    else:
                        acc = max(acc, v) if or_op == 0 else _probor(acc, v)
                stk[base] = acc
                sp = base + 1
                k += 2
        w[r] = stk[0] * f_weight(ints, f, r)
        if w[r] > 0.0:
            fired[nf] = r
            nf += 1
    return nf


@kernel(inline=True)
def _probor(a: float, b: float) -> float:
    """a + b - a b, exact at the ends: 1 - (1 - a)(1 - b) once either is >= 1/2 (so that
    probor(1, b) is 1 and NOT of it 0, whatever b), else the sum form (no loss for small
    values)."""
    if a >= 0.5 or b >= 0.5:
        return 1.0 - (1.0 - a) * (1.0 - b)
    return a + b - a * b


@kernel(inline=True)
def f_weight(ints: IntArray, f: FloatArray, r: int) -> float:
    """Weight of rule r."""
    return f[ints[H_FWEIGHT] + r]


# ---------------------------------------------------------------------------------------------
# the items of one output: (term, height) pairs whose implied sets are aggregated


@kernel(inline=True)
def _items(ints: IntArray, w: FloatArray, fired: IntArray, nf: int, o: int, hts: FloatArray,
           lab: IntArray, h: FloatArray) -> int:
    """Fill lab/h with the output-o items that fired; return their number.

    Max aggregation: one item per term, its height the largest strength of the rules naming it
    (max of min/product implications = implication of the max). Other aggregations: one item
    per (rule, consequent)."""
    n_t = ints[ints[H_OUTS] + _OUT_FIELDS * o + 5]
    rt = ints[H_RULES]
    ct = ints[H_CONS]
    n = 0
    if ints[H_AGG] == 0:
        for j in range(n_t):
            hts[j] = 0.0
        for q in range(nf):
            r = fired[q]
            c0 = ct + ints[rt + 4 * r + 2]
            for c in range(ints[rt + 4 * r + 3]):
                if ints[c0 + 2 * c] == o:
                    j = ints[c0 + 2 * c + 1]
                    if w[r] > hts[j]:
                        hts[j] = w[r]
        for j in range(n_t):
            if hts[j] > 0.0:
                lab[n] = j
                h[n] = hts[j]
                n += 1
        return n
    for q in range(nf):
        r = fired[q]
        c0 = ct + ints[rt + 4 * r + 2]
        for c in range(ints[rt + 4 * r + 3]):
            if ints[c0 + 2 * c] == o:
                lab[n] = ints[c0 + 2 * c + 1]
                h[n] = w[r]
                n += 1
    return n


# ---------------------------------------------------------------------------------------------
# piecewise-linear outputs: exact


@kernel(inline=True)
def _agg_lines(y: float, na: int, c: FloatArray, m: FloatArray, hh: FloatArray, impl: int,
               agg: int) -> tuple[float, float]:
    """(aggregate, unclamped sum) at y of the na lines c + m y clipped / scaled by hh."""
    best = 0.0
    total = 0.0
    for i in range(na):
        line = c[i] + m[i] * y
        if line < 0.0:
            line = 0.0
        if impl == 0 and abs(line - hh[i]) <= 1e-15 * (abs(c[i]) + abs(m[i] * y)):
            # the clip crossing: c + m y is hh up to its rounding (eps |c|, a large relative
            # error when hh is small), so the plateau it ends stays flat
            line = hh[i]
        fv = min(hh[i], line) if impl == 0 else hh[i] * line
        total += fv
        if fv > best:
            best = fv
    if agg == 0:
        return best, best
    if agg == 1:
        return min(1.0, total), total
    return total, total


@kernel(inline=True)
def _pl_segments(n_items: int, lab: IntArray, h: FloatArray, f: FloatArray, bp_off: int,
                 k0: int, k1: int, s_off: int, i_off: int, n_t: int, impl: int, agg: int,
                 c: FloatArray, m: FloatArray, hh: FloatArray, cand: FloatArray,
                 su: FloatArray, sv: FloatArray, gu: FloatArray, gv: FloatArray) -> int:
    """Exact linear pieces (su, sv, gu, gv) of the aggregate on the intervals k0..k1 of the
    breakpoints (the support of the fired terms); returns their number."""
    n_seg = 0
    for k in range(k0, k1 + 1):
        p = f[bp_off + k]
        q = f[bp_off + k + 1]
        na = 0
        for i in range(n_items):
            j = lab[i]
            mm = f[s_off + k * n_t + j]
            cc = f[i_off + k * n_t + j]
            if mm == 0.0 and cc <= 0.0:
                continue
            c[na] = cc
            m[na] = mm
            hh[na] = h[i]
            na += 1
        if na == 0:
            continue
        cand[0] = p
        cand[1] = q
        nc = 2
        for i in range(na):
            if m[i] != 0.0:
                y = -c[i] / m[i]
                if p < y < q:
                    nc = insort(cand, nc, y)
                if impl == 0:
                    y = (hh[i] - c[i]) / m[i]
                    if p < y < q:
                        nc = insort(cand, nc, y)
            if agg == 0:
                for jj in range(na):
                    if jj == i:
                        continue
                    if impl == 0:
                        if m[i] != 0.0:
                            y = (hh[jj] - c[i]) / m[i]
                            if p < y < q:
                                nc = insort(cand, nc, y)
                        if jj > i and m[i] != m[jj]:
                            y = (c[jj] - c[i]) / (m[i] - m[jj])
                            if p < y < q:
                                nc = insort(cand, nc, y)
                    elif jj > i:
                        di = hh[i] * m[i] - hh[jj] * m[jj]
                        if di != 0.0:
                            y = (hh[jj] * c[jj] - hh[i] * c[i]) / di
                            if p < y < q:
                                nc = insort(cand, nc, y)
        # the interval's lines give the one-sided values at p and q and are continuous inside,
        # so one evaluation per candidate serves both pieces that meet there
        au, tu = _agg_lines(cand[0], na, c, m, hh, impl, agg)
        for t in range(nc - 1):
            u = cand[t]
            v = cand[t + 1]
            if v <= u:
                continue
            av, tv = _agg_lines(v, na, c, m, hh, impl, agg)
            if au == 0.0 and av == 0.0:
                au = av
                tu = tv
                continue
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
            au = av
            tu = tv
    return n_seg


@kernel(inline=True)
def _point_x(code: int, f: FloatArray, off: int) -> float:
    """Where a zero-width term sits (triangle a = c, trapezoid a = d; shapes.point_of), NaN
    for any other term."""
    if code == _TRI and f[off] == f[off + 2]:
        return f[off]
    if code == _TRAP and f[off] == f[off + 3]:
        return f[off]
    return np.nan


@kernel(inline=True)
def _pl_points(ints: IntArray, f: FloatArray, o: int, n_items: int, lab: IntArray,
               h: FloatArray, px: FloatArray, pv: FloatArray) -> int:
    """The zero-width items of output o inside its range: their places (px) and the
    aggregate there (pv: every item's exact membership at that point, aggregated). The linear
    pieces cannot hold them (they have no width); the maxima methods read them."""
    n_in = ints[H_NIN]
    fv = ints[H_FVARS] + 4 * (n_in + o)
    tt = ints[H_TERMS]
    first = ints[ints[H_VARS] + 2 * (n_in + o)]
    n = 0
    for i in range(n_items):
        t = first + lab[i]
        x0 = _point_x(ints[tt + 3 * t], f, ints[tt + 3 * t + 1])
        if x0 == x0 and f[fv] <= x0 <= f[fv + 1]:
            px[n] = x0
            pv[n] = _g(x0, ints, f, first, n_items, lab, h)
            n += 1
    return n


@kernel(inline=True)
def _defuzz_segments(n_seg: int, su: FloatArray, sv: FloatArray, gu: FloatArray,
                     gv: FloatArray, mode: int, px: FloatArray, pv: FloatArray,
                     n_pt: int) -> float:
    """Centroid (0), bisector (1), mean (2), smallest (3) or largest (4) of maximum of a
    piecewise-linear function given by its pieces and by n_pt isolated points (px, pv: the
    zero-width terms, no area, read by the maxima only); NaN for zero area (centroid,
    bisector) or a zero maximum."""
    area = 0.0
    moment = 0.0
    gmax = 0.0
    ref = su[0] if n_seg > 0 else 0.0
    # the moment in units of the span (a product of two abscissae overflows past 1e154)
    span = sv[n_seg - 1] - ref if n_seg > 0 else 1.0
    if not span > 0.0:
        span = 1.0
    for s in range(n_seg):
        u = (su[s] - ref) / span
        v = (sv[s] - ref) / span
        moment += (v - u) * (u * (2.0 * gu[s] + gv[s]) + v * (gu[s] + 2.0 * gv[s])) / 6.0
        area += 0.5 * (sv[s] - su[s]) * (gu[s] + gv[s])
        gmax = max(gmax, gu[s], gv[s])
    gpt = 0.0
    for i in range(n_pt):
        gpt = max(gpt, pv[i])
    if not area > 0.0 and (mode <= 1 or not gpt > 0.0):
        return np.nan
    if mode == 0:
        return ref + span * (moment * span) / area
    if mode == 1:
        # in units of the largest value: the quadratic squares the values (no underflow)
        sc = 1.0 / gmax
        half = 0.5 * area * sc
        acc = 0.0
        for s in range(n_seg):
            u = su[s]
            v = sv[s]
            a = gu[s] * sc
            b = gv[s] * sc
            seg = 0.5 * (v - u) * (a + b)
            if acc + seg >= half and seg > 0.0:
                need = half - acc
                length = v - u
                sl = (b - a) / length
                if abs(sl) * length <= 1e-14 * max(a, b):
                    return u + need / (0.5 * (a + b))
                disc = a * a + 2.0 * sl * need
                t_root = 2.0 * need / (a + math.sqrt(max(disc, 0.0)))
                return u + min(max(t_root, 0.0), length)
            acc += seg
        return sv[n_seg - 1]
    # the maximum over the pieces and the points (gmax itself without zero-width terms)
    gmax = max(gmax, gpt)
    tol = 1e-12 * gmax
    if mode == 2:
        plen = 0.0
        pmom = 0.0
        # a plateau shorter than 1e-12 of the support is a peak's rounding (the clip point of
        # a line through the peak lands 1e-16 beside it), not a set of positive length
        minlen = 1e-12 * (sv[n_seg - 1] - su[0]) if n_seg > 0 else 0.0
        for s in range(n_seg):
            if gu[s] >= gmax - tol and gv[s] >= gmax - tol and sv[s] - su[s] > minlen:
                plen += sv[s] - su[s]
                pmom += 0.5 * (sv[s] - su[s]) * (sv[s] + su[s])
        if plen > 0.0:
            return pmom / plen
        cnt = 0
        tot = 0.0
        last = -np.inf
        for s in range(n_seg):
            if gu[s] >= gmax - tol and su[s] > last + minlen:
                cnt += 1
                tot += su[s]
                last = su[s]
            if gv[s] >= gmax - tol and sv[s] > last + minlen:
                cnt += 1
                tot += sv[s]
                last = sv[s]
        # the maximising points of zero width, each place once (a piece's end there is one)
        for i in range(n_pt):
            if pv[i] < gmax - tol:
                continue
            seen = False
            for j in range(i):
                if pv[j] >= gmax - tol and px[j] == px[i]:
                    seen = True
            for s in range(n_seg):
                if (gu[s] >= gmax - tol and abs(su[s] - px[i]) <= minlen) or \
                        (gv[s] >= gmax - tol and abs(sv[s] - px[i]) <= minlen):
                    seen = True
            if not seen:
                cnt += 1
                tot += px[i]
        return tot / cnt
    best = np.nan
    if mode == 3:
        for s in range(n_seg):
            if gu[s] >= gmax - tol:
                best = su[s]
                break
            if gv[s] >= gmax - tol:
                best = sv[s]
                break
        for i in range(n_pt):
            if pv[i] >= gmax - tol and not px[i] >= best:
                best = px[i]
        return best
    for s in range(n_seg - 1, -1, -1):
        if gv[s] >= gmax - tol:
            best = sv[s]
            break
        if gu[s] >= gmax - tol:
            best = su[s]
            break
    for i in range(n_pt):
        if pv[i] >= gmax - tol and not px[i] <= best:
            best = px[i]
    return best


# ---------------------------------------------------------------------------------------------
# singleton outputs


@kernel
def _singletons(ints: IntArray, f: FloatArray, o: int, n_items: int, lab: IntArray,
                h: FloatArray, hts: FloatArray, mode: int) -> float:
    """COGS and the maxima of singleton outputs (heights aggregated per singleton)."""
    n_t = ints[ints[H_OUTS] + _OUT_FIELDS * o + 5]
    agg = ints[H_AGG]
    impl = ints[H_IMPL]
    tt = ints[H_TERMS]
    first = ints[ints[H_VARS] + 2 * (ints[H_NIN] + o)]
    for j in range(n_t):
        hts[j] = 0.0
    for i in range(n_items):
        j = lab[i]
        off = ints[tt + 3 * (first + j) + 1]
        # the implication of the strength with the singleton's membership, its height
        v = min(h[i], f[off + 1]) if impl == 0 else h[i] * f[off + 1]
        if agg == 0:
            hts[j] = max(hts[j], v)
        elif agg == 1:
            hts[j] = min(1.0, hts[j] + v)
        elif agg == 2:
            hts[j] += v
        else:
            hts[j] = _probor(hts[j], v)
    num = 0.0
    den = 0.0
    gmax = 0.0
    for j in range(n_t):
        off = ints[tt + 3 * (first + j) + 1]
        num += hts[j] * f[off]
        den += hts[j]
        gmax = max(gmax, hts[j])
    if not den > 0.0:
        return np.nan
    if mode == 0:
        return num / den
    best_lo = np.inf
    best_hi = -np.inf
    tot = 0.0
    cnt = 0
    for j in range(n_t):
        if hts[j] >= gmax * (1.0 - 1e-12) and hts[j] > 0.0:
            x = f[ints[tt + 3 * (first + j) + 1]]
            best_lo = min(best_lo, x)
            best_hi = max(best_hi, x)
            # the mean of the maximising points: a position held by an earlier term once
            seen = False
            for jj in range(j):
                if hts[jj] >= gmax * (1.0 - 1e-12) and hts[jj] > 0.0 and \
                        f[ints[tt + 3 * (first + jj) + 1]] == x:
                    seen = True
                    break
            if not seen:
                tot += x
                cnt += 1
    if mode == 2:
        return tot / cnt
    return best_lo if mode == 3 else best_hi


# ---------------------------------------------------------------------------------------------
# smooth outputs: pieces located, adaptive Gauss-Kronrod


@kernel(error_model="numpy")
def _g(y: float, ints: IntArray, f: FloatArray, first: int, n_items: int, lab: IntArray,
       h: FloatArray) -> float:
    """The aggregate at y."""
    tt = ints[H_TERMS]
    impl = ints[H_IMPL]
    agg = ints[H_AGG]
    acc = 0.0
    for i in range(n_items):
        t = first + lab[i]
        mu = mf_value(ints[tt + 3 * t], f, ints[tt + 3 * t + 1], ints[tt + 3 * t + 2], y)
        v = min(h[i], mu) if impl == 0 else h[i] * mu
        if agg == 0:
            if v > acc:
                acc = v
        elif agg == 3:
            acc = _probor(acc, v)
        else:
            acc += v
    if agg == 1 and acc > 1.0:
        acc = 1.0
    return acc


@kernel(error_model="numpy")
def _signature(y: float, ints: IntArray, f: FloatArray, first: int, n_items: int,
               lab: IntArray, h: FloatArray) -> int:
    """Which smooth piece y lies on: the largest item (max), the clipped items, saturation."""
    tt = ints[H_TERMS]
    impl = ints[H_IMPL]
    agg = ints[H_AGG]
    key = 0
    best = -1.0
    arg = 0
    total = 0.0
    for i in range(n_items):
        t = first + lab[i]
        code = ints[tt + 3 * t]
        off = ints[tt + 3 * t + 1]
        mu = mf_value(code, f, off, ints[tt + 3 * t + 2], y)
        # strictly above: a rule of strength 1 clips a term of height 1 nowhere, though mu
        # rounds to 1 on the float-flat shoulders of a plateau (smf is 1 - 2 t^2 there)
        clipped = impl == 0 and mu > h[i]
        v = min(h[i], mu) if impl == 0 else h[i] * mu
        total += v
        if v > best:
            best = v
            arg = i
        # a dsigmoid |sig1 - sig2| bends where its sigmoids cross (at no parameter)
        bend = code == _DSIG and _sigmoid(y, f[off], f[off + 1]) >= \
            _sigmoid(y, f[off + 3], f[off + 2])
        key = key * 1000003 + (1 if clipped else 0) + (2 if mu > 0.0 else 0) + \
            (4 if bend else 0)
    if agg == 0:
        key = key * 1000003 + arg
    elif agg == 1:
        key = key * 1000003 + (1 if total >= 1.0 else 0)
    return key


@kernel
def _knots(code: int, f: FloatArray, off: int, n: int, lo: float, hi: float, buf: FloatArray,
           k: int) -> int:
    """Add to buf the points inside (lo, hi) where a term is not smooth or peaks."""
    if code == _DISC:
        for i in range(n // 2):
            x = f[off + 2 * i]
            if lo < x < hi:
                buf[k] = x
                k += 1
        return k
    cnt = n
    if code == _BELL or code == _GAUSS or code == _SING:
        cnt = 1
    elif code == _SIG:
        cnt = 1
    for i in range(cnt):
        x = f[off + i]
        if code == _GAUSS2 and i % 2 == 1:
            continue
        if (code == _DSIG or code == _PSIG) and (i == 1 or i == 2):
            continue
        if code == _SIG and i == 1:
            continue
        if lo < x < hi:
            buf[k] = x
            k += 1
    if code == _S or code == _Z or code == _PI:
        for i in range(0, n, 2):
            x = 0.5 * (f[off + i] + f[off + i + 1])
            if lo < x < hi:
                buf[k] = x
                k += 1
    return k


@kernel(error_model="numpy")
def _gk(a: float, b: float, c0: float, ints: IntArray, f: FloatArray, first: int,
        n_items: int, lab: IntArray, h: FloatArray, xgk: FloatArray, wgk: FloatArray,
        wg: FloatArray) -> tuple[float, float, float, float]:
    """(K15 area, G7 area, K15 moment, G7 moment) of g and (y - c0) g on [a, b]."""
    hl = 0.5 * (b - a)
    cen = 0.5 * (a + b)
    gc = _g(cen, ints, f, first, n_items, lab, h)
    ka = wgk[7] * gc
    ga = wg[3] * gc
    # the moment of (y - c0) / (b - a) (no overflow for abscissae past 1e154): the caller
    # multiplies by the interval's width
    inv = 1.0 / (b - a)
    km = wgk[7] * gc * (cen - c0) * inv
    gm = wg[3] * gc * (cen - c0) * inv
    for j in range(7):
        dx = hl * xgk[j]
        y1 = cen - dx
        y2 = cen + dx
        g1 = _g(y1, ints, f, first, n_items, lab, h)
        g2 = _g(y2, ints, f, first, n_items, lab, h)
        ka += wgk[j] * (g1 + g2)
        km += wgk[j] * (g1 * (y1 - c0) + g2 * (y2 - c0)) * inv
        if j % 2 == 1:
            ga += wg[j // 2] * (g1 + g2)
            gm += wg[j // 2] * (g1 * (y1 - c0) + g2 * (y2 - c0)) * inv
    return ka * hl, ga * hl, km * hl, gm * hl


@kernel(error_model="numpy")
def _golden_max(a: float, b: float, span: float, ints: IntArray, f: FloatArray, first: int,
                n_items: int, lab: IntArray, h: FloatArray) -> float:
    """Golden-section search for the maximum of the aggregate on [a, b]."""
    invphi = (math.sqrt(5.0) - 1.0) / 2.0
    x1 = b - invphi * (b - a)
    x2 = a + invphi * (b - a)
    f1 = _g(x1, ints, f, first, n_items, lab, h)
    f2 = _g(x2, ints, f, first, n_items, lab, h)
    aa = a
    bb = b
    for _ in range(200):
        if bb - aa <= 1e-15 * span:
            break
        if f1 < f2:
            aa = x1
            x1 = x2
            f1 = f2
            x2 = aa + invphi * (bb - aa)
            f2 = _g(x2, ints, f, first, n_items, lab, h)
        else:
            bb = x2
            x2 = x1
            f2 = f1
            x1 = bb - invphi * (bb - aa)
            f1 = _g(x1, ints, f, first, n_items, lab, h)
    return 0.5 * (aa + bb)


@kernel(error_model="numpy")
def _newton_max(x: float, d: float, d2: float, ints: IntArray, f: FloatArray, first: int,
                n_items: int, lab: IntArray, h: FloatArray) -> tuple[float, bool]:
    """Newton steps from x on the Richardson-extrapolated central difference of step d (the
    second derivative d2 < 0 held fixed); (root, whether the steps converged)."""
    xn = x
    for _ in range(8):
        g1 = (_g(xn + d, ints, f, first, n_items, lab, h)
              - _g(xn - d, ints, f, first, n_items, lab, h)) / (2.0 * d)
        g2 = (_g(xn + 0.5 * d, ints, f, first, n_items, lab, h)
              - _g(xn - 0.5 * d, ints, f, first, n_items, lab, h)) / d
        step = -((4.0 * g2 - g1) / 3.0) / d2
        xn += step
        if abs(step) <= 1e-3 * d:
            return xn, True
    return xn, False


@kernel(error_model="numpy")
def _refine_max(x: float, a: float, b: float, span: float, ints: IntArray, f: FloatArray,
                first: int, n_items: int, lab: IntArray, h: FloatArray) -> float:
    """Newton steps on the derivative (central differences, Richardson-extrapolated) from a
    maximum x found in [a, b] by comparing values. A quadratic maximum moves to the
    derivative's zero; at a kink, on a plateau or on a flat top x is kept (as it is when a step
    lowers the value)."""
    gx = _g(x, ints, f, first, n_items, lab, h)
    if not gx > 0.0:
        return x
    # the step: from a quarter of the bracket down until the second difference is the same
    # at half the step (the quadratic part of a smooth maximum); a kink (it doubles) or a
    # flat top like a steep bell's (it grows by 2^(p-2)) never gets there before rounding
    # dominates: keep x
    d = 0.25 * (b - a)
    d2 = 0.0
    quadratic = False
    for _ in range(12):
        d2 = (_g(x + d, ints, f, first, n_items, lab, h) - 2.0 * gx
              + _g(x - d, ints, f, first, n_items, lab, h)) / (d * d)
        d2h = (_g(x + 0.5 * d, ints, f, first, n_items, lab, h) - 2.0 * gx
               + _g(x - 0.5 * d, ints, f, first, n_items, lab, h)) / (0.25 * d * d)
        if not (d2 < 0.0 and d2h < 0.0) or 16e-16 * gx / (0.25 * d * d) > 1e-3 * -d2h:
            return x
        if abs(d2h - d2) <= 1e-2 * -d2:
            quadratic = True
            break
        d *= 0.1
    if not quadratic:
        return x
    # Newton's roots at steps d and 2 d: the Richardson step leaves a bias d^4 g^(5) / 480
    # (large near a steep bell's centre), 16 times larger at 2 d, so their difference is 15
    # times the bias at d; refine d until that is below tol_x (1e-11 of the range), keep x
    # once rounding (its share, about eps g / (d |g''|)) would decide
    tol_x = 1e-11 * span
    while True:
        if 2e-16 * gx / (d * -d2) > tol_x:
            return x
        xn, converged = _newton_max(x, d, d2, ints, f, first, n_items, lab, h)
        x2, converged2 = _newton_max(x, 2.0 * d, d2, ints, f, first, n_items, lab, h)
        if not (converged and converged2):
            return x
        if abs(xn - x2) <= 15.0 * tol_x:
            break
        d *= 0.1
    xn = min(max(xn, a), b)  # past the bracket: the maximum is at its end (a cut) or beyond
    if _g(xn, ints, f, first, n_items, lab, h) < gx - 4e-16 * gx:
        return x
    return xn


@kernel(error_model="numpy")
def _smooth(ints: IntArray, f: FloatArray, o: int, n_items: int, lab: IntArray, h: FloatArray,
            mode: int, xgk: FloatArray, wgk: FloatArray, wg: FloatArray) -> float:
    """Defuzzified smooth aggregate of output o (NaN if empty)."""
    n_in = ints[H_NIN]
    fv = ints[H_FVARS] + 4 * (n_in + o)
    lo = f[fv]
    hi = f[fv + 1]
    tt = ints[H_TERMS]
    first = ints[ints[H_VARS] + 2 * (n_in + o)]
    # knots of the fired terms
    nk_max = 2
    for i in range(n_items):
        nk_max += ints[tt + 3 * (first + lab[i]) + 2] + 4
    knots = np.empty(nk_max)
    knots[0] = lo
    knots[1] = hi
    nk = 2
    for i in range(n_items):
        t = first + lab[i]
        nk = _knots(ints[tt + 3 * t], f, ints[tt + 3 * t + 1], ints[tt + 3 * t + 2], lo, hi,
                    knots, nk)
    knots = np.sort(knots[:nk])
    # pieces: the knots, and the points where the signature changes on a scan (bisected)
    cuts = np.empty(nk * (CELL_CHANGES * SCAN_CELLS + 1) + 2)
    nc = 0
    for k in range(nk - 1):
        p = knots[k]
        q = knots[k + 1]
        if not q > p:
            continue
        cuts[nc] = p
        nc += 1
        dy = (q - p) / SCAN_CELLS
        ya = p + 0.5 * dy * 1e-9
        sa = _signature(ya, ints, f, first, n_items, lab, h)
        for s in range(1, SCAN_CELLS + 1):
            yb = p + s * dy if s < SCAN_CELLS else q - 0.5 * dy * 1e-9
            sb = _signature(yb, ints, f, first, n_items, lab, h)
            # every change inside the cell: bisect to the first, then go on from it
            sc = sa
            yc = ya
            for _ in range(CELL_CHANGES):
                if sb == sc:
                    break
                a = yc
                b = yb
                for _ in range(200):
                    mid = 0.5 * (a + b)
                    if mid <= a or mid >= b:
                        break
                    if _signature(mid, ints, f, first, n_items, lab, h) == sc:
                        a = mid
                    else:
                        b = mid
                cuts[nc] = 0.5 * (a + b)
                nc += 1
                yc = b
                sc = _signature(yc, ints, f, first, n_items, lab, h)
            ya = yb
            sa = sb
    cuts[nc] = knots[nk - 1]
    nc += 1
    c0 = 0.5 * (lo + hi)
    # first pass: K15 on every piece for the scale of the area
    a0 = 0.0
    for k in range(nc - 1):
        if cuts[k + 1] > cuts[k]:
            ka, _, _, _ = _gk(cuts[k], cuts[k + 1], c0, ints, f, first, n_items, lab, h, xgk,
                              wgk, wg)
            a0 += abs(ka)
    if not a0 > 0.0:
        # no area: no centroid or bisector; the maxima are the fired zero-width terms' points
        # (none fired: NaN, as before they were accepted)
        if mode <= 1:
            return np.nan
        px = np.empty(n_items)
        pv = np.empty(n_items)
        n_pt = _pl_points(ints, f, o, n_items, lab, h, px, pv)
        return _defuzz_segments(0, px, px, pv, pv, mode, px, pv, n_pt)
    span = hi - lo
    cap = QUAD_MAX_SUB * (nc + 1)
    acc_a = np.empty(cap)
    acc_b = np.empty(cap)
    acc_area = np.empty(cap)
    n_acc = 0
    stack_a = np.empty(256)
    stack_b = np.empty(256)
    area = 0.0
    mom = 0.0
    for k in range(nc - 1):
        if not cuts[k + 1] > cuts[k]:
            continue
        sp = 0
        stack_a[0] = cuts[k]
        stack_b[0] = cuts[k + 1]
        sp = 1
        while sp > 0:
            sp -= 1
            a = stack_a[sp]
            b = stack_b[sp]
            ka, ga, km, gm = _gk(a, b, c0, ints, f, first, n_items, lab, h, xgk, wgk, wg)
            tol = QUAD_RTOL * a0 * (b - a) / span
            # km, gm: moments of (y - c0) / (b - a); tol span / (b - a) is QUAD_RTOL a0
            ok = abs(ka - ga) <= tol and abs(km - gm) <= QUAD_RTOL * a0
            mid = 0.5 * (a + b)
            if ok or sp >= 254 or n_acc >= cap or not (a < mid < b):
                area += ka
                mom += km * ((b - a) / span)  # in units of the span
                if n_acc == acc_a.shape[0]:
                    # past the subdivision budget every interval left on the stack is
                    # accepted: the record of accepted intervals grows instead of overflowing
                    grown = np.empty(2 * n_acc)
                    grown[:n_acc] = acc_a
                    acc_a = grown
                    grown = np.empty(2 * n_acc)
                    grown[:n_acc] = acc_b
                    acc_b = grown
                    grown = np.empty(2 * n_acc)
                    grown[:n_acc] = acc_area
                    acc_area = grown
                acc_a[n_acc] = a
                acc_b[n_acc] = b
                acc_area[n_acc] = ka
                n_acc += 1
            else:
                stack_a[sp] = mid
                stack_b[sp] = b
                stack_a[sp + 1] = a
                stack_b[sp + 1] = mid
                sp += 2
    if not area > 0.0:
        return np.nan
    if mode == 0:
        return c0 + span * (mom / area)
    if mode == 1:
        half = 0.5 * area
        cum = 0.0
        for i in range(n_acc):
            if cum + acc_area[i] >= half:
                a = acc_a[i]
                b = acc_b[i]
                need = half - cum
                # solve int_a^t g = need on [a, b] by bisection on K15 partial integrals
                ta = a
                tb = b
                for _ in range(80):
                    tm = 0.5 * (ta + tb)
                    if tm <= ta or tm >= tb:
                        break
                    pa, _, _, _ = _gk(a, tm, c0, ints, f, first, n_items, lab, h, xgk, wgk,
                                      wg)
                    if pa < need:
                        ta = tm
                    else:
                        tb = tm
                return 0.5 * (ta + tb)
            cum += acc_area[i]
        return hi
    # maxima: the cut points, and in every piece each local maximum of a scan of SCAN_CELLS
    # cells (a sum of terms may have several between two knots), located by golden section
    # and refined to the zero of the derivative (values alone place it to ~1e-8 only)
    gmax = 0.0
    cap = (nc + 1) * (SCAN_CELLS + 3)
    cand = np.empty(cap)
    cv = np.empty(cap)
    ys = np.empty(SCAN_CELLS + 1)
    gs = np.empty(SCAN_CELLS + 1)
    ncand = 0
    for k in range(nc - 1):
        a = cuts[k]
        b = cuts[k + 1]
        if not b > a:
            continue
        for s in range(SCAN_CELLS + 1):
            ys[s] = a + (b - a) * s / SCAN_CELLS if s < SCAN_CELLS else b
            gs[s] = _g(ys[s], ints, f, first, n_items, lab, h)
        for s in (0, SCAN_CELLS):
            cand[ncand] = ys[s]
            cv[ncand] = gs[s]
            ncand += 1
        for s in range(SCAN_CELLS + 1):
            left = gs[s - 1] if s > 0 else -1.0
            right = gs[s + 1] if s < SCAN_CELLS else -1.0
            if gs[s] < left or gs[s] < right or (left == gs[s] and gs[s] == right):
                continue
            aa = ys[max(s - 1, 0)]
            bb = ys[min(s + 1, SCAN_CELLS)]
            xm = _golden_max(aa, bb, span, ints, f, first, n_items, lab, h)
            xr = _refine_max(xm, aa, bb, span, ints, f, first, n_items, lab, h)
            if xr == xm:
                # not a smooth maximum (a kink, a plateau's edge, a flat top like a steep
                # bell's): values tie over a band around it, and it is exact only at a cut
                gx = _g(xm, ints, f, first, n_items, lab, h)
                if s <= 1 and gs[0] >= gx - 1e-12 * gx:
                    xr = a
                elif s >= SCAN_CELLS - 1 and gs[SCAN_CELLS] >= gx - 1e-12 * gx:
                    xr = b
            xm = xr
            cand[ncand] = xm
            cv[ncand] = _g(xm, ints, f, first, n_items, lab, h)
            ncand += 1
    for i in range(ncand):
        gmax = max(gmax, cv[i])
    tolm = 1e-12 * gmax
    # plateaus: pieces where g stays at gmax (both ends and the middle)
    plen = 0.0
    pmom = 0.0
    pmin = np.inf
    pmax = -np.inf
    for k in range(nc - 1):
        a = cuts[k]
        b = cuts[k + 1]
        if not b > a:
            continue
        if (_g(a, ints, f, first, n_items, lab, h) >= gmax - tolm
                and _g(b, ints, f, first, n_items, lab, h) >= gmax - tolm
                and _g(0.5 * (a + b), ints, f, first, n_items, lab, h) >= gmax - tolm):
            plen += b - a
            pmom += 0.5 * (b - a) * (a + b)
            pmin = min(pmin, a)
            pmax = max(pmax, b)
    lo_pt = np.inf
    hi_pt = -np.inf
    tot = 0.0
    cnt = 0
    for i in range(ncand):
        if cv[i] >= gmax - tolm:
            lo_pt = min(lo_pt, cand[i])
            hi_pt = max(hi_pt, cand[i])
            tot += cand[i]
            cnt += 1
    if mode == 2:
        return pmom / plen if plen > 0.0 else tot / cnt
    if mode == 3:
        return min(pmin, lo_pt)
    return max(pmax, hi_pt)


# ---------------------------------------------------------------------------------------------
# one point, a batch, the loop's two-input call


@kernel(error_model="numpy")
def eval_point(ints: IntArray, f: FloatArray, x: FloatArray, out: FloatArray,
               work: FloatArray, iw: IntArray) -> None:
    """Evaluate every output at the point x (n_in,) into out (n_out,); work and iw are
    scratch of ints[H_WORK] floats and ints[H_IWORK] integers. NaN input: NaN outputs."""
    n_in = ints[H_NIN]
    n_out = ints[H_NOUT]
    fvo = ints[H_FVARS]
    for i in range(n_in):
        if x[i] != x[i]:
            for o in range(n_out):
                out[o] = np.nan
            return
    xin = work[:n_in]
    for i in range(n_in):
        v = x[i]
        if f[fvo + 4 * i + 3] != 0.0:
            lo = f[fvo + 4 * i]
            hi = f[fvo + 4 * i + 1]
            if v < lo:
                v = lo
            elif v > hi:
                v = hi
        xin[i] = v
    if ints[H_PART] >= 0:
        eval_partition(xin, ints[ints[H_PART]:], f[ints[H_PARTF]:], out, work[n_in:], iw)
        for o in range(n_out):
            fv = fvo + 4 * (n_in + o)
            if out[o] != out[o]:
                out[o] = f[fv + 2]
            elif f[fv + 3] != 0.0:
                out[o] = min(max(out[o], f[fv]), f[fv + 1])
        return
    n_terms = ints[H_NTERMS]
    n_rules = ints[H_NRULES]
    items = ints[H_MAXITEMS]
    pos = n_in
    mu = work[pos:pos + n_terms]
    pos += n_terms
    w = work[pos:pos + n_rules]
    pos += n_rules
    stk = work[pos:pos + ints[H_STACK]]
    pos += ints[H_STACK]
    hts = work[pos:pos + items]
    pos += items
    h = work[pos:pos + items]
    pos += items
    rest = work[pos:]
    lab = iw[:items]
    fired = iw[items:items + n_rules]
    nz = iw[items + n_rules:]
    nf = _strengths(ints, f, xin, mu, w, stk, fired, nz)
    ot = ints[H_OUTS]
    impl = ints[H_IMPL]
    agg = ints[H_AGG]
    dmode = ints[H_DEFUZZ]
    tt = ints[H_TERMS]
    for o in range(n_out):
        mode = ints[ot + _OUT_FIELDS * o]
        val = np.nan
        if mode == _M_SUGENO:
            first = ints[ints[H_VARS] + 2 * (n_in + o)]
            rt = ints[H_RULES]
            ct = ints[H_CONS]
            num = 0.0
            den = 0.0
            for qq in range(nf):
                r = fired[qq]
                c0 = ct + ints[rt + 4 * r + 2]
                for c in range(ints[rt + 4 * r + 3]):
                    if ints[c0 + 2 * c] != o:
                        continue
                    t = first + ints[c0 + 2 * c + 1]
                    off = ints[tt + 3 * t + 1]
                    npar = ints[tt + 3 * t + 2]
                    if ints[tt + 3 * t] == _CONST:
                        z = f[off]
                    else:
                        z = f[off + npar - 1]
                        for i in range(n_in):
                            z += f[off + i] * xin[i]
                    num += w[r] * z
                    den += w[r]
            if den > 0.0:
                val = num / den if dmode == 5 else num
        else:
            n_items = _items(ints, w, fired, nf, o, hts, lab, h)
            if n_items > 0:
                if mode == _M_PL:
                    base = ot + _OUT_FIELDS * o
                    mi = items
                    n_cand = 2 + 2 * mi + 3 * mi * mi
                    n_bp = ints[base + 2]
                    n_seg = 2 * max(n_bp - 1, 1) * n_cand
                    lc = rest[:mi]
                    m = rest[mi:2 * mi]
                    hh = rest[2 * mi:3 * mi]
                    p = 3 * mi
                    cand = rest[p:p + n_cand]
                    p += n_cand
                    su = rest[p:p + n_seg]
                    sv = rest[p + n_seg:p + 2 * n_seg]
                    gu = rest[p + 2 * n_seg:p + 3 * n_seg]
                    gv = rest[p + 3 * n_seg:p + 4 * n_seg]
                    so = ints[base + 6]
                    k0 = n_bp
                    k1 = -1
                    for i in range(n_items):
                        k0 = min(k0, ints[so + 2 * lab[i]])
                        k1 = max(k1, ints[so + 2 * lab[i] + 1])
                    ns = _pl_segments(n_items, lab, h, f, ints[base + 1], k0, k1,
                                      ints[base + 3], ints[base + 4], ints[base + 5], impl,
                                      agg, lc, m, hh, cand, su, sv, gu, gv)
                    # the zero-width items (maxima only) in the candidates' scratch, which
                    # _pl_segments is done with (2 + 2 mi + 3 mi^2 >= 2 mi places)
                    px = cand[:mi]
                    pv = cand[mi:2 * mi]
                    n_pt = 0
                    if dmode >= 2:
                        n_pt = _pl_points(ints, f, o, n_items, lab, h, px, pv)
                    val = _defuzz_segments(ns, su, sv, gu, gv, dmode, px, pv, n_pt)
                elif mode == _M_SING:
                    val = _singletons(ints, f, o, n_items, lab, h, hts, dmode)
                else:
                    val = _smooth(ints, f, o, n_items, lab, h, dmode, _XGK, _WGK, _WG)
        fv = fvo + 4 * (n_in + o)
        if val != val:
            val = f[fv + 2]
        elif f[fv + 3] != 0.0:
            val = min(max(val, f[fv]), f[fv + 1])
        out[o] = val


@kernel
def eval_batch(ints: IntArray, f: FloatArray, x: FloatArray, out: FloatArray) -> None:
    """out[i, :] = outputs at x[i, :] (one core)."""
    work = np.empty(ints[H_WORK])
    iw = np.empty(ints[H_IWORK], dtype=np.int64)
    for i in range(x.shape[0]):
        eval_point(ints, f, x[i], out[i], work, iw)


@kernel(parallel=True)
def eval_parallel(ints: IntArray, f: FloatArray, x: FloatArray, out: FloatArray,
                   n_chunks: int) -> None:
    n = x.shape[0]
    for c in numba.prange(n_chunks):
        lo = c * n // n_chunks
        hi = (c + 1) * n // n_chunks
        work = np.empty(ints[H_WORK])
        iw = np.empty(ints[H_IWORK], dtype=np.int64)
        for i in range(lo, hi):
            eval_point(ints, f, x[i], out[i], work, iw)


@kernel(error_model="numpy")
def eval_first2(x1: float, x2: float, ints: IntArray, f: FloatArray) -> float:
    """First output of a two-input system at (x1, x2): the call of the controllers' loops."""
    # one float and one integer allocation per call: the point and the outputs live in the
    # float scratch's tail
    n_out = ints[H_NOUT]
    buf = np.empty(ints[H_WORK] + 2 + n_out)
    x = buf[ints[H_WORK]:ints[H_WORK] + 2]
    out = buf[ints[H_WORK] + 2:]
    x[0] = x1
    x[1] = x2
    eval_point(ints, f, x, out, buf[:ints[H_WORK]], np.empty(ints[H_IWORK], dtype=np.int64))
    return out[0]
