"""Checks of the public API's arguments, with one message form.

The public functions (``build_plant``, ``build_controller``, ``simulate``, ...) take numbers,
mappings and objects from callers who may pass a string, None or a list by mistake. Each
check here raises :class:`~fuzzyservo.errors.ParameterError` naming the argument, the value
given and its type, and what is allowed, instead of the AttributeError, TypeError or
OverflowError the code below would raise. Free for every layer (docs/architecture.md).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from typing import Any

from .errors import ParameterError

__all__ = ["MAX_SEED", "given", "mapping", "real", "seed"]

#: Largest seed of a random generator: TOML's largest integer (a signed 64-bit one), since
#: seeds are recorded in gains files and sweep specs that other TOML readers must read back;
#: far above what a seed needs, and within numpy's SeedSequence (128-bit pool), so distinct
#: seeds stay distinct streams.
MAX_SEED = 2**63 - 1


def given(value: Any) -> str:
    """``value`` as messages show it: its repr (cut to 60 characters) and its type."""
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{text} ({type(value).__name__})"


def real(value: Any, name: str, unit: str = "", *, positive: bool = False,
         nonnegative: bool = False, finite: bool = True) -> float:
    """``value`` as a float: a real number (not a bool, not a string), finite unless
    ``finite`` is False, and > 0 (``positive``) or >= 0 (``nonnegative``) if asked.

    Raises
    ------
    ParameterError
        Another type, a value too large for a float, or out of the range asked for; the
        message names ``name``, the value, its type and what is allowed.
    """
    rule = ("a finite " if finite else "a ") + "real number" + (
        " > 0" if positive else " >= 0" if nonnegative else "") + (f" [{unit}]" if unit else "")
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be {rule}, got {given(value)}")
    try:
        v = float(value)
    except OverflowError:
        raise ParameterError(f"{name} must be {rule}, got {given(value)}, too large for a "
                             f"float") from None
    bad = ((finite and not math.isfinite(v)) or math.isnan(v)
           or (positive and not v > 0.0) or (nonnegative and not v >= 0.0))
    if bad:
        raise ParameterError(f"{name} must be {rule}, got {v!r}")
    return v


def mapping(value: Any, name: str, example: str) -> Mapping[Any, Any]:
    """``value`` if it is a mapping (a dict), else ParameterError naming ``name``, the value
    and an ``example`` of what is allowed."""
    if not isinstance(value, Mapping):
        raise ParameterError(f"{name} must be a mapping ({example}), got {given(value)}")
    return value


def seed(value: Any, name: str = "seed") -> int:
    """``value`` as a seed: an integer (not a bool) from 0 to :data:`MAX_SEED`.

    Raises
    ------
    ParameterError
        Another type or a value out of that range (the message names ``name`` and shows at
        most 40 digits of the value).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ParameterError(f"{name} must be an integer from 0 to {MAX_SEED} (2**63 - 1), "
                             f"got {given(value)}")
    v = int(value)
    if not 0 <= v <= MAX_SEED:
        shown = str(v) if len(str(v)) <= 40 else f"{str(v)[:37]}... ({len(str(v))} digits)"
        raise ParameterError(f"{name} must be an integer from 0 to {MAX_SEED} (2**63 - 1), "
                             f"got {shown}")
    return v
