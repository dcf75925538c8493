"""Figures of the fuzzy systems (the paper's Fig. 3): membership functions, control surfaces.

Each figure is computed first (a small frozen data object: curves or a surface sampled from
the system) and rendered second (a matplotlib ``Figure``, object API, no global state);
:func:`fig3` does both for the paper's two systems and writes PNG files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .._io import atomic_write
from .._typing import FloatArray
from ..errors import ParameterError
from ..fuzzy import LinguisticVariable, MamdaniSystem

__all__ = [
    "MembershipData",
    "SurfaceData",
    "fig3",
    "membership_data",
    "render_memberships",
    "render_surface",
    "surface_data",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class MembershipData:
    """Membership curves of the variables of a system."""

    names: tuple[str, ...]  #: variable names
    x: tuple[FloatArray, ...]  #: sample points of each universe [unit of the variable]
    labels: tuple[tuple[str, ...], ...]  #: term labels of each variable
    mu: tuple[FloatArray, ...]  #: memberships, (n_terms, n_x) per variable [1]


@dataclass(frozen=True, slots=True, kw_only=True)
class SurfaceData:
    """A control surface sampled on a grid."""

    title: str  #: figure title
    e: FloatArray  #: (n,) grid of the first input [unit of e]
    de: FloatArray  #: (n,) grid of the second input [unit of de]
    value: FloatArray  #: (n, n) output, value[i_de, i_e] [unit of the output]
    output_name: str  #: name of the output variable


def membership_data(system: MamdaniSystem, n: int = 401) -> MembershipData:
    """Sample the membership functions of the inputs and the output of ``system``.

    Parameters
    ----------
    system : MamdaniSystem
        The fuzzy system.
    n : int
        Points per universe, >= 2.
    """
    if n < 2:
        raise ParameterError(f"need at least 2 points per universe, got {n}")
    variables: tuple[LinguisticVariable, ...] = (*system.inputs, system.output)
    xs = tuple(np.linspace(*v.universe, n) for v in variables)
    mus = tuple(np.stack([mf(x) for _, mf in v.terms]) for v, x in zip(variables, xs,
                                                                       strict=True))
    return MembershipData(names=tuple(v.name for v in variables), x=xs,
                          labels=tuple(v.labels for v in variables), mu=mus)


def surface_data(system: MamdaniSystem, n: int = 81, title: str = "") -> SurfaceData:
    """Evaluate ``system`` on an n x n grid over its input universes.

    Parameters
    ----------
    system : MamdaniSystem
        The fuzzy system.
    n : int
        Grid points per input, >= 2.
    title : str
        Figure title.
    """
    if n < 2:
        raise ParameterError(f"need a grid of at least 2 x 2, got n={n}")
    e = np.linspace(*system.inputs[0].universe, n)
    de = np.linspace(*system.inputs[1].universe, n)
    value = system.evaluate(e[None, :], de[:, None])
    return SurfaceData(title=title, e=e, de=de, value=value, output_name=system.output.name)


def render_memberships(data: MembershipData, title: str = "") -> Figure:
    """One panel per variable with its labelled membership functions."""
    k = len(data.names)
    fig = Figure(figsize=(4.0 * k, 3.2), layout="constrained")
    axes = fig.subplots(1, k, squeeze=False)[0]
    for ax, name, x, labels, mu in zip(axes, data.names, data.x, data.labels, data.mu,
                                       strict=True):
        for label, m in zip(labels, mu, strict=True):
            line = ax.plot(x, m, lw=1.5)[0]
            peak = int(np.argmax(m))
            ax.annotate(label, (x[peak], 1.02), ha="center", va="bottom", fontsize=8,
                        color=line.get_color())
        ax.set_xlabel(name)
        ax.set_ylim(0.0, 1.15)
        ax.set_xlim(x[0], x[-1])
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("membership")
    if title:
        fig.suptitle(title)
    return fig


def render_surface(data: SurfaceData) -> Figure:
    """3-D surface with a contour map beside it."""
    fig = Figure(figsize=(10.0, 4.2), layout="constrained")
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ee, dd = np.meshgrid(data.e, data.de)
    ax3.plot_surface(ee, dd, data.value, cmap="viridis", linewidth=0, antialiased=True)
    ax3.set_xlabel("e")
    ax3.set_ylabel("Δe")
    ax3.set_zlabel(data.output_name)
    ax2 = fig.add_subplot(1, 2, 2)
    cs = ax2.contourf(ee, dd, data.value, levels=21, cmap="viridis")
    fig.colorbar(cs, ax=ax2, label=data.output_name)
    ax2.set_xlabel("e")
    ax2.set_ylabel("Δe")
    ax2.set_aspect("equal")
    if data.title:
        fig.suptitle(data.title)
    return fig


def fig3(du: MamdaniSystem, alpha: MamdaniSystem, out_dir: Path, n: int = 81,
         formats: tuple[str, ...] = ("png",)) -> list[Path]:
    """Write the paper's Fig. 3: MFs of both systems and both control surfaces.

    Parameters
    ----------
    du, alpha : MamdaniSystem
        The Δu system (Fig. 3a) and the α system (Fig. 3b).
    out_dir : Path
        Output directory (created if missing).
    n : int
        Grid points per input of the surfaces.
    formats : tuple of str
        File formats to write, e.g. ``("png", "svg")``.

    Returns
    -------
    list of Path
        The files written.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    jobs = [
        ("fig3a_memberships.png",
         render_memberships(membership_data(du), "Fig. 3a: membership functions of e, Δe, Δu")),
        ("fig3b_memberships.png",
         render_memberships(membership_data(alpha), "Fig. 3b: membership functions of α")),
        ("fig3a_surface_du.png",
         render_surface(surface_data(du, n, "Fig. 3a: control surface Δu_n(e_n, Δe_n)"))),
        ("fig3b_surface_alpha.png",
         render_surface(surface_data(alpha, n, "Fig. 3b: gain updating factor α(e_n, Δe_n)"))),
    ]
    written = []
    for name, fig in jobs:
        for fmt in formats:
            path = (out_dir / name).with_suffix(f".{fmt}")
            with atomic_write(path, binary=True) as fh:
                fig.savefig(fh, format=fmt, dpi=120)
            written.append(path)
    return written
