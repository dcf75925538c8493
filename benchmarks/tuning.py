"""Wall time of ``fuzzyservo tune`` (default settings) for pid and stfpi on both plants.

Run after compilation (a tiny warm-up tuning first). ``--write-gains DIR`` instead re-tunes
every design of the paper study and writes its gain files (``fuzzyservo.study.runner.retune``:
the committed files in src/fuzzyservo/data/gains are made this way).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from fuzzyservo.analysis.autotune import TuningSetup, tune_controller
from fuzzyservo.paper import named_set
from fuzzyservo.study.runner import PLANTS, retune


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--write-gains", type=Path, default=None, metavar="DIR")
    args = parser.parse_args()
    params = named_set("paper")
    if args.write_gains:
        for plant in PLANTS:
            retune(plant, params, "paper", args.write_gains, progress=print)
        return 0
    for plant in PLANTS:  # warm-up: compile/load every kernel
        for kind in ("stfpi", "pid"):
            tune_controller(TuningSetup(controller=kind, plant=plant, popsize=2, maxiter=1,
                                        duration=0.5), params)
    print(f"{'controller':<10} {'plant':<10} {'wall [s]':>9} {'runs':>6} {'itae':>9} "
          f"{'overshoot [%]':>13} {'rise [s]':>8} {'settle [s]':>10} feasible")
    for plant in PLANTS:
        for kind in ("pid", "stfpi"):
            setup = TuningSetup(controller=kind, plant=plant)
            t0 = time.perf_counter()
            tuned = tune_controller(setup, params)
            wall = time.perf_counter() - t0
            m = tuned.metrics
            print(f"{kind:<10} {plant:<10} {wall:9.1f} {tuned.n_evaluations:6d} "
                  f"{tuned.objective_value:9.4g} {m['overshoot']:13.3g} {m['rise_time']:8.3f} "
                  f"{m['settling_time']:10.3f} {tuned.feasible}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
