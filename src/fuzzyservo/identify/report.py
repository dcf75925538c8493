"""The offline HTML page of an identification (``fuzzyservo identify ... --html PAGE.html``).

Written with the project's one HTML writer (:mod:`fuzzyservo.files.html`): everything is
embedded (the figure as a base64 PNG), so the page opens without a network connection or any
file beside it, and every string from outside (the data file's name, the command line) is
escaped by the writer. The page holds, in order: the data file, its SHA-256 digest, the plant,
mode and start position (the header); a summary; the identifiability warnings, each on its own
line; the estimates (start value, estimate, standard error, SE %, bootstrap interval, bounds);
their correlation matrix; the residual RMS of each channel (in mm or bar and in SI); the fit's
numbers (reduced chi-square, starts, model runs); the notes; the figure
(:func:`fuzzyservo.plots.identification.identification_figure`); the command that made it.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from .._io import sha256_file, write_text_atomic
from ..files.html import Figure, Section, Table, render_html
from ..plots.identification import CHANNEL_DISPLAY, save_identification_figure

__all__ = ["FIGURE_CAPTION", "format_estimate", "render_report", "report_title", "write_report"]

#: Caption of the embedded figure.
FIGURE_CAPTION = ("Measured (grey), identified model (blue) and starting model (dashed) per "
                  "channel; below each, the residual measured - identified with ±2σ (σ: the "
                  "channel's weight in the fit); shaded: samples flagged and left out of the "
                  "fit. Right: each estimate divided by its start value, ±2 standard errors "
                  "and the bootstrap interval when one was run.")


def report_title(ident: Any) -> str:
    """The page's title: the fitted fields and the model."""
    return f"fuzzyservo identification: {', '.join(ident.names)} ({ident.plant} model)"


def _num(x: float, digits: int = 4) -> str:
    """``x`` to ``digits`` significant digits, trailing zeros kept (they are significant)."""
    if not math.isfinite(x):
        return "n/a"
    text = f"{x:#.{digits}g}"
    mant, e, exp = text.partition("e")
    return mant.rstrip(".") + e + exp


def format_estimate(value: float, std_error: float) -> str:
    """``value`` with as many significant digits as its standard error makes meaningful:
    down to the second significant digit of the error, at least 4 and at most 12 digits."""
    if not math.isfinite(value):
        return "n/a"
    if value == 0.0 or not (math.isfinite(std_error) and std_error > 0.0):
        return _num(value)
    digits = math.floor(math.log10(abs(value))) - math.floor(math.log10(std_error)) + 2
    return _num(value, min(12, max(4, digits)))


def _estimates_table(ident: Any) -> Table:
    interval = None if ident.interval is None else np.asarray(ident.interval, np.float64)
    level = f"{float(ident.level):.0%}"
    rows: list[list[object]] = []
    for i, (name, unit) in enumerate(zip(ident.names, ident.units, strict=True)):
        est = float(ident.estimate[i])
        se = float(ident.std_error[i])
        rel = 100.0 * se / abs(est) if est != 0.0 else math.nan
        if interval is None:
            ci = "not run"
        else:
            ci = (f"{format_estimate(float(interval[i, 0]), se)} to "
                  f"{format_estimate(float(interval[i, 1]), se)}")
        lo, hi = (float(v) for v in ident.bounds[i])
        rows.append([name, unit, f"{float(ident.initial[i]):.6g}", format_estimate(est, se),
                     _num(se, 2), _num(rel, 2), ci, lo, hi])
    return Table(["parameter", "unit", "start value", "estimate", "standard error", "SE [%]",
                  f"bootstrap {level} interval", "lower bound", "upper bound"], rows,
                 caption="Estimates [SI units of each row]")


def _correlation_table(ident: Any) -> Table:
    corr = np.asarray(ident.correlation, dtype=np.float64)
    rows = [[name, *(float(v) for v in corr[i])] for i, name in enumerate(ident.names)]
    return Table(["", *ident.names], rows, caption="Correlation of the estimates [-]")


def _residual_table(ident: Any) -> Table:
    used = np.asarray(ident.used, dtype=bool)
    rows: list[list[object]] = []
    for c in ident.channels:
        label, unit, scale = CHANNEL_DISPLAY.get(c, (c, "SI", 1.0))
        si_unit = {"y": "m", "p_f": "Pa", "p_n": "Pa"}.get(c, "SI")
        rms = float(ident.residual_rms[c])
        span = float(np.ptp(np.asarray(ident.measured[c])[used])) if used.any() else math.nan
        rows.append([c, rms * scale, unit, rms, si_unit,
                     100.0 * rms / span if span > 0.0 else math.nan,
                     float(ident.sigma[c]) * scale])
    return Table(["channel", "residual RMS", "unit", "residual RMS (SI)", "SI unit",
                  "RMS / measured range [%]", "weight σ [display unit]"], rows,
                 caption="Residuals over the samples used (measured - identified)")


def _fit_table(ident: Any) -> Table:
    used = np.asarray(ident.used, dtype=bool)
    costs = np.asarray(ident.start_costs, dtype=np.float64)
    rows: list[list[object]] = [
        ["reduced chi-square", float(ident.chi2)],
        ["samples", int(used.size)],
        ["samples used (not flagged)", int(np.count_nonzero(used))],
        ["channels compared", ", ".join(ident.channels)],
        ["starts", int(costs.size)],
        ["final cost of each start", ", ".join(_num(float(c)) for c in costs)],
        ["widest relative distance of a start at the best cost", float(ident.start_spread)],
        ["model runs", int(ident.n_runs)],
    ]
    return Table(["quantity", "value"], rows, caption="The fit")


def render_report(ident: Any, *, command: str, data: str, digest: str | None = None,
                  figure: str | Path | None = None) -> str:
    """The HTML page of an identification, as one string with everything embedded.

    Parameters
    ----------
    ident : Identification
        The result of :func:`fuzzyservo.identify.identify`.
    command : str
        The command line that made it (shown escaped).
    data : str
        The data file's name as given (shown escaped).
    digest : str, optional
        SHA-256 of the data file, hex; None: shown as "not recorded".
    figure : str or Path, optional
        A PNG file of the figure to embed; None: no figure.

    Returns
    -------
    str
        The page.
    """
    warnings = tuple(ident.warnings)
    notes = tuple(ident.notes)
    used = np.asarray(ident.used, dtype=bool)
    n_flag = int(used.size - np.count_nonzero(used))
    summary = (f"Fitted {len(ident.names)} parameter(s) of the {ident.plant} model ("
               f"{ident.mode}) to {', '.join(ident.channels)} over {used.size} samples"
               + (f" ({n_flag} flagged and left out)" if n_flag else "")
               + f"; reduced chi-square {_num(float(ident.chi2))}; "
               + (f"{len(warnings)} warning(s)." if warnings else "no warning."))
    sections = [
        Section("Summary", summary=summary),
        Section("Warnings", items=warnings) if warnings else
        Section("Warnings", paragraphs=["None: the data determine every fitted parameter."]),
        Section("Estimates", tables=[_estimates_table(ident), _correlation_table(ident)],
                paragraphs=["Standard errors by the delta method from s² (JᵀJ)⁻¹ at the "
                            "optimum; bootstrap intervals (when run) are percentile intervals "
                            "of refits to the fitted traces plus moving blocks of the "
                            "residuals."]),
        Section("Residuals", tables=[_residual_table(ident), _fit_table(ident)]),
    ]
    if notes:
        sections.append(Section("Notes", items=notes))
    if figure is not None:
        sections.append(Section("Figure", figures=[Figure(Path(figure), FIGURE_CAPTION)]))
    sections.append(Section("Command", paragraphs=[command]))
    from .. import __version__

    meta = {
        "data": data,
        "data digest (SHA-256)": digest or "not recorded",
        "plant": ident.plant,
        "mode": ident.mode,
        "start position": f"{float(ident.position) * 1e3:.6g} mm from the retracted end",
        "fitted": ", ".join(ident.names),
        "written by": f"fuzzyservo {__version__}",
        "command": command,
    }
    return render_html(report_title(ident), sections, meta)


def write_report(ident: Any, path: str | Path, *, command: str, data: str,
                 digest: str | None = None, figure_path: str | Path | None = None) -> Path:
    """Write :func:`render_report` to ``path`` atomically (an error leaves an existing file as
    it was) and return the path.

    Parameters
    ----------
    ident : Identification
        The result of :func:`fuzzyservo.identify.identify`.
    path : str or Path
        The page to write.
    command : str
        The command line that made it.
    data : str
        The data file's name as given.
    digest : str, optional
        SHA-256 of the data file; None: computed from ``data`` when it names a file (else
        "not recorded").
    figure_path : str or Path, optional
        A PNG of the figure already written (``--plot``), embedded as it is; None or an SVG:
        the figure is drawn to a temporary PNG and embedded.

    Raises
    ------
    OutputError
        ``path`` cannot be written.
    """
    if digest is None and Path(data).is_file():
        digest = sha256_file(data)
    if figure_path is not None and Path(figure_path).suffix.lower() == ".png":
        text = render_report(ident, command=command, data=data, digest=digest,
                             figure=figure_path)
    else:
        with tempfile.TemporaryDirectory(prefix="fuzzyservo-identify-report-") as tmp:
            png = save_identification_figure(ident, Path(tmp) / "identification.png")
            text = render_report(ident, command=command, data=data, digest=digest, figure=png)
    return write_text_atomic(path, text)
