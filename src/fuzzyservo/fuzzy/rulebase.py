"""Linguistic variables and rule bases (from a table, as the paper prints them, or from text)."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._typing import IntArray
from ..errors import ParameterError
from .membership import MembershipFunction, Triangle

__all__ = ["LinguisticVariable", "Rule", "RuleBase"]

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


@dataclass(frozen=True, slots=True, kw_only=True)
class LinguisticVariable:
    """A named variable over a universe, covered by labelled membership functions.

    Parameters
    ----------
    name : str
        Identifier used in rule text (letters, digits, underscore).
    universe : tuple of float
        (lo, hi) with lo < hi, both finite [unit of the variable]. Inputs are clipped to it and
        the output set is integrated over it only.
    terms : tuple of (str, MembershipFunction)
        Labels and their MFs, in order (the order of a rule table's rows or columns).
    """

    name: str  #: identifier used in rule text
    universe: tuple[float, float]  #: (lo, hi) [unit of the variable]
    terms: tuple[tuple[str, MembershipFunction], ...]  #: ordered (label, MF) pairs

    def __post_init__(self) -> None:
        if not _NAME.match(self.name):
            raise ParameterError(
                f"variable name {self.name!r} is not allowed: use letters, digits and _"
            )
        lo, hi = self.universe
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo >= hi:
            raise ParameterError(
                f"universe of {self.name!r} must be finite with lo < hi, got ({lo!r}, {hi!r})"
            )
        if not self.terms:
            raise ParameterError(f"variable {self.name!r} needs at least one term")
        labels = [label for label, _ in self.terms]
        for label, mf in self.terms:
            if not _NAME.match(label):
                raise ParameterError(
                    f"label {label!r} of {self.name!r} is not allowed: use letters, digits and _"
                )
            if not isinstance(mf, MembershipFunction):
                raise ParameterError(
                    f"term {label!r} of {self.name!r} is not a membership function"
                )
        dup = sorted({x for x in labels if labels.count(x) > 1})
        if dup:
            raise ParameterError(f"variable {self.name!r} repeats labels {dup}")

    @classmethod
    def uniform(
        cls, name: str, universe: tuple[float, float], labels: Sequence[str]
    ) -> LinguisticVariable:
        """Uniform triangles with 50 % overlap, peaks at lo + k (hi - lo) / (n - 1).

        The end triangles peak at the universe ends; their outer halves lie outside the universe
        and are cut by it (clipped inputs, output integrated over the universe only), so they
        act as shoulders.

        Parameters
        ----------
        name : str
            Variable name.
        universe : tuple of float
            (lo, hi) [unit of the variable].
        labels : sequence of str
            At least two labels, from lo to hi.
        """
        lo, hi = float(universe[0]), float(universe[1])
        if len(labels) < 2:
            raise ParameterError(f"a uniform partition needs >= 2 labels, got {len(labels)}")
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo >= hi:
            raise ParameterError(
                f"universe of {name!r} must be finite with lo < hi, got ({lo!r}, {hi!r})"
            )
        n = len(labels)
        d = (hi - lo) / (n - 1)
        # one list of peaks, shared by neighbouring triangles as their feet, so that a foot
        # and the neighbour's peak are the same float; weighted means keep a symmetric
        # universe's peaks symmetric (-1/3 and 1/3, and 0 exactly)
        peaks = [(lo * (n - 1 - k) + hi * k) / (n - 1) for k in range(n)]
        peaks[-1] = hi
        ext = [lo - d, *peaks, hi + d]
        terms = tuple(
            (label, Triangle(a=ext[k], b=ext[k + 1], c=ext[k + 2]))
            for k, label in enumerate(labels)
        )
        return cls(name=name, universe=(lo, hi), terms=terms)

    @property
    def labels(self) -> tuple[str, ...]:
        """The labels, in order."""
        return tuple(label for label, _ in self.terms)

    def index(self, label: str) -> int:
        """Position of ``label``; raises ``ParameterError`` naming the allowed labels."""
        for i, (name, _) in enumerate(self.terms):
            if name == label:
                return i
        raise ParameterError(
            f"unknown label {label!r} for {self.name!r}; allowed: {', '.join(self.labels)}"
        )

    def is_uniform_triangles(self) -> bool:
        """True if the terms are exactly the partition :meth:`uniform` builds (to 1e-12)."""
        n = len(self.terms)
        if n < 2:
            return False
        lo, hi = self.universe
        d = (hi - lo) / (n - 1)
        tol = 1e-12 * (hi - lo)  # rounding of k * d
        for k, (_, mf) in enumerate(self.terms):
            if not isinstance(mf, Triangle):
                return False
            p = lo + k * d
            if abs(mf.b - p) > tol or abs(mf.a - (p - d)) > tol or abs(mf.c - (p + d)) > tol:
                return False
        return True


@dataclass(frozen=True, slots=True, kw_only=True)
class Rule:
    """``if x1 is A and x2 is B then y is C``, by term indices.

    Parameters
    ----------
    antecedent : tuple of int
        One term index per input, or -1 where the rule does not mention that input.
    consequent : int
        Term index of the output.
    """

    antecedent: tuple[int, ...]  #: term index per input, -1 = not mentioned
    consequent: int  #: output term index


@dataclass(frozen=True, slots=True, kw_only=True)
class RuleBase:
    """Rules over given input variables and one output variable.

    Build it with :meth:`from_table` or :meth:`from_text`.
    """

    inputs: tuple[LinguisticVariable, ...]  #: input variables, in evaluation order
    output: LinguisticVariable  #: output variable
    rules: tuple[Rule, ...]  #: the rules

    def __post_init__(self) -> None:
        if not self.rules:
            raise ParameterError("a rule base needs at least one rule")
        for rule in self.rules:
            if len(rule.antecedent) != len(self.inputs):
                raise ParameterError(
                    f"rule {rule} names {len(rule.antecedent)} inputs, need {len(self.inputs)}"
                )
            if all(i < 0 for i in rule.antecedent):
                raise ParameterError(f"rule {rule} mentions no input")
            for var, i in zip(self.inputs, rule.antecedent, strict=True):
                if not -1 <= i < len(var.terms):
                    raise ParameterError(
                        f"rule {rule}: term index {i} of {var.name!r} outside "
                        f"-1..{len(var.terms) - 1}"
                    )
            if not 0 <= rule.consequent < len(self.output.terms):
                raise ParameterError(
                    f"rule {rule}: output index {rule.consequent} outside "
                    f"0..{len(self.output.terms) - 1}"
                )

    @classmethod
    def from_table(
        cls,
        table: Sequence[Sequence[str | None]],
        *,
        columns: LinguisticVariable,
        rows: LinguisticVariable,
        output: LinguisticVariable,
    ) -> RuleBase:
        """Rules from a table ``table[row][column]`` of output labels (None or "-": no rule).

        The paper prints rows Δe and columns e, both ordered NB .. PB; the inputs are then
        ``(columns, rows)`` = (e, Δe).

        Parameters
        ----------
        table : sequence of sequences of str or None
            ``len(rows.terms)`` rows of ``len(columns.terms)`` labels each.
        columns : LinguisticVariable
            First input (the table's columns).
        rows : LinguisticVariable
            Second input (the table's rows).
        output : LinguisticVariable
            Output variable whose labels the cells name.
        """
        nr, nc = len(rows.terms), len(columns.terms)
        if len(table) != nr or any(len(row) != nc for row in table):
            shape = f"{len(table)} rows of lengths {[len(r) for r in table]}"
            raise ParameterError(
                f"rule table must have {nr} rows ({rows.name}) of {nc} cells ({columns.name}), "
                f"got {shape}"
            )
        rules = []
        for i2, row in enumerate(table):
            for i1, cell in enumerate(row):
                if cell is None or cell == "-":
                    continue
                rules.append(Rule(antecedent=(i1, i2), consequent=output.index(cell)))
        return cls(inputs=(columns, rows), output=output, rules=tuple(rules))

    @classmethod
    def from_text(
        cls, text: str, *, inputs: Sequence[LinguisticVariable], output: LinguisticVariable
    ) -> RuleBase:
        """Rules from lines like ``if e is NB and de is PS then du is NM``.

        Blank lines and lines starting with ``#`` are ignored; keywords are case-insensitive,
        names and labels are case-sensitive.

        Parameters
        ----------
        text : str
            One rule per line.
        inputs : sequence of LinguisticVariable
            The input variables, in evaluation order.
        output : LinguisticVariable
            The output variable.
        """
        by_name = {v.name: k for k, v in enumerate(inputs)}
        pattern = re.compile(r"^\s*if\s+(?P<ante>.+?)\s+then\s+(?P<out>.+?)\s*$", re.IGNORECASE)
        clause = re.compile(r"^\s*(\w+)\s+is\s+(\w+)\s*$", re.IGNORECASE)
        rules = []
        for lineno, line in enumerate(text.splitlines(), start=1):
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            m = pattern.match(line)
            if m is None:
                raise ParameterError(
                    f"rule line {lineno} {line.strip()!r} is not "
                    "'if X is A [and Y is B] then Z is C'"
                )
            ante = [-1] * len(inputs)
            for part in re.split(r"\s+and\s+", m.group("ante"), flags=re.IGNORECASE):
                c = clause.match(part)
                if c is None:
                    raise ParameterError(f"rule line {lineno}: cannot read clause {part.strip()!r}")
                name, label = c.group(1), c.group(2)
                if name not in by_name:
                    raise ParameterError(
                        f"rule line {lineno}: unknown input {name!r}; allowed: {', '.join(by_name)}"
                    )
                k = by_name[name]
                if ante[k] >= 0:
                    raise ParameterError(f"rule line {lineno}: input {name!r} named twice")
                try:
                    ante[k] = inputs[k].index(label)
                except ParameterError as exc:
                    raise ParameterError(f"rule line {lineno}: {exc}") from None
            c = clause.match(m.group("out"))
            if c is None or c.group(1) != output.name:
                raise ParameterError(
                    f"rule line {lineno}: consequent must read '{output.name} is LABEL', "
                    f"got {m.group('out')!r}"
                )
            try:
                cons = output.index(c.group(2))
            except ParameterError as exc:
                raise ParameterError(f"rule line {lineno}: {exc}") from None
            rules.append(Rule(antecedent=tuple(ante), consequent=cons))
        return cls(inputs=tuple(inputs), output=output, rules=tuple(rules))

    def as_table(self) -> IntArray:
        """Two-input rule bases as ``table[i2, i1]`` = output index (-1 = no rule).

        Raises ``ParameterError`` if there are not two inputs, a rule leaves an input out, or
        two rules share an antecedent.
        """
        if len(self.inputs) != 2:
            raise ParameterError(
                f"a rule table needs 2 inputs, this rule base has {len(self.inputs)}"
            )
        n1, n2 = len(self.inputs[0].terms), len(self.inputs[1].terms)
        table = np.full((n2, n1), -1, dtype=np.int64)
        for rule in self.rules:
            i1, i2 = rule.antecedent
            if i1 < 0 or i2 < 0:
                raise ParameterError(f"rule {rule} does not name both inputs: not a table")
            if table[i2, i1] >= 0:
                raise ParameterError(f"two rules share the antecedent ({i1}, {i2}): not a table")
            table[i2, i1] = rule.consequent
        return table
