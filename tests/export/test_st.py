"""The exported Structured Text, checked by a compiler we did not write.

Each block is translated by MatIEC's ``iec2c`` (the IEC 61131-3 compiler of Beremiz and
OpenPLC, built by ``make test``), its C compiled with gcc against MatIEC's runtime headers, and
run one PLC cycle per sample (tests/export/st_harness.py). Compared with:

- LREAL: the Python controller (the compiled kernels), on recorded closed loops of both plants
  (``fuzzyservo.sim.simulate``: the runs' r, y and, for feed-forward laws, the reference's
  rates) and on random sequences; bound 1e-12 (the acceptance; observed: 0, the port is line
  by line and the literals exact);
- REAL (``--real``): the C export compiled in float (``export c --float``), fed the same
  float32 inputs: equal bit for bit (the float32 result of the same operations).

Every registered controller with the committed gains files, random gains (given as the block's
inputs, so the block re-packs them) and options; the systems of the shipped .fis/.fcl/.fll
files; online gain changes, a bad gain, ENABLE and RESET; the example program run as OpenPLC
runs a configuration; and broken ST, which iec2c must refuse (the check can fail).
"""

from __future__ import annotations

import math
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fuzzyservo.errors import ParameterError
from fuzzyservo.export._st import check_st_name, st_comment_text, st_literal
from fuzzyservo.export.st import STController
from fuzzyservo.export.st_fuzzy import partition_system
from fuzzyservo.export.targets import generate_c, generate_st
from fuzzyservo.files import read_gains_file
from fuzzyservo.formats import loads, read_system
from fuzzyservo.fuzzy.engine import pack
from fuzzyservo.fuzzy.loop import loop_system
from fuzzyservo.registry import build_controller, controller_kind, controller_names
from tests.export.cbuild import gcc
from tests.export.ctl_harness import CStep, build
from tests.export.st_harness import STBlock, matiec_prefix, translate
from tests.export.test_controller_c import (
    GAINS,
    PARAMS,
    SYSTEMS,
    TS,
    _random_gains,
    _random_options,
    _rates,
    _reference,
    _run,
)

ROOT = Path(__file__).resolve().parents[2]
#: |u_ST - u_py| bound in LREAL [-] (the acceptance).
LREAL_TOL = 1e-12
N_RANDOM = 2000


def _block(st: STController, folder: Path) -> STBlock:
    return STBlock(st, folder)


def _input_gains(st: STController, gains: dict[str, float]) -> list[float]:
    """The block's gain inputs for ``gains`` (infinity as 0 where the port reads it so)."""
    out = []
    for g in st.gain_names:
        v = float(gains[g.lower()])
        out.append(0.0 if math.isinf(v) and g in st.inf_as_zero else v)
    return out


def _replay(block: STBlock, res: Any, plant: Any, rates: Any = None,
            gains: list[float] | None = None, *, alpha: bool = False) -> np.ndarray:
    """The block's commands (and, with ``alpha``, its ALPHA output as a second column) over
    a recorded run: the first cycle starts it at rest at y0 holding u0 (the run's start), as
    the simulator starts the controller."""
    n = res.r.size
    rd, rdd = (None, None) if rates is None else rates
    rows = block.rows(res.r, res.y, rd=rd, rdd=rdd, hold=float(plant.u0),
                      gains=None if gains is None else np.tile(gains, (n, 1)))
    assert float(res.y[0]) == float(plant.y0)
    out = block.run(rows)
    return out[:, :2] if alpha else out[:, 0]


def _python(controller: Any, r: np.ndarray, y: np.ndarray, *, rd: np.ndarray, rdd: np.ndarray,
            u0: float, packed: list[tuple[int, np.ndarray]] | None = None) -> np.ndarray:
    """The Python controller's commands over a sequence, from rest at y[0] holding u0;
    ``packed`` (sample, parameters) switches the packed parameters from that sample on."""
    law = controller.law
    p = np.ascontiguousarray(controller.pack(), dtype=np.float64).reshape(-1)
    s = np.ascontiguousarray(controller.rest_states(p[None, :], float(y[0]), u0)[0])
    switch = dict(packed or [])
    tables = controller.tables()
    u = np.empty(r.size)
    for k in range(r.size):
        if k in switch:
            p = np.ascontiguousarray(switch[k], dtype=np.float64).reshape(-1)
        u[k] = law.step_arrays(p, s, float(r[k]), float(y[k]), tables, float(rd[k]),
                               float(rdd[k]))
    return u


def _gains_files() -> list[Path]:
    files = sorted(GAINS.glob("*.toml"))
    assert len(files) == 20
    return files


def test_matiec_is_built_with_the_lreal_literal_patch(tmp_path: Path) -> None:
    """The oracle is there (make test builds it), with the LREAL-literal patch: stock iec2c
    refuses an LREAL literal beyond REAL's range (upstream issue #12); this one takes it."""
    assert (matiec_prefix() / "lib" / "C" / "iec_std_lib.h").is_file()
    text = ("FUNCTION_BLOCK tiny\nVAR_OUTPUT\n    X : LREAL;\nEND_VAR\nVAR CONSTANT\n"
            "    SMALL : LREAL := 1.0E-300;\nEND_VAR\n    X := SMALL;\nEND_FUNCTION_BLOCK\n")
    proc = translate(text, tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1.0E-300" in (tmp_path / "c" / "POUS.c").read_text()


@pytest.mark.parametrize("path", _gains_files(), ids=lambda p: p.stem)
def test_committed_gains_on_both_plants(path: Path, tmp_path: Path) -> None:
    """The block of every committed gains file (its gains compiled in as the packed initial
    values) equals the Python controller on closed loops of both plants."""
    g = read_gains_file(path)
    st = generate_st(g.controller, dict(g.gains), ts=g.ts)
    block = _block(st, tmp_path)
    worst = 0.0
    for plant_name in ("linear", "nonlinear"):
        for ref in (0.1, -0.2):
            block.dll.st_init()
            plant, res = _run(g.controller, dict(g.gains), plant_name, options={},
                              systems=None, reference=ref)
            out = _replay(block, res, plant, rates=_rates(g.controller, ref, res), alpha=True)
            u = out[:, 0]
            assert np.all(np.isfinite(u))
            worst = max(worst, float(np.max(np.abs(u - res.u))))
            if st.self_tuning:  # ALPHA is the run's alpha
                worst = max(worst, float(np.max(np.abs(out[:, 1] - res.alpha))))
    assert worst <= LREAL_TOL, worst


@pytest.mark.parametrize("kind", controller_names())
def test_random_gains_options_and_references(kind: str, tmp_path: Path) -> None:
    """Per kind: 2 option sets (one block each) x 3 gain sets (the first compiled in, the
    others given to the block's inputs, so it re-packs them) x both plants, random step
    references: LREAL equals the Python."""
    rng = np.random.default_rng(sum(map(ord, kind)) + 26)
    worst = 0.0
    for i in range(2):
        options = _random_options(kind, rng)
        gains0 = _random_gains(kind, rng, options)
        st = generate_st(kind, gains0, ts=TS, options=options)
        block = _block(st, tmp_path / f"o{i}")
        for j in range(3):
            gains = gains0 if j == 0 else _random_gains(kind, rng, options)
            for plant_name in ("linear", "nonlinear"):
                stroke = PARAMS.cylinder.stroke
                ref = _reference(rng, int(round(1.0 / TS)) + 1, stroke, 0.5 * stroke)
                plant, res = _run(kind, gains, plant_name, options=options, systems=None,
                                  reference=ref)
                block.dll.st_init()
                u = _replay(block, res, plant, rates=_rates(kind, ref, res),
                            gains=_input_gains(st, gains))
                worst = max(worst, float(np.max(np.abs(u - res.u))))
    assert worst <= LREAL_TOL, worst


def _shipped_systems() -> list[tuple[str, dict[str, Any]]]:
    out = []
    for fmt in ("fis", "fcl", "fll"):
        systems = {role: loop_system(read_system(SYSTEMS / f"paper-{role}.{fmt}"),
                                     source=str(SYSTEMS / f"paper-{role}.{fmt}"))
                   for role in ("du", "alpha")}
        out.append((fmt, systems))
    return out


@pytest.mark.parametrize("case", _shipped_systems(), ids=lambda c: c[0])
@pytest.mark.parametrize("kind", ["fpi", "stfpi", "wfpi"])
def test_systems_of_the_shipped_files(kind: str, case: tuple[str, dict[str, Any]],
                                      tmp_path: Path) -> None:
    """The systems read from the shipped .fis/.fcl/.fll files, in the block, equal the
    Python controller that reads them, on both plants."""
    _fmt, systems = case
    use = {r: s for r, s in systems.items() if r in controller_kind(kind).systems}
    g = dict(read_gains_file(GAINS / f"linear-{kind}.toml").gains)
    st = generate_st(kind, g, ts=TS, systems=use)
    assert st.digest
    block = _block(st, tmp_path)
    worst = moved = 0.0
    for plant_name in ("linear", "nonlinear"):
        block.dll.st_init()
        plant, res = _run(kind, g, plant_name, options={}, systems=use, reference=0.1)
        u = _replay(block, res, plant)
        worst = max(worst, float(np.max(np.abs(u - res.u))))
        moved = max(moved, float(np.ptp(res.u)))
    assert moved > 1e-3
    assert worst <= LREAL_TOL, worst


UNEVEN = Path(__file__).with_name("data") / "uneven.fll"


def _partition_cases() -> list[tuple[str, dict[str, Any], dict[str, float]]]:
    """Systems that take the general evaluator's partition path: the paper's two packed for
    the general evaluator, and an uneven 5 x 3 table with shoulder ramps and two empty cells,
    with min and with product AND and implication."""
    paper = {"du": loop_system(read_system(SYSTEMS / "paper-du.fis"), grid=False),
             "alpha": loop_system(read_system(SYSTEMS / "paper-alpha.fll"), grid=False)}
    text = UNEVEN.read_text()
    prod = text.replace("conjunction: Minimum", "conjunction: AlgebraicProduct").replace(
        "implication: Minimum", "implication: AlgebraicProduct")
    gains = {"ke": 8.0, "kde": 1500.0, "kdu": 0.02}
    out = [("paper", paper, dict(read_gains_file(GAINS / "linear-stfpi.toml").gains))]
    for name, src in (("uneven-min", text), ("uneven-prod", prod)):
        du = loop_system(loads(src, "fll"), source=name)
        out.append((name, {"du": du, "alpha": paper["alpha"]}, gains))
    for _name, systems, _g in out:
        assert all(s.packed.path == "partition" for s in systems.values())
    return out


@pytest.mark.parametrize("case", _partition_cases(), ids=lambda c: c[0])
@pytest.mark.parametrize("kind", ["fpi", "stfpi"])
def test_partition_systems(kind: str, case: tuple[str, dict[str, Any], dict[str, float]],
                           tmp_path: Path) -> None:
    """Rule tables over fuzzy partitions (the general evaluator's fast path, ported to ST):
    LREAL equals the Python on both plants; --real equals the float C on a random
    sequence."""
    _name, systems, gains = case
    use = {r: s for r, s in systems.items() if r in controller_kind(kind).systems}
    st = generate_st(kind, gains, ts=TS, systems=use)
    assert "DU_PI : ARRAY" in st.block and "FOR " not in st.block
    block = _block(st, tmp_path / "st")
    worst = moved = 0.0
    for plant_name in ("linear", "nonlinear"):
        for ref in (0.1, -0.05):
            block.dll.st_init()
            plant, res = _run(kind, gains, plant_name, options={}, systems=use, reference=ref)
            u = _replay(block, res, plant)
            worst = max(worst, float(np.max(np.abs(u - res.u))))
            moved = max(moved, float(np.ptp(res.u)))
    assert moved > 1e-3
    assert worst <= LREAL_TOL, worst

    rng = np.random.default_rng(5)
    st32 = generate_st(kind, gains, ts=TS, systems=use, real="REAL")
    b32 = _block(st32, tmp_path / "st32")
    cc = generate_c(kind, gains, ts=TS, systems=use, real="float", name=f"c_{kind}")
    c = CStep(build(cc, tmp_path / "c"), cc)
    n = N_RANDOM
    r = _f32(0.5 + np.repeat(rng.uniform(-0.02, 0.02, n // 200), 200))
    y = _f32(0.5 + np.cumsum(rng.normal(0.0, 2e-5, n)))
    c.init(y[0], 0.0)
    u_c = np.array([c.step(r[k], y[k]) for k in range(n)])
    u32 = b32.run(b32.rows(r, y))[:, 0]
    assert np.ptp(u_c) > 1e-3
    assert np.array_equal(u32, u_c), float(np.max(np.abs(u32 - u_c)))


def _f32(a: np.ndarray) -> np.ndarray:
    return np.asarray(a, dtype=np.float32).astype(np.float64)


@pytest.mark.parametrize("kind", controller_names())
def test_real_equals_the_float_c(kind: str, tmp_path: Path) -> None:
    """--real: the block equals the C export compiled in float bit for bit, on a random
    sequence near mid-stroke with random rates (float32 inputs to both), from the committed
    nonlinear gains (or random ones for P and PI)."""
    rng = np.random.default_rng(sum(map(ord, kind)) + 2612)
    path = GAINS / f"nonlinear-{kind}.toml"
    gains = dict(read_gains_file(path).gains) if path.exists() else \
        _random_gains(kind, rng, {})
    st = generate_st(kind, gains, ts=TS, real="REAL")
    assert st.real == "REAL" and "LREAL" not in st.block
    block = _block(st, tmp_path / "st")
    cc = generate_c(kind, gains, ts=TS, real="float", name=f"c_{kind}")
    c = CStep(build(cc, tmp_path / "c"), cc)
    n = N_RANDOM
    r = _f32(0.5 + np.repeat(rng.uniform(-0.02, 0.02, n // 200), 200))
    y = _f32(0.5 + np.cumsum(rng.normal(0.0, 2e-5, n)))
    rd, rdd = _f32(rng.normal(0, 0.05, n)), _f32(rng.normal(0, 0.5, n))
    hold = float(np.float32(0.013))
    c.init(y[0], hold)
    u_c = np.array([c.step_ff(r[k], rd[k], rdd[k], y[k]) for k in range(n)])
    u = block.run(block.rows(r, y, rd=rd, rdd=rdd, hold=hold))[:, 0]
    assert np.ptp(u_c) > 1e-3  # the commands moved
    assert np.array_equal(u, u_c), float(np.max(np.abs(u - u_c)))
    # and it is float arithmetic: the LREAL block differs
    st64 = generate_st(kind, gains, ts=TS)
    u64 = _block(st64, tmp_path / "st64").run(block.rows(r, y, rd=rd, rdd=rdd, hold=hold))[:, 0]
    assert not np.array_equal(u, u64)


@pytest.mark.parametrize("kind", ["pid2", "stfpi", "smc"])
def test_online_gain_change_bad_gain_enable_and_reset(kind: str, tmp_path: Path) -> None:
    """The block's other inputs, against the Python controller on a random sequence:
    a gain change at sample 500 (re-packed that cycle); a negative gain at 900 and NaN at 1000
    (GAIN_ERROR names it, the block keeps the gains last accepted); disabled from 1200 to
    1299 (COMMAND = HOLD_COMMAND, ACTIVE false; the next enabled cycle restarts bumpless at
    its measurement); RESET at 1600 (the same restart)."""
    rng = np.random.default_rng(7)
    g0 = dict(read_gains_file(GAINS / f"linear-{kind}.toml").gains)
    st = generate_st(kind, g0, ts=TS)
    block = _block(st, tmp_path)
    n = N_RANDOM
    r = 0.5 + np.repeat(rng.uniform(-0.01, 0.01, n // 250), 250)
    y = 0.5 + np.cumsum(rng.normal(0.0, 2e-5, n))
    rd, rdd = rng.normal(0, 0.05, n), rng.normal(0, 0.5, n)
    hold = 0.021
    g1 = {k: v * (1.3 if i == 0 else 1.0) for i, (k, v) in enumerate(g0.items())}
    base = np.array(_input_gains(st, g0))
    new = np.array(_input_gains(st, g1))
    gains = np.tile(base, (n, 1))
    gains[500:] = new
    bad = new.copy()
    bad[-1] = -1.0
    gains[900:1000] = bad
    nan = new.copy()
    nan[0] = math.nan
    gains[1000:1100] = nan
    enable = np.ones(n)
    enable[1200:1300] = 0.0
    reset = np.zeros(n)
    reset[1600] = 1.0
    out = block.run(block.rows(r, y, rd=rd, rdd=rdd, hold=hold, enable=enable, reset=reset,
                               gains=gains))
    u, err, active = out[:, 0], out[:, 2], out[:, 3]
    assert np.all(err[:900] == 0) and np.all(err[1100:] == 0)
    assert np.all(err[900:1000] == len(base)) and np.all(err[1000:1100] == 1)
    assert np.all(u[1200:1300] == hold) and not np.any(active[1200:1300])
    assert np.all(active[:1200]) and np.all(active[1300:])

    c0 = build_controller(kind, g0, dt=TS)
    c1 = build_controller(kind, g1, dt=TS)
    ref = np.empty(n)
    ref[:1200] = _python(c0, r[:1200], y[:1200], rd=rd[:1200], rdd=rdd[:1200], u0=hold,
                         packed=[(500, c1.pack())])
    ref[1200:1300] = hold
    ref[1300:1600] = _python(c1, r[1300:1600], y[1300:1600], rd=rd[1300:1600],
                             rdd=rdd[1300:1600], u0=hold)
    ref[1600:] = _python(c1, r[1600:], y[1600:], rd=rd[1600:], rdd=rdd[1600:], u0=hold)
    assert np.ptp(ref) > 1e-3
    assert float(np.max(np.abs(u - ref))) <= LREAL_TOL


def test_a_model_gain_of_zero_is_refused_online(tmp_path: Path) -> None:
    """smc's k_o and omega_0 divide: the block refuses 0 for them (GAIN_ERROR names the
    input, the gains last accepted stay), as the registry and the C export's set_gains do."""
    g = dict(read_gains_file(GAINS / "linear-smc.toml").gains)
    st = generate_st("smc", g, ts=TS)
    assert "K_O : LREAL" in st.block and "K_O > 0.0" in st.block
    block = _block(st, tmp_path / "st")
    n = 200
    r, y = np.full(n, 0.31), 0.3 + 1e-4 * np.sin(np.arange(n))
    gains = np.tile(_input_gains(st, g), (n, 1))
    k_o = st.gain_names.index("K_O")
    gains[100:, k_o] = 0.0
    out = block.run(block.rows(r, y, gains=gains))
    assert np.all(out[:100, 2] == 0) and np.all(out[100:, 2] == k_o + 1)
    c = build_controller("smc", g, dt=TS)
    ref = _python(c, r, y, rd=np.zeros(n), rdd=np.zeros(n), u0=0.0)
    assert np.all(np.isfinite(out[:, 0])) and np.array_equal(out[:, 0], ref)
    cc = generate_c("smc", g, ts=TS, name="c_smc")
    cs = CStep(build(cc, tmp_path / "c"), cc)
    cs.init(0.3, 0.0)
    bad = [g[k] for k in controller_kind("smc").gain_names]
    bad[k_o] = 0.0
    assert cs.set_gains(bad) == k_o + 1


@pytest.mark.parametrize("kind", controller_names())
def test_bumpless_start(kind: str, tmp_path: Path) -> None:
    """With the setpoint at the measurement, the first enabled cycle returns HOLD_COMMAND
    (holding -0.04, 0 and 0.3), for every kind: the block's start is the simulator's rest
    (and where the Python's first command is HOLD_COMMAND only to rounding, pid2 with b < 1,
    the block's is the Python's)."""
    path = GAINS / f"linear-{kind}.toml"
    g = dict(read_gains_file(path).gains) if path.exists() else \
        _random_gains(kind, np.random.default_rng(3), {})
    st = generate_st(kind, g, ts=TS)
    block = _block(st, tmp_path)
    c = build_controller(kind, g, dt=TS)
    for hold in (-0.04, 0.0, 0.3):
        block.dll.st_init()
        u = block.run(block.rows(np.array([0.4]), np.array([0.4]), hold=hold))[0, 0]
        ref = _python(c, np.array([0.4]), np.array([0.4]), rd=np.zeros(1), rdd=np.zeros(1),
                      u0=hold)[0]
        assert u == ref and abs(u - hold) <= 1e-15, (hold, u, ref)


def test_example_program_runs_as_a_configuration(tmp_path: Path) -> None:
    """NAME.st and NAME_example.st together: iec2c translates the configuration, and run as
    OpenPLC runs it (config_init__, then config_run__ per 1 ms tick) the program's valve
    command equals the Python controller's on the program's constant inputs."""
    g = dict(read_gains_file(GAINS / "linear-stfpi.toml").gains)
    st = generate_st("stfpi", g, ts=TS)
    assert "INTERVAL := T#1ms" in st.example
    proc = translate(st.block + "\n" + st.example, tmp_path, "project.st")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    c_dir = tmp_path / "c"
    res = f"{st.name}_RES".upper()
    inst = f"{res}__{st.name.upper()}_MAIN"
    main = f"""
#include <stdio.h>
#include "{st.name}_CONFIG.c"
#include "{st.name}_RES.c"
int main(void)
{{
    unsigned long tick;
    config_init__();
    {inst}.POSITION_SETPOINT.value = 0.101;
    {inst}.POSITION.value = 0.1;
    {inst}.NULL_COMMAND.value = 0.01;
    for (tick = 0; tick < 50; tick++) {{
        config_run__(tick);
        printf("%a\\n", (double){inst}.VALVE_COMMAND.value);
    }}
    return 0;
}}
"""
    (c_dir / "main.c").write_text(main, encoding="utf-8")
    exe = tmp_path / "plc"
    built = subprocess.run([gcc(), "-std=gnu11", "-O2", "-ffp-contract=off", "-w", "-I",
                            str(matiec_prefix() / "lib" / "C"), "-I", str(c_dir), "-o",
                            str(exe), str(c_dir / "main.c"), "-lm"],
                           capture_output=True, text=True, check=False, timeout=600)
    assert built.returncode == 0, built.stderr
    ran = subprocess.run([str(exe)], capture_output=True, text=True, check=True, timeout=60)
    u = np.array([float.fromhex(s) for s in ran.stdout.split()])
    n = u.size
    c = build_controller("stfpi", g, dt=TS)
    ref = _python(c, np.full(n, 0.101), np.full(n, 0.1), rd=np.zeros(n), rdd=np.zeros(n),
                  u0=0.01)
    assert u[0] != 0.01 and np.ptp(ref) > 0
    assert np.array_equal(u, ref)


def _broken(text: str, what: str) -> str:
    if what == "semicolon":
        return text.replace("END_IF;", "END_IF", 1)
    if what == "literal":
        return text.replace("    COMMAND := U;", "    COMMAND := U + 1e-05;", 1)
    if what == "undeclared":
        return text.replace("    COMMAND := U;", "    COMMAND := U_UNDECLARED;", 1)
    if what == "type":
        return text.replace("    COMMAND := U;", "    COMMAND := ENABLE;", 1)
    raise AssertionError(what)


@pytest.mark.parametrize("what", ["semicolon", "literal", "undeclared", "type"])
def test_iec2c_refuses_broken_st(what: str, tmp_path: Path) -> None:
    """The check can fail: iec2c accepts the block as written and refuses it broken (a
    missing END_IF semicolon, a C-style literal 1e-05, an undeclared variable, a BOOL
    assigned to a real), naming the file and line."""
    st = generate_st("fpi", {"ke": 3.0, "kde": 1.0, "kdu": 0.01}, ts=TS)
    ok = translate(st.block, tmp_path / "ok", "block.st")
    assert ok.returncode == 0, ok.stdout + ok.stderr
    bad_text = _broken(st.block, what)
    assert bad_text != st.block
    bad = translate(bad_text, tmp_path / "bad", "block.st")
    assert bad.returncode != 0
    assert "block.st:" in bad.stdout + bad.stderr


def test_lreal_literals_beyond_real_range_are_exact(tmp_path: Path) -> None:
    """Packed parameters beyond REAL's range (K_p = 1e-300, K_i h = 1.7e-303) are written as
    LREAL literals and read back exactly (MatIEC with its LREAL-literal patch; any conforming
    compiler): with an error of exactly 1 m the command is K_p itself, then K_p plus the
    integral, and equals the Python's bit for bit."""
    gains = {"kp": 1e-300, "ki": 1.7e-300, "kd": 0.0, "n": math.inf}
    st = generate_st("pid", gains, ts=TS)
    assert "P_KP : LREAL := 1.0E-300;" in st.block
    assert f"P_KI_H : LREAL := {st_literal(1.7e-300 * TS)};" in st.block
    assert "N : LREAL := 0.0;" in st.block
    block = _block(st, tmp_path)
    n = 5
    r, y = np.full(n, 1.5), np.full(n, 0.5)
    u = block.run(block.rows(r, y, hold=0.0))[:, 0]
    c = build_controller("pid", gains, dt=TS)
    ref = _python(c, r, y, rd=np.zeros(n), rdd=np.zeros(n), u0=0.0)
    assert ref[0] == 1e-300 + 1.7e-300 * TS and ref[1] > ref[0]
    assert np.array_equal(u, ref)


def test_a_sample_time_of_a_fraction_of_a_millisecond(tmp_path: Path) -> None:
    """ts = 1.5 ms: the example's task interval is T#1.5ms (MatIEC refuses T#1500us in a
    task), and block and example translate."""
    st = generate_st("pi", {"kp": 2.0, "ki": 1.0}, ts=1.5e-3)
    assert "INTERVAL := T#1.5ms" in st.example
    proc = translate(st.block + "\n" + st.example, tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1500000ULL" in (tmp_path / "c" / f"{st.name}_CONFIG.c").read_text()


# --- the writer's guards (no compiler needed) ---------------------------------------------


@pytest.mark.parametrize("v", [0.0, -0.0, 1.0, 0.1, 1e-5, 1.5e300, -2.5e-310, 123456789.0,
                               1e16, 5e-324, 2.0**-1074, 1.7976931348623157e308])
def test_lreal_literals_are_st_and_exact(v: float) -> None:
    s = st_literal(v, "LREAL")
    assert "e" not in s and "." in s.split("E")[0]
    assert float(s) == v and math.copysign(1.0, float(s)) == math.copysign(1.0, v)


def test_real_literals_are_the_nearest_float() -> None:
    for v in (0.1, 1.0 / 3.0, 1e-30, 3.0e38):
        s = st_literal(v, "REAL")
        assert float(s) == float(np.float32(v))
    for v, why in ((1e39, "beyond"), (1e-50, "rounds to 0"), (math.nan, "NaN"),
                   (math.inf, "infinities")):
        with pytest.raises(ParameterError, match=why):
            st_literal(v, "REAL")


def test_recorded_text_cannot_end_or_open_a_comment() -> None:
    for hostile in ("a *) b", "(* x", "x // y", "x /* y", "line\nbreak", "\u0394e *)(*"):
        s = st_comment_text(hostile)
        assert "*)" not in s and "(*" not in s and "//" not in s and "/*" not in s
        assert "\n" not in s and s.isascii()


def test_hostile_command_and_paths_stay_in_the_comment(tmp_path: Path) -> None:
    """A command line and a file name with comment ends and line breaks are recorded inside
    the header, and the block still translates."""
    st = generate_st("fpi", {"ke": 3.0, "kde": 1.0, "kdu": 0.01}, ts=TS,
                     command="fuzzyservo export st --out '*)\nEND_FUNCTION_BLOCK (*'",
                     systems_record=(("du", "/tmp/x*)y.fis", "0" * 64),))
    header = st.block.split("\nFUNCTION_BLOCK ", 1)[0]
    assert header.count("*)") == 1 and header.rstrip().endswith("*)")
    proc = translate(st.block, tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.parametrize("name", ["PID", "pid", "ton", "REAL_TO_INT", "ADD_LREAL", "x__y", "a_",
                                  "_a", "9a", "", "a" * 25, "fs_ctl", "EN", "x y", "caf\u00e9"])
def test_bad_block_names_are_refused(name: str) -> None:
    with pytest.raises(ParameterError, match="--name"):
        check_st_name(name)


def test_general_systems_and_portless_laws_are_refused() -> None:
    """A system of the general evaluator's other paths (here smooth shapes) and a law without
    an ST port: one line each, naming what is allowed."""
    smooth = read_system(ROOT / "tests" / "formats" / "data" / "fis" / "all_mfs.fis")
    o0, o1 = smooth.outputs[0].range
    du = loop_system(smooth, no_rule_value=0.5 * (o0 + o1))
    assert du.packed.path == "smooth"
    with pytest.raises(ParameterError, match="rules form a table over fuzzy partitions"):
        generate_st("fpi", {"ke": 3.0, "kde": 1.0, "kdu": 0.01}, ts=TS, systems={"du": du})
    # a partition system whose no-rule value is NaN (two empty cells: it can be reached;
    # the Python gives NaN there, ST has no literal for it)
    nan_default = loads(UNEVEN.read_text().replace("default: 0", "default: nan"), "fll")
    table = pack(nan_default)
    assert table.path == "partition"
    with pytest.raises(ParameterError, match="no-rule value is NaN"):
        partition_system("DU", table.rules, table.lims)
    from fuzzyservo.export.st import emit_st
    from tests.export.feedforward_law import FeedForwardController  # a user's law with C only

    kind = controller_kind("pid")
    ctl = FeedForwardController(dt=TS)
    with pytest.raises(ParameterError, match="no Structured Text port"):
        emit_st(kind, {"kp": 1.0, "ki": 0.0, "kd": 0.0, "n": 100.0}, ctl, name="ff_ctl")
