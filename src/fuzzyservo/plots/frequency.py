"""Bode figure of closed loops: magnitude and phase of T against frequency, several designs,
analytic lines (:func:`fuzzyservo.analysis.closed_loop_bode`) and measured markers
(:func:`fuzzyservo.analysis.measured_response`). Data first (:class:`BodeCurve`,
:func:`bode_curve`), drawing second (:func:`bode_figure`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._typing import FloatArray
from ..analysis.frequency import BodeResult, MeasuredResponse
from .runs import _COLOURS, check_text

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["BodeCurve", "bode_curve", "bode_figure"]


@dataclass(frozen=True, slots=True, kw_only=True)
class BodeCurve:
    """What the figure draws of one design, in display units."""

    label: str  #: legend label
    colour: str | None  #: line and marker colour; None: the next of the figure's
    frequency: FloatArray  #: analytic frequencies [Hz] (may be empty)
    magnitude_db: FloatArray  #: analytic |T| [dB]
    phase_deg: FloatArray  #: analytic ∠T [deg]
    measured_frequency: FloatArray  #: measured frequencies [Hz] (may be empty)
    measured_db: FloatArray  #: measured gain [dB]
    measured_phase_deg: FloatArray  #: measured phase [deg]
    bandwidth: float = math.nan  #: analytic -3 dB bandwidth, marked when finite [Hz]


def bode_curve(label: str, analytic: BodeResult | None = None,
               measured: MeasuredResponse | None = None, *,
               colour: str | None = None) -> BodeCurve:
    """One design's curve: its analytic response (a line) and/or measured one (markers);
    measured phases are shifted by whole turns to lie nearest the analytic phase."""
    empty = np.empty(0)
    f = analytic.frequency if analytic is not None else empty
    mag = analytic.magnitude_db if analytic is not None else empty
    ph = analytic.phase_deg if analytic is not None else empty
    mf, mdb, mph = empty, empty, empty
    if measured is not None:
        order = np.argsort(measured.frequency)
        mf = measured.frequency[order]
        mdb = measured.magnitude_db[order]
        mph = measured.phase_deg[order]
        if f.size:
            near = np.interp(np.log(mf), np.log(f), ph)
            mph = mph + 360.0 * np.round((near - mph) / 360.0)
    bw = analytic.margins.bandwidth if analytic is not None else math.nan
    return BodeCurve(label=label, colour=colour, frequency=f, magnitude_db=mag, phase_deg=ph,
                     measured_frequency=mf, measured_db=mdb, measured_phase_deg=mph,
                     bandwidth=bw)


def bode_figure(curves: Sequence[BodeCurve], title: str | None = None) -> Figure:
    """Magnitude [dB] and phase [deg] of the closed loops against frequency [Hz] (log):
    a line per analytic response, markers per measured one, in each curve's colour; the -3 dB
    line and each curve's bandwidth dotted.

    Raises
    ------
    InputError
        A label or the title is mathtext matplotlib cannot parse.
    """
    from matplotlib.figure import Figure

    for c in curves:
        check_text(c.label, "label")
    if title:
        check_text(title, "title")
    many = len(curves) > 4  # the legend goes below the plots, the figure grows
    fig = Figure(figsize=(9.0, 8.0) if many else (7.0, 6.0),
                 layout="constrained" if many else None)
    ax_m, ax_p = fig.subplots(2, 1, sharex=True)
    for i, c in enumerate(curves):
        colour = c.colour or _COLOURS[i % len(_COLOURS)]
        if c.frequency.size:
            ax_m.semilogx(c.frequency, c.magnitude_db, color=colour, label=c.label)
            ax_p.semilogx(c.frequency, c.phase_deg, color=colour)
            if math.isfinite(c.bandwidth):
                ax_m.axvline(c.bandwidth, color=colour, linestyle=":", linewidth=0.8)
        if c.measured_frequency.size:
            label = None if c.frequency.size else c.label
            ax_m.semilogx(c.measured_frequency, c.measured_db, "o", color=colour,
                          markerfacecolor="none", label=label)
            ax_p.semilogx(c.measured_frequency, c.measured_phase_deg, "o", color=colour,
                          markerfacecolor="none")
    ax_m.axhline(-3.0, color="0.5", linestyle="--", linewidth=0.8)
    ax_m.set_ylabel("|T| [dB]")
    ax_p.set_ylabel("∠T [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", alpha=0.3)
    if any(c.measured_frequency.size for c in curves):
        ax_m.plot([], [], "o", color="0.3", markerfacecolor="none", label="measured")
    # a closed loop's |T| far below -60 dB says nothing the phase does not: the axis stops
    # there, so the designs' differences near 0 dB stay readable
    lo, hi = ax_m.get_ylim()
    if lo < -60.0:
        ax_m.set_ylim(-60.0, max(hi, 5.0))
    if many:
        handles, labels = ax_m.get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside lower center", ncols=2, fontsize="small",
                   frameon=False)
    else:
        ax_m.legend(fontsize="small")
    if title:
        fig.suptitle(title)
    if not many:
        fig.tight_layout()
    return fig
