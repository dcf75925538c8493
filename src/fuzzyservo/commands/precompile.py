"""``fuzzyservo precompile``: compile the closed-loop kernels once, into numba's on-disk cache.

The kernels are compiled on their first call and cached next to their sources
(``cache=True``). A cold compile takes about seven minutes of CPU (the controller laws and the
fuzzy evaluators are inlined into every loop so the loops run fast), and a fresh install pays
it in every process that starts before the cache is written: a sweep's worker processes, a
test suite's workers, the processes a test starts. ``fuzzyservo precompile`` pays it once,
in two processes (the linear plant's loops in one, the nonlinear plant's and the per-step
API in the other), so every process started afterwards loads the compiled code in about a
second. ``make test``, ``make reproduce`` and ``make bench`` run it first; a container image
or a Dask worker's environment can run it at build time.

It runs each closed-loop entry point once, briefly, with the argument types the package
passes (C-contiguous float64 and int64 arrays): the single-run loops (``simulate``, with a
delay and noise), the batch kernels (``simulate_batch``: with and without traces, per-run
plants, delays, noise rows and reference rows; on the linear plant the two-run loop too) and
the per-step API (``controller.step``). The fuzzy evaluators the loops call are compiled with
them; evaluators used only outside the loops (surfaces, batch evaluation of a file's system)
compile on first use.
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from typing import Any

from ..errors import ParameterError

__all__ = ["GROUPS", "compile_group", "precompile", "register", "run"]

#: What each process compiles: (plants whose loops it runs, whether it compiles the per-step
#: API). The linear loops take about twice as long to compile as the nonlinear one, so the
#: per-step API goes with the nonlinear plant.
GROUPS: tuple[tuple[tuple[str, ...], bool], ...] = ((("linear", "small-signal"), False),
                                                     (("nonlinear",), True))


def compile_group(plants: tuple[str, ...], per_step: bool = False) -> float:
    """Run the closed loops of ``plants`` once (short runs) with every registered controller
    and, if ``per_step``, their per-step API; return the seconds it took.

    The controllers are the registry's templates (their required gains 0): the kernels are
    compiled for argument types, not values, and a controller kind is a runtime argument, so
    the first kind compiles the loops and the others run them from memory."""
    import numpy as np

    from ..paper.published import paper_params
    from ..registry import build_plant, controller_kind, controller_names
    from ..sim import Step, simulate, simulate_batch

    t0 = time.perf_counter()
    params = paper_params()
    ts = 1e-3
    ctls = [controller_kind(name).template(dt=ts) for name in controller_names()]
    for name in plants:
        plant = build_plant(name, params)
        for ctl in ctls:
            simulate(ctl, plant, Step(0.01), duration=0.02, delay=0.0015, noise_std=1e-6,
                     rng=np.random.default_rng(0))
            for keep in (False, True):  # three runs: a pair and one alone
                simulate_batch(ctl, plant=plant, reference=Step(0.01), duration=0.02,
                               delay=[0.0, 0.0015, 0.003], noise=np.zeros((3, 21)),
                               keep_traces=keep)
            simulate_batch(ctl, plant=[plant] * 3, reference=np.zeros((3, 21)),
                           duration=0.02)
    if per_step:
        for ctl in ctls:
            ctl.step(ctl.initial_state(), 0.01, 0.0)
    return time.perf_counter() - t0


def precompile(processes: int = 2) -> list[tuple[str, float]]:
    """Compile the closed-loop kernels into numba's cache.

    Parameters
    ----------
    processes : int
        1: everything in this process, one group after the other; 2: the groups of
        :data:`GROUPS` in two processes at once.

    Returns
    -------
    list of (str, float)
        Each group's description and the seconds it took [s].

    Raises
    ------
    ParameterError
        ``processes`` is not 1 or 2.
    """
    if processes not in (1, 2):
        raise ParameterError(f"--processes must be 1 or 2, got {processes!r}")
    names = [", ".join(plants) + (" plant loops" + (" and the per-step API" if step else ""))
             for plants, step in GROUPS]
    if processes == 1:
        secs = [compile_group(*g) for g in GROUPS]
    else:
        with ProcessPoolExecutor(max_workers=len(GROUPS),
                                 mp_context=get_context("spawn")) as pool:
            secs = list(pool.map(compile_group, *zip(*GROUPS, strict=True)))
    return list(zip(names, secs, strict=True))


def register(subparsers: Any) -> None:
    """Add the ``precompile`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "precompile",
        help="compile the closed-loop kernels once, into numba's cache",
        description=(
            "Compile the closed-loop kernels into numba's on-disk cache, so that every "
            "process started afterwards (a sweep's workers, Dask workers, test workers) loads "
            "them in about a second instead of compiling them for minutes. With the cache "
            "warm it returns in a few seconds."
        ),
    )
    parser.add_argument("--processes", type=int, default=2, metavar="N",
                        help="1 or 2 processes (default 2: linear and nonlinear loops at once)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo precompile``."""
    t0 = time.perf_counter()
    for name, secs in precompile(args.processes):
        print(f"precompile: {name} in {secs:.0f} s", file=sys.stderr)
    print(f"precompile: done in {time.perf_counter() - t0:.0f} s (numba's cache, next to the "
          f"sources)", file=sys.stderr)
    return 0
