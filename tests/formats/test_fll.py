"""fuzzylite FLL reader and writer (fuzzyservo.formats.fll).

References: the model terms each FLL class maps to are written out by hand from fuzzylite 6's
definitions (fuzzylite's term classes, checked with its CLI where they differ from MATLAB's
naming); fuzzylite 6's CLI is the independent reader and evaluator
(tests/formats/fuzzylite_oracle.py): it reads the hand-written files in tests/formats/data/fll/
and fuzzylite's own published examples, and its values at a centroid resolution of 10^6 are
compared with :func:`fuzzyservo.fuzzy.evaluate` on what :func:`parse` read.
"""

from __future__ import annotations

import math
import random
import re
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.errors import FormatError, ParameterError
from fuzzyservo.formats.fll import (
    MAX_DEPTH,
    MAX_NUMBERS,
    MAX_TERMS,
    MAX_VARIABLES,
    WRITE_RESOLUTION,
    dump,
    parse,
)
from fuzzyservo.fuzzy import evaluate, general
from fuzzyservo.fuzzy.system import (
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
from tests.formats.fuzzylite_oracle import EXAMPLES, fuzzylite_eval, fuzzylite_translate

DATA = Path(__file__).parent / "data" / "fll"
FILES = sorted(p.name for p in DATA.glob("*.fll"))

BASE = """\
Engine: base
InputVariable: x
  enabled: true
  range: 0 10
  lock-range: false
  term: lo Triangle 0 2 5
  term: hi Ramp 4 10
InputVariable: w
  range: -1 1
  term: neg Ramp 0 -1
  term: pos Ramp 0 1
OutputVariable: y
  enabled: true
  range: 0 1
  lock-range: true
  aggregation: Maximum
  defuzzifier: Centroid 200
  default: nan
  lock-previous: false
  term: a Triangle 0 0.25 0.5
  term: b Triangle 0.5 0.75 1
RuleBlock: rules
  enabled: true
  conjunction: Minimum
  disjunction: Maximum
  implication: Minimum
  activation: General
  rule: if x is lo then y is a
  rule: if x is hi then y is b
"""


def with_lines(text: str, **over: str) -> str:
    """``text`` with each ``key:`` line (key with - written as _) set to a new value."""
    for key, value in over.items():
        k = key.replace("_", "-")
        text, n = re.subn(rf"^(\s*{k}:).*$", rf"\g<1> {value}", text, count=1, flags=re.M)
        assert n == 1, key
    return text


def add_rules(text: str, *rules: str) -> str:
    return text + "".join(f"  rule: {r}\n" for r in rules)


def error_of(text: str) -> str:
    with pytest.raises(FormatError) as info:
        parse(text, "f.fll")
    msg = str(info.value)
    assert "\n" not in msg
    return msg


def antecedent(rule_text: str) -> Expr:
    return parse(add_rules(BASE, rule_text)).rules[-1].antecedent


# ----------------------------------------------------------------------------- reading


def test_base_system() -> None:
    s = parse(BASE, "base.fll")
    x = Variable("x", (0.0, 10.0), (Term("lo", "triangle", (0.0, 2.0, 5.0)),
                                     Term("hi", "ramp", (4.0, 10.0))), clip=False)
    # lock-range absent: false (fuzzylite's default).
    w = Variable("w", (-1.0, 1.0), (Term("neg", "ramp", (0.0, -1.0)),
                                    Term("pos", "ramp", (0.0, 1.0))), clip=False)
    y = Variable("y", (0.0, 1.0), (Term("a", "triangle", (0.0, 0.25, 0.5)),
                                   Term("b", "triangle", (0.5, 0.75, 1.0))), clip=True)
    want = FuzzySystem(
        name="base", kind="mamdani", inputs=(x, w), outputs=(y,),
        rules=(Rule(Is(0, 0), (Consequent(0, 0),)), Rule(Is(0, 1), (Consequent(0, 1),))),
        and_op="min", or_op="max", implication="min", aggregation="max",
        defuzzifier="centroid")
    assert s == want
    assert math.isnan(s.outputs[0].default)
    assert any("resolution 200 ignored" in n for n in s.notes)


# FLL text -> the model term (fuzzylite 6's parameter order is the model's for every class).
TERMS = [
    ("Triangle 1 2 3", Term("t", "triangle", (1.0, 2.0, 3.0))),
    ("Triangle 1 2 3 0.5", Term("t", "triangle", (1.0, 2.0, 3.0), 0.5)),
    ("Triangle -inf 2 3", Term("t", "trapezoid", (-math.inf, 2.0, 2.0, 3.0))),
    ("Triangle 1 2 inf 0.25", Term("t", "trapezoid", (1.0, 2.0, 2.0, math.inf), 0.25)),
    ("Trapezoid 1 2 3 4", Term("t", "trapezoid", (1.0, 2.0, 3.0, 4.0))),
    ("Trapezoid -inf 2 3 4 1", Term("t", "trapezoid", (-math.inf, 2.0, 3.0, 4.0))),
    ("Trapezoid 1 2 3 inf", Term("t", "trapezoid", (1.0, 2.0, 3.0, math.inf))),
    ("Rectangle 1 4 0.75", Term("t", "rectangle", (1.0, 4.0), 0.75)),
    ("Ramp 4 1", Term("t", "ramp", (4.0, 1.0))),
    ("Discrete 0 0 1 1 2 0", Term("t", "discrete", (0.0, 0.0, 1.0, 1.0, 2.0, 0.0))),
    ("Discrete 0 0 1 1 1 0.5 2 0 0.5",
     Term("t", "discrete", (0.0, 0.0, 1.0, 1.0, 1.0, 0.5, 2.0, 0.0), 0.5)),
    ("Gaussian 5 1.5", Term("t", "gaussian", (5.0, 1.5))),
    ("GaussianProduct 4 1 6 2 0.9", Term("t", "gaussian2", (4.0, 1.0, 6.0, 2.0), 0.9)),
    ("Bell 8 2 3", Term("t", "bell", (8.0, 2.0, 3.0))),
    ("Sigmoid 7 -2", Term("t", "sigmoid", (7.0, -2.0))),
    ("SigmoidDifference 2 10 5 8", Term("t", "dsigmoid", (2.0, 10.0, 5.0, 8.0))),
    ("SigmoidProduct 2 10 -5 8", Term("t", "psigmoid", (2.0, 10.0, -5.0, 8.0))),
    ("PiShape 1 2 3 4", Term("t", "pi", (1.0, 2.0, 3.0, 4.0))),
    ("SShape 1 4 1e-1", Term("t", "s", (1.0, 4.0), 0.1)),
    ("ZShape 1 4", Term("t", "z", (1.0, 4.0))),
    # Binary start direction: h where x >= start (direction above) or x <= start (below).
    ("Binary 3 inf", Term("t", "trapezoid", (3.0, 3.0, 3.0, math.inf))),
    ("Binary 3 -inf 0.5", Term("t", "trapezoid", (-math.inf, 3.0, 3.0, 3.0), 0.5)),
    ("Binary 3 4", Term("t", "trapezoid", (3.0, 3.0, 3.0, math.inf))),
]


@pytest.mark.parametrize(("fll", "term"), TERMS, ids=[t[0] for t in TERMS])
def test_input_term_classes(fll: str, term: Term) -> None:
    s = parse(BASE.replace("term: lo Triangle 0 2 5", f"term: t {fll}").replace(
        "x is lo", "x is t"))
    assert s.inputs[0].terms[0] == term


def sugeno(defuzz: str = "WeightedAverage TakagiSugeno", terms: str = "", rest: str = "") -> str:
    text = with_lines(BASE, defuzzifier=defuzz, aggregation="none", implication="none")
    text = text.replace("  term: a Triangle 0 0.25 0.5\n  term: b Triangle 0.5 0.75 1\n",
                        terms or "  term: a Constant 0.25\n  term: b Linear 0.5 -2 0.125\n")
    return text + rest


def test_sugeno_constant_and_linear() -> None:
    s = parse(sugeno())
    assert s.kind == "sugeno" and s.defuzzifier == "wtaver"
    # Linear: one coefficient per input (x, w), then the constant.
    assert s.outputs[0].terms == (Term("a", "constant", (0.25,)),
                                  Term("b", "linear", (0.5, -2.0, 0.125)))
    # implication and aggregation none: the model's defaults (unused by a Sugeno system).
    assert (s.implication, s.aggregation) == ("min", "max")


@pytest.mark.parametrize(("fll", "name"), [
    ("WeightedAverage TakagiSugeno", "wtaver"), ("WeightedAverage Automatic", "wtaver"),
    ("WeightedAverage", "wtaver"), ("WeightedSum TakagiSugeno", "wtsum"),
    ("WeightedSum", "wtsum")])
def test_weighted_defuzzifiers(fll: str, name: str) -> None:
    s = parse(sugeno(fll))
    assert (s.kind, s.defuzzifier) == ("sugeno", name)


@pytest.mark.parametrize(("fll", "name"), [
    ("Centroid", "centroid"), ("Centroid 1e6", "centroid"), ("Bisector 100", "bisector"),
    ("MeanOfMaximum 500", "mom"), ("SmallestOfMaximum", "som"),
    ("LargestOfMaximum 7", "lom")])
def test_integral_defuzzifiers(fll: str, name: str) -> None:
    s = parse(with_lines(BASE, defuzzifier=fll))
    assert (s.kind, s.defuzzifier) == ("mamdani", name)


@pytest.mark.parametrize(("key", "fll", "field", "value"), [
    ("aggregation", "Maximum", "aggregation", "max"),
    ("aggregation", "BoundedSum", "aggregation", "bounded_sum"),
    ("aggregation", "UnboundedSum", "aggregation", "sum"),
    ("aggregation", "AlgebraicSum", "aggregation", "probor"),
    ("conjunction", "Minimum", "and_op", "min"),
    ("conjunction", "AlgebraicProduct", "and_op", "product"),
    ("conjunction", "none", "and_op", "min"),
    ("disjunction", "Maximum", "or_op", "max"),
    ("disjunction", "AlgebraicSum", "or_op", "probor"),
    ("disjunction", "none", "or_op", "max"),
    ("implication", "Minimum", "implication", "min"),
    ("implication", "AlgebraicProduct", "implication", "product"),
])
def test_operators(key: str, fll: str, field: str, value: str) -> None:
    s = parse(with_lines(BASE, **{key: fll}))
    assert getattr(s, field) == value


def test_activation_none_is_general() -> None:
    # fuzzylite 6 evaluates a rule block without activation method as General.
    assert parse(with_lines(BASE, activation="none")) == parse(BASE)


def test_default_lock_range_and_activation_absent() -> None:
    text = with_lines(BASE, default="0.125", lock_range="true")  # the first: input x
    text = text.replace("  activation: General\n", "")
    s = parse(text)
    assert s.outputs[0].default == 0.125
    assert s.inputs[0].clip and not s.inputs[1].clip and s.outputs[0].clip
    assert parse(with_lines(BASE, default="-0.5")).outputs[0].default == -0.5


def test_precedence_and_parentheses() -> None:
    lo, hi, neg, pos = Is(0, 0), Is(0, 1), Is(1, 0), Is(1, 1)
    # `and` binds tighter than `or` (fuzzylite: "a or b and c" is "a or (b and c)").
    assert antecedent("if x is lo or x is hi and w is neg then y is a") == \
        Or((lo, And((hi, neg))))
    assert antecedent("if x is lo and x is hi or w is neg and w is pos then y is a") == \
        Or((And((lo, hi)), And((neg, pos))))
    # A chain is one n-ary node; a parenthesised group stays a nested node.
    assert antecedent("if x is lo and x is hi and w is neg then y is a") == \
        And((lo, hi, neg))
    assert antecedent("if x is lo and (x is hi and w is neg) then y is a") == \
        And((lo, And((hi, neg))))
    assert antecedent("if (x is lo and x is hi) and w is neg then y is a") == \
        And((And((lo, hi)), neg))
    assert antecedent("if ((x is lo or (w is pos))) then y is a") == Or((lo, pos))
    assert antecedent("if (x is lo)and(w is pos) then y is a") == And((lo, pos))


def test_hedge_not() -> None:
    assert antecedent("if x is not lo then y is a") == Is(0, 0, negated=True)
    # Each `not` is 1 - value, applied in turn (fuzzylite's hedges).
    # (the model keeps the canonical form: NOT of a negated clause is the clause)
    assert antecedent("if x is not not lo then y is a") == Is(0, 0)
    assert antecedent("if x is not not not hi then y is a") == Is(0, 1, negated=True)


def test_weights_and_several_consequents() -> None:
    text = BASE.replace("OutputVariable: y", """OutputVariable: z
  range: 0 2
  aggregation: Maximum
  defuzzifier: Centroid
  term: c Triangle 0 1 2
OutputVariable: y""")
    s = parse(add_rules(text, "if x is lo then y is b and z is c with 0.25",
                        "if w is pos then z is c and y is a with 1e-1"))
    assert s.rules[-2] == Rule(Is(0, 0), (Consequent(1, 1), Consequent(0, 0)), 0.25)
    assert s.rules[-1] == Rule(Is(1, 1), (Consequent(0, 0), Consequent(1, 0)), 0.1)


def test_comments_blank_lines_crlf_bom_and_descriptions() -> None:
    text = ("\ufeff# leading comment\r\nEngine: base # name\r\ndescription: a: b\r\n\r\n"
            + BASE.split("\n", 1)[1].replace("\n", "  # c\r\n", 3).replace(
                "InputVariable: w", "InputVariable: w\n  description: the w"))
    assert parse(text) == parse(BASE)


def test_engine_line_optional() -> None:
    s = parse(BASE.replace("Engine: base\n", ""))
    assert s.name == "fuzzy"
    assert parse(BASE.replace("Engine: base", "Engine:")).name == "fuzzy"


def test_several_rule_blocks_are_merged() -> None:
    block2 = """RuleBlock: second
  conjunction: none
  disjunction: Maximum
  implication: Minimum
  rule: if w is neg or w is pos then y is b
RuleBlock: third
  enabled: false
  conjunction: EinsteinProduct
  rule: if x is lo and x is hi then y is a with 0.5
"""
    s = parse(BASE + block2)
    assert [r.antecedent for r in s.rules] == [Is(0, 0), Is(0, 1), Or((Is(1, 0), Is(1, 1)))]
    assert any("'third'" in n and "disabled" in n for n in s.notes)


def test_sugeno_aggregation_is_noted() -> None:
    s = parse(sugeno().replace("aggregation: none", "aggregation: Maximum"))
    assert s.aggregation == "max"
    assert any("pyfuzzylite 8" in n for n in s.notes)


def test_rule_block_order_follows_declarations() -> None:
    # fuzzylite resolves rules against the variables declared above them (it drops the others):
    # a rule that names a variable declared below its block is an error here.
    text = BASE.replace("OutputVariable: y", "RuleBlock: mid\n  implication: Minimum\n"
                        "  rule: if w is pos then y is b\nOutputVariable: y")
    line, col = at(text, 14, "y is b")
    msg = error_of(text)
    assert msg.startswith(f"f.fll:{line}:{col}: rule: expected an output variable declared "
                          f"above this rule block (none), found 'y'"), msg


# ------------------------------------------------------------------- malformed: locations


def at(text: str, line: int, snippet: str, delta: int = 0) -> tuple[int, int]:
    """(line, column) of ``snippet`` (plus ``delta`` characters) on the 1-based ``line``."""
    col = text.split("\n")[line - 1].index(snippet) + 1 + delta
    return line, col


MALFORMED = [
    # (what, text, (line, snippet at the expected column[, characters after it]), message)
    ("no colon", BASE.replace("  enabled: true\n  range: 0 10", "  enabled true\n  range: 0 10"),
     (3, "enabled"), "expected 'key: value', found 'enabled true'"),
    ("unknown key", BASE.replace("lock-previous", "lock-prev"), (19, "lock-prev"),
     "unknown key 'lock-prev' in OutputVariable"),
    ("repeated key", BASE.replace("  range: 0 10\n", "  range: 0 10\n  range: 0 9\n"),
     (5, "range"), "'range' repeated in InputVariable (first at line 4)"),
    ("bad number", BASE.replace("Triangle 0 2 5", "Triangle 0 2 5x"), (6, "5x"),
     "expected a number, found '5x'"),
    ("too many params", BASE.replace("Triangle 0 2 5", "Triangle 0 2 5 1 1"), (6, "Triangle"),
     "Triangle takes 3 parameters and an optional height, got 5"),
    ("too few params", BASE.replace("Ramp 4 10", "Ramp 4"), (7, "Ramp"),
     "Ramp takes 2 parameters and an optional height, got 1"),
    ("model refuses the term", BASE.replace("Triangle 0 2 5", "Triangle 5 2 0"), (6, "lo"),
     "triangle needs a <= b <= c"),
    ("height 0", BASE.replace("Triangle 0 2 5", "Triangle 0 2 5 0"), (6, "lo"),
     "height must be in (0, 1]"),
    ("range", BASE.replace("range: 0 10", "range: 10 0"), (4, "10 0"),
     "range needs finite lo < hi"),
    ("range count", BASE.replace("range: 0 10", "range: 0"), (4, "0"),
     "range: expected two numbers"),
    ("boolean", BASE.replace("lock-range: false", "lock-range: no"), (5, "no"),
     "expected true or false, found 'no'"),
    ("missing is", add_rules(BASE, "if x lo then y is a"), (30, "lo then"),
     "expected 'is' after 'x', found 'lo'"),
    ("unknown term", add_rules(BASE, "if x is mid then y is a"), (30, "mid"),
     "expected a term of input 'x' (lo, hi), found 'mid'"),
    ("unknown variable", add_rules(BASE, "if v is lo then y is a"), (30, "v is"),
     "expected an input variable declared above this rule block (x, w), found 'v'"),
    ("unbalanced (", add_rules(BASE, "if (x is lo and w is pos then y is a"), (30, "then"),
     "expected 'and', 'or' or ')', found 'then'"),
    ("unbalanced )", add_rules(BASE, "if x is lo) then y is a"), (30, ")"),
     "expected 'then' (unbalanced ')'), found ')'"),
    ("no then", add_rules(BASE, "if x is lo"), (30, "lo", 2),
     "expected 'and', 'or' or 'then', found end of rule"),
    ("no if", add_rules(BASE, "x is lo then y is a"), (30, "x is"), "expected 'if'"),
    ("and without conjunction",
     add_rules(with_lines(BASE, conjunction="none"), "if x is lo and w is pos then y is a"),
     (30, "and"), "rule uses 'and' but the rule block's conjunction is none"),
    ("or without disjunction",
     add_rules(with_lines(BASE, disjunction="none"), "if x is lo or w is pos then y is a"),
     (30, "or"), "rule uses 'or' but the rule block's disjunction is none"),
    ("weight", add_rules(BASE, "if x is lo then y is a with 1.5"), (30, "1.5"),
     "rule weight must be in [0, 1], got 1.5"),
    ("after weight", add_rules(BASE, "if x is lo then y is a with 0.5 0.25"), (30, "0.25"),
     "expected the end of the rule"),
    ("input as consequent", add_rules(BASE, "if x is lo then w is pos"), (30, "w is pos"),
     "'w' is an input; a consequent needs an output variable"),
    ("duplicate variable", BASE.replace("InputVariable: w", "InputVariable: x"), (8, "x"),
     "variable 'x' already declared at line 2"),
    ("duplicate term", BASE.replace("term: hi Ramp", "term: lo Ramp"), (7, "lo Ramp"),
     "input 'x' repeats term 'lo' (first at line 6)"),
    ("bad name", BASE.replace("InputVariable: w", "InputVariable: 2w"), (8, "2w"),
     "variable name '2w' is not allowed"),
    ("no range", BASE.replace("  range: -1 1\n", ""), (8, "InputVariable"),
     "input variable 'w' has no 'range:'"),
    ("no defuzzifier", BASE.replace("  defuzzifier: Centroid 200\n", ""),
     (12, "OutputVariable"), "output 'y' has no 'defuzzifier:'"),
    ("mamdani without aggregation", with_lines(BASE, aggregation="none"),
     (16, "none"), "Mamdani output 'y' needs an aggregation"),
    ("mamdani without implication", with_lines(BASE, implication="none"),
     (26, "none"), "a Mamdani rule block needs an implication"),
    ("linear coefficients", sugeno(terms="  term: a Linear 1 2\n"), (20, "a Linear"),
     "Linear needs 3 coefficients (one per input, then the constant), got 2"),
    ("Constant with a height", sugeno(terms="  term: a Constant 1 0.5\n"), (20, "Constant"),
     "Constant takes 1 parameter, got 2"),
    ("Mamdani term in Sugeno", sugeno(terms="  term: a Triangle 0 1 2\n"),
     (20, "a Triangle"), "Sugeno output 'y' term 'a': needs Constant or Linear"),
    ("Sugeno term in Mamdani", BASE.replace("term: a Triangle 0 0.25 0.5", "term: a Constant 1"),
     (20, "a Constant"), "Mamdani output 'y' term 'a': constant needs WeightedAverage"),
    ("no inputs", "Engine: e\n", (1, "e"), "expected at least one InputVariable block"),
    ("second Engine", BASE + "Engine: again\n", (30, "Engine"), "a second 'Engine:' line"),
    ("empty rule", BASE + "  rule:\n", (30, ":"), "rule: expected 'if ... then ...'"),
]


@pytest.mark.parametrize(("text", "where", "fragment"), [m[1:] for m in MALFORMED],
                         ids=[m[0] for m in MALFORMED])
def test_malformed_location(text: str, where: tuple[int, str] | tuple[int, str, int],
                            fragment: str) -> None:
    msg = error_of(text)
    line, col = at(text, *where)
    if where[1] == ":":  # the end of an empty value: just after the colon
        col += 1
    if where == (1, "e") and fragment.startswith("expected at least one"):
        col = len("Engine: e") + 1  # the end of the file's text
    assert msg.startswith(f"f.fll:{line}:{col}: "), msg
    assert fragment in msg, msg


UNSUPPORTED = [
    # (feature, text, fragment naming it)
    ("term class", BASE.replace("Ramp 4 10", "Spike 4 10"), "unsupported term class: Spike"),
    ("term class Cosine", BASE.replace("Ramp 4 10", "Cosine 4 10"),
     "unsupported term class: Cosine"),
    ("term class Concave", BASE.replace("Ramp 4 10", "Concave 4 10"),
     "unsupported term class: Concave"),
    ("term class Function", BASE.replace("Ramp 4 10", "Function x*2"),
     "unsupported term class: Function"),
    ("aggregation", with_lines(BASE, aggregation="EinsteinSum"),
     "unsupported aggregation: EinsteinSum (supported: Maximum, BoundedSum"),
    ("conjunction", with_lines(BASE, conjunction="EinsteinProduct"),
     "unsupported conjunction: EinsteinProduct (supported: Minimum, AlgebraicProduct, none)"),
    ("disjunction", with_lines(BASE, disjunction="DrasticSum"),
     "unsupported disjunction: DrasticSum"),
    ("implication", with_lines(BASE, implication="HamacherProduct"),
     "unsupported implication: HamacherProduct"),
    ("activation", with_lines(BASE, activation="Highest 2"),
     "unsupported activation: Highest"),
    ("defuzzifier", with_lines(BASE, defuzzifier="CenterOfGravity"),
     "unsupported defuzzifier: CenterOfGravity"),
    ("Tsukamoto", sugeno("WeightedAverage Tsukamoto"),
     "unsupported defuzzifier: WeightedAverage Tsukamoto"),
    ("Tsukamoto by inference", with_lines(BASE, defuzzifier="WeightedSum Automatic"),
     "unsupported defuzzifier: WeightedSum Tsukamoto"),
    ("lock-previous", with_lines(BASE, lock_previous="true"), "unsupported: lock-previous"),
    ("disabled variable", with_lines(BASE, enabled="false"),
     "unsupported: disabled input variable 'x'"),
    ("hedge very", add_rules(BASE, "if x is very lo then y is a"), "unsupported hedge: very"),
    ("hedge somewhat", add_rules(BASE, "if x is somewhat lo then y is a"),
     "unsupported hedge: somewhat"),
    ("hedge seldom", add_rules(BASE, "if x is not seldom lo then y is a"),
     "unsupported hedge: seldom"),
    ("hedge extremely", add_rules(BASE, "if x is extremely lo then y is a"),
     "unsupported hedge: extremely"),
    ("hedge any", add_rules(BASE, "if x is any then y is a"), "unsupported hedge: any"),
    ("hedge in consequent", add_rules(BASE, "if x is lo then y is not a"),
     "unsupported: hedge 'not' in a consequent"),
    ("chained", BASE.replace("RuleBlock: rules", "OutputVariable: y2\n  range: 0 1\n"
                             "  aggregation: Maximum\n  defuzzifier: Centroid\n"
                             "  term: c Triangle 0 1 2\nRuleBlock: rules")
     + "  rule: if y is a then y2 is c\n",
     "unsupported: output variable 'y' in a rule's condition (chained systems)"),
    ("two defuzzifiers", BASE.replace("RuleBlock: rules", "OutputVariable: y2\n  range: 0 1\n"
                                      "  aggregation: Maximum\n  defuzzifier: Bisector\n"
                                      "  term: c Triangle 0 1 2\nRuleBlock: rules"),
     "unsupported: output 'y2' has defuzzifier Bisector, output 'y' has Centroid 200"),
    ("two aggregations", BASE.replace("RuleBlock: rules", "OutputVariable: y2\n  range: 0 1\n"
                                      "  aggregation: BoundedSum\n  defuzzifier: Centroid\n"
                                      "  term: c Triangle 0 1 2\nRuleBlock: rules"),
     "unsupported: output 'y2' has aggregation BoundedSum, output 'y' has Maximum"),
    ("blocks disagree", BASE + "RuleBlock: more\n  conjunction: AlgebraicProduct\n"
     "  implication: Minimum\n",
     "unsupported: conjunction AlgebraicProduct differs from the Minimum at line 24"),
]


@pytest.mark.parametrize(("text", "fragment"), [u[1:] for u in UNSUPPORTED],
                         ids=[u[0] for u in UNSUPPORTED])
def test_unsupported_features_are_named(text: str, fragment: str) -> None:
    msg = error_of(text)
    assert re.match(r"f\.fll:\d+:\d+: ", msg), msg
    assert fragment in msg, msg


def test_unsupported_location() -> None:
    text = add_rules(BASE, "if x is lo or (w is pos and x is very hi) then y is a")
    line, col = at(text, 30, "very")
    assert error_of(text).startswith(f"f.fll:{line}:{col}: unsupported hedge: very")


def test_nesting_is_bounded() -> None:
    deep = "(" * (MAX_DEPTH + 1) + "x is lo" + ")" * (MAX_DEPTH + 1)
    assert f"parentheses nested deeper than {MAX_DEPTH}" in error_of(
        add_rules(BASE, f"if {deep} then y is a"))
    ok = "(" * MAX_DEPTH + "x is lo" + ")" * MAX_DEPTH
    assert parse(add_rules(BASE, f"if {ok} then y is a")).rules[-1].antecedent == Is(0, 0)
    nots = "not " * 10_000
    assert f"more than {MAX_DEPTH} nested" in error_of(
        add_rules(BASE, f"if x is {nots}lo then y is a"))


def test_sizes_are_bounded() -> None:
    many = " ".join(["0.5"] * (MAX_NUMBERS + 1))
    text = BASE.replace("term: hi Ramp 4 10", f"term: hi Discrete {many}")
    line, col = at(text, 7, "0.5", 4 * MAX_NUMBERS)
    assert error_of(text).startswith(f"f.fll:{line}:{col}: term 'hi': more than {MAX_NUMBERS}")
    terms = "".join(f"  term: t{i} Ramp 0 1\n" for i in range(MAX_TERMS + 1))
    text = BASE.replace("  term: hi Ramp 4 10\n", terms)
    assert error_of(text).startswith(f"f.fll:{6 + MAX_TERMS}:3: input 'x': more than")
    inputs = "".join(f"InputVariable: v{i}\n  range: 0 1\n" for i in range(MAX_VARIABLES))
    assert f"more than {MAX_VARIABLES} variables" in error_of(
        BASE.replace("OutputVariable: y", inputs + "OutputVariable: y"))


def test_mutated_files_raise_only_format_errors() -> None:
    # A small deterministic fuzz (the project's hypothesis fuzzer throws far more): cut, repeat
    # or replace pieces of every hand-written file; parse either succeeds or raises FormatError.
    rng = random.Random(7)
    texts = [(DATA / f).read_text(encoding="utf-8") for f in FILES] + [BASE]
    pieces = [" ", "(", ")", ":", "#", "\n", "not ", "and ", "inf", "nan", "-", "1e999", "0",
              "term: t Discrete 1\n", "rule: if\n", "\x00", "é", "RuleBlock:\n"]
    outcomes = {"ok": 0, "error": 0}
    for _ in range(1500):
        t = rng.choice(texts)
        for _ in range(rng.randint(1, 4)):
            i = rng.randrange(len(t) + 1)
            j = min(len(t), i + rng.randint(0, 12))
            op = rng.random()
            if op < 0.4:
                t = t[:i] + t[j:]
            elif op < 0.7:
                t = t[:i] + rng.choice(pieces) + t[i:]
            else:
                t = t[:i] + t[i:j] * 2 + t[j:]
        try:
            parse(t, "m.fll")
            outcomes["ok"] += 1
        except FormatError as exc:
            assert re.match(r"m\.fll:\d+:\d+: \S", str(exc)) and "\n" not in str(exc), exc
            outcomes["error"] += 1
    assert outcomes["ok"] > 50 and outcomes["error"] > 50, outcomes


# ----------------------------------------------------------------------------- writing


def systems() -> list[tuple[str, FuzzySystem]]:
    """Systems for the round trip: the hand-written files, and constructs the files do not
    show in the form a round trip must keep (nested Not, non-default Sugeno operators)."""
    out = [(f, parse((DATA / f).read_text(encoding="utf-8"), f)) for f in FILES]
    x = Variable("x", (-1.5, 2.0), (
        Term("a", "triangle", (-1.5, -1.5, 0.1)),
        Term("b", "trapezoid", (-math.inf, 0.0, 0.3, 1.0 / 3.0), 0.3),
        Term("c", "discrete", (0.0, 0.0, 0.5, 1.0, 0.5, 0.25, 2.0, 0.125)),
        Term("d", "rectangle", (0.1, 0.7)),
        Term("e", "gaussian", (0.2, 1e-3)),
    ), clip=True)
    z = Variable("z", (0.0, 1.0), (Term("f", "bell", (0.5, -0.25, 2.5)),
                                   Term("g", "pi", (0.0, 0.2, 0.2, 0.9))), clip=False)
    y = Variable("y", (-1e-300, 5e300), (Term("lo", "ramp", (0.0, 1.0)),
                                         Term("hi", "s", (1e-5, 3e300), 1e-9)),
                 default=-0.0, clip=False)
    rules = (
        Rule(Not(Not(Is(0, 1, negated=True))), (Consequent(0, 1),), 0.0),
        Rule(Or((And((Is(0, 0), Or((Is(1, 0), Is(0, 2))))), Is(1, 1, negated=True))),
             (Consequent(0, 0), Consequent(0, 1)), 0.1 + 0.2),
        Rule(And((And((Is(0, 3), Is(0, 4))), Is(1, 0))), (Consequent(0, 0),)),
    )
    out.append(("constructed mamdani", FuzzySystem(
        name="m.1", kind="mamdani", inputs=(x, z), outputs=(y,), rules=rules,
        and_op="product", or_op="probor", implication="product", aggregation="probor",
        defuzzifier="lom")))
    u = Variable("u", (0.0, 1.0), (Term("k", "constant", (1 / 3,)),
                                   Term("l", "linear", (0.1, -7.0, 1e-17))), default=0.5)
    for agg, impl in (("sum", "product"), ("bounded_sum", "min"), ("probor", "min")):
        out.append((f"constructed sugeno {agg} {impl}", FuzzySystem(
            name="s", kind="sugeno", inputs=(x, z), outputs=(u,), rules=rules[1:],
            implication=impl, aggregation=agg, defuzzifier="wtsum")))  # type: ignore[arg-type]
    return out


@pytest.mark.parametrize(("label", "system"), systems(), ids=lambda v: v if isinstance(
    v, str) else "")
def test_round_trip(label: str, system: FuzzySystem) -> None:
    text = dump(system)
    assert parse(text, label) == system
    assert dump(parse(text)) == text


def test_written_text() -> None:
    s = parse(BASE)
    text = dump(s)
    assert f"defuzzifier: Centroid {WRITE_RESOLUTION}\n" in text
    assert "  lock-range: true\n  aggregation: Maximum\n" in text
    su = parse(sugeno())
    t2 = dump(su)
    assert "aggregation: none" in t2 and "implication: none" in t2
    assert "defuzzifier: WeightedAverage TakagiSugeno" in t2
    assert "term: b Linear 0.5 -2 0.125\n" in t2


def test_fuzzylite_reads_what_is_written() -> None:
    # fuzzylite's own reader and writer: its FLL of our text describes the same system.
    for _, system in systems():
        text = dump(system)
        again = fuzzylite_translate(text, "fll", "fll")
        # fuzzylite writes 3 decimals by default: compare the structure, not the values.
        assert again.count("term:") == text.count("term:")
        assert again.count("rule:") == text.count("rule:")
        assert re.findall(r"defuzzifier: (\w+)", again) == re.findall(r"defuzzifier: (\w+)",
                                                                       text)


def test_nonstandard_not_is_written_with_the_same_value() -> None:
    # Not(Is(...)) and Is(..., negated=True) are both 1 - membership: FLL writes both as the
    # hedge `not`, and reads the canonical form back.
    s = parse(BASE)
    rules = (Rule(Not(Is(0, 0)), (Consequent(0, 0),)),
             Rule(Not(Not(Is(0, 1))), (Consequent(0, 1),)))
    s2 = FuzzySystem(name="n", inputs=s.inputs, outputs=s.outputs, rules=rules)
    back = parse(dump(s2))
    assert [r.antecedent for r in back.rules] == [Is(0, 0, negated=True), Is(0, 1)]
    x = np.linspace(-1.0, 11.0, 25)[:, None] * np.ones((1, 2)) * np.array([1.0, 0.1])
    np.testing.assert_array_equal(evaluate(back, x), evaluate(s2, x))


REFUSED = [
    ("singleton", lambda s: FuzzySystem(
        name="q", inputs=s.inputs, outputs=(Variable("y", (0.0, 1.0), (
            Term("a", "singleton", (0.5,)),)),), rules=()),
     "FLL cannot hold the singleton term 'a' of output 'y'"),
    ("constant height", lambda s: FuzzySystem(
        name="q", kind="sugeno", inputs=s.inputs, outputs=(Variable("y", (0.0, 1.0), (
            Term("a", "constant", (0.5,), 0.5),)),), rules=(), defuzzifier="wtaver"),
     "FLL cannot hold term height 0.5 of output 'y' term 'a'"),
    ("not of compound", lambda s: FuzzySystem(
        name="q", inputs=s.inputs, outputs=s.outputs, rules=(
            Rule(Not(And((Is(0, 0), Is(1, 0)))), (Consequent(0, 0),)),)),
     "FLL cannot hold rule 1's 'not' of a compound expression"),
    ("keyword name", lambda s: FuzzySystem(
        name="q", inputs=(Variable("if", (0.0, 1.0), ()),), outputs=s.outputs, rules=()),
     "FLL cannot hold the variable name 'if'"),
    ("keyword term", lambda s: FuzzySystem(
        name="q", inputs=(Variable("v", (0.0, 1.0), (Term("very", "ramp", (0.0, 1.0)),)),),
        outputs=s.outputs, rules=()),
     "FLL cannot hold the term name 'very'"),
    ("input default", lambda s: FuzzySystem(
        name="q", inputs=(Variable("v", (0.0, 1.0), (), default=0.0),), outputs=s.outputs,
        rules=()),
     "FLL cannot hold the default 0 of input 'v'"),
]


@pytest.mark.parametrize(("make", "fragment"), [r[1:] for r in REFUSED],
                         ids=[r[0] for r in REFUSED])
def test_writer_refuses_what_fll_cannot_hold(make: object, fragment: str) -> None:
    system = make(parse(BASE))  # type: ignore[operator]
    with pytest.raises(ParameterError, match=re.escape(fragment)):
        dump(system)


# -------------------------------------------------------------- fuzzylite's published files

# Every example .fll installed with fuzzylite 6 either parses or is refused naming why.
EXAMPLE_REFUSALS = {
    "hybrid/ObstacleAvoidance.fll":
        "output 'tsSteer' has defuzzifier WeightedAverage Automatic, output 'mSteer' has",
    "hybrid/tipper.fll":
        "output 'tsTip' has defuzzifier WeightedAverage TakagiSugeno, output 'mTip' has",
    "mamdani/AllTerms.fll": "unsupported term class: Concave",
    "mamdani/Laundry.fll": "unsupported: output variable 'Detergent' in a rule's condition",
    "mamdani/SimpleDimmerChained.fll": "unsupported term class: Cosine",
    "mamdani/SimpleDimmerInverse.fll": "unsupported term class: Cosine",
    "mamdani/octave/investment_portfolio.fll": "unsupported aggregation: EinsteinSum",
    "original/mamdani/AllTerms.fll": "unsupported term class: Concave",
    "original/mamdani/Laundry.fll":
        "unsupported: output variable 'Detergent' in a rule's condition",
    "original/mamdani/SimpleDimmerInverse.fll": "unsupported term class: Cosine",
    "original/mamdani/octave/investment_portfolio.fll": "unsupported aggregation: EinsteinSum",
    "original/takagi-sugeno/approximation.fll": "unsupported: lock-previous: true",
    "original/takagi-sugeno/octave/sugeno_tip_calculator.fll":
        "unsupported conjunction: EinsteinProduct",
    "original/tsukamoto/tsukamoto.fll": "unsupported term class: Concave",
    "takagi-sugeno/approximation.fll": "unsupported: lock-previous: true",
    "takagi-sugeno/octave/sugeno_tip_calculator.fll": "unsupported conjunction: EinsteinProduct",
    "tsukamoto/tsukamoto.fll": "unsupported term class: Concave",
}


def example_files() -> list[str]:
    return sorted(str(p.relative_to(EXAMPLES)) for p in EXAMPLES.rglob("*.fll"))


def test_examples_are_installed() -> None:
    # A missing oracle fails (never skips): 31 files with fuzzylite 6.0's Debian package.
    assert len(example_files()) == 31, example_files()
    assert set(EXAMPLE_REFUSALS) <= set(example_files())


@pytest.mark.parametrize("rel", example_files() or ["<missing examples>"])
def test_fuzzylite_example(rel: str) -> None:
    text = (EXAMPLES / rel).read_text(encoding="utf-8")
    if rel in EXAMPLE_REFUSALS:
        msg = error_of(text)
        assert EXAMPLE_REFUSALS[rel] in msg, msg
        return
    system = parse(text, rel)
    assert parse(dump(system)) == system
    # fuzzylite evaluates the file as published, at resolution 10^6 (bound: see below).
    check_against_fuzzylite(text, system, n=20, seed=3)


# ---------------------------------------------------------------- fuzzylite as the oracle

RESOLUTION = 1_000_000
#: Allowed |fuzzylite - exact| of a Mamdani output, as a fraction of the output's range R.
#: fuzzylite samples the aggregate at the midpoints of N = 10^6 cells of width dx = R / N.
#: Centroid: the midpoint rule is exact on linear pieces and errs by O(dx^2) at a kink; a jump
#: of height J (a Rectangle, a vertical edge, a Discrete step) inside a cell moves the area by
#: at most J dx and the moment about the centroid by at most J dx R, so about R / N per jump
#: (the files' aggregates have at most 4 jumps). Bisector: fuzzylite stops at a cell, and
#: the maxima methods take a sample point (plus fuzzylite's 1e-6 tolerance on equal values,
#: 1e-6 / slope <= 5e-6 R here): each within a cell or two. 10 R / N bounds all of them.
MAMDANI_TOL = 10.0 / RESOLUTION
#: Sugeno outputs are not sampled: the same sums in another order, so rounding only.
SUGENO_TOL = 1e-12


def rule_strengths(system: FuzzySystem, x: np.ndarray) -> np.ndarray:
    """Firing strength (weight included) of every rule at each point, (n, n_rules): only to
    choose test points away from fuzzylite's thresholds, never as an expected value."""
    xs = x.copy()
    for i, v in enumerate(system.inputs):
        if v.clip:
            xs[:, i] = np.clip(xs[:, i], *v.range)
    mu = [[general.membership(t.shape, t.params, xs[:, i], t.height) for t in v.terms]
          for i, v in enumerate(system.inputs)]

    def value(e: Expr) -> np.ndarray:
        if isinstance(e, Is):
            m = mu[e.variable][e.term]
            return 1.0 - m if e.negated else m
        if isinstance(e, Not):
            return 1.0 - value(e.operand)
        vals = [value(op) for op in e.operands]
        r = vals[0]
        for q in vals[1:]:
            if isinstance(e, And):
                r = np.minimum(r, q) if system.and_op == "min" else r * q
            else:
                r = np.maximum(r, q) if system.or_op == "max" else r + q - r * q
        return r

    if not system.rules:
        return np.zeros((len(x), 0))
    return np.array([r.weight * value(r.antecedent) for r in system.rules]).T


def oracle_points(system: FuzzySystem, n: int, seed: int, maxima: bool) -> np.ndarray:
    """``n`` random inputs (fixed seed) from each range widened by 10 % on both sides (inputs
    without lock-range are evaluated outside their range), avoiding fuzzylite's quirks:
    rules firing at most 1e-5 (fuzzylite ignores activations <= 1e-6) unless negligibly
    (< 1e-12), and points within 1e-5 of a term's parameter (fuzzylite takes
    |x - vertex| < 1e-6 as the vertex: a jump there differs). For the maxima methods the
    strongest rule must beat the next by 0.02 and fire at least 0.3: the maximum is then one
    interval (fuzzylite's MeanOfMaximum is the middle of the first plateau only) and its
    edges fall by more than fuzzylite's 1e-6 tolerance per sample (else its LargestOfMaximum
    creeps down a gentle slope)."""
    rng = np.random.default_rng(seed)
    lo = np.array([v.range[0] for v in system.inputs])
    hi = np.array([v.range[1] for v in system.inputs])
    cand = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), size=(20 * n, len(lo)))
    w = rule_strengths(system, cand)
    ok = ~np.any((w > 1e-12) & (w <= 1e-5), axis=1)
    for i, v in enumerate(system.inputs):
        for t in v.terms:
            for p in t.params:
                ok &= ~(np.abs(cand[:, i] - p) < 1e-5)
    if maxima:
        top = np.sort(w, axis=1)
        ok &= (top[:, -1] - top[:, -2] > 0.02) & (top[:, -1] >= 0.3)
    x = cand[ok][:n]
    assert len(x) == n, f"only {len(x)} usable points"
    return x


def check_against_fuzzylite(text: str, system: FuzzySystem, n: int, seed: int,
                            maxima: bool = False) -> list[float]:
    """Compare fuzzylite at resolution 10^6 with evaluate; the worst error per output
    as a fraction of its range."""
    x = oracle_points(system, n, seed, maxima)
    names, fl = fuzzylite_eval(text, "fll", [v.name for v in system.inputs], x, RESOLUTION)
    assert names == [v.name for v in system.outputs]
    ours = evaluate(system, x)
    tol = SUGENO_TOL if system.kind == "sugeno" else MAMDANI_TOL
    worst = []
    for o, v in enumerate(system.outputs):
        r = v.range[1] - v.range[0]
        same_nan = np.isnan(fl[:, o]) == np.isnan(ours[:, o])
        assert same_nan.all(), (v.name, x[~same_nan], fl[~same_nan, o], ours[~same_nan, o])
        both = ~np.isnan(fl[:, o])
        err = np.abs(fl[both, o] - ours[both, o]) / r
        worst.append(float(err.max()) if err.size else 0.0)
        assert np.all(err <= tol), (v.name, float(err.max()), tol)
    return worst


PRODUCT = {"conjunction": "AlgebraicProduct", "disjunction": "AlgebraicSum",
           "implication": "AlgebraicProduct"}
#: The hand-written files with their operator lines replaced: every aggregation, every
#: defuzzifier, both conjunctions, disjunctions and implications.
VARIANTS: list[tuple[str, dict[str, str], bool]] = [
    *[(f, over, False) for f in ("mamdani_piecewise.fll", "mamdani_smooth.fll") for over in (
        {},
        PRODUCT,
        {"aggregation": "BoundedSum"},
        {"aggregation": "UnboundedSum", "implication": "AlgebraicProduct"},
        {"aggregation": "AlgebraicSum"},
        {"defuzzifier": "Bisector 200"},
        {**PRODUCT, "aggregation": "BoundedSum", "defuzzifier": "Bisector 200"},
    )],
    *[("mamdani_maxima.fll", {"defuzzifier": d, **ops}, True)
      for d in ("MeanOfMaximum", "SmallestOfMaximum", "LargestOfMaximum")
      for ops in ({}, PRODUCT)],
    ("sugeno.fll", {}, False),
    ("sugeno.fll", {"defuzzifier": "WeightedSum TakagiSugeno", "conjunction": "AlgebraicProduct",
                    "disjunction": "AlgebraicSum"}, False),
    ("sugeno.fll", {"defuzzifier": "WeightedAverage"}, False),
]


def variant_id(v: tuple[str, dict[str, str], bool]) -> str:
    return v[0].removesuffix(".fll") + "".join(f"-{k}={x}" for k, x in v[1].items())


def test_variants_cover_everything() -> None:
    seen: dict[str, set[str]] = {k: set() for k in (
        "conjunction", "disjunction", "implication", "aggregation", "defuzzifier")}
    for f, over, _ in VARIANTS:
        text = (DATA / f).read_text(encoding="utf-8")
        for k in seen:
            line = over.get(k) or re.findall(rf"^\s*{k}: (.*)$", text, re.M)[0]
            seen[k].add(line.split()[0])
    assert seen == {
        "conjunction": {"Minimum", "AlgebraicProduct"},
        "disjunction": {"Maximum", "AlgebraicSum"},
        "implication": {"Minimum", "AlgebraicProduct", "none"},
        "aggregation": {"Maximum", "BoundedSum", "UnboundedSum", "AlgebraicSum", "none"},
        "defuzzifier": {"Centroid", "Bisector", "MeanOfMaximum", "SmallestOfMaximum",
                        "LargestOfMaximum", "WeightedAverage", "WeightedSum"},
    }


@pytest.mark.slow
@pytest.mark.parametrize("variant", VARIANTS, ids=[variant_id(v) for v in VARIANTS])
def test_fuzzylite_agrees(variant: tuple[str, dict[str, str], bool]) -> None:
    name, over, maxima = variant
    text = (DATA / name).read_text(encoding="utf-8")
    for k, v in over.items():  # every line of the key (both outputs of a file)
        text, n = re.subn(rf"^(\s*{k}:).*$", rf"\g<1> {v}", text, flags=re.M)
        assert n >= 1, k
    system = parse(text, name)
    check_against_fuzzylite(text, system, n=50, seed=11, maxima=maxima)


#: zero_width.fll is compared with fuzzylite in tests/formats/test_zero_width.py, on points
#: that keep clear of the documented differences (an input clipped onto a point's range end
#: fires the output point alone: no area for us, a sampled spike for fuzzylite).
WRITTEN = [name for name in FILES if name != "zero_width.fll"]


@pytest.mark.slow
@pytest.mark.parametrize("name", WRITTEN)
def test_fuzzylite_agrees_on_written_text(name: str) -> None:
    # The writer's text, evaluated by fuzzylite, is the system parse() read.
    system = parse((DATA / name).read_text(encoding="utf-8"), name)
    check_against_fuzzylite(dump(system), system, n=20, seed=5,
                            maxima=system.defuzzifier in ("mom", "som", "lom"))
