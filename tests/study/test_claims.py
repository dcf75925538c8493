"""Claim verdicts follow the metrics they are given (no verdict is typed in)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzyservo.study.claims import HOLDS, NOT_HOLDS, PARTLY, alpha_settles, evaluate_claims

KEYS = ("pid_paper_1", "pid_paper_2", "pid_tuned", "pid2_tuned", "fpi", "stfpi")


def _m(os_: float = 0.0, tr: float = 1.0, ts: float = 2.0, umax: float = 0.5,
       sse: float = 0.0) -> dict[str, float]:
    return {"overshoot": os_, "rise_time": tr, "settling_time": ts, "u_max": umax,
            "steady_state_error": sse, "steady_state_error_fraction": sse / 0.1}


def _claims(metrics: dict, **kw: object) -> dict[str, str]:
    t = np.linspace(0.0, 10.0, 1001)
    alpha = kw.pop("alpha", np.full_like(t, 0.2))
    args = dict(
        stfpi="stfpi", fpi="fpi", paper_pids=KEYS[:2], tuned_pids=KEYS[2:4],
        alpha_trace=(t, alpha), delayed=metrics["stfpi"], delay=0.006,
        delay_margins={k: 0.05 for k in KEYS}, variants={"mass x2": metrics})
    args.update(kw)
    rows = evaluate_claims("linear", metrics, {k: k for k in KEYS}, **args)  # type: ignore[arg-type]
    assert [r.id for r in rows] == [f"C{i}" for i in range(1, 9)]
    assert all(r.plant == "linear" and r.evidence for r in rows)
    return {r.id: r.verdict for r in rows}


def _base() -> dict[str, dict[str, float]]:
    return {
        "pid_paper_1": _m(os_=8.0, tr=2.0, ts=5.0, umax=1.0),
        "pid_paper_2": _m(os_=0.0, tr=3.0, ts=6.0, umax=0.8),
        "pid_tuned": _m(os_=9.0, tr=1.5, ts=4.0, umax=1.0),
        "pid2_tuned": _m(os_=0.0, tr=1.8, ts=3.0, umax=1.0),
        "fpi": _m(os_=1.0, tr=1.2, ts=3.5, umax=0.4),
        "stfpi": _m(os_=0.1, tr=1.0, ts=2.0, umax=0.4),
    }


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


def test_c3_c5_c7_follow_their_numbers() -> None:
    m = _base()
    m["stfpi"]["u_max"] = 0.9
    m["fpi"]["settling_time"] = 1.5
    m["pid_paper_1"]["overshoot"] = 40.0
    v = _claims(m)
    assert (v["C3"], v["C5"], v["C7"]) == (NOT_HOLDS, NOT_HOLDS, PARTLY)


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


@pytest.mark.parametrize("os_, verdict", [(2.0, HOLDS), (25.0, NOT_HOLDS)])
def test_changed_plant_claim(os_: float, verdict: str) -> None:
    m = _base()
    changed = {k: dict(v) for k, v in m.items()}
    changed["stfpi"]["overshoot"] = os_
    assert _claims(m, variants={"mass x2": changed})["C8"] == verdict


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
            stfpi_equal="stfpi_10", stfpi_overshoot_limit=limit)
        return rows[0].verdict

    assert c1(0.5) == PARTLY  # tuned for no overshoot; tuned like the PIDs it overshoots
    assert c1(10.0) == HOLDS  # no overshoot although 10 % was allowed
    m["stfpi_10"]["overshoot"] = 0.2
    assert c1(0.5) == HOLDS
