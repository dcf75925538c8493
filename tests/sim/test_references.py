"""References checked against the run and the plant (issue 9, rows 17 and 18): the limits
themselves pass, a hair beyond them is refused with one line naming the limit."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from fuzzyservo.control import PIDController
from fuzzyservo.errors import InputError
from fuzzyservo.paper import paper_params
from fuzzyservo.registry import build_plant
from fuzzyservo.sim import MultiStep, Ramp, Sine, Step, Trapezoid, UserReference, simulate
from fuzzyservo.sim.references import check_reference, check_reference_samples


@pytest.mark.parametrize("make", [
    lambda: Step(0.1, -1e-12), lambda: Ramp(1.0, -0.5), lambda: MultiStep((-1.0,), (0.1,)),
    lambda: MultiStep((0.0, -1.0), (0.1, 0.2)), lambda: Trapezoid(0.1, 1.0, 10.0, -2.0),
    lambda: Sine(0.1, -5.0), lambda: Sine(0.1, 0.0), lambda: Ramp(1.0, 0.0, -0.2),
    lambda: Ramp(-1.0, 0.0, 0.2)])
def test_negative_times_and_contrary_values_refused(make: Callable[[], object]) -> None:
    with pytest.raises(InputError) as info:
        make()
    assert "\n" not in str(info.value)


def test_times_at_zero_and_negative_levels_allowed() -> None:
    Step(-0.1, 0.0)
    Ramp(-1.0, 0.0, -0.2)
    MultiStep((0.0, 0.5), (-0.1, 0.1))
    Sine(-0.1, 1.0)


@pytest.mark.parametrize(("ts", "ok", "bad"), [(1e-3, 499.999, 500.0), (0.01, 49.9, 50.0),
                                              (3e-4, 1666.0, 1666.67)])
def test_sine_must_lie_below_half_the_sample_rate(ts: float, ok: float, bad: float) -> None:
    check_reference(Sine(0.1, ok), ts=ts, duration=1.0)
    with pytest.raises(InputError, match="at or above half the sample rate"):
        check_reference(Sine(0.1, bad), ts=ts, duration=1.0)


def test_the_sine_the_issue_found_flat_is_refused() -> None:
    """At f = 1/ts every sample lands on a multiple of the period: the samples are flat."""
    t = np.arange(1001) * 1e-3
    assert np.max(np.abs(Sine(0.1, 1000.0).values(t))) < 1e-12
    with pytest.raises(InputError, match=r"1/\(2 ts\) = 500 Hz at ts = 0\.001 s"):
        check_reference(Sine(0.1, 1000.0), ts=1e-3, duration=1.0)


@pytest.mark.parametrize("ref", [Step(0.1, 2.0), Ramp(0.1, 2.0), MultiStep((2.0,), (0.1,)),
                                 Trapezoid(0.1, 1.0, 10.0, 2.0)])
def test_a_reference_starting_after_the_run_is_refused(ref: Step) -> None:
    check_reference(ref, ts=1e-3, duration=2.001)
    with pytest.raises(InputError, match=r"time 2\.0 s is at or after the end of the run"):
        check_reference(ref, ts=1e-3, duration=2.0)


def test_samples_against_the_stroke_and_the_resolution() -> None:
    t = np.array([0.0, 0.1, 0.2])
    check_reference_samples(np.array([0.5, 1.0, 0.0]), t, start=0.5, stroke=1.0)
    with pytest.raises(InputError, match=r"reaches 1\.0001 m at t = 0\.1 s .* outside the "
                                         r"stroke \[0, 1\] m"):
        check_reference_samples(np.array([0.5, 1.0001, 0.5]), t, start=0.5, stroke=1.0)
    with pytest.raises(InputError, match=r"reaches -0\.0001 m at t = 0\.2 s"):
        check_reference_samples(np.array([0.5, 0.5, -1e-4]), t, start=0.5, stroke=1.0)
    check_reference_samples(np.array([0.5, 5.0, 0.5]), t, start=0.5, stroke=None)  # unknown
    r = np.array([0.5, 0.5 + 0.1, 0.5])
    check_reference_samples(r, t, start=0.5, stroke=1.0, resolution=0.1)  # as coarse: ok
    with pytest.raises(InputError, match="coarser than the reference's largest move 0.1 m"):
        check_reference_samples(r, t, start=0.5, stroke=1.0, resolution=0.1001)
    check_reference_samples(np.full(3, 0.5), t, start=0.5, stroke=1.0, resolution=10.0)


def test_simulate_checks_a_sampled_reference_too() -> None:
    """An array or a user reference is checked against the stroke like a parsed one."""
    plant = build_plant("small-signal", paper_params(), 0.5)
    ctl = PIDController(dt=1e-3, kp=20.0, ki=2.0, kd=0.1)
    with pytest.raises(InputError, match="outside the stroke"):
        simulate(ctl, plant, np.full(11, 0.6), duration=0.01)
    with pytest.raises(InputError, match="outside the stroke"):
        simulate(ctl, plant, UserReference(np.array([0.0, 0.01]), np.array([0.0, -0.6])),
                 duration=0.01)
