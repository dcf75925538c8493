"""Format dispatch: the file extension names the format."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

from ..errors import ParameterError
from ..fuzzy.system import FuzzySystem

__all__ = ["FORMATS", "dumps", "format_of", "loads", "read_system", "write_system"]

#: Supported formats, by file extension without the dot.
FORMATS: tuple[str, ...] = ("fis", "fcl", "fll")
#: Largest file read [bytes]: far above any hand-written system, below anything pathological.
MAX_BYTES = 16 * 1024 * 1024


def format_of(path: str | Path) -> str:
    """The format named by a path's extension; ParameterError for another extension."""
    ext = Path(path).suffix.lower().lstrip(".")
    if ext not in FORMATS:
        raise ParameterError(
            f"cannot tell the format of {str(path)!r} from its extension: use .fis, .fcl or .fll")
    return ext


def _module(fmt: str) -> Any:
    if fmt not in FORMATS:
        raise ParameterError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    return importlib.import_module(f"{__package__}.{fmt}")


def loads(text: str, fmt: str, source: str = "<string>") -> FuzzySystem:
    """Parse ``text`` in format ``fmt`` ("fis", "fcl", "fll"); ``source`` names it in errors."""
    system: FuzzySystem = _module(fmt).parse(text, source)
    return system


def dumps(system: FuzzySystem, fmt: str) -> str:
    """The text of ``system`` in format ``fmt``; ParameterError naming what it cannot hold."""
    text: str = _module(fmt).dump(system)
    return text


def read_system(path: str | Path) -> FuzzySystem:
    """Read a fuzzy system from a .fis, .fcl or .fll file (format from the extension): a
    regular file of at most :data:`MAX_BYTES` (a FIFO, a device or a larger file is an
    InputError naming it)."""
    from .._io import read_bytes

    p = Path(path)
    fmt = format_of(p)
    data = read_bytes(p, "", MAX_BYTES)  # a regular file, one bounded read
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    return loads(text, fmt, str(p))


def write_system(system: FuzzySystem, path: str | Path) -> None:
    """Write ``system`` to a .fis, .fcl or .fll file, atomically (format from the extension)."""
    from .._io import write_text_atomic

    p = Path(path)
    text = dumps(system, format_of(p))
    write_text_atomic(p, text)
