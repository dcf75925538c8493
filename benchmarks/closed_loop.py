"""Speed of the closed-loop simulator, all figures measured in one run, printed as one table.

1. One 5 s self-tuning fuzzy PI run on the linear plant (eq. 8) at 1 kHz with the 6 ms delay,
   through the public :func:`fuzzyservo.sim.simulate`, after compilation (best of repeats).
   Target (issue 4): <= 5 ms.
2. Batched runs (:func:`fuzzyservo.sim.simulate_batch`, numba ``prange`` on every core, metrics
   and tail oscillation per run, no traces kept) on the linear plant: controller-plus-plant
   steps per second for the self-tuning fuzzy PI and for the PID. Targets: >= 10 million/s
   (issue 4); for the self-tuning fuzzy PI >= 30 million/s on 2 threads (issue 13).
3. Batched runs on the nonlinear plant (RK4, the default 0.5 ms steps, 2 per sample):
   controller samples per second. Targets: >= 1 million/s (issue 4); >= 4 million/s on 2
   threads (issue 13).
   Rows 2 and 3 are also measured on one thread (``numba.set_num_threads(1)``): on a machine
   shared with other work the one-thread rate is the steadier figure, and the two-thread
   target is about twice it.
4. The same loop written with the peers' per-step APIs: python-control's discrete
   ``StateSpace.dynamics/output`` for the plant and scikit-fuzzy's ``ControlSystemSimulation``
   (the Δu and α systems of Fig. 3) for the controller, one call per sample, on a shorter run
   scaled to 5 s; the table gives the ratio against item 1.

Run: ``python benchmarks/closed_loop.py`` (``make bench`` runs every benchmark).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numba
import numpy as np

from fuzzyservo.control import PIDController, SelfTuningFuzzyPIController
from fuzzyservo.paper import alpha_system, du_system, paper_params
from fuzzyservo.plant import LinearServo, linearize
from fuzzyservo.sim import LinearPlant, NonlinearPlant, Step, simulate, simulate_batch

TS = 1e-3
DURATION = 5.0
DELAY = 0.006
GAINS = (10.0, 5000.0, 0.006)  # ke [1/m], kde [1/m], kdu [-]


def _best_time(fn: Callable[[], object], repeats: int) -> float:
    """Best of ``repeats`` wall-clock times [s]: the machine is shared, and other processes
    only ever add time (the convention of ``timeit``)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def _stfpi(kdu: float = GAINS[2]) -> SelfTuningFuzzyPIController:
    return SelfTuningFuzzyPIController.from_systems(
        du_system(), alpha_system(), dt=TS, ke=GAINS[0], kde=GAINS[1], kdu=kdu)


def _peer_loop(servo: LinearServo, n: int) -> float:
    """Seconds for n samples of the loop written with python-control + scikit-fuzzy."""
    import control
    import skfuzzy as fuzz
    from skfuzzy import control as ctrl

    labels = ["NB", "NM", "NS", "ZO", "PS", "PM", "PB"]
    a_labels = ["ZO", "VS", "S", "SB", "MB", "B", "VB"]
    du_rules = np.array(du_system().rule_table())
    a_rules = np.array(alpha_system().rule_table())
    uni = np.linspace(-1.0, 1.0, 201)
    a_uni = np.linspace(0.0, 1.0, 201)

    def build(out_uni: np.ndarray, out_labels: list[str], table: np.ndarray) -> object:
        e = ctrl.Antecedent(uni, "e")
        de = ctrl.Antecedent(uni, "de")
        out = ctrl.Consequent(out_uni, "out")
        for var, u, labs in ((e, uni, labels), (de, uni, labels), (out, out_uni, out_labels)):
            lo, hi = u[0], u[-1]
            d = (hi - lo) / 6
            for k, lab in enumerate(labs):
                var[lab] = fuzz.trimf(u, [lo + (k - 1) * d, lo + k * d, lo + (k + 1) * d])
        rules = [ctrl.Rule(e[labels[i1]] & de[labels[i2]], out[out_labels[table[i2, i1]]])
                 for i2 in range(7) for i1 in range(7)]
        return ctrl.ControlSystemSimulation(ctrl.ControlSystem(rules))

    sim_du = build(uni, labels, du_rules)
    sim_a = build(a_uni, a_labels, a_rules)
    a, b, c, d = servo.state_space()
    plant = control.ss(a, b, c, d).sample(TS)
    ke, kde, kdu = GAINS
    t0 = time.perf_counter()
    x = np.zeros(a.shape[0])
    fifo = [0.0] * int(round(DELAY / TS))
    u_prev = e_prev = 0.0
    for k in range(n):
        y = float(plant.output(k * TS, x, [fifo[0]])[0])
        e = 0.1 - y
        en = float(np.clip(ke * e, -1, 1))
        den = float(np.clip(kde * (e - e_prev), -1, 1))
        for s in (sim_du, sim_a):
            s.input["e"] = en  # type: ignore[attr-defined]
            s.input["de"] = den  # type: ignore[attr-defined]
            s.compute()  # type: ignore[attr-defined]
        du = float(sim_du.output["out"])  # type: ignore[attr-defined]
        alpha = float(sim_a.output["out"])  # type: ignore[attr-defined]
        u_prev = min(max(u_prev + alpha * kdu * du, -1.0), 1.0)
        e_prev = e
        fifo.append(u_prev)
        x = plant.dynamics(k * TS, x, [fifo.pop(0)])
    return time.perf_counter() - t0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000, help="runs per linear batch")
    parser.add_argument("--nl-runs", type=int, default=64, help="runs per nonlinear batch")
    parser.add_argument("--peer-samples", type=int, default=300,
                        help="samples of the peer loop (scaled to 5 s)")
    parser.add_argument("--repeats", type=int, default=5,
                        help="repeats of each batch timing (the best is reported)")
    args = parser.parse_args()
    params = paper_params()
    servo = LinearServo.from_params(params, linearize(params))
    lin = LinearPlant.from_servo(servo)
    nonlin = NonlinearPlant.from_params(params)
    stfpi = _stfpi()
    n_steps = int(round(DURATION / TS)) + 1
    threads = numba.get_num_threads()

    # the single run first: after a parallel region numba's worker threads may still spin
    simulate(stfpi, lin, Step(0.1), duration=DURATION, delay=DELAY)
    single = _best_time(
        lambda: simulate(stfpi, lin, Step(0.1), duration=DURATION, delay=DELAY), 21)

    # warm-up (compilation or cache load) of the batch paths measured below
    g_f = np.column_stack([np.full(4, GAINS[0]), np.full(4, GAINS[1]),
                           np.linspace(0.002, 0.01, 4)])
    simulate_batch(stfpi, g_f, plant=lin, reference=Step(0.1), duration=0.1, delay=DELAY)
    simulate_batch(stfpi, g_f, plant=nonlin, reference=Step(0.05), duration=0.1, delay=DELAY)
    pid = PIDController(dt=TS, kp=8.0, ki=1.0, kd=0.1, b=0.0, c=0.0)
    g_p = np.tile([8.0, 1.0, 0.1, 100.0, 0.0, 0.0], (4, 1))
    simulate_batch(pid, g_p, plant=lin, reference=Step(0.1), duration=0.1, delay=DELAY)

    n = args.runs
    g_f = np.column_stack([np.full(n, GAINS[0]), np.full(n, GAINS[1]),
                           np.linspace(0.002, 0.01, n)])
    t_f = _best_time(lambda: simulate_batch(stfpi, g_f, plant=lin, reference=Step(0.1),
                                            duration=DURATION, delay=DELAY), args.repeats)
    g_p = np.tile([8.0, 1.0, 0.1, 100.0, 0.0, 0.0], (n, 1))
    g_p[:, 0] = np.linspace(2.0, 10.0, n)
    t_p = _best_time(lambda: simulate_batch(pid, g_p, plant=lin, reference=Step(0.1),
                                            duration=DURATION, delay=DELAY), args.repeats)
    m = args.nl_runs
    g_n = np.column_stack([np.full(m, GAINS[0]), np.full(m, GAINS[1]),
                           np.linspace(0.002, 0.01, m)])
    t_n = _best_time(lambda: simulate_batch(stfpi, g_n, plant=nonlin, reference=Step(0.05),
                                            duration=DURATION, delay=DELAY), args.repeats)
    numba.set_num_threads(1)
    t_f1 = _best_time(lambda: simulate_batch(stfpi, g_f[:n // 4], plant=lin,
                                             reference=Step(0.1), duration=DURATION,
                                             delay=DELAY), args.repeats)
    t_n1 = _best_time(lambda: simulate_batch(stfpi, g_n[:m // 2], plant=nonlin,
                                             reference=Step(0.05), duration=DURATION,
                                             delay=DELAY), args.repeats)
    numba.set_num_threads(threads)
    fine = NonlinearPlant.from_params(params, substep=1e-4)
    simulate_batch(stfpi, g_n[:2], plant=fine, reference=Step(0.05), duration=0.1, delay=DELAY)
    t_fine = _best_time(lambda: simulate_batch(stfpi, g_n, plant=fine, reference=Step(0.05),
                                               duration=DURATION, delay=DELAY), 3)
    peer = _peer_loop(servo, args.peer_samples) * n_steps / args.peer_samples

    rate_f = n * n_steps / t_f
    rate_p = n * n_steps / t_p
    rate_n = m * n_steps / t_n
    rows = [
        ("single 5 s stfpi run, linear plant, 1 kHz", f"{single * 1e3:.2f} ms", "<= 5 ms"),
        (f"batch stfpi, linear plant ({n} runs, {threads} threads)",
         f"{rate_f / 1e6:.1f} M steps/s", ">= 30 M/s on 2 threads (issue 13)"),
        (f"  same on 1 thread ({n // 4} runs)",
         f"{(n // 4) * n_steps / t_f1 / 1e6:.1f} M steps/s", ""),
        (f"batch PID (I-PD), linear plant ({n} runs, {threads} threads)",
         f"{rate_p / 1e6:.1f} M steps/s", ">= 10 M/s"),
        (f"batch stfpi, nonlinear plant, RK4 0.5 ms ({m} runs, {threads} threads)",
         f"{rate_n / 1e6:.2f} M samples/s", ">= 4 M/s on 2 threads (issue 13)"),
        (f"  same on 1 thread ({m // 2} runs)",
         f"{(m // 2) * n_steps / t_n1 / 1e6:.2f} M samples/s", ""),
        (f"  same with RK4 0.1 ms (open-loop accuracy, {m} runs)",
         f"{m * n_steps / t_fine / 1e6:.2f} M samples/s", ""),
        ("python-control + scikit-fuzzy per-step loop, 5 s (scaled from "
         f"{args.peer_samples} samples)", f"{peer:.2f} s", ""),
        ("ratio peer loop / single fuzzyservo run", f"{peer / single:,.0f} x", ""),
    ]
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    print(f"{'closed loop (benchmarks/closed_loop.py)':<{w0}}  {'measured':>{w1}}  target")
    for name, value, target in rows:
        print(f"{name:<{w0}}  {value:>{w1}}  {target}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
