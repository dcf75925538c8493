"""Random fuzzy systems and file texts for the format fuzzers (test-only).

Used by ``tests/formats/test_fuzz.py`` (through hypothesis) and ``benchmarks/fuzz_formats.py``
(through a plain ``numpy.random.Generator``, much faster): every generator is written once
against :class:`Rand`, a small source of choices with two implementations, :class:`NumpyRand`
and :class:`DrawRand` (a hypothesis ``draw``, so that failures shrink).

- :func:`random_system`: a valid :class:`~fuzzyservo.fuzzy.system.FuzzySystem` with 1-3
  inputs and 1-2 outputs, every term shape the model has with valid parameters (grid points,
  so that vertices coincide, and arbitrary floats, tiny and huge ones included), heights,
  Mamdani (singleton outputs included) and Sugeno, every operator and defuzzifier, random
  rules (AND / OR / NOT nested, weights, several consequents), defaults including NaN, and
  names that are keywords of some format. ``fit="fis" | "fcl" | "fll"`` restricts it to what
  that format's module docstring says it can hold, so the writer must accept it.
- :func:`random_text`: a text for a reader: mostly a valid file (:data:`SEED_FILES`, or a
  writer's output of a random system) mutated the way a typo, a hostile file or a broken
  transfer mutates it; else random text or random bytes decoded.
- :data:`CODE_PAYLOADS`: code that must never run; :data:`MARKER` is the file it would
  create.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import re
import sys
import tempfile
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Protocol, TypeVar

import numpy as np
from hypothesis import strategies as st

# the readers are imported here, before any CodeWatch: an import runs code (a dataclass's
# methods are made by exec), which the watch would report
import fuzzyservo.formats.fis  # noqa: F401
from fuzzyservo.errors import FormatError, ParameterError
from fuzzyservo.formats import fcl, fll
from fuzzyservo.formats.io import dumps, loads
from fuzzyservo.fuzzy import evaluate
from fuzzyservo.fuzzy.system import (
    AGGREGATIONS,
    AND_OPS,
    IMPLICATIONS,
    OR_OPS,
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

ROOT = Path(__file__).resolve().parents[2]
FORMATS = ("fis", "fcl", "fll")
T = TypeVar("T")

# ------------------------------------------------------------------------------ randomness


class Rand(Protocol):
    """A source of choices."""

    def integer(self, lo: int, hi: int) -> int:
        """An integer in [lo, hi]."""

    def unit(self) -> float:
        """A float in [0, 1]."""


class NumpyRand:
    """Choices from a ``numpy.random.Generator``."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng

    def integer(self, lo: int, hi: int) -> int:
        return int(self.rng.integers(lo, hi + 1))

    def unit(self) -> float:
        return float(self.rng.random())


class DrawRand:
    """Choices from a hypothesis ``draw`` (they shrink towards the first options)."""

    def __init__(self, draw: st.DrawFn) -> None:
        self.draw = draw

    def integer(self, lo: int, hi: int) -> int:
        return self.draw(st.integers(lo, hi))

    def unit(self) -> float:
        return self.draw(st.floats(0.0, 1.0))


def choice(r: Rand, options: Sequence[T]) -> T:
    """One of ``options``."""
    return options[r.integer(0, len(options) - 1)]


def chance(r: Rand, p: float) -> bool:
    """True with probability ``p`` (to 1/1000)."""
    return r.integer(0, 999) < p * 1000


def between(lo: float, hi: float, t: float) -> float:
    """The point a fraction ``t`` (may be outside [0, 1]) from lo to hi, without overflow;
    the nearer end when it is not finite."""
    v = lo * (1.0 - t) + hi * t
    if not math.isfinite(v):
        v = lo if t < 0.5 else hi
    return v


# ------------------------------------------------------------------------------ systems

#: Names that some format reads as a keyword, a number or a class (each format must either
#: write them so that they read back, or refuse them by name).
TRICKY_NAMES = (
    "if", "IF", "then", "is", "IS", "not", "NOT", "and", "AND", "or", "with", "none", "very",
    "any", "seldom", "RANGE", "Range", "TERM", "term", "rule", "RULE", "Engine", "REAL", "nan",
    "NaN", "inf", "Inf", "infinity", "e", "E1", "e5", "x.", "a..b", "_", "_1", "Triangle",
    "Constant", "trimf", "MF1", "Name", "System", "Rules", "END_VAR", "NC", "true", "false",
    "x.y.z", "range", "default", "lock", "LOCK", "COG", "METHOD", "min", "max", "General",
    "FUNCTION_BLOCK", "VAR_INPUT", "ACCU", "enabled", "description",
)
#: Every keyword-like name of any format, lower case (fit systems avoid them).
_AVOID = frozenset(n.lower() for n in TRICKY_NAMES) | frozenset({
    "if", "then", "is", "not", "and", "or", "with", "none", "very", "somewhat", "seldom",
    "extremely", "any", "function_block", "end_function_block", "var_input", "var_output",
    "var", "end_var", "fuzzify", "end_fuzzify", "defuzzify", "end_defuzzify", "ruleblock",
    "end_ruleblock", "option", "end_option", "term", "range", "method", "default", "accu",
    "act", "lock", "enabled", "rule", "real", "nc", "nan", "inf", "infinity"})

_FIRST = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ_"
_REST = _FIRST + "0123456789"


_FCL_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z0-9_]+)*\Z")


def name_fits(fmt: str, name: str) -> bool:
    """Whether ``fmt``'s writer takes ``name`` for any variable, term or system (as its
    module docstring says: FCL neither keywords nor fuzzylite's hedges nor dots at an end;
    FLL no rule keywords; .fis anything)."""
    if fmt == "fcl":
        return bool(_FCL_NAME.match(name)) and name.upper() not in fcl._RESERVED \
            and name.lower() not in fcl._HEDGES
    if fmt == "fll":
        return name not in fll._KEYWORDS
    return True


def ident(r: Rand, fit: str | None) -> str:
    """A name the model accepts; often a tricky one (with ``fit``, one that format takes)."""
    if chance(r, 0.3):
        name = choice(r, TRICKY_NAMES)
        if fit is None or name_fits(fit, name):
            return name
    while True:
        name = choice(r, _FIRST) + "".join(choice(r, _REST) for _ in range(r.integer(0, 5)))
        if fit is None and chance(r, 0.1):
            name += choice(r, (".", ".1", ".a.b", "..x"))
        if name.lower() not in _AVOID and (fit is None or name_fits(fit, name)):
            return name


def unique_names(r: Rand, n: int, fit: str | None, taken: set[str]) -> list[str]:
    """``n`` names not in ``taken`` (added to it)."""
    out: list[str] = []
    while len(out) < n:
        name = ident(r, fit)
        if name not in taken:
            taken.add(name)
            out.append(name)
    return out


def a_range(r: Rand) -> tuple[float, float]:
    """A variable's range: plain ones, and tiny, huge or far-from-zero spans."""
    k = r.integer(0, 9)
    if k <= 4:
        return choice(r, ((0.0, 1.0), (-1.0, 1.0), (-10.0, 10.0), (0.0, 100.0),
                          (-0.5, 2.5), (1.0 / 3.0, 0.7)))
    if k == 5:
        return choice(r, ((-1e300, 1e300), (-1.7976931348623157e308, 1.7976931348623157e308),
                          (0.0, 5e-324), (1e15, 1e15 + 1.0), (-1e-300, 1e-300)))
    lo = (r.unit() * 2.0 - 1.0) * 10.0 ** r.integer(-5, 6)
    hi = lo + r.unit() * 10.0 ** r.integer(-6, 6)
    if not hi > lo:
        hi = math.nextafter(lo, math.inf)
    return lo, hi


def coord(r: Rand, lo: float, hi: float) -> float:
    """A point around [lo, hi]: on a grid of eighths (coinciding vertices), arbitrary, or a
    special value."""
    k = r.integer(0, 9)
    if k <= 4:
        return between(lo, hi, r.integer(-2, 10) / 8.0)
    if k <= 8:
        return between(lo, hi, r.unit() * 1.5 - 0.25)
    return choice(r, (0.0, -0.0, 1.0 / 3.0, 5e-324, -5e-324, 1e-300, lo, hi,
                      math.nextafter(lo, math.inf), math.nextafter(hi, -math.inf)))


def positive(r: Rand, w: float) -> float:
    """A positive width or sigma on the scale ``w``."""
    v = w * choice(r, (1.0 / 8.0, 1.0 / 3.0, 1.0, r.unit() + 1e-3, 1e-6, 5.0))
    return v if math.isfinite(v) and v > 0.0 else 1.0


def sorted_coords(r: Rand, n: int, lo: float, hi: float) -> list[float]:
    """``n`` sorted points around [lo, hi]."""
    return sorted(coord(r, lo, hi) for _ in range(n))


MAMDANI_SHAPES = ("triangle", "trapezoid", "rectangle", "ramp", "discrete", "gaussian",
                  "gaussian2", "bell", "sigmoid", "dsigmoid", "psigmoid", "s", "z", "pi")
#: Shapes MATLAB's .fis knows.
FIS_SHAPES = ("triangle", "trapezoid", "gaussian", "gaussian2", "bell", "sigmoid", "dsigmoid",
              "psigmoid", "s", "z", "pi")


def _params(r: Rand, shape: str, lo: float, hi: float, n_in: int) -> tuple[float, ...]:
    w = hi - lo if math.isfinite(hi - lo) else 1e308
    if shape == "triangle":
        return tuple(sorted_coords(r, 3, lo, hi))
    if shape == "trapezoid":
        p = sorted_coords(r, 4, lo, hi)
        k = r.integer(0, 5)
        if k == 0:
            p[0] = -math.inf
        elif k == 1:
            p[3] = math.inf
        return tuple(p)
    if shape == "rectangle":
        return tuple(sorted_coords(r, 2, lo, hi))
    if shape == "ramp":
        a = coord(r, lo, hi)
        return (a, a if chance(r, 0.1) else coord(r, lo, hi))
    if shape == "discrete":
        xs = sorted_coords(r, r.integer(2, 6), lo, hi)
        if chance(r, 0.3) and len(xs) >= 3:  # a jump: one x twice
            i = r.integer(1, len(xs) - 1)
            xs[i] = xs[i - 1]
            if i + 1 < len(xs) and xs[i + 1] == xs[i]:
                xs[i + 1] = math.nextafter(xs[i], math.inf)
        ys = [choice(r, (0.0, 1.0, 0.5, r.unit())) for _ in xs]
        return tuple(v for xy in zip(xs, ys, strict=True) for v in xy)
    if shape == "singleton":
        return (coord(r, lo, hi),)
    if shape == "gaussian":
        return (coord(r, lo, hi), positive(r, w))
    if shape == "gaussian2":
        return (coord(r, lo, hi), positive(r, w), coord(r, lo, hi), positive(r, w))
    if shape == "bell":
        width = positive(r, w) * (-1.0 if chance(r, 0.2) else 1.0)
        return (coord(r, lo, hi), width, choice(r, (0.5, 1.0, 2.0, 2.5, r.unit() * 5 + 0.01)))
    if shape == "sigmoid":
        return (coord(r, lo, hi), slope(r, w))
    if shape in ("dsigmoid", "psigmoid"):
        return (coord(r, lo, hi), slope(r, w), slope(r, w), coord(r, lo, hi))
    if shape in ("s", "z"):
        return tuple(sorted_coords(r, 2, lo, hi))
    if shape == "pi":
        return tuple(sorted_coords(r, 4, lo, hi))
    if shape == "constant":
        return (coord(r, lo, hi) if chance(r, 0.9) else choice(r, (1e300, -1e300, 0.0)),)
    if shape == "linear":
        return tuple(choice(r, (0.0, 1.0, -2.0, 0.5, (r.unit() - 0.5) * 20.0, 1e-17))
                     for _ in range(n_in + 1))
    raise AssertionError(shape)


def slope(r: Rand, w: float) -> float:
    """A sigmoid slope on the scale 1 / ``w`` (either sign, zero sometimes)."""
    v = choice(r, (0.0, 1.0, -1.0, 10.0, (r.unit() - 0.5) * 40.0)) / w
    return v if math.isfinite(v) else 1.0


def _fallback(shape: str, lo: float, hi: float, n_in: int) -> tuple[float, ...]:
    """Valid parameters of ``shape`` on [lo, hi] (when random ones were not)."""
    mid = between(lo, hi, 0.5)
    q1, q3 = between(lo, hi, 0.25), between(lo, hi, 0.75)
    w = max(hi - lo if math.isfinite(hi - lo) else 1e308, 5e-324)
    return {
        "triangle": (lo, mid, hi), "trapezoid": (lo, q1, q3, hi), "rectangle": (q1, q3),
        "ramp": (lo, hi), "discrete": (lo, 0.0, hi, 1.0), "singleton": (mid,),
        "gaussian": (mid, w), "gaussian2": (q1, w, q3, w), "bell": (mid, w, 2.0),
        "sigmoid": (mid, 1.0), "dsigmoid": (q1, 1.0, 1.0, q3), "psigmoid": (q1, 1.0, -1.0, q3),
        "s": (lo, hi), "z": (lo, hi), "pi": (lo, q1, q3, hi), "constant": (mid,),
        "linear": (0.0,) * n_in + (mid,),
    }[shape]


def term(r: Rand, name: str, shape: str, lo: float, hi: float, n_in: int, fit: str | None
         ) -> Term:
    """A valid term of ``shape``."""
    height = 1.0
    heights_ok = fit is None or (fit in ("fcl", "fll") and shape not in (
        "singleton", "constant", "linear"))
    if heights_ok and chance(r, 0.25):
        height = choice(r, (0.5, 0.25, 1e-3, 5e-324, max(r.unit(), 1e-9)))
    try:
        return Term(name, shape, _params(r, shape, lo, hi, n_in), height)
    except ParameterError:
        pass
    try:
        return Term(name, shape, _fallback(shape, lo, hi, n_in), height)
    except ParameterError:
        pass
    return Term(name, shape, _fallback(shape, 0.0, 1.0, n_in), height)  # a range too narrow


def _middle(lo: float, hi: float) -> float:
    mid = (lo + hi) / 2
    return mid if math.isfinite(mid) else lo / 2 + hi / 2


def variable(r: Rand, name: str, role: str, kind: str, shapes: Sequence[str], n_in: int,
             fit: str | None) -> Variable:
    """A random input or output variable."""
    lo, hi = a_range(r)
    n_terms = r.integer(0, 4) if chance(r, 0.1) else r.integer(1, 4)
    names = unique_names(r, n_terms, fit, set())
    terms = tuple(term(r, n, choice(r, shapes), lo, hi, n_in, fit) for n in names)
    default = math.nan
    clip = chance(r, 0.7)
    if role == "input":
        if fit is None and chance(r, 0.1):
            default = coord(r, lo, hi)
        if fit in ("fis", "fcl"):
            clip = True
    else:
        default = choice(r, (math.nan, math.nan, _middle(lo, hi), 0.0, -0.0,
                             coord(r, lo, hi)))
        if fit == "fis":
            default = _middle(lo, hi)
            clip = kind == "mamdani"
    return Variable(name, (lo, hi), terms, default=default, clip=clip)


def expr(r: Rand, inputs: Sequence[Variable], depth: int, fit: str | None) -> Expr:
    """A random antecedent over inputs that have terms."""
    usable = [i for i, v in enumerate(inputs) if v.terms]
    k = r.integer(0, 9)
    if depth >= 3 or k <= 4:
        i = choice(r, usable)
        clause = Is(i, r.integer(0, len(inputs[i].terms) - 1), chance(r, 0.3))
        return Not(clause) if chance(r, 0.1) else clause
    if k == 5 and fit is None:
        return Not(expr(r, inputs, depth + 1, fit))
    ops = tuple(expr(r, inputs, depth + 1, fit) for _ in range(r.integer(2, 3)))
    return And(ops) if chance(r, 0.5) else Or(ops)


def flat_expr(r: Rand, inputs: Sequence[Variable]) -> Expr:
    """One clause, or an AND / OR of clauses over distinct inputs in input order (.fis)."""
    usable = [i for i, v in enumerate(inputs) if v.terms]
    chosen = [i for i in usable if chance(r, 0.6)] or [choice(r, usable)]
    clauses: list[Expr] = []
    for i in chosen:
        clause = Is(i, r.integer(0, len(inputs[i].terms) - 1), chance(r, 0.3))
        clauses.append(Not(Is(clause.variable, clause.term)) if clause.negated
                       and chance(r, 0.3) else clause)
    if len(clauses) == 1:
        return clauses[0]
    return And(tuple(clauses)) if chance(r, 0.5) else Or(tuple(clauses))


def rule(r: Rand, inputs: Sequence[Variable], outputs: Sequence[Variable], fit: str | None
         ) -> Rule:
    """A random rule."""
    ante = flat_expr(r, inputs) if fit == "fis" else expr(r, inputs, 0, fit)
    usable = [j for j, v in enumerate(outputs) if v.terms]
    if fit == "fis":
        chosen = [j for j in usable if chance(r, 0.6)] or [choice(r, usable)]
    else:
        chosen = [choice(r, usable) for _ in range(r.integer(1, 2))]
    cons = tuple(Consequent(j, r.integer(0, len(outputs[j].terms) - 1)) for j in chosen)
    weight = choice(r, (1.0, 1.0, 1.0, 0.0, 0.5, 1.0 / 3.0, 5e-324, r.unit()))
    return Rule(ante, cons, weight)


def random_system(r: Rand, fit: str | None = None) -> FuzzySystem:
    """A random valid system; with ``fit``, one that format can hold."""
    kind = "sugeno" if chance(r, 0.35) else "mamdani"
    n_in, n_out = r.integer(1, 3), r.integer(1, 2)
    taken: set[str] = set()
    in_names = unique_names(r, n_in, fit, taken)
    out_names = unique_names(r, n_out, fit, taken)
    in_shapes = FIS_SHAPES if fit == "fis" else MAMDANI_SHAPES
    inputs = [variable(r, n, "input", kind, in_shapes, n_in, fit) for n in in_names]
    if kind == "sugeno":
        out_shapes: Sequence[str] = ("constant", "linear")
        defuzzifier = choice(r, ("wtaver", "wtsum"))
    else:
        defuzzifier = choice(r, ("centroid", "bisector", "mom", "som", "lom"))
        singletons = fit not in ("fis", "fll") and chance(r, 0.2) and (
            defuzzifier != "bisector") and not (fit == "fcl" and defuzzifier != "centroid")
        out_shapes = ("singleton",) if singletons else in_shapes
    outputs = [variable(r, n, "output", kind, out_shapes, n_in, fit) for n in out_names]
    if defuzzifier == "bisector":  # the model refuses an output without terms there (all([]))
        outputs = [v if v.terms else Variable(v.name, v.range, (Term("t", "triangle", (
            v.range[0], v.range[0], v.range[1])),), v.default, v.clip) for v in outputs]
    if fit == "fcl" and kind == "sugeno" and not any(v.terms for v in outputs):
        outputs[0] = Variable(outputs[0].name, outputs[0].range,
                              (Term("c", "constant", (0.0,)),), outputs[0].default,
                              outputs[0].clip)
    rules: list[Rule] = []
    if any(v.terms for v in inputs) and any(v.terms for v in outputs):
        rules = [rule(r, inputs, outputs, fit) for _ in range(r.integer(0, 5))]
    aggregation = choice(r, AGGREGATIONS)
    if fit == "fis" and aggregation == "bounded_sum":
        aggregation = "max"
    return FuzzySystem(
        name=ident(r, fit), kind=kind, inputs=tuple(inputs), outputs=tuple(outputs),  # type: ignore[arg-type]
        rules=tuple(rules), and_op=choice(r, AND_OPS), or_op=choice(r, OR_OPS),  # type: ignore[arg-type]
        implication=choice(r, IMPLICATIONS), aggregation=aggregation,  # type: ignore[arg-type]
        defuzzifier=defuzzifier)  # type: ignore[arg-type]


def in_fis_order(s: FuzzySystem) -> FuzzySystem:
    """``s`` with each flat rule's clauses in input order and consequents in output order:
    the only change the .fis writer makes (a .fis rule has one column per variable; its
    module docstring says so), so ``parse(dump(s)) == in_fis_order(s)``."""

    def key(e: Expr) -> int:
        return e.variable if isinstance(e, Is) else -1

    rules = []
    for rl in s.rules:
        ante = rl.antecedent
        if isinstance(ante, And | Or) and all(isinstance(o, Is) for o in ante.operands):
            ops = tuple(sorted(ante.operands, key=key))
            ante = And(ops) if isinstance(ante, And) else Or(ops)
        cons = tuple(sorted(rl.consequents, key=lambda c: c.variable))
        rules.append(Rule(ante, cons, rl.weight))
    return FuzzySystem(name=s.name, kind=s.kind, inputs=s.inputs, outputs=s.outputs,
                       rules=tuple(rules), and_op=s.and_op, or_op=s.or_op,
                       implication=s.implication, aggregation=s.aggregation,
                       defuzzifier=s.defuzzifier)


def expected_after(fmt: str, s: FuzzySystem) -> FuzzySystem:
    """What reading ``s`` written as ``fmt`` must give."""
    return in_fis_order(s) if fmt == "fis" else s


# ------------------------------------------------------------------------------ texts


def _seed_files() -> dict[str, tuple[str, ...]]:
    out: dict[str, list[str]] = {f: [] for f in FORMATS}
    for folder in (ROOT / "src/fuzzyservo/data/systems",
                   *sorted((ROOT / "tests/formats/data").iterdir())):
        for p in sorted(folder.iterdir()):
            if p.suffix[1:] in out:
                out[p.suffix[1:]].append(p.read_text(encoding="utf-8"))
    return {f: tuple(v) for f, v in out.items()}


#: The valid files in the repository, by format: shipped systems and the format tests' data.
SEED_FILES = _seed_files()

#: A file the code payloads would create if any text were run as code.
MARKER = Path(tempfile.gettempdir()) / "fuzzyservo-fuzz-formats-evaluated-code"
CODE_PAYLOADS = (
    f"__import__('os').system('touch {MARKER}')",
    f"eval(\"__import__('os').system('touch {MARKER}')\")",
    f"'); __import__('os').system('touch {MARKER}'); ('",
    f"[__import__('os').system('touch {MARKER}')]",
    f"{{{{__import__('os').system('touch {MARKER}')}}}}",
)

NUMBERS = (
    "1e309", "-1e309", "1e-400", "nan", "NaN", "-nan", "+nan", "inf", "-inf", "Inf", "+Inf",
    "-Infinity", "infinity", "-0", "-0.0", "0", "0.0", "5e-324", "1e308", "1.7976931348623157e308",
    "9" * 400, "-" + "9" * 401, "1" + "0" * 30, "0x1F", "1_000", "1e", "1e+", ".", "-", "+-1",
    "1.5.2", "1..2", "--1", "\u0661", "\u00bd", "1,5", "1 2", "2.", ".5", "-.5e-3", "1E5",
    "0.1", "1", "2", "-1", "0.5", "10", "100",
)
COMMON_PIECES = (
    "\n", "\r\n", "\r", "\t", " ", "\x00", "\ufeff", "\x85", "\u2028", "\udcff", "\ud800",
    "\x1b[31m", "\u00e9", "\u65e5", "\U0001f600", "'", '"', "\\", "(", ")", "[", "]", "{", "}",
    ",", ";", ":", "=", ":=", "..", "|", "#", "%", "//", "/*", "*/", "(*", "*)",
)
KEYWORDS = {
    "fis": ("[System]", "[Input1]", "[Input2]", "[Output1]", "[Output2]", "[Rules]", "[Input0]",
            "[Input 1]", "Name=", "Name='x'", "Type='mamdani'", "Type='sugeno'", "Version=2.0",
            "NumInputs=2", "NumOutputs=1", "NumRules=1", "NumMFs=2", "MF1=", "MF2=",
            "MF3='t':'trimf',[0 1 2]", "'trimf'", "'trapmf'", "'gaussmf'", "'constant'",
            "'linear'", "'discretemf'", "'rampmf'", "'cosinemf'", "Range=[0 1]", "Range=[1 0]",
            "AndMethod='prod'", "OrMethod=''", "ImpMethod='min'", "AggMethod='sum'",
            "DefuzzMethod='wtaver'", "DefuzzMethod='centroid'", "Default=nan", "LockRange=1",
            "LockPrevious=1", "Enabled=0", "1 1, 1 (1) : 1", "0 0, 0 (1) : 2", "-1 2, -1 (0.5) : 1",
            "1.2", "(1)", ": 1", ": 3"),
    "fcl": ("FUNCTION_BLOCK", "END_FUNCTION_BLOCK", "VAR_INPUT", "VAR_OUTPUT", "END_VAR",
            "VAR", "FUZZIFY", "END_FUZZIFY", "DEFUZZIFY", "END_DEFUZZIFY", "RULEBLOCK",
            "END_RULEBLOCK", "TERM t :=", "TERM t := 1;", "RANGE := (0 .. 1);",
            "RANGE := (1 .. 0);", "METHOD : COG;", "METHOD : COGS;", "METHOD : COGSS;",
            "METHOD : COA;", "METHOD : NONE;", "DEFAULT := nan;", "DEFAULT := NC;",
            "LOCK : RANGE;", "LOCK : PREVIOUS;", "ACCU : MAX;", "ACCU : NSUM;", "AND : PROD;",
            "OR : ASUM;", "ACT : MIN;", "ENABLED : FALSE;", "RULE 1 : IF", "IF", "THEN", "IS",
            "NOT", "AND", "OR", "WITH", "x : REAL;", "x : INT;", "Constant 1", "Linear 1 2 3",
            "Discrete 0 0 1 1", "TRIAN 0 1 2", "GBELL 1 2 0", "(0, 0) (1, 1)", "(0, 1)",
            "very", "x IS t", "x IS NOT t", "NOT (x IS t)", "y IS u", "x", "t"),
    "fll": ("Engine:", "Engine: e", "InputVariable:", "InputVariable: x", "OutputVariable:",
            "OutputVariable: y", "RuleBlock:", "RuleBlock: r", "range:", "range: 0 1",
            "range: 1 0", "term:", "term: t Triangle 0 1 2", "term: t Constant 1",
            "term: t Linear 1 2", "term: t Discrete 0 0 1 1 0.5", "term: t Binary 0 inf",
            "term: t Spike 0 1", "rule:", "rule: if x is t then y is t", "if", "then", "is",
            "not", "and", "or", "with", "very", "enabled: false", "enabled: true",
            "lock-range: true", "lock-previous: true", "aggregation: none",
            "aggregation: Maximum", "defuzzifier: Centroid 100",
            "defuzzifier: WeightedAverage TakagiSugeno", "defuzzifier: WeightedSum Tsukamoto",
            "default: nan", "conjunction: none", "disjunction: AlgebraicSum",
            "implication: none", "activation: Highest", "description: x", "x", "t", "y"),
}
#: Nesting that a recursive reader must bound.
DEEP = ("(" * 201, "(" * 5000, ")" * 300, "not " * 201, "NOT " * 201, "NOT (" * 250,
        "[" * 300, "if " * 100)


def number_spans(text: str) -> list[tuple[int, int]]:
    """Spans of the numbers in ``text``."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c.isdigit() or (c in "-+." and i + 1 < n and text[i + 1].isdigit()):
            j = i + 1
            while j < n and (text[j].isdigit() or text[j] in ".eE" or (
                    text[j] in "+-" and text[j - 1] in "eE")):
                j += 1
            if i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_"):
                out.append((i, j))
            i = j
        else:
            i += 1
    return out


def name_spans(text: str) -> list[tuple[int, int]]:
    """Spans of the words (names, keywords) in ``text``."""
    out = []
    i, n = 0, len(text)
    while i < n:
        if text[i].isalpha() or text[i] == "_":
            j = i + 1
            while j < n and (text[j].isalnum() or text[j] in "_."):
                j += 1
            out.append((i, j))
            i = j
        else:
            i += 1
    return out


def piece(r: Rand, fmt: str) -> str:
    """Something to insert."""
    k = r.integer(0, 9)
    if k <= 3:
        return choice(r, KEYWORDS[fmt])
    if k <= 5:
        return choice(r, NUMBERS)
    if k <= 7:
        return choice(r, COMMON_PIECES)
    if k == 8:
        return choice(r, DEEP) if chance(r, 0.7) else choice(r, CODE_PAYLOADS)
    return choice(r, TRICKY_NAMES)


def mutate(r: Rand, text: str, fmt: str) -> str:
    """One to four random edits of ``text`` (one half the time)."""
    for _ in range(choice(r, (1, 1, 1, 1, 2, 2, 3, 4))):
        op = r.integer(0, 13)
        n = len(text)
        at = r.integer(0, n)
        if op <= 2:  # lines: delete, duplicate, swap
            lines = text.split("\n")
            i, j = r.integer(0, len(lines) - 1), r.integer(0, len(lines) - 1)
            if op == 0:
                del lines[i]
            elif op == 1:
                lines.insert(j, lines[i])
            else:
                lines[i], lines[j] = lines[j], lines[i]
            text = "\n".join(lines)
        elif op <= 4:  # insert a piece
            p = piece(r, fmt)
            sep = choice(r, ("", " ", "\n"))
            text = text[:at] + sep + p + sep + text[at:]
        elif op <= 6:  # a number replaced by a special number, or by a name
            spans = number_spans(text)
            if spans:
                a, b = choice(r, spans)
                new = choice(r, NUMBERS) if op == 5 else choice(r, (*TRICKY_NAMES, "x", "t"))
                text = text[:a] + new + text[b:]
        elif op == 7:  # a name replaced
            spans = name_spans(text)
            if spans:
                a, b = choice(r, spans)
                new = choice(r, (*TRICKY_NAMES, *KEYWORDS[fmt])) if chance(r, 0.8) else \
                    text[a:b].swapcase()
                text = text[:a] + new + text[b:]
        elif op == 8:  # delete a span
            text = text[:at] + text[min(n, at + r.integer(1, 40)):]
        elif op == 9:  # duplicate a span
            b = min(n, at + r.integer(1, 200))
            k = r.integer(0, n)
            text = text[:k] + text[at:b] + text[k:]
        elif op == 10:  # truncate
            text = text[:at]
        elif op == 11:  # line ends and byte-order mark
            k = r.integer(0, 4)
            text = (text.replace("\n", "\r\n"), text.replace("\n", "\r"), "\ufeff" + text,
                    text.rstrip("\n"), text + "\n\n\n")[k]
        elif op == 12:  # a random character
            text = text[:at] + chr(r.integer(0, 0x2FFF)) + text[at:]
        else:  # deep nesting at a random place
            text = text[:at] + choice(r, DEEP) + text[at:]
    return text


def garbage(r: Rand) -> str:
    """Random text, or random bytes decoded as a reader of files would."""
    n = r.integer(0, 300)
    k = r.integer(0, 3)
    if k == 0:
        return "".join(chr(r.integer(0, 0x10FFFF)) for _ in range(n))
    if k == 1:
        alphabet = "".join(dict.fromkeys(" \n[]()=:;,.'#%-+0123456789eEinfa" + "".join(
            KEYWORDS[choice(r, FORMATS)])))
        return "".join(choice(r, alphabet) for _ in range(n))
    data = bytes(r.integer(0, 255) for _ in range(n))
    how = r.integer(0, 3)
    if how == 0:  # as fuzzyservo.formats.io.read_system decodes a file
        try:
            return data.decode("utf-8")
        except UnicodeDecodeError:
            return data.decode("latin-1")
    if how == 1:
        return data.decode("utf-16-le", errors="replace")
    return data.decode("utf-8", errors=choice(r, ("replace", "surrogateescape", "ignore")))


def system_text(r: Rand, fmt: str) -> str:
    """A random system written as ``fmt`` (a seed file when the writer refuses it)."""
    s = random_system(r, choice(r, (None, fmt, fmt)))
    try:
        return dumps(s, fmt)
    except ParameterError:
        return choice(r, SEED_FILES[fmt])


def random_text(r: Rand, fmt: str, extra_seeds: Sequence[str] = ()) -> str:
    """A text for the ``fmt`` reader: mostly a mutated valid file."""
    k = r.integer(0, 19)
    if k <= 1:
        return garbage(r)
    seeds = (*SEED_FILES[fmt], *extra_seeds)
    base = system_text(r, fmt) if k <= 7 else choice(r, seeds)
    if k == 19:
        return base  # unchanged: a valid file must be read
    return mutate(r, base, fmt)


# ------------------------------------------------------------------------------ hypothesis


def _composite(make: Callable[[Rand], T]) -> st.SearchStrategy[T]:
    @st.composite
    def strategy(draw: st.DrawFn) -> T:
        return make(DrawRand(draw))

    return strategy()


def systems(fit: str | None = None) -> st.SearchStrategy[FuzzySystem]:
    """Random valid systems (see :func:`random_system`)."""
    return _composite(lambda r: random_system(r, fit))


def points(s: FuzzySystem) -> st.SearchStrategy[np.ndarray]:
    """Points inside the inputs' ranges (see :func:`sample_points`)."""
    return _composite(lambda r: sample_points(r, s))


def texts(fmt: str) -> st.SearchStrategy[str]:
    """Texts for the ``fmt`` reader (see :func:`random_text`)."""
    return _composite(lambda r: random_text(r, fmt))


# ------------------------------------------------------------------------------ checks


class Broken(Exception):
    """A property does not hold: ``kind`` says which, ``detail`` shows it."""

    def __init__(self, kind: str, detail: str) -> None:
        super().__init__(f"{kind}: {detail}")
        self.kind, self.detail = kind, detail


def _lines_of(text: str) -> list[str]:
    """The lines as the readers count them (BOM dropped, CRLF and CR read as LF)."""
    if text.startswith("\ufeff"):
        text = text[1:]
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def check_format_error(exc: FormatError, text: str, source: str) -> None:
    """The error is exactly a FormatError, on one line ``source:LINE:COL: message``, located
    inside the text."""
    msg = str(exc)
    if type(exc) is not FormatError:
        raise Broken("a subclass of FormatError", f"{type(exc).__name__}: {msg}")
    if len(msg.splitlines()) != 1 or "\n" in msg or "\r" in msg:
        raise Broken("message over several lines", repr(msg))
    m = re.match(rf"{re.escape(source)}:(\d+):(\d+): \S.*\Z", msg, re.DOTALL)
    if m is None:
        raise Broken("message not 'file:line:col: what'", repr(msg))
    line, col = int(m.group(1)), int(m.group(2))
    lines = _lines_of(text)
    if not 1 <= line <= len(lines) + 1:
        raise Broken("line outside the text", f"{msg!r} ({len(lines)} lines)")
    if line <= len(lines) and not 1 <= col <= len(lines[line - 1]) + 1:
        raise Broken("column outside the line",
                     f"{msg!r} (line {line} has {len(lines[line - 1])} characters)")


def check_parse(text: str, fmt: str) -> FuzzySystem | None:
    """``loads``: a system, or None after a FormatError that passes
    :func:`check_format_error`; any other exception propagates."""
    source = f"f.{fmt}"
    try:
        return loads(text, fmt, source)
    except FormatError as exc:
        check_format_error(exc, text, source)
        return None


def _difference(a: FuzzySystem, b: FuzzySystem) -> str:
    """The first field where two systems differ, for messages."""
    for f in ("name", "kind", "and_op", "or_op", "implication", "aggregation", "defuzzifier"):
        if getattr(a, f) != getattr(b, f):
            return f"{f}: {getattr(a, f)!r} != {getattr(b, f)!r}"
    for what in ("inputs", "outputs"):
        va, vb = getattr(a, what), getattr(b, what)
        if len(va) != len(vb):
            return f"{what}: {len(va)} != {len(vb)}"
        for x, y in zip(va, vb, strict=True):
            if x != y:
                return f"{what}: {x!r} != {y!r}"
    if len(a.rules) != len(b.rules):
        return f"rules: {len(a.rules)} != {len(b.rules)}"
    for k, (x, y) in enumerate(zip(a.rules, b.rules, strict=True), start=1):
        if x != y:
            return f"rule {k}: {x!r} != {y!r}"
    return "no difference found"


def check_round_trip(s: FuzzySystem, fmt: str) -> str | None:
    """``dumps(s, fmt)`` refuses with a one-line ParameterError that names the format (None
    is returned), or its text reads back to :func:`expected_after` and writes again to the
    same text (the text is returned)."""
    try:
        text = dumps(s, fmt)
    except ParameterError as exc:
        msg = str(exc)
        if len(msg.splitlines()) != 1 or fmt not in msg.lower():
            raise Broken("refusal not one line naming the format", repr(msg)) from None
        return None
    try:
        back = loads(text, fmt, f"w.{fmt}")
    except FormatError as exc:
        raise Broken("the writer's text is refused by its reader", f"{exc}\n{text}") from None
    want = expected_after(fmt, s)
    if back != want:
        raise Broken("read back differs", f"{_difference(want, back)}\n{text}")
    again = dumps(back, fmt)
    if again != text:
        raise Broken("written again differs", f"{text}\n---\n{again}")
    return text


def sample_points(r: Rand, s: FuzzySystem, n: int = 4) -> np.ndarray:
    """``n`` points inside the inputs' ranges (their ends, grid points, arbitrary ones)."""
    return np.array([[between(v.range[0], v.range[1], choice(r, (
        0.0, 1.0, 0.5, 0.25, r.unit()))) for v in s.inputs] for _ in range(n)])


def sugeno_bound(s: FuzzySystem, j: int, x: np.ndarray) -> float:
    """A bound of |output j| of a Sugeno system at the point ``x``: each rule adds at most
    the largest |c0| + sum |ci xi| of the output's terms (weights and strengths are <= 1,
    and a weighted average is at most the largest value)."""
    largest = 0.0
    for t in s.outputs[j].terms:
        c = t.params
        z = abs(c[-1]) + (sum(abs(ci) * abs(float(xi)) for ci, xi in zip(c[:-1], x, strict=True))
                          if t.shape == "linear" else 0.0)
        largest = max(largest, z)
    count = sum(1 for r in s.rules for c in r.consequents if c.variable == j)
    return largest * max(count, 1)


def check_evaluate(s: FuzzySystem, x: np.ndarray) -> None:
    """``evaluate`` gives finite outputs, NaN only for an output whose default is NaN; a
    Sugeno output may be infinite only where its exact value may exceed the largest float
    (:func:`sugeno_bound`; a linear term of an input near 1e308 can)."""
    y = evaluate(s, x)
    for j, v in enumerate(s.outputs):
        col = y[:, j].copy()
        if s.kind == "sugeno":
            for i in range(len(col)):
                if np.isinf(col[i]) and not sugeno_bound(s, j, x[i]) < 1.7e308:
                    col[i] = 0.0  # the exact value may overflow
        if np.isinf(col).any() or (np.isnan(col).any() and not math.isnan(v.default)):
            raise Broken("evaluate: not finite", f"output {v.name!r} (default {v.default!r}) "
                         f"at {x.tolist()}: {col.tolist()}")


class EvalWorker:
    """:func:`check_evaluate` in a child process, so that a crash of the compiled evaluator
    (an abort, a segmentation fault, or a hang: a corrupted heap can deadlock in ``free``
    instead of aborting) is a reported failure and not the end of the fuzzer.
    A :class:`Broken` or any exception in the child is raised here as :class:`Broken`
    (kind ``evaluate: <exception type>``, detail: the child's traceback)."""

    def __init__(self, timeout: float = 20.0) -> None:
        self.timeout = timeout
        # load the compiled evaluator here, once: every child (a new one after a crash) is
        # forked with it
        x = Variable("x", (0.0, 1.0), (Term("a", "triangle", (0.0, 0.5, 1.0)),))
        evaluate(FuzzySystem(inputs=(x,), outputs=(Variable("y", x.range, x.terms),),
                             rules=(Rule(Is(0, 0), (Consequent(0, 0),)),)), [[0.25]])
        self._start()

    def _start(self) -> None:
        ctx = mp.get_context("fork")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, args=(child,), daemon=True)
        self.proc.start()
        child.close()

    def _restart(self) -> int | None:
        self.proc.kill()
        self.proc.join()
        code = self.proc.exitcode
        self.conn.close()
        self._start()
        return code

    def close(self) -> None:
        """Stop the child."""
        self.proc.kill()
        self.proc.join()
        self.conn.close()

    def __call__(self, s: FuzzySystem, x: np.ndarray) -> None:
        try:
            self.conn.send((s, x))
            if not self.conn.poll(self.timeout):
                self._restart()
                raise Broken("evaluate: no answer", f"{self.timeout} s at {x.tolist()}")
            status, kind, detail = self.conn.recv()
        except (EOFError, BrokenPipeError, ConnectionResetError):
            self.proc.join(5.0)
            code = self.proc.exitcode
            self._restart()
            raise Broken("evaluate: the process died", f"exit code {code} at {x.tolist()}"
                         ) from None
        if status != "ok":
            raise Broken(kind, detail)


def _serve(conn: Connection) -> None:
    import traceback

    with np.errstate(all="ignore"):
        while True:
            try:
                s, x = conn.recv()
            except EOFError:
                return
            try:
                check_evaluate(s, x)
                conn.send(("ok", "", ""))
            except Broken as exc:
                conn.send(("broken", exc.kind, exc.detail))
            except Exception as exc:  # noqa: BLE001 - every exception is reported
                frames = traceback.extract_tb(exc.__traceback__)
                where = f"{Path(frames[-1].filename).name}:{frames[-1].lineno}" if frames else "?"
                conn.send(("error", f"evaluate: {type(exc).__name__} at {where}",
                           "".join(traceback.format_exception(exc))))


#: Audit events that run code or start a process.
_RUN_EVENTS = frozenset({"os.system", "os.exec", "os.posix_spawn", "os.spawn", "os.fork",
                         "os.forkpty", "subprocess.Popen", "ctypes.dlopen", "builtins.input"})


class CodeWatch:
    """A ``sys.audit`` hook (installed once per process) that records, between
    :meth:`start` and :meth:`stop`, every ``compile`` and ``exec`` of code that does not come
    from a ``.py`` file (an import compiles and runs its module's file; ``eval`` of a text
    does not) and every process start; :meth:`stop` raises :class:`Broken` if there was any.
    """

    _installed: CodeWatch | None = None

    def __new__(cls) -> CodeWatch:
        if cls._installed is None:
            watch = super().__new__(cls)
            watch.on = False
            watch.events = []
            sys.addaudithook(watch._hook)
            cls._installed = watch
        return cls._installed

    on: bool
    events: list[str]

    def _hook(self, event: str, args: tuple[object, ...]) -> None:
        if not self.on:
            return
        if event == "compile":
            filename = args[1] if len(args) > 1 else None
            if not (isinstance(filename, str) and filename.endswith(".py")):
                self.events.append(f"compile {filename!r}")
        elif event == "exec":
            code = args[0] if args else None
            filename = getattr(code, "co_filename", None)
            if not (isinstance(filename, str) and filename.endswith(".py")):
                self.events.append(f"exec {filename!r}")
        elif event in _RUN_EVENTS:
            self.events.append(event)

    def start(self) -> None:
        """Start recording."""
        self.events = []
        self.on = True

    def stop(self) -> None:
        """Stop recording; Broken if code was run."""
        self.on = False
        if self.events:
            raise Broken("code was run", ", ".join(sorted(set(self.events))))
