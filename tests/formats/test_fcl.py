"""IEC 61131-7 FCL reader and writer (fuzzyservo.formats.fcl).

References: the systems each test file stands for are written out by hand from IEC 61131-7's,
jFuzzyLogic's and fuzzylite's definitions (jFuzzyLogic's GBELL and SIGM formulas are copied
from its source as independent lambdas); analytic centroids of symmetric clipped triangles;
fuzzylite 6's CLI as the independent reader and evaluator (tests/formats/fuzzylite_oracle.py).
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzyservo._typing import FloatArray
from fuzzyservo.errors import FormatError, ParameterError
from fuzzyservo.formats.fcl import dump, parse
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
from tests.formats.fuzzylite_oracle import EXAMPLES, fuzzylite_binary, fuzzylite_eval

DATA = Path(__file__).parent / "data" / "fcl"
INF = math.inf


def read(name: str) -> FuzzySystem:
    return parse((DATA / name).read_text(encoding="utf-8"), name)


def V(name: str, lo: float, hi: float, *terms: Term, default: float = math.nan,
      clip: bool = True) -> Variable:
    return Variable(name, (lo, hi), terms, default=default, clip=clip)


def T(name: str, shape: str, *params: float, height: float = 1.0) -> Term:
    return Term(name, shape, params, height)


# The file most tests modify (one change each). Line numbers, for the error locations below:
#  1 FUNCTION_BLOCK  8 FUZZIFY x  13 DEFUZZIFY y  17 METHOD   20 RULEBLOCK r  24 RULE 1
#  3 x : REAL;       9 RANGE      14 RANGE        18 DEFAULT  21 AND          25 RULE 2
#  6 y : REAL;      10 TERM lo    15 TERM lo                  22 ACT          26 END_RULEBLOCK
#                   11 TERM hi    16 TERM hi                  23 ACCU         27 END_FUNCTION_BLOCK
BASE = """FUNCTION_BLOCK f
VAR_INPUT
  x : REAL;
END_VAR
VAR_OUTPUT
  y : REAL;
END_VAR
FUZZIFY x
  RANGE := (0 .. 10);
  TERM lo := (0, 1) (10, 0);
  TERM hi := (0, 0) (10, 1);
END_FUZZIFY
DEFUZZIFY y
  RANGE := (0 .. 1);
  TERM lo := TRIAN 0 0 1;
  TERM hi := TRIAN 0 1 1;
  METHOD : COG;
  DEFAULT := 0;
END_DEFUZZIFY
RULEBLOCK r
  AND : MIN;
  ACT : MIN;
  ACCU : MAX;
  RULE 1 : IF x IS lo THEN y IS lo;
  RULE 2 : IF x IS hi THEN y IS hi;
END_RULEBLOCK
END_FUNCTION_BLOCK
"""

BASE_SYSTEM = FuzzySystem(
    name="f",
    inputs=(V("x", 0, 10, T("lo", "ramp", 10, 0), T("hi", "ramp", 0, 10)),),
    outputs=(V("y", 0, 1, T("lo", "triangle", 0, 0, 1), T("hi", "triangle", 0, 1, 1),
               default=0.0, clip=False),),
    rules=(Rule(Is(0, 0), (Consequent(0, 0),)), Rule(Is(0, 1), (Consequent(0, 1),))),
    and_op="min", or_op="max", implication="min", aggregation="max", defuzzifier="centroid")


def base(old: str, new: str) -> str:
    assert BASE.count(old) >= 1, old
    return BASE.replace(old, new, 1)


def with_ops(s: FuzzySystem, **kw: object) -> FuzzySystem:
    return dataclasses.replace(s, **kw)  # type: ignore[arg-type]


# ------------------------------------------------------------------------------ the files


def test_base_file() -> None:
    s = parse(BASE, "f.fcl")
    assert s == BASE_SYSTEM


def test_jfuzzylogic_tipper_with_bom_crlf_block_comments() -> None:
    raw = (DATA / "tipper_jfl.fcl").read_bytes()
    assert raw.startswith(b"\xef\xbb\xbf") and b"\r\n" in raw  # the file keeps its point
    s = parse(raw.decode("utf-8"), "tipper_jfl.fcl")
    service = V("service", 0, 10, T("poor", "trapezoid", 0, 0, 2.5, 5),
                T("good", "triangle", 2.5, 5, 7.5), T("excellent", "trapezoid", 5, 7.5, 10, 10))
    food = V("food", 0, 9, T("rancid", "trapezoid", -INF, 0, 1, 3),  # (0,1)(1,1)(3,0)
             T("delicious", "ramp", 7, 9))                          # (7,0)(9,1)
    tip = V("tip", 0, 30, T("cheap", "triangle", 0, 5, 10), T("average", "triangle", 10, 15, 20),
            T("generous", "triangle", 20, 25, 30), default=0.0, clip=False)
    bonus = V("bonus", 0, 5, T("none", "singleton", 0), T("some", "singleton", 5), clip=False)
    rules = (
        Rule(Or((Is(0, 0), Is(1, 0))), (Consequent(0, 0), Consequent(1, 0))),
        Rule(Is(0, 1), (Consequent(0, 1),)),
        Rule(And((Is(0, 2), Not(Or((Is(1, 0), Is(0, 0)))))),
             (Consequent(0, 2), Consequent(1, 1)), 0.8),
    )
    assert s == FuzzySystem(name="tipper", inputs=(service, food), outputs=(tip, bonus),
                            rules=rules, and_op="min", or_op="max", implication="min",
                            aggregation="max", defuzzifier="centroid")
    assert any("no OR given" in n for n in s.notes)
    # analytic values (exact evaluator): a lone clipped symmetric triangle has its peak as
    # centroid; singletons: the one that fires
    y = evaluate(s, np.array([[5.0, 5.0], [0.0, 0.0], [10.0, 10.0]]))
    assert y[0, 0] == pytest.approx(15.0, abs=1e-12)   # only rule 2: average
    assert math.isnan(y[0, 1])                           # no rule for bonus, no DEFAULT
    assert y[1, 0] == pytest.approx(5.0, abs=1e-12)     # rule 1: cheap
    assert y[1, 1] == 0.0                                # rule 1: none at 0
    assert y[2, 0] == pytest.approx(25.0, abs=1e-12)    # rule 3 (0.8): generous
    assert y[2, 1] == 5.0                                # rule 3: some at 5


def test_iec_point_lists() -> None:
    s = read("iec_points.fcl")
    level = V("level", 0, 10, T("low", "ramp", 4, 0), T("ok", "triangle", 2, 5, 8),
              T("high", "ramp", 6, 10), T("band", "trapezoid", 1, 2, 3, 4))
    rate = V("rate", -1, 1, T("neg", "trapezoid", -INF, -1, -0.5, 0),
             T("pos", "trapezoid", 0, 0.5, 1, INF),
             T("step", "discrete", -1, 0, 0, 0, 0, 1, 1, 1),
             T("bump", "discrete", -1, 0, 0, 0.5, 1, 0))
    opening = V("opening", 0, 100, T("closed", "ramp", 50, 0), T("half", "triangle", 25, 50, 75),
                T("open", "ramp", 50, 100), default=50.0, clip=False)
    alarm = V("alarm", 0, 1, T("off", "singleton", 0), T("on", "singleton", 1), default=0.0,
              clip=False)
    rules = (
        Rule(Is(0, 0), (Consequent(0, 2), Consequent(1, 1))),
        Rule(And((Is(0, 1), Is(1, 1, True))), (Consequent(0, 1),)),
        Rule(And((Or((Is(0, 2), Is(0, 3))), Is(1, 2))), (Consequent(0, 0),), 0.5),
        Rule(And((Is(0, 2), Is(1, 3))), (Consequent(1, 0),)),
    )
    assert s == FuzzySystem(name="valve", inputs=(level, rate), outputs=(opening, alarm),
                            rules=rules, and_op="product", or_op="probor",
                            implication="product", aggregation="max", defuzzifier="centroid")
    # level 3, rate 0.25: rule 1 fires 0.25 (alarm on), rule 4 none: COGS gives on = 1
    assert evaluate(s, np.array([3.0, 0.25]))[1] == 1.0


def test_fuzzylite_dialect() -> None:
    s = read("fuzzylite_dialect.fcl")
    a = V("a", -1, 1, T("neg", "trapezoid", -INF, -1, -0.5, 0, height=0.8),
          T("zero", "gaussian", 0, 0.3), T("pos", "sigmoid", 0.5, 12))
    b = V("b", 0, 4, T("small", "z", 0, 2), T("mid", "bell", 2, 0.8, 2.5),
          T("large", "s", 2, 4, height=0.9))
    u = V("u", 0, 10, T("lo", "triangle", 0, 2, 5, height=0.7), T("mid", "pi", 2, 4, 6, 8),
          T("hi", "discrete", 5, 0, 8, 1, 10, 1, height=0.9), clip=True)
    v = V("v", -5, 5, T("down", "singleton", -4), T("flat", "singleton", 0),
          T("up", "singleton", 4), default=0.0, clip=False)
    rules = (
        Rule(And((Is(0, 0), Is(1, 2, True))), (Consequent(0, 0), Consequent(1, 0))),
        Rule(Or((Is(0, 1), Is(1, 1))), (Consequent(0, 1), Consequent(1, 1)), 0.6),
        Rule(Is(0, 2), (Consequent(0, 2), Consequent(1, 2))),
    )
    assert s == FuzzySystem(name="dialect", inputs=(a, b), outputs=(u, v), rules=rules,
                            and_op="product", or_op="max", implication="min",
                            aggregation="max", defuzzifier="centroid")


# ------------------------------------------------------------------------- term dialects


def jfl_gbell(x: FloatArray, a: float, b: float, mean: float) -> FloatArray:
    """jFuzzyLogic's MembershipFunctionGenBell.membership (GBELL a b mean)."""
    out: FloatArray = 1.0 / (1.0 + np.abs((x - mean) / a) ** (2.0 * b))
    return out


def jfl_sigm(x: FloatArray, gain: float, center: float) -> FloatArray:
    """jFuzzyLogic's MembershipFunctionSigmoidal.membership (SIGM gain center)."""
    out: FloatArray = 1.0 / (1.0 + np.exp(-gain * (x - center)))
    return out


@pytest.mark.parametrize(("text", "expected"), [
    ("(0, 0) (1, 1)", T("t", "ramp", 0, 1)),
    ("(0, 1) (1, 0)", T("t", "ramp", 1, 0)),
    ("(0, 0) (1, 1) (2, 0)", T("t", "triangle", 0, 1, 2)),
    ("(0, 0) (1, 1) (2, 1) (3, 0)", T("t", "trapezoid", 0, 1, 2, 3)),
    ("(1, 1) (2, 1) (3, 0)", T("t", "trapezoid", -INF, 1, 2, 3)),
    ("(0, 0) (1, 1) (2, 1)", T("t", "trapezoid", 0, 1, 2, INF)),
    ("(0,0)(1,1)(2,0)", T("t", "triangle", 0, 1, 2)),
    ("(0, 0) (1, 0.5) (2, 0)", T("t", "discrete", 0, 0, 1, 0.5, 2, 0)),
    ("(0, 0) (0, 1) (2, 0)", T("t", "discrete", 0, 0, 0, 1, 2, 0)),   # vertical edge
    ("(0, 0) (1, 1) (2, 0) (3, 1)", T("t", "discrete", 0, 0, 1, 1, 2, 0, 3, 1)),
    ("TRIAN 0 1 2", T("t", "triangle", 0, 1, 2)),
    ("trian 0 1 2", T("t", "triangle", 0, 1, 2)),
    ("TRAPE 0 1 2 3", T("t", "trapezoid", 0, 1, 2, 3)),
    ("GAUSS 1 0.5", T("t", "gaussian", 1, 0.5)),
    ("GAUSS2 1 0.5 2 0.25", T("t", "gaussian2", 1, 0.5, 2, 0.25)),
    ("GBELL 0.5 2 1", T("t", "bell", 1, 0.5, 2)),         # a b mean -> center width slope
    ("SIGM 4 1", T("t", "sigmoid", 1, 4)),                 # gain center -> inflection slope
    ("Triangle 0 1 2", T("t", "triangle", 0, 1, 2)),
    ("Triangle 0 1 2 0.5", T("t", "triangle", 0, 1, 2, height=0.5)),
    ("Trapezoid -inf 0 1 2", T("t", "trapezoid", -INF, 0, 1, 2)),
    ("Trapezoid 0 1 2 inf 0.25", T("t", "trapezoid", 0, 1, 2, INF, height=0.25)),
    ("Rectangle 0 1", T("t", "rectangle", 0, 1)),
    ("Ramp 2 1", T("t", "ramp", 2, 1)),
    ("Discrete 0 0 1 1 2 0", T("t", "discrete", 0, 0, 1, 1, 2, 0)),   # no canonical shape
    ("Discrete 0 0 1 1 0.75", T("t", "discrete", 0, 0, 1, 1, height=0.75)),
    ("Gaussian 1 0.5", T("t", "gaussian", 1, 0.5)),
    ("GaussianProduct 1 0.5 2 0.25", T("t", "gaussian2", 1, 0.5, 2, 0.25)),
    ("Bell 1 0.5 2", T("t", "bell", 1, 0.5, 2)),
    ("Sigmoid 1 4", T("t", "sigmoid", 1, 4)),
    ("SigmoidDifference 0.5 10 10 1.5", T("t", "dsigmoid", 0.5, 10, 10, 1.5)),
    ("SigmoidProduct 0.5 10 -10 1.5", T("t", "psigmoid", 0.5, 10, -10, 1.5)),
    ("PiShape 0 1 2 3", T("t", "pi", 0, 1, 2, 3)),
    ("SShape 0 2", T("t", "s", 0, 2)),
    ("ZShape 0 2 0.5", T("t", "z", 0, 2, height=0.5)),
    ("1.5e0", T("t", "singleton", 1.5)),
    ("-.5", T("t", "singleton", -0.5)),
])
def test_term_dialects(text: str, expected: Term) -> None:
    role = "output" if expected.shape == "singleton" else "input"
    src = BASE.replace("  TERM hi := (0, 0) (10, 1);", f"  TERM t := {text};")
    if role == "output":
        src = BASE.replace("  TERM hi := TRIAN 0 1 1;", f"  TERM t := {text};")
        src = src.replace("TRIAN 0 0 1;", "0;").replace("METHOD : COG;", "METHOD : COGS;")
        src = src.replace("THEN y IS hi", "THEN y IS t")
        s = parse(src, "t.fcl")
        assert s.outputs[0].terms[1] == expected
    else:
        src = src.replace("IF x IS hi", "IF x IS t")
        s = parse(src, "t.fcl")
        assert s.inputs[0].terms[1] == expected


def test_jfuzzylogic_gbell_and_sigm_follow_its_formulas() -> None:
    x = np.linspace(-3.0, 5.0, 161)
    src = base("  TERM hi := (0, 0) (10, 1);",
               "  TERM g := GBELL 0.5 2 1;\n  TERM s := SIGM 4 1;")
    s = parse(src.replace("IF x IS hi", "IF x IS g"), "t.fcl")
    g, sg = s.inputs[0].terms[1], s.inputs[0].terms[2]
    # jFuzzyLogic: 1 / (1 + |(x - mean) / a|^(2 b)), 1 / (1 + exp(-gain (x - center)))
    np.testing.assert_allclose(general.membership(g.shape, g.params, x), jfl_gbell(x, 0.5, 2, 1),
                               rtol=1e-14, atol=1e-15)  # same formula: rounding only
    np.testing.assert_allclose(general.membership(sg.shape, sg.params, x), jfl_sigm(x, 4, 1),
                               rtol=1e-14, atol=1e-15)  # same formula: rounding only


def test_keywords_case_insensitive_names_case_sensitive() -> None:
    lower = "\n".join(ln if ln.strip().startswith(("TERM", "RULE")) else ln.lower()
                      for ln in BASE.splitlines())
    s = parse(lower.replace("TERM", "term").replace(" IS ", " is ").replace("IF ", "if ")
              .replace("THEN", "then").replace("TRIAN", "Trian"), "lower.fcl")
    assert s == BASE_SYSTEM
    with pytest.raises(FormatError, match="has no term 'LO'"):
        parse(base("IF x IS lo", "IF x IS LO"), "f.fcl")


@pytest.mark.parametrize("comment", [
    "(* an IEC comment\n over two lines *)", "/* a C comment */", "// to the line end\n",
    "# fuzzylite's comment\n"])
def test_comments(comment: str) -> None:
    assert parse(base("  TERM hi", f"  {comment} TERM hi"), "c.fcl") == BASE_SYSTEM


def test_bom_and_crlf() -> None:
    assert parse("\ufeff" + BASE.replace("\n", "\r\n"), "crlf.fcl") == BASE_SYSTEM
    with pytest.raises(FormatError, match=r"^crlf\.fcl:10:11: "):
        parse(base("TERM lo := (0", "TERM lo = (0").replace("\n", "\r\n"), "crlf.fcl")


def test_range_in_var_block_jfuzzylogic() -> None:
    src = base("  x : REAL;", "  x : REAL; RANGE := (0 .. 10);").replace(
        "  RANGE := (0 .. 10);\n  TERM lo", "  TERM lo")
    assert parse(src, "f.fcl") == BASE_SYSTEM
    clash = base("  x : REAL;", "  x : REAL; RANGE := (0 .. 5);")
    with pytest.raises(FormatError, match=r":9:3: RANGE of 'x' differs"):
        parse(clash, "f.fcl")


# -------------------------------------------------------------------- methods, operators


@pytest.mark.parametrize(("word", "defuzzifier"), [
    ("COG", "centroid"), ("COA", "bisector"), ("LM", "som"), ("RM", "lom"), ("MM", "mom"),
    ("MOM", "mom"), ("cog", "centroid"), ("Centroid", "centroid"),
    ("SmallestOfMaximum", "som")])
def test_methods(word: str, defuzzifier: str) -> None:
    s = parse(base("METHOD : COG;", f"METHOD : {word};"), "f.fcl")
    assert s.defuzzifier == defuzzifier


def test_cogs_over_singletons_is_centroid() -> None:
    src = base("TRIAN 0 0 1;", "0;").replace("TRIAN 0 1 1;", "1;").replace("COG;", "COGS;")
    s = parse(src, "f.fcl")
    assert s.kind == "mamdani" and s.defuzzifier == "centroid"
    assert s.outputs[0].terms == (T("lo", "singleton", 0), T("hi", "singleton", 1))


def test_sugeno_in_fuzzylite_dialect() -> None:
    src = base("TRIAN 0 0 1;", "Constant 0.25;").replace("TRIAN 0 1 1;", "Linear 0.5 -1;")
    s = parse(src.replace("COG;", "COGS;"), "f.fcl")
    assert s.kind == "sugeno" and s.defuzzifier == "wtaver"
    assert s.outputs[0].terms == (T("lo", "constant", 0.25), T("hi", "linear", 0.5, -1))
    s = parse(base("TRIAN 0 0 1;", "0;").replace("TRIAN 0 1 1;", "1;")
              .replace("COG;", "COGSS;"), "f.fcl")
    assert s.kind == "sugeno" and s.defuzzifier == "wtsum"
    assert s.outputs[0].terms == (T("lo", "constant", 0), T("hi", "constant", 1))


@pytest.mark.parametrize(("where", "line", "field", "value"), [
    ("AND : MIN;", "AND : PROD;", "and_op", "product"),
    ("AND : MIN;", "AND : MIN;\n  OR : ASUM;", "or_op", "probor"),
    ("ACT : MIN;", "ACT : PROD;", "implication", "product"),
    ("ACCU : MAX;", "ACCU : BSUM;", "aggregation", "bounded_sum"),
    ("ACCU : MAX;", "ACCU : SUM;", "aggregation", "sum"),
    ("ACCU : MAX;", "ACCU : PROBOR;", "aggregation", "probor"),
    ("ACCU : MAX;", "ACCU : UnboundedSum;", "aggregation", "sum"),
    ("AND : MIN;", "AND : AlgebraicProduct;", "and_op", "product"),
])
def test_operators(where: str, line: str, field: str, value: str) -> None:
    assert getattr(parse(base(where, line), "f.fcl"), field) == value


def test_accu_in_defuzzify_as_fuzzylite_writes_it() -> None:
    src = base("  ACCU : MAX;\n", "").replace("  METHOD : COG;", "  METHOD : COG;\n  ACCU : BSUM;")
    assert parse(src, "f.fcl").aggregation == "bounded_sum"


def test_missing_operators_use_de_morgan_pairs_and_iec_defaults() -> None:
    bare = base("  AND : MIN;\n  ACT : MIN;\n  ACCU : MAX;\n", "")
    s = parse(bare, "f.fcl")
    assert (s.and_op, s.or_op, s.implication, s.aggregation) == ("min", "max", "min", "max")
    assert parse(bare.replace("RULEBLOCK r\n", "RULEBLOCK r\n  AND : PROD;\n"),
                 "f.fcl").or_op == "probor"
    assert parse(bare.replace("RULEBLOCK r\n", "RULEBLOCK r\n  OR : ASUM;\n"),
                 "f.fcl").and_op == "product"
    assert parse(bare.replace("RULEBLOCK r\n", "RULEBLOCK r\n  OR : MAX;\n"),
                 "f.fcl").and_op == "min"
    # no ACCU over singleton outputs: SUM, fuzzylite's weighted average of the rules
    single = bare.replace("TRIAN 0 0 1;", "0;").replace("TRIAN 0 1 1;", "1;")
    assert parse(single.replace("COG;", "COGS;"), "f.fcl").aggregation == "sum"


def test_several_ruleblocks_merge_when_they_agree() -> None:
    two = base("  RULE 2 : IF x IS hi THEN y IS hi;\nEND_RULEBLOCK",
               "END_RULEBLOCK\nRULEBLOCK second\n  AND : MIN;\n"
               "  RULE 2 : IF x IS hi THEN y IS hi;\nEND_RULEBLOCK")
    assert parse(two, "f.fcl") == BASE_SYSTEM
    with pytest.raises(FormatError, match=r"^f\.fcl:27:9: unsupported: AND PROD differs"):
        parse(two.replace("  AND : MIN;\n  RULE 2", "  AND : PROD;\n  RULE 2"), "f.fcl")


def test_default_missing_is_nan_and_nan_accepted() -> None:
    s = parse(base("  DEFAULT := 0;\n", ""), "f.fcl")
    assert math.isnan(s.outputs[0].default)
    assert any("no DEFAULT" in n for n in s.notes)
    assert math.isnan(parse(base("DEFAULT := 0;", "DEFAULT := nan;"), "f").outputs[0].default)
    assert parse(base("DEFAULT := 0;", "DEFAULT := -2.5e-1;"), "f").outputs[0].default == -0.25


def test_lock_range_clamps_the_output() -> None:
    assert parse(base("  DEFAULT := 0;", "  DEFAULT := 0;\n  LOCK : RANGE;"),
                 "f").outputs[0].clip


def test_missing_ranges_span_the_terms() -> None:
    src = base("  RANGE := (0 .. 10);\n", "").replace("  RANGE := (0 .. 1);\n", "")
    s = parse(src, "f.fcl")
    assert s == BASE_SYSTEM  # points 0 .. 10, triangles 0 .. 1
    assert sum("has no RANGE" in n for n in s.notes) == 2
    shoulder = src.replace("TRIAN 0 1 1", "TRAPE 0.5 1 2 2")  # 1 at its right end: cut at 2
    assert parse(shoulder, "f.fcl").outputs[0].range == (0.0, 2.0)


def test_missing_range_with_unbounded_terms_is_refused() -> None:
    src = base("  RANGE := (0 .. 10);\n", "").replace("(0, 0) (10, 1)", "GAUSS 5 1")
    with pytest.raises(FormatError, match=r"^f\.fcl:8:9: input 'x' has no RANGE and term "
                                          r"'hi' \(gaussian\) has no bounded support"):
        parse(src, "f.fcl")


# ------------------------------------------------------------------------------ rules


def rules_of(*lines: str) -> FuzzySystem:
    src = base("  RULE 1 : IF x IS lo THEN y IS lo;\n  RULE 2 : IF x IS hi THEN y IS hi;",
               "\n".join(lines))
    return parse(src, "r.fcl")


def test_rule_expressions() -> None:
    s = rules_of(
        "RULE 1 : IF x IS lo AND x IS hi AND x IS NOT lo THEN y IS lo;",
        "RULE 2 : IF (x IS lo AND x IS hi) AND x IS lo THEN y IS lo WITH 0.25;",
        "RULE 3 : IF NOT x IS lo OR NOT (x IS hi AND x IS lo) THEN y IS hi;",
        "RULE 4 : IF ((x IS lo)) THEN y IS hi, y IS lo;",
        "RULE 5 : IF x IS lo THEN (y IS hi) AND (y IS lo);",
        "RULE six : IF x IS lo\n  OR x IS hi\n  THEN y\n IS hi\n WITH\n 1;")
    lo, hi = Is(0, 0), Is(0, 1)
    assert [r.antecedent for r in s.rules] == [
        And((lo, hi, Is(0, 0, True))), And((And((lo, hi)), lo)),
        Or((Is(0, 0, True), Not(And((hi, lo))))), lo, lo, Or((lo, hi))]  # NOT clause: canonical
    assert [r.weight for r in s.rules] == [1.0, 0.25, 1.0, 1.0, 1.0, 1.0]
    assert s.rules[3].consequents == (Consequent(0, 1), Consequent(0, 0))
    assert s.rules[4].consequents == (Consequent(0, 1), Consequent(0, 0))


def test_rules_without_semicolons_as_fuzzylite_writes_them() -> None:
    s = rules_of("RULE 1 : if x is lo then y is lo", "RULE 2 : if x is hi then y is hi with 1.0")
    assert s == BASE_SYSTEM
    rb = BASE.replace("RULEBLOCK r\n  AND : MIN;\n", "RULEBLOCK r\n").replace(
        "y IS hi;\nEND_RULEBLOCK", "y IS hi\n  AND : MIN;\nEND_RULEBLOCK")
    assert parse(rb, "f.fcl") == BASE_SYSTEM


def test_deep_nesting_is_bounded() -> None:
    ok = "(" * 150 + "x IS lo" + ")" * 150
    assert rules_of(f"RULE 1 : IF {ok} THEN y IS lo;").rules[0].antecedent == Is(0, 0)
    deep = "(" * 5000 + "x IS lo" + ")" * 5000
    with pytest.raises(FormatError, match="nested deeper than 200"):
        rules_of(f"RULE 1 : IF {deep} THEN y IS lo;")
    nots = "NOT " * 5000 + "x IS lo"
    with pytest.raises(FormatError, match="nested deeper than 200"):
        rules_of(f"RULE 1 : IF {nots} THEN y IS lo;")


# ------------------------------------------------------------------- malformed files


@pytest.mark.parametrize(("old", "new", "where", "message"), [
    ("TERM lo := (0", "TERM lo = (0", "10:11", "expected ':=', found '='"),
    ("RANGE := (0 .. 10);", "RANGE := (0 .. 10)", "10:3", "expected ';', found 'TERM'"),
    ("END_FUZZIFY\n", "", "12:1", "expected TERM, RANGE or END_FUZZIFY, found 'DEFUZZIFY'"),
    ("THEN y IS hi;", "THEN y IS high;", "25:33", "output 'y' has no term 'high'"),
    ("END_FUNCTION_BLOCK\n", "END_FUNCTION_BLOCK\n(* open", "28:1",
     "comment (* is never closed"),
    ("(0 .. 10)", "(0 .. 1x0)", "9:18", "malformed number '1x'"),
    ("y IS lo;", "y IS lo WITH 1.5;", "24:41", "rule weight must be in [0, 1], got 1.5"),
    ("IF x IS lo THEN", "IF x IS lo y", "24:23", "expected THEN, found 'y'"),
    ("END_FUNCTION_BLOCK\n", "", "27:1", "found end of file"),
    ("END_FUNCTION_BLOCK\n", "END_FUNCTION_BLOCK\njunk\n", "28:1",
     "expected end of file after END_FUNCTION_BLOCK, found 'junk'"),
    ("AND : MIN;", "AND : MIN$;", "21:12", "expected ';', found '$'"),
    ("(0 .. 10)", "(10 .. 0)", "9:3", "range needs finite lo < hi"),
    ("TRIAN 0 0 1", "TRIAN 1 0 0", "15:8", "triangle needs a <= b <= c"),
    ("  y : REAL;", "  y : REAL;\n  x : REAL;", "7:3", "variable 'x' is declared twice"),
    ("TRIAN 0 1 1", "TRIAN 0 1", "16:14", "TRIAN takes 3 parameters, got 2"),
    ("TERM hi := (0, 0) (10, 1)", "TERM hi := (0, 0) (10 1)", "11:25", "expected ','"),
    ("FUZZIFY x", "FUZZIFY z", "8:9", "FUZZIFY of 'z', which is not declared"),
    ("IF x IS hi", "IF q IS hi", "25:15", "unknown input variable 'q'"),
    ("TERM hi := (0, 0)", "TERM lo := (0, 0)", "11:8", "'x' has a second term 'lo'"),
    ("FUNCTION_BLOCK f", "FUNCTION f", "1:1", "expected FUNCTION_BLOCK, found 'FUNCTION'"),
    ("TERM hi := (0, 0)", "TERM IS := (0, 0)", "11:8", "found the keyword 'IS'"),
    ("THEN y IS hi;", "THEN x IS hi;", "25:28", "a conclusion must name an output"),
])
def test_malformed_files_give_one_located_error(old: str, new: str, where: str,
                                                message: str) -> None:
    with pytest.raises(FormatError) as info:
        parse(base(old, new), "bad.fcl")
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(f"bad.fcl:{where}: "), text
    assert message in text, text


@pytest.mark.parametrize(("old", "new", "where", "message"), [
    ("METHOD : COG;", "METHOD : COGF;", "17:12", "unsupported METHOD: COGF"),
    ("METHOD : COG;", "METHOD : NONE;", "17:12", "unsupported METHOD: NONE"),
    ("METHOD : COG;", "METHOD : COGS;", "17:12", "METHOD COGS needs singleton terms"),
    ("DEFAULT := 0;", "DEFAULT := NC;", "18:14", "unsupported: DEFAULT := NC"),
    ("DEFAULT := 0;", "DEFAULT := 0 | NC;", "18:16", "unsupported: DEFAULT ... | NC"),
    ("DEFAULT := 0;", "LOCK : PREVIOUS;", "18:10", "unsupported: LOCK : PREVIOUS"),
    ("AND : MIN;", "AND : BDIF;", "21:9", "unsupported AND method: BDIF (supported: MIN, PROD)"),
    ("ACT : MIN;", "OR : BSUM;", "22:8", "unsupported OR method: BSUM (bounded sum as OR)"),
    ("ACCU : MAX;", "ACCU : NSUM;", "23:10", "unsupported ACCU method: NSUM (normalised sum)"),
    ("ACT : MIN;", "ENABLED : FALSE;", "22:13", "unsupported: ENABLED : FALSE"),
    ("IF x IS hi", "IF x IS very hi", "25:20", "unsupported hedge: very"),
    ("IF x IS hi", "IF x IS any", "25:20", "unsupported hedge: any"),
    ("IF x IS hi", "IF y IS hi", "25:15", "unsupported: rule antecedent uses output variable "
                                          "'y' (chained rule bases)"),
    ("TRIAN 0 1 1", "COSINE 0.5 1", "16:14", "unsupported term shape: COSINE"),
    ("TRIAN 0 1 1", "DSIGM 10 0.2 10 0.8", "16:14", "unsupported term shape: DSIGM"),
    ("TRIAN 0 1 1", "Concave 0.5 1", "16:14", "unsupported term shape: Concave"),
    ("TRIAN 0 1 1", "SINGLETONS (0, 1) (1, 1)", "16:14", "unsupported term shape: SINGLETONS"),
    ("TRIAN 0 1 1", "FUNCTION x", "16:14", "unsupported term shape: FUNCTION"),
    ("(0, 0) (10, 1)", "(0, 0) (top, 1)", "11:22", "unsupported: a point's x given by a "
                                                   "variable name (top)"),
    ("END_FUNCTION_BLOCK\n", "END_FUNCTION_BLOCK\nFUNCTION_BLOCK g\nEND_FUNCTION_BLOCK\n",
     "28:1", "unsupported: a second FUNCTION_BLOCK 'g'"),
    ("IF x IS lo THEN", "IF x IS lo AND x IS hi OR x IS lo THEN", "24:35",
     "mixing AND and OR without parentheses is ambiguous"),
    ("RULEBLOCK r", "VAR\nEND_VAR\nRULEBLOCK r", "20:1", "unsupported block: VAR"),
    ("  x : REAL;", "  x : INT;", "3:7", "unsupported type: INT (supported: REAL)"),
    ("y IS lo;", "y IS lo WITH w;", "24:41", "unsupported: the rule weight given by a "
                                            "variable name (w)"),
])
def test_unsupported_features_are_named(old: str, new: str, where: str, message: str) -> None:
    with pytest.raises(FormatError) as info:
        parse(base(old, new), "u.fcl")
    text = str(info.value)
    assert text.startswith(f"u.fcl:{where}: "), text
    assert message in text, text


def test_outputs_with_different_methods_are_refused() -> None:
    src = base("  y : REAL;", "  y : REAL;\n  z : REAL;").replace(
        "END_DEFUZZIFY", "END_DEFUZZIFY\nDEFUZZIFY z\n  RANGE := (0 .. 1);\n"
                         "  TERM a := TRIAN 0 0.5 1;\n  METHOD : COA;\nEND_DEFUZZIFY")
    with pytest.raises(FormatError, match=r"^f\.fcl:24:12: unsupported: outputs with "
                                          r"different METHODs \(COG and COA\)"):
        parse(src, "f.fcl")


def test_missing_method_is_refused() -> None:
    with pytest.raises(FormatError, match=r"^f\.fcl:13:11: output 'y' has no METHOD"):
        parse(base("  METHOD : COG;\n", ""), "f.fcl")


# ------------------------------------------------------------------------ writer


def every_shape_system() -> FuzzySystem:
    """Every term shape, heights, vertical edges, a discrete that looks like a triangle."""
    a = V("a", -1, 1,
          T("tri", "triangle", -1, -0.5, 0), T("tri_v", "triangle", -0.5, -0.5, 0.5),
          T("trap", "trapezoid", -0.75, -0.25, 0.25, 0.75, height=0.75),
          T("lsh", "trapezoid", -INF, -0.8, -0.6, -0.2),
          T("rsh", "trapezoid", 0.2, 0.6, 0.8, INF, height=0.5),
          T("rect", "rectangle", -0.1, 0.3), T("up", "ramp", -1, 1), T("down", "ramp", 1, -1),
          T("flat", "ramp", 0.5, 0.5), T("disc", "discrete", -1, 0, 0, 1, 1, 0),
          T("step", "discrete", -1, 0.25, 0, 0.25, 0, 0.75, 1, 0.75, height=0.5))
    b = V("b", 0, 4,
          T("g", "gaussian", 2, 0.7), T("g2", "gaussian2", 1, 0.3, 2.5, 0.6, height=0.9),
          T("bell", "bell", 3, 0.5, 2), T("sig", "sigmoid", 2, -3),
          T("dsig", "dsigmoid", 1, 6, 6, 3), T("psig", "psigmoid", 1, 6, -6, 3),
          T("s", "s", 0.5, 3.5), T("z", "z", 0.5, 3.5), T("pi", "pi", 0.5, 1.5, 2.5, 3.5))
    u = V("u", 0, 10, T("lo", "triangle", 0, 2, 5, height=0.7), T("mid", "pi", 2, 4, 6, 8),
          T("hi", "discrete", 5, 0, 8, 1, 10, 1, height=0.9), T("box", "rectangle", 4, 6),
          T("bump", "gaussian", 7, 1), default=-1.0)
    ins = (a, b)
    rules = []
    for i in range(len(a.terms)):
        ante: Expr = And((Is(0, i), Is(1, i % len(b.terms), i % 2 == 1)))
        rules.append(Rule(ante, (Consequent(0, i % len(u.terms)),), 1.0 if i % 3 else 0.5))
    rules.append(Rule(Or((Is(0, 0), And((Is(0, 1), Is(1, 2))))), (Consequent(0, 4),)))
    return FuzzySystem(name="every_shape", inputs=ins, outputs=(u,), rules=tuple(rules),
                       and_op="product", or_op="probor", implication="product",
                       aggregation="max", defuzzifier="centroid")


def singleton_system(aggregation: str = "sum") -> FuzzySystem:
    x = V("x", 0, 1, T("lo", "triangle", -1, 0, 1), T("hi", "triangle", 0, 1, 2))
    y = V("y", 0, 1, T("lo", "triangle", -1, 0, 1), T("hi", "triangle", 0, 1, 2))
    out = V("z", -2, 2, T("neg", "singleton", -1.5), T("zero", "singleton", 0),
            T("pos", "singleton", 1.25), default=0.5)
    rules = (Rule(And((Is(0, 0), Is(1, 0))), (Consequent(0, 0),)),
             Rule(And((Is(0, 1), Is(1, 0))), (Consequent(0, 1),)),
             Rule(And((Is(0, 0), Is(1, 1))), (Consequent(0, 1),), 0.75),   # shares 'zero'
             Rule(And((Is(0, 1), Is(1, 1))), (Consequent(0, 2),)))
    return FuzzySystem(name="singletons", inputs=(x, y), outputs=(out,), rules=rules,
                       aggregation=aggregation)  # type: ignore[arg-type]


def sugeno_system(defuzzifier: str) -> FuzzySystem:
    x = V("x", 0, 1, T("lo", "ramp", 1, 0), T("hi", "ramp", 0, 1))
    y = V("y", -1, 1, T("neg", "sigmoid", 0, -5), T("pos", "sigmoid", 0, 5))
    out = V("z", -10, 10, T("c", "constant", 2.5), T("l", "linear", 3, -2, 0.5),
            T("m", "linear", -1, 0.25, -4))
    rules = (Rule(Is(0, 0), (Consequent(0, 0),)),
             Rule(And((Is(0, 1), Is(1, 0))), (Consequent(0, 1),), 0.5),
             Rule(Or((Is(0, 1), Is(1, 1))), (Consequent(0, 2),)))
    return FuzzySystem(name=f"sugeno_{defuzzifier}", kind="sugeno", inputs=(x, y),
                       outputs=(out,), rules=rules, and_op="product",
                       defuzzifier=defuzzifier)  # type: ignore[arg-type]


def paper_systems() -> list[FuzzySystem]:
    from fuzzyservo.paper import alpha_system, du_system

    return [dataclasses.replace(du_system(), name="du"),
            dataclasses.replace(alpha_system(), name="alpha")]


def round_trip_cases() -> list[FuzzySystem]:
    cases = [*paper_systems(), BASE_SYSTEM, every_shape_system(), singleton_system("max"),
             sugeno_system("wtaver"), sugeno_system("wtsum")]
    cases.append(read("iec_points.fcl"))
    cases.append(read("fuzzylite_dialect.fcl"))
    for and_op, or_op in (("min", "max"), ("product", "probor"), ("min", "probor")):
        for impl in ("min", "product"):
            for agg in ("max", "bounded_sum", "sum", "probor"):
                cases.append(with_ops(every_shape_system(), and_op=and_op, or_op=or_op,
                                      implication=impl, aggregation=agg))
    for d in ("bisector", "mom", "som", "lom"):
        cases.append(with_ops(BASE_SYSTEM, defuzzifier=d))
    return cases


@pytest.mark.parametrize("system", round_trip_cases(), ids=lambda s: s.name)
def test_round_trip(system: FuzzySystem) -> None:
    text = dump(system)
    back = parse(text, "dumped.fcl")
    assert back == system
    # everything was stated, but a NaN default, which is written by leaving DEFAULT out
    nan_default = [v.name for v in system.outputs if math.isnan(v.default)]
    assert back.notes == tuple(f"output {n!r} has no DEFAULT: NaN when no rule fires"
                               for n in nan_default)
    assert dump(back) == text


def test_writer_uses_point_lists_where_exact_and_class_names_elsewhere() -> None:
    text = dump(every_shape_system())
    for line in ("TERM tri := (-1, 0) (-0.5, 1) (0, 0);",
                 "TERM tri_v := Triangle -0.5 -0.5 0.5;",          # vertical edge
                 "TERM trap := Trapezoid -0.75 -0.25 0.25 0.75 0.75;",  # height
                 "TERM lsh := (-0.8, 1) (-0.6, 1) (-0.2, 0);",
                 "TERM rsh := Trapezoid 0.2 0.6 0.8 inf 0.5;",
                 "TERM rect := Rectangle -0.1 0.3;", "TERM up := (-1, 0) (1, 1);",
                 "TERM down := (-1, 1) (1, 0);", "TERM flat := Ramp 0.5 0.5;",
                 "TERM disc := Discrete -1 0 0 1 1 0;",            # would read as a triangle
                 "TERM step := Discrete -1 0.25 0 0.25 0 0.75 1 0.75 0.5;",
                 "TERM g2 := GaussianProduct 1 0.3 2.5 0.6 0.9;", "TERM bell := Bell 3 0.5 2;",
                 "TERM sig := Sigmoid 2 -3;", "METHOD : COG;", "ACCU : MAX;",
                 "DEFAULT := -1;", "LOCK : RANGE;", "AND : PROD;", "OR : ASUM;", "ACT : PROD;",
                 "RULE 12 : if a is tri or (a is tri_v and b is bell) then u is bump;",
                 "RULE 1 : if a is tri and b is g then u is lo with 0.5;",
                 "RULE 2 : if a is tri_v and b is not g2 then u is mid;"):
        assert f"  {line}\n" in text, line
    no_default = with_ops(BASE_SYSTEM, outputs=(
        dataclasses.replace(BASE_SYSTEM.outputs[0], default=math.nan),))
    assert "DEFAULT" not in dump(no_default)  # NaN: left out, read back as NaN


def test_writer_refuses_what_fcl_cannot_hold() -> None:
    s = BASE_SYSTEM
    x = s.inputs[0]
    cases: list[tuple[FuzzySystem, str]] = [
        (with_ops(s, inputs=(dataclasses.replace(x, clip=False),)),
         "FCL cannot hold input 'x' without clipping"),
        (with_ops(s, rules=(Rule(Not(And((Is(0, 0), Is(0, 0)))), (Consequent(0, 0),)),)),
         "cannot hold NOT applied to an expression (rule 1"),
        (with_ops(s, inputs=(dataclasses.replace(x, terms=(T("very", "ramp", 0, 10),)),),
                  rules=()), "term name 'very': fuzzylite reads it as a hedge"),
        (with_ops(s, inputs=(dataclasses.replace(x, name="Then"),)),
         "input name 'Then': it is an FCL keyword"),
        (with_ops(s, name="a..b"), "cannot spell the system name 'a..b'"),
        (with_ops(singleton_system(), outputs=(dataclasses.replace(
            singleton_system().outputs[0], terms=(T("neg", "singleton", -1.5, height=0.5),
                                                  T("zero", "singleton", 0),
                                                  T("pos", "singleton", 1.25))),)),
         "FCL cannot hold term height 0.5 of output 'z' term 'neg'"),
        (with_ops(singleton_system(), defuzzifier="som"),
         "cannot hold LM over the singleton terms of output 'z'"),
        (with_ops(sugeno_system("wtaver"), outputs=(dataclasses.replace(
            sugeno_system("wtaver").outputs[0], terms=()),), rules=()),
         "FCL cannot mark a Sugeno system whose outputs have no terms"),
    ]
    for system, message in cases:
        with pytest.raises(ParameterError, match=message.replace("(", r"\(")):
            dump(system)


# -------------------------------------------------------------- fuzzylite's examples


#: Every FCL example installed with fuzzylite 6: None if it is read, else the named refusal.
EXAMPLE_OUTCOMES: dict[str, str | None] = {
    "hybrid/ObstacleAvoidance.fcl": None,
    "hybrid/tipper.fcl": None,
    "mamdani/AllTerms.fcl": ":20:13: unsupported term shape: Concave",
    "mamdani/Laundry.fcl": ":54:15: unsupported: rule antecedent uses output variable "
                           "'Detergent' (chained rule bases)",
    "mamdani/ObstacleAvoidance.fcl": None,
    "mamdani/SimpleDimmer.fcl": None,
    "mamdani/SimpleDimmerChained.fcl": ":33:15: unsupported term shape: Cosine",
    "mamdani/SimpleDimmerInverse.fcl": ":33:15: unsupported term shape: Cosine",
    "mamdani/octave/investment_portfolio.fcl": ":42:26: unsupported hedge: extremely",
    "mamdani/octave/mamdani_tip_calculator.fcl": None,
    "takagi-sugeno/ObstacleAvoidance.fcl": None,
    "takagi-sugeno/SimpleDimmer.fcl": None,
    "takagi-sugeno/approximation.fcl": ":40:18: unsupported: DEFAULT ... | NC",
    "takagi-sugeno/octave/cubic_approximator.fcl": None,
    "takagi-sugeno/octave/heart_disease_risk.fcl": None,
    "takagi-sugeno/octave/linear_tip_calculator.fcl": None,
    "takagi-sugeno/octave/sugeno_tip_calculator.fcl": ":57:30: unsupported hedge: extremely",
    "tsukamoto/tsukamoto.fcl": ":52:13: unsupported term shape: Concave",
}


def example_files() -> list[str]:
    return sorted(str(p.relative_to(EXAMPLES)) for p in EXAMPLES.rglob("*.fcl"))


def test_every_installed_example_is_listed() -> None:
    assert example_files() == sorted(EXAMPLE_OUTCOMES)


@pytest.mark.parametrize("name", sorted(EXAMPLE_OUTCOMES))
def test_installed_examples_parse_or_are_refused_by_name(name: str) -> None:
    text = (EXAMPLES / name).read_text(encoding="utf-8")
    outcome = EXAMPLE_OUTCOMES[name]
    if outcome is None:
        s = parse(text, name)
        assert parse(dump(s), name) == s
    else:
        with pytest.raises(FormatError) as info:
            parse(text, name)
        assert str(info.value).startswith(name + outcome), str(info.value)


# --------------------------------------------------------------------- fuzzylite oracle

#: fuzzylite's centroid resolution in the oracle runs.
RESOLUTION = 1_000_000
#: fuzzylite integrates by the midpoint rule on RESOLUTION cells: exact on linear pieces,
#: O(dx^2) on cells with a kink or a smooth curve, and at most one cell's width dx per
#: vertical edge (a jump). Ten cells' width of the range bounds all the systems here (a few
#: vertical edges each); the observed differences are 1e-11 of the range or below without
#: vertical edges.
TOL_CELLS = 10.0


def fcl_to_fll(text: str) -> str:
    """fuzzylite's own reading of an FCL file, written back by fuzzylite as FLL with every
    digit (fuzzylite_translate writes 3 decimals, which would change the systems)."""
    with tempfile.TemporaryDirectory() as d:
        src, dst = Path(d) / "in.fcl", Path(d) / "out.fll"
        src.write_text(text, encoding="utf-8")
        proc = subprocess.run([fuzzylite_binary(), "-i", str(src), "-if", "fcl", "-o", str(dst),
                               "-of", "fll", "-decimals", "17"], capture_output=True, text=True,
                              timeout=600, check=False)
        assert proc.returncode == 0 and "error" not in proc.stderr.lower(), proc.stderr
        return dst.read_text(encoding="utf-8")


def activations(system: FuzzySystem, x: FloatArray) -> FloatArray:
    """Each rule's weighted firing strength at the points x (n, n_inputs), (n, n_rules)."""
    mu = [[general.membership(t.shape, t.params, np.clip(x[:, i], *v.range), t.height)
           for t in v.terms] for i, v in enumerate(system.inputs)]

    def ev(e: Expr) -> FloatArray:
        if isinstance(e, Is):
            m = mu[e.variable][e.term]
            return 1.0 - m if e.negated else m
        if isinstance(e, Not):
            return 1.0 - ev(e.operand)
        vals = [ev(op) for op in e.operands]
        out = vals[0]
        for v in vals[1:]:
            if isinstance(e, And):
                out = np.minimum(out, v) if system.and_op == "min" else out * v
            else:
                out = np.maximum(out, v) if system.or_op == "max" else out + v - out * v
        return out

    return np.stack([r.weight * ev(r.antecedent) for r in system.rules], axis=1)


def strong_points(system: FuzzySystem, n: int, seed: int,
                  keep: Callable[[FloatArray], FloatArray] | None = None) -> FloatArray:
    """n random points inside the ranges where no rule fires with 0 < strength <= 1e-5
    (fuzzylite drops rules at or below 1e-6 and snaps values within 1e-6 of a vertex)."""
    rng = np.random.default_rng(seed)
    lo = np.array([v.range[0] for v in system.inputs])
    hi = np.array([v.range[1] for v in system.inputs])
    pts: list[FloatArray] = []
    while sum(len(p) for p in pts) < n:
        x = lo + (hi - lo) * rng.random((20 * n, len(lo)))
        w = activations(system, x)
        ok = ~np.any((w > 0.0) & (w <= 1e-5), axis=1)
        if keep is not None:
            ok &= keep(x)
        pts.append(x[ok])
    return np.concatenate(pts)[:n]


def assert_fuzzylite_agrees(text: str, system: FuzzySystem, x: FloatArray) -> float:
    """Largest |ours - fuzzylite| / range over the outputs; asserts the bound."""
    names, theirs = fuzzylite_eval(fcl_to_fll(text), "fll", [v.name for v in system.inputs], x,
                                   RESOLUTION)
    assert names == [v.name for v in system.outputs]
    ours = evaluate(system, x)
    worst = 0.0
    for k, v in enumerate(system.outputs):
        span = v.range[1] - v.range[0]
        np.testing.assert_array_equal(np.isnan(ours[:, k]), np.isnan(theirs[:, k]))
        d = np.abs(ours[:, k] - theirs[:, k])
        d = d[~np.isnan(d)]
        if d.size:
            worst = max(worst, float(d.max()) / span)
        np.testing.assert_allclose(ours[:, k], theirs[:, k], rtol=0,
                                   atol=TOL_CELLS * span / RESOLUTION)
    return worst


def oracle_cases() -> list[tuple[str, str, FuzzySystem]]:
    cases = [(s.name, dump(s), s) for s in paper_systems()]
    for s in (every_shape_system(), singleton_system("sum"), sugeno_system("wtaver"),
              sugeno_system("wtsum"), read("iec_points.fcl"),
              with_ops(every_shape_system(), and_op="min", or_op="max", implication="min",
                       aggregation="bounded_sum", name="every_shape_minmax"),
              with_ops(every_shape_system(), aggregation="sum", name="every_shape_sum")):
        cases.append((s.name, dump(s), s))
    text = (DATA / "fuzzylite_dialect.fcl").read_text(encoding="utf-8")
    cases.append(("fuzzylite_dialect.fcl", text, parse(text)))
    for name, outcome in EXAMPLE_OUTCOMES.items():
        if outcome is None and name != "hybrid/tipper.fcl":
            text = (EXAMPLES / name).read_text(encoding="utf-8")
            cases.append((name, text, parse(text, name)))
    return cases


@pytest.mark.parametrize(("name", "text", "system"), oracle_cases(), ids=lambda c: str(c)[:40])
def test_fuzzylite_agrees(name: str, text: str, system: FuzzySystem) -> None:
    x = strong_points(system, 50, seed=len(name))
    assert_fuzzylite_agrees(text, system, x)


def test_fuzzylite_tipper_agrees_where_its_cogs_reading_does() -> None:
    """hybrid/tipper.fcl: tsTip's rules 3 and 4 conclude the same singleton. IEC accumulates
    them by the file's ACCU : MAX; fuzzylite's COGS adds the rules (a weighted average of the
    rules) whatever ACCU says. Both agree wherever rule 4 does not fire, and differ where both
    do: that is the documented difference, not a sampling error."""
    name = "hybrid/tipper.fcl"
    text = (EXAMPLES / name).read_text(encoding="utf-8")
    s = parse(text, name)
    assert s.aggregation == "max"
    x = strong_points(s, 50, 7, keep=lambda x: activations(s, x)[:, 3] == 0.0)
    assert_fuzzylite_agrees(text, s, x)
    both = strong_points(s, 20, 8, keep=lambda x: np.min(activations(s, x)[:, 2:4], axis=1) > 0.1)
    _, theirs = fuzzylite_eval(fcl_to_fll(text), "fll", ["service", "food"], both, RESOLUTION)
    ours = evaluate(s, both)
    assert np.all(np.abs(ours[:, 1] - theirs[:, 1]) > 1e-3)  # tsTip: max vs sum of degrees
    np.testing.assert_allclose(ours[:, 0], theirs[:, 0], rtol=0,
                               atol=TOL_CELLS * 30 / RESOLUTION)  # mTip agrees


# ---------------------------------------------------------------------------- fuzzing


_SNIPPETS = ["(", ")", ";", ":", ":=", "..", ",", "|", "(*", "*)", "/*", "//", "#", "\n",
             "RULE 9 :", "IF", "THEN", "AND", "OR", "NOT", "IS", "WITH", "TERM t :=", "RANGE",
             "END_FUZZIFY", "FUNCTION_BLOCK", "1e999", "-inf", "nan", "0", "-1", "x", "y",
             "lo", "TRIAN", "Discrete", "(" * 300, "NOT " * 300, "\ufeff", "\r", "é"]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, len(BASE)), st.integers(0, 20),
                          st.sampled_from(_SNIPPETS)), min_size=1, max_size=6))
def test_mutated_files_raise_only_format_errors(edits: list[tuple[int, int, str]]) -> None:
    text = BASE
    for at, cut, snippet in edits:
        at = min(at, len(text))
        text = text[:at] + snippet + text[at + cut:]
    try:
        s = parse(text, "m.fcl")
    except FormatError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("m.fcl:")
        return
    assert isinstance(s, FuzzySystem)


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=300))
def test_random_text_raises_only_format_errors(text: str) -> None:
    try:
        parse(text, "r.fcl")
    except FormatError:
        pass
