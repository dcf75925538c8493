"""Run CSVs, as ``fuzzyservo simulate`` writes them, read back for ``metrics`` and ``plot``.

A run CSV has one header row naming the columns, then one row per sample; lines starting with
``#`` are ignored. Closed loop: ``t, r, y, u, alpha`` and then the plant states; open loop:
``t, u, y`` and then the plant states. Units: t [s]; r, y [m], absolute positions in the
stroke on every plant (r the start position plus the reference offset, y the measured
position); u [-], the valve command as a fraction of rated input; alpha [-] (NaN for the PID
family, 1 for the fuzzy PI); states in SI units.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._typing import FloatArray
from ..errors import InputError

__all__ = ["RunData", "read_csv_columns", "read_run_csv"]


@dataclass(frozen=True, slots=True, eq=False)
class RunData:
    """The columns of a run CSV."""

    path: Path  #: where it was read from
    columns: dict[str, FloatArray]  #: every column by name, in file order [SI]

    @property
    def t(self) -> FloatArray:
        """Sample times [s]."""
        return self.columns["t"]

    @property
    def y(self) -> FloatArray:
        """Measured position [m]."""
        return self.columns["y"]

    @property
    def u(self) -> FloatArray:
        """Valve command [-]."""
        return self.columns["u"]

    @property
    def r(self) -> FloatArray | None:
        """Reference [m], or None for an open-loop run."""
        return self.columns.get("r")

    @property
    def alpha(self) -> FloatArray | None:
        """Self-tuning factor [-], or None where the file has none or it is all NaN."""
        a = self.columns.get("alpha")
        return None if a is None or bool(np.all(np.isnan(a))) else a


def read_csv_columns(path: str | Path, required: tuple[str, ...], *, what: str,
                     min_rows: int = 1) -> dict[str, FloatArray]:
    """The numeric columns of a CSV with a header row, as float arrays (``#`` lines ignored).

    ``required`` columns must be present and finite; another column is kept when every cell
    is a number (NaN allowed) and left out otherwise (a text column); ``what`` names the file
    in messages.

    Raises
    ------
    InputError
        The file cannot be read, has no header, names a column twice, lacks a required column,
        has fewer than ``min_rows`` data rows, or holds a value that is not a number (the
        message names the line and column).
    """
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = [(n, row) for n, row in enumerate(csv.reader(fh), start=1)
                    if row and not row[0].lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise InputError(f"cannot read {what} {str(path)!r}: {reason}") from exc
    want = ", ".join(required)
    if not rows:
        raise InputError(f"{what} {str(path)!r} is empty; expected a header with {want}")
    header = [name.strip() for name in rows[0][1]]
    twice = sorted({h for h in header if header.count(h) > 1})
    if twice:
        raise InputError(f"{what} {str(path)!r} names column(s) {', '.join(twice)} twice")
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(
            f"{what} {str(path)!r} lacks column(s) {', '.join(missing)}; expected {want} "
            f"(found {', '.join(header) or 'none'})")
    if len(rows) - 1 < min_rows:
        raise InputError(f"{what} {str(path)!r} has {len(rows) - 1} data row(s); at least "
                         f"{min_rows} needed")
    columns: dict[str, FloatArray] = {}
    for j, name in enumerate(header):
        values = np.empty(len(rows) - 1)
        for i, (lineno, row) in enumerate(rows[1:]):
            cell = row[j].strip() if j < len(row) else ""
            try:
                values[i] = float(cell)
            except ValueError:
                if name not in required:
                    break  # a text column: left out
                raise InputError(f"{what} {str(path)!r} line {lineno}, column {name!r}: "
                                 f"{cell or '(empty)'!r} is not a number") from None
            if name in required and not math.isfinite(values[i]):
                raise InputError(f"{what} {str(path)!r} line {lineno}, column {name!r}: "
                                 f"{cell!r} is not finite; every value must be a number")
        else:
            columns[name] = values
    return columns


def read_run_csv(path: str | Path, required: tuple[str, ...] = ("t", "y", "u")) -> RunData:
    """Read every column of a run CSV as float arrays (:func:`read_csv_columns`, at least two
    samples).

    Raises
    ------
    InputError
        As :func:`read_csv_columns`.
    """
    columns = read_csv_columns(path, required, what="run CSV", min_rows=2)
    return RunData(path=Path(path), columns=columns)
