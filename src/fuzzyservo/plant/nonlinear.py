"""Nonlinear two-chamber model of the valve-controlled asymmetric cylinder (numba kernels).

The equations are written once, as njit functions on a packed parameter vector
(:func:`pack`), and shared by the per-step API (:class:`NonlinearServo`), the open-loop
simulator (:mod:`fuzzyservo.sim.open_loop`) and the closed-loop batch kernels.

State vector (``STATE_NAMES``, SI units):

====  ===============  =======  ==========================================================
idx   name             unit     meaning
====  ===============  =======  ==========================================================
0     ``spool_lag``    1        output of the optional first-order stage τ_v of eq. (1)
1     ``spool``        1        spool opening x_v / x_v,max (1 = rated opening)
2     ``spool_rate``   1/s      d(spool)/dt
3     ``p_f``          Pa       full-bore chamber pressure (absolute)
4     ``p_n``          Pa       annulus chamber pressure (absolute)
5     ``x``            m        piston position, 0 = retracted, L = extended
6     ``v``            m/s      piston velocity
====  ===============  =======  ==========================================================

The command ``u`` passed to :func:`rhs` is the command *at the valve*, i.e. already delayed by
the hose transport delay; simulators apply the delay (any delay, a fraction of a sample
included: ``plant.zoh.split_delay`` and the loops of ``sim.closed_loop``, in open and closed
loop alike). ``u`` is limited to [-1, 1] (``COMMAND_LIMIT``) inside
:func:`rhs`.

Named physical limits (documented in docs/model.md):

- ``COMMAND_LIMIT``: |u| <= 1, the rated input.
- end-stop cushions: a spring-damper ``cylinder.stop_stiffness/stop_damping`` acting beyond
  0 and L, pushing only;
- pressure floor: ``fluid.pressure_floor``; a falling chamber pressure slows smoothly over
  ``PRESSURE_FLOOR_BAND`` above it and stops at it (:func:`floor_factor`);
- volume floor: the cylinder part of a chamber volume is not allowed below 0 (inside the
  cushion), the hose volume remains.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from .._typing import FloatArray
from ..errors import SimulationDivergedError
from .params import ServoParams

__all__ = [
    "COMMAND_LIMIT",
    "N_PARAMS",
    "N_STATE",
    "PRESSURE_FLOOR_BAND",
    "NonlinearServo",
    "STATE_NAMES",
    "STATE_UNITS",
    "check_finite",
    "pack",
    "rhs",
    "rk4_advance",
    "rk4_advance_ws",
    "rk4_steps",
]

STATE_NAMES: tuple[str, ...] = ("spool_lag", "spool", "spool_rate", "p_f", "p_n", "x", "v")
STATE_UNITS: tuple[str, ...] = ("1", "1", "1/s", "Pa", "Pa", "m", "m/s")
N_STATE = len(STATE_NAMES)
S_LAG, S_SPOOL, S_RATE, S_PF, S_PN, S_X, S_V = range(N_STATE)

#: Width of the smooth pressure floor above ``fluid.pressure_floor`` [Pa].
PRESSURE_FLOOR_BAND = 1.0e5

#: The valve command is a fraction of rated input and is limited to [-COMMAND_LIMIT, COMMAND_LIMIT].
COMMAND_LIMIT = 1.0

# Packed parameter layout (indices into the float64 vector from pack()).
P_AF = 0  # full-bore area A_f [m²]
P_AN = 1  # annulus area A_n [m²]
P_L = 2  # stroke [m]
P_V0F = 3  # dead volume full side [m³]
P_V0N = 4  # dead volume annulus side [m³]
P_CLI = 5  # internal leakage [m³/(s·Pa)]
P_KSTOP = 6  # end-stop stiffness [N/m]
P_CSTOP = 7  # end-stop damping [N·s/m]
P_G = 8  # orifice coefficient G [m³/(s·Pa^0.5)]
P_WV = 9  # ω_v [rad/s]
P_ZV = 10  # ζ_v [1]
P_TAU = 11  # τ_v [s]
P_KL0 = 12  # null leakage per land [m³/(s·Pa)]
P_PCR = 13  # laminar transition pressure [Pa]
P_BC = 14  # effective cylinder bulk modulus [Pa]
P_CH = 15  # hose capacitance V_hose / β_hose,eff [m³/Pa]
P_PFLOOR = 16  # pressure floor [Pa]
P_M = 17  # mass [kg]
P_B = 18  # viscous damping [N·s/m]
P_FC = 19  # Coulomb friction [N]
P_FS = 20  # static friction [N]
P_VS = 21  # Stribeck velocity [m/s]
P_EPS = 22  # friction smoothing velocity [m/s]
P_FEXT = 23  # external force opposing extension [N]
P_PS = 24  # supply pressure [Pa]
P_PT = 25  # tank pressure [Pa]
P_RIPA = 26  # ripple amplitude [Pa]
P_RIPF = 27  # ripple frequency [Hz]
P_DELAY = 28  # transport delay [s]
P_NOISE = 29  # transducer noise std [m]
P_RES = 30  # transducer resolution [m]
N_PARAMS = 31


def pack(params: ServoParams) -> FloatArray:
    """Flatten ``params`` into the float64 vector the kernels read (layout ``P_*``)."""
    c, v, f, ld, s = params.cylinder, params.valve, params.fluid, params.load, params.supply
    p = np.zeros(N_PARAMS, dtype=np.float64)
    p[P_AF] = c.piston_area
    p[P_AN] = c.ring_area
    p[P_L] = c.stroke
    p[P_V0F] = c.dead_volume_f
    p[P_V0N] = c.dead_volume_n
    p[P_CLI] = c.internal_leakage
    p[P_KSTOP] = c.stop_stiffness
    p[P_CSTOP] = c.stop_damping
    p[P_G] = params.orifice_coefficient
    p[P_WV] = v.omega_v
    p[P_ZV] = v.zeta_v
    p[P_TAU] = v.tau_v
    p[P_KL0] = v.null_leakage
    p[P_PCR] = v.laminar_pressure
    p[P_BC] = f.cylinder_bulk_modulus
    p[P_CH] = f.hose_volume / f.hose_bulk_modulus
    p[P_PFLOOR] = f.pressure_floor
    p[P_M] = ld.mass
    p[P_B] = ld.viscous_damping
    p[P_FC] = ld.coulomb_friction
    p[P_FS] = ld.static_friction
    p[P_VS] = ld.stribeck_velocity
    p[P_EPS] = ld.friction_smoothing_velocity
    p[P_FEXT] = ld.external_force
    p[P_PS] = s.pressure
    p[P_PT] = s.tank_pressure
    p[P_RIPA] = s.ripple_amplitude
    p[P_RIPF] = s.ripple_frequency
    p[P_DELAY] = params.delay.transport_delay
    p[P_NOISE] = params.transducer.noise_std
    p[P_RES] = params.transducer.resolution
    return p


@kernel(error_model="numpy")
def orifice_root(dp: float, p_cr: float) -> float:
    """sgn(Δp) sqrt|Δp| with a laminar regularisation: Δp / (Δp² + p_cr²)^(1/4) [Pa^0.5]."""
    return dp / math.sqrt(math.sqrt(dp * dp + p_cr * p_cr))


@kernel(error_model="numpy")
def supply_pressure(t: float, p: FloatArray) -> float:
    """P_s(t) = P_s + ripple sin(2π f t) [Pa]."""
    if p[P_RIPA] == 0.0:
        # P_s + 0 sin(..) is P_s to the bit (P_s > 0, the sine finite): no sine to evaluate
        return p[P_PS]
    return p[P_PS] + p[P_RIPA] * math.sin(2.0 * math.pi * p[P_RIPF] * t)


@kernel(error_model="numpy")
def valve_flows(xv: float, pf: float, pn: float, ps: float, p: FloatArray) -> tuple[float, float]:
    """Flow into the full-bore side Q_f and out of the annulus side Q_n [m³/s], eqs. (2)-(3).

    Critically lapped symmetric 4/3 valve (P->A and B->T for x_v >= 0, P->B and A->T for
    x_v < 0) plus the laminar null leakage of all four lands.
    """
    g = p[P_G]
    pcr = p[P_PCR]
    pt = p[P_PT]
    if xv >= 0.0:
        qf = g * xv * orifice_root(ps - pf, pcr)
        qn = g * xv * orifice_root(pn - pt, pcr)
    else:
        qf = g * xv * orifice_root(pf - pt, pcr)
        qn = g * xv * orifice_root(ps - pn, pcr)
    kl = p[P_KL0]
    qf += kl * (ps - pf) - kl * (pf - pt)
    qn -= kl * (ps - pn) - kl * (pn - pt)
    return qf, qn


@kernel(error_model="numpy")
def friction_force(v: float, p: FloatArray) -> float:
    """Viscous plus smoothed Stribeck/Coulomb friction opposing v [N]."""
    f = p[P_B] * v
    if p[P_FS] > 0.0:
        a = v / p[P_VS]
        f += (p[P_FC] + (p[P_FS] - p[P_FC]) * math.exp(-a * a)) * math.tanh(v / p[P_EPS])
    return f


@kernel(error_model="numpy")
def stop_force(x: float, v: float, p: FloatArray) -> float:
    """End-stop cushion force (spring-damper beyond 0 and L, pushing only) [N]."""
    if x < 0.0:
        f = -p[P_KSTOP] * x - p[P_CSTOP] * v
        return f if f > 0.0 else 0.0
    if x > p[P_L]:
        f = -p[P_KSTOP] * (x - p[P_L]) - p[P_CSTOP] * v
        return f if f < 0.0 else 0.0
    return 0.0


@kernel(error_model="numpy")
def floor_factor(pressure: float, floor: float) -> float:
    """Factor on a falling chamber pressure's rate: 0 at the floor, 1 from floor + band up.

    A smoothstep over ``PRESSURE_FLOOR_BAND`` (air release below atmospheric pressure lowers
    the effective bulk modulus to nothing); a rising pressure is never slowed. Smooth, so the
    fixed-step integrator keeps its order when a chamber cavitates.
    """
    z = (pressure - floor) / PRESSURE_FLOOR_BAND
    if z <= 0.0:
        return 0.0
    if z >= 1.0:
        return 1.0
    return z * z * (3.0 - 2.0 * z)


@kernel(error_model="numpy")
def rhs(t: float, x: FloatArray, u: float, p: FloatArray, dx: FloatArray) -> None:
    """Write dx/dt of the nonlinear servo into ``dx`` (no allocation).

    Parameters
    ----------
    t : float
        Time (supply ripple) [s].
    x : float64[N_STATE]
        State, see ``STATE_NAMES``.
    u : float
        Valve command (already delayed), fraction of rated input; limited to [-1, 1] [1].
    p : float64[N_PARAMS]
        Packed parameters from :func:`pack`.
    dx : float64[N_STATE]
        Output derivative.

    ``x``, ``p`` and ``dx`` may also be data pointers (the compiled loops pass pointers: a
    call with arrays passes each array's shape, strides and owner too). A chamber whose
    capacitance is 0 (no hose, the piston deep in the cushion) gives an infinite rate, so
    the loops report a divergence (numpy's division, not Python's ZeroDivisionError).

    Notes
    -----
    Eq. (1) spool dynamics, eqs. (2)-(3) orifice flows, chamber continuity (the corrected
    eq. 4 with dP/dt), eq. (5) force balance with friction, external force and end stops.
    """
    if u > COMMAND_LIMIT:
        u = COMMAND_LIMIT
    elif u < -COMMAND_LIMIT:
        u = -COMMAND_LIMIT
    # eq. (1): optional first-order stage, then the second-order spool
    tau = p[P_TAU]
    if tau > 0.0:
        dx[S_LAG] = (u - x[S_LAG]) / tau
        s_in = x[S_LAG]
    else:
        dx[S_LAG] = 0.0
        s_in = u
    wv = p[P_WV]
    dx[S_SPOOL] = x[S_RATE]
    dx[S_RATE] = wv * wv * (s_in - x[S_SPOOL]) - 2.0 * p[P_ZV] * wv * x[S_RATE]

    pf = x[S_PF]
    pn = x[S_PN]
    xp = x[S_X]
    vp = x[S_V]
    ps = supply_pressure(t, p)
    qf, qn = valve_flows(x[S_SPOOL], pf, pn, ps, p)
    qi = p[P_CLI] * (pf - pn)

    af = p[P_AF]
    an = p[P_AN]
    vcf = p[P_V0F] + af * xp
    vcn = p[P_V0N] + an * (p[P_L] - xp)
    if vcf < 0.0:
        vcf = 0.0
    if vcn < 0.0:
        vcn = 0.0
    cf = vcf / p[P_BC] + p[P_CH]
    cn = vcn / p[P_BC] + p[P_CH]
    dpf = (qf - af * vp - qi) / cf
    dpn = (-qn + an * vp + qi) / cn
    if dpf < 0.0:
        dpf *= floor_factor(pf, p[P_PFLOOR])
    if dpn < 0.0:
        dpn *= floor_factor(pn, p[P_PFLOOR])
    dx[S_PF] = dpf
    dx[S_PN] = dpn

    force = af * pf - an * pn - friction_force(vp, p) - p[P_FEXT] + stop_force(xp, vp, p)
    dx[S_X] = vp
    dx[S_V] = force / p[P_M]


@kernel(error_model="numpy")
def rk4_steps(t: float, x: FloatArray, u: float, p: FloatArray, dt: float, n_sub: int,
              k1: FloatArray, k2: FloatArray, k3: FloatArray, k4: FloatArray,
              xt: FloatArray) -> bool:
    """Advance ``x`` (N_STATE values) in place over ``dt`` with ``n_sub`` classical RK4
    substeps, ``u`` held; ``k1`` .. ``xt`` are N_STATE scratch values each.

    The one RK4 of the model: :func:`rk4_advance_ws` calls it with arrays, the closed-loop
    kernels with data pointers. Returns False if the state became non-finite.
    """
    h = dt / n_sub
    n = N_STATE
    for j in range(n_sub):
        tj = t + j * h
        rhs(tj, x, u, p, k1)
        for i in range(n):
            xt[i] = x[i] + 0.5 * h * k1[i]
        rhs(tj + 0.5 * h, xt, u, p, k2)
        for i in range(n):
            xt[i] = x[i] + 0.5 * h * k2[i]
        rhs(tj + 0.5 * h, xt, u, p, k3)
        for i in range(n):
            xt[i] = x[i] + h * k3[i]
        rhs(tj + h, xt, u, p, k4)
        for i in range(n):
            x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    for i in range(n):
        if not math.isfinite(x[i]):
            return False
    return True


@kernel
def rk4_advance_ws(t: float, x: FloatArray, u: float, p: FloatArray, dt: float, n_sub: int,
                   work: FloatArray) -> bool:
    """Advance ``x`` in place over ``dt`` with ``n_sub`` classical RK4 substeps, ``u`` held.

    ``work`` is a (5, N_STATE) float64 scratch array (no allocation). Returns False if the
    state became non-finite (the caller raises :class:`SimulationDivergedError`).
    """
    return rk4_steps(t, x, u, p, dt, n_sub, work[0], work[1], work[2], work[3], work[4])


@kernel
def rk4_advance(t: float, x: FloatArray, u: float, p: FloatArray, dt: float, n_sub: int) -> bool:
    """:func:`rk4_advance_ws` with its own scratch array (one small allocation per call)."""
    work = np.empty((5, x.shape[0]))
    return rk4_advance_ws(t, x, u, p, dt, n_sub, work)


def check_finite(t: float, x: FloatArray) -> None:
    """Raise :class:`SimulationDivergedError` naming ``t`` and the state if ``x`` is not finite."""
    if not np.all(np.isfinite(x)):
        state = ", ".join(f"{n}={float(v):.6g}" for n, v in zip(STATE_NAMES, x, strict=True))
        raise SimulationDivergedError(f"simulation diverged at t = {t:.6g} s: state {state}")


class NonlinearServo:
    """Per-step API of the nonlinear model: the same njit kernels as the batch simulators.

    Parameters
    ----------
    params : ServoParams
        Servo parameters.
    substep : float
        Upper bound of the RK4 substep [s]; 1e-4 s resolves the valve (ω_v h = 0.07).

    Examples
    --------
    >>> from fuzzyservo.paper import paper_params
    >>> servo = NonlinearServo(paper_params())
    >>> x = servo.rest_state(0.5)
    >>> x = servo.step(0.0, x, 0.1, 1e-3)
    >>> bool(x[6] > 0.0)
    True
    """

    def __init__(self, params: ServoParams, *, substep: float = 1.0e-4) -> None:
        if not (math.isfinite(substep) and substep > 0.0):
            from ..errors import ParameterError

            raise ParameterError(f"substep must be a finite number > 0 s, got {substep!r}")
        self.params = params
        self.packed = pack(params)
        self.substep = substep
        self._work = np.empty((5, N_STATE))

    def rest_state(self, position: float) -> FloatArray:
        """State at rest at ``position`` [m], valve centred, pressures at the zero-leakage limit.

        The pressures balance the piston (A_f p_f = A_n p_n + F_L) with p_f + p_n = P_s + P_T
        shifted accordingly; see :func:`fuzzyservo.plant.linearize.trim` for the exact
        equilibrium with leakage.
        """
        c, s = self.params.cylinder, self.params.supply
        af, an = c.piston_area, c.ring_area
        total = s.pressure + s.tank_pressure
        pf = (an * total + self.params.load.external_force) / (af + an)
        pn = total - pf
        x = np.zeros(N_STATE)
        x[S_PF] = pf
        x[S_PN] = pn
        x[S_X] = position
        return x

    def derivative(self, t: float, x: FloatArray, u: float) -> FloatArray:
        """dx/dt at (t, x, u) as a new array."""
        dx = np.empty(N_STATE)
        rhs(t, np.ascontiguousarray(x, dtype=np.float64), float(u), self.packed, dx)
        return dx

    def step(self, t: float, x: FloatArray, u: float, dt: float) -> FloatArray:
        """Return the state after ``dt`` [s] with the valve command ``u`` held (RK4)."""
        n_sub = max(1, math.ceil(dt / self.substep - 1e-9))
        xn = np.array(x, dtype=np.float64)
        if not rk4_advance_ws(t, xn, float(u), self.packed, dt, n_sub, self._work):
            check_finite(t + dt, xn)
        return xn
