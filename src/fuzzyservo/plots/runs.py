"""Figures of one's own runs: position against reference, command and α, runs overlaid.

:func:`runs_figure` takes any single-run results, a :class:`~fuzzyservo.sim.SimResult`, an
:class:`~fuzzyservo.sim.OpenLoopResult` or a run CSV read by
:func:`fuzzyservo.files.read_run_csv`, computes what it draws first (:func:`run_curves`:
curves in display units, with step metrics when asked) and renders it second; it is the
figure of ``fuzzyservo plot`` and ``fuzzyservo simulate --plot``. :func:`save_figure` writes
PNG or SVG by the file's suffix.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._io import atomic_write
from .._typing import FloatArray
from ..analysis.step_metrics import Run, step_metrics
from ..errors import InputError

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["FIGURE_FORMATS", "RunCurve", "check_text", "run_curves", "runs_figure",
           "save_figure"]

#: File suffixes :func:`save_figure` writes.
FIGURE_FORMATS: tuple[str, ...] = (".png", ".svg")

#: One colour per run, in order (matplotlib's tab10); after ten runs the colours repeat with
#: another line style, so every run stays distinct.
_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
            "#7f7f7f", "#bcbd22", "#17becf")
_STYLES = ("-", "-.", ":")


@dataclass(frozen=True, slots=True, kw_only=True)
class RunCurve:
    """What the figure draws of one run, in display units."""

    label: str  #: legend label (with metrics when asked)
    t: FloatArray  #: time [s]
    y_mm: FloatArray  #: position [mm]
    r_mm: FloatArray | None  #: reference [mm], None in open loop
    u_pct: FloatArray  #: command [% of rated input], one per sample (held to the next)
    alpha: FloatArray | None  #: self-tuning factor [-], None where the run has none


def _optional(run: Any, name: str) -> FloatArray | None:
    v = getattr(run, name, None)
    if v is None:
        return None
    a = np.asarray(v, dtype=np.float64)
    return None if a.size == 0 or bool(np.all(np.isnan(a))) else a


def _metrics_text(run: Any) -> str:
    m = step_metrics(run)

    def f(x: float, unit: str, digits: int = 3) -> str:
        return "n/a" if math.isnan(x) else f"{x:.{digits}g} {unit}"

    return (f"rise {f(m.rise_time, 's')}, settling {f(m.settling_time, 's')}, "
            f"overshoot {f(m.overshoot, '%', 2)}")


def run_curves(runs: Sequence[Run], labels: Sequence[str] | None = None, *,
               metrics: bool = False, relative: bool = False) -> list[RunCurve]:
    """The curves of :func:`runs_figure` (computed, not drawn).

    Parameters
    ----------
    runs : sequence of results
        Each with ``t``, ``y``, ``u`` and optionally ``r``, ``alpha``.
    labels : sequence of str, optional
        One legend label per run; default "run 1", "run 2", ...
    metrics : bool
        Append rise time, settling time and overshoot to each closed-loop run's label.
    relative : bool
        Positions as offsets from each run's start position y(0) instead of absolute.

    Raises
    ------
    InputError
        No runs, a label count that does not match, or ``metrics`` for an open-loop run.
    """
    if not runs:
        raise InputError("nothing to plot: give at least one run")
    names = list(labels) if labels is not None else [f"run {i + 1}" for i in range(len(runs))]
    if len(names) != len(runs):
        raise InputError(f"{len(names)} label(s) for {len(runs)} run(s); give one per run")
    out = []
    for run, name in zip(runs, names, strict=True):
        t = np.asarray(run.t, dtype=np.float64)
        y = np.asarray(run.y, dtype=np.float64)
        u = np.asarray(run.u, dtype=np.float64)
        if u.size == t.size - 1:  # an open-loop result: one command per interval
            u = np.append(u, u[-1])
        r = _optional(run, "r")
        off = float(y[0]) if relative else 0.0
        label = name
        if metrics:
            if r is None:
                raise InputError(f"{name}: step metrics need a reference; an open-loop run "
                                 f"has none")
            label = f"{name}: {_metrics_text(run)}"
        out.append(RunCurve(label=label, t=t, y_mm=(y - off) * 1e3,
                            r_mm=None if r is None else (r - off) * 1e3, u_pct=u * 100.0,
                            alpha=_optional(run, "alpha")))
    return out


def check_text(text: str, what: str) -> str:
    """Check that matplotlib can draw ``text`` (a label or title) and return it.

    Text with an even, non-zero number of unescaped ``$`` is mathtext to matplotlib; mathtext
    it cannot parse would fail only when the figure is drawn, with a multi-line error.

    Raises
    ------
    InputError
        ``text`` is mathtext that does not parse; the message names ``what``, the text and
        matplotlib's reason, on one line.
    """
    from matplotlib import cbook, mathtext

    if cbook.is_math_text(text):
        try:
            mathtext.MathTextParser("path").parse(text)
        except ValueError as exc:  # matplotlib's parse error: the text, a caret, the reason
            reason = next((ln.strip() for ln in reversed(str(exc).splitlines()) if ln.strip()),
                          type(exc).__name__)
            # the text as typed (a repr would double every backslash of the TeX)
            raise InputError(f"{what} '{text}' is not valid mathtext ({reason}); write a "
                             f"literal dollar sign as \\$") from None
    return text


def runs_figure(runs: Sequence[Run], labels: Sequence[str] | None = None, *,
                metrics: bool = False, relative: bool = False,
                title: str | None = None) -> Figure:
    """Overlay runs: position and reference [mm], command [% of rated input], and α [-]
    where any run has it; one colour per run (reference dashed in the run's colour).

    Parameters as :func:`run_curves`; ``title`` heads the figure.

    Raises
    ------
    InputError
        A label or the title is mathtext matplotlib cannot parse (:func:`check_text`).
    """
    # imported when drawing, so that importing fuzzyservo.plots does not load matplotlib
    from matplotlib.figure import Figure

    curves = run_curves(runs, labels, metrics=metrics, relative=relative)
    for c in curves:
        check_text(c.label, "label")
    if title:
        check_text(title, "title")
    with_alpha = any(c.alpha is not None for c in curves)
    n_rows = 3 if with_alpha else 2
    fig = Figure(figsize=(8.0, 2.2 + 2.3 * n_rows), dpi=110)
    axes = fig.subplots(n_rows, 1, sharex=True, squeeze=False)[:, 0]
    ax_y, ax_u = axes[0], axes[1]
    for i, c in enumerate(curves):
        colour = _COLOURS[i % len(_COLOURS)]
        ls = _STYLES[(i // len(_COLOURS)) % len(_STYLES)]
        ax_y.plot(c.t, c.y_mm, color=colour, lw=1.5, ls=ls, label=c.label)
        if c.r_mm is not None:
            ax_y.plot(c.t, c.r_mm, color=colour, lw=1.0, ls="--")
        ax_u.step(c.t, c.u_pct, where="post", color=colour, lw=1.2, ls=ls)
        if with_alpha and c.alpha is not None:
            axes[2].step(c.t, c.alpha, where="post", color=colour, lw=1.2, ls=ls)
    ax_y.set_ylabel("position x - x(0) [mm]" if relative else "position x [mm]")
    ax_u.set_ylabel("valve command u\n[% of rated input]")
    ax_u.axhline(0.0, color="black", lw=0.6)
    if with_alpha:
        axes[2].set_ylabel(r"$\alpha_F$ [-]")
        axes[2].set_ylim(0.0, 1.0)
    if any(c.r_mm is not None for c in curves):
        ax_y.plot([], [], color="black", lw=1.0, ls="--", label="reference (dashed)")
    ax_y.legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("time t [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Write ``fig`` as PNG or SVG, chosen by the suffix of ``path``.

    Raises
    ------
    InputError
        Another suffix.
    OutputError
        The file cannot be written (the previous file, if any, is left as it was).
    """
    path = Path(path)
    if path.suffix.lower() not in FIGURE_FORMATS:
        raise InputError(f"figure {str(path)!r}: the file name must end in "
                         f"{' or '.join(FIGURE_FORMATS)}")
    with atomic_write(path, binary=True) as fh:
        fig.savefig(fh, format=path.suffix.lower()[1:])
    return path
