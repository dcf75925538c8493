"""IEC 61131-7 Fuzzy Control Language (FCL): reader and writer.

:func:`parse` reads one ``FUNCTION_BLOCK`` into a :class:`~fuzzyservo.fuzzy.system.FuzzySystem`;
:func:`dump` writes a system as FCL that :func:`parse` reads back to an equal system and that
fuzzylite 6's FCL importer reads too.

What is read
------------
- The IEC 61131-7 language: ``FUNCTION_BLOCK`` (one per file), ``VAR_INPUT`` / ``VAR_OUTPUT``
  (``name : REAL;``, optionally followed by ``RANGE := (lo .. hi);`` as jFuzzyLogic allows),
  ``FUZZIFY``, ``DEFUZZIFY`` (``TERM``, ``METHOD``, ``DEFAULT``, ``RANGE``, ``ACCU``),
  ``RULEBLOCK`` (``AND``, ``OR``, ``ACT``, ``ACCU``, ``RULE n : IF ... THEN ... WITH w;``).
  Keywords are case-insensitive; names are case-sensitive. Comments ``(* *)``, ``/* */``,
  ``//`` and ``#`` (fuzzylite) are skipped; a byte-order mark and CRLF line ends are accepted.
- Terms: IEC point lists ``(x, y) (x, y) ...``; a number alone (IEC singleton); jFuzzyLogic's
  ``TRIAN a b c``, ``TRAPE a b c d``, ``GAUSS mean sigma``, ``GAUSS2 m1 s1 m2 s2``,
  ``GBELL a b mean`` (width a, slope b: jFuzzyLogic's parser order), ``SIGM gain center``;
  fuzzylite's class names ``Triangle``, ``Trapezoid``, ``Rectangle``, ``Ramp``, ``Discrete``,
  ``Gaussian``, ``GaussianProduct``, ``Bell``, ``Sigmoid``, ``SigmoidDifference``,
  ``SigmoidProduct``, ``PiShape``, ``SShape``, ``ZShape`` (each with fuzzylite's optional
  trailing height), ``Constant`` and ``Linear``.
- fuzzylite's dialect: ``ACCU`` and ``LOCK : RANGE`` inside ``DEFUZZIFY``, ``ENABLED : TRUE``,
  ``DEFAULT := nan``, rules without ``;``, lower-case rule keywords, ``,`` or ``and`` between
  consequents, fuzzylite's operator class names (``AlgebraicProduct``, ``UnboundedSum``, ...).
- Rules may span several lines; ``x IS NOT t`` gives a negated clause, ``NOT x IS t`` and
  ``NOT (expr)`` a :class:`~fuzzyservo.fuzzy.system.Not`; ``(a AND b) AND c`` keeps its
  structure, ``a AND b AND c`` is one three-operand AND.

Mappings and decisions
----------------------
- METHOD: ``COG`` -> centroid, ``COGS`` -> centroid over singleton terms (IEC: the singletons'
  accumulated degrees weight their positions), ``COA`` -> bisector, ``LM`` (left-most maximum)
  -> som, ``RM`` (right-most maximum) -> lom, ``MM`` / ``MOM`` -> mom. Every output must name a
  method, and all of them the same one (the model has one defuzzifier; ``COG`` and ``COGS``
  agree).
- Sugeno: IEC FCL has none; a number alone is a Mamdani singleton. The system is read as
  Sugeno only in fuzzylite's dialect: a ``Constant`` or ``Linear`` term, or ``METHOD : COGSS``
  (weighted sum); then numbers alone are Sugeno constants, ``COGS`` is the weighted average.
- Operators: AND ``MIN`` | ``PROD``; OR ``MAX`` | ``ASUM`` (probabilistic sum); ACT ``MIN`` |
  ``PROD``; ACCU ``MAX`` | ``BSUM`` (bounded sum) | ``SUM`` (unbounded) | ``PROBOR`` / ``ASUM``.
  Missing AND or OR: the other's De Morgan pair (IEC 61131-7 pairs MIN with MAX and PROD with
  ASUM); both missing: MIN and MAX. Missing ACT: MIN. Missing ACCU (IEC requires it; fuzzylite
  leaves it out for COGS): SUM when every output with terms has singleton terms only, so that
  COGS is fuzzylite's weighted average of the rules, else MAX. Several RULEBLOCKs are merged
  when every operator they state agrees (the model has one set of operators).
- ``DEFAULT`` missing: NaN ("no value"; fuzzylite's convention, and IEC 61131-7's grammar
  requires the line, so a file without it is outside the standard). ``DEFAULT := NC`` ("no
  change": keep the previous output) is refused: it makes the system stateful.
- Ranges: an input without RANGE spans its terms' points (the outermost vertices of its
  piecewise-linear terms): every such term is constant beyond them, so the choice changes no
  membership value. An output without RANGE likewise spans its terms' points (what
  jFuzzyLogic integrates over); a term that is non-zero at that end (a shoulder) is cut there,
  so such a file's centroid depends on this choice: give a RANGE. A variable without RANGE
  whose terms have no bounded support (smooth shapes, Sugeno terms) is refused.
- Clipping: FCL cannot say whether an input outside its RANGE is clipped; inputs are read as
  clipped (``Variable.clip = True``, the model's and MATLAB's convention; fuzzylite and
  jFuzzyLogic evaluate the terms at the raw value instead, which differs only outside the
  range). An output is clamped to its range only with fuzzylite's ``LOCK : RANGE``.
- Point lists are read as the simplest shape with exactly the same vertices when the x are
  strictly increasing and y follows a pattern: ``(a,0) (b,1)`` a ramp, ``(a,0) (b,1) (c,0)`` a
  triangle, ``(a,0) (b,1) (c,1) (d,0)`` a trapezoid, ``(b,1) (c,1) (d,0)`` a left shoulder
  (trapezoid from -inf); any other list (including vertical edges) is a discrete term. The
  membership is the same either way; the writer relies on it to write point lists.
- Sizes: a term has at most :data:`~fuzzyservo.formats._text.MAX_POINTS` points (IEC sets no
  bound; fuzzylite's FLL reader's bound, so a system read from any format fits in each).
- Mixing AND and OR without parentheses is refused: fuzzylite binds AND tighter, jFuzzyLogic
  reads left to right, so the file means different things to different tools.

Refused (a FormatError naming the feature): a second FUNCTION_BLOCK, ``VAR`` / ``OPTION``
blocks, types other than REAL, ``DEFAULT := NC``, ``LOCK : PREVIOUS``, ``ENABLED : FALSE``,
METHOD ``COGF`` / ``NONE`` and unknown methods, AND ``BDIF`` and other t-norms, OR ``BSUM``
and other s-norms, ACCU ``NSUM``, hedges (``very``, ``any``, ...), rules whose antecedent uses
an output (chained rule bases), term shapes ``COSINE``, ``DSIGM`` (jFuzzyLogic clips the
difference at 0, the model takes its absolute value), ``SINGLETONS``, ``FUNCTION``, and
fuzzylite's ``Cosine``, ``Concave``, ``Spike``, ``Binary``, ``Function``; point coordinates,
singletons or weights given by a variable name.

What is written
---------------
IEC 61131-7 layout with fuzzylite's conventions so that fuzzylite 6 reads it: ``RANGE`` in every
FUZZIFY / DEFUZZIFY, ``ACCU`` in DEFUZZIFY, rules on one line with lower-case keywords and
``and`` between consequents, nested operands in parentheses. Piecewise-linear terms of height
1 without vertical edges are IEC point lists (read back as the same shape, see above); other
terms use fuzzylite's class names (jFuzzyLogic's shape names are not read by fuzzylite), with
the height as fuzzylite's trailing parameter. A NaN default is written by leaving ``DEFAULT``
out. Numbers are written exactly (:func:`~fuzzyservo.formats._text.fmt_float`).

:func:`dump` raises ParameterError for what FCL (as fuzzylite reads it) cannot hold: an input
that is not clipped or has a default other than NaN, a :class:`~fuzzyservo.fuzzy.system.Not` of
an expression (fuzzylite reads only ``is not``), a singleton or Sugeno term with a height below
1, a maximum method (LM, RM, MM) over singleton terms, a weighted-average Sugeno system without
any output term (nothing would mark it as Sugeno), names that are FCL keywords or fuzzylite
hedges, and names FCL cannot spell.

fuzzylite's known differences from this reading (documented, not refused): ``COGS`` over
terms that several rules conclude sums the rules' degrees whatever ``ACCU`` says (IEC and this
package accumulate them with ``ACCU``); inputs outside their range are not clipped.
"""

from __future__ import annotations

import math
import re
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import partial
from typing import NoReturn

from ..errors import FormatError, ParameterError
from ..fuzzy.shapes import PIECEWISE_LINEAR, SHAPE_TABLE
from ..fuzzy.system import (
    And,
    Consequent,
    Expr,
    FuzzySystem,
    Is,
    Not,
    Or,
    Rule,
    Term,
    Variable,
)
from ._text import MAX_POINTS, Source, fmt_float, fuzzylite_rule

__all__ = ["dump", "parse"]

#: Largest text read [characters]: the size limit of :mod:`fuzzyservo.formats.io`.
MAX_CHARS = 16 * 1024 * 1024
#: Deepest nesting of parentheses and NOT in a rule.
MAX_DEPTH = 200

# --------------------------------------------------------------------------------------------
# lexer
# --------------------------------------------------------------------------------------------

_ID = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z0-9_]+)*")
_NUM = re.compile(r"[+-]?(?:\d+(?:\.(?!\.)\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_SIGNED_WORD = re.compile(r"[+-](?:infinity|inf|nan)(?![A-Za-z0-9_])", re.IGNORECASE)
_SPACE = re.compile(r"[ \t\n\f\v]+")
_NUM_WORDS = {"nan": math.nan, "inf": math.inf, "infinity": math.inf}


@dataclass(frozen=True, slots=True)
class _Tok:
    kind: str  # "id", "num", ":=", ":", ";", "(", ")", ",", "..", "|", "eof", "?" (other)
    text: str
    pos: int
    value: float = 0.0


def _lex(src: Source) -> Iterator[_Tok]:
    """The tokens of the file, lazily (a lexical error is raised when the parser gets there);
    ends with an endless supply of "eof" tokens."""
    text = src.text
    n = len(text)
    i = 0
    while i < n:
        c = text[i]
        m = _SPACE.match(text, i)
        if m:
            i = m.end()
            continue
        two = text[i:i + 2]
        if two in ("(*", "/*"):
            end = text.find("*)" if two == "(*" else "*/", i + 2)
            if end < 0:
                raise src.error(i, f"comment {two} is never closed")
            i = end + 2
            continue
        if two == "//" or c == "#":
            end = text.find("\n", i)
            i = n if end < 0 else end + 1
            continue
        if two == ":=":
            yield _Tok(":=", two, i)
            i += 2
            continue
        if two == "..":
            yield _Tok("..", two, i)
            i += 2
            continue
        if c in ":;(),|":
            yield _Tok(c, c, i)
            i += 1
            continue
        m = _SIGNED_WORD.match(text, i)
        if m:
            word = m.group()
            sign = -1.0 if word[0] == "-" else 1.0
            yield _Tok("num", word, i, sign * _NUM_WORDS[word[1:].lower()])
            i = m.end()
            continue
        m = _NUM.match(text, i)
        if m:
            end = m.end()
            if end < n and (text[end].isalnum() or text[end] == "_"):
                raise src.error(i, f"malformed number {text[i:end + 1]!r}")
            word = m.group()
            yield _Tok("num", word, i, float(word))
            i = end
            continue
        m = _ID.match(text, i)
        if m:
            yield _Tok("id", m.group(), i)
            i = m.end()
            continue
        yield _Tok("?", c, i)  # the parser says what it expected here
        i += 1
    while True:
        yield _Tok("eof", "", n)


# --------------------------------------------------------------------------------------------
# vocabulary
# --------------------------------------------------------------------------------------------

#: Words that cannot name a variable or term (case-insensitive).
_RESERVED = frozenset({
    "FUNCTION_BLOCK", "END_FUNCTION_BLOCK", "VAR_INPUT", "VAR_OUTPUT", "VAR", "END_VAR",
    "FUZZIFY", "END_FUZZIFY", "DEFUZZIFY", "END_DEFUZZIFY", "RULEBLOCK", "END_RULEBLOCK",
    "OPTION", "END_OPTION", "TERM", "RANGE", "METHOD", "DEFAULT", "ACCU", "ACT", "LOCK",
    "ENABLED", "RULE", "IF", "THEN", "IS", "NOT", "AND", "OR", "WITH", "REAL", "NC",
})
#: fuzzylite 6's hedges: a term with one of these names is misread by fuzzylite's rule parser.
_HEDGES = frozenset({"any", "extremely", "not", "seldom", "somewhat", "very"})

_AND_OPS = {"MIN": "min", "MINIMUM": "min", "PROD": "product", "ALGEBRAICPRODUCT": "product"}
_OR_OPS = {"MAX": "max", "MAXIMUM": "max", "ASUM": "probor", "ALGEBRAICSUM": "probor",
           "PROBOR": "probor"}
_ACT_OPS = _AND_OPS
_ACCU_OPS = {"MAX": "max", "MAXIMUM": "max", "BSUM": "bounded_sum", "BOUNDEDSUM": "bounded_sum",
             "SUM": "sum", "UNBOUNDEDSUM": "sum", "PROBOR": "probor", "ASUM": "probor",
             "ALGEBRAICSUM": "probor"}
_OP_TABLES = {"AND": (_AND_OPS, "MIN, PROD"), "OR": (_OR_OPS, "MAX, ASUM"),
              "ACT": (_ACT_OPS, "MIN, PROD"), "ACCU": (_ACCU_OPS, "MAX, BSUM, SUM, PROBOR")}
_DUAL = {"min": "max", "max": "min", "product": "probor", "probor": "product"}

#: METHOD -> (defuzzifier, Sugeno?); None for Sugeno-or-singleton COGS (resolved later).
_METHODS: dict[str, tuple[str, bool]] = {
    "COG": ("centroid", False), "CENTROID": ("centroid", False),
    "COGS": ("cogs", False),
    "COA": ("bisector", False), "BISECTOR": ("bisector", False),
    "LM": ("som", False), "SMALLESTOFMAXIMUM": ("som", False),
    "RM": ("lom", False), "LARGESTOFMAXIMUM": ("lom", False),
    "MM": ("mom", False), "MOM": ("mom", False), "MEANOFMAXIMUM": ("mom", False),
    "COGSS": ("wtsum", True), "WEIGHTEDSUM": ("wtsum", True),
    "WEIGHTEDAVERAGE": ("wtaver", True),
}
_METHOD_NAMES = "COG, COGS, COA, LM, RM, MM"

#: Term shape keywords: lower-case name -> (model shape, number of parameters (None: any),
#: accepts fuzzylite's trailing height, Sugeno class).
_SHAPE_WORDS: dict[str, tuple[str, int | None, bool]] = {
    **{s.fcl_short: (s.name, len(s.params or ()), False)
       for s in SHAPE_TABLE if s.fcl_short is not None},
    **{s.fll.lower(): (s.name, None if s.params is None else len(s.params),
                       s.family != "sugeno")
       for s in SHAPE_TABLE if s.fll is not None},
}
_SHAPE_NAMES = ("point lists, a number (singleton), TRIAN, TRAPE, GAUSS, GAUSS2, GBELL, SIGM, "
                "Triangle, Trapezoid, Rectangle, Ramp, Discrete, Gaussian, GaussianProduct, "
                "Bell, Sigmoid, SigmoidDifference, SigmoidProduct, PiShape, SShape, ZShape, "
                "Constant, Linear")
_SUGENO_WORDS = frozenset(s.fll.lower() for s in SHAPE_TABLE
                          if s.family == "sugeno" and s.fll is not None)

# fuzzylite class names written for each model shape (parameters in the model's order except
# where noted in _write_term)
_CLASS_OF = {s.name: s.fll for s in SHAPE_TABLE if s.fll is not None}


# --------------------------------------------------------------------------------------------
# parsed pieces (before the model is built)
# --------------------------------------------------------------------------------------------

@dataclass(slots=True)
class _TermSpec:
    name: _Tok
    kind: str  # "points", "number", "class"
    word: str = ""  # lower-case shape keyword for "class"
    shape_tok: _Tok | None = None
    params: list[float] = field(default_factory=list)


@dataclass(slots=True)
class _Decl:
    name: _Tok
    output: bool
    range: tuple[float, float] | None = None
    range_tok: _Tok | None = None


@dataclass(slots=True)
class _Block:
    name: _Tok
    terms: list[_TermSpec] = field(default_factory=list)
    range: tuple[float, float] | None = None
    range_tok: _Tok | None = None
    method: _Tok | None = None
    default: float | None = None
    accu: _Tok | None = None
    lock: bool = False
    term_names: set[str] = field(default_factory=set)  # for the repeated-name check


@dataclass(frozen=True, slots=True)
class _NIs:
    var: _Tok
    term: _Tok
    negated: bool


@dataclass(frozen=True, slots=True)
class _NNot:
    operand: _Node
    tok: _Tok


@dataclass(frozen=True, slots=True)
class _NOp:
    word: str  # "AND" or "OR"
    operands: tuple[_Node, ...]


_Node = _NIs | _NNot | _NOp


@dataclass(slots=True)
class _RuleSpec:
    tok: _Tok
    antecedent: _Node
    consequents: list[tuple[_Tok, _Tok]]
    weight: float


@dataclass(slots=True)
class _RuleBlock:
    tok: _Tok
    ops: dict[str, _Tok] = field(default_factory=dict)
    rules: list[_RuleSpec] = field(default_factory=list)


# --------------------------------------------------------------------------------------------
# parser
# --------------------------------------------------------------------------------------------

def _describe(t: _Tok) -> str:
    return "end of file" if t.kind == "eof" else repr(t.text)


class _Parser:
    """Recursive descent over the token list (one instance per file)."""

    def __init__(self, src: Source, toks: Iterator[_Tok]) -> None:
        self.src = src
        self.toks = toks
        self.ahead: deque[_Tok] = deque()
        self.fb_tok: _Tok = self.peek()
        self.fb_name: str | None = None
        self.decls: dict[str, _Decl] = {}
        self.order_in: list[str] = []
        self.order_out: list[str] = []
        self.fuzzify: dict[str, _Block] = {}
        self.defuzzify: dict[str, _Block] = {}
        self.blocks: list[_RuleBlock] = []

    # -- token helpers ----------------------------------------------------------------------
    def peek(self, k: int = 0) -> _Tok:
        while len(self.ahead) <= k:
            self.ahead.append(next(self.toks))
        return self.ahead[k]

    def advance(self) -> _Tok:
        t = self.peek()
        self.ahead.popleft()
        return t

    def err(self, t: _Tok, msg: str) -> FormatError:
        return self.src.error(t.pos, msg)

    @staticmethod
    def is_kw(t: _Tok, *words: str) -> bool:
        return t.kind == "id" and t.text.upper() in words

    def expect(self, kind: str, what: str) -> _Tok:
        t = self.peek()
        if t.kind != kind:
            raise self.err(t, f"expected {what}, found {_describe(t)}")
        return self.advance()

    def expect_kw(self, word: str) -> _Tok:
        t = self.peek()
        if not self.is_kw(t, word):
            raise self.err(t, f"expected {word}, found {_describe(t)}")
        return self.advance()

    def name(self, what: str) -> _Tok:
        t = self.peek()
        if t.kind != "id":
            raise self.err(t, f"expected {what}, found {_describe(t)}")
        if t.text.upper() in _RESERVED:
            raise self.err(t, f"expected {what}, found the keyword {t.text!r}")
        return self.advance()

    def number(self, what: str) -> float:
        t = self.peek()
        if t.kind == "num":
            self.advance()
            return t.value
        if t.kind == "id" and t.text.lower() in _NUM_WORDS:
            self.advance()
            return _NUM_WORDS[t.text.lower()]
        if t.kind == "id" and t.text.upper() not in _RESERVED:
            raise self.err(t, f"unsupported: {what} given by a variable name ({t.text}); "
                              f"only numbers are supported")
        raise self.err(t, f"expected {what} (a number), found {_describe(t)}")

    def is_number(self, t: _Tok) -> bool:
        return t.kind == "num" or (t.kind == "id" and t.text.lower() in _NUM_WORDS)

    # -- file -------------------------------------------------------------------------------
    def file(self) -> None:
        t = self.peek()
        if not self.is_kw(t, "FUNCTION_BLOCK"):
            raise self.err(t, f"expected FUNCTION_BLOCK, found {_describe(t)}")
        self.fb_tok = self.advance()
        nt = self.peek()
        if nt.kind == "id" and nt.text.upper() not in _RESERVED:
            self.fb_name = self.advance().text
        while True:
            t = self.peek()
            if self.is_kw(t, "END_FUNCTION_BLOCK"):
                self.advance()
                break
            if self.is_kw(t, "VAR_INPUT", "VAR_OUTPUT"):
                self.var_block()
            elif self.is_kw(t, "FUZZIFY"):
                self.fuzzify_block()
            elif self.is_kw(t, "DEFUZZIFY"):
                self.defuzzify_block()
            elif self.is_kw(t, "RULEBLOCK"):
                self.rule_block()
            elif self.is_kw(t, "VAR", "OPTION"):
                raise self.err(t, f"unsupported block: {t.text.upper()} (supported: VAR_INPUT, "
                                  f"VAR_OUTPUT, FUZZIFY, DEFUZZIFY, RULEBLOCK)")
            else:
                raise self.err(t, "expected VAR_INPUT, VAR_OUTPUT, FUZZIFY, DEFUZZIFY, "
                                  f"RULEBLOCK or END_FUNCTION_BLOCK, found {_describe(t)}")
        t = self.peek()
        if self.is_kw(t, "FUNCTION_BLOCK"):
            nt = self.peek(1)
            label = f" {nt.text!r}" if nt.kind == "id" else ""
            raise self.err(t, f"unsupported: a second FUNCTION_BLOCK{label} (one system per "
                              f"file)")
        if t.kind != "eof":
            raise self.err(t, f"expected end of file after END_FUNCTION_BLOCK, found "
                              f"{_describe(t)}")

    # -- VAR_INPUT / VAR_OUTPUT -------------------------------------------------------------
    def var_block(self) -> None:
        output = self.advance().text.upper() == "VAR_OUTPUT"
        while not self.is_kw(self.peek(), "END_VAR"):
            t = self.peek()
            if self.is_kw(t, "RANGE"):
                raise self.err(t, "RANGE must follow a variable declaration")
            name = self.name("a variable name or END_VAR")
            if name.text in self.decls:
                raise self.err(name, f"variable {name.text!r} is declared twice")
            self.expect(":", "':'")
            ty = self.peek()
            if ty.kind != "id":
                raise self.err(ty, f"expected a type (REAL), found {_describe(ty)}")
            if ty.text.upper() != "REAL":
                raise self.err(ty, f"unsupported type: {ty.text} (supported: REAL)")
            self.advance()
            if self.peek().kind == ":=":
                raise self.err(self.peek(), "unsupported: an initial value in a variable "
                                            "declaration")
            self.expect(";", "';'")
            d = _Decl(name, output)
            if self.is_kw(self.peek(), "RANGE"):
                d.range_tok = self.peek()
                d.range = self.range_stmt()
            self.decls[name.text] = d
            (self.order_out if output else self.order_in).append(name.text)
        self.advance()

    def range_stmt(self) -> tuple[float, float]:
        self.expect_kw("RANGE")
        self.expect(":=", "':='")
        self.expect("(", "'('")
        lo = self.number("the lower end of RANGE")
        self.expect("..", "'..'")
        hi = self.number("the upper end of RANGE")
        self.expect(")", "')'")
        self.expect(";", "';'")
        return lo, hi

    def colon_word(self, what: str) -> _Tok:
        self.expect(":", "':'")
        t = self.peek()
        if t.kind != "id":
            raise self.err(t, f"expected {what}, found {_describe(t)}")
        self.advance()
        self.expect(";", "';'")
        return t

    def enabled(self) -> None:
        self.advance()
        t = self.colon_word("TRUE or FALSE")
        if t.text.upper() == "FALSE":
            raise self.err(t, "unsupported: ENABLED : FALSE (a disabled block)")
        if t.text.upper() != "TRUE":
            raise self.err(t, f"expected TRUE or FALSE, found {t.text!r}")

    # -- FUZZIFY / DEFUZZIFY ----------------------------------------------------------------
    def var_header(self, output: bool) -> _Block:
        kw = self.advance()
        name = self.name("a variable name")
        d = self.decls.get(name.text)
        role = "output" if output else "input"
        if d is None:
            raise self.err(name, f"{kw.text.upper()} of {name.text!r}, which is not declared "
                                 f"in VAR_{role.upper()}")
        if d.output != output:
            other = "output" if d.output else "input"
            raise self.err(name, f"{kw.text.upper()} of {name.text!r}, which is an {other} "
                                 f"(use {'DEFUZZIFY' if d.output else 'FUZZIFY'})")
        table = self.defuzzify if output else self.fuzzify
        if name.text in table:
            raise self.err(name, f"second {kw.text.upper()} block for {name.text!r}")
        b = _Block(name)
        table[name.text] = b
        return b

    def fuzzify_block(self) -> None:
        b = self.var_header(False)
        while True:
            t = self.peek()
            if self.is_kw(t, "END_FUZZIFY"):
                self.advance()
                return
            if self.is_kw(t, "TERM"):
                self.term(b)
            elif self.is_kw(t, "RANGE"):
                self.block_range(b)
            elif self.is_kw(t, "ENABLED"):
                self.enabled()
            else:
                raise self.err(t, f"expected TERM, RANGE or END_FUZZIFY, found {_describe(t)}")

    def block_range(self, b: _Block) -> None:
        t = self.peek()
        if b.range is not None:
            raise self.err(t, f"second RANGE for {b.name.text!r}")
        b.range_tok = t
        b.range = self.range_stmt()

    def defuzzify_block(self) -> None:
        b = self.var_header(True)
        while True:
            t = self.peek()
            word = t.text.upper() if t.kind == "id" else ""
            if word == "END_DEFUZZIFY":
                self.advance()
                return
            if word == "TERM":
                self.term(b)
            elif word == "RANGE":
                self.block_range(b)
            elif word == "ENABLED":
                self.enabled()
            elif word == "METHOD":
                if b.method is not None:
                    raise self.err(t, f"second METHOD for {b.name.text!r}")
                self.advance()
                b.method = self.colon_word("a defuzzification method")
            elif word == "ACCU":
                if b.accu is not None:
                    raise self.err(t, f"second ACCU for {b.name.text!r}")
                self.advance()
                b.accu = self.colon_word("an accumulation method")
            elif word == "DEFAULT":
                if b.default is not None:
                    raise self.err(t, f"second DEFAULT for {b.name.text!r}")
                self.advance()
                b.default = self.default()
            elif word == "LOCK":
                self.advance()
                self.expect(":", "':'")
                self.lock(b)
            else:
                raise self.err(t, "expected TERM, METHOD, DEFAULT, RANGE, ACCU or "
                                  f"END_DEFUZZIFY, found {_describe(t)}")

    def default(self) -> float:
        self.expect(":=", "':='")
        t = self.peek()
        if self.is_kw(t, "NC"):
            raise self.err(t, "unsupported: DEFAULT := NC (no change: the output keeps its "
                              "previous value, which makes the system stateful)")
        value = self.number("the DEFAULT value")
        if self.peek().kind == "|":
            nc = self.advance()
            raise self.err(nc, "unsupported: DEFAULT ... | NC (no change: the output keeps "
                               "its previous value, which makes the system stateful)")
        self.expect(";", "';'")
        return value

    def lock(self, b: _Block) -> None:
        flags: list[_Tok] = []
        while True:
            t = self.peek()
            if t.kind != "id":
                raise self.err(t, f"expected RANGE or PREVIOUS, found {_describe(t)}")
            flags.append(self.advance())
            if self.peek().kind != "|":
                break
            self.advance()
        self.expect(";", "';'")
        for f in flags:
            word = f.text.upper()
            if word == "PREVIOUS":
                raise self.err(f, "unsupported: LOCK : PREVIOUS (the previous output when no "
                                  "rule fires makes the system stateful)")
            if word != "RANGE":
                raise self.err(f, f"unsupported LOCK flag: {f.text} (supported: RANGE)")
        b.lock = True

    def term(self, b: _Block) -> None:
        self.advance()
        name = self.name("a term name")
        if name.text in b.term_names:
            raise self.err(name, f"{b.name.text!r} has a second term {name.text!r}")
        b.term_names.add(name.text)
        self.expect(":=", "':='")
        t = self.peek()
        if t.kind == "(":
            params: list[float] = []
            while self.peek().kind == "(":
                if len(params) == 2 * MAX_POINTS:
                    text = self.src.text
                    end = text.find(";", t.pos)
                    count = text.count("(", t.pos, end if end >= 0 else len(text))
                    raise self.err(t, f"term {name.text!r} has {count} points; a term takes "
                                      f"at most {MAX_POINTS}")
                self.advance()
                params.append(self.number("a point's x"))
                self.expect(",", "','")
                params.append(self.number("a point's y"))
                self.expect(")", "')'")
            spec = _TermSpec(name, "points", params=params)
        elif self.is_number(t):
            spec = _TermSpec(name, "number", params=[self.number("the singleton's value")])
        elif t.kind == "id":
            word = t.text.lower()
            if word not in _SHAPE_WORDS:
                raise self.err(t, f"unsupported term shape: {t.text} (supported: "
                                  f"{_SHAPE_NAMES})")
            self.advance()
            params = []
            while self.peek().kind != ";":
                if len(params) == 2 * MAX_POINTS + 1:  # a Discrete term's points, its height
                    raise self.err(t, f"term {name.text!r}: more than {2 * MAX_POINTS + 1} "
                                      f"numbers ({MAX_POINTS} points and a height at most)")
                params.append(self.number(f"a parameter of {t.text}"))
            spec = _TermSpec(name, "class", word=word, shape_tok=t, params=params)
        else:
            raise self.err(t, f"expected a membership function, found {_describe(t)}")
        self.expect(";", "';'")
        b.terms.append(spec)

    # -- RULEBLOCK --------------------------------------------------------------------------
    def rule_block(self) -> None:
        rb = _RuleBlock(self.advance())
        nt = self.peek()
        if nt.kind == "id" and nt.text.upper() not in _RESERVED:
            self.advance()
        elif nt.kind == "num":
            self.advance()
        self.blocks.append(rb)
        while True:
            t = self.peek()
            word = t.text.upper() if t.kind == "id" else ""
            if word == "END_RULEBLOCK":
                self.advance()
                return
            if word in _OP_TABLES:
                self.advance()
                if word in rb.ops:
                    raise self.err(t, f"second {word} in this RULEBLOCK")
                rb.ops[word] = self.colon_word(f"an {word} method")
            elif word == "ENABLED":
                self.enabled()
            elif word == "RULE":
                rb.rules.append(self.rule())
            else:
                raise self.err(t, "expected RULE, AND, OR, ACT, ACCU or END_RULEBLOCK, found "
                                  f"{_describe(t)}")

    def at_item(self) -> bool:
        """True at a token that starts the next RULEBLOCK item (a rule without ';')."""
        t = self.peek()
        if self.is_kw(t, "RULE", "END_RULEBLOCK", "ENABLED"):
            return True
        return self.is_kw(t, "AND", "OR", "ACT", "ACCU") and self.peek(1).kind == ":"

    def rule(self) -> _RuleSpec:
        tok = self.advance()
        label = self.peek()
        if label.kind in ("num", "id") and not self.is_kw(label, "IF"):
            self.advance()
        else:
            raise self.err(label, f"expected a rule number, found {_describe(label)}")
        self.expect(":", "':'")
        self.expect_kw("IF")
        ante = self.cond(1)
        self.expect_kw("THEN")
        cons = [self.conclusion()]
        while True:
            t = self.peek()
            if t.kind == "," or (self.is_kw(t, "AND") and self.peek(1).kind != ":"):
                self.advance()
                cons.append(self.conclusion())
            else:
                break
        weight = 1.0
        if self.is_kw(self.peek(), "WITH"):
            self.advance()
            nt = self.peek()
            weight = self.number("the rule weight")
            if not (0.0 <= weight <= 1.0):
                raise self.err(nt, f"rule weight must be in [0, 1], got {nt.text}")
        if self.peek().kind == ";":
            self.advance()
        elif not self.at_item():
            t = self.peek()
            raise self.err(t, f"expected ';' or the next RULE, found {_describe(t)}")
        return _RuleSpec(tok, ante, cons, weight)

    def cond(self, depth: int) -> _Node:
        first = self.sub(depth)
        items = [first]
        op: str | None = None
        while True:
            t = self.peek()
            if not self.is_kw(t, "AND", "OR"):
                break
            word = t.text.upper()
            if op is None:
                op = word
            elif word != op:
                raise self.err(t, "mixing AND and OR without parentheses is ambiguous "
                                  "(fuzzylite binds AND tighter, jFuzzyLogic reads left to "
                                  "right): add parentheses")
            self.advance()
            items.append(self.sub(depth))
        if op is None:
            return first
        return _NOp(op, tuple(items))

    def sub(self, depth: int) -> _Node:
        t = self.peek()
        if depth > MAX_DEPTH:
            raise self.err(t, f"rule nested deeper than {MAX_DEPTH} levels")
        if self.is_kw(t, "NOT"):
            self.advance()
            return _NNot(self.sub(depth + 1), t)
        if t.kind == "(":
            self.advance()
            node = self.cond(depth + 1)
            self.expect(")", "')'")
            return node
        var = self.name("a variable name, NOT or '('")
        self.expect_kw("IS")
        negated = False
        if self.is_kw(self.peek(), "NOT"):
            self.advance()
            negated = True
        term = self.term_ref()
        return _NIs(var, term, negated)

    def term_ref(self) -> _Tok:
        t = self.peek()
        if self.is_kw(t, "NOT"):
            raise self.err(t, "unsupported hedge: NOT after IS NOT (supported: IS NOT once)")
        term = self.name("a term name")
        nt = self.peek()
        if nt.kind == "id" and nt.text.upper() not in _RESERVED and term.text.lower() in _HEDGES:
            raise self.err(term, f"unsupported hedge: {term.text} (supported: NOT)")
        return term

    def conclusion(self) -> tuple[_Tok, _Tok]:
        paren = self.peek().kind == "("
        if paren:
            self.advance()
        var = self.name("an output variable name")
        self.expect_kw("IS")
        if self.is_kw(self.peek(), "NOT"):
            raise self.err(self.peek(), "unsupported: IS NOT in a conclusion")
        term = self.term_ref()
        if paren:
            self.expect(")", "')'")
        return var, term


# --------------------------------------------------------------------------------------------
# building the model
# --------------------------------------------------------------------------------------------

def _canonical(params: list[float] | tuple[float, ...]) -> tuple[str, tuple[float, ...]]:
    """The simplest shape with exactly the vertices of a point list (x, y, x, y, ...)."""
    xs, ys = list(params[0::2]), tuple(params[1::2])
    p = tuple(params)
    if len(xs) < 2 or any(not (b > a) for a, b in zip(xs, xs[1:], strict=False)):
        return "discrete", p
    inf = math.inf
    if ys == (0.0, 1.0):
        return "ramp", (xs[0], xs[1])
    if ys == (1.0, 0.0):
        return "ramp", (xs[1], xs[0])
    if ys == (0.0, 1.0, 0.0):
        return "triangle", (xs[0], xs[1], xs[2])
    if ys == (1.0, 1.0, 0.0):
        return "trapezoid", (-inf, xs[0], xs[1], xs[2])
    if ys == (0.0, 1.0, 1.0):
        return "trapezoid", (xs[0], xs[1], xs[2], inf)
    if ys == (0.0, 1.0, 1.0, 0.0):
        return "trapezoid", (xs[0], xs[1], xs[2], xs[3])
    return "discrete", p


class _Builder:
    """Turns the parsed pieces into a FuzzySystem, with file locations for every error."""

    def __init__(self, p: _Parser) -> None:
        self.p = p
        self.notes: list[str] = []
        # name -> index of the inputs, outputs and each variable's terms (rules look names
        # up in constant time: a scan per clause made large files quadratic)
        self.input_at: dict[str, int] = {}
        self.output_at: dict[str, int] = {}
        self.term_at: dict[str, dict[str, int]] = {}

    def err(self, t: _Tok, msg: str) -> FormatError:
        return self.p.err(t, msg)

    def sugeno(self) -> bool:
        for b in self.p.defuzzify.values():
            if any(ts.kind == "class" and ts.word in _SUGENO_WORDS for ts in b.terms):
                return True
            if b.method is not None:
                entry = _METHODS.get(b.method.text.upper())
                if entry is not None and entry[1]:
                    return True
        return False

    def term(self, ts: _TermSpec, sugeno: bool) -> Term:
        params = ts.params
        height = 1.0
        if ts.kind == "points":
            shape, pars = _canonical(params)
        elif ts.kind == "number":
            shape, pars = ("constant" if sugeno else "singleton"), tuple(params)
        else:
            assert ts.shape_tok is not None
            shape, count, has_height = _SHAPE_WORDS[ts.word]
            label = ts.shape_tok.text
            if shape == "discrete":
                if len(params) % 2 == 1:
                    params, height = params[:-1], params[-1]
            elif shape == "linear":
                pass
            else:
                assert count is not None
                if has_height and len(params) == count + 1:
                    params, height = params[:-1], params[-1]
                if len(params) != count:
                    extra = " (and an optional height)" if has_height else ""
                    raise self.err(ts.shape_tok, f"{label} takes {count} parameters{extra}, "
                                                 f"got {len(ts.params)}")
            if ts.word == "gbell":  # jFuzzyLogic: GBELL a(width) b(slope) mean
                params = [params[2], params[0], params[1]]
            elif ts.word == "sigm":  # jFuzzyLogic: SIGM gain center
                params = [params[1], params[0]]
            pars = tuple(params)
        try:
            return Term(ts.name.text, shape, pars, height)
        except ParameterError as exc:
            raise self.err(ts.name, str(exc)) from None

    def span(self, terms: tuple[Term, ...], what: str, where: _Tok) -> tuple[float, float]:
        xs: list[float] = []
        for t in terms:
            v = t.vertices
            if t.shape in ("ramp", "singleton"):
                xs.extend(t.params)
            elif v is not None:
                xs.extend(x for x, _ in v)
            else:
                raise self.err(where, f"{what} has no RANGE and term {t.name!r} ({t.shape}) "
                                      f"has no bounded support: add RANGE := (lo .. hi)")
        if not xs or min(xs) == max(xs):
            raise self.err(where, f"{what} has no RANGE and its terms do not span an "
                                  f"interval: add RANGE := (lo .. hi)")
        lo, hi = min(xs), max(xs)
        self.notes.append(f"{what} has no RANGE: using the span of its terms "
                          f"[{fmt_float(lo)}, {fmt_float(hi)}]")
        return lo, hi

    def variable(self, name: str, sugeno: bool) -> Variable:
        p = self.p
        d = p.decls[name]
        table = p.defuzzify if d.output else p.fuzzify
        block = table.get(name)
        terms = tuple(self.term(ts, sugeno) for ts in block.terms) if block else ()
        rng = d.range
        rtok = d.range_tok
        if block is not None and block.range is not None:
            if rng is not None and rng != block.range:
                assert block.range_tok is not None
                raise self.err(block.range_tok, f"RANGE of {name!r} differs from the one in "
                                                f"its declaration")
            rng, rtok = block.range, block.range_tok
        role = "output" if d.output else "input"
        where = block.name if block is not None else d.name
        if rng is None:
            rng = self.span(terms, f"{role} {name!r}", where)
            rtok = where
        assert rtok is not None
        default = math.nan
        clip = True
        if d.output:
            clip = block.lock if block is not None else False
            if block is not None and block.default is not None:
                default = block.default
            else:
                self.notes.append(f"output {name!r} has no DEFAULT: NaN when no rule fires")
        try:
            return Variable(name, rng, terms, default=default, clip=clip)
        except ParameterError as exc:
            msg = str(exc)
            t = rtok if "range" in msg else where
            raise self.err(t, msg) from None

    def defuzzifier(self, sugeno: bool, outputs: tuple[Variable, ...]) -> str:
        chosen: str | None = None
        chosen_tok: _Tok | None = None
        for v in outputs:
            b = self.p.defuzzify.get(v.name)
            if b is None or b.method is None:
                where = b.name if b is not None else self.p.decls[v.name].name
                raise self.err(where, f"output {v.name!r} has no METHOD (IEC 61131-7 "
                                      f"requires one)")
            mt = b.method
            word = mt.text.upper()
            entry = _METHODS.get(word)
            if entry is None:
                raise self.err(mt, f"unsupported METHOD: {mt.text} (supported: "
                                   f"{_METHOD_NAMES})")
            method = entry[0]
            if method == "cogs":
                if sugeno:
                    method = "wtaver"
                else:
                    if not v.terms or any(t.shape != "singleton" for t in v.terms):
                        raise self.err(mt, f"METHOD COGS needs singleton terms (numbers); "
                                           f"output {v.name!r} has others")
                    method = "centroid"
            if sugeno and method not in ("wtaver", "wtsum"):
                raise self.err(mt, f"METHOD {mt.text} on a Sugeno system (Constant / Linear "
                                   f"terms): use COGS (weighted average) or COGSS (weighted "
                                   f"sum)")
            if not sugeno and v.terms and all(t.shape == "singleton" for t in v.terms) \
                    and method == "bisector":
                raise self.err(mt, f"METHOD COA of singleton terms (output {v.name!r}) is "
                                   f"not defined: use COGS or a maximum method")
            if chosen is None:
                chosen, chosen_tok = method, mt
            elif method != chosen:
                assert chosen_tok is not None
                raise self.err(mt, f"unsupported: outputs with different METHODs "
                                   f"({chosen_tok.text} and {mt.text}); the model has one "
                                   f"defuzzifier")
        assert chosen is not None
        return chosen

    def operators(self, outputs: tuple[Variable, ...]) -> dict[str, str]:
        stated: dict[str, tuple[str, _Tok]] = {}

        def note(word: str, t: _Tok) -> None:
            table, names = _OP_TABLES[word]
            value = table.get(t.text.upper())
            if value is None:
                extra = ""
                if word == "OR" and t.text.upper() in ("BSUM", "BOUNDEDSUM"):
                    extra = " (bounded sum as OR)"
                if word == "ACCU" and t.text.upper() in ("NSUM", "NORMALIZEDSUM"):
                    extra = " (normalised sum)"
                raise self.err(t, f"unsupported {word} method: {t.text}{extra} (supported: "
                                  f"{names})")
            if word in stated and stated[word][0] != value:
                raise self.err(t, f"unsupported: {word} {t.text} differs from "
                                  f"{word} {stated[word][1].text} stated before (the model "
                                  f"has one {word} for all rules and outputs)")
            stated.setdefault(word, (value, t))

        for rb in self.p.blocks:
            for word, t in rb.ops.items():
                note(word, t)
        for b in self.p.defuzzify.values():
            if b.accu is not None:
                note("ACCU", b.accu)
        ops = {k: v[0] for k, v in stated.items()}
        if "AND" not in ops and "OR" not in ops:
            ops["AND"], ops["OR"] = "min", "max"
            self.notes.append("no AND or OR given: MIN and MAX")
        elif "AND" not in ops:
            ops["AND"] = _DUAL[ops["OR"]]
            self.notes.append(f"no AND given: {ops['AND']}, the De Morgan pair of OR")
        elif "OR" not in ops:
            ops["OR"] = _DUAL[ops["AND"]]
            self.notes.append(f"no OR given: {ops['OR']}, the De Morgan pair of AND")
        if "ACT" not in ops:
            ops["ACT"] = "min"
            self.notes.append("no ACT given: MIN")
        if "ACCU" not in ops:
            # IEC 61131-7 requires ACCU; files without it come from fuzzylite, whose COGS is
            # the weighted average of the rules: accumulation by SUM over singletons
            single = [all(t.shape == "singleton" for t in v.terms) for v in outputs if v.terms]
            ops["ACCU"] = "sum" if single and all(single) else "max"
            self.notes.append(f"no ACCU given: {ops['ACCU'].upper()}")
        return ops

    def expr(self, n: _Node, inputs: tuple[Variable, ...]) -> Expr:
        if isinstance(n, _NIs):
            name = n.var.text
            idx = self.input_at.get(name)
            if idx is None:
                d = self.p.decls.get(name)
                if d is not None and d.output:
                    raise self.err(n.var, f"unsupported: rule antecedent uses output variable "
                                          f"{name!r} (chained rule bases)")
                raise self.err(n.var, f"unknown input variable {name!r} (inputs: "
                                      f"{', '.join(v.name for v in inputs) or 'none'})")
            return Is(idx, self.term_index(inputs[idx], n.term, "input"), n.negated)
        if isinstance(n, _NNot):
            return Not(self.expr(n.operand, inputs))
        ops = tuple(self.expr(o, inputs) for o in n.operands)
        return And(ops) if n.word == "AND" else Or(ops)

    def term_index(self, v: Variable, t: _Tok, role: str) -> int:
        index = self.term_at.get(v.name)
        if index is None:
            index = self.term_at[v.name] = {term.name: i for i, term in enumerate(v.terms)}
        if t.text in index:
            return index[t.text]
        if t.text.lower() in _HEDGES:
            raise self.err(t, f"unsupported hedge: {t.text} (supported: NOT)")
        raise self.err(t, f"{role} {v.name!r} has no term {t.text!r} (terms: "
                          f"{', '.join(x.name for x in v.terms) or 'none'})")

    def rules(self, inputs: tuple[Variable, ...],
              outputs: tuple[Variable, ...]) -> tuple[Rule, ...]:
        out: list[Rule] = []
        for rb in self.p.blocks:
            for rs in rb.rules:
                ante = self.expr(rs.antecedent, inputs)
                cons: list[Consequent] = []
                for vt, tt in rs.consequents:
                    idx = self.output_at.get(vt.text)
                    if idx is None:
                        d = self.p.decls.get(vt.text)
                        if d is not None:
                            raise self.err(vt, f"a conclusion must name an output; "
                                               f"{vt.text!r} is an input")
                        raise self.err(vt, f"unknown output variable {vt.text!r} (outputs: "
                                           f"{', '.join(v.name for v in outputs)})")
                    cons.append(Consequent(idx, self.term_index(outputs[idx], tt, "output")))
                out.append(Rule(ante, tuple(cons), rs.weight))
        return tuple(out)

    def check_outputs(self, kind: str, outputs: tuple[Variable, ...], n_in: int) -> None:
        p = self.p
        for v in outputs:
            b = p.defuzzify.get(v.name)
            for ts, t in zip(b.terms if b else [], v.terms, strict=True):
                if kind == "sugeno" and t.shape not in ("constant", "linear"):
                    raise self.err(ts.name, f"term {t.name!r} of output {v.name!r} is a "
                                            f"{t.shape}: a Sugeno system (Constant / Linear "
                                            f"terms, COGS / COGSS) needs Constant or Linear "
                                            f"terms only")
                if kind == "sugeno" and t.shape == "linear" and len(t.params) != n_in + 1:
                    raise self.err(ts.name, f"Linear term {t.name!r} needs {n_in + 1} "
                                            f"coefficients (one per input, then the "
                                            f"constant), got {len(t.params)}")
            single = [t.shape == "singleton" for t in v.terms]
            if any(single) and not all(single):
                where = b.name if b is not None else p.decls[v.name].name
                raise self.err(where, f"output {v.name!r} mixes singleton terms with terms "
                                      f"that have area; use singletons only (COGS) or none")

    def build(self) -> FuzzySystem:
        p = self.p
        if not p.order_in or not p.order_out:
            raise self.err(p.fb_tok, "a FUNCTION_BLOCK needs at least one VAR_INPUT and one "
                                     "VAR_OUTPUT variable")
        sugeno = self.sugeno()
        inputs = tuple(self.variable(n, False) for n in p.order_in)
        outputs = tuple(self.variable(n, sugeno) for n in p.order_out)
        kind = "sugeno" if sugeno else "mamdani"
        self.check_outputs(kind, outputs, len(inputs))
        defuzz = self.defuzzifier(sugeno, outputs)
        ops = self.operators(outputs)
        self.input_at = {v.name: i for i, v in enumerate(inputs)}
        self.output_at = {v.name: i for i, v in enumerate(outputs)}
        rules = self.rules(inputs, outputs)
        name = p.fb_name if p.fb_name is not None else "fuzzy"
        if p.fb_name is None:
            self.notes.append("FUNCTION_BLOCK has no name: 'fuzzy'")
        try:
            return FuzzySystem(
                name=name, kind=kind, inputs=inputs, outputs=outputs, rules=rules,  # type: ignore[arg-type]
                and_op=ops["AND"], or_op=ops["OR"], implication=ops["ACT"],  # type: ignore[arg-type]
                aggregation=ops["ACCU"], defuzzifier=defuzz,  # type: ignore[arg-type]
                notes=tuple(self.notes))
        except ParameterError as exc:
            raise self.err(p.fb_tok, str(exc)) from None


def parse(text: str, source: str = "<string>") -> FuzzySystem:
    """Read an FCL file (IEC 61131-7, with jFuzzyLogic's and fuzzylite's dialects).

    Parameters
    ----------
    text : str
        The file's text (a byte-order mark and CRLF line ends are accepted).
    source : str
        The file name shown in error messages.

    Returns
    -------
    FuzzySystem
        The system; ``notes`` lists the defaults the reader chose (missing RANGE, DEFAULT,
        operators).

    Raises
    ------
    FormatError
        ``source:line:col: message`` for a malformed file or an unsupported feature (named).
    """
    if not isinstance(text, str):
        raise FormatError(f"{source}:1:1: expected text, got {type(text).__name__}")
    if len(text) > MAX_CHARS:
        raise FormatError(f"{source}:1:1: file of {len(text)} characters is larger than the "
                          f"{MAX_CHARS}-character limit")
    src = Source(text, source)
    p = _Parser(src, _lex(src))
    p.file()
    return _Builder(p).build()


# --------------------------------------------------------------------------------------------
# writer
# --------------------------------------------------------------------------------------------

_WRITE_AND = {"min": "MIN", "product": "PROD"}
_WRITE_OR = {"max": "MAX", "probor": "ASUM"}
_WRITE_ACT = {"min": "MIN", "product": "PROD"}
# fuzzylite's FCL reader knows MAX, BSUM, ASUM and reads other names as its class names
_WRITE_ACCU = {"max": "MAX", "bounded_sum": "BSUM", "probor": "ASUM", "sum": "UnboundedSum"}
_WRITE_METHOD = {"centroid": "COG", "bisector": "COA", "som": "LM", "lom": "RM", "mom": "MM",
                 "wtaver": "COGS", "wtsum": "COGSS"}
_FULL_ID = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z0-9_]+)*$")


def _check_name(what: str, name: str, hedge_ok: bool = True) -> None:
    if not _FULL_ID.match(name):
        raise ParameterError(f"FCL cannot spell the {what} name {name!r} (letters, digits, _ "
                             f"and inner dots only)")
    if name.upper() in _RESERVED:
        raise ParameterError(f"FCL cannot hold the {what} name {name!r}: it is an FCL keyword")
    if not hedge_ok and name.lower() in _HEDGES:
        raise ParameterError(f"FCL cannot hold the {what} name {name!r}: fuzzylite reads it as "
                             f"a hedge")


def _points(vertices: tuple[tuple[float, float], ...]) -> str:
    return " ".join(f"({fmt_float(x)}, {fmt_float(y)})" for x, y in vertices)


def _write_term(system: FuzzySystem, v: Variable, t: Term, role: str) -> str:
    where = f"{role} {v.name!r} term {t.name!r}"
    if t.shape in ("singleton", "constant", "linear") and t.height != 1.0:
        raise ParameterError(f"FCL cannot hold term height {fmt_float(t.height)} of {where} "
                             f"(a {t.shape} has no height in FCL)")
    if t.shape == "singleton":
        return fmt_float(t.params[0])
    if t.shape in PIECEWISE_LINEAR and t.height == 1.0:
        if t.shape == "discrete":
            pts = tuple(zip(t.params[0::2], t.params[1::2], strict=True))
        else:
            vert = t.vertices
            assert vert is not None
            pts = vert
        flat = [c for xy in pts for c in xy]
        shape, pars = _canonical(flat)
        if shape == t.shape and pars == t.params:
            return _points(pts)
    values = list(t.params)
    if t.height != 1.0:
        values.append(t.height)
    return " ".join([_CLASS_OF[t.shape], *(fmt_float(x) for x in values)])


def _negation(system: FuzzySystem, k: int, e: Not) -> NoReturn:
    """NOT in rule k: refused (a clause's own ``negated`` is written as ``is not``)."""
    raise ParameterError(
        f"FCL (as fuzzylite reads it) cannot hold NOT applied to an expression (rule {k}: "
        f"{system.rule_text(system.rules[k - 1])}); use 'variable is not term' clauses")


def dump(system: FuzzySystem) -> str:
    """The FCL text of a fuzzy system (IEC 61131-7 layout that fuzzylite 6 also reads).

    Parameters
    ----------
    system : FuzzySystem
        The system to write.

    Returns
    -------
    str
        FCL text; :func:`parse` reads it back to a system equal to ``system``.

    Raises
    ------
    ParameterError
        Naming what FCL cannot hold (see the module notes): an input that is not clipped, NOT
        of an expression, the height of a singleton or Sugeno term, a maximum method over
        singleton terms, names FCL cannot spell or that are keywords.
    """
    if not isinstance(system, FuzzySystem):
        raise ParameterError(f"expected a FuzzySystem, got {type(system).__name__}")
    _check_name("system", system.name)
    for v in system.inputs:
        _check_name("input", v.name)
        if not math.isnan(v.default):
            raise ParameterError(f"FCL cannot hold the default {fmt_float(v.default)} of input "
                                 f"{v.name!r} (inputs have no default)")
        if not v.clip:
            raise ParameterError(
                f"FCL cannot hold input {v.name!r} without clipping: FCL has no flag for it "
                f"and this reader clips inputs to their RANGE (fis convert --clip-inputs "
                f"clips them)")
    for v in system.outputs:
        _check_name("output", v.name)
    if system.kind == "sugeno" and system.defuzzifier == "wtaver" \
            and not any(v.terms for v in system.outputs):
        raise ParameterError(
            "FCL cannot mark a Sugeno system whose outputs have no terms: it is read as Sugeno "
            "from its Constant / Linear terms (or METHOD COGSS)")
    for role, vs in (("input", system.inputs), ("output", system.outputs)):
        for v in vs:
            for t in v.terms:
                _check_name(f"{role} {v.name!r} term", t.name, hedge_ok=False)

    lines = [f"FUNCTION_BLOCK {system.name}", "", "VAR_INPUT"]
    lines += [f"  {v.name} : REAL;" for v in system.inputs]
    lines += ["END_VAR", "", "VAR_OUTPUT"]
    lines += [f"  {v.name} : REAL;" for v in system.outputs]
    lines += ["END_VAR", ""]
    for v in system.inputs:
        lines.append(f"FUZZIFY {v.name}")
        lines.append(f"  RANGE := ({fmt_float(v.range[0])} .. {fmt_float(v.range[1])});")
        for t in v.terms:
            lines.append(f"  TERM {t.name} := {_write_term(system, v, t, 'input')};")
        lines += ["END_FUZZIFY", ""]
    for v in system.outputs:
        single = bool(v.terms) and all(t.shape == "singleton" for t in v.terms)
        method = _WRITE_METHOD[system.defuzzifier]
        if single:
            if system.defuzzifier != "centroid":
                raise ParameterError(
                    f"FCL (as fuzzylite reads it) cannot hold {method} over the singleton "
                    f"terms of output {v.name!r}: only COGS (centroid) is read as singletons")
            method = "COGS"
        lines.append(f"DEFUZZIFY {v.name}")
        lines.append(f"  RANGE := ({fmt_float(v.range[0])} .. {fmt_float(v.range[1])});")
        for t in v.terms:
            lines.append(f"  TERM {t.name} := {_write_term(system, v, t, 'output')};")
        lines.append(f"  METHOD : {method};")
        lines.append(f"  ACCU : {_WRITE_ACCU[system.aggregation]};")
        if not math.isnan(v.default):
            lines.append(f"  DEFAULT := {fmt_float(v.default)};")
        if v.clip:
            lines.append("  LOCK : RANGE;")
        lines += ["END_DEFUZZIFY", ""]
    lines.append("RULEBLOCK rules")
    lines.append(f"  AND : {_WRITE_AND[system.and_op]};")
    lines.append(f"  OR : {_WRITE_OR[system.or_op]};")
    lines.append(f"  ACT : {_WRITE_ACT[system.implication]};")
    for k, r in enumerate(system.rules, start=1):
        lines.append(f"  RULE {k} : {fuzzylite_rule(system, r, partial(_negation, system, k))};")
    lines += ["END_RULEBLOCK", "", "END_FUNCTION_BLOCK", ""]
    return "\n".join(lines)
