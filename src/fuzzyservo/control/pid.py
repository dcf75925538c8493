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
from typing import ClassVar, Literal

import numba
import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import ParameterError

__all__ = [
    "PID_GAIN_NAMES",
    "AntiWindup",
    "PIDController",
    "PIDState",
    "p_controller",
    "pi_controller",
    "pid_step",
]

AntiWindup = Literal["clamping", "back-calculation", "none"]
_AW_CODE: dict[str, int] = {"none": 0, "clamping": 1, "back-calculation": 2}

#: Gains a batch may vary for the PID family, in column order.
PID_GAIN_NAMES: tuple[str, ...] = ("kp", "ki", "kd", "n", "b", "c")

# packed parameter layout
_KP, _BI, _AD, _BD, _B, _C, _UMIN, _UMAX, _AW, _KBH = range(10)
_NP = 10
# packed state layout: integral, derivative, previous derivative-path error, (unused), alpha
_I, _D, _EDP = 0, 1, 2


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def pid_step(p: FloatArray, s: FloatArray, r: float, y: float) -> float:
    """One PID sample on packed parameters ``p`` and state ``s`` (updated in place); returns u.

    ``p`` and ``s`` are arrays or their data pointers (the compiled loops inline this step
    with pointers: no reference counting per sample)."""
    e = r - y
    ed = p[_C] * r - y
    d = p[_AD] * s[_D] + p[_BD] * (ed - s[_EDP])
    i_new = s[_I] + p[_BI] * e
    v = p[_KP] * (p[_B] * r - y) + i_new + d
    u = min(max(v, p[_UMIN]), p[_UMAX])
    aw = p[_AW]
    if aw == 1.0:
        if (v > p[_UMAX] and e > 0.0) or (v < p[_UMIN] and e < 0.0):
            i_new = s[_I]
    elif aw == 2.0:
        i_new += p[_KBH] * (u - v)
    s[_I] = i_new
    s[_D] = d
    s[_EDP] = ed
    return u


@numba.njit(cache=True, nogil=True)
def pid_step_arrays(p: FloatArray, s: FloatArray, r: float, y: float) -> float:
    """:func:`pid_step` on the controller's arrays (the per-step API's call)."""
    return pid_step(p, s, r, y)


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
class PIDController:
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

    kind: ClassVar[int] = 0
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

    def pack(self) -> FloatArray:
        """Packed parameter vector for :func:`pid_step`."""
        g = np.array([[self.kp, self.ki, self.kd, self.n, self.b, self.c]])
        return self.pack_gains(g)[0]

    def pack_gains(self, gains: FloatArray) -> FloatArray:
        """Pack one parameter row per row of ``gains`` (columns ``kp, ki, kd, n, b, c``),
        with this controller's dt, limits and anti-windup."""
        g = np.asarray(gains, dtype=np.float64)
        if g.ndim != 2 or g.shape[1] != len(PID_GAIN_NAMES):
            raise ParameterError(
                f"PID gains need shape (runs, {len(PID_GAIN_NAMES)}) with columns "
                f"{', '.join(PID_GAIN_NAMES)}, got {g.shape}")
        for j, name in enumerate(PID_GAIN_NAMES):
            col = g[:, j]
            bad = ~(col > 0.0) if name == "n" else ~(np.isfinite(col) & (col >= 0.0))
            if name == "n":
                bad |= np.isnan(col)
            if np.any(bad):
                value = col[np.argmax(bad)]
                allowed = "> 0 (inf: no filter)" if name == "n" else "finite and >= 0"
                raise ParameterError(f"gain {name} must be {allowed}, got {value!r}")
        kp, ki, kd, n, b, c = g.T
        h = self.dt
        out = np.empty((g.shape[0], _NP))
        out[:, _KP] = kp
        out[:, _BI] = ki * h
        with np.errstate(invalid="ignore", divide="ignore"):
            unfiltered = np.isinf(n)
            out[:, _AD] = np.where(unfiltered, 0.0, 1.0 / (1.0 + n * h))
            out[:, _BD] = np.where(unfiltered, kd / h, kd * n / (1.0 + n * h))
            if self.tracking_time is not None:
                tt = np.full(g.shape[0], self.tracking_time)
            else:
                tt = np.where(kd > 0.0, np.sqrt(kd / ki), kp / ki)
            kbh = np.where((ki > 0.0) & (tt > 0.0), np.minimum(h / tt, 1.0), 0.0)
        out[:, _B] = b
        out[:, _C] = c
        out[:, _UMIN] = self.u_min
        out[:, _UMAX] = self.u_max
        out[:, _AW] = _AW_CODE[self.anti_windup]
        out[:, _KBH] = np.nan_to_num(kbh, nan=0.0)
        return out

    def rest_states(self, packed: FloatArray, y0: float, u0: float) -> FloatArray:
        """Packed bumpless states, one per packed parameter row: at rest with r = y = ``y0``
        [m] and command ``u0`` [-] (as :meth:`initial_state`)."""
        out = np.zeros((packed.shape[0], 5))
        out[:, _I] = u0 - packed[:, _KP] * (packed[:, _B] - 1.0) * y0
        out[:, _EDP] = (packed[:, _C] - 1.0) * y0
        out[:, 4] = np.nan
        return out

    def tables(self) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
        """Placeholder rule tables (the PID family uses none; typed for the kernels)."""
        return no_tables()

    def pack_state(self, state: object) -> FloatArray:
        """Packed state vector (integral, derivative, ed_prev, 0, alpha = NaN)."""
        if not isinstance(state, PIDState):
            raise ParameterError(f"expected a PIDState, got {type(state).__name__}")
        return np.array([state.integral, state.derivative, state.ed_prev, 0.0, np.nan])

    def unpack_state(self, s: FloatArray) -> PIDState:
        """Inverse of :meth:`pack_state`."""
        return PIDState(integral=float(s[_I]), derivative=float(s[_D]), ed_prev=float(s[_EDP]))

    def step(self, state: PIDState, reference: float, measurement: float
             ) -> tuple[float, PIDState]:
        """One sample: command u [-] from reference and measurement [m], and the new state."""
        s = self.pack_state(state)
        u = pid_step_arrays(self.pack(), s, float(reference), float(measurement))
        return float(u), self.unpack_state(s)


def no_tables() -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
    """Placeholder rule tables for controllers without fuzzy systems (typed for the kernels)."""
    rules = np.full((2, 2), -1, dtype=np.int64)
    lims = np.array([-1.0, 1.0, -1.0, 1.0, 0.0, 1.0, 2.0, 0.0])
    return rules, lims, rules.copy(), lims.copy()


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
