"""Figures of the paper's study (Figs. 4-8 and the robustness sweeps), rendered from results.

Every function takes data that the study already computed and returns a matplotlib Figure;
:func:`save` writes it as PNG and SVG. One colour per controller throughout, from
:data:`CONTROLLER_COLOURS`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from .._io import atomic_write  # noqa: E402
from .._typing import FloatArray  # noqa: E402

__all__ = [
    "CONTROLLER_COLOURS",
    "Curve",
    "alpha_figure",
    "command_figure",
    "delay_sweep_figure",
    "save",
    "step_figure",
]

#: Fixed colour of each controller of the study, the same in every figure.
CONTROLLER_COLOURS: dict[str, str] = {
    "pid_paper_1": "#d62728",   # red
    "pid_paper_2": "#ff7f0e",   # orange
    "pid_tuned": "#8c564b",     # brown
    "pid2_tuned": "#9467bd",    # purple
    "fpi": "#2ca02c",           # green
    "stfpi": "#1f77b4",         # blue
    "stfpi_10": "#e377c2",      # pink
    "stfpi_delay": "#17becf",   # cyan
}


@dataclass(frozen=True, slots=True)
class Curve:
    """One controller's trace: key (for the colour), legend label and the signals."""

    key: str
    label: str
    t: FloatArray
    y: FloatArray
    u: FloatArray
    alpha: FloatArray
    r: FloatArray
    linestyle: str = "-"


#: Colours of changed plants (robustness figures), distinct from the controllers' colours.
VARIANT_COLOURS: tuple[str, ...] = ("#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173",
                                    "#5254a3", "#8ca252")


def _colour(key: str) -> str:
    if key.startswith("variant") and key[7:].isdigit():
        return VARIANT_COLOURS[int(key[7:]) % len(VARIANT_COLOURS)]
    return CONTROLLER_COLOURS.get(key, "#7f7f7f")


def _new(title: str, ylabel: str, *, height: float = 4.2) -> tuple[Figure, Axes]:
    fig, ax = plt.subplots(figsize=(8.0, height), dpi=110)
    ax.set_title(title)
    ax.set_xlabel("time t [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    return fig, ax


def step_figure(curves: Sequence[Curve], title: str, *, y0: float = 0.0,
                zoom: float | None = 4.0) -> Figure:
    """Position response of each controller [mm from the start position] with the reference.

    With ``zoom`` a second panel shows the first ``zoom`` seconds.
    """
    ncols = 1 if zoom is None or zoom >= float(curves[0].t[-1]) else 2
    fig, axes = plt.subplots(1, ncols, figsize=(8.0 if ncols == 1 else 12.0, 4.4), dpi=110,
                             squeeze=False)
    ref = curves[0]
    for i, ax in enumerate(axes[0]):
        ax.plot(ref.t, (ref.r - y0) * 1e3, color="black", lw=1.0, ls="--", label="reference")
        for c in curves:
            ax.plot(c.t, (c.y - y0) * 1e3, color=_colour(c.key), lw=1.6, ls=c.linestyle,
                    label=c.label)
        ax.set_xlabel("time t [s]")
        ax.set_ylabel("piston position x - x(0) [mm]")
        ax.grid(True, alpha=0.3)
        if i == 1 and zoom is not None:
            ax.set_xlim(0.0, zoom)
            ax.set_title(f"first {zoom:g} s")
    axes[0][0].legend(loc="lower right", fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def command_figure(curves: Sequence[Curve], title: str) -> Figure:
    """Valve command of each controller [% of rated input]."""
    fig, ax = _new(title, "valve command u [% of rated input]")
    for c in curves:
        ax.step(c.t, c.u * 100.0, where="post", color=_colour(c.key), lw=1.3, ls=c.linestyle,
                label=c.label)
    ax.axhline(0.0, color="black", lw=0.6)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return fig


def alpha_figure(curves: Sequence[Curve], title: str) -> Figure:
    """Self-tuning factor alpha_F(t) [-]."""
    fig, ax = _new(title, "gain updating factor alpha_F [-]")
    for c in curves:
        ax.step(c.t, c.alpha, where="post", color=_colour(c.key), lw=1.4, ls=c.linestyle,
                label=c.label)
    ax.set_ylim(0.0, 1.0)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return fig


def delay_sweep_figure(delays: FloatArray, values: Mapping[str, FloatArray],
                       labels: Mapping[str, str], title: str, *, ylabel: str,
                       limit: float | None = None) -> Figure:
    """A metric (e.g. overshoot [%]) against the transport delay [ms], one line per controller."""
    fig, ax = _new(title, ylabel)
    ax.set_xlabel("transport (hose) delay [ms]")
    d_ms = np.asarray(delays) * 1e3
    for key, v in values.items():
        ax.plot(d_ms, v, marker="o", ms=3, color=_colour(key), lw=1.4, label=labels[key])
    if limit is not None:
        ax.axhline(limit, color="black", ls=":", lw=1.0, label=f"failure threshold ({limit:g})")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    return fig


def save(fig: Figure, stem: Path) -> list[Path]:
    """Write ``stem.png`` and ``stem.svg``, close the figure and return both paths."""
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_suffix(".png"), stem.with_suffix(".svg")]
    try:
        for p in paths:
            with atomic_write(p, binary=True) as fh:
                fig.savefig(fh, format=p.suffix[1:])
    finally:
        plt.close(fig)
    return paths
