"""The generated C of every registered controller computes the Python controller's commands.

Each closed loop is simulated in Python (``fuzzyservo.sim.simulate``, the compiled kernels);
the C step is then driven through ctypes with the run's samples (r_k, y_k) from the same
bumpless start, and its commands are compared with the run's. That compares the two
controllers on the very inputs of the closed loop, on both plants; the FMU tests close the loop
with the C controller itself (tests/export/test_fmu.py). Cases: the committed gains files,
random gains, options and references, the paper's systems and systems read from files.

Bounds: double, 1e-12 (the acceptance; the code is a line-by-line port, so the observed
difference is 0 or a few ulps); float, 2e-5 of the command range (reasoned below).
"""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fuzzyservo.export.targets import generate_c
from fuzzyservo.files import read_gains_file
from fuzzyservo.formats import read_system
from fuzzyservo.fuzzy.loop import loop_system
from fuzzyservo.paper.published import named_set
from fuzzyservo.registry import (
    build_controller,
    build_plant,
    controller_kind,
    controller_names,
    default_systems,
)
from fuzzyservo.sim import simulate
from fuzzyservo.sim.references import reference_rates
from tests.export.ctl_harness import SANITIZE, STRICT, CStep, build, gcc, write

ROOT = Path(__file__).resolve().parents[2]
GAINS = ROOT / "src" / "fuzzyservo" / "data" / "gains"
SYSTEMS = ROOT / "src" / "fuzzyservo" / "data" / "systems"
PARAMS = named_set("paper")
DURATION = 1.0
TS = 1e-3

#: |u_C - u_py| bound for double code [-] (the acceptance).
DOUBLE_TOL = 1e-12
#: |u_C - u_py| bound for float code [-] (docs/export.md, "float"). The controllers take
#: absolute positions: in float, y near 0.5 m is quantised to 2^-24 m (6e-8 m), and the
#: derivative path amplifies a change of y by b_d = K_d N/(1 + N h) (168 1/m for the tuned
#: 2-DOF PID), the fuzzy PIs a change of e by K_Δu K_Δe (72 1/m for the tuned self-tuning
#: fuzzy PI): a few 1e-6 per sample, and the fuzzy PIs sum their increments over the run.
#: Measured over 1 s on both plants: 1.0e-6 (pid), 2.9e-5 (pid2), 8.4e-6 (fpi), 8.9e-6
#: (stfpi); bound 5e-5, 2.5e-5 of the command range.
FLOAT_TOL = 5e-5


def _reference(rng: np.random.Generator, n: int, stroke: float, start: float) -> np.ndarray:
    """A random sequence of steps inside the stroke: offsets from the start [m]."""
    edges = np.sort(rng.integers(1, n, size=4))
    levels = rng.uniform(0.05, 0.95, size=5) * stroke - start
    return levels[np.searchsorted(edges, np.arange(n), side="right")]


def _run(kind: str, gains: dict[str, float], plant_name: str, *, options: dict[str, Any],
         systems: dict[str, Any] | None, reference: np.ndarray | float,
         start: float = 0.5) -> tuple[Any, Any]:
    plant = build_plant(plant_name, PARAMS, start * PARAMS.cylinder.stroke)
    ctl = build_controller(kind, gains, dt=TS, systems=systems, options=options)
    ref = reference if isinstance(reference, np.ndarray) else np.full(
        int(round(DURATION / TS)) + 1, reference)
    return plant, simulate(ctl, plant, ref, duration=DURATION)


def _rates(kind: str, reference: np.ndarray | float, res: Any) -> tuple[Any, Any] | None:
    """The reference's rates the run's law saw (sim.references.reference_rates of the same
    samples), for a law with feed-forward (replayed through NAME_step_ff); None otherwise."""
    if not res.info["controller"].law.feedforward:  # the run's law (a fuzzy PI's is chosen
        return None                                 # per instance)
    ref = reference if isinstance(reference, np.ndarray) else np.full(res.t.size, reference)
    return reference_rates(ref, res.t)


def _compiled(kind: str, gains: dict[str, float], folder: Path, *, options: dict[str, Any],
              systems: dict[str, Any] | None, real: str = "double",
              name: str | None = None) -> CStep:
    cc = generate_c(kind, gains, ts=TS, options=options, systems=systems, real=real,  # type: ignore[arg-type]
                    name=name or f"c_{kind}")
    return CStep(build(cc, folder), cc)


def _gains_files() -> list[Path]:
    files = sorted(GAINS.glob("*.toml"))
    # the study's 12, the two robust self-tuning fuzzy PIs and the baselines (ffpd, smc,
    # wfpi) on 2 plants
    assert len(files) == 20
    return files


@pytest.mark.parametrize("path", _gains_files(), ids=lambda p: p.stem)
def test_committed_gains_on_both_plants(path: Path, tmp_path: Path) -> None:
    g = read_gains_file(path)
    assert g.ts == TS
    c = _compiled(g.controller, dict(g.gains), tmp_path, options={}, systems=None)
    worst = 0.0
    for plant_name in ("linear", "nonlinear"):
        for ref in (0.1, -0.2):
            plant, res = _run(g.controller, dict(g.gains), plant_name, options={},
                              systems=None, reference=ref)
            u = c.replay(res.r, res.y, plant.y0, plant.u0,
                         rates=_rates(g.controller, ref, res))
            assert np.all(np.isfinite(u))
            worst = max(worst, float(np.max(np.abs(u - res.u))))
    assert worst <= DOUBLE_TOL, worst


def _random_gains(kind_name: str, rng: np.random.Generator,
                  options: dict[str, Any]) -> dict[str, float]:
    """Gains drawn in the tuner's boxes for a 0.1 m step (kde per second when the options
    say so)."""
    kind = controller_kind(kind_name)
    out = {}
    for name, lo, hi, log, _zero in kind.search_box(0.1):
        out[name] = float(np.exp(rng.uniform(np.log(lo), np.log(hi))) if log
                          else rng.uniform(lo, hi))
    for g in kind.gains:
        if g.name not in out:
            out[g.name] = float(rng.choice([g.held_value(), rng.uniform(0.0, 1.0)])
                                if g.name in ("b", "c") else g.held_value())
    if "n" in out:
        out["n"] = float(rng.choice([10.0, 100.0, 1e3, np.inf]))
    if "ki" in out and rng.uniform() < 0.2:
        out["ki"] = 0.0
    if options.get("de_per") == "second":
        out["kde"] *= TS
    return out


def _random_options(kind_name: str, rng: np.random.Generator) -> dict[str, Any]:
    kind = controller_kind(kind_name)
    opts: dict[str, Any] = {}
    if "anti_windup" in kind.options:
        opts["anti_windup"] = str(rng.choice(["clamping", "back-calculation", "none"]))
        if opts["anti_windup"] == "back-calculation" and rng.uniform() < 0.5:
            opts["tracking_time"] = float(rng.uniform(0.01, 0.5))
    if "initial_error" in kind.options:
        opts["initial_error"] = str(rng.choice(["zero", "first"]))
        opts["de_per"] = str(rng.choice(["sample", "second"]))
        opts["filter_time"] = float(rng.choice([0.0, 0.003]))
    if "integral_action" in kind.options:
        opts["integral_action"] = str(rng.choice(["off", "on"]))
        opts["reference_jerk"] = str(rng.choice(["difference", "zero"]))
    if rng.uniform() < 0.3:
        opts["u_min"], opts["u_max"] = -0.6, 0.8
    return opts


@pytest.mark.parametrize("kind", controller_names())
def test_random_gains_options_and_references(kind: str, tmp_path: Path) -> None:
    """Per kind: 3 option sets (one compiled library each) x 3 random gain sets set through
    NAME_set_gains x both plants, random step references; kde per second where de_per says
    so."""
    rng = np.random.default_rng(sum(map(ord, kind)))  # fixed per kind
    worst = 0.0
    for i in range(3):
        options = _random_options(kind, rng)
        gains0 = _random_gains(kind, rng, options)
        c = _compiled(kind, gains0, tmp_path / f"o{i}", options=options, systems=None)
        for j in range(3):
            gains = gains0 if j == 0 else _random_gains(kind, rng, options)
            for plant_name in ("linear", "nonlinear"):
                stroke = PARAMS.cylinder.stroke
                ref = _reference(rng, int(round(DURATION / TS)) + 1, stroke, 0.5 * stroke)
                plant, res = _run(kind, gains, plant_name, options=options, systems=None,
                                  reference=ref)
                kind_gains = [gains[n] for n in controller_kind(kind).gain_names]
                u = c.replay(res.r, res.y, plant.y0, plant.u0,
                             gains=None if j == 0 else kind_gains,
                             rates=_rates(kind, ref, res))
                worst = max(worst, float(np.max(np.abs(u - res.u))))
    assert worst <= DOUBLE_TOL, worst


FORMATS = ROOT / "tests" / "formats" / "data"


def _file_systems() -> list[tuple[str, dict[str, Any], dict[str, dict[str, float]]]]:
    """Systems from files in the loop, with gains per kind: the paper's (the general
    evaluator's partition path) with the committed gains, and every two-input file of the
    format tests (smooth and piecewise-linear Mamdani systems, all their defuzzifiers;
    Sugeno systems) with gains that map a 0.1 m step and a 0.3 mm change per sample onto the
    input ranges and keep the increments small (so the command is not held at its limit,
    where it would hide the evaluator)."""
    paper = {"du": loop_system(read_system(SYSTEMS / "paper-du.fis"), grid=False),
             "alpha": loop_system(read_system(SYSTEMS / "paper-alpha.fll"), grid=False)}
    assert all(v.packed.path == "partition" for v in paper.values())
    out = [("paper-fis", paper, {k: dict(read_gains_file(GAINS / f"linear-{k}.toml").gains)
                                 for k in ("fpi", "stfpi")})]
    for path in sorted(FORMATS.rglob("*.*")):
        system = read_system(path)
        if len(system.inputs) != 2:
            continue
        (a0, a1), (b0, b1) = (v.range for v in system.inputs)
        o0, o1 = system.outputs[0].range
        gains = {"ke": (a1 - a0) / 0.2, "kde": (b1 - b0) / 6e-4, "kdu": 0.02 / (o1 - o0)}
        du = loop_system(system, source=str(path), no_rule_value=0.5 * (o0 + o1))
        out.append((f"{path.parent.name}-{path.stem}",
                    {"du": du, "alpha": default_systems(("alpha",))["alpha"]},
                    {"fpi": gains, "stfpi": gains}))
    return out


@pytest.mark.parametrize("case", _file_systems(), ids=lambda c: c[0])
@pytest.mark.parametrize("kind", ["fpi", "stfpi"])
def test_systems_from_files(kind: str, case: tuple[str, dict[str, Any], Any],
                            tmp_path: Path) -> None:
    _name, systems, per_kind = case
    gains = per_kind[kind]
    c = _compiled(kind, gains, tmp_path, options={}, systems=systems)
    worst = 0.0
    moved = 0.0
    for plant_name in ("linear", "nonlinear"):
        plant, res = _run(kind, gains, plant_name, options={}, systems=systems,
                          reference=0.1)
        u = c.replay(res.r, res.y, plant.y0, plant.u0)
        worst = max(worst, float(np.max(np.abs(u - res.u))))
        moved = max(moved, float(np.ptp(res.u)))
    assert moved > 1e-3  # the system drove the command
    assert worst <= DOUBLE_TOL, worst


@pytest.mark.parametrize("path", [GAINS / f"nonlinear-{k}.toml" for k in
                                  ("pid", "pid2", "fpi", "stfpi")], ids=lambda p: p.stem)
def test_float_code_stays_within_its_bound(path: Path, tmp_path: Path) -> None:
    g = read_gains_file(path)
    c = _compiled(g.controller, dict(g.gains), tmp_path, options={}, systems=None,
                  real="float")
    worst = 0.0
    for plant_name in ("linear", "nonlinear"):
        plant, res = _run(g.controller, dict(g.gains), plant_name, options={}, systems=None,
                          reference=0.1)
        u = c.replay(res.r, res.y, plant.y0, plant.u0)
        worst = max(worst, float(np.max(np.abs(u - res.u))))
    assert 0.0 < worst <= FLOAT_TOL, worst  # 0 would mean the float code is not float


def test_start_is_bumpless_and_instances_are_independent(tmp_path: Path) -> None:
    g = read_gains_file(GAINS / "nonlinear-pid2.toml")
    cc = generate_c(g.controller, dict(g.gains), ts=TS, name="twin")
    a = CStep(build(cc, tmp_path), cc)
    b = CStep.__new__(CStep)
    b.__dict__.update(a.__dict__)
    import ctypes

    b.buf = ctypes.create_string_buffer(4096)
    py = build_controller(g.controller, dict(g.gains), dt=TS)
    s0 = py.unpack_state(py.rest_states(py.pack()[None, :], 0.3, -0.04)[0])
    a.init(0.3, -0.04)
    b.init(0.1, 0.2)
    u = a.step(0.3, 0.3)
    # at rest, the holding command: to rounding of kp (b - 1) y0 = -14 (b = 0.34), and
    # exactly what the Python computes
    assert u == py.step(s0, 0.3, 0.3)[0] and u == pytest.approx(-0.04, abs=1e-14)
    for _ in range(50):
        a.step(0.4, 0.3)
    ub = b.step(0.1, 0.1)  # untouched by the other instance
    assert ub == py.step(py.unpack_state(py.rest_states(py.pack()[None, :], 0.1, 0.2)[0]),
                         0.1, 0.1)[0]
    assert a.set_gains([1.0, -1.0, 0.0, 100.0, 1.0, 1.0]) == 2  # gain 2 (ki) refused
    assert a.set_gains([1.0, 1.0, 0.0, 0.0, 1.0, 1.0]) == 4  # n must be > 0


def test_sanitizers_find_nothing(tmp_path: Path) -> None:
    """Each kind, with the paper's systems and with systems from files, built with
    -O2 -fsanitize=address,undefined and driven by a C main over a closed-loop run: no report,
    and the commands equal Python's."""
    driver = """
#include <stdio.h>
#include "NAME.h"
int main(int argc, char **argv)
{
    NAME_ctl c;
    double r, y, y0, u0;
    FILE *f = fopen(argv[1], "r");
    (void)argc;
    if (f == NULL || fscanf(f, "%lf %lf", &y0, &u0) != 2) {
        return 3;
    }
    NAME_init(&c, y0, u0);
    while (fscanf(f, "%lf %lf", &r, &y) == 2) {
        printf("%a\\n", (double)NAME_step(&c, r, y));
    }
    fclose(f);
    return 0;
}
"""
    cases: list[tuple[str, dict[str, Any] | None]] = [(k, None) for k in controller_names()]
    gains_of: dict[int, dict[str, float]] = {}
    for name, systems_, per_kind in _file_systems():
        kind = "stfpi" if name == "paper-fis" else "fpi"
        gains_of[len(cases)] = per_kind[kind]
        cases.append((kind, systems_))
    for i, (kind, systems) in enumerate(cases):
        gains = gains_of.get(i, {n: 0.5 for n in controller_kind(kind).gain_names})
        if systems is None and kind in ("fpi", "stfpi"):
            gains = dict(read_gains_file(GAINS / f"linear-{kind}.toml").gains)
        name = f"s{i}_{kind}"
        cc = generate_c(kind, gains, ts=TS, systems=systems, name=name)
        folder = tmp_path / name
        src = write(cc, folder)
        (folder / "main.c").write_text(driver.replace("NAME", name))
        exe = folder / "run"
        proc = subprocess.run(
            [gcc(), *STRICT, *SANITIZE, "-o", str(exe), str(folder / "main.c"), str(src),
             "-lm"], capture_output=True, text=True, check=False)
        assert proc.returncode == 0, proc.stderr
        plant, res = _run(kind, gains, "nonlinear", options={}, systems=systems,
                          reference=0.1)
        data = folder / "run.txt"
        rows = [f"{float(plant.y0).hex()} {float(plant.u0).hex()}"] + [
            f"{float(a).hex()} {float(b).hex()}" for a, b in zip(res.r, res.y, strict=True)]
        data.write_text("\n".join(rows) + "\n")
        proc = subprocess.run([str(exe), str(data)], capture_output=True, text=True,
                              check=False)
        assert proc.returncode == 0 and proc.stderr == "", proc.stderr
        u = np.array([float.fromhex(s) for s in proc.stdout.split()])
        assert np.max(np.abs(u - res.u)) <= DOUBLE_TOL, (kind, np.max(np.abs(u - res.u)))


def test_two_exports_link_into_one_program(tmp_path: Path) -> None:
    """Two controllers (a PID and a self-tuning fuzzy PI with a system from a file) in one
    program: no symbol clashes, each computes its own commands."""
    a = generate_c("pid", {"kp": 20.0, "ki": 5.0, "kd": 0.1}, ts=TS, name="axis1")
    systems = {"du": loop_system(read_system(SYSTEMS / "paper-du.fcl"), grid=False),
               "alpha": default_systems(("alpha",))["alpha"]}
    b = generate_c("stfpi", dict(read_gains_file(GAINS / "linear-stfpi.toml").gains), ts=TS,
                   systems=systems, name="axis2")
    main_c = """
#include <stdio.h>
#include "axis1.h"
#include "axis2.h"
int main(void)
{
    axis1_ctl a;
    axis2_ctl b;
    axis1_init(&a, 0.5, 0.0);
    axis2_init(&b, 0.5, 0.0);
    printf("%a %a\\n", (double)axis1_step(&a, 0.6, 0.5), (double)axis2_step(&b, 0.6, 0.5));
    return 0;
}
"""
    srcs = [write(a, tmp_path), write(b, tmp_path)]
    (tmp_path / "main.c").write_text(main_c)
    exe = tmp_path / "two"
    proc = subprocess.run([gcc(), *STRICT, "-O2", "-o", str(exe), str(tmp_path / "main.c"),
                           *map(str, srcs), "-lm"], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split()
    ua, ub = (float.fromhex(v) for v in out)
    pa = build_controller("pid", {"kp": 20.0, "ki": 5.0, "kd": 0.1}, dt=TS)
    pb = build_controller("stfpi", dict(read_gains_file(GAINS / "linear-stfpi.toml").gains),
                          dt=TS, systems=systems)
    assert ua == pa.step(pa.initial_state(r0=0.5, y0=0.5), 0.6, 0.5)[0]
    assert ub == pb.step(pb.initial_state(), 0.6, 0.5)[0]
