"""Speed of fuzzy systems read from files: the general evaluator, pyfuzzylite, the loops.

One table, every figure measured in this run, on two two-input 7x7 triangle systems given as
FLL files: (a) the paper's Δu system as shipped (``fuzzyservo.paper.system_file("du", "fll")``)
and (b) a non-uniform one (unequally spaced peaks, different for e, Δe and Δu, the paper's rule
table), written with ``fuzzyservo.formats.write_system`` to a temporary .fll and read back.
Points: uniform on [-1.2, 1.2]^2 (seed 0; both files clip the inputs to [-1, 1]).

1. The general evaluator (``fuzzyservo.fuzzy.general``), 10^6 points, best of 3: the compiled
   ``eval_batch`` on one core (``numba.set_num_threads(1)``), the public ``evaluate``
   (validation included) on one core and with ``parallel=True`` on 2 threads; for the paper's
   system also the uniform-grid path (``evaluate`` of ``pack(du_system())``) on the same points,
   with the largest difference between the two exact evaluators.
   Target: >= 5 M evaluations/s per core (``eval_batch``).
2. pyfuzzylite 8 (batched: numpy arrays as input values, then ``Engine.process``) importing
   the very same FLL file with ``FllImporter``: at the file's resolution (our writer writes
   ``Centroid 10000``) and at pyfuzzylite's default 1000 (set on the imported defuzzifier),
   one timed batch each; max |err| against our exact values (its centroid is a midpoint rule
   of 10000 or 1000 samples, step 2e-4 or 2e-3 of this range). pyfuzzylite pins numpy<2, so it
   runs in its own environment, given by ``--fuzzylite-python`` (``make bench`` creates
   ``.venv-fuzzylite``). Target: our ``evaluate`` (one core) >= 500x pyfuzzylite batched.
3. The controllers' loops (fpi, stfpi via ``fuzzyservo.registry.build_controller``, 1 kHz,
   6 ms delay, linear and nonlinear plant): the built-in systems, the Δu system from the
   shipped FLL file on the general evaluator (``fuzzyservo.fuzzy.loop.loop_system(...,
   grid=False)``: the shipped files have the uniform-grid form, which ``pack`` would
   otherwise take; α built-in), and (stfpi) both Δu and α from files. ``simulate``: one
   10 s run, best of 15; ``simulate_batch``: 64 runs of 10 s (kdu varied), on every core,
   best of 3. Controller steps per second and the ratio
   file/built-in. Target: the loop with the Δu system from a file >= 1/3 of the built-in rate.

Absolute rates drift on a shared machine; the ratios are taken between figures of this run.
Run: ``python benchmarks/fuzzy_files.py --fuzzylite-python .venv-fuzzylite/bin/python``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
import numpy as np

from fuzzyservo.formats import read_system, write_system
from fuzzyservo.fuzzy import PackedSystem, evaluate, general, pack
from fuzzyservo.fuzzy.loop import loop_system
from fuzzyservo.fuzzy.system import FuzzySystem, Term, Variable
from fuzzyservo.paper import du_system, paper_params, system_file
from fuzzyservo.registry import build_controller, build_plant, default_systems
from fuzzyservo.sim import Step, simulate, simulate_batch

SEED = 0
TS = 1e-3  # sample period [s]
DURATION = 10.0  # [s]
DELAY = 0.006  # [s]
GAINS = {"ke": 10.0, "kde": 5000.0, "kdu": 0.006}
RUNS = 64
TARGET_RATE = 5e6  # evaluations/s per core
TARGET_PEER = 500.0  # ours / pyfuzzylite batched
TARGET_LOOP = 1.0 / 3.0  # file / built-in
# unequally spaced peaks on [-1, 1] (7 terms each), different per variable
PEAKS = {
    "e": (-1.0, -0.55, -0.2, 0.0, 0.1, 0.45, 1.0),
    "de": (-1.0, -0.7, -0.35, -0.05, 0.2, 0.6, 1.0),
    "du": (-1.0, -0.6, -0.15, 0.05, 0.3, 0.7, 1.0),
}


def _best(fn: Callable[[], object], repeat: int = 3) -> float:
    """Best wall-clock time of ``repeat`` calls [s] (others on the machine only add time)."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return float(best)


def _nonuniform(base: FuzzySystem) -> FuzzySystem:
    """``base`` (the paper's Δu system) with unequally spaced triangles: neighbour peaks are
    the feet; the end triangles reach past the range by their inner gap."""

    def var(v: Variable) -> Variable:
        p = PEAKS[v.name]
        feet = (2 * p[0] - p[1], *p, 2 * p[-1] - p[-2])
        terms = tuple(Term(name=t.name, shape="triangle", params=(feet[k], feet[k + 1],
                                                                   feet[k + 2]))
                      for k, t in enumerate(v.terms))
        return dataclasses.replace(v, terms=terms)

    return dataclasses.replace(base, name="nonuniform_du",
                               inputs=tuple(var(v) for v in base.inputs),
                               outputs=tuple(var(v) for v in base.outputs))


FUZZYLITE_SCRIPT = r'''
import json, sys, time
import numpy as np
import fuzzylite as fl
path, pts, out = sys.argv[1], sys.argv[2], sys.argv[3]
counts = json.loads(sys.argv[4])  # [[resolution or 0 (the file's), n points], ...]
x = np.load(pts)
engine = fl.FllImporter().from_file(path)
inputs, output = engine.input_variables, engine.output_variables[0]
file_res = output.defuzzifier.resolution
info, vals = [], []
for res, n in counts:
    output.defuzzifier.resolution = res or file_res
    t0 = time.perf_counter()
    for v, col in zip(inputs, x[:n].T):
        v.value = col
    engine.process()
    y = np.array(output.value, dtype=float, copy=True)
    info.append({"resolution": output.defuzzifier.resolution, "n": n,
                 "t": time.perf_counter() - t0})
    vals.append(y)
np.save(out, np.concatenate(vals))
print(json.dumps({"version": fl.__version__, "file_resolution": file_res, "runs": info}))
'''


def _fuzzylite(python: str | None, path: Path, x: np.ndarray,
               counts: list[tuple[int, int]]) -> list[dict[str, Any]] | str:
    """pyfuzzylite on the FLL file at ``path``: per (resolution, n) its rate, values and
    resolution, or the reason it is not available."""
    if python is None or not Path(python).exists():
        return "not available (no --fuzzylite-python)"
    with tempfile.TemporaryDirectory() as tmp:
        pts, res, script = Path(tmp, "pts.npy"), Path(tmp, "res.npy"), Path(tmp, "fl.py")
        np.save(pts, x[:max(n for _, n in counts)])
        script.write_text(FUZZYLITE_SCRIPT)
        proc = subprocess.run(
            [python, str(script), str(path), str(pts), str(res), json.dumps(counts)],
            capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            msg = proc.stderr.strip().splitlines()[-1:] or ["failed"]
            return f"not available ({msg[0][:60]})"
        info = json.loads(proc.stdout.strip().splitlines()[-1])
        vals = np.load(res)
    out, k = [], 0
    for run in info["runs"]:
        n = int(run["n"])
        out.append({"resolution": int(run["resolution"]), "n": n, "rate": n / run["t"],
                    "vals": vals[k:k + n], "file": int(info["file_resolution"]),
                    "version": info["version"]})
        k += n
    return out


Row = tuple[str, str, str, int, float, float, str]  # item, what, system, n, rate, ratio, err


def _fmt(row: Row) -> str:
    item, what, system, n, rate, ratio, err = row
    rate_s = "-" if np.isnan(rate) else f"{rate:.4g}"
    ratio_s = "-" if np.isnan(ratio) else f"{ratio:.3g}"
    n_s = "-" if n == 0 else str(n)
    return f"{item:<2} {what:<52} {system:<19} {n_s:>8} {rate_s:>11} {ratio_s:>8} {err:>9}"


def _evaluator(packed: PackedSystem, x: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Rates [evaluations/s] of ``eval_batch`` and ``evaluate`` at the current thread count
    (best of 3, after a compiling call) and the values."""
    comp = packed.compiled
    assert comp is not None  # packed for the general evaluator
    out = np.empty((x.shape[0], len(comp.system.outputs)))
    general.eval_batch(comp.ints, comp.floats, x[:10], out[:10])  # compile / load

    def kernel() -> None:
        general.eval_batch(comp.ints, comp.floats, x, out)

    def public() -> None:
        evaluate(packed, x)

    vals = evaluate(packed, x)
    return x.shape[0] / _best(kernel), x.shape[0] / _best(public), vals[:, 0]


def _parallel(comp: PackedSystem, x: np.ndarray) -> float:
    """Rate of ``evaluate(..., parallel=True)`` at the current thread count [evaluations/s]."""
    evaluate(comp, x[:2000], parallel=True)  # compile / load

    def run() -> None:
        evaluate(comp, x, parallel=True)

    return float(x.shape[0] / _best(run))


def _builtin(x: np.ndarray) -> tuple[float, np.ndarray]:
    """Rate of the built-in uniform-grid path (``evaluate`` of ``pack(du_system())``) and its
    values."""
    du = pack(du_system())
    assert du.path == "uniform grid"
    vals = evaluate(du, x)[:, 0]

    def run() -> None:
        evaluate(du, x)

    return x.shape[0] / _best(run), vals


Plants = dict[str, tuple[Any, Step]]


def _single(ctl: Any, plant: Any, ref: Step) -> float:
    """Controller steps/s of one ``simulate`` run of DURATION (best of 15)."""
    simulate(ctl, plant, ref, duration=0.1, delay=DELAY)  # compile / load

    def run() -> None:
        simulate(ctl, plant, ref, duration=DURATION, delay=DELAY)

    return (int(round(DURATION / TS)) + 1) / _best(run, 15)


def _batch(ctl: Any, plant: Any, ref: Step) -> float:
    """Controller steps/s of ``simulate_batch``, RUNS runs of DURATION (best of 3)."""
    gains = np.column_stack([np.full(RUNS, GAINS["ke"]), np.full(RUNS, GAINS["kde"]),
                             np.linspace(0.002, 0.01, RUNS)])
    simulate_batch(ctl, gains[:2], plant=plant, reference=ref, duration=0.1,
                   delay=DELAY)  # compile / load

    def run() -> None:
        simulate_batch(ctl, gains, plant=plant, reference=ref, duration=DURATION, delay=DELAY)

    return RUNS * (int(round(DURATION / TS)) + 1) / _best(run, 3)


def _met(ok: bool) -> str:
    return "met" if ok else "NOT met"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fuzzylite-python", default=None,
                        help="python of an environment with pyfuzzylite (numpy<2)")
    parser.add_argument("--points", type=int, default=1_000_000, help="batch size (item 1)")
    parser.add_argument("--quick", action="store_true", help="small pyfuzzylite batches")
    args = parser.parse_args()
    threads = numba.get_num_threads()
    cores = min(2, threads)
    n_pts = args.points
    x = np.ascontiguousarray(np.random.default_rng(SEED).uniform(-1.2, 1.2, (n_pts, 2)))
    n_steps = int(round(DURATION / TS)) + 1

    paper_path = system_file("du", "fll")
    alpha_path = system_file("alpha", "fll")
    with tempfile.TemporaryDirectory() as tmp:
        nonuni_path = Path(tmp, "nonuniform_du.fll")
        write_system(_nonuniform(read_system(paper_path)), nonuni_path)
        files = {"paper Δu": paper_path, "non-uniform": nonuni_path}
        # 2 first, in its own process while this one is idle: pyfuzzylite on the same files
        counts = [(0, 200), (1000, 1000)] if args.quick else [(0, 2000), (1000, 10_000)]
        peer = {name: _fuzzylite(args.fuzzylite_python, path, x, counts)
                for name, path in files.items()}
        comps = {name: pack(read_system(path), grid=False) for name, path in files.items()}

    # 1: the general evaluator, one core
    numba.set_num_threads(1)
    serial = {name: _evaluator(comp, x) for name, comp in comps.items()}
    builtin_rate, builtin_vals = _builtin(x)

    # 3a: single runs (before any parallel region: numba's workers may still spin after)
    params = paper_params()
    plants: Plants = {"linear": (build_plant("linear", params), Step(0.1)),
                      "nonlinear": (build_plant("nonlinear", params), Step(0.05))}
    du_file = loop_system(read_system(paper_path), source=str(paper_path), grid=False)
    alpha_file = loop_system(read_system(alpha_path), source=str(alpha_path), grid=False)
    alpha_builtin = default_systems(("alpha",))["alpha"]
    configs: list[tuple[str, str, dict[str, Any] | None]] = [
        ("fpi", "built-in", None),
        ("fpi", "Δu file", {"du": du_file}),
        ("stfpi", "built-in", None),
        ("stfpi", "Δu file, α built-in", {"du": du_file, "alpha": alpha_builtin}),
        ("stfpi", "Δu and α files", {"du": du_file, "alpha": alpha_file}),
    ]
    ctls = {(kind, label): build_controller(kind, GAINS, dt=TS, systems=systems)
            for kind, label, systems in configs}
    loops: dict[tuple[str, str, str, str], float] = {}
    for pname, (plant, ref) in plants.items():
        for (kind, label), ctl in ctls.items():
            loops["simulate", pname, kind, label] = _single(ctl, plant, ref)

    # 1 (parallel) and 3b: every core
    numba.set_num_threads(cores)
    parallel = {name: _parallel(comp, x) for name, comp in comps.items()}
    for pname, (plant, ref) in plants.items():
        for (kind, label), ctl in ctls.items():
            loops["batch", pname, kind, label] = _batch(ctl, plant, ref)
    numba.set_num_threads(threads)

    rows: list[Row] = []
    for name, (r_kernel, r_eval, vals) in serial.items():
        rows.append(("1", "general eval_batch, 1 core", name, n_pts, r_kernel, 1.0, "exact"))
        rows.append(("1", "general evaluate, 1 core", name, n_pts, r_eval, r_eval / r_kernel,
                     "exact"))
        rows.append(("1", f"general evaluate, parallel=True, {cores} threads", name, n_pts,
                     parallel[name], parallel[name] / r_kernel, "exact"))
        if name == "paper Δu":
            diff = float(np.max(np.abs(builtin_vals - vals)))
            rows.append(("1", "uniform-grid path (evaluate, pack(du_system()))", name, n_pts,
                         builtin_rate, builtin_rate / r_kernel, f"{diff:.1e}"))
    # 2: ratio = our evaluate on one core over pyfuzzylite's batch
    peer_ratios: list[tuple[str, float]] = []
    for name, res in peer.items():
        if isinstance(res, str):
            rows.append(("2", f"pyfuzzylite batched: {res}", name, 0, np.nan, np.nan, "-"))
            continue
        for run in res:
            which = "file's" if run["resolution"] == run["file"] else "default"
            err = float(np.max(np.abs(run["vals"] - serial[name][2][:run["n"]])))
            ratio = serial[name][1] / run["rate"]
            rows.append(("2", f"pyfuzzylite {run['version']} batched, Centroid "
                              f"{run['resolution']} ({which})", name, run["n"], run["rate"],
                         ratio, f"{err:.1e}"))
            peer_ratios.append((which, ratio))
    # 3: ratio = over the built-in systems' rate (same mode, plant and controller)
    for (mode, pname, kind, label), rate in loops.items():
        base = loops[mode, pname, kind, "built-in"]
        how = "simulate 10 s" if mode == "simulate" else f"simulate_batch {RUNS}x10 s"
        n = n_steps if mode == "simulate" else RUNS * n_steps
        rows.append(("3", f"{how}, {pname}, {kind}", label, n, rate, rate / base, "-"))

    print(f"Fuzzy systems from FLL files: points uniform on [-1.2, 1.2]^2 (seed {SEED}); "
          f"loops at {1 / TS:g} Hz with a {DELAY * 1e3:g} ms delay; {cores} cores")
    head = (f"{'#':<2} {'what':<52} {'system':<19} {'n':>8} {'rate [/s]':>11} {'ratio':>8} "
            f"{'max |err|':>9}")
    print(head)
    print("-" * len(head))
    for row in rows:
        print(_fmt(row))
    print("rate: evaluations/s (1, 2), controller steps/s (3). ratio: (1) over eval_batch on "
          "the same system; (2) our evaluate, 1 core,\nover pyfuzzylite's; (3) over the "
          "built-in systems in the same mode, plant and controller. max |err|: (1) built-in "
          "vs\ngeneral; (2) pyfuzzylite vs our exact values (its midpoint step is "
          "2/resolution).")

    print("Acceptance targets:")
    rates = {name: s[0] for name, s in serial.items()}
    print(f"  1. general eval_batch, 1 core, 7x7 triangles: "
          f"{', '.join(f'{n} {r / 1e6:.2f} M/s' for n, r in rates.items())} (the built-in "
          f"uniform path {builtin_rate / rates['paper Δu']:.1f}x the paper's); "
          f"target >= {TARGET_RATE / 1e6:g} M/s: {_met(min(rates.values()) >= TARGET_RATE)}")
    if peer_ratios:
        file_min = min(r for w, r in peer_ratios if w == "file's")
        dflt = [r for w, r in peer_ratios if w == "default"]
        extra = f"; at its default Centroid 1000: min {min(dflt):.0f}x" if dflt else ""
        print(f"  2. ours / pyfuzzylite batched on the same FLL file (the file's Centroid "
              f"10000): min {file_min:.0f}x{extra}; target >= {TARGET_PEER:g}x while exact: "
              f"{_met(file_min >= TARGET_PEER)}")
    else:
        print(f"  2. ours / pyfuzzylite batched: not measured (pyfuzzylite not available); "
              f"target >= {TARGET_PEER:g}x: not measured")
    du_only = {k: r / loops[k[0], k[1], k[2], "built-in"] for k, r in loops.items()
               if k[3] not in ("built-in", "Δu and α files")}
    worst = min(du_only, key=du_only.__getitem__)
    both = min(r / loops[k[0], k[1], k[2], "built-in"] for k, r in loops.items()
               if k[3] == "Δu and α files")
    print(f"  3. loop with the Δu system from a file / built-in: min {du_only[worst]:.2f} "
          f"({worst[0]}, {worst[1]}, {worst[2]}); with α also from a file min {both:.2f}; "
          f"target >= 1/3: {_met(du_only[worst] >= TARGET_LOOP)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
