"""The one outcome rule (analysis/outcome.py): the tail oscillation it reads, and
:func:`classify` against the rule written as a chain of ifs, one run at a time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzyservo.analysis.outcome import (
    LIMIT_CYCLE_MIN_PP,
    LIMIT_CYCLE_MIN_SUSTAIN,
    LIMIT_CYCLE_MIN_SWINGS,
    MAX_OVERSHOOT_PCT,
    OUTCOMES,
    classify,
    tail_oscillation,
)


def _t(duration: float = 20.0, dt: float = 0.001) -> np.ndarray:
    return np.arange(round(duration / dt) + 1) * dt


def test_tail_oscillation_of_a_sinusoid() -> None:
    t = _t()
    amp, period = 0.004, 0.35  # [m, s]
    osc = tail_oscillation(t, 0.6 + amp * np.sin(2 * np.pi * t / period))
    assert osc.peak_to_peak == pytest.approx(2 * amp, rel=1e-3)  # 1 ms samples of the crest
    assert osc.period == pytest.approx(period, abs=2e-3)  # swing times to a sample each
    assert abs(osc.swings - 2 * osc.window / period) <= 1  # a half period at either end
    assert osc.sustain == pytest.approx(1.0, abs=1e-3)
    assert osc.window == pytest.approx(5.0, abs=1e-12)
    flat = tail_oscillation(t, np.full_like(t, 0.6))
    assert flat.peak_to_peak == 0.0 and flat.swings == 0


def _tail_oscillation_numpy(t: np.ndarray, y: np.ndarray, tail: float = 0.25
                            ) -> tuple[float, int, float, float, float]:
    """The numpy formulation tail_oscillation had before it moved into the compiled
    sim.stepinfo.tail_oscillation_core, kept as an independent reference."""
    start = t[0] + (1.0 - tail) * (t[-1] - t[0])
    sel = t >= start
    tt, yy = t[sel], y[sel]
    window = float(t[-1] - start)
    if yy.size < 2:
        return (math.nan, 0, math.nan, math.nan, window)
    pp = float(np.ptp(yy))
    dev = yy - float(np.mean(yy))
    h = pp / 4.0
    side = np.where(dev > h, 1, np.where(dev < -h, -1, 0))
    on = side != 0
    sides, times = side[on], tt[on]
    change = np.nonzero(np.diff(sides))[0] + 1
    swings = int(change.size)
    period = float(2.0 * np.mean(np.diff(times[change]))) if swings >= 3 else math.nan
    mid = tt[0] + 0.5 * (tt[-1] - tt[0])
    first, second = yy[tt < mid], yy[tt >= mid]
    p1 = float(np.ptp(first)) if first.size else 0.0
    p2 = float(np.ptp(second)) if second.size else 0.0
    sustain = p2 / p1 if p1 > 0.0 else math.nan
    return (pp, swings, period, sustain, window)


def _tail_cases() -> list[tuple[np.ndarray, np.ndarray, float]]:
    rng = np.random.default_rng(13)
    cases = []
    for i in range(240):
        # long runs now and then: the pairwise sums split into halves several times
        n = int(rng.integers(1, 2000)) if i % 12 else int(rng.integers(20_000, 120_000))
        t = np.arange(n) * (1e-3 * rng.uniform(0.5, 2.0))
        kind = i % 6
        if kind == 0:  # white noise: many swings
            y = rng.normal(size=n)
        elif kind == 1:  # a decaying or sustained oscillation with a little noise
            y = (np.sin(2 * np.pi * t / rng.uniform(0.005, 0.5)) * np.exp(-t * rng.uniform(0, 3))
                 + 1e-3 * rng.normal(size=n))
        elif kind == 2:  # few levels: ties with the mean and the hysteresis
            y = np.round(3 * rng.normal(size=n)) / 7
        elif kind == 3:  # a NaN somewhere
            y = rng.normal(size=n)
            y[rng.integers(0, n)] = np.nan
        elif kind == 4:  # flat: pp = 0, p1 = 0
            y = np.full(n, 0.3)
        else:  # a step that settles: swings < 3
            y = 0.5 + 0.1 * (1 - np.exp(-t / 0.05))
        tail = float(rng.choice([0.25, 0.1, 0.5, 1.0, 0.0, 1e-4, 0.9]))
        cases.append((t, y, tail))
    t2 = np.array([0.0, 1.0])  # one sample in a quarter tail, two in the whole
    cases += [(t2, np.array([0.0, 1.0]), 0.25), (t2, np.array([0.0, 1.0]), 1.0),
              (np.array([0.0]), np.array([2.0]), 0.25)]
    return cases


def test_tail_oscillation_equals_its_numpy_formulation() -> None:
    """The compiled core against the numpy reference, bit for bit (same sums in numpy's
    pairwise order), on noise, oscillations, ties, NaN, flat traces, settling steps and tails
    of fewer than 2 samples."""
    seen = {"period": 0, "no period": 0, "short": 0, "no sustain": 0}
    for t, y, tail in _tail_cases():
        ref = _tail_oscillation_numpy(t, y, tail)
        got = tail_oscillation(t, y, tail=tail)
        assert np.array_equal(np.array(ref, dtype=float),
                              [got.peak_to_peak, got.swings, got.period, got.sustain,
                               got.window], equal_nan=True), (t.size, tail, ref, got)
        assert isinstance(got.swings, int)
        seen["period"] += not math.isnan(ref[2])
        seen["no period"] += math.isnan(ref[2]) and ref[1] > 0
        seen["short"] += math.isnan(ref[0]) and ref[1] == 0 and math.isnan(ref[3])
        seen["no sustain"] += math.isnan(ref[3]) and not math.isnan(ref[0])
    assert min(seen.values()) > 0, seen  # every branch was exercised


def _one_run(os_: float, ts: float, pp: float, swings: float, sustain: float, step: float,
             diverged: bool, invalid: bool) -> str:
    """The rule as the study's claims wrote it for one run before it was written once."""
    if invalid:
        return "invalid"
    if diverged:
        return "diverged"
    if (pp >= LIMIT_CYCLE_MIN_PP * abs(step) and swings >= LIMIT_CYCLE_MIN_SWINGS
            and sustain >= LIMIT_CYCLE_MIN_SUSTAIN):
        return "limit cycle"
    if math.isnan(ts):
        return "not settled"
    if os_ > MAX_OVERSHOOT_PCT:
        return "overshoots"
    return "settles"


def test_classify_is_the_rule_run_by_run() -> None:
    """Every combination near the thresholds, NaN included (an unmeasured tail is no limit
    cycle, an undefined overshoot no overshoot), in one call and one run at a time."""
    rng = np.random.default_rng(24)
    n = 4000
    nan = math.nan
    step = rng.choice([0.1, -0.1, 0.0, nan], n)
    cols = {
        "overshoot": rng.choice([0.0, MAX_OVERSHOOT_PCT, 10.5, 50.0, nan], n),
        "settling_time": rng.choice([1.0, 2.5, nan], n),
        "tail_peak_to_peak": rng.choice([0.0, 0.5e-3, LIMIT_CYCLE_MIN_PP * 0.1, 0.01, nan], n),
        "tail_swings": rng.choice([0.0, 3.0, float(LIMIT_CYCLE_MIN_SWINGS), 9.0, nan], n),
        "tail_sustain": rng.choice([0.2, LIMIT_CYCLE_MIN_SUSTAIN, 1.0, nan], n),
    }
    diverged = rng.random(n) < 0.1
    invalid = rng.random(n) < 0.05
    got = classify(cols, step, diverged, invalid)
    want = [_one_run(cols["overshoot"][i], cols["settling_time"][i],
                     cols["tail_peak_to_peak"][i], cols["tail_swings"][i],
                     cols["tail_sustain"][i], step[i], bool(diverged[i]), bool(invalid[i]))
            for i in range(n)]
    assert got.tolist() == want
    assert set(want) == set(OUTCOMES)  # every outcome was reached
    for i in range(0, n, 97):  # a run alone is classified as it is among others
        one = {k: v[i:i + 1] for k, v in cols.items()}
        assert classify(one, step[i:i + 1], diverged[i:i + 1])[0] == (
            want[i] if not invalid[i] else _one_run(*(one[k][0] for k in cols), step[i],
                                                    bool(diverged[i]), False))
