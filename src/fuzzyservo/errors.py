"""The exceptions fuzzyservo raises.

Every error a user can cause derives from :class:`FuzzyServoError` and also from the matching
built-in (``ValueError`` for bad input, ``RuntimeError`` for a run that fails), so callers may
catch either. Messages name the offending item, its value and what is allowed; the CLI prints
them on one line and exits with status 2.
"""

from __future__ import annotations

from collections.abc import Iterator

__all__ = [
    "INTERRUPTED",
    "EmptyFuzzySetError",
    "FormatError",
    "FuzzyServoError",
    "InputError",
    "OutputError",
    "ParameterError",
    "SimulationDivergedError",
    "UsageError",
    "error_chain",
]

#: What Ctrl-C prints, in the entry point (``fuzzyservo._entry``) and in
#: ``fuzzyservo.cli.main``. Here, not in either, so that neither imports the other for it.
INTERRUPTED = "fuzzyservo: interrupted; files being written were left as they were"


class FuzzyServoError(Exception):
    """Base class of every error fuzzyservo raises on purpose."""


class ParameterError(FuzzyServoError, ValueError):
    """A parameter, specification or rule is outside what is allowed."""


class InputError(FuzzyServoError, ValueError):
    """A signal, file or command-line value is malformed (NaN, missing column, ...)."""


class FormatError(InputError):
    """A fuzzy-system file is malformed or uses a feature fuzzyservo does not support; the
    message starts with ``file:line:column:`` and says what was expected or what is not
    supported."""


class OutputError(FuzzyServoError, OSError):
    """A file could not be written (missing folder, permission, full disk, size limit); the
    previous file, if any, is unchanged."""


class EmptyFuzzySetError(FuzzyServoError, ValueError):
    """The aggregated output set is empty and the system declares no default output."""


class SimulationDivergedError(FuzzyServoError, RuntimeError):
    """A simulation produced a non-finite state; the message names the time and the state."""


class UsageError(FuzzyServoError, ValueError):
    """A usage error of a command line a front end builds: the line the CLI would print
    (``fuzzyservo simulate: error: argument --duration: ...``)."""


def error_chain(exc: BaseException) -> Iterator[BaseException]:
    """``exc``, then its causes and contexts, each once (scipy wraps errors raised in
    callbacks; a front end looks for its own in the chain)."""
    seen: set[int] = set()
    cur: BaseException | None = exc
    while cur is not None and id(cur) not in seen:
        seen.add(id(cur))
        yield cur
        cur = cur.__cause__ or cur.__context__
