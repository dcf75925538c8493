"""Shared helpers of the file readers and writers: locations and one-line errors, numbers,
and the rule text FLL and FCL share."""

from __future__ import annotations

import math
from collections.abc import Callable

from ..errors import FormatError
from ..fuzzy.system import And, Expr, FuzzySystem, Is, Not, Rule

__all__ = ["MAX_POINTS", "Source", "clause_text", "fmt_float", "fuzzylite_rule", "parse_float"]

#: Most points of one piecewise-linear term (an FCL point list, a Discrete term, a .fis
#: ``discretemf``): fuzzylite's FLL reader's bound of 1024 numbers a term (fll.MAX_NUMBERS), so
#: every format reads the same systems. Far above hand-drawn terms; a term of 200,000 points
#: made every evaluation of the system take minutes.
MAX_POINTS = 512


class Source:
    """A file's text with its name, turning character offsets into ``file:line:col`` errors.

    Parameters
    ----------
    text : str
        The whole file (a leading byte-order mark is dropped; CRLF and CR line ends are read
        as LF, so columns count characters of the line without its end).
    name : str
        The file name shown in messages.
    """

    def __init__(self, text: str, name: str) -> None:
        if text.startswith("\ufeff"):
            text = text[1:]
        self.text = text.replace("\r\n", "\n").replace("\r", "\n")
        self.name = name
        self._starts = [0]
        for i, ch in enumerate(self.text):
            if ch == "\n":
                self._starts.append(i + 1)

    def where(self, offset: int) -> tuple[int, int]:
        """(line, column), both from 1, of a character offset."""
        import bisect

        offset = max(0, min(offset, len(self.text)))
        line = bisect.bisect_right(self._starts, offset) - 1
        return line + 1, offset - self._starts[line] + 1

    def error(self, offset: int, message: str) -> FormatError:
        """A FormatError ``name:line:col: message`` (message kept on one line)."""
        line, col = self.where(offset)
        one = " ".join(message.split())
        return FormatError(f"{self.name}:{line}:{col}: {one}")

    def error_at(self, line: int, col: int, message: str) -> FormatError:
        """A FormatError at a known line and column (both from 1)."""
        one = " ".join(message.split())
        return FormatError(f"{self.name}:{line}:{col}: {one}")


def parse_float(token: str) -> float | None:
    """A decimal number (also ``inf``, ``-inf``, ``Inf``, ``nan``, case-insensitive), or None.

    Never evaluates anything: only ``float()`` of a token of digits, signs, ``.``, ``e`` and
    the words inf / infinity / nan is tried.
    """
    t = token.strip()
    if not t or len(t) > 400:
        return None
    low = t.lower().lstrip("+-")
    if low not in ("inf", "infinity", "nan") and not all(c in "0123456789.eE+-" for c in t):
        return None
    try:
        return float(t)
    except ValueError:
        return None


def fmt_float(x: float) -> str:
    """The shortest text that reads back to exactly ``x`` (``repr``), inf as ``inf``/``-inf``,
    NaN as ``nan``; integers without a trailing ``.0``."""
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == int(x) and abs(x) < 1e15:
        return str(int(x)) if x != 0 or math.copysign(1.0, x) > 0 else "-0.0"
    return repr(x)


def clause_text(system: FuzzySystem, e: Is, nots: int = 0) -> str:
    """A clause as fuzzylite writes it: ``input is term``, with ``not`` before the term once
    for a negated clause and once for each of ``nots`` enclosing NOTs."""
    v = system.inputs[e.variable]
    return f"{v.name} is {'not ' * (nots + e.negated)}{v.terms[e.term].name}"


def fuzzylite_rule(system: FuzzySystem, rule: Rule, negation: Callable[[Not], str]) -> str:
    """A rule in the grammar FLL's ``rule:`` and FCL's ``RULE k :`` share (fuzzylite reads
    both alike): ``if A then C``, then ``with w`` when the weight is not 1.

    A joins the operands of AND and OR by ``and`` / ``or``, an operand that is itself AND or
    OR in parentheses, clauses by :func:`clause_text`; ``negation`` writes a NOT (or raises
    ParameterError naming what the format cannot hold), each format by its own rule. C is
    ``output is term`` per consequent, joined by ``and``.
    """

    def expr(e: Expr, top: bool) -> str:
        if isinstance(e, Is):
            return clause_text(system, e)
        if isinstance(e, Not):
            return negation(e)
        word = " and " if isinstance(e, And) else " or "
        body = word.join(expr(op, False) for op in e.operands)
        return body if top else f"({body})"

    ante = expr(rule.antecedent, True)
    cons = " and ".join(
        f"{system.outputs[c.variable].name} is "
        f"{system.outputs[c.variable].terms[c.term].name}" for c in rule.consequents)
    weight = "" if rule.weight == 1.0 else f" with {fmt_float(rule.weight)}"
    return f"if {ante} then {cons}{weight}"
