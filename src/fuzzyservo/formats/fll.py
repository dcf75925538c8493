"""fuzzylite FLL: reader and writer.

FLL is the text format of fuzzylite 6 (the C++ library and its ``fuzzylite`` CLI) and, nearly
unchanged, of pyfuzzylite 8: one ``key: value`` statement per line, ``#`` comments to the end of
the line, blocks opened by ``Engine:``, ``InputVariable:``, ``OutputVariable:`` and
``RuleBlock:``::

    Engine: tipper
    InputVariable: service
      enabled: true
      range: 0 10
      lock-range: true
      term: poor Trapezoid 0 0 2.5 5
    OutputVariable: tip
      enabled: true
      range: 0 30
      lock-range: false
      aggregation: Maximum
      defuzzifier: Centroid 10000
      default: nan
      lock-previous: false
      term: cheap Triangle 0 5 10
    RuleBlock: rules
      enabled: true
      conjunction: Minimum
      disjunction: Maximum
      implication: Minimum
      activation: General
      rule: if service is poor then tip is cheap with 0.5

What is read (fuzzylite 6 semantics throughout):

- Terms ``NAME Class params [height]``; the optional number after the class's parameters is
  the term's height (Discrete: an odd count of numbers ends with it). Classes: Triangle,
  Trapezoid, Rectangle, Ramp, Discrete (x y pairs), Gaussian (mean sd), GaussianProduct
  (meanA sdA meanB sdB), Bell (center width slope), Sigmoid (inflection slope),
  SigmoidDifference and SigmoidProduct (left rising falling right), PiShape, SShape, ZShape,
  Constant (value, no height) and Linear (one coefficient per input, then the constant; no
  height). A Triangle with an infinite first or last vertex is fuzzylite's shoulder and reads as
  the equal trapezoid; ``Binary start +-inf`` reads as the equal trapezoid
  ``(start, start, start, inf)`` or ``(-inf, start, start, start)``. Spike, Cosine, Concave,
  Function, Arc, SemiEllipse, Activated and Aggregated are refused by name.
- ``lock-range`` is :attr:`Variable.clip` (absent: false, fuzzylite's default); ``default``
  is the output's value when no rule fires (``nan`` allowed: fuzzylite's "no value").
- Aggregation Maximum, BoundedSum, UnboundedSum, AlgebraicSum; conjunction Minimum,
  AlgebraicProduct; disjunction Maximum, AlgebraicSum; implication Minimum, AlgebraicProduct;
  ``none`` where the system does not need the operator. Activation General (``none`` or
  absent: fuzzylite 6 then uses General).
- Defuzzifiers Centroid, Bisector, MeanOfMaximum, SmallestOfMaximum, LargestOfMaximum (an
  optional resolution is read and ignored: fuzzyservo integrates exactly; a note says so) make a
  Mamdani system; WeightedAverage and WeightedSum (TakagiSugeno, Automatic with Constant/Linear
  terms, or no type) a Sugeno system.
- Rules ``if A then y is t [and z is u ...] [with w]``: ``and`` binds tighter than ``or`` (as in
  fuzzylite), parentheses nest up to :data:`MAX_DEPTH` levels, the only hedge is ``not``
  (``x is not t``; repeated ``not`` is applied repeatedly). A chain ``a and b and c`` is one
  n-ary :class:`And`; a parenthesised group stays a nested node, so the order in which the
  operands are combined is the file's.

Decisions:

- One aggregation and one defuzzifier per system (the model holds one set): outputs that
  differ are refused naming the output. Several rule blocks are merged in file order when their
  operators agree (``none`` agrees with anything); a rule that uses ``and`` (``or``) in a block
  whose conjunction (disjunction) is ``none`` is an error at that word.
- A rule block with ``enabled: false`` is dropped with a note (fuzzylite ignores it); a
  disabled variable is refused (fuzzylite would still count it in Linear terms and make its
  clauses 0, which the model cannot hold). ``lock-previous: true`` is refused (it makes the
  output depend on the previous call).
- A Sugeno system ignores the aggregation and implication (fuzzylite 6's weighted
  defuzzifiers do: they weight each fired rule separately). The reader maps ``none`` to the
  model's defaults (max, min); the writer writes those defaults as ``none`` and any other value
  by name, so the values survive a round trip. pyfuzzylite 8 instead groups the fired rules of
  each term by the aggregation: ``none`` and UnboundedSum give the same result as fuzzylite 6; a
  note says when a file names another aggregation for a Sugeno output.
- Rules may only mention variables declared above their rule block (fuzzylite loads rules as
  it reads them and silently drops the ones it cannot resolve); an output variable in an
  antecedent (a chained system) is refused.
- fuzzylite's MeanOfMaximum is the middle of the *first* plateau of the sampled maximum; the
  model's ``mom`` is the mean of the maximising set. They agree when the maximum is reached on
  one interval, which is the common case; the reader and writer map one to the other.
- Sizes are bounded: :data:`MAX_DEPTH` nested parentheses and ``not``, :data:`MAX_NUMBERS`
  numbers per term, :data:`MAX_TERMS` terms per variable, :data:`MAX_VARIABLES` variables.
- Names must be the model's identifiers; the Engine name may be absent or empty (the system is
  then called ``fuzzy``). Keys are case-sensitive, as in fuzzylite; a repeated key (two
  ``range:`` lines) is an error (fuzzylite keeps the last one).

What is written: every value with :func:`fmt_float` (exact), ``enabled: true``,
``lock-previous: false``, ``activation: General``, one rule block. fuzzylite samples the
integral defuzzifiers; the written resolution is :data:`WRITE_RESOLUTION` (10^4 samples, a
midpoint-rule error of about range/10^4 per kink or edge of the aggregate, a hundred times finer
than fuzzylite's default 100); our reader ignores it, so a round trip is exact either way. The
writer refuses (``ParameterError``) what FLL cannot hold: singleton terms, a height other than 1
on Constant or Linear terms, a ``not`` of a compound expression (FLL's ``not`` is a hedge of
one clause), names that are FLL keywords, and a non-NaN default on an input.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from functools import partial
from typing import cast

from ..errors import FormatError, ParameterError
from ..fuzzy.shapes import SHAPE_TABLE, SUGENO
from ..fuzzy.system import (
    AggregationOp,
    And,
    AndOp,
    Consequent,
    DefuzzifierName,
    Expr,
    FuzzySystem,
    ImplicationOp,
    Is,
    Kind,
    Not,
    Or,
    OrOp,
    Rule,
    Term,
    Variable,
)
from ._text import Source, clause_text, fmt_float, fuzzylite_rule, parse_float

__all__ = ["MAX_DEPTH", "MAX_NUMBERS", "MAX_TERMS", "MAX_VARIABLES", "WRITE_RESOLUTION", "dump",
           "parse"]

#: Deepest nesting of parentheses and ``not`` hedges in one rule.
MAX_DEPTH = 200
#: Most numbers after a term's class (Discrete: 512 points), terms per variable, and
#: variables: far above hand-written systems, and they keep the model's checks (quadratic in
#: these counts) fast on hostile files.
MAX_NUMBERS = 1024
MAX_TERMS = 1024
MAX_VARIABLES = 1024
#: Resolution written after Centroid, Bisector and the maxima defuzzifiers [samples].
WRITE_RESOLUTION = 10_000

#: FLL term class -> (model shape, number of parameters before the optional height; None:
#: variable), from the shape table; fuzzylite's Binary (start, direction) is read as a
#: shoulder trapezoid.
_CLASSES: dict[str, tuple[str, int | None]] = {
    **{s.fll: (s.name, None if s.params is None else len(s.params))
       for s in SHAPE_TABLE if s.fll is not None},
    "Binary": ("trapezoid", 2),
}
_SHAPE_CLASS = {shape: cls for cls, (shape, _) in _CLASSES.items() if cls != "Binary"}

_AGGREGATIONS = {"Maximum": "max", "BoundedSum": "bounded_sum", "UnboundedSum": "sum",
                 "AlgebraicSum": "probor"}
_CONJUNCTIONS = {"Minimum": "min", "AlgebraicProduct": "product"}
_DISJUNCTIONS = {"Maximum": "max", "AlgebraicSum": "probor"}
_IMPLICATIONS = {"Minimum": "min", "AlgebraicProduct": "product"}
_INTEGRAL = {"Centroid": "centroid", "Bisector": "bisector", "MeanOfMaximum": "mom",
             "SmallestOfMaximum": "som", "LargestOfMaximum": "lom"}
_WEIGHTED = {"WeightedAverage": "wtaver", "WeightedSum": "wtsum"}
_AGG_CLASS = {m: c for c, m in _AGGREGATIONS.items()}
_AND_CLASS = {m: c for c, m in _CONJUNCTIONS.items()}
_OR_CLASS = {m: c for c, m in _DISJUNCTIONS.items()}
_IMP_CLASS = {m: c for c, m in _IMPLICATIONS.items()}
_DEFUZZ_CLASS = {m: c for c, m in (*_INTEGRAL.items(), *_WEIGHTED.items())}
_HEDGES = ("not", "very", "somewhat", "seldom", "extremely", "any")
_KEYWORDS = frozenset({"if", "then", "with", "and", "or", "is", "none", *_HEDGES})

_KEYS = {
    "Engine": ("description",),
    "InputVariable": ("description", "enabled", "range", "lock-range", "term"),
    "OutputVariable": ("description", "enabled", "range", "lock-range", "aggregation",
                       "defuzzifier", "default", "lock-previous", "term"),
    "RuleBlock": ("description", "enabled", "conjunction", "disjunction", "implication",
                  "activation", "rule"),
}
_BLOCKS = ("InputVariable", "OutputVariable", "RuleBlock")
_TOKEN = re.compile(r"\S+")
_RULE_TOKEN = re.compile(r"[()]|[^\s()]+")


# ----------------------------------------------------------------------------------- reader


@dataclass(frozen=True, slots=True)
class _Tok:
    text: str  #: the token
    off: int  #: offset of its first character in the file


@dataclass(frozen=True, slots=True)
class _Line:
    key: str  #: text before the colon, stripped
    key_off: int  #: offset of the key
    value: str  #: text after the colon, comment removed, stripped
    val_off: int  #: offset of the value (or of the end of the line when empty)

    def tokens(self, pattern: re.Pattern[str] = _TOKEN) -> list[_Tok]:
        return [_Tok(m.group(), self.val_off + m.start()) for m in pattern.finditer(self.value)]


@dataclass(slots=True)
class _Block:
    kind: str  #: "Engine", "InputVariable", "OutputVariable" or "RuleBlock"
    head: _Line  #: the opening line
    fields: dict[str, _Line] = field(default_factory=dict)  #: single-valued keys
    items: list[_Line] = field(default_factory=list)  #: term: / rule: lines, in order


def _lines(src: Source) -> list[_Line]:
    out: list[_Line] = []
    start = 0
    for raw in src.text.split("\n"):
        line_off = start
        start += len(raw) + 1
        hash_at = raw.find("#")
        body = raw if hash_at < 0 else raw[:hash_at]
        if not body.strip():
            continue
        lead = len(body) - len(body.lstrip())
        colon = body.find(":")
        if colon < 0:
            raise src.error(line_off + lead, f"expected 'key: value', found {body.strip()!r}")
        key = body[:colon].strip()
        if not key:
            raise src.error(line_off + lead, "expected a key before ':'")
        rest = body[colon + 1:]
        value = rest.strip()
        vlead = len(rest) - len(rest.lstrip())
        val_off = line_off + colon + 1 + (vlead if value else len(rest.rstrip()))
        out.append(_Line(key, line_off + lead, value, val_off))
    return out


def _blocks(src: Source, lines: list[_Line]) -> list[_Block]:
    blocks: list[_Block] = []
    engine: _Block | None = None
    for ln in lines:
        if ln.key == "Engine":
            if engine is not None:
                raise src.error(ln.key_off, "a second 'Engine:' line (one engine per file)")
            if blocks:
                raise src.error(ln.key_off, "'Engine:' must come before the variables and rule "
                                            "blocks")
            engine = _Block("Engine", ln)
            blocks.append(engine)
            continue
        if ln.key in _BLOCKS:
            blocks.append(_Block(ln.key, ln))
            continue
        if not blocks:  # keys before any block: an unnamed engine's
            blocks.append(_Block("Engine", _Line("Engine", ln.key_off, "", ln.key_off)))
        blk = blocks[-1]
        allowed = _KEYS[blk.kind]
        if ln.key not in allowed:
            where = "before the first block" if blk.kind == "Engine" else f"in {blk.kind}"
            expected = ", ".join(repr(k) for k in (*allowed, *_BLOCKS))
            raise src.error(ln.key_off, f"unknown key {ln.key!r} {where} (expected one of "
                                        f"{expected})")
        if ln.key in ("term", "rule"):
            blk.items.append(ln)
        elif ln.key in blk.fields:
            first, _ = src.where(blk.fields[ln.key].key_off)
            raise src.error(ln.key_off, f"{ln.key!r} repeated in {blk.kind} (first at line "
                                        f"{first})")
        else:
            blk.fields[ln.key] = ln
    return blocks


def _bool(src: Source, ln: _Line) -> bool:
    if ln.value == "true":
        return True
    if ln.value == "false":
        return False
    raise src.error(ln.val_off, f"{ln.key}: expected true or false, found {ln.value!r}")


def _number(src: Source, tok: _Tok, what: str) -> float:
    v = parse_float(tok.text)
    if v is None:
        raise src.error(tok.off, f"{what}: expected a number, found {tok.text!r}")
    return v


def _one_token(src: Source, ln: _Line) -> _Tok:
    toks = ln.tokens()
    if not toks:
        raise src.error(ln.val_off, f"{ln.key}: expected a value, found nothing")
    if len(toks) > 1:
        raise src.error(toks[1].off, f"{ln.key}: expected one value, found also "
                                     f"{toks[1].text!r}")
    return toks[0]


def _named(src: Source, ln: _Line, table: dict[str, str], what: str) -> str | None:
    """The model name of an operator, None for ``none``; unsupported names are named."""
    tok = _one_token(src, ln)
    if tok.text == "none":
        return None
    if tok.text not in table:
        options = ", ".join([*table, "none"])
        raise src.error(tok.off, f"unsupported {what}: {tok.text} (supported: {options})")
    return table[tok.text]


def _check_name(src: Source, off: int, what: str, name: str) -> None:
    try:
        # The model's own rule for names, through a variable without terms.
        Variable(name, (0.0, 1.0), ())
    except ParameterError:
        raise src.error(off, f"{what} name {name!r} is not allowed: use a letter or _ then "
                             f"letters, digits, _ or .") from None


@dataclass(slots=True)
class _Var:
    """A variable as read, before the system is assembled."""

    block: _Block
    name: str
    output: bool
    terms: list[Term]
    term_lines: list[_Line]
    range: tuple[float, float]
    clip: bool
    default: float = math.nan
    defuzz_line: _Line | None = None
    agg_line: _Line | None = None


def _term(src: Source, ln: _Line) -> Term:
    toks = ln.tokens()
    if len(toks) < 2:
        raise src.error(ln.val_off, "term: expected 'NAME Class parameters', found "
                                    f"{ln.value!r}")
    name, cls = toks[0], toks[1]
    _check_name(src, name.off, "term", name.text)
    if cls.text not in _CLASSES:
        supported = ", ".join(_CLASSES)
        raise src.error(cls.off, f"unsupported term class: {cls.text} (supported: "
                                 f"{supported})")
    shape, n = _CLASSES[cls.text]
    if len(toks) - 2 > MAX_NUMBERS:
        raise src.error(toks[2 + MAX_NUMBERS].off, f"term {name.text!r}: more than "
                                                   f"{MAX_NUMBERS} numbers")
    values = [_number(src, t, f"term {name.text!r} ({cls.text})") for t in toks[2:]]
    height = 1.0
    if cls.text == "Discrete":
        if len(values) % 2 == 1:
            height = values.pop()
    elif cls.text == "Linear":
        pass
    elif n is not None:
        extra = 0 if cls.text == "Constant" else 1
        if not n <= len(values) <= n + extra:
            takes = f"{n} parameter{'s' if n > 1 else ''}"
            opt = " and an optional height" if extra else ""
            raise src.error(cls.off, f"{cls.text} takes {takes}{opt}, got {len(values)}")
        if len(values) == n + 1:
            height = values.pop()
    params = tuple(values)
    if cls.text == "Triangle" and (math.isinf(params[0]) or math.isinf(params[2])):
        # fuzzylite's shoulder: 1 beyond the peak on the infinite side.
        a, b, c = params
        if a == -math.inf and c != math.inf:
            shape, params = "trapezoid", (a, b, b, c)
        elif c == math.inf and a != -math.inf:
            shape, params = "trapezoid", (a, b, b, c)
    elif cls.text == "Binary":
        start, direction = params
        if math.isnan(direction) or direction == start or not math.isfinite(start):
            raise src.error(cls.off, "Binary needs a finite start and a direction above or "
                                     f"below it, got {list(params)}")
        params = ((start, start, start, math.inf) if direction > start
                  else (-math.inf, start, start, start))
    try:
        return Term(name.text, shape, params, height)
    except ParameterError as exc:
        raise src.error(name.off, str(exc)) from None


def _variable(src: Source, blk: _Block, output: bool) -> _Var:
    head = blk.head
    what = "output" if output else "input"
    if not head.value:
        raise src.error(head.val_off, f"{blk.kind}: expected a name")
    name_tok = _one_token(src, head)
    _check_name(src, name_tok.off, "variable", name_tok.text)
    name = name_tok.text
    f = blk.fields
    if "enabled" in f and not _bool(src, f["enabled"]):
        raise src.error(f["enabled"].val_off,
                        f"unsupported: disabled {what} variable {name!r} (enabled: false)")
    if "range" not in f:
        raise src.error(head.key_off, f"{what} variable {name!r} has no 'range:'")
    rng = f["range"].tokens()
    if len(rng) != 2:
        raise src.error(f["range"].val_off, f"range: expected two numbers, found "
                                            f"{f['range'].value!r}")
    lo = _number(src, rng[0], "range")
    hi = _number(src, rng[1], "range")
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise src.error(rng[0].off, f"range needs finite lo < hi, got {rng[0].text} "
                                    f"{rng[1].text}")
    clip = _bool(src, f["lock-range"]) if "lock-range" in f else False
    terms: list[Term] = []
    seen: dict[str, int] = {}
    if len(blk.items) > MAX_TERMS:
        raise src.error(blk.items[MAX_TERMS].key_off, f"{what} {name!r}: more than "
                                                      f"{MAX_TERMS} terms")
    for ln in blk.items:
        t = _term(src, ln)
        if t.name in seen:
            raise src.error(ln.val_off, f"{what} {name!r} repeats term {t.name!r} (first at "
                                        f"line {seen[t.name]})")
        seen[t.name] = src.where(ln.key_off)[0]
        terms.append(t)
    var = _Var(blk, name, output, terms, list(blk.items), (lo, hi), clip)
    if output:
        if "lock-previous" in f and _bool(src, f["lock-previous"]):
            raise src.error(f["lock-previous"].val_off,
                            f"unsupported: lock-previous: true on output {name!r} (the value "
                            f"would depend on the previous evaluation)")
        if "default" in f:
            tok = _one_token(src, f["default"])
            var.default = _number(src, tok, "default")
            if math.isinf(var.default):
                raise src.error(tok.off, f"default must be finite or nan, got {tok.text}")
        if "defuzzifier" not in f:
            raise src.error(head.key_off, f"output {name!r} has no 'defuzzifier:'")
        var.defuzz_line = f["defuzzifier"]
        var.agg_line = f.get("aggregation")
    return var


def _defuzzifier(src: Source, var: _Var, notes: list[str]) -> str:
    """The model defuzzifier of an output (its kind follows from it)."""
    ln = var.defuzz_line
    assert ln is not None
    toks = ln.tokens()
    if not toks or toks[0].text == "none":
        raise src.error(ln.val_off, f"output {var.name!r} needs a defuzzifier, found "
                                    f"{ln.value or 'nothing'!r}")
    cls = toks[0]
    if len(toks) > 2:
        raise src.error(toks[2].off, f"defuzzifier: unexpected {toks[2].text!r}")
    if cls.text in _INTEGRAL:
        if len(toks) == 2:
            res = _number(src, toks[1], f"{cls.text} resolution")
            if not (math.isfinite(res) and res >= 1):
                raise src.error(toks[1].off, f"{cls.text} resolution must be a number >= 1, "
                                             f"got {toks[1].text}")
            notes.append(f"output {var.name!r}: {cls.text} resolution {toks[1].text} ignored "
                         f"(fuzzyservo integrates exactly)")
        return _INTEGRAL[cls.text]
    if cls.text in _WEIGHTED:
        kind = toks[1].text if len(toks) == 2 else "Automatic"
        if kind not in ("TakagiSugeno", "Automatic", "Tsukamoto"):
            raise src.error(toks[1].off, f"{cls.text}: expected TakagiSugeno, Automatic or "
                                         f"Tsukamoto, found {kind!r}")
        sugeno = all(t.shape in SUGENO for t in var.terms)
        if kind == "Tsukamoto" or (kind == "Automatic" and var.terms and not sugeno):
            at = toks[1].off if len(toks) == 2 else cls.off
            raise src.error(at, f"unsupported defuzzifier: {cls.text} Tsukamoto (supported: "
                                f"TakagiSugeno with Constant and Linear terms)")
        return _WEIGHTED[cls.text]
    supported = ", ".join([*_INTEGRAL, *_WEIGHTED])
    raise src.error(cls.off, f"unsupported defuzzifier: {cls.text} (supported: {supported})")


@dataclass(slots=True)
class _RuleCtx:
    src: Source
    inputs: dict[str, int]
    input_vars: list[Variable]
    outputs: dict[str, int]
    output_vars: list[Variable]
    toks: list[_Tok]
    pos: int = 0
    used_and: _Tok | None = None
    used_or: _Tok | None = None
    #: term name -> index, per input and per output (a scan per clause made large files
    #: quadratic)
    in_terms: list[dict[str, int]] = field(default_factory=list)
    out_terms: list[dict[str, int]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.in_terms = [{t.name: i for i, t in enumerate(v.terms)} for v in self.input_vars]
        self.out_terms = [{t.name: i for i, t in enumerate(v.terms)} for v in self.output_vars]

    def peek(self) -> _Tok | None:
        return self.toks[self.pos] if self.pos < len(self.toks) else None

    def end_off(self) -> int:
        last = self.toks[-1]
        return last.off + len(last.text)

    def expect_what(self, what: str) -> FormatError:
        tok = self.peek()
        if tok is None:
            return self.src.error(self.end_off(), f"rule: expected {what}, found end of rule")
        return self.src.error(tok.off, f"rule: expected {what}, found {tok.text!r}")

    def expect_is(self, var: Variable) -> None:
        """Step over the 'is' after variable ``var``."""
        tok = self.peek()
        if tok is None or tok.text != "is":
            raise self.expect_what(f"'is' after {var.name!r}")
        self.pos += 1

    def read_term(self, index: dict[str, int], role: str, var: Variable) -> int:
        """Read a term of ``var`` (an input or output, ``role``): its index in ``index``."""
        t = self.peek()
        if t is None or t.text not in index:
            raise self.expect_what(f"a term of {role} {var.name!r} "
                                   f"({', '.join(index) or 'none'})")
        self.pos += 1
        return index[t.text]


def _parse_or(ctx: _RuleCtx, depth: int) -> Expr:
    ops = [_parse_and(ctx, depth)]
    while (tok := ctx.peek()) is not None and tok.text == "or":
        ctx.used_or = ctx.used_or or tok
        ctx.pos += 1
        ops.append(_parse_and(ctx, depth))
    return ops[0] if len(ops) == 1 else Or(tuple(ops))


def _parse_and(ctx: _RuleCtx, depth: int) -> Expr:
    ops = [_primary(ctx, depth)]
    while (tok := ctx.peek()) is not None and tok.text == "and":
        ctx.used_and = ctx.used_and or tok
        ctx.pos += 1
        ops.append(_primary(ctx, depth))
    return ops[0] if len(ops) == 1 else And(tuple(ops))


def _primary(ctx: _RuleCtx, depth: int) -> Expr:
    tok = ctx.peek()
    if tok is not None and tok.text == "(":
        if depth >= MAX_DEPTH:
            raise ctx.src.error(tok.off, f"rule: parentheses nested deeper than {MAX_DEPTH}")
        ctx.pos += 1
        inner = _parse_or(ctx, depth + 1)
        close = ctx.peek()
        if close is None or close.text != ")":
            raise ctx.expect_what("'and', 'or' or ')'")
        ctx.pos += 1
        return inner
    return _proposition(ctx, depth)


def _proposition(ctx: _RuleCtx, depth: int) -> Expr:
    src = ctx.src
    tok = ctx.peek()
    if tok is None or tok.text in _KEYWORDS or tok.text in "()":
        raise ctx.expect_what("an input variable")
    if tok.text not in ctx.inputs:
        if tok.text in ctx.outputs:
            raise src.error(tok.off, f"unsupported: output variable {tok.text!r} in a rule's "
                                     f"condition (chained systems)")
        known = ", ".join(ctx.inputs) or "none"
        raise src.error(tok.off, f"rule: expected an input variable declared above this rule "
                                 f"block ({known}), found {tok.text!r}")
    v = ctx.inputs[tok.text]
    var = ctx.input_vars[v]
    ctx.pos += 1
    ctx.expect_is(var)
    nots = 0
    while (h := ctx.peek()) is not None and h.text in _HEDGES:
        if h.text != "not":
            raise src.error(h.off, f"unsupported hedge: {h.text} (supported: not)")
        nots += 1
        if depth + nots > MAX_DEPTH:
            raise src.error(h.off, f"rule: more than {MAX_DEPTH} nested 'not' and parentheses")
        ctx.pos += 1
    expr: Expr = Is(v, ctx.read_term(ctx.in_terms[v], "input", var), negated=nots > 0)
    for _ in range(nots - 1):
        expr = Not(expr)
    return expr


def _consequents(ctx: _RuleCtx) -> tuple[Consequent, ...]:
    src = ctx.src
    out: list[Consequent] = []
    while True:
        tok = ctx.peek()
        if tok is None or tok.text not in ctx.outputs:
            if tok is not None and tok.text in ctx.inputs:
                raise src.error(tok.off, f"rule: {tok.text!r} is an input; a consequent needs "
                                         f"an output variable")
            known = ", ".join(ctx.outputs) or "none"
            raise ctx.expect_what(f"an output variable declared above this rule block "
                                  f"({known})")
        o = ctx.outputs[tok.text]
        var = ctx.output_vars[o]
        ctx.pos += 1
        ctx.expect_is(var)
        t = ctx.peek()
        if t is not None and t.text in _HEDGES:
            raise src.error(t.off, f"unsupported: hedge {t.text!r} in a consequent")
        out.append(Consequent(o, ctx.read_term(ctx.out_terms[o], "output", var)))
        nxt = ctx.peek()
        if nxt is None or nxt.text != "and":
            return tuple(out)
        ctx.pos += 1


@dataclass(slots=True)
class _Ops:
    """Operators of the rule blocks, with the line that set each first."""

    values: dict[str, tuple[str, _Line]] = field(default_factory=dict)

    def agree(self, src: Source, what: str, value: str | None, ln: _Line | None) -> None:
        if value is None or ln is None:
            return
        if what in self.values and self.values[what][0] != value:
            first, fln = self.values[what]
            line = src.where(fln.key_off)[0]
            raise src.error(ln.val_off, f"unsupported: {what} {ln.value} differs from the "
                                        f"{fln.value} at line {line} (one {what} per "
                                        f"system)")
        self.values.setdefault(what, (value, ln))


def _rule(ctx: _RuleCtx, ln: _Line) -> Rule:
    src = ctx.src
    ctx.toks = ln.tokens(_RULE_TOKEN)
    ctx.pos = 0
    if not ctx.toks:
        raise src.error(ln.val_off, "rule: expected 'if ... then ...', found nothing")
    if ctx.toks[0].text != "if":
        raise ctx.expect_what("'if'")
    ctx.pos = 1
    ante = _parse_or(ctx, 0)
    tok = ctx.peek()
    if tok is None or tok.text != "then":
        raise ctx.expect_what("'and', 'or' or 'then'" if tok is None or tok.text != ")"
                              else "'then' (unbalanced ')')")
    ctx.pos += 1
    cons = _consequents(ctx)
    weight = 1.0
    tok = ctx.peek()
    if tok is not None:
        if tok.text != "with":
            raise ctx.expect_what("'and', 'with' or the end of the rule")
        ctx.pos += 1
        w = ctx.peek()
        if w is None:
            raise ctx.expect_what("a weight after 'with'")
        weight = _number(src, w, "rule weight")
        if not 0.0 <= weight <= 1.0:
            raise src.error(w.off, f"rule weight must be in [0, 1], got {w.text}")
        ctx.pos += 1
        if ctx.peek() is not None:
            raise ctx.expect_what("the end of the rule")
    return Rule(ante, cons, weight)


def parse(text: str, source: str = "<string>") -> FuzzySystem:
    """Read a fuzzylite FLL file.

    Parameters
    ----------
    text : str
        The file's text.
    source : str
        The file's name, used in error messages.

    Returns
    -------
    FuzzySystem
        The system; ``notes`` lists what was dropped or ignored (disabled rule blocks,
        defuzzifier resolutions).

    Raises
    ------
    FormatError
        ``source:line:col: ...`` for a malformed file or an unsupported feature (named).
    """
    src = Source(text, source)
    blocks = _blocks(src, _lines(src))
    notes: list[str] = []
    name = "fuzzy"
    engine_off = 0
    inputs: list[_Var] = []
    outputs: list[_Var] = []
    declared: dict[str, int] = {}
    rule_blocks: list[tuple[_Block, dict[str, int], dict[str, int]]] = []
    for blk in blocks:
        if blk.kind == "Engine":
            engine_off = blk.head.key_off
            if blk.head.value:
                tok = _one_token(src, blk.head)
                _check_name(src, tok.off, "engine", tok.text)
                name = tok.text
        elif blk.kind in ("InputVariable", "OutputVariable"):
            var = _variable(src, blk, blk.kind == "OutputVariable")
            if var.name in declared:
                raise src.error(blk.head.val_off, f"variable {var.name!r} already declared at "
                                                  f"line {declared[var.name]}")
            declared[var.name] = src.where(blk.head.key_off)[0]
            if len(declared) > MAX_VARIABLES:
                raise src.error(blk.head.key_off, f"more than {MAX_VARIABLES} variables")
            (outputs if var.output else inputs).append(var)
        else:
            # Rules see the variables declared so far, as fuzzylite's reader does.
            rule_blocks.append((blk, {v.name: i for i, v in enumerate(inputs)},
                                {v.name: i for i, v in enumerate(outputs)}))
    end = len(src.text.rstrip())
    if not inputs:
        raise src.error(end, "expected at least one InputVariable block, found none")
    if not outputs:
        raise src.error(end, "expected at least one OutputVariable block, found none")

    # One defuzzifier and aggregation per system.
    kind = ""
    defuzz = ""
    aggregation = "max"
    first_out: _Var | None = None
    for var in outputs:
        d = _defuzzifier(src, var, notes)
        k = "sugeno" if d in _WEIGHTED.values() else "mamdani"
        agg_ln = var.agg_line
        agg = _named(src, agg_ln, _AGGREGATIONS, "aggregation") if agg_ln else None
        if k == "mamdani" and agg is None:
            at = agg_ln.val_off if agg_ln else var.block.head.key_off
            raise src.error(at, f"Mamdani output {var.name!r} needs an aggregation "
                                f"({', '.join(_AGGREGATIONS)})")
        if k == "sugeno" and agg is not None and agg != "sum" and agg_ln is not None:
            notes.append(f"output {var.name!r}: aggregation {agg_ln.value} of a weighted "
                         f"defuzzifier is ignored, as by fuzzylite 6 (pyfuzzylite 8 groups "
                         f"the rules of each term by it)")
        agg = agg or "max"
        if first_out is None:
            first_out, kind, defuzz, aggregation = var, k, d, agg
        elif (d, agg) != (defuzz, aggregation):
            dl = var.defuzz_line
            assert dl is not None and first_out.defuzz_line is not None
            if d != defuzz:
                raise src.error(dl.val_off, f"unsupported: output {var.name!r} has "
                                            f"defuzzifier {dl.value}, output "
                                            f"{first_out.name!r} has "
                                            f"{first_out.defuzz_line.value} (one defuzzifier "
                                            f"per system)")
            at = var.agg_line.val_off if var.agg_line else var.block.head.key_off
            raise src.error(at, f"unsupported: output {var.name!r} has aggregation "
                                f"{_AGG_CLASS[agg]}, output {first_out.name!r} has "
                                f"{_AGG_CLASS[aggregation]} (one aggregation per system)")

    n_in = len(inputs)
    for var in outputs:
        for t, ln in zip(var.terms, var.term_lines, strict=True):
            sugeno_term = t.shape in SUGENO
            if kind == "sugeno" and not sugeno_term:
                raise src.error(ln.val_off, f"Sugeno output {var.name!r} term {t.name!r}: "
                                            f"needs Constant or Linear, got {t.shape}")
            if kind == "mamdani" and sugeno_term:
                raise src.error(ln.val_off, f"Mamdani output {var.name!r} term {t.name!r}: "
                                            f"{t.shape} needs WeightedAverage or WeightedSum")
            if t.shape == "linear" and len(t.params) != n_in + 1:
                raise src.error(ln.val_off, f"output {var.name!r} term {t.name!r}: Linear "
                                            f"needs {n_in + 1} coefficients (one per input, "
                                            f"then the constant), got {len(t.params)}")

    def model(v: _Var) -> Variable:
        try:
            return Variable(v.name, v.range, tuple(v.terms), default=v.default, clip=v.clip)
        except ParameterError as exc:
            raise src.error(v.block.head.key_off, str(exc)) from None

    in_vars = [model(v) for v in inputs]
    out_vars = [model(v) for v in outputs]

    ops = _Ops()
    rules: list[Rule] = []
    for blk, in_names, out_names in rule_blocks:
        f = blk.fields
        label = blk.head.value or f"at line {src.where(blk.head.key_off)[0]}"
        if "enabled" in f and not _bool(src, f["enabled"]):
            notes.append(f"rule block {label!r} is disabled (enabled: false) and was dropped, "
                         f"as fuzzylite ignores it")
            continue
        conj = _named(src, f["conjunction"], _CONJUNCTIONS, "conjunction") \
            if "conjunction" in f else None
        disj = _named(src, f["disjunction"], _DISJUNCTIONS, "disjunction") \
            if "disjunction" in f else None
        impl = _named(src, f["implication"], _IMPLICATIONS, "implication") \
            if "implication" in f else None
        if "activation" in f:
            act = f["activation"].tokens()
            if act and act[0].text not in ("General", "none"):
                raise src.error(act[0].off, f"unsupported activation: {act[0].text} "
                                            f"(supported: General, none)")
            _one_token(src, f["activation"])
        if kind == "mamdani" and impl is None and blk.items:
            at = f["implication"].val_off if "implication" in f else blk.head.key_off
            raise src.error(at, "a Mamdani rule block needs an implication (Minimum or "
                                "AlgebraicProduct), found none")
        ops.agree(src, "conjunction", conj, f.get("conjunction"))
        ops.agree(src, "disjunction", disj, f.get("disjunction"))
        ops.agree(src, "implication", impl, f.get("implication"))
        ctx = _RuleCtx(src, in_names, in_vars[:len(in_names)], out_names,
                       out_vars[:len(out_names)], [])
        for ln in blk.items:
            ctx.used_and = ctx.used_or = None
            rule = _rule(ctx, ln)
            if ctx.used_and is not None and conj is None:
                raise src.error(ctx.used_and.off, "rule uses 'and' but the rule block's "
                                                  "conjunction is none")
            if ctx.used_or is not None and disj is None:
                raise src.error(ctx.used_or.off, "rule uses 'or' but the rule block's "
                                                 "disjunction is none")
            rules.append(rule)

    def op(what: str, default: str) -> str:
        return ops.values[what][0] if what in ops.values else default

    try:
        return FuzzySystem(
            name=name, kind=cast(Kind, kind), inputs=tuple(in_vars), outputs=tuple(out_vars),
            rules=tuple(rules), and_op=cast(AndOp, op("conjunction", "min")),
            or_op=cast(OrOp, op("disjunction", "max")),
            implication=cast(ImplicationOp, op("implication", "min")),
            aggregation=cast(AggregationOp, aggregation),
            defuzzifier=cast(DefuzzifierName, defuzz), notes=tuple(notes))
    except ParameterError as exc:
        raise src.error(engine_off, str(exc)) from None


# ----------------------------------------------------------------------------------- writer


def _fmt_name(what: str, name: str) -> str:
    if name in _KEYWORDS:
        raise ParameterError(f"FLL cannot hold the {what} name {name!r}: it is an FLL rule "
                             f"keyword")
    return name


def _term_line(kind: str, var: Variable, t: Term) -> str:
    if t.shape not in _SHAPE_CLASS:
        raise ParameterError(f"FLL cannot hold the {t.shape} term {t.name!r} of {kind} "
                             f"{var.name!r}: fuzzylite has no such class")
    cls = _SHAPE_CLASS[t.shape]
    values = [fmt_float(p) for p in t.params]
    if t.height != 1.0:
        if t.shape in SUGENO:
            raise ParameterError(f"FLL cannot hold term height {fmt_float(t.height)} of {kind} "
                                 f"{var.name!r} term {t.name!r}: {cls} has no height")
        values.append(fmt_float(t.height))
    return f"  term: {_fmt_name('term', t.name)} {cls} {' '.join(values)}"


def _negation(system: FuzzySystem, k: int, e: Not) -> str:
    """NOT in rule k: FLL's 'not' is a hedge of one clause, so NOT (NOT ...) of a clause is
    that clause with a 'not' per NOT, and a NOT of a compound expression is refused."""
    nots = 0
    inner: Expr = e
    while isinstance(inner, Not):
        nots += 1
        inner = inner.operand
    if not isinstance(inner, Is):
        raise ParameterError(f"FLL cannot hold rule {k}'s 'not' of a compound expression "
                             f"(FLL's 'not' is a hedge of one clause): "
                             f"{system.rule_text(system.rules[k - 1])}")
    return clause_text(system, inner, nots)


def dump(system: FuzzySystem) -> str:
    """The FLL text of a system, for fuzzylite 6 and :func:`parse`.

    Parameters
    ----------
    system : FuzzySystem
        The system to write.

    Returns
    -------
    str
        FLL text; ``parse(dump(s)) == s``.

    Raises
    ------
    ParameterError
        Naming what FLL cannot hold (a singleton term, a height on a Constant or Linear term,
        a ``not`` of a compound expression, a keyword used as a name, an input's default).
    """
    sugeno = system.kind == "sugeno"
    out = [f"Engine: {system.name}"]
    for v in system.inputs:
        if not math.isnan(v.default):
            raise ParameterError(f"FLL cannot hold the default {fmt_float(v.default)} of input "
                                 f"{v.name!r} (inputs have no default)")
        out += [f"InputVariable: {_fmt_name('variable', v.name)}", "  enabled: true",
                f"  range: {fmt_float(v.range[0])} {fmt_float(v.range[1])}",
                f"  lock-range: {'true' if v.clip else 'false'}"]
        out += [_term_line("input", v, t) for t in v.terms]
    agg = _AGG_CLASS[system.aggregation]
    defuzz = _DEFUZZ_CLASS[system.defuzzifier]
    if sugeno:
        agg = "none" if system.aggregation == "max" else agg
        defuzz += " TakagiSugeno"
    else:
        defuzz += f" {WRITE_RESOLUTION}"
    for v in system.outputs:
        out += [f"OutputVariable: {_fmt_name('variable', v.name)}", "  enabled: true",
                f"  range: {fmt_float(v.range[0])} {fmt_float(v.range[1])}",
                f"  lock-range: {'true' if v.clip else 'false'}",
                f"  aggregation: {agg}", f"  defuzzifier: {defuzz}",
                f"  default: {fmt_float(v.default)}", "  lock-previous: false"]
        out += [_term_line("output", v, t) for t in v.terms]
    impl = "none" if sugeno and system.implication == "min" else _IMP_CLASS[system.implication]
    out += ["RuleBlock: rules", "  enabled: true",
            f"  conjunction: {_AND_CLASS[system.and_op]}",
            f"  disjunction: {_OR_CLASS[system.or_op]}",
            f"  implication: {impl}", "  activation: General"]
    for k, r in enumerate(system.rules, start=1):
        out.append(f"  rule: {fuzzylite_rule(system, r, partial(_negation, system, k))}")
    return "\n".join(out) + "\n"
