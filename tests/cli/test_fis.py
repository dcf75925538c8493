"""``fuzzyservo fis eval|convert|info|show``, run in-process, and the figure data behind ``show``.

References: hand-computed values (a symmetric triangle's centroid is its peak; a Gaussian
truncated to the output range has the truncated-normal mean; a linear Sugeno output is its
formula), the exact evaluator itself for whole tables (the command must pass its values on
unchanged, so equality is exact), and the membership function the evaluator uses for the
drawn curves.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.cli import main
from fuzzyservo.formats import read_system
from fuzzyservo.fuzzy import evaluate, membership
from fuzzyservo.fuzzy.system import Term
from fuzzyservo.plots.systems import response_data, system_figure_data, term_curve

PNG = b"\x89PNG\r\n\x1a\n"

#: Two inputs, two outputs; x in (4, 6) fires no rule (u, v: .fis defaults, mid-range);
#: x = 0 fires rule 1 alone at full strength.
TWO_FIS = """\
[System]
Name='two'
Type='mamdani'
Version=2.0
NumInputs=2
NumOutputs=2
NumRules=3
AndMethod='min'
OrMethod='max'
ImpMethod='min'
AggMethod='max'
DefuzzMethod='centroid'

[Input1]
Name='x'
Range=[0 10]
NumMFs=2
MF1='low':'trimf',[0 0 4]
MF2='high':'trimf',[6 10 10]

[Input2]
Name='y'
Range=[-1 1]
NumMFs=2
MF1='neg':'trapmf',[-Inf -1 -0.5 0.5]
MF2='pos':'trapmf',[-0.5 0.5 1 1]

[Output1]
Name='u'
Range=[0 1]
NumMFs=2
MF1='small':'trimf',[0 0.25 0.5]
MF2='large':'trimf',[0.5 0.75 1]

[Output2]
Name='v'
Range=[-5 5]
NumMFs=2
MF1='down':'gaussmf',[1 -2]
MF2='up':'gaussmf',[1 2]

[Rules]
1 0, 1 1 (1) : 1
2 1, 2 0 (1) : 1
2 2, 2 2 (0.5) : 1
"""

#: One input; no DEFAULT, so y is NaN where no rule fires (x in [4, 6]). Output terms are
#: symmetric triangles: with one rule firing, y is the triangle's peak whatever the strength.
ONE_FCL = """\
FUNCTION_BLOCK one
VAR_INPUT
  x : REAL;
END_VAR
VAR_OUTPUT
  y : REAL;
END_VAR
FUZZIFY x
  RANGE := (0 .. 10);
  TERM low := (0, 1) (4, 0);
  TERM high := (6, 0) (10, 1);
END_FUZZIFY
DEFUZZIFY y
  RANGE := (0 .. 10);
  TERM small := (0, 0) (2, 1) (4, 0);
  TERM big := (6, 0) (8, 1) (10, 0);
  METHOD : COG;
  ACCU : MAX;
END_DEFUZZIFY
RULEBLOCK r
  AND : MIN;
  ACT : MIN;
  RULE 1 : IF x IS low THEN y IS small;
  RULE 2 : IF x IS high THEN y IS big;
END_RULEBLOCK
END_FUNCTION_BLOCK
"""

#: Three inputs, one rule that always fires fully: z = a + 2 b + 3 c + 0.5 everywhere.
THREE_FIS = """\
[System]
Name='three'
Type='sugeno'
Version=2.0
NumInputs=3
NumOutputs=1
NumRules=1
AndMethod='min'
OrMethod='max'
ImpMethod='prod'
AggMethod='sum'
DefuzzMethod='wtaver'

[Input1]
Name='a'
Range=[0 1]
NumMFs=1
MF1='all':'trapmf',[-1 0 1 2]

[Input2]
Name='b'
Range=[0 1]
NumMFs=1
MF1='all':'trapmf',[-1 0 1 2]

[Input3]
Name='c'
Range=[0 1]
NumMFs=1
MF1='all':'trapmf',[-1 0 1 2]

[Output1]
Name='z'
Range=[-10 10]
NumMFs=1
MF1='sum':'linear',[1 2 3 0.5]

[Rules]
1 1 1, 1 (1) : 1
"""


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    out = {}
    for name, text in (("two.fis", TWO_FIS), ("one.fcl", ONE_FCL), ("three.fis", THREE_FIS)):
        p = tmp_path / name
        p.write_text(text)
        out[name] = p
    return out


def _table(text: str) -> tuple[list[str], np.ndarray]:
    rows = list(csv.reader(io.StringIO(text)))
    return rows[0], np.array(rows[1:], dtype=float)


def _one_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    return err


def _truncated_normal_mean(mu: float, sigma: float, lo: float, hi: float) -> float:
    a, b = (lo - mu) / sigma, (hi - mu) / sigma

    def phi(z: float) -> float:
        return math.exp(-z * z / 2) / math.sqrt(2 * math.pi)

    def cdf(z: float) -> float:
        return 0.5 * (1 + math.erf(z / math.sqrt(2)))

    return mu + sigma * (phi(a) - phi(b)) / (cdf(b) - cdf(a))


# ---------------------------------------------------------------------------------------------
# eval


def test_eval_at_points(files: dict[str, Path], tmp_path: Path) -> None:
    pts = tmp_path / "pts.csv"
    # columns in another order, an extra column, a comment: all allowed
    pts.write_text("# points\ny,note,x\n0.3,a,0\n-1,b,10\n0,c,5\n0.25,d,7.5\n")
    out = tmp_path / "out.csv"
    assert main(["fis", "eval", str(files["two.fis"]), "--at", str(pts), "--out", str(out)]) == 0
    header, data = _table(out.read_text())
    assert header == ["x", "y", "u", "v"]  # inputs in the system's order, then the outputs
    np.testing.assert_array_equal(data[:, 0], [0, 10, 5, 7.5])
    np.testing.assert_array_equal(data[:, 1], [0.3, -1, 0, 0.25])
    # the evaluator's values, unchanged (written with repr)
    np.testing.assert_array_equal(data[:, 2:], evaluate(read_system(files["two.fis"]),
                                                        data[:, :2]))
    # analytic: x = 0 fires rule 1 alone: u is the peak of the symmetric triangle 'small'
    # (rounding only), v the mean of N(-2, 1) truncated to [-5, 5] (the evaluator's quadrature
    # is documented at 1e-12 of the range; 1e-10 absolute leaves room)
    assert data[0, 2] == pytest.approx(0.25, abs=1e-15)
    assert data[0, 3] == pytest.approx(_truncated_normal_mean(-2, 1, -5, 5), abs=1e-10)
    # x = 10, y = -1: rule 2 alone, and nothing for v: its .fis default, the middle of [-5, 5]
    assert data[1, 2] == pytest.approx(0.75, abs=1e-15) and data[1, 3] == 0.0
    # x = 5: no rule fires: every output at the middle of its range (MATLAB's convention)
    assert list(data[2, 2:]) == [0.5, 0.0]


@pytest.mark.parametrize("out", [[], ["--out", "-"]])
def test_eval_writes_to_standard_output(files: dict[str, Path],
                                        capsys: pytest.CaptureFixture[str],
                                        out: list[str]) -> None:
    assert main(["fis", "eval", str(files["three.fis"]), "--at", str(_points(files)),
                 *out]) == 0
    header, data = _table(capsys.readouterr().out)
    assert header == ["a", "b", "c", "z"]
    a, b, c = data[:, 0], data[:, 1], data[:, 2]
    np.testing.assert_allclose(data[:, 3], a + 2 * b + 3 * c + 0.5, rtol=0,
                               atol=1e-15 * 8)  # rounding of a 4-term sum of values <= 6


def _points(files: dict[str, Path]) -> Path:
    p = files["three.fis"].parent / "abc.csv"
    p.write_text("c,b,a\n0.1,0.2,0.3\n1,1,1\n0,0,0\n0.7,0.05,0.9\n")
    return p


def test_eval_grid_one_input_nan_where_no_rule_fires(files: dict[str, Path],
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fis", "eval", str(files["one.fcl"]), "--grid", "11"]) == 0
    text = capsys.readouterr().out
    header, data = _table(text)
    assert header == ["x", "y"]
    np.testing.assert_array_equal(data[:, 0], np.linspace(0, 10, 11))
    # one rule at a time, symmetric output triangles: the peaks 2 and 8 (rounding only);
    # x in [4, 6] fires nothing and the FCL file gives no DEFAULT: nan
    want = [2, 2, 2, 2, math.nan, math.nan, math.nan, 8, 8, 8, 8]
    np.testing.assert_allclose(data[:, 1], want, rtol=0, atol=1e-14, equal_nan=True)
    assert text.splitlines()[5] == "4.0,nan"
    np.testing.assert_array_equal(data[:, 1], evaluate(read_system(files["one.fcl"]),
                                                       data[:, :1])[:, 0])


def test_no_rule_value_replaces_only_a_nan_default(files: dict[str, Path],
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fis", "eval", str(files["one.fcl"]), "--grid", "3",
                 "--no-rule-value", "-1.5"]) == 0
    _, data = _table(capsys.readouterr().out)
    np.testing.assert_allclose(data[:, 1], [2, -1.5, 8], rtol=0, atol=1e-14)
    assert data[1, 1] == -1.5
    # a default the file sets (.fis: the middle of the range) is kept
    assert main(["fis", "eval", str(files["two.fis"]), "--grid", "3",
                 "--no-rule-value", "-1.5"]) == 0
    header, data = _table(capsys.readouterr().out)
    middle = (data[:, 0] == 5.0)
    assert middle.sum() == 3 and (data[middle, 2] == 0.5).all() and (data[middle, 3] == 0).all()


def test_eval_grid_two_inputs_first_varies_fastest(files: dict[str, Path],
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fis", "eval", str(files["two.fis"]), "--grid", "3"]) == 0
    _, data = _table(capsys.readouterr().out)
    np.testing.assert_array_equal(data[:, 0], [0, 5, 10] * 3)
    np.testing.assert_array_equal(data[:, 1], np.repeat([-1.0, 0.0, 1.0], 3))
    np.testing.assert_array_equal(data[:, 2:], evaluate(read_system(files["two.fis"]),
                                                        data[:, :2]))


def test_eval_round_trips_every_value(files: dict[str, Path], tmp_path: Path) -> None:
    """Values that need 17 digits are written so they read back to the same float."""
    x = np.array([0.1, 1 / 3, 2 / 7, 4.000000000000001, 5.999999999999999, math.pi])
    pts = tmp_path / "p.csv"
    pts.write_text("x\n" + "".join(f"{v!r}\n" for v in x.tolist()))
    out = tmp_path / "o.csv"
    assert main(["fis", "eval", str(files["one.fcl"]), "--at", str(pts), "--out", str(out)]) == 0
    _, data = _table(out.read_text())
    np.testing.assert_array_equal(data[:, 0], x)
    np.testing.assert_array_equal(data[:, 1], evaluate(read_system(files["one.fcl"]),
                                                       x[:, None])[:, 0])


@pytest.mark.parametrize(("argv", "match"), [
    (["fis", "eval", "{d}/missing.fis", "--grid", "3"], "cannot read '{d}/missing.fis'"),
    (["fis", "eval", "{d}/sys.txt", "--grid", "3"],
     "cannot tell the format of '{d}/sys.txt' from its extension: use .fis, .fcl or .fll"),
    (["fis", "eval", "{d}/three.fis", "--grid", "3"],
     "--grid needs a system with one or two inputs; 'three' has 3 (a, b, c)"),
    (["fis", "eval", "{d}/one.fcl", "--grid", "1"], "--grid must be between 2 and 1000, got 1"),
    (["fis", "eval", "{d}/two.fis", "--at", "{d}/xonly.csv"],
     "points CSV '{d}/xonly.csv' lacks column(s) y; expected x, y (found 'x', 'z')"),
    (["fis", "eval", "{d}/two.fis", "--at", "{d}/inf.csv"],
     "line 3, column 'y': 'inf' is not finite"),
    (["fis", "eval", "{d}/two.fis", "--at", "{d}/inf.csv", "--out", "{d}/no/o.csv"],
     "--out '{d}/no/o.csv': folder '{d}/no' does not exist"),
    (["fis", "eval", "{d}/two.fis", "--at", "{d}/xonly.csv", "--out", "{d}/two.fis"],
     "is also an input of this command"),
    (["fis", "eval", "{d}/one.fcl", "--grid", "3", "--no-rule-value", "nan"],
     "argument --no-rule-value: expected a finite number, got 'nan'"),
    (["fis", "eval", "{d}/one.fcl"], "one of the arguments --at --grid is required"),
])
def test_eval_bad_input(files: dict[str, Path], tmp_path: Path,
                        capsys: pytest.CaptureFixture[str], argv: list[str],
                        match: str) -> None:
    (tmp_path / "sys.txt").write_text(TWO_FIS)
    (tmp_path / "xonly.csv").write_text("x,z\n1,2\n")
    (tmp_path / "inf.csv").write_text("x,y\n1,0\n2,inf\n")
    before = sorted(p.name for p in tmp_path.iterdir())
    err = _one_error([a.format(d=tmp_path) for a in argv], capsys)
    assert match.format(d=tmp_path) in err
    assert capsys.readouterr().out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    assert (tmp_path / "two.fis").read_text() == TWO_FIS


def test_malformed_file_is_one_located_line(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.fis"
    bad.write_text(TWO_FIS.replace("NumInputs=2", "NumInputs=two"))
    for argv in (["eval", str(bad), "--grid", "3"], ["info", str(bad)],
                 ["convert", str(bad), str(tmp_path / "o.fll")],
                 ["show", str(bad), "--out", str(tmp_path / "o.png")]):
        err = _one_error(["fis", *argv], capsys)
        # the FormatError's own line: file:line:col: what
        assert re.match(rf"fuzzyservo: error: {re.escape(str(bad))}:5:\d+: \S", err), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.fis"]


# ---------------------------------------------------------------------------------------------
# convert


@pytest.mark.parametrize(("src", "dst"), [("two.fis", "two.fll"), ("two.fis", "two.fcl"),
                                          ("one.fcl", "one.fll"), ("three.fis", "three.fll")])
def test_convert_is_exact(files: dict[str, Path], tmp_path: Path, src: str, dst: str) -> None:
    out = tmp_path / dst
    assert main(["fis", "convert", str(files[src]), str(out)]) == 0
    a, b = read_system(files[src]), read_system(out)
    assert b == a
    assert out.read_text().startswith({"fll": "Engine:", "fcl": "FUNCTION_BLOCK",
                                       "fis": "[System]"}[dst.rsplit(".", 1)[1]])
    # and back: the same system again
    back = tmp_path / f"back.{src.rsplit('.', 1)[1]}"
    assert main(["fis", "convert", str(out), str(back)]) == 0
    assert read_system(back) == a


def test_convert_refuses_what_the_target_cannot_hold(
        files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "one.fis"
    out.write_text("old")
    err = _one_error(["fis", "convert", str(files["one.fcl"]), str(out)], capsys)
    # .fis has no ramp (and no NaN default): named, nothing written, the old file kept
    assert f"cannot convert '{files['one.fcl']}' to .fis: " in err
    assert "ramp" in err and "nothing written" in err
    assert out.read_text() == "old"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".one.fis")]


@pytest.mark.parametrize(("target", "match"), [
    ("{d}/two.fis", "OUT '{d}/two.fis' is also an input of this command"),
    ("{d}/./two.fis", "is also an input of this command"),
    ("{d}/two.json", "cannot tell the format of '{d}/two.json' from its extension"),
    ("{d}/nodir/two.fll", "OUT '{d}/nodir/two.fll': folder '{d}/nodir' does not exist"),
    ("{d}", "is a folder"),
])
def test_convert_bad_target(files: dict[str, Path], tmp_path: Path,
                            capsys: pytest.CaptureFixture[str], target: str, match: str) -> None:
    if target == "{d}":
        target = str(tmp_path / "adir.fll")
        (tmp_path / "adir.fll").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    err = _one_error(["fis", "convert", str(files["two.fis"]), target.format(d=tmp_path)],
                     capsys)
    assert match.format(d=tmp_path) in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert files["two.fis"].read_text() == TWO_FIS


def test_convert_prints_the_readers_notes(files: dict[str, Path], tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fis", "convert", str(files["one.fcl"]), str(tmp_path / "o.fll")]) == 0
    err = capsys.readouterr().err
    notes = read_system(files["one.fcl"]).notes
    assert notes and err.splitlines() == [
        f"fuzzyservo: note: '{files['one.fcl']}': {n}" for n in notes]


# ---------------------------------------------------------------------------------------------
# info


def test_info_text(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fis", "info", str(files["two.fis"])]) == 0
    lines = capsys.readouterr().out.splitlines()
    for want in ("name:         two", "kind:         mamdani", "and:          min",
                 "implication:  min", "aggregation:  max", "defuzzifier:  centroid",
                 "  input x: range [0, 10], clip yes, 2 term(s)",
                 "    neg  trapezoid  a=-inf b=-1 c=-0.5 d=0.5",
                 "  output v: range [-5, 5], default 0, clip yes, 2 term(s)",
                 "    down  gaussian   mean=-2 sigma=1",
                 "  1. if x is low then u is small and v is down",
                 "  3. if x is high and y is pos then u is large and v is up with 0.5",
                 "notes: none"):
        assert want in lines, want


def test_info_sugeno_and_notes(files: dict[str, Path],
                               capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fis", "info", str(files["three.fis"])]) == 0
    out = capsys.readouterr().out
    assert "    sum  linear     c1=1 c2=2 c3=3 c0=0.5" in out.splitlines()
    assert "implication:  product (not used by a sugeno system)" in out
    assert main(["fis", "info", str(files["one.fcl"])]) == 0
    out = capsys.readouterr().out
    notes = read_system(files["one.fcl"]).notes
    assert "default nan" in out and f"notes ({len(notes)}):" in out
    assert all(f"  - {n}" in out.splitlines() for n in notes)


def test_info_json_is_strict(files: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    def no_constants(name: str) -> None:
        raise AssertionError(f"non-standard JSON constant {name}")

    assert main(["fis", "info", str(files["two.fis"]), "--json"]) == 0
    d = json.loads(capsys.readouterr().out, parse_constant=no_constants)
    assert d["name"] == "two" and d["kind"] == "mamdani"
    assert d["operators"] == {"and": "min", "or": "max", "implication": "min",
                              "aggregation": "max", "defuzzifier": "centroid"}
    neg = d["inputs"][1]["terms"][0]
    assert neg == {"name": "neg", "shape": "trapezoid",
                   "params": {"a": None, "b": -1.0, "c": -0.5, "d": 0.5}, "height": 1.0}
    assert "default" not in d["inputs"][0] and d["outputs"][0]["default"] == 0.5
    assert d["outputs"][1]["terms"][1]["params"] == {"mean": 2.0, "sigma": 1.0}
    assert [r["weight"] for r in d["rules"]] == [1.0, 1.0, 0.5]
    assert d["rules"][1]["text"] == "if x is high and y is neg then u is large"
    assert d["notes"] == []
    assert main(["fis", "info", str(files["one.fcl"]), "--json"]) == 0
    d = json.loads(capsys.readouterr().out, parse_constant=no_constants)
    # a Mamdani output's clip is canonically True (its value always lies in its range)
    assert d["outputs"][0]["default"] is None and d["outputs"][0]["clip"] is True
    assert d["notes"] == list(read_system(files["one.fcl"]).notes)


# ---------------------------------------------------------------------------------------------
# show and the figure data


@pytest.mark.parametrize(("name", "suffix"), [("two.fis", "png"), ("one.fcl", "svg"),
                                              ("three.fis", "png")])
def test_show_writes_a_figure(files: dict[str, Path], tmp_path: Path, name: str,
                              suffix: str) -> None:
    out = tmp_path / f"fig.{suffix}"
    grid = [] if name == "three.fis" else ["--grid", "11"]
    assert main(["fis", "show", str(files[name]), "--out", str(out), *grid]) == 0
    data = out.read_bytes()
    assert len(data) > 10_000
    if suffix == "png":
        assert data[:8] == PNG
    else:
        assert data.lstrip()[:5] in (b"<?xml", b"<svg ")


@pytest.mark.parametrize(("argv", "match"), [
    (["{d}/two.fis", "--out", "{d}/f.pdf"], "--out '{d}/f.pdf': the file name must end in "
                                            ".png or .svg"),
    (["{d}/two.fis", "--out", "{d}/no/f.png"], "folder '{d}/no' does not exist"),
    (["{d}/two.fis", "--out", "{d}/f.png", "--grid", "1"], "--grid must be between 2 and 501"),
    (["{d}/three.fis", "--out", "{d}/f.png", "--grid", "5"], "'three' has 3 inputs"),
    (["{d}/missing.fll", "--out", "{d}/f.png"], "cannot read '{d}/missing.fll'"),
])
def test_show_bad_input(files: dict[str, Path], tmp_path: Path,
                        capsys: pytest.CaptureFixture[str], argv: list[str], match: str) -> None:
    err = _one_error(["fis", "show", *(a.format(d=tmp_path) for a in argv)], capsys)
    assert match.format(d=tmp_path) in err
    assert not (tmp_path / "f.png").exists() and not (tmp_path / "f.pdf").exists()


def test_figure_response_is_the_evaluator(files: dict[str, Path]) -> None:
    two = read_system(files["two.fis"])
    data = system_figure_data(two, grid=5)
    assert data.response is not None
    x1, x2 = data.response.axes
    np.testing.assert_array_equal(x1, np.linspace(0, 10, 5))
    np.testing.assert_array_equal(x2, np.linspace(-1, 1, 5))
    g1, g2 = np.meshgrid(x1, x2)
    want = evaluate(two, np.column_stack([g1.ravel(), g2.ravel()]))
    for k in range(2):  # values[k, i2, i1]
        np.testing.assert_array_equal(data.response.values[k], want[:, k].reshape(5, 5))
    assert [p.name for p in data.panels] == ["x", "y", "u", "v"]
    # one input: the curve includes every vertex of the input's terms (4 and 6 are not on
    # the 5-point grid 0, 2.5, 5, 7.5, 10), NaN where no rule fires
    one = read_system(files["one.fcl"])
    r = response_data(one, 5)
    assert {0.0, 4.0, 6.0, 10.0} <= set(r.axes[0].tolist())
    assert np.isnan(r.values[0][r.axes[0] == 5.0]).all()
    # three inputs: no response, the membership functions only; Sugeno output as text
    three = system_figure_data(read_system(files["three.fis"]))
    assert three.response is None
    assert three.panels[-1].functions == ("sum: z = a + 2 b + 3 c + 0.5",)


@pytest.mark.parametrize("term", [
    Term("tri", "triangle", (-2.0, 1.0, 12.0)),  # feet outside the range: cut at its ends
    Term("left", "triangle", (0.0, 0.0, 4.0)),  # a vertical edge at the range's start
    Term("rect", "rectangle", (2.0, 4.0), 0.5),  # two vertical edges, height 0.5
    Term("sh", "trapezoid", (-math.inf, 1.0, 3.0, 5.0)),  # a shoulder
    Term("fall", "ramp", (7.0, 3.0)),
    Term("disc", "discrete", (1.0, 0.0, 2.0, 1.0, 2.0, 0.25, 9.0, 0.75)),  # a jump at 2
])
def test_piecewise_linear_curves_are_exact(term: Term) -> None:
    lo, hi = 0.0, 10.0
    c = term_curve(term, lo, hi)
    x, mu = c.x, c.mu
    assert x[0] == lo and x[-1] == hi and (np.diff(x) >= 0).all()
    # every vertex inside the range is a point of the curve
    assert {v for v, _ in term.vertices or () if lo <= v <= hi} <= set(x.tolist())
    ref = membership(term.shape, term.params, x, term.height)
    jump = np.zeros(len(x), dtype=bool)
    jump[:-1] |= x[:-1] == x[1:]
    jump[1:] |= x[:-1] == x[1:]
    # away from a vertical edge, the curve is the evaluator's membership (rounding of the
    # boundary interpolation only); at an edge, its two points are the two one-sided limits
    np.testing.assert_allclose(mu[~jump], ref[~jump], rtol=0, atol=1e-15)
    for i in np.flatnonzero(jump[:-1] & (x[:-1] == x[1:])):
        eps = 1e-9
        left = membership(term.shape, term.params, [x[i] - eps], term.height)[0]
        right = membership(term.shape, term.params, [x[i] + eps], term.height)[0]
        assert (mu[i], mu[i + 1]) == pytest.approx((left, right), abs=1e-8)  # slope * eps


def test_smooth_curves_include_their_knots() -> None:
    g = term_curve(Term("g", "gaussian", (5.3, 0.7), 0.8), 0.0, 10.0)
    assert 5.3 in g.x.tolist() and g.mu.max() == 0.8  # the peak at its true height
    np.testing.assert_array_equal(g.mu, membership("gaussian", (5.3, 0.7), g.x, 0.8))
    p = term_curve(Term("p", "pi", (1.1, 2.3, 6.7, 8.9)), 0.0, 10.0)
    assert {1.1, 1.7, 2.3, 6.7, 7.8, 8.9} <= set(np.round(p.x, 12).tolist())
    s = term_curve(Term("one", "singleton", (0.4,), 0.6), 0.0, 1.0)
    assert s.stem and s.x.tolist() == [0.4] and s.mu.tolist() == [0.6]


def test_convert_states_the_changes_fis_needs_from_an_fll_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tests.formats.fuzzylite_oracle import EXAMPLES

    src = EXAMPLES / "mamdani" / "SimpleDimmer.fll"  # lock-range false, default nan
    out = tmp_path / "sd.fis"
    assert main(["fis", "convert", str(src), str(out)]) == 2
    err = capsys.readouterr().err
    assert "--clip-inputs" in err and err.count("\n") == 1 and not out.exists()
    assert main(["fis", "convert", str(src), str(out), "--clip-inputs"]) == 2
    assert "--no-rule-value middle" in capsys.readouterr().err and not out.exists()
    assert main(["fis", "convert", str(src), str(out), "--clip-inputs", "--no-rule-value",
                 "middle"]) == 0
    err = capsys.readouterr().err
    assert "Power = 0.5 (--no-rule-value)" in err
    assert "inputs now clipped to their ranges: Ambient (--clip-inputs)" in err
    a, b = read_system(src), read_system(out)
    x = np.linspace(0.0, 1.0, 101)[:, None]  # inside the range
    ya, yb = evaluate(a, x), evaluate(b, x)
    fired = np.isfinite(ya)  # where a rule fires the two are equal; elsewhere 0.5 for NaN
    assert np.array_equal(ya[fired], yb[fired]) and np.all(yb[~fired] == 0.5)
    assert (~fired).sum() == 2  # the range's ends, where every triangle is 0
    assert main(["fis", "convert", str(src), str(out), "--no-rule-value", "inf"]) == 2
    assert "finite number or 'middle'" in capsys.readouterr().err
