"""Figures of a robustness sweep's report, rendered from numbers the report already computed
(:mod:`fuzzyservo.sweep.report`): nothing here reads a dataset or bins a row.

Each renderer takes small arrays (one value per controller and outcome, per quantile, per bin
or per map cell) and returns a matplotlib ``Figure`` (object API, no global state); the
controllers of a sweep are always drawn side by side, each in the same colour in every figure
(:func:`controller_colours`, in the spec's order). :func:`save_png` writes a figure.
matplotlib is imported only when a figure is drawn.

Figures:

- :func:`outcomes_figure`: the share of each outcome, one stacked bar per controller;
- :func:`distributions_figure`: empirical CDFs of metrics, one curve per controller, as a
  fraction of all the controller's runs (a curve ends below 1 by the share of runs where the
  metric is undefined);
- :func:`paired_figure`: for every two controllers, the share of points where the row's is
  better than the column's;
- :func:`effects_figure`: a statistic per bin (or grid value) of each varied quantity;
- :func:`map_figure`: a statistic over two varied quantities, one panel per controller, one
  colour scale shared by all panels.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._io import atomic_write
from .._typing import BoolArray, FloatArray
from .study_figures import DPI

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "OUTCOME_COLOURS",
    "SWEEP_COLOURS",
    "Distribution",
    "MapAxis",
    "controller_colours",
    "distributions_figure",
    "effects_figure",
    "map_figure",
    "outcomes_figure",
    "paired_figure",
    "save_png",
]

#: Colours of a sweep's controllers, in the spec's order: the Okabe-Ito colour-blind-safe
#: palette without its yellow (too light on white), then Tol's muted olive, indigo and rose.
SWEEP_COLOURS: tuple[str, ...] = ("#0072b2", "#d55e00", "#009e73", "#cc79a7", "#e69f00",
                                  "#56b4e9", "#000000", "#999933", "#332288", "#882255")

#: Colour of each outcome (``fuzzyservo.analysis.outcome.OUTCOMES``): green to red as they
#: worsen, grey for a point without a valid plant.
OUTCOME_COLOURS: dict[str, str] = {
    "settles": "#1a9850",
    "overshoots": "#a6d96a",
    "not settled": "#fdae61",
    "limit cycle": "#d73027",
    "diverged": "#67001f",
    "invalid": "#bdbdbd",
}

#: Panels per row of the figures that draw one panel per controller or per quantity.
PANELS_PER_ROW = 4


def controller_colours(n: int) -> list[str]:
    """Colours of ``n`` controllers, in order (the palette repeats after 10)."""
    return [SWEEP_COLOURS[i % len(SWEEP_COLOURS)] for i in range(n)]


def _figure(width: float, height: float) -> Figure:
    from matplotlib.figure import Figure  # only when drawing (see the module's doc)

    return Figure(figsize=(width, height), dpi=DPI, layout="constrained")


def _grid(fig: Figure, n: int, *, sharex: bool = False, sharey: bool = False
          ) -> list[Axes]:
    """``n`` panels, :data:`PANELS_PER_ROW` a row; unused cells are removed."""
    cols = min(n, PANELS_PER_ROW)
    rows = -(-n // cols)
    axes = fig.subplots(rows, cols, squeeze=False, sharex=sharex, sharey=sharey).ravel()
    for ax in axes[n:]:
        ax.remove()
    return list(axes[:n])


def save_png(fig: Figure, path: Path) -> Path:
    """Write ``fig`` as PNG to ``path`` atomically and return the path."""
    path = Path(path)
    with atomic_write(path, binary=True) as fh:
        fig.savefig(fh, format="png", dpi=DPI)
    return path


# --- outcomes --------------------------------------------------------------------------------

def outcomes_figure(controllers: Sequence[str], outcomes: Sequence[str], shares: FloatArray,
                    title: str) -> Figure:
    """Share of each outcome per controller, as one stacked horizontal bar a controller.

    Parameters
    ----------
    controllers : sequence of str
        Controller labels, top to bottom.
    outcomes : sequence of str
        Outcome names, best first (:data:`OUTCOME_COLOURS` colours them).
    shares : ndarray
        (len(controllers), len(outcomes)) fractions of each controller's runs [-].
    title : str
        Figure title.
    """
    n = len(controllers)
    fig = _figure(10.0, 1.6 + 0.55 * n)
    ax = fig.add_subplot(1, 1, 1)
    y = np.arange(n)
    left = np.zeros(n)
    for k, name in enumerate(outcomes):
        w = np.asarray(shares[:, k], dtype=np.float64) * 100.0
        if not np.any(w > 0.0):
            continue
        ax.barh(y, w, left=left, color=OUTCOME_COLOURS.get(name, "#7f7f7f"), label=name,
                edgecolor="white", lw=0.6, height=0.62)
        for i in np.flatnonzero(w >= 6.0):  # a label where it fits
            dark = name in ("limit cycle", "diverged", "settles")
            ax.text(left[i] + w[i] / 2.0, y[i], f"{w[i]:.3g} %", ha="center", va="center",
                    fontsize=8, color="white" if dark else "black")
        left = left + w
    ax.set_yticks(y, list(controllers))
    ax.set_ylim(n - 0.5, -0.5)
    ax.set_xlim(0.0, 100.0)
    ax.set_xlabel("share of the controller's runs [%]")
    ax.grid(True, axis="x", alpha=0.3)
    ax.set_title(title)
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=len(handles),
                   fontsize=8, frameon=False)
    return fig


# --- distributions ---------------------------------------------------------------------------

@dataclass(frozen=True, slots=True, kw_only=True)
class Distribution:
    """One metric's empirical CDFs, one per controller.

    ``x[i]`` are sorted values of controller ``i`` (quantiles of its defined values, at most a
    few hundred), ``y[i]`` the fraction of all its runs at or below each [-]; ``defined[i]``
    the fraction of its runs where the metric is defined [-].
    """

    label: str  #: axis label with unit
    x: tuple[FloatArray, ...]  #: values per controller [unit of the label]
    y: tuple[FloatArray, ...]  #: cumulative fractions per controller [-]
    defined: tuple[float, ...]  #: share of runs with a defined value per controller [-]
    log: bool = False  #: logarithmic value axis


def distributions_figure(controllers: Sequence[str], panels: Sequence[Distribution],
                         title: str) -> Figure:
    """Empirical CDFs of some metrics, one panel a metric, one curve a controller; a
    controller without a defined value in a panel is named in it."""
    colours = controller_colours(len(controllers))
    n = len(panels)
    cols = min(n, PANELS_PER_ROW)
    rows = -(-n // cols)
    fig = _figure(3.3 * cols + 0.6, 3.0 * rows + 1.0)
    axes = _grid(fig, n, sharey=True)
    for ax, p in zip(axes, panels, strict=True):
        missing = []
        for i, lab in enumerate(controllers):
            if p.x[i].size == 0:
                missing.append(lab)
                continue
            # from 0 at the smallest value, then a step at each quantile
            xs = np.concatenate([p.x[i][:1], p.x[i]])
            ys = np.concatenate([[0.0], p.y[i]])
            ax.step(xs, ys * 100.0, where="post", color=colours[i], lw=1.6)
        if p.log:
            ax.set_xscale("log")
            _plain_log(ax.xaxis, np.concatenate(p.x))
        if missing:
            ax.text(0.98, 0.03, "no defined value:\n" + "\n".join(missing), ha="right",
                    va="bottom", fontsize=7, transform=ax.transAxes, color="#555555")
        if all(x.size == 0 for x in p.x):
            ax.set_xticks([])
        ax.set_xlabel(p.label)
        ax.set_ylim(0.0, 102.0)
        ax.grid(True, alpha=0.3)
    for ax in axes[::cols]:
        ax.set_ylabel("runs at or below [%]")
    _controller_legend(fig, controllers, colours)
    fig.suptitle(title)
    return fig


def _controller_legend(fig: Figure, controllers: Sequence[str], colours: Sequence[str]
                       ) -> None:
    from matplotlib.lines import Line2D  # only when drawing

    handles = [Line2D([], [], color=c, lw=2.0) for c in colours]
    fig.legend(handles, list(controllers), loc="outside lower center",
               ncols=min(len(controllers), 4), fontsize=8, frameon=False)


# --- paired comparisons ----------------------------------------------------------------------

def paired_figure(controllers: Sequence[str], matrices: Sequence[tuple[str, FloatArray]],
                  title: str) -> Figure:
    """Win matrices: ``matrices[k] = (name, M)`` with ``M[i, j]`` the share of the points where
    controller ``i`` is better than controller ``j`` by ``name`` [-] (NaN on the diagonal)."""
    n = len(controllers)
    m = len(matrices)
    side = max(3.4, 0.9 * n + 1.8)
    fig = _figure(side * m + 1.0, side + 0.6)
    axes = fig.subplots(1, m, squeeze=False)[0]
    image: Any = None
    for ax, (name, mat) in zip(axes, matrices, strict=True):
        pct = np.asarray(mat, dtype=np.float64) * 100.0
        ax.set_facecolor("#d9d9d9")  # the diagonal (a controller against itself) in grey
        # sequential, not diverging: 50 % is no neutral point when ties are common
        image = ax.imshow(np.ma.masked_invalid(pct), cmap="Blues", vmin=0.0, vmax=100.0)
        for i in range(n):
            for j in range(n):
                if i == j or not math.isfinite(pct[i, j]):
                    continue
                v = pct[i, j]
                ax.text(j, i, f"{v:.3g} %", ha="center", va="center", fontsize=8,
                        color="white" if v > 60.0 else "black")
        ax.set_xticks(range(n), list(controllers), rotation=30, ha="right", fontsize=8)
        ax.set_yticks(range(n), list(controllers), fontsize=8)
        ax.set_xlabel("... than this controller")
        ax.set_title(name, fontsize=10)
    axes[0].set_ylabel("this controller is better ...")
    if image is not None:
        fig.colorbar(image, ax=list(axes), shrink=0.8,
                     label="points where the row is better [%]")
    fig.suptitle(title)
    return fig


# --- effects of the varied quantities and maps -----------------------------------------------

@dataclass(frozen=True, slots=True, kw_only=True)
class MapAxis:
    """One axis of an effect plot or map: grid values (categorical) or bins of drawn values.

    ``centres`` holds the display value of each category or bin; ``edges`` the bin edges of a
    binned axis (``len(centres) + 1`` values), empty for a categorical one.
    """

    label: str  #: axis label with unit (display units)
    centres: FloatArray  #: value of each category or bin [display unit]
    edges: FloatArray  #: bin edges [display unit], empty when categorical
    log: bool = False  #: logarithmic axis (positive values only)

    @property
    def categorical(self) -> bool:
        """Whether the axis holds grid values rather than bins."""
        return self.edges.size == 0


def _plain_log(axis: Any, values: FloatArray | None = None) -> None:
    """Label a logarithmic axis with plain numbers (0.5, 1, 2) rather than powers of ten:
    1-1.5-2-3-5-7 within a decade, 1-2-5 over up to three, powers of ten over more."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter  # only when drawing

    subs: tuple[float, ...] = (1.0, 2.0, 5.0)
    if values is not None:
        v = np.asarray(values, dtype=np.float64)
        v = v[np.isfinite(v) & (v > 0.0)]
        if v.size:
            decades = math.log10(float(v.max()) / float(v.min()))
            if decades < 1.0:
                subs = (1.0, 1.5, 2.0, 3.0, 5.0, 7.0)
            elif decades > 3.0:
                subs = (1.0,)
    axis.set_major_locator(LogLocator(subs=subs))
    axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def _set_value_axis(ax: Axes, axis: MapAxis) -> None:
    if axis.log:
        ax.set_xscale("log")
        _plain_log(ax.xaxis, axis.centres)
    ax.set_xlabel(axis.label)


def effects_figure(controllers: Sequence[str], axes_: Sequence[MapAxis],
                   values: Sequence[FloatArray], *, ylabel: str, title: str,
                   sparse: Sequence[BoolArray] | None = None, log_y: bool = False,
                   ylim: tuple[float, float] | None = None) -> Figure:
    """A statistic per bin (or grid value) of each varied quantity, one panel a quantity, one
    line a controller; ``values[q]`` is (controllers, bins of quantity q), NaN where a bin has
    no value [unit of ``ylabel``]; ``sparse[q]`` marks the bins drawn hollow (few runs)."""
    colours = controller_colours(len(controllers))
    n = len(axes_)
    cols = min(n, PANELS_PER_ROW)
    rows = -(-n // cols)
    fig = _figure(3.3 * cols + 0.6, 2.9 * rows + 1.0)
    panels = _grid(fig, n, sharey=True)
    for q_i, (ax, axis, vals) in enumerate(zip(panels, axes_, values, strict=True)):
        drawn = False
        for i in range(len(controllers)):
            v = np.asarray(vals[i], dtype=np.float64)
            ok = np.isfinite(v)
            if log_y:
                ok &= v > 0.0
            if not ok.any():
                continue
            drawn = True
            few = (np.asarray(sparse[q_i], dtype=bool) if sparse is not None
                   else np.zeros(v.shape, dtype=bool))
            ax.plot(axis.centres[ok], v[ok], color=colours[i], lw=1.4)
            ax.plot(axis.centres[ok & ~few], v[ok & ~few], ls="none", color=colours[i],
                    marker="o", ms=4)
            ax.plot(axis.centres[ok & few], v[ok & few], ls="none", color=colours[i],
                    marker="o", ms=4, mfc="white")
        if not drawn:
            ax.text(0.5, 0.5, "no value to show", ha="center", va="center",
                    transform=ax.transAxes, fontsize=8, color="#555555")
        _set_value_axis(ax, axis)
        if axis.categorical and axis.centres.size <= 12:
            ax.set_xticks(axis.centres, [f"{c:.3g}" for c in axis.centres])
            ax.minorticks_off()
        if log_y:
            ax.set_yscale("log")
            _plain_log(ax.yaxis, np.asarray(vals, dtype=np.float64))
        if ylim is not None:
            ax.set_ylim(*ylim)
        ax.grid(True, alpha=0.3)
    for ax in panels[::cols]:
        ax.set_ylabel(ylabel)
    _controller_legend(fig, controllers, colours)
    fig.suptitle(title)
    return fig


def _map_edges(axis: MapAxis) -> FloatArray:
    if axis.categorical:
        return np.arange(axis.centres.size + 1, dtype=np.float64) - 0.5
    return np.asarray(axis.edges, dtype=np.float64)


def map_figure(controllers: Sequence[str], xaxis: MapAxis, yaxis: MapAxis,
               values: FloatArray, *, label: str, title: str, log: bool = False,
               vmin: float | None = None, vmax: float | None = None, cmap: str = "viridis",
               percent: bool = False) -> Figure:
    """A statistic over two varied quantities, one panel a controller, one colour scale.

    Parameters
    ----------
    controllers : sequence of str
        Controller labels (one panel each).
    xaxis, yaxis : MapAxis
        The two quantities: grid values as equal cells labelled by value, bins on a value axis.
    values : ndarray
        (controllers, len(yaxis.centres), len(xaxis.centres)); NaN where a cell has too few
        runs (drawn hatched) [unit of ``label``].
    label : str
        Colour bar label.
    title : str
        Figure title.
    log : bool
        Logarithmic colour scale (positive values only).
    vmin, vmax : float, optional
        Colour scale limits (default: the finite values' range).
    cmap : str
        matplotlib colour map.
    percent : bool
        Annotate cells as percentages (values are fractions); else 3 significant digits.
    """
    from matplotlib.colors import LogNorm, Normalize  # only when drawing
    from matplotlib.patches import Rectangle
    from matplotlib.ticker import PercentFormatter

    vals = np.asarray(values, dtype=np.float64)
    finite = vals[np.isfinite(vals) & ((vals > 0.0) if log else True)]
    lo = vmin if vmin is not None else (float(finite.min()) if finite.size else 0.0)
    hi = vmax if vmax is not None else (float(finite.max()) if finite.size else 1.0)
    if not hi > lo:
        hi = lo * 1.5 if log and lo > 0.0 else lo + 1.0
    norm = LogNorm(lo, hi) if log and lo > 0.0 else Normalize(lo, hi)
    n = len(controllers)
    cols = min(n, PANELS_PER_ROW)
    rows = -(-n // cols)
    fig = _figure(3.6 * cols + 1.2, 3.2 * rows + 0.9)
    panels = _grid(fig, n)
    xe, ye = _map_edges(xaxis), _map_edges(yaxis)
    # a value in each cell only where it fits: a 3.6-inch panel holds about 6 labels a row
    annotate = xaxis.centres.size <= 6 and yaxis.centres.size <= 10
    mesh: Any = None
    for i, (ax, name) in enumerate(zip(panels, controllers, strict=True)):
        z = vals[i]
        shown = np.isfinite(z) & ((z > 0.0) if log else True)
        # hatched background: a cell without a value shows it
        ax.add_patch(Rectangle((0.0, 0.0), 1.0, 1.0, transform=ax.transAxes, fill=False,
                               hatch="///", edgecolor="#c8c8c8", lw=0.0, zorder=0))
        mesh = ax.pcolormesh(xe, ye, np.ma.masked_where(~shown, z), cmap=cmap, norm=norm,
                             edgecolors="white", linewidth=0.5)
        if annotate:
            xc = (xe[:-1] + xe[1:]) / 2.0 if not xaxis.log else np.sqrt(xe[:-1] * xe[1:])
            yc = (ye[:-1] + ye[1:]) / 2.0 if not yaxis.log else np.sqrt(ye[:-1] * ye[1:])
            for r, c in zip(*np.nonzero(shown), strict=True):
                v = float(z[r, c])
                text = f"{100.0 * v:.3g} %" if percent else f"{v:.3g}"
                rgba = mesh.cmap(norm(v))
                light = 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2] > 0.55
                ax.text(xc[c], yc[r], text, ha="center", va="center", fontsize=7,
                        color="black" if light else "white")
        if not shown.any():
            ax.text(0.5, 0.5, "no value to show", ha="center", va="center",
                    transform=ax.transAxes, fontsize=9, color="#333333")
        for axis, mpl_axis, scale in ((xaxis, ax.xaxis, ax.set_xscale),
                                      (yaxis, ax.yaxis, ax.set_yscale)):
            if axis.categorical:
                mpl_axis.set_ticks(range(axis.centres.size), [f"{c:.3g}" for c in axis.centres])
            else:
                if axis.log:
                    scale("log")
                    _plain_log(mpl_axis, axis.edges)
                if axis.edges.size <= 9:  # few bins: their edges are the ticks
                    mpl_axis.set_ticks(axis.edges, [f"{e:.3g}" for e in axis.edges])
                    mpl_axis.set_ticks([], minor=True)
            mpl_axis.set_label_text(axis.label, fontsize=8)
        ax.set_title(name, fontsize=10, color=controller_colours(n)[i])
    if mesh is not None:
        cb = fig.colorbar(mesh, ax=panels, shrink=0.85, label=label)
        if percent:
            cb.ax.yaxis.set_major_formatter(PercentFormatter(xmax=1.0))
    fig.suptitle(title)
    return fig
