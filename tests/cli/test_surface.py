"""``fuzzyservo surface`` and ``fuzzyservo reproduce``, run in-process."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.cli import main
from fuzzyservo.paper import alpha_system, du_system

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
    np.testing.assert_array_equal(data[:, 2], alpha_system().evaluate(data[:, 0], data[:, 1]))


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
    np.testing.assert_array_equal(data[:, 2], du_system().evaluate(data[:, 0], data[:, 1]))
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
        (["--grid", "1", "--out", "o.csv"], "--grid must be between 2 and 4000, got 1"),
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


def test_unknown_system_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["surface", "beta", "--grid", "3"]) == 2
    assert "invalid choice: 'beta'" in capsys.readouterr().err


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
