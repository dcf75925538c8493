"""Claim verdicts follow the metrics and traces they are given (no verdict is typed in).

Rule-level tests on synthetic metrics and traces whose answer is known analytically; the
acceptance tests on real simulations are in test_claim_acceptance.py.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo._io import strict_json
from fuzzyservo.analysis.outcome import LIMIT_CYCLE_MIN_PP
from fuzzyservo.study.claims import (
    CLAIM_RULES,
    HOLDS,
    NOT_HOLDS,
    PARTLY,
    Claim,
    alpha_settles,
    command_amplitude,
    evaluate_claims,
    response_outcome,
    summarize,
    transient_window,
)

KEYS = ("pid_paper_1", "pid_paper_2", "pid_tuned", "pid2_tuned", "fpi", "stfpi")
STEP = 0.1  # [m]
T_END = 20.0  # [s]


def _m(os_: float = 0.0, tr: float = 1.0, ts: float = 2.0, umax: float = 0.5,
       sse: float = 0.0, u_after: float | None = None, u_rms: float | None = None
       ) -> dict[str, float]:
    return {"overshoot": os_, "rise_time": tr, "settling_time": ts, "u_max": umax,
            "u_max_after": umax if u_after is None else u_after,
            "u_rms": umax / 4 if u_rms is None else u_rms, "itae": 0.05,
            "steady_state_error": sse, "steady_state_error_fraction": sse / STEP}


def _rows(metrics: dict, **kw: object) -> dict[str, Claim]:
    t = np.linspace(0.0, 10.0, 1001)
    alpha = kw.pop("alpha", np.full_like(t, 0.2))
    args = dict(
        stfpi="stfpi", fpi="fpi", paper_pids=KEYS[:2], tuned_pids=KEYS[2:4],
        alpha_trace=(t, alpha), delayed=metrics["stfpi"], delay=0.006,
        delay_margins={k: 0.05 for k in KEYS}, variants={"mass x2": metrics},
        duration=T_END, amplitude_after=0.1)
    args.update(kw)
    rows = evaluate_claims("linear", metrics, {k: k for k in KEYS}, **args)  # type: ignore[arg-type]
    assert [r.id for r in rows] == [f"C{i}" for i in range(1, 9)]
    assert all(r.plant == "linear" and r.evidence and r.rule == CLAIM_RULES[r.id]
               for r in rows)
    return {r.id: r for r in rows}


def _claims(metrics: dict, **kw: object) -> dict[str, str]:
    return {k: r.verdict for k, r in _rows(metrics, **kw).items()}


def _base() -> dict[str, dict[str, float]]:
    return {
        "pid_paper_1": _m(os_=8.0, tr=2.0, ts=5.0, umax=1.0),
        "pid_paper_2": _m(os_=0.0, tr=3.0, ts=6.0, umax=0.8),
        "pid_tuned": _m(os_=9.0, tr=1.5, ts=4.0, umax=1.0),
        "pid2_tuned": _m(os_=0.0, tr=1.8, ts=3.0, umax=1.0),
        "fpi": _m(os_=1.0, tr=1.2, ts=3.5, umax=0.4),
        "stfpi": _m(os_=0.1, tr=1.0, ts=2.0, umax=0.4),
    }


def _t(duration: float = T_END, dt: float = 0.001) -> np.ndarray:
    return np.arange(round(duration / dt) + 1) * dt


def _trace(y_dev: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A step of STEP from 0.5 m: y = target + y_dev after a first sample at rest."""
    y = 0.5 + STEP + y_dev
    y[0] = 0.5
    return t, y, np.full_like(t, 0.5 + STEP)


def test_all_claims_hold_when_the_metrics_support_them() -> None:
    v = _claims(_base())
    assert v == {f"C{i}": HOLDS for i in range(1, 9)}


def test_overshoot_of_the_self_tuning_controller_breaks_c1() -> None:
    m = _base()
    m["stfpi"]["overshoot"] = 3.0
    assert _claims(m)["C1"] == NOT_HOLDS


def test_a_faster_tuned_pid_makes_c2_partial_and_a_faster_paper_pid_breaks_it() -> None:
    m = _base()
    m["pid2_tuned"]["settling_time"] = 1.0
    assert _claims(m)["C2"] == PARTLY
    m["pid_paper_1"]["rise_time"] = 0.5
    m["pid_paper_1"]["settling_time"] = 1.0
    assert _claims(m)["C2"] == NOT_HOLDS


def test_never_settling_counts_as_slowest() -> None:
    m = _base()
    m["pid_paper_2"]["settling_time"] = math.nan
    assert _claims(m)["C2"] == HOLDS
    m["stfpi"]["settling_time"] = math.nan
    assert _claims(m)["C2"] == NOT_HOLDS


# ------------------------------------------------------------------------------------ C3
def test_command_amplitude_of_a_sinusoid_and_of_a_decaying_kick() -> None:
    t = _t(2.0)  # 1 ms samples, 2 s: ten periods of 0.2 s
    a = 0.3
    u = a * np.sin(2 * np.pi * t / 0.2)
    amp = command_amplitude(t, u, after=0.1)
    # held samples over whole periods: sum sin^2 = n/2 exactly, up to rounding
    assert amp["u_rms"] == pytest.approx(a / math.sqrt(2), rel=1e-9)
    assert amp["u_max_after"] == pytest.approx(a, rel=1e-4)  # the sample nearest the crest
    # a derivative kick kd N dr = 7.5 decaying at N = 100 1/s, clipped at 1: over the run
    # its peak is the limit; from 10/N on, what is left is 7.5 e^-10 (sample at 0.1 s)
    kick = np.minimum(7.5 * np.exp(-100.0 * t), 1.0)
    amp = command_amplitude(t, kick, after=transient_window(100.0, 0.001))
    assert amp["u_max_after"] == pytest.approx(7.5 * math.exp(-10.0), rel=1e-9)
    assert transient_window(100.0, 0.001) == pytest.approx(0.1, rel=1e-15)
    assert transient_window(math.inf, 0.001) == pytest.approx(0.01, rel=1e-15)


@pytest.mark.parametrize("smaller, verdict", [
    ((True, True, True), HOLDS),
    ((True, False, False), PARTLY),
    ((False, True, True), PARTLY),
    ((False, False, False), NOT_HOLDS),
])
def test_c3_says_which_measure_supports_it(smaller: tuple[bool, bool, bool],
                                           verdict: str) -> None:
    m = _base()
    names = ("u_max", "u_max_after", "u_rms")
    for name, ok in zip(names, smaller, strict=True):
        pid = min(m[k][name] for k in KEYS[:2])
        m["stfpi"][name] = 0.5 * pid if ok else 1.5 * pid
    c3 = _rows(m)["C3"]
    assert c3.verdict == verdict
    assert c3.data["smaller than both paper PIDs"] == dict(zip(names, smaller, strict=True))
    for k in ("stfpi", *KEYS[:2]):
        assert {n: c3.data[k][n] for n in names} == {n: m[k][n] for n in names}
    assert c3.thresholds["window_start_s"] == 0.1
    said = c3.evidence.split(". Smaller by ")[1]
    if verdict == PARTLY:
        by, not_by = said.split(" only; not by ")
        assert ("peak |u| over the run" in by) == smaller[0]
        assert ("peak |u| after 0.1 s" in not_by) == (not smaller[1])
    else:
        assert said.startswith("all three" if verdict == HOLDS else "none of the three")


# ------------------------------------------------------------------------------------ C4, C5
def test_c5_follows_the_settling_times() -> None:
    m = _base()
    m["fpi"]["settling_time"] = 1.5
    assert _claims(m)["C5"] == NOT_HOLDS


def test_alpha_that_keeps_moving_breaks_c4() -> None:
    t = np.linspace(0.0, 10.0, 1001)
    moving = 0.2 + 0.1 * np.sin(t)
    assert _claims(_base(), alpha=moving)["C4"] == NOT_HOLDS
    settled, final, spread = alpha_settles(t, np.full_like(t, 0.3))
    assert settled and final == 0.3 and spread == 0.0


def test_delay_claim_depends_on_the_delayed_run_and_the_sweep() -> None:
    m = _base()
    margins = {k: 0.05 for k in KEYS}
    margins["fpi"] = 0.2
    assert _claims(m, delay_margins=margins)["C6"] == PARTLY
    bad = dict(m["stfpi"], overshoot=30.0)
    assert _claims(m, delayed=bad)["C6"] == NOT_HOLDS


# ------------------------------------------------------------------------- the outcome of a run
def _settled_metrics(ts: float = 2.0, os_: float = 0.3) -> dict[str, float]:
    return {"overshoot": os_, "settling_time": ts}


def test_a_sustained_oscillation_is_a_limit_cycle_even_inside_the_band() -> None:
    t = _t()
    # +-0.6 % of the step: inside the 2 % band (so "settled"), above the 1 % peak-to-peak floor
    amp = 0.6 * LIMIT_CYCLE_MIN_PP * STEP
    tr = _trace(amp * np.sin(2 * np.pi * t / 0.4), t)
    out = response_outcome(_settled_metrics(), tr, duration=T_END)
    assert (out.kind, out.robust) == ("limit cycle", False)
    assert "period 0.4 s" in out.text and "+-0.6 mm" in out.text
    # the same at +-0.4 %: below what the rule calls a limit cycle
    small = _trace(0.4 * LIMIT_CYCLE_MIN_PP * STEP * np.sin(2 * np.pi * t / 0.4), t)
    assert response_outcome(_settled_metrics(), small, duration=T_END).kind == "settles"


def test_a_decaying_oscillation_is_not_a_limit_cycle() -> None:
    t = _t()
    # e^(-t/2): over the 2.5 s halves of the tail its amplitude falls by e^-1.25 = 0.29 < 0.5
    # (a 0.5 s period: five in each half, so the halves' crests are 2.5 s apart)
    y = 0.02 * np.exp(-t / 2.0) * np.sin(2 * np.pi * t / 0.5)
    out = response_outcome({"overshoot": 20.0, "settling_time": math.nan}, _trace(y, t),
                           duration=T_END)
    assert out.kind == "not settled" and not out.robust
    assert "not settled by t = 20 s" in out.text
    # crests sampled to 1 ms: the ratio of two crest pairs to ~1e-3
    assert out.data["tail_sustain"] == pytest.approx(math.exp(-1.25), rel=0.01)


def test_outcome_kinds_from_the_metrics() -> None:
    flat = _trace(np.zeros(_t().size), _t())
    assert response_outcome(_settled_metrics(), flat, duration=T_END).robust
    assert response_outcome(_settled_metrics(os_=12.0), flat,
                            duration=T_END).kind == "overshoots"
    assert response_outcome({"overshoot": math.nan, "settling_time": math.nan,
                             "diverged": 1.0}, None, duration=T_END).kind == "diverged"
    assert response_outcome(_settled_metrics(), None, duration=T_END).kind == "settles"


# ------------------------------------------------------------------------------------ C7
def test_c7_quotes_no_steady_state_error_for_an_unsettled_response() -> None:
    m = _base()
    m["pid_paper_1"].update(settling_time=math.nan, steady_state_error=-0.007,
                            steady_state_error_fraction=-0.07)
    c7 = _rows(m)["C7"]
    assert "not settled by t = 20 s" in c7.evidence and "-7" not in c7.evidence
    assert math.isnan(c7.data["pid_paper_1"]["steady_state_error_fraction"])  # type: ignore[arg-type]
    parts = c7.data["parts"]
    assert list(parts.values()) == [True, False, True]
    assert c7.verdict == PARTLY and "holds for: pid_paper_1 overshoot" in c7.evidence
    # settled with a 0.1 % error: every part holds
    m["pid_paper_1"].update(settling_time=5.0, steady_state_error_fraction=0.001)
    assert _claims(m)["C7"] == HOLDS
    m["pid_paper_1"]["overshoot"] = 40.0
    m["pid_paper_2"]["overshoot"] = 3.0
    m["pid_paper_1"]["settling_time"] = math.nan
    assert _claims(m)["C7"] == NOT_HOLDS


# ------------------------------------------------------------------------------------ C8
def _variants(m: dict, names: tuple[str, ...]) -> dict[str, dict]:
    return {n: {k: dict(v) for k, v in m.items()} for n in names}


def test_c8_names_the_changes_that_fail_with_their_result() -> None:
    m = _base()
    var = _variants(m, ("bulk x0.5", "mass x0.5", "mass x2"))
    var["mass x2"]["stfpi"]["settling_time"] = math.nan
    t = _t()
    cycle = _trace(0.012 * np.sin(2 * np.pi * t / 0.36), t)
    rest = _trace(np.zeros(t.size), t)
    traces = {"bulk x0.5": cycle, "mass x0.5": rest, "mass x2": rest}
    c8 = _rows(m, variants=var, variant_traces=traces)["C8"]
    assert c8.verdict == NOT_HOLDS
    assert c8.evidence.startswith("2 of 3 changes fail: bulk x0.5: limit cycle: +-12 mm")
    assert "mass x2: not settled by t = 20 s" in c8.evidence
    assert "Robust under: mass x0.5 (settles in 2 s" in c8.evidence
    assert [c8.data[n]["outcome"] for n in traces] == ["limit cycle", "settles", "not settled"]
    assert c8.data["bulk x0.5"]["tail_period"] == pytest.approx(0.36, abs=2e-3)


@pytest.mark.parametrize("os_, verdict", [(2.0, HOLDS), (25.0, NOT_HOLDS)])
def test_changed_plant_overshoot(os_: float, verdict: str) -> None:
    m = _base()
    changed = {k: dict(v) for k, v in m.items()}
    changed["stfpi"]["overshoot"] = os_
    assert _claims(m, variants={"mass x2": changed})["C8"] == verdict


def test_robust_but_not_faster_is_c8_under_stated_conditions() -> None:
    m = _base()
    var = _variants(m, ("a", "b"))
    var["b"]["pid_paper_2"]["settling_time"] = 1.0
    c8 = _rows(m, variants=var)["C8"]
    assert c8.verdict == PARTLY
    assert c8.evidence.startswith("0 of 2 changes fail")
    assert "not faster than the paper's PIDs under: b" in c8.evidence
    assert c8.data["b"]["faster_than_paper_pids"] is False


def test_c1_is_partial_when_no_overshoot_comes_from_the_tuning_constraint() -> None:
    m = _base()
    m["stfpi_10"] = _m(os_=9.0, tr=0.8, ts=2.5)
    labels = {k: k for k in m}
    t = np.linspace(0.0, 10.0, 101)

    def c1(limit: float | None) -> str:
        rows = evaluate_claims(
            "linear", m, labels, stfpi="stfpi", fpi="fpi", paper_pids=KEYS[:2],
            tuned_pids=KEYS[2:4], alpha_trace=(t, np.full_like(t, 0.2)), delayed=m["stfpi"],
            delay=0.006, delay_margins={k: 0.05 for k in KEYS}, variants={"x": m},
            duration=T_END, amplitude_after=0.1,
            stfpi_equal="stfpi_10", stfpi_overshoot_limit=limit)
        return rows[0].verdict

    assert c1(0.5) == PARTLY  # tuned for no overshoot; tuned like the PIDs it overshoots
    assert c1(10.0) == HOLDS  # no overshoot although 10 % was allowed
    m["stfpi_10"]["overshoot"] = 0.2
    assert c1(0.5) == HOLDS


# ------------------------------------------------------------------- claims.json, summary, docs
def test_every_claim_serialises_with_its_rule_thresholds_and_data() -> None:
    m = _base()
    m["pid_paper_1"]["settling_time"] = math.nan
    for c in _rows(m).values():
        doc = json.loads(strict_json(c.as_dict()))
        assert set(doc) == {"id", "claim", "verdict", "evidence", "plant", "rule",
                            "thresholds", "data"}
        assert doc["rule"] == CLAIM_RULES[c.id] and doc["thresholds"] and doc["data"]


def test_summary_counts_the_verdicts_and_compares_with_the_tuned_designs() -> None:
    m = _base()
    m["stfpi"]["overshoot"] = 3.0
    lin = _rows(m)
    m = _base()
    m["stfpi"]["overshoot"] = 3.0
    m["pid_paper_1"]["overshoot"] = 40.0
    non = {k: Claim(c.id, c.claim, c.verdict, c.evidence, "nonlinear")
           for k, c in _rows(m).items()}
    st = dict(_base()["stfpi"], itae=0.06, rise_time=1.4, settling_time=2.2)
    tuned = {"P (1-DOF PID with ki = kd = 0)": dict(st, itae=0.025, rise_time=0.75,
                                                     settling_time=2.4),
             "2-DOF PID": dict(st, itae=0.026, rise_time=0.76, settling_time=math.nan)}
    out = summarize([*lin.values(), *non.values()],
                    {"linear": (st, tuned), "nonlinear": (st, tuned)})
    assert 1 <= len(out) <= 5 and all(s.endswith(".") for s in out)
    assert out[0] == ("Of the paper's 8 claims, on the linear plant 7 hold (C2, C3, C4, C5, "
                      "C6, C7, C8) and 1 does not hold (C1); on the nonlinear plant 6 hold "
                      "(C2, C3, C4, C5, C6, "
                      "C8), 1 holds only under stated conditions (C7) and 1 does not hold "
                      "(C1).")
    assert out[1] == ("C1 (no overshoot) does not hold on any plant; "
                      "C2 (faster than the PIDs), C3 (smaller control amplitude), C4 "
                      "(α_F settles), C5 (fuzzy PI settles more slowly), C6 (robust with "
                      "the hose delay) and C8 (robust to parameter changes) hold on every "
                      "plant.")
    assert out[2] == ("On the linear plant, against the tuned P (1-DOF PID with ki = kd = 0) "
                      "and 2-DOF PID, the self-tuning fuzzy PI tuned like them (ITAE, "
                      "overshoot <= 10 %) has larger ITAE (0.06 m s^2 "
                      "against 0.025 and 0.026 m s^2), longer rise time (1.4 s against 0.75 "
                      "and 0.76 s) and shorter 2 % settling time (2.2 s against 2.4 and n/a "
                      "(never reached) s).")


def test_the_rules_are_written_in_docs_word_for_word() -> None:
    docs = (Path(__file__).parents[2] / "docs" / "model.md").read_text()
    text = re.sub(r"\s+", " ", docs.replace("\\|", "|"))
    section = text[text.index("### How a verdict is reached"):]
    for cid, rule in CLAIM_RULES.items():
        assert rule in section, cid
