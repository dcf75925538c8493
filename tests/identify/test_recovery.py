"""Recovery of known parameters from data simulated by fuzzyservo (issue 27; the 50-trial
coverage figures are ``benchmarks/identify.py``'s).

The truth is the ``paper`` set with the mass x1.2, the oil's bulk modulus 1.2 GPa and the
spool's omega_v 600 rad/s; the fit starts from the ``paper`` set's values (-17 %, +25 %,
+15 %). 5 s at 1 kHz: 0.5 s at rest, command pulses of +-0.15, a log chirp 1 -> 80 Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from fuzzyservo.identify import FitSettings, identify
from fuzzyservo.paper.published import named_set
from fuzzyservo.plant import ServoParams, with_overrides
from fuzzyservo.registry import build_plant
from fuzzyservo.sim import simulate_open_loop

DT = 1e-3
REST = 500
NAMES = ("load.mass", "fluid.oil_bulk_modulus", "valve.omega_v")


@dataclass(frozen=True, slots=True, kw_only=True)
class Log:
    """A logged open-loop experiment, as :func:`fuzzyservo.identify.identify` reads it."""

    t: np.ndarray
    dt: float
    y: np.ndarray
    u: np.ndarray
    p_f: np.ndarray | None
    p_n: np.ndarray | None
    r: None = None
    flagged: None = None
    rest: int = REST


def base() -> ServoParams:
    return named_set("paper")


def truth_set() -> ServoParams:
    b = base()
    return with_overrides(b, {"load.mass": 1.2 * b.load.mass,
                              "fluid.oil_bulk_modulus": 1.2e9, "valve.omega_v": 600.0})


def truth_values() -> np.ndarray:
    p = truth_set()
    return np.array([p.load.mass, p.fluid.oil_bulk_modulus, p.valve.omega_v])


def excitation(duration: float, *, chirp: tuple[float, float, float, float],
               amplitude: float = 0.15) -> tuple[np.ndarray, np.ndarray]:
    """Sample times and a command: rest, pulses +a -a (0.25 s each) from 0.5 s, and a log
    chirp (t0, t1, f0, f1) [s, s, Hz, Hz]."""
    n = int(round(duration / DT)) + 1
    t = np.arange(n) * DT
    u = np.zeros(n)

    def during(a: float, b: float) -> np.ndarray:
        return (t >= a - 1e-9) & (t < b - 1e-9)

    u[during(0.5, 0.75)] = amplitude
    u[during(0.75, 1.0)] = -amplitude
    t0, t1, f0, f1 = chirp
    m = during(t0, t1)
    k = (f1 / f0) ** (1.0 / (t1 - t0))
    u[m] = amplitude * np.sin(2.0 * np.pi * f0 * (k ** (t[m] - t0) - 1.0) / math.log(k))
    return t, u


def simulate(u: np.ndarray, substep: float) -> dict[str, np.ndarray]:
    truth = truth_set()
    plant = build_plant("nonlinear", truth, 0.5, substep=substep)
    sim = simulate_open_loop(plant, u[:-1] + plant.u0, duration=(u.size - 1) * DT, dt=DT,
                             delay=truth.delay.transport_delay)
    return {"y": np.asarray(sim.y), "p_f": np.asarray(sim.p_f), "p_n": np.asarray(sim.p_n)}


def log_of(t: np.ndarray, u: np.ndarray, x: dict[str, np.ndarray], seed: int | None, *,
           pressures: bool = True) -> Log:
    """The run as logged: 30 dB of white noise on each channel (std(x)/sqrt(1000)) unless
    ``seed`` is None, and a logged command with a null offset of +0.01."""
    out = dict(x)
    if seed is not None:
        rng = np.random.default_rng(seed)
        out = {c: v + rng.normal(0.0, float(np.std(v)) / math.sqrt(1000.0), v.size)
               for c, v in x.items()}
    return Log(t=t, dt=DT, y=out["y"], u=u + 0.01,
               p_f=out["p_f"] if pressures else None, p_n=out["p_n"] if pressures else None)


@pytest.fixture(scope="module")
def five_seconds() -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    t, u = excitation(5.0, chirp=(1.5, 4.8, 1.0, 80.0))
    return t, u, simulate(u, substep=1e-4)


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_noisy_data_recover_the_truth(
        five_seconds: tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]],
        seed: int) -> None:
    """Each estimate within 3 standard errors and 2 % of the truth. Three seeds of three
    parameters are nine draws: were the standard errors exact, all nine would lie within 2 SE
    in 0.95^9 = 63 % of seed sets, within 3 SE in 0.9973^9 = 97.6 %; the seeds are fixed, so
    the test is deterministic, and 3 SE keeps a seed set taken blind (these were) from
    failing by chance. The 2-SE coverage over 50 trials is the benchmark's figure."""
    t, u, x = five_seconds
    res = identify(log_of(t, u, x, seed), plant="nonlinear", params=base(), fit=NAMES,
                   settings=FitSettings(starts=1, seed=seed))
    truth = truth_values()
    assert np.all(np.abs(res.estimate - truth) <= 3.0 * res.std_error), (
        (res.estimate - truth) / res.std_error)
    assert np.all(np.abs(res.estimate / truth - 1.0) <= 0.02), res.estimate / truth - 1.0


def test_noise_free_data_recover_the_truth_exactly() -> None:
    """Data from the fitted model itself (the same 0.5 ms RK4 substep), no noise: the fit
    lands on the truth to 1e-6 relative from starts 15-25 % off."""
    t, u = excitation(5.0, chirp=(1.5, 4.8, 1.0, 80.0))
    x = simulate(u, substep=5e-4)
    res = identify(log_of(t, u, x, None), plant="nonlinear", params=base(), fit=NAMES,
                   substep=5e-4, settings=FitSettings(starts=1))
    truth = truth_values()
    assert np.all(np.abs(res.initial / truth - 1.0) > 0.14)
    np.testing.assert_allclose(res.estimate, truth, rtol=1e-6)

