"""``fuzzyservo surface du|alpha``: evaluate the paper's fuzzy systems on points or a grid.

Input CSV (``--at``): a header naming at least the columns ``e`` and ``de``, one point per
row, lines starting with ``#`` ignored. Output CSV (``--out``): header ``e,de,value``, values
written with 17 significant digits (round-trip exact). ``--grid N`` evaluates an N x N grid
over [-1, 1]^2 instead. ``--plot`` writes the control surface and ``--mf-plot`` the
membership functions, as PNG or SVG by the file name's suffix
(:data:`fuzzyservo.plots.runs.FIGURE_FORMATS`).

Every output is checked before any work (its folder exists and is writable, it is not a
folder, not the ``--at`` file, not another output of the same command, and a figure's suffix
is a supported format), and written atomically: an error leaves the previous file as it was.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path
from typing import Any

import numpy as np

from .._io import atomic_write, check_output_path
from .._typing import FloatArray
from ..errors import InputError
from ..files import read_csv_columns
from ..fuzzy import MamdaniSystem
from ..paper import alpha_system, du_system
from ..plots.figures import membership_data, render_memberships, render_surface, surface_data
from ..plots.runs import FIGURE_FORMATS

__all__ = ["read_points_csv", "register", "run", "write_values_csv"]

SYSTEMS = {"du": du_system, "alpha": alpha_system}
MAX_GRID = 4000


def register(subparsers: Any) -> None:
    """Add the ``surface`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "surface",
        help="evaluate the paper's du or alpha fuzzy system on points or a grid",
        description=(
            "Evaluate the paper's fuzzy system (du: Fig. 3a, alpha: Fig. 3b; exact centroid) "
            "at the points of a CSV with columns e,de (--at) or on an N x N grid over "
            "[-1, 1]^2 (--grid), writing a CSV with columns e,de,value (--out); optionally "
            "plot the surface (--plot) and the membership functions (--mf-plot) as "
            f"{' or '.join(f[1:].upper() for f in FIGURE_FORMATS)} (by the file name's "
            "suffix)."
        ),
    )
    parser.add_argument("system", choices=sorted(SYSTEMS), help="which system of Fig. 3")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--at", type=Path, metavar="POINTS.csv",
                       help="CSV with header e,de: the points to evaluate")
    where.add_argument("--grid", type=int, metavar="N",
                       help=f"evaluate an N x N grid over [-1, 1]^2 (2 <= N <= {MAX_GRID})")
    parser.add_argument("--out", type=Path, metavar="OUT.csv", help="CSV to write: e,de,value")
    suffixes = "|".join(f[1:] for f in FIGURE_FORMATS)
    parser.add_argument("--plot", type=Path, metavar=f"SURFACE.{suffixes}",
                        help="figure of the control surface (on the --grid, default 81 x 81)")
    parser.add_argument("--mf-plot", type=Path, metavar=f"MF.{suffixes}",
                        help="figure of the membership functions")
    parser.set_defaults(handler=run)


def read_points_csv(path: Path) -> tuple[FloatArray, FloatArray]:
    """Read the ``e`` and ``de`` columns of a CSV as finite float arrays (other columns, such
    as the ``value`` of a CSV this command wrote, are ignored).

    Raises
    ------
    InputError
        The file cannot be read, lacks a header with ``e`` and ``de``, or a value is not a
        finite number (the message names the line and column).
    """
    cols = read_csv_columns(path, ("e", "de"), what="points CSV")
    return cols["e"], cols["de"]


def write_values_csv(path: Path, e: FloatArray, de: FloatArray, value: FloatArray) -> None:
    """Write ``e,de,value`` rows with round-trip precision, atomically.

    Raises
    ------
    OutputError
        The file cannot be written; the previous file, if any, is unchanged.
    """
    with atomic_write(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["e", "de", "value"])
        for row in zip(e.tolist(), de.tolist(), value.tolist(), strict=True):
            w.writerow([repr(x) for x in row])


def _save(fig: Any, path: Path) -> None:
    with atomic_write(path, binary=True) as fh:
        fig.savefig(fh, format=path.suffix.lower()[1:], dpi=120)


def _check_outputs(args: argparse.Namespace) -> None:
    """Every output path, before any work: writable, not a folder, not an input, not given
    twice; a figure's suffix one of :data:`FIGURE_FORMATS`."""
    seen: dict[Path, str] = {}
    for option, path, figure in (("--out", args.out, False), ("--plot", args.plot, True),
                                 ("--mf-plot", args.mf_plot, True)):
        if path is None:
            continue
        check_output_path(path, option=option, inputs=(args.at,))
        if figure and path.suffix.lower() not in FIGURE_FORMATS:
            raise InputError(f"{option} {str(path)!r}: the file name must end in "
                             f"{' or '.join(FIGURE_FORMATS)}, the figure formats supported")
        key = path.resolve()
        if key in seen:
            raise InputError(f"{option} {str(path)!r} is also {seen[key]}; give each output "
                             f"its own file")
        seen[key] = option


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo surface``."""
    system: MamdaniSystem = SYSTEMS[args.system]()
    if args.grid is not None and not 2 <= args.grid <= MAX_GRID:
        raise InputError(f"--grid must be between 2 and {MAX_GRID}, got {args.grid}")
    if args.out is None and args.plot is None and args.mf_plot is None:
        raise InputError("nothing to do: give --out (with --at or --grid), --plot or --mf-plot")
    if args.out is not None and args.at is None and args.grid is None:
        raise InputError("--out needs the points: give --at POINTS.csv or --grid N")
    _check_outputs(args)
    if args.out is not None:
        if args.at is not None:
            e, de = read_points_csv(args.at)
        else:
            g = np.linspace(-1.0, 1.0, args.grid)
            ee, dd = np.meshgrid(g, g)
            e, de = ee.ravel(), dd.ravel()
        write_values_csv(args.out, e, de, system.evaluate(e, de))
    if args.plot is not None:
        n = args.grid if args.grid is not None else 81
        _save(render_surface(surface_data(system, n, f"{args.system}(e, Δe)")), args.plot)
    if args.mf_plot is not None:
        _save(render_memberships(membership_data(system), f"{args.system} system"), args.mf_plot)
    return 0
