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
                   help="address to listen on (default 127.0.0.1: this machine only); "
                        "another lets other machines run the simulator, with a warning")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo app``."""
    if not 1 <= args.port <= 65535:
        raise ParameterError(f"--port must be in 1..65535, got {args.port}")
    if args.param_set not in SET_NAMES:
        raise ParameterError(f"--set {args.param_set!r}: unknown parameter set; allowed: "
                             f"{', '.join(SET_NAMES)}")
    if ":" in args.host:
        raise ParameterError(f"--host {args.host}: an IPv6 address cannot be served (Bokeh's "
                             f"server checks the page's origin by host:port); give an IPv4 "
                             f"address or a name, e.g. 127.0.0.1")
    try:
        import panel  # noqa: F401
    except ImportError:
        raise InputError("the page needs Panel: pip install 'fuzzyservo[app]'") from None
    from ..app.server import LOCAL_HOSTS, serve

    if args.host not in LOCAL_HOSTS:
        print(f"fuzzyservo: warning: --host {args.host}: the page is served to other "
              f"machines, with no password; anyone who reaches port {args.port} can run "
              f"the simulator and the tuner here", file=sys.stderr, flush=True)
    _port_free(args.host, args.port)
    try:
        serve(port=args.port, host=args.host, param_set=args.param_set,
              open_browser=args.browser)
    except KeyboardInterrupt:
        print("fuzzyservo app: stopped", file=sys.stderr)
        return 0
    return 0


def _port_free(host: str, port: int) -> None:
    """One line, status 2, when the port is taken (Tornado would end in a traceback)."""
    import socket

    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as exc:
            raise InputError(f"--port {port}: cannot listen on {host}:{port} "
                             f"({exc.strerror}); give another --port") from None
