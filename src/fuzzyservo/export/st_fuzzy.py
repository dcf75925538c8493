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
import re
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
        note = " (NaN in the system, written as 0.0: never used, the table is complete)"
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


# --- the partition fast path of the general evaluator ---------------------------------------

# header fields of the general evaluator's packed integers (fuzzyservo.fuzzy.general)
_H_NIN, _H_NOUT, _H_NTERMS, _H_FVARS, _H_PART, _H_PARTF = 1, 2, 3, 19, 27, 28


@dataclass(frozen=True, slots=True)
class PartitionSystem:
    """A packed general system that takes the partition fast path
    (:mod:`fuzzyservo.fuzzy.partition`): its tables as the ST writes them.

    Attributes
    ----------
    prefix : str
        Its tables' prefix (``DU``, ``ALPHA``).
    pi, pf : ndarray
        The partition tables (integers, floats; offsets relative to their starts).
    n_in, n_out, n_work, n_iwork : int
        Inputs, outputs, and the scratch sizes.
    clip : tuple of bool
        Per input, whether it is clipped to its range; ``ranges`` the ranges.
    out_range, out_clip, default : tuple, bool, float
        The first output's range, whether it is clipped to it, its no-rule value.
    """

    prefix: str
    pi: IntArray
    pf: FloatArray
    n_in: int
    n_out: int
    n_work: int
    n_iwork: int
    clip: tuple[bool, ...]
    ranges: tuple[tuple[float, float], ...]
    out_range: tuple[float, float]
    out_clip: bool
    default: float


def partition_system(prefix: str, ints: IntArray, floats: FloatArray) -> PartitionSystem:
    """Check a packed general system and take its partition tables.

    Raises
    ------
    ParameterError
        The system does not take the partition path (other shapes, operators or
        defuzzifiers), or its no-rule value is NaN where ST would have to write it.
    """
    i = np.asarray(ints).reshape(-1).astype(np.int64)
    f = np.asarray(floats, dtype=np.float64).reshape(-1)
    if i.size <= _H_PARTF or int(i[_H_PART]) < 0:
        raise ParameterError(
            f"the {prefix.lower()} system is evaluated by the general evaluator's "
            f"{'piecewise-linear, singleton, smooth or Sugeno' } path: the Structured Text "
            f"export writes two-input Mamdani systems whose rules form a table over fuzzy "
            f"partitions of triangles or trapezoids (even or uneven; min or product AND and "
            f"implication, max aggregation, centroid) and rule tables on uniform triangular "
            f"partitions (the paper's form, and that of every shipped .fis/.fcl/.fll file); "
            f"export it with 'export c' or 'export fmu', or give such a system")
    n_in, n_out = int(i[_H_NIN]), int(i[_H_NOUT])
    if n_in != 2:
        raise ParameterError(f"{prefix.lower()} system: a controller's system has two inputs, "
                             f"got {n_in}")
    fvo = int(i[_H_FVARS])
    clip = tuple(bool(f[fvo + 4 * k + 3] != 0.0) for k in range(n_in))
    ranges = tuple((float(f[fvo + 4 * k]), float(f[fvo + 4 * k + 1])) for k in range(n_in))
    fv = fvo + 4 * n_in
    default = float(f[fv + 2])
    if math.isnan(default):
        raise ParameterError(f"{prefix.lower()} system: its no-rule value is NaN, which "
                             f"Structured Text cannot write; give a number (--no-rule-value, "
                             f"or a DEFAULT in the file)")
    n_terms = int(i[_H_NTERMS])
    return PartitionSystem(
        prefix=prefix, pi=i[int(i[_H_PART]):], pf=f[int(i[_H_PARTF]):], n_in=n_in,
        n_out=n_out, n_work=n_in + n_terms + 8, n_iwork=2 * n_in + n_terms, clip=clip,
        ranges=ranges, out_range=(float(f[fv]), float(f[fv + 1])),
        out_clip=bool(f[fv + 3] != 0.0), default=default)


def st_partition_tables(g: PartitionSystem, real: StReal) -> list[str]:
    """``VAR CONSTANT`` declarations of a partition system's tables."""
    ints = [str(int(v)) for v in g.pi]
    flo = [st_literal(float(v), real, f"{g.prefix}_PF[{k}]") for k, v in enumerate(g.pf)]

    def rows(items: list[str], per: int) -> str:
        return ",\n        ".join(", ".join(items[k:k + per]) for k in range(0, len(items), per))

    return [
        f"(* {g.prefix.lower()} system: a rule table over fuzzy partitions (the general "
        f"evaluator's partition tables, fuzzyservo.fuzzy.partition; offsets into these "
        f"arrays) *)",
        f"{g.prefix}_PI : ARRAY[0..{len(ints) - 1}] OF DINT := [\n        {rows(ints, 16)}];",
        f"{g.prefix}_PF : ARRAY[0..{len(flo) - 1}] OF {real} := [\n        {rows(flo, 4)}];",
    ]


def st_partition_temps(systems: list[PartitionSystem], real: StReal) -> list[str]:
    """Declarations of the partition evaluator's working variables (``FZ_*``)."""
    n_work = max(g.n_work for g in systems)
    n_iwork = max(g.n_iwork for g in systems)
    ints = ("FZ_I", "FZ_O", "FZ_K", "FZ_POS", "FZ_BASE", "FZ_NBP", "FZ_XBOFF", "FZ_ENTF",
            "FZ_TERMSAT", "FZ_LO", "FZ_HI", "FZ_MID", "FZ_K0", "FZ_CNT", "FZ_HOFF", "FZ_NH",
            "FZ_DIG", "FZ_TOTAL", "FZ_COMBO", "FZ_CELL", "FZ_P0", "FZ_D", "FZ_CE", "FZ_ST",
            "FZ_Q", "FZ_RR", "FZ_HO", "FZ_JX", "FZ_OB", "FZ_NINT", "FZ_BPOFF", "FZ_NT",
            "FZ_LINEOFF", "FZ_PAIRS", "FZ_SUP", "FZ_KK0", "FZ_KK1", "FZ_J1", "FZ_J2",
            "FZ_LO4", "FZ_N", "FZ_II", "FZ_NIN", "FZ_NOUT", "FZ_GT", "FZ_ANDOP", "FZ_IMPL",
            "FZ_RO")
    reals = ("FZ_XV", "FZ_INV", "FZ_T", "FZ_MVAL", "FZ_ACC", "FZ_V", "FZ_WR", "FZ_MOM",
             "FZ_REF", "FZ_SPAN", "FZ_SCALE", "FZ_A", "FZ_B", "FZ_P", "FZ_WW", "FZ_PQ",
             "FZ_Y", "FZ_LEVEL", "FZ_U", "FZ_GU", "FZ_GV", "FZ_UU", "FZ_VV", "FZ_M1", "FZ_C1",
             "FZ_M2", "FZ_C2", "FZ_IA", "FZ_IM", "FZ_DD", "FZ_GY", "FZ_Q1", "FZ_Q2", "FZ_G",
             "FZ_OUTV")
    lines = []
    for k in range(0, len(ints), 12):
        lines.append(", ".join(ints[k:k + 12]) + " : DINT;")
    for k in range(0, len(reals), 12):
        lines.append(", ".join(reals[k:k + 12]) + f" : {real};")
    lines += ["FZ_NONE : BOOL;",
              f"FZ_XIN : ARRAY[0..1] OF {real};",
              f"FZ_WORK : ARRAY[0..{n_work - 1}] OF {real};",
              f"FZ_IW : ARRAY[0..{n_iwork - 1}] OF DINT;",
              f"FZ_CAND : ARRAY[0..7] OF {real};"]
    return lines


def _g2(y: str, out: str, tol: str, real: StReal, ind: str) -> list[str]:
    """fs_g2: max(impl(a, F), impl(b, R)) at y (F = c1 + m1 y, R = c2 + m2 y, >= 0)."""
    zero = st_typed(0.0, real)
    return [
        f"{ind}FZ_GY := {y};",
        f"{ind}FZ_Q1 := FZ_C1 + FZ_M1 * FZ_GY;",
        f"{ind}FZ_Q2 := FZ_C2 + FZ_M2 * FZ_GY;",
        f"{ind}IF FZ_Q1 < {zero} THEN",
        f"{ind}    FZ_Q1 := {zero};",
        f"{ind}END_IF;",
        f"{ind}IF FZ_Q2 < {zero} THEN",
        f"{ind}    FZ_Q2 := {zero};",
        f"{ind}END_IF;",
        f"{ind}IF FZ_IMPL = 0 THEN",
        f"{ind}    (* at a clip crossing c + m y is the clip height up to its rounding *)",
        f"{ind}    IF ABS(FZ_Q1 - FZ_A) <= {tol} * (ABS(FZ_C1) + ABS(FZ_M1 * FZ_GY)) THEN",
        f"{ind}        FZ_Q1 := FZ_A;",
        f"{ind}    END_IF;",
        f"{ind}    IF ABS(FZ_Q2 - FZ_B) <= {tol} * (ABS(FZ_C2) + ABS(FZ_M2 * FZ_GY)) THEN",
        f"{ind}        FZ_Q2 := FZ_B;",
        f"{ind}    END_IF;",
        f"{ind}    IF FZ_Q1 < FZ_A THEN (* fs_min(a, f1) *)",
        f"{ind}        FZ_G := FZ_Q1;",
        f"{ind}    ELSE",
        f"{ind}        FZ_G := FZ_A;",
        f"{ind}    END_IF;",
        f"{ind}    FZ_Q1 := FZ_G;",
        f"{ind}    IF FZ_Q2 < FZ_B THEN",
        f"{ind}        FZ_G := FZ_Q2;",
        f"{ind}    ELSE",
        f"{ind}        FZ_G := FZ_B;",
        f"{ind}    END_IF;",
        f"{ind}    FZ_Q2 := FZ_G;",
        f"{ind}ELSE",
        f"{ind}    FZ_Q1 := FZ_A * FZ_Q1;",
        f"{ind}    FZ_Q2 := FZ_B * FZ_Q2;",
        f"{ind}END_IF;",
        f"{ind}IF FZ_Q1 > FZ_Q2 THEN",
        f"{ind}    {out} := FZ_Q1;",
        f"{ind}ELSE",
        f"{ind}    {out} := FZ_Q2;",
        f"{ind}END_IF;",
    ]


def _insort(ind: str) -> list[str]:
    """insort(cand, n, y): FZ_Y into the sorted FZ_CAND[0..FZ_N-1] (no short-circuit AND in
    ST: the index is tested before the element is read)."""
    return [
        f"{ind}FZ_II := FZ_N;",
        f"{ind}WHILE FZ_II > 0 DO",
        f"{ind}    IF FZ_CAND[FZ_II - 1] > FZ_Y THEN",
        f"{ind}        FZ_CAND[FZ_II] := FZ_CAND[FZ_II - 1];",
        f"{ind}        FZ_II := FZ_II - 1;",
        f"{ind}    ELSE",
        f"{ind}        EXIT;",
        f"{ind}    END_IF;",
        f"{ind}END_WHILE;",
        f"{ind}FZ_CAND[FZ_II] := FZ_Y;",
        f"{ind}FZ_N := FZ_N + 1;",
    ]


def _interval(real: StReal, tol: str, ind: str) -> list[str]:
    """fs_interval: area FZ_IA and moment FZ_IM of max(impl(a, F), impl(b, R)) on [FZ_P,
    FZ_PQ] (moment of (y - ref) scale)."""
    zero, half, two, six = (st_typed(v, real) for v in (0.0, 0.5, 2.0, 6.0))
    i2, i3 = ind + "    ", ind + "        "
    lines = [f"{ind}FZ_CAND[0] := FZ_P;", f"{ind}FZ_N := 1;", f"{ind}IF FZ_IMPL = 0 THEN"]
    for m, c in (("FZ_M1", "FZ_C1"), ("FZ_M2", "FZ_C2")):
        lines += [f"{i2}IF {m} <> {zero} THEN"]
        for level in ("FZ_A", "FZ_B"):
            lines += [f"{i3}FZ_Y := ({level} - {c}) / {m};",
                      f"{i3}IF FZ_P < FZ_Y AND FZ_Y < FZ_PQ THEN",
                      *_insort(i3 + "    "),
                      f"{i3}END_IF;"]
        lines += [f"{i2}END_IF;"]
    lines += [
        f"{i2}IF FZ_M1 <> FZ_M2 AND FZ_A > {zero} AND FZ_B > {zero} THEN",
        f"{i3}FZ_Y := (FZ_C2 - FZ_C1) / (FZ_M1 - FZ_M2);",
        f"{i3}IF FZ_P < FZ_Y AND FZ_Y < FZ_PQ THEN",
        *_insort(i3 + "    "),
        f"{i3}END_IF;",
        f"{i2}END_IF;",
        f"{ind}ELSE",
        f"{i2}FZ_DD := FZ_A * FZ_M1 - FZ_B * FZ_M2;",
        f"{i2}IF FZ_DD <> {zero} AND FZ_A > {zero} AND FZ_B > {zero} THEN",
        f"{i3}FZ_Y := (FZ_B * FZ_C2 - FZ_A * FZ_C1) / FZ_DD;",
        f"{i3}IF FZ_P < FZ_Y AND FZ_Y < FZ_PQ THEN",
        *_insort(i3 + "    "),
        f"{i3}END_IF;",
        f"{i2}END_IF;",
        f"{ind}END_IF;",
        f"{ind}FZ_CAND[FZ_N] := FZ_PQ;",
        f"{ind}FZ_N := FZ_N + 1;",
        f"{ind}FZ_IA := {zero};",
        f"{ind}FZ_IM := {zero};",
        f"{ind}FZ_U := FZ_CAND[0];",
        *_g2("FZ_U", "FZ_GU", tol, real, ind),
        f"{ind}FOR FZ_II := 1 TO FZ_N - 1 DO",
        f"{i2}FZ_V := FZ_CAND[FZ_II];",
        *_g2("FZ_V", "FZ_GV", tol, real, i2),
        f"{i2}FZ_WW := FZ_V - FZ_U;",
        f"{i2}IF FZ_WW > {zero} AND (FZ_GU > {zero} OR FZ_GV > {zero}) THEN",
        f"{i3}FZ_UU := (FZ_U - FZ_REF) * FZ_SCALE;",
        f"{i3}FZ_VV := (FZ_V - FZ_REF) * FZ_SCALE;",
        f"{i3}FZ_IA := FZ_IA + {half} * FZ_WW * (FZ_GU + FZ_GV);",
        f"{i3}FZ_IM := FZ_IM + FZ_WW * (FZ_UU * ({two} * FZ_GU + FZ_GV) + FZ_VV * (FZ_GU + "
        f"{two} * FZ_GV)) / {six};",
        f"{i2}END_IF;",
        f"{i2}FZ_U := FZ_V;",
        f"{i2}FZ_GU := FZ_GV;",
        f"{ind}END_FOR;",
    ]
    return lines


_FOR = re.compile(r"^(\s*)FOR (\w+) := (.+) TO (.+) DO$")


def _while_loops(lines: list[str]) -> list[str]:
    """``FOR v := a TO b DO ... END_FOR;`` as ``v := a; WHILE v <= b DO ... v := v + 1;
    END_WHILE;`` (b does not change in the loops written here). MatIEC's C runs a FOR loop of
    exactly one iteration (a = b) zero times (it tests v < b before the body); WHILE is
    translated as written, and every target runs it the same."""
    out: list[str] = []
    stack: list[tuple[str, str]] = []
    for line in lines:
        m = _FOR.match(line)
        if m:
            ind, var, start, end = m.groups()
            out += [f"{ind}{var} := {start};", f"{ind}WHILE {var} <= {end} DO"]
            stack.append((ind, var))
        elif line.strip() == "END_FOR;":
            ind, var = stack.pop()
            out += [f"{ind}    {var} := {var} + 1;", f"{ind}END_WHILE;"]
        else:
            out.append(line)
    if stack:
        raise ParameterError("unbalanced FOR in generated ST")
    return out


def st_partition_eval(g: PartitionSystem, x1: str, x2: str, out: str, real: StReal,
                      ind: str = "") -> list[str]:
    """Statements evaluating the partition system ``g`` at (x1, x2) into ``out``: the
    general evaluator's point (a NaN input gives NaN; inputs clipped to their ranges where the
    system says so; no rule fired: the no-rule value; the output clipped where it says so)
    with :func:`fuzzyservo.fuzzy.partition.eval_partition` (its C port ``fs_eval_partition``)
    line by line; the first output."""
    p = g.prefix
    zero, one, half = (st_typed(v, real) for v in (0.0, 1.0, 0.5))
    tol = st_typed(1e-15 if real == "LREAL" else float(np.float32(1e-15 * 536870912.0)),
                   real)
    i2, i3, i4, i5 = (ind + "    " * k for k in (1, 2, 3, 4))
    lines = [f"{ind}FZ_IN1 := {x1};", f"{ind}FZ_IN2 := {x2};",
             f"{ind}IF FZ_IN1 <> FZ_IN1 OR FZ_IN2 <> FZ_IN2 THEN (* a NaN input: NaN *)",
             f"{i2}{out} := FZ_IN1 + FZ_IN2;", f"{ind}ELSE"]
    for k, name in enumerate(("FZ_IN1", "FZ_IN2")):
        lines.append(f"{i2}FZ_XIN[{k}] := {name};")
        if g.clip[k]:
            lines += [f"{i2}IF FZ_XIN[{k}] < {p}_XLO{k} THEN",
                      f"{i3}FZ_XIN[{k}] := {p}_XLO{k};",
                      f"{i2}ELSIF FZ_XIN[{k}] > {p}_XHI{k} THEN",
                      f"{i3}FZ_XIN[{k}] := {p}_XHI{k};",
                      f"{i2}END_IF;"]
    lines += [
        f"{i2}FZ_NIN := {p}_PI[0];",
        f"{i2}FZ_NOUT := {p}_PI[1];",
        f"{i2}FZ_GT := {p}_PI[2];",
        f"{i2}FZ_ANDOP := {p}_PI[3];",
        f"{i2}FZ_IMPL := {p}_PI[4];",
        f"{i2}FZ_RO := {p}_PI[6];",
        f"{i2}FZ_POS := FZ_NIN;",
        f"{i2}FZ_NONE := FALSE;",
        f"{i2}(* each input: its non-zero terms (FZ_IW[FZ_I] of them; local indices and values "
        f"at FZ_IW/FZ_WORK[FZ_POS...]) *)",
        f"{i2}FOR FZ_I := 0 TO FZ_NIN - 1 DO",
        f"{i3}IF NOT FZ_NONE THEN",
        f"{i4}FZ_BASE := {p}_PI[8 + FZ_I];",
        f"{i4}FZ_NBP := {p}_PI[FZ_BASE];",
        f"{i4}FZ_XBOFF := {p}_PI[FZ_BASE + 1];",
        f"{i4}FZ_ENTF := {p}_PI[FZ_BASE + 3];",
        f"{i4}FZ_TERMSAT := {p}_PI[FZ_BASE + 4];",
        f"{i4}FZ_XV := FZ_XIN[FZ_I];",
        f"{i4}FZ_INV := {p}_PF[{p}_PI[FZ_BASE + 5]];",
        f"{i4}IF FZ_INV > {zero} THEN",
        f"{i5}FZ_T := (FZ_XV - {p}_PF[FZ_XBOFF]) * FZ_INV;",
        f"{i5}IF FZ_T >= {zero} THEN",
        f"{i5}    IF FZ_T >= DINT_TO_{real}(FZ_NBP) THEN",
        f"{i5}        FZ_LO := FZ_NBP;",
        f"{i5}    ELSE",
        f"{i5}        FZ_LO := TRUNC(FZ_T) + 1;",
        f"{i5}    END_IF;",
        f"{i5}ELSE",
        f"{i5}    FZ_LO := 0;",
        f"{i5}END_IF;",
        f"{i5}IF FZ_LO > FZ_NBP THEN",
        f"{i5}    FZ_LO := FZ_NBP;",
        f"{i5}END_IF;",
        f"{i5}(* t rounded near a vertex: settle on the exact comparison *)",
        f"{i5}WHILE FZ_LO > 0 DO",
        f"{i5}    IF {p}_PF[FZ_XBOFF + FZ_LO - 1] > FZ_XV THEN",
        f"{i5}        FZ_LO := FZ_LO - 1;",
        f"{i5}    ELSE",
        f"{i5}        EXIT;",
        f"{i5}    END_IF;",
        f"{i5}END_WHILE;",
        f"{i5}WHILE FZ_LO < FZ_NBP DO",
        f"{i5}    IF {p}_PF[FZ_XBOFF + FZ_LO] <= FZ_XV THEN",
        f"{i5}        FZ_LO := FZ_LO + 1;",
        f"{i5}    ELSE",
        f"{i5}        EXIT;",
        f"{i5}    END_IF;",
        f"{i5}END_WHILE;",
        f"{i4}ELSE",
        f"{i5}FZ_LO := 0;",
        f"{i5}FZ_HI := FZ_NBP;",
        f"{i5}WHILE FZ_LO < FZ_HI DO",
        f"{i5}    FZ_MID := (FZ_LO + FZ_HI) / 2;",
        f"{i5}    IF {p}_PF[FZ_XBOFF + FZ_MID] <= FZ_XV THEN",
        f"{i5}        FZ_LO := FZ_MID + 1;",
        f"{i5}    ELSE",
        f"{i5}        FZ_HI := FZ_MID;",
        f"{i5}    END_IF;",
        f"{i5}END_WHILE;",
        f"{i4}END_IF;",
        f"{i4}FZ_K0 := {p}_PI[FZ_BASE + 6 + 2 * FZ_LO];",
        f"{i4}FZ_CNT := 0;",
        f"{i4}FOR FZ_K := FZ_K0 TO FZ_K0 + {p}_PI[FZ_BASE + 6 + 2 * FZ_LO + 1] - 1 DO",
        f"{i5}FZ_MVAL := {p}_PF[FZ_ENTF + 2 * FZ_K] * FZ_XV + {p}_PF[FZ_ENTF + 2 * FZ_K + 1];",
        f"{i5}IF FZ_MVAL > {zero} THEN",
        f"{i5}    FZ_IW[FZ_POS + FZ_CNT] := {p}_PI[FZ_TERMSAT + FZ_K];",
        f"{i5}    FZ_WORK[FZ_POS + FZ_CNT] := FZ_MVAL;",
        f"{i5}    FZ_CNT := FZ_CNT + 1;",
        f"{i5}END_IF;",
        f"{i4}END_FOR;",
        f"{i4}IF FZ_CNT = 0 THEN",
        f"{i4}    FZ_NONE := TRUE; (* no term of this input: no rule fires *)",
        f"{i4}ELSE",
        f"{i4}    FZ_IW[FZ_I] := FZ_CNT;",
        f"{i4}    FZ_POS := FZ_POS + FZ_CNT;",
        f"{i4}END_IF;",
        f"{i3}END_IF;",
        f"{i2}END_FOR;",
        f"{i2}FZ_AREA := {zero};",
        f"{i2}FZ_MOM := {zero};",
        f"{i2}IF NOT FZ_NONE THEN",
        f"{i3}(* heights of the output terms: the largest strength of the fired rules naming "
        f"each *)",
        f"{i3}FZ_HOFF := FZ_POS;",
        f"{i3}FZ_NH := 0;",
        f"{i3}FOR FZ_O := 0 TO FZ_NOUT - 1 DO",
        f"{i4}FZ_NH := FZ_NH + {p}_PI[{p}_PI[8 + FZ_NIN + FZ_O] + 2];",
        f"{i3}END_FOR;",
        f"{i3}FOR FZ_K := 0 TO FZ_NH - 1 DO",
        f"{i4}FZ_WORK[FZ_HOFF + FZ_K] := {zero};",
        f"{i3}END_FOR;",
        f"{i3}FZ_DIG := FZ_POS;",
        f"{i3}FOR FZ_I := 0 TO FZ_NIN - 1 DO",
        f"{i4}FZ_IW[FZ_DIG + FZ_I] := 0;",
        f"{i3}END_FOR;",
        f"{i3}FZ_TOTAL := 1;",
        f"{i3}FOR FZ_I := 0 TO FZ_NIN - 1 DO",
        f"{i4}FZ_TOTAL := FZ_TOTAL * FZ_IW[FZ_I];",
        f"{i3}END_FOR;",
        f"{i3}FOR FZ_COMBO := 0 TO FZ_TOTAL - 1 DO",
        f"{i4}FZ_CELL := 0;",
        f"{i4}FZ_P0 := FZ_NIN;",
        f"{i4}FZ_ACC := {one};",
        f"{i4}FOR FZ_I := 0 TO FZ_NIN - 1 DO",
        f"{i5}FZ_D := FZ_IW[FZ_DIG + FZ_I];",
        f"{i5}FZ_CELL := FZ_CELL + {p}_PI[FZ_GT + FZ_I] * FZ_IW[FZ_P0 + FZ_D];",
        f"{i5}FZ_V := FZ_WORK[FZ_P0 + FZ_D];",
        f"{i5}IF FZ_ANDOP = 0 THEN",
        f"{i5}    IF FZ_V < FZ_ACC THEN",
        f"{i5}        FZ_ACC := FZ_V;",
        f"{i5}    END_IF;",
        f"{i5}ELSE",
        f"{i5}    FZ_ACC := FZ_ACC * FZ_V;",
        f"{i5}END_IF;",
        f"{i5}FZ_P0 := FZ_P0 + FZ_IW[FZ_I];",
        f"{i4}END_FOR;",
        f"{i4}FZ_CE := FZ_GT + FZ_NIN + 2 * FZ_CELL;",
        f"{i4}FZ_ST := {p}_PI[FZ_CE];",
        f"{i4}FOR FZ_Q := 0 TO {p}_PI[FZ_CE + 1] - 1 DO",
        f"{i5}FZ_RR := {p}_PI[FZ_ST + FZ_Q];",
        f"{i5}FZ_WR := FZ_ACC * {p}_PF[FZ_RR];",
        f"{i5}IF FZ_WR > {zero} THEN",
        f"{i5}    FZ_HO := FZ_HOFF;",
        f"{i5}    FOR FZ_O := 0 TO FZ_NOUT - 1 DO",
        f"{i5}        FZ_JX := {p}_PI[FZ_RO + FZ_RR * FZ_NOUT + FZ_O];",
        f"{i5}        IF FZ_JX >= 0 THEN",
        f"{i5}            IF FZ_WR > FZ_WORK[FZ_HO + FZ_JX] THEN",
        f"{i5}                FZ_WORK[FZ_HO + FZ_JX] := FZ_WR;",
        f"{i5}            END_IF;",
        f"{i5}        END_IF;",
        f"{i5}        FZ_HO := FZ_HO + {p}_PI[{p}_PI[8 + FZ_NIN + FZ_O] + 2];",
        f"{i5}    END_FOR;",
        f"{i5}END_IF;",
        f"{i4}END_FOR;",
        f"{i4}(* next combination (odometer) *)",
        f"{i4}FOR FZ_I := 0 TO FZ_NIN - 1 DO",
        f"{i5}FZ_IW[FZ_DIG + FZ_I] := FZ_IW[FZ_DIG + FZ_I] + 1;",
        f"{i5}IF FZ_IW[FZ_DIG + FZ_I] < FZ_IW[FZ_I] THEN",
        f"{i5}    EXIT;",
        f"{i5}END_IF;",
        f"{i5}FZ_IW[FZ_DIG + FZ_I] := 0;",
        f"{i4}END_FOR;",
        f"{i3}END_FOR;",
        f"{i3}(* the first output: its intervals between the output terms' vertices *)",
        f"{i3}FZ_HO := FZ_HOFF;",
        f"{i3}FZ_OB := {p}_PI[8 + FZ_NIN];",
        f"{i3}FZ_NINT := {p}_PI[FZ_OB];",
        f"{i3}FZ_BPOFF := {p}_PI[FZ_OB + 1];",
        f"{i3}FZ_NT := {p}_PI[FZ_OB + 2];",
        f"{i3}FZ_LINEOFF := {p}_PI[FZ_OB + 3];",
        f"{i3}FZ_PAIRS := FZ_OB + 4;",
        f"{i3}FZ_SUP := FZ_PAIRS + 3 * FZ_NINT;",
        f"{i3}FZ_KK0 := FZ_NINT;",
        f"{i3}FZ_KK1 := -1;",
        f"{i3}FOR FZ_JX := 0 TO FZ_NT - 1 DO",
        f"{i4}IF FZ_WORK[FZ_HO + FZ_JX] > {zero} THEN",
        f"{i5}IF {p}_PI[FZ_SUP + 2 * FZ_JX] < FZ_KK0 THEN",
        f"{i5}    FZ_KK0 := {p}_PI[FZ_SUP + 2 * FZ_JX];",
        f"{i5}END_IF;",
        f"{i5}IF {p}_PI[FZ_SUP + 2 * FZ_JX + 1] > FZ_KK1 THEN",
        f"{i5}    FZ_KK1 := {p}_PI[FZ_SUP + 2 * FZ_JX + 1];",
        f"{i5}END_IF;",
        f"{i4}END_IF;",
        f"{i3}END_FOR;",
        f"{i3}FZ_REF := {p}_PF[FZ_BPOFF];",
        f"{i3}FZ_SPAN := {p}_PF[FZ_BPOFF + FZ_NINT] - FZ_REF;",
        f"{i3}FZ_SCALE := {one} / FZ_SPAN;",
        f"{i3}FOR FZ_K := FZ_KK0 TO FZ_KK1 DO",
        f"{i4}FZ_J1 := {p}_PI[FZ_PAIRS + 3 * FZ_K];",
        f"{i4}FZ_J2 := {p}_PI[FZ_PAIRS + 3 * FZ_K + 1];",
        f"{i4}FZ_A := {zero};",
        f"{i4}IF FZ_J1 >= 0 THEN",
        f"{i4}    FZ_A := FZ_WORK[FZ_HO + FZ_J1];",
        f"{i4}END_IF;",
        f"{i4}FZ_B := {zero};",
        f"{i4}IF FZ_J2 >= 0 THEN",
        f"{i4}    FZ_B := FZ_WORK[FZ_HO + FZ_J2];",
        f"{i4}END_IF;",
        f"{i4}IF FZ_A > {zero} OR FZ_B > {zero} THEN",
        f"{i5}IF FZ_IMPL = 0 AND {p}_PI[FZ_PAIRS + 3 * FZ_K + 2] = 1 THEN",
        f"{i5}    FZ_P := {p}_PF[FZ_BPOFF + FZ_K];",
        f"{i5}    FZ_WW := {p}_PF[FZ_BPOFF + FZ_K + 1] - FZ_P;",
        f"{i5}    (* segment_integrals(a, b) *)",
        f"{i5}    FZ_M := FZ_A;",
        f"{i5}    IF FZ_B < FZ_M THEN",
        f"{i5}        FZ_M := FZ_B;",
        f"{i5}    END_IF;",
        f"{i5}    IF {half} < FZ_M THEN",
        f"{i5}        FZ_M := {half};",
        f"{i5}    END_IF;",
        f"{i5}    FZ_TM := FZ_M - FZ_M * FZ_M;",
        f"{i5}    FZ_AR := FZ_A - {half} * FZ_A * FZ_A + FZ_B - {half} * FZ_B * FZ_B - FZ_TM;",
        f"{i5}    FZ_MO := {half} * (FZ_A - FZ_A * FZ_A + FZ_B - FZ_TM) + (FZ_A * FZ_A * FZ_A "
        f"- FZ_B * FZ_B * FZ_B) * ({one} / {st_typed(6.0, real)});",
        f"{i5}    FZ_AREA := FZ_AREA + FZ_WW * FZ_AR;",
        f"{i5}    FZ_MOM := FZ_MOM + FZ_WW * ((FZ_P - FZ_REF) * FZ_SCALE * FZ_AR + (FZ_WW * "
        f"FZ_SCALE) * FZ_MO);",
        f"{i5}ELSE",
        f"{i5}    FZ_LO4 := FZ_LINEOFF + 4 * FZ_K;",
        f"{i5}    FZ_P := {p}_PF[FZ_BPOFF + FZ_K];",
        f"{i5}    FZ_PQ := {p}_PF[FZ_BPOFF + FZ_K + 1];",
        f"{i5}    FZ_M1 := {p}_PF[FZ_LO4];",
        f"{i5}    FZ_C1 := {p}_PF[FZ_LO4 + 1];",
        f"{i5}    FZ_M2 := {p}_PF[FZ_LO4 + 2];",
        f"{i5}    FZ_C2 := {p}_PF[FZ_LO4 + 3];",
        *_interval(real, tol, i5 + "    "),
        f"{i5}    FZ_AREA := FZ_AREA + FZ_IA;",
        f"{i5}    FZ_MOM := FZ_MOM + FZ_IM;",
        f"{i5}END_IF;",
        f"{i4}END_IF;",
        f"{i3}END_FOR;",
        f"{i2}END_IF;",
        f"{i2}IF FZ_AREA > {zero} THEN",
        f"{i3}FZ_OUTV := FZ_REF + FZ_SPAN * (FZ_MOM / FZ_AREA);",
    ]
    if g.out_clip:
        lines += [f"{i3}IF {p}_YLO > FZ_OUTV THEN (* fs_min(fs_max(out, lo), hi) *)",
                  f"{i3}    FZ_OUTV := {p}_YLO;",
                  f"{i3}END_IF;",
                  f"{i3}IF {p}_YHI < FZ_OUTV THEN",
                  f"{i3}    FZ_OUTV := {p}_YHI;",
                  f"{i3}END_IF;"]
    lines += [f"{i3}{out} := FZ_OUTV;",
              f"{i2}ELSE",
              f"{i3}{out} := {p}_DEFAULT; (* no rule fired *)",
              f"{i2}END_IF;",
              f"{ind}END_IF;"]
    return _while_loops(lines)


def st_partition_consts(g: PartitionSystem, real: StReal) -> list[str]:
    """The ranges, clip limits and no-rule value of a partition system, as constants."""
    out = []
    for k, (lo, hi) in enumerate(g.ranges):
        if g.clip[k]:
            out.append(f"{g.prefix}_XLO{k} : {real} := {st_literal(lo, real)}; "
                       f"{g.prefix}_XHI{k} : {real} := {st_literal(hi, real)}; "
                       f"(* input {k + 1} range *)")
    if g.out_clip:
        out.append(f"{g.prefix}_YLO : {real} := {st_literal(g.out_range[0], real)}; "
                   f"{g.prefix}_YHI : {real} := {st_literal(g.out_range[1], real)}; "
                   f"(* output range *)")
    out.append(f"{g.prefix}_DEFAULT : {real} := {st_literal(g.default, real)}; (* no-rule value *)")
    return out
