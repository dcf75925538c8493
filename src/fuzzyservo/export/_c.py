"""C text shared by the generators: exact literals, constant arrays, comment blocks."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import numpy as np

from ..errors import ParameterError

__all__ = ["Real", "c_array", "c_comment", "c_literal"]

Real = Literal["double", "float"]


def c_literal(value: float, real: Real = "double", where: str = "a number") -> str:
    """``value`` as an exact C literal of type ``real``: a C99 hexadecimal double (the very
    bits Python holds), or for float the nearest float (hexadecimal, ``f`` suffix);
    ``NAN``, ``INFINITY`` and ``-INFINITY`` from <math.h>.

    Raises
    ------
    ParameterError
        In float, a number beyond the largest float, or a non-zero one that rounds to 0
        (``where`` names it).
    """
    v = float(value)
    if math.isnan(v):
        return "NAN"
    if math.isinf(v):
        return "INFINITY" if v > 0 else "-INFINITY"
    if real == "double":
        return v.hex()
    f32 = np.float32(v) if abs(v) <= float(np.finfo(np.float32).max) else np.float32(np.inf)
    if not np.isfinite(f32):
        raise ParameterError(f"{where}: {v!r} is beyond the largest float (3.4e38); export in "
                             f"double")
    if f32 == 0.0 and v != 0.0:
        raise ParameterError(f"{where}: {v!r} is not zero but rounds to 0 in float; export in "
                             f"double")
    return float(f32).hex() + "f"


def c_array(ctype: str, name: str, items: Sequence[str], per_line: int = 3) -> str:
    """A ``static const`` C array of the literal ``items``, ``per_line`` to a line."""
    rows = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
    body = ",\n    ".join(rows)
    return f"static const {ctype} {name}[{len(items)}] = {{\n    {body}\n}};"


def c_comment(lines: Sequence[str]) -> str:
    """A C block comment of ``lines``."""
    return "/*\n" + "\n".join(f" * {line}".rstrip() for line in lines) + "\n */"
