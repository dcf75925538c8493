"""Drive ``fuzzyservo app`` in Debian's headless Chromium (Selenium with the system's
ChromeDriver: browsers cannot be downloaded here). Used by tests/app/test_browser.py and by
benchmarks/app_latency.py.

The page's widgets carry CSS classes (``fs-gain-kp``, ``fs-metrics``, ...) on their Bokeh
models; :meth:`Page.model` finds a model by class, :meth:`Page.element` the element a user
would touch inside its view (Bokeh renders each view in its own shadow root).
"""

from __future__ import annotations

import contextlib
import html
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"

#: Chromium's flags: headless, and none of its own connections (background networking,
#: component updates, sync), which this machine's closed network refuses.
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-dev-shm-usage", "--window-size=1500,1000")

_JS = r"""
window.fs = {
  // the view of the model with CSS class cls that is on the page (a model replaced by a
  // newer one, e.g. the gain rows of another controller, has no view left)
  view(cls) {
    for (const v of Bokeh.index.all_views())
      if (v.model.css_classes && v.model.css_classes.includes(cls)) return v;
    return null;
  },
  model(cls) {
    const v = fs.view(cls);
    return v ? v.model : null;
  },
  named(name) {
    for (const doc of Bokeh.documents) { const m = doc.get_model_by_name(name); if (m) return m; }
    return null;
  },
};
"""


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def require_browser() -> None:
    """Fail (never skip) when Chromium or ChromeDriver is missing: `make browser` installs
    them, and `make test` runs it."""
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not Path(p).exists()]
    assert not missing, (f"{', '.join(missing)} missing: run 'make browser' (Debian's "
                         f"chromium and chromium-driver)")


@contextlib.contextmanager
def app_server(*args: str, timeout: float = 120.0,
               log: list[str] | None = None) -> Iterator[str]:
    """Start ``fuzzyservo app --no-browser`` on a free port; yield its URL (once it listens:
    the command prints it then); stop it. ``log`` gets the lines it printed."""
    port = free_port()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    exe = shutil.which("fuzzyservo", path=str(Path(sys.executable).parent)) or "fuzzyservo"
    proc = subprocess.Popen([exe, "app", "--no-browser", "--port", str(port), *args],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=env)
    url = None
    lines: list[str] = []
    deadline = time.monotonic() + timeout
    assert proc.stdout is not None
    try:
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            m = re.search(r"serving (http://\S+)", line)
            if m:
                url = m.group(1)
                break
        assert url is not None, "fuzzyservo app did not start:\n" + "".join(lines)
        yield url
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if log is not None:
            log.extend(lines)
            log.extend(proc.stdout.read().splitlines(keepends=True))


class Page:
    """A browser tab on the page, with helpers to act as a user and to read what it shows."""

    def __init__(self, url: str, *, width: int = 1500, height: int = 1000) -> None:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service

        require_browser()
        opts = webdriver.ChromeOptions()
        for flag in FLAGS:
            opts.add_argument(flag)
        opts.add_argument(f"--window-size={width},{height}")
        opts.binary_location = CHROMIUM
        opts.set_capability("goog:loggingPrefs", {"performance": "ALL", "browser": "ALL"})
        self.driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
        self.url = url
        self.driver.get(url)
        self.wait(lambda: self.js("return typeof Bokeh !== 'undefined' && "
                                  "Bokeh.documents.length > 0"), 60)
        self.driver.execute_script(_JS)
        self.wait_for_run(1, 60)

    def close(self) -> None:
        self.driver.quit()

    def __enter__(self) -> Page:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def js(self, code: str, *args: Any) -> Any:
        """Run ``code`` in the page (``fs`` helpers defined) and return its value."""
        return self.driver.execute_script(code, *args)

    def wait(self, cond: Any, timeout: float = 30.0, what: str = "") -> Any:
        deadline = time.monotonic() + timeout
        while True:
            value = cond()
            if value:
                return value
            if time.monotonic() > deadline:
                raise TimeoutError(f"timed out waiting for {what or cond}")
            # sleep: the condition is the page's state read by script; the driver has no
            # event for an arbitrary predicate, so it is polled until the deadline
            time.sleep(0.02)

    # -- reading
    def text(self, cls: str) -> str:
        """The text a pane shows (rendered, inside its view's shadow root)."""
        text = self.js("const v = fs.view(arguments[0]); if (!v) return null;"
                       "const root = v.shadow_el || v.el;"
                       "return Array.from(root.children)"
                       ".filter(c => !['STYLE', 'LINK'].includes(c.tagName))"
                       ".map(c => c.innerText || '').join(' ');",
                       cls)
        assert text is not None, f"no view with class {cls}"
        return str(text)

    def run_number(self) -> int:
        """Number of the request whose run the page shows (0: none yet)."""
        m = re.search(r"request (\d+): run", self.text("fs-status"))
        return int(m.group(1)) if m else 0

    def status(self) -> str:
        return " ".join(self.text("fs-status").split())

    def wait_for_run(self, after: int = 0, timeout: float = 120.0) -> int:
        """Wait until the page shows a run of a request numbered >= ``after`` and the
        status is settled; return its number.

        ``timeout`` bounds a wait for an event, not a speed: a run of a few ms is shown
        within a second on an idle machine, but in the full suite the other test worker, the
        page's server and headless Chromium share two cores, and a fresh clone's suite once
        waited over 30 s for the first run after a plant change (nothing is asserted on how
        long it takes)."""
        return int(self.wait(lambda: (n := self.run_number()) >= after and n, timeout,
                             f"a run numbered >= {after}"))

    def metrics(self, column: int = 0) -> dict[str, str]:
        """The metrics table as ``{name: "value unit"}`` for run column ``column`` (0: this
        run, 1..: pins), in the table's 6 significant digits."""
        raw = self.js("const m = fs.model('fs-metrics'); return m ? m.text : null;")
        try:
            raw = json.loads(raw)
        except (TypeError, ValueError):
            pass
        rows = re.findall(r"<tr><td>(\w+)</td>(.*?)<td>([^<]*)</td></tr>", html.unescape(raw))
        out = {}
        for name, cells, unit in rows:
            values = re.findall(r"<td[^>]*>([^<]*)</td>", cells)
            out[name] = f"{values[column]} {unit}"
        return out

    def error(self) -> str | None:
        """The error line shown, or None."""
        visible = self.js("const m = fs.model('fs-error'); return m ? m.visible : null;")
        if not visible:
            return None
        return " ".join(self.text("fs-error").split())

    def value(self, cls: str) -> Any:
        return self.js("return fs.model(arguments[0]).value;", cls)

    # -- acting
    def set_value(self, cls: str, value: Any) -> None:
        """Set a widget's value as the browser does when a user edits it."""
        self.js("fs.model(arguments[0]).value = arguments[1];", cls, value)

    def show_tab(self, index: int) -> None:
        """Show tab ``index`` of the page (0 response, 1 tuner, 2 fuzzy systems, 3 export),
        as a click on its header does."""
        self.js("fs.model('fs-tabs').active = arguments[0];", index)

    def click(self, cls: str) -> None:
        """Click a button (its model's click event, as the view sends it)."""
        self.js("const m = fs.model(arguments[0]); "
                "m.trigger_event(new (Bokeh.require('core/bokeh_events').ButtonClick)());",
                cls)

    def slider_handle(self, cls: str) -> Any:
        """The handle element of a slider, inside its view's shadow root."""
        return self.js(
            "const v = fs.view(arguments[0]);"
            "return v ? v.shadow_el.querySelector('.noUi-handle') : null;", cls)

    def requested_urls(self) -> list[str]:
        """Every URL the browser requested so far (from Chromium's performance log)."""
        urls = []
        for entry in self.driver.get_log("performance"):
            msg = json.loads(entry["message"])["message"]
            if msg["method"] == "Network.requestWillBeSent":
                urls.append(msg["params"]["request"]["url"])
            elif msg["method"] == "Network.webSocketCreated":
                urls.append(msg["params"]["url"])
        return urls

    def screenshot(self, path: str | Path) -> None:
        self.driver.save_screenshot(str(path))
