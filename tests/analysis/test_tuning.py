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
