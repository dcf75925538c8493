"""The fuzzy PI with Woo, Chung & Lin (2000)'s scaling functions (kind ``wfpi``, control/woo.py)
against the plain fuzzy PI and the closed forms of φ and ψ."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzyservo.control import WooFuzzyPIController
from fuzzyservo.errors import ParameterError
from fuzzyservo.paper import paper_params
from fuzzyservo.registry import build_controller, build_plant, default_systems
from fuzzyservo.sim import Step, simulate

H = 1e-3
STEP = 0.1
#: About the fuzzy PI's tuned gains on the linear plant (data/gains/linear-fpi.toml).
GAINS = {"ke": 12.0, "kde": 6600.0, "kdu": 0.0017}


def _run(kind: str, gains: dict[str, float], duration: float = 1.0):  # noqa: ANN202
    plant = build_plant("linear", paper_params())
    ctl = build_controller(kind, gains, dt=H)
    return simulate(ctl, plant, Step(STEP), duration=duration)


def test_unit_functions_give_the_fuzzy_pi_bit_for_bit() -> None:
    # a = c = 0, b = d = 1: φ = ψ = 1 exactly, and x * 1.0 is x in IEEE arithmetic
    fpi = _run("fpi", GAINS)
    woo = _run("wfpi", {**GAINS, "phi_a": 0.0, "phi_b": 1.0, "psi_c": 0.0, "psi_d": 1.0})
    assert np.array_equal(fpi.y, woo.y) and np.array_equal(fpi.u, woo.u)
    assert np.all(woo.alpha == 1.0)


def test_alpha_trace_is_psi_of_the_clipped_normalised_error() -> None:
    a, b, c, d = 1.0, 1.0, 1.5, 0.5
    res = _run("wfpi", {**GAINS, "phi_a": a, "phi_b": b, "psi_c": c, "psi_d": d},
               duration=3.0)
    m = np.minimum(np.abs(GAINS["ke"] * (res.r - res.y)), 1.0)  # no filter: e = r - y
    assert res.alpha == pytest.approx(c * (1.0 - m) + d, abs=1e-14, rel=0)
    # far from the setpoint (K_e e >= 1 at the step: 12 * 0.1) ψ is its low end d; where the
    # error crosses zero it reaches its high end c + d (to within the error of one sample)
    assert res.alpha[0] == d
    assert res.alpha.max() == pytest.approx(c + d, abs=1e-2)
    assert np.abs(res.r - res.y)[-100:].max() < 0.02 * STEP  # and the loop settles


@pytest.mark.parametrize(("e", "a", "b", "c", "d"),
                         [(0.01, 2.0, 1.0, 3.0, 0.5), (0.03, 0.7, 0.4, 0.0, 1.7),
                          (-0.02, 5.0, 0.2, 9.0, 0.0)])
def test_first_command_is_the_fuzzy_pi_with_phi_and_psi_applied(e: float, a: float, b: float,
                                                                  c: float, d: float) -> None:
    # first sample from rest, e(-1) = 0: Δe = e, so the Woo controller's command is the plain
    # fuzzy PI's with K_Δe scaled by φ(m) and K_Δu by ψ(m), m = |K_e e| (here inside [0, 1])
    ke, kde, kdu = 20.0, 9.0, 0.3
    m = abs(ke * e)
    phi, psi = a * m + b, c * (1.0 - m) + d
    woo = build_controller("wfpi", {"ke": ke, "kde": kde, "kdu": kdu, "phi_a": a, "phi_b": b,
                                    "psi_c": c, "psi_d": d}, dt=H)
    fpi = build_controller("fpi", {"ke": ke, "kde": phi * kde, "kdu": psi * kdu}, dt=H)
    u_woo, s = woo.step(woo.initial_state(), e, 0.0)
    u_fpi, _ = fpi.step(fpi.initial_state(), e, 0.0)
    assert u_woo == pytest.approx(u_fpi, abs=1e-15, rel=1e-13)  # operation order only
    assert s.alpha == pytest.approx(psi, rel=1e-15)
    assert u_woo != 0.0


def test_the_functions_make_the_step_response_differ_from_the_fuzzy_pi() -> None:
    fpi = _run("fpi", GAINS)
    woo = _run("wfpi", {**GAINS, "phi_a": 2.0, "psi_c": 3.0})
    assert not np.allclose(fpi.y, woo.y, atol=1e-4)


@pytest.mark.parametrize("gain", ["phi_a", "phi_b", "psi_c", "psi_d"])
@pytest.mark.parametrize("value", [-0.5, math.nan, math.inf])
def test_bad_coefficients_are_refused_naming_the_value(gain: str, value: float) -> None:
    with pytest.raises(ParameterError, match=rf"gain {gain} must be finite and >= 0, got "):
        build_controller("wfpi", {**GAINS, gain: value}, dt=H)
    du = default_systems(("du",))["du"]
    with pytest.raises(ParameterError, match=rf"gain {gain} must be finite and >= 0, got "):
        WooFuzzyPIController.from_systems(du, dt=H, **GAINS, **{gain: value})


def test_needs_only_the_du_system() -> None:
    ctl = build_controller("wfpi", GAINS, dt=H)
    assert list(ctl.systems()) == ["du"]
    assert ctl.law.name == "fuzzy_pi_woo" and ctl.law_constants()[5] == 2.0
