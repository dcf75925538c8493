"""Run a sweep: chunks of points through the batched closed-loop kernels, locally or on a Dask
cluster, into the folder's Parquet dataset.

:func:`compute_chunk` is a pure function of the spec and the chunk index: the table of chunk
``c`` is the same computed alone, after a resume, with any number of numba threads, or on any
Dask worker. :func:`run_sweep` runs the chunks not yet written, writes each as it arrives
(:mod:`fuzzyservo.sweep.dataset`), and shows a progress bar of runs with rate and ETA.

Each run's ``outcome`` is :func:`fuzzyservo.analysis.outcome.classify` of the kernels' metrics
(the rule of the study's claims C6 and C8, with its thresholds), plus ``invalid`` for a point
without a valid plant (a drawn parameter out of its range, no equilibrium, a delay longer than
the run, a reference out of the stroke; ``error`` says why).

One difference from :func:`fuzzyservo.study.claims.response_outcome`: the step a limit cycle
is measured against is the reference's move (r at the end minus the start position), not r at
the end minus the first measured sample; they differ by the first sample's noise and
transducer rounding.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._io import confined, refuse_links, sha256_file
from .._typing import FloatArray
from ..analysis.outcome import TAIL_FRACTION, classify
from ..errors import FuzzyServoError, InputError, OutputError, ParameterError
from ..plant import with_overrides
from ..registry import build_plant
from ..sim import simulate_batch
from ..sim.closed_loop import check_delay, plant_limits, time_grid
from ..sim.disturbances import LoadStep, load_force_samples, parse_load_force
from ..sim.references import Step, check_reference, check_reference_samples, parse_reference
from ..sim.stepinfo import METRIC_NAMES
from .dataset import (
    FOLDER_ENTRIES,
    Manifest,
    adopt,
    chunk_path,
    finished_files,
    read_manifest,
    write_chunk,
)
from .sampling import Points, points
from .spec import UNRECORDED_SCHEME, SweepSpec, canonical_digest

__all__ = [
    "TAIL_COLUMNS",
    "PointRuns",
    "build_controllers",
    "columns",
    "compute_chunk",
    "run_sweep",
]

#: Tail-oscillation columns (``fuzzyservo.sim.stepinfo.TAIL_NAMES``).
TAIL_COLUMNS: tuple[str, ...] = ("tail_peak_to_peak", "tail_swings", "tail_period",
                                 "tail_sustain")


def columns(spec: SweepSpec) -> list[str]:
    """Column names of the sweep's table, in order."""
    return ["point", "cell", "sample", "controller", *[v.name for v in spec.vary],
            "noise_seed", *METRIC_NAMES, *TAIL_COLUMNS, "diverged", "outcome", "robust",
            "error"]


def build_controllers(spec: SweepSpec) -> list[Any]:
    """The spec's controllers, built once (they are shipped to Dask workers as they are)."""
    return [c.build(spec.ts) for c in spec.controllers]


class PointRuns:
    """The plants, delays, references and noise of some points of a sweep (what every
    controller runs on): ``plants[j]`` (None for an invalid point, ``error[j]`` says why),
    ``valid`` (bool per point), ``delay`` [s], ``roff`` (per-point reference offsets [m], or
    None when all share ``ref``), ``noise`` (rows for the valid points [m], or None), ``step``
    (the reference's move per point [m])."""

    def __init__(self, spec: SweepSpec, pts: Points, t: FloatArray) -> None:
        m = len(pts)
        self.error: list[str | None] = [None] * m
        self.plants: list[Any] = [None] * m
        nominal = spec.nominal
        param_names = [v.name for v in spec.vary if "." in v.name]
        ref = parse_reference(spec.reference)
        amp = pts.values.get("amplitude")
        delay = pts.values.get("delay", np.full(m, spec.delay))
        self.delay = np.asarray(delay, dtype=np.float64)
        self.noise_std = np.asarray(pts.values.get("noise_std", np.full(m, spec.noise_std)))
        cache: dict[tuple[float, ...], Any] = {}
        base_force: dict[tuple[float, ...], float] = {}
        checked_refs: dict[float, Any] = {}
        # the check of the sampled reference against the plant depends on these only: done
        # once per distinct (start, stroke, resolution, amplitude), not per point (on 20 s
        # runs it was a fifth of the set-up)
        checked: dict[tuple[float, float | None, float, float | None], Exception | None] = {}
        self.roff: FloatArray | None = None
        if amp is not None:
            assert isinstance(ref, Step)
            self.roff = np.empty((m, t.size))
        base_roff = None
        for j in range(m):
            key = tuple(float(pts.values[nm][j]) for nm in param_names)
            if key not in cache:
                try:
                    params = with_overrides(nominal, dict(zip(param_names, key, strict=True))) \
                        if param_names else nominal
                    cache[key] = build_plant(spec.plant, params,
                                             spec.start * params.cylinder.stroke,
                                             substep=spec.substep)
                    base_force[key] = float(params.load.external_force)
                except FuzzyServoError as exc:
                    cache[key] = exc
            plant = cache[key]
            try:
                if isinstance(plant, FuzzyServoError):
                    raise plant
                check_delay(float(self.delay[j]), duration=spec.duration)
                if amp is not None:
                    a = float(amp[j])
                    if a not in checked_refs:
                        assert isinstance(ref, Step)
                        r_j = Step(a, ref.time)
                        check_reference(r_j, ts=spec.ts, duration=spec.duration)
                        from ..sim.references import sample_reference

                        checked_refs[a] = sample_reference(r_j, t)
                    roff = checked_refs[a]
                    assert self.roff is not None
                    self.roff[j] = roff
                else:
                    if base_roff is None:
                        from ..sim.references import sample_reference

                        check_reference(ref, ts=spec.ts, duration=spec.duration)
                        base_roff = sample_reference(ref, t)
                    roff = base_roff
                stroke, resolution = plant_limits(plant)
                ck = (float(plant.y0), stroke, resolution,
                      float(amp[j]) if amp is not None else None)
                if ck not in checked:
                    try:
                        check_reference_samples(plant.y0 + roff, t, start=plant.y0,
                                                stroke=stroke, resolution=resolution)
                        checked[ck] = None
                    except FuzzyServoError as exc:
                        checked[ck] = exc
                failed = checked[ck]
                if failed is not None:
                    raise failed.with_traceback(None)  # not a growing traceback
                self.plants[j] = plant
            except FuzzyServoError as exc:
                self.error[j] = " ".join(str(exc).split())
        self.ref = ref
        self.valid = np.array([e is None for e in self.error], dtype=bool)
        n = t.size
        noisy = self.valid & (self.noise_std > 0.0)
        self.noise: FloatArray | None = None
        if np.any(noisy):
            idx = np.flatnonzero(self.valid)
            self.noise = np.zeros((idx.size, n))
            for row, pj in enumerate(idx.tolist()):
                if noisy[pj]:
                    rng = np.random.default_rng(int(pts.noise_seed[pj]))
                    self.noise[row] = rng.normal(0.0, float(self.noise_std[pj]), size=(n,))
        # the total external force per valid point [N]: its set's load.external_force plus
        # the load force (its step's F varied by load_force_step)
        self.force: FloatArray | None = None
        load = parse_load_force(spec.load_force)
        if load is not None and np.any(self.valid):
            f_step = pts.values.get("load_force_step")
            idx = np.flatnonzero(self.valid)
            self.force = np.empty((idx.size, n))
            for row, pj in enumerate(idx.tolist()):
                key = tuple(float(pts.values[nm][pj]) for nm in param_names)
                prof = load if f_step is None else \
                    LoadStep(float(f_step[pj]), spec.load_step.time)  # type: ignore[union-attr]
                self.force[row] = load_force_samples(prof, t, base_force[key])
        # the move the limit-cycle test measures against [m]
        if amp is not None:
            self.step = np.asarray(amp, dtype=np.float64).copy()
        else:
            self.step = np.full(m, float(base_roff[-1]) if base_roff is not None else math.nan)


def compute_chunk(spec: SweepSpec, c: int, controllers: Sequence[Any] | None = None,
                  threads: int | None = None) -> Any:
    """The rows of chunk ``c`` as a ``pyarrow.Table`` (columns :func:`columns`), sorted by
    (point, controller order of the spec).

    ``controllers`` are the spec's, built (default: built here); ``threads`` sets numba's
    threads for the batch kernels (None: as they are).
    """
    import pyarrow as pa

    if threads is not None:
        import numba

        most = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
        numba.set_num_threads(max(1, min(int(threads), most)))
    ctls = list(controllers) if controllers is not None else build_controllers(spec)
    lo, hi = spec.chunk_range(c)
    pts = points(spec, lo, hi)
    t = time_grid(spec.duration, spec.ts)
    runs = PointRuns(spec, pts, t)
    m = len(pts)
    idx = np.flatnonzero(runs.valid)
    n_ctl = len(ctls)
    n_rows = m * n_ctl
    metric_cols = {name: np.full(n_rows, np.nan) for name in (*METRIC_NAMES, *TAIL_COLUMNS)}
    diverged = np.zeros(n_rows, dtype=bool)
    for k, ctl in enumerate(ctls):
        if idx.size == 0:
            break
        reference: Any = runs.ref if runs.roff is None else runs.roff[idx]
        res = simulate_batch(ctl, None, plant=[runs.plants[j] for j in idx], reference=reference,
                             duration=spec.duration, delay=runs.delay[idx], noise=runs.noise,
                             disturbance=runs.force, tail_fraction=TAIL_FRACTION)
        rows = idx * n_ctl + k
        for i, name in enumerate(res.metric_names):
            metric_cols[name][rows] = res.metrics[:, i]
        for i, name in enumerate(res.tail_names):
            metric_cols[name][rows] = res.tail[:, i]
        diverged[rows] = res.diverged
    rep = np.repeat
    invalid = rep(~runs.valid, n_ctl)
    outcome = classify(metric_cols, rep(runs.step, n_ctl), diverged, invalid)
    data: dict[str, Any] = {
        "point": pa.array(rep(pts.index, n_ctl)),
        "cell": pa.array(rep(pts.cell, n_ctl)),
        "sample": pa.array(rep(pts.sample, n_ctl)),
        "controller": pa.array([e.label for e in spec.controllers] * m).dictionary_encode(),
    }
    for name, vals in pts.values.items():
        data[name] = pa.array(rep(vals, n_ctl))
    data["noise_seed"] = pa.array(rep(pts.noise_seed, n_ctl))
    for name, vals in metric_cols.items():
        data[name] = pa.array(vals)
    data["diverged"] = pa.array(diverged)
    data["outcome"] = pa.array(outcome.tolist(), type=pa.string()).dictionary_encode()
    data["robust"] = pa.array(outcome == "settles")
    data["error"] = pa.array([e for e in runs.error for _ in range(n_ctl)], type=pa.string())
    return pa.table(data)


# ---- orchestration ----------------------------------------------------------------------------

def _check_folder(spec: SweepSpec, out: Path, resume: bool) -> Manifest | None:
    """Refuse a folder the sweep must not write (read-only); its manifest when resuming."""
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {str(out)!r} is a file; give a folder for the sweep")
    if os.path.lexists(out / "manifest.json"):
        man = read_manifest(out)  # checks the folder's own files: no link, chunks a folder
        if not resume:
            raise OutputError(f"{str(out)!r} already holds a sweep ({len(man.chunks)} of "
                              f"{man.n_chunks} chunks): add --resume to continue it, or give "
                              f"a new folder")
        scheme = man.spec.get("sampling", UNRECORDED_SCHEME)
        if scheme != spec.sampling_scheme:
            raise InputError(f"{str(out)!r} holds a sweep drawn by sampling scheme "
                             f"{scheme!r:.20}; this fuzzyservo draws scheme "
                             f"{spec.sampling_scheme}, so --resume "
                             f"would mix two draws: give a new folder")
        try:
            recorded = canonical_digest(man.spec)
        except (TypeError, ValueError):
            recorded = ""
        if recorded != man.digest:
            raise InputError(f"sweep manifest {str(out / 'manifest.json')!r} is corrupted: "
                             f"its digest is not that of the spec it records; give another "
                             f"folder, or start the sweep afresh in a new one")
        canon = spec.canonical()
        if "sampling" not in man.spec:  # written before the scheme was recorded
            del canon["sampling"]
        if man.digest != canonical_digest(canon):
            diff = sorted(k for k in set(man.spec) | set(canon)
                          if man.spec.get(k) != canon.get(k))
            raise InputError(f"{str(out)!r} holds a different sweep (its spec differs in "
                             f"{', '.join(diff) or 'its files'}); --resume continues only the "
                             f"same spec: give a new folder")
        if (man.n_points, man.n_chunks, man.n_runs) != (spec.n_points, spec.n_chunks,
                                                        spec.n_runs):
            raise InputError(f"sweep manifest {str(out / 'manifest.json')!r} is corrupted: "
                             f"it counts {man.n_points} points, {man.n_chunks} chunks and "
                             f"{man.n_runs} runs, its spec {spec.n_points}, {spec.n_chunks} "
                             f"and {spec.n_runs}; give another folder")
        for c, entry in man.chunks.items():
            lo, hi = spec.chunk_range(int(c))
            if entry["rows"] != (hi - lo) * len(spec.controllers):
                raise InputError(f"sweep manifest {str(out / 'manifest.json')!r} is "
                                 f"corrupted: chunk {c} has {entry['rows']} rows, the spec "
                                 f"gives it {(hi - lo) * len(spec.controllers)}; give "
                                 f"another folder")
        return man
    if out.is_dir() and any(out.iterdir()):
        raise OutputError(f"--out {str(out)!r} is a folder that is not empty and holds no "
                          f"sweep; give a new or empty folder")
    if resume:
        raise InputError(f"--resume: {str(out)!r} holds no sweep to resume")
    return None


def _reopen(spec: SweepSpec, out: Path, man: Manifest) -> Manifest:
    """Check and reopen a sweep's folder for a resume; called with its lock held (what it
    removes could otherwise be another sweep's temporary files)."""
    for tmp in (out / "chunks").glob(".chunk-*.tmp"):  # left by a kill mid-write
        tmp.unlink(missing_ok=True)
    changed = False
    for c in sorted(man.done):  # a listed chunk must be there, as it was written
        path = chunk_path(out, c)
        if not path.is_file() or sha256_file(path) != man.chunks[str(c)]["sha256"]:
            del man.chunks[str(c)]
            path.unlink(missing_ok=True)
            changed = True
    adopted = False
    for c, _path in finished_files(out).items():
        if str(c) not in man.chunks and c < man.n_chunks:
            lo, hi = spec.chunk_range(c)
            adopted |= adopt(out, man, c, (hi - lo) * len(spec.controllers))
    if adopted or changed:
        man.write(out)
    return man


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process
        return True
    return True


def _create_folder(out: Path, man: Manifest, spec_text: str | None) -> int:
    """Create a new sweep's folder as one step: ``chunks/``, ``spec.toml``, the manifest and
    ``.lock`` are written into a hidden sibling, ``.NAME.new-PID``, renamed onto ``out``
    (absent, or an empty folder) at the end, and the lock is taken before the rename, so the
    folder is never seen unlocked while this sweep runs. Returns the lock's descriptor. An
    interruption before the rename leaves ``out`` as it was (a rerun of the same command
    starts afresh, a reproduce finds no half-made sweep); siblings left by killed sweeps are
    removed here."""
    import shutil

    from .._io import fsync_folder, write_text_atomic

    parent = out.absolute().parent
    prefix = f".{out.name}.new-"
    try:
        parent.mkdir(parents=True, exist_ok=True)
        for old in parent.glob(prefix + "*"):
            pid = old.name[len(prefix):]
            if pid.isdigit() and not _pid_alive(int(pid)):
                shutil.rmtree(old, ignore_errors=True)
    except OSError as exc:
        raise OutputError(f"cannot create {str(out)!r}: {exc.strerror or exc}") from None
    tmp = parent / f"{prefix}{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    lock = -1
    try:
        (tmp / "chunks").mkdir(parents=True)
        lock = _lock(tmp, out)
        if spec_text is not None:
            write_text_atomic(tmp / "spec.toml", spec_text)
        man.write(tmp)
        os.replace(tmp, out)  # onto an absent or empty folder: atomic
        fsync_folder(parent)  # and durable, as the chunks' renames are
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if lock >= 0:
            os.close(lock)
        raise OutputError(f"cannot create {str(out)!r}: {exc.strerror or exc}") from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        if lock >= 0:
            os.close(lock)
        raise
    return lock


@contextlib.contextmanager
def _progress(total: int, done: int, enabled: bool | None) -> Iterator[Callable[[int], None]]:
    show = sys.stderr.isatty() if enabled is None else enabled
    if not show:
        yield lambda k: None
        return
    from tqdm import tqdm

    bar = tqdm(total=total, initial=done, unit=" runs", unit_scale=True, desc="sweep",
               file=sys.stderr, smoothing=0.1)
    try:
        yield bar.update
    except BaseException:
        bar.leave = False
        raise
    finally:
        bar.close()


def _cores() -> int:
    """Cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def _chunk_task(spec: SweepSpec, c: int, controllers: Sequence[Any]) -> tuple[int, Any]:
    """A Dask task: chunk ``c`` on one numba thread (the worker is the unit of parallelism)."""
    return c, compute_chunk(spec, c, controllers, threads=1)


def _worker_init(parent: int) -> None:
    """A local worker process: Ctrl-C is the parent's to handle (it stops the pool), the batch
    kernels run on one thread (the process is the unit of parallelism), and the process ends
    when its parent does (Linux: ``PR_SET_PDEATHSIG``), so ``kill -9`` of a sweep leaves no
    worker computing a chunk nobody will write."""
    import signal

    import numba

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    numba.set_num_threads(1)
    if sys.platform.startswith("linux"):  # die with the parent, even after its SIGKILL
        import ctypes

        pr_set_pdeathsig = 1
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL))
    if os.getppid() != parent:  # the parent died before the line above: nobody to serve
        os._exit(1)


def _local_chunks(spec: SweepSpec, todo: list[int], controllers: Sequence[Any],
                  processes: int) -> Iterator[tuple[int, Any]]:
    """Chunks on a pool of local processes, at most two per process queued at a time."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait

    ctx = multiprocessing.get_context("spawn")  # numba's threads and fork do not mix
    pool = ProcessPoolExecutor(max_workers=processes, mp_context=ctx,
                               initializer=_worker_init, initargs=(os.getpid(),))
    pending = list(todo)
    running: set[Future[tuple[int, Any]]] = set()
    try:
        while pending or running:
            while pending and len(running) < 2 * processes:
                running.add(pool.submit(_chunk_task, spec, pending.pop(0), controllers))
            finished, running = wait(running, return_when=FIRST_COMPLETED)
            for fut in sorted(finished, key=lambda f: f.result()[0]):
                yield fut.result()
    finally:
        for fut in running:
            fut.cancel()
        procs = list(getattr(pool, "_processes", {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:  # a chunk in flight is lost by design; do not wait for it
            if proc.is_alive():
                proc.terminate()
        for proc in procs:
            proc.join(timeout=5)


#: How long a scheduler has to connect and answer Dask's handshake [s]: ``Client``'s own
#: timeout covers the connection, not a peer that accepts it and then says nothing.
SCHEDULER_TIMEOUT = 20.0


def _connect(dd: Any, scheduler: str) -> Any:
    """A ``distributed.Client`` of the scheduler at ``scheduler``, made in a daemon thread
    waited on for :data:`SCHEDULER_TIMEOUT`. A peer that speaks another protocol (an SSH or
    HTTP server) makes Dask read its bytes as a frame length and fail with MemoryError, or
    wait for ever: both are named as "no Dask scheduler answered"."""
    import threading

    box: dict[str, Any] = {}

    def connect() -> None:
        try:
            box["client"] = dd.Client(scheduler, timeout="10s")
        except BaseException as exc:  # noqa: BLE001 - handed to the caller below
            box["error"] = exc

    worker = threading.Thread(target=connect, name="fuzzyservo-dask-connect", daemon=True)
    worker.start()
    worker.join(SCHEDULER_TIMEOUT)
    exc = box.get("error")
    if worker.is_alive() or isinstance(exc, MemoryError):
        raise InputError(f"--scheduler {scheduler!r}: no Dask scheduler answered at that "
                         f"address (" + ("something accepted the connection and spoke "
                                         "another protocol" if exc is not None else
                                         f"no Dask handshake within {SCHEDULER_TIMEOUT:g} s")
                         + "); give the address of a dask scheduler, e.g. tcp://host:8786")
    if isinstance(exc, OSError | TimeoutError | ValueError):
        why = " ".join(str(exc).split())
        raise InputError(f"--scheduler {scheduler!r}: cannot connect ({why})") from None
    if exc is not None:
        raise exc
    return box["client"]


def _dask_client(workers: int | None, scheduler: str | None) -> tuple[Any, Any]:
    """(client, local cluster or None): connected before the folder is touched, so a bad
    address leaves nothing behind."""
    try:
        import distributed
    except ImportError:
        raise InputError("--workers and --scheduler run on dask.distributed, which is not "
                         "installed: pip install 'fuzzyservo[distributed]'") from None
    dd: Any = distributed  # untyped library: calls through Any
    if scheduler is not None:
        return _connect(dd, scheduler), None
    cluster = dd.LocalCluster(n_workers=int(workers or 1), threads_per_worker=1,
                              processes=True, host="127.0.0.1", dashboard_address=None,
                              silence_logs=40)
    return dd.Client(cluster), cluster


def _dask_chunks(spec: SweepSpec, todo: list[int], controllers: Sequence[Any],
                 client: Any, workers: int | None) -> Iterator[tuple[int, Any]]:
    """Chunks as Dask tasks, at most two per worker queued at a time."""
    import distributed

    dd: Any = distributed
    n_workers = max(1, len(client.scheduler_info().get("workers", {})) or int(workers or 1))
    ctl_future = client.scatter(list(controllers), broadcast=True)
    spec_future = client.scatter(spec, broadcast=True)
    pending = list(todo)
    ac = dd.as_completed()
    for _ in range(min(2 * n_workers, len(pending))):
        ac.add(client.submit(_chunk_task, spec_future, pending.pop(0), ctl_future, pure=False))
    for fut in ac:
        c, table = fut.result()
        fut.release()
        if pending:
            ac.add(client.submit(_chunk_task, spec_future, pending.pop(0), ctl_future,
                                 pure=False))
        yield c, table


def run_sweep(spec: SweepSpec, out: str | Path, *, resume: bool = False,
              workers: int | None = None, scheduler: str | None = None,
              processes: int | None = None, progress: bool | None = None,
              spec_text: str | None = None,
              on_chunk: Callable[[int], None] | None = None,
              on_start: Callable[[Manifest, int], None] | None = None) -> Manifest:
    """Run the chunks of ``spec`` not yet in ``out`` and return the manifest.

    Parameters
    ----------
    spec : SweepSpec
        The sweep.
    out : path
        Its folder: new or empty, or (``resume``) one holding the same sweep.
    resume : bool
        Continue a sweep: skip its finished chunks.
    processes : int, optional
        Without Dask: local worker processes, each running whole chunks on one thread
        (default: one per core; 1: in this process, the batch kernels on every numba
        thread). Processes also spread the plants' set-up (linearisation, trim), which is
        Python, over the cores.
    workers : int, optional
        Run on a local Dask cluster of this many single-threaded worker processes
        (127.0.0.1 only).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``) to run the chunks on.
    progress : bool, optional
        Show a progress bar on standard error (default: when it is a terminal).
    spec_text : str, optional
        The spec file's text, kept as ``spec.toml`` in a new folder.
    on_chunk : callable, optional
        Called with each chunk index once it is written (tests use it to interrupt).
    on_start : callable, optional
        Called with the manifest and the number of chunks to run, once the folder is ready.

    Raises
    ------
    OutputError
        ``out`` holds something else, or cannot be written.
    InputError
        A resume of a different sweep, or no sweep to resume.
    """
    if workers is not None and scheduler is not None:
        raise ParameterError("give --workers N (a local Dask cluster) or --scheduler ADDRESS, "
                             "not both")
    if workers is not None and not (isinstance(workers, int) and 1 <= workers <= 1024):
        raise ParameterError(f"--workers must be an integer in [1, 1024], got {workers!r}")
    if processes is not None and not (isinstance(processes, int) and 1 <= processes <= 1024):
        raise ParameterError(f"--processes must be an integer in [1, 1024], got "
                             f"{processes!r}")
    if processes is not None and (workers is not None or scheduler is not None):
        raise ParameterError("--processes runs the chunks without Dask; drop it with "
                             "--workers or --scheduler")
    out = Path(out)
    _check_folder(spec, out, resume)  # before a cluster starts or a scheduler is reached
    client = cluster = None
    if workers is not None or scheduler is not None:
        client, cluster = _dask_client(workers, scheduler)
    try:
        return _run(spec, out, resume, spec_text, processes, workers, client, progress,
                    on_chunk, on_start)
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()


def _lock(folder: Path, shown: Path) -> int:
    """Open ``folder/.lock`` (never through a link) and take it; its descriptor.

    Raises
    ------
    OutputError
        Another sweep holds it, or it is a link.
    """
    import fcntl

    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
    try:
        fd = os.open(folder / ".lock", flags, 0o666)
    except OSError as exc:
        why = ("it is a symbolic link; fuzzyservo never writes through a link in its output "
               "folders: remove it" if os.path.islink(folder / ".lock")
               else exc.strerror or str(exc))
        raise OutputError(f"cannot lock {str(shown / '.lock')!r}: {why}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise OutputError(f"another fuzzyservo sweep is writing {str(shown)!r}; wait for it "
                          f"to finish or give another --out") from None
    except BaseException:
        os.close(fd)
        raise
    return fd


def _run(spec: SweepSpec, out: Path, resume: bool, spec_text: str | None,
         processes: int | None, workers: int | None, client: Any, progress: bool | None,
         on_chunk: Callable[[int], None] | None,
         on_start: Callable[[Manifest, int], None] | None) -> Manifest:
    """Take the folder's lock before anything in it is touched (a new folder is locked
    before it appears), check it again under the lock (another sweep may have changed it
    since the check without it), then run."""
    if os.path.lexists(out / "manifest.json"):
        refuse_links(out, what="sweep folder", entries=FOLDER_ENTRIES)  # .lock among them
        lock = _lock(out, out)
        try:
            man = _check_folder(spec, out, resume)
            assert man is not None  # a folder with a manifest is a sweep, or is refused
            with confined(out):
                man = _reopen(spec, out, man)
        except BaseException:
            os.close(lock)
            raise
    else:
        _check_folder(spec, out, resume)  # a folder that is not empty, --resume of nothing
        man = Manifest.new(spec.digest, spec.canonical(), spec.n_points, spec.n_chunks,
                           spec.n_runs, columns(spec))
        lock = _create_folder(out, man, spec_text)
    try:
        with confined(out):
            return _run_locked(spec, out, man, processes, workers, client, progress,
                               on_chunk, on_start)
    finally:
        os.close(lock)  # releases the lock


def _run_locked(spec: SweepSpec, out: Path, man: Manifest, processes: int | None,
                workers: int | None, client: Any, progress: bool | None,
                on_chunk: Callable[[int], None] | None,
                on_start: Callable[[Manifest, int], None] | None) -> Manifest:
    todo = [c for c in range(spec.n_chunks) if c not in man.done]
    if on_start is not None:
        on_start(man, len(todo))
    controllers = build_controllers(spec)
    n_ctl = len(spec.controllers)
    done_runs = sum(int(v["rows"]) for v in man.chunks.values())
    with _progress(spec.n_runs, done_runs, progress) as tick:
        procs = min(processes or _cores(), len(todo))
        if client is None and procs <= 1:
            chunks: Iterator[tuple[int, Any]] = (
                (c, compute_chunk(spec, c, controllers)) for c in todo)
        elif client is None:
            chunks = _local_chunks(spec, todo, controllers, procs)
        else:
            chunks = _dask_chunks(spec, todo, controllers, client, workers)
        last = 0.0
        try:
            for c, table in chunks:
                man.chunks[str(c)] = write_chunk(out, c, table)
                # the manifest at most every 2 s (rewriting it after each of 10^5 chunks is
                # quadratic): a chunk written but not yet listed is adopted on resume
                if time.monotonic() - last >= 2.0 or len(man.chunks) == man.n_chunks:
                    man.write(out)
                    last = time.monotonic()
                lo, hi = spec.chunk_range(c)
                tick((hi - lo) * n_ctl)
                if on_chunk is not None:
                    on_chunk(c)
        finally:
            if len(man.chunks) != man.n_chunks:
                man.write(out)  # what is finished, listed (an interruption included)
    return man
