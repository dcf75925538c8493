"""Position control with feed-forward: the industrial controller of hydraulic axes.

The structure (Jelali & Kroll, *Hydraulic Servo-systems: Modelling, Identification and
Control*, Springer 2003, the chapter on linear position control: proportional position
control of a valve-controlled cylinder, velocity and acceleration feed-forward from the
reference profile, and state feedback of the load pressure, or equivalently of the
acceleration, for active damping)::

    u = K_x e + K_vff ṙ + K_aff r̈ + K_afb (r̈ - â) + I,      e = r - y,   |u| limited
    I = K_i ∫ e dt                                           (clamping anti-windup)

- **Proportional position gain** K_x [1/m]: with eq. (8)'s velocity gain K_o the loop gain
  (the "velocity gain" of hydraulics texts) is K_v = K_x K_o [1/s]; a P loop on eq. (8) follows
  a ramp of slope v with the steady error v / (K_x K_o), the plant having one integrator.
- **Velocity and acceleration feed-forward** from the reference's exact rates ṙ, r̈ (the
  reference objects' ``rates``). The inverse of eq. (8)'s hydraulic part,
  u = [s (s²/ω₀² + 2δ s/ω₀ + 1) / K_o] r, truncated after r̈, gives
  K_vff = 1/K_o [s/m] and K_aff = 2δ/(ω₀ K_o) [s²/m]. With any K_x > 0 and K_vff = 1/K_o
  the steady ramp error is 0 (tests/control/test_ffpd.py). Without feedback (K_x = 0), on
  eq. (8): a move of bounded acceleration (an S-curve) cruises at speed v with the error
  v (2ζ_v/ω_v + h/2), what the truncated inverse leaves (the valve's lag, and the hold's half
  sample accumulated while accelerating), and ends at rest on its target (eq. 8 integrates
  K_o u); a ramp, whose acceleration is an impulse at its start that no sample carries,
  cruises with v (2δ/ω₀ + 2ζ_v/ω_v), as with K_aff = 0.
- **Active damping by acceleration feedback** K_afb [s²/m]. Jelali & Kroll damp the
  hydraulic mode by feeding back the load pressure p_L; no pressure measurement reaches a law
  here (the linear eq. (8) has none), so the law feeds back the acceleration estimated from
  the measured position instead, the substitute they also describe: the load's equation of
  motion A p_L = m ẍ + (friction and load force) makes the two equivalent up to friction and
  load force. On eq. (8), u = u_c - K_afb s² y turns the hydraulic part into
  K_o / [s (s²/ω₀² + (2δ/ω₀ + K_o K_afb) s + 1)]: the damping becomes
  δ' = δ + K_o K_afb ω₀ / 2 at the same ω₀. The term acts on the acceleration *error*
  r̈ - â, not on -â: it then does not oppose the acceleration the profile asks for, so the
  feed-forward K_aff = 2δ/(ω₀ K_o) stays the exact inverse whatever K_afb (with -â it would
  have to be 2δ'/(ω₀ K_o), and a tuned K_afb would leave a held K_aff wrong). On a step
  (r̈ = 0 at every sample) the two forms are the same.
- **Integral action** K_i [1/(m s)], optional (default 0: the plant integrates), with
  clamping anti-windup (conditional integration, as the PID's ``"clamping"``: when the
  unlimited command is beyond a limit and e pushes further into it, I keeps its value).

Estimates of velocity and acceleration from the measurement, each a backward difference
through a first-order filter of time constant T_f (``tf``; the transfer function
s/(T_f s + 1) discretised by backward Euler, s ≈ (1 - z⁻¹)/h)::

    v̂_k = a v̂_{k-1} + b (y_k - y_{k-1})          a = T_f/(T_f + h),  b = 1/(T_f + h)
    â_k = a â_{k-1} + b (v̂_k - v̂_{k-1})

so â = s² / (T_f s + 1)² · y; T_f = 0 gives the plain differences (y_k - 2 y_{k-1} +
y_{k-2})/h². Backward Euler keeps the filter stable and free of ringing for every T_f.

One sample (h the sample time)::

    I_k = I_{k-1} + K_i h e_k
    w_k = K_x e_k + K_vff ṙ_k + K_aff r̈_k + K_afb (r̈_k - â_k) + I_k
    u_k = min(max(w_k, u_min), u_max)
    if (w_k > u_max and e_k > 0) or (w_k < u_min and e_k < 0): I_k = I_{k-1}

At rest at y0 holding u0: I = u0, y_{k-1} = y0, v̂ = â = 0 (bumpless).

Default gains from the linear model (:func:`ffpd_model_gains`, docs/model.md, "Position
control with feed-forward"): K_vff, K_aff the inverse above; K_afb for a target damping δ*
(default 0.5): K_afb = 2 (δ* - δ)/(ω₀ K_o) (0 if δ >= δ*); the loop gain
K_v = min(ω₀/3, 2 δ' ω₀ / g_m) with gain margin g_m = 2 (Merritt's bound K_v < 2 δ' ω₀ for a
P loop on K_v / [s (s²/ω₀² + 2δ' s/ω₀ + 1)], and the rule of thumb K_v ≈ ω₀/3 of industrial
practice), K_x = K_v / K_o; T_f = 0.1/ω₀ (11° of filter phase at ω₀); K_i = 0.

References
----------
M. Jelali and A. Kroll, *Hydraulic Servo-systems: Modelling, Identification and Control*,
Springer, 2003. doi:10.1007/978-1-4471-0099-7.
H. E. Merritt, *Hydraulic Control Systems*, Wiley, 1967.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Protocol

import numpy as np

from .._jit import kernel
from .._typing import FloatArray
from ..errors import ParameterError
from .law import Field, Law, LawController, indices

__all__ = [
    "FFPD_GAIN_NAMES",
    "FFPD_LAW",
    "FFPDController",
    "FFPDState",
    "ffpd_model_gains",
    "ffpd_step",
]

#: The law's packed parameters (:data:`FFPD_LAW`).
PARAMS = (
    Field("kx", "1/m", "proportional position gain K_x"),
    Field("ki_h", "1/m", "integral gain times the sample time, K_i h"),
    Field("kv_ff", "s/m", "velocity feed-forward gain K_vff"),
    Field("ka_ff", "s^2/m", "acceleration feed-forward gain K_aff"),
    Field("ka_fb", "s^2/m", "acceleration feedback (active damping) gain K_afb"),
    Field("a_f", "-", "estimate filter pole T_f/(T_f + h)"),
    Field("b_f", "1/s", "estimate filter difference gain 1/(T_f + h)"),
    Field("u_min", "-", "lower command limit"),
    Field("u_max", "-", "upper command limit"),
)
#: The law's packed state.
STATE = (
    Field("integral", "-", "integral term I_k (holds the command at rest)"),
    Field("y_prev", "m", "previous measurement y_{k-1}"),
    Field("v_est", "m/s", "filtered velocity estimate v_hat_k"),
    Field("a_est", "m/s^2", "filtered acceleration estimate a_hat_k"),
)
#: Gains a batch may vary, in column order.
GAINS = (
    Field("kx", "1/m", "proportional position gain"),
    Field("ki", "1/(m s)", "integral gain"),
    Field("kv_ff", "s/m", "velocity feed-forward gain"),
    Field("ka_ff", "s^2/m", "acceleration feed-forward gain"),
    Field("ka_fb", "s^2/m", "acceleration feedback gain (active damping)"),
    Field("tf", "s", "time constant of the velocity and acceleration estimate filters"),
)
#: What the packing takes besides the gains.
CONSTANTS = (
    Field("ts", "s", "sample time h"),
    Field("u_min", "-", "lower command limit"),
    Field("u_max", "-", "upper command limit"),
)
FFPD_GAIN_NAMES: tuple[str, ...] = tuple(f.name for f in GAINS)

P = indices("FFPDParams", PARAMS)
S = indices("FFPDStateIndex", STATE)


@kernel(inline=True, error_model="numpy")
def ffpd_step(p: Any, s: Any, r: float, y: float, aux: Any, rd: float, rdd: float) -> float:
    """One sample on packed parameters ``p`` and state ``s`` (updated in place); returns u.

    ``rd`` [m/s], ``rdd`` [m/s²]: the reference's velocity and acceleration; ``aux`` unused."""
    e = r - y
    v_est = p[P.a_f] * s[S.v_est] + p[P.b_f] * (y - s[S.y_prev])
    a_est = p[P.a_f] * s[S.a_est] + p[P.b_f] * (v_est - s[S.v_est])
    i_new = s[S.integral] + p[P.ki_h] * e
    w = (p[P.kx] * e + p[P.kv_ff] * rd + p[P.ka_ff] * rdd + p[P.ka_fb] * (rdd - a_est)
         + i_new)
    u = min(max(w, p[P.u_min]), p[P.u_max])
    if (w > p[P.u_max] and e > 0.0) or (w < p[P.u_min] and e < 0.0):
        i_new = s[S.integral]  # clamping anti-windup
    s[S.integral] = i_new
    s[S.y_prev] = y
    s[S.v_est] = v_est
    s[S.a_est] = a_est
    return u


@kernel(inline=True)
def _no_aux(tables: Any) -> float:
    """The law needs nothing of its (placeholder) tables."""
    return 0.0


def _pack(g: FloatArray, k: FloatArray) -> FloatArray:
    """Packed rows from gain rows (kx, ki, kv_ff, ka_ff, ka_fb, tf) and the constants (ts,
    u_min, u_max)."""
    kx, ki, kv_ff, ka_ff, ka_fb, tf = g.T
    h = float(k[0])
    out = np.empty((g.shape[0], len(PARAMS)))
    out[:, P.kx] = kx
    out[:, P.ki_h] = ki * h
    out[:, P.kv_ff] = kv_ff
    out[:, P.ka_ff] = ka_ff
    out[:, P.ka_fb] = ka_fb
    out[:, P.a_f] = tf / (tf + h)
    out[:, P.b_f] = 1.0 / (tf + h)
    out[:, P.u_min] = k[1]
    out[:, P.u_max] = k[2]
    return out


def _rest(packed: FloatArray, y0: float, u0: float) -> FloatArray:
    """Bumpless states: at rest at y0 [m] with command u0 [-]."""
    out = np.zeros((packed.shape[0], len(STATE)))
    out[:, S.integral] = u0
    out[:, S.y_prev] = y0
    return out


#: The law: its layout, step, packing, C port (``ffpd.c``) and ST port (``ffpd.st``).
FFPD_LAW = Law(name="ffpd", title="position control with feed-forward", params=PARAMS,
               state=STATE, gains=GAINS, constants=CONSTANTS, step=ffpd_step,
               prepare=_no_aux, pack=_pack, rest=_rest, feedforward=True,
               c_source=Path(__file__).with_name("ffpd.c"),
               st_source=Path(__file__).with_name("ffpd.st"))


@dataclass(frozen=True, slots=True)
class FFPDState:
    """State of a :class:`FFPDController` between samples."""

    integral: float  #: integral term I_k, holding the command at rest [-]
    y_prev: float  #: previous measurement [m]
    v_est: float  #: filtered velocity estimate [m/s]
    a_est: float  #: filtered acceleration estimate [m/s²]


@dataclass(frozen=True, slots=True, kw_only=True)
class FFPDController(LawController):
    """Position controller with feed-forward and active damping (module docstring).

    Parameters
    ----------
    dt : float
        Sample period h [s].
    kx : float
        Proportional position gain K_x [1/m], >= 0.
    ki : float
        Integral gain K_i [1/(m s)], >= 0 (0: none).
    kv_ff : float
        Velocity feed-forward gain K_vff [s/m], >= 0 (the model's 1/K_o).
    ka_ff : float
        Acceleration feed-forward gain K_aff [s²/m], >= 0 (the model's 2δ/(ω₀ K_o)).
    ka_fb : float
        Acceleration feedback gain K_afb [s²/m], >= 0, on r̈ - â (active damping).
    tf : float
        Time constant T_f of the velocity and acceleration estimate filters [s], >= 0
        (0: plain differences).
    u_min, u_max : float
        Command limits [-] (fractions of the rated valve input).
    """

    dt: float  #: sample period [s]
    kx: float = 0.0  #: proportional position gain [1/m]
    ki: float = 0.0  #: integral gain [1/(m s)]
    kv_ff: float = 0.0  #: velocity feed-forward gain [s/m]
    ka_ff: float = 0.0  #: acceleration feed-forward gain [s²/m]
    ka_fb: float = 0.0  #: acceleration feedback gain [s²/m]
    tf: float = 0.0  #: estimate filter time constant [s]
    u_min: float = -1.0  #: lower command limit [-]
    u_max: float = 1.0  #: upper command limit [-]

    law: ClassVar[Law] = FFPD_LAW
    state_class: ClassVar[type] = FFPDState
    gain_names: ClassVar[tuple[str, ...]] = FFPD_GAIN_NAMES

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ParameterError(f"sample time dt must be finite and > 0 s, got {self.dt!r}")
        self.check_gain_rows(self.gain_row()[None, :])
        if not (math.isfinite(self.u_min) and math.isfinite(self.u_max)
                and self.u_min < self.u_max):
            raise ParameterError(
                f"need finite u_min < u_max, got u_min={self.u_min!r}, u_max={self.u_max!r}")
        if not self.u_min <= 0.0 <= self.u_max:
            raise ParameterError(
                f"the limits must contain 0, got [{self.u_min!r}, {self.u_max!r}]")

    def initial_state(self, *, r0: float = 0.0, y0: float = 0.0, u0: float = 0.0
                      ) -> FFPDState:
        """Bumpless state: at rest at ``y0`` [m] with reference ``r0`` [m] (not moving) and
        command ``u0`` [-]; the next sample with the same r and y returns ``u0``."""
        integral = u0 - self.kx * (r0 - y0) - self.ki * self.dt * (r0 - y0)
        return FFPDState(integral=integral, y_prev=y0, v_est=0.0, a_est=0.0)

    def law_constants(self) -> FloatArray:
        """The packing constants: ts, u_min, u_max."""
        return np.array([self.dt, self.u_min, self.u_max])


class _LinearModel(Protocol):
    """What :func:`ffpd_model_gains` reads of a linear model (a
    :class:`fuzzyservo.plant.LinearServo`)."""

    @property
    def K_o(self) -> float: ...  # velocity gain [m/s per unit command]

    @property
    def omega_0(self) -> float: ...  # hydraulic natural frequency [rad/s]

    @property
    def damping(self) -> float: ...  # hydraulic damping ratio [-]


def ffpd_model_gains(linear_servo: _LinearModel, *, damping: float = 0.5,
                     gain_margin: float = 2.0, loop_ratio: float = 1.0 / 3.0,
                     filter_ratio: float = 0.1, include_valve: bool = False
                     ) -> dict[str, float]:
    """The controller's gains from eq. (8)'s hydraulic part (K_o, ω₀, δ).

    Parameters
    ----------
    linear_servo : LinearServo
        The axis' linear model (:class:`fuzzyservo.plant.LinearServo`, or anything with
        ``K_o`` [m/s per unit command], ``omega_0`` [rad/s] and ``damping`` [-]).
    damping : float
        Target damping ratio δ* of the hydraulic mode with acceleration feedback [-], > 0.
    gain_margin : float
        Gain margin g_m of the P loop on the damped model [-], > 1: K_v <= 2 δ' ω₀ / g_m.
    loop_ratio : float
        The loop gain's rule of thumb K_v <= ``loop_ratio`` ω₀ [-], > 0 (default 1/3).
    filter_ratio : float
        T_f = ``filter_ratio`` / ω₀ [-], >= 0.
    include_valve : bool
        Also invert the valve's lag in K_aff: K_aff = (2δ/ω₀ + 2ζ_v/ω_v + τ_v)/K_o, the s²
        coefficient of the whole of eq. (8)'s inverse (reads ``zeta_v`` [-], ``omega_v``
        [rad/s] and ``tau_v`` [s] of the model). Default False: the hydraulic part only, as
        the feed-forward of hydraulics texts (the valve's lag is 1 ms on the paper's axis).

    Returns
    -------
    dict of str to float
        ``kx`` [1/m], ``ki`` (0) [1/(m s)], ``kv_ff`` [s/m], ``ka_ff`` [s²/m], ``ka_fb``
        [s²/m], ``tf`` [s], and the loop gain ``kv`` [1/s] and damping ``damping`` [-] they
        give (not gains of the controller).

    Raises
    ------
    ParameterError
        A model coefficient or an option that is not a finite number in its range.

    Notes
    -----
    K_vff = 1/K_o, K_aff = 2δ/(ω₀ K_o) (the inverse of the hydraulic part up to r̈; with
    ``include_valve`` the valve's lag added);
    K_afb = 2 max(δ* - δ, 0)/(ω₀ K_o), so δ' = max(δ, δ*); K_v = min(loop_ratio ω₀,
    2 δ' ω₀ / g_m); K_x = K_v / K_o (module docstring; docs/model.md).

    Examples
    --------
    >>> from fuzzyservo.plant import LinearServo
    >>> lin = LinearServo(K_o=0.25, omega_0=20.0, damping=0.1, omega_v=700.0, zeta_v=0.4)
    >>> g = ffpd_model_gains(lin)
    >>> round(g["kv_ff"], 12), round(g["ka_ff"], 12), round(g["ka_fb"], 12)
    (4.0, 0.04, 0.16)
    """
    k_o, w0, d = (_positive(f"linear_servo.{n}", getattr(linear_servo, n))
                  for n in ("K_o", "omega_0", "damping"))
    damping = _positive("damping", damping)
    if not (math.isfinite(gain_margin) and gain_margin > 1.0):
        raise ParameterError(f"gain_margin must be finite and > 1, got {gain_margin!r}")
    loop_ratio = _positive("loop_ratio", loop_ratio)
    if not (math.isfinite(filter_ratio) and filter_ratio >= 0.0):
        raise ParameterError(f"filter_ratio must be finite and >= 0, got {filter_ratio!r}")
    lag = 2.0 * d / w0
    if include_valve:
        lag += 2.0 * _positive("linear_servo.zeta_v", getattr(linear_servo, "zeta_v", None)) / (
            _positive("linear_servo.omega_v", getattr(linear_servo, "omega_v", None)))
        tau_v = float(getattr(linear_servo, "tau_v", 0.0))
        if not (math.isfinite(tau_v) and tau_v >= 0.0):
            raise ParameterError(f"linear_servo.tau_v must be finite and >= 0 s, got "
                                 f"{tau_v!r}")
        lag += tau_v
    d_eff = max(d, damping)
    kv = min(loop_ratio * w0, 2.0 * d_eff * w0 / gain_margin)
    return {"kx": kv / k_o, "ki": 0.0, "kv_ff": 1.0 / k_o, "ka_ff": lag / k_o,
            "ka_fb": 2.0 * (d_eff - d) / (w0 * k_o), "tf": filter_ratio / w0, "kv": kv,
            "damping": d_eff}


def _positive(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number > 0, got {value!r}") from None
    if not (math.isfinite(v) and v > 0.0):
        raise ParameterError(f"{name} must be finite and > 0, got {value!r}")
    return v
