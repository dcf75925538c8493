"""Figures of the paper's study (Figs. 4-8, the delay sweep and the changed plants), rendered
from results the study already computed.

Each renderer takes data and returns a matplotlib ``Figure`` (object API, no global state);
:func:`save` writes it as PNG and SVG. What a figure marks is computed by plain functions
first, so the captions can quote the same numbers: curves that coincide
(:func:`coinciding`), a command at its limit at the start (:func:`first_saturation`), where
and how fast a run oscillates (:func:`oscillation`) and its min/max band
(:func:`minmax_envelope`). matplotlib is imported only when a figure is drawn.

Choices (docs/model.md, "Figures"):

- each run in the colour its caller gives it (:attr:`Curve.colour`; the study draws each
  controller in one colour throughout, its kind's from the registry); the changed plants take
  colours of a colour-blind-safe palette (:data:`VARIANT_COLOURS`);
- a curve within a given distance of an earlier one over the whole run is drawn dashed over
  the earlier, widened one, and its legend label says how far apart they are;
- a run that oscillates without settling is drawn over the whole run as its rise, then its
  min/max band over 1.5 oscillation periods, not as dense oscillations; zoom panels draw it
  in full;
- the delay sweep has a symmetric-log delay axis (linear up to 10 ms, logarithmic above), so
  0-20 ms takes over a third of its width; where a controller fails (no 2 % settling within
  the run, or divergence) it is marked with a cross in a strip below the plot, in its colour;
- legends list only what is drawn.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._io import atomic_write
from .._typing import BoolArray, FloatArray

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "DPI",
    "NO_COLOUR",
    "SWEEP_LINTHRESH_MS",
    "VARIANT_COLOURS",
    "Coincidence",
    "Curve",
    "alpha_figure",
    "coinciding",
    "command_figure",
    "delay_figure",
    "delay_sweep_figure",
    "first_saturation",
    "minmax_envelope",
    "oscillation",
    "save",
    "step_figure",
    "tracking_figure",
]

#: Colour of a run given none (:attr:`Curve.colour`).
NO_COLOUR = "#7f7f7f"

#: Colours of the changed plants (robustness figure), beside the nominal run's blue:
#: vermillion, bluish green and reddish purple of the Okabe-Ito colour-blind-safe palette,
#: olive and indigo of Tol's muted palette, then black; any two, and each and the blue, at
#: least 40 apart in CIELAB (a test holds them apart).
VARIANT_COLOURS: tuple[str, ...] = ("#d55e00", "#009e73", "#cc79a7", "#999933", "#332288",
                                    "#000000")

#: Resolution of the PNG files [dots per inch].
DPI = 110

#: Delay axis of the sweep: linear up to this delay [ms], logarithmic above.
SWEEP_LINTHRESH_MS = 10.0

_SWEEP_TICKS_MS = (0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0)
_REFERENCE: dict[str, Any] = {"color": "#555555", "lw": 1.0, "ls": (0, (4, 3))}


@dataclass(frozen=True, slots=True)
class Curve:
    """One run as drawn: ``key`` (which run), legend label and the signals [SI].

    ``envelope`` draws the run, over its full length, as its rise and then its min/max band
    (for a run that oscillates without settling); zoom panels draw it in full. ``colour``
    is the run's colour (None: a changed plant's, ``variant<i>``, takes the i-th of
    :data:`VARIANT_COLOURS`, any other :data:`NO_COLOUR`).
    """

    key: str
    label: str
    t: FloatArray
    y: FloatArray
    u: FloatArray
    alpha: FloatArray
    r: FloatArray
    linestyle: str | tuple[float, tuple[float, ...]] = "-"
    envelope: bool = False
    colour: str | None = None


@dataclass(frozen=True, slots=True)
class Coincidence:
    """Curve ``later`` stays within ``max_diff`` [m] of the earlier curve ``earlier``
    (indices into the list of curves)."""

    earlier: int
    later: int
    max_diff: float


_HATCHES = ("////", "\\\\\\\\", "xxx", "...", "+++", "ooo")


def _hatch(key: str) -> str:
    if key.startswith("variant") and key[7:].isdigit():
        return _HATCHES[int(key[7:]) % len(_HATCHES)]
    return _HATCHES[0]


def _colour(c: Curve) -> str:
    if c.colour is not None:
        return c.colour
    if c.key.startswith("variant") and c.key[7:].isdigit():
        return VARIANT_COLOURS[int(c.key[7:]) % len(VARIANT_COLOURS)]
    return NO_COLOUR


# --- data: what the figures mark -------------------------------------------------------------

def coinciding(curves: Sequence[Curve], tol: float) -> list[Coincidence]:
    """Curves that stay within ``tol`` [m] of an earlier curve over the whole run.

    Each later curve is paired with the first earlier one it follows; curves on other time
    grids are never paired.
    """
    out = []
    for j, cj in enumerate(curves):
        for i in range(j):
            ci = curves[i]
            if ci.t.shape != cj.t.shape or not np.array_equal(ci.t, cj.t):
                continue
            d = float(np.max(np.abs(cj.y - ci.y)))
            if d <= tol:
                out.append(Coincidence(i, j, d))
                break
    return out


def first_saturation(t: FloatArray, u: FloatArray, limit: float = 1.0
                     ) -> tuple[float, float] | None:
    """The first interval [start, end) [s] in which the held command is at ``limit`` in
    magnitude (to 1e-9 relative), or None. Sample k holds over [t_k, t_k+1)."""
    at = np.abs(np.asarray(u)) >= limit * (1.0 - 1e-9)
    if not at.any():
        return None
    k0 = int(np.argmax(at))
    rest = at[k0:]
    k1 = k0 + (rest.size if rest.all() else int(np.argmin(rest)))
    dt = float(t[1] - t[0]) if t.size > 1 else 0.0
    end = float(t[k1]) if k1 < t.size else float(t[-1]) + dt
    return float(t[k0]), end


def oscillation(t: FloatArray, y: FloatArray, r: FloatArray) -> tuple[int, float]:
    """Where a run starts oscillating about its reference and how fast: (index of its first
    crossing of the reference, 0 if none; period [s] from the crossings from there on, NaN
    with fewer than three crossings)."""
    e = np.asarray(y) - np.asarray(r)
    below = np.signbit(e)
    cross = np.flatnonzero(below[1:] != below[:-1]) + 1
    if cross.size == 0:
        return 0, math.nan
    k0 = int(cross[0])
    if cross.size < 3:
        return k0, math.nan
    return k0, 2.0 * float(t[cross[-1]] - t[cross[0]]) / (cross.size - 1)


def minmax_envelope(t: FloatArray, y: FloatArray, width: float
                    ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Min and max of ``y`` in consecutive slices of ``width`` [s] (at least one sample):
    (t at each slice's start then the last t, lo, hi), one point more than slices (the last
    slice repeated), to be drawn as a step band."""
    n = t.size
    dt = float(t[1] - t[0]) if n > 1 else 1.0
    per = max(1, round(width / dt))
    edges = np.arange(0, n, per, dtype=np.intp)
    lo = np.minimum.reduceat(y, edges)
    hi = np.maximum.reduceat(y, edges)
    tb = np.append(t[edges], t[-1])
    return tb, np.append(lo, lo[-1]), np.append(hi, hi[-1])


# --- rendering -------------------------------------------------------------------------------

def _figure(width: float, height: float) -> Figure:
    from matplotlib.figure import Figure  # only when drawing (see the module's doc)

    return Figure(figsize=(width, height), dpi=DPI, layout="constrained")


def _window(t: FloatArray, until: float) -> slice:
    """The samples up to ``until`` [s] and one beyond (held commands reach the edge)."""
    return slice(0, min(int(np.searchsorted(t, until, side="right")) + 1, t.size))


def _legend_below(fig: Figure, ax: Axes, ncols: int) -> None:
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=ncols, fontsize=8,
                   frameon=False)


def _draw_positions(ax: Axes, curves: Sequence[Curve], y0: float,
                    styles: Sequence[dict[str, Any]], *, until: float | None,
                    envelopes: bool) -> None:
    from matplotlib.colors import to_rgb  # only when drawing

    ref = curves[0]
    w = _window(ref.t, until) if until is not None else slice(None)
    ax.plot(ref.t[w], (ref.r[w] - y0) * 1e3, label="reference", **_REFERENCE)
    for c, style in zip(curves, styles, strict=True):
        colour = _colour(c)
        if c.envelope and envelopes:
            # the rise as a line, then the oscillation as its min/max band over 1.5 periods
            # (at least 1/400 of the run, about a pixel column)
            k0, period = oscillation(c.t, c.y, c.r)
            span = float(c.t[-1] - c.t[0])
            width = max(1.5 * period if math.isfinite(period) else 0.0, span / 400)
            ax.plot(c.t[:k0 + 1], (c.y[:k0 + 1] - y0) * 1e3, color=colour, **style)
            tb, lo, hi = minmax_envelope(c.t[k0:], (c.y[k0:] - y0) * 1e3, width)
            # hatched in the run's colour, so that overlapping bands show both colours
            ax.fill_between(tb, lo, hi, step="post", facecolor=(*to_rgb(colour), 0.12),
                            edgecolor=colour, hatch=_hatch(c.key), lw=0.0, label=c.label,
                            gid=f"envelope:{c.key}")
            ax.step(tb, lo, where="post", color=colour, lw=0.8)
            ax.step(tb, hi, where="post", color=colour, lw=0.8)
            continue
        w = _window(c.t, until) if until is not None else slice(None)
        ax.plot(c.t[w], (c.y[w] - y0) * 1e3, color=colour, label=c.label, **style)


def _styles(curves: Sequence[Curve], pairs: Sequence[Coincidence]) -> list[dict[str, Any]]:
    styles: list[dict[str, Any]] = [{"lw": 1.6, "ls": c.linestyle, "zorder": 2}
                                    for c in curves]
    for p in pairs:
        styles[p.earlier].update(lw=3.4, alpha=0.55, zorder=2)
        styles[p.later].update(lw=1.5, ls=(0, (5, 3)), zorder=3)
    return styles


def step_figure(curves: Sequence[Curve], title: str, *, y0: float = 0.0,
                zoom: float | None = 4.0, near: float | None = None) -> Figure:
    """Position response of each run [mm from the start position ``y0`` [m]] with the
    reference; with ``zoom`` [s] a second panel shows the first ``zoom`` seconds.

    ``near`` [m]: a curve within ``near`` of an earlier one over the whole run
    (:func:`coinciding`) is drawn dashed over the earlier one, widened, and its legend label
    gives the largest distance.
    """
    pairs = coinciding(curves, near) if near is not None else []
    labelled = list(curves)
    for p in pairs:
        c = labelled[p.later]
        labelled[p.later] = replace(
            c, label=f"{c.label} (dashed: within {p.max_diff * 1e3:.2g} mm of "
                     f"{curves[p.earlier].label})")
    styles = _styles(curves, pairs)
    t_end = float(curves[0].t[-1])
    two = zoom is not None and zoom < t_end
    fig = _figure(12.0 if two else 8.0, 5.0)
    axes = fig.subplots(1, 2 if two else 1, squeeze=False)[0]
    for i, ax in enumerate(axes):
        until = zoom if i == 1 else None
        _draw_positions(ax, labelled, y0, styles, until=until, envelopes=i == 0)
        ax.set_xlabel("time t [s]")
        ax.set_ylabel(r"piston position $x - x(0)$ [mm]")
        ax.grid(True, alpha=0.3)
        if until is not None:
            ax.set_xlim(0.0, until)
            ax.set_title(f"first {until:g} s")
        else:
            ax.set_xlim(0.0, t_end)
            if two:
                ax.set_title(f"whole run ({t_end:g} s)")
    _legend_below(fig, axes[0], 3 if len(curves) < 4 else 2)
    fig.suptitle(title)
    return fig


def _u_limits(values: Sequence[FloatArray]) -> tuple[float, float]:
    """y-limits [%] holding every value and 0 with a margin of 8 % of the span each side,
    so that a command at its limit is never drawn on the frame."""
    lo = min(0.0, *(float(np.min(v)) for v in values))
    hi = max(0.0, *(float(np.max(v)) for v in values))
    pad = 0.08 * max(hi - lo, 1e-9)
    return lo - pad, hi + pad


def command_figure(curves: Sequence[Curve], title: str, *, zoom: float = 0.2,
                   limit: float = 1.0) -> Figure:
    """Valve command of each run [% of rated input] over the whole run and, in a second
    panel, over the first ``zoom`` seconds (the PIDs' derivative kick); dotted lines at the
    command limit ``limit`` [-] when a run reaches it. A run at its limit within the zoom says
    when in its legend label."""
    fig = _figure(12.0, 5.0)
    axes = fig.subplots(1, 2, width_ratios=(1.6, 1.0))
    sats = [first_saturation(c.t, c.u, limit) for c in curves]
    saturates = any(s is not None for s in sats)
    for i, ax in enumerate(axes):
        shown = []
        for c, sat in zip(curves, sats, strict=True):
            w = _window(c.t, zoom) if i == 1 else slice(None)
            label = c.label
            if sat is not None and sat[0] < zoom:
                label += (f" (|u| = {limit * 100:g} % from {sat[0] * 1e3:.3g} to "
                          f"{sat[1] * 1e3:.3g} ms)")
            u = c.u[w] * 100.0
            shown.append(u)
            ax.step(c.t[w], u, where="post", color=_colour(c), lw=1.3, ls=c.linestyle,
                    label=label)
        if saturates:
            for s in (-1.0, 1.0):
                ax.axhline(s * limit * 100.0, color="black", lw=0.8, ls=":",
                           label=f"command limit |u| = {limit * 100:g} %" if s > 0 else None)
        ax.axhline(0.0, color="black", lw=0.6)
        lo, hi = _u_limits(shown)
        if saturates:  # the limit lines inside the frame as well
            lo, hi = min(lo, -0.08 * limit * 100.0), max(hi, 1.08 * limit * 100.0)
        ax.set_ylim(lo, hi)
        ax.set_xlabel("time t [s]")
        ax.grid(True, alpha=0.3)
        if i == 1:
            ax.set_xlim(0.0, zoom)
            ax.set_title(f"first {zoom:g} s")
        else:
            ax.set_xlim(0.0, float(curves[0].t[-1]))
            ax.set_ylabel(r"valve command $u$ [% of rated input]")
            ax.set_title("whole run")
    _legend_below(fig, axes[0], 2)
    fig.suptitle(title)
    return fig


def alpha_figure(curves: Sequence[Curve], title: str) -> Figure:
    """Gain updating factor :math:`\\alpha_F(t)` [-] of each run."""
    fig = _figure(8.0, 4.4)
    ax = fig.add_subplot(1, 1, 1)
    for c in curves:
        ax.step(c.t, c.alpha, where="post", color=_colour(c), lw=1.4, ls=c.linestyle,
                label=c.label)
    ax.set_ylim(0.0, 1.0)
    ax.set_xlim(0.0, float(curves[0].t[-1]))
    ax.set_xlabel("time t [s]")
    ax.set_ylabel(r"gain updating factor $\alpha_F$ [-]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title)
    return fig


def delay_figure(nominal: Curve, delayed: Curve, title: str, *, y0: float = 0.0,
                 zoom: float = 4.0) -> Figure:
    """Fig. 8: the run without and with the delay (top) and their difference, with delay
    minus without [mm] (bottom), over the whole run (left) and the first ``zoom`` s
    (right)."""
    diff = (np.interp(nominal.t, delayed.t, delayed.y) - nominal.y) * 1e3
    fig = _figure(12.0, 6.8)
    axes = fig.subplots(2, 2, height_ratios=(2.0, 1.0), sharex="col")
    styles: list[dict[str, Any]] = [{"lw": 2.6, "ls": "-", "zorder": 2},
                                    {"lw": 1.4, "ls": (0, (5, 3)), "zorder": 3}]
    t_end = float(nominal.t[-1])
    for col in range(2):
        until = zoom if col == 1 else None
        top, bottom = axes[0][col], axes[1][col]
        _draw_positions(top, [nominal, delayed], y0, styles, until=until, envelopes=False)
        top.set_ylabel(r"piston position $x - x(0)$ [mm]")
        top.set_title(f"first {zoom:g} s" if until is not None else f"whole run ({t_end:g} s)")
        w = _window(nominal.t, until) if until is not None else slice(None)
        bottom.plot(nominal.t[w], diff[w], color=_colour(delayed), lw=1.2,
                    label=rf"difference (with delay $-$ without): largest "
                          rf"$|\Delta x|$ = {np.max(np.abs(diff)):.3g} mm")
        bottom.axhline(0.0, color="black", lw=0.6)
        bottom.set_ylabel("with $-$ without\ndelay [mm]")
        bottom.set_xlabel("time t [s]")
        bottom.set_xlim(0.0, until if until is not None else t_end)
        for ax in (top, bottom):
            ax.grid(True, alpha=0.3)
    handles, labels = axes[0][0].get_legend_handles_labels()
    h2, l2 = axes[1][0].get_legend_handles_labels()
    fig.legend(handles + h2, labels + l2, loc="outside lower center", ncols=2, fontsize=8,
               frameon=False)
    fig.suptitle(title)
    return fig


def _minor_ticks(top_ms: float) -> list[float]:
    """1-9 ms, then 2-9 times each decade from 10 ms, up to ``top_ms``."""
    ticks = [float(k) for k in range(1, 10)]
    decade = 10.0
    while decade < top_ms:
        ticks += [k * decade for k in range(2, 10)]
        decade *= 10.0
    return [x for x in ticks if x <= top_ms]


def delay_sweep_figure(delays: FloatArray, values: Mapping[str, FloatArray],
                       labels: Mapping[str, str], title: str, *, ylabel: str,
                       failed: Mapping[str, BoolArray], run_length: float,
                       colours: Mapping[str, str] | None = None,
                       show_failed: bool = False, limit: float | None = None,
                       limit_label: str = "", mark: tuple[float, str] | None = None,
                       log_y: bool = False) -> Figure:
    """A metric against the transport delay [ms], one line per controller, on a delay axis
    linear up to :data:`SWEEP_LINTHRESH_MS` and logarithmic above.

    Parameters
    ----------
    delays : ndarray
        The sweep's delays [s].
    values, labels : mapping
        Per controller key: the metric at each delay [unit of ``ylabel``]; legend label.
    colours : mapping, optional
        Per controller key: its colour (a key not given: :data:`NO_COLOUR`).
    title, ylabel : str
        Figure title and y-axis label.
    failed : mapping of key to bool ndarray
        Where each controller fails (no 2 % settling within the run, or divergence): marked
        with a cross in a strip below the plot, one row per controller that fails somewhere.
    run_length : float
        Length of each run [s] (named in the strip's title).
    show_failed : bool
        Draw the metric of a failing run too, as a hollow marker (solid line and filled
        markers join the runs that settle); otherwise only settling runs are drawn.
    limit, limit_label : float, str
        A horizontal line at ``limit`` and its legend label (e.g. a claim's limit).
    mark : (float, str), optional
        A delay [s] to mark with a vertical line, and its legend label.
    log_y : bool
        A y axis linear up to ``limit`` (or 10) and logarithmic above.
    """
    from matplotlib.ticker import FixedLocator, NullFormatter  # only when drawing

    d_ms = np.asarray(delays, dtype=np.float64) * 1e3
    bad = {k: np.asarray(failed[k], dtype=bool) for k in values}
    fails = [k for k in values if bool(bad[k].any())]
    fig = _figure(11.0, 4.6 + 0.22 * len(fails))
    strip: Axes | None
    if fails:
        ax, strip = fig.subplots(2, 1, sharex=True,
                                 height_ratios=(3.6, 0.35 + 0.24 * len(fails)))
    else:
        ax, strip = fig.add_subplot(1, 1, 1), None
    def colour_of(key: str) -> str:
        return (colours or {}).get(key, NO_COLOUR)

    hollow = False
    for key, v in values.items():
        colour = colour_of(key)
        ok = ~bad[key] & np.isfinite(v)
        if ok.any():
            ax.plot(d_ms, np.where(ok, v, np.nan), color=colour, lw=1.5, marker="o", ms=4,
                    label=labels[key])
        shown_bad = bad[key] & np.isfinite(v)
        if show_failed and shown_bad.any():
            hollow = True
            ax.plot(d_ms, np.where(np.isfinite(v), v, np.nan), color=colour, lw=0.8, ls=":",
                    zorder=1)
            ax.plot(d_ms[shown_bad], v[shown_bad], ls="none", marker="o", ms=5, mfc="white",
                    mec=colour, label=None if ok.any() else labels[key])
    if hollow:
        ax.plot([], [], ls="none", marker="o", ms=5, mfc="white", mec="black",
                label="hollow: the run fails (see below)")
    if limit is not None:
        ax.axhline(limit, color="black", ls="--", lw=1.0, label=limit_label or None)
    if mark is not None:
        for a in (ax, strip):
            if a is not None:
                a.axvline(mark[0] * 1e3, color="#555555", ls=":", lw=1.2,
                          label=mark[1] if a is ax else None)
    ax.set_xscale("symlog", linthresh=SWEEP_LINTHRESH_MS, linscale=1.0)
    ticks = [x for x in _SWEEP_TICKS_MS if x <= d_ms.max() * 1.0001]
    ax.set_xticks(ticks, [f"{x:g}" for x in ticks])
    ax.xaxis.set_minor_locator(FixedLocator(_minor_ticks(float(d_ms.max()))))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlim(-0.4, d_ms.max() * 1.08)  # a point at 0 ms clear of the frame
    if log_y:
        ax.set_yscale("symlog", linthresh=limit if limit else 10.0, linscale=1.0)
        finite = [x for v in values.values() for x in np.asarray(v)[np.isfinite(v)]]
        top = max([1.0, *finite])
        low = min([0.0, *finite])
        yt = [y for y in (0, 2, 4, 6, 8, 10, 20, 50, 100, 200, 500, 1000) if y <= top * 1.5]
        ax.set_yticks(yt, [f"{y:g}" for y in yt])
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_ylim(low - 0.4, top * 1.4)
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.grid(True, which="minor", axis="x", alpha=0.12)
    ax.set_title(title)
    handles, hl = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, hl, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8,
                  frameon=False)
    bottom = ax
    if strip is not None:
        for row, key in enumerate(fails):
            f = bad[key]
            strip.plot(d_ms[f], np.full(int(f.sum()), row), ls="none", marker="x", ms=6,
                       mew=1.6, color=colour_of(key))
        strip.set_yticks(range(len(fails)), [labels[k] for k in fails], fontsize=7)
        for tick, key in zip(strip.get_yticklabels(), fails, strict=True):
            tick.set_color(colour_of(key))
        strip.set_ylim(len(fails) - 0.5, -0.5)
        strip.set_title(f"× fails at this delay: no 2 % settling within the {run_length:g} s "
                        f"run, or diverged", fontsize=8, loc="left")
        strip.grid(True, axis="x", alpha=0.3)
        bottom = strip
    bottom.set_xlabel("transport (hose) delay [ms]  (linear to "
                      f"{SWEEP_LINTHRESH_MS:g} ms, logarithmic above)")
    return fig


def tracking_figure(curves: Sequence[Curve], title: str, *, what: str = "error",
                    since: float = 0.0, mark: float | None = None,
                    mark_label: str = "") -> Figure:
    """A tracking or disturbance experiment: above, the reference and each run's position
    [mm from the first sample]; below, each run's tracking error r - y (``what="error"``)
    or its deviation from its position at ``mark`` (``what="deviation"``) [mm], from
    ``since`` [s] on; a dotted line at ``mark`` [s] (the end of a move, a load step)."""
    fig = _figure(10.0, 6.5)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(1.0, 1.3))
    ref = curves[0]
    y0 = float(ref.y[0])
    k0 = int(np.searchsorted(ref.t, since, side="left"))
    top.plot(ref.t[k0:], (ref.r[k0:] - y0) * 1e3, color="k", lw=1.0, ls=(0, (4, 3)),
             label="reference", zorder=5)  # over the runs, which often cover it
    for c in curves:
        colour = _colour(c)
        top.plot(c.t[k0:], (c.y[k0:] - y0) * 1e3, color=colour, lw=1.2, ls=c.linestyle,
                 label=c.label)
        if what == "deviation":
            km = int(np.searchsorted(c.t, mark if mark is not None else 0.0, side="left"))
            v = (c.y - c.y[min(km, c.y.size - 1)]) * 1e3
        else:
            v = (c.r - c.y) * 1e3
        bottom.plot(c.t[k0:], v[k0:], color=colour, lw=1.2, ls=c.linestyle)
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
        if mark is not None:
            ax.axvline(mark, color="0.4", lw=0.8, ls=":")
    if mark is not None and mark_label:
        bottom.text(mark, 1.0, f" {mark_label}", transform=bottom.get_xaxis_transform(),
                    va="top", ha="left", fontsize=8, color="0.3")
    top.set_ylabel(r"position $x - x(0)$ [mm]")
    bottom.set_ylabel("deviation from the position at the load step [mm]"
                      if what == "deviation" else "tracking error r - y [mm]")
    bottom.set_xlabel("time t [s]")
    bottom.set_xlim(float(ref.t[k0]), float(ref.t[-1]))
    _legend_below(fig, top, 2)
    fig.suptitle(title)
    return fig


def save(fig: Figure, stem: Path) -> list[Path]:
    """Write ``stem.png`` and ``stem.svg`` atomically and return both paths."""
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.parent / f"{stem.name}.png", stem.parent / f"{stem.name}.svg"]
    for p in paths:
        with atomic_write(p, binary=True) as fh:
            fig.savefig(fh, format=p.suffix[1:], dpi=DPI)
        fig.set_layout_engine("none")  # laid out once: the second format reuses it
    return paths
