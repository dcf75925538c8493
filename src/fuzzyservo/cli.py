"""Command-line interface: ``fuzzyservo <command> ...``.

Each subcommand lives in ``fuzzyservo.commands.<name>`` and exposes ``register(subparsers)``,
which adds its parser and sets ``handler`` (a function ``(argparse.Namespace) -> int``).
Errors a user can cause (:class:`~fuzzyservo.errors.FuzzyServoError`) are printed on one line
and give exit status 2, without a traceback. A reader that closes the pipe early
(``fuzzyservo linearize | head -1``) ends the command quietly with status 141, the status of a
process ended by SIGPIPE, as other command-line tools do. Standard output that cannot take
the text (``> /dev/full``, a full disk, a quota or a file-size limit) ends the command with
status 2 and one line naming the reason, the same quiet exit otherwise.

Interruptions end on one line too: Ctrl-C (SIGINT) with status 130, at any point including
start-up, and SIGTERM during a write with 143 (128 + the signal); every file being written at
that moment is left as it was (``fuzzyservo._io.atomic_write``). SIGTERM at any other moment
keeps its default action and ends the process at once (a Python handler would wait for a
compiled loop to finish). numpy floating-point warnings are not
printed: a run that goes non-finite is reported by the simulator as an error of its own. An
error of ours raised inside a library that wraps it (scipy's optimiser, the integrator) is
found in the exception's chain and printed as itself.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import importlib
import io
import os
import signal
import stat
import sys
import threading
import warnings
from collections.abc import Sequence
from typing import Any

from . import __version__
from ._io import Terminated, terminate_gracefully
from .commands import COMMANDS as _COMMAND_MODULES
from .commands import HELP as _HELP
from .errors import INTERRUPTED, FuzzyServoError, UsageError, error_chain

#: Subcommands, in the order ``--help`` lists them (``fuzzyservo.commands.COMMANDS`` names
#: each one's module).
COMMANDS: tuple[str, ...] = tuple(_COMMAND_MODULES)

#: Exit status after the reader of standard output went away (128 + SIGPIPE).
EXIT_PIPE = 141

#: Exit status after Ctrl-C (128 + SIGINT).
EXIT_INTERRUPT = 130

#: errno values of a write that found no room: on standard output they end the command on one
#: line (files are written by ``_io.atomic_write``, which names them in an ``OutputError``).
_NO_ROOM = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT})


def _unraisable(previous: Any) -> Any:
    """A ``sys.unraisablehook`` that re-raises an interruption swallowed by a finalizer.

    Ctrl-C that lands inside a weakref callback or ``__del__`` (matplotlib runs many) is
    "ignored" by Python, with a traceback on stderr, and the run goes on. This hook prints
    nothing and raises the same signal again, so the main code sees it at the next step."""
    def hook(unraisable: Any) -> None:
        exc = unraisable.exc_value
        if isinstance(exc, KeyboardInterrupt):
            if _STOP["handled"]:
                return
            timer = _STOP["timer"]
            if timer is None or not timer.is_alive():  # one signal again, not one per swallow
                signum = exc.signum if isinstance(exc, Terminated) else signal.SIGINT
                # sent from another thread, it is handled once this hook has returned; 50 ms
                # leave the hook time to return on a loaded machine, and if the signal still
                # lands in here (while start() waits for the thread), it is sent once more
                while True:
                    try:
                        _STOP["timer"] = threading.Timer(0.05, _resend, (signum,))
                        _STOP["timer"].start()
                        break
                    except KeyboardInterrupt:
                        continue
            return
        previous(unraisable)
    return hook


_STOP: dict[str, Any] = {"handled": False, "timer": None, "sigint": False}


def _on_sigint(signum: int, frame: Any) -> None:
    """Ctrl-C: recorded, then Python's own KeyboardInterrupt.

    The record keeps an interruption one when a compiled library turns it into an error of
    its own: the KeyboardInterrupt raised inside one of the Python calls of matplotlib's Agg
    renderer is dropped, and the renderer raises ``ValueError: Invalid bounding box`` instead
    (seen while ``reproduce`` drew Fig. 3). :func:`_foreign` reads it."""
    _STOP["sigint"] = True
    signal.default_int_handler(signum, frame)


def _resend(signum: int) -> None:
    if not _STOP["handled"]:
        os.kill(os.getpid(), signum)


def _ours(exc: BaseException) -> FuzzyServoError | None:
    """The first error of ours in ``exc``'s chain (scipy wraps errors raised in callbacks)."""
    return next((e for e in error_chain(exc) if isinstance(e, FuzzyServoError)), None)


def _stdout_is_full(exc: OSError) -> bool:
    """Whether ``exc`` (no room, no file name) is standard output's: a character device
    (``/dev/full``; a terminal never runs out of room), or a file on a full disk or past the
    file size limit. Else it was a temporary file's."""
    try:
        fd = sys.__stdout__.fileno() if sys.__stdout__ is not None else 1
        st = os.fstat(fd)
        if stat.S_ISCHR(st.st_mode):
            return True
        if not stat.S_ISREG(st.st_mode):
            return False  # a pipe or a socket: no disk to fill
        if exc.errno == errno.EFBIG:
            return True
        vfs = os.fstatvfs(fd)
        return vfs.f_bavail == 0 or vfs.f_bfree == 0
    except (OSError, ValueError):
        return False


def _foreign(exc: BaseException) -> int:
    """An exception not ours: an interruption in its chain is re-raised; one of our errors
    wrapped by a library is its one line; anything else propagates (a defect: traceback).

    Ctrl-C inside a class body being created (a module imported lazily, e.g. matplotlib's)
    reaches us as a RuntimeError from __set_name__ with the KeyboardInterrupt as its cause:
    it is still an interruption."""
    stop = next((e for e in error_chain(exc) if isinstance(e, KeyboardInterrupt)), None)
    if stop is not None:
        raise stop from None
    if _STOP["sigint"]:  # Ctrl-C came and a library made another error of it (_on_sigint)
        raise KeyboardInterrupt from None
    ours = _ours(exc)
    if ours is None:
        raise exc
    return _error(str(ours))


def _error(message: str) -> int:
    print(f"fuzzyservo: error: {' '.join(message.split())}", file=sys.stderr)
    return 2


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors exit with status 2 on one line."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())}\n")


class _RaisingParser(argparse.ArgumentParser):
    """A parser whose usage errors raise :class:`UsageError` (for front ends that build a
    command line and show its errors as the CLI would, e.g. the browser page)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise UsageError(f"{self.prog}: error: {' '.join(message.split())}")


def build_parser(*, raising: bool = False, argv: Sequence[str] | None = None
                 ) -> argparse.ArgumentParser:
    """Build the top-level parser with every subcommand (``raising``: usage errors raise
    :class:`UsageError` instead of ending the process).

    With ``argv``, only the subcommand it names (its first word) is built in full and the
    others are listed by name and help, so a command imports only its own module and
    ``--help`` and ``--version`` import none (they answer in a few tens of ms)."""
    cls = _RaisingParser if raising else _Parser
    parser = cls(
        prog="fuzzyservo",
        description="Electro-hydraulic servo models and fuzzy / PID control (Aly et al., 2012).",
    )
    parser.add_argument("--version", action="version", version=f"fuzzyservo {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=cls)
    wanted = (set(_COMMAND_MODULES.values()) if argv is None
              else {_COMMAND_MODULES.get(_command_of(argv), "")})
    done: set[str] = set()
    for name in COMMANDS:
        module = _COMMAND_MODULES[name]
        if module in wanted:
            if module not in done:  # a module may register several (sweep, sweep-report)
                done.add(module)
                importlib.import_module(f"fuzzyservo.commands.{module}").register(sub)
        else:
            sub.add_parser(name, help=_HELP[name], add_help=False)
    return parser


def _command_of(argv: Sequence[str]) -> str:
    """The subcommand ``argv`` names (its first word that is not an option), or ""."""
    return next((a for a in argv if not a.startswith("-")), "")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with ``argv`` (default: ``sys.argv[1:]``) and return the exit status."""
    terminate_gracefully(True)
    _STOP.update(handled=False, timer=None, sigint=False)
    hook = sys.unraisablehook
    sys.unraisablehook = _unraisable(hook)
    sigint = None
    with contextlib.suppress(ValueError):  # ValueError: not the main thread (no handlers)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            sigint = signal.signal(signal.SIGINT, _on_sigint)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            import numpy as np

            with np.errstate(all="ignore"):
                return _run(argv)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM at any point, start-up included
        _STOP["handled"] = True
        if _STOP["timer"] is not None:
            _STOP["timer"].cancel()
        if isinstance(exc, Terminated):
            print("fuzzyservo: terminated; files being written were left as they were",
                  file=sys.stderr)
            return 128 + exc.signum
        print(INTERRUPTED, file=sys.stderr)
        return EXIT_INTERRUPT
    finally:
        if sigint is not None:
            with contextlib.suppress(ValueError):
                signal.signal(signal.SIGINT, sigint)
        sys.unraisablehook = hook
        terminate_gracefully(False)


def _numba_cache_best_effort() -> None:
    """Make a failure to *save* numba's on-disk cache of compiled kernels harmless.

    numba saves a kernel's machine code beside the source on its first call. Under a file-size
    limit, on a full disk or a read-only install that write fails with an OSError that ends
    the run with a traceback, although the kernel is compiled and the cache is only a speed-up
    for the next run. The CLI ignores such failures (the next run compiles again)."""
    from numba.core import caching

    if getattr(caching.Cache, "_fuzzyservo_best_effort", False):
        return
    save: Any = caching.Cache.save_overload

    def save_overload(self: Any, sig: Any, data: Any) -> None:
        with contextlib.suppress(OSError):
            save(self, sig, data)

    caching.Cache.save_overload = save_overload  # type: ignore[method-assign]
    caching.Cache._fuzzyservo_best_effort = True  # type: ignore[attr-defined]


def _stdout_to_devnull() -> None:
    """Point standard output's descriptor at /dev/null (what its buffer still holds is
    dropped quietly at exit)."""
    with contextlib.suppress(OSError, ValueError, io.UnsupportedOperation):
        fd = sys.stdout.fileno()
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, fd)
        os.close(devnull)


def _run(argv: Sequence[str] | None) -> int:
    try:
        words = list(sys.argv[1:] if argv is None else argv)
        parser = build_parser(argv=words)
        args = parser.parse_args(words)
        _numba_cache_best_effort()
        args.argv = list(sys.argv[1:] if argv is None else argv)  # recorded by some outputs
        status: int = args.handler(args)
        sys.stdout.flush()
    except BrokenPipeError:
        # the reader closed the pipe: say nothing, and keep Python's exit-time flush quiet
        _stdout_to_devnull()
        return EXIT_PIPE
    except SystemExit as exc:  # argparse: usage errors (2, one line), --help and --version (0)
        return exc.code if isinstance(exc.code, int) else 2
    except FuzzyServoError as exc:
        return _error(str(exc))
    except MemoryError:
        return _error("out of memory; ask for less: a shorter or coarser run, a smaller "
                      "grid or population")
    except OSError as exc:
        # no room for a write to a stream, not to a named file (those are OutputErrors,
        # handled above): standard output's (what is left in its buffer goes nowhere, so
        # the exit stays quiet), else a temporary file's disk
        if exc.errno not in _NO_ROOM or exc.filename is not None:
            return _foreign(exc)
        if _stdout_is_full(exc):
            _stdout_to_devnull()
            return _error(f"cannot write standard output: {exc.strerror or 'no room'}")
        return _error(f"cannot write a temporary file: {exc.strerror or 'no room'} (free some "
                      f"space, or point TMPDIR at a disk that has it)")
    except Exception as exc:  # a library wrapped one of our errors, or an interruption
        return _foreign(exc)
    return status

