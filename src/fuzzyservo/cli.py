"""Command-line interface: ``fuzzyservo <command> ...``.

Each subcommand lives in ``fuzzyservo.commands.<name>`` and exposes ``register(subparsers)``,
which adds its parser and sets ``handler`` (a function ``(argparse.Namespace) -> int``).
Errors a user can cause (:class:`~fuzzyservo.errors.FuzzyServoError`) are printed on one line
and give exit status 2, without a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from .errors import FuzzyServoError

#: Subcommand modules, in the order ``--help`` lists them.
COMMANDS: tuple[str, ...] = (
    "metrics",
    "linearize",
    "simulate",
    "tune",
    "surface",
    "reproduce",
)


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
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name in COMMANDS:
        importlib.import_module(f"fuzzyservo.commands.{name}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with ``argv`` (default: ``sys.argv[1:]``) and return the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        status: int = args.handler(args)
    except FuzzyServoError as exc:
        message = " ".join(str(exc).split())
        print(f"fuzzyservo: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fuzzyservo: interrupted; results already written are kept", file=sys.stderr)
        return 130
    return status
