"""One conformance suite over every registered controller kind (STYLE sections 3 and 12, like
Gymnasium's check_env).

The cases are built from the registry: every name of ``controller_names()`` with sample gains,
plus the special variants (anti-windup schemes, asymmetric limits, the fuzzy PI's conventions),
so a new kind is covered as soon as it is registered. Each case is checked for structure
(frozen, hashable state; pure step), the per-step law against a textbook re-implementation
written here, and the batched kernels against the per-step API.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from fuzzyservo.control import (
    FFPDController,
    FuzzyPIController,
    PIDController,
    SlidingModeController,
    WooFuzzyPIController,
)
from fuzzyservo.fuzzy import FuzzySystem, PackedSystem, Term, Variable, evaluate, pack
from fuzzyservo.fuzzy.engine import grid_form
from fuzzyservo.paper import alpha_system, du_system, paper_params
from fuzzyservo.paper.rulebases import ALPHA_TABLE, DU_TABLE
from fuzzyservo.registry import build_controller, build_plant, controller_kind, controller_names
from fuzzyservo.sim import Step, simulate_batch

H = 1e-3

#: Sample gains by name: awkward values (no exact ties at the limits), large enough that the
#: integral, the filtered derivative, the setpoint weights and saturation all matter within a
#: few dozen samples, and fuzzy scalings that keep e_n, Δe_n inside [-1, 1] part of the time.
SAMPLE_GAINS: dict[str, float] = {
    "kp": 4.3, "ki": 270.0, "kd": 0.031, "n": 90.0, "b": 0.6, "c": 0.35,
    "ke": 0.9, "kde": 0.7, "kdu": 0.21, "kx": 4.7,
    # sliding mode: s(0) = λ² 0.1 m = 1.37 inside the layer φ = 2.9 (every gain reaches the
    # first command), k_s/b = 1.49 (a unit error saturates the command)
    "lam": 3.7, "ks": 150.0, "phi": 2.9,
}


def _sample_gains(name: str) -> dict[str, float]:
    """Sample gains for every gain of kind ``name``; a gain unknown here (a new kind) takes
    the geometric mean of its tuning box, else its default."""
    out = {}
    for g in controller_kind(name).gains:
        if g.name in SAMPLE_GAINS:
            out[g.name] = SAMPLE_GAINS[g.name]
        elif g.search is not None:
            lo, hi = g.search
            out[g.name] = math.sqrt(lo * hi) if lo > 0 else 0.5 * (lo + hi)
        else:
            assert g.default is not None, f"{name}: gain {g.name} needs a sample value"
            out[g.name] = g.default
    return out


# (case id, registry name, gains over the samples, options)
VARIANTS: list[tuple[str, str, dict[str, float], dict[str, Any]]] = [
    ("pid-back-calculation", "pid", {}, {"anti_windup": "back-calculation"}),
    ("pid2-ipd-tracking", "pid2", {"b": 0.0, "c": 0.0},
     {"anti_windup": "back-calculation", "tracking_time": 0.004}),
    ("pid-none-asymmetric", "pid", {}, {"anti_windup": "none", "u_min": -0.3, "u_max": 0.5}),
    ("pi-clamping-asymmetric", "pi", {}, {"u_min": -0.2, "u_max": 0.7}),
    ("pid-unfiltered", "pid", {"n": math.inf}, {}),
    # per second, Δe is ~1/h larger: kde scaled down to keep Δe_n partly unsaturated
    ("fpi-first-filtered-per-second", "fpi", {"kde": 7e-4},
     {"initial_error": "first", "filter_time": 0.01, "de_per": "second"}),
    ("stfpi-asymmetric", "stfpi", {}, {"u_min": -0.4, "u_max": 0.7}),
    ("stfpi-first-filtered-per-second", "stfpi", {"kde": 7e-4},
     {"initial_error": "first", "filter_time": 0.003, "de_per": "second"}),
    ("smc-integral-asymmetric", "smc", {}, {"integral_action": "on", "u_min": -0.4,
                                           "u_max": 0.7}),
    # a thin layer (the ideal relay φ = 0 is test_smc.py's: its sign of a rounding-level s
    # cannot be compared with another implementation)
    ("smc-thin-no-jerk", "smc", {"phi": 0.05, "omega_f": 50.0, "zeta_f": 0.6},
     {"reference_jerk": "zero"}),
    # Woo et al.'s functions with offsets other than 1 (b < 1 shrinks φ near the setpoint)
    ("wfpi-offsets-asymmetric", "wfpi", {"phi_b": 0.4, "psi_d": 1.7},
     {"u_min": -0.4, "u_max": 0.7}),
    ("wfpi-first-filtered-per-second", "wfpi", {"kde": 7e-4},
     {"initial_error": "first", "filter_time": 0.003, "de_per": "second"}),
]

CASES: dict[str, tuple[str, dict[str, float], dict[str, Any]]] = {
    **{name: (name, _sample_gains(name), {}) for name in controller_names()},
    **{cid: (name, {**_sample_gains(name), **over}, opts) for cid, name, over, opts in VARIANTS},
}
IDS = list(CASES)


def _build(cid: str) -> Any:
    name, gains, options = CASES[cid]
    return build_controller(name, gains, dt=H, options=options)


signals = st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1)), min_size=1, max_size=40)
#: A long step that drives every case into saturation and back out (anti-windup matters).
WINDUP = [(1.0, 0.0)] * 25 + [(0.0, 0.4)] * 10 + [(-0.6, 0.2)] * 5 + [(0.05, 0.0)] * 10
#: Beyond a limit while the error pulls back (clamping must then integrate): a derivative kick
#: with e < 0, then b r - y > 0 with e < 0 (setpoint weight b < 1).
REVERSAL = [(0.0, 0.9)] * 40 + [(0.0, 0.1)] * 20 + [(-1.0, -0.9)] * 10 + [(0.0, 0.0)] * 5


def _run(ctl: Any, seq: list[tuple[float, float]], s: Any = None) -> tuple[list[float], Any]:
    s = ctl.initial_state() if s is None else s
    out = []
    for r, y in seq:
        u, s = ctl.step(s, r, y)
        out.append(u)
    return out, s


# ---------------------------------------------------------------------------------------------
# (a) structure: what the runtime_checkable Protocol could not check


@pytest.mark.parametrize("cid", IDS)
def test_structure(cid: str) -> None:
    ctl = _build(cid)
    assert type(ctl.dt) is float and math.isfinite(ctl.dt) and ctl.dt > 0.0
    assert ctl.dt == H  # exact: the value passed in, stored
    s0 = ctl.initial_state()
    assert dataclasses.is_dataclass(s0) and not isinstance(s0, type)
    for f in dataclasses.fields(s0):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(s0, f.name, getattr(s0, f.name))
    again = ctl.initial_state()
    assert again == s0 and hash(again) == hash(s0)
    packed, tables = ctl.pack().copy(), [t.copy() for t in ctl.tables()]
    s = s0
    for r, y in [(0.3, 0.0), (0.3, 0.1), (-0.2, 0.25)]:
        before = dataclasses.astuple(s)
        u, s_new = ctl.step(s, r, y)
        assert type(u) is float
        assert type(s_new) is type(s0)
        assert dataclasses.astuple(s) == before  # the state passed in is untouched
        s = s_new
    assert s != s0  # the state moved
    # the controller's own packed parameters and rule tables are untouched by stepping
    assert np.array_equal(ctl.pack(), packed, equal_nan=True)
    assert all(np.array_equal(a, b, equal_nan=True)
               for a, b in zip(ctl.tables(), tables, strict=True))


# ---------------------------------------------------------------------------------------------
# properties kept from the first suite


@pytest.mark.parametrize("cid", IDS)
def test_zero_error_from_rest_gives_zero_command(cid: str) -> None:
    u, _ = _run(_build(cid), [(0.0, 0.0)] * 50)
    assert u == [0.0] * 50  # exact: every term is a product with a zero error


@pytest.mark.parametrize("cid", IDS)
@settings(max_examples=30, deadline=None)
@given(seq=signals)
@example(seq=WINDUP)
def test_limits_hold_and_runs_are_deterministic(cid: str, seq: list[tuple[float, float]]
                                                ) -> None:
    ctl = _build(cid)
    u1, s1 = _run(ctl, seq)
    u2, s2 = _run(_build(cid), seq)
    assert u1 == u2 and s1 == s2  # exact: same inputs, same operations
    assert all(ctl.u_min <= u <= ctl.u_max for u in u1)  # exact: min/max clamp


@pytest.mark.parametrize("cid", IDS)
def test_limits_are_reached(cid: str) -> None:
    # the limits test above is not vacuous: the windup sequence hits the upper limit
    ctl = _build(cid)
    u, _ = _run(ctl, WINDUP)
    assert max(u) == ctl.u_max  # exact: the clamp returns the limit itself


@pytest.mark.parametrize("cid", IDS)
@settings(max_examples=20, deadline=None)
@given(seq=signals)
def test_state_round_trips_and_resumes(cid: str, seq: list[tuple[float, float]]) -> None:
    ctl = _build(cid)
    _, s = _run(ctl, seq)
    copy = ctl.unpack_state(ctl.pack_state(s))
    assert copy == s and type(copy) is type(s)  # exact: floats stored and read back
    tail = [(0.2, -0.1), (0.0, 0.05), (0.6, 0.1)]
    assert _run(ctl, tail, s) == _run(ctl, tail, copy)  # exact: equal states, same law
    # and resuming equals running the whole sequence in one go
    assert _run(ctl, seq + tail)[0][len(seq):] == _run(ctl, tail, copy)[0]  # exact, as above


# ---------------------------------------------------------------------------------------------
# (b) the per-step law against textbook re-implementations


def _params(cid: str) -> dict[str, Any]:
    """Every class parameter of case ``cid`` from the registry's declared data (gain defaults,
    the gains a kind fixes) and the case's options, with the class defaults of pid.py /
    fuzzy_pi.py's docstrings for the rest (not read from the built controller)."""
    name, gains, options = CASES[cid]
    kind = controller_kind(name)
    par: dict[str, Any] = {g.name: g.default for g in kind.gains}
    par.update(kind.implied)
    par.update(gains)
    par.update({"u_min": -1.0, "u_max": 1.0, "anti_windup": "clamping", "tracking_time": None,
                "initial_error": "zero", "de_per": "sample", "filter_time": 0.0,
                "integral_action": "off", "reference_jerk": "difference"})
    par.update(options)
    return par


def _textbook_pid(par: Mapping[str, Any], seq: list[tuple[float, float]],
                  integral0: float = 0.0) -> list[float]:
    """Backward-Euler 2-DOF PID with derivative filter and anti-windup, as in pid.py's
    module docstring (Åström & Hägglund 2006, ch. 3), from rest."""
    kp, ki, kd, n, b, c = (par[k] for k in ("kp", "ki", "kd", "n", "b", "c"))
    h, lo, hi = H, par["u_min"], par["u_max"]
    if par["anti_windup"] == "back-calculation":
        tt = par["tracking_time"]
        if tt is None:  # √(T_i T_d) = √(K_d/K_i), or T_i = K_p/K_i without derivative
            tt = math.sqrt(kd / ki) if kd > 0 else kp / ki
        kb = min(h / tt, 1.0)
    integral, deriv, ed_prev = integral0, 0.0, 0.0
    out = []
    for r, y in seq:
        e = r - y
        ed = c * r - y
        if math.isinf(n):
            deriv = kd * (ed - ed_prev) / h
        else:
            deriv = deriv / (1 + n * h) + kd * n / (1 + n * h) * (ed - ed_prev)
        i_new = integral + ki * h * e
        v = kp * (b * r - y) + i_new + deriv
        u = min(max(v, lo), hi)
        if par["anti_windup"] == "clamping":
            if (v > hi and e > 0) or (v < lo and e < 0):
                i_new = integral
        elif par["anti_windup"] == "back-calculation":
            i_new += kb * (u - v)
        integral, ed_prev = i_new, ed
        out.append(u)
    return out


def _general(system: FuzzySystem, table: tuple[tuple[str, ...], ...]) -> PackedSystem:
    """The paper's system from its printed table, with the output triangles written as
    degenerate trapezoids: the same sets, but evaluated by the general engine (rule strengths,
    piecewise-linear exact centroid), not the uniform-grid kernel the controllers use."""
    o = system.outputs[0]
    out = Variable(o.name, o.range, tuple(
        Term(t.name, "trapezoid", (t.params[0], t.params[1], t.params[1], t.params[2]))
        for t in o.terms))
    e, de = system.inputs
    general = FuzzySystem.from_table(table, columns=e, rows=de, output=out)
    assert grid_form(general) is None  # proof that the uniform kernel is not used
    packed = pack(general)
    assert packed.path != "uniform grid" and packed.compiled is not None
    return packed


_DU_GENERAL = _general(du_system(), DU_TABLE)
_ALPHA_GENERAL = _general(alpha_system(), ALPHA_TABLE)


def _textbook_fuzzy(par: Mapping[str, Any], self_tuning: bool | str,
                    seq: list[tuple[float, float]], u0: float = 0.0) -> list[float]:
    """Velocity-form fuzzy PI, fuzzy_pi.py's docstring (paper eqs. 9-12; Mudi & Pal 1999);
    ``self_tuning="woo"``: Woo, Chung & Lin (2000)'s φ and ψ of |e_n|, woo.py's docstring."""
    ke, kde, kdu, lo, hi = (par[k] for k in ("ke", "kde", "kdu", "u_min", "u_max"))
    a = math.exp(-H / par["filter_time"]) if par["filter_time"] > 0 else 0.0
    u_prev, e_prev, yf = u0, 0.0, 0.0
    out = []
    for k, (r, y) in enumerate(seq):
        if k == 0:
            yf = y
            e = r - yf
            e_prev = e if par["initial_error"] == "first" else 0.0
        else:
            yf = a * yf + (1 - a) * y
            e = r - yf
        de = e - e_prev if par["de_per"] == "sample" else (e - e_prev) / H
        en = min(max(ke * e, -1.0), 1.0)
        phi = psi = 1.0
        if self_tuning == "woo":
            phi = par["phi_a"] * abs(en) + par["phi_b"]
            psi = par["psi_c"] * (1.0 - abs(en)) + par["psi_d"]
        den = min(max(phi * kde * de, -1.0), 1.0)
        dun = float(evaluate(_DU_GENERAL, [en, den])[0])
        alpha = psi
        if self_tuning is True:
            alpha = float(evaluate(_ALPHA_GENERAL, [en, den])[0])
        u_prev = min(max(u_prev + alpha * kdu * dun, lo), hi)
        e_prev = e
        out.append(u_prev)
    return out


def _textbook_ffpd(par: Mapping[str, Any], seq: list[tuple[float, float]],
                   integral0: float = 0.0, y_prev: float = 0.0) -> list[float]:
    """Position control with feed-forward, ffpd.py's docstring (Jelali & Kroll 2003), from
    rest; the reference's rates are 0 here (these sequences have none): u = K_x e - K_afb â
    + I, â the filtered second difference of y, clamping anti-windup."""
    h, tf, lo, hi = H, par["tf"], par["u_min"], par["u_max"]
    integral, v_est, a_est = integral0, 0.0, 0.0
    out = []
    for r, y in seq:
        e = r - y
        v_new = (tf * v_est + (y - y_prev)) / (tf + h)  # backward Euler of s/(T_f s + 1)
        a_new = (tf * a_est + (v_new - v_est)) / (tf + h)
        i_new = integral + par["ki"] * h * e
        w = par["kx"] * e - par["ka_fb"] * a_new + i_new
        if not ((w > hi and e > 0) or (w < lo and e < 0)):
            integral = i_new
        y_prev, v_est, a_est = y, v_new, a_new
        out.append(min(max(w, lo), hi))
    return out


def _textbook_smc(par: Mapping[str, Any], seq: list[tuple[float, float]],
                  u0: float = 0.0) -> list[float]:
    """Sliding-mode law, smc.py's docstring (Slotine & Li 1991, ch. 7): the state-variable
    filter integrated by the trapezoidal rule (a linear solve per sample, not smc.py's closed
    form), s = (d/dt + λ)² e or (d/dt + λ)³ ∫e, u = u₀ + u_eq + (k_s/b) sat(s/φ), clamping;
    rd = rdd = 0 (the conformance sequences give none)."""
    lam, ks, phi, wf, zf = (par[k] for k in ("lam", "ks", "phi", "omega_f", "zeta_f"))
    b = par["k_o"] * par["omega_0"] ** 2
    a1, a2 = par["omega_0"] ** 2, 2.0 * par["delta"] * par["omega_0"]
    integral = par.get("integral_action", "off") == "on"
    c2, c1, c0 = (3 * lam, 3 * lam**2, lam**3) if integral else (2 * lam, lam**2, 0.0)
    lo, hi = par["u_min"], par["u_max"]
    a = np.array([[0.0, 1.0], [-wf * wf, -2.0 * zf * wf]])
    bb = np.array([0.0, wf * wf])
    lhs, rhs = np.eye(2) - 0.5 * H * a, np.eye(2) + 0.5 * H * a
    x, y_prev, ei = np.zeros(2), 0.0, 0.0
    out = []
    for k, (r, y) in enumerate(seq):
        if k == 0:
            x = np.array([y, 0.0])
        else:
            x = np.linalg.solve(lhs, rhs @ x + 0.5 * H * bb * (y + y_prev))
        acc = wf * wf * (y - x[0]) - 2.0 * zf * wf * x[1]
        e, ed, edd = r - y, -x[1], -acc
        ei_new = ei + (H * e if integral else 0.0)
        s = edd + c2 * ed + c1 * e + c0 * ei_new
        ueq = (a2 * acc + a1 * x[1] + c2 * edd + c1 * ed + c0 * e) / b
        sat = min(max(s / phi, -1.0), 1.0) if phi > 0 else float(np.sign(s))
        v = u0 + ueq + ks / b * sat
        u = min(max(v, lo), hi)
        if not ((v > hi and e > 0) or (v < lo and e < 0)):
            ei = ei_new
        y_prev = y
        out.append(u)
    return out


def _reference(cid: str, ctl: Any, seq: list[tuple[float, float]]) -> list[float]:
    par = _params(cid)
    if type(ctl) is PIDController:
        return _textbook_pid(par, seq)
    if type(ctl) is FFPDController:
        return _textbook_ffpd(par, seq)
    if isinstance(ctl, WooFuzzyPIController):
        return _textbook_fuzzy(par, "woo", seq)
    if isinstance(ctl, FuzzyPIController):
        return _textbook_fuzzy(par, type(ctl).self_tuning, seq)
    if isinstance(ctl, SlidingModeController):
        return _textbook_smc(par, seq)
    raise NotImplementedError(f"no textbook reference for {type(ctl).__name__}: add one here")


@pytest.mark.parametrize("cid", IDS)
@settings(max_examples=25, deadline=None)
@given(seq=signals)
@example(seq=WINDUP)
@example(seq=REVERSAL)
def test_step_follows_the_textbook_law(cid: str, seq: list[tuple[float, float]]) -> None:
    ctl = _build(cid)
    got, _ = _run(ctl, seq)
    # same formulas, some operations in another order: rounding only (commands are O(1);
    # the ffpd's acceleration estimate divides differences of O(1) m by (T_f + h)², up to
    # 1e6, where the limits clip it); the sliding-mode command is a sum of terms up to
    # (a2 + c2) ω_f² Δy/b ~ 1e3-1e4 on these jumps of y (its textbook solves the filter,
    # smc.py writes it out): 100 x
    tol = 1e-10 if CASES[cid][0] == "smc" else 1e-12
    assert got == pytest.approx(_reference(cid, ctl, seq), abs=tol, rel=0)


def test_anti_windup_schemes_differ_on_the_windup_sequence() -> None:
    # the textbook comparison above distinguishes the schemes: on WINDUP they give three
    # different command histories
    runs = {aw: _run(build_controller("pid", _sample_gains("pid"), dt=H,
                                      options={"anti_windup": aw}), WINDUP)[0]
            for aw in ("clamping", "back-calculation", "none")}
    assert runs["clamping"] != runs["back-calculation"] != runs["none"] != runs["clamping"]


# ---------------------------------------------------------------------------------------------
# (c) the batched kernels run the same law, row by row

STEP = 0.1  #: reference step of the batch runs [m]
#: Gains that cannot reach a first command from rest: the sliding-mode law's derivative
#: filter and the model's damping multiply ŷ', ŷ'' (0 while y has not moved).
FIRST_SAMPLE_BLIND: dict[str, tuple[str, ...]] = {
    "smc": ("omega_f", "zeta_f", "delta"), "ffpd": ("kv_ff", "ka_ff", "ka_fb", "tf")}


def _first_command(cid: str, gains: Mapping[str, float], y0: float, u0: float) -> float:
    """The textbook first command from rest at y0 holding u0, for a step of STEP."""
    par = {**_params(cid), **gains}
    name = CASES[cid][0]
    if controller_kind(name).cls is PIDController:
        # from the bumpless rest state the PID acts on offsets from y0 with integral u0
        return _textbook_pid(par, [(STEP, 0.0)], integral0=u0)[0]
    cls = controller_kind(name).cls
    if cls is FFPDController:
        return _textbook_ffpd(par, [(y0 + STEP, y0)], integral0=u0, y_prev=y0)[0]
    if cls is SlidingModeController:
        return _textbook_smc(par, [(y0 + STEP, y0)], u0)[0]
    mode = "woo" if issubclass(cls, WooFuzzyPIController) else cls.self_tuning
    return _textbook_fuzzy(par, mode, [(y0 + STEP, y0)], u0)[0]


def _changed(name: str, value: float) -> float:
    if math.isinf(value):
        return 60.0
    return 0.5 * value if name in ("b", "c") and value > 0 else 1.5 * value + 0.1


@pytest.mark.parametrize("cid", IDS)
def test_batch_first_commands_follow_each_rows_gains(cid: str) -> None:
    name, gains, options = CASES[cid]
    kind = controller_kind(name)
    plant = build_plant("linear", paper_params())
    rows = [gains] + [{**gains, g: _changed(g, gains[g])} for g in kind.gain_names]
    table = np.array([kind.class_row(kind.check_gains(r)) for r in rows])
    template = build_controller(name, gains, dt=H, options=options)
    res = simulate_batch(template, table, plant=plant, reference=Step(STEP), duration=5 * H,
                         keep_traces=True)
    assert res.u is not None and not res.diverged.any()
    batch_u0 = res.u[:, 0]
    for i, row in enumerate(rows):
        ctl = build_controller(name, row, dt=H, options=options)
        state = (ctl.initial_state(r0=plant.y0, y0=plant.y0, u0=plant.u0)
                 if isinstance(ctl, PIDController | FFPDController)
                 else ctl.initial_state(u0=plant.u0))
        u_step, _ = ctl.step(state, plant.y0 + STEP, plant.y0)
        # one compiled law on both paths (STYLE section 11): rounding only
        assert batch_u0[i] == pytest.approx(u_step, abs=1e-12, rel=0)
        assert batch_u0[i] == pytest.approx(  # textbook: operation order only
            _first_command(cid, row, plant.y0, plant.u0), abs=1e-12, rel=0)
    # a row differs from the first exactly when the textbook says its gain reaches u[0]
    expect = [abs(_first_command(cid, r, plant.y0, plant.u0)
                  - _first_command(cid, rows[0], plant.y0, plant.u0)) > 1e-9 for r in rows[1:]]
    differ = [abs(u - batch_u0[0]) > 1e-9 for u in batch_u0[1:]]  # far above rounding
    assert differ == expect
    if cid in controller_names():
        # the plain sample gains are chosen so that every gain reaches the first command,
        # except what a step from rest cannot reach: feed-forward gains (a step's ṙ and r̈
        # are 0 at every sample) and what acts only on the measurement's derivatives, 0 at
        # the first sample
        blind = FIRST_SAMPLE_BLIND.get(name, ())
        assert all(x for g, x in zip(kind.gain_names, expect, strict=True) if g not in blind), \
            dict(zip(kind.gain_names, expect, strict=True))
        if name == "ffpd":
            assert not any(x for g, x in zip(kind.gain_names, expect, strict=True)
                           if g in blind)


def test_first_error_convention_hides_kde_from_the_first_command() -> None:
    # e(-1) = e(0): Δe(0) = 0, so K_Δe cannot reach u[0] whatever its value
    expect = {}
    for kde in (1e-4, 7e-4, 3e-3):
        ctl = build_controller("fpi", {"ke": 0.9, "kde": kde, "kdu": 0.21}, dt=H,
                               options={"initial_error": "first"})
        expect[kde], _ = ctl.step(ctl.initial_state(), STEP, 0.0)
    assert len(set(expect.values())) == 1  # exact: Δe(0) = 0 whatever K_Δe multiplies
    # with e(-1) = 0 it does
    ctl = build_controller("fpi", {"ke": 0.9, "kde": 0.7, "kdu": 0.21}, dt=H)
    ctl2 = build_controller("fpi", {"ke": 0.9, "kde": 1.4, "kdu": 0.21}, dt=H)
    assert ctl.step(ctl.initial_state(), STEP, 0.0)[0] != ctl2.step(ctl2.initial_state(), STEP,
                                                                   0.0)[0]
