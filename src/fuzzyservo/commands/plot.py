"""``fuzzyservo plot RUN.csv [RUN2.csv ...] --out FIG.png|.svg``: overlay one's own runs.

Reads run CSVs as ``fuzzyservo simulate`` writes them (closed loop: ``t, r, y, u, alpha``;
open loop: ``t, u, y``; plant states after) and draws position against reference [mm], the
valve command [% of rated input] and, where a run has it, the self-tuning factor α, one
colour per run (:func:`fuzzyservo.plots.runs_figure`).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from .._io import check_output_path
from ..errors import InputError
from ..files import read_run_csv
from ..plots.runs import FIGURE_FORMATS, check_text, runs_figure, save_figure
from . import HELP

__all__ = ["register", "run"]


def register(subparsers: Any) -> None:
    """Add the ``plot`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "plot",
        help=HELP["plot"],
        description=(
            "Overlay runs written by 'fuzzyservo simulate': piston position against the "
            "reference [mm], the valve command [% of rated input] and the self-tuning factor "
            "alpha where present, one colour per run; PNG or SVG by the suffix of --out."),
    )
    parser.add_argument("csv", type=Path, nargs="+", metavar="RUN.csv",
                        help="run CSV(s) with columns t, y, u (and r, alpha)")
    parser.add_argument("--out", type=Path, required=True, metavar="FIG.png|FIG.svg",
                        help="figure to write")
    parser.add_argument("--label", action="append", default=None, metavar="TEXT",
                        help="legend label of a run, once per run in order (default: the "
                             "file names)")
    parser.add_argument("--metrics", action="store_true",
                        help="add rise time, settling time and overshoot to the legend")
    parser.add_argument("--relative", action="store_true",
                        help="plot positions from each run's start position, x - x(0)")
    parser.add_argument("--title", default=None, help="figure title")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo plot``."""
    if args.out.suffix.lower() not in FIGURE_FORMATS:
        raise InputError(f"--out {str(args.out)!r}: the file name must end in "
                         f"{' or '.join(FIGURE_FORMATS)}")
    check_output_path(args.out, option="--out", inputs=args.csv)
    labels = args.label if args.label is not None else [p.stem for p in args.csv]
    if len(labels) != len(args.csv):
        raise InputError(f"{len(labels)} --label for {len(args.csv)} run CSV(s); give one "
                         f"per run or none")
    for label in labels:
        check_text(label, "--label")
    if args.title:
        check_text(args.title, "--title")
    runs = [read_run_csv(p) for p in args.csv]
    if args.metrics:
        for p, r in zip(args.csv, runs, strict=True):
            if r.r is None:
                raise InputError(f"--metrics: {str(p)!r} is an open-loop run (no column r); "
                                 f"step metrics need a reference")
    fig = runs_figure(runs, labels, metrics=args.metrics, relative=args.relative,
                      title=args.title)
    save_figure(fig, args.out)
    return 0
