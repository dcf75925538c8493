"""The local web server of ``fuzzyservo app``: Panel's (Tornado and Bokeh), bound to
127.0.0.1 unless asked otherwise; every asset comes from it, so the page works offline."""

from __future__ import annotations

import sys
import tempfile
import threading
from pathlib import Path
from typing import Any

__all__ = ["LOCAL_HOSTS", "serve"]

#: Addresses that reach only this machine.
LOCAL_HOSTS = ("127.0.0.1", "localhost")


def _open(url: str) -> None:
    import webbrowser

    try:
        opened = webbrowser.open(url)
    except Exception:
        opened = False
    if not opened:
        print(f"fuzzyservo app: no browser to open here; open {url}", file=sys.stderr,
              flush=True)


def serve(*, port: int, host: str = "127.0.0.1", param_set: str = "paper",
          open_browser: bool = True, workdir: Path | None = None,
          ready: Any = None) -> None:
    """Serve the page until interrupted.

    Parameters
    ----------
    port : int
        TCP port.
    host : str
        Address to listen on; another than :data:`LOCAL_HOSTS` lets other machines in (the
        command warns).
    param_set : str
        Parameter set the page starts with.
    open_browser : bool
        Open the page in the default browser.
    workdir : Path, optional
        Folder for uploaded fuzzy-system files (default: a new temporary folder).
    ready : callable, optional
        Called with the page's URL once the server listens.
    """
    local = host in LOCAL_HOSTS
    shown = "127.0.0.1" if host in ("127.0.0.1", "localhost") else host
    url = f"http://{shown if ':' not in shown else f'[{shown}]'}:{port}/"
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

    origins = [f"127.0.0.1:{port}", f"localhost:{port}"] if local else ["*"]
    server = pn.serve({"/": page}, port=port, address=host, websocket_origin=origins,
                      show=False, start=False, title="fuzzyservo: tune by looking",
                      threaded=False, check_unused_sessions=2000,
                      unused_session_lifetime=15000)
    server.start()
    print(f"fuzzyservo app: serving {url} (Ctrl-C stops it)", flush=True)
    if ready is not None:
        ready(url)
    if open_browser:
        # once the server is running: a browser command that waits for its window to close
        # ($BROWSER) must not hold the page's server
        server.io_loop.add_callback(
            lambda: threading.Thread(target=_open, args=(url,), daemon=True).start())
    try:
        server.io_loop.start()
    finally:
        server.stop()
