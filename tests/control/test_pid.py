"""PID family: difference equations, anti-windup, bumpless start, special cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzyservo.control import PIDController, PIDState, p_controller, pi_controller
from fuzzyservo.errors import ParameterError

H = 1e-3


def _run(c: PIDController, r: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, PIDState]:
    s = c.initial_state()
    u = np.empty(r.size)
    for k in range(r.size):
        u[k], s = c.step(s, float(r[k]), float(y[k]))
    return u, s


def test_unsaturated_pid_equals_transfer_functions_from_scipy() -> None:
    """u = C_r(z) r - C_y(z) y with the backward-Euler transfer functions, via lfilter."""
    from scipy.signal import lfilter

    kp, ki, kd, n, b, c = 1.3, 0.7, 0.2, 50.0, 0.6, 0.3
    ctl = PIDController(dt=H, kp=kp, ki=ki, kd=kd, n=n, b=b, c=c, u_min=-1e9, u_max=1e9)
    rng = np.random.default_rng(1)
    r, y = rng.normal(size=300), rng.normal(size=300)
    u, _ = _run(ctl, r, y)
    ad = 1.0 / (1.0 + n * H)
    bd = kd * n / (1.0 + n * H)

    def filt(w_p: float, w_d: float, x: np.ndarray) -> np.ndarray:
        return (w_p * x + lfilter([ki * H], [1.0, -1.0], x)
                + lfilter([bd * w_d, -bd * w_d], [1.0, -ad], x))

    ref = filt(kp * b, c, r) - filt(kp, 1.0, y)
    assert u == pytest.approx(ref, rel=1e-10, abs=1e-12)  # float rounding only


def test_derivative_of_a_ramp_settles_to_kd_times_slope() -> None:
    """Analytic: a filtered derivative of a ramp of slope s tends to K_d s."""
    ctl = PIDController(dt=H, kd=0.4, n=20.0, u_min=-10, u_max=10)
    t = np.arange(2000) * H
    u, s = _run(ctl, np.zeros_like(t), -0.5 * t)  # y = -0.5 t: d(c r - y)/dt = 0.5
    assert s.derivative == pytest.approx(0.4 * 0.5, rel=1e-9)  # e^{-N t}, N t = 40: exact


def test_unfiltered_derivative_is_a_difference() -> None:
    ctl = PIDController(dt=H, kd=0.1, n=math.inf, u_min=-1e6, u_max=1e6)
    u, _ = _run(ctl, np.array([0.0, 0.0, 0.0]), np.array([0.0, 1e-3, 3e-3]))
    assert u == pytest.approx([0.0, -0.1, -0.2], abs=1e-12)  # exact arithmetic


@pytest.mark.parametrize("scheme", ["none", "clamping", "back-calculation"])
def test_anti_windup_schemes(scheme: str) -> None:
    ctl = PIDController(dt=H, kp=2.0, ki=5.0, anti_windup=scheme)  # type: ignore[arg-type]
    u, s = _run(ctl, np.full(12000, 1.0), np.zeros(12000))  # e = 1 for 12 s: saturated
    assert np.all(u == 1.0)
    if scheme == "none":
        assert s.integral == pytest.approx(5.0 * 12000 * H, rel=1e-9)  # integrates freely
    elif scheme == "clamping":
        assert s.integral == 0.0  # never integrates while pushing into the limit
    else:
        # fixed point of I += ki h e + (h/T_t)(u_max - v), T_t = T_i = kp/ki: bounded
        tt = 2.0 / 5.0
        k = H / tt
        i_ss = (5.0 * H * 1.0 + k * (1.0 - 2.0 - 5.0 * H)) / k
        assert s.integral == pytest.approx(i_ss, rel=1e-9)  # (1 - h/T_t)^12000 ~ e^-30


def test_bumpless_initial_state() -> None:
    ctl = PIDController(dt=H, kp=1.5, ki=2.0, kd=0.3, b=0.5, c=0.0)
    s = ctl.initial_state(r0=0.3, y0=0.25, u0=0.2)
    u, _ = ctl.step(s, 0.3, 0.25)
    assert u == pytest.approx(0.2, abs=1e-15)  # exact up to rounding


def test_special_cases_and_packed_rest_state() -> None:
    p = p_controller(dt=H, kp=3.0)
    assert p.step(p.initial_state(), 0.1, 0.0)[0] == pytest.approx(0.3, rel=1e-15)  # kp e
    pi = pi_controller(dt=H, kp=1.0, ki=10.0)
    assert pi.step(pi.initial_state(), 0.1, 0.0)[0] == pytest.approx(0.1 + 10 * H * 0.1,
                                                                      rel=1e-12)  # rounding
    ctl = PIDController(dt=H, kp=1.5, ki=2.0, kd=0.3, b=0.5, c=0.2)
    packed = ctl.rest_states(ctl.pack()[None, :], 0.4, 0.1)[0]
    ref = ctl.pack_state(ctl.initial_state(r0=0.4, y0=0.4, u0=0.1))
    assert packed[:3] == pytest.approx(ref[:3], abs=1e-15)  # same formula


@pytest.mark.parametrize(
    "kw",
    [{"kp": -1.0}, {"ki": math.nan}, {"kd": math.inf}, {"n": 0.0}, {"dt": 0.0},
     {"u_min": 1.0}, {"anti_windup": "magic"}, {"tracking_time": -1.0}],
)
def test_bad_parameters_raise(kw: dict[str, object]) -> None:
    args: dict[str, object] = {"dt": H, "kp": 1.0}
    args.update(kw)
    with pytest.raises(ParameterError):
        PIDController(**args)  # type: ignore[arg-type]


def test_bad_gain_rows_name_the_gain() -> None:
    ctl = PIDController(dt=H, kp=1.0)
    with pytest.raises(ParameterError, match="gain ki"):
        ctl.pack_gains(np.array([[1.0, -2.0, 0.0, 100.0, 1.0, 1.0]]))


@settings(max_examples=25, deadline=None)
@given(a=st.floats(-3, 3), b=st.floats(-3, 3), seed=st.integers(0, 2**32 - 1))
def test_unsaturated_pid_obeys_superposition(a: float, b: float, seed: int) -> None:
    """Linear in (r, y) while no limit is reached: u(a x1 + b x2) = a u(x1) + b u(x2)."""
    ctl = PIDController(dt=H, kp=2.0, ki=3.0, kd=0.1, n=80.0, b=0.4, c=0.2,
                        u_min=-1e12, u_max=1e12)
    rng = np.random.default_rng(seed)
    r1, y1, r2, y2 = rng.normal(size=(4, 50))
    u1, _ = _run(ctl, r1, y1)
    u2, _ = _run(ctl, r2, y2)
    u12, _ = _run(ctl, a * r1 + b * r2, a * y1 + b * y2)
    scale = 1.0 + np.max(np.abs(u1)) + np.max(np.abs(u2))
    assert np.max(np.abs(u12 - (a * u1 + b * u2))) <= 1e-12 * 6 * scale  # rounding only
