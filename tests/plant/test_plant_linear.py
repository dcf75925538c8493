"""Linear model eq. (8): transfer function, state space, ZOH discretisation."""

from __future__ import annotations

import control
import numpy as np
import pytest
from scipy import signal

from fuzzyservo.errors import ParameterError
from fuzzyservo.paper import paper_params
from fuzzyservo.plant import LinearServo, linearize


@pytest.fixture(scope="module")
def model() -> LinearServo:
    p = paper_params()
    return LinearServo.from_params(p, linearize(p))


def test_k_o_from_physical_factors(model: LinearServo) -> None:
    # K_o = K_a K_tr C_v / A_f with K_a = K_tr = 1: 2.613e-3 / 9.9756e-3 = 0.2619 m/s
    # (model notes §4.3 quote 0.262, 3 digits)
    assert model.K_o == pytest.approx(0.262, rel=2e-3)


@pytest.mark.parametrize("tau_v", [0.0, 1e-3])
def test_state_space_equals_transfer_function(model: LinearServo, tau_v: float) -> None:
    from dataclasses import replace

    m = replace(model, tau_v=tau_v)
    num, den = m.transfer_function()
    a, b, c, d = m.state_space()
    w = np.logspace(-1, 4, 40)
    h_tf = np.polyval(num, 1j * w) / np.polyval(den, 1j * w)
    h_ss = control.ss(a, b, c, d)(1j * w)
    # two algebraically equal forms; 1e-9 relative covers the conditioning of den (1e-9 .. 1)
    np.testing.assert_allclose(np.squeeze(h_ss), h_tf, rtol=1e-9)
    poles = np.sort_complex(control.ss(a, b, c, d).poles())
    expect = np.sort_complex(np.roots(den))
    # eigenvalues of a 6x6 companion-like system; 1e-8 relative is LAPACK accuracy here
    np.testing.assert_allclose(poles, expect, rtol=1e-8)


def test_dc_velocity_gain(model: LinearServo) -> None:
    a, b, c, d = model.state_space()
    # ramp slope of a unit step is K_o: drop the integrating x state, output v = dx/dt
    sysv = control.ss(a[:-1, :-1], b[:-1], a[-1:, :-1], d)
    assert control.dcgain(sysv) == pytest.approx(model.K_o, rel=1e-9)  # exact up to rounding


def test_discretize_matches_scipy(model: LinearServo) -> None:
    m = model.discretize(1e-3)
    a, b, c, d = model.state_space()
    ref = signal.cont2discrete((a, b, c, d), 1e-3, method="zoh")
    # both expm of the same matrix; 1e-10 absolute for entries of order <= 1e3
    np.testing.assert_allclose(m.phi, ref[0], atol=1e-10, rtol=1e-10)
    np.testing.assert_allclose(m.gamma0, ref[1][:, 0], atol=1e-10, rtol=1e-10)
    assert (m.d, m.f) == (0, 0.0) and not np.any(m.gamma1)


def test_fractional_delay_splits_the_input_vector(model: LinearServo) -> None:
    """Γ_0 + Γ_1 is the undelayed input vector; Γ_1 is the part of a sample the previous
    command still acts (Åström & Wittenmark): against scipy's ZOH over f and over ts - f."""
    ts, delay = 1e-3, 2.4e-3
    m = model.discretize(ts, delay)
    assert m.d == 2 and m.f == pytest.approx(0.4e-3, rel=1e-12)
    a, b, c, d = model.state_space()
    full = signal.cont2discrete((a, b, c, d), ts, method="zoh")
    np.testing.assert_allclose(m.phi, full[0], atol=1e-10, rtol=1e-10)
    np.testing.assert_allclose(m.gamma, full[1][:, 0], atol=1e-10, rtol=1e-10)
    head = signal.cont2discrete((a, b, c, d), ts - m.f, method="zoh")
    tail = signal.cont2discrete((a, b, c, d), m.f, method="zoh")
    np.testing.assert_allclose(m.gamma0, head[1][:, 0], atol=1e-10, rtol=1e-10)
    np.testing.assert_allclose(m.gamma1, head[0] @ tail[1][:, 0], atol=1e-10, rtol=1e-10)


def test_invalid_linear_model() -> None:
    with pytest.raises(ParameterError, match="LinearServo.omega_0 must be a finite number > 0"):
        LinearServo(K_o=0.26, omega_0=0.0, damping=0.1, omega_v=688.7, zeta_v=0.36)
    with pytest.raises(ParameterError, match="sample time ts must be finite and > 0"):
        LinearServo(K_o=0.26, omega_0=19.6, damping=0.1, omega_v=688.7,
                    zeta_v=0.36).discretize(-1.0)
