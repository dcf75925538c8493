"""The compiled loops are the per-step laws, bit for bit (issue 13: faster kernels, same numbers).

The loops inline the controllers' step on data pointers, unroll the linear plant's sums for up
to 8 states and pass the nonlinear plant's arrays to its RK4 as pointers. None of that may
change a bit: here the loops are checked against Python loops over the per-step APIs
(``controller.step``, the packed ZOH matrices summed in the documented order,
``NonlinearServo.step``), and the batch against single runs, with ``np.array_equal``.
"""

from __future__ import annotations

import dataclasses

import numba
import numpy as np
import pytest

from fuzzyservo.control import (
    FuzzyPIController,
    PIDController,
    SelfTuningFuzzyPIController,
)
from fuzzyservo.errors import SimulationDivergedError
from fuzzyservo.formats import read_system
from fuzzyservo.fuzzy.loop import loop_system
from fuzzyservo.paper import alpha_system, du_system, paper_params, system_file
from fuzzyservo.plant import LinearServo, NonlinearServo, linearize
from fuzzyservo.plant.zoh import split_delay
from fuzzyservo.registry import build_controller, build_plant
from fuzzyservo.sim import (
    METRIC_NAMES,
    LinearPlant,
    NonlinearPlant,
    Step,
    simulate,
    simulate_batch,
)
from fuzzyservo.sim.stepinfo import TAIL_NAMES, tail_oscillation_core

H = 1e-3


def _files() -> dict[str, object]:
    # the general evaluator in the loops (the shipped files also have the uniform-grid form)
    return {r: loop_system(read_system(system_file(r, "fll")), source=r, grid=False)
            for r in ("du", "alpha")}


CONTROLLERS = {
    "pid": lambda: PIDController(dt=H, kp=8.0, ki=2.0, kd=0.1, n=50.0, b=0.5, c=0.0),
    "pid-bc": lambda: PIDController(dt=H, kp=30.0, ki=40.0, kd=0.0, u_min=-0.4, u_max=0.6,
                                    anti_windup="back-calculation"),
    "pid-raw": lambda: PIDController(dt=H, kp=5.0, ki=1.0, kd=0.05, n=np.inf,
                                     anti_windup="none"),
    "fpi": lambda: FuzzyPIController.from_systems(du_system(), dt=H, ke=10.0, kde=5000.0,
                                                  kdu=0.01),
    "stfpi": lambda: SelfTuningFuzzyPIController.from_systems(
        du_system(), alpha_system(), dt=H, ke=10.0, kde=5000.0, kdu=0.006),
    "stfpi-options": lambda: SelfTuningFuzzyPIController.from_systems(
        du_system(), alpha_system(), dt=H, ke=12.0, kde=6.0, kdu=0.008, de_per="second",
        initial_error="first", filter_time=0.004),
    "stfpi-files": lambda: build_controller("stfpi", {"ke": 10.0, "kde": 5000.0, "kdu": 0.006},
                                            dt=H, systems=_files()),
}


def _stable_plant(n: int, seed: int) -> LinearPlant:
    """A stable n-state plant with an integrator-like slow mode (so loops move)."""
    rng = np.random.default_rng(seed)
    a = np.diag(-rng.uniform(2.0, 40.0, n)) + 0.3 * np.triu(rng.normal(size=(n, n)), 1)
    a[0, 0] = -0.05
    return LinearPlant.from_state_space(a, rng.normal(size=n) + 2.0, rng.normal(size=n) * 0.2
                                        + np.eye(n)[0], x_op=rng.normal(size=n) * 0.01,
                                        u0=0.01)


def _python_linear(ctl: object, plant: LinearPlant, r: np.ndarray, delay: float,
                   noise: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linear loop in Python floats: controller.step, y = y0 + sum C_i x_i in index order,
    x_i <- G0_i u0 + G1_i u1 + sum Phi_ij x_j in index order (sim.closed_loop's contract)."""
    lp = plant.discretize(H, delay).tolist()
    n, d = int(lp[0]), int(lp[1])
    phi, g0, g1, c = lp[2:2 + n * n], lp[2 + n * n:2 + n * n + n], \
        lp[2 + n * n + n:2 + n * n + 2 * n], lp[2 + n * n + 2 * n:]
    y0 = plant.y0
    state = ctl.initial_state(u0=plant.u0) if hasattr(ctl, "alpha_rules") else \
        ctl.initial_state(r0=y0, y0=y0, u0=plant.u0)  # type: ignore[attr-defined]
    x = [0.0] * n
    us: list[float] = []
    ys, alphas = [], []
    for k in range(r.size):
        y = y0
        for i in range(n):
            y += c[i] * x[i]
        if noise.size:
            y += float(noise[k])
        u, state = ctl.step(state, float(r[k]), y)  # type: ignore[attr-defined]
        ys.append(y)
        us.append(u)
        alphas.append(getattr(state, "alpha", np.nan))
        u0 = us[k - d] if k - d >= 0 else plant.u0
        u1 = us[k - d - 1] if k - d - 1 >= 0 else plant.u0
        u0 -= plant.u0
        u1 -= plant.u0
        xn = []
        for i in range(n):
            acc = g0[i] * u0 + g1[i] * u1
            for j in range(n):
                acc += phi[i * n + j] * x[j]
            xn.append(acc)
        x = xn
    return np.array(ys), np.array(us), np.array(alphas)


@pytest.mark.parametrize("n", [1, 2, 5, 6, 8, 9])
@pytest.mark.parametrize("name", ["pid", "stfpi", "stfpi-options"])
def test_linear_loop_is_the_per_step_api(n: int, name: str) -> None:
    """Every unrolled plant size (1..8) and the generic one (9); a fractional delay; noise."""
    ctl = CONTROLLERS[name]()
    plant = _stable_plant(n, seed=n)
    dur = 0.4
    t = np.arange(round(dur / H) + 1) * H
    noise = np.random.default_rng(n).normal(0.0, 1e-5, t.size)
    res = simulate(ctl, plant, Step(0.02, time=0.01), duration=dur, delay=0.0037,
                   noise_std=1e-5, rng=np.random.default_rng(n))
    y, u, alpha = _python_linear(ctl, plant, res.r, 0.0037, noise)
    assert np.array_equal(res.y, y) and np.array_equal(res.u, u)
    assert np.array_equal(res.alpha, alpha, equal_nan=True)
    assert np.ptp(res.u) > 0.0  # the loop moved


def test_paper_plant_loops_are_the_per_step_api() -> None:
    """The paper's linear servo (eq. 8) and its small-signal model with every controller."""
    params = paper_params()
    plants = [LinearPlant.from_servo(LinearServo.from_params(params, linearize(params)), 0.2),
              build_plant("small-signal", params)]
    for plant in plants:
        for name, make in CONTROLLERS.items():
            ctl = make()
            res = simulate(ctl, plant, Step(0.05), duration=0.6, delay=0.0063)
            y, u, alpha = _python_linear(ctl, plant, res.r, 0.0063, np.empty(0))
            assert np.array_equal(res.y, y) and np.array_equal(res.u, u), name
            assert np.array_equal(res.alpha, alpha, equal_nan=True), name


@pytest.mark.parametrize("name", ["pid", "stfpi", "stfpi-files"])
def test_nonlinear_loop_is_the_per_step_api(name: str) -> None:
    """NonlinearServo.step (rk4_advance_ws on arrays) and controller.step in Python against the
    compiled loop (rk4_steps on pointers), whole-sample delay, with a supply ripple (the sine
    the ripple-free plant skips) and without."""
    base = paper_params()
    rippled = dataclasses.replace(base, supply=dataclasses.replace(
        base.supply, ripple_amplitude=2.0e5))
    for params in (base, rippled):
        plant = NonlinearPlant.from_params(params, 0.4)
        ctl = CONTROLLERS[name]()
        res = simulate(ctl, plant, Step(0.03), duration=0.5, delay=0.004)
        servo = NonlinearServo(params, substep=plant.substep)
        x = plant.x0.copy()
        state = ctl.initial_state(u0=plant.u0) if hasattr(ctl, "alpha_rules") else \
            ctl.initial_state(r0=plant.y0, y0=plant.y0, u0=plant.u0)  # type: ignore
        d, f = split_delay(0.004, H)
        assert f == 0.0
        us: list[float] = []
        ys = []
        for k in range(res.t.size):
            y = float(x[5])
            u, state = ctl.step(state, float(res.r[k]), y)  # type: ignore[attr-defined]
            us.append(u)
            ys.append(y)
            x = servo.step(k * H, x, us[k - d] if k >= d else plant.u0, H)
        assert np.array_equal(res.y, ys) and np.array_equal(res.u, us)


def _batch_cases() -> list[tuple[str, str]]:
    return [(c, p) for c in ("pid", "pid-bc", "fpi", "stfpi", "stfpi-files")
            for p in ("linear", "nonlinear")]


@pytest.mark.parametrize(("name", "kind"), _batch_cases())
def test_batch_rows_are_single_runs(name: str, kind: str) -> None:
    """Per-run gains, plants, fractional delays and seeded noise rows; one run that diverges
    (flagged, NaN after its last good sample) while the others go on."""
    params = paper_params()
    ctl = CONTROLLERS[name]()
    if kind == "linear":
        servo = LinearServo.from_params(params, linearize(params))
        plants: list[object] = [LinearPlant.from_servo(servo, 0.1),
                                build_plant("small-signal", params),
                                LinearPlant.from_servo(servo, 0.3),
                                LinearPlant.from_state_space([[800.0]], [1.0], [1.0])]
        dur, ref = 1.2, Step(0.05)
    else:
        heavy = dataclasses.replace(params, load=dataclasses.replace(params.load,
                                                                     mass=3.0e4))
        light = dataclasses.replace(params, load=dataclasses.replace(
            params.load, mass=params.load.mass * 1e-6))
        plants = [NonlinearPlant.from_params(params), NonlinearPlant.from_params(heavy),
                  NonlinearPlant.from_params(params, 0.3, substep=3e-4),
                  NonlinearPlant.from_params(light, substep=1e-3)]
        dur, ref = 0.5, Step(0.02)
    base = np.array([getattr(ctl, g) for g in ctl.gain_names])
    rows = np.vstack([base, base * 1.3, base * 0.7, base])
    if name.startswith("pid"):
        rows[:, 3] = base[3]  # keep n
    delays = np.array([0.0, 0.0063, 0.0125, 0.002])
    n = round(dur / H) + 1
    seeds, stds = [11, 12, 13, 14], [2e-5, 0.0, 1e-5, 0.0]
    noise = np.vstack([np.random.default_rng(s).normal(0.0, sd, n)
                       for s, sd in zip(seeds, stds, strict=True)])
    # the four cases in six rotations (24 runs). The kernel makes min(runs, 4 x threads)
    # chunks and advances a chunk's runs two at a time: on one thread 4 chunks of 6 runs (all
    # in pairs; the diverging case is the first run of a pair and the second), on two 8 of 3
    # (a pair and one alone), whatever the machine's core count
    order = [(j + r) % 4 for r in range(6) for j in range(4)]
    results = []
    threads = numba.get_num_threads()
    try:
        for n_threads in (1, 2):
            numba.set_num_threads(min(n_threads, numba.config.NUMBA_NUM_THREADS))
            results.append(simulate_batch(
                ctl, rows[order], plant=[plants[j] for j in order], reference=ref,
                duration=dur, delay=delays[order], noise=noise[order],
                keep_traces=True))  # type: ignore[arg-type]
    finally:
        numba.set_num_threads(threads)
    res = results[0]
    for other in results[1:]:  # the same bits however the runs were grouped
        assert other.y is not None and other.u is not None
        assert np.array_equal(other.y, res.y, equal_nan=True)  # type: ignore[arg-type]
        assert np.array_equal(other.u, res.u, equal_nan=True)  # type: ignore[arg-type]
        assert np.array_equal(other.metrics, res.metrics, equal_nan=True)
        assert np.array_equal(other.tail, res.tail, equal_nan=True)
    assert res.y is not None and res.u is not None
    assert res.diverged.tolist() == [j == 3 for j in order]
    singles = []
    for i in range(3):
        one_ctl = dataclasses.replace(ctl, **dict(zip(ctl.gain_names, rows[i], strict=True)))
        one = simulate(one_ctl, plants[i], ref, duration=dur, delay=float(delays[i]),
                       noise_std=stds[i], rng=np.random.default_rng(seeds[i]))  # type: ignore
        singles.append(one)
    with pytest.raises(SimulationDivergedError):
        simulate(ctl, plants[3], ref, duration=dur, delay=float(delays[3]))  # type: ignore
    for row, j in enumerate(order):
        if j == 3:
            bad = np.flatnonzero(np.isnan(res.y[row]))
            assert bad.size and np.all(np.isnan(res.y[row, bad[0]:]))
            assert np.all(np.isfinite(res.y[row, :bad[0]]))
            assert np.all(np.isnan(res.metrics[row]))
            first = order.index(3)  # the same traces, in a pair or alone
            assert np.array_equal(res.y[row], res.y[first], equal_nan=True)
            assert np.array_equal(res.u[row], res.u[first], equal_nan=True)
            continue
        one = singles[j]
        assert np.array_equal(res.y[row], one.y) and np.array_equal(res.u[row], one.u)
        assert np.array_equal(res.alpha[row], one.alpha, equal_nan=True)  # type: ignore
        metrics = np.array([one.metrics()[m] for m in METRIC_NAMES])
        assert np.array_equal(res.metrics[row], metrics, equal_nan=True)
        tail = np.empty(len(TAIL_NAMES) + 1)
        tail_oscillation_core(one.t, one.y, 0.25, tail)
        assert np.array_equal(res.tail[row], tail[:-1], equal_nan=True)
