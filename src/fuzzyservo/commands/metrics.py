"""``fuzzyservo metrics run.csv [--json]``: step-response metrics of a simulated run.

Reads the CSV that ``fuzzyservo simulate`` writes (a header row naming the columns, ``t, r, y,
u, alpha`` first, lines starting with ``#`` ignored), computes
:func:`fuzzyservo.analysis.step_metrics` with the reference ``r``, the command ``u``, the
target ``r[-1]`` and the initial value ``y[0]``, and prints one metric per line or, with
``--json``, one JSON object (NaN written as ``null``).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis.step_metrics import step_metrics
from ..errors import InputError

__all__ = ["register", "run", "read_run_csv"]

#: Columns the command needs; others (``alpha``, plant states) are ignored.
REQUIRED_COLUMNS: tuple[str, ...] = ("t", "r", "y", "u")

#: Units of each metric for a run CSV (position in m, command as a fraction of rated input).
UNITS: dict[str, str] = {
    "rise_time": "s",
    "settling_time": "s",
    "settling_time_5": "s",
    "overshoot": "%",
    "peak": "m",
    "peak_time": "s",
    "steady_state_error": "m",
    "iae": "m*s",
    "ise": "m^2*s",
    "itae": "m*s^2",
    "itse": "m^2*s^2",
    "u_max": "1",
    "u_sq_integral": "s",
    "u_total_variation": "1",
}


def register(subparsers: Any) -> None:
    """Add the ``metrics`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "metrics",
        help="step-response metrics of a run CSV",
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
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(handler=run)


def read_run_csv(path: Path) -> dict[str, np.ndarray]:
    """Read the columns ``t, r, y, u`` of a run CSV as float arrays.

    Raises
    ------
    InputError
        The file cannot be read, has no header, lacks a required column or holds a value
        that is not a number.
    """
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = [row for row in csv.reader(fh) if row and not row[0].lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise InputError(f"cannot read run CSV {str(path)!r}: {reason}") from exc
    if not rows:
        raise InputError(f"run CSV {str(path)!r} is empty; expected a header with t, r, y, u")
    header = [name.strip() for name in rows[0]]
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise InputError(
            f"run CSV {str(path)!r} lacks column(s) {', '.join(missing)}; "
            f"expected t, r, y, u (found {', '.join(header) or 'none'})"
        )
    columns: dict[str, np.ndarray] = {}
    for name in REQUIRED_COLUMNS:
        j = header.index(name)
        values = np.empty(len(rows) - 1)
        for i, row in enumerate(rows[1:]):
            cell = row[j].strip() if j < len(row) else ""
            try:
                values[i] = float(cell)
            except ValueError:
                raise InputError(
                    f"run CSV {str(path)!r} line {i + 2}, column {name!r}: {cell!r} is not a number"
                ) from None
        columns[name] = values
    return columns


def run(args: argparse.Namespace) -> int:
    """Handle ``fuzzyservo metrics``: print the metrics of ``args.csv``; return 0."""
    cols = read_run_csv(args.csv)
    metrics = step_metrics(cols["t"], cols["y"], u=cols["u"], r=cols["r"]).as_dict()
    if args.json:
        print(json.dumps({k: (None if math.isnan(v) else v) for k, v in metrics.items()}))
    else:
        width = max(len(k) for k in metrics)
        for name, value in metrics.items():
            print(f"{name:<{width}}  {value:.6g} {UNITS[name]}")
    return 0
