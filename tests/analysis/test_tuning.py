"""The tuner finds known constrained optima of analytic objectives."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzyservo.analysis.tuning import (
    GainBounds,
    TuningConstraints,
    constraint_violation,
    penalised_cost,
    tune,
)
from fuzzyservo.errors import ParameterError


def _bowl(gains: np.ndarray) -> dict[str, np.ndarray]:
    """IAE is a bowl centred on (a, b) = (1, 2); overshoot grows with a (20 % per unit)."""
    a, b = gains[:, 0], gains[:, 1]
    n = gains.shape[0]
    return {
        "iae": 0.1 * (0.1 + (a - 1.0) ** 2 + (np.log10(b) - np.log10(2.0)) ** 2),
        "itae": np.zeros(n), "ise": np.zeros(n),
        "overshoot": 20.0 * a, "steady_state_error": np.zeros(n),
        "settling_time": np.ones(n), "u_max": np.ones(n),
    }


def test_unconstrained_optimum_is_found() -> None:
    bounds = GainBounds(names=("a", "b"), lower=(0.0, 0.1), upper=(3.0, 50.0),
                        log_scale=(False, True))
    res = tune(_bowl, bounds, objective="iae", step_size=0.1, seed=1,
               constraints=TuningConstraints(max_overshoot=None))
    # Nelder-Mead polish with xatol 1e-4 in search coordinates
    assert res.gains["a"] == pytest.approx(1.0, abs=1e-3)
    assert res.gains["b"] == pytest.approx(2.0, rel=1e-3)
    assert res.feasible
    assert res.n_evaluations > res.generations > 0


def test_overshoot_constraint_moves_optimum_to_its_boundary() -> None:
    bounds = GainBounds(names=("a", "b"), lower=(0.0, 0.1), upper=(3.0, 50.0),
                        log_scale=(False, True))
    res = tune(_bowl, bounds, objective="iae", step_size=0.1, seed=2,
               constraints=TuningConstraints(max_overshoot=10.0))
    # the constrained optimum is a = 0.5 (overshoot exactly 10 %); the penalty is exact (L1),
    # so the optimum sits on the boundary up to the polish tolerance
    assert res.metrics["overshoot"] <= 10.0 + 1e-6
    assert res.gains["a"] == pytest.approx(0.5, abs=2e-3)
    assert res.feasible


def test_seed_makes_the_search_reproducible() -> None:
    bounds = GainBounds(names=("a", "b"), lower=(0.0, 0.1), upper=(3.0, 50.0))
    r1 = tune(_bowl, bounds, objective="iae", step_size=0.1, seed=7, maxiter=5, polish=False)
    r2 = tune(_bowl, bounds, objective="iae", step_size=0.1, seed=7, maxiter=5, polish=False)
    assert r1.gains == r2.gains


def test_non_finite_metrics_are_infeasible_not_errors() -> None:
    m = _bowl(np.array([[1.0, 2.0], [1.0, 2.0]]))
    m["iae"][1] = np.nan
    m["settling_time"][0] = np.nan
    c = penalised_cost(m, "iae", TuningConstraints(max_overshoot=None), 0.1)
    assert np.all(np.isfinite(c))
    assert c[1] == 1.0e6
    assert constraint_violation(m, TuningConstraints(max_overshoot=None), 0.1)[0] == 1.0


@pytest.mark.parametrize("kwargs, word", [
    ({"names": ("a",), "lower": (1.0,), "upper": (1.0,)}, "lower < upper"),
    ({"names": ("a",), "lower": (-1.0,), "upper": (1.0,)}, ">= 0"),
    ({"names": ("a",), "lower": (0.0,), "upper": (1.0,), "log_scale": (True,)}, "log scale"),
    ({"names": ("a", "b"), "lower": (0.0,), "upper": (1.0, 2.0)}, "entries"),
])
def test_bad_bounds_are_named(kwargs: dict, word: str) -> None:
    with pytest.raises(ParameterError, match=word):
        GainBounds(**kwargs)


def test_unknown_objective_is_rejected() -> None:
    bounds = GainBounds(names=("a",), lower=(0.0,), upper=(1.0,))
    with pytest.raises(ParameterError, match="objective"):
        tune(lambda g: {}, bounds, objective="mse", step_size=0.1)


# ------------------------------------------------------ stopping rule, zero region, parsimony

def test_stop_rule_needs_a_stalled_best_and_a_gathered_population() -> None:
    from fuzzyservo.analysis.tuning import StopRule

    rule = StopRule(patience=3, rtol=1e-3, spread=0.01)
    gathered = np.array([1.0, 1.005, 1.009, 2.0])  # median 1.007: within 1 % of the best
    assert not rule.converged((5.0, 2.0, 1.0), gathered)  # fewer than 3 generations
    assert rule.converged((1.0005, 1.0, 1.0, 1.0), gathered)  # improved 5e-4 <= 1e-3
    assert not rule.converged((1.01, 1.0, 1.0, 1.0), gathered)  # improved 1e-2
    spread_out = np.array([1.0, 1.5, 2.0, 3.0])  # median 1.75
    assert not rule.converged((1.0, 1.0, 1.0, 1.0), spread_out)
    with pytest.raises(ParameterError, match="patience"):
        StopRule(patience=0)


def test_a_gain_that_may_be_zero_has_a_decade_that_means_zero() -> None:
    from fuzzyservo.analysis.tuning import ZERO_DECADES

    b = GainBounds(names=("kp", "ki"), lower=(0.01, 1e-3), upper=(100.0, 1e3),
                   log_scale=(True, True), zero=(False, True))
    span = 6.0 + ZERO_DECADES  # ki: log10 1e-3 .. 1e3, plus the zero decade
    u = np.array([[0.5, 0.0], [0.5, 0.999 * ZERO_DECADES / span],
                  [0.5, ZERO_DECADES / span], [0.5, 1.0]])
    g = b.from_unit(u)
    assert g[0, 1] == 0.0 and g[1, 1] == 0.0  # the whole zero decade is 0
    assert g[2, 1] == pytest.approx(1e-3) and g[3, 1] == pytest.approx(1e3)
    back = b.to_unit(np.array([[1.0, 0.0], [1.0, 1e-3]]))
    assert back[0, 1] == pytest.approx(0.5 * ZERO_DECADES / span)  # middle of the decade
    assert b.from_unit(back)[0, 1] == 0.0 and b.from_unit(back)[1, 1] == pytest.approx(1e-3)
    assert b.at_bounds(np.array([1.0, 0.0])) == {"ki": "lower"}
    assert b.at_bounds(np.array([1.0, 1e-3])) == {}  # the smallest non-zero value is no bound
    assert b.at_bounds(np.array([100.0, 1e3])) == {"kp": "upper", "ki": "upper"}
    assert b.at_bounds(np.array([0.01, 5.0])) == {"kp": "lower"}
    with pytest.raises(ParameterError, match="may be 0 only on a log scale"):
        GainBounds(names=("b",), lower=(0.0,), upper=(1.0,), zero=(True,))


def _flat(gains: np.ndarray) -> dict[str, np.ndarray]:
    """IAE grows with a, and b barely matters (1e-6 per unit); the overshoot is exactly at a
    10 % limit, and 1e-9 points above it when b = 0."""
    a, b = gains[:, 0], gains[:, 1]
    n = gains.shape[0]
    return {"iae": 0.1 * (0.1 + (a - 1.0) ** 2) + 1e-6 * b, "itae": np.zeros(n),
            "ise": np.zeros(n), "overshoot": 10.0 + (b == 0.0) * 1e-9,
            "steady_state_error": np.zeros(n), "settling_time": np.ones(n),
            "u_max": np.ones(n)}


def test_switching_a_term_off_never_makes_a_feasible_result_infeasible() -> None:
    """b costs next to nothing, so the parsimony step would switch it off; but b = 0 breaks
    the overshoot limit by 1e-9 points (a penalty far below the stopping tolerance), so it
    is kept (the reviewer's case: a feasible result turned infeasible by a switched-off
    term)."""
    bounds = GainBounds(names=("a", "b"), lower=(0.0, 1e-3), upper=(3.0, 1.0),
                        log_scale=(False, True), zero=(False, True))
    res = tune(_flat, bounds, objective="iae", step_size=0.1, seed=3,
               constraints=TuningConstraints(max_overshoot=10.0))
    assert res.feasible and res.gains["b"] > 0.0


def test_an_infeasible_neighbour_never_beats_a_feasible_one_on_the_boundary() -> None:
    from fuzzyservo.analysis.tuning import INFEASIBLE_STEP

    m = _bowl(np.array([[0.5, 2.0], [0.5 + 1e-9, 2.0]]))  # overshoot 10 % and 10 % + 2e-8
    c = penalised_cost(m, "iae", TuningConstraints(max_overshoot=10.0), 0.1)
    assert c[1] - c[0] >= INFEASIBLE_STEP
