"""Zero-width terms (issue 29) in all three formats, against fuzzylite's CLI.

A triangle a = b = c (``TRIAN 0 0 0``, ``trimf [0 0 0]``, ``Triangle 0 0 0``) and a trapezoid
a = b = c = d are points: membership 1 (the height) exactly there and 0 elsewhere. In an input
that is a crisp point; in an output the term has no area (it adds nothing to a centroid or a
bisector) and is a point of the aggregate for the maxima methods (docs/fuzzy-files.md,
"Zero-width terms").

The oracle is fuzzylite 6's CLI reading each file itself. It takes |x - vertex| < 1e-6 as the
vertex, so its zero-width term is a spike of width 2e-6; sampled at resolution 10^6 on [-1, 1]
(cells of 2e-6) the spike covers one cell centre at most, so the output points of the fixture
sit on cell centres (0.500001, -0.299999) where fuzzylite's sampled maxima see them; a centroid
then differs by one cell's weight, like a vertical edge (the bound below).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.cli import main
from fuzzyservo.formats import dumps, loads, read_system
from fuzzyservo.fuzzy import evaluate
from fuzzyservo.fuzzy.shapes import point_of
from fuzzyservo.fuzzy.system import Consequent, FuzzySystem, Is, Rule
from tests.formats.fuzzylite_oracle import fuzzylite_eval

DATA = Path(__file__).parent / "data"
FILES = {fmt: DATA / fmt / f"zero_width.{fmt}" for fmt in ("fll", "fis", "fcl")}
#: How each format names the defuzzifier (the fixtures say centroid).
METHODS = {
    "fll": {"centroid": "defuzzifier: Centroid", "bisector": "defuzzifier: Bisector",
            "mom": "defuzzifier: MeanOfMaximum", "som": "defuzzifier: SmallestOfMaximum",
            "lom": "defuzzifier: LargestOfMaximum"},
    "fis": {d: f"DefuzzMethod='{d}'" for d in ("centroid", "bisector", "mom", "som", "lom")},
    "fcl": {"centroid": "METHOD : COG", "bisector": "METHOD : COA", "mom": "METHOD : MM",
            "som": "METHOD : LM", "lom": "METHOD : RM"},
}
DEFUZZIFIERS = ("centroid", "bisector", "mom", "som", "lom")
#: The output's zero-width terms (cell centres of fuzzylite's 10^6 samples of [-1, 1]).
Z, Q = 0.500001, -0.299999
#: The input's zero-width terms: 'at' (a triangle) and 'at2' (a trapezoid).
AT, AT2 = 0.4, 0.7
RESOLUTION = 1_000_000
#: fuzzylite's sampling error without zero-width terms, a fraction of the output range R = 2:
#: its midpoint rule on N = 10^6 cells is exact on linear pieces and O(dx^2) at a kink; the
#: maxima are a sample point plus its 1e-6 equality tolerance. Ten cells bound these (as
#: tests/formats/test_fll.py's MAMDANI_TOL, same reasoning).
TOL = 10.0 / RESOLUTION
R = 2.0
DX = R / RESOLUTION


def spike_bound(x: np.ndarray) -> np.ndarray:
    """What fuzzylite's view of the zero-width output terms adds to |ours - fuzzylite| of a
    centroid or bisector: each is one cell of weight w to it (the strength of its rules: 'low'
    = 1 - x on Z, 1 on Q at x = AT, 1 on Z at x = AT2), area w dx and moment at most w dx R
    about the centroid, so a shift of at most w dx R / A, A the exact area: p = (-1, -0.6, 0.2)
    clipped at 'high' = x, 1.2 x (1 - x / 2). The bisector moves by (w dx / 2) / g at the
    bisector, g = x there (the plateau), which the same bound covers (A / R <= 0.6 x)."""
    w = np.where(x == AT2, 1.0, 1.0 - x) + np.where(x == AT, 1.0, 0.0)
    return w * DX * R / (1.2 * x * (1.0 - 0.5 * x))


def text_of(fmt: str, defuzzifier: str) -> str:
    text = FILES[fmt].read_text(encoding="utf-8")
    old = METHODS[fmt]["centroid"]
    assert text.count(old) == 1
    return text.replace(old, METHODS[fmt][defuzzifier])


def fis_eval(path: Path, x: np.ndarray, tmp_path: Path) -> np.ndarray:
    """`fuzzyservo fis eval FILE --at POINTS --out OUT`: the y column."""
    pts = tmp_path / "points.csv"
    pts.write_text("x\n" + "".join(f"{float(v)!r}\n" for v in x), encoding="utf-8")
    out = tmp_path / "out.csv"
    assert main(["fis", "eval", str(path), "--at", str(pts), "--out", str(out)]) == 0
    rows = list(csv.reader(io.StringIO(out.read_text(encoding="utf-8"))))
    assert rows[0] == ["x", "y"]
    data = np.array(rows[1:], dtype=float)
    np.testing.assert_array_equal(data[:, 0], x)
    return data[:, 1]


def oracle_points(maxima: bool) -> np.ndarray:
    """Random inputs (fixed seed) more than 1e-5 from every term parameter (fuzzylite's 1e-6
    vertex window, and its activations <= 1e-6 dropped); for the maxima the two rules that
    fire differ by more than 0.02 (low = 1 - x, high = x: fuzzylite's LargestOfMaximum would
    creep along a tie). Then the inputs' zero-width points exactly, and the range's end."""
    x = np.random.default_rng(29).uniform(0.0, 1.0, 400)
    for p in (0.0, AT, AT2, 1.0):
        x = x[np.abs(x - p) > 1e-5]
    if maxima:
        x = x[np.abs(1.0 - 2.0 * x) > 0.02]
    return np.concatenate([x[:30], [AT, AT2, 1.0]])


def analytic(defuzzifier: str, x: np.ndarray) -> np.ndarray:
    """The maxima from the rules by hand: 'low' (1 - x) fires the point Z, 'high' (x) the
    triangle p = (-1, -0.6, 0.2) clipped at x, whose top is [-1 + 0.4 x, 0.2 - 0.8 x]; at
    x = AT the point Q at 1, at x = AT2 the point Z at 1 win."""
    lo, hi = -1.0 + 0.4 * x, 0.2 - 0.8 * x
    top = {"som": lo, "lom": hi, "mom": 0.5 * (lo + hi)}[defuzzifier]
    out = np.where(1.0 - x > x, Z, top)
    out[x == AT] = Q
    out[x == AT2] = Z
    return out


@pytest.mark.parametrize("defuzzifier", DEFUZZIFIERS)
@pytest.mark.parametrize("fmt", sorted(FILES))
def test_fis_eval_of_zero_width_terms_agrees_with_fuzzylite(fmt: str, defuzzifier: str,
                                                            tmp_path: Path) -> None:
    text = text_of(fmt, defuzzifier)
    path = tmp_path / f"sys.{fmt}"
    path.write_text(text, encoding="utf-8")
    assert read_system(path).defuzzifier == defuzzifier
    maxima = defuzzifier in ("mom", "som", "lom")
    x = oracle_points(maxima)
    ours = fis_eval(path, x, tmp_path)
    names, theirs = fuzzylite_eval(text, fmt, ["x"], x[:, None], RESOLUTION)
    assert names == ["y"]
    assert not np.any(np.isnan(ours)) and not np.any(np.isnan(theirs))
    bound = TOL * R + (0.0 if maxima else spike_bound(x))
    assert np.all(np.abs(ours - theirs[:, 0]) <= bound), np.abs(ours - theirs[:, 0]) / bound
    if maxima:
        # exact: the maxima are vertices and points (rounding of -1 + 0.4 x and the like)
        np.testing.assert_allclose(ours, analytic(defuzzifier, x), rtol=0, atol=1e-15)


def without_points(system: FuzzySystem) -> FuzzySystem:
    """The system with only rule 2 (high -> p): what is left when the zero-width terms add
    nothing."""
    return FuzzySystem(name="p_only", inputs=system.inputs, outputs=system.outputs,
                       rules=(Rule(Is(0, 1), (Consequent(0, 1),)),),
                       defuzzifier=system.defuzzifier)


@pytest.mark.parametrize("defuzzifier", ["centroid", "bisector"])
def test_zero_width_output_terms_add_no_area(defuzzifier: str) -> None:
    s = loads(text_of("fll", defuzzifier), "fll")
    x = np.concatenate([oracle_points(False), [AT - 1e-9, 0.25]])[:, None]
    # the points split a linear piece at Z or Q: rounding only (a few ulps of the range)
    np.testing.assert_allclose(evaluate(s, x), evaluate(without_points(s), x), rtol=0,
                               atol=1e-15 * R)


@pytest.mark.parametrize("fmt", sorted(FILES))
def test_only_zero_width_terms_fired(fmt: str, tmp_path: Path) -> None:
    """x = 0 fires 'low' alone (the point Z): no area, so centroid and bisector give the
    output's default as when no rule fires (FLL NaN, .fis the middle 0, the FCL file 0.25);
    the maxima give Z. fuzzylite's centroid is its 0 / 0 (NaN, whatever the default) at its
    importers' resolution (100: no cell centre within 1e-6 of Z), and Z only when a sample
    lands in its spike: a resolution artefact, not a value."""
    default = {"fll": np.nan, "fis": 0.0, "fcl": 0.25}[fmt]
    x = np.array([0.0])
    for d in DEFUZZIFIERS:
        path = tmp_path / f"{d}.{fmt}"
        path.write_text(text_of(fmt, d), encoding="utf-8")
        ours = fis_eval(path, x, tmp_path)[0]
        if d in ("centroid", "bisector"):
            np.testing.assert_equal(ours, default)
            _, theirs = fuzzylite_eval(text_of(fmt, d), fmt, ["x"], x[:, None], None)
            assert np.isnan(theirs[0, 0])
        else:
            assert ours == Z
            _, theirs = fuzzylite_eval(text_of(fmt, d), fmt, ["x"], x[:, None], RESOLUTION)
            assert abs(theirs[0, 0] - Z) <= TOL * R


def test_an_input_point_is_exactly_its_value(tmp_path: Path) -> None:
    """'at' fires only at exactly 0.4 in both; fuzzylite also within its 1e-6 vertex window
    (0.4 + 5e-7 fires it there: Q is the maximum), the documented difference."""
    text = text_of("fll", "som")
    path = tmp_path / "som.fll"
    path.write_text(text, encoding="utf-8")
    x = np.array([AT, AT + 5e-7, np.nextafter(AT, 1.0), AT2, np.nextafter(AT2, 0.0)])
    ours = fis_eval(path, x, tmp_path)
    # the last: p's plateau starts at -1 + 0.4 x (rounding of that product and sum only)
    np.testing.assert_allclose(ours, [Q, Z, Z, Z, -1.0 + 0.4 * np.nextafter(AT2, 0.0)],
                               rtol=0, atol=1e-15 * R)
    _, theirs = fuzzylite_eval(text, "fll", ["x"], x[:, None], RESOLUTION)
    assert abs(theirs[0, 0] - Q) <= TOL * R and abs(theirs[1, 0] - Q) <= TOL * R


def test_the_formats_read_the_same_points() -> None:
    systems = {fmt: read_system(p) for fmt, p in FILES.items()}
    for s in systems.values():
        assert [point_of(t.shape, t.params) for t in s.inputs[0].terms] == [None, None, AT, AT2]
        assert [point_of(t.shape, t.params) for t in s.outputs[0].terms] == [Z, None, Q]
        assert s.inputs == systems["fll"].inputs and s.rules == systems["fll"].rules
    for fmt, s in systems.items():  # and the writers keep them
        assert loads(dumps(s, fmt), fmt) == s


def test_jfuzzylogic_trian_and_trape_of_zero_width() -> None:
    """The issue's line, `TERM zero := TRIAN 0 0 0;`, and jFuzzyLogic's shape words for the
    fixture's terms read as fuzzylite's class names do."""
    text = FILES["fcl"].read_text(encoding="utf-8")
    jfl = text.replace("Triangle", "TRIAN").replace("Trapezoid", "TRAPE").replace(
        "TERM q :=", "TERM zero := TRIAN 0 0 0;\n  TERM q :=")
    s, base = loads(jfl, "fcl"), loads(text, "fcl")
    assert s.outputs[0].terms[2].params == (0.0, 0.0, 0.0)
    assert point_of("triangle", s.outputs[0].terms[2].params) == 0.0
    assert s.inputs == base.inputs
    assert [t for k, t in enumerate(s.outputs[0].terms) if k != 2] == list(base.outputs[0].terms)
