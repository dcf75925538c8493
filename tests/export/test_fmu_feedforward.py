"""The controller FMU's feed-forward inputs (issue 25): ``r_rate`` [m/s] and ``r_accel``
[m/s²], the reference's velocity and acceleration that ``simulate`` gives a law at each
sample, passed to ``NAME_step_ff``. Tested on a law that uses them (tests/export/
feedforward_law.py, registered only while these tests run: the package may have no such
kind) and on one that ignores them."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from fuzzyservo.cli import main
from fuzzyservo.paper.published import named_set
from fuzzyservo.registry import (
    build_controller,
    build_plant,
    controller_kind,
    register_controller,
    unregister_controller,
)
from fuzzyservo.sim import SCurve, simulate
from tests.export import feedforward_law
from tests.export.fmu_harness import slaves

PARAMS = named_set("paper")
STROKE = PARAMS.cylinder.stroke
TS = 1e-3
#: Feedback and both feed-forward gains: kv ~ 1/(K_o K_v), so the feed-forward carries most
#: of the move.
GAINS = {"kp": 15.0, "kv": 4.0, "ka": 0.02}
#: A jerk-limited 0.1 m move from 50 ms: its velocity and acceleration are exact polynomials.
REFERENCE = SCurve(distance=0.1, v_max=0.25, a_max=3.0, j_max=150.0, time=0.05)


@pytest.fixture(autouse=True, scope="module")
def _registered() -> Iterator[None]:
    register_controller(feedforward_law.KIND, replace=True)
    yield
    unregister_controller(feedforward_law.KIND.name)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory, _registered: None) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("ff")
    out = {"ff": d / "ff.fmu", "pid": d / "pid.fmu"}
    assert main(["export", "fmu", "--controller", "testff", "--gains",
                 ",".join(f"{k}={v!r}" for k, v in GAINS.items()), "--out",
                 str(out["ff"])]) == 0
    assert main(["export", "fmu", "--controller", "pid", "--gains", "kp=20,ki=5,kd=0.5",
                 "--out", str(out["pid"])]) == 0
    return out


def _drive(path: Path, r: np.ndarray, y: np.ndarray, rd: np.ndarray, rdd: np.ndarray,
           u0: float) -> np.ndarray:
    """The controller FMU alone, fed at each sample the r_k, y_k, r'_k and r''_k of a
    recorded run; returns its commands."""
    us = []
    with slaves((path, "ctl")) as (ctl,):
        ctl.set(u_start=u0, y=float(y[0]), r=float(y[0]))
        ctl.fmu.exitInitializationMode()
        t = 0.0
        for k in range(r.size):
            ctl.set(r=float(r[k]), y=float(y[k]), r_rate=float(rd[k]), r_accel=float(rdd[k]))
            ctl.fmu.doStep(t, TS)
            t += TS
            us.append(ctl.get("u")[0])
    return np.array(us)


def test_the_feed_forward_law_is_one(fmus: dict[str, Path]) -> None:
    """The test law declares feed-forward (the FMU's inputs are then its inputs); its
    model description says so, the PID's says they are ignored."""
    assert controller_kind("testff").cls.law.feedforward
    assert not controller_kind("pid").cls.law.feedforward
    for key, used in (("ff", True), ("pid", False)):
        assert validate_fmu(str(fmus[key])) == []
        md = read_model_description(str(fmus[key]))
        v = {x.name: x for x in md.modelVariables}
        for name, unit in (("r_rate", "m/s"), ("r_accel", "m/s2")):
            assert (v[name].causality, v[name].variability, v[name].unit,
                    float(v[name].start)) == ("input", "continuous", unit, 0.0)
            assert ("ignored by this law" in v[name].description) is not used


@pytest.mark.parametrize("plant", ["linear", "nonlinear"])
def test_feed_forward_inputs_give_simulates_commands(plant: str,
                                                     fmus: dict[str, Path]) -> None:
    """An S-curve reference: the FMU given r, r_rate = r'(t_k), r_accel = r''(t_k)
    (``SCurve.values``/``rates``) and the run's measurements gives the commands
    ``simulate`` gives to 1e-12 (one port of one law, the same operations); without the
    rates (0, as NAME_step) it does not, so the inputs reach the law."""
    plant_obj = build_plant(plant, PARAMS, 0.5 * STROKE)
    ctl = build_controller("testff", GAINS, dt=TS)
    res = simulate(ctl, plant_obj, REFERENCE, duration=0.6)
    rd, rdd = REFERENCE.rates(res.t)
    assert np.array_equal(res.r, REFERENCE.values(res.t) + plant_obj.y0)
    u = _drive(fmus["ff"], res.r, res.y, rd, rdd, plant_obj.u0)
    assert np.max(np.abs(u - res.u)) <= 1e-12, np.max(np.abs(u - res.u))
    u_fb = _drive(fmus["ff"], res.r, res.y, 0.0 * rd, 0.0 * rdd, plant_obj.u0)
    assert np.max(np.abs(u_fb - res.u)) > 0.1  # the feed-forward is most of the command
    assert np.ptp(res.y) > 0.05  # the loop followed the move


def test_a_law_without_feed_forward_ignores_the_inputs(fmus: dict[str, Path]) -> None:
    """The PID's FMU has the same inputs and gives the same commands whatever they are."""
    plant_obj = build_plant("linear", PARAMS, 0.5 * STROKE)
    res = simulate(build_controller("pid", {"kp": 20.0, "ki": 5.0, "kd": 0.5}, dt=TS),
                   plant_obj, REFERENCE, duration=0.3)
    rd, rdd = REFERENCE.rates(res.t)
    u = _drive(fmus["pid"], res.r, res.y, rd, rdd, plant_obj.u0)
    assert np.max(np.abs(u - res.u)) <= 1e-12
    assert np.max(np.abs(rd)) > 0.1
