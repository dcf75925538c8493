"""Sliding-mode control on the third-order linear model of the servo, with a boundary layer.

The model the law assumes is the paper's eq. (8) with the valve dynamics neglected (ω_v → ∞:
the valve's 688 rad/s lie far above the loop's and the hydraulic mode's frequencies; what is
neglected is then part of the model error the switching term must dominate)::

    x''' = -2 δ ω₀ ẍ - ω₀² ẋ + b u,      b = K_o ω₀²                      (model)

with u the command [-] (fraction of the rated valve input) and x [m]; K_o, ω₀ and δ are gains
of the kind (defaults: the paper's linear model at mid-stroke, :func:`smc_model_gains`).

Tracking error e = r - y, its derivatives from the reference's exact rates rd, rdd and the
derivative estimates ŷ', ŷ'' of the measured y (below)::

    ė = rd - ŷ',   ë = rdd - ŷ''

Sliding surface (Slotine & Li 1991, eq. 7.3: s = (d/dt + λ)^(n-1) e for an n-th order plant,
or (d/dt + λ)^n ∫e with integral action), λ > 0 [1/s]::

    s = ë + 2 λ ė + λ² e                                    integral_action = "off"
    s = ë + 3 λ ė + 3 λ² e + λ³ ∫e                          integral_action = "on"

written s = ë + c₂ ė + c₁ e + c₀ ∫e. On s = 0 the error decays as (p + λ)² e = 0 (or
(p + λ)³ ∫e = 0): a double (triple) real pole at -λ. Equivalent control: ṡ = 0 on the model::

    u_eq = [r''' + 2 δ ω₀ ŷ'' + ω₀² ŷ' + c₂ ë + c₁ ė + c₀ e] / b

The reference's jerk r''' is not among the law's inputs: ``reference_jerk="difference"``
(default) takes the backward difference (rdd_k - rdd_{k-1})/h of the exact acceleration
(unfiltered: rdd is computed in closed form, noise-free; exact inside every piece of an
S-curve, whose acceleration is piecewise linear), ``"zero"`` takes r''' = 0 (a step has
rd = rdd = r''' = 0 either way). Switching term with a boundary layer of width φ [m/s²]
against chattering (Slotine & Li 1991, Sec. 7.2)::

    u = u₀ + u_eq + (k_s / b) sat(s / φ),     sat(x) = min(max(x, -1), 1)
    u_k = min(max(v, u_min), u_max)

u₀ is the command held at rest (the bumpless start: 0 on the linear plant, the trim on the
nonlinear one). On the model and while u is not limited, ṡ = -k_s sat(s/φ): outside the layer
s moves towards it at the constant rate η = k_s [m/s³] (the reaching law ṡ = -η sgn s), so
|s| ≤ φ is reached from s(0) within t_r = (|s(0)| - φ)/η, and inside it s decays as
exp(-k_s t/φ). φ = 0 is the ideal relay (sat(s/0) = sgn s, 0 at s = 0), which chatters.
Within the layer the error is bounded by |e| ≤ φ/λ² (plain surface, Slotine & Li eq. 7.42).

Derivative estimates: a second-order state-variable filter on y with bandwidth ω_f [rad/s]
and damping ζ_f::

    ŷ'' = ω_f² (y - ŷ) - 2 ζ_f ω_f ŷ'

discretised by the trapezoidal rule (Tustin, exact for a piecewise-linear y, stable for every
ω_f h): with x = (ŷ, ŷ') and x' = A x + B y,
x_k = (I - A h/2)⁻¹ [(I + A h/2) x_{k-1} + (B h/2)(y_k + y_{k-1})]. Written out (Δ = 1 +
ζ_f ω_f h + ω_f² h²/4, d_k = (y_k - ŷ_{k-1}) + (y_{k-1} - ŷ_{k-1}))::

    ŷ_k  = ŷ_{k-1} + (h/Δ) ŷ'_{k-1} + (ω_f² h²/(4Δ)) d_k
    ŷ'_k = ((1 - ζ_f ω_f h - ω_f² h²/4)/Δ) ŷ'_{k-1} + (ω_f² h/(2Δ)) d_k

the same recursion in deviations from ŷ (so a constant y leaves the filter exactly at rest
and the absolute position, 0.5 m, does not round the derivatives), with the same arithmetic
in :func:`smc_step` and ``smc.c``; the estimates at sample k are ŷ'_k and
ŷ''_k = ω_f² (y_k - ŷ_k) - 2 ζ_f ω_f ŷ'_k. The filter starts at the
first measurement at rest (ŷ = y₀, ŷ' = 0: bumpless) and rdd_{-1} = rdd₀ (no jerk kick).

Anti-windup of ∫e: clamping (conditional integration, as :mod:`fuzzyservo.control.pid`):
when v is beyond a limit and e pushes further into it, ∫e keeps its previous value;
∫e is the backward-Euler sum ∫e_k = ∫e_{k-1} + h e_k.

The state's ``sigma`` is s of the last sample, recorded as the run's α column (``trace``).

Departures from the sources: Slotine & Li's switching gain is a function k(x) bounding the
model error; here it is the constant k_s (tuned). Guan & Pan (2008) design an adaptive
robust controller from the nonlinear EHS model with pressure feedback; no pressure reaches
a law here, so the law keeps the third-order linear model of the paper's eq. (8) and
estimates ẏ, ÿ from y. Bonchis et al. (2001) use a variable-structure surface on position
and velocity with a boundary layer; here the surface is third order (the model's order).

References
----------
J.-J. E. Slotine, W. Li, *Applied Nonlinear Control*, Prentice Hall, 1991, ch. 7.
C. Guan, S. Pan, "Nonlinear adaptive robust control of single-rod electro-hydraulic actuator
with unknown nonlinear parameters", IEEE Trans. Control Syst. Technol. 16(3), 2008, 434-445.
A. Bonchis, P. I. Corke, D. C. Rye, Q. P. Ha, "Variable structure methods in hydraulic servo
systems control", Automatica 37(4), 2001, 589-595.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal, Protocol

import numpy as np

from .._jit import kernel
from .._typing import FloatArray
from ..errors import ParameterError
from .law import Field, Law, LawController, indices

__all__ = [
    "SMC_GAIN_NAMES",
    "SMC_LAW",
    "SlidingModeController",
    "SlidingModeState",
    "smc_model_gains",
    "smc_step",
]

IntegralAction = Literal["off", "on"]
ReferenceJerk = Literal["difference", "zero"]
_INTEGRAL_CODE: dict[str, int] = {"off": 0, "on": 1}
_JERK_CODE: dict[str, int] = {"zero": 0, "difference": 1}

#: The law's packed parameters (:data:`SMC_LAW`).
PARAMS = (
    Field("c2", "1/s", "surface coefficient of ė: 2 λ (3 λ with integral action)"),
    Field("c1", "1/s²", "surface coefficient of e: λ² (3 λ²)"),
    Field("c0", "1/s³", "surface coefficient of ∫e: 0 (λ³)"),
    Field("h_int", "s", "integration step of ∫e: 0 without integral action, else h"),
    Field("inv_b", "s³/m", "1/b = 1/(K_o ω₀²), the model's inverse input gain"),
    Field("a1", "1/s²", "model coefficient of ẋ: ω₀²"),
    Field("a2", "1/s", "model coefficient of ẍ: 2 δ ω₀"),
    Field("ks_b", "-", "switching gain k_s/b"),
    Field("phi", "m/s²", "boundary-layer width φ (0: ideal relay)"),
    Field("jerk_gain", "1/s", "r''' = jerk_gain (rdd_k - rdd_{k-1}): 1/h, or 0"),
    Field("wf2", "1/s²", "filter ω_f²"),
    Field("cv", "1/s", "filter 2 ζ_f ω_f"),
    Field("m12", "s", "filter transition, ŷ from ŷ'"),
    Field("m22", "-", "filter transition, ŷ' from ŷ'"),
    Field("n1", "-", "filter gain of (y_k - ŷ) + (y_{k-1} - ŷ) to ŷ"),
    Field("n2", "1/s", "filter gain of (y_k - ŷ) + (y_{k-1} - ŷ) to ŷ'"),
    Field("u_min", "-", "lower command limit"),
    Field("u_max", "-", "upper command limit"),
)
#: The law's packed state.
STATE = (
    Field("started", "-", "1 once the first sample has started the filter"),
    Field("y_f", "m", "filtered position ŷ"),
    Field("v_f", "m/s", "velocity estimate ŷ'"),
    Field("y_prev", "m", "previous measurement y_{k-1}"),
    Field("e_int", "m s", "integral of the error ∫e"),
    Field("rdd_prev", "m/s²", "previous reference acceleration rdd_{k-1}"),
    Field("u_off", "-", "command held at rest u₀"),
    Field("sigma", "m/s²", "sliding variable s of the last sample"),
)
#: Gains a batch may vary, in column order.
GAINS = (
    Field("lam", "1/s", "surface bandwidth λ"),
    Field("ks", "m/s³", "switching gain k_s (reaching rate η)"),
    Field("phi", "m/s²", "boundary-layer width φ"),
    Field("omega_f", "rad/s", "derivative filter bandwidth ω_f"),
    Field("zeta_f", "-", "derivative filter damping ζ_f"),
    Field("k_o", "m/s", "model velocity gain K_o"),
    Field("omega_0", "rad/s", "model hydraulic natural frequency ω₀"),
    Field("delta", "-", "model hydraulic damping ratio δ"),
)
#: What the packing takes besides the gains.
CONSTANTS = (
    Field("ts", "s", "sample time h"),
    Field("u_min", "-", "lower command limit"),
    Field("u_max", "-", "upper command limit"),
    Field("integral", "-", "integral action: 0 off, 1 on"),
    Field("jerk", "-", "reference jerk: 0 zero, 1 backward difference of rdd"),
)
SMC_GAIN_NAMES: tuple[str, ...] = tuple(f.name for f in GAINS)

P = indices("SMCParams", PARAMS)
S = indices("SMCStateIndex", STATE)


@kernel(inline=True, error_model="numpy")
def smc_step(p: Any, s: Any, r: float, y: float, aux: Any, rd: float, rdd: float) -> float:
    """One sliding-mode sample on packed parameters ``p`` and state ``s`` (updated in
    place); returns u. ``aux`` is unused (no tables)."""
    if s[S.started] == 0.0:
        yf = y
        vf = 0.0
        rdd_prev = rdd
        s[S.started] = 1.0
    else:
        d = (y - s[S.y_f]) + (s[S.y_prev] - s[S.y_f])
        yf = s[S.y_f] + p[P.m12] * s[S.v_f] + p[P.n1] * d
        vf = p[P.m22] * s[S.v_f] + p[P.n2] * d
        rdd_prev = s[S.rdd_prev]
    acc = p[P.wf2] * (y - yf) - p[P.cv] * vf
    e = r - y
    ed = rd - vf
    edd = rdd - acc
    jerk = p[P.jerk_gain] * (rdd - rdd_prev)
    ei = s[S.e_int] + p[P.h_int] * e
    sv = edd + p[P.c2] * ed + p[P.c1] * e + p[P.c0] * ei
    ueq = p[P.inv_b] * (jerk + p[P.a2] * acc + p[P.a1] * vf + p[P.c2] * edd + p[P.c1] * ed
                        + p[P.c0] * e)
    phi = p[P.phi]
    if sv > phi:
        sw = 1.0
    elif sv < -phi:
        sw = -1.0
    elif phi > 0.0:
        sw = sv / phi
    else:
        sw = 0.0
    v = s[S.u_off] + ueq + p[P.ks_b] * sw
    u = min(max(v, p[P.u_min]), p[P.u_max])
    if (v > p[P.u_max] and e > 0.0) or (v < p[P.u_min] and e < 0.0):
        ei = s[S.e_int]  # clamping: conditional integration
    s[S.y_f] = yf
    s[S.v_f] = vf
    s[S.y_prev] = y
    s[S.e_int] = ei
    s[S.rdd_prev] = rdd
    s[S.sigma] = sv
    return u


@kernel(inline=True)
def _no_aux(tables: Any) -> float:
    """The law needs nothing of its (placeholder) tables."""
    return 0.0


def _pack(g: FloatArray, k: FloatArray) -> FloatArray:
    """Packed rows from gain rows (lam, ks, phi, omega_f, zeta_f, k_o, omega_0, delta) and the
    constants (ts, u_min, u_max, integral code, jerk code)."""
    lam, ks, phi, wf, zf, ko, w0, delta = g.T
    h = float(k[0])
    integral = k[3] == 1.0
    out = np.empty((g.shape[0], len(PARAMS)))
    if integral:
        out[:, P.c2] = 3.0 * lam
        out[:, P.c1] = 3.0 * (lam * lam)
        out[:, P.c0] = lam * lam * lam
        out[:, P.h_int] = h
    else:
        out[:, P.c2] = 2.0 * lam
        out[:, P.c1] = lam * lam
        out[:, P.c0] = 0.0
        out[:, P.h_int] = 0.0
    b = ko * (w0 * w0)
    out[:, P.inv_b] = 1.0 / b
    out[:, P.a1] = w0 * w0
    out[:, P.a2] = 2.0 * delta * w0
    out[:, P.ks_b] = ks / b
    out[:, P.phi] = phi
    out[:, P.jerk_gain] = 1.0 / h if k[4] == 1.0 else 0.0
    # Tustin: (I - A h/2)^-1 (I + A h/2) and (I - A h/2)^-1 B h/2, A = [[0, 1], [-w², -2 z w]]
    wf2 = wf * wf
    cv = 2.0 * zf * wf
    hh = 0.5 * h
    q = wf2 * hh * hh
    det = 1.0 + cv * hh + q
    out[:, P.wf2] = wf2
    out[:, P.cv] = cv
    out[:, P.m12] = h / det
    out[:, P.m22] = (1.0 - cv * hh - q) / det
    out[:, P.n1] = q / det
    out[:, P.n2] = (wf2 * hh) / det
    out[:, P.u_min] = k[1]
    out[:, P.u_max] = k[2]
    return out


def _rest(packed: FloatArray, y0: float, u0: float) -> FloatArray:
    """States before the first sample, holding the command u0 [-] (y0 [m] is not needed: the
    first sample starts the filter at the measurement)."""
    out = np.zeros((packed.shape[0], len(STATE)))
    out[:, S.u_off] = u0
    return out


#: The sliding-mode law: its layout, step, packing and C port (``smc.c``); its traced state
#: (the run's α column) is the sliding variable s.
SMC_LAW = Law(name="smc", title="sliding-mode control", params=PARAMS, state=STATE,
              gains=GAINS, constants=CONSTANTS, step=smc_step, prepare=_no_aux, pack=_pack,
              rest=_rest, trace="sigma", c_source=Path(__file__).with_name("smc.c"),
              st_source=Path(__file__).with_name("smc.st"),
              feedforward=True)


class _LinearModel(Protocol):
    """What :func:`smc_model_gains` reads of a linear servo model
    (:class:`fuzzyservo.plant.linear.LinearServo`)."""

    K_o: float
    omega_0: float
    damping: float


def smc_model_gains(linear_servo: _LinearModel) -> dict[str, float]:
    """The model gains of the sliding-mode law from a linear servo model (eq. 8).

    Parameters
    ----------
    linear_servo : LinearServo
        The model (:class:`fuzzyservo.plant.linear.LinearServo`: ``K_o`` [m/s], ``omega_0``
        [rad/s], ``damping`` [-]); its valve stage is what the law neglects.

    Returns
    -------
    dict
        ``{"k_o": K_o [m/s], "omega_0": ω₀ [rad/s], "delta": δ [-]}``, gains of the kind.

    Examples
    --------
    >>> from fuzzyservo.plant import LinearServo
    >>> m = LinearServo(K_o=0.26, omega_0=19.6, damping=0.1, omega_v=688.7, zeta_v=0.357)
    >>> smc_model_gains(m)
    {'k_o': 0.26, 'omega_0': 19.6, 'delta': 0.1}
    """
    return {"k_o": float(linear_servo.K_o), "omega_0": float(linear_servo.omega_0),
            "delta": float(linear_servo.damping)}


@dataclass(frozen=True, slots=True)
class SlidingModeState:
    """State of a :class:`SlidingModeController` between samples."""

    started: bool  #: False before the first sample (the filter not yet started)
    y_f: float  #: filtered position ŷ [m]
    v_f: float  #: velocity estimate ŷ' [m/s]
    y_prev: float  #: previous measurement [m]
    e_int: float  #: integral of the error [m s]
    rdd_prev: float  #: previous reference acceleration [m/s²]
    u_off: float  #: command held at rest [-]
    sigma: float = 0.0  #: sliding variable s of the last sample [m/s²]


#: Defaults of the model gains: the paper's linear model at mid-stroke (0.5 m),
#: ``smc_model_gains(LinearServo.from_params(paper_params(), linearize(paper_params(), 0.5)))``
#: (K_o = Q_rated/A_f; ω₀, δ of the linearisation; tests/control/test_smc.py checks them).
PAPER_MODEL_GAINS: dict[str, float] = {
    "k_o": 0.2619399234560411,
    "omega_0": 19.60000000000001,
    "delta": 0.09999999999994526,
}


@dataclass(frozen=True, slots=True, kw_only=True)
class SlidingModeController(LawController):
    """Sliding-mode controller with boundary layer (see the module docstring for the law).

    Parameters
    ----------
    dt : float
        Sample period h [s].
    lam : float
        Surface bandwidth λ [1/s], >= 0.
    ks : float
        Switching gain k_s [m/s³] (the reaching rate η), >= 0.
    phi : float
        Boundary-layer width φ [m/s²], >= 0 (0: ideal relay).
    omega_f, zeta_f : float
        Bandwidth [rad/s] and damping [-] of the derivative filter, >= 0.
    k_o, omega_0, delta : float
        The model's velocity gain K_o [m/s] (> 0), hydraulic natural frequency ω₀ [rad/s]
        (> 0) and damping ratio δ [-] (>= 0).
    u_min, u_max : float
        Command limits [-].
    integral_action : {"off", "on"}
        Surface without or with the integral term (clamping anti-windup).
    reference_jerk : {"difference", "zero"}
        r''' in the equivalent control: backward difference of rdd, or 0.
    """

    dt: float  #: sample period [s]
    lam: float = 5.0  #: surface bandwidth λ [1/s]
    ks: float = 10.0  #: switching gain k_s [m/s³]
    phi: float = 1.0  #: boundary-layer width φ [m/s²]
    omega_f: float = 200.0  #: derivative filter bandwidth ω_f [rad/s]
    zeta_f: float = 1.0  #: derivative filter damping ζ_f [-]
    k_o: float = PAPER_MODEL_GAINS["k_o"]  #: model velocity gain K_o [m/s]
    omega_0: float = PAPER_MODEL_GAINS["omega_0"]  #: model natural frequency ω₀ [rad/s]
    delta: float = PAPER_MODEL_GAINS["delta"]  #: model hydraulic damping ratio δ [-]
    u_min: float = -1.0  #: lower command limit [-]
    u_max: float = 1.0  #: upper command limit [-]
    integral_action: IntegralAction = "off"  #: integral term in the surface
    reference_jerk: ReferenceJerk = "difference"  #: r''' estimate

    law: ClassVar[Law] = SMC_LAW
    state_class: ClassVar[type] = SlidingModeState
    gain_names: ClassVar[tuple[str, ...]] = SMC_GAIN_NAMES

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ParameterError(f"sample time dt must be finite and > 0 s, got {self.dt!r}")
        self.check_gain_rows(self.gain_row()[None, :])
        if not (math.isfinite(self.u_min) and math.isfinite(self.u_max)
                and self.u_min <= 0.0 <= self.u_max and self.u_min < self.u_max):
            raise ParameterError(
                f"need finite u_min <= 0 <= u_max, u_min < u_max, got [{self.u_min!r}, "
                f"{self.u_max!r}]")
        if self.integral_action not in _INTEGRAL_CODE:
            raise ParameterError(f"integral_action must be one of {sorted(_INTEGRAL_CODE)}, "
                                 f"got {self.integral_action!r}")
        if self.reference_jerk not in _JERK_CODE:
            raise ParameterError(f"reference_jerk must be one of {sorted(_JERK_CODE)}, got "
                                 f"{self.reference_jerk!r}")

    def check_gain_rows(self, gains: FloatArray) -> None:
        """Gains finite and >= 0; the model's k_o and omega_0 > 0 (b = K_o ω₀² divides)."""
        for j, name in enumerate(SMC_GAIN_NAMES):
            col = gains[:, j]
            positive = name in ("k_o", "omega_0")
            bad = ~(np.isfinite(col) & ((col > 0.0) if positive else (col >= 0.0)))
            if np.any(bad):
                value = float(col[np.argmax(bad)])
                allowed = "finite and > 0" if positive else "finite and >= 0"
                raise ParameterError(f"gain {name} must be {allowed}, got {value!r}")

    def initial_state(self, *, u0: float = 0.0) -> SlidingModeState:
        """State before the first sample, holding the command ``u0`` [-] (bumpless start:
        the first sample starts the filter at its measurement)."""
        return SlidingModeState(started=False, y_f=0.0, v_f=0.0, y_prev=0.0, e_int=0.0,
                                rdd_prev=0.0, u_off=u0, sigma=0.0)

    def law_constants(self) -> FloatArray:
        """The packing constants: ts, u_min, u_max, integral code, jerk code."""
        return np.array([self.dt, self.u_min, self.u_max,
                         _INTEGRAL_CODE[self.integral_action],
                         _JERK_CODE[self.reference_jerk]], dtype=np.float64)
