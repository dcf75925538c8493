"""Speed and memory of robustness sweeps (``fuzzyservo sweep``), all figures from one run.

1. 10^5 runs of 5 s at 1 kHz, linear plant, self-tuning fuzzy PI, metrics only, each run its
   own plant (claim C8's spread: load mass and oil bulk modulus x0.5-2, supply pressure
   ±10 %, hose delay 0-50 ms, sensor noise 1-20 µm): wall time, runs/s and controller steps/s,
   on the default executor (one local worker process per core). Target (issue 13): <= 60 s.
2. 10^4 runs of the same on the nonlinear plant (RK4, 0.5 ms steps). Target: <= 60 s.
3. Executors on one CPU-bound sweep (10^4 linear runs of 20 s, the C8 sweep's length, about
   20 s of work per core): in this process on numba's threads, local processes, Dask
   LocalCluster with 1 and 2 single-threaded workers, started by the command (``--workers``)
   or already running (``--scheduler``, the cluster started and warmed outside the timing,
   as a user's cluster is). Target: 2 Dask workers >= 1.7 x 1 worker. A ``--workers`` time
   includes the command's start, the cluster's start and its workers' imports (about 3 s,
   the same for 1 and 2 workers); every time includes the sweep's own process (the Dask
   client, writing the chunks) and the scheduler, which share the two cores with the workers
   (about 1.7 s and 0.9 s of CPU for 40 chunks): on two cores 2 workers cannot reach 2 x.
4. Memory: peak resident memory of the sweep's process tree (and of its largest process)
   for 10^4, 10^5 and 10^6 runs of a light sweep (0.5 s runs, PID, noise and amplitude
   drawn per run), run as a command in a child: it must not grow with the number of runs.

Every sweep runs as ``fuzzyservo sweep`` in a child process (start-up and numba's cache
loading included, as a user sees it). Run: ``python benchmarks/sweep.py`` (``make bench``);
``--quick`` divides the sizes by 10.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

C8 = """
[[vary]]
name = "load.mass"
relative = true
distribution = "log-uniform"
low = 0.5
high = 2.0

[[vary]]
name = "fluid.oil_bulk_modulus"
relative = true
distribution = "log-uniform"
low = 0.5
high = 2.0

[[vary]]
name = "supply.pressure"
relative = true
distribution = "uniform"
low = 0.9
high = 1.1

[[vary]]
name = "delay"
distribution = "uniform"
low = 0.0
high = 0.05

[[vary]]
name = "noise_std"
distribution = "log-uniform"
low = 1.0e-6
high = 2.0e-5
"""

LIGHT = """
[[vary]]
name = "noise_std"
distribution = "log-uniform"
low = 1.0e-6
high = 2.0e-5

[[vary]]
name = "amplitude"
distribution = "uniform"
low = 0.05
high = 0.15
"""


def _spec(plant: str, n: int, *, duration: float = 5.0, chunk: int = 1000,
          light: bool = False) -> str:
    ctl = ('controller = "pid"\ngains = { kp = 20.0, ki = 2.0, kd = 0.1 }' if light
           else f'gains = "{plant}-stfpi.toml"')
    return (f'[sweep]\nplant = "{plant}"\nduration = {duration}\nsamples = {n}\nseed = 1\n'
            f'chunk = {chunk}\n\n[[controllers]]\n{ctl}\n' + (LIGHT if light else C8))


def _tree_rss(pid: int) -> tuple[int, int]:
    """(sum, max) resident memory [bytes] of ``pid`` and its descendants."""
    kids: dict[int, list[int]] = {}
    rss: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", encoding="ascii") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            ppid = int(fields[1])
            with open(f"/proc/{entry}/statm", encoding="ascii") as fh:
                rss[int(entry)] = int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
        except (OSError, IndexError, ValueError):
            continue
        kids.setdefault(ppid, []).append(int(entry))
    todo, total, most = [pid], 0, 0
    while todo:
        p = todo.pop()
        total += rss.get(p, 0)
        most = max(most, rss.get(p, 0))
        todo.extend(kids.get(p, []))
    return total, most


def _run(spec_text: str, extra: list[str], folder: Path,
         memory: bool = False) -> tuple[float, int, int]:
    """Run ``fuzzyservo sweep`` in a child: (wall time [s], peak tree RSS, peak process RSS).

    The memory is sampled (every 50 ms, by reading /proc) only when ``memory`` is set: the
    sampling takes CPU from the sweep, and the timed runs are timed without it."""
    spec = folder / "spec.toml"
    spec.write_text(spec_text, encoding="utf-8")
    out = folder / "out"
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "fuzzyservo", "sweep", str(spec), "--out",
                             str(out), "--no-progress", *extra],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    peak = [0, 0]

    def sample() -> None:
        while proc.poll() is None:
            total, most = _tree_rss(proc.pid)
            peak[0], peak[1] = max(peak[0], total), max(peak[1], most)
            time.sleep(0.05)

    th = threading.Thread(target=sample, daemon=True)
    if memory:
        th.start()
    _, err = proc.communicate()
    wall = time.perf_counter() - t0
    if memory:
        th.join()
    if proc.returncode != 0:
        raise SystemExit(f"sweep failed ({proc.returncode}): {err.strip()[-500:]}")
    return wall, peak[0], peak[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="sizes / 10")
    parser.add_argument("--skip-memory", action="store_true", help="skip item 4")
    args = parser.parse_args()
    q = 10 if args.quick else 1
    rows: list[tuple[str, str, str]] = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)

        def run(name: str, text: str, extra: list[str],
                memory: bool = False) -> tuple[float, int, int]:
            folder = root / name
            folder.mkdir()
            return _run(text, extra, folder, memory)

        run("warm", _spec("linear", 200, duration=1.0, chunk=100), [])  # numba's cache
        n = 100_000 // q
        wall, _, _ = run("linear", _spec("linear", n), [])
        rows.append((f"{n:,} linear stfpi runs of 5 s (C8 spread), local processes",
                     f"{wall:.1f} s = {n / wall:,.0f} runs/s = {n * 5001 / wall / 1e6:.1f} M "
                     "steps/s", "<= 60 s" if q == 1 else ""))
        n = 10_000 // q
        wall, _, _ = run("nonlinear", _spec("nonlinear", n, chunk=250), [])
        rows.append((f"{n:,} nonlinear stfpi runs of 5 s (C8 spread), local processes",
                     f"{wall:.1f} s = {n / wall:,.0f} runs/s = {n * 5001 / wall / 1e6:.2f} M "
                     "samples/s", "<= 60 s" if q == 1 else ""))
        n = 10_000 // q
        text = _spec("linear", n, duration=20.0, chunk=250)
        times = {}
        for label, extra in (("in one process, numba threads", ["--processes", "1"]),
                             ("local processes (default)", []),
                             ("Dask LocalCluster, 1 worker", ["--workers", "1"]),
                             ("Dask LocalCluster, 2 workers", ["--workers", "2"])):
            wall, _, _ = run(label.replace(" ", "_").replace(",", ""), text, extra)
            times[label] = wall
            rows.append((f"{n:,} linear stfpi runs of 20 s: {label}", f"{wall:.1f} s", ""))
        ratio = times["Dask LocalCluster, 1 worker"] / times["Dask LocalCluster, 2 workers"]
        rows.append(("Dask 2 workers / 1 worker speed-up (cluster started by the command)",
                     f"{ratio:.2f} x", ">= 1.7 x"))
        # a cluster that is already up, as a user's is: --scheduler ADDRESS
        import distributed

        warm = _spec("linear", 40, duration=1.0, chunk=20)
        on: dict[int, float] = {}
        for n_workers in (1, 2):
            with distributed.LocalCluster(n_workers=n_workers, threads_per_worker=1,
                                          processes=True, host="127.0.0.1",
                                          dashboard_address=None, silence_logs=40) as cl:
                addr = ["--scheduler", cl.scheduler_address]
                run(f"warm-{n_workers}", warm, addr)  # the workers' imports and numba cache
                on[n_workers], _, _ = run(f"running-{n_workers}", text, addr)
            rows.append((f"{n:,} linear stfpi runs of 20 s: Dask cluster running, "
                         f"{n_workers} worker{'s' if n_workers > 1 else ''} (--scheduler)",
                         f"{on[n_workers]:.1f} s", ""))
        rows.append(("Dask 2 workers / 1 worker speed-up (cluster running)",
                     f"{on[1] / on[2]:.2f} x", ">= 1.7 x"))
        rows.append(("local processes / numba threads speed-up",
                     f"{times['in one process, numba threads'] / times['local processes (default)']:.2f} x",  # noqa: E501
                     ""))
        if not args.skip_memory:
            for n in (10_000 // q, 100_000 // q, 1_000_000 // q):
                wall, total, most = run(f"mem{n}", _spec("linear", n, duration=0.5,
                                                         light=True), [], memory=True)
                rows.append((f"peak memory, {n:,} light runs ({wall:.0f} s)",
                             f"{total / 2**20:,.0f} MB in all, {most / 2**20:,.0f} MB largest "
                             "process", "flat in the runs"))
    width = max(len(r[0]) for r in rows) + 2
    print(f"{'sweeps (benchmarks/sweep.py)':<{width}}{'measured':>46}  target")
    for name, value, target in rows:
        print(f"{name:<{width}}{value:>46}  {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
