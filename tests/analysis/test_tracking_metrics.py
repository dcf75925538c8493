"""Tracking and disturbance metrics against signals whose answers are known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzyservo.analysis.tracking import (
    disturbance_metrics,
    harmonic,
    move_metrics,
    sine_metrics,
)
from fuzzyservo.errors import InputError

T = np.arange(0.0, 6.0 + 1e-12, 1e-3)


@pytest.mark.parametrize(("ratio", "lag_deg", "offset"),
                         [(1.0, 0.0, 0.0), (0.8, 30.0, 0.001), (1.2, -10.0, -0.002),
                          (0.5, 170.0, 0.0)])
def test_sine_metrics_of_a_scaled_shifted_sine(ratio: float, lag_deg: float,
                                               offset: float) -> None:
    """y = g A sin(ωt - φ) + m: ratio g, lag φ, and e = r - y with the RMS and peak of the
    difference of two sines, sqrt(A² + (gA)² - 2 g A² cos φ) (/√2 for the RMS) when m = 0."""
    a, f = 0.05, 1.0
    w = 2 * math.pi * f
    phi = math.radians(lag_deg)
    r = a * np.sin(w * T)
    y = ratio * a * np.sin(w * T - phi) + offset
    m = sine_metrics(T, r, y, f)
    assert m.amplitude_ratio == pytest.approx(ratio, rel=1e-9)
    assert m.phase_lag == pytest.approx(lag_deg, abs=1e-7)
    assert m.window == pytest.approx(2.0, abs=1e-12)
    amp = a * math.sqrt(1 + ratio**2 - 2 * ratio * math.cos(phi))
    if offset == 0.0:
        assert m.rms_error == pytest.approx(amp / math.sqrt(2), rel=1e-6)
        assert m.max_error == pytest.approx(amp, rel=1e-5)


def test_harmonic_ignores_the_mean_and_other_harmonics() -> None:
    t = np.arange(0.0, 2.0, 1e-3)  # two whole periods of 1 Hz
    x = 0.3 + 0.02 * np.sin(2 * math.pi * t + 0.4) + 0.01 * np.sin(6 * math.pi * t)
    c = harmonic(t, x, 1.0)
    assert abs(c) == pytest.approx(0.02, rel=1e-9)
    assert math.atan2(c.imag, c.real) == pytest.approx(0.4, abs=1e-9)


def test_move_metrics_of_a_delayed_first_order_follower() -> None:
    """y follows a ramp move through a first-order lag τ: during the ramp the error tends to
    v τ; after the move it decays as v τ e^{-(t - t_end)/τ}, so it enters a band b·d at
    t_end + τ ln(v τ / (b d)) (the discrete samples round it to the grid)."""
    tau, v, d = 0.1, 0.2, 0.2
    t = np.arange(0.0, 3.0, 1e-4)
    t_end = d / v
    r = np.minimum(v * t, d)
    # exact response of a lag to the ramp, then to the hold
    y = np.where(t <= t_end, v * (t - tau * (1 - np.exp(-t / tau))),
                 d - v * tau * (1 - np.exp(-t_end / tau)) * np.exp(-(t - t_end) / tau))
    m = move_metrics(t, r, y, distance=d, t_end=t_end)
    e_end = v * tau * (1 - math.exp(-t_end / tau))
    assert m.max_following_error == pytest.approx(e_end, rel=1e-9)
    assert m.overshoot == 0.0
    assert m.settling_time == pytest.approx(tau * math.log(e_end / (0.02 * d)), abs=2e-4)
    assert m.final_error == pytest.approx(e_end * math.exp(-(3.0 - 1e-4 - t_end) / tau),
                                          rel=1e-6)


def test_move_overshoot_and_never_settling() -> None:
    t = np.arange(0.0, 2.0, 1e-3)
    r = np.minimum(t, 1.0) * 0.1
    y = r + np.where(t > 1.0, 0.01 * np.sin(20 * t), 0.0)  # rings past the end
    m = move_metrics(t, r, y, distance=0.1, t_end=1.0)
    assert m.overshoot == pytest.approx(10.0, rel=1e-3)
    assert math.isnan(m.settling_time)
    m = move_metrics(t, -r, -y, distance=-0.1, t_end=1.0)  # the same move downwards
    assert m.overshoot == pytest.approx(10.0, rel=1e-3)


def test_disturbance_metrics_of_a_damped_response() -> None:
    """Deviation A (e^{-t/τ1} - e^{-t/τ2}) with a remaining offset c (1 - e^{-t/τ1})."""
    t = np.arange(0.0, 5.0, 1e-3)
    ts = 1.0
    s = np.clip(t - ts, 0.0, None)
    dev = 0.004 * (np.exp(-s / 0.3) - np.exp(-s / 0.03))
    y = 0.5 + dev
    m = disturbance_metrics(t, y, t_step=ts)
    assert m.max_deviation == pytest.approx(np.max(dev), rel=1e-12)
    # recovery: the last instant the deviation exceeds 2 % of the peak, by root finding
    from scipy.optimize import brentq

    peak = float(np.max(dev))
    root = brentq(lambda x: 0.004 * (math.exp(-x / 0.3) - math.exp(-x / 0.03)) - 0.02 * peak,
                  0.2, 4.0)
    assert m.recovery_time == pytest.approx(root, abs=1.1e-3)
    assert m.remaining == pytest.approx(float(np.mean(dev[t >= t[-1] - 0.5])), rel=1e-9)
    offset = disturbance_metrics(t, y + 0.001 * (s > 0), t_step=ts)
    assert math.isnan(offset.recovery_time)
    assert offset.remaining == pytest.approx(0.001, rel=1e-2)


def test_bad_input_is_named() -> None:
    with pytest.raises(InputError, match="shorter than 2 periods"):
        sine_metrics(T[:100], T[:100], T[:100], 1.0)
    with pytest.raises(InputError, match="frequency must be > 0"):
        sine_metrics(T, T, T, 0.0)
    with pytest.raises(InputError, match="outside the run"):
        move_metrics(T, T, T, distance=0.1, t_end=10.0)
    with pytest.raises(InputError, match="outside the run"):
        disturbance_metrics(T, T, t_step=-1.0)
