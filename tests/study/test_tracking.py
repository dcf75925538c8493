"""The tracking and disturbance study (claim C9): its rule on hand-made records, and its
runs against the same runs made by ``fuzzyservo simulate``'s API."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from fuzzyservo.analysis.tracking import move_metrics, sine_metrics
from fuzzyservo.paper import named_set
from fuzzyservo.plant import linearize
from fuzzyservo.run import RunSpec
from fuzzyservo.study.claims import CLAIM_RULES, HOLDS, NOT_HOLDS, PARTLY
from fuzzyservo.study.tracking import (
    TrackingConfig,
    TrackingStudy,
    run_tracking_study,
    tracking_claim,
)

CFG = TrackingConfig()  # 50 mm at 0.5, 1, 2 Hz: peak speeds 0.157, 0.314, 0.628 m/s
K_O = 0.2619  # the paper's valve speed at the full command [m/s]


def _sine(ratio: float, lag: float, rms: float) -> dict[str, float]:
    return {"rms_error": rms, "max_error": 2 * rms, "amplitude_ratio": ratio,
            "phase_lag": lag, "diverged": 0.0}


def _study(subject: dict[str, float], other_rms: float) -> TrackingStudy:
    sat = _sine(0.4, 60.0, 0.02)  # what every design does beyond the valve's speed
    return TrackingStudy(
        plant="linear", keys=("stfpi", "pid"),
        sine={"stfpi": {"0.5": subject, "1": sat, "2": sat},
              "pid": {"0.5": _sine(1.0, 5.0, other_rms), "1": sat, "2": sat}},
        move={}, load={}, load_force=1.0)


@pytest.mark.parametrize(("subject", "other_rms", "verdict"), [
    (_sine(1.02, 12.0, 0.002), 0.0015, HOLDS),       # follows, within 1.5 x the best
    (_sine(1.02, 12.0, 0.004), 0.0015, PARTLY),      # follows, 2.7 x the best
    (_sine(0.85, 12.0, 0.004), 0.0015, NOT_HOLDS),   # amplitude 15 % short
    (_sine(1.0, 31.0, 0.001), 0.0015, NOT_HOLDS),    # lags more than 30°
    ({"diverged": 1.0}, 0.0015, NOT_HOLDS),
])
def test_c9_rule(subject: dict[str, float], other_rms: float, verdict: str) -> None:
    c = tracking_claim(_study(subject, other_rms), {"stfpi": "ST", "pid": "PID"},
                       subject="stfpi", capacity=K_O, tcfg=CFG)
    assert c.id == "C9" and c.verdict == verdict and c.rule == CLAIM_RULES["C9"]
    assert list(c.data) == ["sine 0.5 Hz"]  # 1 and 2 Hz are beyond the valve: not judged
    assert "Not judged" in c.evidence and "1 Hz, 2 Hz" in c.evidence
    assert c.thresholds["valve_speed_m_s"] == K_O


def test_c9_with_every_sine_beyond_the_valve_is_not_judged_as_held() -> None:
    c = tracking_claim(_study(_sine(1.0, 0.0, 0.0), 0.001), {}, subject="stfpi",
                       capacity=0.1, tcfg=CFG)
    assert c.verdict == NOT_HOLDS and not c.data and "nothing to judge" in c.evidence


def test_tracking_runs_are_the_runs_their_specs_make() -> None:
    """Each experiment is the step run with its reference, duration and load force
    replaced: the metrics equal those of that RunSpec built and simulated on its own. Under
    the load step a P controller keeps the analytic offset of Merritt's force path on eq.
    (8), K_f F/(K_p K_o) (docs/model.md, "Load force on the linear models"), and a PI
    removes it."""
    params = named_set("paper")
    tcfg = TrackingConfig(sine_frequencies=(0.5,), sine_duration=4.0, move_settle=1.0,
                          load_duration=6.0)
    # K_v = K_p K_o = 2.1 1/s, inside eq. (8)'s limit 2 δ ω₀ = 3.9 1/s
    base = {"p": RunSpec(controller="p", gains=(("kp", 8.0),), plant="linear"),
            "pi": RunSpec(controller="pi", gains=(("kp", 8.0), ("ki", 8.0)), plant="linear")}
    st = run_tracking_study("linear", base.__getitem__, ["p", "pi"], tcfg, params=params)
    spec = replace(base["pi"], reference="sine:0.05:0.5", duration=tcfg.sine_run_duration(0.5))
    res = spec.build(params=params).simulate()
    m = sine_metrics(res.t, res.r, res.y, 0.5)
    assert st.sine["pi"]["0.5"]["rms_error"] == m.rms_error
    assert st.sine["pi"]["0.5"]["phase_lag"] == m.phase_lag
    mv = tcfg.move
    res = replace(base["pi"], reference="scurve:0.2:0.15:0.5:2.0:0.2",
                  duration=mv.time + mv.duration + 1.0).build(params=params).simulate()
    mm = move_metrics(res.t, res.r, res.y, distance=0.2, t_end=mv.time + mv.duration)
    assert st.move["pi"]["max_following_error"] == mm.max_following_error
    force = 0.1 * 7e6 * params.cylinder.piston_area
    assert st.load_force == pytest.approx(force, rel=1e-15)
    lin = linearize(params, 0.5)
    droop = lin.load_compliance * force / (8.0 * params.velocity_gain)
    assert st.load["p"]["remaining"] == pytest.approx(-droop, rel=2e-3)
    assert math.isnan(st.load["p"]["recovery_time"])
    assert abs(st.load["pi"]["remaining"]) < 0.01 * st.load["pi"]["max_deviation"]
    assert st.load["pi"]["recovery_time"] < 5.5
    assert set(st.runs) == {f"{k}/{e}" for k in ("p", "pi") for e in ("sine_0.5", "move", "load")}
