"""The paper's linear model, eq. (8), with input u (unit command) and output x [m].

    X(s)/U(s) = K_o / [(τ_v s + 1)(s²/ω_v² + 2ζ_v s/ω_v + 1) s (s²/ω₀² + 2δ s/ω₀ + 1)]

K_o = K_a K_tr C_v / A_f (the paper's K_tr C_v A_f / K_v is dimensionally wrong, docs/model.md);
with K_a = I_rated (u is a fraction of rated input) and K_tr = 1 m/m, K_o = Q_rated / A_f.
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

    def __post_init__(self) -> None:
        for name in ("K_o", "omega_0", "damping", "omega_v", "zeta_v"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise ParameterError(f"LinearServo.{name} must be a finite number > 0, "
                                     f"got {value!r}")
        if not (math.isfinite(self.tau_v) and self.tau_v >= 0.0):
            raise ParameterError(f"LinearServo.tau_v must be >= 0 s, got {self.tau_v!r}")

    @classmethod
    def from_params(cls, params: ServoParams, lin: Linearization) -> LinearServo:
        """Eq. (8) as the paper writes it: K_o = Q_rated/A_f (large signal), ω₀, δ from ``lin``."""
        v = params.valve
        return cls(K_o=params.velocity_gain, omega_0=lin.omega_0, damping=lin.damping,
                   omega_v=v.omega_v, zeta_v=v.zeta_v, tau_v=v.tau_v)

    @classmethod
    def from_linearization(cls, lin: Linearization) -> LinearServo:
        """Eq. (8) with every coefficient from the linearisation, K_o its small-signal gain."""
        v = lin.params.valve
        return cls(K_o=lin.velocity_gain, omega_0=lin.omega_0, damping=lin.damping,
                   omega_v=v.omega_v, zeta_v=v.zeta_v, tau_v=v.tau_v)

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

    def discretize(self, dt: float, delay: float = 0.0) -> DiscreteModel:
        """Zero-order-hold discretisation of :meth:`state_space` at sample time ``dt`` [s],
        with a transport ``delay`` [s] on the command (exact for any delay; see
        :func:`fuzzyservo.plant.zoh.discretize`, the one ZOH of the package)."""
        a, b, _, _ = self.state_space()
        return discretize(a, b, dt, delay)
