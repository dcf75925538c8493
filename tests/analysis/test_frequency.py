"""The closed loop's frequency response (analysis/frequency.py): the linear loop is the loop the
simulator runs, the PID's linearisation is its exact z-transfer function, the margins are
python-control's, and a sine sweep measured on the linear plant is the analytic response."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.analysis.frequency import (
    closed_loop_bode,
    linearize_controller,
    loop_model,
    margins,
    measured_response,
)
from fuzzyservo.errors import InputError
from fuzzyservo.files import read_gains_file
from fuzzyservo.registry import build_controller, build_plant
from fuzzyservo.sim import Step, simulate

TS = 1e-3
GAINS = Path(__file__).parents[2] / "src" / "fuzzyservo" / "data" / "gains"
#: a full two-degree-of-freedom PID that is stable on the linear plant (every term active)
PID = {"kp": 6.0, "ki": 3.0, "kd": 0.05, "n": 100.0, "b": 0.7, "c": 0.5}


@pytest.fixture(scope="module")
def plant():  # type: ignore[no-untyped-def]
    return build_plant("linear", "paper")


def _pid_exact(z: np.ndarray, g: dict[str, float], h: float) -> tuple[np.ndarray, np.ndarray]:
    """C_r(z), C_y(z) of control/pid.py's docstring: backward-Euler integral and filtered
    derivative, I = K_i h/(1 - z^-1) e, D = K_d N/(1 + N h) (1 - z^-1)/(1 - z^-1/(1 + N h)) ed."""
    zi = 1.0 / z
    integ = g["ki"] * h / (1.0 - zi)
    if math.isinf(g["n"]):
        der = g["kd"] / h * (1.0 - zi)
    else:
        der = g["kd"] * g["n"] / (1.0 + g["n"] * h) * (1.0 - zi) / (1.0 - zi / (1.0 + g["n"] * h))
    return g["kp"] * g["b"] + integ + der * g["c"], -(g["kp"] + integ + der)


@pytest.mark.parametrize("n", [100.0, math.inf])
def test_pid_linearisation_is_its_z_transfer_function(n: float) -> None:
    g = {**PID, "n": n}
    ctl = build_controller("pid2", g, dt=TS)
    lin = linearize_controller(ctl, y0=0.1, u0=0.02)
    z = np.exp(1j * np.linspace(0.01, math.pi, 50))
    want_r, want_y = _pid_exact(z, g, TS)
    # difference quotients of a linear law at h = 1e-3: round-off ~1e-13 relative
    assert lin.from_reference().at(z) == pytest.approx(want_r, rel=1e-10)
    assert lin.from_measurement().at(z) == pytest.approx(want_y, rel=1e-10)
    assert lin.error < 1e-10


def test_closed_loop_state_space_is_the_simulated_loop(plant) -> None:  # type: ignore[no-untyped-def]
    # a fractional delay of 2.5 samples exercises both delayed commands u_{k-d}, u_{k-d-1}
    ctl = build_controller("pid2", PID, dt=TS)
    delay = 2.5e-3
    res = simulate(ctl, plant, Step(0.01), duration=1.0, delay=delay)
    model = loop_model(ctl, plant, delay=delay)
    y = model.closed_loop().simulate(res.r - plant.y0)
    # the same loop, its sums in another order; the simulator's controller works on absolute
    # positions (0.5 m): round-off of 1e-12 of them (measured: 1.3e-14 m)
    assert np.max(np.abs(res.y - plant.y0 - y)) <= 1e-12 * plant.y0


def _python_control_margins(model):  # type: ignore[no-untyped-def]
    """python-control's margin on the same discrete loop, control.ss(A, B, C, D, dt).

    Its margin on the state space itself converts it to a transfer function first, whose
    polynomial coefficients do not hold the loop's poles near z = 1 (1 ms sampling of a
    plant with an integrator): it warns and falls back to a coarse frequency grid (and on a P
    loop finds a spurious crossing near 0 Hz). So it is given its own frequency response of
    the state space (control.frd, 20,001 log-spaced points up to Nyquist, spline
    interpolated) and its crossing search and margin rules do the rest."""
    control = pytest.importorskip("control")
    loop = model.loop_transfer()
    sys = control.ss(loop.a, loop.b[:, None], loop.c[None, :], [[loop.d]], model.ts)
    w = np.geomspace(2 * np.pi * 1e-4, np.pi / model.ts, 20001)[:-1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gm, pm, wcg, wcp = control.margin(control.frd(sys, w, smooth=True))
    return gm, pm, wcg / (2 * np.pi), wcp / (2 * np.pi)


@pytest.mark.parametrize("design", ["linear-pid", "linear-pid2", "linear-fpi", "linear-stfpi",
                                    "pid-delay"])
def test_margins_equal_python_control(design: str, plant) -> None:  # type: ignore[no-untyped-def]
    if design == "pid-delay":
        ctl, delay = build_controller("pid2", PID, dt=TS), 2.5e-3
    else:
        g = read_gains_file(GAINS / f"{design}.toml")
        ctl, delay = build_controller(g.controller, g.gains, dt=TS), 0.0
    model = loop_model(ctl, plant, delay=delay)
    m = margins(model)
    gm, pm, fg, fp = _python_control_margins(model)
    print(f"{design}: gm {m.gain_margin!r} vs {gm!r}, pm {m.phase_margin_deg!r} vs {pm!r}, "
          f"f180 {m.phase_crossover!r} vs {fg!r}, fc {m.gain_crossover!r} vs {fp!r}")
    # both solve the same crossings; python-control's on a spline of its 20,001 points
    assert m.gain_margin == pytest.approx(gm, rel=1e-8)
    assert m.phase_margin_deg == pytest.approx(pm, rel=1e-8, abs=1e-8)
    assert m.phase_crossover == pytest.approx(fg, rel=1e-8)
    assert m.gain_crossover == pytest.approx(fp, rel=1e-8)


def test_measured_response_on_the_linear_plant_is_the_analytic_one(plant) -> None:  # type: ignore[no-untyped-def]
    ctl = build_controller("pid2", PID, dt=TS)
    f = np.array([0.5, 2.0, 7.0, 30.0, 120.0])
    bode = closed_loop_bode(ctl, plant, f, delay=2.5e-3)
    meas = measured_response(ctl, plant, f, amplitude=5e-3, delay=2.5e-3, cycles=3, batch=2)
    # steady state of the sampled loop is exactly the sampled sine through T; what is left
    # is the transient after 14 time constants of the slowest pole (1e-6) and round-off
    assert meas.response == pytest.approx(bode.closed_loop, rel=1e-5, abs=1e-7)
    assert np.all(meas.distortion < 1e-5)


def test_frequencies_must_be_below_nyquist(plant) -> None:  # type: ignore[no-untyped-def]
    ctl = build_controller("pid2", PID, dt=TS)
    with pytest.raises(InputError, match="Nyquist"):
        closed_loop_bode(ctl, plant, [1.0, 600.0])
    with pytest.raises(InputError, match="Nyquist"):
        measured_response(ctl, plant, [500.0], amplitude=1e-3)
