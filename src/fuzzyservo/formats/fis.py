"""MATLAB Fuzzy Logic Toolbox ``.fis`` files: reader (:func:`parse`) and writer (:func:`dump`).

The format: a ``[System]`` section (``Name``, ``Type``, ``Version``, ``NumInputs``,
``NumOutputs``, ``NumRules``, ``AndMethod``, ``OrMethod``, ``ImpMethod``, ``AggMethod``,
``DefuzzMethod``), one ``[InputK]`` / ``[OutputK]`` section per variable (``Name``, ``Range``,
``NumMFs``, ``MF1='name':'trimf',[a b c]`` ...) and ``[Rules]``, one rule a line:
``1 -2, 3 0 (0.5) : 1`` lists a term index per input (0: the input is not used, negative: NOT),
then a term index per output (0: the rule says nothing about that output), the weight in
parentheses and the connection (1: AND, 2: OR).

Reading
-------
- With or without a ``Version=`` line; spaces around ``=`` and ``:`` (old files); values quoted
  with ``'`` or bare; comments from ``%`` or ``#`` (outside quotes) to the end of the line;
  byte-order mark and CRLF. Sections may come in any order; each must appear once.
- Membership functions and their order in the model (:data:`~fuzzyservo.fuzzy.shapes.SHAPES`):
  ``trimf [a b c]`` triangle, ``trapmf [a b c d]`` trapezoid (``-inf`` / ``inf`` feet read as
  shoulders), ``gaussmf [sigma c]`` gaussian (c, sigma), ``gauss2mf [s1 c1 s2 c2]`` gaussian2
  (c1, s1, c2, s2), ``gbellmf [a b c]`` bell (c, a, b), ``sigmf [a c]`` sigmoid (c, a),
  ``dsigmf [a1 c1 a2 c2]`` dsigmoid (c1, a1, a2, c2), ``psigmf [a1 c1 a2 c2]`` psigmoid
  (c1, a1, a2, c2), ``pimf``, ``smf``, ``zmf`` as is, Sugeno ``constant [z]`` and
  ``linear [c1 .. cn c0]``; and three that only fuzzylite writes: ``rampmf [start end]``,
  ``rectmf [start end]``, ``discretemf [x1 y1 x2 y2 ...]`` (for these, fuzzylite's meaning of
  one value more, the term's height, is kept). Refused by name: fuzzylite's ``concavemf``,
  ``cosinemf``, ``spikemf``, ``binarymf``, ``function``, and any other name.
- MATLAB's ``dsigmf`` is the plain difference of the two sigmoids; the model (like fuzzylite)
  takes its absolute value. They differ only where the second sigmoid exceeds the first
  (nowhere for equal slopes a1 = a2 > 0 and c1 < c2).
- A MATLAB membership function given more values than it takes (old files write
  ``trimf [-10 0 10 0]``) is read as MATLAB does, from the first ones (``trimf`` uses
  ``params(1:3)``); the ignored values are named in ``FuzzySystem.notes``. fuzzylite instead
  reads one extra value as the term's height, and gets height 0 for the example.
- Operators: AndMethod ``min``/``prod``, OrMethod ``max``/``probor``, ImpMethod ``min``/``prod``
  (``prod`` is the model's ``product``), AggMethod ``max``/``sum`` (MATLAB's unbounded sum, the
  model's ``sum``)/``probor`` and fuzzylite's ``bounded_sum``, DefuzzMethod ``centroid``,
  ``bisector``, ``mom``, ``som``, ``lom`` (Mamdani), ``wtaver``, ``wtsum`` (Sugeno). An empty
  ``AndMethod``/``OrMethod`` (some fuzzylite files) is read as ``min``/``max`` with a note when
  no rule needs it, and refused when one does. Type ``mamdani`` or ``sugeno``; fuzzylite's
  ``hybrid`` and ``tsukamoto`` are refused.
- When no rule fires for an output, MATLAB returns the middle of the output's range; a .fis
  file cannot say otherwise, so every output's ``default`` is (lo + hi) / 2.
- MATLAB clips inputs to their range, so every input has ``clip=True``. A Mamdani output's
  value lies in its range anyway (``clip=True``); MATLAB does not clamp a Sugeno output (a
  weighted average of linear functions may leave the range), so Sugeno outputs have
  ``clip=False``.
- fuzzylite's older .fis files add ``Enabled=1`` (any variable) and ``Default=``,
  ``LockRange=0|1``, ``LockPrevious=0`` (outputs); they are read (``Default`` and
  ``LockRange`` set the output's ``default`` and ``clip``). ``Enabled=0`` and
  ``LockPrevious=1`` are refused; MATLAB's ``DisableStructuralChecks`` is ignored.
- Names: MATLAB allows any text; the model allows a letter or ``_`` then letters, digits,
  ``_`` and ``.``. Other characters become ``_`` (``'LDL-Level'`` -> ``LDL_Level``), an empty
  name becomes ``fuzzy`` / ``inputK`` / ``outputK`` / ``mfK``; each change is noted. Two names
  that end up equal are refused.
- Sizes: at most :data:`MAX_VARIABLES` inputs and as many outputs, :data:`MAX_TERMS` terms a
  variable, :data:`~fuzzyservo.formats._text.MAX_POINTS` points a ``discretemf``; nothing else
  is bounded but the text (there is no nesting to recurse into).
- Rules: a term index with a fraction (``1.2``: a hedge for fuzzylite and Octave) is refused; a
  rule that mentions no input, or no output, is refused (fuzzylite writes such rules for rules
  that chain outputs, which .fis cannot hold), and so is a negative output index (NOT on an
  output).

Writing
-------
MATLAB's layout with ``Version=2.0``, one rule a line, numbers as the shortest text that reads
back exactly (:func:`~fuzzyservo.formats._text.fmt_float`), so ``parse(dump(s)) == s``. The
writer writes only what MATLAB reads: ``ParameterError`` names anything else:

- term shapes ``ramp``, ``rectangle``, ``discrete`` (fuzzylite's ``rampmf`` etc. are not
  MATLAB's) and ``singleton``; a term height other than 1;
- aggregation ``bounded_sum``;
- an input with ``clip=False`` or a default other than NaN (an input has none in a .fis file);
  a Mamdani output with ``clip=False``; a Sugeno output with
  ``clip=True`` (MATLAB does not clamp it);
- an output default other than the middle of its range (NaN included);
- an antecedent other than one clause or a flat AND / OR of clauses (``Is``, negated or not,
  or ``Not(Is)``) over distinct inputs; a rule with two consequents on one output.

Trapezoid shoulders are written with ``-inf`` / ``inf`` feet: fuzzylite 6 and Octave's
fuzzy-logic-toolkit 0.4.6 read and evaluate them right (checked); MATLAB was not available to
check (its classic ``trapmf.m`` computes NaN for the infinite side's ratio, which ``min``
skips). Octave 0.4.6 reads the files written here, but refuses vertical edges (it needs
a < b < c for ``trimf`` and a < b for ``trapmf``), which MATLAB and fuzzylite accept.

A .fis rule has one column per input and one per output, so a rule whose clauses (or
consequents) are in another order is written, and reads back, in input (output) order, and
``Not(Is(...))`` reads back as ``Is(..., negated=True)``: the same values (AND and OR are
symmetric; with ``product`` or ``probor`` over three or more clauses the last bit of a firing
strength may differ), so ``parse(dump(s)) == s`` holds for rules already in that form.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

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
from ._text import MAX_POINTS, Source, fmt_float, parse_float

__all__ = ["MAX_TERMS", "MAX_VARIABLES", "dump", "parse"]

#: Most inputs (and most outputs) a file may declare: far above any published system.
MAX_VARIABLES = 1000
#: Most terms of one variable: above the largest clustered (ANFIS) systems, and low enough
#: that the model's checks of a variable stay fast.
MAX_TERMS = 10_000

#: MATLAB name -> (model shape, number of values or None for variable, permutation: model
#: parameter i is file value ``perm[i]``; None: same order), from the shape table.
_MF: dict[str, tuple[str, int | None, tuple[int, ...] | None]] = {
    s.fis: (s.name, None if s.params is None else len(s.params), s.fis_order)
    for s in SHAPE_TABLE if s.fis is not None}
#: Membership functions only fuzzylite defines: read with fuzzylite's meaning, never written.
_FUZZYLITE_ONLY = tuple(s.fis for s in SHAPE_TABLE if s.fis is not None and not s.fis_written)
_WRITE_MF = {shape: name for name, (shape, _, _) in _MF.items() if name not in _FUZZYLITE_ONLY}

_KIND: dict[str, Kind] = {"mamdani": "mamdani", "sugeno": "sugeno"}
_AND: dict[str, AndOp] = {"min": "min", "prod": "product"}
_OR: dict[str, OrOp] = {"max": "max", "probor": "probor"}
_IMP: dict[str, ImplicationOp] = {"min": "min", "prod": "product"}
_AGG: dict[str, AggregationOp] = {"max": "max", "sum": "sum", "probor": "probor",
                                  "bounded_sum": "bounded_sum"}
_DEFUZZ: dict[str, DefuzzifierName] = {
    "centroid": "centroid", "bisector": "bisector", "mom": "mom", "som": "som", "lom": "lom",
    "wtaver": "wtaver", "wtsum": "wtsum"}
_AND_NAME = {v: k for k, v in _AND.items()}
_OR_NAME = {v: k for k, v in _OR.items()}
_IMP_NAME = {v: k for k, v in _IMP.items()}
_AGG_NAME = {v: k for k, v in _AGG.items()}
_MAMDANI_DEFUZZ = ("centroid", "bisector", "mom", "som", "lom")
_SUGENO_DEFUZZ = ("wtaver", "wtsum")

_SYSTEM_KEYS = ("Name", "Type", "Version", "NumInputs", "NumOutputs", "NumRules", "AndMethod",
                "OrMethod", "ImpMethod", "AggMethod", "DefuzzMethod", "DisableStructuralChecks")
_VAR_KEYS = ("Name", "Range", "NumMFs", "MFk", "Enabled")
_OUT_KEYS = ("Default", "LockRange", "LockPrevious")
_HEDGES = {0.01: "seldom", 0.05: "somewhat", 0.2: "very", 0.3: "extremely", 0.4: "very very",
           0.99: "any"}

_HEADER = re.compile(r"\[\s*([A-Za-z]+)\s*(\d*)\s*\]")
_KEYVAL = re.compile(r"([A-Za-z][A-Za-z0-9_]*)\s*=\s*")
_MFKEY = re.compile(r"MF(\d{1,9})")
_INT = re.compile(r"\+?\d{1,9}")
_VALID = re.compile(r"[A-Za-z_][A-Za-z0-9_.]*")
_INVALID_CHAR = re.compile(r"[^A-Za-z0-9_.]")
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:inf|Inf|INF|nan|NaN)")


# --------------------------------------------------------------------------- reading


@dataclass
class _Entry:
    """One ``key=value`` line: the value text and offsets of the key and the value."""

    key: str
    value: str
    key_off: int
    val_off: int


@dataclass
class _Section:
    """A section: its kind ("System", "Input", "Output", "Rules"), number, header offset,
    key lines (in order and by key) and, for [Rules], the rule lines with their offsets."""

    kind: str
    number: int
    off: int
    entries: list[_Entry] = field(default_factory=list)
    keys: dict[str, _Entry] = field(default_factory=dict)
    lines: list[tuple[str, int]] = field(default_factory=list)


def _strip_comment(line: str) -> str:
    """The line up to the first ``%`` or ``#`` outside single quotes."""
    quoted = False
    for i, ch in enumerate(line):
        if ch == "'":
            quoted = not quoted
        elif not quoted and ch in "%#":
            return line[:i]
    return line


class _Reader:
    """Turns the text of a .fis file into a FuzzySystem (one instance per file)."""

    def __init__(self, text: str, name: str) -> None:
        self.src = Source(text, name)
        self.notes: list[str] = []

    def err(self, off: int, msg: str) -> FormatError:
        return self.src.error(off, msg)

    # ---- lexing -------------------------------------------------------------------------

    def sections(self) -> list[_Section]:
        out: list[_Section] = []
        pos = 0
        for raw in self.src.text.split("\n"):
            start = pos
            pos += len(raw) + 1
            body = _strip_comment(raw)
            stripped = body.strip()
            if not stripped:
                continue
            off = start + len(body) - len(body.lstrip())
            if stripped.startswith("["):
                out.append(self.header(stripped, off))
                continue
            if not out:
                raise self.err(off, f"expected a section header such as [System], found "
                                    f"{stripped[:40]!r}")
            sec = out[-1]
            if sec.kind == "Rules":
                sec.lines.append((stripped, off))
                continue
            m = _KEYVAL.match(stripped)
            if m is None:
                raise self.err(off, f"expected KEY=VALUE in [{sec.kind}"
                                    f"{sec.number or ''}], found {stripped[:40]!r}")
            key = m.group(1)
            if key in sec.keys:
                raise self.err(off, f"repeated key {key} (first given on line "
                                    f"{self.src.where(sec.keys[key].key_off)[0]})")
            entry = _Entry(key, stripped[m.end():], off, off + m.end())
            sec.entries.append(entry)
            sec.keys[key] = entry
        return out

    def header(self, text: str, off: int) -> _Section:
        if "]" not in text:
            raise self.err(off + len(text), "expected ']' closing the section header")
        m = _HEADER.fullmatch(text)
        if m is None:
            end = text.index("]") + 1
            if _HEADER.fullmatch(text[:end]):
                raise self.err(off + end, f"unexpected text after the section header: "
                                          f"{text[end:][:40]!r}")
            raise self.err(off, f"unsupported section: {text[:40]} (supported: [System], "
                                f"[InputK], [OutputK], [Rules])")
        kind, num = m.group(1), m.group(2)
        numbered = kind in ("Input", "Output")
        if kind not in ("System", "Input", "Output", "Rules") or numbered != bool(num):
            raise self.err(off, f"unsupported section: {text} (supported: [System], "
                                f"[InputK], [OutputK], [Rules])")
        number = int(num) if num else 0
        if numbered and number < 1:
            raise self.err(off, f"section numbers start at 1, found {text}")
        return _Section(kind, number, off)

    # ---- values -------------------------------------------------------------------------

    def string(self, e: _Entry) -> str:
        v = e.value.strip()
        if v.startswith("'"):
            if len(v) < 2 or not v.endswith("'") or "'" in v[1:-1]:
                raise self.err(e.val_off, f"{e.key}: expected one quoted text like 'name', "
                                          f"found {v[:40]!r}")
            return v[1:-1]
        if not v or any(c.isspace() or c == "'" for c in v):
            raise self.err(e.val_off, f"{e.key}: expected a quoted text like 'name', found "
                                      f"{v[:40]!r}")
        return v

    def integer(self, e: _Entry) -> int:
        v = e.value.strip()
        if not _INT.fullmatch(v):
            raise self.err(e.val_off, f"{e.key}: expected a whole number, found {v[:40]!r}")
        return int(v)

    def number(self, e: _Entry) -> float:
        v = e.value.strip()
        x = parse_float(v)
        if x is None:
            raise self.err(e.val_off, f"{e.key}: expected a number, found {v[:40]!r}")
        return x

    def vector(self, text: str, off: int, what: str) -> tuple[list[float], int]:
        """Numbers in ``[...]`` at the start of ``text`` (after blanks), separated by blanks
        or commas; returns them and the index just after ``]``."""
        i = len(text) - len(text.lstrip())
        if i >= len(text) or text[i] != "[":
            raise self.err(off + i, f"{what}: expected '[' opening a list of numbers, found "
                                    f"{text[i:][:40]!r}")
        close = text.find("]", i)
        if close < 0:
            raise self.err(off + len(text), f"{what}: expected ']' closing the list of "
                                            f"numbers")
        values: list[float] = []
        for m in re.finditer(r"[^\s,]+", text[i + 1:close]):
            x = parse_float(m.group())
            if x is None:
                raise self.err(off + i + 1 + m.start(), f"{what}: expected a number, found "
                                                        f"{m.group()[:40]!r}")
            values.append(x)
        return values, close + 1

    def name(self, raw: str, fallback: str, what: str) -> str:
        if _VALID.fullmatch(raw):
            return raw
        new = _INVALID_CHAR.sub("_", raw) if raw else fallback
        if not _VALID.fullmatch(new):
            new = "_" + new
        self.notes.append(f"{what} name {raw!r} read as {new!r} (names are a letter or _ then "
                          f"letters, digits, _ or .)")
        return new

    # ---- sections -----------------------------------------------------------------------

    def parse(self) -> FuzzySystem:
        secs = self.sections()
        system = [s for s in secs if s.kind == "System"]
        if not system:
            raise self.err(len(self.src.text), "missing section [System]")
        if len(system) > 1:
            raise self.err(system[1].off, "repeated section [System]")
        sys_sec = system[0]
        keys = sys_sec.keys
        for e in sys_sec.entries:
            if e.key not in _SYSTEM_KEYS:
                raise self.err(e.key_off, f"unsupported key in [System]: {e.key} "
                                          f"(supported: {', '.join(_SYSTEM_KEYS)})")

        def need(key: str) -> _Entry:
            if key not in keys:
                raise self.err(sys_sec.off, f"[System] needs {key}=...")
            return keys[key]

        kind_text = self.string(need("Type"))
        if kind_text not in _KIND:
            raise self.err(keys["Type"].val_off, f"unsupported Type: {kind_text} (supported: "
                                                 f"mamdani, sugeno)")
        n_in_e, n_out_e = need("NumInputs"), need("NumOutputs")
        n_in, n_out = self.integer(n_in_e), self.integer(n_out_e)
        if n_in < 1 or n_out < 1:
            bad = n_in_e if n_in < 1 else n_out_e
            raise self.err(bad.val_off, f"{bad.key}: a fuzzy system needs at least one")
        for e, n in ((n_in_e, n_in), (n_out_e, n_out)):
            if n > MAX_VARIABLES:
                raise self.err(e.val_off, f"unsupported {e.key}={n} (supported: at most "
                                          f"{MAX_VARIABLES})")
        methods: dict[str, str] = {}
        for key, table in (("AndMethod", _AND), ("OrMethod", _OR), ("ImpMethod", _IMP),
                           ("AggMethod", _AGG), ("DefuzzMethod", _DEFUZZ)):
            e = need(key)
            text = self.string(e)
            if text not in table and not (text == "" and key in ("AndMethod", "OrMethod")):
                raise self.err(e.val_off, f"unsupported {key}: {text or 'empty'} "
                                          f"(supported: {', '.join(table)})")
            methods[key] = text
        defuzz = _DEFUZZ[methods["DefuzzMethod"]]
        allowed = _MAMDANI_DEFUZZ if kind_text == "mamdani" else _SUGENO_DEFUZZ
        if defuzz not in allowed:
            raise self.err(keys["DefuzzMethod"].val_off,
                           f"a {kind_text} system defuzzifies by {', '.join(allowed)}, found "
                           f"{defuzz}")
        if "Version" in keys:
            self.number(keys["Version"])
        if "DisableStructuralChecks" in keys:
            self.integer(keys["DisableStructuralChecks"])
        sys_name = self.name(self.string(keys["Name"]), "fuzzy", "system") \
            if "Name" in keys else "fuzzy"

        inputs = self.variables(secs, "Input", n_in, n_in_e, kind_text, n_in)
        outputs = self.variables(secs, "Output", n_out, n_out_e, kind_text, n_in)
        self.check_var_names(inputs + outputs)

        rules_secs = [s for s in secs if s.kind == "Rules"]
        if not rules_secs:
            raise self.err(len(self.src.text), "missing section [Rules]")
        if len(rules_secs) > 1:
            raise self.err(rules_secs[1].off, "repeated section [Rules]")
        ins = [v for v, _ in inputs]
        outs = [v for v, _ in outputs]
        rules = [self.rule(text, off, ins, outs, methods) for text, off in rules_secs[0].lines]
        if "NumRules" in keys:
            n_rules = self.integer(keys["NumRules"])
            if n_rules != len(rules):
                raise self.err(keys["NumRules"].val_off,
                               f"NumRules={n_rules} but [Rules] has {len(rules)} rules")
        for key, default in (("AndMethod", "min"), ("OrMethod", "max")):
            if methods[key] == "":
                self.notes.append(f"{key} is empty; no rule needs it, read as {default}")
        try:
            return FuzzySystem(
                name=sys_name, kind=_KIND[kind_text], inputs=tuple(ins), outputs=tuple(outs),
                rules=tuple(rules), and_op=_AND.get(methods["AndMethod"], "min"),
                or_op=_OR.get(methods["OrMethod"], "max"),
                implication=_IMP[methods["ImpMethod"]], aggregation=_AGG[methods["AggMethod"]],
                defuzzifier=defuzz, notes=tuple(self.notes))
        except ParameterError as exc:
            raise self.err(sys_sec.off, str(exc)) from None

    def check_var_names(self, variables: list[tuple[Variable, _Entry]]) -> None:
        seen: dict[str, _Entry] = {}
        for v, e in variables:
            if v.name in seen:
                line = self.src.where(seen[v.name].key_off)[0]
                raise self.err(e.val_off, f"variable name {v.name!r} is already used on line "
                                          f"{line}")
            seen[v.name] = e

    def variables(self, secs: list[_Section], kind: str, count: int, count_e: _Entry,
                  sys_kind: str, n_in: int) -> list[tuple[Variable, _Entry]]:
        by_number: dict[int, _Section] = {}
        for s in secs:
            if s.kind != kind:
                continue
            if s.number > count:
                raise self.err(s.off, f"[{kind}{s.number}] but Num{kind}s={count}")
            if s.number in by_number:
                raise self.err(s.off, f"repeated section [{kind}{s.number}]")
            by_number[s.number] = s
        out = []
        for k in range(1, count + 1):
            if k not in by_number:
                raise self.err(count_e.val_off, f"Num{kind}s={count} but there is no section "
                                                f"[{kind}{k}]")
            out.append(self.variable(by_number[k], sys_kind, n_in))
        return out

    def variable(self, sec: _Section, sys_kind: str, n_in: int) -> tuple[Variable, _Entry]:
        label = f"{sec.kind.lower()} {sec.number}"
        is_out = sec.kind == "Output"
        keys: dict[str, _Entry] = {}
        mfs: dict[int, _Entry] = {}
        for e in sec.entries:
            m = _MFKEY.fullmatch(e.key)
            if m is not None:
                mfs[int(m.group(1))] = e
            elif e.key in _VAR_KEYS or (is_out and e.key in _OUT_KEYS):
                keys[e.key] = e
            else:
                supported = _VAR_KEYS + (_OUT_KEYS if is_out else ())
                raise self.err(e.key_off, f"unsupported key in [{sec.kind}{sec.number}]: "
                                          f"{e.key} (supported: {', '.join(supported)})")
        for key in ("Name", "Range", "NumMFs"):
            if key not in keys:
                raise self.err(sec.off, f"[{sec.kind}{sec.number}] needs {key}=...")
        name_e = keys["Name"]
        vname = self.name(self.string(name_e), f"{sec.kind.lower()}{sec.number}", label)
        rng, end = self.vector(keys["Range"].value, keys["Range"].val_off, "Range")
        if len(rng) != 2 or keys["Range"].value[end:].strip():
            raise self.err(keys["Range"].val_off, f"Range: expected [lo hi], found "
                                                  f"{keys['Range'].value.strip()[:40]!r}")
        n_mfs = self.integer(keys["NumMFs"])
        if n_mfs > MAX_TERMS:
            raise self.err(keys["NumMFs"].val_off, f"unsupported NumMFs={n_mfs} (supported: "
                                                   f"at most {MAX_TERMS})")
        for k, e in mfs.items():
            if not 1 <= k <= n_mfs:
                raise self.err(e.key_off, f"MF{k} but NumMFs={n_mfs}")
        terms: list[Term] = []
        term_lines: dict[str, int] = {}
        for k in range(1, n_mfs + 1):
            if k not in mfs:
                raise self.err(keys["NumMFs"].val_off, f"NumMFs={n_mfs} but there is no MF{k}")
            t = self.term(mfs[k], k, vname, is_out, sys_kind, n_in)
            if t.name in term_lines:
                raise self.err(mfs[k].val_off, f"{label} {vname!r}: term name {t.name!r} is "
                                               f"already used on line {term_lines[t.name]}")
            term_lines[t.name] = self.src.where(mfs[k].key_off)[0]
            terms.append(t)
        for key, ok in (("Enabled", 1), ("LockPrevious", 0)):
            if key in keys and self.integer(keys[key]) != ok:
                raise self.err(keys[key].val_off, f"unsupported {key}={keys[key].value.strip()}"
                                                  f" (supported: {key}={ok})")
        lo, hi = rng
        default = math.nan
        clip = True
        if is_out:
            default = _middle(lo, hi)
            clip = sys_kind == "mamdani"
            if "Default" in keys:
                default = self.number(keys["Default"])
                if math.isinf(default):
                    raise self.err(keys["Default"].val_off, "Default: expected a finite "
                                                            "number or nan")
            if "LockRange" in keys:
                lock = self.integer(keys["LockRange"])
                if lock not in (0, 1):
                    raise self.err(keys["LockRange"].val_off, "LockRange: expected 0 or 1")
                clip = lock == 1
        try:
            var = Variable(vname, (lo, hi), tuple(terms), default=default, clip=clip)
        except ParameterError as exc:
            raise self.err(keys["Range"].val_off, str(exc)) from None
        return var, name_e

    def term(self, e: _Entry, k: int, vname: str, is_out: bool, sys_kind: str,
             n_in: int) -> Term:
        text, off = e.value, e.val_off
        where = f"{'output' if is_out else 'input'} {vname!r} MF{k}"
        raw, i = self.token(text, 0, off, ":", f"{where}: term name")
        i = self.expect(text, i, off, ":", f"{where}: expected ':' after the term name")
        tstart = i + len(text[i:]) - len(text[i:].lstrip())
        mf, i = self.token(text, i, off, ",", f"{where}: membership function")
        if mf not in _MF:
            raise self.err(off + tstart, f"unsupported membership function: {mf} (supported: "
                                         f"{', '.join(_MF)})")
        i = self.expect(text, i, off, ",", f"{where}: expected ',' after the membership "
                                           f"function")
        params, end = self.vector(text[i:], off + i, where)
        if text[i + end:].strip():
            raise self.err(off + i + end, f"{where}: unexpected text after ']': "
                                          f"{text[i + end:].strip()[:40]!r}")
        tname = self.name(raw, f"mf{k}", f"{where} term")
        shape, n, perm = _MF[mf]
        height = 1.0
        sugeno_shape = shape in SUGENO
        if is_out and sys_kind == "sugeno" and not sugeno_shape:
            raise self.err(off + tstart, f"{where}: a sugeno output needs constant or linear, "
                                         f"found {mf}")
        if sugeno_shape and not (is_out and sys_kind == "sugeno"):
            raise self.err(off + tstart, f"{where}: {mf} is a sugeno output function")
        if shape == "linear" and len(params) != n_in + 1:
            raise self.err(off + i, f"{where}: linear needs {n_in + 1} values (one per input, "
                                    f"then the constant), found {len(params)}")
        if mf == "discretemf" and len(params) > 2 * MAX_POINTS + 1:
            raise self.err(off + i, f"{where}: discretemf has {len(params) // 2} points; a "
                                    f"term takes at most {MAX_POINTS}")
        if mf == "discretemf" and len(params) % 2 == 1 and len(params) > 4:
            height, params = params[-1], params[:-1]
        elif mf in ("rampmf", "rectmf") and len(params) == 3:
            height, params = params[2], params[:2]
        elif n is not None and len(params) > n and mf not in _FUZZYLITE_ONLY \
                and shape != "constant":
            extra = " ".join(fmt_float(x) for x in params[n:])
            self.notes.append(
                f"{where} term {tname!r}: {mf} takes {n} values; the extra {extra} is ignored "
                f"as MATLAB does (fuzzylite would read one extra value as the term's height)")
            params = params[:n]
        if n is not None and len(params) != n:
            raise self.err(off + i, f"{where}: {mf} takes {n} values, found {len(params)}")
        values = tuple(params) if perm is None else tuple(params[j] for j in perm)
        try:
            return Term(tname, shape, values, height)
        except ParameterError as exc:
            raise self.err(off + i, f"{where}: {exc}") from None

    def token(self, text: str, i: int, off: int, stop: str, what: str) -> tuple[str, int]:
        """A quoted or bare token at ``text[i:]`` (after blanks); returns it and the index
        after it."""
        while i < len(text) and text[i].isspace():
            i += 1
        if i < len(text) and text[i] == "'":
            close = text.find("'", i + 1)
            if close < 0:
                raise self.err(off + i, f"{what}: expected a closing '")
            return text[i + 1:close], close + 1
        j = i
        while j < len(text) and not text[j].isspace() and text[j] not in (stop, "'"):
            j += 1
        if j == i:
            raise self.err(off + i, f"{what}: expected a quoted name, found "
                                    f"{text[i:][:40]!r}")
        return text[i:j], j

    def expect(self, text: str, i: int, off: int, ch: str, msg: str) -> int:
        while i < len(text) and text[i].isspace():
            i += 1
        if i >= len(text) or text[i] != ch:
            raise self.err(off + i, f"{msg}, found {text[i:][:40]!r}")
        return i + 1

    # ---- rules --------------------------------------------------------------------------

    def rule(self, text: str, off: int, ins: list[Variable], outs: list[Variable],
             methods: dict[str, str]) -> Rule:
        toks: list[tuple[str, int]] = []
        i = 0
        while i < len(text):
            if text[i].isspace():
                i += 1
                continue
            if text[i] in ",():":
                toks.append((text[i], i))
                i += 1
                continue
            m = _NUMBER.match(text, i)
            if m is None or (m.end() < len(text) and not text[m.end()].isspace()
                             and text[m.end()] not in ",():"):
                j = i
                while j < len(text) and not text[j].isspace() and text[j] not in ",():":
                    j += 1
                raise self.err(off + i, f"rule: expected a number, found {text[i:j][:40]!r}")
            toks.append((m.group(), i))
            i = m.end()
        toks.append(("", len(text)))
        pos = 0

        def numbers() -> list[tuple[float, int]]:
            nonlocal pos
            got = []
            while toks[pos][0] not in ",():":
                tok, col = toks[pos]
                x = parse_float(tok)
                if x is None:
                    raise self.err(off + col, f"rule: expected a number, found {tok[:40]!r}")
                got.append((x, col))
                pos += 1
            return got

        def expect(sym: str, what: str) -> None:
            nonlocal pos
            tok, col = toks[pos]
            if tok != sym:
                raise self.err(off + col, f"rule: expected {what}, found "
                                          f"{tok or 'the end of the line'!r}")
            pos += 1

        ante = numbers()
        expect(",", "',' after the input indices")
        cons = numbers()
        expect("(", "'(' opening the weight")
        weight = numbers()
        if len(weight) != 1:
            col = weight[1][1] if weight else toks[pos][1]
            raise self.err(off + col, "rule: expected one weight in parentheses")
        expect(")", "')' closing the weight")
        expect(":", "':' before the connection (1: AND, 2: OR)")
        conn = numbers()
        if len(conn) != 1 or toks[pos][0] != "":
            col = conn[1][1] if len(conn) > 1 else toks[pos][1]
            raise self.err(off + col, "rule: expected one connection (1: AND, 2: OR) at the "
                                      "end of the line")
        if len(ante) != len(ins):
            raise self.err(off, f"rule: expected {len(ins)} input indices (one per input), "
                                f"found {len(ante)}")
        if len(cons) != len(outs):
            col = cons[0][1] if cons else toks[pos][1]
            raise self.err(off + col, f"rule: expected {len(outs)} output indices (one per "
                                      f"output), found {len(cons)}")
        w, wcol = weight[0]
        if not 0.0 <= w <= 1.0:
            raise self.err(off + wcol, f"rule: the weight must be in [0, 1], found {w!r}")
        c, ccol = conn[0]
        if c not in (1.0, 2.0):
            raise self.err(off + ccol, f"rule: the connection must be 1 (AND) or 2 (OR), "
                                       f"found {_num_text(c)}")
        clauses: list[Expr] = []
        for j, (x, col) in enumerate(ante):
            k = self.index(x, col, off, ins[j], "input")
            if k:
                clauses.append(Is(j, abs(k) - 1, negated=k < 0))
        consequents = []
        for j, (x, col) in enumerate(cons):
            k = self.index(x, col, off, outs[j], "output")
            if k < 0:
                raise self.err(off + col, f"rule: NOT on an output is not supported (index "
                                          f"{_num_text(x)} for output {outs[j].name!r})")
            if k:
                consequents.append(Consequent(j, k - 1))
        if not clauses:
            raise self.err(off, "rule: mentions no input (every input index is 0)")
        if not consequents:
            raise self.err(off + cons[0][1], "rule: has no consequent (every output index "
                                             "is 0)")
        antecedent: Expr
        if len(clauses) == 1:
            antecedent = clauses[0]
        else:
            key = "AndMethod" if c == 1.0 else "OrMethod"
            if methods[key] == "":
                raise self.err(off + ccol, f"rule: combines clauses with "
                                           f"{'AND' if c == 1.0 else 'OR'} but {key} is empty")
            antecedent = And(tuple(clauses)) if c == 1.0 else Or(tuple(clauses))
        return Rule(antecedent, tuple(consequents), w)

    def index(self, x: float, col: int, off: int, var: Variable, what: str) -> int:
        if not math.isfinite(x):
            raise self.err(off + col, f"rule: expected a term index of {what} {var.name!r}, "
                                      f"found {_num_text(x)}")
        if x != math.floor(x):
            frac = round(abs(x) - math.floor(abs(x)), 6)
            hedge = _HEDGES.get(frac)
            extra = f" (fuzzylite and Octave read the fraction as the hedge '{hedge}')" \
                if hedge else ""
            raise self.err(off + col, f"unsupported hedge in rule: index {_num_text(x)} of "
                                      f"{what} {var.name!r}{extra}; supported: whole term "
                                      f"indices")
        k = int(x)
        if abs(k) > len(var.terms):
            raise self.err(off + col, f"rule: term index {k} out of range for {what} "
                                      f"{var.name!r}, which has {len(var.terms)} terms")
        return k


def _num_text(x: float) -> str:
    """A rule number as text for messages."""
    return fmt_float(x)


def _middle(lo: float, hi: float) -> float:
    """The middle of [lo, hi] (MATLAB's output when no rule fires)."""
    mid = (lo + hi) / 2
    return mid if math.isfinite(mid) else lo / 2 + hi / 2


def parse(text: str, source: str = "<string>") -> FuzzySystem:
    """Read a MATLAB ``.fis`` file (decisions in the module docstring).

    Parameters
    ----------
    text : str
        The file's text.
    source : str
        The file name used in error messages.

    Returns
    -------
    FuzzySystem
        The system; ``notes`` lists anything read in a way worth knowing (renamed names,
        ignored extra values, empty methods).

    Raises
    ------
    FormatError
        ``source:line:col: message`` for a malformed file or an unsupported feature.
    """
    return _Reader(text, source).parse()


# --------------------------------------------------------------------------- writing


def _flat_rule(system: FuzzySystem, k: int, rule: Rule) -> tuple[list[int], int]:
    """Per-input signed term codes (1-based, 0 unused) and the connection (1 AND, 2 OR)."""

    def clause(e: Expr) -> tuple[int, int]:
        if isinstance(e, Is):
            return e.variable, -(e.term + 1) if e.negated else e.term + 1
        if isinstance(e, Not) and isinstance(e.operand, Is) and not e.operand.negated:
            return e.operand.variable, -(e.operand.term + 1)
        raise ParameterError(
            f".fis cannot hold rule {k} ({system.rule_text(rule)}): its antecedent must be "
            f"clauses 'input is [not] term' joined by one AND or one OR")

    conn = 1
    ops: tuple[Expr, ...]
    if isinstance(rule.antecedent, And | Or):
        ops = rule.antecedent.operands
        conn = 1 if isinstance(rule.antecedent, And) else 2
    else:
        ops = (rule.antecedent,)
    codes = [0] * len(system.inputs)
    for op in ops:
        v, code = clause(op)
        if codes[v]:
            raise ParameterError(
                f".fis cannot hold rule {k} ({system.rule_text(rule)}): it uses input "
                f"{system.inputs[v].name!r} twice (a .fis rule has one column per input)")
        codes[v] = code
    return codes, conn


def _term_line(system: FuzzySystem, var: Variable, what: str, k: int, t: Term) -> str:
    label = f"{what} {var.name!r} term {t.name!r}"
    if t.shape not in _WRITE_MF:
        hint = {"ramp": "trapezoid (start, end, end, inf)", "rectangle":
                "trapezoid (start, start, end, end)"}.get(t.shape)
        raise ParameterError(
            f"MATLAB .fis has no {t.shape} membership function ({label})"
            + (f"; the same membership is {hint}" if hint else ""))
    if t.height != 1.0:
        raise ParameterError(f".fis cannot hold term height {t.height!r} of {label}")
    mf = _WRITE_MF[t.shape]
    _, _, perm = _MF[mf]
    values = list(t.params)
    if perm is not None:
        values = [0.0] * len(perm)
        for i, j in enumerate(perm):
            values[j] = t.params[i]
    body = " ".join(fmt_float(x) for x in values)
    return f"MF{k}='{t.name}':'{mf}',[{body}]"


def _variable_lines(system: FuzzySystem, var: Variable, what: str, k: int) -> list[str]:
    lo, hi = var.range
    is_out = what == "output"
    if not is_out and not math.isnan(var.default):
        raise ParameterError(
            f".fis cannot hold the default {fmt_float(var.default)} of input {var.name!r} "
            f"(inputs have no default)")
    if not is_out and not var.clip:
        raise ParameterError(
            f".fis cannot hold input {var.name!r} with clip=False (MATLAB clips inputs to "
            f"their range; fis convert --clip-inputs clips them)")
    if is_out:
        want_clip = system.kind == "mamdani"
        if var.clip != want_clip:
            why = ("a Mamdani output always lies in its range; set clip=True" if want_clip
                   else "MATLAB does not clamp a Sugeno output to its range")
            raise ParameterError(
                f".fis cannot hold {system.kind} output {var.name!r} with clip={var.clip} "
                f"({why})")
        mid = _middle(lo, hi)
        if var.default != mid:
            raise ParameterError(
                f".fis cannot hold the default {var.default!r} of output {var.name!r}: when no "
                f"rule fires MATLAB returns the middle of the range, {mid!r} (fis convert "
                f"--no-rule-value middle sets it)")
    head = "Output" if is_out else "Input"
    lines = [f"[{head}{k}]", f"Name='{var.name}'", f"Range=[{fmt_float(lo)} {fmt_float(hi)}]",
             f"NumMFs={len(var.terms)}"]
    lines += [_term_line(system, var, what, j, t) for j, t in enumerate(var.terms, start=1)]
    return lines


def dump(system: FuzzySystem) -> str:
    """The MATLAB ``.fis`` text of ``system`` (``Version=2.0``, one rule a line).

    Parameters
    ----------
    system : FuzzySystem
        The system to write.

    Returns
    -------
    str
        The file's text; :func:`parse` reads it back to an equal system (rules with their
        clauses in input order and consequents in output order).

    Raises
    ------
    ParameterError
        Naming the first item .fis cannot hold (listed in the module docstring).
    """
    if system.aggregation == "bounded_sum":
        raise ParameterError(".fis cannot hold aggregation 'bounded_sum' (MATLAB has max, "
                             "sum, probor)")
    lines = [
        "[System]",
        f"Name='{system.name}'",
        f"Type='{system.kind}'",
        "Version=2.0",
        f"NumInputs={len(system.inputs)}",
        f"NumOutputs={len(system.outputs)}",
        f"NumRules={len(system.rules)}",
        f"AndMethod='{_AND_NAME[system.and_op]}'",
        f"OrMethod='{_OR_NAME[system.or_op]}'",
        f"ImpMethod='{_IMP_NAME[system.implication]}'",
        f"AggMethod='{_AGG_NAME[system.aggregation]}'",
        f"DefuzzMethod='{system.defuzzifier}'",
    ]
    for k, v in enumerate(system.inputs, start=1):
        lines += ["", *_variable_lines(system, v, "input", k)]
    for k, v in enumerate(system.outputs, start=1):
        lines += ["", *_variable_lines(system, v, "output", k)]
    lines += ["", "[Rules]"]
    for k, rule in enumerate(system.rules, start=1):
        codes, conn = _flat_rule(system, k, rule)
        outs = [0] * len(system.outputs)
        for c in rule.consequents:
            if outs[c.variable]:
                raise ParameterError(
                    f".fis cannot hold rule {k} ({system.rule_text(rule)}): two consequents "
                    f"for output {system.outputs[c.variable].name!r}")
            outs[c.variable] = c.term + 1
        lines.append(f"{' '.join(map(str, codes))}, {' '.join(map(str, outs))} "
                     f"({fmt_float(rule.weight)}) : {conn}")
    return "\n".join(lines) + "\n"
