"""``fuzzyservo app``: a local browser page where the step response follows the sliders."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..errors import InputError, ParameterError
from ..paper.published import SET_NAMES
from . import HELP

__all__ = ["DEFAULT_PORT", "register", "run"]

#: Port of the page when ``--port`` is not given (Bokeh's and Panel's).
DEFAULT_PORT = 5006


def register(subparsers: Any) -> None:
    """Add the ``app`` subcommand to ``subparsers`` and set its handler."""
    p = subparsers.add_parser(
        "app", help=HELP["app"],
        description=(
            "Serve a page on this machine where the controller's gains, the plant and the "
            "reference are sliders and the step response, command and alpha are redrawn as "
            "they move; pin up to four runs, tune, see the fuzzy systems, download the gains, "
            "the run, the C code or the FMU, and copy the 'fuzzyservo simulate' command that "
            "reproduces the run (docs/app.md). Needs the 'app' extra (Panel)."))
    p.add_argument("--port", type=int, default=DEFAULT_PORT, metavar="N",
                   help=f"TCP port (default {DEFAULT_PORT})")
    p.add_argument("--set", dest="param_set", default="paper", metavar="NAME",
                   help=f"parameter set the page starts with: {', '.join(SET_NAMES)} "
                        f"(default paper)")
    p.add_argument("--no-browser", dest="browser", action="store_false",
                   help="print the page's address instead of opening it in a browser")
    p.add_argument("--host", default="127.0.0.1", metavar="ADDRESS",
                   help="address to listen on (default 127.0.0.1: this machine only; any "
                        "loopback address or name, e.g. localhost, is this machine only too); "
                        "another, e.g. 0.0.0.0 for every interface, serves other machines, with "
                        "a warning and a secret token in the page's address")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo app``."""
    if not 1 <= args.port <= 65535:
        raise ParameterError(f"--port must be in 1..65535, got {args.port}")
    if args.param_set not in SET_NAMES:
        raise ParameterError(f"--set {args.param_set!r}: unknown parameter set; allowed: "
                             f"{', '.join(SET_NAMES)}")
    from ..app.access import access_for

    access = access_for(args.host, args.port)
    try:
        import panel  # noqa: F401
    except ImportError:
        raise InputError("the page needs Panel: pip install 'fuzzyservo[app]'") from None
    from ..app.server import serve

    if not access.local:
        print(f"fuzzyservo: warning: --host {args.host}: the page is served to other "
              f"machines; it answers only requests with the token of the address printed "
              f"below, and whoever has that address can run the simulator and the tuner here "
              f"(plain HTTP: the network between can read it)", file=sys.stderr, flush=True)
    _port_free(access.host, args.port)
    try:
        serve(access, param_set=args.param_set, open_browser=args.browser)
    except KeyboardInterrupt:
        pass
    print("fuzzyservo app: stopped", file=sys.stderr)
    return 0


def _port_free(host: str, port: int) -> None:
    """One line, status 2, when the port is taken or the address is not this machine's
    (Tornado would end in a traceback)."""
    import errno
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as exc:
            if exc.errno == errno.EADDRNOTAVAIL:
                raise InputError(f"--host {host}: not an address of this machine "
                                 f"({exc.strerror}); give one of its addresses, 127.0.0.1 "
                                 f"or 0.0.0.0 (every interface)") from None
            raise InputError(f"--port {port}: cannot listen on {host}:{port} "
                             f"({exc.strerror or exc}); give another --port") from None
