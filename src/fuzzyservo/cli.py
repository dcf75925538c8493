"""Command-line interface: ``fuzzyservo <command> ...``.

Each subcommand lives in ``fuzzyservo.commands.<name>`` and exposes ``register(subparsers)``,
which adds its parser and sets ``handler`` (a function ``(argparse.Namespace) -> int``).
Errors a user can cause (:class:`~fuzzyservo.errors.FuzzyServoError`) are printed on one line
and give exit status 2, without a traceback. A reader that closes the pipe early
(``fuzzyservo linearize | head -1``) ends the command quietly with status 141, the status of a
process ended by SIGPIPE, as other command-line tools do.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from . import __version__
from .errors import FuzzyServoError

#: Subcommand modules, in the order ``--help`` lists them.
COMMANDS: tuple[str, ...] = (
    "simulate",
    "plot",
    "metrics",
    "tune",
    "linearize",
    "surface",
    "reproduce",
)

#: Exit status after the reader of standard output went away (128 + SIGPIPE).
EXIT_PIPE = 141


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors exit with status 2 on one line."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every registered subcommand."""
    parser = _Parser(
        prog="fuzzyservo",
        description="Electro-hydraulic servo models and fuzzy / PID control (Aly et al., 2012).",
    )
    parser.add_argument("--version", action="version", version=f"fuzzyservo {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name in COMMANDS:
        importlib.import_module(f"fuzzyservo.commands.{name}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with ``argv`` (default: ``sys.argv[1:]``) and return the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        status: int = args.handler(args)
        sys.stdout.flush()
    except BrokenPipeError:
        # the reader closed the pipe: say nothing, and keep Python's exit-time flush quiet
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        return EXIT_PIPE
    except SystemExit as exc:  # argparse: usage errors (2, one line), --help and --version (0)
        return exc.code if isinstance(exc.code, int) else 2
    except FuzzyServoError as exc:
        message = " ".join(str(exc).split())
        print(f"fuzzyservo: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fuzzyservo: interrupted; results already written are kept", file=sys.stderr)
        return 130
    return status
