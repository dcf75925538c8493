"""The position controller with feed-forward (control/ffpd.py) against analytic values and
independent implementations: its default gains against hand-computed numbers, its step against
scipy's lfilter of the estimate filters, its loop on eq. (8) against python-control, the
steady ramp errors of a P loop (v / (K_x K_o)) and with velocity feed-forward (0), the cruise
errors of pure feed-forward, and its C port (NAME_step_ff) against Python."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
from scipy.signal import lfilter

from fuzzyservo.control import FFPDController, ffpd_model_gains
from fuzzyservo.errors import ParameterError
from fuzzyservo.paper import paper_params
from fuzzyservo.plant import LinearServo, linearize
from fuzzyservo.registry import build_controller, build_plant, controller_kind
from fuzzyservo.sim.closed_loop import LinearPlant, simulate
from fuzzyservo.sim.references import Ramp, SCurve, parse_reference

H = 1e-3


@pytest.fixture(scope="module")
def servo() -> LinearServo:
    """Eq. (8) of the paper's axis at mid-stroke, as the ``linear`` plant builds it."""
    p = paper_params()
    return LinearServo.from_params(p, linearize(p, 0.5 * p.cylinder.stroke))


@pytest.fixture(scope="module")
def plant(servo: LinearServo) -> LinearPlant:
    return LinearPlant.from_servo(servo, 0.5 * paper_params().cylinder.stroke)


# --- default gains from the model -----------------------------------------------------------


def test_model_gains_by_hand() -> None:
    lin = LinearServo(K_o=0.25, omega_0=20.0, damping=0.1, omega_v=700.0, zeta_v=0.35)
    g = ffpd_model_gains(lin)
    # K_vff = 1/0.25; K_aff = 2·0.1/(20·0.25); K_afb = 2(0.5 - 0.1)/(20·0.25);
    # K_v = min(20/3, 2·0.5·20/2 = 10) = 20/3, K_x = (20/3)/0.25; T_f = 0.1/20
    expect = {"kx": 80.0 / 3.0, "ki": 0.0, "kv_ff": 4.0, "ka_ff": 0.04, "ka_fb": 0.16,
              "tf": 0.005, "kv": 20.0 / 3.0, "damping": 0.5}
    assert g == pytest.approx(expect, rel=1e-14, abs=0)  # a few roundings
    # the margin rule binds: target damping 0.2 -> K_v = min(6.67, 2·0.2·20/2 = 4)
    g = ffpd_model_gains(lin, damping=0.2)
    assert (g["kv"], g["kx"], g["ka_fb"]) == pytest.approx((4.0, 16.0, 0.04), rel=1e-14)
    # a plant already damped beyond the target: no feedback, its own damping in the rule
    well = LinearServo(K_o=0.25, omega_0=20.0, damping=0.8, omega_v=700.0, zeta_v=0.35)
    g = ffpd_model_gains(well, loop_ratio=1.0, gain_margin=4.0)
    # K_v = min(1·20, 2·0.8·20/4 = 8) = 8; K_aff = 2·0.8/(20·0.25) = 0.32
    assert (g["ka_fb"], g["kv"], g["ka_ff"], g["damping"]) == pytest.approx(
        (0.0, 8.0, 0.32, 0.8), rel=1e-14, abs=0)
    # the valve's lag added to the acceleration feed-forward: (0.01 + 2·0.35/700 + 0.002)/0.25
    lag = LinearServo(K_o=0.25, omega_0=20.0, damping=0.1, omega_v=700.0, zeta_v=0.35,
                      tau_v=0.002)
    g = ffpd_model_gains(lag, include_valve=True, filter_ratio=0.0)
    assert (g["ka_ff"], g["tf"]) == pytest.approx((0.052, 0.0), rel=1e-14, abs=0)


@pytest.mark.parametrize(("kw", "msg"), [
    ({"damping": 0.0}, "damping must be finite and > 0, got 0.0"),
    ({"gain_margin": 1.0}, "gain_margin must be finite and > 1, got 1.0"),
    ({"loop_ratio": math.inf}, "loop_ratio must be finite and > 0, got inf"),
    ({"filter_ratio": -0.1}, "filter_ratio must be finite and >= 0, got -0.1"),
])
def test_model_gains_refuse_bad_options(servo: LinearServo, kw: dict[str, float],
                                        msg: str) -> None:
    with pytest.raises(ParameterError, match=msg):
        ffpd_model_gains(servo, **kw)


def test_model_gains_refuse_a_model_without_coefficients() -> None:
    with pytest.raises(ParameterError, match="linear_servo.K_o must be a number > 0, got "
                                             "None"):
        ffpd_model_gains(type("M", (), {"K_o": None, "omega_0": 1.0, "damping": 0.1})())


def test_registry_defaults_are_the_paper_models_gains(servo: LinearServo) -> None:
    kind = controller_kind("ffpd")
    model = ffpd_model_gains(servo)
    for g in kind.gains:
        # the registry writes them to 4 significant digits
        assert g.default == pytest.approx(model[g.name], rel=5e-4, abs=0), g.name
    assert kind.searched == ("kx", "ki", "ka_fb")
    assert kind.cls.law.feedforward


# --- the step --------------------------------------------------------------------------------


def _textbook(g: dict[str, float], r: np.ndarray, y: np.ndarray, rd: np.ndarray,
              rdd: np.ndarray) -> np.ndarray:
    """The law unlimited from rest at y = 0, written from the docstring's transfer functions:
    â = [(1 - z⁻¹)/(T_f + h) / (1 - a z⁻¹)]² y with a = T_f/(T_f + h) (scipy's lfilter), and
    the integral as a cumulative sum."""
    a, b = g["tf"] / (g["tf"] + H), 1.0 / (g["tf"] + H)
    acc = lfilter(np.convolve([b, -b], [b, -b]), np.convolve([1.0, -a], [1.0, -a]), y)
    e = r - y
    return (g["kx"] * e + g["kv_ff"] * rd + g["ka_ff"] * rdd + g["ka_fb"] * (rdd - acc)
            + g["ki"] * H * np.cumsum(e))


@pytest.mark.parametrize("tf", [0.0, 0.004])
def test_step_is_the_textbook_law(tf: float) -> None:
    g = {"kx": 23.0, "ki": 7.0, "kv_ff": 3.1, "ka_ff": 0.05, "ka_fb": 0.2, "tf": tf}
    ctl = FFPDController(dt=H, **g, u_min=-1e9, u_max=1e9)
    rng = np.random.default_rng(7)
    n = 300
    r, y = rng.normal(0, 0.01, n), np.cumsum(rng.normal(0, 1e-4, n))
    rd, rdd = rng.normal(0, 0.1, n), rng.normal(0, 1.0, n)
    s = ctl.initial_state()
    got = []
    for k in range(n):
        u, s = ctl.step(s, r[k], y[k], reference_rate=rd[k], reference_acceleration=rdd[k])
        got.append(u)
    ref = _textbook(g, r, y, rd, rdd)
    # one recursion against another of the same filters: rounding of O(1e3) intermediate
    # terms (b² = 1e6 1/s² on 1e-4 m differences)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)


def test_acceleration_estimate_of_a_parabola() -> None:
    # y = c t²: second differences are exactly 2 c h², so â → 2c (the filter's DC gain is 1)
    c = 0.3
    ctl = FFPDController(dt=H, ka_fb=1.0, tf=0.005, u_min=-10.0, u_max=10.0)
    s = ctl.initial_state()
    for k in range(400):
        t = k * H
        u, s = ctl.step(s, c * t * t, c * t * t)
    # 400 samples = 80 T_f: the filters' transient e^-80 is gone; rounding of y differences
    assert s.a_est == pytest.approx(2 * c, rel=1e-6)
    # v̂: the backward difference 2c (t - h/2) through one lag, which trails a ramp by T_f
    assert s.v_est == pytest.approx(2 * c * (399 * H - H / 2 - 0.005), rel=1e-6)
    assert u == pytest.approx(-2 * c, rel=1e-6)  # u = K_afb (r̈ - â) with r̈ = 0


def test_clamping_anti_windup_holds_the_integral() -> None:
    ctl = FFPDController(dt=H, kx=1.0, ki=100.0, u_min=-0.5, u_max=0.5)
    s = ctl.initial_state()
    for _ in range(50):
        u, s = ctl.step(s, 1.0, 0.0)
    # w = 1 + I > u_max from the first sample with e > 0: the integral never moves
    assert u == 0.5 and s.integral == 0.0
    u, s = ctl.step(s, 0.3, 0.0)  # w = 0.3 + 0.03, inside the limits: integrates
    assert s.integral == pytest.approx(0.3 * 100.0 * H, rel=1e-15)
    assert u == pytest.approx(0.3 + 0.03, rel=1e-15)
    for _ in range(10):
        u, s = ctl.step(s, -1.0, 0.0)  # below the lower limit, e < 0: held again
    assert u == -0.5 and s.integral == pytest.approx(0.03, rel=1e-15)


# --- the loop on eq. (8) ---------------------------------------------------------------------


def test_loop_matches_python_control(servo: LinearServo) -> None:
    """python-control: eq. (8) by ZOH (c2d) in feedback with the law's discrete transfer
    functions from y (K_x + K_afb A(z) + K_i h z/(z - 1)), driven by the law's terms in r, ṙ,
    r̈ (unlimited, so the loop is linear)."""
    g = {"kx": 20.0, "ki": 3.0, "kv_ff": 3.8, "ka_ff": 0.04, "ka_fb": 0.15, "tf": 0.005}
    ctl = FFPDController(dt=H, **g, u_min=-1e6, u_max=1e6)
    ref = SCurve(0.05, 0.1, 1.0, 20.0)
    res = simulate(ctl, LinearPlant.from_servo(servo), ref, duration=1.5)
    rd, rdd = ref.rates(res.t)
    a, b = g["tf"] / (g["tf"] + H), 1.0 / (g["tf"] + H)
    acc = control.tf(np.convolve([b, -b], [b, -b]), np.convolve([1.0, -a], [1.0, -a]), H)
    integ = control.tf([g["ki"] * H, 0.0], [1.0, -1.0], H)
    c_y = g["kx"] + g["ka_fb"] * acc + integ
    a_, b_, c_, d_ = servo.state_space()
    pd = control.c2d(control.ss(a_, b_, c_, d_), H, "zoh")
    loop = control.feedback(pd, control.ss(c_y))
    w = (lfilter([g["kx"] + g["ki"] * H, -g["kx"]], [1.0, -1.0], res.r)
         + g["kv_ff"] * rd + (g["ka_ff"] + g["ka_fb"]) * rdd)
    y = np.asarray(control.forced_response(control.ss(loop), T=res.t, U=w).outputs).ravel()
    # both exact ZOH recursions: rounding only, far below 1e-9 of the 0.05 m move
    assert np.max(np.abs(res.y - y)) <= 1e-9 * 0.05
    assert res.y[-1] == pytest.approx(0.05, abs=2e-3)  # the move is made: not vacuous


def test_active_damping_raises_the_hydraulic_damping(servo: LinearServo) -> None:
    """Acceleration feedback alone on eq. (8) sampled: the hydraulic pair's damping goes from
    δ to about δ + K_o ω₀ K_afb / 2 (the filter's and the valve's lags shift it a little)."""
    a_, b_, c_, d_ = servo.state_space()
    pd = control.c2d(control.ss(a_, b_, c_, d_), H, "zoh")
    g = ffpd_model_gains(servo)  # target damping 0.5

    def hydraulic_damping(ka_fb: float) -> float:
        a, b = g["tf"] / (g["tf"] + H), 1.0 / (g["tf"] + H)
        acc = control.tf(np.convolve([b, -b], [b, -b]), np.convolve([1.0, -a], [1.0, -a]), H)
        poles = np.log(control.poles(control.feedback(pd, ka_fb * acc)).astype(complex)) / H
        pair = poles[(np.abs(poles) > 5.0) & (np.abs(poles) < 100.0) & (poles.imag > 0)]
        assert pair.size == 1
        return float(-pair[0].real / abs(pair[0]))

    assert hydraulic_damping(0.0) == pytest.approx(servo.damping, abs=0.005)  # valve, ZOH
    # the filter (T_f ω₀ = 0.1) and the valve take a little of the added damping
    assert hydraulic_damping(g["ka_fb"]) == pytest.approx(0.5, abs=0.05)


def test_p_loop_ramp_error_is_v_over_kx_ko(servo: LinearServo, plant: LinearPlant) -> None:
    """One integrator in eq. (8): in steady state u = v/K_o, so e = v/(K_x K_o) for a P loop
    (damped by K_afb, which sees â = 0 at constant speed), and 0 with K_vff = 1/K_o."""
    g = ffpd_model_gains(servo)
    v = 0.05
    base = {"kx": g["kx"], "ka_fb": g["ka_fb"], "tf": g["tf"]}
    p_only = simulate(FFPDController(dt=H, **base), plant, Ramp(v), duration=10.0)
    e = p_only.r - p_only.y
    # 10 s = 65 loop time constants 1/K_v: the transient is gone; rounding of 0.5 m positions
    assert e[-1] == pytest.approx(v / (g["kx"] * servo.K_o), rel=1e-9)
    assert np.max(np.abs(p_only.u)) < 1.0  # unsaturated: the linear result applies
    ff = simulate(FFPDController(dt=H, **base, kv_ff=1.0 / servo.K_o), plant, Ramp(v),
                  duration=10.0)
    # zero up to the rounding of positions near 0.5 m (1e-16 relative) over 1e4 samples
    assert abs(ff.r[-1] - ff.y[-1]) < 1e-12


def test_pure_feedforward_cruise_and_final_errors(servo: LinearServo,
                                                  plant: LinearPlant) -> None:
    """K_x = 0: eq. (8)'s truncated inverse alone. Expansion of 1 - G F at s = 0 with
    F = (s + 2δ/ω₀ s²)/K_o: the cruise error is v (2ζ_v/ω_v + h/2) (the valve's lag, and
    the hold's half sample gathered while accelerating); without K_aff, v (2δ/ω₀ + 2ζ_v/ω_v
    + h/2); with the valve in K_aff, v h/2. The move ends on its target (eq. 8 integrates
    K_o u, and the sums of the sampled ṙ and r̈ are the distance and 0)."""
    g = ffpd_model_gains(servo)
    v = 0.05
    ref = SCurve(0.3, v, 0.5, 10.0)  # cruise from 0.15 s to 6.0 s
    valve = 2 * servo.zeta_v / servo.omega_v
    hydraulic = 2 * servo.damping / servo.omega_0
    cases = {
        "both": (g["ka_ff"], v * (valve + H / 2)),
        "velocity only": (0.0, v * (hydraulic + valve + H / 2)),
        "with the valve": (ffpd_model_gains(servo, include_valve=True)["ka_ff"], v * H / 2),
    }
    for name, (ka_ff, expect) in cases.items():
        ctl = FFPDController(dt=H, kv_ff=g["kv_ff"], ka_ff=ka_ff)
        res = simulate(ctl, plant, ref, duration=12.0)
        e = res.r - res.y
        cruise = e[np.searchsorted(res.t, 5.9)]
        # the hydraulic mode excited by the jerk decays as e^(-δ ω₀ t) (e^-11 after 5.7 s);
        # the expansion's next terms are O(h²) and O(1/ω_v²): 2e-9 m
        assert cruise == pytest.approx(expect, abs=5e-8), name
        # the end: 1e-6 m, below 1/50 of the smallest cruise error (no lag is left)
        assert abs(e[-1]) < 1e-6, name
    # a ramp: its acceleration is an impulse at t = 0, which no sample carries (r̈_k = 0), and
    # ṙ is v from the first sample (no half sample): K_aff cannot act
    res = simulate(FFPDController(dt=H, kv_ff=g["kv_ff"], ka_ff=g["ka_ff"]), plant, Ramp(v),
                   duration=8.0)
    assert res.r[-1] - res.y[-1] == pytest.approx(v * (hydraulic + valve), abs=5e-8)


def test_feedforward_cuts_the_scurve_following_error() -> None:
    """The feed-forward the tuner cannot see (a step has no rates) matters on a profile: the
    model's K_vff, K_aff cut the largest following error of an S-curve tenfold (what is left
    is mostly the jerk term r⃛/(ω₀² K_o) the truncated inverse leaves out)."""
    p = paper_params()
    plant = build_plant("linear", p, 0.5 * p.cylinder.stroke)
    ref = parse_reference("scurve:0.2:0.2:1:10")
    worst = {}
    for name, over in (("with", {}), ("without", {"kv_ff": 0.0, "ka_ff": 0.0})):
        ctl = build_controller("ffpd", over, dt=H)
        res = simulate(ctl, plant, ref, duration=2.0)
        worst[name] = float(np.max(np.abs(res.r - res.y)))
    assert worst["with"] < 0.1 * worst["without"], worst


# --- the C port with feed-forward ------------------------------------------------------------


@pytest.mark.parametrize("real", ["double", "float"])
def test_c_step_ff_equals_python(tmp_path: object, real: str) -> None:
    from pathlib import Path

    from fuzzyservo.export.targets import generate_c
    from tests.export.ctl_harness import CStep, build

    p = paper_params()
    gains = {"kx": 30.0, "ki": 4.0, "kv_ff": 3.8, "ka_ff": 0.04, "ka_fb": 0.2, "tf": 0.004}
    cc = generate_c("ffpd", gains, ts=H, name="c_ffpd", real=real)  # type: ignore[arg-type]
    c = CStep(build(cc, Path(str(tmp_path))), cc)
    ref = SCurve(0.2, 0.25, 2.0, 40.0, time=0.05)
    worst = 0.0
    for plant_name in ("linear", "nonlinear"):
        plant = build_plant(plant_name, p, 0.5 * p.cylinder.stroke)
        res = simulate(build_controller("ffpd", gains, dt=H), plant, ref, duration=1.0)
        rd, rdd = ref.rates(res.t)
        assert np.max(np.abs(rdd)) > 1.0  # the feed-forward path is exercised
        u = c.replay(res.r, res.y, plant.y0, plant.u0, rates=(rd, rdd))
        worst = max(worst, float(np.max(np.abs(u - res.u))))
    # double: a line-by-line port (tests/export/test_controller_c.py's bound); float: y near
    # 0.5 m is quantised to 6e-8 m and the acceleration path multiplies a change of y by
    # K_afb b² = 0.2/(T_f + h)² = 8e3 1/m: 5e-4, filtered over a few T_f
    assert worst <= (1e-12 if real == "double" else 2e-3), worst
