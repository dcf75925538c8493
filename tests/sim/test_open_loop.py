"""Open-loop simulation: acceptance figures of issue 3, compiled RK4 vs solve_ivp, delay."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from fuzzyservo.errors import InputError, ParameterError, SimulationDivergedError
from fuzzyservo.paper import paper_params
from fuzzyservo.plant import ServoParams, trim, with_overrides
from fuzzyservo.sim.closed_loop import MAX_SAMPLES
from fuzzyservo.sim.open_loop import simulate_open_loop

OFF = {"valve.null_leakage": 0.0, "cylinder.internal_leakage": 0.0,
       "load.coulomb_friction": 0.0, "load.static_friction": 0.0, "load.viscous_damping": 0.0}


@pytest.fixture(scope="module")
def paper() -> ServoParams:
    return paper_params()


@pytest.fixture(scope="module")
def ideal(paper: ServoParams) -> ServoParams:
    return with_overrides(paper, OFF)


def _steady(p: ServoParams, u: float) -> tuple[float, float, float]:
    r = simulate_open_loop(p, u, duration=2.0)
    return float(r.v[-1]), float(r.p_f[-1]), float(r.p_n[-1])


def test_no_load_speeds_and_pressures(ideal: ServoParams) -> None:
    af = ideal.cylinder.piston_area
    rr = ideal.cylinder.area_ratio
    ps = ideal.supply.pressure
    v_ext, pf_e, pn_e = _steady(ideal, 0.5)
    v_ret, pf_r, pn_r = _steady(ideal, -0.5)
    # acceptance: 3 % (the laminar regularisation alone costs 0.15 %)
    assert v_ext == pytest.approx(0.5 * ideal.valve.rated_flow / af, rel=0.03)
    assert -v_ret == pytest.approx(math.sqrt(rr) * v_ext, rel=0.03)
    # orifice balance (model notes §3.1): extension p_f = r³/(1+r³) P_s, p_n = r²/(1+r³) P_s
    assert pf_e == pytest.approx(rr**3 / (1 + rr**3) * ps, rel=0.03)
    assert pn_e == pytest.approx(rr**2 / (1 + rr**3) * ps, rel=0.03)
    # retraction p_f = r/(1+r³) P_s, p_n = 1/(1+r³) P_s
    assert pf_r == pytest.approx(rr / (1 + rr**3) * ps, rel=0.03)
    assert pn_r == pytest.approx(1 / (1 + rr**3) * ps, rel=0.03)


def test_leakage_and_friction_shift_as_documented(paper: ServoParams,
                                                  ideal: ServoParams) -> None:
    """docs/model.md, "Effect of leakage and friction": the numbers stated there."""
    v0e, pf0e, _ = _steady(ideal, 0.5)
    v0r, pf0r, _ = _steady(ideal, -0.5)
    ve, pfe, _ = _steady(paper, 0.5)
    vr, pfr, _ = _steady(paper, -0.5)
    # the doc states one decimal: half a unit of it, 0.05 percentage points
    assert 100 * (ve / v0e - 1) == pytest.approx(6.7, abs=0.05)
    assert 100 * (vr / v0r - 1) == pytest.approx(-8.2, abs=0.05)
    assert 100 * (pfe / pf0e - 1) == pytest.approx(36.9, abs=0.05)
    assert 100 * (pfr / pf0r - 1) == pytest.approx(-10.1, abs=0.05)


def _profile(t: float) -> float:
    return 0.5 if t < 0.5 else (-0.3 if t < 1.2 else 0.1)


def test_rk4_matches_solve_ivp(paper: ServoParams) -> None:
    a = simulate_open_loop(paper, _profile, duration=2.0)
    b = simulate_open_loop(paper, _profile, duration=2.0, method="solve_ivp", rtol=1e-11)
    # acceptance: 1e-6 relative in position (RK4 at 0.1 ms reaches ~1e-8)
    np.testing.assert_allclose(a.x, b.x, rtol=1e-6)
    assert a.p_f.min() < 1e5  # the profile drives a chamber into the pressure floor


def test_delay_is_a_time_shift(paper: ServoParams) -> None:
    no = replace(paper, delay=replace(paper.delay, transport_delay=0.0))
    a = simulate_open_loop(no, _profile, duration=0.6)
    b = simulate_open_loop(paper, _profile, duration=0.6)
    # time invariant (no ripple): shifted by 6 samples exactly, up to rounding
    np.testing.assert_allclose(b.x[6:], a.x[:-6], rtol=0, atol=1e-12)
    with pytest.raises(ParameterError, match="delay.transport_delay = 0.006 s is not a whole"):
        simulate_open_loop(paper, 0.1, duration=0.1, dt=4e-3)


def test_explicit_delay_overrides_the_set(paper: ServoParams) -> None:
    no = replace(paper, delay=replace(paper.delay, transport_delay=0.0))
    a = simulate_open_loop(no, _profile, duration=0.6)
    b = simulate_open_loop(paper, _profile, duration=0.6, delay=0.0)
    c = simulate_open_loop(no, _profile, duration=0.6, delay=0.012)
    # same arithmetic on the same inputs: bit for bit
    np.testing.assert_array_equal(b.states, a.states)
    # shifted by 12 samples, up to rounding
    np.testing.assert_allclose(c.x[12:], a.x[:-12], rtol=0, atol=1e-12)
    with pytest.raises(ParameterError, match=r"delay must be finite and >= 0 s, got -0.001"):
        simulate_open_loop(paper, 0.1, duration=0.1, delay=-1e-3)
    with pytest.raises(ParameterError, match=r"delay = 0.0025 s is not a whole number of "
                                             r"samples of dt = 0.001 s"):
        simulate_open_loop(paper, 0.1, duration=0.1, delay=2.5e-3)


def test_duration_shorter_than_a_sample_or_too_long(paper: ServoParams) -> None:
    with pytest.raises(ParameterError, match=r"at least one sample \(0.001 s\), got 1e-09"):
        simulate_open_loop(paper, 0.1, duration=1e-9)
    # one sample past the limit of the closed loop's grid; fails before allocating
    too_long = (MAX_SAMPLES + 1) * 1e-3
    with pytest.raises(ParameterError, match=f"at most {MAX_SAMPLES} are allowed"):
        simulate_open_loop(paper, 0.5, duration=too_long)
    r = simulate_open_loop(paper, 0.1, duration=2.5e-3)
    # cut to whole samples like the closed loop's grid: 0, 1, 2 ms
    np.testing.assert_array_equal(r.t, [0.0, 1e-3, 2e-3])


def test_linear_plant_small_command(paper: ServoParams) -> None:
    # the linearisation leaves out Coulomb friction (docs/model.md), so compare without it
    p = with_overrides(paper, {"load.coulomb_friction": 0.0, "load.static_friction": 0.0})
    u = trim(p, 0.5).command + 0.005
    lin = simulate_open_loop(p, u, duration=1.0, plant="linear")
    non = simulate_open_loop(p, u, duration=1.0)
    # a small deviation from the trim: the linearisation holds to a few % of the motion
    dx = non.x - 0.5
    np.testing.assert_allclose(lin.x - 0.5, dx, atol=0.03 * abs(dx[-1]))


def test_divergence_names_time_and_state(paper: ServoParams) -> None:
    stiff = with_overrides(paper, {"valve.omega_v": 1e6})
    with pytest.raises(SimulationDivergedError, match=r"diverged at t = .* s: state spool_lag="):
        simulate_open_loop(stiff, 0.1, duration=0.2, substep=1e-3)


def test_bad_inputs(paper: ServoParams) -> None:
    with pytest.raises(InputError, match="not finite at t = 0.002 s"):
        simulate_open_loop(paper, [0.0, 0.0, float("nan")], duration=0.003)
    with pytest.raises(InputError, match="3 samples, need 5"):
        simulate_open_loop(paper, [0.0, 0.0, 0.0], duration=0.005)
    with pytest.raises(ParameterError, match="duration must be finite and at least one"):
        simulate_open_loop(paper, 0.0, duration=-1.0)
    with pytest.raises(ParameterError, match="position must be inside the stroke"):
        simulate_open_loop(paper, 0.0, duration=0.1, position=1.2)
