"""Figures of the fuzzy systems (the paper's Fig. 3): membership functions, rule tables and
control surfaces.

Each figure is computed first (a small frozen data object: curves, a rule table or a surface,
read from the system) and rendered second (a matplotlib ``Figure``, object API, no global
state); :func:`fig3` does both for the paper's two systems and writes the files, which
:func:`fig3_files` lists without drawing anything. matplotlib is imported only when a figure
is drawn, so listing the files (a run that reuses them) does not load it.

Figure text uses mathtext for the paper's symbols (:data:`MATH_NAMES`): :math:`e_n`,
:math:`\\Delta e_n`, :math:`\\Delta u_n` and :math:`\\alpha_F`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._io import atomic_write
from .._typing import FloatArray
from ..errors import ParameterError
from ..fuzzy import FuzzySystem, Variable, membership
from .systems import DPI, new_figure, response_data

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "FIG3_STEMS",
    "MATH_NAMES",
    "MembershipData",
    "RuleTableData",
    "SurfaceData",
    "fig3",
    "fig3_files",
    "math_name",
    "membership_data",
    "render_memberships",
    "render_rule_table",
    "render_surface",
    "rule_table_data",
    "surface_data",
]

#: How figure text writes the variables of the paper's systems (matplotlib mathtext).
MATH_NAMES: dict[str, str] = {
    "e": r"$e_n$",
    "de": r"$\Delta e_n$",
    "du": r"$\Delta u_n$",
    "alpha": r"$\alpha_F$",
}

#: The files of Fig. 3, in the order the report shows them (without suffix).
FIG3_STEMS: tuple[str, ...] = (
    "fig3a_memberships", "fig3a_rules_du", "fig3a_surface_du",
    "fig3b_memberships", "fig3b_rules_alpha", "fig3b_surface_alpha",
)



def math_name(name: str) -> str:
    """The figure text of variable ``name``: mathtext for the paper's variables, else the
    name itself."""
    return MATH_NAMES.get(name, name)


@dataclass(frozen=True, slots=True, kw_only=True)
class MembershipData:
    """Membership curves of the variables of a system."""

    names: tuple[str, ...]  #: variable names
    x: tuple[FloatArray, ...]  #: sample points of each universe [unit of the variable]
    labels: tuple[tuple[str, ...], ...]  #: term labels of each variable
    mu: tuple[FloatArray, ...]  #: memberships, (n_terms, n_x) per variable [1]
    peaks: tuple[FloatArray, ...]  #: where each term is largest, (n_terms,) per variable


@dataclass(frozen=True, slots=True, kw_only=True)
class RuleTableData:
    """A two-input rule base as the paper prints it: rows the second input (Δe), columns
    the first (e), each cell the output term."""

    title: str  #: figure title
    output_name: str  #: name of the output variable
    row_name: str  #: name of the rows' input (Δe)
    column_name: str  #: name of the columns' input (e)
    row_labels: tuple[str, ...]  #: terms of the rows' input, in order
    column_labels: tuple[str, ...]  #: terms of the columns' input, in order
    output_labels: tuple[str, ...]  #: terms of the output, in order
    cells: tuple[tuple[str, ...], ...]  #: cells[row][column], output label or "" (no rule)
    index: FloatArray  #: (n_rows, n_columns) output term index, NaN where no rule


@dataclass(frozen=True, slots=True, kw_only=True)
class SurfaceData:
    """A control surface sampled on a grid."""

    title: str  #: figure title
    e: FloatArray  #: (n,) grid of the first input [unit of e]
    de: FloatArray  #: (n,) grid of the second input [unit of de]
    value: FloatArray  #: (n, n) output, value[i_de, i_e] [unit of the output]
    output_name: str  #: name of the output variable
    input_names: tuple[str, str] = ("e", "de")  #: names of the two inputs


def membership_data(system: FuzzySystem, n: int = 401, *,
                    variables: tuple[str, ...] | None = None) -> MembershipData:
    """Sample the membership functions of the inputs and the output of ``system``.

    Parameters
    ----------
    system : FuzzySystem
        The fuzzy system.
    n : int
        Points per universe, >= 2.
    variables : tuple of str, optional
        Names of the variables to sample, in order; default every input, then the output.
    """
    if n < 2:
        raise ParameterError(f"need at least 2 points per universe, got {n}")
    every: tuple[Variable, ...] = (*system.inputs, system.outputs[0])
    if variables is None:
        chosen = every
    else:
        by_name = {v.name: v for v in every}
        unknown = [v for v in variables if v not in by_name]
        if unknown or not variables:
            raise ParameterError(f"variables {list(variables)!r}: the system has "
                                 f"{', '.join(by_name)}")
        chosen = tuple(by_name[v] for v in variables)
    xs = tuple(np.linspace(*v.range, n) for v in chosen)
    mus = tuple(np.stack([membership(t.shape, t.params, x, t.height) for t in v.terms])
                for v, x in zip(chosen, xs, strict=True))
    peaks = tuple(x[np.argmax(mu, axis=1)] for x, mu in zip(xs, mus, strict=True))
    return MembershipData(names=tuple(v.name for v in chosen), x=xs,
                          labels=tuple(tuple(t.name for t in v.terms) for v in chosen),
                          mu=mus, peaks=peaks)


def rule_table_data(system: FuzzySystem, title: str = "") -> RuleTableData:
    """The rule base of ``system`` as a table: rows the second input, columns the first.

    Read from the system's rules (not from a printed table), so the figure shows the rules
    the controller uses.
    """
    col_var, row_var = system.inputs
    out = system.outputs[0]
    table = np.array(system.rule_table(), dtype=np.float64)
    index = np.where(table < 0, np.nan, table)
    labels = tuple(t.name for t in out.terms)
    cells = tuple(tuple("" if np.isnan(k) else labels[int(k)] for k in row) for row in index)
    return RuleTableData(title=title, output_name=out.name, row_name=row_var.name,
                         column_name=col_var.name,
                         row_labels=tuple(t.name for t in row_var.terms),
                         column_labels=tuple(t.name for t in col_var.terms),
                         output_labels=labels, cells=cells, index=index)


def surface_data(system: FuzzySystem, n: int = 81, title: str = "") -> SurfaceData:
    """Evaluate ``system`` on an n x n grid over its input universes.

    Parameters
    ----------
    system : FuzzySystem
        The fuzzy system.
    n : int
        Grid points per input, >= 2.
    title : str
        Figure title.
    """
    if n < 2:
        raise ParameterError(f"need a grid of at least 2 x 2, got n={n}")
    r = response_data(system, n)
    if len(r.axes) != 2:
        raise ParameterError(f"a control surface needs two inputs, system {system.name!r} has "
                             f"{len(r.axes)}")
    return SurfaceData(title=title, e=r.axes[0], de=r.axes[1], value=r.values[0],
                       output_name=system.outputs[0].name,
                       input_names=(system.inputs[0].name, system.inputs[1].name))


def _five_ticks(ax: Axes, lo: float, hi: float, axis: str = "x") -> None:
    """Ticks at the ends, the middle and the quarters of [lo, hi]: never crowded."""
    ticks = np.linspace(lo, hi, 5)
    (ax.set_xticks if axis == "x" else ax.set_yticks)(ticks)


def render_memberships(data: MembershipData, title: str = "") -> Figure:
    """One panel per variable with its membership functions, each term labelled above its
    peak inside the axes (the end terms aligned inwards, so no label is cut)."""
    k = len(data.names)
    fig = new_figure(max(4.2 * k, 6.0), 3.3)
    axes = fig.subplots(1, k, squeeze=False)[0]
    for ax, name, x, labels, mu, peaks in zip(axes, data.names, data.x, data.labels, data.mu,
                                              data.peaks, strict=True):
        lo, hi = float(x[0]), float(x[-1])
        for label, m, p in zip(labels, mu, peaks, strict=True):
            line = ax.plot(x, m, lw=1.5)[0]
            ha = "left" if p <= lo else "right" if p >= hi else "center"
            nudge = 0.01 * (hi - lo) * (1 if ha == "left" else -1 if ha == "right" else 0)
            ax.text(p + nudge, 1.03, label, ha=ha, va="bottom", fontsize=8,
                    color=line.get_color(), clip_on=False)
        ax.set_xlabel(math_name(name))
        ax.set_ylim(0.0, 1.18)
        ax.set_yticks([0.0, 0.25, 0.5, 0.75, 1.0])
        ax.set_xlim(lo, hi)
        _five_ticks(ax, lo, hi)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(r"membership $\mu$")
    if title:
        fig.suptitle(title)
    return fig


def render_rule_table(data: RuleTableData) -> Figure:
    """The rule base as a table: rows the second input, columns the first; each cell the
    output term, tinted by its position in the output's terms."""
    from matplotlib import colormaps
    from matplotlib.transforms import Bbox

    n_rows, n_cols = data.index.shape
    fig = new_figure(0.6 + 0.75 * (n_cols + 1), 1.1 + 0.36 * (n_rows + 1))
    ax = fig.add_subplot(1, 1, 1)
    ax.set_axis_off()
    signed = data.output_name != "alpha"  # Δu is signed (diverging tints), α is not
    cmap = colormaps["RdBu_r" if signed else "Greens"]
    n_out = max(len(data.output_labels) - 1, 1)
    colours = [[(1.0, 1.0, 1.0, 1.0) if np.isnan(k) else
                cmap(0.15 + 0.7 * k / n_out) if signed else cmap(0.05 + 0.6 * k / n_out)
                for k in row] for row in data.index]
    table = ax.table(cellText=[list(r) for r in data.cells], cellColours=colours,
                     rowLabels=list(data.row_labels), colLabels=list(data.column_labels),
                     cellLoc="center", rowLoc="center",
                     bbox=Bbox.from_bounds(0.0, 0.0, 1.0, 1.0))
    cells = table.get_celld()
    width, height = cells[(1, 0)].get_width(), cells[(1, 0)].get_height()
    corner = table.add_cell(0, -1, width, height, loc="center",
                            text=f"{math_name(data.row_name)} \\ {math_name(data.column_name)}")
    table.auto_set_font_size(False)
    table.set_fontsize(10)
    for (r, c), cell in table.get_celld().items():
        if r == 0 or c < 0:  # the inputs' terms
            cell.set_width(width)
            cell.set_text_props(fontweight="bold")
            cell.set_facecolor("#eeeeee")
    corner.set_text_props(fontweight="normal")
    ax.set_title(f"rows: {math_name(data.row_name)}, columns: {math_name(data.column_name)}"
                 f", cells: {math_name(data.output_name)}", fontsize=10)
    if data.title:
        fig.suptitle(data.title)
    return fig


def render_surface(data: SurfaceData) -> Figure:
    """3-D surface with a contour map beside it."""
    fig = new_figure(10.5, 4.4)
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ee, dd = np.meshgrid(data.e, data.de)
    ax3.plot_surface(ee, dd, data.value, cmap="viridis", linewidth=0, antialiased=True)
    x_name, y_name = (math_name(n) for n in data.input_names)
    z_name = math_name(data.output_name)
    ax3.set_xlabel(x_name)
    ax3.set_ylabel(y_name)
    ax3.set_zlabel(z_name)
    for axis, v in ((ax3.xaxis, data.e), (ax3.yaxis, data.de)):
        axis.set_ticks(np.linspace(v[0], v[-1], 5))
    ax2 = fig.add_subplot(1, 2, 2)
    cs = ax2.contourf(ee, dd, data.value, levels=21, cmap="viridis")
    fig.colorbar(cs, ax=ax2, label=z_name)
    ax2.set_xlabel(x_name)
    ax2.set_ylabel(y_name)
    _five_ticks(ax2, float(data.e[0]), float(data.e[-1]))
    _five_ticks(ax2, float(data.de[0]), float(data.de[-1]), "y")
    ax2.set_aspect("equal")
    if data.title:
        fig.suptitle(data.title)
    return fig


def fig3_files(out_dir: Path, formats: tuple[str, ...] = ("png",)) -> list[Path]:
    """The files :func:`fig3` writes into ``out_dir``, in its order (nothing is drawn)."""
    return [Path(out_dir) / f"{stem}.{fmt}" for stem in FIG3_STEMS for fmt in formats]


def fig3(du: FuzzySystem, alpha: FuzzySystem, out_dir: Path, n: int = 81,
         formats: tuple[str, ...] = ("png",)) -> list[Path]:
    """Write the paper's Fig. 3: for each system the membership functions, the rule table
    and the control surface.

    Parameters
    ----------
    du, alpha : FuzzySystem
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
        The files written, as :func:`fig3_files` lists them.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    out_name = math_name(alpha.outputs[0].name)
    figures = {
        "fig3a_memberships": render_memberships(
            membership_data(du),
            rf"Fig. 3a: membership functions of {math_name('e')}, {math_name('de')} "
            rf"and {math_name('du')}"),
        "fig3a_rules_du": render_rule_table(rule_table_data(
            du, rf"Fig. 3a: rules for {math_name(du.outputs[0].name)}")),
        "fig3a_surface_du": render_surface(surface_data(
            du, n, r"Fig. 3a: control surface $\Delta u_n(e_n, \Delta e_n)$")),
        "fig3b_memberships": render_memberships(
            membership_data(alpha, variables=(alpha.outputs[0].name,)),
            f"Fig. 3b: membership functions of {out_name}"),
        "fig3b_rules_alpha": render_rule_table(rule_table_data(
            alpha, f"Fig. 3b: rules for {out_name}")),
        "fig3b_surface_alpha": render_surface(surface_data(
            alpha, n, r"Fig. 3b: gain updating factor $\alpha_F(e_n, \Delta e_n)$")),
    }
    written = fig3_files(out_dir, formats)
    for path in written:
        with atomic_write(path, binary=True) as fh:
            figures[path.stem].savefig(fh, format=path.suffix[1:], dpi=DPI)
    return written
