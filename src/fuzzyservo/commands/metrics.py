"""``fuzzyservo metrics run.csv [--json]``: step-response metrics of a simulated run.

Reads the CSV that ``fuzzyservo simulate`` writes (a header row naming the columns, ``t, r, y,
u, alpha`` first, lines starting with ``#`` ignored), computes
:func:`fuzzyservo.analysis.step_metrics` with the reference ``r``, the command ``u``, the
target ``r[-1]`` and the initial value ``y[0]``, and prints one metric per line or, with
``--json``, one strict JSON object (RFC 8259): NaN and infinities are written as ``null``
(Python's ``NaN``/``Infinity`` tokens are rejected by strict parsers).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from .._io import strict_json
from ..analysis.step_metrics import METRIC_UNITS, step_metrics
from ..files import read_run_csv
from . import HELP

__all__ = ["REQUIRED_COLUMNS", "UNITS", "print_metrics", "register", "run"]

#: Columns the command needs; others (``alpha``, plant states) are ignored.
REQUIRED_COLUMNS: tuple[str, ...] = ("t", "r", "y", "u")

#: Units of each metric for a run CSV (:data:`fuzzyservo.analysis.step_metrics.METRIC_UNITS`).
UNITS: dict[str, str] = METRIC_UNITS


def register(subparsers: Any) -> None:
    """Add the ``metrics`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "metrics",
        help=HELP["metrics"],
        description=(
            "Print rise time (10-90 %), settling times (2 % and 5 % bands), overshoot, peak, "
            "steady-state error, IAE, ISE, ITAE, ITSE and command metrics of a CSV written by "
            "'fuzzyservo simulate' (columns t, r, y, u). The target is the last reference "
            "value; times are measured from the first sample (a delayed step's wait is "
            "included). A metric the data cannot define is nan (null in JSON): step-shaped "
            "metrics when the reference ends where y started (no step), a settling time when "
            "y leaves its band in the run's last 10 %."
        ),
    )
    parser.add_argument("csv", type=Path, help="run CSV with columns t, r, y, u")
    parser.add_argument("--json", action="store_true",
                        help="print one strict JSON object; a metric that is NaN or infinite "
                             "(e.g. the IAE of a run at ±1e308) is null")
    parser.set_defaults(handler=run)


def print_metrics(metrics: dict[str, float]) -> None:
    """Print one metric per line: name, value (6 significant digits), unit."""
    width = max(len(k) for k in metrics)
    for name, value in metrics.items():
        print(f"{name:<{width}}  {value:.6g} {UNITS[name]}")


def run(args: argparse.Namespace) -> int:
    """Handle ``fuzzyservo metrics``: print the metrics of ``args.csv``; return 0."""
    run_data = read_run_csv(args.csv, REQUIRED_COLUMNS)
    metrics = step_metrics(run_data).as_dict()
    if args.json:
        print(strict_json(metrics))
    else:
        print_metrics(metrics)
    return 0
