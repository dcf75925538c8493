"""The paper's linear model, eq. (8), with input u (unit command) and output x [m].

    X(s)/U(s) = K_o / [(τ_v s + 1)(s²/ω_v² + 2ζ_v s/ω_v + 1) s (s²/ω₀² + 2δ s/ω₀ + 1)]

K_o = K_a K_tr C_v / A_f (the paper's K_tr C_v A_f / K_v is dimensionally wrong, docs/model.md);
with K_a = I_rated (u is a fraction of rated input) and K_tr = 1 m/m, K_o = Q_rated / A_f.

The paper gives eq. (8) no load-force path. :meth:`LinearServo.force_input` adds Merritt's
(Hydraulic Control Systems, 1967, ch. 6) standard one, the load force F (> 0 opposing
extension) entering the hydraulic second order beside the valve's flow:

    X(s) = [K_o Q(s) - (K_ce/A²)(1 + V_t s/(4 β_e K_ce)) F(s)] / [s (s²/ω₀² + 2δ s/ω₀ + 1)]

with K_ce/A² = K_f, the small-signal model's steady velocity lost per newton
(``Linearization.load_compliance``), and V_t/(4 β_e) = A²/(ω₀² M) from Merritt's
ω_h² = 4 β_e A²/(V_t M) with ω_h = ω₀, so the force's lead time constant is
V_t/(4 β_e K_ce) = 1/(ω₀² M K_f) (docs/model.md, "Load force on the linear models").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray
from ..errors import ParameterError
from .linearize import Linearization
from .params import ServoParams
from .zoh import DiscreteModel, discretize

__all__ = ["LinearServo"]


@dataclass(frozen=True, slots=True, kw_only=True)
class LinearServo:
    """Eq. (8) as a transfer function and a state-space model (input u [1], output x [m])."""

    K_o: float  #: velocity (loop) gain [m/s per unit command]
    omega_0: float  #: hydraulic natural frequency ω₀ [rad/s]
    damping: float  #: hydraulic damping ratio δ [1]
    omega_v: float  #: valve natural frequency ω_v [rad/s]
    zeta_v: float  #: valve damping ratio ζ_v [1]
    tau_v: float = 0.0  #: valve first-order time constant τ_v; 0 = absent [s]
    #: steady velocity lost per newton of load force K_f = K_ce/A² [m/(s·N)]
    load_compliance: float = 0.0
    mass: float = 0.0  #: moving mass M of the force path; 0 = no force input [kg]

    def __post_init__(self) -> None:
        for name in ("K_o", "omega_0", "damping", "omega_v", "zeta_v"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise ParameterError(f"LinearServo.{name} must be a finite number > 0, "
                                     f"got {value!r}")
        if not (math.isfinite(self.tau_v) and self.tau_v >= 0.0):
            raise ParameterError(f"LinearServo.tau_v must be >= 0 s, got {self.tau_v!r}")
        for name in ("load_compliance", "mass"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ParameterError(f"LinearServo.{name} must be a finite number >= 0, "
                                     f"got {value!r}")

    @classmethod
    def from_params(cls, params: ServoParams, lin: Linearization) -> LinearServo:
        """Eq. (8) as the paper writes it: K_o = Q_rated/A_f (large signal), ω₀, δ from ``lin``."""
        v = params.valve
        return cls(K_o=params.velocity_gain, omega_0=lin.omega_0, damping=lin.damping,
                   omega_v=v.omega_v, zeta_v=v.zeta_v, tau_v=v.tau_v,
                   load_compliance=lin.load_compliance, mass=params.load.mass)

    @classmethod
    def from_linearization(cls, lin: Linearization) -> LinearServo:
        """Eq. (8) with every coefficient from the linearisation, K_o its small-signal gain."""
        v = lin.params.valve
        return cls(K_o=lin.velocity_gain, omega_0=lin.omega_0, damping=lin.damping,
                   omega_v=v.omega_v, zeta_v=v.zeta_v, tau_v=v.tau_v,
                   load_compliance=lin.load_compliance, mass=lin.params.load.mass)

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the states of :meth:`state_space`, in order."""
        names: tuple[str, ...] = ("spool", "spool_rate", "v", "a", "x")
        return ("spool_lag", *names) if self.tau_v > 0.0 else names

    def transfer_function(self) -> tuple[FloatArray, FloatArray]:
        """Numerator and denominator of eq. (8), highest power first."""
        w0, d, wv, zv = self.omega_0, self.damping, self.omega_v, self.zeta_v
        den = np.polymul([1.0 / wv**2, 2.0 * zv / wv, 1.0], [1.0 / w0**2, 2.0 * d / w0, 1.0])
        den = np.polymul(den, [1.0, 0.0])
        if self.tau_v > 0.0:
            den = np.polymul(den, [self.tau_v, 1.0])
        return np.array([self.K_o]), np.asarray(den, dtype=np.float64)

    def state_space(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(A, B, C, D) of eq. (8) as a series of physical blocks.

        States: [lag (if τ_v > 0), spool, spool rate, v, a, x]: the valve stage(s) give the
        normalised flow q, the hydraulic second order gives the velocity v (v/q = K_o at DC),
        and x integrates v.
        """
        w0, d, wv, zv = self.omega_0, self.damping, self.omega_v, self.zeta_v
        lag = self.tau_v > 0.0
        n = 6 if lag else 5
        a = np.zeros((n, n))
        b = np.zeros((n, 1))
        o = 1 if lag else 0
        if lag:
            a[0, 0] = -1.0 / self.tau_v
            b[0, 0] = 1.0 / self.tau_v
        # spool: s'' = wv²(in - s) - 2 zv wv s'
        a[o, o + 1] = 1.0
        a[o + 1, o] = -(wv**2)
        a[o + 1, o + 1] = -2.0 * zv * wv
        if lag:
            a[o + 1, 0] = wv**2
        else:
            b[o + 1, 0] = wv**2
        # hydraulic: v'' = w0²(K_o s - v) - 2 d w0 v'
        iv = o + 2
        a[iv, iv + 1] = 1.0
        a[iv + 1, iv] = -(w0**2)
        a[iv + 1, iv + 1] = -2.0 * d * w0
        a[iv + 1, o] = w0**2 * self.K_o
        # position
        a[iv + 2, iv] = 1.0
        c = np.zeros((1, n))
        c[0, iv + 2] = 1.0
        return a, b, c, np.zeros((1, 1))

    @property
    def has_force_input(self) -> bool:
        """Whether the model has a load-force path (a mass is given)."""
        return self.mass > 0.0

    def force_input(self) -> FloatArray:
        """The load-force input vector E (n,) of :meth:`state_space` [state unit/s per N]:
        dx/dt = A x + B u + E F, F > 0 opposing extension.

        Merritt's force path (module docstring) in the observer form of the hydraulic
        second order: v' = a - F/M and a' = ω₀²(K_o q - v) - 2δω₀ a + (2δω₀/M - ω₀² K_f) F,
        so V/F = -(s/M + ω₀² K_f)/(s² + 2δω₀ s + ω₀²); at high frequency the force
        decelerates the mass (-F/M), in steady state the piston creeps at -K_f F. With a
        force, the state ``a`` is the acceleration the oil gives, v' + F/M.

        Raises
        ------
        ParameterError
            The model has no force path (``mass`` 0).
        """
        if not self.has_force_input:
            raise ParameterError("this LinearServo has no load-force path: give mass > 0 "
                                 "(LinearServo.from_params does)")
        w0, d, m = self.omega_0, self.damping, self.mass
        o = 1 if self.tau_v > 0.0 else 0
        e = np.zeros(o + 5)
        e[o + 2] = -1.0 / m
        e[o + 3] = 2.0 * d * w0 / m - w0**2 * self.load_compliance
        return e

    def discretize(self, dt: float, delay: float = 0.0) -> DiscreteModel:
        """Zero-order-hold discretisation of :meth:`state_space` at sample time ``dt`` [s],
        with a transport ``delay`` [s] on the command (exact for any delay; see
        :func:`fuzzyservo.plant.zoh.discretize`, the one ZOH of the package)."""
        a, b, _, _ = self.state_space()
        return discretize(a, b, dt, delay)
