"""General fuzzy systems: any number of inputs and outputs, Mamdani or Sugeno, as plain data.

This is the model the file readers (``fuzzyservo.formats``: MATLAB ``.fis``, IEC 61131-7 FCL,
fuzzylite FLL) produce and the writers consume, and that :mod:`fuzzyservo.fuzzy.general`
compiles and evaluates exactly. Everything is a frozen dataclass; equality is value equality,
so "write then read gives the same system" is ``read(write(s)) == s``.

Terms (``Term.shape``, parameters in the order of :mod:`fuzzyservo.fuzzy.shapes`, the table
every module reads; every term is scaled by its ``height``)::

    triangle   a b c            0 outside [a, c], 1 at b, linear between (a == b or b == c: a
                                vertical edge)
    trapezoid  a b c d          0 outside [a, d], 1 on [b, c]; a may be -inf and d +inf
                                (a shoulder)
    rectangle  start end        1 on [start, end], 0 elsewhere
    ramp       start end        0 at start, 1 at end, linear between, constant beyond (falls
                                when start > end; start == end is 0 everywhere, as fuzzylite)
    discrete   x0 y0 x1 y1 ...  linear between the points (x non-decreasing; a repeated x is a
                                jump), y0 left of x0 and yn right of xn (IEC 61131-7)
    singleton  x                a Mamdani output term of zero width: its weight enters the
                                centroid as a point mass (IEC 61131-7 COGS)
    gaussian   mean sigma       exp(-(x - mean)^2 / (2 sigma^2))           (MATLAB gaussmf)
    gaussian2  mean1 sigma1 mean2 sigma2   left half of gaussian 1 below mean1, right half of
                                gaussian 2 above mean2, 1 between; their product (gauss2mf)
    bell       center width slope      1 / (1 + |(x - center) / width|^(2 slope))  (gbellmf)
    sigmoid    inflection slope        1 / (1 + exp(-slope (x - inflection)))    (sigmf)
    dsigmoid   left rising falling right   |sig(left, rising) - sig(right, falling)| (dsigmf)
    psigmoid   left rising falling right   sig(left, rising) sig(right, falling)  (psigmf)
    s          start end        MATLAB smf: 0 .. 1 by two parabolas meeting at the middle
    z          start end        MATLAB zmf: 1 - s
    pi         a b c d          smf(a, b) zmf(c, d)                            (pimf)
    constant   value            Sugeno output z = value
    linear     c1 .. cn c0      Sugeno output z = c1 x1 + .. + cn xn + c0 (n inputs)

Rules: an antecedent is an expression of :class:`Is` clauses (``variable is [not] term``)
combined by :class:`And`, :class:`Or` and :class:`Not`; a rule has one or more consequents
``output is term`` and a weight in [0, 1] that multiplies its firing strength (MATLAB and
fuzzylite both do so).
"""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Literal, get_args

from ..errors import ParameterError
from .shapes import SHAPES, SUGENO, shape, vertices

__all__ = [
    "AGGREGATIONS",
    "AND_OPS",
    "DEFUZZIFIERS",
    "IMPLICATIONS",
    "OR_OPS",
    "And",
    "Consequent",
    "Expr",
    "FuzzySystem",
    "Is",
    "Not",
    "Or",
    "Rule",
    "Term",
    "Variable",
    "uniform_triangles",
    "walk",
]

range_ = range  # the builtin, where a parameter is called range

_SUGENO_TERMS = SUGENO

Kind = Literal["mamdani", "sugeno"]
AndOp = Literal["min", "product"]
OrOp = Literal["max", "probor"]
ImplicationOp = Literal["min", "product"]
AggregationOp = Literal["max", "bounded_sum", "sum", "probor"]
DefuzzifierName = Literal["centroid", "bisector", "mom", "som", "lom", "wtaver", "wtsum"]

AND_OPS: tuple[str, ...] = get_args(AndOp)
OR_OPS: tuple[str, ...] = get_args(OrOp)
IMPLICATIONS: tuple[str, ...] = get_args(ImplicationOp)
AGGREGATIONS: tuple[str, ...] = get_args(AggregationOp)
DEFUZZIFIERS: tuple[str, ...] = get_args(DefuzzifierName)
_MAMDANI_DEFUZZ = ("centroid", "bisector", "mom", "som", "lom")
_SUGENO_DEFUZZ = ("wtaver", "wtsum")

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.]*$")


def _check_name(what: str, name: str) -> None:
    if not isinstance(name, str) or not _NAME.match(name):
        raise ParameterError(
            f"{what} name {name!r} is not allowed: use a letter or _ then letters, digits, _ or .")


@dataclass(frozen=True, slots=True)
class Term:
    """One labelled membership function (or Sugeno output function).

    Parameters
    ----------
    name : str
        Label used in rules.
    shape : str
        One of :data:`fuzzyservo.fuzzy.shapes.SHAPES`.
    params : tuple of float
        The shape's parameters in the order of :data:`fuzzyservo.fuzzy.shapes.SHAPES` [unit of
        the variable; slopes in 1/unit, widths and sigmas in the unit].
    height : float
        Scale of the membership, in (0, 1] (fuzzylite's term height; 1 elsewhere) [-].
    """

    name: str  #: label used in rules
    shape: str  #: one of SHAPES
    params: tuple[float, ...]  #: shape parameters [unit of the variable]
    height: float = 1.0  #: scale of the membership [-]

    def __post_init__(self) -> None:
        _check_name("term", self.name)
        if self.shape not in SHAPES:
            raise ParameterError(
                f"term {self.name!r}: unknown shape {self.shape!r}; known: "
                f"{', '.join(SHAPES)}")
        p = tuple(float(v) for v in self.params)
        object.__setattr__(self, "params", p)
        if not (0.0 < self.height <= 1.0):
            raise ParameterError(
                f"term {self.name!r}: height must be in (0, 1], got {self.height!r}")
        names = SHAPES[self.shape]
        if names is not None and len(p) != len(names):
            raise ParameterError(
                f"term {self.name!r}: {self.shape} takes {len(names)} parameters "
                f"({' '.join(names)}), got {len(p)}")
        inf_ok = shape(self.shape).infinite
        for i, v in enumerate(p):
            if math.isnan(v) or (math.isinf(v) and i not in inf_ok):
                raise ParameterError(
                    f"term {self.name!r}: parameter {i + 1} of {self.shape} must be finite, "
                    f"got {v!r}")
        self._check_shape(p)

    def _check_shape(self, p: tuple[float, ...]) -> None:
        needs = shape(self.shape).needs
        what = None if needs is None else needs(p)
        if what is not None:
            raise ParameterError(f"term {self.name!r}: {self.shape} needs {what}, got {list(p)}")

    @property
    def vertices(self) -> tuple[tuple[float, float], ...] | None:
        """(x, y) vertices of a piecewise-linear term (height applied), constant beyond the
        first and last, a repeated x being a jump; None for other shapes
        (:func:`fuzzyservo.fuzzy.shapes.vertices`)."""
        return vertices(self.shape, self.params, self.height)


@dataclass(frozen=True, slots=True)
class Variable:
    """An input or output variable: a name, a range and its terms.

    Parameters
    ----------
    name : str
        Identifier used in rules.
    range : tuple of float
        (lo, hi), finite, lo < hi [unit of the variable]. Inputs outside it are clipped to it
        when ``clip`` is set; a Mamdani output is integrated over it only.
    terms : tuple of Term
        The labelled terms.
    default : float
        Output only: the value when no rule fires for this output (NaN allowed: "no value")
        [unit of the variable].
    clip : bool
        Input: clip the input to the range before fuzzifying (MATLAB; fuzzylite's
        ``lock-range``). Output: clamp the crisp value to the range.
    """

    name: str  #: identifier used in rules
    range: tuple[float, float]  #: (lo, hi) [unit of the variable]
    terms: tuple[Term, ...]  #: labelled terms
    default: float = math.nan  #: output when no rule fires [unit of the variable]
    clip: bool = True  #: clip inputs / clamp outputs to the range

    def __post_init__(self) -> None:
        _check_name("variable", self.name)
        lo, hi = (float(v) for v in self.range)
        object.__setattr__(self, "range", (lo, hi))
        object.__setattr__(self, "terms", tuple(self.terms))
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ParameterError(
                f"variable {self.name!r}: range needs finite lo < hi, got [{lo!r}, {hi!r}]")
        if math.isinf(self.default):
            raise ParameterError(
                f"variable {self.name!r}: default must be finite or NaN, got {self.default!r}")
        dup = sorted(n for n, c in Counter(t.name for t in self.terms).items() if c > 1)
        if dup:
            raise ParameterError(f"variable {self.name!r} repeats terms {dup}")

    @classmethod
    def uniform(cls, name: str, range: tuple[float, float], labels: Sequence[str], *,
                default: float = math.nan) -> Variable:
        """Uniform triangles with 50 % overlap, peaks at lo + k (hi - lo) / (n - 1).

        The end triangles peak at the range's ends; their outer halves lie outside the range
        and are cut by it (clipped inputs, an output integrated over its range only), so they
        act as shoulders. This is the form the uniform-grid path of the evaluator takes
        (:func:`fuzzyservo.fuzzy.engine.pack`).

        Parameters
        ----------
        name : str
            Variable name.
        range : tuple of float
            (lo, hi) [unit of the variable].
        labels : sequence of str
            At least two labels, from lo to hi.
        default : float
            Output only: the value when no rule fires (NaN: none) [unit of the variable].
        """
        return cls(name, range, uniform_triangles(range, labels), default)

    def term_index(self, name: str) -> int:
        """Index of the term called ``name``; ParameterError naming the known terms if none."""
        for i, t in enumerate(self.terms):
            if t.name == name:
                return i
        raise ParameterError(
            f"variable {self.name!r} has no term {name!r}; it has "
            f"{', '.join(t.name for t in self.terms) or 'none'}")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Variable):
            return NotImplemented
        same_default = (self.default == other.default
                        or (math.isnan(self.default) and math.isnan(other.default)))
        return (self.name, self.range, self.terms, self.clip) == (
            other.name, other.range, other.terms, other.clip) and same_default

    def __hash__(self) -> int:
        return hash((self.name, self.range, self.terms, self.clip))


@dataclass(frozen=True, slots=True)
class Is:
    """The clause ``inputs[variable] is [not] terms[term]`` (indices)."""

    variable: int  #: index into FuzzySystem.inputs
    term: int  #: index into that variable's terms
    negated: bool = False  #: ``is not``: 1 - membership


@dataclass(frozen=True, slots=True)
class Not:
    """1 - the operand."""

    operand: Expr  #: the negated expression


@dataclass(frozen=True, slots=True)
class And:
    """The system's AND (min or product) of the operands."""

    operands: tuple[Expr, ...]  #: two or more


@dataclass(frozen=True, slots=True)
class Or:
    """The system's OR (max or probabilistic sum) of the operands."""

    operands: tuple[Expr, ...]  #: two or more


Expr = Is | Not | And | Or


@dataclass(frozen=True, slots=True)
class Consequent:
    """``outputs[variable] is terms[term]`` (indices)."""

    variable: int  #: index into FuzzySystem.outputs
    term: int  #: index into that variable's terms


@dataclass(frozen=True, slots=True)
class Rule:
    """``IF antecedent THEN consequents WITH weight``."""

    antecedent: Expr  #: the condition
    consequents: tuple[Consequent, ...]  #: one or more
    weight: float = 1.0  #: multiplies the firing strength, in [0, 1] [-]


def _canonical(e: Expr) -> Expr:
    """``Not(Is(v, t, n))`` as ``Is(v, t, not n)``, double negations removed, recursively."""
    if isinstance(e, Not):
        inner = _canonical(e.operand)
        if isinstance(inner, Is):
            return Is(inner.variable, inner.term, not inner.negated)
        if isinstance(inner, Not):
            return inner.operand
        return Not(inner)
    if isinstance(e, And):
        return And(tuple(_canonical(o) for o in e.operands))
    if isinstance(e, Or):
        return Or(tuple(_canonical(o) for o in e.operands))
    return e


def walk(expr: Expr) -> Iterator[Is]:
    """Every clause of an expression, left to right."""
    if isinstance(expr, Is):
        yield expr
    elif isinstance(expr, Not):
        yield from walk(expr.operand)
    else:
        for op in expr.operands:
            yield from walk(op)


@dataclass(frozen=True, slots=True, kw_only=True)
class FuzzySystem:
    """A Mamdani or Sugeno fuzzy inference system.

    Parameters
    ----------
    name : str
        The system's name.
    kind : {"mamdani", "sugeno"}
        Inference type.
    inputs, outputs : tuple of Variable
        Input and output variables (at least one of each).
    rules : tuple of Rule
        The rule base.
    and_op : {"min", "product"}
        AND of antecedent clauses.
    or_op : {"max", "probor"}
        OR of antecedent clauses (probor: a + b - a b).
    implication : {"min", "product"}
        Mamdani: clipping or scaling of a consequent set by the rule strength.
    aggregation : {"max", "bounded_sum", "sum", "probor"}
        Mamdani: combination of the implied sets (bounded sum: min(1, a + b); sum: a + b,
        unbounded, as MATLAB's "sum").
    defuzzifier : {"centroid", "bisector", "mom", "som", "lom", "wtaver", "wtsum"}
        Mamdani: centroid, bisector of area, mean / smallest / largest of maximum (mom: the
        mean of the set where the aggregate reaches its maximum, by length; the mean of its
        points when it is a finite set). Sugeno: weighted average or weighted sum.

    Notes
    -----
    Two forms are made canonical on construction: ``Not(Is(...))`` becomes the negated clause,
    and a Mamdani output's ``clip`` is True (its value is always in its range).
    """

    name: str = "fuzzy"  #: the system's name
    kind: Kind = "mamdani"  #: inference type
    inputs: tuple[Variable, ...]  #: input variables
    outputs: tuple[Variable, ...]  #: output variables
    rules: tuple[Rule, ...]  #: the rule base
    and_op: AndOp = "min"  #: AND operator
    or_op: OrOp = "max"  #: OR operator
    implication: ImplicationOp = "min"  #: Mamdani implication
    aggregation: AggregationOp = "max"  #: Mamdani aggregation
    defuzzifier: DefuzzifierName = "centroid"  #: defuzzification method
    notes: tuple[str, ...] = field(default=(), compare=False)  #: reader remarks (not compared)

    def __post_init__(self) -> None:
        _check_name("system", self.name)
        object.__setattr__(self, "inputs", tuple(self.inputs))
        object.__setattr__(self, "outputs", tuple(self.outputs))
        object.__setattr__(self, "rules", tuple(self.rules))
        for what, value, allowed in (
            ("kind", self.kind, ("mamdani", "sugeno")), ("and_op", self.and_op, AND_OPS),
            ("or_op", self.or_op, OR_OPS), ("implication", self.implication, IMPLICATIONS),
            ("aggregation", self.aggregation, AGGREGATIONS),
            ("defuzzifier", self.defuzzifier, DEFUZZIFIERS),
        ):
            if value not in allowed:
                raise ParameterError(
                    f"{what} must be one of {', '.join(map(repr, allowed))}, got {value!r}")
        if not self.inputs or not self.outputs:
            raise ParameterError("a fuzzy system needs at least one input and one output")
        dup = sorted(n for n, c in Counter(v.name for v in self.inputs + self.outputs).items()
                     if c > 1)
        if dup:
            raise ParameterError(f"variable names must be unique, repeated: {dup}")
        allowed_defuzz = _MAMDANI_DEFUZZ if self.kind == "mamdani" else _SUGENO_DEFUZZ
        if self.defuzzifier not in allowed_defuzz:
            raise ParameterError(
                f"a {self.kind} system defuzzifies by {', '.join(allowed_defuzz)}, got "
                f"{self.defuzzifier!r}")
        for v in self.inputs:
            for t in v.terms:
                if shape(t.shape).family in ("singleton", "sugeno"):
                    raise ParameterError(
                        f"input {v.name!r} term {t.name!r}: {t.shape} is an output shape")
        for v in self.outputs:
            self._check_output(v)
        for k, rule in enumerate(self.rules, start=1):
            self._check_rule(k, rule)
        # canonical forms, so that equal systems compare equal whichever file they came from:
        # NOT of a clause is the clause negated; a Mamdani output always lies in its range
        # (a defuzzified set on the range), so its clip flag means nothing and is True
        object.__setattr__(self, "rules", tuple(
            Rule(_canonical(r.antecedent), r.consequents, r.weight) for r in self.rules))
        if self.kind == "mamdani":
            object.__setattr__(self, "outputs", tuple(
                v if v.clip else Variable(v.name, v.range, v.terms, v.default, True)
                for v in self.outputs))

    def _check_output(self, v: Variable) -> None:
        for t in v.terms:
            if self.kind == "sugeno" and t.shape not in _SUGENO_TERMS:
                raise ParameterError(
                    f"sugeno output {v.name!r} term {t.name!r}: needs constant or linear, "
                    f"got {t.shape}")
            if self.kind == "mamdani" and t.shape in _SUGENO_TERMS:
                raise ParameterError(
                    f"mamdani output {v.name!r} term {t.name!r}: {t.shape} is a Sugeno shape")
            if t.shape == "linear" and len(t.params) != len(self.inputs) + 1:
                raise ParameterError(
                    f"output {v.name!r} term {t.name!r}: linear needs {len(self.inputs) + 1} "
                    f"coefficients (one per input, then the constant), got {len(t.params)}")
        if self.kind == "mamdani":
            single = [shape(t.shape).family == "singleton" for t in v.terms]
            if any(single) and not all(single):
                raise ParameterError(
                    f"output {v.name!r} mixes singleton terms with terms that have area; "
                    f"use singletons only (COGS) or none")
            if all(single) and self.defuzzifier == "bisector":
                raise ParameterError(
                    f"output {v.name!r}: the bisector of singletons is not defined; use "
                    f"centroid (COGS) or a maximum method")

    def _check_rule(self, k: int, rule: Rule) -> None:
        if not (0.0 <= rule.weight <= 1.0):
            raise ParameterError(f"rule {k}: weight must be in [0, 1], got {rule.weight!r}")
        self._check_expr(k, rule.antecedent)
        if not rule.consequents:
            raise ParameterError(f"rule {k}: needs at least one consequent")
        for c in rule.consequents:
            if not 0 <= c.variable < len(self.outputs):
                raise ParameterError(f"rule {k}: output index {c.variable} out of range")
            if not 0 <= c.term < len(self.outputs[c.variable].terms):
                raise ParameterError(
                    f"rule {k}: term index {c.term} out of range for output "
                    f"{self.outputs[c.variable].name!r}")

    def _check_expr(self, k: int, e: Expr) -> None:
        if isinstance(e, Is):
            if not 0 <= e.variable < len(self.inputs):
                raise ParameterError(f"rule {k}: input index {e.variable} out of range")
            if not 0 <= e.term < len(self.inputs[e.variable].terms):
                raise ParameterError(
                    f"rule {k}: term index {e.term} out of range for input "
                    f"{self.inputs[e.variable].name!r}")
        elif isinstance(e, Not):
            self._check_expr(k, e.operand)
        elif isinstance(e, And | Or):
            if len(e.operands) < 2:
                raise ParameterError(f"rule {k}: AND / OR need two or more operands")
            for op in e.operands:
                self._check_expr(k, op)
        else:
            raise ParameterError(f"rule {k}: not an expression: {e!r}")

    @classmethod
    def from_table(cls, table: Sequence[Sequence[str | None]], *, columns: Variable,
                   rows: Variable, output: Variable, name: str = "fuzzy",
                   **operators: str) -> FuzzySystem:
        """A two-input Mamdani system from a rule table ``table[row][column]`` of output
        labels (None or "-": no rule).

        The inputs are ``(columns, rows)``; the rules are ``columns is A and rows is B then
        output is C``, row by row. The paper prints rows Δe and columns e, both ordered NB .. PB.

        Parameters
        ----------
        table : sequence of sequences of str or None
            ``len(rows.terms)`` rows of ``len(columns.terms)`` labels each.
        columns, rows : Variable
            First input (the table's columns) and second input (its rows).
        output : Variable
            The output, whose term names the cells hold.
        name : str
            The system's name.
        **operators
            ``and_op``, ``or_op``, ``implication``, ``aggregation``, ``defuzzifier`` (default
            min, max, min, max, centroid).
        """
        nr, nc = len(rows.terms), len(columns.terms)
        if len(table) != nr or any(len(row) != nc for row in table):
            shape_ = f"{len(table)} rows of lengths {[len(r) for r in table]}"
            raise ParameterError(
                f"rule table must have {nr} rows ({rows.name}) of {nc} cells "
                f"({columns.name}), got {shape_}")
        rules = []
        for i2, row in enumerate(table):
            for i1, cell in enumerate(row):
                if cell is None or cell == "-":
                    continue
                rules.append(Rule(And((Is(0, i1), Is(1, i2))),
                                  (Consequent(0, output.term_index(cell)),)))
        return cls(name=name, kind="mamdani", inputs=(columns, rows), outputs=(output,),
                   rules=tuple(rules), **operators)  # type: ignore[arg-type]

    def rule_table(self) -> list[list[int]]:
        """A two-input system's rules as ``table[i2][i1]`` = term of output 0 (-1: no rule):
        rows the second input's terms, columns the first's.

        Raises
        ------
        ParameterError
            Not two inputs, or a rule that is not ``x1 is A and x2 is B then y is C`` (weight
            1, one consequent on output 0), or two rules on one cell.
        """
        if len(self.inputs) != 2:
            raise ParameterError(f"a rule table needs 2 inputs, system {self.name!r} has "
                                 f"{len(self.inputs)}")
        n1, n2 = (len(v.terms) for v in self.inputs)
        table = [[-1] * n1 for _ in range_(n2)]
        for k, r in enumerate(self.rules, start=1):
            a = r.antecedent
            ops = a.operands if isinstance(a, And) else ()
            if (len(ops) != 2 or not all(isinstance(o, Is) and not o.negated for o in ops)
                    or (ops[0].variable, ops[1].variable) != (0, 1)  # type: ignore[union-attr]
                    or r.weight != 1.0 or len(r.consequents) != 1
                    or r.consequents[0].variable != 0):
                raise ParameterError(f"rule {k} ({self.rule_text(r)}) is not a cell of a rule "
                                     f"table")
            i1, i2 = ops[0].term, ops[1].term  # type: ignore[union-attr]
            if table[i2][i1] >= 0:
                raise ParameterError(f"rule {k} ({self.rule_text(r)}): two rules on one cell")
            table[i2][i1] = r.consequents[0].term
        return table

    def input_index(self, name: str) -> int:
        """Index of the input called ``name``."""
        for i, v in enumerate(self.inputs):
            if v.name == name:
                return i
        raise ParameterError(
            f"system {self.name!r} has no input {name!r}; inputs: "
            f"{', '.join(v.name for v in self.inputs)}")

    def output_index(self, name: str) -> int:
        """Index of the output called ``name``."""
        for i, v in enumerate(self.outputs):
            if v.name == name:
                return i
        raise ParameterError(
            f"system {self.name!r} has no output {name!r}; outputs: "
            f"{', '.join(v.name for v in self.outputs)}")

    def rule_text(self, rule: Rule) -> str:
        """A rule as readable text (FLL-like)."""

        def expr(e: Expr, top: bool = True) -> str:
            if isinstance(e, Is):
                v = self.inputs[e.variable]
                neg = "not " if e.negated else ""
                return f"{v.name} is {neg}{v.terms[e.term].name}"
            if isinstance(e, Not):
                return f"not ({expr(e.operand)})"
            word = " and " if isinstance(e, And) else " or "
            body = word.join(expr(op, False) for op in e.operands)
            return body if top else f"({body})"

        cons = " and ".join(
            f"{self.outputs[c.variable].name} is "
            f"{self.outputs[c.variable].terms[c.term].name}" for c in rule.consequents)
        w = "" if rule.weight == 1.0 else f" with {rule.weight!r}"
        return f"if {expr(rule.antecedent)} then {cons}{w}"


def uniform_triangles(range: tuple[float, float], labels: Sequence[str]) -> tuple[Term, ...]:
    """The terms of :meth:`Variable.uniform`: n uniform triangles on ``range``.

    One list of peaks is shared by neighbouring triangles as their feet, so that a foot and
    the neighbour's peak are the same float; weighted means keep a symmetric range's peaks
    symmetric (-1/3 and 1/3, and 0 exactly).
    """
    lo, hi = float(range[0]), float(range[1])
    n = len(labels)
    if n < 2:
        raise ParameterError(f"a uniform partition needs >= 2 labels, got {n}")
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo >= hi:
        raise ParameterError(f"a uniform partition needs a finite range lo < hi, got "
                             f"({lo!r}, {hi!r})")
    d = (hi - lo) / (n - 1)
    peaks = [(lo * (n - 1 - k) + hi * k) / (n - 1) for k in range_(n)]
    peaks[-1] = hi
    ext = [lo - d, *peaks, hi + d]
    return tuple(Term(label, "triangle", (ext[k], ext[k + 1], ext[k + 2]))
                 for k, label in enumerate(labels))
