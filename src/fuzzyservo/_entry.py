"""Entry point of the ``fuzzyservo`` command and of ``python -m fuzzyservo``.

Kept apart from ``fuzzyservo.cli`` so that it needs no import of its own: Ctrl-C while the CLI
and its libraries are being imported is caught here and ends on the same one line as
everywhere else (``fuzzyservo.cli.main`` handles it from then on). The first tens of
milliseconds, before this module runs, belong to the interpreter.

The process then ends at once with ``os._exit``, once standard output and error are flushed
(every file is complete or rolled back by then): a Ctrl-C that lands in the interpreter's own
shutdown would otherwise kill it with SIGINT after its work was done and its status decided
(seen in review: status -2 instead of 0 or 130, with nothing on stderr).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys

from .errors import INTERRUPTED  # already imported with the package: costs nothing


def run() -> None:
    """Run the CLI with ``sys.argv`` and end the process with its status."""
    try:
        from .cli import main

        status = main()
    except KeyboardInterrupt:  # while importing the CLI
        print(INTERRUPTED, file=sys.stderr)
        status = 130
    with contextlib.suppress(ValueError):  # ValueError: not the main thread
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):  # a closed pipe: main already said nothing
            stream.flush()
    os._exit(status)
