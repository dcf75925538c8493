"""The references' velocity and acceleration (``rates``): the feed-forward signals.

Checked against the references' own values by central differences (an independent
computation: the closed forms of ``rates`` share no code with ``values``), and the S-curve
against its limits and the phase durations computed by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzyservo.errors import InputError
from fuzzyservo.sim import parse_reference, simulate
from fuzzyservo.sim.references import (
    Chirp,
    Ramp,
    SCurve,
    Sine,
    Step,
    Trapezoid,
    UserReference,
    check_reference,
    reference_rates,
)

H = 1e-6  # central-difference step [s]


def _diff(f, t: np.ndarray) -> np.ndarray:
    return (f(t + H) - f(t - H)) / (2.0 * H)


SMOOTH = {
    "sine": Sine(0.05, 2.0),
    "chirp": Chirp(0.01, 0.5, 5.0, 3.0),
    "scurve": SCurve(0.2, 0.25, 2.0, 40.0, 0.1),
    "scurve-short": SCurve(-0.01, 0.25, 2.0, 40.0),
    "scurve-no-const-acc": SCurve(0.2, 0.25, 2.0, 8.0),
    "trapezoid": Trapezoid(0.1, 0.1, 0.5, 0.2),
    "ramp": Ramp(0.05, 0.3, 0.02),
    "user": UserReference(np.array([0.0, 0.5, 1.0, 2.0]), np.array([0.0, 0.01, -0.02, 0.0])),
}


def _kinks(ref: object) -> np.ndarray:
    """Instants where a rate jumps (excluded from the difference checks)."""
    if isinstance(ref, SCurve):
        tj, ta, tv, _ = ref.phases()
        b = np.array([0, tj, ta - tj, ta, ta + tv, ta + tv + tj, 2 * ta + tv - tj,
                      2 * ta + tv])
        return ref.time + b
    if isinstance(ref, Trapezoid):
        v = min(ref.v_max, math.sqrt(abs(ref.distance) * ref.a_max))
        ta = v / ref.a_max
        tc = (abs(ref.distance) - v * ta) / v
        return ref.time + np.array([0, ta, ta + tc, 2 * ta + tc])
    if isinstance(ref, Ramp):
        return np.array([ref.time, ref.time + ref.final / ref.slope])
    if isinstance(ref, UserReference):
        return ref.times
    if isinstance(ref, Chirp):
        return np.array([ref.duration])
    return np.array([])


@pytest.mark.parametrize("name", sorted(SMOOTH))
def test_rates_are_the_derivatives_of_the_values(name: str) -> None:
    ref = SMOOTH[name]
    t = np.linspace(0.0, 3.0, 3001) + 1.234e-4  # off the sample grid's round instants
    t = t[np.min(np.abs(t[:, None] - _kinks(ref)[None, :]), axis=1) > 1e-4] \
        if _kinks(ref).size else t
    v, a = ref.rates(t)
    scale_v = max(np.max(np.abs(v)), 1e-12)
    np.testing.assert_allclose(v, _diff(ref.values, t), rtol=0, atol=2e-6 * scale_v + 1e-12)
    if not isinstance(ref, UserReference | Ramp):
        scale_a = max(np.max(np.abs(a)), 1e-12)
        np.testing.assert_allclose(a, _diff(lambda x: ref.rates(x)[0], t), rtol=0,
                                   atol=2e-5 * scale_a + 1e-12)


def test_scurve_phases_by_hand() -> None:
    """0.2 m at 0.25 m/s, 2 m/s², 40 m/s³: T_j = a/j = 0.05 s, T_a = T_j + v/a = 0.175 s
    (v j = 10 >= a² = 4: the acceleration limit is reached), cruise 0.2/0.25 - 0.175 =
    0.625 s, duration 0.975 s."""
    ref = SCurve(0.2, 0.25, 2.0, 40.0)
    tj, ta, tv, vl = ref.phases()
    assert (tj, ta, vl) == (0.05, 0.175, 0.25)
    assert tv == pytest.approx(0.625, abs=1e-15)
    assert ref.duration == pytest.approx(0.975, abs=1e-15)
    t = np.arange(0, 1.2, 1e-4)
    r = ref.values(t)
    v, a = ref.rates(t)
    assert r[-1] == 0.2 and r[0] == 0.0
    assert np.max(v) == pytest.approx(0.25, abs=1e-12) and np.max(np.abs(v)) <= 0.25 + 1e-15
    assert np.max(np.abs(a)) <= 2.0 + 1e-12
    jerk = np.diff(a) / 1e-4
    assert np.max(np.abs(jerk[np.abs(jerk) < 1e3])) <= 40.0 + 1e-6
    # position continuous: no step larger than v_max h
    assert np.max(np.abs(np.diff(r))) <= 0.25 * 1e-4 * (1 + 1e-9)


def test_scurve_short_move_never_cruises_and_ends_on_target() -> None:
    ref = SCurve(0.01, 0.25, 2.0, 40.0)
    tj, ta, tv, vl = ref.phases()
    assert vl < 0.25 and tv == pytest.approx(0.0, abs=1e-12)
    assert vl * ta == pytest.approx(0.01, rel=1e-12)  # the two phases cover the move
    t = np.linspace(0.0, ref.duration + 0.1, 20001)
    assert ref.values(t)[-1] == 0.01
    assert np.max(np.abs(np.diff(ref.values(t)))) < 1e-5


def test_steps_have_no_sampled_impulses() -> None:
    t = np.arange(0.0, 1.0, 1e-3)
    for ref in (Step(0.1, 0.5), parse_reference("multistep:0.1=0.05,0.5=0.1")):
        v, a = ref.rates(t)
        assert not v.any() and not a.any()


def test_sampled_references_use_second_order_differences() -> None:
    t = np.arange(0.0, 1.0, 1e-3)
    r = 0.3 * t**2  # exact for second-order differences
    v, a = reference_rates(r, t)
    np.testing.assert_allclose(v, 0.6 * t, atol=1e-12)
    np.testing.assert_allclose(a, 0.6, atol=1e-9)


def test_parse_and_check_new_references() -> None:
    assert parse_reference("scurve:0.2:0.25:2:40") == SCurve(0.2, 0.25, 2.0, 40.0)
    assert parse_reference("scurve:0.2:0.25:2:40:0.5").time == 0.5
    assert parse_reference("chirp:0.005:0.5:20:10") == Chirp(0.005, 0.5, 20.0, 10.0)
    with pytest.raises(InputError, match="scurve j_max must be > 0"):
        parse_reference("scurve:0.2:0.25:2:0")
    with pytest.raises(InputError, match="chirp end frequency must be > 0"):
        parse_reference("chirp:0.005:0.5:-1:10")
    with pytest.raises(InputError, match="expected 4..5 numbers"):
        parse_reference("scurve:0.2")
    with pytest.raises(InputError, match="chirp frequency 600.0 Hz is at or above half"):
        check_reference(Chirp(0.005, 0.5, 600.0, 1.0), ts=1e-3, duration=2.0)
    with pytest.raises(InputError, match="scurve start time 3.0 s is at or after the end"):
        check_reference(SCurve(0.1, 0.1, 1.0, 10.0, 3.0), ts=1e-3, duration=2.0)


def test_the_law_sees_the_rates_the_reference_gives() -> None:
    """A law's step receives (r, ṙ, r̈) of each sample: the leadlag test law of
    tests/control ignores them, and a run of an S-curve equals a run of its samples as a
    user array whatever the rates (the reference array's rates are differences)."""
    from fuzzyservo.registry import build_controller, build_plant

    ctl = build_controller("pid", {"kp": 5.0, "ki": 0.5, "kd": 0.0}, dt=1e-3)
    plant = build_plant("linear", "paper")
    ref = SCurve(0.1, 0.2, 1.0, 20.0)
    a = simulate(ctl, plant, ref, duration=1.5)
    b = simulate(ctl, plant, ref.values(a.t), duration=1.5)
    assert np.array_equal(a.y, b.y)
