"""The identification's figure: what it draws is the Identification's data, in display units
(mm for the position, bar for the pressures), laid out as a trace and a residual axis per
channel and one estimates axis."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

import fuzzyservo._io as io
from fuzzyservo.errors import InputError, OutputError
from fuzzyservo.identify import Identification
from fuzzyservo.plots.identification import (
    flagged_spans,
    identification_data,
    identification_figure,
    save_identification_figure,
)
from tests.identify.simulated import FLAGGED, identification

#: display units per SI unit of each channel: mm per m, bar per Pa (definitions)
SCALE = {"y": 1.0e3, "p_f": 1.0e-5, "p_n": 1.0e-5}
UNIT = {"y": "[mm]", "p_f": "[bar]", "p_n": "[bar]"}


@pytest.fixture(scope="module")
def ident() -> Identification:
    return identification()


@pytest.fixture(scope="module")
def fig(ident: Identification) -> Figure:
    return identification_figure(ident)


def _line(ax: Axes, label: str) -> np.ndarray:
    (line,) = [ln for ln in ax.get_lines() if ln.get_label() == label]
    return np.asarray(line.get_ydata(), dtype=np.float64)


def _spans(ax: Axes) -> list[tuple[float, float, float, float]]:
    """Rectangles drawn by axvspan/axhspan (x0, x1, y0, y1) in their own coordinates."""
    out = []
    for p in ax.patches:
        if isinstance(p, Rectangle):
            x0, y0 = p.get_xy()
            out.append((x0, x0 + p.get_width(), y0, y0 + p.get_height()))
        else:  # matplotlib >= 3.9 draws spans as Polygons
            xy = np.asarray(p.get_xy())
            out.append((xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max()))
    return out


def test_the_fit_compares_all_three_channels(ident: Identification) -> None:
    # the premise of the layout tests: position and both pressures were logged and fitted
    assert ident.channels == ("y", "p_f", "p_n")


def test_a_trace_and_a_residual_axis_per_channel_and_an_estimates_axis(
        ident: Identification, fig: Figure) -> None:
    assert len(fig.axes) == 2 * len(ident.channels) + 1
    for k, c in enumerate(ident.channels):
        ax, ax_r = fig.axes[2 * k], fig.axes[2 * k + 1]
        assert UNIT[c] in ax.get_ylabel() and UNIT[c] in ax_r.get_ylabel()
        assert "residual" in ax_r.get_ylabel()
    assert fig.axes[-2].get_xlabel() == "time t [s]"


def test_trace_lines_are_the_identifications_arrays(ident: Identification, fig: Figure) -> None:
    for k, c in enumerate(ident.channels):
        ax = fig.axes[2 * k]
        for line in ax.get_lines():  # every trace against the sample times
            np.testing.assert_array_equal(line.get_xdata(), ident.t)
        # the same numbers times a power of ten: exact to a few ulps
        np.testing.assert_allclose(_line(ax, "measured"), ident.measured[c] * SCALE[c],
                                   rtol=1e-15, atol=0)
        np.testing.assert_allclose(_line(ax, "identified model"), ident.fitted[c] * SCALE[c],
                                   rtol=1e-15, atol=0)
        np.testing.assert_allclose(_line(ax, "starting model"), ident.start_fit[c] * SCALE[c],
                                   rtol=1e-15, atol=0)


def test_residuals_and_their_two_sigma_band(ident: Identification, fig: Figure) -> None:
    for k, c in enumerate(ident.channels):
        ax_r = fig.axes[2 * k + 1]
        (res,) = [ln for ln in ax_r.get_lines() if np.size(ln.get_ydata()) == ident.t.size]
        expected = (ident.measured[c] - ident.fitted[c]) * SCALE[c]
        # a difference of scaled values against a scaled difference: rounding only
        tol = 1e-12 * float(np.max(np.abs(ident.measured[c]))) * SCALE[c]
        np.testing.assert_allclose(res.get_ydata(), expected, rtol=0, atol=tol)
        bands = [s for s in _spans(ax_r) if s[2] < 0.0 < s[3]]
        assert len(bands) == 1
        two_sigma = 2.0 * ident.sigma[c] * SCALE[c]
        assert bands[0][2] == pytest.approx(-two_sigma, rel=1e-12)  # same product, rounding
        assert bands[0][3] == pytest.approx(two_sigma, rel=1e-12)


def test_flagged_samples_are_shaded_on_every_time_axis(ident: Identification,
                                                       fig: Figure) -> None:
    t = ident.t
    flagged = ~ident.used
    assert np.count_nonzero(flagged) == FLAGGED.stop - FLAGGED.start  # the log's block
    half = 0.5 * (t[1] - t[0])
    for ax in fig.axes[:-1]:
        spans = [(x0, x1) for x0, x1, y0, y1 in _spans(ax) if (y0, y1) == (0.0, 1.0)]
        # one span from half a sample before the first flagged sample to half after the last
        assert spans == [pytest.approx((t[FLAGGED.start] - half, t[FLAGGED.stop - 1] + half),
                                       abs=1e-12)]


def test_flagged_spans_cover_exactly_the_flagged_samples() -> None:
    t = np.arange(50) * 0.01
    rng = np.random.default_rng(3)
    flagged = rng.random(50) < 0.3
    flagged[0] = flagged[-1] = True  # runs touching both ends
    spans = flagged_spans(t, flagged)
    covered = np.array([any(a < x < b for a, b in spans) for x in t])
    np.testing.assert_array_equal(covered, flagged)  # brute force: each sample's time
    assert all(b > a for a, b in spans)
    assert flagged_spans(t, np.zeros(50, bool)) == ()


def test_estimates_axis_one_row_per_parameter(ident: Identification, fig: Figure) -> None:
    ax = fig.axes[-1]
    labels = [tl.get_text() for tl in ax.get_yticklabels()]
    assert len(labels) == len(ident.names)
    for label, name, unit in zip(labels, ident.names, ident.units, strict=True):
        assert label.startswith(f"{name} [{unit}]")
    ratio = ident.estimate / ident.initial
    (marker,) = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
    np.testing.assert_allclose(np.asarray(marker.get_xdata(), dtype=np.float64), ratio,
                               rtol=1e-15)  # the same division
    # the error bar: ratio ± 2 SE / start value
    (bars,) = [c for c in ax.collections if isinstance(c, LineCollection)]
    seg = np.asarray(bars.get_segments()[0])
    half = 2.0 * ident.std_error[0] / ident.initial[0]
    np.testing.assert_allclose(sorted(seg[:, 0]), [ratio[0] - half, ratio[0] + half],
                               rtol=1e-12)
    # the bootstrap interval over the start value
    assert ident.interval is not None
    (boot,) = [ln for ln in ax.get_lines() if ln.get_label().startswith("bootstrap")]
    np.testing.assert_allclose(np.asarray(boot.get_xdata(), dtype=np.float64),
                               ident.interval[0] / ident.initial[0],
                               rtol=1e-15)


def test_a_zero_start_value_is_shown_against_the_upper_bound(ident: Identification) -> None:
    zero = dataclasses.replace(ident, initial=np.array([0.0]))
    (row,) = identification_data(zero).estimates
    assert row.reference == ident.bounds[0, 1]
    assert row.ratio == ident.estimate[0] / ident.bounds[0, 1]
    assert "upper bound" in row.label


def test_no_bootstrap_no_interval_drawn(ident: Identification) -> None:
    fig = identification_figure(dataclasses.replace(ident, interval=None, bootstrap=None))
    assert not [ln for ln in fig.axes[-1].get_lines()
                if ln.get_label().startswith("bootstrap")]


@pytest.mark.parametrize("suffix, magic", [(".png", b"\x89PNG\r\n\x1a\n"), (".svg", b"<?xml")])
def test_saved_as_png_or_svg(ident: Identification, tmp_path: Path, suffix: str,
                             magic: bytes) -> None:
    path = save_identification_figure(ident, tmp_path / f"fit{suffix}")
    assert path.read_bytes().startswith(magic)


def test_another_suffix_is_refused_before_drawing(ident: Identification,
                                                  tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"\.png or \.svg"):
        save_identification_figure(ident, tmp_path / "fit.pdf")
    assert list(tmp_path.iterdir()) == []


def test_a_failing_write_leaves_the_old_file(ident: Identification, tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "fit.png"
    out.write_bytes(b"old figure")

    def refuse(src: object, dst: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(io.os, "replace", refuse)
    with pytest.raises(OutputError):
        save_identification_figure(ident, out)
    assert out.read_bytes() == b"old figure"
    assert [p.name for p in tmp_path.iterdir()] == ["fit.png"]  # no temporary file left
