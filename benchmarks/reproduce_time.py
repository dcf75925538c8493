"""Wall time of ``fuzzyservo reproduce`` after set-up, for this checkout and others.

"After set-up" is the README's budget: the compiled kernels are in their cache (a warm-up run
into a throwaway folder compiles whatever a checkout needs), the output folder is new (no
result cache: every simulation, figure and report is made). Each checkout's runs alternate
with the others' (this machine's speed drifts by tens of percent over minutes), and the
medians and their ratio to the first checkout are printed; ``--warm`` also times a second run
into the same folder (the cached results and kept figures).

    python benchmarks/reproduce_time.py                           # this checkout, 3 runs
    python benchmarks/reproduce_time.py --tree /tmp/base --runs 3  # before (first) and after

Each checkout runs with its own ``src`` on ``PYTHONPATH`` and this interpreter (the
dependencies are the same).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(tree: Path, out: Path) -> float:
    env = dict(os.environ, PYTHONPATH=str(tree / "src"))
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "fuzzyservo", "reproduce", "--out", str(out),
                    "--quiet"], env=env, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", type=Path, action="append", default=[],
                    help="another checkout to time first (repeatable), e.g. the previous "
                         "commit's clone")
    ap.add_argument("--runs", type=int, default=3, help="timed runs per checkout")
    ap.add_argument("--warm", action="store_true", help="also time a rerun of each")
    args = ap.parse_args()
    trees = [*(t.resolve() for t in args.tree), ROOT]
    scratch = Path(tempfile.mkdtemp(prefix="reproduce_time_"))
    try:
        for i, tree in enumerate(trees):  # compile into the kernels' cache
            print(f"warm-up {tree} ...", flush=True)
            _run(tree, scratch / f"warmup{i}")
        cold: dict[Path, list[float]] = {t: [] for t in trees}
        warm: dict[Path, list[float]] = {t: [] for t in trees}
        for k in range(args.runs):
            for i, tree in enumerate(trees):
                out = scratch / f"run{k}_{i}"
                cold[tree].append(_run(tree, out))
                if args.warm:
                    warm[tree].append(_run(tree, out))
                shutil.rmtree(out, ignore_errors=True)
                print(f"run {k + 1}/{args.runs} {tree.name}: {cold[tree][-1]:.1f} s", flush=True)
        base = statistics.median(cold[trees[0]])
        print(f"\n{'checkout':<40} {'cold median [s]':>16} {'ratio':>7}"
              + (f" {'rerun median [s]':>17}" if args.warm else ""))
        for tree in trees:
            med = statistics.median(cold[tree])
            line = f"{str(tree):<40} {med:>16.1f} {med / base:>7.2f}"
            if args.warm:
                line += f" {statistics.median(warm[tree]):>17.1f}"
            print(line)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
