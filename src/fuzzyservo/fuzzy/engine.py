"""One packer and one exact engine for every fuzzy system.

:func:`pack` chooses how a :class:`~fuzzyservo.fuzzy.system.FuzzySystem` is evaluated, from
its form alone (docs/fuzzy-files.md, "Exactness"):

- **uniform grid**: two inputs and one output, each a partition of uniform triangles
  (:meth:`Variable.uniform <fuzzyservo.fuzzy.system.Variable.uniform>`, compared exactly), a
  rule table with at most one rule per cell (AND of one plain clause per input, weight 1),
  min AND, min implication, max aggregation, centroid, clipped inputs. The paper's systems
  have this form; :mod:`fuzzyservo.fuzzy.kernels` integrates the aggregate in closed form.
- everything else: the general evaluator (:mod:`fuzzyservo.fuzzy.general`), which itself
  takes the **partition** path for rule tables over fuzzy partitions
  (:mod:`fuzzyservo.fuzzy.partition`), integrates **piecewise-linear** aggregates exactly
  between their breakpoints, and **smooth** ones by adaptive Gauss-Kronrod quadrature.

The result, a :class:`PackedSystem`, is what the controllers' compiled loops take
(``kernel_args()``), and :func:`evaluate` runs the same compiled functions the loops call
(:func:`eval_system` for a two-input system, the general evaluator's ``eval_point`` for
others): the per-sample answer and the loop's answer are the same code, bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numba
import numpy as np
from numba.np.numpy_support import carray

from .._jit import data_pointer, kernel
from .._typing import ArrayLike, FloatArray, IntArray
from ..errors import InputError, ParameterError
from .general import (
    _M_PL,
    _M_SING,
    _M_SUGENO,
    H_OUTS,
    H_PART,
    MAGIC,
    CompiledSystem,
    compile_system,
    eval_batch,
    eval_first2,
    eval_parallel,
)
from .kernels import LIMS_SIZE, GridTable, grid_eval, grid_table
from .system import FuzzySystem, Variable, uniform_triangles

__all__ = [
    "PackedSystem",
    "Path",
    "SystemTable",
    "check_packed",
    "eval_system",
    "evaluate",
    "grid_form",
    "pack",
    "system_table",
]

#: The evaluation path a packed system takes (first output, for the general evaluator).
Path = Literal["uniform grid", "partition", "piecewise linear", "singletons", "smooth",
               "sugeno"]

#: A packed system as the compiled loops take it (:func:`system_table`).
SystemTable = tuple[int, GridTable, Any, int, Any, int]


# ---------------------------------------------------------------------------------------------
# the compiled dispatch (the loops inline it; evaluate calls it)


@kernel(inline=True)
def system_table(rules: IntArray, lims: FloatArray) -> SystemTable:
    """A packed system's ``kernel_args()`` as one value the compiled code takes (the arrays
    must outlive it): ``(general, grid table, packed integers, their count, packed floats,
    their count)``; ``general`` is 1 for the general evaluator's arrays (rules (1, N),
    C-contiguous), whose grid table is a placeholder, else 0."""
    rp = data_pointer(rules)
    lp = data_pointer(lims)
    if rules.shape[0] == 1:
        return (1, (rp, 2, 2, 0, 0, -1.0, 1.0, -1.0, 1.0, 0.0, 1.0, 2, 0.0), rp,
                rules.shape[1], lp, lims.shape[0])
    return (0, grid_table(rules, lims), rp, 0, lp, 0)


@kernel(error_model="numpy")
def eval_system(x1: float, x2: float, tab: SystemTable) -> float:
    """A two-input packed system (:func:`system_table`) at (x1, x2), its first output: the
    uniform-grid path for a rule table, the general evaluator otherwise."""
    if tab[0] == 1:
        return eval_first2(x1, x2, carray(tab[2], tab[3]), carray(tab[4], tab[5]))
    return grid_eval(x1, x2, tab[1])


@kernel(error_model="numpy")
def _eval_two(x: FloatArray, rules: IntArray, lims: FloatArray, out: FloatArray) -> None:
    tab = system_table(rules, lims)
    for i in range(x.shape[0]):
        out[i, 0] = eval_system(x[i, 0], x[i, 1], tab)


# ---------------------------------------------------------------------------------------------
# packing


def grid_form(system: FuzzySystem) -> tuple[IntArray, FloatArray] | None:
    """``(rules, lims)`` of the uniform-grid path if ``system`` has its form, else None.

    ``rules[i2, i1]`` is the output term of the rule on (input 1 term i1, input 2 term i2),
    -1 for no rule; ``lims`` holds lo1, hi1, lo2, hi2, the output's lo, hi, number of terms
    and default (:func:`fuzzyservo.fuzzy.kernels.eval_uniform_grid`).
    """
    s = system
    if (s.kind, s.and_op, s.implication, s.aggregation, s.defuzzifier) != (
            "mamdani", "min", "min", "max", "centroid"):
        return None
    if len(s.inputs) != 2 or len(s.outputs) != 1 or not s.rules:
        return None
    if not all(v.clip and _is_uniform(v) for v in (*s.inputs, *s.outputs)):
        return None
    try:
        table = np.array(s.rule_table(), dtype=np.int64)
    except ParameterError:
        return None
    v1, v2 = s.inputs
    out = s.outputs[0]
    lims = np.empty(LIMS_SIZE, dtype=np.float64)
    lims[0:2] = v1.range
    lims[2:4] = v2.range
    lims[4:6] = out.range
    lims[6] = len(out.terms)
    lims[7] = out.default
    return table, lims


def _is_uniform(v: Variable) -> bool:
    """The terms are exactly those of :meth:`Variable.uniform` (same floats, height 1)."""
    if len(v.terms) < 2 or any(t.height != 1.0 for t in v.terms):
        return False
    want = uniform_triangles(v.range, [t.name for t in v.terms])
    return all((t.shape, t.params) == (w.shape, w.params) for t, w in zip(v.terms, want,
                                                                           strict=True))


@dataclass(frozen=True, slots=True, eq=False)
class PackedSystem:
    """A fuzzy system packed for the compiled evaluator (see :func:`pack`).

    Attributes
    ----------
    system : FuzzySystem
        The system.
    path : str
        How its (first) output is evaluated: "uniform grid", "partition", "piecewise
        linear", "singletons", "smooth" or "sugeno".
    rules, lims : ndarray
        The grid tables (``(n2, n1)`` int64, 8 floats) or the general evaluator's arrays
        (``(1, N)`` int64, floats).
    compiled : CompiledSystem or None
        The general evaluator's packing (None on the uniform grid).
    """

    system: FuzzySystem  #: the packed system
    path: Path  #: evaluation path of the first output
    rules: IntArray  #: grid table or the general integers (one row)
    lims: FloatArray  #: grid limits or the general floats
    compiled: CompiledSystem | None  #: the general evaluator's packing, if it is used

    def kernel_args(self) -> tuple[IntArray, FloatArray]:
        """``(rules, lims)`` for the controllers' compiled loops (copies)."""
        return self.rules.copy(), self.lims.copy()


def _general_path(comp: CompiledSystem) -> Path:
    ints = comp.ints
    mode = int(ints[int(ints[H_OUTS])])
    if mode == _M_SUGENO:
        return "sugeno"
    if mode == _M_SING:
        return "singletons"
    if mode == _M_PL:
        return "partition" if ints[H_PART] >= 0 else "piecewise linear"
    return "smooth"


def pack(system: FuzzySystem, *, grid: bool = True) -> PackedSystem:
    """Pack ``system`` for evaluation (done once per system).

    Parameters
    ----------
    system : FuzzySystem
        Any system.
    grid : bool
        Take the uniform-grid path when the system has its form (:func:`grid_form`); False
        always packs for the general evaluator (to compare the paths, or to compile the
        general loops).

    Raises
    ------
    ParameterError
        If ``system`` is not a FuzzySystem.
    """
    if not isinstance(system, FuzzySystem):
        raise ParameterError(f"expected a FuzzySystem, got {type(system).__name__}")
    tables = grid_form(system) if grid else None
    if tables is not None:
        return PackedSystem(system, "uniform grid", tables[0], tables[1], None)
    comp = compile_system(system)
    return PackedSystem(system, _general_path(comp), comp.ints.reshape(1, -1), comp.floats,
                        comp)


# ---------------------------------------------------------------------------------------------
# evaluation


def evaluate(system: FuzzySystem | PackedSystem, x: ArrayLike, *,
             parallel: bool = False) -> FloatArray:
    """Crisp outputs of a fuzzy system, by the compiled code the controllers' loops run.

    Parameters
    ----------
    system : FuzzySystem or PackedSystem
        The system (packed here if needed: :func:`pack` once to evaluate many times).
    x : array_like, shape (n, n_inputs) or (n_inputs,)
        Input values, columns in the order of ``system.inputs`` [units of the inputs].
    parallel : bool
        Spread the points over the cores (the general evaluator, 1000 points or more).

    Returns
    -------
    ndarray, shape (n, n_outputs) (or (n_outputs,) for one point)
        Outputs in the order of ``system.outputs``; an output's ``default`` where no rule
        fires for it (NaN when the default is NaN).

    Raises
    ------
    InputError
        If ``x`` is not numeric, has the wrong number of columns or a non-finite value.
    """
    packed = system if isinstance(system, PackedSystem) else pack(system)
    s = packed.system
    n_in = len(s.inputs)
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"inputs must be numeric: {exc}") from None
    one = arr.ndim == 1
    pts = np.ascontiguousarray(np.atleast_2d(arr))
    if pts.ndim != 2 or pts.shape[1] != n_in:
        raise InputError(
            f"inputs need shape (n, {n_in}) (columns "
            f"{', '.join(v.name for v in s.inputs)}), got {arr.shape}")
    bad = ~np.isfinite(pts)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise InputError(
            f"input {s.inputs[j].name!r} must be finite, got {pts[i, j]!r} at row {i}")
    out = np.empty((pts.shape[0], len(s.outputs)))
    if packed.compiled is None:
        _eval_two(pts, packed.rules, packed.lims, out)
    elif parallel and pts.shape[0] >= 1000:
        eval_parallel(packed.compiled.ints, packed.compiled.floats, pts, out,
                      4 * numba.get_num_threads())
    else:
        eval_batch(packed.compiled.ints, packed.compiled.floats, pts, out)
    return out[0] if one else out


def check_packed(rules: Any, lims: Any, what: str) -> tuple[IntArray, FloatArray]:
    """``kernel_args()`` of a two-input packed system, checked and made contiguous.

    Raises
    ------
    ParameterError
        Tables of neither form, or a general packing that does not take two inputs.
    """
    r = np.ascontiguousarray(rules, dtype=np.int64)
    m = np.ascontiguousarray(lims, dtype=np.float64)
    if r.ndim == 2 and r.shape[0] == 1:
        if r.shape[1] < 2 or r[0, 0] != MAGIC or r[0, 1] != 2 or m.ndim != 1:
            raise ParameterError(f"{what}: a packed fuzzy system for a loop needs two inputs "
                                 f"(e, de) (fuzzyservo.fuzzy.engine.pack)")
        return r, m
    if r.ndim != 2 or min(r.shape) < 2 or m.shape != (LIMS_SIZE,) \
            or not np.all(np.isfinite(m[:7])):
        raise ParameterError(
            f"{what} tables need rules (n2, n1 >= 2) and 8 lims (first 7 finite), "
            f"got rules {r.shape}, lims {m.shape}")
    n_out = int(m[6])
    if np.any((r < -1) | (r >= n_out)):
        raise ParameterError(f"{what} rules must be -1 or 0..{n_out - 1}")
    return r, m

