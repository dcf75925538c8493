"""Trimmed equilibrium and numerical linearisation of the nonlinear model at any stroke position.

With null leakage an asymmetric cylinder is not held by a centred valve: the leakage sets
p_f ≈ p_n, so A_f p_f > A_n p_n and the holding command is slightly negative (model notes
§4.3). :func:`trim` finds that command and the chamber pressures; :func:`linearize` takes the
central-difference Jacobian of :func:`~fuzzyservo.plant.nonlinear.rhs` there and reads off
ω₀, δ, the velocity gain and the eigenvalues.

The Coulomb/Stribeck friction is left out of the linearisation: sgn(v) has no derivative at
v = 0 and the slope of its tanh regularisation is a numerical artefact, not a damping
(docs/model.md). Viscous damping is kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import optimize

from .._typing import FloatArray
from ..errors import ParameterError, SimulationDivergedError
from .dense import eigvals, modulus, solve
from .nonlinear import (
    N_STATE,
    P_AF,
    P_FEXT,
    P_M,
    S_LAG,
    S_PF,
    S_PN,
    S_SPOOL,
    S_V,
    S_X,
    STATE_NAMES,
    pack,
    rhs,
)
from .params import ServoParams

__all__ = ["Linearization", "Trim", "linearize", "trim"]

# Null leakage used only to pick the equilibrium pressures of a leak-free valve (the limit of
# the leaky trim as K_l0 -> 0 does not depend on K_l0) [m³/(s·Pa)].
_LIMIT_LEAKAGE = 1.0e-13


@dataclass(frozen=True, slots=True, kw_only=True)
class Trim:
    """Equilibrium at rest at one stroke position."""

    position: float  #: piston position [m]
    command: float  #: valve command that holds the piston still [1]
    p_f: float  #: full-bore chamber pressure [Pa]
    p_n: float  #: annulus chamber pressure [Pa]
    state: FloatArray  #: full state vector at the equilibrium (STATE_NAMES)


@dataclass(frozen=True, slots=True, kw_only=True)
class Linearization:
    """Small-signal model dx/dt = A dx + B du, y = C dx around a :class:`Trim`."""

    trim: Trim  #: the operating point
    state_names: tuple[str, ...]  #: names of the states kept in A (spool_lag dropped if τ_v = 0)
    a: FloatArray  #: state matrix [SI per SI]
    b: FloatArray  #: input matrix (per unit command)
    c: FloatArray  #: output matrix, y = piston position [m]
    eigenvalues: FloatArray  #: eigenvalues of A, sorted by modulus [1/s] (complex)
    omega_0: float  #: hydraulic natural frequency, modulus of the slowest complex pair [rad/s]
    damping: float  #: hydraulic damping ratio δ of that pair [1]
    velocity_gain: float  #: steady piston velocity per unit command [m/s]
    params: ServoParams  #: the parameters linearised (friction as given by the caller)
    #: load-force input column E = ∂(dx/dt)/∂F_ext, F_ext > 0 opposing extension [SI per N]
    e: FloatArray = field(default_factory=lambda: np.empty(0))
    #: steady piston velocity lost per newton of load force, K_f = -dv/dF at rest with the
    #: position free (Merritt's K_ce/A²) [m/(s·N)]
    load_compliance: float = 0.0


def _trim_residual(z: FloatArray, position: float, p: FloatArray, ps: float) -> FloatArray:
    x = np.zeros(N_STATE)
    u = z[0]
    x[S_LAG] = u
    x[S_SPOOL] = u
    x[S_PF] = z[1] * ps
    x[S_PN] = z[2] * ps
    x[S_X] = position
    dx = np.empty(N_STATE)
    rhs(0.0, x, u, p, dx)
    # scale: pressures to Pa/s over P_s/s, force balance to P_s A_f
    return np.array([dx[S_PF] / ps * 1e-3, dx[S_PN] / ps * 1e-3, dx[S_V] * p[P_M] / (ps * p[P_AF])])


def trim(params: ServoParams, position: float) -> Trim:
    """Valve command and pressures that hold the piston at rest at ``position`` [m].

    Ripple is ignored (the nominal supply is used). Without any leakage the equilibrium
    pressures are not unique; the limit of the leaky equilibrium as the leakage vanishes is
    used (command 0).

    Raises
    ------
    ParameterError
        If ``position`` is outside (0, stroke) or no equilibrium exists (e.g. an external force
        the supply cannot hold).
    """
    stroke = params.cylinder.stroke
    if not (math.isfinite(position) and 0.0 < position < stroke):
        raise ParameterError(
            f"position must be inside the stroke (0, {stroke!r}) m, got {position!r}"
        )
    leaky = params.valve.null_leakage > 0.0 or params.cylinder.internal_leakage > 0.0
    work = params if leaky else replace(
        params, valve=replace(params.valve, null_leakage=_LIMIT_LEAKAGE))
    work = replace(work, supply=replace(work.supply, ripple_amplitude=0.0))
    p = pack(work)
    ps = work.supply.pressure
    c = work.cylinder
    total = (ps + work.supply.tank_pressure) / ps
    pf0 = (c.ring_area * total + work.load.external_force / ps) / (c.piston_area + c.ring_area)
    sol = optimize.root(_trim_residual, np.array([0.0, pf0, total - pf0]),
                        args=(position, p, ps), method="hybr", options={"xtol": 1e-13})
    res = _trim_residual(sol.x, position, p, ps)
    u = float(sol.x[0])
    where = (f"no equilibrium at position {position!r} m with external force "
             f"{params.load.external_force!r} N")
    if not sol.success and float(np.max(np.abs(res))) > 1e-9:
        reason = " ".join(str(sol.message).split())
        hold = ps * max(c.piston_area, c.ring_area)
        raise ParameterError(f"{where}: the root finder found no pressures that balance it "
                             f"(it stopped: {reason}); the supply holds at most about "
                             f"{hold:.4g} N (supply.pressure x piston area)")
    if abs(u) > 1.0:
        raise ParameterError(
            f"{where}: holding the piston needs a valve command of {u:.4g}, outside the "
            f"valve's range [-1, 1]; the leakage (valve.null_leakage "
            f"{params.valve.null_leakage!r} m³/(s·Pa), cylinder.internal_leakage "
            f"{params.cylinder.internal_leakage!r} m³/(s·Pa)) or the load is too large for "
            f"the valve")
    if not leaky:
        u = 0.0
    x = np.zeros(N_STATE)
    x[S_LAG] = u
    x[S_SPOOL] = u
    x[S_PF] = sol.x[1] * ps
    x[S_PN] = sol.x[2] * ps
    x[S_X] = position
    return Trim(position=position, command=u, p_f=float(x[S_PF]), p_n=float(x[S_PN]), state=x)


def _jacobian(x0: FloatArray, u0: float, p: FloatArray, scale: FloatArray) -> tuple[
        FloatArray, FloatArray]:
    n = x0.shape[0]
    a = np.empty((n, n))
    dxp = np.empty(n)
    dxm = np.empty(n)
    for j in range(n):
        h = 1e-6 * scale[j]
        xp = x0.copy()
        xm = x0.copy()
        xp[j] += h
        xm[j] -= h
        rhs(0.0, xp, u0, p, dxp)
        rhs(0.0, xm, u0, p, dxm)
        a[:, j] = (dxp - dxm) / (2.0 * h)
    h = 1e-6
    rhs(0.0, x0, u0 + h, p, dxp)
    rhs(0.0, x0, u0 - h, p, dxm)
    return a, (dxp - dxm) / (2.0 * h)


def _force_column(x0: FloatArray, u0: float, p: FloatArray, scale: float) -> FloatArray:
    """Central difference of :func:`rhs` with respect to the external force p[P_FEXT] (the
    same step rule as the state columns: 1e-6 of the force scale)."""
    n = x0.shape[0]
    dxp = np.empty(n)
    dxm = np.empty(n)
    h = 1e-6 * scale
    pp, pm = p.copy(), p.copy()
    pp[P_FEXT] += h
    pm[P_FEXT] -= h
    rhs(0.0, x0, u0, pp, dxp)
    rhs(0.0, x0, u0, pm, dxm)
    return (dxp - dxm) / (2.0 * h)


def linearize(params: ServoParams, position: float | None = None) -> Linearization:
    """Linearise the nonlinear model at rest at ``position`` [m] (default mid-stroke).

    Parameters
    ----------
    params : ServoParams
        Servo parameters; Coulomb/Stribeck friction and supply ripple are set to zero for the
        linearisation (see module docstring).
    position : float, optional
        Piston position inside (0, stroke) [m]; default ``stroke / 2``.

    Returns
    -------
    Linearization
        Matrices, eigenvalues, ω₀ [rad/s], δ [1] and the velocity gain [m/s per unit command].

    Raises
    ------
    ParameterError
        For a position outside the stroke, or when the model has no lightly damped
        hydraulic mode (ω₀, δ are then undefined).
    """
    if position is None:
        position = params.cylinder.stroke / 2.0
    lp = replace(params, load=replace(params.load, coulomb_friction=0.0, static_friction=0.0),
                 supply=replace(params.supply, ripple_amplitude=0.0))
    tr = trim(lp, position)
    p = pack(lp)
    ps = lp.supply.pressure
    scale = np.array([1.0, 1.0, lp.valve.omega_v, ps, ps, lp.cylinder.stroke,
                      lp.velocity_gain])
    a, b = _jacobian(tr.state, tr.command, p, scale)
    force_scale = ps * lp.cylinder.piston_area  # the supply's stall force [N]
    e = _force_column(tr.state, tr.command, p, force_scale)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and np.all(np.isfinite(e))):
        raise SimulationDivergedError(f"non-finite Jacobian at position {position!r} m")
    keep = list(range(N_STATE))
    if lp.valve.tau_v == 0.0:
        keep.remove(S_LAG)
    a = a[np.ix_(keep, keep)]
    b = b[keep]
    e = e[keep]
    names = tuple(STATE_NAMES[i] for i in keep)
    c = np.zeros(len(keep))
    c[names.index("x")] = 1.0
    # eigenvalues and the solve below in plain IEEE arithmetic: LAPACK's last bits depend on
    # the BLAS kernel, and the derived parameter sets are root solves over these (.dense)
    eig = eigvals(a)
    eig = eig[np.argsort(np.array([modulus(lam) for lam in eig.tolist()]), kind="stable")]
    # hydraulic mode: slowest complex pair, excluding the spool's own pair
    omega_v = lp.valve.omega_v
    pairs = [lam for lam in eig.tolist()
             if lam.imag > 1e-9 and abs(modulus(lam) - omega_v) > 0.2 * omega_v]
    if not pairs:
        raise ParameterError(
            "the linearised model has no oscillatory hydraulic mode (damping >= 1); "
            "omega_0 and damping are undefined for these parameters"
        )
    lam = pairs[0]
    omega_0 = modulus(lam)
    damping = float(-lam.real / omega_0)
    # steady velocity per unit command: solve the model without the position state; a
    # leak-free model has no steady pressure level, so take the limit of vanishing leakage
    aa, bb, ee = a, b, e
    if lp.valve.null_leakage == 0.0 and lp.cylinder.internal_leakage == 0.0:
        limit = replace(lp, valve=replace(lp.valve, null_leakage=_LIMIT_LEAKAGE))
        aa, bb = _jacobian(tr.state, tr.command, pack(limit), scale)
        ee = _force_column(tr.state, tr.command, pack(limit), force_scale)[keep]
        aa, bb = aa[np.ix_(keep, keep)], bb[keep]
    red = [i for i, n in enumerate(names) if n != "x"]
    z = solve(aa[np.ix_(red, red)], -bb[red])
    velocity_gain = float(z[red.index(names.index("v"))])
    # the same steady solve for the force: the velocity the load force leaves [m/s per N]
    zf = solve(aa[np.ix_(red, red)], -ee[red])
    load_compliance = -float(zf[red.index(names.index("v"))])
    return Linearization(trim=tr, state_names=names, a=a, b=b, c=c,
                         eigenvalues=eig.astype(np.complex128), omega_0=omega_0,
                         damping=damping, velocity_gain=velocity_gain, params=lp, e=e,
                         load_compliance=load_compliance)
