"""``fuzzyservo plot RUN.csv ... --out FIG``: files written, the data drawn equals the CSVs,
metrics in the legend equal ``fuzzyservo metrics``, and user errors on one line."""

from __future__ import annotations

import csv
import json
import re
import struct
from pathlib import Path
from typing import Any

import matplotlib.image as mpimg
import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure

import fuzzyservo.commands.plot as plot_command
from fuzzyservo.cli import main
from fuzzyservo.files import read_run_csv
from fuzzyservo.plots.runs import run_curves, runs_figure

SIM = ["simulate", "--plant", "linear"]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Run CSVs by name: PID (alpha NaN), fuzzy PI (alpha 1), self-tuning (alpha varies),
    open loop (no r, no alpha)."""
    d = tmp_path_factory.mktemp("runs")
    args = {
        "pid": ["--controller", "pid", "--gains", "kp=8,ki=0.1,kd=0.001", "--duration", "2"],
        "fpi": ["--controller", "fpi", "--gains", "ke=10,kde=5000,kdu=0.006", "--duration", "1"],
        "stfpi": ["--controller", "stfpi", "--gains", "ke=10,kde=5000,kdu=0.006",
                  "--duration", "2"],
        "ol": ["--open-loop", "--command", "0.3", "--duration", "0.5"],
    }
    out = {}
    for name, a in args.items():
        out[name] = d / f"{name}.csv"
        assert main([*SIM, *a, "--out", str(out[name])]) == 0
    return out


def _columns(path: Path) -> dict[str, np.ndarray]:
    """The CSV read with the csv module alone (not fuzzyservo's reader)."""
    with path.open(encoding="utf-8", newline="") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    return {h: np.array([float(r[j]) for r in rows[1:]]) for j, h in enumerate(rows[0])}


@pytest.fixture
def drawn(monkeypatch: pytest.MonkeyPatch) -> list[Figure]:
    """The figures the plot command saves (the real save still runs)."""
    figs: list[Figure] = []
    real = plot_command.save_figure

    def capture(fig: Figure, path: Any) -> Path:
        figs.append(fig)
        return real(fig, path)

    monkeypatch.setattr(plot_command, "save_figure", capture)
    return figs


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == PNG_MAGIC and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


# ---------------------------------------------------------------------------------------------
# files


def test_png_of_three_runs(runs: dict[str, Path], tmp_path: Path, drawn: list[Figure],
                           capsys: pytest.CaptureFixture[str]) -> None:
    fig_path = tmp_path / "fig.png"
    assert main(["plot", str(runs["pid"]), str(runs["stfpi"]), str(runs["ol"]),
                 "--out", str(fig_path)]) == 0
    assert capsys.readouterr() == ("", "")
    data = fig_path.read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > 20_000
    (fig,) = drawn
    w, h = fig.get_size_inches() * fig.dpi
    assert _png_size(data) == (round(w), round(h))  # the file is this figure, at its dpi
    # every run's colour is in the picture (lines > 1 px wide cover whole pixels)
    img = (mpimg.imread(fig_path)[..., :3] * 255).round().astype(int)
    colours = {tuple(c) for c in img.reshape(-1, 3).tolist()}
    ax_y = fig.axes[0]
    for line in ax_y.get_lines()[:5:2]:  # y of run 1, y of run 2, y of run 3 (see below)
        assert tuple(round(255 * v) for v in to_rgb(line.get_color())) in colours


def test_svg(runs: dict[str, Path], tmp_path: Path) -> None:
    fig_path = tmp_path / "fig.svg"
    assert main(["plot", str(runs["stfpi"]), "--out", str(fig_path), "--title", "T"]) == 0
    text = fig_path.read_text(encoding="utf-8")
    assert text.lstrip().startswith(("<?xml", "<svg")) and "<svg" in text
    assert text.rstrip().endswith("</svg>") and len(text) > 20_000


# ---------------------------------------------------------------------------------------------
# what is drawn


def test_three_runs_overlaid_with_the_csv_data(runs: dict[str, Path], tmp_path: Path,
                                               drawn: list[Figure]) -> None:
    names = ["pid", "stfpi", "ol"]
    assert main(["plot", *(str(runs[n]) for n in names), "--out", str(tmp_path / "f.png"),
                 "--label", "A", "--label", "B", "--label", "C", "--title", "my runs"]) == 0
    (fig,) = drawn
    assert fig.get_suptitle() == "my runs"
    assert len(fig.axes) == 3  # the self-tuning run has alpha
    ax_y, ax_u, ax_a = fig.axes
    y_lines = ax_y.get_lines()
    # per closed-loop run: position then dashed reference; the open loop: position only;
    # then the legend's "reference (dashed)" entry
    assert [ln.get_linestyle() for ln in y_lines] == ["-", "--", "-", "--", "-", "--"]
    assert [ln.get_label() for ln in y_lines[::2]] == ["A", "B", "C"]
    for k, n in enumerate(names):
        col = _columns(runs[n])
        y_line = y_lines[2 * k] if k < 2 else y_lines[4]
        # display units, exactly: mm = m * 1e3, % = fraction * 100 (one multiplication)
        assert np.array_equal(y_line.get_xdata(), col["t"])  # exact: repr round-trips
        assert np.array_equal(y_line.get_ydata(), col["y"] * 1e3)
        assert np.array_equal(ax_u.get_lines()[k].get_ydata(), col["u"] * 100.0)
        if k < 2:
            r_line = y_lines[2 * k + 1]
            assert np.array_equal(r_line.get_ydata(), col["r"] * 1e3)
            assert r_line.get_color() == y_line.get_color()  # reference in the run's colour
    assert len({ln.get_color() for ln in y_lines[:5:2]}) == 3  # one colour per run
    # alpha panel: only the self-tuning run draws, its alpha column as is
    (a_line,) = ax_a.get_lines()
    # exact: alpha is drawn as read
    assert np.array_equal(a_line.get_ydata(), _columns(runs["stfpi"])["alpha"])
    assert a_line.get_color() == y_lines[2].get_color()


@pytest.mark.parametrize("names", [["pid"], ["stfpi"], ["ol"], ["fpi"], ["pid", "ol"],
                                   ["ol", "stfpi"], ["pid", "fpi", "ol"]])
def test_run_curves_are_the_csv_columns(runs: dict[str, Path], names: list[str]) -> None:
    data = [read_run_csv(runs[n]) for n in names]
    curves = run_curves(data, names)
    assert [c.label for c in curves] == names
    for c, n in zip(curves, names, strict=True):
        col = _columns(runs[n])
        assert np.array_equal(c.t, col["t"])
        assert np.array_equal(c.y_mm, col["y"] * 1e3)  # exact: the same single product
        assert np.array_equal(c.u_pct, col["u"] * 100.0)  # exact, as above
        if "r" in col:
            assert c.r_mm is not None and np.array_equal(c.r_mm, col["r"] * 1e3)
        else:
            assert c.r_mm is None
        finite_alpha = "alpha" in col and bool(np.isfinite(col["alpha"]).all())
        if finite_alpha:
            assert c.alpha is not None and np.array_equal(c.alpha, col["alpha"])
        else:
            assert c.alpha is None
    with_alpha = any("alpha" in (col := _columns(runs[n])) and np.isfinite(col["alpha"]).any()
                     for n in names)
    assert len(runs_figure(data, names).axes) == (3 if with_alpha else 2)
    # reference dashed only for closed-loop runs (plus the one legend entry)
    dashed = [ln for ln in runs_figure(data, names).axes[0].get_lines()
              if ln.get_linestyle() == "--"]
    closed = sum("r" in _columns(runs[n]) for n in names)
    assert len(dashed) == (closed + 1 if closed else 0)


def test_relative_starts_at_zero(runs: dict[str, Path], tmp_path: Path,
                                 drawn: list[Figure]) -> None:
    assert main(["plot", str(runs["pid"]), str(runs["ol"]), "--relative",
                 "--out", str(tmp_path / "f.png")]) == 0
    (fig,) = drawn
    y_lines = fig.axes[0].get_lines()
    pid, ol = _columns(runs["pid"]), _columns(runs["ol"])
    assert pid["y"][0] != 0.0  # absolute positions start mid-stroke
    # exact: x - x is 0
    assert y_lines[0].get_ydata()[0] == 0.0 and y_lines[2].get_ydata()[0] == 0.0
    # exact: the same subtraction and product, in the same order
    assert np.array_equal(y_lines[0].get_ydata(), (pid["y"] - pid["y"][0]) * 1e3)
    assert np.array_equal(y_lines[1].get_ydata(), (pid["r"] - pid["y"][0]) * 1e3)
    assert np.array_equal(y_lines[2].get_ydata(), (ol["y"] - ol["y"][0]) * 1e3)
    assert "x(0)" in fig.axes[0].get_ylabel()


# ---------------------------------------------------------------------------------------------
# --metrics

_LABEL = re.compile(r"^(?P<name>\w+): rise (?P<rise>\S+)(?: s)?, settling (?P<settling>\S+)"
                    r"(?: s)?, overshoot (?P<overshoot>\S+)(?: %)?$")


def _printed(value: float | None, digits: int) -> str:
    return "n/a" if value is None else f"{value:.{digits}g}"


def test_metrics_in_the_legend_equal_the_metrics_command(
        runs: dict[str, Path], tmp_path: Path, drawn: list[Figure],
        capsys: pytest.CaptureFixture[str]) -> None:
    names = ["pid", "stfpi"]
    assert main(["plot", *(str(runs[n]) for n in names), "--metrics",
                 "--out", str(tmp_path / "f.svg")]) == 0
    (fig,) = drawn
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert texts[-1] == "reference (dashed)"
    seen_nan = seen_number = False
    for text, n in zip(texts[:-1], names, strict=True):
        m = _LABEL.match(text)
        assert m is not None, text
        assert m["name"] == n  # default label: the file name's stem
        capsys.readouterr()
        assert main(["metrics", str(runs[n]), "--json"]) == 0
        ref = json.loads(capsys.readouterr().out)
        # to the digits the legend prints: 3 significant for times, 2 for the overshoot
        assert m["rise"] == _printed(ref["rise_time"], 3)
        assert m["settling"] == _printed(ref["settling_time"], 3)
        assert m["overshoot"] == _printed(ref["overshoot"], 2)
        for key in ("rise_time", "settling_time", "overshoot"):
            seen_nan |= ref[key] is None
            seen_number |= ref[key] is not None
    assert seen_nan and seen_number  # both the "n/a" and the number branch were compared


# ---------------------------------------------------------------------------------------------
# user errors: one line, status 2, nothing written


def _fails(argv: list[str], out: Path, capsys: pytest.CaptureFixture[str]) -> str:
    capsys.readouterr()
    assert main([*argv, "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("fuzzyservo: error: "), captured.err
    assert not out.exists()
    return lines[0]


def test_metrics_on_an_open_loop_run_fails(runs: dict[str, Path], tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    msg = _fails(["plot", str(runs["pid"]), str(runs["ol"]), "--metrics"],
                 tmp_path / "f.png", capsys)
    assert "ol.csv" in msg and "open-loop" in msg


def test_label_count_mismatch_fails(runs: dict[str, Path], tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    msg = _fails(["plot", str(runs["pid"]), str(runs["stfpi"]), "--label", "one"],
                 tmp_path / "f.png", capsys)
    assert "1 --label for 2" in msg


def test_jpg_output_fails(runs: dict[str, Path], tmp_path: Path,
                          capsys: pytest.CaptureFixture[str]) -> None:
    msg = _fails(["plot", str(runs["pid"])], tmp_path / "f.jpg", capsys)
    assert ".png" in msg and ".svg" in msg


def test_missing_csv_fails(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    msg = _fails(["plot", str(tmp_path / "nope.csv")], tmp_path / "f.png", capsys)
    assert "nope.csv" in msg


def test_csv_without_y_fails(runs: dict[str, Path], tmp_path: Path,
                             capsys: pytest.CaptureFixture[str]) -> None:
    col = _columns(runs["pid"])
    bad = tmp_path / "no_y.csv"
    bad.write_text("t,r,u\n" + "".join(f"{a!r},{b!r},{c!r}\n" for a, b, c in
                                        zip(col["t"], col["r"], col["u"], strict=True)),
                   encoding="utf-8")
    msg = _fails(["plot", str(bad)], tmp_path / "f.png", capsys)
    assert "no_y.csv" in msg and "lacks column(s) y" in msg
