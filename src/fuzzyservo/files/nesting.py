"""A bound on the nesting of JSON and TOML text, checked before the text is parsed.

Python's ``json`` and ``tomllib`` parse nested arrays and tables by recursion: a file of a
few kilobytes (``[[[[...]]]]`` 5000 deep) ends in ``RecursionError``, a traceback, instead of
a message. :func:`_nesting_check` counts the brackets and braces outside strings and
comments in one pass and refuses the text when they nest deeper than a bound; what it lets
through then parses without recursing more than the bound.
"""

from __future__ import annotations

from typing import Any, Literal

from ..errors import InputError

__all__ = ["MAX_NESTING", "_depth_check", "_nesting_check"]

#: Deepest nesting of arrays and tables a file of fuzzyservo's may have: its specs,
#: manifests and records nest less than 10 deep.
MAX_NESTING = 64


def _nesting_check(text: str, *, what: str, syntax: Literal["json", "toml"],
                   limit: int = MAX_NESTING) -> None:
    """Refuse ``text`` if its arrays and tables (``[``, ``{``) nest deeper than ``limit``.

    Strings are skipped (JSON ``"..."`` with escapes; TOML also ``'...'``, ``\"\"\"...\"\"\"``
    and ``'''...'''``), and TOML comments. Text that is not valid JSON or TOML is left to
    the parser to refuse: the count is exact up to the first syntax error, and the parser
    does not read past it.

    Raises
    ------
    InputError
        Nesting deeper than ``limit``; the message names ``what`` and the line.
    """
    depth = 0
    i, n = 0, len(text)
    toml = syntax == "toml"
    while i < n:
        ch = text[i]
        if ch in "[{":
            depth += 1
            if depth > limit:
                line = text.count("\n", 0, i) + 1
                raise InputError(f"{what} nests arrays or tables more than {limit} deep "
                                 f"(line {line}); fuzzyservo's files nest far less")
        elif ch in "]}":
            depth = max(0, depth - 1)
        elif ch == "#" and toml:
            j = text.find("\n", i)
            i = n if j < 0 else j
            continue
        elif ch == '"' or (ch == "'" and toml):
            triple = toml and text.startswith(ch * 3, i)
            quote = ch * 3 if triple else ch
            j = i + len(quote)
            escapes = ch == '"'
            while j < n:
                if escapes and text[j] == "\\":
                    j += 2
                    continue
                if text.startswith(quote, j):
                    break
                if not triple and text[j] == "\n":  # an unclosed string: the parser says so
                    break
                j += 1
            if triple:  # a closing run of up to five quotes keeps one or two in the string
                while j + len(quote) < n and text[j + len(quote)] == ch:
                    j += 1
            i = j + len(quote)
            continue
        i += 1


def _depth_check(doc: Any, *, what: str, limit: int = MAX_NESTING) -> None:
    """Refuse parsed data (dicts and lists) nested deeper than ``limit``, without recursing:
    TOML's dotted keys (``a.b.c... = 1``, ``[a.b.c...]``) nest tables without a bracket, so
    :func:`_nesting_check` cannot see them, and code that walks or prints the result
    recursively would end in ``RecursionError``.

    Raises
    ------
    InputError
        Nesting deeper than ``limit``; the message names ``what``.
    """
    stack: list[tuple[Any, int]] = [(doc, 0)]
    while stack:
        obj, depth = stack.pop()
        if depth > limit:
            raise InputError(f"{what} nests tables or arrays more than {limit} deep; "
                             f"fuzzyservo's files nest far less")
        if isinstance(obj, dict):
            stack.extend((v, depth + 1) for v in obj.values())
        elif isinstance(obj, list):
            stack.extend((v, depth + 1) for v in obj)
