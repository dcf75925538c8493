"""The sliding-mode law (control/smc.py) against analytic and independent references: the
model gains are the paper's linear model, the derivative estimates are the bilinear transform
of the state-variable filter (scipy), the surface reaches its boundary layer within the time
the reaching law gives (on the model the law assumes and on the ``linear`` plant), and the
reference's rates make it track a jerk-limited move."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from fuzzyservo.control import SlidingModeController, smc_model_gains
from fuzzyservo.control.smc import PAPER_MODEL_GAINS
from fuzzyservo.errors import ParameterError
from fuzzyservo.paper import paper_params
from fuzzyservo.plant import LinearServo
from fuzzyservo.plant.linearize import linearize
from fuzzyservo.registry import build_controller, build_plant
from fuzzyservo.sim import Step, simulate
from fuzzyservo.sim.closed_loop import LinearPlant
from fuzzyservo.sim.references import SCurve

H = 1e-3
M = PAPER_MODEL_GAINS


def _model_plant() -> LinearPlant:
    """The model the law assumes, x''' = -2 δ ω₀ ẍ - ω₀² ẋ + K_o ω₀² u (eq. 8 without the
    valve), at rest at 0.5 m: states v, a, x."""
    ko, w0, d = M["k_o"], M["omega_0"], M["delta"]
    a = np.array([[0.0, 1.0, 0.0], [-w0**2, -2.0 * d * w0, 0.0], [1.0, 0.0, 0.0]])
    b = np.array([0.0, ko * w0**2, 0.0])
    return LinearPlant(a, b, np.array([0.0, 0.0, 1.0]), state_names=("v", "a", "x"),
                       x_op=np.array([0.0, 0.0, 0.5]))


def test_model_gain_defaults_are_the_paper_linear_model() -> None:
    p = paper_params()
    servo = LinearServo.from_params(p, linearize(p, 0.5 * p.cylinder.stroke))
    got = smc_model_gains(servo)
    # the defaults are this computation written out: equal to its rounding
    assert got == pytest.approx(PAPER_MODEL_GAINS, rel=1e-12)
    assert got["k_o"] == pytest.approx(0.2619, abs=5e-5)  # printed values (eq. 8)
    assert got["omega_0"] == pytest.approx(19.6, abs=0.05)
    assert got["delta"] == pytest.approx(0.1, abs=5e-3)
    ctl = build_controller("smc", {}, dt=H)
    assert (ctl.k_o, ctl.omega_0, ctl.delta) == tuple(PAPER_MODEL_GAINS.values())


@pytest.mark.parametrize(("wf", "zf"), [(200.0, 1.0), (60.0, 0.4), (1500.0, 2.0)])
def test_derivative_estimates_are_the_bilinear_state_variable_filter(wf: float,
                                                                     zf: float) -> None:
    """ŷ' and ŷ'' are ω_f² s/D(s) and ω_f² s²/D(s) of y, D = s² + 2 ζ_f ω_f s + ω_f², by
    Tustin's rule (scipy.signal.bilinear), from rest at y = 0."""
    ctl = SlidingModeController(dt=H, lam=0.0, ks=0.0, omega_f=wf, zeta_f=zf)
    rng = np.random.default_rng(3)
    y = np.cumsum(rng.normal(0.0, 1e-3, 400))
    y[0] = 0.0  # at rest: the filter starts at y(0) = 0, as lfilter's zero state
    den = [1.0, 2.0 * zf * wf, wf * wf]
    vb, va = signal.bilinear([wf * wf, 0.0], den, fs=1.0 / H)
    ab, aa = signal.bilinear([wf * wf, 0.0, 0.0], den, fs=1.0 / H)
    v_ref, a_ref = signal.lfilter(vb, va, y), signal.lfilter(ab, aa, y)
    s = ctl.initial_state()
    v, acc = [], []
    for yk in y:
        _, s = ctl.step(s, 0.0, float(yk))
        v.append(s.v_f)
        acc.append(-s.sigma)  # λ = 0, r = rd = rdd = 0: s = ë = -ŷ''
    scale_v, scale_a = np.max(np.abs(v_ref)), np.max(np.abs(a_ref))
    # two recursions of the same transfer function: rounding, relative to the signal
    assert np.max(np.abs(np.array(v) - v_ref)) <= 1e-10 * scale_v
    assert np.max(np.abs(np.array(acc) - a_ref)) <= 1e-10 * scale_a


def _reaching(plant: object, lam: float, ks: float, phi: float) -> tuple[float, float, float]:
    """(measured time to |s| <= φ, the reaching law's (|s(0)| - φ)/η, largest |s|/φ after)
    for a 0.1 m step, the command unlimited (±50) so the law is what moves s."""
    ctl = build_controller("smc", {"lam": lam, "ks": ks, "phi": phi, "omega_f": 2000.0},
                           dt=H, options={"u_min": -50.0, "u_max": 50.0})
    res = simulate(ctl, plant, Step(0.1), duration=1.0)  # type: ignore[arg-type]
    s = res.alpha  # the law's traced state: s
    assert s[0] == pytest.approx(lam**2 * 0.1, rel=1e-12)  # s(0) = λ² e(0): no kick
    assert np.max(np.abs(res.u)) < 50.0  # never limited: the reaching law is not capped
    inside = np.abs(s) <= phi
    i = int(np.argmax(inside))
    assert inside[i]
    return float(res.t[i]), (abs(s[0]) - phi) / ks, float(np.max(np.abs(s[i:])) / phi)


#: (λ [1/s], k_s [m/s³], φ [m/s²]): moderate, fast, and the tuned gains on the linear plant
REACHING = [(10.0, 50.0, 0.5), (20.0, 200.0, 2.0), (16.18, 200.0, 1.791)]


@pytest.mark.parametrize(("lam", "ks", "phi"), REACHING)
def test_surface_reaches_the_layer_within_the_reaching_time_on_the_model(
        lam: float, ks: float, phi: float) -> None:
    """On the model the law assumes, outside the layer ṡ = -η sgn s (η = k_s): the layer
    |s| <= φ is reached at t_r = (|s(0)| - φ)/η, and it is never left."""
    t, bound, after = _reaching(_model_plant(), lam, ks, phi)
    # not before the law allows (one sample: s is seen at the samples), and not later than
    # three samples: the crossing is seen at the next sample (1), the estimates lag by
    # 2 ζ_f/ω_f = 1 ms (1) and the command is held over the sample (1)
    assert round((t - bound) / H) in (-1, 0, 1, 2, 3), (t, bound)
    assert after <= 1.0  # the layer is invariant


@pytest.mark.parametrize(("lam", "ks", "phi"), REACHING)
def test_surface_reaches_the_layer_within_the_reaching_time_on_the_linear_plant(
        lam: float, ks: float, phi: float) -> None:
    """The same on the ``linear`` plant, eq. (8) with the valve the law neglects: its lag
    (2 ζ_v/ω_v = 1.0 ms) adds up to two samples."""
    t, bound, after = _reaching(build_plant("linear", paper_params()), lam, ks, phi)
    assert round((t - bound) / H) in range(-1, 6), (t, bound)
    assert after <= 1.0


def test_the_reference_rates_make_it_track_a_jerk_limited_move() -> None:
    """On the model, an S-curve move tracked with the reference's exact rates: the error
    stays well inside the boundary layer's bound φ/λ², and taking r''' from the
    acceleration's difference holds s nearer 0 than r''' = 0 (the jerk enters the equivalent
    control instead of being left to the switching term). With the estimates nearly exact
    (ω_f = 2000 rad/s) it halves the error; at the default 200 rad/s the estimates' lag sets
    the error (0.8 mm on this move, with either)."""
    ref = SCurve(0.1, 0.15, 1.0, 20.0)  # b u = 20 + 2 δ ω₀ 1 + ω₀² 0.15 = 81.5 < b = 100.6
    err, s_max = {}, {}
    for jerk in ("difference", "zero"):
        ctl = build_controller("smc", {"lam": 20.0, "ks": 200.0, "phi": 2.0,
                                       "omega_f": 2000.0}, dt=H,
                               options={"reference_jerk": jerk})
        res = simulate(ctl, _model_plant(), ref, duration=1.5)
        assert np.max(np.abs(res.u)) < 1.0  # within the limits: the law is not capped
        err[jerk] = float(np.max(np.abs(res.r - res.y)))
        s_max[jerk] = float(np.max(np.abs(res.alpha)))
    assert err["difference"] <= 2.0 / 20.0**2  # |e| <= φ/λ² (Slotine & Li eq. 7.42)
    # without r''' the switching term carries it: |s| = φ j_max/k_s = 0.2 m/s² (the lag 5 %)
    assert s_max["zero"] == pytest.approx(2.0 * 20.0 / 200.0, rel=0.05)
    assert s_max["difference"] < 0.25 * s_max["zero"]
    assert err["difference"] < 0.6 * err["zero"]


def test_integral_action_holds_against_a_constant_disturbance() -> None:
    """A plant that needs u = 0.05 to hold still (a constant flow offset the law does not
    know): without integral action the boundary layer's finite gain leaves the error
    u_needed b φ/(k_s λ²); with it the error goes to 0."""
    base = _model_plant()
    plant = LinearPlant(base.a, base.b, base.c, state_names=base.state_names,
                        x_op=base.x_op, u0=0.05)
    gains = {"lam": 10.0, "ks": 100.0, "phi": 2.0}
    final = {}
    for mode in ("off", "on"):
        ctl = build_controller("smc", gains, dt=H, options={"integral_action": mode})
        # started at zero command, not the plant's holding 0.05: that is the disturbance
        s = ctl.initial_state(u0=0.0)
        y = plant.y0
        x = np.zeros(3)
        phi_d, gam = _zoh(plant.a, plant.b, H)
        for _ in range(int(5.0 / H)):
            u, s = ctl.step(s, plant.y0 + 0.02, y)
            x = phi_d @ x + gam * (u - plant.u0)
            y = plant.y0 + float(plant.c @ x)
        final[mode] = plant.y0 + 0.02 - y
    b = M["k_o"] * M["omega_0"] ** 2
    expect = 0.05 * b * 2.0 / (100.0 * 10.0**2)  # (k_s/b) λ² e/φ = 0.05 at rest
    assert final["off"] == pytest.approx(expect, rel=1e-6)  # settled after 5 s: rounding
    assert abs(final["on"]) < 1e-9


def _zoh(a: np.ndarray, b: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation by scipy."""
    ad, bd, *_ = signal.cont2discrete((a, b[:, None], np.eye(len(b)), 0.0), h, method="zoh")
    return ad, bd[:, 0]


@pytest.mark.parametrize(("gains", "options", "message"), [
    ({"k_o": 0.0}, {}, "gain k_o must be finite and > 0, got 0.0"),
    ({"omega_0": math.inf}, {}, "gain omega_0 must be finite and > 0, got inf"),
    ({"phi": -1.0}, {}, "gain phi must be finite and >= 0, got -1.0"),
    ({}, {"integral_action": "yes"}, "integral_action must be one of ['off', 'on'], got 'yes'"),
    ({}, {"reference_jerk": "exact"},
     "reference_jerk must be one of ['difference', 'zero'], got 'exact'"),
])
def test_bad_input_is_refused_in_one_line(gains: dict[str, float], options: dict[str, str],
                                          message: str) -> None:
    with pytest.raises(ParameterError) as info:
        build_controller("smc", gains, dt=H, options=options)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_phi_zero_is_the_ideal_relay() -> None:
    ctl = SlidingModeController(dt=H, lam=5.0, ks=30.0, phi=0.0)
    b = M["k_o"] * M["omega_0"] ** 2
    u, s = ctl.step(ctl.initial_state(), 0.01, 0.0)
    assert u == pytest.approx(30.0 / b, rel=1e-15)  # sgn(s) k_s/b; u_eq = 0 at rest
    u, s = ctl.step(ctl.initial_state(), 0.0, 0.0)
    assert u == 0.0  # sgn(0) = 0: no command at zero error
