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
from array import array
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from .._io import open_input
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


_BOMS = ((b"\xff\xfe\x00\x00", "UTF-32"), (b"\x00\x00\xfe\xff", "UTF-32"),
         (b"\xff\xfe", "UTF-16"), (b"\xfe\xff", "UTF-16"))


#: Longest line of a CSV read [bytes]: a run CSV's row is a few hundred bytes, a points CSV's
#: about 25 a column; a longer line (a file of zeros without a line end) is refused rather
#: than read whole into memory.
MAX_LINE_BYTES = 1024 * 1024


def _text_lines(fh: BinaryIO, path: Path, what: str) -> Iterator[str]:
    """The lines of a binary file as strict UTF-8 text, one at a time (a UTF-8 byte-order mark
    skipped); a bad byte or a NUL is an error naming the file and the byte offset, and so is
    a line longer than :data:`MAX_LINE_BYTES` (each line is one bounded read)."""
    offset = 0
    for n, raw in enumerate(iter(lambda: fh.readline(MAX_LINE_BYTES + 1), b"")):
        if len(raw) > MAX_LINE_BYTES and not raw.endswith(b"\n"):
            raise InputError(f"{what} {str(path)!r} line {n + 1} is longer than "
                             f"{MAX_LINE_BYTES} bytes (at offset {offset}); a CSV row is "
                             f"far shorter")
        if n == 0:
            for bom, name in _BOMS:
                if raw.startswith(bom):
                    raise InputError(f"{what} {str(path)!r} is {name} text (byte-order mark "
                                     f"at byte 0); save it as UTF-8")
            if raw.startswith(b"\xef\xbb\xbf"):  # UTF-8 byte-order mark: skipped
                raw = raw[3:]
                offset = 3
        try:
            line = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InputError(f"{what} {str(path)!r} is not UTF-8 text: byte "
                             f"0x{raw[exc.start]:02x} at offset {offset + exc.start}") from None
        nul = raw.find(b"\0")
        if nul >= 0:
            raise InputError(f"{what} {str(path)!r} is not text: NUL character at offset "
                             f"{offset + nul}")
        offset += len(raw)
        yield line


def read_csv_columns(path: str | Path, required: tuple[str, ...], *, what: str,
                     min_rows: int = 1) -> dict[str, FloatArray]:
    """The numeric columns of a CSV with a header row, as float arrays (``#`` lines ignored).

    ``required`` columns must be present and finite; another column is kept when every cell
    is a number (NaN allowed) and left out otherwise (a text column); ``what`` names the file
    in messages. The file is read as a stream (memory: the float columns, 8 bytes a value),
    as strict UTF-8, and every row must have one value per column of the header. Only a
    regular file is read (a FIFO or a device is refused), each line at most
    :data:`MAX_LINE_BYTES`.

    Raises
    ------
    InputError
        The file cannot be read or is not a regular file, has a line longer than
        :data:`MAX_LINE_BYTES`, is not UTF-8 (the message names the byte offset), has no
        header, names a column twice, lacks a required column, has a row with more or fewer
        values than the header names (a row cut short), has fewer than ``min_rows`` data
        rows, or holds a value that is not a number (the message names the line and column).
    """
    path = Path(path)
    want = ", ".join(required)
    header: list[str] | None = None
    values: list[array[float] | None] = []
    need: list[bool] = []
    rows = 0
    try:
        with open_input(path, what) as fh:  # a regular file (not a FIFO, not a device)
            reader = csv.reader(_text_lines(fh, path, what))
            for row in reader:
                if not row or row[0].lstrip().startswith("#"):
                    continue
                lineno = reader.line_num
                if header is None:
                    header = [name.strip() for name in row]
                    twice = sorted({h for h in header if header.count(h) > 1})
                    if twice:
                        raise InputError(f"{what} {str(path)!r} names column(s) "
                                         f"{', '.join(repr(h) for h in twice)} twice; name "
                                         f"each column once")
                    missing = [c for c in required if c not in header]
                    if missing:
                        raise InputError(
                            f"{what} {str(path)!r} lacks column(s) {', '.join(missing)}; "
                            f"expected {want} (found "
                            f"{', '.join(repr(h) for h in header) or 'none'})")
                    need = [h in required for h in header]
                    values = [array("d") for _ in header]
                    continue
                if len(row) != len(header):
                    raise InputError(
                        f"{what} {str(path)!r} line {lineno} has {len(row)} value(s), the "
                        f"header names {len(header)} columns"
                        + (" (a row cut short?)" if len(row) < len(header) else ""))
                rows += 1
                for j, cell in enumerate(row):
                    col = values[j]
                    if col is None:
                        continue  # a text column
                    try:
                        v = float(cell)
                    except ValueError:
                        if not need[j]:
                            values[j] = None
                            continue
                        raise InputError(f"{what} {str(path)!r} line {lineno}, column "
                                         f"{header[j]!r}: {cell.strip() or '(empty)'!r} is "
                                         f"not a number") from None
                    if need[j] and not math.isfinite(v):
                        raise InputError(f"{what} {str(path)!r} line {lineno}, column "
                                         f"{header[j]!r}: {cell.strip()!r} is not finite; "
                                         f"every value must be a number")
                    col.append(v)
    except OSError as exc:
        raise InputError(f"cannot read {what} {str(path)!r}: {exc.strerror or exc}") from None
    except csv.Error as exc:
        raise InputError(f"{what} {str(path)!r} is not a CSV file: {exc}") from None
    if header is None:
        raise InputError(f"{what} {str(path)!r} is empty; expected a header with {want}")
    if rows < min_rows:
        raise InputError(f"{what} {str(path)!r} has {rows} data row(s); at least "
                         f"{min_rows} needed")
    return {name: np.frombuffer(col, dtype=np.float64)  # a view: no copy
            for name, col in zip(header, values, strict=True) if col is not None}


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
