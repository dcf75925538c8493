"""``fuzzyservo reproduce --out DIR``: write the paper's figures that exist so far.

For now: the membership functions and the two control surfaces of Fig. 3 (PNG). The full
study (Figs. 4-8) will be added here; each figure is one compute-then-render function in
``fuzzyservo.plots``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..paper import alpha_system, du_system
from ..plots.figures import fig3

__all__ = ["register", "run"]


def register(subparsers: Any) -> None:
    """Add the ``reproduce`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "reproduce",
        help="write the paper's figures into a directory",
        description="Write the paper's figures (Fig. 3: membership functions and control "
                    "surfaces) as PNG files into --out.",
    )
    parser.add_argument("--out", type=Path, default=Path("results"), metavar="DIR",
                        help="output directory (default: results)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo reproduce``."""
    out: Path = args.out
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {str(out)!r} exists and is not a directory")
    try:
        written = fig3(du_system(), alpha_system(), out)
    except OSError as exc:
        raise InputError(f"cannot write into {str(out)!r}: {exc.strerror or exc}") from exc
    for path in written:
        print(path)
    return 0
