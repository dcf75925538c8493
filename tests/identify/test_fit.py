"""The fit's core (fuzzyservo.identify.fit) on data the project's own model made: exact
recovery without noise, the closed loop, the record round trip, the bootstrap's exact resume,
identifiability warnings and every refusal. The independent model's check is
test_independent.py; the noisy recovery statistics, benchmarks/identify.py."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from fuzzyservo.errors import InputError, ParameterError
from fuzzyservo.identify import FitSettings, identify, render_axis_toml
from fuzzyservo.paper.published import named_set
from fuzzyservo.plant import load_toml, with_overrides
from fuzzyservo.registry import build_controller, build_plant
from fuzzyservo.sim import simulate, simulate_open_loop
from fuzzyservo.sim.references import MultiStep

BASE = named_set("paper")
DT = 1e-3


def _command(n: int) -> np.ndarray:
    """Rest 0.2 s, then pulses of both signs and a short sweep."""
    t = np.arange(n) * DT
    u = np.zeros(n)
    u[(t >= 0.2) & (t < 0.5)] = 0.15
    u[(t >= 0.5) & (t < 0.8)] = -0.15
    m = t >= 1.0
    u[m] = 0.1 * np.sin(2 * np.pi * (2.0 * (t[m] - 1.0) + 4.0 * (t[m] - 1.0) ** 2))
    return u


def _open_loop_data(truth, duration=2.0, *, noise=0.0, seed=0, pressures=True):
    n = int(round(duration / DT)) + 1
    u = _command(n)
    plant = build_plant("nonlinear", truth, 0.5)
    run = simulate_open_loop(plant, u[:-1] + plant.u0, duration=duration, dt=DT,
                             delay=truth.delay.transport_delay)
    rng = np.random.default_rng(seed)

    def noisy(x):
        return x + (rng.normal(0.0, noise * np.std(x), x.size) if noise else 0.0)

    return SimpleNamespace(t=run.t, dt=DT, y=noisy(run.y), u=u + 0.02, r=None,
                           p_f=noisy(run.p_f) if pressures else None,
                           p_n=noisy(run.p_n) if pressures else None, flagged=None, rest=200,
                           digest="sha256:test", source="test")


def test_noise_free_open_loop_recovers_the_truth_exactly():
    truth = with_overrides(BASE, {"load.mass": 1.3 * BASE.load.mass, "valve.omega_v": 550.0})
    m = _open_loop_data(truth)
    res = identify(m, plant="nonlinear", params=BASE, fit=["load.mass", "valve.omega_v"],
                   settings=FitSettings(starts=1))
    # the data are the model's own output: the least-squares optimum is the truth, to the
    # solver's tolerances (xtol 1e-10 in log coordinates)
    np.testing.assert_allclose(res.estimate, [truth.load.mass, 550.0], rtol=1e-6)
    assert res.channels == ("y", "p_f", "p_n")
    assert res.params.load.mass == res.value("load.mass")
    assert res.units == ("kg", "rad/s")
    assert res.mode == "open loop" and res.position == pytest.approx(0.5, abs=1e-12)


def test_closed_loop_data_are_fitted_through_the_controller():
    truth = with_overrides(BASE, {"load.mass": 0.8 * BASE.load.mass})
    ctl = build_controller("pid", {"kp": 8.0, "ki": 1.0, "kd": 0.2}, dt=DT)
    plant = build_plant("nonlinear", truth, 0.5)
    run = simulate(ctl, plant, MultiStep(times=(0.1, 1.0), levels=(0.05, -0.02)), duration=2.0,
                   delay=truth.delay.transport_delay)
    m = SimpleNamespace(t=run.t, dt=DT, y=run.y, u=run.u, r=run.r, p_f=None, p_n=None,
                        flagged=None, rest=100)
    res = identify(m, plant="nonlinear", params=BASE, fit=["load.mass"], controller=ctl,
                   settings=FitSettings(starts=1))
    assert res.mode == "closed loop"
    np.testing.assert_allclose(res.estimate, [truth.load.mass], rtol=1e-6)


def test_a_feed_forward_law_on_steps_gets_the_steps_exact_rates():
    # simulate gives a multistep its exact rates, zero; differences of the logged samples
    # would make each jump a spike of velocity and acceleration the controller never saw
    truth = with_overrides(BASE, {"load.mass": 0.8 * BASE.load.mass})
    ctl = build_controller("ffpd", {}, dt=DT)
    plant = build_plant("nonlinear", truth, 0.5)
    run = simulate(ctl, plant, MultiStep(times=(0.1, 1.0), levels=(0.05, -0.02)),
                   duration=2.0, delay=truth.delay.transport_delay)
    m = SimpleNamespace(t=run.t, dt=DT, y=run.y, u=run.u, r=run.r, p_f=None, p_n=None,
                        flagged=None, rest=100)
    res = identify(m, plant="nonlinear", params=BASE, fit=["load.mass"], controller=ctl,
                   settings=FitSettings(starts=1))
    np.testing.assert_allclose(res.estimate, [truth.load.mass], rtol=1e-6)
    assert "the reference's rates for the feed-forward: zero (--reference-rates)" in res.notes
    spiked = identify(m, plant="nonlinear", params=BASE, fit=["load.mass"], controller=ctl,
                      reference_rates="difference", settings=FitSettings(starts=1))
    assert abs(spiked.value("load.mass") / truth.load.mass - 1.0) > 1e-3


def test_the_axis_file_gives_the_identified_set_bit_for_bit(tmp_path):
    truth = with_overrides(BASE, {"load.mass": 1.1 * BASE.load.mass})
    res = identify(_open_loop_data(truth, noise=1e-3), plant="nonlinear", params=BASE,
                   fit=["load.mass"], settings=FitSettings(starts=1))
    text = render_axis_toml(res, data="rig.csv", digest="sha256:abc", command="fuzzyservo x",
                            base_set="paper", version="0")
    path = tmp_path / "axis.toml"
    path.write_text(text)
    # read over another set: the file lists every field, so the set is the identified one
    again = load_toml(path, named_set("stiff-oil"))
    assert again == res.params
    import tomllib

    rec = tomllib.loads(text)["identification"]
    assert rec["fitted"] == ["load.mass"] and rec["estimate"] == [res.value("load.mass")]
    assert rec["data_digest"] == "sha256:abc" and rec["command"] == "fuzzyservo x"
    assert rec["std_error"][0] == res.error("load.mass") > 0
    assert np.array(rec["correlation"]).shape == (1, 1)


def test_bootstrap_resumed_equals_the_uninterrupted_run():
    truth = with_overrides(BASE, {"load.mass": 1.1 * BASE.load.mass})
    m = _open_loop_data(truth, noise=2e-3, seed=3, pressures=False)
    cfg = FitSettings(starts=1, bootstrap=4, seed=5)
    saved = []
    full = identify(m, plant="nonlinear", params=BASE, fit=["load.mass"], settings=cfg,
                    checkpoint=lambda done: saved.append(done))
    assert [s.shape[0] for s in saved] == [1, 2, 3, 4]
    resumed = identify(m, plant="nonlinear", params=BASE, fit=["load.mass"], settings=cfg,
                       resume=saved[1])
    assert np.array_equal(full.bootstrap, resumed.bootstrap)
    assert np.array_equal(full.interval, resumed.interval)
    lo, hi = full.interval[0]
    assert lo <= full.value("load.mass") <= hi


def test_a_parameter_the_data_cannot_see_is_flagged_with_the_experiment_to_run():
    # the supply ripple's frequency does nothing without a ripple: its column of the Jacobian
    # is zero, its standard error unbounded
    m = _open_loop_data(BASE, pressures=False)
    res = identify(m, plant="nonlinear", params=BASE,
                   fit=["load.mass", "supply.ripple_frequency"],
                   settings=FitSettings(starts=1, max_nfev=5))
    lines = [w for w in res.warnings if w.startswith("supply.ripple_frequency does not act")]
    assert len(lines) == 1 and "hold it at a known value" in lines[0]
    assert res.std_error[1] == np.inf and np.isfinite(res.std_error[0])


def test_two_moduli_in_series_are_determined_only_together():
    # without hose, the oil's and the cylinder wall's moduli act only as the series
    # combination 1/(1/b_oil + 1/b_wall): the data cannot tell them apart, at any noise
    params = with_overrides(BASE, {"fluid.hose_volume": 0.0, "cylinder.dead_volume_f": 1e-3,
                                   "cylinder.dead_volume_n": 1e-3})
    m = _open_loop_data(params)
    res = identify(m, plant="nonlinear", params=params,
                   fit=["fluid.oil_bulk_modulus", "fluid.cylinder_wall_bulk_modulus"],
                   settings=FitSettings(starts=1, max_nfev=8))
    assert res.warnings == ("fluid.oil_bulk_modulus and fluid.cylinder_wall_bulk_modulus act "
                            "on these data only together (a combination of them is "
                            "determined, not each): fit one and hold the others at known "
                            "values (a datasheet's)",)
    assert np.all(res.std_error == np.inf)
    # the series modulus they make is what the data fix: the start's, exactly
    series = 1 / (1 / res.estimate[0] + 1 / res.estimate[1])
    assert series == pytest.approx(params.fluid.cylinder_bulk_modulus, rel=1e-6)


def test_the_warning_of_the_issue_for_position_alone():
    from fuzzyservo.identify import identifiability_warnings

    corr = np.array([[1.0, 0.97], [0.97, 1.0]])
    lines = identifiability_warnings(["load.mass", "fluid.oil_bulk_modulus"],
                                     np.array([1.5e4, 1.5e9]), np.array([300.0, 6e7]), corr,
                                     channels=("y",), omega_0=19.6, omega_v=688.7,
                                     excited=2.0)
    assert lines == ["load.mass and fluid.oil_bulk_modulus are not separable from position "
                     "alone (correlation +0.970; standard errors 2 % and 4 %, which include "
                     "it): log the chamber pressures (p_f, p_n) or excite above the hydraulic "
                     "natural frequency (3.12 Hz)"]
    # with pressures logged and the band above omega_h covered, more of the same data
    lines = identifiability_warnings(["load.mass", "fluid.oil_bulk_modulus"],
                                     np.array([1.5e4, 1.5e9]), np.array([300.0, 6e7]), corr,
                                     channels=("y", "p_f", "p_n"), omega_0=19.6,
                                     omega_v=688.7, excited=80.0)
    assert lines[0].endswith("log longer or with less noise (the standard errors shrink as "
                             "one over the square root of the samples)")


@pytest.mark.parametrize("kwargs, match", [
    ({"fit": ["load.nope"]}, "cannot fit unknown parameter 'load.nope'"),
    ({"fit": ["load.mass", "load.mass"]}, "names 'load.mass' twice"),
    ({"fit": []}, "names no parameter"),
    ({"fit": ["load.mass"], "bounds": {"valve.omega_v": (1.0, 2.0)}}, "not fitted"),
    ({"fit": ["load.mass"], "bounds": {"load.mass": (5.0, 1.0)}}, "LO < HI"),
    ({"fit": ["load.coulomb_friction"], "params": with_overrides(BASE, {
        "load.coulomb_friction": 0.0, "load.static_friction": 0.0})},
     "no default search interval; give one with --bounds load.coulomb_friction=LO:HI"),
    ({"fit": ["load.mass"], "plant": "stiff"}, "plant"),
])
def test_bad_arguments_are_refused_in_one_line(kwargs, match):
    args = {"plant": "nonlinear", "params": BASE} | kwargs
    with pytest.raises(ParameterError, match=match):
        identify(_open_loop_data(BASE, duration=1.5), **args)


def test_bad_data_are_refused_in_one_line():
    short = _open_loop_data(BASE, duration=0.6)
    with pytest.raises(InputError, match="too short for the fitted dynamics"):
        identify(short, plant="nonlinear", params=BASE, fit=["load.mass"])
    off = _open_loop_data(BASE, duration=1.5)
    off.y = off.y + 2.0
    with pytest.raises(InputError, match=r"outside the stroke .* \(--position-offset M\)"):
        identify(off, plant="nonlinear", params=BASE, fit=["load.mass"])
    no_u = _open_loop_data(BASE, duration=1.5)
    no_u.u = None
    with pytest.raises(InputError, match="needs the logged command"):
        identify(no_u, plant="nonlinear", params=BASE, fit=["load.mass"])
    with pytest.raises(InputError, match="cannot fit channel 'p_f'"):
        identify(_open_loop_data(BASE, duration=1.5, pressures=False), plant="nonlinear",
                 params=BASE, fit=["load.mass"], channels=["y", "p_f"])
    dead = _open_loop_data(BASE, duration=1.5, pressures=False)
    dead.y = np.full(dead.y.size, 0.5)
    with pytest.raises(InputError, match="position never moves .* dead sensor"):
        identify(dead, plant="nonlinear", params=BASE, fit=["load.mass"])
    with pytest.raises(ParameterError, match=r"bootstrap \(--bootstrap\) must be an integer >= 0"):
        FitSettings(bootstrap=-1)


def test_read_only_measurements_run_the_loops_compiled_for_simulate():
    # a Measurement's arrays are read-only, another type to numba: passed on as they are,
    # they compiled the open loop a second time (seconds of every first fit)
    from fuzzyservo.control.command import COMMAND_LAW
    from fuzzyservo.identify import measurement_from_arrays
    from fuzzyservo.sim import loops

    src = _open_loop_data(BASE, duration=1.5)
    m = measurement_from_arrays(src.t, src.y, u=src.u, p_f=src.p_f, p_n=src.p_n)
    assert not m.t.flags.writeable
    identify(m, plant="nonlinear", params=BASE, fit=["load.mass"],
             settings=FitSettings(starts=1, max_nfev=3))
    fn = loops.kernels(COMMAND_LAW).nonlinear_chunk
    assert len(fn._cache._cache_file._load_index()) == 1
