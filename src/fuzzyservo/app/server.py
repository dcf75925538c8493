"""The web server of ``fuzzyservo app``: Panel's (Tornado and Bokeh), bound to 127.0.0.1 unless
asked otherwise; every asset comes from it, so the page works offline. Every request passes
:class:`.access.Access`'s check (Host, Origin, token) before Bokeh sees it."""

from __future__ import annotations

import logging
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from ..formats.io import MAX_BYTES
from .access import Access, Admit, Refuse

__all__ = ["WEBSOCKET_MAX_MESSAGE_BYTES", "serve"]

log = logging.getLogger(__name__)

#: Largest message the page's WebSocket takes [bytes]: an upload of the file readers' limit
#: (:data:`fuzzyservo.formats.io.MAX_BYTES`, the page's ``MAX_UPLOAD_BYTES``) in base64 (4/3)
#: with 1 MiB for the message around it; a larger one closes the connection.
WEBSOCKET_MAX_MESSAGE_BYTES = 4 * (MAX_BYTES + 2) // 3 + 1024 * 1024


def _open(url: str) -> None:
    import webbrowser

    try:
        opened = webbrowser.open(url)
    except Exception:
        opened = False
    if not opened:
        print(f"fuzzyservo app: no browser to open here; open {url}", file=sys.stderr,
              flush=True)


def serve(access: Access, *, param_set: str = "paper", open_browser: bool = True,
          workdir: Path | None = None, ready: Any = None) -> None:
    """Serve the page until interrupted.

    Parameters
    ----------
    access : Access
        Where to listen and whom to answer (:func:`.access.access_for`): the Host headers,
        the page's origin and, when other machines are served, the token.
    param_set : str
        Parameter set the page starts with.
    open_browser : bool
        Open the page in the default browser.
    workdir : Path, optional
        Folder for uploaded fuzzy-system files (default: a new temporary folder).
    ready : callable, optional
        Called with the page's URL once the server listens.
    """
    url = access.url()
    print(f"fuzzyservo app: starting {url}", flush=True)

    import panel as pn

    from ..paper import named_set
    from .page import ServoPage
    from .settings import warm_up

    named_set(param_set)  # a bad name fails here, in one line
    # compile (or load from the cache) the loops beside the server: the page serves at once
    # and says it is warming up until its first run can be made (a cold cache: seconds)
    threading.Thread(target=warm_up, name="fuzzyservo-warm-up", daemon=True).start()
    folder = workdir or Path(tempfile.mkdtemp(prefix="fuzzyservo-app-"))

    def page() -> Any:
        return ServoPage(param_set=param_set, workdir=folder).view

    # Bokeh's own origin check, on the same names as the gate's (never '*')
    server = pn.serve({"/": page}, port=access.port, address=access.host,
                      websocket_origin=access.hosts(), show=False, start=False,
                      title="fuzzyservo: tune by looking", threaded=False,
                      check_unused_sessions=2000, unused_session_lifetime=15000,
                      websocket_max_message_size=WEBSOCKET_MAX_MESSAGE_BYTES)
    _gate(server, access)
    server.start()
    print(f"fuzzyservo app: serving {url} (Ctrl-C stops it)", flush=True)
    if access.others:
        print("fuzzyservo app: from other machines: "
              + ", ".join(access.url(name) for name in access.others), flush=True)
    if ready is not None:
        ready(url)
    if open_browser:
        # once the server is running: a browser command that waits for its window to close
        # ($BROWSER) must not hold the page's server
        server.io_loop.add_callback(
            lambda: threading.Thread(target=_open, args=(url,), daemon=True).start())
    try:
        server.io_loop.start()  # Panel's Ctrl-C handler stops the loop
    finally:
        server.stop()


def _gate(server: Any, access: Access) -> None:
    """Put :meth:`Access.check` in front of every route of the server (the page, its
    WebSocket, the static files, Panel's own routes): a Tornado rule ahead of the
    application's, which answers a refused request itself."""
    from tornado.routing import Matcher, Rule
    from tornado.web import RequestHandler

    class Gate(Matcher):
        def match(self, request: Any) -> dict[str, Any] | None:
            websocket = request.headers.get("Upgrade", "").lower() == "websocket"
            verdict = access.check(request.headers, request.uri or "/", websocket=websocket)
            if verdict is None and websocket:
                verdict = _bokeh_websocket(request.headers)
            return None if verdict is None else {"target_kwargs": {"verdict": verdict}}

    class Gatekeeper(RequestHandler):
        verdict: Refuse | Admit

        def initialize(self, verdict: Refuse | Admit) -> None:
            self.verdict = verdict

        def prepare(self) -> None:
            v = self.verdict
            if isinstance(v, Admit):
                self.set_header("Set-Cookie", v.cookie)
                self.set_header("Cache-Control", "no-store")
                self.redirect(v.location)
                return
            log.warning("refused %s %s from %s: %s", self.request.method,
                        self.request.path, self.request.remote_ip, v.reason)
            self.set_status(v.status)
            self.set_header("Content-Type", "text/plain; charset=utf-8")
            self.finish(f"fuzzyservo app: refused: {v.reason}\n")

    # the application's own router (Tornado's Application.default_router): Bokeh's Server
    # exposes its Tornado application only as _tornado
    server._tornado.default_router.rules.insert(0, Rule(Gate(), Gatekeeper))


def _bokeh_websocket(headers: Any) -> Refuse | None:
    """Refuse a WebSocket that Bokeh would refuse with a traceback in the log: one without
    Bokeh's subprotocol and a readable, unexpired session token."""
    from bokeh.util.token import get_token_payload

    offered = [p.strip() for p in headers.get("Sec-WebSocket-Protocol", "").split(",")]
    if len(offered) != 2 or offered[0] != "bokeh" or not offered[1]:
        return Refuse(400, "the page's WebSocket speaks Bokeh's protocol "
                           "(Sec-WebSocket-Protocol: bokeh, <session token>)")
    try:
        expiry = float(get_token_payload(offered[1])["session_expiry"])
    except Exception:
        return Refuse(400, "the WebSocket's session token cannot be read")
    if time.time() >= expiry:  # Bokeh's own test, which would end in a traceback
        return Refuse(403, "the session has expired: reload the page")
    return None
