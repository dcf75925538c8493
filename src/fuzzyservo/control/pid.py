"""PID family in parallel form with derivative filter, setpoint weights and anti-windup.

The control law (Åström & Hägglund, *Advanced PID Control*, ISA 2006, ch. 3; MATLAB ``pid2``)::

    u = K_p (b r - y) + K_i ∫ (r - y) dt + K_d · N/(1 + N/s) · (c r - y),   |u| limited

``b = c = 1`` is the one-degree-of-freedom PID, ``b = 1, c = 0`` PI-D, ``b = c = 0`` I-PD;
``kd = 0`` gives PI and ``ki = kd = 0`` P.

Discretisation (sample period h, both terms by backward Euler, s ≈ (1 - z⁻¹)/h)::

    I_k = I_{k-1} + K_i h e_k                                  (e = r - y)
    D_k = D_{k-1}/(1 + N h) + K_d N/(1 + N h) · (ed_k - ed_{k-1})  (ed = c r - y)
    v_k = K_p (b r_k - y_k) + I_k + D_k,   u_k = min(max(v_k, u_min), u_max)

Backward Euler keeps the filtered derivative stable and free of ringing for every N h (Tustin
rings for N h > 2); ``n = inf`` is the unfiltered difference K_d (ed_k - ed_{k-1})/h.
Anti-windup (named, STYLE section 3):

- ``"clamping"`` (conditional integration): when v_k is beyond a limit and e_k pushes further
  into it, I_k keeps its previous value;
- ``"back-calculation"``: I_k += (h/T_t)(u_k - v_k), T_t the tracking time constant (default
  √(T_i T_d) = √(K_d/K_i), or T_i = K_p/K_i without derivative; h/T_t is capped at 1);
- ``"none"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np

from .._jit import kernel
from .._typing import FloatArray
from ..errors import ParameterError
from .law import Field, Law, LawController, indices

__all__ = [
    "PID_GAIN_NAMES",
    "PID_LAW",
    "AntiWindup",
    "PIDController",
    "PIDState",
    "p_controller",
    "pi_controller",
    "pid_step",
]

AntiWindup = Literal["clamping", "back-calculation", "none"]
_AW_CODE: dict[str, int] = {"none": 0, "clamping": 1, "back-calculation": 2}

#: The law's packed parameters (:data:`PID_LAW`).
PARAMS = (
    Field("kp", "1/m", "proportional gain K_p"),
    Field("ki_h", "1/m", "integral gain times the sample time, K_i h"),
    Field("a_d", "-", "derivative filter pole 1/(1 + N h) (0 without filter)"),
    Field("b_d", "1/m", "derivative gain of the filtered difference K_d N/(1 + N h) (K_d/h "
          "without filter)"),
    Field("b", "-", "setpoint weight of the proportional path"),
    Field("c", "-", "setpoint weight of the derivative path"),
    Field("u_min", "-", "lower command limit"),
    Field("u_max", "-", "upper command limit"),
    Field("anti_windup", "-", "anti-windup scheme: 0 none, 1 clamping, 2 back-calculation"),
    Field("kb_h", "-", "back-calculation gain h/T_t, at most 1"),
)
#: The law's packed state.
STATE = (
    Field("integral", "-", "integral term I_k"),
    Field("derivative", "-", "filtered derivative term D_k"),
    Field("ed_prev", "m", "previous derivative-path error c r - y"),
)
#: Gains a batch may vary for the PID family, in column order.
GAINS = (
    Field("kp", "1/m", "proportional gain"),
    Field("ki", "1/(m s)", "integral gain"),
    Field("kd", "s/m", "derivative gain"),
    Field("n", "1/s", "derivative filter coefficient (inf: none)"),
    Field("b", "-", "setpoint weight, proportional path"),
    Field("c", "-", "setpoint weight, derivative path"),
)
#: What the packing takes besides the gains.
CONSTANTS = (
    Field("ts", "s", "sample time h"),
    Field("u_min", "-", "lower command limit"),
    Field("u_max", "-", "upper command limit"),
    Field("anti_windup", "-", "anti-windup scheme code (as in the parameters)"),
    Field("tracking_time", "s", "back-calculation time constant T_t; 0: the default"),
)
PID_GAIN_NAMES: tuple[str, ...] = tuple(f.name for f in GAINS)

P = indices("PIDParams", PARAMS)
S = indices("PIDStateIndex", STATE)


@kernel(inline=True, error_model="numpy")
def pid_step(p: Any, s: Any, r: float, y: float, aux: Any, rd: float,
             rdd: float) -> float:
    """One PID sample on packed parameters ``p`` and state ``s`` (updated in place); returns u.

    ``p`` and ``s`` are data pointers or arrays; ``aux`` is unused (no tables)."""
    e = r - y
    ed = p[P.c] * r - y
    d = p[P.a_d] * s[S.derivative] + p[P.b_d] * (ed - s[S.ed_prev])
    i_new = s[S.integral] + p[P.ki_h] * e
    v = p[P.kp] * (p[P.b] * r - y) + i_new + d
    u = min(max(v, p[P.u_min]), p[P.u_max])
    aw = p[P.anti_windup]
    if aw == 1.0:
        if (v > p[P.u_max] and e > 0.0) or (v < p[P.u_min] and e < 0.0):
            i_new = s[S.integral]
    elif aw == 2.0:
        i_new += p[P.kb_h] * (u - v)
    s[S.integral] = i_new
    s[S.derivative] = d
    s[S.ed_prev] = ed
    return u


@kernel(inline=True)
def _no_aux(tables: Any) -> float:
    """The PID family needs nothing of its (placeholder) tables."""
    return 0.0


def _pack(g: FloatArray, k: FloatArray) -> FloatArray:
    """Packed rows from gain rows (kp, ki, kd, n, b, c) and the constants (ts, u_min, u_max,
    anti-windup code, tracking time or 0)."""
    kp, ki, kd, n, b, c = g.T
    h = float(k[0])
    out = np.empty((g.shape[0], len(PARAMS)))
    out[:, P.kp] = kp
    out[:, P.ki_h] = ki * h
    with np.errstate(invalid="ignore", divide="ignore"):
        unfiltered = np.isinf(n)
        out[:, P.a_d] = np.where(unfiltered, 0.0, 1.0 / (1.0 + n * h))
        out[:, P.b_d] = np.where(unfiltered, kd / h, kd * n / (1.0 + n * h))
        if k[4] > 0.0:
            tt = np.full(g.shape[0], float(k[4]))
        else:
            tt = np.where(kd > 0.0, np.sqrt(kd / ki), kp / ki)
        kbh = np.where((ki > 0.0) & (tt > 0.0), np.minimum(h / tt, 1.0), 0.0)
    out[:, P.b] = b
    out[:, P.c] = c
    out[:, P.u_min] = k[1]
    out[:, P.u_max] = k[2]
    out[:, P.anti_windup] = k[3]
    out[:, P.kb_h] = np.nan_to_num(kbh, nan=0.0)
    return out


def _rest(packed: FloatArray, y0: float, u0: float) -> FloatArray:
    """Bumpless states: at rest with r = y = y0 [m] and command u0 [-]."""
    out = np.zeros((packed.shape[0], len(STATE)))
    out[:, S.integral] = u0 - packed[:, P.kp] * (packed[:, P.b] - 1.0) * y0
    out[:, S.ed_prev] = (packed[:, P.c] - 1.0) * y0
    return out


#: The PID family's law: its layout, step, packing and C port (``pid.c``).
PID_LAW = Law(name="pid", title="PID", params=PARAMS, state=STATE, gains=GAINS,
              constants=CONSTANTS, step=pid_step, prepare=_no_aux, pack=_pack, rest=_rest,
              c_source=Path(__file__).with_name("pid.c"),
              st_source=Path(__file__).with_name("pid.st"))


@dataclass(frozen=True, slots=True)
class PIDState:
    """State of a :class:`PIDController` between samples."""

    integral: float  #: integral term I_k [-]
    derivative: float  #: filtered derivative term D_k [-]
    ed_prev: float  #: previous derivative-path error c r - y [m]


def _check_gain(name: str, value: float) -> None:
    if not (math.isfinite(value) and value >= 0.0):
        raise ParameterError(f"gain {name} must be finite and >= 0, got {value!r}")


@dataclass(frozen=True, slots=True, kw_only=True)
class PIDController(LawController):
    """Two-degree-of-freedom PID in parallel form (see the module docstring for the law).

    Parameters
    ----------
    dt : float
        Sample period h [s].
    kp, ki, kd : float
        Proportional [1/m], integral [1/(m s)] and derivative [s/m] gains, each >= 0.
    n : float
        Derivative filter coefficient N [1/s], > 0; ``math.inf`` for no filter.
    b, c : float
        Setpoint weights of the proportional and derivative paths [-], >= 0.
    u_min, u_max : float
        Command limits [-] (fractions of the rated valve input).
    anti_windup : {"clamping", "back-calculation", "none"}
        Anti-windup scheme.
    tracking_time : float or None
        Back-calculation tracking time constant T_t [s]; None for the default above.
    """

    dt: float  #: sample period [s]
    kp: float = 0.0  #: proportional gain [1/m]
    ki: float = 0.0  #: integral gain [1/(m s)]
    kd: float = 0.0  #: derivative gain [s/m]
    n: float = 100.0  #: derivative filter coefficient [1/s]
    b: float = 1.0  #: setpoint weight, proportional path [-]
    c: float = 1.0  #: setpoint weight, derivative path [-]
    u_min: float = -1.0  #: lower command limit [-]
    u_max: float = 1.0  #: upper command limit [-]
    anti_windup: AntiWindup = "clamping"  #: anti-windup scheme
    tracking_time: float | None = None  #: back-calculation time constant [s]

    law: ClassVar[Law] = PID_LAW
    state_class: ClassVar[type] = PIDState
    gain_names: ClassVar[tuple[str, ...]] = PID_GAIN_NAMES

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ParameterError(f"sample time dt must be finite and > 0 s, got {self.dt!r}")
        for name in ("kp", "ki", "kd", "b", "c"):
            _check_gain(name, getattr(self, name))
        if not (self.n > 0.0) or math.isnan(self.n):
            raise ParameterError(f"derivative filter n must be > 0 (inf: none), got {self.n!r}")
        if not (math.isfinite(self.u_min) and math.isfinite(self.u_max)
                and self.u_min < self.u_max):
            raise ParameterError(
                f"need finite u_min < u_max, got u_min={self.u_min!r}, u_max={self.u_max!r}")
        if not self.u_min <= 0.0 <= self.u_max:
            raise ParameterError(
                f"the limits must contain 0, got [{self.u_min!r}, {self.u_max!r}]")
        if self.anti_windup not in _AW_CODE:
            raise ParameterError(
                f"anti_windup must be one of {sorted(_AW_CODE)}, got {self.anti_windup!r}")
        if self.tracking_time is not None and not (
                math.isfinite(self.tracking_time) and self.tracking_time > 0.0):
            raise ParameterError(
                f"tracking_time must be finite and > 0 s, got {self.tracking_time!r}")

    def initial_state(self, *, r0: float = 0.0, y0: float = 0.0, u0: float = 0.0) -> PIDState:
        """Bumpless state: at rest with reference ``r0`` [m], measurement ``y0`` [m], command
        ``u0`` [-], the next sample with the same r and y returns ``u0`` with no derivative kick.
        """
        integral = u0 - self.kp * (self.b * r0 - y0) - self.ki * self.dt * (r0 - y0)
        return PIDState(integral=integral, derivative=0.0, ed_prev=self.c * r0 - y0)

    def law_constants(self) -> FloatArray:
        """The packing constants: ts, u_min, u_max, anti-windup code, tracking time (0:
        the default)."""
        tt = self.tracking_time if self.tracking_time is not None else 0.0
        return np.array([self.dt, self.u_min, self.u_max, _AW_CODE[self.anti_windup], tt])

    def check_gain_rows(self, gains: FloatArray) -> None:
        """Gains finite and >= 0; n > 0 (inf: no filter)."""
        for j, name in enumerate(PID_GAIN_NAMES):
            col = gains[:, j]
            bad = ~(col > 0.0) if name == "n" else ~(np.isfinite(col) & (col >= 0.0))
            if name == "n":
                bad |= np.isnan(col)
            if np.any(bad):
                value = col[np.argmax(bad)]
                allowed = "> 0 (inf: no filter)" if name == "n" else "finite and >= 0"
                raise ParameterError(f"gain {name} must be {allowed}, got {value!r}")


def p_controller(*, dt: float, kp: float, u_min: float = -1.0, u_max: float = 1.0
                 ) -> PIDController:
    """Proportional controller u = K_p (r - y), limited [dt in s, kp in 1/m]."""
    return PIDController(dt=dt, kp=kp, u_min=u_min, u_max=u_max)


def pi_controller(*, dt: float, kp: float, ki: float, b: float = 1.0,
                  u_min: float = -1.0, u_max: float = 1.0,
                  anti_windup: AntiWindup = "clamping") -> PIDController:
    """PI controller (PID with K_d = 0) [dt in s, kp in 1/m, ki in 1/(m s)]."""
    return PIDController(dt=dt, kp=kp, ki=ki, b=b, u_min=u_min, u_max=u_max,
                         anti_windup=anti_windup)
