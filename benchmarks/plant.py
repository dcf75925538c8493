"""Speed of the nonlinear servo model: 5 s of proportional position control sampled at 1 kHz.

The compiled path is the project's njit RK4 (:func:`fuzzyservo.plant.rk4_advance_ws`, 0.1 ms
substeps) driven by a P controller with the 6 ms hose delay as a FIFO, measured after
compilation on one thread (best of several repeats). The reference is the same run with scipy's
``solve_ivp`` (LSODA, rtol 1e-8) integrating :func:`fuzzyservo.plant.rhs` over each 1 ms
sample with the command held. Target (issue 3): <= 50 ms per 5 s run.

Run: ``python benchmarks/plant.py`` (``make bench`` runs every benchmark).
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np
from scipy import integrate

from fuzzyservo.paper import paper_params
from fuzzyservo.plant import N_STATE, pack, rhs, trim
from fuzzyservo.plant.nonlinear import rk4_advance_ws

DT = 1e-3
N = 5000
KP = 4.0  # [1/m] loop gain ≈ 0.84 1/s
STEP = 0.1  # [m]
DELAY = 6  # samples


@numba.njit(cache=True, nogil=True)
def p_loop(x0: np.ndarray, p: np.ndarray, u_trim: float, n_sub: int, y: np.ndarray) -> None:
    x = x0.copy()
    work = np.empty((5, x.shape[0]))
    fifo = np.full(DELAY, u_trim)
    r = x0[5] + STEP
    for k in range(y.shape[0]):
        y[k] = x[5]
        u = KP * (r - x[5])
        u = min(max(u, -1.0), 1.0)
        j = k % DELAY
        ud = fifo[j]
        fifo[j] = u
        rk4_advance_ws(k * DT, x, ud, p, DT, n_sub, work)


def lsoda_loop(x0: np.ndarray, p: np.ndarray, u_trim: float, rtol: float) -> np.ndarray:
    scale = np.array([1.0, 1.0, 700.0, 7e6, 7e6, 1.0, 0.3])
    x = x0.copy()
    fifo = [u_trim] * DELAY
    r = x0[5] + STEP
    y = np.empty(N)
    dx = np.empty(N_STATE)

    def f(t: float, xx: np.ndarray, u: float) -> np.ndarray:
        rhs(t, xx, u, p, dx)
        return dx.copy()

    for k in range(N):
        y[k] = x[5]
        fifo.append(min(max(KP * (r - x[5]), -1.0), 1.0))
        u = fifo.pop(0)
        sol = integrate.solve_ivp(f, (k * DT, (k + 1) * DT), x, method="LSODA", args=(u,),
                                  rtol=rtol, atol=rtol * scale)
        x = np.ascontiguousarray(sol.y[:, -1])
    return y


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--substep", type=float, default=1e-4, help="RK4 substep [s]")
    args = parser.parse_args()
    numba.set_num_threads(1)
    params = paper_params()
    p = pack(params)
    tr = trim(params, 0.5)
    n_sub = max(1, round(DT / args.substep))
    y = np.empty(N)
    p_loop(tr.state, p, tr.command, n_sub, y)  # compile (or load the cache)
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        p_loop(tr.state, p, tr.command, n_sub, y)
        times.append(time.perf_counter() - t0)
    t_nb = min(times)
    t0 = time.perf_counter()
    y_ref = lsoda_loop(tr.state, p, tr.command, 1e-8)
    t_ls = time.perf_counter() - t0
    err = float(np.max(np.abs(y - y_ref)))
    print("plant: nonlinear servo, 5 s of P control at 1 kHz (paper set, 0.1 m step, "
          "6 ms delay)")
    print(f"{'path':<34}{'time per run':>14}{'ratio':>10}")
    print(f"{'fuzzyservo njit RK4 (%g ms sub)' % (args.substep * 1e3):<34}"
          f"{t_nb * 1e3:>11.2f} ms{1.0:>10.1f}")
    print(f"{'scipy solve_ivp LSODA rtol 1e-8':<34}{t_ls * 1e3:>11.1f} ms"
          f"{t_ls / t_nb:>10.0f}")
    print(f"target <= 50 ms: {'met' if t_nb <= 0.05 else 'NOT met'}; "
          f"max |x_rk4 - x_lsoda| = {err:.2e} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
