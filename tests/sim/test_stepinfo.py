"""The compiled step-metrics core against python-control's ``step_info`` and hand-made cases."""

from __future__ import annotations

import control as ct
import numpy as np
import pytest

from fuzzyservo.sim.stepinfo import METRIC_NAMES, N_METRICS, step_metrics_core

NO_U = np.empty(0)


def _core(
    t: np.ndarray,
    y: np.ndarray,
    *,
    u: np.ndarray = NO_U,
    r: np.ndarray | None = None,
    y0: float = 0.0,
    y_final: float = 1.0,
    band: float = 0.02,
) -> dict[str, float]:
    out = np.full(N_METRICS, -123.0)
    rr = np.full_like(t, y_final) if r is None else r
    step_metrics_core(t, y, u, rr, y0, y_final, 0.1, 0.9, band, 0.05, out)
    return dict(zip(METRIC_NAMES, out.tolist(), strict=True))


def test_metric_names_are_the_contract() -> None:
    # docs/architecture.md "Step metrics" fixes names and order; the batch kernel relies on it.
    assert METRIC_NAMES == (
        "rise_time",
        "settling_time",
        "settling_time_5",
        "overshoot",
        "peak",
        "peak_time",
        "steady_state_error",
        "iae",
        "ise",
        "itae",
        "itse",
        "u_max",
        "u_sq_integral",
        "u_total_variation",
    )
    assert N_METRICS == 14


@pytest.mark.parametrize(
    "sys",
    [
        ct.tf([-1, 1], [1, 1, 1]),  # step_info docstring example (zero in the RHP)
        ct.tf([1], [1, 0.4, 1]),  # underdamped second order, zeta = 0.2
        ct.tf([1], [2, 1]),  # first order, tau = 2 s
        ct.tf([2, 1], [1, 2, 4]),  # LHP zero, DC gain 0.25
    ],
)
def test_core_matches_python_control(sys: ct.TransferFunction) -> None:
    t, y = ct.step_response(sys)
    ref = ct.step_info(sys, T=t)
    yf = float(sys.dcgain())
    got = _core(t, y, y_final=yf)
    dt = t[1] - t[0]
    # times: one sample (acceptance); both take crossings at samples, so they agree to rounding
    assert got["rise_time"] == pytest.approx(ref["RiseTime"], abs=dt)
    assert got["settling_time"] == pytest.approx(ref["SettlingTime"], abs=dt)
    assert got["peak_time"] == pytest.approx(ref["PeakTime"], abs=dt)
    # amplitudes: 0.5 % (acceptance); overshoot in percentage points of the same 0.5 %
    assert got["overshoot"] == pytest.approx(ref["Overshoot"], abs=0.5)
    assert abs(got["peak"]) == pytest.approx(ref["Peak"], rel=0.005)


def test_core_5_percent_band_matches_python_control() -> None:
    sys = ct.tf([1], [1, 0.4, 1])
    t, y = ct.step_response(sys, 40.0)
    ref = ct.step_info(sys, T=t, SettlingTimeThreshold=0.05)
    got = _core(t, y)
    assert got["settling_time_5"] == pytest.approx(ref["SettlingTime"], abs=t[1] - t[0])  # 1 sample


def test_never_reaching_90_percent_gives_nan_not_exception() -> None:
    t = np.linspace(0.0, 1.0, 101)
    y = 0.5 * (1.0 - np.exp(-t / 0.1))  # stalls at half the target
    got = _core(t, y)
    assert np.isnan(got["rise_time"])
    assert np.isnan(got["settling_time"]) and np.isnan(got["settling_time_5"])
    assert got["overshoot"] == 0.0  # exact: never above the target


def test_no_step_gives_nan_for_step_shape_metrics() -> None:
    t = np.linspace(0.0, 1.0, 11)
    y = np.zeros_like(t)
    got = _core(t, y, y0=0.0, y_final=0.0)
    for name in ("rise_time", "settling_time", "settling_time_5", "overshoot"):
        assert np.isnan(got[name]), name
    assert got["iae"] == 0.0  # exact: e is identically zero


def test_negative_step_and_offset_initial_value() -> None:
    # a step from 2 down to 1 is the mirror image of 0 -> 1 shifted by 2
    t = np.linspace(0.0, 10.0, 1001)
    up = 1.0 - np.exp(-t) * np.cos(2.0 * t)
    a = _core(t, up, y0=0.0, y_final=1.0)
    b = _core(t, 2.0 - up, y0=2.0, y_final=1.0)
    for name in ("rise_time", "settling_time", "settling_time_5", "overshoot", "peak_time"):
        assert b[name] == pytest.approx(a[name], abs=1e-12), name  # same samples, same indices
    assert b["peak"] == pytest.approx(2.0 - a["peak"], abs=1e-12)  # mirrored value


def test_buffer_beyond_n_metrics_untouched_and_u_metrics() -> None:
    t = np.array([0.0, 0.5, 1.0, 2.0])
    y = np.array([0.0, 0.5, 1.0, 1.0])
    u = np.array([1.0, -2.0, 0.5, 0.5])
    out = np.full(N_METRICS + 3, 7.0)
    step_metrics_core(t, y, u, np.ones(4), 0.0, 1.0, 0.1, 0.9, 0.02, 0.05, out)
    got = dict(zip(METRIC_NAMES, out[:N_METRICS].tolist(), strict=True))
    assert out[N_METRICS:].tolist() == [7.0, 7.0, 7.0]
    # hand values (exact binary fractions): ZOH left sum 1*0.5 + 4*0.5 + 0.25*1 = 2.75
    assert got["u_max"] == 2.0
    assert got["u_sq_integral"] == 2.75
    assert got["u_total_variation"] == 3.0 + 2.5 + 0.0
    # trapezoid on e = (1, 0.5, 0, 0): 0.5*0.5*1.5 + 0.5*0.5*0.5 = 0.5
    assert got["iae"] == 0.5
    assert got["rise_time"] == 1.0 - 0.5  # first >= 0.1 at t=0.5, first >= 0.9 at t=1.0
    assert got["settling_time"] == 1.0


def test_no_command_gives_nan_u_metrics() -> None:
    t = np.linspace(0.0, 1.0, 5)
    got = _core(t, 1.0 - np.exp(-5 * t))
    assert all(np.isnan(got[k]) for k in ("u_max", "u_sq_integral", "u_total_variation"))
