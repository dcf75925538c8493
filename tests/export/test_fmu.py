"""The FMUs: FMPy validates them; the servo FMU in open loop equals ``fuzzyservo simulate
--open-loop``, and the controller FMU and the servo FMU connected by the small master loop
below equal ``fuzzyservo simulate`` of the same loop, within 1e-9 of the stroke (the
acceptance; both are ports of the same code on the same bits, so the observed difference is
0 or rounding)."""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from fuzzyservo.cli import main
from fuzzyservo.control.command import CommandSchedule
from fuzzyservo.files import read_gains_file
from fuzzyservo.formats import read_system, write_system
from fuzzyservo.fuzzy import FuzzySystem, Term, Variable
from fuzzyservo.fuzzy.loop import loop_system
from fuzzyservo.paper import paper_fuzzy_system
from fuzzyservo.paper.published import named_set
from fuzzyservo.plant import with_overrides
from fuzzyservo.registry import build_controller, build_plant, controller_names
from fuzzyservo.run import RunSpec
from fuzzyservo.sim import simulate, simulate_open_loop
from fuzzyservo.sim.closed_loop import run_loop, time_grid
from fuzzyservo.sim.disturbances import load_force_samples
from tests.export.fmu_harness import slaves

ROOT = Path(__file__).resolve().parents[2]
GAINS = ROOT / "src" / "fuzzyservo" / "data" / "gains"
SYSTEMS = ROOT / "src" / "fuzzyservo" / "data" / "systems"
PARAMS = named_set("paper")
STROKE = PARAMS.cylinder.stroke
#: The acceptance's bound on positions [m].
TOL = 1e-9 * STROKE
#: A load the servo is trimmed against at rest (the FMUs built with it) [N].
FEXT = 3000.0


def _export(argv: list[str]) -> None:
    assert main(["export", "fmu", *argv]) == 0


def _general_form(role: str) -> FuzzySystem:
    """The paper's system with its output triangles written as degenerate trapezoids: the
    same sets, evaluated by the general evaluator (the shipped files take the uniform grid)."""
    s = paper_fuzzy_system(role)
    o = s.outputs[0]
    out = Variable(o.name, o.range, tuple(
        Term(t.name, "trapezoid", (t.params[0], t.params[1], t.params[1], t.params[2]))
        for t in o.terms), o.default)
    return FuzzySystem.from_table(
        [[o.terms[k].name for k in row] for row in s.rule_table()], columns=s.inputs[0],
        rows=s.inputs[1], output=out, name=s.name)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("fmus")
    out: dict[str, Path] = {}
    for kind in controller_names():
        gains = GAINS / f"nonlinear-{kind}.toml"
        if gains.exists():
            argv = ["--gains", str(gains)]
        else:
            argv = ["--controller", kind, "--gains", "kp=20" if kind == "p" else "kp=20,ki=20"]
        out[kind] = d / f"{kind}.fmu"
        _export([*argv, "--out", str(out[kind])])
    out["stfpi-files"] = d / "stfpi-files.fmu"
    _export(["--gains", str(GAINS / "nonlinear-stfpi.toml"), "--du-system",
             str(SYSTEMS / "paper-du.fcl"), "--alpha-system", str(SYSTEMS / "paper-alpha.fis"),
             "--name", "stfpi_files", "--out", str(out["stfpi-files"])])
    for role in ("du", "alpha"):  # beside the FMU (test_master_loop_... reads them)
        write_system(_general_form(role), d / f"general-{role}.fll")
    out["stfpi-general"] = d / "stfpi-general.fmu"
    _export(["--gains", str(GAINS / "nonlinear-stfpi.toml"), "--du-system",
             str(d / "general-du.fll"), "--alpha-system", str(d / "general-alpha.fll"),
             "--name", "stfpi_general", "--out", str(out["stfpi-general"])])
    out["stfpi-float"] = d / "stfpi-float.fmu"
    _export(["--gains", str(GAINS / "nonlinear-stfpi.toml"), "--float", "--name",
             "stfpi_float", "--out", str(out["stfpi-float"])])
    for plant in ("linear", "small-signal", "nonlinear"):
        for delay in ("0", "hose"):
            key = f"servo-{plant}-{delay}"
            out[key] = d / f"{key}.fmu"
            _export(["--plant", plant, "--delay", delay, "--out", str(out[key])])
    out["servo-nonlinear-frac"] = d / "servo-nonlinear-frac.fmu"
    _export(["--plant", "nonlinear", "--delay", "0.0025", "--param",
             "load.mass=150", "--start", "0.3", "--out", str(out["servo-nonlinear-frac"])])
    for plant in ("linear", "small-signal"):  # a load at rest: F_op != 0 (issue 25)
        key = f"servo-{plant}-fext"
        out[key] = d / f"{key}.fmu"
        _export(["--plant", plant, "--delay", "0.0025", "--param",
                 f"load.external_force={FEXT!r}", "--start", "0.3", "--out", str(out[key])])
    return out


def test_fmpy_validates_every_fmu(fmus: dict[str, Path]) -> None:
    problems = {k: validate_fmu(str(p)) for k, p in fmus.items()}
    assert all(v == [] for v in problems.values()), problems
    md = read_model_description(str(fmus["stfpi"]))
    causal = {v.name: (v.causality, v.variability) for v in md.modelVariables}
    assert causal["r"] == causal["y"] == ("input", "continuous")
    assert causal["u"] == ("output", "discrete") and causal["alpha"][0] == "output"
    assert {k: causal[k] for k in ("ke", "kde", "kdu")} == dict.fromkeys(
        ("ke", "kde", "kdu"), ("parameter", "tunable"))
    assert md.defaultExperiment.stepSize == "0.001"
    md = read_model_description(str(fmus["servo-nonlinear-0"]))
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    assert outputs == ["y", "spool_lag", "spool", "spool_rate", "p_f", "p_n", "x", "v"]


def _csv(path: Path) -> dict[str, np.ndarray]:
    with path.open() as fh:
        rows = list(csv.reader(fh))
    return {h: np.array([float(r[i]) for r in rows[1:]]) for i, h in enumerate(rows[0])}


@pytest.mark.parametrize("plant", ["linear", "small-signal", "nonlinear"])
@pytest.mark.parametrize("delay", ["0", "hose"])
def test_servo_fmu_open_loop_equals_simulate_open_loop(
        plant: str, delay: str, fmus: dict[str, Path], tmp_path: Path) -> None:
    """FMPy's own master (simulate_fmu) with a constant command against the CLI's CSV."""
    csv_path = tmp_path / "run.csv"
    command = "0.3"
    assert main(["simulate", "--plant", plant, "--open-loop", "--command", command,
                 "--delay", delay, "--duration", "1", "--out", str(csv_path)]) == 0
    ref = _csv(csv_path)
    res = simulate_fmu(str(fmus[f"servo-{plant}-{delay}"]), stop_time=1.0, step_size=1e-3,
                       output_interval=1e-3, start_values={"u": float(command)})
    assert np.allclose(res["time"], ref["t"], rtol=0, atol=1e-12)
    worst = {}
    for name in res.dtype.names[1:]:
        scale = STROKE if name in ("y", "x") else max(1.0, float(np.ptp(ref[name])),
                                                      float(np.max(np.abs(ref[name]))))
        worst[name] = float(np.max(np.abs(res[name] - ref[name]))) / scale
    assert max(worst.values()) <= 1e-9, worst
    assert float(np.ptp(ref["x"])) > 1e-3  # it moved


def test_servo_fmu_follows_a_random_command_schedule(fmus: dict[str, Path]) -> None:
    """Commands that change every sample, at the limits too, with a fractional delay,
    another load and start: the FMU stepped by hand against simulate_open_loop."""
    rng = np.random.default_rng(12)
    n = 800
    u = np.clip(np.cumsum(rng.normal(0, 0.08, n)), -1.0, 1.0)
    params = named_set("paper")
    from fuzzyservo.plant import with_overrides

    params = with_overrides(params, {"load.mass": 150.0})
    plant = build_plant("nonlinear", params, 0.3 * STROKE)
    ref = simulate_open_loop(plant, u, duration=n * 1e-3, dt=1e-3, delay=0.0025)
    with slaves((fmus["servo-nonlinear-frac"], "servo")) as (servo,):
        servo.fmu.exitInitializationMode()
        y = [servo.get("y")[0]]
        t = 0.0
        for k in range(n):
            servo.set(u=float(u[k]))
            servo.fmu.doStep(t, 1e-3)
            t += 1e-3
            y.append(servo.get("y")[0])
    assert len(y) == len(ref.y) == n + 1
    assert np.max(np.abs(np.array(y) - ref.y)) <= TOL
    assert np.ptp(ref.y) > 1e-3


def _master(ctl_path: Path, servo_path: Path, r: np.ndarray, *,
            change: tuple[int, str, float] | None = None,
            force: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The small master loop: at t_k the controller reads (r_k, y_k) and steps, its u_k goes
    to the servo, which steps to t_{k+1} (under the load force F_k when ``force`` is given);
    returns the y_k and u_k."""
    ys, us = [], []
    with slaves((ctl_path, "ctl"), (servo_path, "servo")) as (ctl, servo):
        servo.fmu.exitInitializationMode()
        y0 = servo.get("y")[0]
        ctl.set(u_start=servo.get("u_trim")[0], y=y0, r=y0)
        ctl.fmu.exitInitializationMode()
        y = y0
        t = 0.0
        for k, rk in enumerate(r):
            if change is not None and k == change[0]:
                ctl.set(**{change[1]: change[2]})
            ctl.set(r=float(rk), y=y)
            ctl.fmu.doStep(t, 1e-3)
            u = ctl.get("u")[0]
            ys.append(y)
            us.append(u)
            servo.set(u=u)
            if force is not None:
                servo.set(load_force=float(force[k]))
            servo.fmu.doStep(t, 1e-3)
            t += 1e-3
            y = servo.get("y")[0]
    return np.array(ys), np.array(us)


CASES = [("pid", "nonlinear", "hose"), ("pid2", "nonlinear", "0"), ("fpi", "linear", "hose"),
         ("stfpi", "nonlinear", "hose"), ("stfpi", "linear", "0"),
         ("stfpi-files", "nonlinear", "0"), ("stfpi-general", "nonlinear", "0"),
         ("p", "small-signal", "0"),
         ("pi", "nonlinear", "0")]


@pytest.mark.parametrize("key, plant, delay", CASES)
def test_master_loop_of_the_two_fmus_equals_simulate(key: str, plant: str, delay: str,
                                                     fmus: dict[str, Path]) -> None:
    kind = key.split("-")[0]
    systems = None
    if key == "stfpi-files":
        # the shipped files have the uniform-grid form: the exported FMU takes that path
        systems = {"du": loop_system(read_system(SYSTEMS / "paper-du.fcl")),
                   "alpha": loop_system(read_system(SYSTEMS / "paper-alpha.fis"))}
        assert all(v.packed.path == "uniform grid" for v in systems.values())
    elif key == "stfpi-general":
        # the same sets in the general evaluator's form (the partition path), in both
        folder = fmus["stfpi-general"].parent
        systems = {r: loop_system(read_system(folder / f"general-{r}.fll"))
                   for r in ("du", "alpha")}
        assert all(v.packed.path == "partition" for v in systems.values())
    path = GAINS / f"nonlinear-{kind}.toml"
    gains = dict(read_gains_file(path).gains) if path.exists() else (
        {"kp": 20.0} if kind == "p" else {"kp": 20.0, "ki": 20.0})
    plant_obj = build_plant(plant, PARAMS, 0.5 * STROKE)
    ctl = build_controller(kind, gains, dt=1e-3, systems=systems)
    n = 1500
    offsets = np.where(np.arange(n) < 700, 0.1, -0.15)
    res = simulate(ctl, plant_obj, offsets, duration=(n - 1) * 1e-3,
                   delay=PARAMS.delay.transport_delay if delay == "hose" else 0.0)
    y, u = _master(fmus[key], fmus[f"servo-{plant}-{delay}"], res.r)
    assert np.max(np.abs(y - res.y)) <= TOL, np.max(np.abs(y - res.y))
    assert np.max(np.abs(u - res.u)) <= 1e-9, np.max(np.abs(u - res.u))
    assert np.ptp(res.y) > 0.1  # the loop followed the steps


def test_float_controller_fmu_in_the_loop(fmus: dict[str, Path]) -> None:
    """The float build in the loop stays near the double one: 1e-5 of the stroke (float
    commands differ by ~1e-6, a stable loop does not amplify them)."""
    gains = dict(read_gains_file(GAINS / "nonlinear-stfpi.toml").gains)
    plant = build_plant("nonlinear", PARAMS, 0.5 * STROKE)
    res = simulate(build_controller("stfpi", gains, dt=1e-3), plant, np.full(1001, 0.1),
                   duration=1.0)
    y, _u = _master(fmus["stfpi-float"], fmus["servo-nonlinear-0"], res.r)
    dev = float(np.max(np.abs(y - res.y)))
    assert 0.0 < dev <= 1e-5 * STROKE, dev


def test_a_tuned_gain_takes_effect_at_the_next_sample(fmus: dict[str, Path]) -> None:
    """Setting kdu through the FMU mid-run equals the Python controller whose kdu changes
    at that sample (per-step API: the same state, a controller with the new gain)."""
    gains = dict(read_gains_file(GAINS / "linear-fpi.toml").gains)
    n, k_change, new = 1000, 400, gains["kdu"] * 1.5
    plant = build_plant("linear", PARAMS, 0.5 * STROKE)
    r = np.full(n, plant.y0 + 0.1)
    y_f, u_f = _master(fmus_linear_fpi(fmus, gains), fmus["servo-linear-0"], r,
                       change=(k_change, "kdu", new))
    a = build_controller("fpi", gains, dt=1e-3)
    b = build_controller("fpi", {**gains, "kdu": new}, dt=1e-3)
    state: Any = a.initial_state(u0=plant.u0)
    u_py = []
    for k in range(n):
        u_k, state = (a if k < k_change else b).step(state, r[k], y_f[k])
        u_py.append(u_k)
    assert np.max(np.abs(np.array(u_py) - u_f)) <= 1e-12


def fmus_linear_fpi(fmus: dict[str, Path], gains: dict[str, float]) -> Path:
    path = fmus["fpi"].with_name("fpi-linear.fmu")
    if not path.exists():
        _export(["--controller", "fpi", "--gains", ",".join(f"{k}={v!r}" for k, v in
                                                           gains.items()),
                 "--out", str(path), "--name", "fpi_lin"])
    return path


def test_fmu_refuses_steps_that_skip_a_sample(fmus: dict[str, Path]) -> None:
    with slaves((fmus["pi"], "ctl"), (fmus["servo-linear-0"], "servo")) as (ctl, servo):
        ctl.fmu.exitInitializationMode()
        servo.fmu.exitInitializationMode()
        ctl.fmu.doStep(0.0, 5e-4)  # shorter than ts: fine, u held
        ctl.fmu.doStep(5e-4, 5e-4)
        with pytest.raises(Exception, match="(?i)error"):
            ctl.fmu.doStep(1e-3, 2e-3)  # passes the sample at 2 ms
        with pytest.raises(Exception, match="(?i)error"):
            servo.fmu.doStep(0.0, 1.5e-3)  # not a whole number of samples


def test_no_filter_pid_fmu_is_valid(tmp_path: Path) -> None:
    """n = inf (no derivative filter) is written as XML's INF: the model description stays
    valid and the start value reads back as infinity."""
    out = tmp_path / "pid_inf.fmu"
    _export(["--controller", "pid", "--gains", "kp=5,ki=10,kd=0.1,n=inf", "--out", str(out)])
    assert validate_fmu(str(out)) == []
    md = read_model_description(str(out))
    n = next(v for v in md.modelVariables if v.name == "n")
    assert float(n.start) == float("inf") and n.causality == "parameter"


def test_a_step_from_elsewhere_or_not_finite_is_an_error(fmus: dict[str, Path]) -> None:
    for key in ("pi", "servo-linear-0"):
        for t, h in ((0.0, float("nan")), (float("inf"), 1e-3), (5e-3, 1e-3), (0.0, -1e-3)):
            with slaves((fmus[key], "x")) as (x,):
                x.fmu.exitInitializationMode()
                with pytest.raises(Exception, match="(?i)error"):
                    x.fmu.doStep(t, h)


DRIVER = r"""
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    va_list ap;
    (void)env;
    (void)name;
    (void)category;
    va_start(ap, message);
    printf("log %d: ", (int)status);
    vprintf(message, ap);
    printf("\n");
    va_end(ap);
}

#define CHECK(x) \
    do { if (!(x)) { printf("FAILED %s (line %d)\n", #x, __LINE__); return 1; } } while (0)

int main(void)
{
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c;
    fmi2FMUstate st = NULL, st2 = NULL;
    fmi2ValueReference vr_in[1] = {IN_VR}, vr_out[1] = {OUT_VR};
    fmi2Real v = 0.3, out1, out2, t = 0.0;
    size_t n = 0;
    fmi2Byte *buf;
    int k;
    CHECK(fmi2Instantiate("x", fmi2CoSimulation, "{wrong}", "", &cb, 0, 0) == NULL);
    CHECK(fmi2Instantiate("x", fmi2ModelExchange, GUID, "", &cb, 0, 0) == NULL);
    c = fmi2Instantiate("x", fmi2CoSimulation, GUID, "", &cb, 0, 1);
    CHECK(c != NULL);
    CHECK(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == fmi2OK);
    CHECK(fmi2EnterInitializationMode(c) == fmi2OK);
    CHECK(fmi2SetReal(c, vr_in, 1, &v) == fmi2OK);
    CHECK(fmi2ExitInitializationMode(c) == fmi2OK);
    for (k = 0; k < 20; k++, t += 1e-3) {
        CHECK(fmi2DoStep(c, t, 1e-3, fmi2True) == fmi2OK);
    }
    CHECK(fmi2GetFMUstate(c, &st) == fmi2OK);
    CHECK(fmi2DoStep(c, t, 1e-3, fmi2True) == fmi2OK);
    CHECK(fmi2GetReal(c, vr_out, 1, &out1) == fmi2OK);
    CHECK(fmi2SerializedFMUstateSize(c, st, &n) == fmi2OK);
    buf = (fmi2Byte *)malloc(n);
    CHECK(fmi2SerializeFMUstate(c, st, buf, n) == fmi2OK);
    CHECK(fmi2DeSerializeFMUstate(c, buf, n, &st2) == fmi2OK);
    CHECK(fmi2SetFMUstate(c, st2) == fmi2OK);
    CHECK(fmi2DoStep(c, t, 1e-3, fmi2True) == fmi2OK); /* the same step again */
    CHECK(fmi2GetReal(c, vr_out, 1, &out2) == fmi2OK);
    CHECK(out1 == out2);
    buf[n - 1] ^= 0x7f; /* a corrupted state (the phase or time) is refused */
    memset(buf + n - sizeof(int) * 2, 0x7f, sizeof(int));
    CHECK(fmi2DeSerializeFMUstate(c, buf, n - 1, &st2) == fmi2Error);
    CHECK(fmi2Reset(c) == fmi2OK);
    CHECK(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == fmi2OK);
    CHECK(fmi2EnterInitializationMode(c) == fmi2OK);
    CHECK(fmi2ExitInitializationMode(c) == fmi2OK);
    CHECK(fmi2DoStep(c, 0.0, 0.0 / 0.0 + 1e-3, fmi2True) == fmi2Error);
    CHECK(fmi2GetReal(c, vr_out, 1, &out1) == fmi2OK); /* readable in the error state */
    CHECK(fmi2FreeFMUstate(c, &st) == fmi2OK && st == NULL);
    CHECK(fmi2FreeFMUstate(c, &st2) == fmi2OK);
    free(buf);
    fmi2FreeInstance(c);
    printf("done\n");
    return 0;
}
"""


@pytest.mark.parametrize("key, in_name, out_name", [("stfpi", "y", "u"),
                                                    ("servo-nonlinear-hose", "u", "x")])
def test_the_fmi_wrapper_under_the_sanitizers(key: str, in_name: str, out_name: str,
                                              fmus: dict[str, Path], tmp_path: Path) -> None:
    """The FMU's own sources with a C driver of the FMI calls (instantiate, wrong GUID and
    type, initialise, steps, get/set/serialise/deserialise the state and replay a step,
    a corrupted state, reset, a NaN step, free), built with -O2 -fsanitize=address,undefined:
    every call answers as FMI 2.0 says and the sanitizers find nothing."""
    import subprocess
    import zipfile

    from tests.export.cbuild import SANITIZE, STRICT, gcc

    md = read_model_description(str(fmus[key]))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    src = tmp_path / "src"
    with zipfile.ZipFile(fmus[key]) as zf:
        names = [n for n in zf.namelist() if n.startswith("sources/")]
        zf.extractall(tmp_path, names)
    (tmp_path / "sources" / "driver.c").write_text(
        DRIVER.replace("IN_VR", str(vr[in_name])).replace("OUT_VR", str(vr[out_name]))
        .replace("GUID", f'"{md.guid}"'))
    src = tmp_path / "sources"
    fmi2 = ROOT / "src" / "fuzzyservo" / "export" / "csrc" / "fmi2"
    exe = tmp_path / "driver"
    cfiles = [str(p) for p in sorted(src.glob("*.c"))]
    proc = subprocess.run([gcc(), *STRICT, *SANITIZE, f"-I{fmi2}", f"-I{src}", "-o", str(exe),
                           *cfiles, "-lm"], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, check=False)
    assert run.returncode == 0 and run.stderr == "", run.stdout + run.stderr
    assert run.stdout.strip().endswith("done")
    assert "must be finite" in run.stdout and "not a state of this FMU" in run.stdout


# --- issue 29, item 5: time as a master accumulates it, the stop time, alpha, units --------

TS = 1e-3
CONTROLLERS = ["p", "pi", "pid", "pid2", "fpi", "stfpi", "stfpi-general"]


def _accumulating_loop(ctl_path: Path, servo_path: Path, n: int, *, start: float,
                       substeps: int, stop: float | None = None
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The controller and the servo in a loop, as a master that accumulates time (t += h,
    each FMU on its own clock): the controller in ``substeps`` steps of ts / substeps per
    sample, the servo in steps of ts. Returns y_k, u_k, alpha_k and the number of steps
    each FMU took (counted, and FMPy raises at the first refused one)."""
    ys, us, alphas = [], [], []
    steps = 0
    with slaves((ctl_path, "ctl"), (servo_path, "servo"), start=start, stop=stop) as (
            ctl, servo):
        servo.fmu.exitInitializationMode()
        y0 = servo.get("y")[0]
        ctl.set(u_start=servo.get("u_trim")[0], y=y0, r=y0)
        ctl.fmu.exitInitializationMode()
        y, t_ctl, t_servo, h = y0, start, start, TS / substeps
        for k in range(n):
            ctl.set(r=y0 + (0.1 if k < n // 2 else -0.05), y=y)
            for _ in range(substeps):
                ctl.fmu.doStep(t_ctl, h)
                t_ctl += h
                steps += 1
            u, a = ctl.get("u", "alpha")
            ys.append(y)
            us.append(u)
            alphas.append(a)
            servo.set(u=u)
            servo.fmu.doStep(t_servo, TS)
            t_servo += TS
            y = servo.get("y")[0]
    assert steps == n * substeps
    return np.array(ys), np.array(us), np.array(alphas), steps


@pytest.mark.parametrize("key", CONTROLLERS)
def test_a_master_accumulating_time_steps_past_a_million_seconds(
        key: str, fmus: dict[str, Path]) -> None:
    """Issue 29: with t + h stepping, a controller FMU refused a step after 334 s (the
    accumulated t missed the sample instant by more than 1e-9 s). Started at 1e6 s - 0.1 s
    and stepped past 1e6 s in quarter samples (2.5e-4 s is not a binary fraction: every
    t + h rounds, by up to 6e-11 s at 1e6 s, so the old test failed within 25 steps), both
    FMUs take every step and compute the very samples of the same loop started at 0 in
    whole samples (bit for bit: nothing in a step depends on t)."""
    n = 400
    ref = _accumulating_loop(fmus[key], fmus["servo-linear-0"], n, start=0.0, substeps=1)
    far = _accumulating_loop(fmus[key], fmus["servo-linear-0"], n, start=1e6 - 0.1,
                             substeps=4)
    assert far[3] == 4 * n and 1e6 - 0.1 + far[3] * TS / 4 > 1e6 + 0.29
    for a, b in zip(ref[:3], far[:3], strict=True):
        np.testing.assert_array_equal(a, b)
    assert np.ptp(ref[0]) > 0.05  # the loop moved


def test_alpha_is_what_simulate_records(fmus: dict[str, Path]) -> None:
    """Issue 29: alpha read 1 in the pid2 and fpi FMUs where simulate writes NaN. Each
    controller's alpha equals simulate's alpha of the same loop, NaN where it is NaN."""
    plant = build_plant("linear", PARAMS, 0.5 * STROKE)
    n = 300
    for key in CONTROLLERS[:-1]:
        path = GAINS / f"nonlinear-{key}.toml"
        gains = dict(read_gains_file(path).gains) if path.exists() else (
            {"kp": 20.0} if key == "p" else {"kp": 20.0, "ki": 20.0})
        offsets = np.where(np.arange(n) < n // 2, 0.1, -0.05)
        res = simulate(build_controller(key, gains, dt=TS), plant, offsets,
                       duration=(n - 1) * TS)
        y, u, alpha, _ = _accumulating_loop(fmus[key], fmus["servo-linear-0"], n, start=0.0,
                                            substeps=1)
        assert res.alpha is not None
        np.testing.assert_array_equal(alpha, res.alpha, err_msg=key)
        assert np.max(np.abs(u - res.u)) <= 1e-9, key
    # the kinds this covers: NaN (no gain-updating factor), 1 (fpi), varying (stfpi)
    assert np.isnan(res.alpha).sum() == 0 and np.ptp(res.alpha) > 0


@pytest.mark.parametrize("key", ["pid2", "stfpi", "servo-linear-0", "servo-nonlinear-hose"])
def test_the_stop_time_is_enforced(key: str, fmus: dict[str, Path],
                                   capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 29, FMI 2.0 (fmi2SetupExperiment): with stopTimeDefined a step past stopTime
    is fmi2Error; it was fmi2OK. Up to the stop (t + h steps from 1e6 s, the last clipped
    to land on it as fmuCheck does) every step is taken; one more step, and a step that
    passes the stop within a sample, are refused for that reason."""
    start, n = 1e6, 50
    stop = start + n * TS
    with slaves((fmus[key], "x"), start=start, stop=stop) as (x,):
        x.fmu.exitInitializationMode()
        t, taken = start, 0
        for _ in range(n - 1):
            x.fmu.doStep(t, TS)
            t += TS
            taken += 1
        x.fmu.doStep(t, stop - t)
        taken += 1
        assert taken == n
        capsys.readouterr()
        with pytest.raises(Exception, match="(?i)error"):
            x.fmu.doStep(stop, TS)
        assert "passes the stop time" in capsys.readouterr().out
    with slaves((fmus[key], "y"), start=0.0, stop=2.5 * TS) as (y,):
        y.fmu.exitInitializationMode()
        y.fmu.doStep(0.0, TS)
        y.fmu.doStep(TS, TS)
        capsys.readouterr()
        with pytest.raises(Exception, match="(?i)error"):
            y.fmu.doStep(2 * TS, TS)
        assert "passes the stop time" in capsys.readouterr().out
    with slaves((fmus[key], "z"), start=0.0) as (z,):  # no stop time: no limit
        z.fmu.exitInitializationMode()
        for k in range(5):
            z.fmu.doStep(k * TS, TS)


FMUCHECK_LOOP = r"""
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    va_list ap;
    (void)env;
    (void)name;
    (void)status;
    (void)category;
    va_start(ap, message);
    printf("log: ");
    vprintf(message, ap);
    printf("\n");
    va_end(ap);
}

/* The FMI Compliance Checker's co-simulation loop (fmi2_cs_sim.c): tnext = tcur + h, the
 * last step clipped to land on tend when the FMU takes variable steps. Prints the steps
 * taken and the time reached. */
int main(int argc, char **argv)
{
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    double tstart, tend, h, tcur;
    int clip, stop_defined;
    long steps = 0;
    fmi2Component c;
    if (argc != 6) {
        return 2;
    }
    tstart = atof(argv[1]);
    tend = atof(argv[2]);
    h = atof(argv[3]);
    clip = atoi(argv[4]);
    stop_defined = atoi(argv[5]);
    tcur = tstart;
    c = fmi2Instantiate("x", fmi2CoSimulation, GUID, "", &cb, 0, 0);
    if (c == NULL || fmi2SetupExperiment(c, 0, 0.0, tstart, stop_defined, tend) != fmi2OK
        || fmi2EnterInitializationMode(c) != fmi2OK
        || fmi2ExitInitializationMode(c) != fmi2OK) {
        printf("failed to initialise\n");
        return 1;
    }
    while (tcur < tend) {
        double hstep = h, tnext = tcur + h;
        if (tnext > tend - 1e-3 * h && clip) {
            hstep = tend - tcur;
            tnext = tend;
        }
        if (fmi2DoStep(c, tcur, hstep, fmi2True) != fmi2OK) {
            printf("refused %ld %.17g\n", steps, tcur);
            return 1;
        }
        tcur = tnext;
        steps += 1;
    }
    printf("steps %ld %.17g\n", steps, tcur);
    fmi2Terminate(c);
    fmi2FreeInstance(c);
    return 0;
}
"""


@pytest.mark.parametrize("key, clip", [("stfpi", 1), ("pid", 1), ("servo-nonlinear-0", 0)])
def test_the_compliance_checkers_loop_runs_to_the_end(key: str, clip: int,
                                                      fmus: dict[str, Path],
                                                      tmp_path: Path) -> None:
    """Issue 29: ``fmuCheck.linux64 -k cs -h 0.001 -s 400 stfpi.fmu`` stopped at 334.587 s.
    Its loop, in C against the FMU's sources: 0 to 400 s and 0 to 1000 s in 1 ms steps
    (the last clipped to land on the end, carrying the accumulated rounding: 2.5e-9 s and
    1.7e-8 s), and 1e6 to 1e6 + 200 s, with and without a stop time; the servo, which
    takes whole samples only, unclipped. Every step is taken (counted)."""
    import subprocess
    import zipfile

    from tests.export.cbuild import STRICT, gcc

    md = read_model_description(str(fmus[key]))
    with zipfile.ZipFile(fmus[key]) as zf:
        names = [n for n in zf.namelist() if n.startswith("sources/")]
        zf.extractall(tmp_path, names)
    src = tmp_path / "sources"
    (src / "driver.c").write_text(FMUCHECK_LOOP.replace("GUID", f'"{md.guid}"'))
    fmi2 = ROOT / "src" / "fuzzyservo" / "export" / "csrc" / "fmi2"
    exe = tmp_path / "driver"
    proc = subprocess.run([gcc(), *STRICT, "-O2", f"-I{fmi2}", f"-I{src}", "-o", str(exe),
                           *map(str, sorted(src.glob("*.c"))), "-lm"],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    for tstart, tend in ((0.0, 400.0), (0.0, 1000.0), (1e6, 1e6 + 200.0)):
        n, reached = _fmucheck_steps(tstart, tend, TS, clip)
        # unclipped, the accumulated t may fall short of tend and the loop step past it,
        # which a stop time forbids: the servo runs without one, as fmuCheck runs it
        for stop_defined in (0, 1) if clip else (0,):
            run = subprocess.run([str(exe), repr(tstart), repr(tend), repr(TS), str(clip),
                                  str(stop_defined)], capture_output=True, text=True,
                                 check=False, timeout=600)
            assert run.returncode == 0, run.stdout
            word, steps, t_end = run.stdout.split()
            assert (word, int(steps), float(t_end)) == ("steps", n, reached), run.stdout
            assert n >= round((tend - tstart) / TS)


def _fmucheck_steps(tstart: float, tend: float, h: float, clip: int) -> tuple[int, float]:
    """The steps fmuCheck's loop makes and the time it reaches (the loop in Python: the same
    IEEE double arithmetic, no FMU)."""
    tcur, steps = tstart, 0
    while tcur < tend:
        tnext = tcur + h
        if tnext > tend - 1e-3 * h and clip:
            tnext = tend
        tcur = tnext
        steps += 1
    return steps, tcur


def test_every_variable_has_a_declared_unit(fmus: dict[str, Path]) -> None:
    """Issue 29: ``kde`` had no unit. Every Real variable of every FMU names a unit that the
    model description declares (FMI 2.0 <UnitDefinitions>)."""
    import xml.etree.ElementTree as ET
    import zipfile

    for key, path in fmus.items():
        with zipfile.ZipFile(path) as zf:
            root = ET.fromstring(zf.read("modelDescription.xml"))
        declared = {u.attrib["name"] for u in root.iter("Unit")}
        for v in root.iter("ScalarVariable"):
            unit = v.find("Real").attrib.get("unit")  # type: ignore[union-attr]
            assert unit in declared, (key, v.attrib["name"], unit)
    root = ET.fromstring(zipfile.ZipFile(fmus["stfpi"]).read("modelDescription.xml"))
    kde = next(v for v in root.iter("ScalarVariable") if v.attrib["name"] == "kde")
    assert kde.find("Real").attrib["unit"] == "1/m per sample"  # type: ignore[union-attr]


def test_a_refused_gain_leaves_the_error_state_docs_describe(
        fmus: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    """docs/export.md, "Tuning": a gain out of range is fmi2Error; the instance is then in
    FMI's error state: the gains read back unchanged, a step is refused, a state saved
    before restores it (the run goes on as if the call had not been made), and
    fmi2Reset starts afresh."""
    with slaves((fmus["fpi"], "ctl")) as (ctl,):
        ctl.set(y=0.5, r=0.5)
        ctl.fmu.exitInitializationMode()
        t = 0.0
        for _ in range(5):
            ctl.set(r=0.6)
            ctl.fmu.doStep(t, TS)
            t += TS
        saved = ctl.fmu.getFMUstate()
        before = ctl.get("kdu", "u")
        capsys.readouterr()
        with pytest.raises(Exception, match="(?i)error"):
            ctl.set(kdu=-1.0)
        assert "gain kdu = -1 is out of range" in capsys.readouterr().out
        assert ctl.get("kdu", "u") == before
        with pytest.raises(Exception, match="(?i)error"):
            ctl.fmu.doStep(t, TS)
        ctl.fmu.setFMUstate(saved)
        ctl.fmu.doStep(t, TS)
        after_restore = ctl.get("u")
        ctl.fmu.freeFMUstate(saved)
        ctl.fmu.reset()
        ctl.fmu.setupExperiment(startTime=0.0)
        ctl.fmu.enterInitializationMode()
        ctl.set(y=0.5, r=0.5)
        ctl.fmu.exitInitializationMode()
        t = 0.0
        for _ in range(6):
            ctl.set(r=0.6)
            ctl.fmu.doStep(t, TS)
            t += TS
        assert ctl.get("u") == after_restore  # the same run as if the call had not been made


# --- issue 25: the servo FMU's load force ------------------------------------------------

#: The load step of the closed-loop test: 20 kN opposing extension from 0.5 s on.
LOAD = "step:20000:0.5"


@pytest.mark.parametrize("key, plant, delay", [("pid", "nonlinear", "hose"),
                                               ("pi", "linear", "0"),
                                               ("p", "small-signal", "hose")])
def test_a_load_step_on_the_servo_fmu_equals_simulate_load_force(
        key: str, plant: str, delay: str, fmus: dict[str, Path]) -> None:
    """``simulate --load-force step:F:T`` (its RunSpec) against the master loop of the two
    FMUs, the servo's input ``load_force`` set each sample to the same total force
    (load.external_force + F from T on): positions within the acceptance's 1e-9 of the
    stroke, commands within 1e-9, as the loop without a force."""
    path = GAINS / f"nonlinear-{key}.toml"
    gains = dict(read_gains_file(path).gains) if path.exists() else (
        {"kp": 20.0} if key == "p" else {"kp": 20.0, "ki": 20.0})
    spec = RunSpec(controller=key, gains=tuple(gains.items()), plant=plant,
                   reference="step:0.05", duration=1.2, load_force=LOAD,
                   delay=PARAMS.delay.transport_delay if delay == "hose" else 0.0)
    res = spec.run()
    force = load_force_samples(spec.checked_load_force(), res.t, PARAMS.load.external_force)
    y, u = _master(fmus[key], fmus[f"servo-{plant}-{delay}"], res.r, force=force)
    assert np.max(np.abs(y - res.y)) <= TOL, np.max(np.abs(y - res.y))
    assert np.max(np.abs(u - res.u)) <= 1e-9, np.max(np.abs(u - res.u))
    free = replace(spec, load_force="").run()
    assert np.max(np.abs(res.y - free.y)) > 1e-4  # the force moved the piston


@pytest.mark.parametrize("key, plant", [("servo-nonlinear-frac", "nonlinear"),
                                        ("servo-linear-fext", "linear"),
                                        ("servo-small-signal-fext", "small-signal")])
def test_the_servo_fmu_holds_a_load_force_over_each_step(key: str, plant: str,
                                                         fmus: dict[str, Path]) -> None:
    """A fixed command and a load force that changes at every communication step (steps of
    1 and 3 samples, the force held over the whole step, as u is), about a load at rest
    that is not 0 on the linear plants (F - F_op), with a fractional delay: y and every
    state against the Python loop given the same per-sample forces, within 1e-9 of the
    stroke (positions) and of each state's range."""
    over = ({"load.mass": 150.0} if plant == "nonlinear" else
            {"load.external_force": FEXT})
    params = with_overrides(PARAMS, over)
    plant_obj = build_plant(plant, params, 0.3 * STROKE)
    f_op = params.load.external_force
    rng = np.random.default_rng(25)
    sizes = rng.choice([1, 3], size=300)
    sizes = sizes[np.cumsum(sizes) <= 600]
    n = int(sizes.sum())
    force = np.repeat(f_op + rng.normal(0.0, 8000.0, sizes.size), sizes)
    u = np.full(n + 1, plant_obj.u0)
    run = run_loop(CommandSchedule(dt=TS), plant_obj, u, delay=0.0025,
                   disturbance=np.append(force, force[-1]), noise=np.empty(0),
                   t=time_grid(n * TS, TS), what="open loop")
    with slaves((fmus[key], "servo")) as (servo,):
        assert servo.get("load_force") == [f_op]  # the start value: the load at rest
        servo.fmu.exitInitializationMode()
        names = [v.name for v in servo.md.modelVariables if v.causality == "output"]
        rows = [servo.get(*names)]
        t, k = 0.0, 0
        for m in sizes:
            servo.set(u=float(plant_obj.u0), load_force=float(force[k]))
            servo.fmu.doStep(t, m * TS)
            t, k = t + m * TS, k + int(m)
            rows.append(servo.get(*names))
    out = np.array(rows)
    at = np.concatenate([[0], np.cumsum(sizes)])
    ref = np.column_stack([run.y, run.x])[at]
    worst = {}
    for i, name in enumerate(names):
        scale = STROKE if name in ("y", "x") else max(1.0, float(np.ptp(ref[:, i])),
                                                      float(np.max(np.abs(ref[:, i]))))
        worst[name] = float(np.max(np.abs(out[:, i] - ref[:, i]))) / scale
    assert max(worst.values()) <= 1e-9, worst
    assert float(np.ptp(run.y)) > 1e-4  # the force moved it


def test_the_load_force_input_keeps_the_other_value_references(fmus: dict[str, Path]) -> None:
    """``load_force`` [N] is numbered after the existing variables (u 0, the outputs, ts,
    u_trim, delay), so those keep their value references; a non-finite force is refused."""
    for key in ("servo-linear-0", "servo-nonlinear-0"):
        md = read_model_description(str(fmus[key]))
        names = [v.name for v in md.modelVariables]
        assert [v.valueReference for v in md.modelVariables] == list(range(len(names)))
        n_out = sum(v.causality == "output" for v in md.modelVariables)
        assert names[0] == "u" and names[n_out + 1:] == ["ts", "u_trim", "delay", "load_force"]
        lf = md.modelVariables[-1]
        assert (lf.causality, lf.variability, lf.unit, float(lf.start)) == (
            "input", "continuous", "N", PARAMS.load.external_force)
        with slaves((fmus[key], "servo")) as (servo,):
            servo.fmu.exitInitializationMode()
            with pytest.raises(Exception, match="(?i)error"):
                servo.set(load_force=float("nan"))
