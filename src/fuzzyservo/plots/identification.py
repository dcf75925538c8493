"""The figure of an identification: measured against fitted traces, residuals, the estimates.

:func:`identification_figure` takes the result of :func:`fuzzyservo.identify.identify` (read
through its attributes only: plots does not import the identify layer), computes what it draws
first (:func:`identification_data`: traces and residuals in display units, the flagged time
spans, each estimate relative to its starting value) and renders it second. Per channel
(position y [mm], chamber pressures p_f and p_n [bar]):

- the measured trace (thin grey), the identified model (colour) and the starting model
  (dashed, light) against time;
- below it, the residual (measured - fitted) with the band ±2σ, σ the channel's weight in
  the fit (after re-weighting, the residual RMS of the first fit);
- samples left out of the fit (flagged) shaded on every time axis.

Beside them, one row per fitted parameter: the estimate divided by its starting value, with
±2 standard errors and, when the fit ran a bootstrap, its percentile interval; a start value
of 0 (a friction) is replaced by the upper bound of the search, and the row says so.
:func:`save_identification_figure` writes PNG or SVG atomically (:func:`~.runs.save_figure`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._typing import FloatArray
from ..errors import InputError
from .runs import FIGURE_FORMATS, check_text, save_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["ChannelTrace", "EstimateRow", "IdentificationData", "identification_data",
           "identification_figure", "save_identification_figure"]

#: Each channel as drawn: axis label (mathtext), display unit, display units per SI unit.
CHANNEL_DISPLAY: dict[str, tuple[str, str, float]] = {
    "y": ("position $y$", "mm", 1.0e3),
    "p_f": ("full-bore pressure $p_f$", "bar", 1.0e-5),
    "p_n": ("annulus pressure $p_n$", "bar", 1.0e-5),
}

_MEASURED: dict[str, Any] = {"color": "0.45", "lw": 0.7}
_FITTED: dict[str, Any] = {"color": "#1f77b4", "lw": 1.3}
_START: dict[str, Any] = {"color": "#ff7f0e", "lw": 1.0, "ls": "--", "alpha": 0.6}
_BAND: dict[str, Any] = {"color": "#1f77b4", "alpha": 0.15, "lw": 0.0}
_FLAGGED: dict[str, Any] = {"color": "#d62728", "alpha": 0.12, "lw": 0.0}
_BOOT = "#2ca02c"
_ON_BOUND = "#d62728"


@dataclass(frozen=True, slots=True, kw_only=True)
class ChannelTrace:
    """One channel as drawn, in display units."""

    name: str  #: channel name (``y``, ``p_f``, ``p_n``)
    label: str  #: axis label, without the unit
    unit: str  #: display unit (mm, bar)
    scale: float  #: display units per SI unit
    measured: FloatArray  #: logged trace [display unit]
    fitted: FloatArray  #: identified model's trace [display unit]
    start: FloatArray  #: starting model's trace [display unit]
    residual: FloatArray  #: measured - fitted [display unit]
    sigma: float  #: the channel's weight σ in the fit [display unit]
    rms: float  #: residual RMS over the samples used [display unit]


@dataclass(frozen=True, slots=True, kw_only=True)
class EstimateRow:
    """One fitted parameter as drawn: its estimate relative to a reference value."""

    label: str  #: row label: name, unit, estimate and start value
    reference: float  #: the value divided by: the start value, or the upper bound when 0 [SI]
    ratio: float  #: estimate / reference [1]
    half_width: float  #: 2 standard errors / reference [1]
    interval: tuple[float, float] | None  #: bootstrap interval / reference [1], or None
    on_bound: bool  #: the estimate lies on a bound of its search interval


@dataclass(frozen=True, slots=True, kw_only=True)
class IdentificationData:
    """What :func:`identification_figure` draws (computed, not drawn)."""

    t: FloatArray  #: sample times [s]
    channels: tuple[ChannelTrace, ...]  #: compared signals, in the fit's order
    flagged: tuple[tuple[float, float], ...]  #: time spans left out of the fit [s]
    estimates: tuple[EstimateRow, ...]  #: one per fitted parameter, in the fit's order
    level: float  #: coverage of the bootstrap intervals [1]
    title: str  #: figure title


def flagged_spans(t: FloatArray, flagged: Any) -> tuple[tuple[float, float], ...]:
    """Runs of consecutive flagged samples as time spans [s]: each sample covers half a
    sample period either side of its time."""
    f = np.asarray(flagged, dtype=bool)
    if t.size == 0 or not f.any():
        return ()
    half = 0.5 * (float(t[1] - t[0]) if t.size > 1 else 0.0)
    edges = np.diff(np.concatenate(([0], f.astype(np.int8), [0])))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1) - 1
    return tuple((float(t[a]) - half, float(t[b]) + half)
                 for a, b in zip(starts, ends, strict=True))


def _estimate_rows(ident: Any) -> tuple[EstimateRow, ...]:
    rows = []
    bounds = np.asarray(ident.bounds, dtype=np.float64)
    interval = None if ident.interval is None else np.asarray(ident.interval, np.float64)
    for i, (name, unit) in enumerate(zip(ident.names, ident.units, strict=True)):
        start = float(ident.initial[i])
        est = float(ident.estimate[i])
        se = float(ident.std_error[i])
        lo, hi = float(bounds[i, 0]), float(bounds[i, 1])
        ref = start if start != 0.0 and math.isfinite(start) else hi
        on_bound = est <= lo + 1e-6 * abs(lo) or est >= hi - 1e-6 * abs(hi)
        label = f"{name} [{unit}]\n{est:.4g} (start {start:.4g})"
        if ref != start:
            label += ", ÷ upper bound"
        if on_bound:
            label += ", on a bound"
        rows.append(EstimateRow(
            label=label, reference=ref, ratio=est / ref, half_width=2.0 * se / abs(ref),
            interval=None if interval is None else (float(interval[i, 0]) / ref,
                                                    float(interval[i, 1]) / ref),
            on_bound=on_bound))
    return tuple(rows)


def identification_data(ident: Any, *, title: str | None = None) -> IdentificationData:
    """The data of :func:`identification_figure` (computed, not drawn).

    Parameters
    ----------
    ident : Identification
        The result of :func:`fuzzyservo.identify.identify`, read through its attributes
        ``t``, ``channels``, ``measured``, ``fitted``, ``start_fit``, ``used``, ``sigma``,
        ``residual_rms``, ``names``, ``units``, ``initial``, ``estimate``, ``std_error``,
        ``bounds``, ``interval``, ``level``, ``plant``, ``mode``, ``chi2``.
    title : str, optional
        Figure title; default the plant, the mode and the reduced chi-square.
    """
    t = np.asarray(ident.t, dtype=np.float64)
    traces = []
    for c in ident.channels:
        label, unit, scale = CHANNEL_DISPLAY.get(c, (c, "SI", 1.0))
        meas = np.asarray(ident.measured[c], dtype=np.float64) * scale
        fit = np.asarray(ident.fitted[c], dtype=np.float64) * scale
        traces.append(ChannelTrace(
            name=c, label=label, unit=unit, scale=scale, measured=meas, fitted=fit,
            start=np.asarray(ident.start_fit[c], dtype=np.float64) * scale,
            residual=meas - fit, sigma=float(ident.sigma[c]) * scale,
            rms=float(ident.residual_rms[c]) * scale))
    if title is None:
        title = (f"identification: {ident.plant} model, {ident.mode}, "
                 rf"reduced $\chi^2$ = {float(ident.chi2):.3g}")
    return IdentificationData(
        t=t, channels=tuple(traces), flagged=flagged_spans(t, ~np.asarray(ident.used, bool)),
        estimates=_estimate_rows(ident), level=float(ident.level), title=title)


def identification_figure(ident: Any, *, title: str | None = None) -> Figure:
    """Measured against fitted traces, residuals with ±2σ, and the estimates relative to
    their starting values with 2-SE error bars and bootstrap intervals.

    Parameters
    ----------
    ident : Identification
        The result of :func:`fuzzyservo.identify.identify` (see :func:`identification_data`).
    title : str, optional
        Figure title; default the plant, the mode and the reduced chi-square.

    Returns
    -------
    matplotlib.figure.Figure
        Left column: per channel a trace axis and a residual axis below it (time shared);
        right column: the estimates axis.

    Raises
    ------
    InputError
        ``title`` is mathtext matplotlib cannot parse.
    """
    from matplotlib.figure import Figure

    d = identification_data(ident, title=title)
    check_text(d.title, "title")
    n_c = len(d.channels)
    n_p = len(d.estimates)
    height = max(1.2 + 2.9 * n_c, 1.6 + 0.55 * n_p)
    fig = Figure(figsize=(12.0, height), dpi=110, layout="constrained")
    gs = fig.add_gridspec(2 * n_c, 2, width_ratios=(2.3, 1.0),
                          height_ratios=[h for _ in range(n_c) for h in (3.0, 1.2)])
    first = None
    for k, ch in enumerate(d.channels):
        ax = fig.add_subplot(gs[2 * k, 0], sharex=first)
        first = first or ax
        ax_r = fig.add_subplot(gs[2 * k + 1, 0], sharex=first)
        for a in (ax, ax_r):
            for t0, t1 in d.flagged:
                a.axvspan(t0, t1, **_FLAGGED)
            a.grid(True, alpha=0.3)
        ax.plot(d.t, ch.measured, label="measured", **_MEASURED)
        ax.plot(d.t, ch.start, label="starting model", **_START)
        ax.plot(d.t, ch.fitted, label="identified model", **_FITTED)
        ax.set_ylabel(f"{ch.label}\n[{ch.unit}]")
        ax.tick_params(labelbottom=False)
        ax_r.axhspan(-2.0 * ch.sigma, 2.0 * ch.sigma, **_BAND)
        ax_r.axhline(0.0, color="black", lw=0.6)
        ax_r.plot(d.t, ch.residual, **_MEASURED)
        ax_r.set_ylabel(f"residual\n[{ch.unit}]")
        ax_r.text(0.995, 0.95, f"RMS {ch.rms:.3g} {ch.unit}, σ {ch.sigma:.3g} {ch.unit}",
                  transform=ax_r.transAxes, ha="right", va="top", fontsize=7.5,
                  bbox={"facecolor": "white", "alpha": 0.7, "lw": 0.0, "pad": 1.0})
        if k < n_c - 1:
            ax_r.tick_params(labelbottom=False)
        else:
            ax_r.set_xlabel("time t [s]")
        if k == 0:  # one legend, for every channel's axes
            ax.fill_between([], [], [], label=r"residual band $\pm 2\sigma$", **_BAND)
            if d.flagged:
                ax.fill_between([], [], [], label="flagged (not fitted)", **_FLAGGED)
            ax.legend(loc="best", fontsize=8)
    if first is not None:
        first.set_xlim(float(d.t[0]), float(d.t[-1]))
    _estimates_axis(fig.add_subplot(gs[:, 1]), d)
    fig.suptitle(d.title)
    return fig


def _estimates_axis(ax: Any, d: IdentificationData) -> None:
    n = len(d.estimates)
    ys = np.arange(n)[::-1].astype(np.float64)  # the first parameter on top
    ext: list[float] = [1.0]
    boot_drawn = False
    for y, row in zip(ys, d.estimates, strict=True):
        colour = _ON_BOUND if row.on_bound else _FITTED["color"]
        ax.errorbar([row.ratio], [y], xerr=[[row.half_width], [row.half_width]], fmt="o",
                    color=colour, ms=5, capsize=4, lw=1.4,
                    label="estimate ± 2 SE (in % of it)" if y == ys[0] else None)
        ext.append(row.ratio)
        rel = 100.0 * row.half_width / abs(row.ratio) if row.ratio != 0.0 else math.inf
        if rel <= 100.0:  # a wider bar runs off the axis (its size is written above it)
            ext += [row.ratio - row.half_width, row.ratio + row.half_width]
        ax.annotate(f"±{rel:.2g} %" if rel < 100.0 else f"±{rel:.0f} %", (row.ratio, y),
                    xytext=(0.0, 6.0),
                    textcoords="offset points", ha="center", va="bottom", fontsize=7.5,
                    color=colour)
        if row.interval is not None:
            lo, hi = row.interval
            ax.plot([lo, hi], [y - 0.12, y - 0.12], color=_BOOT, lw=5.0, alpha=0.7,
                    solid_capstyle="butt",
                    label=f"bootstrap {d.level:.0%} interval" if not boot_drawn else None)
            boot_drawn = True
            ext += [lo, hi] if hi - lo <= 2.0 * abs(row.ratio) else []
    ax.axvline(1.0, color="0.3", lw=0.8, ls="--", label="start value")
    finite = [e for e in ext if math.isfinite(e)]
    lo, hi = min(finite), max(finite)
    if lo > 0.0 and hi / lo > 20.0:
        ax.set_xscale("log")
        ax.set_xlim(lo / 1.3, hi * 1.3)
    else:  # room either side, so the start line and the end points stay clear of the frame
        pad = 0.1 * (hi - lo) or 0.05
        ax.set_xlim(lo - pad, hi + pad)
    ax.set_yticks(ys, [r.label for r in d.estimates], fontsize=8)
    ax.set_ylim(-0.7, n - 0.3)
    ax.set_xlabel("estimate / start value [-]")
    ax.grid(True, axis="x", alpha=0.3)
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), fontsize=7.5, ncols=1,
              frameon=False, title="estimates", title_fontsize=10)


def save_identification_figure(ident: Any, path: str | Path, *,
                               title: str | None = None) -> Path:
    """Draw :func:`identification_figure` and write it as PNG or SVG (by the suffix of
    ``path``) atomically; return the path.

    Raises
    ------
    InputError
        A suffix other than .png or .svg, or a title matplotlib cannot parse.
    OutputError
        The file cannot be written (the previous file, if any, is left as it was).
    """
    path = Path(path)
    if path.suffix.lower() not in FIGURE_FORMATS:  # refused before the figure is drawn
        raise InputError(f"figure {str(path)!r}: the file name must end in "
                         f"{' or '.join(FIGURE_FORMATS)}")
    return save_figure(identification_figure(ident, title=title), path)
