"""The membership shapes: one table that every module reads.

Each :class:`Shape` names a term shape of :class:`~fuzzyservo.fuzzy.system.Term` and says
everything the package needs to know about it: its parameters (in the order ``Term.params``
holds them), its family (which exact integration the evaluator uses), its code in the compiled
evaluator (:func:`fuzzyservo.fuzzy.general.mf_value`), its breakpoints (``vertices``) and the
open interval where it is positive (``support``), and how each file format writes it (MATLAB
``.fis`` type and parameter order, fuzzylite's FLL class, whose lower-case name is also its FCL
keyword, and IEC 61131-7's short FCL keyword where there is one).

The value of a shape is computed in one place, the compiled ``mf_value``; numpy callers use
:func:`fuzzyservo.fuzzy.general.membership`.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

__all__ = [
    "PIECEWISE_LINEAR",
    "SHAPES",
    "SHAPE_TABLE",
    "SMOOTH",
    "SUGENO",
    "Family",
    "Shape",
    "knots",
    "point_of",
    "shape",
    "support",
    "vertices",
]

#: How a shape is integrated: exactly by linear pieces, by adaptive Gauss-Kronrod quadrature,
#: as a point mass (a singleton output), or not at all (a Sugeno output function).
Family = Literal["piecewise linear", "smooth", "singleton", "sugeno"]

Points = tuple[tuple[float, float], ...]


def _tri_vertices(p: tuple[float, ...], h: float) -> list[tuple[float, float]]:
    a, b, c = p
    return [(a, 0.0), (b, h), (c, 0.0)]


def _trap_vertices(p: tuple[float, ...], h: float) -> list[tuple[float, float]]:
    a, b, c, d = p
    pts = [(b, h)] if a == -math.inf else [(a, 0.0), (b, h)]
    pts += [(c, h)] if d == math.inf else [(c, h), (d, 0.0)]
    return pts


def _rect_vertices(p: tuple[float, ...], h: float) -> list[tuple[float, float]]:
    a, b = p
    return [(a, 0.0), (a, h), (b, h), (b, 0.0)]


def _ramp_vertices(p: tuple[float, ...], h: float) -> list[tuple[float, float]]:
    a, b = p
    if a == b:
        return [(a, 0.0), (a + 1.0, 0.0)]
    return [(a, 0.0), (b, h)] if a < b else [(b, h), (a, 0.0)]


def _discrete_vertices(p: tuple[float, ...], h: float) -> list[tuple[float, float]]:
    return [(x, h * y) for x, y in zip(p[0::2], p[1::2], strict=True)]


# what a shape's parameters must satisfy: the first requirement they fail, or None


# a = b = c (a triangle) and a = b = c = d (a trapezoid) are zero-width terms: a point, as
# fuzzylite and jFuzzyLogic read them (`TRIAN 0 0 0`); see point_of and docs/fuzzy-files.md


def _tri_needs(p: tuple[float, ...]) -> str | None:
    return None if p[0] <= p[1] <= p[2] else "a <= b <= c"


def _trap_needs(p: tuple[float, ...]) -> str | None:
    if not (p[0] <= p[1] <= p[2] <= p[3] and math.isfinite(p[1]) and math.isfinite(p[2])):
        return "a <= b <= c <= d with b, c finite"
    return "a finite or d finite" if p[0] == -math.inf and p[3] == math.inf else None


def _discrete_needs(p: tuple[float, ...]) -> str | None:
    if not (len(p) >= 4 and len(p) % 2 == 0):
        return "at least two (x, y) pairs"
    xs, ys = p[0::2], p[1::2]
    if not (all(b >= a for a, b in zip(xs, xs[1:], strict=False)) and xs[0] < xs[-1]):
        return "x non-decreasing and not all equal"
    if not all(0.0 <= y <= 1.0 for y in ys):
        return "every y in [0, 1]"
    return "no x more than twice" if max(Counter(xs).values()) > 2 else None


def _rising(p: tuple[float, ...]) -> str | None:
    return None if p[0] < p[1] else "start < end"


def _sigma(p: tuple[float, ...]) -> str | None:
    return None if p[1] > 0.0 else "sigma > 0"


_INF = (-math.inf, math.inf)


def _first(p: tuple[float, ...]) -> list[float]:
    return [p[0]]


def _sz_knots(p: tuple[float, ...]) -> list[float]:
    return [p[0], 0.5 * (p[0] + p[1]), p[1]]


def _pi_knots(p: tuple[float, ...]) -> list[float]:
    return [*_sz_knots(p[:2]), *_sz_knots(p[2:])]


def _ramp_support(p: tuple[float, ...]) -> tuple[float, float] | None:
    a, b = p
    if a == b:
        return None
    return (a, math.inf) if a < b else (-math.inf, a)


def _open(lo: float, hi: float) -> tuple[float, float] | None:
    return (lo, hi) if lo < hi else None


def _discrete_support(p: tuple[float, ...]) -> tuple[float, float] | None:
    return _INF if all(y > 0.0 for y in p[1::2]) else None


@dataclass(frozen=True, slots=True)
class Shape:
    """One membership shape.

    Parameters
    ----------
    name : str
        The model's name (``Term.shape``).
    params : tuple of str or None
        Parameter names in the model's order; None: a variable number (``discrete``: x, y
        pairs; ``linear``: one coefficient per input, then the constant).
    family : {"piecewise linear", "smooth", "singleton", "sugeno"}
        How an aggregate of the shape is integrated.
    code : int
        The shape's code in the compiled evaluator.
    fis : str or None
        MATLAB ``.fis`` type (None: not a MATLAB shape).
    fis_order : tuple of int or None
        Model parameter i is .fis value ``fis_order[i]`` (None: the same order).
    fis_written : bool
        Written to .fis (False: read with fuzzylite's meaning only, MATLAB has no such type).
    fll : str or None
        fuzzylite class (FLL, and, lower-cased, fuzzylite's FCL keyword).
    fcl_short : str or None
        IEC 61131-7's own FCL keyword (TRIAN, TRAPE, ...), read only.
    infinite : tuple of int
        Parameters that may be infinite (a trapezoid's open ends: a shoulder).
    vertices : callable or None
        ``(params, height) -> [(x, y), ...]`` of a piecewise-linear shape: constant beyond the
        first and last point, a repeated x a jump.
    support : callable or None
        ``params -> (lo, hi)``: an open interval on which the shape is > 0 (None: not known
        to have one).
    needs : callable or None
        ``params -> str | None``: the first requirement the parameters fail (None: they are
        valid); checked by :class:`~fuzzyservo.fuzzy.system.Term` after their count and
        finiteness.
    knots : callable or None
        ``params -> [x, ...]``: where a smooth shape changes character (its location
        parameters, the joints of s, z and pi): a plot samples them exactly. None: the
        parameters themselves (the breakpoints of a piecewise-linear shape).
    """

    name: str  #: the model's name
    params: tuple[str, ...] | None  #: parameter names, in order
    family: Family  #: how it is integrated
    code: int  #: code in the compiled evaluator
    fis: str | None = None  #: MATLAB type
    fis_order: tuple[int, ...] | None = None  #: .fis value index of each model parameter
    fis_written: bool = True  #: written to .fis (else read only)
    fll: str | None = None  #: fuzzylite class
    fcl_short: str | None = None  #: IEC 61131-7 short keyword (read only)
    infinite: tuple[int, ...] = ()  #: parameters that may be infinite
    vertices: Callable[[tuple[float, ...], float], list[tuple[float, float]]] | None = None
    support: Callable[[tuple[float, ...]], tuple[float, float] | None] | None = None
    knots: Callable[[tuple[float, ...]], list[float]] | None = None
    needs: Callable[[tuple[float, ...]], str | None] | None = None


#: Every shape, in the order of their codes (the compiled evaluator's switch).
SHAPE_TABLE: tuple[Shape, ...] = (
    Shape("triangle", ("a", "b", "c"), "piecewise linear", 0, "trimf", None, True,
          "Triangle", "trian", vertices=_tri_vertices, support=lambda p: _open(p[0], p[2]),
          needs=_tri_needs),
    Shape("trapezoid", ("a", "b", "c", "d"), "piecewise linear", 1, "trapmf", None, True,
          "Trapezoid", "trape", infinite=(0, 3), vertices=_trap_vertices,
          support=lambda p: _open(p[0], p[3]), needs=_trap_needs),
    Shape("rectangle", ("start", "end"), "piecewise linear", 2, "rectmf", None, False,
          "Rectangle", vertices=_rect_vertices,
          needs=lambda p: None if p[0] <= p[1] else "start <= end"),
    Shape("ramp", ("start", "end"), "piecewise linear", 3, "rampmf", None, False, "Ramp",
          vertices=_ramp_vertices, support=_ramp_support),
    Shape("discrete", None, "piecewise linear", 4, "discretemf", None, False, "Discrete",
          vertices=_discrete_vertices, support=_discrete_support, needs=_discrete_needs),
    Shape("singleton", ("x",), "singleton", 5),
    Shape("gaussian", ("mean", "sigma"), "smooth", 6, "gaussmf", (1, 0), True, "Gaussian",
          "gauss", support=lambda p: _INF, knots=_first, needs=_sigma),
    Shape("gaussian2", ("mean1", "sigma1", "mean2", "sigma2"), "smooth", 7, "gauss2mf",
          (1, 0, 3, 2), True, "GaussianProduct", "gauss2", support=lambda p: _INF,
          knots=lambda p: [p[0], p[2]],
          needs=lambda p: None if p[1] > 0.0 and p[3] > 0.0 else "sigma1 > 0 and sigma2 > 0"),
    Shape("bell", ("center", "width", "slope"), "smooth", 8, "gbellmf", (2, 0, 1), True,
          "Bell", "gbell", support=lambda p: _INF, knots=_first,
          needs=lambda p: None if p[1] != 0.0 and p[2] > 0.0 else "width != 0 and slope > 0"),
    Shape("sigmoid", ("inflection", "slope"), "smooth", 9, "sigmf", (1, 0), True, "Sigmoid",
          "sigm", support=lambda p: _INF, knots=_first),
    Shape("dsigmoid", ("left", "rising", "falling", "right"), "smooth", 10, "dsigmf",
          (1, 0, 2, 3), True, "SigmoidDifference", knots=lambda p: [p[0], p[3]]),
    Shape("psigmoid", ("left", "rising", "falling", "right"), "smooth", 11, "psigmf",
          (1, 0, 2, 3), True, "SigmoidProduct", support=lambda p: _INF,
          knots=lambda p: [p[0], p[3]]),
    Shape("s", ("start", "end"), "smooth", 12, "smf", None, True, "SShape",
          support=lambda p: (p[0], math.inf), knots=_sz_knots, needs=_rising),
    Shape("z", ("start", "end"), "smooth", 13, "zmf", None, True, "ZShape",
          support=lambda p: (-math.inf, p[1]), knots=_sz_knots, needs=_rising),
    Shape("pi", ("a", "b", "c", "d"), "smooth", 14, "pimf", None, True, "PiShape",
          support=lambda p: (p[0], p[3]), knots=_pi_knots,
          needs=lambda p: None if p[0] < p[1] <= p[2] < p[3] else "a < b <= c < d"),
    Shape("constant", ("value",), "sugeno", 15, "constant", None, True, "Constant"),
    Shape("linear", None, "sugeno", 16, "linear", None, True, "Linear",
          needs=lambda p: None if len(p) >= 1 else "at least the constant c0"),
)

_BY_NAME: dict[str, Shape] = {s.name: s for s in SHAPE_TABLE}
assert all(s.code == k for k, s in enumerate(SHAPE_TABLE))

#: Parameter names of every shape (None: a variable number), by name.
SHAPES: dict[str, tuple[str, ...] | None] = {s.name: s.params for s in SHAPE_TABLE}
#: Shapes whose membership is piecewise linear: aggregates of them are integrated exactly.
PIECEWISE_LINEAR = frozenset(s.name for s in SHAPE_TABLE if s.family == "piecewise linear")
#: Shapes integrated by adaptive Gauss-Kronrod quadrature (error bound in docs/fuzzy-files.md).
SMOOTH = frozenset(s.name for s in SHAPE_TABLE if s.family == "smooth")
#: Sugeno output functions.
SUGENO = frozenset(s.name for s in SHAPE_TABLE if s.family == "sugeno")


def shape(name: str) -> Shape:
    """The shape called ``name`` (KeyError for an unknown one: names are checked by Term)."""
    return _BY_NAME[name]


def vertices(name: str, params: tuple[float, ...], height: float = 1.0) -> Points | None:
    """(x, y) vertices of a piecewise-linear shape (height applied); None for the others."""
    f = _BY_NAME[name].vertices
    return None if f is None else tuple(f(params, height))


def knots(name: str, params: tuple[float, ...]) -> list[float]:
    """Abscissae where a shape changes character (see :attr:`Shape.knots`)."""
    f = _BY_NAME[name].knots
    return list(params) if f is None else f(params)


def support(name: str, params: tuple[float, ...]) -> tuple[float, float] | None:
    """An open interval (lo, hi) on which the shape is > 0, or None if not known to be one."""
    f = _BY_NAME[name].support
    return None if f is None else f(params)


def point_of(name: str, params: tuple[float, ...]) -> float | None:
    """Where a zero-width term sits (a triangle a = b = c, a trapezoid a = b = c = d), None
    for any other term. (A rectangle with start = end keeps its earlier reading: zero area,
    no point for any method; tests/fuzzy/test_general.py::test_zero_width_pieces.)

    Such a term is 1 (its height) at that point and 0 elsewhere, as fuzzylite, jFuzzyLogic and
    MATLAB's trimf compute it exactly there: in an input a crisp point; in an output it has no
    area (it adds nothing to a centroid or bisector) and is a point for the maxima methods.
    """
    if name == "triangle" and params[0] == params[2]:
        return params[0]
    if name == "trapezoid" and params[0] == params[3]:
        return params[0]
    return None
