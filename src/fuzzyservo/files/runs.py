"""Run CSVs, as ``fuzzyservo simulate`` writes them, read back for ``metrics`` and ``plot``.

A run CSV has one header row naming the columns, then one row per sample; lines starting with
``#`` are ignored. Closed loop: ``t, r, y, u, alpha`` and then the plant states; open loop:
``t, u, y`` and then the plant states. Units: t [s]; r, y [m], absolute positions in the
stroke on every plant (r the start position plus the reference offset, y the measured
position); u [-], the valve command as a fraction of rated input; alpha [-] (NaN for the PID
family, 1 for the fuzzy PI); states in SI units.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._io import read_csv_columns
from .._typing import FloatArray

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
