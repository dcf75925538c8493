"""Compile the closed-loop kernels once, ahead of use, into numba's on-disk cache.

The kernels are compiled on their first call and cached next to their sources
(``cache=True``). The first call is slow (about three minutes on two cores for both plants:
the controller laws and the fuzzy evaluators are inlined into every loop so the loops run
fast), and a fresh install pays it in every process that starts before the cache is written:
a sweep's worker processes, a test suite's workers. ``python -m fuzzyservo.sim.precompile``
pays it once, in two processes (the linear and the nonlinear plant's loops), so everything
started afterwards loads the compiled code in about a second. ``make test`` runs it first;
a container image can run it at build time.

It runs each entry point with the argument types the package passes (C-contiguous float64
and int64 arrays): the per-run loops (``simulate``), the batch kernels (``simulate_batch``,
with and without traces, noise and per-run references), and the per-step API.
"""

from __future__ import annotations

import sys
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

__all__ = ["precompile"]

#: What each process compiles: the plants whose loops it runs.
GROUPS: tuple[tuple[str, ...], ...] = (("linear", "small-signal"), ("nonlinear",))


def _compile(plants: tuple[str, ...]) -> float:
    """Run the loops of ``plants`` once (short runs); return the seconds it took."""
    import numpy as np

    from ..paper.published import paper_params
    from ..registry import build_controller, build_plant
    from .batch import simulate_batch
    from .closed_loop import simulate
    from .references import Step

    t0 = time.perf_counter()
    params = paper_params()
    ts = 1e-3
    ctl = build_controller("stfpi", {"ke": 40.0, "kde": 20.0, "kdu": 0.005}, dt=ts)
    for name in plants:
        plant = build_plant(name, params)
        simulate(ctl, plant, Step(0.01), duration=0.02, delay=0.0015, noise_std=1e-6,
                 rng=np.random.default_rng(0))
        for keep in (False, True):
            simulate_batch(ctl, np.tile([40.0, 20.0, 0.005], (2, 1)), plant=plant,
                           reference=Step(0.01), duration=0.02, delay=[0.0, 0.0015],
                           noise=np.zeros((2, 21)), keep_traces=keep)
        simulate_batch(ctl, plant=[plant, plant], reference=np.zeros((2, 21)), duration=0.02)
    pid = build_controller("pid", {"kp": 1.2, "ki": 1.0, "kd": 0.75}, dt=ts)
    for c in (pid, ctl):  # the per-step API
        c.step(c.initial_state(), 0.01, 0.0)
    return time.perf_counter() - t0


def precompile(*, processes: int = 2, verbose: bool = True) -> float:
    """Compile every kernel into the cache; return the wall time [s].

    ``processes`` (1 or 2) splits the plants' loops over that many processes.
    """
    t0 = time.perf_counter()
    if processes <= 1:
        for group in GROUPS:
            _compile(group)
    else:
        with ProcessPoolExecutor(max_workers=min(processes, len(GROUPS)),
                                 mp_context=get_context("spawn")) as pool:
            for group, secs in zip(GROUPS, pool.map(_compile, GROUPS), strict=True):
                if verbose:
                    print(f"precompile: {', '.join(group)} plant loops in {secs:.0f} s",
                          file=sys.stderr)
    wall = time.perf_counter() - t0
    if verbose:
        print(f"precompile: done in {wall:.0f} s (numba cache next to the sources)",
              file=sys.stderr)
    return wall


if __name__ == "__main__":  # pragma: no cover - exercised by make test
    precompile()
