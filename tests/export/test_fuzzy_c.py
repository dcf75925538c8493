"""The C port of the fuzzy evaluators (``csrc/fuzzy.c``, ``fuzzyservo.export.fuzzy_c``)
against the compiled Python it mirrors.

Every case compiles the fragment with the strict flags (``-std=c99 -Wall -Wextra -Werror
-pedantic -O2``; float builds also ``-Wdouble-promotion -Wfloat-conversion``, so float mode
does float maths) and compares, point by point, with the numba functions the controllers
call: ``eval_uniform_grid`` and ``eval_uniform_pair`` (rule tables), ``eval_point`` /
``eval_first2`` (packed systems: the partition fast path, the exact piecewise-linear path,
singletons, Sugeno, the smooth Gauss-Kronrod path). Systems: the paper's, the same read from
the package's .fis/.fcl/.fll files, every file under ``tests/formats/data`` and fuzzylite's
installed examples that we read, the general evaluator's operator matrices and regression
cases, and random systems (``tests/formats/strategies.py``, ``tests/fuzzy/test_general.py``'s
strategies: every shape, operator, defuzzifier, weights, NOT, no rule firing). Points: random,
the universe ends, the term parameters (vertices, peaks, breakpoints) and their float
neighbours, points outside the universes, infinities and NaN.

Tolerances:

- double: |C - Python| <= 1e-13 max(1, output range) (:data:`DOUBLE_TOL`); the C does the
  same operations in the same order, so the observed difference is 0 (bit-identical) on every
  path; the tolerance leaves room for a C library whose exp/pow round otherwise than the one
  numba calls. NaN where Python gives NaN.
- float (C in float against Python in double, at float inputs): :data:`FLOAT_TOL` of the
  output's scale (its range, or the value when that is larger: unclamped Sugeno outputs).
  Measured at most 1.5e-6 (a Sugeno cubic approximator), 4e-7 on the smooth centroid and
  2e-7 on the exact paths: float rounding (6e-8) amplified by sums and the centroid's
  division. The maxima of smooth aggregates are the exception: where values tie to float
  precision (flat tops, broad peaks, near-equal maxima) float picks another point; there
  only a share of the points is held to the bound (see the test).

gcc is required: without it these tests fail.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzyservo.errors import FormatError, ParameterError
from fuzzyservo.export.fuzzy_c import emit_pair, emit_system, fragment, scratch_sizes
from fuzzyservo.formats import read_system
from fuzzyservo.fuzzy import general
from fuzzyservo.fuzzy.engine import pack
from fuzzyservo.fuzzy.general import compile_system, eval_batch, eval_first2
from fuzzyservo.fuzzy.kernels import eval_uniform_grid, eval_uniform_pair
from fuzzyservo.fuzzy.loop import loop_system
from fuzzyservo.fuzzy.system import (
    And,
    Consequent,
    FuzzySystem,
    Is,
    Not,
    Or,
    Rule,
    Term,
    Variable,
)
from fuzzyservo.paper import alpha_system, du_system
from tests.formats.fuzzylite_oracle import EXAMPLES
from tests.formats.strategies import systems as random_systems
from tests.fuzzy.test_general import FIXED, FULL, SMOOTH, TWO_GAUSS, pl_system, table_system
from tests.fuzzy.test_zero_width import zero_width_systems

from .cbuild import compile_objects, compile_shared
from .fuzzy_harness import (
    CFuzzy,
    Emitted,
    build_executable,
    build_shared,
    emitted_case,
    grid_case,
    pair_case,
    run_cases,
    sys_case,
)

#: |C - Python| in double, as a fraction of max(1, output range) (module docstring).
DOUBLE_TOL = 1e-13
#: |C float - Python double|, as a fraction of the output's scale (module docstring): 84 float
#: ulps, 7x the largest deviation measured.
FLOAT_TOL = 1e-5

ROOT = Path(__file__).resolve().parents[2]
PACKAGE_SYSTEMS = ROOT / "src" / "fuzzyservo" / "data" / "systems"
FORMAT_FILES = ROOT / "tests" / "formats" / "data"
HYP = settings(deadline=None, derandomize=True, database=None,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                      HealthCheck.large_base_example])


# --- builds (one per module and real type) ---------------------------------------------------


@pytest.fixture(scope="module")
def cd(tmp_path_factory: pytest.TempPathFactory) -> CFuzzy:
    """The harness in double."""
    return CFuzzy(build_shared("double", tmp_path_factory.mktemp("fsh_double")), "double")


@pytest.fixture(scope="module")
def cf(tmp_path_factory: pytest.TempPathFactory) -> CFuzzy:
    """The harness in float."""
    return CFuzzy(build_shared("float", tmp_path_factory.mktemp("fsh_float")), "float")


# --- comparisons -------------------------------------------------------------------------------


def _scale(lo: float, hi: float) -> float:
    """max(1, hi - lo), or the larger end when the range overflows."""
    w = hi - lo
    return max(1.0, w) if math.isfinite(w) else max(abs(lo), abs(hi))


def assert_double(c: np.ndarray, py: np.ndarray, scale: float | np.ndarray, what: str
                  ) -> float:
    """C equals Python within DOUBLE_TOL of the scale (NaN where NaN); returns the largest
    difference relative to the scale."""
    c, py = np.asarray(c, dtype=float), np.asarray(py, dtype=float)
    nan = np.isnan(py)
    assert np.array_equal(np.isnan(c), nan), f"{what}: NaN differs: C {c[np.isnan(c) != nan]}"
    with np.errstate(invalid="ignore"):
        same = (c == py) | nan
        rel = np.where(same, 0.0, np.abs(c - py) / scale)
    worst = float(np.max(rel, initial=0.0))
    if worst > DOUBLE_TOL:
        i = np.unravel_index(int(np.argmax(rel)), rel.shape)
        raise AssertionError(f"{what}: C {c[i]!r}, Python {py[i]!r} (difference {worst:.3g} "
                             f"of the scale) at index {i}")
    return worst


def float_deviation(c: np.ndarray, py: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """|C float - Python| / max(scale, |Python|); inf where exactly one of them is NaN."""
    c, py = np.asarray(c, dtype=float), np.asarray(py, dtype=float)
    with np.errstate(invalid="ignore"):
        dev = np.abs(c - py) / np.maximum(scale, np.abs(py))
    both = np.isnan(c) & np.isnan(py)
    one = np.isnan(c) != np.isnan(py)
    return np.where(both, 0.0, np.where(one, np.inf, dev))


def f32(x: np.ndarray) -> np.ndarray:
    """x rounded to float (the inputs a float controller sees), as float64."""
    with np.errstate(over="ignore"):
        return np.asarray(x, dtype=np.float32).astype(np.float64)


#: Float ulps an input is moved by to find where Python's own result is unstable.
STABLE_ULPS = 8


def float_stable(py: Callable[[np.ndarray], np.ndarray], x: np.ndarray, scale: np.ndarray
                 ) -> np.ndarray:
    """Points where Python's result stays within FLOAT_TOL / 4 of the scale (and NaN stays
    NaN) when any one input moves by STABLE_ULPS float ulps either way. Elsewhere the exact
    result jumps within float resolution (a rule starting to fire at a support's end, a tie
    between maxima) and a float evaluation, whose parameters and strengths carry that much
    rounding, may be on either side."""
    base = py(x)
    ok = np.ones(x.shape[0], dtype=bool)
    x32 = x.astype(np.float32)
    with np.errstate(invalid="ignore", over="ignore"):
        step = np.spacing(np.abs(x32)) * STABLE_ULPS
    for j in range(x.shape[1]):
        for sign in (-1.0, 1.0):
            xp = x.copy()
            xp[:, j] = f32(x32[:, j] + sign * step[:, j])
            dev = float_deviation(py(xp), base, scale).reshape(x.shape[0], -1)
            ok &= np.all(dev <= FLOAT_TOL / 4, axis=1)
    return ok


# --- points -------------------------------------------------------------------------------------


def _specials(lo: float, hi: float, params: list[float]) -> list[float]:
    w = hi - lo if math.isfinite(hi - lo) else 1.0
    pts = [lo, hi, lo - 0.25 * w, hi + 0.25 * w, 0.5 * lo + 0.5 * hi]
    for p in params:
        if math.isfinite(p):
            pts += [p, math.nextafter(p, -math.inf), math.nextafter(p, math.inf)]
    return [p for p in pts if math.isfinite(p)]


def grid_points(lims: np.ndarray, n2: int, n1: int, rng: np.random.Generator,
                n: int = 400) -> np.ndarray:
    """Random points (a little beyond the universes), the universe ends and every peak
    lo + k (hi - lo) / (n - 1) (the grid's breakpoints) and their neighbours, combined;
    infinities and NaN."""
    lo1, hi1, lo2, hi2 = (float(v) for v in lims[:4])
    s1 = _specials(lo1, hi1, [lo1 + k * (hi1 - lo1) / (n1 - 1) for k in range(n1)])
    s2 = _specials(lo2, hi2, [lo2 + k * (hi2 - lo2) / (n2 - 1) for k in range(n2)])
    w1, w2 = hi1 - lo1, hi2 - lo2
    rand = rng.uniform([lo1 - 0.2 * w1, lo2 - 0.2 * w2], [hi1 + 0.2 * w1, hi2 + 0.2 * w2],
                       (n, 2))
    mixed = np.column_stack([rng.choice(s1, n), rng.choice(s2, n)])
    grid = np.array([[a, b] for a in s1[::3] for b in s2[::3]])
    odd = np.array([[math.nan, 0.0], [0.0, math.nan], [math.nan, math.nan],
                    [math.inf, -math.inf], [-math.inf, 0.5 * (lo2 + hi2)], [1e300, -1e300]])
    return np.vstack([rand, mixed, grid, odd])


def system_points(s: FuzzySystem, rng: np.random.Generator, n: int = 24) -> np.ndarray:
    """Points of a system's inputs: special values (range ends, outside the ranges, every
    finite term parameter and its float neighbours) and random ones, mixed per input; a NaN
    input in the last row."""
    cols = []
    for v in s.inputs:
        lo, hi = v.range
        params = [p for t in v.terms for p in (t.params[0::2] if t.shape == "discrete"
                                                 else t.params)]
        spec = np.array(_specials(lo, hi, params))
        w = hi - lo if math.isfinite(hi - lo) else 1.0
        span = (lo - 0.1 * w, hi + 0.1 * w) if math.isfinite(lo - 0.1 * w) and \
            math.isfinite(hi + 0.1 * w) else (lo, hi)
        with np.errstate(over="ignore"):
            rand = rng.uniform(span[0] / 2, span[1] / 2, n) * 2 if not math.isfinite(
                span[1] - span[0]) else rng.uniform(span[0], span[1], n)
        pick = rng.random(n) < 0.5
        cols.append(np.where(pick, rng.choice(spec, n), rand))
    x = np.column_stack(cols)
    x[-1, 0] = math.nan
    return x


# --- the Python side ----------------------------------------------------------------------------


def py_sys(comp: general.CompiledSystem, x: np.ndarray) -> np.ndarray:
    """eval_point at every row (eval_batch, which does not refuse NaN inputs)."""
    out = np.empty((x.shape[0], int(comp.ints[general.H_NOUT])))
    eval_batch(comp.ints, comp.floats, np.ascontiguousarray(x), out)
    return out


def out_scales(s: FuzzySystem) -> np.ndarray:
    return np.array([_scale(*v.range) for v in s.outputs])


def check_system_double(cd: CFuzzy, s: FuzzySystem, x: np.ndarray, what: str) -> float:
    """fs_sys_eval (every output) and, for two inputs, fs_sys_eval2 against Python."""
    comp = compile_system(s)
    py = py_sys(comp, x)
    worst = assert_double(cd.sys(x, comp.ints, comp.floats), py, out_scales(s), what)
    if len(s.inputs) == 2:
        first = np.array([eval_first2(a, b, comp.ints, comp.floats) for a, b in x])
        assert np.array_equal(first, py[:, 0], equal_nan=True)  # the same function
        worst = max(worst, assert_double(cd.sys2(x[:, 0], x[:, 1], comp.ints, comp.floats),
                                         first, out_scales(s)[0], what + " (eval2)"))
    return worst


# --- the fragment -----------------------------------------------------------------------------


def test_fragment_constants_are_the_python_ones() -> None:
    text = fragment()
    defines = {m[0]: m[1] for m in re.findall(r"#define (FS_\w+) (-?[0-9]+)L?\b", text)}
    for name in ("MAGIC", "NIN", "NOUT", "NTERMS", "NRULES", "KIND", "AND", "OR", "IMPL",
                 "AGG", "DEFUZZ", "VARS", "TERMS", "RULES", "PROG", "CONS", "OUTS", "WORK",
                 "STACK", "FVARS", "FLAT", "FLATOFF", "MAXITEMS", "FWEIGHT", "PIVOT", "IWORK",
                 "GRID", "PART", "PARTF"):
        assert int(defines[f"FS_H_{name}"]) == getattr(general, f"H_{name}"), name
    assert int(defines["FS_MAGIC"]) == general.MAGIC
    codes = {"triangle": "TRI", "trapezoid": "TRAP", "rectangle": "RECT", "ramp": "RAMP",
             "discrete": "DISC", "singleton": "SING", "gaussian": "GAUSS",
             "gaussian2": "GAUSS2", "bell": "BELL", "sigmoid": "SIG", "dsigmoid": "DSIG",
             "psigmoid": "PSIG", "s": "SMF", "z": "ZMF", "pi": "PIMF", "constant": "CONST",
             "linear": "LIN"}
    assert {int(defines[f"FS_{c}"]) for c in codes.values()} == set(range(17))
    for shape, c in codes.items():
        assert int(defines[f"FS_{c}"]) == general.SHAPE_CODE[shape], shape
    assert int(defines["FS_SCAN_CELLS"]) == general.SCAN_CELLS
    assert int(defines["FS_CELL_CHANGES"]) == general.CELL_CHANGES
    assert int(defines["FS_QUAD_MAX_SUB"]) == general.QUAD_MAX_SUB
    assert int(defines["FS_OUT_FIELDS"]) == general._OUT_FIELDS
    double = text[text.index("#else\n#define FS_TOL_CLIP"):]
    assert re.search(r"#define FS_QUAD_RTOL 1e-12\n", double)  # general.QUAD_RTOL
    assert general.QUAD_RTOL == 1e-12
    for cname, table in (("fs_xgk", general._XGK), ("fs_wgk", general._WGK),
                         ("fs_wg", general._WG)):
        body = text[text.index(f"{cname}["):].split("};")[0]
        lits = re.findall(r"FS_R\((0x[0-9a-fp.+-]+)\)", body)
        assert [float.fromhex(v) for v in lits] == table.tolist(), cname


def test_fragment_is_static_and_self_contained() -> None:
    text = fragment()
    code = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    # every function is static and named fs_*; only the C standard library is included
    heads = re.findall(r"^(?:FS_MAYBE_UNUSED )?(static )?[a-z_0-9]+ \*?(\w+)\(", code, re.M)
    assert heads and all(st_ == "static " and name.startswith("fs_") for st_, name in heads)
    assert set(re.findall(r"#include <([^>]+)>", code)) <= {"math.h", "stdint.h", "float.h",
                                                            "string.h"}
    assert "malloc" not in code and "alloca" not in code
    # no writable storage outside functions: file-scope tables are const
    assert not re.search(r"^static (?!const)[^(]*;", code, re.M)


# --- rule tables on uniform triangles -----------------------------------------------------------


def _grid(system: FuzzySystem) -> tuple[np.ndarray, np.ndarray]:
    """The uniform-grid tables of a paper system (``pack`` takes that path for them)."""
    packed = pack(system)
    assert packed.path == "uniform grid"
    return packed.kernel_args()


@pytest.mark.parametrize("make", [du_system, alpha_system], ids=["du", "alpha"])
def test_paper_rule_tables_are_bit_identical(cd: CFuzzy, make: object) -> None:
    rules, lims = _grid(make())  # type: ignore[operator]
    x = grid_points(lims, *rules.shape, np.random.default_rng(1), n=5000)
    py = np.array([eval_uniform_grid(a, b, rules, lims) for a, b in x])
    c = cd.grid(x[:, 0], x[:, 1], rules, lims)
    # the same operations in the same order: nothing to round differently
    assert np.array_equal(c, py, equal_nan=True)


def _random_table(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    n2, n1, n_out = (int(v) for v in rng.integers(2, 9, 3))
    rules = rng.integers(-1, n_out, (n2, n1))
    lo = rng.uniform(-3, 1, 3)
    hi = lo + rng.choice([0.5, 1.0, 2.0, 1 / 3, 7.25], 3)
    default = rng.choice([math.nan, 0.0, float(lo[2])])
    lims = np.array([lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], n_out, default])
    return rules, lims


def test_random_rule_tables(cd: CFuzzy) -> None:
    rng = np.random.default_rng(2)
    for k in range(60):
        rules, lims = _random_table(rng)
        x = grid_points(lims, *rules.shape, rng, n=300)
        py = np.array([eval_uniform_grid(a, b, rules, lims) for a, b in x])
        assert_double(cd.grid(x[:, 0], x[:, 1], rules, lims), py,
                      _scale(lims[4], lims[5]), f"table {k}")


def test_pairs_on_the_same_and_on_other_grids(cd: CFuzzy) -> None:
    (ra, la), (rb, lb) = _grid(du_system()), _grid(alpha_system())
    rng = np.random.default_rng(3)
    other_lims = lb.copy()
    other_lims[2:4] = [-0.5, 2.0]  # another x2 universe: located again
    r5 = rng.integers(-1, 7, (5, 5))  # another table shape: located again
    for rb_, lb_ in ((rb, lb), (rb, other_lims), (r5, lb), (ra, la)):
        x = grid_points(la, *ra.shape, rng, n=2000)
        want = np.array([eval_uniform_pair(a, b, ra, la, rb_, lb_) for a, b in x])
        ca, cb = cd.pair(x[:, 0], x[:, 1], ra, la, rb_, lb_)
        assert np.array_equal(ca, want[:, 0], equal_nan=True)
        assert np.array_equal(cb, want[:, 1], equal_nan=True)


# --- packed systems: the paper's, files -------------------------------------------------------


@pytest.mark.parametrize("path", sorted(PACKAGE_SYSTEMS.glob("paper-*")), ids=lambda p: p.name)
def test_paper_files_take_the_partition_path_bit_identically(cd: CFuzzy, path: Path) -> None:
    rules, lims = loop_system(read_system(path), source=path.name, grid=False).kernel_args()
    assert rules[0, general.H_PART] >= 0  # the partition fast path
    x = grid_points(np.array([-1.0, 1.0, -1.0, 1.0]), 7, 7, np.random.default_rng(4),
                    n=3000)
    py = np.array([eval_first2(a, b, rules[0], lims) for a, b in x])
    c = cd.sys2(x[:, 0], x[:, 1], rules[0], lims)
    assert np.array_equal(c, py, equal_nan=True)


@pytest.mark.parametrize("defuzzifier", ["centroid", "bisector", "mom", "som", "lom"])
@pytest.mark.parametrize("aggregation", ["max", "sum"])
def test_paper_systems_on_the_general_path(cd: CFuzzy, defuzzifier: str,
                                          aggregation: str) -> None:
    # off the partition fast path (it takes max and centroid only): the exact
    # piecewise-linear path on the paper's 7 x 7 tables
    rng = np.random.default_rng(5)
    for make in (du_system, alpha_system):
        s = dataclasses.replace(make(), defuzzifier=defuzzifier,
                                aggregation=aggregation)
        x = grid_points(np.array([-1.0, 1.0, -1.0, 1.0]), 7, 7, rng, n=150)
        check_system_double(cd, s, x, f"{make.__name__} {defuzzifier} {aggregation}")


def system_files() -> list[Path]:
    """Every system file of tests/formats/data, the package and fuzzylite's examples."""
    roots = [FORMAT_FILES, PACKAGE_SYSTEMS, EXAMPLES]
    return sorted(p for r in roots for ext in ("fis", "fcl", "fll") for p in r.rglob(f"*.{ext}"))


def _readable() -> Iterator[tuple[str, FuzzySystem]]:
    for p in system_files():
        try:
            yield str(p.relative_to(p.parents[2])), read_system(p)
        except (FormatError, ParameterError):
            continue  # refused by the reader (tests/formats checks which and why)


def test_the_system_files_are_found() -> None:
    # fuzzylite's examples are installed by `make oracles` (a missing oracle fails)
    assert len(system_files()) >= 90
    assert sum(1 for _ in _readable()) >= 50


@pytest.mark.parametrize(("name", "system"), list(_readable()) or [("<none>", None)],
                         ids=lambda v: v if isinstance(v, str) else "")
def test_system_files(cd: CFuzzy, name: str, system: FuzzySystem) -> None:
    assert system is not None, "no system file found"
    x = system_points(system, np.random.default_rng(6), n=40)
    check_system_double(cd, system, x, name)


# --- packed systems: every operator and method, the regressions ------------------------------


@pytest.mark.parametrize("defuzzifier", ["centroid", "bisector", "mom", "som", "lom"])
@pytest.mark.parametrize("aggregation", ["max", "bounded_sum", "sum"])
def test_piecewise_linear_operator_matrix(cd: CFuzzy, aggregation: str,
                                          defuzzifier: str) -> None:
    rng = np.random.default_rng(7)
    for and_op in ("min", "product"):
        for or_op in ("max", "probor"):
            for implication in ("min", "product"):
                s = dataclasses.replace(FIXED, and_op=and_op, or_op=or_op,
                                        implication=implication, aggregation=aggregation,
                                        defuzzifier=defuzzifier)
                check_system_double(cd, s, system_points(s, rng, n=12), str(s.rules[0]))


@pytest.mark.parametrize("defuzzifier", ["centroid", "bisector", "mom", "som", "lom"])
@pytest.mark.parametrize("aggregation", ["max", "bounded_sum", "sum", "probor"])
def test_smooth_operator_matrix(cd: CFuzzy, aggregation: str, defuzzifier: str) -> None:
    rng = np.random.default_rng(8)
    for implication in ("min", "product"):
        s = dataclasses.replace(SMOOTH, aggregation=aggregation, implication=implication,
                                defuzzifier=defuzzifier)
        x = np.vstack([[[0.3, -0.4], [0.75, 0.5], [0.05, 0.95], [0.5, 0.0], [1.0, -1.0]],
                       system_points(s, rng, n=6)])
        check_system_double(cd, s, x, f"SMOOTH {implication}")


def regression_systems() -> list[tuple[str, FuzzySystem, list[list[float]]]]:
    """The general evaluator's regression cases (tests/fuzzy/test_general.py), each at the
    points its bug showed."""
    one_in = Variable("x", (0.0, 1.0), (Term("lo", "triangle", (-1.0, 0.0, 1.0)),
                                        Term("hi", "triangle", (0.0, 1.0, 2.0))))
    ramp_in = Variable("x", (0.0, 1.0), (Term("r", "ramp", (0.0, 1.0)),))
    out: list[tuple[str, FuzzySystem, list[list[float]]]] = []
    for d in ("centroid", "bisector", "mom", "som", "lom"):
        plateau = Variable("y", (0.0, 0.5), (
            Term("o", "trapezoid", (0.0, 0.0, 0.0, 0.125), 0.5),
            Term("p", "triangle", (0.25, 0.375, 0.5))))
        out.append((f"weak plateau {d}", FuzzySystem(
            inputs=(ramp_in,), outputs=(plateau,), defuzzifier=d,
            rules=(Rule(Is(0, 0), (Consequent(0, 0),)),
                   Rule(Is(0, 0), (Consequent(0, 1),), weight=0.25))),
            [[1e-4], [1e-8], [1e-12], [1e-15]]))
        eps = 2.0**-50
        edge = Variable("y", (0.0, 1.0), (
            Term("step", "discrete", (0.0, 0.0, 0.5 + eps, 0.0, 0.5 + eps, 1.0, 1.0, 1.0)),
            Term("tri", "triangle", (0.25, 0.5, 0.75)),
            Term("sliver", "rectangle", (0.125, 0.125 + 1e-14), height=0.25)))
        for imp in ("min", "product"):
            out.append((f"vertical edge {d} {imp}", FuzzySystem(
                inputs=(one_in,), outputs=(edge,), implication=imp, defuzzifier=d,
                rules=(Rule(Is(0, 0), (Consequent(0, 0), Consequent(0, 2))),
                       Rule(Is(0, 1), (Consequent(0, 1),)))), [[0.3], [0.6], [0.0], [1.0]]))
    for imp in ("min", "product"):
        tri = Variable("y", (0.0, 4.0), (Term("t", "triangle", (0.0, 3.0, 4.0)),))
        out.append((f"weak bisector {imp}", FuzzySystem(
            inputs=(ramp_in,), outputs=(tri,), defuzzifier="bisector", implication=imp,
            rules=(Rule(Is(0, 0), (Consequent(0, 0),)),)), [[1e-174], [1e-300], [0.5]]))
    for d in ("mom", "som", "lom", "centroid", "bisector"):
        out.append((f"two gaussians {d}", dataclasses.replace(TWO_GAUSS, defuzzifier=d),
                    [[0.55], [0.45], [0.3]]))
        bells = Variable("y", (2.661909850584017, 8.051569729651108), (
            Term("z", "z", (3.631296154155191, 7.355863971656047)),
            Term("b1", "bell", (7.353769838081282, 0.32351639016859596, 1.293895970507795),
                 0.664116727852507),
            Term("b2", "bell", (4.45116579671814, 1.006757130259792, 2.177328355919955),
                 0.9609145246388349)))
        out.append((f"steep bell {d}", FuzzySystem(
            inputs=(FULL,), outputs=(bells,), implication="product", aggregation="probor",
            defuzzifier=d, rules=tuple(Rule(Is(0, 0), (Consequent(0, j),), weight=w)
                                       for j, w in ((1, 1.0), (1, 0.16697255156056712),
                                                    (2, 0.2747010253720238),
                                                    (0, 0.40010261059859037)))), [[0.5]]))
        pi = Variable("y", (-1.6702824544327264, 7.005912949860138), (Term(
            "p", "pi", (-2.456312312092072, -1.4726463844023334, 3.765901739057053,
                        7.008031742631984)),))
        out.append((f"full plateau {d}", FuzzySystem(
            inputs=(FULL,), outputs=(pi,), defuzzifier=d,
            rules=(Rule(Is(0, 0), (Consequent(0, 0),)),)), [[0.5], [0.25]]))
    dsig = Variable("y", (-1.1855219145578468, 5.554708546842855), (
        Term("d", "dsigmoid", (5.2817628745602, 0.30109946035904694, 3.7501200933618577,
                               5.293919614794379), 0.8085717542925399),
        Term("e", "dsigmoid", (0.37448776481894996, 3.4486041556683307, 0.7482216646448595,
                               4.286724566387948))))
    for d in ("centroid", "bisector"):
        out.append((f"dsigmoid bend {d}", FuzzySystem(
            inputs=(FULL,), outputs=(dsig,), defuzzifier=d, aggregation="sum",
            rules=(Rule(Is(0, 1), (Consequent(0, 0),)), Rule(Is(0, 0), (Consequent(0, 1),)))),
            [[0.3345311121081156]]))
    x0 = Variable("x0", (0.0, 9.0), (Term("t0", "triangle", (0.0, 0.0, 2.25)),
                                      Term("t2", "triangle", (0.0, 0.0, 10.0))), clip=False)
    y0 = Variable("y0", (0.0, 1.0), (Term("o0", "triangle", (0.0, 0.0, 0.25)),))
    out.append(("probor of one", FuzzySystem(
        inputs=(x0,), outputs=(y0,), or_op="probor", defuzzifier="bisector",
        rules=(Rule(Not(Or((Is(0, 0, True), Is(0, 1)))), (Consequent(0, 0),)),)), [[2.25]]))
    return out + zero_width_systems()


@pytest.mark.parametrize(("name", "system", "points"), regression_systems(),
                         ids=[r[0] for r in regression_systems()])
def test_general_evaluator_regressions(cd: CFuzzy, name: str, system: FuzzySystem,
                                       points: list[list[float]]) -> None:
    check_system_double(cd, system, np.array(points, dtype=float), name)


def test_unclipped_input_far_outside_a_partition(cd: CFuzzy) -> None:
    # the partition path locates an unclipped input from t = (x - x0) / spacing; Python's
    # int(t) overflows for t >= 2^63 (reported); the C gives what every smaller t beyond the
    # last vertex gives
    tri = (Term("a", "triangle", (-1.0, 0.0, 1.0)), Term("b", "triangle", (0.0, 1.0, 2.0)))
    x = Variable("x", (0.0, 1.0), tri, clip=False)
    s = FuzzySystem(inputs=(x, dataclasses.replace(x, name="y")),
                    outputs=(Variable("u", (0.0, 1.0), tri, default=0.25),),
                    rules=tuple(Rule(And((Is(0, i), Is(1, j))), (Consequent(0, (i + j) % 2),))
                                for i in range(2) for j in range(2)))
    comp = compile_system(s)
    assert comp.ints[general.H_PART] >= 0
    big = np.array([[1e19, 0.5], [1e300, 0.5], [math.inf, 0.5], [-1e300, 0.5]])
    moderate = np.array([[1e10, 0.5], [1e10, 0.5], [1e10, 0.5], [-1e10, 0.5]])
    c = cd.sys(big, comp.ints, comp.floats)
    assert np.array_equal(c, py_sys(comp, moderate), equal_nan=True)


# --- random systems ---------------------------------------------------------------------------


@settings(HYP, max_examples=250)
@given(data=st.data())
def test_random_systems(cd: CFuzzy, data: st.DataObject) -> None:
    # every shape and operator, extreme ranges and heights, weights, NOT, no rule firing
    s = data.draw(random_systems())
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    check_system_double(cd, s, system_points(s, rng, n=8), "random system")


@settings(HYP, max_examples=150)
@given(data=st.data())
def test_random_piecewise_linear_and_table_systems(cd: CFuzzy, data: st.DataObject) -> None:
    s = data.draw(pl_system() if data.draw(st.booleans()) else table_system())
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    check_system_double(cd, s, system_points(s, rng, n=8), "random system")


# --- the generated functions (emit_system, emit_pair) -----------------------------------------


def _emitted_set() -> tuple[Emitted, list[tuple[str, object]]]:
    """Systems in every form the generator emits, with the Python call each mirrors: the
    paper's tables, every two-input system file (all paths of the general evaluator, with
    their tables constant: what the compiler sees in generated code), pairs of each kind."""
    du, al = _grid(du_system()), _grid(alpha_system())
    gen_du = loop_system(read_system(PACKAGE_SYSTEMS / "paper-du.fis"),
                         grid=False).kernel_args()
    smooth = loop_system(dataclasses.replace(SMOOTH, defuzzifier="bisector"),
                         no_rule_value=0.5).kernel_args()
    pl = loop_system(dataclasses.replace(FIXED, defuzzifier="mom")).kernel_args()
    singles: list[tuple[str, np.ndarray, np.ndarray]] = [
        ("e_grid", *du), ("e_part", *gen_du), ("e_smooth", *smooth), ("e_pl", *pl)]
    kinds: list[tuple[str, object]] = [("grid", du), ("general", gen_du), ("general", smooth),
                                       ("general", pl)]
    for k, (_, s) in enumerate(_readable()):
        if len(s.inputs) == 2:
            comp = compile_system(s)
            tables = (comp.ints[None, :].copy(), comp.floats.copy())
            singles.append((f"e_file{k}", *tables))
            kinds.append(("general", tables))
    em = Emitted(singles=singles,
                 pairs=[("p_grids", du, al), ("p_mixed", du, smooth), ("p_general", pl, gen_du)])
    return em, kinds + [("pair", (du, al)), ("two", (du, smooth)), ("two", (pl, gen_du))]


def _box(rules: np.ndarray, lims: np.ndarray) -> np.ndarray:
    """The two inputs' ranges (lo1, hi1, lo2, hi2) of a rule table or a packed system."""
    if rules.shape[0] != 1:
        return lims[:4]
    f = int(rules[0, general.H_FVARS])
    return np.array([lims[f], lims[f + 1], lims[f + 4], lims[f + 5]])


def _out_range(rules: np.ndarray, lims: np.ndarray) -> float:
    """The width of output 0's range of a rule table or a packed system."""
    if rules.shape[0] != 1:
        return float(lims[5] - lims[4])
    f = int(rules[0, general.H_FVARS]) + 4 * int(rules[0, general.H_NIN])
    return float(lims[f + 1] - lims[f])


def _eval_system(rules: np.ndarray, lims: np.ndarray, a: float, b: float) -> float:
    """fuzzy_pi.eval_system's dispatch."""
    if rules.shape[0] == 1:
        return float(eval_first2(a, b, rules[0], lims))
    return float(eval_uniform_grid(a, b, rules, lims))


def _expected(kind: str, tables: object, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    zeros = np.zeros(x.shape[0])
    if kind in ("grid", "general"):
        r, m = tables  # type: ignore[misc]
        return np.array([_eval_system(r, m, a, b) for a, b in x]), zeros
    (ra, la), (rb, lb) = tables  # type: ignore[misc]
    if kind == "pair":
        v = np.array([eval_uniform_pair(a, b, ra, la, rb, lb) for a, b in x])
        return v[:, 0], v[:, 1]
    return (np.array([_eval_system(ra, la, a, b) for a, b in x]),
            np.array([_eval_system(rb, lb, a, b) for a, b in x]))


@pytest.mark.parametrize("real", ["double", "float"])
def test_emitted_functions(tmp_path: Path, real: str) -> None:
    em, kinds = _emitted_set()
    c = CFuzzy(build_shared(real, tmp_path, em), real)
    rng = np.random.default_rng(9)
    for k, (kind, tables) in enumerate(kinds):
        first = tables[0] if kind in ("pair", "two") else tables  # type: ignore[index]
        x = grid_points(_box(*first), 7, 7, rng, n=60)  # type: ignore[misc]
        x = f32(x) if real == "float" else x
        want_a, want_b = _expected(kind, tables, x)
        got_a, got_b = c.emitted(k, x[:, 0], x[:, 1])
        if real == "double":
            assert np.array_equal(got_a, want_a, equal_nan=True), (k, kind)
            assert np.array_equal(got_b, want_b, equal_nan=True), (k, kind)
        else:
            def both(xs: np.ndarray, kind: str = kind, tables: object = tables) -> np.ndarray:
                return np.column_stack(_expected(kind, tables, xs))

            second = tables[1] if kind in ("pair", "two") else None  # type: ignore[index]
            scale = np.array([_out_range(*first),  # type: ignore[misc]
                              _out_range(*second) if second is not None else 1.0])
            ok = float_stable(both, x, scale)
            assert np.mean(ok) > 0.8, (k, np.mean(ok))
            for got, want, sc in ((got_a, want_a, scale[0]), (got_b, want_b, scale[1])):
                dev = float_deviation(got, want, np.full(want.shape, sc))
                assert np.max(dev[ok]) <= FLOAT_TOL, (k, kind, np.max(dev[ok]))


def _alone(real: str, name: str, body: str, call: str) -> str:
    head = "typedef double fs_real;\n" if real == "double" else \
        "typedef float fs_real;\n#define FS_FLOAT 1\n"
    return head + fragment() + body + f"fs_real call_{name}(fs_real a, fs_real b);\n" \
        f"fs_real call_{name}(fs_real a, fs_real b) {{ {call} }}\n"


def test_each_generated_system_compiles_alone(tmp_path: Path) -> None:
    # Generated code holds one or two systems and calls each once: the compiler inlines the
    # evaluator and propagates the constant tables, and its warnings (-Warray-bounds on paths
    # the tables never take) are errors under the strict flags. Each form alone in its own
    # translation unit: the two-input system files at -O2 in double, one per form (the paths
    # it takes), and the pairs; some at -O3 and in float.
    em, _ = _emitted_set()
    du, al = _grid(du_system()), _grid(alpha_system())

    def units(real: str, singles: list[tuple[str, np.ndarray, np.ndarray]], pairs: bool
              ) -> list[str]:
        out = [_alone(real, n, emit_system(n, r, m, real=real), f"return {n}(a, b);")  # type: ignore[arg-type]
               for n, r, m in singles]
        if pairs:
            for n, x, y in em.pairs:
                out.append(_alone(real, n, emit_pair(n, x, y, real=real),  # type: ignore[arg-type]
                                  f"fs_real u, v; {n}(a, b, &u, &v); return u + v;"))
        return out

    def form(rules: np.ndarray) -> tuple[int, ...]:
        """The paths a system takes: its output modes, partition, grid, pivot, flat rules."""
        if rules.shape[0] != 1:
            return (-1,)
        i = rules[0]
        ot = int(i[general.H_OUTS])
        return (*(int(i[ot + general._OUT_FIELDS * o]) for o in range(int(i[general.H_NOUT]))),
                *(int(i[k] >= 0) for k in (general.H_PART, general.H_GRID, general.H_PIVOT)),
                int(i[general.H_FLAT]))

    forms = {form(r): (n, r, m) for n, r, m in reversed(em.singles)}
    compile_objects(units("double", list(forms.values()), True), tmp_path / "o2")
    some = em.singles[:4] + [("e_alpha", *al), ("e_du", *du)]
    compile_objects(units("double", some, False), tmp_path / "o3", flags=("-O3",))
    compile_objects(units("float", some, True), tmp_path / "float",
                    flags=("-O2", "-Wdouble-promotion", "-Wfloat-conversion"))


def test_emitted_tables_are_exact() -> None:
    rules, lims = loop_system(read_system(PACKAGE_SYSTEMS / "paper-alpha.fll"),
                              grid=False).kernel_args()
    text = emit_system("sys", rules, lims, real="double")
    body = text[text.index("sys_floats["):].split("};")[0].split("=", 1)[1]
    lits = [v.strip(" {\n") for v in body.split(",")]
    assert np.array_equal([float.fromhex(v) if v != "NAN" else math.nan for v in lits], lims,
                          equal_nan=True)
    ints = text[text.index("sys_ints["):].split("};")[0].split("=", 1)[1]
    assert [int(v.strip(" {\n")) for v in ints.split(",")] == rules[0].tolist()
    sz = scratch_sizes(rules[0])
    assert f"#define SYS_WORK {sz.work}\n" in text and f"#define SYS_IWORK {sz.iwork}\n" in text
    assert sz.smooth == 0 and "SYS_SMOOTH" not in text and "iwork, NULL);" in text
    # the partition path: the inputs and its scratch only (7 + 7 input terms, 7 output terms)
    assert sz.work == 2 + (2 + 14 + 7 + 8) < rules[0, general.H_WORK]
    ftext = emit_system("sys", rules, lims, real="float")
    body = ftext[ftext.index("sys_floats["):].split("};")[0].split("=", 1)[1]
    lits = [v.strip(" {\n") for v in body.split(",")]
    assert all(v.endswith("f") or v == "NAN" for v in lits)
    assert np.array_equal([float.fromhex(v[:-1]) if v != "NAN" else math.nan for v in lits],
                          f32(lims), equal_nan=True)


def test_emitted_code_refuses_the_other_real_type(tmp_path: Path) -> None:
    du = _grid(du_system())
    text = "typedef float fs_real;\n#define FS_FLOAT 1\n" + fragment() + \
        emit_system("sys", *du, real="double")
    with pytest.raises(AssertionError, match="sys_needs_double"):
        compile_shared(text, tmp_path)


# --- sanitizers -------------------------------------------------------------------------------


def test_under_address_and_undefined_behaviour_sanitizers(tmp_path: Path) -> None:
    # a driver executable: each scratch array malloc'ed at exactly the size scratch_sizes
    # gives (an overrun is reported), the generated functions' fixed-size local arrays
    em, kinds = _emitted_set()
    exe = build_executable("double", tmp_path, em, sanitize=True)
    rng = np.random.default_rng(10)
    cases: list[bytes] = []
    expect: list[np.ndarray] = []
    (ra, la), (rb, lb) = _grid(du_system()), _grid(alpha_system())
    xg = grid_points(la, 7, 7, rng, n=200)
    cases.append(grid_case(ra, la, xg))
    expect.append(np.array([eval_uniform_grid(a, b, ra, la) for a, b in xg]))
    cases.append(pair_case(ra, la, rb, lb, xg))
    pair = np.array([eval_uniform_pair(a, b, ra, la, rb, lb) for a, b in xg])
    expect += [pair[:, 0], pair[:, 1]]
    systems = [s for _, s in _readable()]
    systems += [dataclasses.replace(SMOOTH, aggregation=a, defuzzifier=d)
                for a in ("max", "probor") for d in ("centroid", "bisector", "mom")]
    systems += [dataclasses.replace(FIXED, aggregation=a, defuzzifier=d)
                for a in ("max", "bounded_sum") for d in ("bisector", "lom")]
    systems += [s for _, s, _ in regression_systems()]
    systems += [_seeded_random_system(k) for k in range(40)]
    for s in systems:
        comp = compile_system(s)
        x = system_points(s, rng, n=6)
        cases.append(sys_case(comp.ints, comp.floats, x))
        py = py_sys(comp, x)
        expect.append(py.reshape(-1))
        if len(s.inputs) == 2:
            expect.append(py[:, 0])
    xe = grid_points(np.array([-1.0, 1.0, -1.0, 1.0]), 7, 7, rng, n=40)
    for k, (kind, tables) in enumerate(kinds):
        cases.append(emitted_case(k, xe))
        expect += list(_expected(kind, tables, xe))
    got = run_cases(exe, cases, tmp_path)
    want = np.concatenate(expect)
    assert got.shape == want.shape
    assert np.array_equal(got, want, equal_nan=True)


def _seeded_random_system(seed: int) -> FuzzySystem:
    from tests.formats.strategies import NumpyRand, random_system

    return random_system(NumpyRand(np.random.default_rng(1000 + seed)))


# --- float ----------------------------------------------------------------------------------


@pytest.mark.parametrize("make", [du_system, alpha_system], ids=["du", "alpha"])
def test_float_rule_tables_and_pair(cf: CFuzzy, make: object) -> None:
    rules, lims = _grid(make())  # type: ignore[operator]
    x = f32(grid_points(lims, *rules.shape, np.random.default_rng(11), n=3000))
    py = np.array([eval_uniform_grid(a, b, rules, lims) for a, b in x])
    scale = np.full(py.shape, lims[5] - lims[4])
    assert np.max(float_deviation(cf.grid(x[:, 0], x[:, 1], rules, lims), py, scale)) \
        <= FLOAT_TOL
    (ra, la), (rb, lb) = _grid(du_system()), _grid(alpha_system())
    want = np.array([eval_uniform_pair(a, b, ra, la, rb, lb) for a, b in x])
    ca, cb = cf.pair(x[:, 0], x[:, 1], ra, la, rb, lb)
    assert np.max(float_deviation(ca, want[:, 0], scale)) <= FLOAT_TOL
    assert np.max(float_deviation(cb, want[:, 1], scale)) <= FLOAT_TOL


def float_systems() -> list[tuple[str, FuzzySystem]]:
    """Systems whose numbers a float holds, with moderate ranges: the files, the paper's on
    the general paths, the operator matrices and the regression cases."""
    out = list(_readable())
    for make in (du_system, alpha_system):
        for d in ("centroid", "bisector", "mom", "som", "lom"):
            out.append((f"{make.__name__} {d}",
                        dataclasses.replace(make(), defuzzifier=d)))
    for agg in ("max", "bounded_sum", "sum", "probor"):
        for imp in ("min", "product"):
            for d in ("centroid", "bisector", "mom", "som", "lom"):
                out.append((f"SMOOTH {agg} {imp} {d}", dataclasses.replace(
                    SMOOTH, aggregation=agg, implication=imp, defuzzifier=d)))
                if agg != "probor":
                    out.append((f"FIXED {agg} {imp} {d}", dataclasses.replace(
                        FIXED, aggregation=agg, implication=imp, defuzzifier=d)))
    return out


def to_float(s: FuzzySystem) -> FuzzySystem | None:
    """``s`` with every number rounded to float (None if that makes it invalid)."""
    def r(v: float) -> float:
        return float(np.float32(v)) if math.isfinite(v) else v

    def var(v: Variable) -> Variable:
        return dataclasses.replace(v, range=(r(v.range[0]), r(v.range[1])), default=r(
            v.default), terms=tuple(dataclasses.replace(t, params=tuple(map(r, t.params)),
                                                        height=r(t.height)) for t in v.terms))

    try:
        return dataclasses.replace(s, inputs=tuple(map(var, s.inputs)),
                                   outputs=tuple(map(var, s.outputs)),
                                   rules=tuple(dataclasses.replace(rl, weight=r(rl.weight))
                                               for rl in s.rules))
    except ParameterError:
        return None


def _smooth_maxima(comp: general.CompiledSystem, s: FuzzySystem) -> np.ndarray:
    """Per output: True for a smooth output defuzzified by a maximum method."""
    ot = int(comp.ints[general.H_OUTS])
    return np.array([s.defuzzifier in ("mom", "som", "lom") and int(
        comp.ints[ot + general._OUT_FIELDS * o]) == general._M_SMOOTH
        for o in range(len(s.outputs))])


def test_float_general_systems(cf: CFuzzy) -> None:
    rng = np.random.default_rng(12)
    exact: list[np.ndarray] = []
    maxima: list[np.ndarray] = []
    for _, s in float_systems():
        comp = compile_system(s)
        lo = np.array([v.range[0] for v in s.inputs])
        hi = np.array([v.range[1] for v in s.inputs])
        x = f32(rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), (24, len(s.inputs))))
        py = py_sys(comp, x)
        dev = float_deviation(cf.sys(x, comp.ints, comp.floats), py,
                              np.array([v.range[1] - v.range[0] for v in s.outputs]))
        sm = _smooth_maxima(comp, s)
        exact.append(dev[:, ~sm].ravel())
        maxima.append(dev[:, sm].ravel())
        if len(s.inputs) == 2:  # the two-input call does the same
            c2 = cf.sys2(x[:, 0], x[:, 1], comp.ints, comp.floats)
            assert np.array_equal(c2, cf.sys(x, comp.ints, comp.floats)[:, 0],
                                  equal_nan=True)
    e, m = np.concatenate(exact), np.concatenate(maxima)
    assert e.size > 5000 and np.max(e) <= FLOAT_TOL, np.max(e)
    # the maxima of smooth aggregates: a float locates a smooth maximum to ~1e-5 of the
    # range (measured: 90 % of the points), but where the aggregate is flat to float
    # precision (a steep bell's top, a broad peak) or two maxima tie within it, another
    # maximising point is taken (measured up to 0.11 of the range): every result in range,
    # NaN exactly where Python's is, most within the bound
    assert m.size > 1500 and np.all(np.isfinite(m)) and np.max(m) <= 1.0
    assert np.mean(m <= FLOAT_TOL) >= 0.85, np.mean(m <= FLOAT_TOL)


@settings(HYP, max_examples=100)
@given(data=st.data())
def test_float_random_piecewise_linear_and_table_systems(cf: CFuzzy,
                                                         data: st.DataObject) -> None:
    # the system with its numbers rounded to float, as the float code holds them: what is
    # compared is then float arithmetic against double arithmetic
    s = to_float(data.draw(pl_system() if data.draw(st.booleans()) else table_system()))
    if s is None:
        return  # rounding to float made it invalid (two vertices merged)
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    comp = compile_system(s)
    x = f32(system_points(s, rng, n=8))
    scale = np.array([v.range[1] - v.range[0] for v in s.outputs])
    ok = float_stable(lambda xs: py_sys(comp, xs), x, scale)
    dev = float_deviation(cf.sys(x, comp.ints, comp.floats), py_sys(comp, x), scale)
    assert np.max(dev[ok], initial=0.0) <= FLOAT_TOL, (np.max(dev[ok]), x[ok].tolist())


@pytest.mark.parametrize(("name", "system", "points"), regression_systems(),
                         ids=[r[0] for r in regression_systems()])
def test_float_regressions(cf: CFuzzy, name: str, system: FuzzySystem,
                           points: list[list[float]]) -> None:
    # the general evaluator's regression cases hold in float too
    comp = compile_system(system)
    x = f32(np.array(points))
    py = py_sys(comp, x)
    dev = float_deviation(cf.sys(x, comp.ints, comp.floats), py, out_scales(system))
    # the steep bell's maximum lies 0.0018 from its centre, where |t|^2.59 leaves the top flat
    # to float precision over ~1e-4 of the range (measured 3.3e-5); elsewhere FLOAT_TOL
    bound = 1e-4 if name.startswith("steep bell") and system.defuzzifier in (
        "mom", "som", "lom") else FLOAT_TOL
    assert np.max(dev) <= bound, (np.max(dev), name)


# --- validation -------------------------------------------------------------------------------


def test_bad_tables_are_refused_in_one_line() -> None:
    du = _grid(du_system())
    packed = loop_system(read_system(PACKAGE_SYSTEMS / "paper-du.fis"),
                         grid=False).kernel_args()
    cases: list[tuple[object, object, str, str]] = [
        (du[0] + 2**31, du[1], "double", "int32"),
        (du[0], np.r_[du[1][:7], 0.0][:7], "double", "8 lims"),
        (du[0], np.r_[math.nan, du[1][1:]], "double", "finite"),
        (du[0], np.r_[1.0, -1.0, du[1][2:]], "double", "lo < hi"),
        (du[0], np.r_[du[1][:6], 2.5, du[1][7]], "double", "integer"),
        (np.full((7, 7), 7), du[1], "double", "rules must be"),
        (np.array([[0.5, 1.0], [1.0, 1.0]]), du[1], "double", "integers"),
        (packed[0][:, :20], packed[1], "double", "not a packed"),
        (packed[0], np.r_[packed[1][:-1], 1e39], "float", "largest float"),
        (packed[0], np.r_[packed[1][:-1], 1e-300], "float", "rounds to 0"),
        (packed[0], packed[1], "single", "real must be"),
    ]
    for rules, lims, real, msg in cases:
        with pytest.raises(ParameterError, match=msg) as info:
            emit_system("sys", rules, lims, real=real)  # type: ignore[arg-type]
        assert "\n" not in str(info.value)
    three = compile_system(dataclasses.replace(
        SMOOTH, inputs=(*SMOOTH.inputs, dataclasses.replace(SMOOTH.inputs[0], name="w"))))
    with pytest.raises(ParameterError, match="two inputs"):
        emit_system("sys", three.ints[None, :], three.floats, real="double")
    for name in ("2x", "a-b", "int", "fs_sys_eval", "fs_real", ""):
        with pytest.raises(ParameterError, match="C name"):
            emit_system(name, *du, real="double")
    with pytest.raises(ParameterError, match="would redefine 'fs_min'"):
        emit_pair("fs_min", du, du, real="double")


def test_names_the_generator_uses_are_accepted() -> None:
    du, al = _grid(du_system()), _grid(alpha_system())
    text = emit_pair("fs_sys", du, al, real="float")
    assert "static void fs_sys(fs_real x1, fs_real x2, fs_real *du, fs_real *alpha)" in text
    assert "fs_grid_pair(x1, x2, fs_sys_du_rules, 7, 7" in text
    assert "static fs_real fs_sys_du(fs_real x1, fs_real x2)" in \
        emit_system("fs_sys_du", *du, real="double")


def test_scratch_sizes_cover_every_path() -> None:
    packed = loop_system(read_system(PACKAGE_SYSTEMS / "paper-du.fis"),
                         grid=False).kernel_args()[0][0]
    assert scratch_sizes(packed) == (2 + (2 + 14 + 7 + 8), packed[general.H_IWORK], 0,
                                     packed[general.H_WORK] + 2 + 1)
    smooth = compile_system(SMOOTH).ints
    # the worst smooth output of SMOOTH (max aggregation: one item per term) is m: 2 + (2 + 4)
    # + (4 + 4) + (3 + 4) + (2 + 4) = 29 knots, 257 cuts per knot (+ 2), two stacks of 256,
    # the scan's 2 x 33
    sz = scratch_sizes(smooth)
    assert sz.smooth == 29 + 29 * 257 + 2 + 512 + 66
    assert (sz.work, sz.single) == (smooth[general.H_WORK],
                                    smooth[general.H_WORK] + 2 + 4 + sz.smooth)
    # sum aggregation, every rule twice: one knot list entry per item (rule, consequent), 2 +
    # 2 x 27 for m, but the cuts still bounded by the 29 distinct knots
    s = compile_system(dataclasses.replace(SMOOTH, aggregation="sum",
                                           rules=SMOOTH.rules + SMOOTH.rules)).ints
    assert scratch_sizes(s).smooth == (2 + 2 * 27) + 29 * 257 + 2 + 512 + 66
