"""Fuzzy PI and self-tuning fuzzy PI against an independent scikit-fuzzy implementation."""

from __future__ import annotations

import numpy as np
import pytest
import skfuzzy as fuzz

from fuzzyservo.control import FuzzyPIController, SelfTuningFuzzyPIController
from fuzzyservo.errors import ParameterError
from fuzzyservo.fuzzy import evaluate, pack
from fuzzyservo.paper import alpha_system, du_system

H = 1e-3
# Fig. 3a / 3b as printed (rows Δe NB..PB, columns e NB..PB), transcribed here independently
_DU = ["NB NB NB NM NS NS ZO", "NB NM NM NM NS ZO PS", "NB NM NS NS ZO PS PM",
       "NB NM NS ZO PS PM PB", "NM NS ZO PS PS PM PB", "NS ZO PS PM PM PM PB",
       "ZO PS PS PM PB PB PB"]
_ALPHA = ["VB VB VB B SB S ZO", "VB VB B B MB S VS", "VB MB B VB VS S VS",
          "S SB MB ZO MB SB S", "VS S VS VB B MB VB", "VS S MB B B VB VB",
          "ZO S SB B VB VB VB"]
_DUL = ["NB", "NM", "NS", "ZO", "PS", "PM", "PB"]
_AL = ["ZO", "VS", "S", "SB", "MB", "B", "VB"]
_U = np.linspace(-1.0, 1.0, 40001)
_A = np.linspace(0.0, 1.0, 40001)


def _sets(x: np.ndarray, lo: float, hi: float) -> list[np.ndarray]:
    d = (hi - lo) / 6
    return [fuzz.trimf(x, [lo + (k - 1) * d, lo + k * d, lo + (k + 1) * d]) for k in range(7)]


def _mamdani(e: float, de: float, rows: list[str], labels: list[str], out: np.ndarray) -> float:
    e, de = float(np.clip(e, -1, 1)), float(np.clip(de, -1, 1))
    mu_e = [float(m[0]) for m in _sets(np.array([e]), -1, 1)]
    mu_d = [float(m[0]) for m in _sets(np.array([de]), -1, 1)]
    out_sets = _sets(out, out[0], out[-1])
    agg = np.zeros_like(out)
    for i2, row in enumerate(rows):
        for i1, lab in enumerate(row.split()):
            w = min(mu_d[i2], mu_e[i1])
            if w > 0:
                agg = np.maximum(agg, np.minimum(w, out_sets[labels.index(lab)]))
    return float(fuzz.defuzz(out, agg, "centroid"))


def _reference(seq: list[tuple[float, float]], ke: float, kde: float, kdu: float,
               self_tuning: bool) -> tuple[list[float], list[float]]:
    """Eqs. (9)-(12) written out, e(-1) = 0, u(-1) = 0, |u| <= 1."""
    u_prev, e_prev = 0.0, 0.0
    us, alphas = [], []
    for r, y in seq:
        e = r - y
        de = e - e_prev
        dun = _mamdani(ke * e, kde * de, _DU, _DUL, _U)
        alpha = _mamdani(ke * e, kde * de, _ALPHA, _AL, _A) if self_tuning else 1.0
        u_prev = min(max(u_prev + alpha * kdu * dun, -1.0), 1.0)
        e_prev = e
        us.append(u_prev)
        alphas.append(alpha)
    return us, alphas


@pytest.mark.parametrize("cls", [FuzzyPIController, SelfTuningFuzzyPIController])
def test_matches_scikit_fuzzy_reference(cls: type[FuzzyPIController]) -> None:
    rng = np.random.default_rng(7)
    seq = [(0.1, float(y)) for y in np.cumsum(rng.normal(0.004, 0.01, 40))]
    ctl = cls.from_systems(du_system(), alpha_system(), dt=H, ke=10.0, kde=50.0, kdu=0.2)
    s = ctl.initial_state()
    us, alphas = [], []
    for r, y in seq:
        u, s = ctl.step(s, r, y)
        us.append(u)
        alphas.append(s.alpha)
    # a packed system is taken as it is: the same tables as packing here
    packed = cls.from_systems(pack(du_system()), pack(alpha_system()), dt=H, ke=10.0,
                              kde=50.0, kdu=0.2)
    assert np.array_equal(packed.pack(), ctl.pack(), equal_nan=True)
    assert all(np.array_equal(a, b, equal_nan=True)
               for a, b in zip(packed.tables(), ctl.tables(), strict=True))
    ref_u, ref_a = _reference(seq, 10.0, 50.0, 0.2, cls.self_tuning)
    # skfuzzy samples the output universe (40001 points): centroid error < 1e-7 per sample
    assert us == pytest.approx(ref_u, abs=1e-6)
    assert alphas == pytest.approx(ref_a, abs=1e-6)


def test_alpha_bounds_and_steady_state_value() -> None:
    ctl = SelfTuningFuzzyPIController.from_systems(du_system(), alpha_system(), dt=H, ke=10.0,
                                                   kde=5000.0, kdu=0.01)
    s = ctl.initial_state()
    rng = np.random.default_rng(3)
    for r, y in rng.uniform(-0.3, 0.3, (500, 2)):
        _, s = ctl.step(s, float(r), float(y))
        assert 1 / 18 - 1e-12 <= s.alpha <= 17 / 18 + 1e-12  # exact centroid bounds
    for _ in range(2):
        _, s = ctl.step(s, 0.2, 0.2)
    assert s.alpha == pytest.approx(1 / 18, abs=1e-12)  # α(ZO, ZO): exact centroid, rounding


def test_options_initial_error_and_de_per_second() -> None:
    kw = {"ke": 10.0, "kdu": 0.3}
    first = FuzzyPIController.from_systems(du_system(), dt=H, kde=50.0, initial_error="first",
                                           **kw)
    u, _ = first.step(first.initial_state(), 0.05, 0.0)
    # e(-1) = e(0): Δe = 0, so Δu_n = Δu(e_n = 0.5, 0) from the Δu system alone
    assert u == pytest.approx(0.3 * float(evaluate(du_system(), [0.5, 0.0])[0]), rel=1e-12)
    per_s = FuzzyPIController.from_systems(du_system(), dt=H, kde=50.0 * H, de_per="second",
                                           **kw)
    per_k = FuzzyPIController.from_systems(du_system(), dt=H, kde=50.0, **kw)
    sa, sb = per_s.initial_state(), per_k.initial_state()
    for y in np.linspace(0.0, 0.04, 30):
        ua, sa = per_s.step(sa, 0.05, float(y))
        ub, sb = per_k.step(sb, 0.05, float(y))
        assert ua == pytest.approx(ub, rel=1e-12, abs=1e-15)  # same Δe_n up to rounding


def test_measurement_filter_is_first_order() -> None:
    tf = 0.02
    ctl = FuzzyPIController.from_systems(du_system(), dt=H, ke=1.0, kde=1.0, kdu=0.0,
                                         filter_time=tf)
    s = ctl.initial_state()
    _, s = ctl.step(s, 0.0, 0.0)  # filter starts at y(0) = 0
    for _ in range(100):
        _, s = ctl.step(s, 0.0, 1.0)
    a = np.exp(-H / tf)
    assert s.y_filtered == pytest.approx(1.0 - a**100, rel=1e-12)  # y_f(k) = a y_f + (1-a) y


def test_self_tuning_needs_alpha_rules_and_gains_are_checked() -> None:
    with pytest.raises(ParameterError, match="alpha"):
        SelfTuningFuzzyPIController.from_systems(du_system(), dt=H, ke=1.0, kde=1.0, kdu=1.0)
    with pytest.raises(ParameterError, match="kde"):
        FuzzyPIController.from_systems(du_system(), dt=H, ke=1.0, kde=-1.0, kdu=1.0)
    with pytest.raises(ParameterError, match="initial_error"):
        FuzzyPIController.from_systems(du_system(), dt=H, ke=1.0, kde=1.0, kdu=1.0,
                                       initial_error="one")
