"""fuzzyservo.formats: fuzzy systems from and to MATLAB .fis, IEC 61131-7 FCL and fuzzylite FLL.

Readers never evaluate text as code; a malformed file raises ``FormatError`` with file, line,
column and what was expected, an unsupported feature is named in the same way. Writers raise
``ParameterError`` naming what the target format cannot hold.
"""

from __future__ import annotations

from .io import FORMATS, dumps, format_of, loads, read_system, write_system

__all__ = ["FORMATS", "dumps", "format_of", "loads", "read_system", "write_system"]
