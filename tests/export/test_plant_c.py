"""The C port of the servo plant (``fuzzyservo.export.plant_c`` and ``csrc/plant.c``) against
the Python it mirrors.

Every case compiles the fragment, the generated source and a small C driver with the strict
flags (``-std=c99 -Wall -Wextra -Werror -pedantic -O2``), drives ``fs_servo_sample`` with a
command schedule and compares each output at each sample with ``simulate_open_loop`` (or,
for commands beyond the rated input, which the open loop refuses, with the closed loop's
``run_loop`` under the same pass-through controller the open loop uses). The cases cover the
three registered plants, the paper's parameters and a changed set, no delay, fractional
delays, the hose delay and several whole samples, two sample times and two RK4 substeps.
One more build runs under AddressSanitizer and UndefinedBehaviorSanitizer.

Tolerance: 1e-12 of the stroke on outputs in metres (y, x), 1e-12 of the output's largest
magnitude in the run on the others (of one SI unit when it is 0 throughout). The C does the
numba kernels' operations in the same order, so the observed difference is 0 (bit-identical);
the tolerance leaves room for a libm that rounds sin/exp/tanh differently from the one numba
calls, or a build that fuses multiply-adds (-ffp-contract=fast with FMA: 3e-15 relative).

Builds go through ``tests/export/cbuild.py``; gcc is required: without it these tests fail.
"""

from __future__ import annotations

import ctypes
import math
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fuzzyservo.cli import main
from fuzzyservo.control.command import CommandSchedule
from fuzzyservo.errors import ParameterError, SimulationDivergedError
from fuzzyservo.export.plant_c import ServoC, emit_servo, plant_fragment, substep_split
from fuzzyservo.paper import named_set
from fuzzyservo.plant import COMMAND_LIMIT, ServoParams, with_overrides
from fuzzyservo.plant import nonlinear as nl
from fuzzyservo.registry import build_controller, build_plant
from fuzzyservo.sim import (
    LinearPlant,
    NonlinearPlant,
    parse_reference,
    simulate,
    simulate_open_loop,
)
from fuzzyservo.sim.closed_loop import run_loop, time_grid
from fuzzyservo.sim.disturbances import load_force_samples, parse_load_force
from tests.export.cbuild import compile_executable, compile_shared

#: Relative tolerance of every comparison (module docstring).
REL = 1e-12

#: A changed parameter set: valve lag (a seventh linear state), transducer resolution, supply
#: ripple, load force, leakage, dead volume and a pressure floor, each a branch the paper's set
#: leaves untaken (``--param`` names).
CHANGED = {
    "valve.tau_v": 2e-3,
    "transducer.resolution": 1e-5,
    "supply.ripple_amplitude": 3e5,
    "load.external_force": 2.0e3,
    "cylinder.internal_leakage": 1e-13,
    "cylinder.dead_volume_f": 5e-5,
    "fluid.pressure_floor": 2e4,
}


def _params(name: str) -> ServoParams:
    if name == "changed":
        return with_overrides(named_set("paper"), CHANGED)
    return named_set(name)


# --- the C driver -----------------------------------------------------------------------

#: Appended to each generated plant: runs a schedule (and a load force per sample unless
#: ``force`` is NULL), writes t then every output per sample (rows of FS_SERVO_NX + 2), returns
#: the first sample whose state is non-finite, or -1.
DRIVER = r"""
int fs_run_@ID@(const double *u, const double *force, int n, double *out)
{
    fs_servo s;
    int i, k, bad = -1;
    fs_servo_init(&s);
    for (k = 0;; k++) {
        double *row = out + (long)k * (FS_SERVO_NX + 2);
        row[0] = fs_servo_time(&s);
        for (i = 0; i <= FS_SERVO_NX; i++) {
            row[1 + i] = fs_servo_output(&s, i);
        }
        if (k == n) {
            break;
        }
        if (force != 0 && fs_servo_set_force(&s, force[k]) != 0) {
            return -2;
        }
        if (fs_servo_sample(&s, u[k]) != 0 && bad < 0) {
            bad = k + 1;
        }
    }
    return bad;
}

int fs_outside_@ID@(void)
{
    fs_servo s;
    fs_servo_init(&s);
    return isnan(fs_servo_output(&s, -1)) && isnan(fs_servo_output(&s, FS_SERVO_NX + 1));
}

double fs_force_@ID@(void)
{
    fs_servo s;
    fs_servo_init(&s);
    return fs_servo_force(&s);
}
"""


def _unit(cid: str, sc: ServoC) -> str:
    return plant_fragment() + "\n" + sc.source + "\n" + DRIVER.replace("@ID@", cid)


def _run_c(lib: ctypes.CDLL, cid: str, sc: ServoC, u: np.ndarray,
           force: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    fn = getattr(lib, f"fs_run_{cid}")
    fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p]
    fn.restype = ctypes.c_int
    u = np.ascontiguousarray(u, dtype=np.float64)
    f = None if force is None else np.ascontiguousarray(force, dtype=np.float64)
    assert f is None or f.size >= u.size
    out = np.zeros((u.size + 1, len(sc.outputs) + 1))
    bad = fn(u.ctypes.data, None if f is None else f.ctypes.data, u.size, out.ctypes.data)
    return out, int(bad)


# --- the Python reference ----------------------------------------------------------------


def _python_run(plant: Any, u: np.ndarray, ts: float, delay: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, y, states) of the Python open loop under the schedule ``u``."""
    n = u.size
    if np.all(np.abs(u) <= COMMAND_LIMIT):
        res = simulate_open_loop(plant, u, duration=n * ts, dt=ts, delay=delay)
        return res.t, res.y, res.states
    # simulate_open_loop refuses commands beyond the rated input; its loop takes them, as it
    # takes a controller's whose limits exceed it
    t = time_grid(n * ts, ts)
    run = run_loop(CommandSchedule(dt=ts), plant, np.append(u, u[-1]), delay=delay,
                   disturbance=None, noise=np.empty(0), t=t, what="open loop")
    return t, run.y, run.x


def _schedule(kind: str, n: int, seed: int) -> np.ndarray:
    """Steps of random length and level, one random value per sample, or steps reaching
    beyond the rated input (COMMAND_LIMIT)."""
    rng = np.random.default_rng(seed)
    if kind == "random":
        return rng.uniform(-1.0, 1.0, n)
    hi = 1.6 if kind == "beyond" else 1.0
    u = np.empty(n)
    k = 0
    while k < n:
        m = int(rng.integers(3, 60))
        u[k:k + m] = rng.uniform(-hi, hi)
        k += m
    if kind == "beyond":
        u[: n // 4] = 1.5  # past the limit for a while in each direction
        u[n // 4: n // 2] = -1.3
    return u


@dataclass(frozen=True)
class Case:
    """One comparison."""

    cid: str
    plant: str  #: registered name
    params: str  #: "paper", "changed" or another named set
    ts: float  #: [s]
    delay: float | str  #: [s] or "hose"
    schedule: str  #: "steps", "random", "beyond", or "stop" (into the end stop)
    substep: float = 5e-4  #: [s]
    start: float = 0.5  #: fraction of the stroke
    n: int = 0  #: samples (0: about 0.3 s)

    def delay_s(self) -> float:
        if self.delay == "hose":
            return float(_params(self.params).delay.transport_delay)
        return float(self.delay)

    def samples(self) -> int:
        return self.n or int(round(0.3 / self.ts))

    def commands(self, seed: int) -> np.ndarray:
        n = self.samples()
        if self.schedule == "stop":  # full speed into the cap-side stop, then off it
            u = np.full(n, -1.0)
            u[2 * n // 3:] = 0.8
            return u
        return _schedule(self.schedule, n, seed)


#: Delays per sample time: none, a fraction (2.5 samples; 1.5 at 2.5 ms), the hose delay
#: (6 samples at 1 ms, 2.4 at 2.5 ms), several whole samples.
DELAYS: dict[float, tuple[float | str, ...]] = {1e-3: (0.0, 0.0025, "hose", 0.004),
                                               2.5e-3: (0.0, 0.00375, "hose", 0.01)}
SCHEDULES = ("steps", "random", "beyond")


def _cases() -> list[Case]:
    cases: list[Case] = []
    for plant in ("linear", "small-signal", "nonlinear"):
        substeps = (5e-4, 1e-4) if plant == "nonlinear" else (5e-4,)
        for params in ("paper", "changed"):
            for ts, delays in DELAYS.items():
                for delay in delays:
                    for sub in substeps:
                        sched = SCHEDULES[len(cases) % len(SCHEDULES)]
                        cases.append(Case(f"c{len(cases)}", plant, params, ts, delay, sched,
                                          substep=sub))
    k = len(cases)
    cases += [
        # an exact half in round(n_sub f / ts) = round(5 * 2^-10 / 2^-9): half to even, 2
        Case(f"c{k}", "nonlinear", "changed", 2.0**-9, 1.5 * 2.0**-9, "steps", substep=4e-4),
        # into the end stop at 0 (cushion force, cavitation at the pressure floor)
        Case(f"c{k + 1}", "nonlinear", "paper", 1e-3, 0.0025, "stop", start=0.02),
        Case(f"c{k + 2}", "nonlinear", "changed", 1e-3, 0.0, "stop", start=0.02),
        Case(f"c{k + 3}", "nonlinear", "stiff-oil", 1e-3, "hose", "random"),
        Case(f"c{k + 4}", "small-signal", "stiff-oil", 1e-3, 0.0025, "beyond"),
        # the longest delay a Python run allows, its whole duration: nothing arrives
        Case(f"c{k + 5}", "nonlinear", "paper", 1e-3, 0.05, "random", n=50),
        Case(f"c{k + 6}", "linear", "changed", 1e-3, 0.05, "random", n=50),
    ]
    return cases


CASES = _cases()


def _plant(case: Case) -> Any:
    params = _params(case.params)
    return build_plant(case.plant, params, case.start * params.cylinder.stroke,
                       substep=case.substep)


@dataclass
class Built:
    lib: ctypes.CDLL
    servo: dict[str, ServoC]
    plants: dict[str, Any]


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Built:
    """Every case's plant compiled into one shared library (one gcc call)."""
    servo: dict[str, ServoC] = {}
    plants: dict[str, Any] = {}
    units = []
    for case in CASES:
        plant = _plant(case)
        sc = emit_servo(plant, ts=case.ts, delay=case.delay_s())
        plants[case.cid], servo[case.cid] = plant, sc
        units.append(_unit(case.cid, sc))
    lib = compile_shared(units, tmp_path_factory.mktemp("plant_c"), name="plants")
    return Built(ctypes.CDLL(str(lib)), servo, plants)


def _deviation(out: np.ndarray, t: np.ndarray, y: np.ndarray, states: np.ndarray,
               sc: ServoC) -> list[float]:
    """Largest |C - Python| of each output, in units of its tolerance scale."""
    py = np.column_stack([y, states])
    devs = []
    for i, unit in enumerate(sc.units):
        col = py[:, i]
        scale = sc.stroke if unit == "m" and sc.stroke else float(np.max(np.abs(col)))
        diff = float(np.max(np.abs(out[:, 1 + i] - col)))
        devs.append(diff / (scale or 1.0))  # an output at 0 throughout: one SI unit
    return devs


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c.cid}-{c.plant}-{c.params}-ts"
                         f"{c.ts:g}-d{c.delay}-{c.schedule}-h{c.substep:g}")
def test_c_plant_equals_python(built: Built, case: Case) -> None:
    sc, plant = built.servo[case.cid], built.plants[case.cid]
    u = case.commands(seed=int(case.cid[1:]))
    out, bad = _run_c(built.lib, case.cid, sc, u)
    t, y, states = _python_run(plant, u, case.ts, case.delay_s())
    assert bad == -1
    assert out.shape == (t.size, len(sc.outputs) + 1)
    assert np.array_equal(out[:, 0], t)  # fs_servo_time is the Python's grid, exactly
    devs = _deviation(out, t, y, states, sc)
    worst = max(devs)
    assert worst <= REL, dict(zip(sc.outputs, devs, strict=True))  # module docstring
    if case.schedule == "stop":  # the case reaches what it is meant to
        x = states[:, plant.state_names.index("x")]
        assert x.min() < 0.0
    assert getattr(built.lib, f"fs_outside_{case.cid}")() == 1  # other indices: NaN


def test_the_cases_cover_the_splits(built: Built) -> None:
    """Whole-sample, fractional and exactly-half splits of the delay are among the cases."""
    splits = {(sc.whole_samples, sc.fraction > 0.0) for sc in built.servo.values()}
    assert {(0, False), (2, True), (6, False), (4, False), (1, True)} <= splits
    half = CASES[-7]
    assert built.servo[half.cid].n_split == (2, 3)  # round(2.5) = 2, as Python rounds
    assert substep_split(5, 2.0**-10, 2.0**-9) == (2, 3)
    assert substep_split(1, 0.5e-3, 1e-3) == (1, 1)  # nonlinear_one's floor of one step each
    assert substep_split(10, 0.99e-3, 1e-3) == (9, 1)


@pytest.mark.parametrize("name", ["small-signal", "nonlinear"])
def test_c_plant_in_the_python_closed_loop(tmp_path: Path, name: str) -> None:
    """Fed the commands a PI computed in ``simulate`` (from the measurements, rounded to the
    transducer's resolution), the C plant returns the measurements and states of that run:
    a controller equal to the Python's closes the same loop around it."""
    params = _params("changed")
    plant = build_plant(name, params, 0.4, substep=1e-4)
    ctl = build_controller("pi", {"kp": 40.0, "ki": 8.0}, dt=1e-3,
                           options={"u_min": -1.5, "u_max": 1.5})
    res = simulate(ctl, plant, parse_reference("step:0.05"), duration=0.3, delay=0.0025)
    assert np.max(np.abs(res.u)) > COMMAND_LIMIT  # the limit inside rhs is reached
    sc = emit_servo(plant, ts=1e-3, delay=0.0025)
    lib = compile_shared(_unit("cl", sc), tmp_path)
    out, bad = _run_c(ctypes.CDLL(str(lib)), "cl", sc, res.u[:-1])
    assert bad == -1
    assert np.array_equal(out[:, 0], res.t)
    assert max(_deviation(out, res.t, res.y, res.x, sc)) <= REL


@pytest.mark.parametrize("name", ["linear", "small-signal", "nonlinear"])
def test_c_plant_takes_the_load_force(tmp_path: Path, name: str) -> None:
    """Issue 25: fed the commands of a PI in ``simulate`` under a load force (about the
    changed set's load at rest, F_op = 2 kN; a step and a piecewise-linear ramp, each
    sample's force held over it) and the same forces through ``fs_servo_set_force``, the C
    plant returns that run's measurements and states: the nonlinear plant's force balance,
    the linear plants' superposition through their force column. At init the force is F_op."""
    params = _params("changed")
    plant = build_plant(name, params, 0.4, substep=1e-4)
    ctl = build_controller("pi", {"kp": 40.0, "ki": 8.0}, dt=1e-3)
    load = parse_load_force("pwl:0:0,0.05:0,0.051:-15000,0.2:9000")
    t = time_grid(0.3, 1e-3)
    force = load_force_samples(load, t, params.load.external_force)
    res = simulate(ctl, plant, parse_reference("step:0.02"), duration=0.3, delay=0.0025,
                   disturbance=force)
    free = simulate(ctl, plant, parse_reference("step:0.02"), duration=0.3, delay=0.0025)
    assert np.max(np.abs(res.y - free.y)) > 1e-4  # the force moved it
    sc = emit_servo(plant, ts=1e-3, delay=0.0025)
    assert sc.force_input and sc.force_op == params.load.external_force == 2.0e3
    lib = ctypes.CDLL(str(compile_shared(_unit("lf", sc), tmp_path)))
    lib.fs_force_lf.restype = ctypes.c_double
    assert lib.fs_force_lf() == sc.force_op
    out, bad = _run_c(lib, "lf", sc, res.u[:-1], force)
    assert bad == -1
    assert max(_deviation(out, res.t, res.y, res.x, sc)) <= REL
    out, _ = _run_c(lib, "lf", sc, res.u[:-1])  # the force is what made the difference
    assert np.max(np.abs(out[:, 1] - res.y)) > 1e-4


# --- names, units and the CLI ------------------------------------------------------------


@pytest.mark.parametrize("name", ["linear", "small-signal", "nonlinear"])
def test_outputs_are_the_cli_columns(tmp_path: Path, name: str) -> None:
    """The outputs are the CSV columns of ``fuzzyservo simulate --open-loop`` after t and u,
    and the C reproduces that CSV's numbers (written with repr: exact)."""
    csv = tmp_path / "run.csv"
    argv = ["simulate", "--open-loop", "--plant", name, "--command", "0.4", "--duration",
            "0.08", "--delay", "0.0025", "--param", "transducer.resolution=1e-6",
            "--out", str(csv)]
    assert main(argv) == 0
    header = csv.read_text(encoding="utf-8").splitlines()[0].split(",")
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    params = with_overrides(named_set("paper"), {"transducer.resolution": 1e-6})
    plant = build_plant(name, params, 0.5 * params.cylinder.stroke)
    sc = emit_servo(plant, ts=1e-3, delay=0.0025)
    assert header[:2] == ["t", "u"]
    assert tuple(header[2:]) == sc.outputs
    assert len(sc.units) == len(sc.descriptions) == len(sc.start) == len(sc.outputs)
    assert all(sc.units) and all(sc.descriptions)
    lib = compile_shared(_unit("cli", sc), tmp_path)
    out, bad = _run_c(ctypes.CDLL(str(lib)), "cli", sc, data[:-1, 1])
    assert bad == -1
    assert np.array_equal(out[:, 0], data[:, 0])
    devs = _deviation(out, data[:, 0], data[:, 2], data[:, 3:], sc)
    assert max(devs) <= REL
    assert tuple(out[0, 1:]) == sc.start


def test_servo_record() -> None:
    """What a model description reads: kinds, units, the start and the delay's split."""
    params = _params("changed")
    nl_plant = build_plant("nonlinear", params, 0.3, substep=1e-4)
    assert isinstance(nl_plant, NonlinearPlant)
    sc = emit_servo(nl_plant, ts=1e-3, delay=0.0025, n_samples_max=1000)
    assert (sc.kind, sc.whole_samples, sc.ring, sc.n_sub, sc.n_split) == (
        "nonlinear", 2, 4, 10, (5, 5))
    assert sc.fraction == pytest.approx(5e-4, abs=1e-15)  # 0.0025 - 2 * 0.001 in doubles
    assert sc.units == ("m", "1", "1", "1/s", "Pa", "Pa", "m", "m/s")
    assert sc.outputs == ("y", *nl.STATE_NAMES)
    assert sc.start[6] == 0.3
    assert sc.start[0] == 1e-5 * math.floor(0.3 / 1e-5 + 0.5)  # rounded as the loop rounds
    assert sc.u0 == nl_plant.u0 and sc.stroke == 1.0 and sc.n_samples_max == 1000
    lin = build_plant("linear", params, 0.3)
    sl = emit_servo(lin, ts=2.5e-3, delay=0.0)
    assert (sl.kind, sl.ring, sl.n_sub, sl.n_split) == ("linear", 2, 0, (0, 0))
    assert sl.units == ("m", "1", "1", "1/s", "m/s", "m/s2", "m")
    assert sl.start[0] == lin.y0 and sl.u0 == 0.0
    # every float of the plant is an exact hex literal
    for value in (*nl_plant.packed, *nl_plant.x0, nl_plant.u0):
        if value != 0.0:
            assert float(value).hex() in sc.source


def test_fragment_constants_are_the_python() -> None:
    """The fragment's indices and named limits are those of fuzzyservo.plant.nonlinear."""
    text = plant_fragment()
    enum = dict((m[1], int(m[2])) for m in re.finditer(r"FS_NL_([A-Z0-9_]+) = (\d+)", text))
    names = [n for n in dir(nl) if re.fullmatch(r"[PS]_[A-Z0-9]+|N_PARAMS|N_STATE", n)]
    assert len(names) == nl.N_PARAMS + nl.N_STATE + 2
    for name in names:
        assert enum[name] == getattr(nl, name), name
    define = dict((m[1], m[2]) for m in re.finditer(r"#define FS_NL_(\w+) (\S+)", text))
    assert float(define["COMMAND_LIMIT"]) == COMMAND_LIMIT
    assert float(define["PRESSURE_FLOOR_BAND"]) == nl.PRESSURE_FLOOR_BAND
    assert float.fromhex(define["PI"]) == math.pi
    assert re.search(r"^static (?!inline)", text, re.M) is None  # all static inline


# --- divergence ---------------------------------------------------------------------------


def _python_diverges_at(plant: Any, u: np.ndarray, ts: float) -> int:
    with pytest.raises(SimulationDivergedError) as info:
        simulate_open_loop(plant, u, duration=u.size * ts, dt=ts)
    t = float(re.search(r"at t = (\S+) s", str(info.value))[1])  # type: ignore[index]
    return int(round(t / ts))


def test_divergence_is_reported_at_the_python_sample(tmp_path: Path) -> None:
    """A state that turns non-finite makes fs_servo_sample return non-zero on the sample
    the Python names."""
    light = with_overrides(named_set("paper"), {"load.mass": 1e-3})
    unstable: list[tuple[str, LinearPlant | NonlinearPlant, float]] = [
        ("nl", NonlinearPlant.from_params(light, substep=1e-3), 1e-3),
        ("lin", LinearPlant.from_state_space([[4000.0]], [1.0], [1.0]), 1e-3),
    ]
    servo = {cid: emit_servo(plant, ts=ts, delay=0.0) for cid, plant, ts in unstable}
    lib = ctypes.CDLL(str(compile_shared([_unit(cid, servo[cid]) for cid in servo],
                                         tmp_path)))
    for cid, plant, ts in unstable:
        u = np.full(300, 0.5)
        _, bad = _run_c(lib, cid, servo[cid], u)
        assert bad > 0
        assert bad == _python_diverges_at(plant, u, ts)
    assert servo["lin"].units == ("m", "") and servo["lin"].stroke is None


# --- sanitizers --------------------------------------------------------------------------

SAN_MAIN = r"""
#include <stdio.h>
@DECLS@
int main(void)
{
    static double out[@ROWS@];
    int k, i;
@RUNS@
    return 0;
}
"""


def test_sanitizer_build(tmp_path: Path) -> None:
    """ASan + UBSan build of a nonlinear plant (changed set, fractional delay, commands past
    the limit) and a small-signal one (hose delay at 2.5 ms): clean, and equal to the
    Python."""
    picks = [Case("s0", "nonlinear", "changed", 1e-3, 0.0025, "beyond", substep=1e-4, n=150),
             Case("s1", "small-signal", "changed", 2.5e-3, "hose", "random", n=80)]
    units, decls, runs = [], [], []
    rows = 0
    expected = []
    for case in picks:
        plant = _plant(case)
        sc = emit_servo(plant, ts=case.ts, delay=case.delay_s())
        u = case.commands(seed=7)
        units.append(_unit(case.cid, sc))
        items = ", ".join(float(v).hex() for v in u)
        decls.append(f"int fs_run_{case.cid}(const double *u, const double *force, int n, "
                     f"double *out);\n"
                     f"static const double u_{case.cid}[{u.size}] = {{{items}}};")
        width = len(sc.outputs) + 1
        runs.append(
            f"    printf(\"bad %d\\n\", fs_run_{case.cid}(u_{case.cid}, 0, {u.size}, "
            f"out));\n"
            f"    for (k = 0; k <= {u.size}; k++) {{\n"
            f"        for (i = 0; i < {width}; i++) {{\n"
            f"            printf(\"%a \", out[k * {width} + i]);\n"
            f"        }}\n"
            f"        printf(\"\\n\");\n"
            f"    }}")
        rows = max(rows, (u.size + 1) * width)
        expected.append((sc, _python_run(plant, u, case.ts, case.delay_s()), u.size))
    main_c = (SAN_MAIN.replace("@DECLS@", "\n".join(decls)).replace("@ROWS@", str(rows))
              .replace("@RUNS@", "\n".join(runs)))
    exe = compile_executable([main_c, *units], tmp_path, sanitize=True, name="san")
    proc = subprocess.run([str(exe)], capture_output=True, text=True, check=False,
                          timeout=60)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    lines = proc.stdout.splitlines()
    for sc, (t, y, states), n in expected:
        assert lines[0] == "bad -1"
        out = np.array([[float.fromhex(v) for v in line.split()] for line in lines[1:n + 2]])
        lines = lines[n + 2:]
        assert np.array_equal(out[:, 0], t)
        assert max(_deviation(out, t, y, states, sc)) <= REL
    assert lines == []


# --- refusals ------------------------------------------------------------------------------


def test_emit_servo_refuses_what_it_cannot_compile() -> None:
    plant = build_plant("nonlinear", named_set("paper"))
    assert isinstance(plant, NonlinearPlant)
    with pytest.raises(ParameterError, match="ts"):
        emit_servo(plant, ts=0.0, delay=0.0)
    with pytest.raises(ParameterError, match="delay"):
        emit_servo(plant, ts=1e-3, delay=-1e-3)
    with pytest.raises(ParameterError, match="longer than the run"):
        emit_servo(plant, ts=1e-3, delay=0.2, n_samples_max=100)
    emit_servo(plant, ts=1e-3, delay=0.1, n_samples_max=100)  # the whole run is allowed
    with pytest.raises(ParameterError, match="n_samples_max"):
        emit_servo(plant, ts=1e-3, delay=0.0, n_samples_max=0)
    with pytest.raises(ParameterError, match="n_samples_max"):
        emit_servo(plant, ts=1e-3, delay=0.0, n_samples_max=True)
    with pytest.raises(ParameterError, match="samples"):
        emit_servo(plant, ts=1e-6, delay=100.0)
    with pytest.raises(ParameterError, match="RK4"):
        emit_servo(NonlinearPlant(plant.packed, plant.x0, plant.u0, substep=1e-9), ts=1e-3,
                   delay=0.0, n_samples_max=10**6)
    with pytest.raises(ParameterError, match="LinearPlant or NonlinearPlant"):
        emit_servo("nonlinear", ts=1e-3, delay=0.0)  # type: ignore[arg-type]
