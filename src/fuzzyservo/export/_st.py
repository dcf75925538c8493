"""Structured Text (IEC 61131-3) text shared by the ST generators: exact literals, safe
comments, identifiers.

Exactness of literals (checked with MatIEC, tests/export/test_st.py): an untyped real literal
is copied into the C that ``iec2c`` writes as written, so the shortest decimal that reads back
as the double (Python's ``repr``) comes out bit-identical; a typed ``LREAL#`` literal would be
parsed as a C ``long double`` first (a second rounding), so LREAL code writes none. In REAL
code an untyped literal in an expression is computed in double: expressions use ``REAL#``
literals, which become ``(float)x``, x written as the float's exact value (the double that
holds it, printed shortest), so no second rounding happens either.
"""

from __future__ import annotations

import math
import re
from typing import Literal

import numpy as np

from ..errors import ParameterError
from ._c import escape_text

__all__ = ["ST_RESERVED", "StReal", "check_st_name", "st_comment", "st_comment_text",
           "st_literal", "st_typed"]

#: The arithmetic type of generated Structured Text.
StReal = Literal["LREAL", "REAL"]

_FLOAT_MAX = float(np.finfo(np.float32).max)


def _decimal(v: float) -> str:
    """``v`` (finite) as an ST real literal: Python's shortest repr with a decimal point and
    an upper-case exponent of at least two digits (``1.0E-05``; ``1e-05`` is not ST)."""
    s = repr(float(v))
    if "e" in s:
        mant, exp = s.split("e")
        if "." not in mant:
            mant += ".0"
        e = int(exp)
        return f"{mant}E{'+' if e >= 0 else '-'}{abs(e):02d}"
    if "." not in s:
        s += ".0"
    return s


def st_literal(value: float, real: StReal = "LREAL", where: str = "a number") -> str:
    """``value`` as an exact ST literal for a variable of type ``real`` (declarations and
    array initialisers: the declared type gives the type): the double, or for REAL the
    nearest float, written so that it reads back exactly.

    Raises
    ------
    ParameterError
        NaN or an infinity (ST has no literal for them), or in REAL a number beyond the
        largest float or a non-zero one that rounds to 0 (``where`` names it).
    """
    v = float(value)
    if not math.isfinite(v):
        raise ParameterError(f"{where}: {v!r} has no Structured Text literal (NaN and "
                             f"infinities cannot be written)")
    if real == "LREAL":
        return _decimal(v)
    if abs(v) > _FLOAT_MAX:
        raise ParameterError(f"{where}: {v!r} is beyond the largest REAL (3.4E+38); export "
                             f"in LREAL")
    f32 = float(np.float32(v))
    if f32 == 0.0 and v != 0.0:
        raise ParameterError(f"{where}: {v!r} is not zero but rounds to 0 in REAL; export "
                             f"in LREAL")
    return _decimal(f32)


def st_typed(value: float, real: StReal) -> str:
    """A literal of ``value`` (finite, >= 0) inside an expression of type ``real``: untyped
    in LREAL (an untyped literal is a double in the C MatIEC writes, and in LREAL
    expressions on every target), ``REAL#x`` in REAL (untyped, it would be computed in
    double)."""
    lit = st_literal(value, real)
    if lit.startswith("-"):
        raise ParameterError(f"a typed literal must not be negative, got {value!r}")
    return lit if real == "LREAL" else f"REAL#{lit}"


def st_comment_text(text: object) -> str:
    """``text`` safe on one line of an ST comment ``(* ... *)``, readable back:
    :func:`~fuzzyservo.export._c.escape_text` (one line of printable ASCII), then ``(*`` and
    ``*)`` broken with a space (some targets nest comments, so an opening one must not
    appear either), and ``//`` and ``/*`` likewise (comment starts of other dialects)."""
    s = escape_text(text)
    return _BREAK.sub(lambda m: m.group(0) + " ", s)


# a space after the first character of "(*", "*)", "//" and "/*" (overlaps included)
_BREAK = re.compile(r"\((?=\*)|\*(?=\))|/(?=/)|/(?=\*)")


def st_comment(lines: list[str]) -> str:
    """An ST block comment of ``lines``, each made safe by :func:`st_comment_text`."""
    body = "\n".join(f"   {st_comment_text(line)}".rstrip() for line in lines)
    return "(*\n" + body + "\n*)"


#: Words a generated name must not be (any case): IEC 61131-3 keywords, elementary and
#: generic data types, the standard functions and function blocks, and names the dialects
#: of TwinCAT, CODESYS, TIA Portal (SCL) and MatIEC reserve.
ST_RESERVED = frozenset("""
ACTION END_ACTION AND ANY ANY_BIT ANY_DATE ANY_DERIVED ANY_ELEMENTARY ANY_INT ANY_MAGNITUDE
ANY_NUM ANY_REAL ANY_STRING ARRAY AT BY CASE END_CASE CONFIGURATION END_CONFIGURATION CONSTANT
DO ELSE ELSIF END_IF EN ENO EXIT FALSE F_EDGE FOR END_FOR FROM FUNCTION END_FUNCTION
FUNCTION_BLOCK END_FUNCTION_BLOCK IF INITIAL_STEP END_STEP INTERVAL METHOD END_METHOD MOD NOT
NON_RETAIN OF ON OR PRIORITY PROGRAM END_PROGRAM READ_ONLY READ_WRITE REF REF_TO REPEAT
END_REPEAT RESOURCE END_RESOURCE RETAIN RETURN R_EDGE SINGLE STEP STRUCT END_STRUCT SUPER TASK
THEN THIS TO TRANSITION END_TRANSITION TRUE TYPE END_TYPE UNTIL END_UNTIL USING VAR END_VAR
VAR_ACCESS VAR_CONFIG VAR_EXTERNAL VAR_GLOBAL VAR_INPUT VAR_IN_OUT VAR_OUTPUT VAR_TEMP WHILE
END_WHILE WITH XOR INTERFACE END_INTERFACE IMPLEMENTS EXTENDS ABSTRACT FINAL PUBLIC PRIVATE
PROTECTED INTERNAL OVERRIDE PROPERTY END_PROPERTY NAMESPACE END_NAMESPACE CONTINUE JMP
BOOL SINT INT DINT LINT USINT UINT UDINT ULINT REAL LREAL TIME LTIME DATE LDATE TIME_OF_DAY TOD
LTOD DATE_AND_TIME DT LDT STRING WSTRING CHAR WCHAR BYTE WORD DWORD LWORD POINTER REFERENCE
T D LT LD
ABS SQRT LN LOG EXP SIN COS TAN ASIN ACOS ATAN ATAN2 EXPT ADD SUB MUL DIV MOVE SHL SHR ROR ROL
SEL MAX MIN LIMIT MUX GT GE EQ LE LT NE LEN LEFT RIGHT MID CONCAT INSERT DELETE REPLACE FIND
TRUNC ROUND CEIL FLOOR SIZEOF ADR ADRINST
SR RS TP TON TOF CTU CTD CTUD R_TRIG F_TRIG RTC SEMA PID RAMP HYSTERESIS INTEGRAL DERIVATIVE
OK NIL VOID BEGIN GOTO REGION END_REGION LABEL END_LABEL CONST END_CONST DATA_BLOCK
END_DATA_BLOCK ORGANIZATION_BLOCK END_ORGANIZATION_BLOCK VARIANT NULL TIMER COUNTER UNION
END_UNION VAR_STAT BIT LTIME_OF_DAY TITLE VERSION AUTHOR FAMILY AND_THEN OR_ELSE

""".split())

_NAME = re.compile(r"[A-Za-z][A-Za-z0-9]*(?:_[A-Za-z0-9]+)*")
_TYPES = ("BOOL|SINT|INT|DINT|LINT|USINT|UINT|UDINT|ULINT|REAL|LREAL|TIME|DATE|TOD|DT|STRING|"
          "BYTE|WORD|DWORD|LWORD")
#: The standard library's typed variants (``ADD_REAL``, ``CTU_DINT``, ``MUX_INT_LREAL``) and
#: conversions (``REAL_TO_INT``, ``WORD_BCD_TO_UINT``).
_STD_TYPED = re.compile(rf"[A-Z0-9]+(?:_(?:{_TYPES}))+")
_STD_CONVERSION = re.compile(rf"\w+_TO_(?:{_TYPES}|BCD\w*)")
#: Longest block name: ``NAME_EXAMPLE`` and the example's other names stay within 32
#: characters (the shortest limit among the documented targets' identifiers).
MAX_NAME = 24


_STD_PREFIXES = frozenset(ST_RESERVED | {"BYTE", "WORD", "DWORD", "LWORD", "DIVTIME", "MULTIME",
                                         "CONCAT", "UDINT", "UINT", "ULINT", "USINT"})


def check_st_name(name: object, what: str = "--name") -> str:
    """``name`` if it may name the function block and its files: an IEC 61131-3 identifier of
    1 to 24 ASCII letters, digits and single ``_`` between them (no leading, trailing or
    doubled underscore: the standard forbids them, and MatIEC's C uses ``__``), not a
    reserved word (:data:`ST_RESERVED`, any case) and not starting with the generated code's
    prefix ``FS``/``FZ`` followed by ``_``.

    Raises
    ------
    ParameterError
        Any other ``name`` (one line naming ``what`` and the value, escaped).
    """
    shown = repr(name) if not isinstance(name, str) else "'" + escape_text(name) + "'"
    if not isinstance(name, str) or not _NAME.fullmatch(name) or len(name) > MAX_NAME:
        why = ("is empty" if name == "" else f"is not an IEC 61131-3 identifier of at most "
               f"{MAX_NAME} ASCII letters and digits, with single _ between them, starting "
               f"with a letter")
        raise ParameterError(f"{what} {shown} {why}")
    up = name.upper()
    if (up in ST_RESERVED or _STD_CONVERSION.fullmatch(up)
            or (_STD_TYPED.fullmatch(up) and up.split("_")[0] in _STD_PREFIXES)):
        raise ParameterError(f"{what} {shown} is a reserved word of Structured Text; choose "
                             f"another name")
    if name.upper().startswith(("FS_", "FZ_")):
        raise ParameterError(f"{what} {shown} takes a prefix of the generated code (FS_, "
                             f"FZ_); choose another name")
    return name
