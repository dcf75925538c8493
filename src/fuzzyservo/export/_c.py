"""C text shared by the generators: exact literals, constant arrays, comment blocks."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Literal

import numpy as np

from ..errors import ParameterError

__all__ = ["C_HEADERS", "C_KEYWORDS", "Real", "c_array", "c_comment", "c_comment_text",
           "c_literal", "c_string", "check_identifier", "escape_text"]

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


def escape_text(text: object) -> str:
    """``text`` in printable ASCII, reversibly: printable ASCII stays, a backslash is
    doubled, anything else (line breaks, control characters, non-ASCII, lone surrogates
    from undecodable file names) is written as a Python-style escape (``\\n``, ``\\t``,
    ``\\xNN``, ``\\uNNNN``, ``\\UNNNNNNNN``). The text of every string from outside that the
    generated files record (commands, paths, names), before the escapes of its context."""
    out = []
    for ch in str(text):
        o = ord(ch)
        if ch == "\\":
            out.append("\\\\")
        elif 0x20 <= o < 0x7F:
            out.append(ch)
        elif ch in _NAMED:
            out.append(_NAMED[ch])
        elif o < 0x100:
            out.append(f"\\x{o:02x}")
        elif o < 0x10000:
            out.append(f"\\u{o:04x}")
        else:
            out.append(f"\\U{o:08x}")
    return "".join(out)


_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def c_comment_text(text: object) -> str:
    """``text`` safe on one line of a C block comment, and readable back: :func:`escape_text`
    (one line of printable ASCII), then ``*/`` and ``/*`` broken (``*\\/``, ``/\\*``) so that
    nothing ends or nests a comment, and ``??`` broken (``?\\?``) so that no trigraph
    (``??/`` is a backslash under ``-std=c99``) is formed."""
    return _BREAK.sub(lambda m: m.group(0) + "\\", escape_text(text))


# a backslash after the first character of every "*/", "/*" and "??" (overlaps included)
_BREAK = re.compile(r"\*(?=/)|/(?=\*)|\?(?=\?)")


def c_comment(lines: Sequence[str]) -> str:
    """A C block comment of ``lines``, each made safe by :func:`c_comment_text` (a line
    cannot end the comment or start another line)."""
    return "/*\n" + "\n".join(f" * {c_comment_text(line)}".rstrip() for line in lines) + "\n */"


def c_string(text: object) -> str:
    """``text`` as a C string literal (with its quotes) of printable ASCII: ``"``, ``\\``
    and ``?`` (trigraphs) escaped, everything else outside printable ASCII as 3-digit octal
    escapes of its UTF-8 bytes (octal: a hexadecimal escape would swallow a following hex
    digit); a lone surrogate (an undecodable file name) as the byte it stands for."""
    out = ['"']
    for b in str(text).encode("utf-8", "surrogateescape"):
        ch = chr(b)
        if ch in '"\\?':
            out.append("\\" + ch)
        elif 0x20 <= b < 0x7F:
            out.append(ch)
        else:
            out.append(f"\\{b:03o}")
    out.append('"')
    return "".join(out)


#: C keywords (C89 to C23), and names C++ keeps (the header is included from C++ too).
C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto "
    "if inline int long register restrict return short signed sizeof static struct switch "
    "typedef union unsigned void volatile while _Bool _Complex _Imaginary _Alignas _Alignof "
    "_Atomic _Generic _Noreturn _Static_assert _Thread_local _BitInt _Decimal32 _Decimal64 "
    "_Decimal128 alignas alignof bool constexpr false nullptr static_assert thread_local "
    "true typeof typeof_unqual main".split())

#: The C standard library's headers (C89 to C23), without ``.h``: a generated ``NAME.h``
#: of one of these names would shadow it for every file compiled with ``-I`` of its folder
#: (on a case-insensitive file system also in another case).
C_HEADERS = frozenset(
    "assert complex ctype errno fenv float inttypes iso646 limits locale math setjmp signal "
    "stdalign stdarg stdatomic stdbit stdbool stdckdint stddef stdint stdio stdlib "
    "stdnoreturn string tgmath threads time uchar wchar wctype".split())

_IDENT = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,30}")


def check_identifier(name: object, what: str = "--name") -> str:
    """``name`` if it may prefix the generated C identifiers and name its files: a C
    identifier of 1 to 31 letters, digits and ``_`` starting with a letter (ASCII), not a C
    keyword, not the name of a C standard header in any case (:data:`C_HEADERS`), and not
    the generated code's own prefixes (``fs``, ``fsm``, ``fs_...``, ``fsm_...``, ``fmi...``).

    Raises
    ------
    ParameterError
        Any other ``name`` (one line naming ``what`` and the value, escaped).
    """
    shown = repr(name) if not isinstance(name, str) else "'" + escape_text(name) + "'"
    if not isinstance(name, str) or not _IDENT.fullmatch(name):
        why = ("is empty" if name == "" else "is not a C identifier of at most 31 ASCII "
               "letters, digits and _ starting with a letter")
        raise ParameterError(f"{what} {shown} {why}")
    low = name.lower()
    if name in C_KEYWORDS:
        raise ParameterError(f"{what} {shown} is a C keyword; choose another name")
    if low in C_HEADERS:
        raise ParameterError(f"{what} {shown} is the name of the C standard header "
                             f"<{low}.h>, which {name}.h would shadow; choose another name")
    if low in ("fs", "fsm") or low.startswith(("fs_", "fsm_", "fmi")):
        raise ParameterError(f"{what} {shown} takes a prefix of the generated code (fs, fsm, "
                             f"fs_..., fsm_..., fmi...); choose another name")
    return name
