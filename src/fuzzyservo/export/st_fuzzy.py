"""Structured Text port of the exact uniform-grid fuzzy evaluator.

A line-by-line port of the C port (``csrc/fuzzy.c``: ``fs_grid_cell``, ``fs_grid_centroid``,
``fs_segment_integrals``, ``fs_height``, ``fs_grid_pair``) of the compiled Python evaluator
(:func:`fuzzyservo.fuzzy.kernels.eval_uniform_grid` and ``eval_uniform_pair``): two inputs on
uniform triangular partitions, min AND, min implication, max aggregation and the exact
centroid, integrated in closed form (no sampling). The same operations in the same order,
so in LREAL the results are the Python's bit for bit, and in REAL the C export's float code's.

The code is written inline into the function block (no FUNCTION with array arguments, which
the dialects declare differently), once per evaluation site, on the block's ``FZ_*``
variables; each system's table is a ``VAR CONSTANT`` pair: ``<ROLE>_RULES``, an ``ARRAY[0..n2
- 1, 0..n1 - 1] OF DINT`` of output label indices (-1: no rule; rows x2, columns x1), and
``<ROLE>_LIMS``, an ``ARRAY[0..7]`` of the input universes, the output universe, the number of
output labels and the no-rule value (the breakpoints of the uniform partitions: peaks at
``lo + k (hi - lo)/(n - 1)``).

Only this form is written: the systems of every registered controller and of the shipped
.fis/.fcl/.fll files have it. A general system (other shapes, operators or defuzzifiers) is
refused (:class:`~fuzzyservo.errors.ParameterError`); docs/export-st.md says why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import ParameterError
from ..fuzzy.kernels import LIMS_SIZE
from ._st import StReal, st_literal, st_typed

__all__ = ["GridSystem", "grid_system", "st_eval", "st_tables", "st_temps"]

_INT_VARS = ("FZ_K1", "FZ_K2", "FZ_LA", "FZ_LB", "FZ_LC", "FZ_LD", "FZ_LMIN", "FZ_LMAX",
             "FZ_J", "FZ_JEND", "FZ_JJ")
_REAL_VARS = ("FZ_IN1", "FZ_IN2", "FZ_X1", "FZ_X2", "FZ_T1", "FZ_T2", "FZ_F1", "FZ_F2",
              "FZ_G1", "FZ_G2", "FZ_WA", "FZ_WB", "FZ_WC", "FZ_WD", "FZ_H1", "FZ_H2", "FZ_H3",
              "FZ_H4", "FZ_HA", "FZ_HB", "FZ_M", "FZ_TM", "FZ_AR", "FZ_MO", "FZ_AREA", "FZ_PAREA",
              "FZ_MOMENT")


@dataclass(frozen=True, slots=True)
class GridSystem:
    """One two-input system on uniform triangles, as the ST writes it.

    Attributes
    ----------
    prefix : str
        Its tables' prefix (``DU``, ``ALPHA``).
    rules : int ndarray (n2, n1)
        Output label per cell corner, -1 for no rule.
    lims : float ndarray (8,)
        lo1, hi1, lo2, hi2, out_lo, out_hi, n_out, no-rule value.
    """

    prefix: str
    rules: IntArray
    lims: FloatArray

    @property
    def n2(self) -> int:
        return int(self.rules.shape[0])

    @property
    def n1(self) -> int:
        return int(self.rules.shape[1])

    @property
    def n_out(self) -> int:
        return int(self.lims[6])

    @property
    def complete(self) -> bool:
        """Every cell corner names a label (some rule always fires: the no-rule value is
        never returned)."""
        return bool(np.all(self.rules >= 0))


def grid_system(prefix: str, rules: IntArray, lims: FloatArray) -> GridSystem:
    """Check a controller's system in kernel form and name it.

    Raises
    ------
    ParameterError
        A packed general system (refused: see the module docstring), or a table the
        evaluator does not take.
    """
    r = np.asarray(rules)
    m = np.asarray(lims, dtype=np.float64)
    if r.ndim != 2 or r.shape[0] == 1:
        raise ParameterError(
            f"the {prefix.lower()} system is a general fuzzy system (evaluated by the general "
            f"exact evaluator): the Structured Text export writes systems of two inputs on "
            f"uniform triangular partitions with a complete or partial rule table, min/min/"
            f"max and centroid (the paper's form, and that of every shipped .fis/.fcl/.fll "
            f"file); export it with 'export c' or 'export fmu', or give such a system")
    if min(r.shape) < 2 or m.shape != (LIMS_SIZE,):
        raise ParameterError(f"{prefix.lower()} system: a rule table needs rules (n2, n1 >= "
                             f"2) and {LIMS_SIZE} lims, got {r.shape}, {m.shape}")
    if not np.all(np.isfinite(m[:7])) or not (m[0] < m[1] and m[2] < m[3] and m[4] < m[5]):
        raise ParameterError(f"{prefix.lower()} system: universes need finite lo < hi, got "
                             f"{m[:6].tolist()}")
    n_out = m[6]
    if not (n_out == int(n_out) and 2 <= n_out <= 2**31 - 1):
        raise ParameterError(f"{prefix.lower()} system: lims[6] (output labels) must be an "
                             f"integer >= 2, got {n_out!r}")
    if np.any((r < -1) | (r >= int(n_out))):
        raise ParameterError(f"{prefix.lower()} system: rules must be -1 or 0..{int(n_out) - 1}")
    return GridSystem(prefix=prefix, rules=r.astype(np.int64), lims=m)


def st_temps(real: StReal) -> list[str]:
    """Declarations of the evaluator's working variables (``FZ_*``)."""
    return [", ".join(_INT_VARS) + " : DINT;", ", ".join(_REAL_VARS) + f" : {real};"]


def st_tables(g: GridSystem, real: StReal) -> list[str]:
    """``VAR CONSTANT`` declarations of ``g``'s tables.

    Raises
    ------
    ParameterError
        A limit REAL cannot hold, or a NaN no-rule value with an incomplete table (ST has no
        NaN literal).
    """
    rows = [", ".join(str(int(v)) for v in row) for row in g.rules]
    body = ",\n        ".join(rows)
    lims = [float(v) for v in g.lims]
    note = ""
    if math.isnan(lims[7]):
        if not g.complete:
            raise ParameterError(
                f"{g.prefix.lower()} system: its no-rule value is NaN, which Structured Text "
                f"cannot write, and its rule table has empty cells; give a number "
                f"(--no-rule-value)")
        lims[7] = 0.0
        note = " (no-rule value NaN written as 0.0: never used, the table is complete)"
    vals = ", ".join(st_literal(v, real, f"{g.prefix}_LIMS[{i}]") for i, v in enumerate(lims))
    return [
        f"(* {g.prefix.lower()} system: {g.n2} x {g.n1} rule table on uniform triangles; "
        f"rows: input 2 (x2), columns: input 1 (x1); output label 0..{g.n_out - 1}, -1 no rule *)",
        f"{g.prefix}_RULES : ARRAY[0..{g.n2 - 1}, 0..{g.n1 - 1}] OF DINT := [\n        "
        f"{body}];",
        f"(* input 1 universe lo, hi; input 2 lo, hi; output lo, hi; output labels; no-rule "
        f"value{note} *)",
        f"{g.prefix}_LIMS : ARRAY[0..7] OF {real} := [{vals}];",
    ]


def _cell(g: GridSystem, real: StReal, ind: str) -> list[str]:
    p = g.prefix
    n1m1, n2m1 = st_typed(g.n1 - 1, real), st_typed(g.n2 - 1, real)
    return [
        f"{ind}(* clip the inputs and locate them: cell (FZ_K1, FZ_K2), fractions (FZ_F1, "
        f"FZ_F2) *)",
        f"{ind}FZ_X1 := FZ_IN1;",
        f"{ind}FZ_X2 := FZ_IN2;",
        f"{ind}IF FZ_X1 < {p}_LIMS[0] THEN",
        f"{ind}    FZ_X1 := {p}_LIMS[0];",
        f"{ind}ELSIF FZ_X1 > {p}_LIMS[1] THEN",
        f"{ind}    FZ_X1 := {p}_LIMS[1];",
        f"{ind}END_IF;",
        f"{ind}IF FZ_X2 < {p}_LIMS[2] THEN",
        f"{ind}    FZ_X2 := {p}_LIMS[2];",
        f"{ind}ELSIF FZ_X2 > {p}_LIMS[3] THEN",
        f"{ind}    FZ_X2 := {p}_LIMS[3];",
        f"{ind}END_IF;",
        f"{ind}FZ_T1 := (FZ_X1 - {p}_LIMS[0]) / ({p}_LIMS[1] - {p}_LIMS[0]) * {n1m1};",
        f"{ind}FZ_T2 := (FZ_X2 - {p}_LIMS[2]) / ({p}_LIMS[3] - {p}_LIMS[2]) * {n2m1};",
        f"{ind}FZ_K1 := TRUNC(FZ_T1); (* FZ_T1 >= 0: toward zero is down *)",
        f"{ind}IF FZ_K1 > {g.n1 - 2} THEN",
        f"{ind}    FZ_K1 := {g.n1 - 2};",
        f"{ind}END_IF;",
        f"{ind}FZ_K2 := TRUNC(FZ_T2);",
        f"{ind}IF FZ_K2 > {g.n2 - 2} THEN",
        f"{ind}    FZ_K2 := {g.n2 - 2};",
        f"{ind}END_IF;",
        f"{ind}FZ_F1 := FZ_T1 - DINT_TO_{real}(FZ_K1);",
        f"{ind}FZ_F2 := FZ_T2 - DINT_TO_{real}(FZ_K2);",
    ]


def _min(out: str, a: str, b: str, ind: str) -> list[str]:
    # fs_min(a, b) = b < a ? b : a (Python's min on two floats)
    return [f"{ind}{out} := {a};", f"{ind}IF {b} < {out} THEN", f"{ind}    {out} := {b};",
            f"{ind}END_IF;"]


def _height(j: str, out: str, zero: str, ind: str) -> list[str]:
    # fs_height: max(max(la == j ? wa : 0, lb == j ? wb : 0), max(lc == j ? wc : 0, ...)),
    # fs_max(a, b) = b > a ? b : a
    lines = [f"{ind}FZ_JJ := {j};"]
    for h, lab, w in (("FZ_H1", "FZ_LA", "FZ_WA"), ("FZ_H2", "FZ_LB", "FZ_WB"),
                      ("FZ_H3", "FZ_LC", "FZ_WC"), ("FZ_H4", "FZ_LD", "FZ_WD")):
        lines += [f"{ind}{h} := {zero};", f"{ind}IF {lab} = FZ_JJ THEN",
                  f"{ind}    {h} := {w};", f"{ind}END_IF;"]
    for a, b in (("FZ_H1", "FZ_H2"), ("FZ_H3", "FZ_H4"), ("FZ_H1", "FZ_H3")):
        lines += [f"{ind}IF {b} > {a} THEN", f"{ind}    {a} := {b};", f"{ind}END_IF;"]
    lines.append(f"{ind}{out} := FZ_H1;")
    return lines


def _centroid(g: GridSystem, out: str, real: StReal, ind: str) -> list[str]:
    p = g.prefix
    zero, one, half, six = (st_typed(v, real) for v in (0.0, 1.0, 0.5, 6.0))
    i2 = ind + "    "
    i3 = i2 + "    "
    lines = [
        f"{ind}(* the (at most) four rules of the cell, with their min-AND strengths *)",
        f"{ind}FZ_G1 := {one} - FZ_F1;",
        f"{ind}FZ_G2 := {one} - FZ_F2;",
        f"{ind}FZ_LA := {p}_RULES[FZ_K2, FZ_K1];",
        f"{ind}FZ_LB := {p}_RULES[FZ_K2, FZ_K1 + 1];",
        f"{ind}FZ_LC := {p}_RULES[FZ_K2 + 1, FZ_K1];",
        f"{ind}FZ_LD := {p}_RULES[FZ_K2 + 1, FZ_K1 + 1];",
        *_min("FZ_WA", "FZ_G1", "FZ_G2", ind),
        *_min("FZ_WB", "FZ_F1", "FZ_G2", ind),
        *_min("FZ_WC", "FZ_G1", "FZ_F2", ind),
        *_min("FZ_WD", "FZ_F1", "FZ_F2", ind),
    ]
    for lab, w in (("FZ_LA", "FZ_WA"), ("FZ_LB", "FZ_WB"), ("FZ_LC", "FZ_WC"),
                   ("FZ_LD", "FZ_WD")):
        lines += [f"{ind}IF {lab} < 0 THEN", f"{ind}    {w} := {zero};", f"{ind}END_IF;"]
    lines += [
        f"{ind}(* the fired labels span FZ_LMIN .. FZ_LMAX: integrate the segments between "
        f"adjacent output peaks from FZ_LMIN - 1 to FZ_LMAX *)",
        f"{ind}FZ_LMIN := {g.n_out};",
        f"{ind}FZ_LMAX := -1;",
    ]
    for lab, w in (("FZ_LA", "FZ_WA"), ("FZ_LB", "FZ_WB"), ("FZ_LC", "FZ_WC"),
                   ("FZ_LD", "FZ_WD")):
        lines += [f"{ind}IF {w} > {zero} THEN",
                  f"{i2}IF {lab} < FZ_LMIN THEN", f"{i3}FZ_LMIN := {lab};", f"{i2}END_IF;",
                  f"{i2}IF {lab} > FZ_LMAX THEN", f"{i3}FZ_LMAX := {lab};", f"{i2}END_IF;",
                  f"{ind}END_IF;"]
    lines += [
        f"{ind}FZ_J := FZ_LMIN - 1;",
        f"{ind}IF 0 > FZ_J THEN",
        f"{ind}    FZ_J := 0;",
        f"{ind}END_IF;",
        f"{ind}FZ_JEND := FZ_LMAX;",
        f"{ind}IF {g.n_out - 2} < FZ_JEND THEN",
        f"{ind}    FZ_JEND := {g.n_out - 2};",
        f"{ind}END_IF;",
        f"{ind}FZ_AREA := {zero};",
        f"{ind}FZ_PAREA := {zero};",
        f"{ind}FZ_MOMENT := {zero};",
        *_height("FZ_J", "FZ_HA", zero, ind),
        f"{ind}WHILE FZ_J <= FZ_JEND DO",
        *_height("FZ_J + 1", "FZ_HB", zero, i2),
        f"{i2}IF FZ_HA > {zero} OR FZ_HB > {zero} THEN",
        f"{i3}(* area and first moment over s in [0, 1] of max(min(a, 1 - s), min(b, s)) *)",
        *_min("FZ_M", "FZ_HA", "FZ_HB", i3),
        f"{i3}IF {half} < FZ_M THEN",
        f"{i3}    FZ_M := {half};",
        f"{i3}END_IF;",
        f"{i3}FZ_TM := FZ_M - FZ_M * FZ_M;",
        f"{i3}FZ_AR := FZ_HA - {half} * FZ_HA * FZ_HA + FZ_HB - {half} * FZ_HB * FZ_HB - FZ_TM;",
        f"{i3}FZ_MO := {half} * (FZ_HA - FZ_HA * FZ_HA + FZ_HB - FZ_TM) + (FZ_HA * FZ_HA * "
        f"FZ_HA - FZ_HB * FZ_HB * FZ_HB) * ({one} / {six});",
        f"{i3}FZ_AREA := FZ_AREA + FZ_AR;",
        f"{i3}FZ_PAREA := FZ_PAREA + DINT_TO_{real}(FZ_J) * FZ_AR;",
        f"{i3}FZ_MOMENT := FZ_MOMENT + FZ_MO;",
        f"{i2}END_IF;",
        f"{i2}FZ_HA := FZ_HB;",
        f"{i2}FZ_J := FZ_J + 1;",
        f"{ind}END_WHILE;",
        f"{ind}IF FZ_AREA <= {zero} THEN",
        f"{ind}    {out} := {p}_LIMS[7]; (* no rule fired *)",
        f"{ind}ELSE",
        f"{ind}    {out} := {p}_LIMS[4] + ({p}_LIMS[5] - {p}_LIMS[4]) * (FZ_PAREA + FZ_MOMENT) "
        f"/ (FZ_AREA * {st_typed(g.n_out - 1, real)});",
        f"{ind}END_IF;",
    ]
    return lines


def _same_grid(a: GridSystem, b: GridSystem) -> bool:
    return (a.n1 == b.n1 and a.n2 == b.n2
            and all(float(a.lims[i]) == float(b.lims[i]) for i in range(4)))


def st_eval(systems: list[GridSystem], x1: str, x2: str, outs: list[str], real: StReal,
            ind: str = "") -> list[str]:
    """Statements evaluating ``systems`` (one, or the pair du and alpha, located once when
    their grids are the same, as ``eval_uniform_pair``) at the inputs ``x1``, ``x2`` (ST
    expressions of the block's variables) into the variables ``outs``; a NaN input gives
    NaN."""
    if len(systems) != len(outs) or not 1 <= len(systems) <= 2:
        raise ParameterError("an evaluation writes one system or a pair")
    i2 = ind + "    "
    lines = [f"{ind}FZ_IN1 := {x1};", f"{ind}FZ_IN2 := {x2};",
             f"{ind}IF FZ_IN1 <> FZ_IN1 OR FZ_IN2 <> FZ_IN2 THEN (* a NaN input: NaN *)"]
    lines += [f"{i2}{o} := FZ_IN1 + FZ_IN2;" for o in outs]
    lines.append(f"{ind}ELSE")
    prev: GridSystem | None = None
    for g, o in zip(systems, outs, strict=True):
        if prev is None or not _same_grid(prev, g):
            lines += _cell(g, real, i2)
        lines += _centroid(g, o, real, i2)
        prev = g
    lines.append(f"{ind}END_IF;")
    return lines
