"""A small real identification for the figure and report tests: the nonlinear plant of the
paper set with ``load.mass`` changed simulates 2 s at 1 kHz under a few command pulses (plus
seeded noise and a flagged block); :func:`fuzzyservo.identify.identify` fits ``load.mass``
back from one start with a short bootstrap. Computed once per test process."""

from __future__ import annotations

import functools
import types

import numpy as np

from fuzzyservo.identify import FitSettings, Identification, identify
from fuzzyservo.paper.published import named_set
from fuzzyservo.plant import with_overrides
from fuzzyservo.registry import build_plant
from fuzzyservo.sim import simulate_open_loop

TRUE_MASS = 1.0e4  #: the simulated axis's load.mass [kg] (the paper set's is 14867 kg)
DT = 1.0e-3  #: sample time [s]
FLAGGED = slice(1200, 1240)  #: samples marked flagged in the log
NOISE = {"y": 2.0e-5, "p_f": 5.0e3, "p_n": 5.0e3}  #: measurement noise [m, Pa, Pa]


def measurement() -> types.SimpleNamespace:
    """The simulated log: t, dt, y, u, r=None, p_f, p_n, flagged, rest=100."""
    params = with_overrides(named_set("paper"), {"load.mass": TRUE_MASS})
    plant = build_plant("nonlinear", params, 0.5)
    n = 2000
    u = np.full(n, plant.u0)  # at rest: the trim command, then pulses of both signs
    for k0, amp in ((200, 0.08), (600, -0.08), (1000, 0.05), (1400, -0.05)):
        u[k0:k0 + 150] += amp
    res = simulate_open_loop(plant, u, duration=n * DT, dt=DT,
                             delay=params.delay.transport_delay)
    rng = np.random.default_rng(27)
    flagged = np.zeros(res.t.size, dtype=bool)
    flagged[FLAGGED] = True
    return types.SimpleNamespace(
        t=res.t, dt=DT, u=np.append(res.u, res.u[-1]), r=None, flagged=flagged, rest=100,
        y=res.y + rng.normal(0.0, NOISE["y"], res.t.size),
        p_f=res.p_f + rng.normal(0.0, NOISE["p_f"], res.t.size),
        p_n=res.p_n + rng.normal(0.0, NOISE["p_n"], res.t.size))


@functools.cache
def identification() -> Identification:
    """``load.mass`` fitted to :func:`measurement` (one start, 4 bootstrap refits)."""
    return identify(measurement(), plant="nonlinear", params=named_set("paper"),
                    fit=["load.mass"], settings=FitSettings(starts=1, bootstrap=4, workers=1))
