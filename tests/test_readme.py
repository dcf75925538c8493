"""Every command and snippet of README.md runs, and does what its text says.

The README is parsed: each ```sh block's commands run in order (``fuzzyservo ...`` in-process
through ``fuzzyservo.cli.main``; ``gcc`` and ``./PROGRAM`` as processes; ``make reproduce`` is
the Makefile's recipe, which the session's ``reproduced`` fixture runs once for this and the
study's tests; ``make test`` is this suite and is not run again), each ```python block is
executed, each ```pycon block is run as a doctest, a ```c block is the file its first
comment names (``/* NAME.c: ... */``), and an ```iecst block (Structured Text) is likewise the
file ``(* NAME.st: ... *)`` names, translated by MatIEC's ``iec2c`` after the Structured Text
the commands above it wrote, and MatIEC's C compiled by gcc. Every block runs in a scratch
folder in which ``src`` points at this repository's ``src/``, as a user's shell in a clone
would; in a chained section (:data:`CHAINED`) the blocks above it in the section run first.
Every shell command must have a check below that holds it to what the README says of it; a
command without one fails the suite, so an example added without a check, or one that stops
doing what it says, is caught.
"""

from __future__ import annotations

import csv
import doctest
import json
import re
import shlex
import subprocess
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from fuzzyservo.cli import main
from fuzzyservo.files import read_gains_toml, read_run_csv
from tests.helpers import printed_metrics

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


@dataclass(frozen=True)
class Block:
    lang: str
    text: str
    line: int  # line of the opening fence
    section: str = ""  # the "## " heading above it

    @property
    def id(self) -> str:
        return f"{self.lang}-line{self.line}"


def _blocks() -> list[Block]:
    out = []
    lines = README.read_text(encoding="utf-8").splitlines()
    i = 0
    section = ""
    while i < len(lines):
        if lines[i].startswith("## "):
            section = lines[i][3:].strip()
        m = re.match(r"^```(\w+)\s*$", lines[i])
        if m:
            j = i + 1
            while not lines[j].startswith("```"):
                j += 1
            out.append(Block(m.group(1), "\n".join(lines[i + 1:j]) + "\n", i + 1, section))
            i = j
        i += 1
    return out


def _commands(block: Block) -> list[str]:
    """Shell commands of a block: continuation lines joined, comments dropped."""
    joined = block.text.replace("\\\n", " ")
    cmds = []
    for line in joined.splitlines():
        words = shlex.split(line, comments=True)
        if words:
            cmds.append(shlex.join(words))
    return cmds




# ------------------------------------------------------------------ what each command says
Check = Callable[[Path, str], None]


def _reproduced(d: Path, out: str) -> None:
    res = d / "paper"
    for name in ("report.html", "claims.json", "metrics.csv", "fig4_linear.png",
                 "fig4_nonlinear.svg"):
        assert (res / name).is_file(), name
    plants = {c["plant"] for c in json.loads((res / "claims.json").read_text())}
    assert plants == {"linear", "nonlinear"}
    for plant in plants:  # claim C8 at scale: the first points of the shipped sweeps
        assert "data:image/png;base64," in (res / f"c8-sweep-{plant}.html").read_text()


def _row_stfpi_10(d: Path, out: str) -> None:
    m = printed_metrics(out)
    # the README quotes these three figures (to their printed digits)
    assert (m["rise_time"], m["settling_time"], round(m["overshoot"], 2)) == (0.509, 0.805, 0.97)


def _stfpi_run(d: Path, out: str) -> None:
    m = printed_metrics(out)
    run = read_run_csv(d / "stfpi.csv")
    assert list(run.columns)[:5] == ["t", "r", "y", "u", "alpha"]
    assert run.y[0] == 0.5 and run.r[-1] == pytest.approx(0.6, abs=1e-12)  # absolute [m]
    # "with the 6 ms hose delay": the piston holds still until the first command arrives
    assert run.u[0] != 0.0 and all(run.y[:7] == 0.5) and run.y[7] > 0.5
    assert m["overshoot"] >= 0.0 and m["settling_time"] < 5.0


def _ipd_run(d: Path, out: str) -> None:
    run = read_run_csv(d / "ipd.csv")
    from fuzzyservo.analysis import step_metrics

    m = step_metrics(run)
    assert run.r is not None
    # "within 2 % of the move from 3.8 s and ends 0.3 mm from the target at 8 s"
    assert round(m.settling_time, 1) == 3.8
    assert round(abs(run.r[-1] - run.y[-1]) * 1e3, 1) == 0.3
    assert run.r[-1] - run.r[0] == pytest.approx(0.2, abs=1e-12)  # the 0.2 m trapezoid
    assert (d / "ipd.png").read_bytes()[:4] == b"\x89PNG"


def _plot(d: Path, out: str) -> None:
    svg = (d / "both.svg").read_text(encoding="utf-8")
    assert svg.lstrip().startswith(("<?xml", "<svg"))
    assert "I-PD" in svg and "overshoot" in svg  # labels and metrics in the legend


def _metrics_json(d: Path, out: str) -> None:
    m = json.loads(out)
    assert m["settling_time"] == pytest.approx(3.78, abs=0.01)


def _linearize_json(d: Path, out: str) -> None:
    s = json.loads(out)
    # the paper set is derived so that eq. (8) has Table A.1's omega_0 and damping
    assert s["omega_0"] == pytest.approx(19.6, rel=1e-9) and s["damping"] == pytest.approx(
        0.1, rel=1e-9)


def _linearize_stiff(d: Path, out: str) -> None:
    assert out.startswith("position        0.1 m") and "omega_0" in out


def _open_loop_nonlinear(d: Path, out: str) -> None:
    run = read_run_csv(d / "run.csv")
    assert list(run.columns)[:3] == ["t", "u", "y"] and "p_f" in run.columns
    assert run.t[-1] == pytest.approx(2.0, abs=1e-12) and run.y[-1] > 0.7  # extends


def _open_loop_small_signal(d: Path, out: str) -> None:
    run = read_run_csv(d / "r.csv")
    assert "p_f" in run.columns and run.y[-1] < 0.5  # u = -0.5 retracts


def _surface_du(d: Path, out: str) -> None:
    with (d / "du.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 41 * 41
    assert (d / "du.png").is_file() and (d / "du_mf.png").is_file()


def _surface_alpha(d: Path, out: str) -> None:
    with (d / "alpha.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 41 * 41  # "at the grid's points"
    assert all(1 / 18 - 1e-12 <= float(r["value"]) <= 17 / 18 + 1e-12 for r in rows)


def _fis_info(d: Path, out: str) -> None:
    assert "rules (49):" in out and "and:          min" in out
    assert "1. if e is NB and de is NB then du is NB" in out


def _fis_convert(d: Path, out: str) -> None:
    from fuzzyservo.formats import read_system
    from fuzzyservo.paper import paper_fuzzy_system

    assert read_system(d / "du.fis") == paper_fuzzy_system("du")  # every value kept


def _fis_eval(d: Path, out: str) -> None:
    with (d / "du3.csv").open() as fh:
        rows = {(float(r["e"]), float(r["de"])): float(r["du"]) for r in csv.DictReader(fh)}
    assert len(rows) == 9
    # "±8/9 at the corners where e and Δe agree": exact up to rounding
    assert rows[(1.0, 1.0)] == pytest.approx(8 / 9, abs=1e-15)
    assert rows[(-1.0, -1.0)] == pytest.approx(-8 / 9, abs=1e-15)


def _fis_show(d: Path, out: str) -> None:
    assert (d / "du_fis.png").read_bytes()[:4] == b"\x89PNG"


def _simulate_du_file(d: Path, out: str) -> None:
    m = printed_metrics(out)
    # "the same rise time (0.509 s), settling time (0.805 s) and overshoot (0.97 %)"
    assert (m["rise_time"], m["settling_time"], round(m["overshoot"], 2)) == (0.509, 0.805,
                                                                              0.97)


def _tune_pid(d: Path, out: str) -> None:
    t = read_gains_toml(d / "pid.toml")
    assert t.controller == "pid" and t.feasible and t.metrics["overshoot"] <= 10.0
    assert t.setup.delay == 0.0


def _simulate_pid_file(d: Path, out: str) -> None:
    t = read_gains_toml(d / "pid.toml")
    m = printed_metrics(out)
    # "runs it": the tuned run's metrics, to the 6 digits simulate prints
    assert m["itae"] == pytest.approx(t.metrics["itae"], rel=5e-6)


def _tune_stfpi(d: Path, out: str) -> None:
    t = read_gains_toml(d / "stfpi.toml")
    assert [s.name for s in t.stages] == ["fpi", "rise", "refine"]  # the paper's steps
    assert t.feasible and t.metrics["overshoot"] <= 0.5


def _tune_pid2(d: Path, out: str) -> None:
    t = read_gains_toml(d / "pid2.toml")
    assert t.controller == "pid2" and t.gains["c"] == 0.0  # held while tuning
    assert t.setup.overrides == (("load.mass", 40.0),) and t.setup.seed == 1


def _export_c(d: Path, out: str) -> None:
    header = (d / "ctl" / "stfpi.h").read_text()
    # "records the package version, the gains, the sample time, the options and a SHA-256"
    assert "fuzzyservo 0." in header and "ke = 34.02696824542279" in header and "0.001 s" in header
    assert "initial_error = zero" in header and "SHA-256" in header
    assert sorted(p.name for p in (d / "ctl").iterdir()) == ["stfpi.c", "stfpi.h"]


def _export_st(d: Path, out: str) -> None:
    block, example = (d / "plc" / "stfpi_ctl.st").read_text(), (
        d / "plc" / "stfpi_ctl_example.st").read_text()
    assert sorted(p.name for p in (d / "plc").iterdir()) == ["stfpi_ctl.st",
                                                             "stfpi_ctl_example.st"]
    # "one FUNCTION_BLOCK", "the gains are inputs whose defaults are the exported values",
    # "the rule tables are VAR CONSTANT arrays", "a cyclic task of the sample time (here 1 ms)"
    assert block.count("FUNCTION_BLOCK stfpi_ctl\n") == 1 and "END_FUNCTION_BLOCK" in block
    inputs = block[block.index("VAR_INPUT\n"):block.index("END_VAR")]
    assert "    KE : LREAL := 34.02696824542279;" in inputs
    constants = block[block.index("VAR CONSTANT\n"):]
    assert "    DU_RULES : ARRAY[0..6, 0..6] OF DINT := [" in constants
    assert "ALPHA_RULES : ARRAY[0..6, 0..6] OF DINT" in constants
    assert "PROGRAM stfpi_ctl_EXAMPLE" in example and "CONFIGURATION stfpi_ctl_CONFIG" in example
    assert "TASK stfpi_ctl_TASK(INTERVAL := T#1ms, PRIORITY := 1);" in example
    # "MatIEC translates both"
    _iec2c(block + "\n" + example, d / "iec2c-export", "stfpi_ctl_example.st")


def _iec2c(text: str, folder: Path, name: str) -> None:
    """MatIEC translates ``text`` into C, and gcc compiles that C with MatIEC's headers."""
    from tests.export.cbuild import gcc
    from tests.export.st_harness import matiec_prefix, translate

    done = translate(text, folder, name)
    assert done.returncode == 0, f"iec2c refused {name}:\n{done.stdout}{done.stderr}"
    shim = folder / "c" / "shim.c"
    shim.write_text('#include "iec_std_lib.h"\n#include "POUS.h"\n#include "POUS.c"\n')
    built = subprocess.run([gcc(), "-std=gnu11", "-w", "-fsyntax-only", "-I",
                            str(matiec_prefix() / "lib" / "C"), "-I", str(shim.parent),
                            str(shim)], capture_output=True, text=True, check=False,
                           timeout=300)
    assert built.returncode == 0, f"gcc refused MatIEC's C of {name}:\n{built.stderr}"


def _recorded(d: Path, out: str) -> None:
    assert len(read_run_csv(d / "recorded.csv").t) == 2001


def _gcc_driver(d: Path, out: str) -> None:
    assert (d / "driver").is_file()


def _driver_run(d: Path, out: str) -> None:
    assert out.strip() == "2001 samples, max |u_C - u_recorded| = 0"  # as the README says


def _sweep_example(d: Path, out: str) -> None:
    assert out == (ROOT / "src/fuzzyservo/data/sweeps/example.toml").read_text(encoding="utf-8")


def _sweep_run(d: Path, out: str) -> None:
    from fuzzyservo.sweep import read_manifest, read_table

    assert read_manifest(d / "example-sweep").complete
    runs = read_table(d / "example-sweep")
    assert runs.num_rows == 540 and len(set(runs.column("controller").to_pylist())) == 3
    assert "540 runs in example-sweep" in out


def _sweep_report(d: Path, out: str) -> None:
    html = (d / "example-report.html").read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>") and "data:image/png;base64," in html


def _app(d: Path, out: str) -> None:
    # out: the page the browser was sent to, fetched (see _run_app)
    assert "<title>fuzzyservo: tune by looking</title>" in out and "static/js/bokeh" in out


def _run_app(block: Block, words: list[str], scratch: Path) -> str:
    """``fuzzyservo app``: a server until stopped. Run it with $BROWSER set to a command that
    records the address the app asks the browser to open; fetch that page; stop the
    server."""
    import os
    import sys
    import urllib.request

    from tests.app.browser import free_port

    opened = scratch / "opened.txt"
    browser = scratch / "browser.py"
    browser.write_text("import sys, pathlib\n"
                       f"pathlib.Path({str(opened)!r}).write_text(sys.argv[1])\n")
    exe = str(Path(sys.executable).parent / "fuzzyservo")
    env = dict(os.environ, BROWSER=f"{sys.executable} {browser} %s")
    proc = subprocess.Popen([exe, *words[1:], "--port", str(free_port())], cwd=scratch,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        for _ in range(1200):
            if opened.exists() and opened.read_text():
                break
            assert proc.poll() is None, f"README line {block.line}: {proc.communicate()}"
            # sleep: polling for the stand-in browser's file (no file-creation event)
            time.sleep(0.1)
        url = opened.read_text()
        assert url.startswith("http://127.0.0.1:"), url
        with urllib.request.urlopen(url, timeout=30) as page:
            return str(page.read().decode())
    finally:
        proc.terminate()
        proc.wait(30)


def _bode(d: Path, out: str) -> None:
    # "margins, bandwidth": the table prints them, and the tuned loop is stable
    assert "gain margin" in out and "phase margin" in out and "bandwidth" in out
    assert "stable          yes" in out


def _loaded(d: Path, out: str) -> None:
    # a positive force opposes extension: from 5 s on the piston is pushed back, below where
    # it stood (the gains file runs 10 s, as tuned; the step response has settled by 5 s)
    run = read_run_csv(d / "loaded.csv")
    before = run.y[run.t <= 5.0][-1]
    assert min(run.y[run.t > 5.0]) < before - 1e-4


def _fmu(name: str, identifier: str) -> Check:
    def check(d: Path, out: str) -> None:
        with zipfile.ZipFile(d / name) as zf:
            assert f"binaries/linux64/{identifier}.so" in zf.namelist()
            assert b"fmiVersion=\"2.0\"" in zf.read("modelDescription.xml")
    return check


def _design(d: Path, out: str) -> None:
    cols = read_run_csv(d / "design.csv", required=("t", "u"))
    # "55 s at 1 kHz": the design's length and rate, as printed
    assert 50.0 <= cols.t[-1] <= 60.0 and abs(cols.t[1] - cols.t[0] - 1e-3) < 1e-12
    assert "log at least" in out


def _rig(d: Path, out: str) -> None:
    cols = read_run_csv(d / "rig.csv", required=("t", "u", "y", "p_f", "p_n"))
    assert cols.t.size > 50_000


#: The rig's hidden parameters (README, "Your own axis").
_TRUTH = {"load.mass": 26000.0, "fluid.oil_bulk_modulus": 1.2e9, "valve.omega_v": 600.0}


def _identified(d: Path, out: str) -> None:
    import tomllib

    rec = tomllib.loads((d / "axis.toml").read_text())["identification"]
    # "each within two standard errors of the truth"
    for name, est, se in zip(rec["fitted"], rec["estimate"], rec["std_error"], strict=True):
        assert abs(est - _TRUTH[name]) <= 2 * se, (name, est, se)
    assert rec["data_digest"].startswith("sha256:") and not rec["warnings"]
    assert (d / "fit.png").stat().st_size > 0
    assert "<h2>Estimates" in (d / "fit.html").read_text(encoding="utf-8")


def _quick_tuned(name: str) -> Check:
    def check(d: Path, out: str) -> None:
        t = read_gains_toml(d / name)
        assert t.controller == "stfpi" and t.feasible and t.metrics["overshoot"] <= 10.0
    return check


def _nominal_on_truth(d: Path, out: str) -> None:
    m = printed_metrics(out)  # "14.0 % (the limit was 10 %) | not settled in 3 s"
    assert m["overshoot"] > 10.0 and m["settling_time"] != m["settling_time"]


def _identified_on_truth(d: Path, out: str) -> None:
    m = printed_metrics(out)  # "6.3 % | 1.8 s"
    assert m["overshoot"] <= 10.0 and m["settling_time"] < 3.0


CHECKS: dict[str, Check] = {
    "fuzzyservo identify --design --out design.csv": _design,
    "--pressure-noise-std 2e4 --seed 1 --out rig.csv": _rig,
    "fuzzyservo identify rig.csv": _identified,
    "--out nominal-stfpi.toml": _quick_tuned("nominal-stfpi.toml"),
    "--params axis.toml --out axis-stfpi.toml": _quick_tuned("axis-stfpi.toml"),
    "fuzzyservo simulate --gains nominal-stfpi.toml": _nominal_on_truth,
    "fuzzyservo simulate --gains axis-stfpi.toml": _identified_on_truth,
    "fuzzyservo export c --gains": _export_c,
    "fuzzyservo export st --gains": _export_st,
    "fuzzyservo simulate --duration 2 --gains": _recorded,
    "gcc -std=c99 -O2 -Ictl": _gcc_driver,
    "./driver recorded.csv": _driver_run,
    "fuzzyservo export fmu --gains": _fmu("stfpi.fmu", "stfpi"),
    "fuzzyservo export fmu --plant nonlinear": _fmu("servo.fmu", "servo_nonlinear"),
    "make reproduce": _reproduced,
    "fuzzyservo sweep --example": _sweep_example,
    "fuzzyservo sweep src/fuzzyservo/data/sweeps/example.toml": _sweep_run,
    "fuzzyservo sweep-report example-sweep": _sweep_report,
    "fuzzyservo simulate --gains src/fuzzyservo/data/gains/linear-stfpi.toml": _row_stfpi_10,
    "--out stfpi.csv --metrics": _stfpi_run,
    "--out ipd.csv --plot ipd.png": _ipd_run,
    "fuzzyservo plot stfpi.csv ipd.csv": _plot,
    "fuzzyservo metrics ipd.csv --json": _metrics_json,
    "fuzzyservo linearize --json": _linearize_json,
    "fuzzyservo linearize --set stiff-oil": _linearize_stiff,
    "--command 0.5 --duration 2 --out run.csv": _open_loop_nonlinear,
    "--plant small-signal --open-loop": _open_loop_small_signal,
    "fuzzyservo surface du": _surface_du,
    "fuzzyservo surface alpha": _surface_alpha,
    "fuzzyservo fis info src/fuzzyservo/data/systems/paper-du.fcl": _fis_info,
    "fuzzyservo fis convert src/fuzzyservo/data/systems/paper-du.fcl du.fis": _fis_convert,
    "fuzzyservo fis eval du.fis --grid 3": _fis_eval,
    "fuzzyservo fis show du.fis": _fis_show,
    "--du-system du.fis": _simulate_du_file,
    "fuzzyservo tune --controller pid --plant linear": _tune_pid,
    "fuzzyservo simulate --gains pid.toml --metrics": _simulate_pid_file,
    "fuzzyservo tune --controller stfpi --plant linear": _tune_stfpi,
    "fuzzyservo tune --controller pid2": _tune_pid2,
    "fuzzyservo app": _app,
    "fuzzyservo bode --gains src/fuzzyservo/data/gains/linear-stfpi.toml": _bode,
    "--load-force step:2000:5 --out loaded.csv": _loaded,
}
#: Not run: the suite itself.
NOT_RUN = {"make test"}

BLOCKS = _blocks()


def _check_for(cmd: str) -> Check:
    hits = [c for key, c in CHECKS.items() if key in cmd]
    assert len(hits) == 1, f"README command without exactly one check: {cmd!r}"
    return hits[0]


@pytest.fixture
def scratch(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    (tmp_path / "src").symlink_to(ROOT / "src", target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_readme_has_the_two_commands_first() -> None:
    first = BLOCKS[0]
    assert first.lang == "sh" and _commands(first) == ["make reproduce", "make test"]
    assert {b.lang for b in BLOCKS} <= {"sh", "python", "pycon", "c", "iecst"}
    assert all(b.section in CHAINED for b in BLOCKS if b.lang in ("c", "iecst"))


#: Sections whose blocks build on each other (a file one writes, the next compiles): before a
#: block runs, the blocks above it in its section run in the same scratch folder.
CHAINED = {"To hardware", "Robustness sweeps", "Your own axis"}


def _source_file(block: Block) -> str:
    """The file a ```c or ```iecst block is: its first comment names it."""
    if block.lang == "c":
        m = re.match(r"/\* ([\w.-]+\.c): ", block.text)
        assert m, f"README line {block.line}: a C block starts with /* NAME.c: ... */"
    else:
        m = re.match(r"\(\* ([\w.-]+\.st): ", block.text)
        assert m, f"README line {block.line}: an ST block starts with (* NAME.st: ... *)"
    return m.group(1)


def _run_command(block: Block, cmd: str, scratch: Path, capsys: pytest.CaptureFixture[str]
                 ) -> str:
    """Run one shell command of the README in ``scratch``; returns its standard output."""
    words = shlex.split(cmd)
    if words[0] == "gcc" or words[0].startswith("./"):
        proc = subprocess.run(words, cwd=scratch, capture_output=True, text=True, check=False)
        assert proc.returncode == 0, f"README line {block.line}: {cmd!r}: {proc.stderr}"
        return proc.stdout
    assert words[0] == "fuzzyservo", f"README line {block.line}: {cmd!r}"
    if words[:2] == ["fuzzyservo", "app"]:
        return _run_app(block, words, scratch)
    capsys.readouterr()
    status = main(words[1:])
    out, err = capsys.readouterr()
    assert status == 0, f"README line {block.line}: {cmd!r} -> {status}: {err}"
    return out


def _replay_before(block: Block, scratch: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Run the blocks above ``block`` in its section, if the section is chained."""
    if block.section not in CHAINED:
        return
    for b in BLOCKS:
        if b is block or b.line > block.line:
            break
        if b.section != block.section:
            continue
        if b.lang in ("c", "iecst"):
            (scratch / _source_file(b)).write_text(b.text, encoding="utf-8")
        elif b.lang == "sh":
            for cmd in _commands(b):
                _run_command(b, cmd, scratch, capsys)
        elif b.lang == "python":
            _exec_block(compile(b.text, f"README.md:{b.line}", "exec"))


def _exec_block(code: object) -> None:
    """Run a Python block as a user's script runs: as a module in ``sys.modules`` (dataclasses
    look their module up), and leave the controller registry as it was (a block that registers
    its own law does not add it to the other tests of this worker)."""
    import sys
    import types

    from fuzzyservo.registry import controllers as reg

    module = types.ModuleType("__readme__")
    saved = dict(reg._CONTROLLERS)
    sys.modules["__readme__"] = module
    try:
        exec(code, module.__dict__)  # noqa: S102 - the README's own code
    finally:
        sys.modules.pop("__readme__", None)
        reg._CONTROLLERS.clear()
        reg._CONTROLLERS.update(saved)


def test_every_command_has_a_check() -> None:
    for b in BLOCKS:
        if b.lang == "sh":
            for cmd in _commands(b):
                if cmd not in NOT_RUN:
                    _check_for(cmd)


#: Commands that take more than a few seconds (the study, tuning): their blocks are ``slow``.
#: (``make reproduce`` is the session's reproduction, shared with tests/study.)
SLOW = ("fuzzyservo tune",)


def _sh_params() -> list[object]:
    return [pytest.param(b, id=b.id, marks=[pytest.mark.slow] if any(
        c.startswith(SLOW) for c in _commands(b)) else []) for b in BLOCKS if b.lang == "sh"]


@pytest.mark.parametrize("block", _sh_params())
def test_shell_block(block: Block, scratch: Path, capsys: pytest.CaptureFixture[str],
                     request: pytest.FixtureRequest) -> None:
    _replay_before(block, scratch, capsys)
    for cmd in _commands(block):
        if cmd in NOT_RUN:
            continue
        words = shlex.split(cmd)
        if words[:2] == ["make", "reproduce"]:
            # the session's reproduction is this recipe (tests/conftest.py): check its output
            paper = request.getfixturevalue("reproduced")
            _check_for(cmd)(paper.parent, "")
            continue
        out = _run_command(block, cmd, scratch, capsys)
        _check_for(cmd)(scratch, out)


def _png(path: Path) -> None:
    assert path.read_bytes()[:4] == b"\x89PNG"


def _gains_file(path: Path) -> None:
    assert read_gains_toml(path).controller == "pid"


#: Files the Python examples say they write, and what each must hold.
WRITTEN: dict[str, Callable[[Path], None]] = {"runs.png": _png, "my-pid.toml": _gains_file}


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.lang == "python"],
                         ids=lambda b: b.id)
def test_python_block(block: Block, scratch: Path,
                      capsys: pytest.CaptureFixture[str]) -> None:
    _replay_before(block, scratch, capsys)
    code = compile(block.text, f"README.md:{block.line}", "exec")
    _exec_block(code)
    for name, check in WRITTEN.items():
        if f'"{name}"' in block.text:
            check(scratch / name)


def test_every_written_file_is_in_a_block() -> None:
    text = "".join(b.text for b in BLOCKS if b.lang == "python")
    assert all(f'"{name}"' in text for name in WRITTEN)


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.lang == "iecst"], ids=lambda b: b.id)
def test_iecst_block(block: Block, scratch: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A Structured Text block calls what the commands above it exported, as they wrote it:
    translated after every function block they wrote (not their examples: one program of the
    README's is enough), it is a valid program to MatIEC and its C to gcc."""
    _replay_before(block, scratch, capsys)
    blocks = sorted(p for p in scratch.glob("*/*.st")
                    if p.parent.name != "src" and not p.name.endswith("_example.st"))
    assert blocks, f"README line {block.line}: no Structured Text exported above the block"
    text = "\n".join(p.read_text(encoding="utf-8") for p in blocks)
    _iec2c(text + "\n" + block.text, scratch / "iec2c-readme", _source_file(block))


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.lang == "pycon"], ids=lambda b: b.id)
def test_pycon_block(block: Block, scratch: Path) -> None:
    test = doctest.DocTestParser().get_doctest(block.text, {}, block.id, str(README),
                                               block.line)
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    assert runner.summarize(verbose=False).failed == 0
