"""Speed and accuracy of the fuzzy engine against scikit-fuzzy, simpful and pyfuzzylite.

One table, every figure measured in this run, on the paper's Δu system (Fig. 3a) at random
points of [-1.2, 1.2]^2 (seed 0):

- ours, batch: the compiled kernel ``eval_uniform_batch`` alone, and the public
  ``fuzzyservo.fuzzy.evaluate`` (validation included) on 10^6 points, one core;
- ours, scalar: a Python loop calling ``evaluate`` on one point at a time (the system packed
  once); for scale, the same loop calling the compiled kernel directly (numba's dispatcher
  overhead) and doing nothing;
- scikit-fuzzy ``ControlSystemSimulation`` at its defaults (201-point universes), one point at a
  time on a subsample, and its fastest array use (arrays as inputs);
- simpful at its defaults (1000 subdivisions), one point at a time on a subsample;
- pyfuzzylite at its defaults (centroid resolution 1000), one at a time and batched; it pins
  numpy<2, so it runs in its own environment, given by ``--fuzzylite-python``.

"ratio" is our throughput over the peer's (our ``evaluate`` batch against batch,
one-at-a-time against our scalar loop); "max |err|" is the peer's largest deviation from our
exact centroid on the points it evaluated. Peers whose package or environment is missing
print "not available". Peers get the inputs clipped to [-1, 1], as our engine does internally.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np

from fuzzyservo.fuzzy import evaluate, pack
from fuzzyservo.fuzzy.kernels import eval_uniform_batch, eval_uniform_checked
from fuzzyservo.paper import du_system
from fuzzyservo.paper.rulebases import DU_TABLE, LABELS

SEED = 0
PEAKS = np.linspace(-1.0, 1.0, 7)
D = PEAKS[1] - PEAKS[0]


def _best(fn: Callable[[], object], repeat: int = 3) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return float(best)


def _skfuzzy(e: np.ndarray, de: np.ndarray, n_one: int, n_arr: int) -> list[tuple]:
    try:
        import skfuzzy as fuzz
        from skfuzzy import control as ctrl
    except ImportError:
        return [("scikit-fuzzy", "not available", 0, np.nan, np.nan, np.nan)]
    u = np.linspace(-1.0, 1.0, 201)
    ant_e = ctrl.Antecedent(u, "e")
    ant_de = ctrl.Antecedent(u, "de")
    con = ctrl.Consequent(u, "du")
    for var in (ant_e, ant_de, con):
        for lab, p in zip(LABELS, PEAKS, strict=True):
            var[lab] = fuzz.trimf(u, [p - D, p, p + D])
    rules = [ctrl.Rule(ant_e[LABELS[i1]] & ant_de[LABELS[i2]], con[cell])
             for i2, row in enumerate(DU_TABLE) for i1, cell in enumerate(row)]
    system = ctrl.ControlSystem(rules)
    sim = ctrl.ControlSystemSimulation(system)
    out = np.empty(n_one)
    t0 = time.perf_counter()
    for k in range(n_one):
        sim.input["e"] = e[k]
        sim.input["de"] = de[k]
        sim.compute()
        out[k] = sim.output["du"]
    t_one = time.perf_counter() - t0
    sim_arr = ctrl.ControlSystemSimulation(system)
    t0 = time.perf_counter()
    sim_arr.input["e"] = e[:n_arr]
    sim_arr.input["de"] = de[:n_arr]
    sim_arr.compute()
    arr = np.asarray(sim_arr.output["du"], dtype=float)
    t_arr = time.perf_counter() - t0
    return [("scikit-fuzzy", "one at a time", n_one, n_one / t_one, out, None),
            ("scikit-fuzzy", "arrays", n_arr, n_arr / t_arr, arr, None)]


def _simpful(e: np.ndarray, de: np.ndarray, n_one: int) -> list[tuple]:
    try:
        import simpful as sf
    except ImportError:
        return [("simpful", "not available", 0, np.nan, np.nan, np.nan)]
    fs = sf.FuzzySystem(show_banner=False, verbose=False)
    for name in ("e", "de", "du"):
        sets = [sf.FuzzySet(function=sf.Triangular_MF(a=p - D, b=p, c=p + D), term=lab)
                for lab, p in zip(LABELS, PEAKS, strict=True)]
        lv = sf.LinguisticVariable(sets, universe_of_discourse=[-1.0, 1.0])
        fs.add_linguistic_variable(name, lv)
    fs.add_rules([f"IF (e IS {LABELS[i1]}) AND (de IS {LABELS[i2]}) THEN (du IS {cell})"
                  for i2, row in enumerate(DU_TABLE) for i1, cell in enumerate(row)])
    out = np.empty(n_one)
    t0 = time.perf_counter()
    for k in range(n_one):
        fs.set_variable("e", float(e[k]))
        fs.set_variable("de", float(de[k]))
        out[k] = fs.Mamdani_inference(["du"])["du"]
    t_one = time.perf_counter() - t0
    return [("simpful", "one at a time", n_one, n_one / t_one, out, None)]


FUZZYLITE_SCRIPT = r'''
import json, sys, time
import numpy as np
import fuzzylite as fl
e, de = np.load(sys.argv[1])
n_one, n_batch = int(sys.argv[2]), int(sys.argv[3])
labels = json.loads(sys.argv[4]); table = json.loads(sys.argv[5])
peaks = np.linspace(-1.0, 1.0, 7); d = peaks[1] - peaks[0]
def terms():
    return [fl.Triangle(l, p - d, p, p + d) for l, p in zip(labels, peaks)]
engine = fl.Engine(
    name="du",
    input_variables=[fl.InputVariable(name=n, minimum=-1.0, maximum=1.0, terms=terms())
                     for n in ("e", "de")],
    output_variables=[fl.OutputVariable(name="du", minimum=-1.0, maximum=1.0,
                                        aggregation=fl.Maximum(), defuzzifier=fl.Centroid(),
                                        terms=terms())],
    rule_blocks=[fl.RuleBlock(conjunction=fl.Minimum(), implication=fl.Minimum(),
                            activation=fl.General(), rules=[
        fl.Rule.create(f"if e is {labels[i1]} and de is {labels[i2]} then du is {c}")
        for i2, row in enumerate(table) for i1, c in enumerate(row)])],
)
ve, vde, vout = (engine.input_variable("e"), engine.input_variable("de"),
                 engine.output_variable("du"))
one = np.empty(n_one)
t0 = time.perf_counter()
for k in range(n_one):
    ve.value = float(e[k]); vde.value = float(de[k])
    engine.process()
    one[k] = float(vout.value)
t_one = time.perf_counter() - t0
t0 = time.perf_counter()
ve.value = e[:n_batch]; vde.value = de[:n_batch]
engine.process()
batch = np.asarray(vout.value, dtype=float)
t_batch = time.perf_counter() - t0
np.save(sys.argv[6], np.concatenate([one, batch]))
print(json.dumps({"t_one": t_one, "t_batch": t_batch, "version": fl.__version__}))
'''


def _fuzzylite(python: str | None, e: np.ndarray, de: np.ndarray, n_one: int,
               n_batch: int) -> list[tuple]:
    if python is None or not Path(python).exists():
        return [("pyfuzzylite", "not available", 0, np.nan, np.nan, np.nan)]
    with tempfile.TemporaryDirectory() as tmp:
        pts, res, script = Path(tmp, "pts.npy"), Path(tmp, "res.npy"), Path(tmp, "fl.py")
        np.save(pts, np.stack([e, de]))
        script.write_text(FUZZYLITE_SCRIPT)
        proc = subprocess.run(
            [python, str(script), str(pts), str(n_one), str(n_batch), json.dumps(LABELS),
             json.dumps(DU_TABLE), str(res)], capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            msg = proc.stderr.strip().splitlines()[-1:] or ["failed"]
            return [("pyfuzzylite", f"not available ({msg[0][:60]})", 0, np.nan, np.nan,
                     np.nan)]
        info = json.loads(proc.stdout.strip().splitlines()[-1])
        vals = np.load(res)
    return [("pyfuzzylite", "one at a time", n_one, n_one / info["t_one"], vals[:n_one], None),
            ("pyfuzzylite", "batched", n_batch, n_batch / info["t_batch"], vals[n_one:], None)]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fuzzylite-python", default=None,
                        help="python of an environment with pyfuzzylite (numpy<2)")
    parser.add_argument("--points", type=int, default=1_000_000, help="batch size")
    parser.add_argument("--quick", action="store_true", help="small peer subsamples")
    args = parser.parse_args()
    numba.set_num_threads(1)  # one core (the kernels are serial anyway)
    rng = np.random.default_rng(SEED)
    e, de = rng.uniform(-1.2, 1.2, (2, args.points))
    ec, dec = np.clip(e, -1.0, 1.0), np.clip(de, -1.0, 1.0)
    du = pack(du_system())
    assert du.path == "uniform grid"
    x = np.column_stack([e, de])
    exact = evaluate(du, x)[:, 0]  # also compiles / loads the cached kernel
    t_batch = _best(lambda: evaluate(du, x))
    rules, lims = du.kernel_args()
    buf = np.empty_like(e)
    t_kernel = _best(lambda: eval_uniform_batch(e, de, rules, lims, buf))
    el, del_ = e.tolist(), de.tolist()

    def loop() -> None:
        for a, b in zip(el, del_, strict=True):
            evaluate(du, (a, b))

    t_scalar = _best(loop, repeat=2)
    kernel = eval_uniform_checked

    def raw() -> None:
        for a, b in zip(el, del_, strict=True):
            kernel(a, b, rules, lims)

    def empty() -> None:
        for _a, _b in zip(el, del_, strict=True):
            pass

    t_raw = _best(raw, repeat=2)
    t_empty = _best(empty, repeat=2)
    ours_batch = args.points / t_batch
    ours_scalar = args.points / t_scalar
    n_skf, n_skf_arr, n_sf, n_fl, n_fl_b = ((50, 2000, 20, 500, 20_000) if args.quick
                                            else (300, 20_000, 100, 5_000, 200_000))
    rows: list[tuple] = [
        ("fuzzyservo", "batch (kernel)", args.points, args.points / t_kernel, exact, 1.0),
        ("fuzzyservo", "batch (evaluate)", args.points, ours_batch, exact, 1.0),
        ("fuzzyservo", "scalar loop", args.points, ours_scalar, exact, 1.0),
        ("fuzzyservo", "  kernel via dispatcher", args.points, args.points / t_raw, exact, 1.0),
        ("fuzzyservo", "  empty Python loop", args.points, args.points / t_empty, exact, 1.0),
    ]
    rows += _skfuzzy(ec, dec, n_skf, n_skf_arr)
    rows += _simpful(ec, dec, n_sf)
    rows += _fuzzylite(args.fuzzylite_python, ec, dec, n_fl, n_fl_b)
    print(f"Fuzzy engine, paper's Δu system (Fig. 3a), random points of [-1.2, 1.2]^2, "
          f"seed {SEED}, one core")
    head = f"{'engine':<13} {'mode':<24} {'points':>9} {'evals/s':>12} {'ratio':>9} " \
           f"{'max |err|':>10}"
    print(head)
    print("-" * len(head))
    for name, mode, n, rate, vals, _ in rows:
        if isinstance(vals, float) and np.isnan(vals):
            print(f"{name:<13} {mode:<24} {'-':>9} {'-':>12} {'-':>9} {'-':>10}")
            continue
        if name == "fuzzyservo":
            print(f"{name:<13} {mode:<24} {n:>9} {rate:>12.4g} {'-':>9} {'exact':>10}")
            continue
        ours = ours_scalar if mode == "one at a time" else ours_batch
        err = float(np.max(np.abs(np.asarray(vals) - exact[:n])))
        print(f"{name:<13} {mode:<24} {n:>9} {rate:>12.4g} {ours / rate:>9.3g} {err:>10.2g}")
    print("ratio = our evals/s over the peer's (batch vs batch, one at a time vs our scalar "
          "loop); max |err| against our exact centroid.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
