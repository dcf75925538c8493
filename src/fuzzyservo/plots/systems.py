"""Figures of general fuzzy systems (:class:`~fuzzyservo.fuzzy.system.FuzzySystem`, read from
.fis, .fcl or .fll files): membership functions of every variable and the system's response.

Data first, render second (as :mod:`fuzzyservo.plots.figures`): :func:`variable_panels`,
:func:`response_data` and :func:`system_figure_data` compute what is drawn, from the model and
the exact evaluator :mod:`fuzzyservo.fuzzy.general`; :func:`render_system` and
:func:`render_variables` draw it (matplotlib object API, imported only when drawing).

How the curves are made exact:

- A piecewise-linear term (triangle, trapezoid, rectangle, ramp, discrete) is drawn as the
  polyline of its vertices (:attr:`~fuzzyservo.fuzzy.system.Term.vertices`, height applied),
  extended flat to the variable's range and cut at its ends: every corner is where it is, and
  a vertical edge (a rectangle, a triangle with ``a == b``, a repeated ``x`` of a discrete
  term) is vertical.
- Any other term is sampled on a dense grid over the range (801 points) to which every one of
  its parameters inside the range is added (means, inflections, feet, and the midpoints of
  ``s``, ``z`` and ``pi``), with the evaluator's own membership function
  (:func:`fuzzyservo.fuzzy.general.membership`).
- A singleton output term is a stem (a vertical line of the term's height with a dot on top).
- A Sugeno output has no membership functions: its panel lists each term's function
  (``z = 2 a - b + 0.5``).

The response: for a two-input system, the control surface of each output on an n x n grid
over the inputs' ranges (a filled contour map with a 3-D view beside it); for a one-input
system, each output's curve over the input's range, sampled at n points plus every vertex and
knot of the input's terms (where the curve may bend). Points where no rule fires and the
output's default is NaN have no value: blank in a map, a gap in a curve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from .._typing import FloatArray
from ..errors import ParameterError
from ..fuzzy import evaluate, membership, pack
from ..fuzzy.shapes import SUGENO, knots
from ..fuzzy.system import FuzzySystem, Term, Variable

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, SubFigure

__all__ = [
    "MAX_DRAWN",
    "MF_SAMPLES",
    "ResponseData",
    "SystemFigureData",
    "TermCurve",
    "VariablePanel",
    "new_figure",
    "render_response",
    "render_system",
    "render_variables",
    "response_data",
    "system_figure_data",
    "term_curve",
    "variable_panels",
]

#: Samples over a variable's range for a term that is not piecewise linear.
MF_SAMPLES = 801
#: Resolution of the PNG files [dots per inch].
DPI = 120
#: Panels per row of the membership functions.
_PANELS_PER_ROW = 3
#: Largest magnitude of a range's end that a figure draws: matplotlib's axis ticks take
#: differences and multiples of the limits, which overflow from about 1e307 (seen: a range of
#: (-8e307, 8e307) fails in its tick locator, (-1e308, 1e308) in its limit check); 1e300
#: leaves that arithmetic seven orders of magnitude of room.
MAX_DRAWN = 1e300


@dataclass(frozen=True, slots=True, kw_only=True)
class TermCurve:
    """The membership curve of one term over its variable's range."""

    name: str  #: the term's label
    x: FloatArray  #: abscissae, non-decreasing (a repeated x is a vertical edge) [unit of var]
    mu: FloatArray  #: membership at x [-]
    stem: bool = False  #: a singleton: one point (x[0], mu[0]) drawn as a stem


@dataclass(frozen=True, slots=True, kw_only=True)
class VariablePanel:
    """What one variable's panel shows."""

    name: str  #: the variable's name
    role: Literal["input", "output"]  #: input or output variable
    range: tuple[float, float]  #: (lo, hi) [unit of the variable]
    curves: tuple[TermCurve, ...]  #: membership curves (none for a Sugeno output)
    functions: tuple[str, ...] = ()  #: Sugeno output terms as text, "name: z = ..."


@dataclass(frozen=True, slots=True, kw_only=True)
class ResponseData:
    """A one- or two-input system's outputs over its inputs' ranges."""

    input_names: tuple[str, ...]  #: the one or two inputs
    output_names: tuple[str, ...]  #: every output
    axes: tuple[FloatArray, ...]  #: grid of each input [unit of the input]
    values: FloatArray  #: (n_out, n) or (n_out, n2, n1): values[k, i2, i1], NaN: no value


@dataclass(frozen=True, slots=True, kw_only=True)
class SystemFigureData:
    """Everything :func:`render_system` draws."""

    title: str  #: figure title
    panels: tuple[VariablePanel, ...]  #: inputs then outputs
    response: ResponseData | None  #: None for three inputs or more


def _num(x: float) -> str:
    """Compact text of a number for figure labels (6 significant digits)."""
    return f"{x:.6g}"


def _polyline(vertices: tuple[tuple[float, float], ...], lo: float, hi: float
              ) -> tuple[FloatArray, FloatArray]:
    """The vertices' polyline, flat beyond the first and last, restricted to [lo, hi]."""
    pts = list(vertices)
    if pts[0][0] > lo:
        pts.insert(0, (lo, pts[0][1]))
    if pts[-1][0] < hi:
        pts.append((hi, pts[-1][1]))
    out = [(x, y) for x, y in pts if lo <= x <= hi]
    for bound, first in ((lo, True), (hi, False)):
        if any(x == bound for x, _ in pts):
            continue
        for (x0, y0), (x1, y1) in zip(pts, pts[1:], strict=False):
            if x0 < bound < x1:
                y = y0 + (y1 - y0) * (bound - x0) / (x1 - x0)
                if first:
                    out.insert(0, (bound, y))
                else:
                    out.append((bound, y))
                break
    xs = np.array([p[0] for p in out], dtype=np.float64)
    ys = np.array([p[1] for p in out], dtype=np.float64)
    return xs, ys


def term_curve(term: Term, lo: float, hi: float, n: int = MF_SAMPLES) -> TermCurve:
    """The membership curve of ``term`` over [lo, hi] (exact corners; see the module's doc).

    Parameters
    ----------
    term : Term
        A term of an input or a Mamdani output (not ``constant`` / ``linear``).
    lo, hi : float
        The variable's range [unit of the variable].
    n : int
        Samples of a term that is not piecewise linear, >= 2.

    Raises
    ------
    ParameterError
        A Sugeno term (it has no membership function), or n < 2.
    """
    if term.shape in SUGENO:
        raise ParameterError(f"term {term.name!r}: a {term.shape} Sugeno term has no "
                             f"membership function to draw")
    if n < 2:
        raise ParameterError(f"need at least 2 samples per range, got {n}")
    if term.shape == "singleton":
        return TermCurve(name=term.name, x=np.array([term.params[0]]),
                         mu=np.array([term.height]), stem=True)
    vertices = term.vertices
    if vertices is not None:
        x, mu = _polyline(vertices, lo, hi)
        return TermCurve(name=term.name, x=x, mu=mu)
    extra = [k for k in knots(term.shape, term.params) if lo <= k <= hi]
    x = np.unique(np.concatenate([np.linspace(lo, hi, n), np.array(extra, dtype=np.float64)]))
    return TermCurve(name=term.name, x=x, mu=membership(term.shape, term.params, x, term.height))


def _sugeno_text(system: FuzzySystem, var: Variable, term: Term) -> str:
    if term.shape == "constant":
        return f"{term.name}: {var.name} = {_num(term.params[0])}"
    parts: list[str] = []
    for c, v in zip(term.params[:-1], system.inputs, strict=True):
        if c == 0.0:
            continue
        sign = "-" if c < 0 else "+"
        mag = "" if abs(c) == 1.0 else f"{_num(abs(c))} "
        parts.append(f"{sign} {mag}{v.name}")
    c0 = term.params[-1]
    if c0 != 0.0 or not parts:
        parts.append(f"{'-' if c0 < 0 else '+'} {_num(abs(c0))}")
    body = " ".join(parts)
    body = body[2:] if body.startswith("+ ") else "-" + body[2:]
    return f"{term.name}: {var.name} = {body}"


def variable_panels(system: FuzzySystem, n: int = MF_SAMPLES) -> tuple[VariablePanel, ...]:
    """One panel per variable of ``system``, inputs first, then outputs.

    Parameters
    ----------
    system : FuzzySystem
        The fuzzy system.
    n : int
        Samples of a term that is not piecewise linear, >= 2.

    Raises
    ------
    ParameterError
        A variable's range reaches beyond +-:data:`MAX_DRAWN` (no axis can show it).
    """
    panels: list[VariablePanel] = []
    for role, variables in (("input", system.inputs), ("output", system.outputs)):
        for v in variables:
            lo, hi = v.range
            if max(-lo, hi) > MAX_DRAWN:
                raise ParameterError(
                    f"cannot draw {role} {v.name!r}: its range [{lo!r}, {hi!r}] reaches "
                    f"beyond +-{MAX_DRAWN:g}, the largest an axis of a figure holds "
                    f"(matplotlib's ticks overflow); give the variable a RANGE within it, "
                    f"or evaluate the system with fis eval")
            if role == "output" and system.kind == "sugeno":
                panels.append(VariablePanel(
                    name=v.name, role="output", range=v.range, curves=(),
                    functions=tuple(_sugeno_text(system, v, t) for t in v.terms)))
            else:
                panels.append(VariablePanel(
                    name=v.name, role="input" if role == "input" else "output",
                    range=v.range, curves=tuple(term_curve(t, lo, hi, n) for t in v.terms)))
    return tuple(panels)


def response_data(system: FuzzySystem, n: int) -> ResponseData:
    """Every output of a one- or two-input system over its inputs' ranges, exactly
    (:func:`fuzzyservo.fuzzy.evaluate`).

    Parameters
    ----------
    system : FuzzySystem
        A system with one or two inputs.
    n : int
        Points per input, >= 2 (one input: plus every vertex and knot of its terms inside
        the range).

    Raises
    ------
    ParameterError
        Three inputs or more, or n < 2.
    """
    if n < 2:
        raise ParameterError(f"need at least 2 points per input, got {n}")
    comp = pack(system)
    names = tuple(v.name for v in system.inputs)
    outs = tuple(v.name for v in system.outputs)
    if len(system.inputs) == 1:
        (var,) = system.inputs
        lo, hi = var.range
        knots_: list[float] = []
        for t in var.terms:
            v = t.vertices
            knots_ += [x for x, _ in v] if v is not None else knots(t.shape, t.params)
        inside = [k for k in knots_ if lo <= k <= hi]
        x = np.unique(np.concatenate([np.linspace(lo, hi, n),
                                      np.array(inside, dtype=np.float64)]))
        values = evaluate(comp, x[:, None], parallel=True).T.copy()
        return ResponseData(input_names=names, output_names=outs, axes=(x,), values=values)
    if len(system.inputs) == 2:
        x1 = np.linspace(*system.inputs[0].range, n)
        x2 = np.linspace(*system.inputs[1].range, n)
        g1, g2 = np.meshgrid(x1, x2)
        pts = np.column_stack([g1.ravel(), g2.ravel()])
        flat = evaluate(comp, pts, parallel=True)
        values = flat.T.reshape(len(outs), n, n).copy()
        return ResponseData(input_names=names, output_names=outs, axes=(x1, x2), values=values)
    raise ParameterError(f"system {system.name!r} has {len(system.inputs)} inputs; a curve or "
                         f"a surface needs one or two")


def system_figure_data(system: FuzzySystem, grid: int | None = None,
                       n_mf: int = MF_SAMPLES) -> SystemFigureData:
    """What :func:`render_system` draws for ``system``.

    Parameters
    ----------
    system : FuzzySystem
        The fuzzy system.
    grid : int, optional
        Points per input of the response: default 81 (a surface, 81 x 81) for two inputs and
        401 for one; ignored for three inputs or more (no response is drawn).
    n_mf : int
        Samples of a membership function that is not piecewise linear.
    """
    panels = variable_panels(system, n_mf)  # first: it refuses ranges no axis can show
    response = None
    if len(system.inputs) <= 2:
        n = grid if grid is not None else (81 if len(system.inputs) == 2 else 401)
        response = response_data(system, n)
    return SystemFigureData(title=f"{system.name} ({system.kind})", panels=panels,
                            response=response)


# ---------------------------------------------------------------------------------------------
# rendering


def _draw_panel(ax: Axes, panel: VariablePanel) -> None:
    lo, hi = panel.range
    ax.set_title(f"{panel.role} {panel.name}", fontsize=10)
    ax.set_xlim(lo, hi)
    ax.set_xticks(np.linspace(lo, hi, 5))
    ax.grid(alpha=0.3)
    if panel.functions:
        ax.set_ylim(0.0, 1.0)
        ax.set_yticks([])
        ax.set_xticks([])
        ax.grid(False)
        step = min(0.12, 0.9 / max(len(panel.functions), 1))
        for i, text in enumerate(panel.functions):
            ax.text(0.04, 0.92 - step * i, text, transform=ax.transAxes, ha="left", va="top",
                    fontsize=9, family="monospace")
        ax.set_xlabel("Sugeno output functions")
        return
    ax.set_yticks([0.0, 0.25, 0.5, 0.75, 1.0])
    ax.set_xlabel(panel.name)
    ax.set_ylabel(r"membership $\mu$")
    labels: list[tuple[float, float, str, str]] = []  # peak x, top, name, colour
    for i, c in enumerate(panel.curves):
        # ten colours, then the same colours dashed, then dotted: every term stays distinct
        colour, ls = f"C{i % 10}", ("-", "--", ":")[(i // 10) % 3]
        if c.stem:
            x0, h = float(c.x[0]), float(c.mu[0])
            ax.plot([x0, x0], [0.0, h], lw=1.8, color=colour, ls=ls)
            ax.plot([x0], [h], "o", ms=4, color=colour)
            labels.append((x0, h, c.name, colour))
        else:
            ax.plot(c.x, c.mu, lw=1.5, color=colour, ls=ls)
            k = int(np.argmax(c.mu))
            # the middle of the plateau at the maximum, so a trapezoid's label is centred
            at_max = c.x[c.mu == c.mu[k]]
            labels.append((0.5 * (float(at_max[0]) + float(at_max[-1])), float(c.mu[k]),
                           c.name, colour))
    levels = _label_levels([(x, name) for x, _, name, _ in labels], lo, hi)
    for (x, top, name, colour), level in zip(labels, levels, strict=True):
        ha = "left" if x <= lo + 0.02 * (hi - lo) else (
            "right" if x >= hi - 0.02 * (hi - lo) else "center")
        ax.text(x, top + 0.03 + _LABEL_STEP * level, name, ha=ha, va="bottom", fontsize=8,
                color=colour, clip_on=False)
    ax.set_ylim(0.0, 1.18 + _LABEL_STEP * max(levels, default=0))
    if any(c.stem for c in panel.curves):  # a stem at an end of the range stays visible
        ax.set_xlim(lo - 0.04 * (hi - lo), hi + 0.04 * (hi - lo))


#: Height of one row of term labels [membership units].
_LABEL_STEP = 0.09
#: Width of one character of a term label, as a fraction of the panel's width.
_CHAR_WIDTH = 0.02


def _label_levels(labels: list[tuple[float, str]], lo: float, hi: float) -> list[int]:
    """A row for each term label (0: just above the curve) so that labels whose text would
    overlap are stacked: each label takes the lowest row where it clears every label placed
    before it (labels placed left to right)."""
    span = hi - lo
    order = sorted(range(len(labels)), key=lambda i: labels[i][0])
    placed: list[tuple[float, float, int]] = []
    levels = [0] * len(labels)
    for i in order:
        x, name = labels[i]
        half = 0.5 * (len(name) + 1) * _CHAR_WIDTH * span
        # labels at the ends are aligned inwards
        a, b = ((x, x + 2 * half) if x <= lo + 0.02 * span else
                (x - 2 * half, x) if x >= hi - 0.02 * span else (x - half, x + half))
        level = 0
        while any(lv == level and a < pb and pa < b for pa, pb, lv in placed):
            level += 1
        placed.append((a, b, level))
        levels[i] = level
    return levels


def new_figure(width: float, height: float) -> Figure:
    """An empty figure of the fuzzy-system plots (constrained layout, :data:`DPI`)."""
    from matplotlib.figure import Figure  # only when drawing (see the module's doc)

    return Figure(figsize=(width, height), layout="constrained", dpi=DPI)


def _draw_panels(fig: Figure | SubFigure, panels: tuple[VariablePanel, ...]) -> None:
    cols = min(_PANELS_PER_ROW, len(panels))
    rows = math.ceil(len(panels) / cols)
    axes = fig.subplots(rows, cols, squeeze=False)
    for i, ax in enumerate(axes.ravel()):
        if i < len(panels):
            _draw_panel(ax, panels[i])
        else:
            ax.set_axis_off()


def render_variables(panels: tuple[VariablePanel, ...], title: str = "") -> Figure:
    """The membership functions alone: one panel per variable, three to a row."""
    if not panels:
        raise ParameterError("no variables to draw")
    cols = min(_PANELS_PER_ROW, len(panels))
    rows = math.ceil(len(panels) / cols)
    fig = new_figure(max(4.2 * cols, 6.0), 3.2 * rows + (0.4 if title else 0.0))
    _draw_panels(fig, panels)
    if title:
        fig.suptitle(title)
    return fig


def _draw_surface(fig: Figure | SubFigure, r: ResponseData, k: int) -> None:
    x1, x2 = r.axes
    z = r.values[k]
    g1, g2 = np.meshgrid(x1, x2)
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    finite = np.isfinite(z)
    out = r.output_names[k]
    if finite.any():
        ax3.plot_surface(g1, g2, np.where(finite, z, np.nan), cmap="viridis", linewidth=0,
                         antialiased=True)
        lo, hi = float(np.min(z[finite])), float(np.max(z[finite]))
        levels: int | FloatArray = 21 if hi > lo else np.array([lo - 0.5, lo + 0.5])
        cs = ax2.contourf(g1, g2, z, levels=levels, cmap="viridis")
        fig.colorbar(cs, ax=ax2, label=out)
    for ax in (ax3, ax2):
        ax.set_xlabel(r.input_names[0])
        ax.set_ylabel(r.input_names[1])
    ax3.set_zlabel(out)
    ax2.set_xlim(float(x1[0]), float(x1[-1]))
    ax2.set_ylim(float(x2[0]), float(x2[-1]))
    blank = "" if finite.all() else " (blank: no rule fires, no value)"
    fig.suptitle(f"output {out}({r.input_names[0]}, {r.input_names[1]}) on a "
                 f"{len(x1)} x {len(x2)} grid{blank}", fontsize=10)


def _draw_curves(fig: Figure | SubFigure, r: ResponseData) -> None:
    (x,) = r.axes
    n_out = len(r.output_names)
    cols = min(_PANELS_PER_ROW, n_out)
    rows = math.ceil(n_out / cols)
    axes = fig.subplots(rows, cols, squeeze=False)
    for k, ax in enumerate(axes.ravel()):
        if k >= n_out:
            ax.set_axis_off()
            continue
        y = r.values[k]
        ax.plot(x, y, lw=1.6)
        ax.set_xlim(float(x[0]), float(x[-1]))
        ax.set_xlabel(r.input_names[0])
        ax.set_ylabel(r.output_names[k])
        blank = "" if np.isfinite(y).all() else " (gaps: no rule fires)"
        ax.set_title(f"output {r.output_names[k]}({r.input_names[0]}){blank}", fontsize=10)
        ax.grid(alpha=0.3)


def render_system(data: SystemFigureData) -> Figure:
    """The membership functions of every variable (three panels to a row), then the response:
    one row per output (3-D surface and contour map) for two inputs, the output curves for
    one input."""
    n = len(data.panels)
    cols = min(_PANELS_PER_ROW, n)
    mf_rows = math.ceil(n / cols)
    r = data.response
    heights = [3.1 * mf_rows]
    if r is not None and len(r.axes) == 2:
        heights += [4.2] * len(r.output_names)
    elif r is not None:
        heights.append(3.1 * math.ceil(len(r.output_names) / _PANELS_PER_ROW))
    width = max(4.2 * cols, 10.5 if r is not None and len(r.axes) == 2 else 6.0)
    fig = new_figure(width, sum(heights) + 0.5)
    subs = fig.subfigures(len(heights), 1, height_ratios=heights, squeeze=False)[:, 0]
    _draw_panels(subs[0], data.panels)
    if r is not None and len(r.axes) == 2:
        for k in range(len(r.output_names)):
            _draw_surface(subs[1 + k], r, k)
    elif r is not None:
        _draw_curves(subs[1], r)
    fig.suptitle(data.title)
    return fig


def render_response(r: ResponseData, title: str = "") -> Figure:
    """The response alone: for two inputs the surface of each output (one row each: 3-D
    view and contour map), for one input the output curves."""
    if len(r.axes) == 2:
        n_out = len(r.output_names)
        fig = new_figure(10.5, 4.2 * n_out + (0.4 if title else 0.0))
        subs = fig.subfigures(n_out, 1, squeeze=False)[:, 0]
        for k in range(n_out):
            _draw_surface(subs[k], r, k)
    else:
        cols = min(_PANELS_PER_ROW, len(r.output_names))
        fig = new_figure(max(4.2 * cols, 6.0),
                      3.1 * math.ceil(len(r.output_names) / cols) + (0.4 if title else 0.0))
        _draw_curves(fig, r)
    if title:
        fig.suptitle(title)
    return fig
