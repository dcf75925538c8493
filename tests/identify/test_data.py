"""Reading rig data (fuzzyservo.identify.data): units, time stamps, bad data, flags, offsets.

References are hand values (a unit's definition), the analytic bound of linear interpolation
(|f - I f| <= h^2/8 max|f''|), the file's bytes (hashlib) and arrays built independently of
the code under test (where a clipped sine sits at its clip level).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.errors import InputError, ParameterError
from fuzzyservo.identify.data import (
    JITTER,
    MAX_GAP,
    Measurement,
    measurement_from_arrays,
    parse_mapping,
    read_measurement,
)

N = 400
DT = 1e-3


def _csv(tmp_path: Path, header: str, rows: list[list[object]], name: str = "m.csv",
         pre: str = "") -> Path:
    p = tmp_path / name
    body = "\n".join(",".join(str(v) for v in row) for row in rows)
    p.write_text(pre + header + "\n" + body + "\n", encoding="utf-8")
    return p


def _step(n: int = N, at: int = 100, level: float = 0.2) -> np.ndarray:
    u = np.zeros(n)
    u[at:] = level
    return u


def _ramp(u: np.ndarray, dt: float = DT, y0: float = 0.5, k: float = 0.26) -> np.ndarray:
    """A position that integrates the command (the servo's velocity gain k [m/s])."""
    return y0 + k * dt * np.cumsum(u)


# ------------------------------------------------------------------------------- units


def test_units_in_the_header_are_converted_to_si(tmp_path: Path) -> None:
    n = 300
    rows = [[0.5 * k, 12.5 + k, 25.0 if k >= 10 else 0.0, 70.0, 1.0, 250.0] for k in range(n)]
    p = _csv(tmp_path, "t[ms],Position (mm),command [%],p_f (bar),p_n [psi],pressure (kPa)",
             rows)
    m = read_measurement(p, min_samples=n)
    # hand values: 1 ms = 1e-3 s; 1 mm = 1e-3 m; 25 % = 0.25; 1 bar = 1e5 Pa;
    # 1 psi = 0.45359237 kg * 9.80665 m/s^2 / (0.0254 m)^2 = 6894.757293168361 Pa
    assert m.dt == pytest.approx(5e-4, rel=1e-12)  # one rounding of the ms -> s division
    assert m.t[3] == pytest.approx(1.5e-3, rel=1e-12)
    assert m.y[0] == 0.0125  # 12.5 / 1000, correctly rounded
    assert m.y[7] == 19.5 / 1000
    assert m.u is not None and m.u[9] == 0.0 and m.u[10] == 0.25
    assert m.p_f is not None and np.all(m.p_f == 7e6)
    assert m.p_n is not None and m.p_n[0] == pytest.approx(6894.757293168361, rel=1e-15)
    assert m.rest == 10
    assert m.channels() == ("y", "u", "p_f", "p_n")  # 'pressure (kPa)' is no signal: ignored
    text = "\n".join(m.notes)
    for unit in ("ms", "mm", "%", "bar", "psi"):
        assert f"from {unit} to" in text


def test_units_option_wins_over_the_header_and_converts_mpa_and_us(tmp_path: Path) -> None:
    n = 250
    rows = [[100 * k, 0.3, 1e3 * k, 0.0 if k < 5 else 0.5, 2.5] for k in range(n)]
    p = _csv(tmp_path, "time [us],r,position [m],U,pa", rows)
    m = read_measurement(p, units={"y": "µm", "p_f": "MPa"}, min_samples=n)
    assert m.dt == pytest.approx(1e-4, rel=1e-12)  # 100 us
    assert m.y[3] == 3e3 / 1e6  # the flag's µm wins over the header's m
    assert m.p_f is not None and np.all(m.p_f == 2.5e6)
    assert any("the header says 'm'" in note for note in m.notes)
    # closed loop (need r): the reference is the excitation, and it never moves here
    with pytest.raises(InputError, match="never moves"):
        read_measurement(p, need=("r",), min_samples=n)


def test_command_in_percent_from_the_units_option(tmp_path: Path) -> None:
    u = _step(level=40.0)
    m = measurement_from_arrays(np.arange(N) * DT, _ramp(u / 100), u=u, units={"u": "%"})
    assert m.u is not None and m.u[-1] == 0.4  # 40 / 100, correctly rounded


@pytest.mark.parametrize(("header", "units", "column", "unit"), [
    ("t,y [inch],u", None, "y [inch]", "inch"),
    ("t,y,u", {"u": "percent"}, "u", "percent"),
    ("t,y,u,p_f (atm)", None, "p_f (atm)", "atm"),
    ("t [min],y,u", None, "t [min]", "min"),
])
def test_an_unknown_unit_names_the_column_the_unit_and_the_allowed_ones(
        tmp_path: Path, header: str, units: dict[str, str] | None, column: str,
        unit: str) -> None:
    ncol = header.count(",") + 1
    rows = [[k * DT, 0.5, 0.1 * (k > 10), 1e5][:ncol] for k in range(N)]
    p = _csv(tmp_path, header, rows)
    with pytest.raises(InputError) as exc:
        read_measurement(p, units=units)
    msg = str(exc.value)
    assert repr(column) in msg and repr(unit) in msg and "allowed:" in msg


def test_a_flag_wins_over_an_unknown_header_unit(tmp_path: Path) -> None:
    rows = [[k * DT, 500.0 + k, 0.1 * (k > 10)] for k in range(N)]
    m = read_measurement(_csv(tmp_path, "t,y [furlong],u", rows), units={"y": "mm"})
    assert m.y[1] == 501.0 / 1000


# --------------------------------------------------------------------------- time stamps


def test_uniform_data_are_kept_bit_for_bit(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    t0 = 12.0
    t = t0 + np.arange(N) * DT
    y = 0.5 + 1e-3 * rng.standard_normal(N)
    u = _step() + 1e-4 * rng.standard_normal(N)
    pf = 3e6 + 1e4 * rng.standard_normal(N)
    rows = [[repr(float(v)) for v in (t[k], y[k], u[k], pf[k])] for k in range(N)]
    p = _csv(tmp_path, "t,y,u,p_f", rows)
    m = read_measurement(p)
    assert m.y.tobytes() == y.tobytes()  # repr round-trips a double exactly
    assert m.u is not None and m.u.tobytes() == u.tobytes()
    assert m.p_f is not None and m.p_f.tobytes() == pf.tobytes()
    assert m.t.tobytes() == (t - t[0]).tobytes()  # the logged stamps, shifted to start at 0
    assert m.dt == pytest.approx(DT, rel=1e-9)  # the stamps' step, up to their rounding
    assert not any("resampled" in note for note in m.notes)
    assert m.digest == "sha256:" + hashlib.sha256(p.read_bytes()).hexdigest()
    assert m.source == str(p)
    a = measurement_from_arrays(t, y, u=u, p_f=pf)
    assert a.y.tobytes() == y.tobytes() and a.t.tobytes() == (t - t[0]).tobytes()


def test_jittered_stamps_are_resampled_within_the_interpolation_bound() -> None:
    rng = np.random.default_rng(3)
    h, amp, w = 1e-3, 0.05, 2 * np.pi * 7.0
    t = np.arange(2000) * h + rng.uniform(-0.2, 0.2, 2000) * h  # stamps off by up to 20 %
    t[0] = 0.0
    y = amp * np.sin(w * t)
    u = np.sin(w * t)
    m = measurement_from_arrays(t, y, u=u)
    steps = np.diff(t)
    assert m.dt == float(np.median(steps))  # the grid is at the median step
    assert np.array_equal(m.t, np.arange(m.n) * m.dt)
    assert m.t[-1] <= t[-1] < m.t[-1] + m.dt
    # linear interpolation between stamps at most hmax apart: error <= hmax^2/8 max|y''|
    bound = float(np.max(steps)) ** 2 / 8 * amp * w**2
    err = np.abs(m.y - amp * np.sin(w * m.t))
    assert float(np.max(err)) <= bound + 1e-15  # plus a few ulps of the sine
    assert float(np.max(err)) > 0.05 * bound  # the bound is not vacuous for this signal
    note = next(note for note in m.notes if "resampled" in note)
    assert "not uniform" in note and f"dt = {m.dt:.6g} s" in note


def test_jittered_stamps_in_a_csv_are_resampled(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    t = np.arange(N) * DT + rng.uniform(-0.05, 0.05, N) * DT
    t[0] = 0.0
    rows = [[repr(float(t[k])), repr(float(0.5 + 0.01 * t[k])), 0.1 * (k > 50)]
            for k in range(N)]
    m = read_measurement(_csv(tmp_path, "t,y,u", rows))
    assert np.array_equal(m.t, np.arange(m.n) * m.dt)
    # a straight line is interpolated exactly, up to rounding
    np.testing.assert_allclose(m.y, 0.5 + 0.01 * m.t, rtol=0, atol=1e-15)


def test_small_steps_that_drift_from_the_grid_are_resampled() -> None:
    # every step within JITTER of the median, but the stamps drift 20 % of a step away
    steps = np.where(np.arange(999) < 500, 1.0004e-3, 0.9996e-3)
    assert np.max(np.abs(steps - np.median(steps))) <= JITTER * np.median(steps)
    t = np.concatenate(([0.0], np.cumsum(steps)))
    m = measurement_from_arrays(t, 0.5 + t, u=_step(1000))
    assert any("resampled" in note for note in m.notes)
    np.testing.assert_allclose(m.y, 0.5 + m.t, rtol=0, atol=1e-15)  # a line: exact


def test_a_given_dt_that_differs_resamples_onto_it() -> None:
    t = np.arange(N) * DT
    m = measurement_from_arrays(t, 0.5 + 2 * t, u=_step(), dt=2e-3)
    assert m.dt == 2e-3 and np.array_equal(m.t, np.arange(m.n) * 2e-3)
    assert m.n == (N - 1) // 2 + 1
    np.testing.assert_allclose(m.y, 0.5 + 2 * m.t, rtol=0, atol=1e-15)
    assert any("dt = 0.002 s given" in note and "anti-alias" in note for note in m.notes)
    kept = measurement_from_arrays(t, 0.5 + 2 * t, u=_step(), dt=DT)
    assert kept.dt == DT and not any("resampled" in note for note in kept.notes)
    # finer than logged: interpolated samples share their noise, a fit's errors go wrong
    with pytest.raises(InputError, match=r"dt = 0.0005 s is finer than the logged step"):
        measurement_from_arrays(t, 0.5 + 2 * t, u=_step(), dt=5e-4)



def test_no_time_column_with_dt(tmp_path: Path) -> None:
    rows = [[0.5, 0.1 * (k > 10)] for k in range(N)]
    p = _csv(tmp_path, "y,u", rows)
    m = read_measurement(p, dt=2e-3)
    assert m.dt == 2e-3 and m.t[-1] == (N - 1) * 2e-3
    with pytest.raises(InputError, match=r"no time \(t\) column; found 'y', 'u'"):
        read_measurement(p)


# ------------------------------------------------------------------------------ bad data


def _rows(n: int = N) -> list[list[object]]:
    return [[repr(k * DT), repr(0.5 + 1e-4 * k), 0.1 * (k > 50)] for k in range(n)]


def test_nan_in_the_position_names_the_column_and_the_time(tmp_path: Path) -> None:
    rows = _rows()
    rows[123][1] = "nan"
    with pytest.raises(InputError, match=r"column 'y' \(y\) is nan at t = 0\.123 s "
                                         r"\(data row 124\)"):
        read_measurement(_csv(tmp_path, "t,y,u", rows))


def test_inf_in_a_needed_command_names_it_and_nan_in_an_optional_one_drops_it(
        tmp_path: Path) -> None:
    rows = [[*row, 2e6] for row in _rows()]
    rows[200][2] = "inf"
    p = _csv(tmp_path, "t,y,cmd,p_f", rows)
    with pytest.raises(InputError, match=r"column 'cmd' \(u\) is inf at t = 0\.2 s"):
        read_measurement(p, columns={"u": "cmd"})
    rows = [[*row, 2e6] for row in _rows()]
    rows[300][3] = "nan"
    m = read_measurement(_csv(tmp_path, "t,y,u,p_f", rows, name="b.csv"))
    assert m.p_f is None and m.channels() == ("y", "u")
    assert any("'p_f' (p_f) is nan at t = 0.3 s" in note for note in m.notes)


def test_a_needed_column_holding_text_names_the_line(tmp_path: Path) -> None:
    rows = _rows()
    rows[10][2] = "OPEN"
    with pytest.raises(InputError, match=r"line 12, column 'u': 'OPEN' is not a number"):
        read_measurement(_csv(tmp_path, "t,y,u", rows))


def test_nan_time_names_the_line(tmp_path: Path) -> None:
    rows = _rows()
    rows[40][0] = "nan"
    with pytest.raises(InputError, match=r"line 42, column 't': 'nan' is not finite"):
        read_measurement(_csv(tmp_path, "t,y,u", rows))
    t = np.arange(N) * DT
    t[40] = np.inf
    with pytest.raises(InputError, match=r"the time, t, is inf at sample 41"):
        measurement_from_arrays(t, np.zeros(N), u=_step())


@pytest.mark.parametrize("bad", [0.0335, 0.034])  # decreasing, then repeated
def test_time_that_does_not_increase_names_the_row_and_the_times(
        tmp_path: Path, bad: float) -> None:
    rows = _rows()
    rows[35][0] = repr(bad)  # after 0.034
    with pytest.raises(InputError, match=rf"does not increase at data row 36: 0\.034 then "
                                         rf"{bad}"):
        read_measurement(_csv(tmp_path, "t,y,u", rows))


def test_a_gap_is_refused() -> None:
    t = np.arange(N) * DT
    t[200:] += MAX_GAP * DT  # one step of 6 sample times
    with pytest.raises(InputError, match=r"holes: the time jumps by 0\.006 s \(6\.0 sample "
                                         r"times of 0\.001 s\) after t = 0\.199 s"):
        measurement_from_arrays(t, np.zeros(N), u=_step())
    t = np.arange(N) * DT
    t[200:] += (MAX_GAP - 1.5) * DT  # 4.5 sample times: bridged, resampled
    m = measurement_from_arrays(t, 0.5 + t, u=_step())
    assert any("resampled" in note for note in m.notes)


def test_too_short_names_the_count_and_the_minimum(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="has 150 samples; at least 200 are needed"):
        read_measurement(_csv(tmp_path, "t,y,u", _rows(150)))
    assert read_measurement(_csv(tmp_path, "t,y,u", _rows(150)), min_samples=150).n == 150


def test_a_command_that_never_moves(tmp_path: Path) -> None:
    rows = [[k * DT, 0.5, -0.0385] for k in range(N)]
    with pytest.raises(InputError, match=r"valve command \(u\) never moves \(always -0\.0385\)"
                                         r": nothing to identify"):
        read_measurement(_csv(tmp_path, "t,y,u", rows))


def test_a_missing_column_lists_the_columns_found(tmp_path: Path) -> None:
    rows = [[k * DT, 0.5, 0.1 * (k > 9), 1.0] for k in range(N)]
    p = _csv(tmp_path, "t,pos,u,other", rows)
    with pytest.raises(InputError, match=r"no position \(y\) column; found 't', 'pos', 'u', "
                                         r"'other'"):
        read_measurement(p)
    with pytest.raises(InputError, match=r"no position reference \(r\) column"):
        read_measurement(p, columns={"y": "POS"}, need=("r",))
    assert read_measurement(p, columns={"y": "POS"}).y[0] == 0.5  # case-insensitive
    with pytest.raises(InputError, match=r"no column 'position' \(given for y\); found"):
        read_measurement(p, columns={"y": "position"})


def test_two_columns_for_one_signal_must_be_told_apart(tmp_path: Path) -> None:
    rows = [[k * DT, 0.5, 0.6, 0.1 * (k > 9)] for k in range(N)]
    p = _csv(tmp_path, "t,x [m],position [mm],u", rows)
    with pytest.raises(InputError, match=r"'x \[m\]', 'position \[mm\]' could each be"):
        read_measurement(p)
    assert read_measurement(p, columns={"y": "position"}).y[0] == 0.6 / 1000


@pytest.mark.parametrize(("text", "match"), [
    ("", "not a header|empty"),
    ("# only a comment\n", "empty"),
])
def test_an_empty_file(tmp_path: Path, text: str, match: str) -> None:
    p = tmp_path / "e.csv"
    p.write_text(text, encoding="utf-8")
    with pytest.raises(InputError, match=match):
        read_measurement(p)


def test_bad_mapping_keys_and_arguments(tmp_path: Path) -> None:
    p = _csv(tmp_path, "t,y,u", _rows())
    with pytest.raises(InputError, match=r"columns: 'z' is not a signal; allowed: t, y, u"):
        read_measurement(p, columns={"z": "y"})
    with pytest.raises(ParameterError, match="dt must be a finite real number > 0"):
        read_measurement(p, dt=-1.0)
    with pytest.raises(ParameterError, match="need must be a tuple"):
        read_measurement(p, need=("q",))
    with pytest.raises(InputError, match="differ in length"):
        measurement_from_arrays(np.arange(N) * DT, np.zeros(N - 1), u=_step())


# ------------------------------------------------------------------------ rest and flags


def test_rest_counts_the_samples_before_the_excitation_moves() -> None:
    t = np.arange(N) * DT
    u = _step(at=137)
    u[:137] = -0.0385  # the holding command at rest
    m = measurement_from_arrays(t, _ramp(u), u=u)
    assert m.rest == 137
    r = np.full(N, 0.5)
    r[60:] = 0.55
    m = measurement_from_arrays(t, 0.5 + 0.0 * t, u=u, r=r, need=("r",))
    assert m.rest == 60  # closed loop: the reference is the excitation


def test_a_clipped_position_is_flagged_at_the_clipped_samples() -> None:
    t = np.arange(2000) * DT
    u = np.sin(2 * np.pi * 1.0 * t)
    u[:50] = 0.0
    y_true = 0.5 + 0.1 * np.sin(2 * np.pi * 1.0 * np.clip(t - 0.05, 0, None))
    y = np.minimum(y_true, 0.58)  # the sensor reads at most 0.58 m
    m = measurement_from_arrays(t, y, u=u)
    assert np.array_equal(m.flagged, y_true >= 0.58)  # exactly where the sensor clips
    assert m.flagged.any() and m.rest == 50  # u = sin(2 pi t) departs at sample 50
    note = next(note for note in m.notes if "flagged" in note)
    k = np.flatnonzero(y_true >= 0.58)
    assert f"{k.size} sample(s)" in note and f"t = {t[k[0]]:.6g} .. {t[k[-1]]:.6g} s" in note


def test_a_clipped_pressure_is_flagged_and_steady_values_are_not() -> None:
    t = np.arange(1000) * DT
    u = np.where(t < 0.1, 0.0, 0.3 * np.sin(2 * np.pi * 3 * t))
    pf = 3e6 + 2e6 * u
    pf_read = np.minimum(pf, 3.5e6)  # a 35 bar sensor
    m = measurement_from_arrays(t, _ramp(u), u=u, p_f=pf_read)
    assert np.array_equal(m.flagged, pf >= 3.5e6)
    # a step and a steady response: the settled values are extremes but no clip
    u = _step(1000, at=100, level=0.2)
    y = 0.5 + 0.1 * (1 - np.exp(-np.clip(t - 0.1, 0, None) / 0.02))
    y = np.round(y, 5)  # a quantised sensor: the settled value repeats exactly
    r = np.where(t < 0.1, 0.5, 0.6)
    pf = np.round(np.where(t < 0.1, 3e6, 3.2e6 + 1e5 * np.exp(-t / 0.01)), -3)
    m = measurement_from_arrays(t, y, u=u, r=r, p_f=pf, need=("r",))
    assert not m.flagged.any()


def test_an_end_stop_in_open_loop_is_flagged_and_the_dead_time_is_not() -> None:
    t = np.arange(1000) * DT
    u = _step(1000, at=100, level=0.5)
    y = np.minimum(_ramp(u, y0=0.5), 0.58)  # the piston reaches its end at 0.58 m
    y[100:104] = 0.5  # four samples of dead time at the rest position (the minimum)
    m = measurement_from_arrays(t, y, u=u)
    assert np.array_equal(m.flagged, y == 0.58) and m.flagged.sum() > 100
    assert m.rest == 100


def test_more_than_half_flagged_is_refused() -> None:
    t = np.arange(1000) * DT
    u = np.where(t < 0.1, 0.0, np.sin(2 * np.pi * 5 * t))
    y = np.minimum(0.5 + 0.1 * u, 0.5)  # clipped whenever u > 0, about half the time
    y[400:] = 0.5
    with pytest.raises(InputError, match=r"of 1000 samples are clipped .*more than half"):
        measurement_from_arrays(t, y, u=u)


def test_a_saturated_command_is_noted_not_flagged() -> None:
    t = np.arange(N) * DT
    u = _step(level=1.2)
    m = measurement_from_arrays(t, _ramp(u, k=0.01), u=u)
    assert not m.flagged.any()
    assert any(f"(|u| >= 1) at {N - 100} sample(s), t = 0.1 .. 0.399 s" in note
               for note in m.notes)


# ------------------------------------------------------------------------------- offsets


def test_offsets_are_added_and_noted(tmp_path: Path) -> None:
    t = 5.0 + np.arange(N) * DT
    y = np.full(N, 0.25)
    r = np.where(np.arange(N) < 20, 0.25, 0.3)
    pf = np.full(N, 2e6)
    m = measurement_from_arrays(t, y, r=r, p_f=pf, p_n=pf / 2, need=("r",),
                                position_offset=0.5, pressure_offset=101325.0)
    assert m.t[0] == 0.0 and m.t[-1] == pytest.approx((N - 1) * DT, abs=1e-12)
    assert np.all(m.y == 0.25 + 0.5) and m.r is not None and m.r[-1] == 0.3 + 0.5
    assert m.p_f is not None and np.all(m.p_f == 2e6 + 101325.0)
    assert m.p_n is not None and np.all(m.p_n == 1e6 + 101325.0)
    text = "\n".join(m.notes)
    assert "position offset +0.5 m added to y and r" in text
    assert "pressure offset +101325 Pa added to p_f and p_n" in text
    kept = measurement_from_arrays(t, y, r=r, need=("r",))
    assert np.array_equal(kept.y, y)  # None: as logged
    gauge = measurement_from_arrays(t, y, r=r, p_f=pf - 3e6, need=("r",))
    assert any("below 0: a gauge pressure?" in note for note in gauge.notes)


def test_the_record_is_read_only(tmp_path: Path) -> None:
    m = read_measurement(_csv(tmp_path, "t,y,u", _rows()))
    assert isinstance(m, Measurement)
    for a in (m.t, m.y, m.u, m.flagged):
        assert a is not None
        with pytest.raises(ValueError, match="read-only"):
            a[0] = 1.0


# -------------------------------------------------------------------------- option values


def test_parse_mapping() -> None:
    assert parse_mapping("y=pos_mm, u = cmd ,p_f=position [mm]", "--columns") == {
        "y": "pos_mm", "u": "cmd", "p_f": "position [mm]"}
    for bad in ("y", "y=", "=mm", "y=a,,u=b", "y=a,y=b"):
        with pytest.raises(InputError, match="--units"):
            parse_mapping(bad, "--units")


def test_a_run_csv_of_simulate_reads_y_not_x_and_says_why_a_late_step_is_refused(
        tmp_path: Path) -> None:
    # fuzzyservo simulate's closed-loop CSV: t, r, y, u, alpha, states (x is the state)
    rows = [[k * DT, 0.5 if k < 30 else 0.6, 0.5 + 1e-4 * k, 0.1, "nan", 0.5 + 1e-4 * k]
            for k in range(N)]
    p = _csv(tmp_path, "t,r,y,u,alpha,x", rows)
    m = read_measurement(p, need=("r",))
    assert m.rest == 30 and m.y[1] == 0.5 + 1e-4
    assert any("column 'y' read as y; 'x' not used" in note for note in m.notes)
    late = _csv(tmp_path, "t,r,y,u", [row[:4] for row in rows[30:]], name="late.csv")
    with pytest.raises(InputError, match="never moves .*the step came before the log began"):
        read_measurement(late, need=("r",), min_samples=2)


def test_comments_a_byte_order_mark_and_text_columns(tmp_path: Path) -> None:
    rows = [[*row, "ok" if k else "?", "OPEN"] for k, row in enumerate(_rows())]
    p = tmp_path / "bom.csv"
    text = "# logger v2\n\n" + "t,y,u,status,p_f\n" + "\n".join(
        ",".join(str(v) for v in row) for row in rows) + "\n"
    p.write_bytes(b"\xef\xbb\xbf" + text.encode())
    m = read_measurement(p)
    assert m.n == N and m.p_f is None
    assert any("'p_f' (p_f) holds text, not numbers: left out" in note for note in m.notes)
    with pytest.raises(InputError, match=r"column 'p_f': 'OPEN' is not a number"):
        read_measurement(p, need=("u", "p_f"))


def test_options_are_checked_before_the_file_is_read(tmp_path: Path) -> None:
    missing = tmp_path / "not-there.csv"
    with pytest.raises(ParameterError, match="pressure_offset must be a finite real number"):
        read_measurement(missing, pressure_offset=float("nan"))
    with pytest.raises(ParameterError, match="min_samples must be an integer >= 2"):
        read_measurement(missing, min_samples=1)
    with pytest.raises(InputError, match="cannot read measurement CSV"):
        read_measurement(missing)


def test_arrays_without_time_take_dt() -> None:
    m = measurement_from_arrays(None, np.full(N, 0.5), u=_step(), dt=2e-3)
    assert m.dt == 2e-3 and np.array_equal(m.t, np.arange(N) * 2e-3)
    assert m.digest.startswith("sha256:") and len(m.digest) == 7 + 64
