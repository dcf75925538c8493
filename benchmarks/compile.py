"""Compile time and start-up: what a new user waits for, from an empty cache and then warm.

Each case runs as a fresh process with ``NUMBA_CACHE_DIR`` set to a new empty folder (the
package's cache goes under it, ``$NUMBA_CACHE_DIR/fuzzyservo/<digest>``), and is timed from
outside (wall seconds):

- ``precompile``: ``fuzzyservo precompile`` (every law's loops on both plants, the batch
  kernels and the per-step API, two processes);
- ``first simulate, linear`` / ``nonlinear``: the issue's command, self-tuning fuzzy PI, 5 s
  step, ``--metrics``, each from its own empty cache;
- ``warm simulate``: the same command once the cache holds it: a process started afterwards,
  import to result;
- ``--version`` and ``--help``.

``--baseline-src DIR`` runs the first-simulate cases of another source tree (e.g. a worktree
of the previous commit: ``git worktree add /tmp/base HEAD~1``) the same way, for a ratio in
the same session (its precompile only with ``--baseline-precompile``: minutes).

    python benchmarks/compile.py [--baseline-src /tmp/base/src] [--skip-precompile]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SIMULATE = ["simulate", "--controller", "stfpi", "--gains", "ke=10,kde=5000,kdu=0.006",
            "--reference", "step:0.1", "--duration", "5", "--metrics"]


def _timed(argv: list[str], src: Path, cache: Path) -> tuple[float, str]:
    env = {k: v for k, v in os.environ.items() if k != "FUZZYSERVO_CACHE_DIR"}
    env.update(NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(src))
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "fuzzyservo", *argv], capture_output=True,
                          text=True, env=env, check=False)
    secs = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return secs, proc.stderr


def _cases(src: Path, precompile: bool) -> dict[str, float]:
    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        if precompile:
            out["precompile (cold)"], _ = _timed(["precompile"], src, root / "pre")
            out["precompile (warm)"], _ = _timed(["precompile"], src, root / "pre")
        for plant in ("linear", "nonlinear"):
            cache = root / plant
            out[f"first simulate, {plant} (cold)"], err = _timed(
                [*SIMULATE[:1], "--plant", plant, *SIMULATE[1:]], src, cache)
            notice = err.splitlines()[0] if err else "(nothing on stderr)"
            print(f"   stderr of the cold {plant} run begins: {notice[:110]}", flush=True)
            out[f"warm simulate, {plant}"], err = _timed(
                [*SIMULATE[:1], "--plant", plant, *SIMULATE[1:]], src, cache)
            if err:
                print(f"   warm {plant} run printed on stderr: {err[:200]}")
        out["--version"], _ = _timed(["--version"], src, root / "linear")
        out["--help"], _ = _timed(["--help"], src, root / "linear")
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--baseline-src", type=Path, default=None,
                        help="src/ of another tree to time the same way")
    parser.add_argument("--baseline-precompile", action="store_true",
                        help="also time the baseline's precompile (minutes before issue 28)")
    parser.add_argument("--skip-precompile", action="store_true")
    args = parser.parse_args()
    print(f"compile and start-up, {os.cpu_count()} cores, wall seconds", flush=True)
    here = _cases(ROOT / "src", not args.skip_precompile)
    base = (_cases(args.baseline_src, args.baseline_precompile)
            if args.baseline_src is not None else {})
    print(f"{'case':34s} {'this tree':>10s}" + (f" {'baseline':>10s} {'ratio':>7s}"
                                                  if base else ""))
    for name, secs in here.items():
        row = f"{name:34s} {secs:10.2f}"
        if name in base:
            row += f" {base[name]:10.2f} {base[name] / secs:6.1f}x"
        print(row)
    return 0


if __name__ == "__main__":
    sys.exit(main())
