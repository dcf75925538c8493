"""``fuzzyservo surface`` and ``fuzzyservo reproduce``, run in-process."""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.cli import main
from fuzzyservo.formats import read_system, write_system
from fuzzyservo.fuzzy import evaluate
from fuzzyservo.paper import alpha_system, du_system
from tests.cli.test_fis import ONE_FCL, THREE_FIS, TWO_FIS

PNG = b"\x89PNG\r\n\x1a\n"


def _read(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], dtype=float)


def test_surface_at_points(tmp_path: Path) -> None:
    pts = tmp_path / "pts.csv"
    pts.write_text("# comment\nde,e,extra\n0.25,-0.5,x\n1,1,y\n-3,0.0,z\n")
    out = tmp_path / "out.csv"
    assert main(["surface", "alpha", "--at", str(pts), "--out", str(out)]) == 0
    header, data = _read(out)
    assert header == ["e", "de", "value"]
    np.testing.assert_array_equal(data[:, 0], [-0.5, 1.0, 0.0])
    np.testing.assert_array_equal(data[:, 1], [0.25, 1.0, -3.0])
    # written with repr: round-trip exact
    np.testing.assert_array_equal(data[:, 2], evaluate(alpha_system(), data[:, :2])[:, 0])


def test_surface_grid_and_plots(tmp_path: Path) -> None:
    out, png, mf = tmp_path / "g.csv", tmp_path / "s.png", tmp_path / "m.png"
    assert main(["surface", "du", "--grid", "7", "--out", str(out), "--plot", str(png),
                 "--mf-plot", str(mf)]) == 0
    _, data = _read(out)
    assert data.shape == (49, 3)
    assert set(np.round(data[:, 0], 12)) == set(np.round(np.linspace(-1, 1, 7), 12))
    # the corners: -8/9 and 8/9 (only NB / PB fire); rounding only
    assert data[0, 2] == pytest.approx(-8 / 9, abs=1e-15)
    assert data[-1, 2] == pytest.approx(8 / 9, abs=1e-15)
    np.testing.assert_array_equal(data[:, 2], evaluate(du_system(), data[:, :2])[:, 0])
    assert png.read_bytes()[:8] == PNG and mf.read_bytes()[:8] == PNG


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("x,y\n1,2\n", "lacks column(s) e, de; expected e, de (found 'x', 'y')"),
        ("e,x\n1,2\n", "lacks column(s) de"),
        ("", "is empty"),
        ("e,de\n0.1,nan\n", "line 2, column 'de': 'nan' is not finite"),
        ("e,de\n0.1,0.2\ninf,0\n", "line 3, column 'e': 'inf' is not finite"),
        ("e,de\n0.1,abc\n", "line 2, column 'de': 'abc' is not a number"),
        ("e,de\n0.1\n", "line 2 has 1 value(s), the header names 2 columns"),
    ],
)
def test_bad_points_csv(tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str,
                        match: str) -> None:
    pts = tmp_path / "pts.csv"
    pts.write_text(content)
    assert main(["surface", "du", "--at", str(pts), "--out", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert match in err
    assert err.count("\n") == 1 and err.startswith("fuzzyservo: error: ")
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--grid", "1", "--out", "o.csv"], "--grid must be between 2 and 1000, got 1"),
        (["--out", "o.csv"], "--out needs the points"),
        ([], "nothing to do"),
        (["--at", "missing.csv", "--out", "o.csv"], "cannot read points CSV"),
    ],
)
def test_bad_arguments(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
                       match: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["surface", "du", *argv]) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1


def test_unknown_system_is_one_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["surface", "beta", "--grid", "3", "--out", "o.csv"]) == 2
    err = capsys.readouterr().err
    assert err == ("fuzzyservo: error: unknown system 'beta': give alpha or du (the systems of "
                   "Fig. 3) or a fuzzy-system file ending in .fis, .fcl, .fll\n")


# ---------------------------------------------------------------------------------------------
# a fuzzy-system file in place of du / alpha


@pytest.fixture
def two_fis(tmp_path: Path) -> Path:
    p = tmp_path / "two.fis"
    p.write_text(TWO_FIS)
    return p


def test_surface_of_a_file_on_a_grid(two_fis: Path, tmp_path: Path) -> None:
    out, png, mf = tmp_path / "s.csv", tmp_path / "s.png", tmp_path / "m.svg"
    assert main(["surface", str(two_fis), "--grid", "5", "--out", str(out), "--plot", str(png),
                 "--mf-plot", str(mf)]) == 0
    header, data = _read(out)
    assert header == ["x", "y", "value"]  # the file's input names, then value
    # the grid spans the inputs' ranges, x = [0, 10] and y = [-1, 1], the first fastest
    np.testing.assert_array_equal(data[:, 0], np.tile(np.linspace(0, 10, 5), 5))
    np.testing.assert_array_equal(data[:, 1], np.repeat(np.linspace(-1, 1, 5), 5))
    # the first output u, exactly as the evaluator gives it
    np.testing.assert_array_equal(data[:, 2], evaluate(read_system(two_fis), data[:, :2])[:, 0])
    # x = 0: rule 1 alone, the symmetric triangle (0, 0.25, 0.5): its peak (rounding only);
    # x = 5: no rule fires, the .fis default (the middle of [0, 1])
    assert (np.abs(data[data[:, 0] == 0, 2] - 0.25) <= 1e-15).all()
    assert (data[data[:, 0] == 5, 2] == 0.5).all()
    assert png.read_bytes()[:8] == PNG and png.stat().st_size > 10_000
    assert mf.read_bytes().lstrip()[:5] in (b"<?xml", b"<svg ")


def test_surface_of_a_file_at_points_with_nan(tmp_path: Path) -> None:
    two = read_system(_write(tmp_path / "two.fis", TWO_FIS))
    no_default = dataclasses.replace(two, outputs=tuple(
        dataclasses.replace(v, default=math.nan) for v in two.outputs))
    fll = tmp_path / "two.fll"
    write_system(no_default, fll)
    pts = _write(tmp_path / "p.csv", "y,e,x\n0.5,9,0\n0,9,5\n-1,9,10\n")
    out = tmp_path / "v.csv"
    assert main(["surface", str(fll), "--at", str(pts), "--out", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "x,y,value" and lines[2] == "5.0,0.0,nan"  # no rule fires, no default
    _, data = _read(out)
    np.testing.assert_array_equal(data[:, :2], [[0, 0.5], [5, 0], [10, -1]])
    np.testing.assert_array_equal(data[:, 2], evaluate(no_default, data[:, :2])[:, 0])


@pytest.mark.parametrize(("text", "extra", "match"), [
    (TWO_FIS, ["--at", "{d}/ede.csv", "--out", "{d}/o.csv"],
     "points CSV '{d}/ede.csv' lacks column(s) x, y; expected x, y (found 'e', 'de')"),
    (TWO_FIS.replace("Name='y'", "Name='value'"), ["--grid", "3", "--out", "{d}/o.csv"],
     "an input is named 'value', the name of the output column"),
    (ONE_FCL, ["--grid", "3", "--out", "{d}/o.csv"],
     "surface needs a system with two inputs; 'one' has 1 (x); use fuzzyservo fis eval"),
    (THREE_FIS, ["--grid", "3", "--out", "{d}/o.csv"], "'three' has 3 (a, b, c)"),
    (TWO_FIS, ["--grid", "3", "--out", "{d}/sys.fis"], "is also an input of this command"),
    (TWO_FIS, ["--grid", "3", "--mf-plot", "{d}/sys.fis"], "is also an input of this command"),
    (TWO_FIS, ["--grid", "3", "--plot", "{d}/no/s.png"], "folder '{d}/no' does not exist"),
    (TWO_FIS.replace("Range=[0 10]", "Range=[10 0]"), ["--grid", "3", "--out", "{d}/o.csv"],
     "{d}/sys.fis:"),
])
def test_surface_of_a_bad_file(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str,
                               extra: list[str], match: str) -> None:
    sys_file = _write(tmp_path / ("sys.fcl" if text == ONE_FCL else "sys.fis"), text)
    _write(tmp_path / "ede.csv", "e,de\n0,0\n")
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["surface", str(sys_file), *(a.format(d=tmp_path) for a in extra)]) == 2
    err = capsys.readouterr().err
    assert match.format(d=tmp_path) in err and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    assert sys_file.read_text() == text


def test_surface_of_a_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["surface", str(tmp_path / "nope.fcl"), "--grid", "3", "--out",
                 str(tmp_path / "o.csv")]) == 2
    assert f"cannot read '{tmp_path / 'nope.fcl'}'" in capsys.readouterr().err
    assert not (tmp_path / "o.csv").exists()


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_reproduce_writes_fig3(reproduced: Path) -> None:
    out = reproduced
    for stem in ("fig3a_memberships", "fig3a_surface_du", "fig3b_memberships",
                 "fig3b_surface_alpha"):
        png = out / f"{stem}.png"
        assert png.read_bytes()[:8] == PNG and png.stat().st_size > 10_000
        assert (out / f"{stem}.svg").read_bytes().lstrip()[:5] in (b"<?xml", b"<svg ")


def test_reproduce_refuses_a_file_as_directory(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["reproduce", "--out", str(f)]) == 2
    assert "is not a directory" in capsys.readouterr().err
