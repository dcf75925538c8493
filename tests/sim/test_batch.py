"""Batched closed loop: equal to the per-step APIs and to single runs; metrics per run."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest

from fuzzyservo.control import PIDController, SelfTuningFuzzyPIController
from fuzzyservo.errors import InputError, ParameterError
from fuzzyservo.paper import alpha_system, du_system, paper_params
from fuzzyservo.plant import LinearServo, NonlinearServo, linearize
from fuzzyservo.sim import (
    METRIC_NAMES,
    LinearPlant,
    NonlinearPlant,
    Step,
    simulate,
    simulate_batch,
    step_metrics_core,
)
from fuzzyservo.sim.stepinfo import TAIL_NAMES, tail_oscillation_core

H = 1e-3


def _stfpi(kdu: float = 0.006) -> SelfTuningFuzzyPIController:
    return SelfTuningFuzzyPIController.from_systems(du_system(), alpha_system(), dt=H, ke=10.0,
                                                    kde=5000.0, kdu=kdu)


@pytest.fixture(scope="module")
def servo() -> LinearServo:
    params = paper_params()
    return LinearServo.from_params(params, linearize(params))


def test_batch_equals_per_step_api_on_linear_plant(servo: LinearServo) -> None:
    """5 s, self-tuning fuzzy PI, 6 ms delay: controller.step() plus the plant's own ZOH
    matrices (LinearServo.discretize) in a Python loop against the compiled batch kernel."""
    ctl = _stfpi()
    res = simulate_batch(ctl, plant=LinearPlant.from_servo(servo), reference=Step(0.1),
                         duration=5.0, delay=0.006, keep_traces=True)
    m = servo.discretize(H)
    phi, gam, c = m.phi, m.gamma, servo.state_space()[2]
    x = np.zeros(phi.shape[0])
    s = ctl.initial_state()
    fifo: deque[float] = deque([0.0] * 6)
    ys, alphas = [], []
    for _k in range(res.t.size):
        y = float((c @ x)[0])
        u, s = ctl.step(s, 0.1, y)
        fifo.append(u)
        x = phi @ x + gam * fifo.popleft()
        ys.append(y)
        alphas.append(s.alpha)
    assert res.y is not None and res.alpha is not None
    # two ZOH computations of the same plant (expm rounding): equal to 1e-12 of the step
    assert np.max(np.abs(res.y[0] - ys)) <= 1e-12 * 0.1
    assert np.max(np.abs(res.alpha[0] - alphas)) <= 1e-12  # α on equal inputs
    assert np.all((res.alpha >= 1 / 18 - 1e-12) & (res.alpha <= 17 / 18 + 1e-12))


def test_batch_equals_per_step_api_on_nonlinear_plant() -> None:
    """5 s on the nonlinear model: NonlinearServo.step (the plant's per-step API) and
    controller.step in Python against the batch kernel, 6 ms delay as a FIFO of commands."""
    params = paper_params()
    plant = NonlinearPlant.from_params(params)
    ctl = _stfpi()
    res = simulate_batch(ctl, plant=plant, reference=Step(0.05), duration=5.0, delay=0.006,
                         keep_traces=True)
    servo = NonlinearServo(params, substep=plant.substep)
    x = plant.x0.copy()
    s = ctl.initial_state(u0=plant.u0)
    fifo: deque[float] = deque([plant.u0] * 6)
    ys = []
    r = plant.y0 + 0.05
    for k in range(res.t.size):
        y = float(x[5])
        u, s = ctl.step(s, r, y)
        fifo.append(u)
        x = servo.step(k * H, x, fifo.popleft(), H)
        ys.append(y)
    assert res.y is not None
    # the same njit functions on the same floats: agreement to 1e-12 of the 0.05 m step
    assert np.max(np.abs(res.y[0] - ys)) <= 1e-12 * 0.05


def test_rows_equal_single_runs_and_metrics_equal_the_core(servo: LinearServo) -> None:
    base = PIDController(dt=H, kp=5.0, ki=1.0, kd=0.1, b=0.5, c=0.0)
    gains = np.array([[5.0, 1.0, 0.1, 100.0, 0.5, 0.0], [8.0, 0.5, 0.0, 50.0, 0.0, 0.0],
                      [3.0, 2.0, 0.2, 20.0, 1.0, 1.0]])
    fast = LinearServo(K_o=servo.K_o * 1.5, omega_0=servo.omega_0, damping=servo.damping,
                       omega_v=servo.omega_v, zeta_v=servo.zeta_v)
    plants = [LinearPlant.from_servo(servo), LinearPlant.from_servo(fast),
              LinearPlant.from_servo(servo)]
    delays = np.array([0.0, 0.0065, 0.012])
    res = simulate_batch(base, gains, plant=plants, reference=Step(0.1), duration=2.0,
                         delay=delays, keep_traces=True)
    assert res.y is not None and res.u is not None
    for i in range(3):
        kp, ki, kd, n, b, c = gains[i]
        ctl = PIDController(dt=H, kp=kp, ki=ki, kd=kd, n=n, b=b, c=c)
        one = simulate(ctl, plants[i], Step(0.1), duration=2.0, delay=float(delays[i]))
        assert np.array_equal(one.y, res.y[i]) and np.array_equal(one.u, res.u[i])
        out = np.empty(len(METRIC_NAMES))
        step_metrics_core(one.t, one.y, one.u, one.r, 0.0, 0.1, 0.1, 0.9, 0.02, 0.05, out)
        assert np.array_equal(out, res.metrics[i], equal_nan=True)
    lean = simulate_batch(base, gains, plant=plants, reference=Step(0.1), duration=2.0,
                          delay=delays)
    assert lean.y is None and np.array_equal(lean.metrics, res.metrics, equal_nan=True)
    assert res.metric("overshoot").shape == (3,)


def test_self_tuning_batch_over_gains_on_two_threads(servo: LinearServo) -> None:
    ctl = _stfpi()
    gains = np.column_stack([np.full(40, 10.0), np.full(40, 5000.0),
                             np.linspace(0.001, 0.02, 40)])
    res = simulate_batch(ctl, gains, plant=LinearPlant.from_servo(servo), reference=Step(0.1),
                         duration=1.0)
    for i in (0, 17, 39):  # rows spread over both threads' chunks
        one = simulate(_stfpi(float(gains[i, 2])), LinearPlant.from_servo(servo), Step(0.1),
                       duration=1.0)
        out = np.empty(len(METRIC_NAMES))
        step_metrics_core(one.t, one.y, one.u, one.r, 0.0, 0.1, 0.1, 0.9, 0.02, 0.05, out)
        assert np.array_equal(out, res.metrics[i], equal_nan=True)


def test_diverged_runs_are_flagged_not_raised() -> None:
    plant = LinearPlant.from_state_space([[60.0]], [1.0], [1.0])
    ctl = PIDController(dt=0.01, kp=1.0)
    res = simulate_batch(ctl, np.array([[1.0, 0, 0, 100, 1, 1]] * 2), plant=plant,
                         reference=Step(0.1), duration=20.0)
    assert res.diverged.tolist() == [True, True] and np.all(np.isnan(res.metrics))


@pytest.mark.parametrize(
    ("gains", "match"),
    [(np.array([[1.0, -1.0, 0.0, 100.0, 1.0, 1.0]]), "gain ki"),
     (np.array([[1.0, 1.0, 0.0]]), "columns"),
     (np.array([[1.0, np.inf, 0.0, 100.0, 1.0, 1.0]]), "gain ki")],
)
def test_bad_gains_raise(servo: LinearServo, gains: np.ndarray, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        simulate_batch(PIDController(dt=H, kp=1.0), gains, plant=LinearPlant.from_servo(servo),
                       reference=Step(0.1), duration=0.1)


def test_mismatched_counts_raise(servo: LinearServo) -> None:
    plant = LinearPlant.from_servo(servo)
    with pytest.raises(ParameterError, match="plants"):
        simulate_batch(PIDController(dt=H, kp=1.0), np.ones((3, 6)), plant=[plant, plant],
                       reference=Step(0.1), duration=0.1)
    with pytest.raises(ParameterError, match="delay"):
        simulate_batch(PIDController(dt=H, kp=1.0), np.ones((3, 6)), plant=plant,
                       reference=Step(0.1), duration=0.1, delay=[0.0, 0.1])


# ------------------------------------------------- explicit noise, references per run, the tail
def _same_run(res: object, i: int, one: object) -> None:
    """Row i of a batch (traces kept) equals a single run bit for bit: y, u, α, metrics."""
    assert np.array_equal(res.y[i], one.y) and np.array_equal(res.u[i], one.u)  # type: ignore
    assert np.array_equal(res.alpha[i], one.alpha, equal_nan=True)  # type: ignore
    ref = np.array([one.metrics()[n] for n in METRIC_NAMES])  # type: ignore
    assert np.array_equal(res.metrics[i], ref, equal_nan=True)  # type: ignore


@pytest.mark.parametrize("kind", ["linear", "nonlinear"])
def test_noise_rows_reproduce_seeded_single_runs(servo: LinearServo, kind: str) -> None:
    """Run i's noise as the sweep draws it, default_rng(seed_i).normal(0, std_i, n): the batch
    row equals simulate(noise_std=std_i, rng=default_rng(seed_i)) in y, u, α and metrics
    (measured from the noisy first sample, as SimResult.metrics is)."""
    plant = (LinearPlant.from_servo(servo, 0.2) if kind == "linear"
             else NonlinearPlant.from_params(paper_params()))
    ctl = _stfpi()
    dur = 1.0
    n = round(dur / H) + 1
    stds, seeds = [1e-4, 0.0, 3e-5], [7, 0, 123]
    noise = np.vstack([np.random.default_rng(sd).normal(0.0, sd_std, size=n)
                       for sd, sd_std in zip(seeds, stds, strict=True)])
    gains = np.array([[10.0, 5000.0, 0.006], [12.0, 4000.0, 0.004], [8.0, 6000.0, 0.008]])
    res = simulate_batch(ctl, gains, plant=plant, reference=Step(0.05), duration=dur,
                         delay=0.0063, noise=noise, keep_traces=True)
    for i in range(3):
        ctl_i = SelfTuningFuzzyPIController.from_systems(
            du_system(), alpha_system(), dt=H, ke=gains[i, 0], kde=gains[i, 1], kdu=gains[i, 2])
        one = simulate(ctl_i, plant, Step(0.05), duration=dur, delay=0.0063,
                       noise_std=stds[i], rng=np.random.default_rng(seeds[i]))
        _same_run(res, i, one)
    # one row shared by every run
    shared = simulate_batch(ctl, gains, plant=plant, reference=Step(0.05), duration=dur,
                            delay=0.0063, noise=noise[0], keep_traces=True)
    assert shared.y is not None and res.y is not None
    assert np.array_equal(shared.y[0], res.y[0])
    assert not np.array_equal(shared.y[2], res.y[2])


def test_noise_is_validated(servo: LinearServo) -> None:
    plant = LinearPlant.from_servo(servo)
    ctl = PIDController(dt=H, kp=1.0)
    kw = {"plant": plant, "reference": Step(0.1), "duration": 0.01}
    with pytest.raises(ParameterError, match="noise_std"):
        simulate_batch(ctl, noise=np.zeros(11), noise_std=1e-3,
                       rng=np.random.default_rng(0), **kw)
    bad = np.zeros((2, 11))
    bad[1, 4] = np.nan
    with pytest.raises(InputError, match="row 1 at sample 4"):
        simulate_batch(ctl, noise=bad, **kw)
    with pytest.raises(InputError, match="shape"):
        simulate_batch(ctl, noise=np.zeros((2, 10)), **kw)
    with pytest.raises(ParameterError, match="noise rows"):
        simulate_batch(ctl, np.ones((3, 6)), noise=np.zeros((2, 11)), **kw)


def test_reference_rows_equal_separate_runs(servo: LinearServo) -> None:
    """A (runs, n) reference: each row is that run's own offset, bit for bit as running it
    alone; rows count as runs."""
    plants = [LinearPlant.from_servo(servo, 0.1), NonlinearPlant.from_params(paper_params())]
    ctl = PIDController(dt=H, kp=8.0, ki=1.0, kd=0.1, b=0.0, c=0.0)
    t = np.arange(801) * H
    refs = np.vstack([0.05 * (t >= 0.1), 0.02 * np.sin(2 * np.pi * t), -0.03 * (t >= 0.0)])
    for plant in plants:
        res = simulate_batch(ctl, plant=plant, reference=refs, duration=0.8, delay=0.0025,
                             keep_traces=True)
        assert res.r.shape == refs.shape and res.y is not None
        for i in range(3):
            alone = simulate_batch(ctl, plant=plant, reference=refs[i], duration=0.8,
                                   delay=0.0025, keep_traces=True)
            assert alone.y is not None
            assert np.array_equal(alone.y[0], res.y[i])
            assert np.array_equal(alone.metrics[0], res.metrics[i], equal_nan=True)
            assert np.array_equal(alone.tail[0], res.tail[i], equal_nan=True)
    bad = refs.copy()
    bad[2, 7] = np.inf
    with pytest.raises(InputError, match="row 2 at sample 7"):
        simulate_batch(ctl, plant=plants[0], reference=bad, duration=0.8)
    with pytest.raises(InputError, match="runs, 801"):
        simulate_batch(ctl, plant=plants[0], reference=refs[:, :-1], duration=0.8)
    with pytest.raises(ParameterError, match="reference rows"):
        simulate_batch(ctl, np.ones((2, 6)), plant=plants[0], reference=refs, duration=0.8)


def test_tail_is_the_core_on_each_run_and_nan_when_diverged(servo: LinearServo) -> None:
    ctl = _stfpi()
    gains = np.column_stack([np.full(3, 10.0), np.full(3, 5000.0), [0.006, 0.03, 0.3]])
    for frac in (0.25, 0.6):
        res = simulate_batch(ctl, gains, plant=LinearPlant.from_servo(servo),
                             reference=Step(0.1), duration=3.0, delay=0.012, keep_traces=True,
                             tail_fraction=frac)
        assert res.tail_names == TAIL_NAMES and res.tail.shape == (3, len(TAIL_NAMES))
        assert res.y is not None
        for i in range(3):
            out = np.empty(len(TAIL_NAMES) + 1)
            tail_oscillation_core(res.t, res.y[i], frac, out)
            assert np.array_equal(res.tail[i], out[:-1], equal_nan=True)
            assert res.metric("tail_swings")[i] == out[1]
    assert np.any(res.tail[:, 1] >= 3)  # the hot gain oscillates: a period is measured
    plant = LinearPlant.from_state_space([[60.0]], [1.0], [1.0])
    div = simulate_batch(PIDController(dt=0.01, kp=1.0), plant=plant, reference=Step(0.1),
                         duration=20.0)
    assert div.diverged.all() and np.all(np.isnan(div.tail))
    with pytest.raises(ParameterError, match="tail_fraction"):
        simulate_batch(ctl, plant=plant, reference=Step(0.1), duration=1.0, tail_fraction=0.0)
