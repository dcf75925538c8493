"""Wall time of ``fuzzyservo tune`` (default settings) for pid and stfpi on both plants.

Run after compilation (a tiny warm-up tuning first). ``--write-gains DIR`` also writes the
committed gain files ``{linear,nonlinear}-{pid,pid2,fpi,stfpi}.toml`` (itae, at most 10 %
overshoot, seed 0, parameter set "paper"); fpi is stage 1 of the stfpi run.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from fuzzyservo.analysis.autotune import (
    TunedGains,
    TuningSetup,
    tune_controller,
    write_gains_toml,
)
from fuzzyservo.analysis.tuning import penalised_cost
from fuzzyservo.paper import alpha_system, du_system, named_set


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--write-gains", type=Path, default=None, metavar="DIR")
    args = parser.parse_args()
    params = named_set("paper")
    du, al = du_system(), alpha_system()
    for plant in ("linear", "nonlinear"):  # warm-up: compile/load every kernel
        tune_controller(TuningSetup(controller="stfpi", plant=plant, popsize=2, maxiter=1,
                                    duration=0.5), params, du_system=du, alpha_system=al)
        tune_controller(TuningSetup(controller="pid", plant=plant, popsize=2, maxiter=1,
                                    duration=0.5), params)
    kinds = ("pid", "pid2", "stfpi") if args.write_gains else ("pid", "stfpi")
    print(f"{'controller':<10} {'plant':<10} {'wall [s]':>9} {'runs':>6} {'itae':>9} "
          f"{'overshoot [%]':>13} {'rise [s]':>8} {'settle [s]':>10} feasible")
    for plant in ("linear", "nonlinear"):
        for kind in kinds:
            setup = TuningSetup(controller=kind, plant=plant)
            t0 = time.perf_counter()
            tuned = tune_controller(setup, params, du_system=du, alpha_system=al)
            wall = time.perf_counter() - t0
            m = tuned.metrics
            print(f"{kind:<10} {plant:<10} {wall:9.1f} {tuned.n_evaluations:6d} "
                  f"{tuned.objective_value:9.4g} {m['overshoot']:13.3g} {m['rise_time']:8.3f} "
                  f"{m['settling_time']:10.3f} {tuned.feasible}", flush=True)
            if args.write_gains:
                args.write_gains.mkdir(parents=True, exist_ok=True)
                write_gains_toml(args.write_gains / f"{plant}-{kind}.toml", tuned)
                if kind == "stfpi":
                    write_gains_toml(args.write_gains / f"{plant}-fpi.toml", _stage1(tuned))
    return 0


def _stage1(t: TunedGains) -> TunedGains:
    s1 = t.stage("fpi")
    return dataclasses.replace(
        t, controller="fpi", gains=dict(s1.gains), metrics=dict(s1.metrics),
        objective_value=s1.objective_value, feasible=s1.feasible,
        setup=dataclasses.replace(t.setup, controller="fpi"), n_evaluations=s1.n_evaluations,
        stages=(s1,), cost=float(penalised_cost(
            {k: np.array([v]) for k, v in s1.metrics.items()}, t.setup.objective,
            t.setup.constraints, t.setup.step)[0]))


if __name__ == "__main__":
    raise SystemExit(main())
