"""The experiment designer: limits held on the project's simulator and analytically, both step
signs, a chirp whose measured frequency passes ω_h, the CSV, the arguments' checks."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo._io import read_csv_columns
from fuzzyservo.errors import ParameterError
from fuzzyservo.identify.design import ExperimentDesign, describe, design_experiment
from fuzzyservo.paper.published import named_set
from fuzzyservo.plant import linearize, trim
from fuzzyservo.registry import build_plant
from fuzzyservo.sim import OpenLoopResult, simulate_open_loop

#: 1 bar above the floor: the nonlinear model's smooth cavitation band [Pa]
BAND = 1.0e5


@pytest.fixture(scope="module", params=[("paper", 0.5), ("stiff-oil", 0.5), ("paper", 0.25)],
                ids=["paper-mid", "stiff-oil-mid", "paper-quarter"])
def case(request: pytest.FixtureRequest) -> tuple[str, float, ExperimentDesign]:
    name, x0 = request.param
    return name, x0, design_experiment(named_set(name), position=x0, sensitivity=False)


def _run(name: str, x0: float, d: ExperimentDesign) -> OpenLoopResult:
    params = named_set(name)
    plant = build_plant("nonlinear", params, x0)
    return simulate_open_loop(plant, d.u, duration=d.duration, dt=d.dt,
                              delay=params.delay.transport_delay)


def _runs(u: np.ndarray, hold: float) -> list[tuple[float, int]]:
    """(level about the hold, length) of each run of a constant, non-zero excitation."""
    e = u - hold
    edges = np.flatnonzero(np.diff(e) != 0.0) + 1
    out = []
    for seg in np.split(e, edges):
        if seg[0] != 0.0:
            out.append((float(seg[0]), int(seg.shape[0])))
    return out


def test_design_stays_within_stroke_pressure_and_valve_limits_on_the_simulator(
        case: tuple[str, float, ExperimentDesign]) -> None:
    name, x0, d = case
    params = named_set(name)
    stroke = params.cylinder.stroke
    res = _run(name, x0, d)
    margin = 0.1  # the default
    assert res.x.min() >= margin * stroke
    assert res.x.max() <= (1.0 - margin) * stroke
    floor = params.fluid.pressure_floor + BAND
    assert min(res.p_f.min(), res.p_n.min()) > floor
    # the valve: commands in [-1, 1], the excitation about the hold within the amplitude
    hold = trim(params, x0).command
    assert np.all(np.abs(d.u) <= 1.0)
    assert np.max(np.abs(d.u - hold)) <= 0.2 + 1e-12  # default amplitude; rounding only
    # the run starts and ends at the hold, so it starts from rest and is left at rest
    assert d.u[0] == pytest.approx(hold, abs=1e-12)  # the trim's root-solve precision
    assert d.u[-1] == pytest.approx(hold, abs=1e-12)
    # the recorded prediction is this simulation's
    assert d.predicted_min == pytest.approx(res.x.min(), abs=1e-9)  # same run, same model
    assert d.predicted_max == pytest.approx(res.x.max(), abs=1e-9)


def test_design_returns_near_its_start(case: tuple[str, float, ExperimentDesign]) -> None:
    name, x0, d = case
    res = _run(name, x0, d)
    # the pulse lengths and the chirp's bias cancel the net drift on the nominal model:
    # what is left is a small fraction of the excursions (1 % of the stroke)
    assert abs(res.x[-1] - x0) < 0.01 * named_set(name).cylinder.stroke
    assert abs(res.v[-1]) < 1e-3  # at rest at the end [m/s]: the final settling


def test_pulses_obey_the_analytic_excursion_bound(
        case: tuple[str, float, ExperimentDesign]) -> None:
    """On eq. (8) a pulse of a for T moves the piston at most K_o a T plus the hydraulic
    mode's ringing, (2 zeta + 1/sqrt(1 - zeta^2))/omega_0 <= 3/omega_0 of travel per start or
    stop; K_o = Q_rated/A_f is the no-load extension speed per unit command, the fastest the
    nonlinear model moves. The bound from the command alone must fit inside the margins."""
    name, x0, d = case
    params = named_set(name)
    lin = linearize(params, x0)
    k_o = params.valve.rated_flow / params.cylinder.piston_area
    pulses = [r for r in _runs(d.u, trim(params, x0).command) if r[1] * d.dt > 0.5]
    a = max(abs(level) for level, _ in pulses) + abs(trim(params, x0).command)
    t_max = max(n for _, n in pulses) * d.dt
    bound = k_o * a * (t_max + 2.0 * 3.0 / lin.omega_0)
    stroke = params.cylinder.stroke
    assert x0 - bound >= 0.1 * stroke
    assert x0 + bound <= 0.9 * stroke
    # and the simulator's excursion over the pulses is inside it
    res = _run(name, x0, d)
    k = int(round(d.segments[1][2] / d.dt))  # the pulses' end
    assert np.max(np.abs(res.x[:k] - x0)) <= bound


def test_design_holds_steps_of_both_signs(case: tuple[str, float, ExperimentDesign]) -> None:
    name, x0, d = case
    params = named_set(name)
    runs = _runs(d.u, trim(params, x0).command)
    omega_0 = linearize(params, x0).omega_0
    # long constant pulses: at least three periods of the hydraulic mode each
    long = [level for level, n in runs if n * d.dt >= 3.0 * 2.0 * math.pi / omega_0]
    assert any(level > 0.0 for level in long)
    assert any(level < 0.0 for level in long)


def _peak_frequencies(u: np.ndarray, dt: float, window: float) -> np.ndarray:
    """Frequency of the largest peak of each half-overlapping Hann window's spectrum [Hz]."""
    n = int(round(window / dt))
    w = np.hanning(n)
    freqs = np.fft.rfftfreq(n, dt)
    out = []
    for start in range(0, u.shape[0] - n + 1, n // 2):
        seg = u[start:start + n]
        seg = seg - seg.mean()
        if np.ptp(seg) == 0.0:
            out.append(0.0)
            continue
        spec = np.abs(np.fft.rfft(seg * w))
        out.append(freqs[int(np.argmax(spec[1:])) + 1])
    return np.array(out)


def test_chirp_passes_the_hydraulic_natural_frequency(
        case: tuple[str, float, ExperimentDesign]) -> None:
    name, x0, d = case
    f_h = linearize(named_set(name), x0).omega_0 / (2.0 * math.pi)
    peaks = _peak_frequencies(d.u, d.dt, window=2.0)
    assert peaks.max() > 1.5 * f_h  # default top 3 f_h; 2 s windows resolve 0.5 Hz
    # and it starts well below: some window's content is below half of f_h
    active = peaks[peaks > 0.0]
    assert active.min() < 0.5 * f_h
    # counted independently: the zero crossings of the excitation in the last few
    # seconds of the chirp give its frequency there, above f_h
    hold = trim(named_set(name), x0).command
    e = d.u - hold
    end = np.flatnonzero(e != 0.0)[-1]
    tail = e[end - int(round(2.0 / d.dt)):end - int(round(1.0 / d.dt))]  # a 1 s slice
    crossings = np.count_nonzero(np.signbit(tail[1:]) != np.signbit(tail[:-1]))
    assert crossings / 2.0 > 1.2 * f_h  # cycles in 1 s


def test_user_f_max_sets_the_top_and_the_valve_band_is_kept_by_default() -> None:
    params = named_set("paper")
    f_h = linearize(params).omega_0 / (2.0 * math.pi)
    d = design_experiment(params, f_max=2.0 * f_h, sensitivity=False)
    peaks = _peak_frequencies(d.u, d.dt, window=2.0)
    assert 1.3 * f_h < peaks.max() < 2.3 * f_h  # 0.5 Hz resolution of the 2 s windows
    coarse = design_experiment(params, dt=0.01, sensitivity=False)  # 1/(10 dt) = 10 Hz
    assert coarse.chirp_band[1] <= 10.0
    assert coarse.chirp_band[1] > f_h


def test_csv_round_trips_through_numpy_loadtxt(tmp_path: Path) -> None:
    d = design_experiment(named_set("paper"), sensitivity=False, repeats=1)
    path = tmp_path / "design.csv"
    d.to_csv(path)
    lines = path.read_text(encoding="utf-8").splitlines()
    comments = sum(1 for line in lines if line.startswith("#"))
    assert comments == len(d.notes) + 1
    assert lines[comments] == "t,u"
    data = np.loadtxt(path, delimiter=",", skiprows=comments + 1)
    np.testing.assert_array_equal(data[:, 0], d.t)  # repr: exact round trip
    np.testing.assert_array_equal(data[:, 1], d.u)
    cols = read_csv_columns(path, ("t", "u"), what="design")  # the project's reader too
    np.testing.assert_array_equal(cols["u"], d.u)


def test_notes_say_what_and_how_long_to_log() -> None:
    d = design_experiment(named_set("paper"), sensitivity=False, repeats=1)
    text = "\n".join(d.notes)
    assert f"log at least {math.ceil(d.duration)} s" in text
    for column in ("position", "p_f", "p_n", "1000 Hz"):
        assert column in text
    assert all("\n" not in line for line in d.notes)
    lines = describe(d)
    assert any("chirp" in line for line in lines)
    assert d.duration == pytest.approx(d.t.shape[0] * d.dt, abs=1e-9)  # whole samples


def test_small_room_lowers_the_pulse_amplitude_and_says_so() -> None:
    params = named_set("paper")
    d = design_experiment(params, position=0.14, sensitivity=False, repeats=1)
    assert d.step_amplitude < 0.2
    assert any("room to the margins" in n for n in d.notes)
    res = _run("paper", 0.14, d)
    assert res.x.min() >= 0.1


def test_sensitivity_check_is_non_degenerate() -> None:
    """Finite differences of position and pressures to load.mass, fluid.oil_bulk_modulus and
    valve.omega_v: the three directions are told apart (a finite, moderate condition
    number; a degenerate pair would give ~1e8 and more at these differences' precision)."""
    d = design_experiment(named_set("paper"), repeats=1)
    assert 1.0 < d.condition < 1e4
    assert 1.0 < d.condition_position < 1e5
    assert any("condition number" in n for n in d.notes)


@pytest.mark.parametrize(("kw", "value", "fragment"), [
    ("amplitude", 0.0, "amplitude must be in (0, 1]"),
    ("amplitude", 1.5, "got 1.5"),
    ("amplitude", float("nan"), "amplitude"),
    ("amplitude", "0.2", "amplitude"),
    ("margin", -0.1, "margin must be in [0, 0.45)"),
    ("margin", 0.45, "got 0.45"),
    ("dt", 0.0, "dt must be"),
    ("dt", -1e-3, "-0.001"),
    ("position", -0.1, "inside the stroke"),
    ("position", 1.5, "got 1.5"),
    ("position", 0.05, "inside the margins"),
    ("f_max", 0.0, "f_max must be"),
    ("f_max", -1.0, "f_max"),
    ("f_max", 1.0, "above the hydraulic natural frequency"),
    ("f_max", 500.0, "got 500.0"),
    ("repeats", 0, "repeats must be an integer from 1 to 20"),
    ("repeats", 2.5, "2.5"),
    ("repeats", True, "repeats"),
])
def test_bad_arguments_are_parameter_errors(kw: str, value: object, fragment: str) -> None:
    with pytest.raises(ParameterError) as info:
        design_experiment(named_set("paper"), sensitivity=False, **{kw: value})  # type: ignore[arg-type]
    assert fragment in str(info.value)


def test_coarse_dt_that_cannot_excite_omega_h_is_refused() -> None:
    with pytest.raises(ParameterError, match="too coarse"):
        design_experiment(named_set("paper"), dt=0.05, sensitivity=False)


def test_params_must_be_servo_params() -> None:
    with pytest.raises(ParameterError, match="ServoParams"):
        design_experiment("paper", sensitivity=False)  # type: ignore[arg-type]
