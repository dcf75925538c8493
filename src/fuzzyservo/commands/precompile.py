"""``fuzzyservo precompile``: compile every closed-loop kernel once, into the package's cache.

The kernels compile on their first call and are cached in a folder keyed by the package's
sources (:func:`fuzzyservo._jit.cache_dir`), so a process started afterwards loads them in a
fraction of a second. A first ``simulate`` compiles only what it runs (a few seconds, with a
notice on standard error); ``fuzzyservo precompile`` compiles everything at once, in two
processes: for each control law of the registry (and each fuzzy law's variant for general
fuzzy systems, and the open loop's command schedule) its loop on the linear plant, its loop on the
nonlinear plant (single runs and batches share each) and its per-step API. ``make test``,
``make reproduce`` and ``make bench`` run it first; a container image or a Dask worker's
environment can run it at build time.

Each job runs its entry points briefly with the argument types the package passes (simulate
with a delay and noise, simulate_batch with and without traces, per-run plants, delays and
noise rows), so what it compiles is what the package calls. Evaluators used only outside the
loops (surfaces, batch evaluation of a file's system) compile on first use.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from multiprocessing import get_context
from typing import Any

from ..errors import ParameterError
from . import HELP

__all__ = ["Job", "controllers", "jobs", "precompile", "register", "run", "run_job"]

#: The entry points a job compiles: the closed loop on one plant, or the per-step API.
TARGETS: tuple[str, ...] = ("linear", "nonlinear", "per-step")


@dataclass(frozen=True, slots=True)
class Job:
    """One law's kernels for one target.

    Attributes
    ----------
    law : str
        The law's controller as :func:`controllers` names it (a registry name, ``general``
        for the fuzzy PI on general systems, ``command`` for the open loop).
    target : str
        One of :data:`TARGETS`.
    title : str
        What it is, for the progress lines.
    seconds : float
        About how long it compiles on one core [s] (for the order and the estimate).
    """

    law: str
    target: str
    title: str
    seconds: float


@functools.cache
def controllers() -> dict[str, tuple[Any, str]]:
    """One controller per distinct compiled law: ``{name: (controller, title)}``; the
    registry's kinds in order (the first kind of each law), then each fuzzy law on general
    systems (the paper's systems read from the shipped .fis files, packed for the general
    evaluator: ``general`` the fuzzy PI's, ``general-KIND`` another's, e.g. ``wfpi``) and the
    command schedule."""
    from importlib import resources

    from ..control.command import CommandSchedule
    from ..formats.io import read_system
    from ..fuzzy.loop import loop_system
    from ..registry import controller_kind, controller_names

    ts = 1e-3
    out: dict[str, tuple[Any, str]] = {}
    seen: set[str] = set()
    for name in controller_names():
        kind = controller_kind(name)
        ctl = kind.template(dt=ts)
        if ctl.law.key not in seen:
            seen.add(ctl.law.key)
            out[name] = (ctl, ctl.law.title)
    data = resources.files("fuzzyservo") / "data" / "systems"
    # packed for the general evaluator (grid=False): as read, they would take the uniform grid
    systems = {role: loop_system(read_system(str(data / f"paper-{role}.fis")),
                                 source=f"paper-{role}.fis", grid=False)
               for role in ("du", "alpha")}
    for name in controller_names():
        kind = controller_kind(name)
        if kind.systems:
            ctl = kind.template(dt=ts, systems={r: systems[r] for r in kind.systems})
            if ctl.law.key not in seen:  # "general", then "general-KIND" for another law
                seen.add(ctl.law.key)
                out["general" if "general" not in out else f"general-{name}"] = (
                    ctl, ctl.law.title)
    cmd = CommandSchedule(dt=ts)
    if cmd.law.key not in seen:
        out["command"] = (cmd, "the open loop's command schedule")
    return out


#: Rough compile seconds of one target on one core (the order of the jobs: longest first).
_SECONDS = {"linear": 10.0, "nonlinear": 7.0, "per-step": 2.0}


def jobs() -> list[Job]:
    """Every job, longest first: each law's closed loops on both plants and its per-step API
    (the command schedule has no per-step API a user calls)."""
    out = []
    for name, (_ctl, title) in controllers().items():
        for target in TARGETS:
            if name == "command" and target == "per-step":
                continue
            scale = 1.0
            if name.startswith("general"):  # the general fuzzy evaluator: about 20 s, once
                scale = 12.0 if target == "per-step" else 1.2
            what = ("the per-step API" if target == "per-step"
                    else f"the closed loop on the {target} plant")
            out.append(Job(name, target, f"{what} for {title}", _SECONDS[target] * scale))
    # longest first; the general variant's per-step API (which compiles the general fuzzy
    # evaluator, see precompile) at the front
    return sorted(out, key=lambda j: (not (j.law == "general" and j.target == "per-step"),
                                      -j.seconds))


def run_job(law: str, target: str) -> float:
    """Compile (or load) one job's kernels by running them briefly; return the seconds."""
    import numpy as np

    from ..paper.published import paper_params
    from ..registry import build_plant
    from ..sim import Step, simulate, simulate_batch, simulate_open_loop

    t0 = time.perf_counter()
    ctl, _title = controllers()[law]
    if target == "per-step":
        ctl.step(ctl.initial_state(), 0.01, 0.0)
        return time.perf_counter() - t0
    params = paper_params()
    plants = ("linear", "small-signal") if target == "linear" else ("nonlinear",)
    for name in plants:
        plant = build_plant(name, params)
        if law == "command":
            simulate_open_loop(plant, 0.1, duration=0.02)
            continue
        simulate(ctl, plant, Step(0.01), duration=0.02, delay=0.0015, noise_std=1e-6,
                 rng=np.random.default_rng(0))
        for keep in (False, True):  # three runs: a pair and one alone
            simulate_batch(ctl, plant=plant, reference=Step(0.01), duration=0.02,
                           delay=[0.0, 0.0015, 0.003], noise=np.zeros((3, 21)),
                           keep_traces=keep)
        simulate_batch(ctl, plant=[plant] * 3, reference=np.zeros((3, 21)), duration=0.02)
    return time.perf_counter() - t0


def _worker_init() -> None:
    os.environ["FUZZYSERVO_COMPILE_NOTICE"] = "0"  # precompile reports for its workers


def precompile(processes: int = 2,
               progress: Callable[[int, int, Job, float, float], None] | None = None
               ) -> list[tuple[Job, float]]:
    """Compile every closed-loop kernel into the package's cache.

    Parameters
    ----------
    processes : int
        1: every job in this process, one after the other; 2: in two processes at once.
    progress : callable, optional
        ``progress(done, total, job, seconds, elapsed)`` after each job.

    Returns
    -------
    list of (Job, float)
        Each job and the seconds it took [s], in the order they ended.

    Raises
    ------
    ParameterError
        ``processes`` is not 1 or 2.
    """
    if processes not in (1, 2):
        raise ParameterError(f"--processes must be 1 or 2, got {processes!r}")
    todo = jobs()
    done: list[tuple[Job, float]] = []
    t0 = time.perf_counter()

    def report(job: Job, secs: float) -> None:
        done.append((job, secs))
        if progress is not None:
            progress(len(done), len(todo), job, secs, time.perf_counter() - t0)

    if processes == 1:
        before = os.environ.get("FUZZYSERVO_COMPILE_NOTICE")
        os.environ["FUZZYSERVO_COMPILE_NOTICE"] = "0"  # precompile reports the jobs itself
        try:
            for job in todo:
                report(job, run_job(job.law, job.target))
        finally:
            if before is None:
                del os.environ["FUZZYSERVO_COMPILE_NOTICE"]
            else:
                os.environ["FUZZYSERVO_COMPILE_NOTICE"] = before
        return done
    # the general fuzzy evaluator is most of the compile of the general variant's kernels:
    # its per-step API compiles it first, then its loops and the other general laws' kernels
    # load it (not compile it twice)
    first = [j for j in todo if not (j.law.startswith("general")
                                     and (j.law, j.target) != ("general", "per-step"))]
    later = [j for j in todo if j not in first]
    with ProcessPoolExecutor(max_workers=processes, mp_context=get_context("spawn"),
                             initializer=_worker_init) as pool:
        futures = {pool.submit(run_job, j.law, j.target): j for j in first}
        pending = set(futures)
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in sorted(finished, key=lambda f: todo.index(futures[f])):
                job = futures[fut]
                report(job, fut.result())
                if job.law == "general" and job.target == "per-step":
                    for j in later:
                        f = pool.submit(run_job, j.law, j.target)
                        futures[f] = j
                        pending.add(f)
    return done


def register(subparsers: Any) -> None:
    """Add the ``precompile`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "precompile",
        help=HELP["precompile"],
        description=(
            "Compile every closed-loop kernel (each control law on both plants, single runs "
            "and batches, and the per-step API) into the package's cache, so that every "
            "process started afterwards (a sweep's workers, Dask workers, test workers) loads "
            "them in a fraction of a second. With the cache warm it returns in a few seconds."
        ),
    )
    parser.add_argument("--processes", type=int, default=2, metavar="N",
                        help="1 or 2 processes (default 2)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo precompile``."""
    from .._jit import cache_dir

    if args.processes not in (1, 2):
        raise ParameterError(f"--processes must be 1 or 2, got {args.processes!r}")
    todo = jobs()
    est = sum(j.seconds for j in todo) / args.processes
    print(f"precompile: {len(todo)} jobs in {args.processes} process(es) into {cache_dir()} "
          f"(once per install; about {est:.0f} s when the cache is empty, seconds when warm)",
          file=sys.stderr, flush=True)

    est_done = [0.0]

    def progress(n: int, total: int, job: Job, secs: float, elapsed: float) -> None:
        est_done[0] += job.seconds  # the rate so far, in estimated seconds per second
        left = elapsed * (sum(j.seconds for j in todo) - est_done[0]) / est_done[0]
        eta = f", about {left:.0f} s left" if n < total and elapsed > 5 else ""
        print(f"precompile: [{n}/{total}] {job.title} in {secs:.1f} s{eta}", file=sys.stderr,
              flush=True)

    t0 = time.perf_counter()
    precompile(args.processes, progress)
    print(f"precompile: done in {time.perf_counter() - t0:.0f} s ({cache_dir()})",
          file=sys.stderr)
    return 0
