"""Issue 9, "inputs bounded before any work" and "errors are one line": each row of the issue's
table that these commands own gives status 2, exactly one line on standard error naming the
value and the limit, no traceback, and leaves an output that existed before byte-identical.

Every case fails before a simulation or a search starts, so the file runs in a few seconds.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import fuzzyservo.analysis.autotune as autotune
import fuzzyservo.commands.linearize as linearize_cmd
import fuzzyservo.commands.tune as tune_cmd
import fuzzyservo.run.spec as run_spec
from fuzzyservo.analysis.autotune import (
    MAX_MAXITER,
    MAX_POPSIZE,
    Checkpoint,
    TuningSetup,
    setup_record,
)
from fuzzyservo.analysis.tuning import SearchState
from fuzzyservo.cli import main
from fuzzyservo.errors import ParameterError
from fuzzyservo.files import checkpoint_path, save_checkpoint

PID = ["--controller", "pid", "--gains", "kp=20,ki=2,kd=0.1"]
LINEAR = ["simulate", "--plant", "linear", *PID, "--duration", "0.05"]
NONLINEAR = ["simulate", "--plant", "nonlinear", *PID, "--duration", "0.05"]
TUNE = ["tune", "--controller", "pid", "--plant", "linear", "--quiet"]
OLD = b"t,r,y,u\n0,0,0,0\n"  # what an output held before the command


def _error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``argv``; assert status 2 and one line on stderr without a traceback; return it."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.startswith("fuzzyservo: error: ") and err.endswith("\n")
    assert err.count("\n") == 1, err
    return err


def _keep(path: Path) -> Path:
    path.write_bytes(OLD)
    return path


@pytest.fixture
def no_search(monkeypatch: pytest.MonkeyPatch) -> None:
    """A ``tune`` that reaches the search fails the test: the error must come before it."""

    def fail(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("the search started")

    monkeypatch.setattr(tune_cmd, "tune_controller", fail)


# ------------------------------------------------------------- row 8: non-UTF-8 input files

BAD_TEXT = {
    "random": (bytes([0x8D, 0x01, 0xFE, 0x20]) * 64, "not UTF-8 text: byte 0x8d at offset 0"),
    "utf16": ("[load]\nmass = 100.0\n".encode("utf-16"), "UTF-16 text (byte-order mark"),
    "late": (b"[load]\nmass = 1\xe9.0\n", "byte 0xe9 at offset 15"),
}


@pytest.mark.parametrize("kind", sorted(BAD_TEXT))
@pytest.mark.parametrize("command", ["linearize", "tune"])
def test_row8_params_file_not_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                   no_search: None, kind: str, command: str) -> None:
    data, message = BAD_TEXT[kind]
    bad = tmp_path / "bin.toml"
    bad.write_bytes(data)
    out = _keep(tmp_path / "g.toml")
    argv = ["linearize"] if command == "linearize" else [*TUNE, "--out", str(out)]
    err = _error([*argv, "--params", str(bad)], capsys)
    assert message in err and "bin.toml" in err
    assert out.read_bytes() == OLD


@pytest.mark.parametrize("kind", sorted(BAD_TEXT))
def test_row8_gains_file_not_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                  kind: str) -> None:
    data, message = BAD_TEXT[kind]
    bad = tmp_path / "gains.toml"
    bad.write_bytes(data)
    out = _keep(tmp_path / "run.csv")
    err = _error(["simulate", "--plant", "linear", "--gains", str(bad), "--out", str(out)],
                 capsys)
    assert "gains file" in err and "gains.toml" in err and message in err
    assert out.read_bytes() == OLD


@pytest.mark.parametrize(("data", "message"), [
    (b"t,r,y,u\n0,0,0,0\n0.1,1,\xff1,1\n", "not UTF-8 text: byte 0xff at offset 22"),
    (b"\xef\xbb\xbft,r,y,u\n0,0,0,0\n0.1,1,\xc3(,1\n", "byte 0xc3 at offset 25"),
    ("t,r,y,u\n0,0,0,0\n".encode("utf-16"), "UTF-16 text"),
    (b"t,r,y,u\n0,0,0\x00,0\n", "NUL character at offset 13"),
    # row 23: two columns of one name; a last row cut short; a row with a value too many
    (b"t,r,y,u,t\n0,0,0,0,5\n0.1,1,1,1,6\n", "names column(s) 't' twice"),
    (b"t,r,y,u\n0,0,0,0\n0.1,1,0.5\n", "line 3 has 3 value(s), the header names 4 columns "
                                       "(a row cut short?)"),
    (b"t,r,y,u\n0,0,0,0,9\n0.1,1,0.5,1\n", "line 2 has 5 value(s), the header names 4"),
])
def test_row8_row23_run_csv_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                    data: bytes, message: str) -> None:
    csv = tmp_path / "run.csv"
    csv.write_bytes(data)
    err = _error(["metrics", str(csv)], capsys)
    assert message in err and "run.csv" in err


# ------------------------------------------------------- row 9: a delay longer than the run

@pytest.mark.parametrize("argv", [
    [*LINEAR, "--delay", "1e9"],
    [*LINEAR, "--delay", "1e7"],
    [*NONLINEAR, "--delay", "1e9"],
    ["simulate", "--open-loop", "--command", "0.1", "--duration", "0.05", "--delay", "1e9"],
    ["simulate", "--open-loop", "--command", "0.1", "--duration", "0.05", "--delay", "1e9",
     "--method", "solve_ivp"],
], ids=["linear-1e9", "linear-1e7", "nonlinear", "open-loop", "open-loop-solve_ivp"])
def test_row9_simulate_delay_longer_than_the_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    out = _keep(tmp_path / "keep.csv")
    err = _error([*argv, "--out", str(out)], capsys)
    delay = float(argv[argv.index("--delay") + 1])
    assert f"delay {delay!r} s is longer than the run (0.05 s)" in err
    assert "at most the run's duration" in err
    assert out.read_bytes() == OLD


def test_row9_a_delay_of_the_whole_run_is_allowed(tmp_path: Path) -> None:
    assert main([*LINEAR, "--delay", "0.05", "--out", str(tmp_path / "r.csv")]) == 0


def test_row9_tune_delay_longer_than_the_run(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str],
                                             no_search: None) -> None:
    out = _keep(tmp_path / "g.toml")
    err = _error([*TUNE, "--delay", "1e9", "--out", str(out)], capsys)
    assert "delay 1000000000.0 s is longer than the run (10.0 s)" in err
    assert out.read_bytes() == OLD


# ----------------------------------- row 10: tune's run bounded, errors of the search itself

@pytest.mark.parametrize(("option", "value", "samples"), [
    ("--duration", "1e9", "1e+12"), ("--ts", "1e-9", "1e+10")])
def test_row10_tune_samples_capped_before_the_search(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], no_search: None, option: str,
        value: str, samples: str) -> None:
    err = _error([*TUNE, option, value, "--out", str(tmp_path / "g.toml")], capsys)
    assert f"needs {samples} samples; at most 10000000 are allowed" in err


def test_row10_error_inside_the_search_surfaces_as_itself(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """scipy's differential evolution re-raises a ValueError of the objective as a
    RuntimeError; the project's own error must come out as itself, on one line."""
    calls = []

    def failing_batch(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        raise ParameterError("objective refused its input (a test's error)")

    monkeypatch.setattr(run_spec, "simulate_batch", failing_batch)  # the tuner's batches
    out = _keep(tmp_path / "g.toml")
    err = _error([*TUNE, "--popsize", "3", "--maxiter", "2", "--duration", "0.5",
                  "--out", str(out)], capsys)
    assert calls, "the objective ran inside the search"
    assert "objective refused its input (a test's error)" in err
    assert out.read_bytes() == OLD


# ------------------------------------------------------- row 11: a truncated checkpoint

def test_row11_truncated_checkpoint(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                    no_search: None) -> None:
    out = tmp_path / "g.toml"
    ckpt = checkpoint_path(out)
    rng = np.random.default_rng(0)
    state = SearchState(generation=3, population=rng.random((30, 3)), costs=rng.random(30),
                        rng_state=dict(rng.bit_generator.state), history=(4.0, 3.0, 2.0, 1.0),
                        n_evaluations=120)
    save_checkpoint(ckpt, Checkpoint(setup=setup_record(TuningSetup(controller="pid")),
                                     params="0" * 64, version="0", stage="search",
                                     state=state))
    data = ckpt.read_bytes()[:800]
    ckpt.write_bytes(data)
    err = _error([*TUNE, "--out", str(out), "--resume"], capsys)
    assert f"checkpoint {str(ckpt)!r} is unreadable" in err
    assert "delete it or run without --resume" in err
    assert ckpt.read_bytes() == data and not out.exists()


# ---------------------------------------------------- row 12: solve_ivp has a step limit

def test_row12_solve_ivp_stops_at_its_limit(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """The pathological run of the issue (1 ms of it needs ~1e9 evaluations) stops at the
    limit with advice; the default limit (1e6, MAX_RHS_EVALUATIONS) is lowered here with
    --max-evaluations so the test takes a fraction of a second (with the default it stops
    after ~10 s, measured)."""
    out = _keep(tmp_path / "x.csv")
    err = _error(["simulate", "--open-loop", "--command", "0.5", "--param", "load.mass=1e-6",
                  "--method", "solve_ivp", "--duration", "1", "--max-evaluations", "20000",
                  "--out", str(out)], capsys)
    assert "after 20000 right-hand-side evaluations, its limit (max_rhs_evals)" in err
    assert "--method rk4" in err and "of 1 s" in err and "--max-evaluations" in err
    assert out.read_bytes() == OLD


# ------------------------------------------- rows 13, 15, 21, 22: output paths checked first

@pytest.mark.parametrize(("extra", "message"), [
    (["--grid", "5", "--mf-plot", "mf.txt"], "--mf-plot 'mf.txt': the file name must end "
                                              "in .png or .svg"),
    (["--grid", "5", "--plot", "x.unknownext"], "--plot 'x.unknownext': the file name must "
                                                 "end in .png or .svg"),
    (["--grid", "5", "--plot", "adir"], "--plot 'adir' is a folder"),
    (["--grid", "5", "--plot", "s.svg", "--mf-plot", "s.svg"], "--mf-plot 's.svg' is also "
                                                                "--plot"),
    (["--grid", "5", "--plot", "nodir/s.png"], "folder 'nodir' does not exist"),
])
def test_rows13_21_surface_figure_paths(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                        monkeypatch: pytest.MonkeyPatch, extra: list[str],
                                        message: str) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "adir").mkdir()
    out = _keep(tmp_path / "v.csv")
    err = _error(["surface", "alpha", "--out", "v.csv", *extra], capsys)
    assert message in err
    # nothing written: not the CSV before the figure, not adir.png beside the folder
    assert out.read_bytes() == OLD
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir", "v.csv"]


def test_row15_surface_out_is_its_input(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    pts = tmp_path / "p.csv"
    pts.write_bytes(b"e,de\n0.1,0.2\n")
    err = _error(["surface", "alpha", "--at", str(pts), "--out", str(pts)], capsys)
    assert "is also an input of this command" in err
    assert pts.read_bytes() == b"e,de\n0.1,0.2\n"


def test_surface_writes_every_format(tmp_path: Path) -> None:
    assert main(["surface", "alpha", "--grid", "5", "--out", str(tmp_path / "v.csv"),
                 "--plot", str(tmp_path / "s.svg"), "--mf-plot", str(tmp_path / "m.png")]) == 0
    assert (tmp_path / "s.svg").read_bytes().lstrip().startswith(b"<?xml")
    assert (tmp_path / "m.png").read_bytes().startswith(b"\x89PNG")
    lines = (tmp_path / "v.csv").read_text().splitlines()
    assert lines[0] == "e,de,value" and len(lines) == 26


@pytest.mark.parametrize(("extra", "message"), [
    (["--out", "{tmp}/nodir/x.toml"], "folder '{tmp}/nodir' does not exist"),
    (["--out", "{tmp}"], "is a folder"),
    (["--popsize", "100000", "--out", "{tmp}/g.toml"],
     f"popsize must be between 2 and {MAX_POPSIZE}, got 100000"),
    (["--maxiter", "100000", "--out", "{tmp}/g.toml"],
     f"maxiter must be between 1 and {MAX_MAXITER}, got 100000"),
    (["--step", "5", "--out", "{tmp}/g.toml"],
     "the reference reaches 5.5 m at t = 0 s (start 0.5 m + offset 5 m), outside the stroke "
     "[0, 1] m"),
    (["--plant", "nonlinear", "--param", "transducer.resolution=10", "--out", "{tmp}/g.toml"],
     "transducer.resolution 10.0 m is coarser than the reference's largest move 0.1 m"),
])
def test_row22_tune_refuses_before_the_search(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch,
                                              extra: list[str], message: str) -> None:
    """The checks of tune_controller (stroke, resolution) run before its search: the search
    function is replaced by one that fails the test."""
    monkeypatch.setattr(autotune, "_search", lambda *a, **k: pytest.fail("search started"))
    argv = [a.replace("{tmp}", str(tmp_path)) for a in extra]
    err = _error([*TUNE, *argv], capsys)
    assert message.replace("{tmp}", str(tmp_path)) in err
    assert not (tmp_path / "g.toml").exists()


def test_row15_tune_out_is_its_params_file(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str],
                                           no_search: None) -> None:
    params = tmp_path / "g.toml"
    params.write_bytes(b"[load]\nmass = 100.0\n")
    err = _error([*TUNE, "--params", str(params), "--out", str(params)], capsys)
    assert "is also an input of this command" in err
    assert params.read_bytes() == b"[load]\nmass = 100.0\n"


# ----------------------------------------- rows 17, 18: references against the run and plant

@pytest.mark.parametrize(("argv", "message"), [
    ([*LINEAR, "--reference", "sine:0.1:1000"],
     "sine frequency 1000.0 Hz is at or above half the sample rate, 1/(2 ts) = 500 Hz at "
     "ts = 0.001 s"),
    ([*LINEAR, "--reference", "sine:0.1:500"], "sine frequency 500.0 Hz is at or above"),
    ([*LINEAR, "--reference", "sine:0.1:50", "--ts", "0.01"],
     "sine frequency 50.0 Hz is at or above half the sample rate, 1/(2 ts) = 50 Hz"),
    ([*NONLINEAR, "--reference", "step:5"],
     "the reference reaches 5.5 m at t = 0 s (start 0.5 m + offset 5 m), outside the stroke "
     "[0, 1] m"),
    ([*NONLINEAR, "--reference", "step:-0.7", "--start", "0.6"],
     "the reference reaches -0.1 m at t = 0 s"),
    (["simulate", "--plant", "small-signal", *PID, "--duration", "0.05", "--reference",
      "step:5"], "outside the stroke [0, 1] m"),
    ([*NONLINEAR, "--reference", "ramp:10", "--duration", "0.2"],
     "the reference reaches 1.01 m at t = 0.051 s"),
    ([*LINEAR, "--reference", "step:0.1:-1"],
     "reference step time must be >= 0 s (the run starts at t = 0), got -1.0"),
    ([*LINEAR, "--reference", "ramp:1:-1"], "reference ramp time must be >= 0 s"),
    ([*LINEAR, "--reference", "multistep:-1=0.1"], "reference multistep time must be >= 0 s"),
    ([*LINEAR, "--reference", "trapezoid:0.1:1:10:-2"],
     "reference trapezoid start time must be >= 0 s"),
    ([*LINEAR, "--reference", "sine:0.1:-5"], "sine frequency must be > 0 Hz"),
    ([*LINEAR, "--reference", "step:0.1:3"],
     "reference step time 3.0 s is at or after the end of the run (0.05 s)"),
    ([*NONLINEAR, "--param", "transducer.resolution=10"],
     "transducer.resolution 10.0 m is coarser than the reference's largest move 0.1 m"),
], ids=["sine-1000", "sine-nyquist", "sine-ts", "step-5", "below-0", "small-signal",
        "ramp-out", "step-t", "ramp-t", "multistep-t", "trapezoid-t", "sine-f", "after-end",
        "resolution"])
def test_rows17_18_references_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                      argv: list[str], message: str) -> None:
    out = _keep(tmp_path / "keep.csv")
    err = _error([*argv, "--out", str(out)], capsys)
    assert message in err
    assert out.read_bytes() == OLD


@pytest.mark.parametrize("argv", [
    [*LINEAR, "--reference", "sine:0.1:499"],
    [*NONLINEAR, "--reference", "step:0.5"],  # to the end stop itself
    [*NONLINEAR, "--param", "transducer.resolution=0.1"],  # as coarse as the step
], ids=["sine-below-nyquist", "to-the-stop", "resolution-as-step"])
def test_rows17_18_limits_themselves_allowed(tmp_path: Path, argv: list[str]) -> None:
    assert main([*argv, "--out", str(tmp_path / "r.csv")]) == 0


# --------------------------------------------------------------- row 19: strict JSON

def _strict(text: str) -> Any:
    def refuse(token: str) -> Any:
        raise ValueError(f"not strict JSON: {token}")

    return json.loads(text, parse_constant=refuse)


def test_row19_metrics_json_is_strict(tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    rows = [f"{k * 0.1!r},1,{1e308 if k % 2 else -1e308!r},0" for k in range(10)]
    (tmp_path / "big.csv").write_text("t,r,y,u\n" + "\n".join(rows) + "\n")
    assert main(["metrics", "--json", str(tmp_path / "big.csv")]) == 0
    out = _strict(capsys.readouterr().out)
    assert out["iae"] is None and out["ise"] is None  # infinite: null
    assert out["rise_time"] is None  # NaN: null
    assert out["peak"] == 1e308


def test_row19_linearize_json_is_strict(capsys: pytest.CaptureFixture[str],
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    real = linearize_cmd.summary

    def with_non_finite(params: Any, fraction: float) -> dict[str, Any]:
        s = real(params, fraction)
        s["damping"], s["omega_0_range"] = math.nan, [math.inf, -math.inf]
        return s

    monkeypatch.setattr(linearize_cmd, "summary", with_non_finite)
    assert main(["linearize", "--json"]) == 0
    out = _strict(capsys.readouterr().out)
    assert out["damping"] is None and out["omega_0_range"] == [None, None]
    assert out["omega_0"] > 0.0


# ------------------------------------------------- row 23: a message that says what is wrong

def test_row23_no_equilibrium_says_why(capsys: pytest.CaptureFixture[str]) -> None:
    err = _error(["linearize", "--param", "valve.null_leakage=1e3"], capsys)
    assert "holding the piston needs a valve command of -9.529e+11, outside the valve's " \
           "range [-1, 1]" in err
    assert "valve.null_leakage 1000.0" in err and "converged" not in err


def test_row12_progress_over_simulated_time() -> None:
    """The bar the CLI draws for solve_ivp: simulated seconds, the rate and the time left;
    nothing when disabled or when standard error is not a terminal (pytest's capture)."""
    import io

    from fuzzyservo.commands._runargs import simulated_time_progress
    from fuzzyservo.paper import paper_params
    from fuzzyservo.plant import with_overrides
    from fuzzyservo.registry import build_plant
    from fuzzyservo.sim import simulate_open_loop

    stream = io.StringIO()
    with simulated_time_progress("solve_ivp", file=stream) as progress:
        assert progress is not None
        simulate_open_loop(build_plant("nonlinear", paper_params(), 0.5), 0.5, duration=0.2,
                           method="solve_ivp", progress=progress)
    text = stream.getvalue()
    assert "solve_ivp: " in text and "0.2/0.2 s simulated" in text and "s/s]" in text
    stream = io.StringIO()
    with pytest.raises(ParameterError), \
            simulated_time_progress("solve_ivp", file=stream) as progress:
        stiff = with_overrides(paper_params(), {"load.mass": 1e-6})
        simulate_open_loop(build_plant("nonlinear", stiff, 0.5), 0.5, duration=0.2,
                           method="solve_ivp", progress=progress, max_rhs_evals=2500)
    assert stream.getvalue().endswith("\r")  # wiped: the error's line stands alone
    with simulated_time_progress("solve_ivp", enabled=False) as progress:
        assert progress is None
    with simulated_time_progress("solve_ivp") as progress:  # stderr captured: not a terminal
        assert progress is None


# ------------------------------------------- issue 29: nesting, devices, FIFOs, bounded reads

DEEP = {
    "arrays": "[load]\nmass = " + "[" * 5000 + "]" * 5000 + "\n",
    "inline-tables": "[load]\nmass = " + "{a = " * 5000 + "1" + "}" * 5000 + "\n",
    "dotted-keys": "[load]\nmass" + ".a" * 5000 + " = 1\n",
}


@pytest.mark.parametrize("kind", sorted(DEEP))
@pytest.mark.parametrize("as_", ["params", "gains"])
def test_issue29_toml_nested_5000_deep(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                       kind: str, as_: str) -> None:
    deep = tmp_path / "deep.toml"
    deep.write_text(DEEP[kind] if as_ == "params" else
                    'controller = "pid"\n' + DEEP[kind].replace("[load]", "[gains]"))
    out = _keep(tmp_path / "r.csv")
    argv = (["linearize", "--params", str(deep)] if as_ == "params" else
            ["simulate", "--plant", "linear", "--gains", str(deep), "--out", str(out)])
    err = _error(argv, capsys)
    what = "parameter file" if as_ == "params" else "gains file"
    assert f"{what} '{deep}' nests" in err and "more than 64 levels deep" in err
    assert out.read_bytes() == OLD


def _special(tmp_path: Path, kind: str, name: str) -> Path:
    """A FIFO without a writer, or a link to /dev/zero, named ``name``."""
    p = tmp_path / name
    if kind == "fifo":
        os.mkfifo(p)
    else:
        p.symlink_to("/dev/zero")
    return p


SPECIAL_INPUTS = {
    "params": (["linearize", "--params", "{f}"], "x.toml", "parameter file"),
    "gains": (["simulate", "--plant", "linear", "--gains", "{f}", "--out", "{d}/r.csv"],
              "g.toml", "gains file"),
    "run-csv": (["metrics", "{f}"], "run.csv", "run CSV"),
    "plot-csv": (["plot", "{f}", "--out", "{d}/f.png"], "run.csv", "run CSV"),
    "points-csv": (["fis", "eval", "{sys}", "--at", "{f}"], "p.csv", "points CSV"),
    "fuzzy-file": (["fis", "info", "{f}"], "s.fis", ""),
    "du-system": (["simulate", "--plant", "linear", "--controller", "fpi", "--gains",
                   "ke=10,kde=5000,kdu=0.006", "--du-system", "{f}", "--out", "{d}/r.csv"],
                  "s.fcl", ""),
    "sweep-spec": (["sweep", "{f}", "--out", "{d}/sw"], "s.toml", "sweep spec"),
}


@pytest.mark.parametrize("kind", ["fifo", "device"])
@pytest.mark.parametrize("case", sorted(SPECIAL_INPUTS))
def test_issue29_fifos_and_devices_are_refused_as_inputs(tmp_path: Path, kind: str,
                                                         case: str) -> None:
    """A FIFO with no writer would block for ever and /dev/zero would be read until memory
    runs out: both end at once, on one line (a subprocess, so a hang fails on its timeout)."""
    argv, name, what = SPECIAL_INPUTS[case]
    f = _special(tmp_path, kind, name)
    system = Path(__file__).resolve().parents[2] / "src/fuzzyservo/data/systems/paper-du.fis"
    args = [a.replace("{f}", str(f)).replace("{d}", str(tmp_path)).replace("{sys}", str(system))
            for a in argv]
    proc = subprocess.run([sys.executable, "-m", "fuzzyservo", *args], capture_output=True,
                          text=True, timeout=300, check=False)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    shown = f"{what} '{f}'" if what else f"'{f}'"
    is_ = "a FIFO (named pipe)" if kind == "fifo" else "a character device"
    assert proc.stderr.splitlines()[-1] == (f"fuzzyservo: error: {shown} is {is_}, not a "
                                            f"regular file; give a file")
    # before the error line, at most the notices of a first compile of the kernels
    assert all(ln.startswith("fuzzyservo: compil") for ln in proc.stderr.splitlines()[:-1])


def test_issue29_dev_zero_as_a_sweep_spec_is_refused_at_once(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = _error(["sweep", "/dev/zero", "--out", str(tmp_path / "x")], capsys)
    assert "sweep spec '/dev/zero' is a character device, not a regular file" in err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("case", ["params", "gains", "fuzzy-file"])
def test_issue29_a_file_over_the_input_limit_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str) -> None:
    """A sparse file of 16 MiB + 1 byte: refused from one bounded read, whatever its size."""
    argv, name, what = SPECIAL_INPUTS[case]
    f = tmp_path / name
    with f.open("wb") as fh:
        fh.truncate(16 * 1024 * 1024 + 1)
    err = _error([a.replace("{f}", str(f)).replace("{d}", str(tmp_path)) for a in argv], capsys)
    shown = f"{what} '{f}'" if what else f"'{f}'"
    assert f"{shown} is larger than the 16777216-byte limit of an input file" in err


def test_issue29_a_csv_line_without_an_end_is_refused(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    """A sparse run CSV of 1 GiB of zeros is one endless line: refused after 1 MiB."""
    f = tmp_path / "run.csv"
    with f.open("wb") as fh:
        fh.write(b"t,r,y,u\n")
        fh.truncate(1 << 30)
    err = _error(["metrics", str(f)], capsys)
    assert f"run CSV '{f}' line 2 is longer than 1048576 bytes (at offset 8)" in err
