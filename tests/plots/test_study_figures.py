"""The study's figures (Figs. 4-8, delay sweep, changed plants) on synthetic runs: what each
figure marks is computed and drawn as issue 10 (item 6) asks."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.colors import to_hex, to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from fuzzyservo.plots.study_figures import (
    NO_COLOUR,
    SWEEP_LINTHRESH_MS,
    VARIANT_COLOURS,
    Curve,
    alpha_figure,
    coinciding,
    command_figure,
    delay_figure,
    delay_sweep_figure,
    first_saturation,
    minmax_envelope,
    oscillation,
    step_figure,
)
from fuzzyservo.registry import controller_colour

#: The synthetic runs' colours, as a caller gives them (the study: its designs' colours)
COLOURS = {"pid_paper_1": "#d62728", "pid_tuned": "#8c564b", "pid2_tuned": "#9467bd",
           "stfpi": "#1f77b4", "stfpi_delay": "#d55e00"}
TS = 1e-3  # sample time of the synthetic runs [s]
T = np.arange(0.0, 20.0 + TS / 2, TS)
STEP = 0.1  # [m]


def _run(key: str, y: np.ndarray, *, u: np.ndarray | None = None, label: str | None = None,
         envelope: bool = False) -> Curve:
    return Curve(key, label or key, T, y, np.zeros_like(T) if u is None else u,
                 np.full_like(T, np.nan), np.full_like(T, STEP), envelope=envelope,
                 colour=COLOURS.get(key))


def _rise(tau: float) -> np.ndarray:
    return STEP * (1.0 - np.exp(-T / tau))


def _legend_texts(fig: Figure) -> list[str]:
    legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes)]
    return [t.get_text() for lg in legends if lg is not None for t in lg.get_texts()]


def _lines(ax: object, colour: str) -> list[Line2D]:
    return [ln for ln in ax.get_lines()  # type: ignore[attr-defined]
            if to_hex(ln.get_color()) == to_hex(colour)]


def test_coinciding_curves_are_both_visible_and_said_to_coincide() -> None:
    """Issue 10: Fig. 4's 1-DOF and 2-DOF tuned PIDs coincide, so one curve is hidden."""
    a = _run("pid_tuned", _rise(0.5), label="1-DOF")
    b = _run("pid2_tuned", _rise(0.5) + 4e-4 * np.sin(T), label="2-DOF")
    c = _run("stfpi", _rise(1.0), label="fuzzy")
    pairs = coinciding([a, b, c], 0.02 * STEP)
    assert [(p.earlier, p.later) for p in pairs] == [(0, 1)]
    assert pairs[0].max_diff == pytest.approx(4e-4, rel=1e-6)  # |sin| reaches 1 in 20 s
    fig = step_figure([a, b, c], "t", near=0.02 * STEP)
    assert any(t.startswith("2-DOF (dashed: within 0.4 mm of 1-DOF)") for t in
               _legend_texts(fig))
    full = fig.axes[0]
    (under,) = _lines(full, COLOURS["pid_tuned"])
    (over,) = _lines(full, COLOURS["pid2_tuned"])
    assert under.get_linewidth() > 2 * over.get_linewidth()  # the earlier one widened
    assert over.get_linestyle() == "--" and over.get_zorder() > under.get_zorder()
    assert _lines(full, COLOURS["stfpi"])[0].get_linestyle() == "-"


def test_command_figure_zooms_on_the_kick_and_keeps_the_limit_off_the_frame() -> None:
    """Issue 10: the paper's PIDs saturate at |u| = 1 for about 20 ms at t = 0, and Fig. 5
    hid the kick against the axis."""
    u = np.where(T < 0.020 - TS / 2, 1.0, 0.3 * np.exp(-T))
    fig = command_figure([_run("pid_paper_1", _rise(1), u=u, label="PID"),
                          _run("stfpi", _rise(1), u=0.2 * np.ones_like(T), label="fuzzy")],
                         "t")
    full, zoom = fig.axes
    assert zoom.get_xlim() == (0.0, 0.2)
    for ax in (full, zoom):
        lo, hi = ax.get_ylim()
        assert hi > 100.0 + 5.0 and lo < -5.0  # |u| = 100 % and 0 % both inside, not on it
    (kick,) = _lines(zoom, COLOURS["pid_paper_1"])
    assert kick.get_xdata()[-1] <= 0.2 + 2 * TS  # the zoom draws the window only
    texts = _legend_texts(fig)
    assert "PID (|u| = 100 % from 0 to 20 ms)" in texts and "fuzzy" in texts
    assert "command limit |u| = 100 %" in texts


def test_first_saturation() -> None:
    u = np.zeros(10)
    u[2:5] = -1.0
    t = np.arange(10) * TS
    assert first_saturation(t, u) == pytest.approx((2 * TS, 5 * TS), abs=1e-15)
    assert first_saturation(t, 0.999 * np.ones(10)) is None
    assert first_saturation(t, np.ones(10)) == pytest.approx((0.0, 10 * TS), abs=1e-15)


def test_delay_figure_has_a_difference_panel_in_mm() -> None:
    """Issue 10: Fig. 8's with/without-delay curves cannot be told apart."""
    nominal = _run("stfpi", _rise(0.5), label="no delay")
    delayed = _run("stfpi_delay", _rise(0.5) + 3e-4 * np.sin(3 * T), label="6 ms")
    fig = delay_figure(nominal, delayed, "t")
    top_full, top_zoom, bottom_full, bottom_zoom = fig.axes
    (diff,) = _lines(bottom_full, COLOURS["stfpi_delay"])
    np.testing.assert_allclose(diff.get_ydata(), 0.3 * np.sin(3 * T), atol=1e-12)  # [mm]
    assert bottom_zoom.get_xlim() == (0.0, 4.0)
    assert "difference (with delay $-$ without): largest $|\\Delta x|$ = 0.3 mm" in \
        _legend_texts(fig)
    assert to_hex(COLOURS["stfpi_delay"]) != to_hex(COLOURS["stfpi"])


DELAYS = np.array([0.0, 0.002, 0.006, 0.01, 0.02, 0.05, 0.1, 0.5, 1.0])  # [s]


def _sweep() -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, str]]:
    nan = math.nan
    settling = {
        "stfpi": np.array([1.5, 1.5, 1.6, 1.7, 2.0, nan, nan, nan, nan]),
        "pid_tuned": np.array([2.0, 2.0, 2.0, 2.0, 2.1, 2.2, 2.5, 9.0, nan]),
        "pid_paper_1": np.full(DELAYS.size, nan),  # never settles: nothing to draw
    }
    failed = {k: np.isnan(v) for k, v in settling.items()}
    failed["pid_tuned"][6] = True  # diverged with a settling time on record: still a failure
    labels = {"stfpi": "self-tuning", "pid_tuned": "PID tuned", "pid_paper_1": "PID paper"}
    return settling, failed, labels


def test_settling_sweep_legend_lists_only_what_is_drawn_and_marks_failures() -> None:
    """Issue 10: the settling legend lists controllers with no points; the failure line
    disagrees with the failure rule."""
    settling, failed, labels = _sweep()
    fig = delay_sweep_figure(DELAYS, settling, labels, "t", ylabel="s", failed=failed,
                             run_length=20.0, colours=COLOURS)
    main, strip = fig.axes
    assert main.get_xscale() == "symlog"
    assert main.xaxis.get_transform().linthresh == SWEEP_LINTHRESH_MS == 10.0
    # 0-20 ms takes over a third of the delay axis (it was 2 % of a linear 0-1000 ms axis)
    x0, x20, x1000 = main.transData.transform([(0, 0), (20, 0), (1000, 0)])[:, 0]
    assert (x20 - x0) / (x1000 - x0) > 1 / 3
    assert _legend_texts(fig) == ["self-tuning", "PID tuned"]  # PID paper has no point
    assert not any("threshold" in t for t in _legend_texts(fig))
    assert [t.get_text() for t in strip.get_yticklabels()] == [
        "self-tuning", "PID tuned", "PID paper"]
    for key, row in (("stfpi", 0), ("pid_tuned", 1), ("pid_paper_1", 2)):
        (marks,) = _lines(strip, COLOURS[key])
        assert marks.get_marker() == "x"
        np.testing.assert_array_equal(marks.get_xdata(), DELAYS[failed[key]] * 1e3)
        assert set(marks.get_ydata()) == {row}
    (drawn,) = _lines(main, COLOURS["pid_tuned"])
    assert np.isnan(drawn.get_ydata()[6]) and np.isnan(drawn.get_ydata()[8])  # failures
    assert "no 2 % settling within the 20 s run, or diverged" in strip.get_title(loc="left")


def test_overshoot_sweep_shows_failing_runs_hollow_and_the_claims_limit() -> None:
    settling, failed, labels = _sweep()
    overshoot = {k: np.linspace(0.0, 200.0, DELAYS.size) for k in settling}
    fig = delay_sweep_figure(DELAYS, overshoot, labels, "t", ylabel="%", failed=failed,
                             run_length=20.0, colours=COLOURS, show_failed=True, limit=10.0,
                             limit_label="overshoot limit of claims C6, C8 (10 %)", log_y=True)
    texts = _legend_texts(fig)
    assert texts == ["self-tuning", "PID tuned", "PID paper", "hollow: the run fails (see "
                     "below)", "overshoot limit of claims C6, C8 (10 %)"]
    main = fig.axes[0]
    assert main.get_yscale() == "symlog"
    hollow = [ln for ln in _lines(main, COLOURS["pid_paper_1"])
              if ln.get_marker() == "o"]
    assert hollow and all(ln.get_markerfacecolor() == "white" for ln in hollow)


def test_no_strip_when_nothing_fails() -> None:
    ok = {"stfpi": np.ones(DELAYS.size)}
    fig = delay_sweep_figure(DELAYS, ok, {"stfpi": "s"}, "t", ylabel="s",
                             failed={"stfpi": np.zeros(DELAYS.size, bool)}, run_length=20.0)
    assert len(fig.axes) == 1 and _legend_texts(fig) == ["s"]


def _limit_cycle() -> np.ndarray:
    """A rise, then a 2 Hz oscillation of ±10 mm about the reference that never settles."""
    return np.minimum(STEP * T / 1.5, STEP) + np.where(T > 1.5, 0.01 * np.sin(
        2 * np.pi * 2.0 * (T - 1.5)), 0.0)


def test_oscillating_run_is_drawn_as_its_envelope_and_in_full_in_the_zoom() -> None:
    """Issue 10: 20 s limit cycles render as solid bands."""
    y = _limit_cycle()
    k0, period = oscillation(T, y, np.full_like(T, STEP))
    assert T[k0] == pytest.approx(1.5, abs=2 * TS)  # the first crossing of the reference
    assert period == pytest.approx(0.5, abs=2 * TS)  # 2 Hz
    fig = step_figure([_run("stfpi", _rise(0.5), label="nominal"),
                       _run("variant1", y, label="changed", envelope=True)], "t")
    full, zoom = fig.axes
    colour = VARIANT_COLOURS[1]
    (band,) = [c for c in full.collections if c.get_gid() == "envelope:variant1"]
    assert isinstance(band, PolyCollection)
    drawn = _lines(full, colour)  # the rise, and the band's two edges
    assert len(drawn) == 3 and all(len(ln.get_xdata()) < 2000 for ln in drawn)
    lo, hi = (np.min(band.get_paths()[0].vertices[:, 1]),
              np.max(band.get_paths()[0].vertices[:, 1]))
    assert (lo, hi) == pytest.approx((90.0, 110.0), abs=0.05)  # ±10 mm about 100 mm
    (line,) = _lines(zoom, colour)  # the zoom draws the oscillation itself
    assert len(line.get_xdata()) == int(round(4.0 / TS)) + 2


def test_a_run_is_drawn_in_the_colour_it_is_given() -> None:
    """The figures hold no colour of a controller: each run comes with its own (the study
    gives its designs' colours), a changed plant without one takes the palette's, any other
    run grey."""
    fig = step_figure([_run("stfpi", _rise(0.5)), _run("other", _rise(0.7)),
                       _run("variant2", _rise(0.9))], "t")
    full = fig.axes[0]
    for colour in (COLOURS["stfpi"], NO_COLOUR, VARIANT_COLOURS[2]):
        assert len(_lines(full, colour)) == 1, colour


def test_minmax_envelope() -> None:
    tb, lo, hi = minmax_envelope(T, np.sin(2 * np.pi * 2.0 * T), 0.75)
    assert tb.size == lo.size == hi.size == math.ceil(T.size / 750) + 1
    # each slice holds 1.5 periods: both extremes, up to the sampling of the sine
    np.testing.assert_allclose(hi[:-2], 1.0, atol=1e-4)
    np.testing.assert_allclose(lo[:-2], -1.0, atol=1e-4)


def _lab(colour: str) -> np.ndarray:
    """CIELAB (D65) of an sRGB colour."""
    rgb = np.array(to_rgb(colour))
    lin = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    m = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722],
                  [0.0193, 0.1192, 0.9505]])
    xyz = m @ lin / np.array([0.95047, 1.0, 1.08883])
    f = np.where(xyz > (6 / 29) ** 3, np.cbrt(xyz), xyz / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def test_changed_plants_have_distinct_colours() -> None:
    """Issue 10: two olive tones could not be told apart (#637939 and #8c6d31: 25 apart)."""
    assert np.linalg.norm(_lab("#637939") - _lab("#8c6d31")) < 40  # the old pair fails
    shown = [controller_colour("stfpi"), *VARIANT_COLOURS]  # the robustness figure's
    for i, a in enumerate(shown):
        for b in shown[i + 1:]:
            assert np.linalg.norm(_lab(a) - _lab(b)) >= 40, (a, b)


def test_figure_text_has_no_literal_underscore() -> None:
    """Issue 10: literal underscores in 'Δu_n' and 'alpha_F'."""
    c = _run("stfpi", _rise(0.5))
    for fig in (alpha_figure([c], "t"), command_figure([c], "t"), step_figure([c], "t")):
        for ax in fig.axes:
            for text in (ax.get_xlabel(), ax.get_ylabel(), ax.get_title()):
                assert "_" not in re.sub(r"\$[^$]*\$", "", text), text
    assert alpha_figure([c], "t").axes[0].get_ylabel() == (
        r"gain updating factor $\alpha_F$ [-]")
