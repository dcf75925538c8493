"""The fuzzy systems of a controller as C99: the evaluators' fragment and each system's tables.

The fragment ``csrc/fuzzy.c`` (:func:`fragment`) is a line-by-line port of the compiled
evaluators the controllers call: :func:`fuzzyservo.fuzzy.kernels.eval_uniform_grid` and
``eval_uniform_pair`` for rule tables on uniform triangles, and
:func:`fuzzyservo.fuzzy.general.eval_first2` (``eval_point``, with the partition fast path,
the exact piecewise-linear path, singletons, Sugeno and the smooth adaptive Gauss-Kronrod
path) for packed general systems. :func:`emit_system` and :func:`emit_pair` write a system's
tables as C constants and a function that evaluates it exactly as
``fuzzyservo.control.fuzzy_pi.eval_system`` (and the self-tuning dispatch of
``fuzzy_pi_step``) does.

Generated code, in this order in one C file::

    typedef double fs_real;                 (or: typedef float fs_real; #define FS_FLOAT 1)
    <fragment()>
    <emit_system("ctl_du", rules, lims, real="double")>
    ... ctl_du(x1, x2) ...

In double precision the C computes what the Python computes, bit for bit on the paths
measured (docs/export-fuzzy-c.md); in float it follows the same algorithm with float
tolerances (the fragment's comments give each).
"""

from __future__ import annotations

import re
from importlib import resources
from typing import NamedTuple

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import ParameterError
from ..fuzzy import general as _g
from ..fuzzy.kernels import LIMS_SIZE
from ._c import C_KEYWORDS, Real, c_literal

__all__ = ["Scratch", "emit_pair", "emit_system", "fragment", "scratch_sizes"]


_INT32_MIN = -(2**31)
_INT32_MAX = 2**31 - 1
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
#: Scratch of the smooth path besides its knots and cuts: two quadrature stacks of 256, the
#: scan's abscissae and values (SCAN_CELLS + 1 each), and the cuts' last 2, as laid out in
#: ``fs_smooth``.
_SMOOTH_FIXED = 2 * 256 + 2 * (_g.SCAN_CELLS + 1) + 2
#: Cuts per knot of the smooth path: the knot, then up to CELL_CHANGES per scan cell.
_CUTS_PER_KNOT = _g.CELL_CHANGES * _g.SCAN_CELLS + 1
_PER_LINE_INTS = 12
_PER_LINE_REALS = 4


def fragment() -> str:
    """The C99 fragment ``csrc/fuzzy.c``: the evaluators (every function ``static``, named
    ``fs_*``), to be pasted after the ``fs_real`` typedef and before :func:`emit_system`'s
    text.

    Returns
    -------
    str
        The fragment's text.
    """
    return resources.files("fuzzyservo.export").joinpath("csrc/fuzzy.c").read_text(
        encoding="utf-8")


def _fragment_names() -> frozenset[str]:
    """Identifiers the fragment defines (``fs_*`` functions, types, tables; ``FS_*``
    macros): a generated name must not take one."""
    return frozenset(re.findall(r"\b(?:fs|FS)_[A-Za-z0-9_]*\b", fragment()))


def _check_name(name: str, extra: tuple[str, ...] = ()) -> None:
    if not isinstance(name, str) or not _IDENT.match(name) or name in C_KEYWORDS:
        raise ParameterError(f"C name {name!r} is not an identifier (a letter or _, then "
                             f"letters, digits or _; not a keyword)")
    taken = _fragment_names()
    clash = [n for n in (name, *extra) if n in taken]
    if clash:
        raise ParameterError(f"C name {name!r} would redefine {clash[0]!r} of the fuzzy "
                             f"evaluators' fragment: choose another prefix")


def _real_literal(v: float, real: Real, where: str) -> str:
    """``v`` as an exact C literal (:func:`fuzzyservo.export._c.c_literal`)."""
    return c_literal(v, real, where)


def _real_array(values: FloatArray, real: Real, where: str) -> str:
    lits = [_real_literal(float(v), real, f"{where}[{i}]") for i, v in enumerate(values)]
    lines = [", ".join(lits[k:k + _PER_LINE_REALS]) for k in range(0, len(lits),
                                                                      _PER_LINE_REALS)]
    return "{\n    " + ",\n    ".join(lines) + "}"


def _int_array(values: IntArray) -> str:
    lits = [str(int(v)) for v in values]
    lines = [", ".join(lits[k:k + _PER_LINE_INTS]) for k in range(0, len(lits),
                                                                     _PER_LINE_INTS)]
    return "{\n    " + ",\n    ".join(lines) + "}"


def _as_ints(a: IntArray, what: str) -> IntArray:
    arr = np.asarray(a)
    if arr.dtype.kind not in "iu":
        raise ParameterError(f"{what} must be integers, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    if arr.size and (int(arr.min()) < _INT32_MIN or int(arr.max()) > _INT32_MAX):
        bad = int(arr.max()) if int(arr.max()) > _INT32_MAX else int(arr.min())
        raise ParameterError(f"{what}: {bad} does not fit the C tables' int32_t")
    return arr


def _as_reals(a: FloatArray, what: str) -> FloatArray:
    try:
        arr = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"{what} must be real numbers") from None
    if arr.ndim != 1:
        raise ParameterError(f"{what} must be one-dimensional, got shape {arr.shape}")
    return arr


def _real_check(name: str, real: Real) -> str:
    """A file-scope typedef that fails to compile when fs_real is not ``real``."""
    size = 8 if real == "double" else 4
    return (f"typedef char {name}_needs_{real}[sizeof(fs_real) == {size} ? 1 : -1];"
            f"  /* emitted for fs_real = {real} */\n")


# --- packed general systems ---------------------------------------------------------------


def _smooth_scratch(ints: IntArray) -> int:
    """Scratch ``fs_smooth`` needs for the worst smooth output of the packed system (0 if it
    has none): the fixed stacks and scan, the knots the Python allocates (2, plus each item
    that can fire: its term's parameter count plus 4) and 257 cuts per distinct knot (at most
    2 plus, per term of the output, its parameter count plus 4)."""
    n_in, n_out = int(ints[_g.H_NIN]), int(ints[_g.H_NOUT])
    vt, tt, rt, ct = (int(ints[k]) for k in (_g.H_VARS, _g.H_TERMS, _g.H_RULES, _g.H_CONS))
    worst = 0
    for o in range(n_out):
        if int(ints[int(ints[_g.H_OUTS]) + _g._OUT_FIELDS * o]) != _g._M_SMOOTH:
            continue
        first, n_t = int(ints[vt + 2 * (n_in + o)]), int(ints[vt + 2 * (n_in + o) + 1])

        def npar(j: int, first: int = first) -> int:
            return int(ints[tt + 3 * (first + j) + 2])

        distinct = 2 + sum(npar(j) + 4 for j in range(n_t))
        if int(ints[_g.H_AGG]) == 0:  # max: one item per term
            items = distinct
        else:  # one item per (rule, consequent) naming output o
            items = 2
            for r in range(int(ints[_g.H_NRULES])):
                c0, nc = ct + int(ints[rt + 4 * r + 2]), int(ints[rt + 4 * r + 3])
                items += sum(npar(int(ints[c0 + 2 * c + 1])) + 4 for c in range(nc)
                             if int(ints[c0 + 2 * c]) == o)
        worst = max(worst, _SMOOTH_FIXED + items + distinct * _CUTS_PER_KNOT)
    return worst


class Scratch(NamedTuple):
    """Scratch sizes of a packed system's C evaluation (:func:`scratch_sizes`)."""

    work: int  #: ``fs_real`` work of ``fs_sys_eval_s``: the evaluator's layout
    iwork: int  #: ``int32_t`` work
    smooth: int  #: ``fs_real`` scratch of the smooth path (0: the system has no smooth output)
    single: int  #: ``fs_real`` work of ``fs_sys_eval`` / ``fs_sys_eval2``: all in one array


def scratch_sizes(ints: IntArray) -> Scratch:
    """Scratch the C evaluation of a packed system needs.

    Parameters
    ----------
    ints : int ndarray
        The packed integers (:attr:`fuzzyservo.fuzzy.general.CompiledSystem.ints`).

    Returns
    -------
    Scratch
        ``work``: the evaluator's layout, ``ints[H_WORK]`` (the Python allocation), or for a
        system on the partition fast path only the inputs and that path's scratch;
        ``iwork``: ``ints[H_IWORK]``; ``smooth``: the smooth path's stacks, scan, knots and
        cuts (``fs_sys_eval_s`` takes them as a separate array, NULL when 0); ``single``:
        the one array of ``fs_sys_eval`` and ``fs_sys_eval2`` (``ints[H_WORK]``, the point
        and the outputs, the smooth scratch).
    """
    n_in, n_out = int(ints[_g.H_NIN]), int(ints[_g.H_NOUT])
    smooth = _smooth_scratch(ints)
    work = int(ints[_g.H_WORK])
    if int(ints[_g.H_PART]) >= 0:  # eval_partition(x, ..., work[n_in:]): partition.scratch_sizes
        vt = int(ints[_g.H_VARS])
        terms = sum(int(ints[vt + 2 * v + 1]) for v in range(n_in + n_out))
        work = n_in + (n_in + terms + 8)
    return Scratch(work=work, iwork=max(int(ints[_g.H_IWORK]), 1), smooth=smooth,
                   single=int(ints[_g.H_WORK]) + n_in + n_out + smooth)


def _packed(rules: IntArray, lims: FloatArray, real: Real, what: str
            ) -> tuple[IntArray, FloatArray]:
    ints = _as_ints(np.asarray(rules).reshape(-1), f"{what}: packed integers")
    floats = _as_reals(lims, f"{what}: packed floats")
    if ints.size < 29 or int(ints[_g.H_MAGIC]) != _g.MAGIC:
        raise ParameterError(f"{what}: not a packed fuzzy system "
                             f"(fuzzyservo.fuzzy.general.compile_system)")
    if int(ints[_g.H_NIN]) != 2:
        raise ParameterError(f"{what}: a controller's fuzzy system takes two inputs (e, de), "
                             f"this one has {int(ints[_g.H_NIN])}")
    for i, v in enumerate(floats):  # a float that C cannot hold in `real`
        _real_literal(float(v), real, f"{what}: floats[{i}]")
    return ints, floats


def _emit_packed(name: str, ints: IntArray, floats: FloatArray, real: Real) -> str:
    up = name.upper()
    sz = scratch_sizes(ints)
    n_out = int(ints[_g.H_NOUT])
    smooth_def = f"#define {up}_SMOOTH {sz.smooth}\n" if sz.smooth else ""
    smooth_arr = f"    FS_SCRATCH fs_real smooth[{up}_SMOOTH];\n" if sz.smooth else ""
    return (
        f"/* fuzzy system {name}: general evaluator (fuzzyservo.fuzzy.general), "
        f"{int(ints[_g.H_NIN])} inputs, {n_out} output(s), output 0 used */\n"
        + _real_check(name, real)
        + f"#define {up}_WORK {sz.work}\n#define {up}_IWORK {sz.iwork}\n" + smooth_def
        + f"static const int32_t {name}_ints[{ints.size}] = {_int_array(ints)};\n"
        f"static const fs_real {name}_floats[{max(floats.size, 1)}] = "
        f"{_real_array(floats if floats.size else np.zeros(1), real, name + '_floats')};\n"
        f"FS_MAYBE_UNUSED static fs_real {name}(fs_real x1, fs_real x2) {{\n"
        f"    fs_real x[2];\n"
        f"    fs_real out[{n_out}];\n"
        f"    FS_SCRATCH fs_real work[{up}_WORK];\n"
        f"    FS_SCRATCH int32_t iwork[{up}_IWORK];\n" + smooth_arr
        + "    x[0] = x1;\n    x[1] = x2;\n"
        f"    fs_sys_eval_s(x, out, {name}_ints, {name}_floats, work, iwork, "
        f"{'smooth' if sz.smooth else 'NULL'});\n"
        f"    return out[0];\n"
        f"}}\n")


# --- uniform rule tables -------------------------------------------------------------------


def _grid(rules: IntArray, lims: FloatArray, what: str) -> tuple[IntArray, FloatArray]:
    r = _as_ints(rules, f"{what}: rules")
    m = _as_reals(lims, f"{what}: lims")
    if r.ndim != 2 or min(r.shape) < 2 or m.shape != (LIMS_SIZE,):
        raise ParameterError(f"{what}: a rule table needs rules (n2, n1 >= 2) and "
                             f"{LIMS_SIZE} lims, got rules {r.shape}, lims {m.shape}")
    if not np.all(np.isfinite(m[:7])):
        raise ParameterError(f"{what}: lims[0:7] must be finite, got {m[:7].tolist()}")
    if not (m[0] < m[1] and m[2] < m[3] and m[4] < m[5]):
        raise ParameterError(f"{what}: universes need lo < hi, got {m[:6].tolist()}")
    n_out = m[6]
    if not (n_out == int(n_out) and 2 <= n_out <= _INT32_MAX):
        raise ParameterError(f"{what}: lims[6] (output labels) must be an integer >= 2, "
                             f"got {n_out!r}")
    if np.any((r < -1) | (r >= int(n_out))):
        raise ParameterError(f"{what}: rules must be -1 or 0..{int(n_out) - 1}")
    return r, m


def _emit_grid(name: str, r: IntArray, m: FloatArray, real: Real) -> str:
    n2, n1 = r.shape
    return (
        f"/* fuzzy system {name}: {n2} x {n1} rule table on uniform triangles "
        f"(fuzzyservo.fuzzy.kernels.eval_uniform_grid); rows x2, columns x1 */\n"
        + _real_check(name, real)
        + f"static const int32_t {name}_rules[{n2 * n1}] = {_int_array(r.reshape(-1))};\n"
        f"static const fs_real {name}_lims[{LIMS_SIZE}] = "
        f"{_real_array(m, real, name + '_lims')};\n"
        f"FS_MAYBE_UNUSED static fs_real {name}(fs_real x1, fs_real x2) {{\n"
        f"    return fs_grid_eval(x1, x2, {name}_rules, {n2}, {n1}, {name}_lims);\n"
        f"}}\n")


def _is_packed(rules: IntArray) -> bool:
    """``eval_system``'s dispatch: a packed system is one row (or the flat integers)."""
    a = np.asarray(rules)
    return a.ndim == 1 or (a.ndim == 2 and a.shape[0] == 1)


def _check_real(real: str) -> None:
    if real not in ("double", "float"):
        raise ParameterError(f"real must be 'double' or 'float', got {real!r}")


def emit_system(name: str, rules: IntArray, lims: FloatArray, *, real: Real) -> str:
    """C definitions of one two-input fuzzy system and ``static fs_real name(fs_real x1,
    fs_real x2)``, which evaluates it as ``fuzzyservo.control.fuzzy_pi.eval_system`` does.

    Parameters
    ----------
    name : str
        C identifier of the function; its tables are ``name_rules`` and ``name_lims`` (a
        rule table) or ``name_ints`` and ``name_floats`` (a packed system), its scratch sizes
        the macros ``NAME_WORK``, ``NAME_IWORK`` and ``NAME_SMOOTH`` (upper case; the last
        only for a system with a smooth output): local arrays of the function, storage class
        ``FS_SCRATCH`` (empty by default).
    rules : int ndarray
        A rule table (n2, n1 >= 2) for :func:`~fuzzyservo.fuzzy.kernels.eval_uniform_grid`,
        or a packed system's integers, shape (1, N) as the controllers hold them (or (N,)).
    lims : float ndarray
        The table's 8 limits, or the packed system's floats.
    real : {"double", "float"}
        The ``fs_real`` the code is compiled with; floats are written exactly (hexadecimal
        literals), in float mode as the nearest float.

    Returns
    -------
    str
        C99 text to paste after :func:`fragment`.

    Raises
    ------
    ParameterError
        A bad name, a table the C cannot hold (an integer beyond int32, a float beyond float
        range or rounding to 0 in float mode, non-finite limits of a rule table) or not a
        two-input system.
    """
    _check_real(real)
    up = name.upper() if isinstance(name, str) else ""
    _check_name(name, (f"{name}_rules", f"{name}_lims", f"{name}_ints", f"{name}_floats",
                       f"{up}_WORK", f"{up}_IWORK", f"{up}_SMOOTH"))
    if _is_packed(rules):
        ints, floats = _packed(rules, lims, real, name)
        return _emit_packed(name, ints, floats, real)
    r, m = _grid(rules, lims, name)
    for i, v in enumerate(m):
        _real_literal(float(v), real, f"{name}: lims[{i}]")
    return _emit_grid(name, r, m, real)


def emit_pair(name: str, du: tuple[IntArray, FloatArray], alpha: tuple[IntArray, FloatArray],
              *, real: Real) -> str:
    """C definitions of the self-tuning controller's two systems and ``static void
    name(fs_real x1, fs_real x2, fs_real *du, fs_real *alpha)``.

    The dispatch is ``fuzzy_pi_step``'s: ``eval_uniform_pair`` (``fs_grid_pair``: the inputs
    located once when both tables share their grid) when both systems are rule tables, else
    each system on its own (``eval_system`` twice).

    Parameters
    ----------
    name : str
        C identifier of the pair's function; the systems are emitted as ``name_du`` and
        ``name_alpha`` (:func:`emit_system`).
    du : tuple of (int ndarray, float ndarray)
        The Δu system's ``(rules, lims)`` (a rule table or a packed system).
    alpha : tuple of (int ndarray, float ndarray)
        The α system's ``(rules, lims)``.
    real : {"double", "float"}
        The ``fs_real`` the code is compiled with.

    Returns
    -------
    str
        C99 text to paste after :func:`fragment`.

    Raises
    ------
    ParameterError
        As :func:`emit_system`, for either system or the name.
    """
    _check_name(name)
    text = (emit_system(f"{name}_du", du[0], du[1], real=real)
            + emit_system(f"{name}_alpha", alpha[0], alpha[1], real=real))
    head = (f"FS_MAYBE_UNUSED static void {name}(fs_real x1, fs_real x2, fs_real *du, "
            f"fs_real *alpha) {{\n")
    if not _is_packed(du[0]) and not _is_packed(alpha[0]):
        (n2a, n1a), (n2b, n1b) = np.shape(du[0]), np.shape(alpha[0])
        body = (f"    fs_grid_pair(x1, x2, {name}_du_rules, {n2a}, {n1a}, {name}_du_lims,\n"
                f"                 {name}_alpha_rules, {n2b}, {n1b}, {name}_alpha_lims, du, "
                f"alpha);\n")
    else:
        body = f"    *du = {name}_du(x1, x2);\n    *alpha = {name}_alpha(x1, x2);\n"
    return text + f"/* {name}: the self-tuning controller's du and alpha at (x1, x2) */\n" \
        + head + body + "}\n"
