"""A load force on every plant: analytic steady deviations on the linear plants, scipy's ZOH
for their force response, the small-signal plant against the nonlinear one, and batches
against single runs (docs/model.md, "Load force on the linear models")."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from fuzzyservo.paper.published import named_set
from fuzzyservo.plant import linearize
from fuzzyservo.registry import build_controller, build_plant, controller_kind
from fuzzyservo.run import RunSpec
from fuzzyservo.sim import simulate, simulate_batch
from fuzzyservo.sim.disturbances import load_force_samples, parse_load_force
from fuzzyservo.sim.references import Step

#: the nonlinear effects the linearisations leave out, off, so that only the model's
#: nonlinearity in the force separates the two
CLEAN = (("load.coulomb_friction", 0.0), ("load.static_friction", 0.0),
         ("transducer.resolution", 0.0), ("supply.ripple_amplitude", 0.0))


@pytest.mark.parametrize("plant", ["linear", "small-signal"])
def test_p_control_steady_error_is_the_analytic_droop(plant: str) -> None:
    """Integrating plant under P control: the force's creep -K_f F is cancelled by
    K_o K_p e, so e = K_f F / (K_p K_o) with K_f = K_ce/A² (Linearization.load_compliance)."""
    kp, force = 10.0, 1000.0
    params = named_set("paper")
    lin = linearize(params, 0.5 * params.cylinder.stroke)
    k_o = params.velocity_gain if plant == "linear" else lin.velocity_gain
    spec = RunSpec(controller="p", gains=(("kp", kp),), plant=plant, reference="step:0",
                   duration=30.0, load_force=f"step:{force}:0.5")
    res = spec.run()
    e_ss = lin.load_compliance * force / (kp * k_o)
    assert e_ss > 1e-5  # a deviation the test can see
    # the slowest closed-loop mode is the hydraulic pair, decaying at 0.63 /s under this P
    # (eigenvalues of A - K_p B C): 29.5 s after the step it is below exp(-18) ~ 2e-8
    assert res.r[-1] - res.y[-1] == pytest.approx(e_ss, rel=1e-5)
    assert res.y[-1] < res.y[0]  # a positive force opposes extension: pushed back


@pytest.mark.parametrize("plant", ["linear", "small-signal"])
def test_force_response_is_scipys_zoh(plant: str) -> None:
    """LinearPlant.force_response against scipy's ZOH discretisation and dlsim of (A, E, C)."""
    lp = build_plant(plant, "paper")
    ts = 1e-3
    t = np.arange(400) * ts
    force = lp.force_op + load_force_samples(parse_load_force("pwl:0:0,0.1:500,0.3:-200"), t)
    y_f, x_f = lp.force_response(force, ts)
    ad, bd, cd, dd, _ = signal.cont2discrete((lp.a, lp.e[:, None], lp.c[None, :],
                                              np.zeros((1, 1))), ts, method="zoh")
    _, y_ref, x_ref = signal.dlsim((ad, bd, cd, dd, ts), force - lp.force_op)
    scale = float(np.max(np.abs(y_ref)))
    assert scale > 1e-6
    # two matrix exponentials (Padé-13 and scipy's): agree to ~1e-12 relative per step
    np.testing.assert_allclose(y_f, y_ref[:, 0], rtol=0, atol=1e-9 * scale)
    col = np.max(np.abs(x_ref), axis=0) + 1e-300
    np.testing.assert_allclose(x_f / col, x_ref / col, rtol=0, atol=1e-9)


def test_kept_states_include_the_force_part() -> None:
    """On a linear plant y = C x holds for the kept states with a force (superposition is
    applied to both)."""
    res = RunSpec(controller="pi", gains=(("kp", 10.0), ("ki", 2.0)), plant="small-signal",
                  duration=0.5, load_force="step:800:0.1").run()
    c = build_plant("small-signal", "paper").c
    y_from_x = res.x @ c
    np.testing.assert_allclose(res.y, y_from_x, rtol=0, atol=1e-12)  # rounding of sums


def test_small_signal_agrees_with_nonlinear_to_first_order() -> None:
    """The force's effect on the small-signal plant differs from the nonlinear plant's by a
    relative amount that shrinks linearly with the force (the linearisation's order)."""
    def dev(plant: str, lf: str) -> np.ndarray:
        spec = RunSpec(controller="pi", gains=(("kp", 10.0), ("ki", 2.0)), plant=plant,
                       overrides=CLEAN, reference="step:0", duration=1.0, load_force=lf,
                       substep=1e-4)
        return np.asarray(spec.run().y)

    base = {p: dev(p, "") for p in ("small-signal", "nonlinear")}
    eps = []
    for force in (100.0, 200.0, 400.0):
        d = {p: dev(p, f"step:{force}:0.1") - base[p] for p in base}
        eps.append(float(np.max(np.abs(d["nonlinear"] - d["small-signal"]))
                         / np.max(np.abs(d["small-signal"]))))
    assert eps[0] < 3e-3  # 0.14 % measured at 100 N
    for a, b in zip(eps, eps[1:], strict=False):
        assert 1.8 < b / a < 2.2  # doubling the force doubles the relative difference


@pytest.mark.parametrize("plant", ["linear", "nonlinear"])
def test_batch_with_a_force_per_run_is_each_run(plant: str) -> None:
    """simulate_batch with one force row per run gives each run's simulate bit for bit."""
    ctl = build_controller("pi", {"kp": 10.0, "ki": 2.0}, dt=1e-3)
    pl = build_plant(plant, "paper")
    t = np.arange(301) * 1e-3
    base = named_set("paper").load.external_force
    rows = np.vstack([load_force_samples(parse_load_force(s), t, base)
                      for s in ("step:300:0.05", "step:-200:0.1", "step:300:0.05")])
    gains = np.array([[10.0, 2.0], [12.0, 1.0], [8.0, 3.0]])
    kind = controller_kind("pi")
    rows_g = np.vstack([kind.class_row({"kp": kp, "ki": ki}) for kp, ki in gains])
    res = simulate_batch(ctl, rows_g, plant=pl, reference=Step(0.01), duration=0.3,
                         disturbance=rows, keep_traces=True)
    for i in range(3):
        one = simulate(build_controller("pi", {"kp": gains[i, 0], "ki": gains[i, 1]},
                                        dt=1e-3),
                       pl, "step:0.01", duration=0.3, disturbance=rows[i])
        assert np.array_equal(res.y[i], one.y) and np.array_equal(res.u[i], one.u)
        assert np.array_equal(res.metrics[i], list(one.metrics().as_dict().values()),
                              equal_nan=True)


def test_no_force_is_the_run_of_before() -> None:
    """An empty load force passes no disturbance: the same samples as a run without one."""
    spec = RunSpec(controller="pi", gains=(("kp", 10.0), ("ki", 2.0)), plant="linear",
                   duration=0.3)
    built = spec.build()
    assert built.disturbance() is None
    a = spec.run()
    b = simulate(built.controller, built.plant, "step:0.1", duration=0.3)
    assert np.array_equal(a.y, b.y)
