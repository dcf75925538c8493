"""Nonlinear model: named limits, per-step API = compiled kernel, ripple, τ_v, external force."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzyservo.errors import ParameterError, SimulationDivergedError
from fuzzyservo.paper import paper_params
from fuzzyservo.plant import (
    COMMAND_LIMIT,
    N_STATE,
    STATE_NAMES,
    NonlinearServo,
    ServoParams,
    linearize,
    pack,
    rhs,
    rk4_advance,
    trim,
    with_overrides,
)
from fuzzyservo.plant.nonlinear import PRESSURE_FLOOR_BAND, floor_factor
from fuzzyservo.registry import build_plant
from fuzzyservo.sim import OpenLoopResult, simulate_open_loop


def _open_loop(p: ServoParams, command: object, *, duration: float,
               position: float | None = None) -> OpenLoopResult:
    """Open loop on the nonlinear plant at the open-loop grade RK4 step (0.1 ms)."""
    plant = build_plant("nonlinear", p, position, substep=1e-4)
    return simulate_open_loop(plant, command, duration=duration)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def paper() -> ServoParams:
    return paper_params()


def test_state_names() -> None:
    assert STATE_NAMES == ("spool_lag", "spool", "spool_rate", "p_f", "p_n", "x", "v")
    assert N_STATE == 7


def test_per_step_api_equals_kernel(paper: ServoParams) -> None:
    prof = np.where(np.arange(300) < 150, 0.4, -0.2)
    run = _open_loop(paper, prof, duration=0.3)
    servo = NonlinearServo(paper)
    x = run.states[0].copy()
    for k in range(300):
        x = servo.step(k * 1e-3, x, float(prof[k]), 1e-3)
    # same njit functions, same arithmetic: STYLE §11 asks for 1e-12
    np.testing.assert_allclose(x, run.states[-1], rtol=1e-12, atol=1e-12)
    x2 = run.states[0].copy()
    for k in range(300):
        assert rk4_advance(k * 1e-3, x2, float(prof[k]), pack(paper), 1e-3, 10)
    np.testing.assert_allclose(x2, run.states[-1], rtol=1e-12, atol=1e-12)


def test_command_limit(paper: ServoParams) -> None:
    p = pack(paper)
    x = trim(paper, 0.5).state
    d1, d2 = np.empty(N_STATE), np.empty(N_STATE)
    rhs(0.0, x, 5.0, p, d1)
    rhs(0.0, x, COMMAND_LIMIT, p, d2)
    assert np.array_equal(d1, d2)


@pytest.mark.parametrize(("u", "end"), [(1.0, "top"), (-1.0, "bottom")])
def test_end_stops_hold(paper: ServoParams, u: float, end: str) -> None:
    run = _open_loop(paper, u, duration=6.0, position=0.2 if u > 0 else 0.8)
    stroke = paper.cylinder.stroke
    k, m = paper.cylinder.stop_stiffness, paper.load.mass
    f = paper.cylinder.piston_area * paper.supply.pressure  # largest hydraulic force
    vmax = float(np.max(np.abs(run.v)))
    # an undamped cushion would stop the mass within F/k + sqrt((F/k)² + M v²/k); the damper
    # only shortens that
    bound = f / k + math.sqrt((f / k) ** 2 + m * vmax**2 / k)
    assert run.x.max() <= stroke + bound and run.x.min() >= -bound
    pen = run.x[-1] - stroke if end == "top" else -run.x[-1]
    # at rest the cushion carries the stall force: (A p_f - A_n p_n)/k, 1 % for friction
    stall = abs(paper.cylinder.piston_area * run.p_f[-1] - paper.cylinder.ring_area
                * run.p_n[-1])
    assert pen == pytest.approx(stall / k, rel=0.01)
    assert abs(run.v[-1]) < 1e-3  # at rest against the stop


def test_pressure_floor(paper: ServoParams) -> None:
    # reversing at full command from full speed cavitates a chamber
    prof = np.where(np.arange(1000) < 400, 1.0, -1.0)
    run = _open_loop(paper, prof, duration=1.0)
    low = min(run.p_f.min(), run.p_n.min())
    assert low < PRESSURE_FLOOR_BAND  # the floor is reached...
    assert low >= -1.0  # ...and not crossed (1 Pa for the RK4 step inside the smoothstep)
    assert floor_factor(0.0, 0.0) == 0.0 and floor_factor(2e5, 0.0) == 1.0
    assert floor_factor(0.5 * PRESSURE_FLOOR_BAND, 0.0) == pytest.approx(0.5, abs=1e-15)


def test_supply_ripple_enters_through_time(paper: ServoParams) -> None:
    rp = with_overrides(paper, {"supply.ripple_amplitude": 5e5})
    p = pack(rp)
    x = trim(rp, 0.5).state
    x[1] = 0.5  # open valve
    d0, d1 = np.empty(N_STATE), np.empty(N_STATE)
    rhs(0.0, x, 0.5, p, d0)
    rhs(1.0 / (4 * 225.0), x, 0.5, p, d1)  # quarter period: P_s + 500 kPa
    assert d1[3] > d0[3]
    # flow into p_f scales with sqrt(P_s - p_f); dp_f/dt = Q/C at v = 0 (regularisation 0.1 %)
    pf = x[3]
    ratio = math.sqrt((7.5e6 - pf) / (7.0e6 - pf))
    qleak0 = rp.valve.null_leakage * (7.0e6 - 2 * pf)
    qleak1 = rp.valve.null_leakage * (7.5e6 - 2 * pf)
    c = 0.5 * rp.cylinder.piston_area / rp.fluid.cylinder_bulk_modulus + \
        rp.fluid.hose_volume / rp.fluid.hose_bulk_modulus
    assert (d1[3] * c - qleak1) / (d0[3] * c - qleak0) == pytest.approx(ratio, rel=2e-3)


def test_tau_v_adds_first_order_pole(paper: ServoParams) -> None:
    lin = linearize(with_overrides(paper, {"valve.tau_v": 1e-3}), 0.5)
    assert lin.state_names[0] == "spool_lag"
    # eigenvalue -1/τ_v exactly (the lag is upstream of everything), rounding of the FD Jacobian
    assert np.min(np.abs(lin.eigenvalues + 1000.0)) < 1e-3


def test_external_force_trim(paper: ServoParams) -> None:
    p = with_overrides(paper, {"load.external_force": 20e3})
    tr = trim(p, 0.3)
    c = p.cylinder
    # static force balance, solver tolerance
    assert c.piston_area * tr.p_f - c.ring_area * tr.p_n == pytest.approx(20e3, rel=1e-8)
    with pytest.raises(ParameterError, match="no equilibrium"):
        trim(with_overrides(paper, {"load.external_force": 1e6}), 0.5)


def test_internal_leakage_only(paper: ServoParams) -> None:
    p = with_overrides(paper, {"valve.null_leakage": 0.0, "cylinder.internal_leakage": 5e-11})
    lin = linearize(p, 0.5)
    assert lin.trim.command < 0.0
    assert 0.0 < lin.damping < 1.0


def test_per_step_errors(paper: ServoParams) -> None:
    with pytest.raises(ParameterError, match="substep"):
        NonlinearServo(paper, substep=0.0)
    servo = NonlinearServo(with_overrides(paper, {"valve.omega_v": 1e6}), substep=1e-3)
    x = servo.rest_state(0.5)
    with pytest.raises(SimulationDivergedError, match="t = "):
        for k in range(200):
            x = servo.step(k * 1e-3, x, 0.5, 1e-3)
