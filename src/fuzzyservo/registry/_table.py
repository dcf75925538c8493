"""Lookup by name shared by the registries."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TypeVar

from ..errors import ParameterError

T = TypeVar("T")


def lookup(table: Mapping[str, T], name: str, what: str) -> T:
    """``table[name]``, or a ParameterError naming the value and the registered names."""
    try:
        return table[name]
    except (KeyError, TypeError):
        raise ParameterError(f"unknown {what} {name!r}; allowed: {', '.join(table)}") from None
