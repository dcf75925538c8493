"""Open loop: acceptance figures of issue 3, compiled RK4 vs solve_ivp, any delay, any plant."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from fuzzyservo.errors import InputError, ParameterError, SimulationDivergedError
from fuzzyservo.paper import paper_params
from fuzzyservo.plant import LinearServo, ServoParams, linearize, trim, with_overrides
from fuzzyservo.registry import build_plant
from fuzzyservo.sim import OpenLoopResult, simulate_open_loop
from fuzzyservo.sim.closed_loop import MAX_SAMPLES

OFF = {"valve.null_leakage": 0.0, "cylinder.internal_leakage": 0.0,
       "load.coulomb_friction": 0.0, "load.static_friction": 0.0, "load.viscous_damping": 0.0}
#: the open-loop characterisation runs RK4 at 0.1 ms (ten steps per 1 ms sample)
FINE = 1e-4


@pytest.fixture(scope="module")
def paper() -> ServoParams:
    return paper_params()


@pytest.fixture(scope="module")
def ideal(paper: ServoParams) -> ServoParams:
    return with_overrides(paper, OFF)


def _run(p: ServoParams, command: object, *, plant: str = "nonlinear", **kw: object
         ) -> OpenLoopResult:
    return simulate_open_loop(build_plant(plant, p, substep=FINE), command,  # type: ignore[arg-type]
                              **kw)  # type: ignore[arg-type]


def _steady(p: ServoParams, u: float) -> tuple[float, float, float]:
    r = _run(p, u, duration=2.0)
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
    assert 100 * (pfe / pf0e - 1) == pytest.approx(36.8, abs=0.05)
    assert 100 * (pfr / pf0r - 1) == pytest.approx(-10.1, abs=0.05)


def _profile(t: float) -> float:
    return 0.5 if t < 0.5 else (-0.3 if t < 1.2 else 0.1)


@pytest.mark.parametrize("delay", [0.0, 0.0063])
def test_rk4_matches_solve_ivp(paper: ServoParams, delay: float) -> None:
    """The compiled loop and scipy's DOP853 integrating the same delayed, held command
    (the fractional delay switches inside a sample: 6 samples + 0.3 ms)."""
    a = _run(paper, _profile, duration=2.0, delay=delay)
    b = _run(paper, _profile, duration=2.0, delay=delay, method="solve_ivp", rtol=1e-11)
    # acceptance: 1e-6 relative in position (RK4 at 0.1 ms reaches ~1e-8)
    np.testing.assert_allclose(a.x, b.x, rtol=1e-6)
    assert a.p_f.min() < 1e5  # the profile drives a chamber into the pressure floor
    assert a.method == "rk4" and b.method == "solve_ivp:DOP853"


def test_delay_is_a_time_shift(paper: ServoParams) -> None:
    a = _run(paper, _profile, duration=0.6)
    b = _run(paper, _profile, duration=0.6, delay=paper.delay.transport_delay)
    # time invariant (no ripple): shifted by 6 samples exactly, up to rounding
    np.testing.assert_allclose(b.x[6:], a.x[:-6], rtol=0, atol=1e-12)
    c = _run(paper, _profile, duration=0.6, delay=0.012)
    np.testing.assert_allclose(c.x[12:], a.x[:-12], rtol=0, atol=1e-12)
    with pytest.raises(ParameterError, match=r"delay must be finite and >= 0 s, got -0.001"):
        _run(paper, 0.1, duration=0.1, delay=-1e-3)


def test_default_is_no_delay(paper: ServoParams) -> None:
    a = _run(paper, _profile, duration=0.3)
    b = _run(paper, _profile, duration=0.3, delay=0.0)
    np.testing.assert_array_equal(a.states, b.states)  # same arithmetic, bit for bit
    assert a.delay == 0.0


@pytest.mark.parametrize("kind", ["linear", "small-signal"])
def test_linear_plants_against_scipy(paper: ServoParams, kind: str) -> None:
    """Exact ZOH with a fractional delay against scipy: the command schedule delayed by
    2.5 samples is a held signal on a half-sample grid, which cont2discrete/dlsim propagate."""
    dt, delay = 1e-3, 2.5e-3
    u = np.where(np.arange(400) < 150, 0.3, -0.2)
    plant = build_plant(kind, paper)
    run = simulate_open_loop(plant, u, duration=0.4, dt=dt, delay=delay)
    if kind == "linear":
        a, b, c, d = LinearServo.from_params(paper, linearize(paper)).state_space()
        u0 = 0.0
    else:
        lin = linearize(paper)
        a, b, c, d = lin.a, lin.b[:, None], lin.c[None, :], np.zeros((1, 1))
        u0 = lin.trim.command
    h = dt / 2
    fine = np.concatenate([np.full(5, u0), np.repeat(u, 2)])[:800] - u0
    ad, bd, cd, dd, _ = signal.cont2discrete((a, b, c, d), h, method="zoh")
    _, y, _ = signal.dlsim((ad, bd, cd, dd, h), fine)
    y = y.ravel()[::2] + plant.y0
    # two exact ZOH recursions of the same system: rounding, far below 1e-9 of the motion
    motion = np.max(np.abs(y - plant.y0))
    assert motion > 1e-3
    np.testing.assert_allclose(run.y[:400], y, rtol=0, atol=1e-9 * motion)
    assert run.method == "zoh"


def test_small_signal_plant_small_command(paper: ServoParams) -> None:
    # the linearisation leaves out Coulomb friction (docs/model.md), so compare without it
    p = with_overrides(paper, {"load.coulomb_friction": 0.0, "load.static_friction": 0.0})
    u = trim(p, 0.5).command + 0.005
    lin = _run(p, u, duration=1.0, plant="small-signal")
    non = _run(p, u, duration=1.0)
    # a small deviation from the trim: the linearisation holds to a few % of the motion
    dx = non.x - 0.5
    np.testing.assert_allclose(lin.x - 0.5, dx, atol=0.03 * abs(dx[-1]))
    # the same state names where both have them, pressures included
    assert set(lin.state_names) <= set(non.state_names) and "p_f" in lin.state_names


def test_eq8_has_no_pressures(paper: ServoParams) -> None:
    run = _run(paper, 0.2, duration=0.1, plant="linear")
    assert run.x[0] == pytest.approx(0.5, abs=0)  # absolute position, mid-stroke
    with pytest.raises(ParameterError, match="no state 'p_f'"):
        _ = run.p_f


def test_duration_shorter_than_a_sample_or_too_long(paper: ServoParams) -> None:
    with pytest.raises(ParameterError, match=r"at least one sample \(0.001 s\), got 1e-09"):
        _run(paper, 0.1, duration=1e-9)
    # one sample past the limit of the closed loop's grid; fails before allocating
    too_long = (MAX_SAMPLES + 1) * 1e-3
    with pytest.raises(ParameterError, match=f"at most {MAX_SAMPLES} are allowed"):
        _run(paper, 0.5, duration=too_long)
    r = _run(paper, 0.1, duration=2.5e-3)
    # cut to whole samples like the closed loop's grid: 0, 1, 2 ms
    np.testing.assert_array_equal(r.t, [0.0, 1e-3, 2e-3])


def test_divergence_names_time_and_state(paper: ServoParams) -> None:
    stiff = with_overrides(paper, {"valve.omega_v": 1e6})
    plant = build_plant("nonlinear", stiff, substep=1e-3)
    with pytest.raises(SimulationDivergedError,
                       match=r"open loop diverged at t = .* s: state spool_lag="):
        simulate_open_loop(plant, 0.1, duration=0.2)


def test_bad_inputs(paper: ServoParams) -> None:
    with pytest.raises(InputError, match="not finite at t = 0.002 s"):
        _run(paper, [0.0, 0.0, float("nan")], duration=0.003)
    with pytest.raises(InputError, match="3 samples, need 5"):
        _run(paper, [0.0, 0.0, 0.0], duration=0.005)
    with pytest.raises(InputError, match=r"command at t = 0.001 s is 1.5; .* in \[-1, 1\]"):
        _run(paper, [0.0, 1.5, 0.0], duration=0.003)
    with pytest.raises(ParameterError, match="duration must be finite and at least one"):
        _run(paper, 0.0, duration=-1.0)
    with pytest.raises(ParameterError, match="position must be inside the stroke"):
        build_plant("nonlinear", paper, 1.2)
    with pytest.raises(ParameterError, match="solve_ivp.*nonlinear"):
        _run(paper, 0.1, duration=0.1, plant="linear", method="solve_ivp")


def test_solve_ivp_has_a_step_limit_and_reports_progress(paper: ServoParams) -> None:
    """Issue 9, row 12: the reference method counts its right-hand-side evaluations. A normal
    1 s run needs about 3e3, far below the default limit (1e6); a stiff model stops at the
    limit with one line saying what to do; progress reports reach the end of the run."""
    plant = build_plant("nonlinear", paper, 0.5)
    seen: list[float] = []
    res = simulate_open_loop(plant, 0.5, duration=1.0, method="solve_ivp",
                             max_rhs_evals=10_000, progress=lambda t, d: seen.append(t / d))
    assert res.method == "solve_ivp:DOP853"
    assert seen and seen[-1] == pytest.approx(1.0) and seen == sorted(seen)
    stiff = build_plant("nonlinear", with_overrides(paper, {"load.mass": 1e-6}), 0.5)
    with pytest.raises(ParameterError, match=r"after 5000 right-hand-side evaluations, its "
                                             r"limit \(max_rhs_evals\).*--method rk4") as info:
        simulate_open_loop(stiff, 0.5, duration=1.0, method="solve_ivp", max_rhs_evals=5000)
    assert "\n" not in str(info.value)
    for bad in (0, -1, 2.5, True):
        with pytest.raises(ParameterError, match="max_rhs_evals must be an integer >= 1"):
            simulate_open_loop(plant, 0.5, duration=0.01, method="solve_ivp",
                               max_rhs_evals=bad)  # type: ignore[arg-type]


def test_open_loop_delay_at_most_the_run(paper: ServoParams) -> None:
    plant = build_plant("linear", paper, 0.5)
    res = simulate_open_loop(plant, 0.1, duration=0.05, delay=0.05)
    assert np.all(res.y == res.y[0])  # the command never arrives
    with pytest.raises(ParameterError, match=r"delay 0\.0501 s is longer than the run"):
        simulate_open_loop(plant, 0.1, duration=0.05, delay=0.0501)
