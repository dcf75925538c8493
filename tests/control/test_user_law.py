"""A control law added from outside the package (tests/control/leadlag.py, a lead-lag
compensator with its C port) runs through every front end with no edit to fuzzyservo:
simulate, simulate_batch (bit-identical to simulate), the per-step API, tune, a sweep, the
page's settings and ``export c`` (compiled with gcc, equal to Python to 1e-12)."""

from __future__ import annotations

import math
import os
import shlex
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.paper import named_set
from fuzzyservo.registry import (
    build_controller,
    build_plant,
    controller_kind,
    controller_names,
    register_controller,
    unregister_controller,
)
from fuzzyservo.sim import Step, simulate, simulate_batch
from tests.control import leadlag
from tests.export.ctl_harness import CStep, build

# importing the module registers the law (as a user's module does); here it is registered only
# while this module's tests run, so the tests that go over every registered kind see the
# package's own
unregister_controller("leadlag")
PARAMS = named_set("paper")
GAINS = {"k": 8.0, "t1": 0.02, "t2": 0.002}
TS = 1e-3
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(autouse=True, scope="module")
def _registered() -> Iterator[None]:
    register_controller(leadlag.KIND, replace=True)
    yield
    unregister_controller("leadlag")


def _tustin(k: float, t1: float, t2: float, e: np.ndarray) -> np.ndarray:
    """The lead-lag's difference equation, unclamped, written here from C(s) (not from the
    module): v_k = b0 e_k + b1 e_{k-1} - a1 v_{k-1}."""
    h = TS
    den = 1.0 + 2.0 * t2 / h
    b0, b1, a1 = k * (1.0 + 2.0 * t1 / h) / den, k * (1.0 - 2.0 * t1 / h) / den, (
        1.0 - 2.0 * t2 / h) / den
    v = np.zeros_like(e)
    for i in range(e.size):
        v[i] = b0 * e[i] + (b1 * e[i - 1] - a1 * v[i - 1] if i else 0.0)
    return v


def test_the_law_is_registered_and_named_everywhere() -> None:
    assert "leadlag" in controller_names()
    kind = controller_kind("leadlag")
    assert kind.cls is leadlag.LeadLagController
    # the layout comes from the declaration: names, and positions by name
    law = leadlag.LEADLAG_LAW
    assert law.param_names == ("b0", "b1", "a1", "u_min", "u_max")
    assert law.state_names == ("e_prev", "v_prev", "u_off")
    assert leadlag.P.a1 == 2 and leadlag.S.u_off == 2


def test_per_step_api_is_the_difference_equation() -> None:
    ctl = build_controller("leadlag", GAINS, dt=TS, options={"u_min": -10.0, "u_max": 10.0})
    rng = np.random.default_rng(1)
    r, y = rng.normal(0, 0.01, 200), rng.normal(0, 0.01, 200)
    state = ctl.initial_state()
    u = []
    for a, b in zip(r, y, strict=True):
        uk, state = ctl.step(state, float(a), float(b))
        u.append(uk)
    np.testing.assert_allclose(u, _tustin(8.0, 0.02, 0.002, r - y), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("plant_name", ["linear", "nonlinear"])
def test_simulate_and_the_batch_agree_bit_for_bit(plant_name: str) -> None:
    plant = build_plant(plant_name, PARAMS)
    ctl = build_controller("leadlag", GAINS, dt=TS)
    one = simulate(ctl, plant, Step(0.05), duration=0.5)
    assert np.all(np.isfinite(one.y)) and abs(one.y[-1] - one.r[-1]) < 0.02
    rows = np.array([[8.0, 0.02, 0.002], [3.0, 0.05, 0.004], [8.0, 0.02, 0.002]])
    batch = simulate_batch(ctl, rows, plant=plant, reference=Step(0.05), duration=0.5,
                           keep_traces=True)
    for i in (0, 2):
        assert batch.y is not None and batch.u is not None
        np.testing.assert_array_equal(batch.y[i], one.y)
        np.testing.assert_array_equal(batch.u[i], one.u)
    other = simulate(build_controller("leadlag", {"k": 3.0, "t1": 0.05, "t2": 0.004}, dt=TS),
                     plant, Step(0.05), duration=0.5)
    np.testing.assert_array_equal(batch.y[1], other.y)


def test_the_traced_state_is_the_unclamped_output() -> None:
    plant = build_plant("linear", PARAMS)
    ctl = build_controller("leadlag", GAINS, dt=TS, options={"u_min": -0.2, "u_max": 0.2})
    res = simulate(ctl, plant, Step(0.05), duration=0.3)
    v = _tustin(8.0, 0.02, 0.002, np.asarray(res.r) - np.asarray(res.y))
    np.testing.assert_allclose(res.alpha, v, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(res.u, np.clip(plant.u0 + v, -0.2, 0.2), rtol=0, atol=1e-15)


def test_tune_searches_the_declared_gains() -> None:
    from fuzzyservo.analysis.autotune import TuningSetup, tune_controller
    from fuzzyservo.analysis.tuning import TuningConstraints

    setup = TuningSetup(controller="leadlag", plant="linear", step=0.02, duration=1.0,
                        constraints=TuningConstraints(max_overshoot=10.0,
                                                      max_steady_state_error=0.01),
                        popsize=4, maxiter=4, restarts=1, seed=1)
    tuned = tune_controller(setup, PARAMS)
    assert set(dict(tuned.gains)) == {"k", "t1", "t2"}
    # the tuned gains reproduce the metrics the tuner reports
    ctl = build_controller("leadlag", dict(tuned.gains), dt=TS)
    res = simulate(ctl, build_plant("linear", PARAMS, 0.5 * PARAMS.cylinder.stroke),
                   Step(0.02), duration=1.0)
    assert res.metrics().as_dict()["itae"] == pytest.approx(dict(tuned.metrics)["itae"],
                                                          rel=1e-12)


def test_a_small_sweep_runs_it(tmp_path: Path) -> None:
    from fuzzyservo.analysis import step_metrics
    from fuzzyservo.cli import main
    from fuzzyservo.files import read_run_csv
    from fuzzyservo.sim.stepinfo import METRIC_NAMES
    from fuzzyservo.sweep import read_table, run_sweep
    from fuzzyservo.sweep.replay import simulate_command
    from fuzzyservo.sweep.spec import parse_spec

    doc = {"sweep": {"name": "lead-lag", "plant": "linear", "param_set": "paper",
                     "start": 0.5, "ts": TS, "duration": 0.5, "samples": 1, "seed": 1,
                     "chunk": 2},
           "reference": {"spec": "step:0.05"},
           "controllers": [{"label": "lead-lag", "controller": "leadlag", "gains": GAINS}],
           "vary": [{"name": "load.mass", "relative": True, "grid": [0.5, 2.0]}]}
    spec = parse_spec(doc, base_dir=tmp_path)
    run_sweep(spec, tmp_path / "out", processes=1, progress=False)
    rows = read_table(tmp_path / "out").to_pylist()
    assert len(rows) == 2 and {r["controller"] for r in rows} == {"lead-lag"}
    # each row is the run its replayed command line makes, metric for metric
    for k, row in enumerate(rows):
        argv = shlex.split(simulate_command(spec, row))[1:]
        argv.remove("--metrics")
        csv = tmp_path / f"run{k}.csv"
        assert main([*argv, "--out", str(csv)]) == 0
        m = step_metrics(read_run_csv(csv)).as_dict()
        assert all(m[n] == row[n] or (math.isnan(m[n]) and math.isnan(row[n]))
                   for n in METRIC_NAMES)
        assert np.isfinite(row["itae"])


def test_the_page_runs_and_pins_it() -> None:
    from fuzzyservo.app.page import pin_colour
    from fuzzyservo.app.settings import PageSettings, run_page

    run = run_page(PageSettings(controller="leadlag", gains=tuple(GAINS.items()),
                                duration=0.5))
    assert run.settings.controller == "leadlag" and np.all(np.isfinite(run.y))
    assert "--controller leadlag" in run.settings.command()
    assert pin_colour("leadlag").startswith("#")


def test_export_c_equals_python(tmp_path: Path) -> None:
    from fuzzyservo.export.targets import generate_c

    cc = generate_c("leadlag", GAINS, ts=TS, name="c_leadlag")
    text = cc.files()["c_leadlag.c"]
    assert "FS_P_B0" in text and "p[0]" not in text  # indexed by name
    c = CStep(build(cc, tmp_path), cc)
    rng = np.random.default_rng(4)
    for plant_name in ("linear", "nonlinear"):
        plant = build_plant(plant_name, PARAMS)
        ref = np.repeat(rng.uniform(-0.1, 0.1, 5), 200)
        res = simulate(build_controller("leadlag", GAINS, dt=TS), plant, ref, duration=0.999)
        u = c.replay(res.r, res.y, plant.y0, plant.u0)
        assert float(np.max(np.abs(u - res.u))) <= 1e-12
        # new gains through NAME_set_gains, in the law's gain columns
        g2 = {"k": 2.0, "t1": 0.1, "t2": 0.01}
        res2 = simulate(build_controller("leadlag", g2, dt=TS), plant, ref, duration=0.999)
        u2 = c.replay(res2.r, res2.y, plant.y0, plant.u0, gains=list(g2.values()))
        assert float(np.max(np.abs(u2 - res2.u))) <= 1e-12


def test_the_command_line_takes_it_from_a_plugin_module(tmp_path: Path) -> None:
    env = {**os.environ, "FUZZYSERVO_PLUGINS": "tests.control.leadlag",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    out = tmp_path / "run.csv"
    proc = subprocess.run(
        [sys.executable, "-m", "fuzzyservo", "simulate", "--plant", "linear",
         "--controller", "leadlag", "--gains", "k=8,t1=0.02,t2=0.002", "--reference",
         "step:0.05", "--duration", "0.5", "--out", str(out)],
        capture_output=True, text=True, env=env, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    data = np.genfromtxt(out, delimiter=",", names=True)
    res = simulate(build_controller("leadlag", GAINS, dt=TS),
                   build_plant("linear", PARAMS, 0.5 * PARAMS.cylinder.stroke), Step(0.05),
                   duration=0.5)
    np.testing.assert_array_equal(data["y"], res.y)
