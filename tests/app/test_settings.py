"""The page's settings are a ``fuzzyservo simulate`` command line: its run and metrics are
the command's, for every controller of the registry and both plant models."""

from __future__ import annotations

import contextlib
import html
import io
import shlex
import socket
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from fuzzyservo.app import PageSettings, error_line, run_page
from fuzzyservo.app.settings import default_gains
from fuzzyservo.cli import main
from fuzzyservo.registry import controller_kind, controller_names
from tests.app.browser import free_port

EXE = str(Path(sys.executable).parent / "fuzzyservo")


def printed(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


def as_printed(metrics: dict[str, float]) -> dict[str, str]:
    return {k: f"{v:.6g}" for k, v in metrics.items()}


@pytest.mark.parametrize("plant", ["linear", "small-signal", "nonlinear"])
@pytest.mark.parametrize("controller", controller_names())
def test_the_run_is_the_commands(controller: str, plant: str) -> None:
    s = PageSettings(controller=controller, plant=plant, gains=default_gains(controller, plant),
                     overrides=(("load.mass", 12000.0),), delay=0.004, noise_std=2e-6,
                     seed=3, reference="step:0.05", duration=3.0)
    assert [g for g, _ in s.gains] == list(controller_kind(controller).gain_names)
    run = run_page(s)
    argv = shlex.split(s.command())
    assert argv[:2] == ["fuzzyservo", "simulate"]
    status, out, err = printed(argv[1:])
    assert status == 0, err
    shown = {ln.split()[0]: ln.split()[1] for ln in out.splitlines()}
    assert shown == as_printed(run.metrics)
    assert run.t.size == 3001 and run.r[-1] == pytest.approx(0.55, abs=1e-12)


@pytest.mark.parametrize("controller, plant, file", [
    ("p", "small-signal", "linear-pid"), ("pi", "nonlinear", "nonlinear-pid"),
    ("pid2", "linear", "linear-pid2"), ("stfpi", "small-signal", "linear-stfpi")])
def test_a_controller_starts_from_the_shipped_gains_the_registry_names(
        controller: str, plant: str, file: str) -> None:
    """The page starts each kind from shipped tuned gains; which file is the registry's
    choice (ControllerKind.start_gains, PlantKind.start_gains), not the page's."""
    import tomllib
    from importlib import resources

    folder = Path(str(resources.files("fuzzyservo") / "data" / "gains"))
    shipped = tomllib.loads((folder / f"{file}.toml").read_text())["gains"]
    gains = dict(default_gains(controller, plant))
    assert gains == {g: float(shipped[g]) for g in controller_kind(controller).gain_names}


def test_gains_and_values_reach_the_command_exactly() -> None:
    s = PageSettings(controller="pid", gains=(("kp", 0.1 + 0.2), ("ki", 1e-300),
                                              ("kd", 0.0), ("n", float("inf"))))
    argv = s.argv()
    assert "kp=0.30000000000000004,ki=1e-300,kd=0.0,n=inf" in argv


@pytest.mark.parametrize("change, needle", [
    ({"gains": (("kp", -1.0),)}, "fuzzyservo: error: gain kp must be finite and >= 0"),
    ({"reference": "sine:0.1"}, "fuzzyservo: error: reference 'sine:0.1'"),
    ({"duration": float("nan")}, "fuzzyservo"),
    ({"overrides": (("load.mass", 0.0),)}, "fuzzyservo: error: "),
    ({"start": 1.5}, "fuzzyservo: error: --start must be a fraction of the stroke"),
])
def test_a_bad_value_is_the_clis_line(change: dict[str, object], needle: str) -> None:
    fields: dict[str, object] = {"controller": "p", "gains": (("kp", 10.0),), **change}
    s = PageSettings(**fields)  # type: ignore[arg-type]
    with pytest.raises(Exception) as info:
        run_page(s)
    line = error_line(info.value)
    assert line.startswith(needle)
    status, _, err = printed(shlex.split(s.command())[1:])
    assert status == 2 and err.strip() == line


def test_numbers_go_as_flag_value_so_a_negative_one_is_named() -> None:
    s = PageSettings(controller="p", gains=(("kp", 10.0),), noise_std=-1e-6)
    assert "--noise-std=-1e-06" in s.argv()
    with pytest.raises(Exception) as info:
        run_page(s)
    assert error_line(info.value) == "fuzzyservo: error: noise_std must be a finite real " \
                                     "number >= 0 [m], got -1e-06"


def test_engineering_units_shift_the_decimal_point() -> None:
    from fuzzyservo.app import PHYSICAL

    noise = next(p for p in PHYSICAL if p.key == "noise_std")
    assert noise.to_si(2.5) == 2.5e-6 != 2.5 * 1e-6
    assert noise.from_si(2.5e-6) == 2.5
    pressure = next(p for p in PHYSICAL if p.key == "supply.pressure")
    assert pressure.to_si(70.0) == 7e6 and pressure.from_si(7e6) == 70.0


def test_the_page_refuses_a_run_too_long_to_draw_in_one_line() -> None:
    from fuzzyservo.app.settings import MAX_PAGE_SAMPLES

    s = PageSettings(controller="p", gains=(("kp", 10.0),), duration=1000.0)
    with pytest.raises(Exception) as info:
        run_page(s)
    assert error_line(info.value) == (
        f"fuzzyservo: error: the page draws at most {MAX_PAGE_SAMPLES:,} samples per run; "
        f"duration / sample time is 1,000,000: shorten the run or run it with the command")


def test_the_paper_systems_read_from_files_run_as_the_paper_systems() -> None:
    import tempfile

    from fuzzyservo.paper import write_system_files

    with tempfile.TemporaryDirectory() as d:
        files = {p.stem: p for p in write_system_files(d)}
        du = next(p for n, p in files.items() if "du" in n)
        s = PageSettings(controller="fpi", gains=default_gains("fpi", "linear"))
        with_file = PageSettings(controller="fpi", gains=s.gains, systems=(("du", str(du)),))
        assert f"--du-system {du}" in with_file.command()
        # the general engine evaluates the file's system; the paper's own kernel agrees to
        # rounding (tests/fuzzy hold the engines to each other)
        got, want = run_page(with_file).metrics, run_page(s).metrics
        assert got == pytest.approx(want, rel=1e-9, abs=1e-15)


def test_the_command_refuses_a_bad_port_or_set_in_one_line() -> None:
    for argv, needle in ((["app", "--port", "0"], "--port must be in 1..65535"),
                         (["app", "--set", "nope"], "unknown parameter set"),
                         (["app", "--host", "::1"], "an IPv6 address cannot be served")):
        status, _, err = printed(argv)
        assert status == 2 and needle in err and len(err.strip().splitlines()) == 1


def test_a_port_in_use_is_one_line() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        status, _, err = printed(["app", "--no-browser", "--port", str(port)])
    assert status == 2
    assert err.startswith(f"fuzzyservo: error: --port {port}: cannot listen on 127.0.0.1")


def test_another_host_is_served_with_a_warning() -> None:
    port = free_port()
    proc = subprocess.Popen([EXE, "app", "--no-browser", "--port", str(port), "--host",
                             "0.0.0.0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()
        assert line.startswith("fuzzyservo: warning: --host 0.0.0.0: the page is served to "
                               "other machines")
    finally:
        proc.terminate()
        proc.wait(20)


@pytest.mark.parametrize("plant", ["linear", "nonlinear"])
def test_the_load_force_is_in_the_run_and_its_command(plant: str) -> None:
    """The page's load force is the run's field: its command line carries it, reads back to
    the same run, and prints the page's metrics."""
    from fuzzyservo.run import RunSpec

    s = PageSettings(controller="pi", plant=plant, gains=(("kp", 10.0), ("ki", 2.0)),
                     load_force="step:1500:0.5", duration=1.0)
    assert "--load-force=step:1500:0.5" in s.argv()
    assert RunSpec.from_argv(s.argv()) == s.run
    run = run_page(s)
    status, out, err = printed(shlex.split(s.command())[1:])
    assert status == 0, err
    assert {ln.split()[0]: ln.split()[1] for ln in out.splitlines()} == as_printed(run.metrics)
    plain = run_page(s.replace(load_force=""))
    assert plain.metrics != run.metrics


def test_the_page_reads_its_load_force_box(tmp_path: Path) -> None:
    """The page's text box is the run's load force (a page built without a browser)."""
    from fuzzyservo.app.page import ServoPage

    page = ServoPage(workdir=tmp_path)
    page.w_load.value = " step:-300:0.2 "
    assert page.read_settings().load_force == "step:-300:0.2"
    assert "--load-force=step:-300:0.2" in page.w_command.value


def _zip_files(buf: io.BytesIO | None) -> dict[str, bytes]:
    assert buf is not None
    with zipfile.ZipFile(buf) as z:
        return {n: z.read(n) for n in z.namelist()}


def test_the_structured_text_download_is_what_its_command_writes(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The page's Structured Text zip (a page built without a browser) holds the two files of
    ``export st``; the block records that command with the download's name, and the command,
    run in the download's folder, writes the same bytes. The self-tuning kind, with a gain
    moved, so both rule tables and the page's gains travel."""
    from fuzzyservo.app.page import ServoPage

    page = ServoPage(workdir=tmp_path / "page")
    page.w_controller.value = "stfpi"
    page.gain_rows["ke"].box.value = 20.5
    got = _zip_files(page._st_file())
    assert page.d_st.filename == "stfpi-st.zip"
    assert sorted(got) == ["stfpi_ctl.st", "stfpi_ctl_example.st"]
    block = got["stfpi_ctl.st"].decode()
    assert "    KE : LREAL := 20.5;" in block and "ALPHA_RULES : ARRAY" in block
    recorded = [ln.split("command:", 1)[1] for ln in block.splitlines()
                if ln.lstrip().startswith("command:")]
    assert len(recorded) == 1
    argv = shlex.split(recorded[0])
    assert argv[:3] == ["fuzzyservo", "export", "st"] and argv[-2:] == ["--out", "stfpi-st"]
    assert argv[1:] == page._export_args("st", "stfpi-st")
    monkeypatch.chdir(tmp_path)
    status, _, err = printed(argv[1:])
    assert status == 0, err
    assert got == {f.name: f.read_bytes() for f in (tmp_path / "stfpi-st").iterdir()}


def test_a_general_fuzzy_system_is_refused_by_the_structured_text_download_as_by_the_command(
        tmp_path: Path) -> None:
    """Structured Text takes uniform-grid systems and rule tables over fuzzy partitions: a
    system with a smooth term (a Gaussian) makes the download show the command's one line,
    and no file."""
    from fuzzyservo.app.page import ServoPage

    paper = Path(__file__).resolve().parents[2] / "src/fuzzyservo/data/systems/paper-du.fis"
    zo = "MF4='ZO':'trimf',[-0.3333333333333333 0 0.3333333333333333]"
    general = tmp_path / "general-du.fis"
    general.write_text(paper.read_text().replace(zo, "MF4='ZO':'gaussmf',[0.15 0]", 1))
    page = ServoPage(workdir=tmp_path / "page")
    page.w_controller.value = "fpi"
    page.systems["du"] = str(general)
    page.submit()
    assert page._st_file() is None
    status, _, err = printed([*page._export_args("st", str(tmp_path / "fpi-st"))])
    assert status == 2 and "general evaluator's" in err and "export c" in err
    assert page.w_error.visible and page.w_error.object == html.escape(err.strip())
    assert not (tmp_path / "fpi-st").exists()
    # the other downloads still work: C takes any system
    assert sorted(_zip_files(page._c_file())) == ["fpi.c", "fpi.h"]
