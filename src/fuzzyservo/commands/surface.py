"""``fuzzyservo surface du|alpha|FILE``: evaluate a two-input fuzzy system on points or a grid.

The system: the paper's ``du`` (Fig. 3a) or ``alpha`` (Fig. 3b), or a fuzzy-system file
(``.fis``, ``.fcl``, ``.fll``, :func:`fuzzyservo.formats.read_system`) with two inputs, of
which the first output is evaluated, exactly (:func:`fuzzyservo.fuzzy.evaluate`).

Columns are named after the system's inputs: ``e`` and ``de`` for du and alpha, the file's
two input names (in the file's order) for a file; the value column is ``value`` for both, so
a script reads the same layout whatever the system. (A file whose input is itself called
``value`` is refused: use ``fuzzyservo fis eval``, which names every column after the file.)

Input CSV (``--at``): a header naming at least the two input columns, one point per row,
lines starting with ``#`` ignored. Output CSV (``--out``): header ``IN1,IN2,value``, values
written with ``repr`` (round-trip exact); where no rule fires and the file's output default
is NaN, ``nan``. ``--grid N`` evaluates an N x N grid instead: over [-1, 1]^2 for du and
alpha, over the inputs' ranges for a file (the first input varies fastest). ``--plot``
writes the control surface and ``--mf-plot`` the membership functions, as PNG or SVG by the
file name's suffix (:data:`fuzzyservo.plots.runs.FIGURE_FORMATS`).

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
from ..formats import FORMATS, read_system
from ..fuzzy import FuzzySystem, evaluate
from ..paper import alpha_system, du_system
from ..plots.figures import membership_data, render_memberships, render_surface, surface_data
from ..plots.runs import FIGURE_FORMATS
from . import HELP

__all__ = ["read_points_csv", "register", "run", "write_values_csv"]

SYSTEMS = {"du": du_system, "alpha": alpha_system}
#: Largest --grid (points per input): the bound of ``fis eval`` and for its reason.
MAX_GRID = 1000


def register(subparsers: Any) -> None:
    """Add the ``surface`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "surface",
        help=HELP["surface"],
        description=(
            "Evaluate the paper's fuzzy system (du: Fig. 3a, alpha: Fig. 3b; exact centroid) "
            "or the first output of a two-input system in a .fis, .fcl or .fll file, exactly, "
            "at the points of a CSV (--at) or on an N x N grid (--grid: over [-1, 1]^2 for du "
            "and alpha, over the inputs' ranges for a file), writing a CSV (--out) with the "
            "two input columns and value: e,de,value for du and alpha, the file's input names "
            "and value for a file (nan where no rule fires and the file gives no default); "
            "optionally plot the surface (--plot) and the membership functions (--mf-plot) as "
            f"{' or '.join(f[1:].upper() for f in FIGURE_FORMATS)} (by the file name's "
            "suffix)."
        ),
    )
    parser.add_argument("system", metavar="du|alpha|FILE",
                        help="du or alpha (the systems of Fig. 3), or a fuzzy-system file "
                             "(.fis, .fcl, .fll) with two inputs")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--at", type=Path, metavar="POINTS.csv",
                       help="CSV with the two input columns (e,de for du and alpha, the "
                            "file's input names for a file): the points to evaluate")
    where.add_argument("--grid", type=int, metavar="N",
                       help=f"evaluate an N x N grid over [-1, 1]^2 (du, alpha) or the inputs' "
                            f"ranges (a file), 2 <= N <= {MAX_GRID}")
    parser.add_argument("--out", type=Path, metavar="OUT.csv",
                        help="CSV to write: the two input columns, then value")
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


def write_values_csv(path: Path, e: FloatArray, de: FloatArray, value: FloatArray, *,
                     names: tuple[str, str] = ("e", "de")) -> None:
    """Write ``e,de,value`` rows (the first two columns named ``names``) with round-trip
    precision, atomically.

    Raises
    ------
    OutputError
        The file cannot be written; the previous file, if any, is unchanged.
    """
    with atomic_write(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow([*names, "value"])
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
        check_output_path(path, option=option, inputs=(args.at, args.system_file))
        if figure and path.suffix.lower() not in FIGURE_FORMATS:
            raise InputError(f"{option} {str(path)!r}: the file name must end in "
                             f"{' or '.join(FIGURE_FORMATS)}, the figure formats supported")
        key = path.resolve()
        if key in seen:
            raise InputError(f"{option} {str(path)!r} is also {seen[key]}; give each output "
                             f"its own file")
        seen[key] = option


def _system_file(name: str) -> Path | None:
    """None for du and alpha, else the fuzzy-system file ``name`` names."""
    if name in SYSTEMS:
        return None
    path = Path(name)
    if path.suffix.lower().lstrip(".") not in FORMATS:
        raise InputError(f"unknown system {name!r}: give {' or '.join(sorted(SYSTEMS))} (the "
                         f"systems of Fig. 3) or a fuzzy-system file ending in "
                         f"{', '.join('.' + f for f in FORMATS)}")
    return path


def _two_inputs(system: FuzzySystem, path: Path) -> tuple[str, str]:
    names = tuple(v.name for v in system.inputs)
    if len(names) != 2:
        raise InputError(f"{str(path)!r}: surface needs a system with two inputs; "
                         f"{system.name!r} has {len(names)} ({', '.join(names)}); use "
                         f"fuzzyservo fis eval for any number of inputs")
    if "value" in names:
        raise InputError(f"{str(path)!r}: an input is named 'value', the name of the output "
                         f"column; use fuzzyservo fis eval, which names every column after "
                         f"the file")
    return names[0], names[1]


def _run_file(args: argparse.Namespace, path: Path) -> int:
    """``surface FILE``: the first output of a two-input system read from a file."""
    from ..plots.systems import (
        ResponseData,
        render_response,
        render_variables,
        response_data,
        variable_panels,
    )

    system = read_system(path)
    names = _two_inputs(system, path)
    out = system.outputs[0].name
    if args.out is not None:
        if args.at is not None:
            cols = read_csv_columns(args.at, names, what="points CSV")
            x1, x2 = cols[names[0]], cols[names[1]]
        else:
            g1, g2 = np.meshgrid(np.linspace(*system.inputs[0].range, args.grid),
                                 np.linspace(*system.inputs[1].range, args.grid))
            x1, x2 = g1.ravel(), g2.ravel()
        value = evaluate(system, np.column_stack([x1, x2]), parallel=True)[:, 0]
        write_values_csv(args.out, x1, x2, np.ascontiguousarray(value), names=names)
    if args.plot is not None:
        r = response_data(system, args.grid if args.grid is not None else 81)
        first = ResponseData(input_names=r.input_names, output_names=(out,), axes=r.axes,
                             values=r.values[:1])
        _save(render_response(first, f"{system.name}: {out}({names[0]}, {names[1]})"),
              args.plot)
    if args.mf_plot is not None:
        _save(render_variables(variable_panels(system), f"{system.name}: membership functions"),
              args.mf_plot)
    return 0


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo surface``."""
    args.system_file = _system_file(args.system)
    if args.grid is not None and not 2 <= args.grid <= MAX_GRID:
        raise InputError(f"--grid must be between 2 and {MAX_GRID}, got {args.grid}")
    if args.out is None and args.plot is None and args.mf_plot is None:
        raise InputError("nothing to do: give --out (with --at or --grid), --plot or --mf-plot")
    if args.out is not None and args.at is None and args.grid is None:
        raise InputError("--out needs the points: give --at POINTS.csv or --grid N")
    _check_outputs(args)
    if args.system_file is not None:
        return _run_file(args, args.system_file)
    system = SYSTEMS[args.system]()
    if args.out is not None:
        if args.at is not None:
            e, de = read_points_csv(args.at)
        else:
            g = np.linspace(-1.0, 1.0, args.grid)
            ee, dd = np.meshgrid(g, g)
            e, de = ee.ravel(), dd.ravel()
        write_values_csv(args.out, e, de, evaluate(system, np.column_stack([e, de]))[:, 0])
    if args.plot is not None:
        n = args.grid if args.grid is not None else 81
        _save(render_surface(surface_data(system, n, f"{args.system}(e, Δe)")), args.plot)
    if args.mf_plot is not None:
        _save(render_memberships(membership_data(system), f"{args.system} system"), args.mf_plot)
    return 0
