"""The page of ``fuzzyservo app`` in a real browser (Debian's headless Chromium, Selenium):
a gain moved with the keyboard redraws the run, and the metrics shown are those of
``fuzzyservo simulate --metrics`` for the same settings, run as a separate process; two
pinned runs are drawn in their controllers' colours; a bad value shows the CLI's one line;
the tuner runs in the page; nothing is requested from any address but the local server."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlparse

import pytest
from selenium.webdriver.common.keys import Keys

from fuzzyservo.app.page import pin_colour
from fuzzyservo.files import read_gains_file
from tests.app.browser import Page, app_server, require_browser

EXE = str(Path(sys.executable).parent / "fuzzyservo")


@pytest.fixture(scope="module")
def url() -> Iterator[str]:
    require_browser()
    with app_server() as u:
        yield u


@pytest.fixture
def page(url: str) -> Iterator[Page]:
    with Page(url) as p:
        yield p


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([EXE, *args], capture_output=True, text=True, timeout=300)


def shown_metrics(text: str) -> dict[str, str]:
    """``simulate --metrics`` output as ``{name: "value unit"}``."""
    out = {}
    for line in text.splitlines():
        name, value, unit = line.split()
        out[name] = f"{value} {unit}"
    return out


def settle(page: Page, quiet: float = 0.6, timeout: float = 30.0) -> int:
    """Wait until the run shown has not changed for ``quiet`` seconds; its number."""
    deadline = time.monotonic() + timeout
    last, since = page.run_number(), time.monotonic()
    while time.monotonic() < deadline:
        # sleep: polling the run shown; 'no redraw for `quiet` s' has no event to wait on
        time.sleep(0.05)
        n = page.run_number()
        if n != last:
            last, since = n, time.monotonic()
        elif time.monotonic() - since >= quiet:
            return n
    raise TimeoutError("the page kept redrawing")


def change(page: Page, cls: str, value: object) -> int:
    """Set a widget as a user would, wait for the run it starts and for the page to settle;
    the number of the run shown."""
    n = page.run_number()
    page.set_value(cls, value)
    page.wait_for_run(n + 1)
    return settle(page)


def live_y(page: Page) -> list[float]:
    return page.js("return Array.from(fs.named('fs-live').data.y_mm);")


def gains_shown(page: Page, names: tuple[str, ...]) -> str:
    return ",".join(f"{n}={float(page.value(f'fs-gain-{n}'))!r}" for n in names)


@pytest.mark.parametrize("plant", ["linear", "nonlinear"])
def test_a_gain_moved_redraws_with_the_metrics_of_simulate(page: Page, plant: str) -> None:
    names = ("ke", "kde", "kdu")
    if plant == "nonlinear":
        change(page, "fs-plant", "nonlinear")
        # the physical changes a user tries first go into the same command
        change(page, "fs-phys-load.mass", 20000.0)
        change(page, "fs-phys-delay", 6.0)
    before_y = live_y(page)
    before = page.value("fs-gain-kdu")
    n = page.run_number()
    handle = page.slider_handle("fs-slider-kdu")
    for _ in range(3):
        handle.send_keys(Keys.ARROW_LEFT)
    page.wait_for_run(n + 1)
    settle(page)
    assert page.value("fs-gain-kdu") < before  # the slider moved the gain
    assert live_y(page) != before_y  # and the plot was redrawn
    argv = ["simulate", "--plant", plant, "--controller", "stfpi", "--gains",
            gains_shown(page, names), "--reference", "step:0.1", "--duration", "5"]
    if plant == "nonlinear":
        argv += ["--param", "load.mass=20000.0", "--delay", "0.006"]
    done = cli(*argv, "--metrics")
    assert done.returncode == 0, done.stderr
    want = shown_metrics(done.stdout)
    assert page.metrics() == want
    assert page.error() is None
    # the command the page offers to copy prints the same
    command = page.value("fs-command")
    assert command.startswith("fuzzyservo simulate ")
    again = cli(*shlex.split(command)[1:])
    assert again.returncode == 0, again.stderr
    assert shown_metrics(again.stdout) == want


def test_two_pinned_runs_are_drawn_in_the_study_colours(page: Page) -> None:
    page.click("fs-pin")
    n0 = page.run_number()
    page.set_value("fs-controller", "pid")
    page.wait_for_run(n0 + 1)
    n = settle(page)
    assert page.value("fs-gain-kp") is not None
    page.click("fs-pin")
    page.wait(lambda: page.js("return fs.named('fs-pin-1').data.t.length") > 0, 20,
              "the second pin")
    drawn = page.js("""
        const out = [];
        for (const m of Bokeh.documents[0].all_models) {
          if (m.type !== 'GlyphRenderer' && !(m.data_source && m.glyph)) continue;
          const n = m.data_source.name;
          if (n && n.startsWith('fs-pin-') && m.visible && m.glyph.y
              && m.glyph.y.field === 'y_mm')
            out.push([n, m.glyph.line_color.value ?? m.glyph.line_color,
                      m.data_source.data.y_mm.length,
                      Array.from(m.data_source.data.y_mm).slice(-1)[0]]);
        }
        return out.sort();""")
    assert [(d[0], d[1], d[2]) for d in drawn] == [
        ("fs-pin-0", pin_colour("stfpi"), 5001), ("fs-pin-1", pin_colour("pid"), 5001)]
    assert drawn[0][3] != drawn[1][3]  # two different runs
    metrics = [page.metrics(c) for c in (0, 1, 2)]
    assert metrics[1] != metrics[2] and metrics[0] == metrics[2]
    assert page.run_number() == n


def test_an_invalid_value_shows_the_cli_line(page: Page) -> None:
    names = ("ke", "kde", "kdu")
    n = page.run_number()
    page.set_value("fs-gain-kdu", -0.5)
    page.wait(lambda: page.error(), 20, "the error line")
    done = cli("simulate", "--plant", "linear", "--controller", "stfpi", "--gains",
               gains_shown(page, names), "--reference", "step:0.1", "--duration", "5",
               "--metrics")
    assert done.returncode == 2
    assert page.error() == done.stderr.strip()
    assert page.error() == "fuzzyservo: error: gain kdu must be finite and >= 0, got -0.5"
    page.set_value("fs-gain-kdu", 0.01)
    page.wait(lambda: page.error() is None, 20, "the error to clear")
    page.set_value("fs-spec", "step:0.1:x")
    page.wait(lambda: page.error(), 20, "the error line")
    done = cli("simulate", "--plant", "linear", "--controller", "stfpi", "--gains",
               gains_shown(page, names), "--reference", "step:0.1:x", "--metrics")
    assert page.error() == done.stderr.strip() != ""
    body = page.js("return document.body.innerText")
    assert "Traceback" not in body
    assert "not run" in page.status() and n >= 1


def test_stale_requests_are_dropped_and_the_last_is_shown(page: Page) -> None:
    # runs of 20 s on the nonlinear plant (several ms each), edits 1 ms apart: faster than
    # the runs, as a fast drag sends them (one message each: edits made in one task of the
    # browser's would reach the server as one). Synchronised on conditions, not on time:
    # the page is done when it shows the run of the last edit's gains (its metrics are the
    # command's), and every request is then accounted for. How many are dropped depends on
    # how the edits and the runs interleave (on the machine's load), so it is not asserted
    # here: tests/app/test_latest.py holds the dropping to its counts deterministically.
    change(page, "fs-plant", "nonlinear")
    first = change(page, "fs-duration", 20.0)
    last = 0.02 + 0.0002 * 40
    done = cli("simulate", "--plant", "nonlinear", "--controller", "stfpi", "--gains",
               f"ke={float(page.value('fs-gain-ke'))!r},kde={float(page.value('fs-gain-kde'))!r},"
               f"kdu={last!r}", "--reference", "step:0.1", "--duration", "20", "--metrics")
    assert done.returncode == 0, done.stderr
    want = shown_metrics(done.stdout)
    assert page.metrics() != want
    page.js("const m = fs.model('fs-gain-kdu'); window.fs_edits = 0;"
            "for (let i = 1; i <= 40; i++) setTimeout(() => {"
            " m.value = 0.02 + 0.0002 * i; window.fs_edits++; }, i);")
    page.wait(lambda: page.js("return window.fs_edits") == 40, 60, "the 40 edits")
    assert page.value("fs-gain-kdu") == last
    page.wait(lambda: page.metrics() == want, 120, "the run of the last edit")
    status = page.status()
    seq, ran, dropped = (int(x) for x in re.search(
        r"request (\d+): run .* (\d+) runs, (\d+) stale", status).groups())
    # the edits reached the server as requests (Panel merges those that arrive together),
    # and each request since the page opened was either run or dropped before its run
    assert seq > first and seq == ran + dropped, status
    assert page.value("fs-gain-kdu") == last  # the last edit is the one shown


def test_the_tuner_runs_in_the_page_and_loads_its_gains(page: Page, tmp_path: Path) -> None:
    change(page, "fs-controller", "pi")
    page.set_value("fs-maxiter", 4)
    page.set_value("fs-restarts", 1)
    page.click("fs-tune")
    page.wait(lambda: "tuned:" in page.text("fs-tune-status"), 240, "the tuner")
    settle(page)
    shown = page.text("fs-tune-status")
    argv = shlex.split(page.text("fs-tune-command"))[1:]
    assert argv[-2:] == ["--out", "gains.toml"]
    out = tmp_path / "gains.toml"
    done = cli(*argv[:-1], str(out), "--quiet")
    assert done.returncode in (0, 1), done.stderr
    tuned = read_gains_file(out).gains
    for name in ("kp", "ki"):
        assert page.value(f"fs-gain-{name}") == tuned[name], shown
    assert page.js("return fs.model('fs-tune-progress').value") == 1000


def test_a_tuning_that_ends_on_another_controller_is_not_loaded(page: Page) -> None:
    page.show_tab(1)
    page.set_value("fs-maxiter", 10)
    page.set_value("fs-restarts", 1)
    page.click("fs-tune")
    change(page, "fs-controller", "fpi")
    fpi = [page.value(f"fs-gain-{n}") for n in ("ke", "kde", "kdu")]
    page.wait(lambda: "has ended" in page.text("fs-tune-status"), 240, "the tuner")
    assert "the tuning of stfpi on the linear plant has ended, but the page now shows fpi" in \
        page.text("fs-tune-status")
    assert [page.value(f"fs-gain-{n}") for n in ("ke", "kde", "kdu")] == fpi


def test_no_request_leaves_the_local_server(page: Page) -> None:
    change(page, "fs-controller", "pid2")
    change(page, "fs-spec", "sine:0.05:0.5")
    page.click("fs-pin")
    change(page, "fs-plant", "nonlinear")
    change(page, "fs-controller", "stfpi")
    for tab in (1, 2, 3, 0):  # the tuner, the fuzzy systems (figures), the downloads
        page.show_tab(tab)
        # sleep: the test looks for requests a tab might make; their absence has no event
        time.sleep(0.5)
    page.wait(lambda: page.js("return fs.view('fs-dl-gains') !== null"), 20, "the tabs")
    origin = urlparse(page.url).netloc
    urls = page.requested_urls()
    assert any(u.startswith("ws://") for u in urls)
    outside = [u for u in urls if urlparse(u).scheme not in ("data", "blob")
               and urlparse(u).netloc != origin]
    assert not outside, outside
    assert len([u for u in urls if urlparse(u).netloc == origin]) > 10


def download(page: Page, cls: str, folder: Path, timeout: float = 60.0) -> Path:
    """Click a download button as a user does; the file the browser saved in ``folder``."""
    page.driver.execute_cdp_cmd("Page.setDownloadBehavior",
                                {"behavior": "allow", "downloadPath": str(folder)})
    page.show_tab(3)
    def shown() -> object:
        b = page.js("const v = fs.view(arguments[0]);"
                    "return v ? v.shadow_el.querySelector('button') : null;", cls)
        return b if b is not None and b.is_displayed() else None

    button = page.wait(shown, 20, cls)
    before = set(folder.iterdir())
    button.click()

    def saved() -> Path | None:
        new = [f for f in set(folder.iterdir()) - before if not f.name.endswith(".crdownload")]
        return new[0] if new else None

    return Path(page.wait(saved, timeout, f"the download of {cls}"))


def test_the_downloads_are_what_the_commands_read_and_write(page: Page,
                                                            tmp_path: Path) -> None:
    change(page, "fs-controller", "fpi")
    change(page, "fs-phys-supply.pressure", 80.0)
    names = ("ke", "kde", "kdu")
    argv = ["--plant", "linear", "--reference", "step:0.1", "--duration", "5",
            "--param", "supply.pressure=8000000.0"]
    gains = download(page, "fs-dl-gains", tmp_path)
    assert gains.suffix == ".toml"
    done = cli("simulate", "--gains", str(gains), *argv, "--metrics")
    assert done.returncode == 0, done.stderr
    assert page.metrics() == shown_metrics(done.stdout)
    assert read_gains_file(gains).controller == "fpi"
    run = download(page, "fs-dl-csv", tmp_path)
    want = tmp_path / "want.csv"
    done = cli("simulate", "--controller", "fpi", "--gains", gains_shown(page, names), *argv,
               "--out", str(want))
    assert done.returncode == 0, done.stderr
    assert run.read_bytes() == want.read_bytes()
    zipped = download(page, "fs-dl-c", tmp_path)
    # the command the files record, run in the download's folder, writes the same files
    done = subprocess.run([EXE, "export", "c", "--controller", "fpi", "--gains",
                           gains_shown(page, names), "--ts", "0.001", "--out", "fpi-c"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300)
    out = tmp_path / "fpi-c"
    assert done.returncode == 0, done.stderr
    import zipfile

    with zipfile.ZipFile(zipped) as z:
        got = {n: z.read(n).decode() for n in z.namelist()}
    want_files = {f.name: f.read_text() for f in out.iterdir()}
    assert sorted(got) == ["fpi.c", "fpi.h"]
    assert got == want_files
    # the Structured Text likewise: its block records the command, which writes the same bytes
    zipped = download(page, "fs-dl-st", tmp_path)
    assert zipped.name == "fpi-st.zip"
    command = ["export", "st", "--controller", "fpi", "--gains", gains_shown(page, names),
               "--ts", "0.001", "--out", "fpi-st"]
    done = subprocess.run([EXE, *command], capture_output=True, text=True, cwd=tmp_path,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    with zipfile.ZipFile(zipped) as z:
        st_files = {n: z.read(n) for n in z.namelist()}
    assert sorted(st_files) == ["fpi_ctl.st", "fpi_ctl_example.st"]
    assert f"command:     fuzzyservo {shlex.join(command)}\n" in st_files["fpi_ctl.st"].decode()
    assert st_files == {f.name: f.read_bytes() for f in (tmp_path / "fpi-st").iterdir()}
    # the FMU: built by the C compiler, read by FMPy, its gains are the page's
    from fmpy import read_model_description

    fmu = download(page, "fs-dl-fmu", tmp_path, timeout=120)
    assert fmu.suffix == ".fmu"
    md = read_model_description(str(fmu))
    starts = {v.name: v.start for v in md.modelVariables}
    for name in names:
        assert float(starts[name]) == float(page.value(f"fs-gain-{name}"))


def test_a_fuzzy_system_from_a_file_runs_as_the_command_with_that_file(page: Page) -> None:
    change(page, "fs-controller", "fpi")
    page.show_tab(2)
    source = Path(__file__).resolve().parents[2] / "src/fuzzyservo/data/systems/paper-du.fis"
    field = page.wait(lambda: page.js(
        "const v = fs.view('fs-du-file');"
        "return v ? v.shadow_el.querySelector('input[type=file]') : null;"), 20, "the input")
    n = page.run_number()
    field.send_keys(str(source))
    page.wait_for_run(n + 1)
    settle(page)
    command = page.value("fs-command")
    argv = shlex.split(command)
    used = Path(argv[argv.index("--du-system") + 1])
    assert used.name == "paper-du.fis" and used.read_bytes() == source.read_bytes()
    done = cli(*argv[1:])
    assert done.returncode == 0, done.stderr
    assert page.metrics() == shown_metrics(done.stdout)
    # the systems tab shows the file's system and its rules
    page.wait(lambda: "paper-du.fis" in page.js(
        "return Array.from(Bokeh.index.all_views()).map(v => v.model.text || '').join(' ')"),
        30, "the file's system in the tab")


def test_an_upload_over_the_readers_limit_or_of_another_kind_is_one_line(
        page: Page, tmp_path: Path) -> None:
    from fuzzyservo.formats.io import MAX_BYTES

    change(page, "fs-controller", "fpi")

    def upload(path: Path) -> str:
        """Choose ``path`` in the systems tab; the error line the response tab then shows
        (the tabs' contents are made when shown: read each on its own tab)."""
        before = page.js("const m = fs.model('fs-error'); return m ? m.text : null;")
        page.show_tab(2)
        field = page.wait(lambda: page.js(
            "const v = fs.view('fs-du-file');"
            "return v ? v.shadow_el.querySelector('input[type=file]') : null;"), 20,
            "the input")
        field.send_keys(str(path))
        page.show_tab(0)
        return str(page.wait(lambda: page.js(
            "const m = fs.model('fs-error'); return m ? m.text : null;") != before
            and page.error(), 120, f"the error line of {path.name}"))

    source = Path(__file__).resolve().parents[2] / "src/fuzzyservo/data/systems/paper-du.fis"
    other = tmp_path / "du.txt"
    other.write_bytes(source.read_bytes())
    assert upload(other) == ("fuzzyservo: error: cannot tell the format of 'du.txt' from its "
                             "extension: use .fis, .fcl or .fll")
    # one byte over the command's limit: the page's WebSocket takes it (in base64, larger
    # than Bokeh's default 20 MB message) and the page refuses it before keeping it
    big = tmp_path / "big.fis"
    big.write_bytes(b"%" * (MAX_BYTES + 1))
    assert upload(big) == (f"fuzzyservo: error: uploaded file big.fis: {MAX_BYTES + 1} bytes "
                           f"is larger than the {MAX_BYTES}-byte limit")
    assert "--du-system" not in page.value("fs-command")  # still the paper's system
    assert "Traceback" not in page.js("return document.body.innerText")
