"""Closed-loop simulator against independent discrete-time references."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import control
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fuzzyservo.control import PIDController, SelfTuningFuzzyPIController, p_controller
from fuzzyservo.errors import InputError, ParameterError, SimulationDivergedError
from fuzzyservo.paper import alpha_system, du_system, paper_params
from fuzzyservo.plant import LinearServo, linearize
from fuzzyservo.sim.closed_loop import LinearPlant, NonlinearPlant, simulate
from fuzzyservo.sim.references import (
    MultiStep,
    Ramp,
    Sine,
    Step,
    Trapezoid,
    UserReference,
    parse_reference,
)

H = 1e-3


@pytest.fixture(scope="module")
def servo() -> LinearServo:
    params = paper_params()
    return LinearServo.from_params(params, linearize(params))


def _control_reference(servo: LinearServo, ctl: PIDController, r: np.ndarray, d: int
                       ) -> np.ndarray:
    """python-control: plant by ZOH (c2d), z^-d delay, the PID's backward-Euler TFs."""
    a, b, c, dd = servo.state_space()
    pd = control.c2d(control.ss(a, b, c, dd), H, "zoh")
    if d:
        pd = pd * control.tf([1.0], [1.0] + [0.0] * d, H)
    h, n = H, ctl.n
    ad, bd = 1.0 / (1.0 + n * h), ctl.kd * n / (1.0 + n * h)
    integ = control.tf([ctl.ki * h, 0.0], [1.0, -1.0], h)
    deriv = control.tf([bd, -bd], [1.0, -ad], h)
    cy = ctl.kp + integ + deriv
    cr = ctl.kp * ctl.b + integ + ctl.c * deriv
    loop = control.feedback(pd, control.ss(cy)) * control.ss(cr)
    resp = control.forced_response(control.ss(loop), T=np.arange(r.size) * H, U=r)
    return np.asarray(resp.outputs).ravel()


@pytest.mark.parametrize(
    ("ctl", "delay_steps"),
    [(p_controller(dt=H, kp=8.0, u_min=-1e6, u_max=1e6), 0),
     (PIDController(dt=H, kp=8.0, ki=2.0, kd=0.2, n=100.0, u_min=-1e6, u_max=1e6), 0),
     (PIDController(dt=H, kp=6.0, ki=1.0, kd=0.1, n=200.0, b=0.5, c=0.0, u_min=-1e6,
                    u_max=1e6), 6)],
)
def test_linear_plant_matches_python_control(servo: LinearServo, ctl: PIDController,
                                             delay_steps: int) -> None:
    res = simulate(ctl, LinearPlant.from_servo(servo), Step(0.1), duration=3.0,
                   delay=delay_steps * H)
    ref = _control_reference(servo, ctl, res.r, delay_steps)
    scale = np.max(np.abs(ref))
    # both are exact ZOH recursions; differences are rounding, far below 1e-9 of the signal
    assert np.max(np.abs(res.y - ref)) <= 1e-9 * scale


def test_fractional_delay_is_exact_against_solve_ivp(servo: LinearServo) -> None:
    """The plant input is u_{k-d-1} on [t_k, t_k + f) and u_{k-d} after: integrate that."""
    ts, delay = 5e-3, 0.0137  # d = 2, f = 3.7 ms
    ctl = PIDController(dt=ts, kp=5.0, ki=1.0, kd=0.05)
    plant = LinearPlant.from_servo(servo)
    res = simulate(ctl, plant, Step(0.05), duration=0.4, delay=delay)
    d, f = 2, delay - 2 * ts
    x = np.zeros(plant.n_states)
    ys = [0.0]
    for k in range(res.t.size - 1):
        u1 = res.u[k - d - 1] if k - d - 1 >= 0 else 0.0
        u0 = res.u[k - d] if k - d >= 0 else 0.0
        for t0, t1, u in ((0.0, f, u1), (f, ts, u0)):
            sol = solve_ivp(lambda _t, z, u=u: plant.a @ z + plant.b * u, (t0, t1), x,
                            rtol=1e-12, atol=1e-15, method="DOP853")
            x = sol.y[:, -1]
        ys.append(float(plant.c @ x))
    # solve_ivp at rtol 1e-12; the response is 0.05 m: 1e-9 relative of the step
    assert np.max(np.abs(res.y - np.array(ys))) <= 1e-9 * 0.05
    assert np.array_equal(res.x[:, -1], res.y)  # noise-free: y is the position state


def test_timing_of_rows_and_csv(servo: LinearServo, tmp_path: Path) -> None:
    ctl = p_controller(dt=H, kp=2.0)
    res = simulate(ctl, LinearPlant.from_servo(servo), Step(0.1, 0.01), duration=0.05)
    assert res.t.size == 51 and res.t[-1] == pytest.approx(0.05, abs=1e-15)  # exact grid
    assert np.all(res.u == np.clip(2.0 * (res.r - res.y), -1, 1))  # u_k from y_k at t_k
    assert res.y[0] == 0.0 and res.r[9] == 0.0 and res.r[10] == 0.1
    out = tmp_path / "run.csv"
    res.to_csv(out)
    with out.open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0][:5] == ["t", "r", "y", "u", "alpha"]
    assert rows[0][5:] == list(res.state_names)
    assert float(rows[11][3]) == res.u[10]  # repr round-trips floats exactly
    assert math.isnan(float(rows[1][4]))  # α is undefined for the PID family


def test_noise_is_seeded_and_additive(servo: LinearServo) -> None:
    ctl = p_controller(dt=H, kp=2.0)
    plant = LinearPlant.from_servo(servo)
    kw = {"duration": 0.2, "noise_std": 1e-4}
    a = simulate(ctl, plant, Step(0.1), rng=np.random.default_rng(5), **kw)  # type: ignore[arg-type]
    b = simulate(ctl, plant, Step(0.1), rng=np.random.default_rng(5), **kw)  # type: ignore[arg-type]
    assert np.array_equal(a.y, b.y)
    noise = np.random.default_rng(5).normal(0.0, 1e-4, a.t.size)
    assert a.y - a.x[:, -1] == pytest.approx(noise, abs=1e-15)  # y = C x + n, rounding only
    with pytest.raises(ParameterError, match="Generator"):
        simulate(ctl, plant, Step(0.1), duration=0.1, noise_std=1e-4)


def test_divergence_names_time_and_state() -> None:
    plant = LinearPlant.from_state_space([[60.0]], [1.0], [1.0], state_names=("z",))
    # e^{60 t} overflows a float after about 11.8 s
    with pytest.raises(SimulationDivergedError, match=r"t = 1\d\.\d+ s: state z=inf"):
        simulate(p_controller(dt=0.01, kp=1.0), plant, Step(0.1), duration=20.0)


def test_nonlinear_plant_tracks_and_load_force_pushes_back() -> None:
    params = paper_params()
    plant = NonlinearPlant.from_params(params)
    ctl = SelfTuningFuzzyPIController.from_systems(du_system(), alpha_system(), dt=H, ke=10.0,
                                                   kde=5000.0, kdu=0.006)
    res = simulate(ctl, plant, Step(0.05), duration=1.5, delay=0.006)
    assert res.y[0] == pytest.approx(0.5 * params.cylinder.stroke, abs=1e-12)  # mid-stroke
    assert np.all((res.alpha >= 1 / 18 - 1e-12) & (res.alpha <= 17 / 18 + 1e-12))
    assert res.y[-1] > res.y[0] + 0.02  # moves towards the target
    p_ctl = p_controller(dt=H, kp=20.0)
    free = simulate(p_ctl, plant, Step(0.0), duration=0.5)
    force = np.where(np.arange(free.t.size) * H >= 0.1, 2e4, 0.0)
    loaded = simulate(p_ctl, plant, Step(0.0), duration=0.5, disturbance=force)
    assert abs(free.y[-1] - free.y[0]) < 1e-6  # trimmed: stays put
    assert loaded.y[-1] < free.y[-1] - 1e-5  # a force opposing extension pushes it back


@pytest.mark.parametrize("which", ["stfpi", "pid"])
def test_default_substep_is_accurate(which: str) -> None:
    """The closed loop's default RK4 step (0.5 ms) against 25 µs steps, 0.1 m step, 6 ms."""
    params = paper_params()
    ctl = (SelfTuningFuzzyPIController.from_systems(du_system(), alpha_system(), dt=H,
                                                    ke=10.0, kde=5000.0, kdu=0.006)
           if which == "stfpi" else PIDController(dt=H, kp=20.0, ki=5.0, kd=0.5))
    coarse = simulate(ctl, NonlinearPlant.from_params(params), Step(0.1), duration=2.0,
                      delay=0.006)
    fine = simulate(ctl, NonlinearPlant.from_params(params, substep=2.5e-5), Step(0.1),
                    duration=2.0, delay=0.0063)
    fine_same = simulate(ctl, NonlinearPlant.from_params(params, substep=2.5e-5), Step(0.1),
                         duration=2.0, delay=0.006)
    assert np.max(np.abs(coarse.y - fine_same.y)) <= 1e-6 * 0.1  # RK4 error, documented
    assert np.max(np.abs(fine.y - fine_same.y)) > 1e-5  # the check can see a 0.3 ms change


def test_reference_shapes() -> None:
    t = np.linspace(0.0, 4.0, 4001)
    assert Step(0.2, 1.0).values(t)[[999, 1000]] == pytest.approx([0.0, 0.2], abs=0)
    ms = MultiStep((0.5, 2.0), (0.1, -0.05)).values(t)
    assert ms[[0, 500, 1999, 2000]] == pytest.approx([0, 0.1, 0.1, -0.05], abs=0)
    assert Ramp(0.1, 1.0, 0.15).values(t)[[1000, 2000, 3000]] == pytest.approx(
        [0.0, 0.1, 0.15], abs=1e-15)  # exact up to rounding
    assert Sine(0.1, 0.5).values(np.array([0.5]))[0] == pytest.approx(0.1, rel=1e-15)
    tr = Trapezoid(0.3, 0.2, 0.4).values(t)
    v = np.diff(tr) / np.diff(t)
    assert tr[-1] == pytest.approx(0.3, abs=1e-15) and np.max(v) <= 0.2 + 1e-9
    assert np.max(np.abs(np.diff(v))) / 1e-3 <= 0.4 + 1e-6  # |a| <= a_max up to rounding
    short = Trapezoid(0.01, 1.0, 1.0).values(t)  # triangular: peak speed sqrt(d a) = 0.1
    assert np.max(np.diff(short) / 1e-3) == pytest.approx(0.1, abs=1e-3)  # one-sample lag
    user = UserReference(np.array([0.0, 1.0]), np.array([0.0, 0.2])).values(t)
    assert user[500] == pytest.approx(0.1, rel=1e-12) and user[-1] == 0.2
    assert parse_reference("step:0.1") == Step(0.1)
    assert parse_reference("ramp:0.05:1") == Ramp(0.05, 1.0)
    assert parse_reference("multistep:0=0.1,2=0.05") == MultiStep((0.0, 2.0), (0.1, 0.05))


@pytest.mark.parametrize("spec", ["step:nan", "step:inf", "ramp:x", "wave:1", "sine:1",
                                  "multistep:1:2", "trapezoid:0.1:0:1"])
def test_bad_references_raise(spec: str) -> None:
    with pytest.raises(InputError):
        parse_reference(spec)


@pytest.mark.parametrize(
    ("kw", "match"),
    [({"duration": 0.0005}, "duration"), ({"duration": 1.0, "delay": -0.01}, "delay"),
     ({"duration": math.nan}, "duration")],
)
def test_bad_run_parameters_raise(servo: LinearServo, kw: dict[str, float], match: str
                                  ) -> None:
    with pytest.raises(ParameterError, match=match):
        simulate(p_controller(dt=H, kp=1.0), LinearPlant.from_servo(servo), Step(0.1), **kw)


@pytest.mark.parametrize("h", [1e-4, 1e-3, 3.7e-3, 1e-2])
def test_matrix_exponential_matches_scipy(servo: LinearServo, h: float) -> None:
    from scipy.linalg import expm

    from fuzzyservo.plant.zoh import expm as expm_pade13

    a, b, _, _ = servo.state_space()
    n = a.shape[0]
    m = np.zeros((n + 1, n + 1))
    m[:n, :n], m[:n, n] = a * h, b[:, 0] * h
    mats = [m, *np.random.default_rng(4).normal(scale=3.0, size=(3, 6, 6))]
    for mat in mats:
        ref = expm(mat)
        # same algorithm family (Higham 2005); differences are rounding
        assert np.max(np.abs(expm_pade13(mat) - ref)) <= 1e-13 * np.max(np.abs(ref))


def test_a_delay_as_long_as_the_run_never_reaches_the_plant(servo: LinearServo) -> None:
    """The command buffer is sized by the run, not by the delay: a delay of the whole run
    holds the plant at its start command throughout (issue 8 review). ``simulate`` refuses a
    longer one (issue 9, row 9); the batch kernels still cap it, 1e9 s costing nothing."""
    from fuzzyservo.paper import paper_params
    from fuzzyservo.registry import build_plant
    from fuzzyservo.sim import simulate_batch

    ctl = PIDController(dt=H, kp=8.0, ki=1.0, kd=0.01)
    for plant in (LinearPlant.from_servo(servo, 0.5), build_plant("nonlinear", paper_params())):
        with pytest.raises(ParameterError, match=r"delay 1000000000\.0 s is longer than the "
                                                 r"run \(0\.5 s\)"):
            simulate(ctl, plant, Step(0.1), duration=0.5, delay=1e9)
        res = simulate(ctl, plant, Step(0.1), duration=0.5, delay=0.5)
        assert np.all(res.y == plant.y0)  # exactly at rest: the trim command is held
        # the error never shrinks: u_k = u0 + kp e + ki h (k + 1) e, the derivative kick of
        # the first sample decayed by (1 + N h)^-500 (1e-21); rounding of the sum only
        assert res.u[-1] == pytest.approx(plant.u0 + 8.0 * 0.1 + 1.0 * 1e-3 * 501 * 0.1,
                                          abs=1e-12)
        b = simulate_batch(ctl, plant=plant, reference=Step(0.1), duration=0.5,
                           delay=[0.0, 1e9], keep_traces=True)
        assert b.y is not None and np.array_equal(b.y[1], res.y)
        assert b.y[0, -1] > plant.y0  # without the delay it moves
