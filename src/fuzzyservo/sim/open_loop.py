"""Open-loop simulation of the servo: a compiled fixed-step RK4 path and a solve_ivp reference.

The command is a sequence sampled every ``dt`` and held in between (zero-order hold). The hose
transport delay shifts it by ``delay`` (default ``delay.transport_delay`` of the parameter
set), which must be a whole number of samples; before t = 0 the valve sees the holding command
of the initial equilibrium, so a run starts at rest (:func:`fuzzyservo.plant.trim`). The
sample grid and its limits are the closed loop's (:func:`fuzzyservo.sim.closed_loop.time_grid`).

``plant="nonlinear"`` integrates :func:`fuzzyservo.plant.rhs` (the same njit function the
closed loop uses); ``plant="linear"`` propagates the small-signal linearisation around the
initial equilibrium exactly (ZOH), so its rows hold the trim plus the deviation and keep the
same columns, pressures included.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numba
import numpy as np
from scipy import integrate, linalg

from .._typing import ArrayLike, FloatArray
from ..errors import InputError, ParameterError
from ..plant import N_STATE, STATE_NAMES, ServoParams, linearize, pack, rhs, trim
from ..plant.nonlinear import check_finite, rk4_advance_ws
from .closed_loop import check_delay, time_grid

__all__ = ["OpenLoopResult", "command_samples", "simulate_open_loop"]

PlantKind = Literal["nonlinear", "linear"]
Method = Literal["rk4", "solve_ivp"]


@dataclass(frozen=True, slots=True, kw_only=True)
class OpenLoopResult:
    """Samples of an open-loop run at t_k = k dt, k = 0..N."""

    t: FloatArray  #: sample times [s]
    u: FloatArray  #: command issued at t_k (before the transport delay) [1]
    states: FloatArray  #: (N+1, N_STATE) states, columns STATE_NAMES [SI]
    params: ServoParams  #: parameters of the run
    plant: str  #: "nonlinear" or "linear"
    method: str  #: "rk4", "solve_ivp:<solver>" or "zoh" (linear)

    @property
    def x(self) -> FloatArray:
        """Piston position [m]."""
        return self.states[:, STATE_NAMES.index("x")]

    @property
    def v(self) -> FloatArray:
        """Piston velocity [m/s]."""
        return self.states[:, STATE_NAMES.index("v")]

    @property
    def p_f(self) -> FloatArray:
        """Full-bore chamber pressure [Pa]."""
        return self.states[:, STATE_NAMES.index("p_f")]

    @property
    def p_n(self) -> FloatArray:
        """Annulus chamber pressure [Pa]."""
        return self.states[:, STATE_NAMES.index("p_n")]


def command_samples(command: float | ArrayLike | Callable[[float], float], n: int,
                    dt: float) -> FloatArray:
    """The command held over each of the ``n`` sample intervals, as a float64 array.

    ``command`` is a constant, a sequence of ``n`` values, or a function of time [s] sampled
    at k dt.

    Raises
    ------
    InputError
        For a wrong length or a non-finite value.
    """
    if callable(command):
        u = np.array([float(command(k * dt)) for k in range(n)], dtype=np.float64)
    elif np.ndim(command) == 0:
        u = np.full(n, float(command))  # type: ignore[arg-type]
    else:
        u = np.asarray(command, dtype=np.float64).ravel()
        if u.shape[0] != n:
            raise InputError(f"command has {u.shape[0]} samples, need {n} (duration/dt)")
    if not np.all(np.isfinite(u)):
        k = int(np.argmin(np.isfinite(u)))
        raise InputError(f"command is not finite at t = {k * dt:.6g} s: {u[k]!r}")
    return u


@numba.njit(cache=True, nogil=True)
def _run_rk4(x0: FloatArray, u_valve: FloatArray, p: FloatArray, dt: float, n_sub: int,
             out: FloatArray) -> int:
    """Fill out[k] with the state at k dt; return -1 or the first non-finite sample index."""
    n = u_valve.shape[0]
    x = x0.copy()
    work = np.empty((5, x.shape[0]))
    out[0, :] = x
    for k in range(n):
        ok = rk4_advance_ws(k * dt, x, u_valve[k], p, dt, n_sub, work)
        out[k + 1, :] = x
        if not ok:
            return k + 1
    return -1


def _delay_samples(td: float, dt: float, what: str) -> int:
    """The delay ``td`` [s] (named ``what`` in errors) in whole samples of ``dt``."""
    d = round(td / dt)
    if abs(d * dt - td) > 1e-9 * max(dt, td):
        raise ParameterError(
            f"{what} = {td!r} s is not a whole number of samples of dt = {dt!r} s; the open "
            f"loop holds the command per sample, so choose dt dividing the delay"
        )
    return int(d)


def simulate_open_loop(
    params: ServoParams,
    command: float | ArrayLike | Callable[[float], float],
    *,
    duration: float,
    dt: float = 1.0e-3,
    position: float | None = None,
    delay: float | None = None,
    plant: PlantKind = "nonlinear",
    method: Method = "rk4",
    substep: float = 1.0e-4,
    solver: str = "DOP853",
    rtol: float = 1e-10,
) -> OpenLoopResult:
    """Simulate the servo in open loop from rest at ``position`` (default mid-stroke).

    Parameters
    ----------
    params : ServoParams
        Servo parameters.
    command : float, array or callable
        Valve command, fraction of rated input, held over each sample (see
        :func:`command_samples`) [1].
    duration : float
        Simulated time [s], at least one sample and at most
        :data:`fuzzyservo.sim.closed_loop.MAX_SAMPLES` samples; cut to whole samples (the
        grid of :func:`fuzzyservo.sim.closed_loop.time_grid`).
    dt : float
        Sample time of the command and of the output [s].
    position : float, optional
        Initial piston position inside the stroke [m]; default stroke/2.
    delay : float, optional
        Transport delay on the command [s], >= 0 and a whole number of samples; default
        ``params.delay.transport_delay``.
    plant : {"nonlinear", "linear"}
        Nonlinear model, or its linearisation around the initial equilibrium.
    method : {"rk4", "solve_ivp"}
        Compiled fixed-step RK4 (``substep`` bound), or scipy's ``solve_ivp`` with ``solver``
        and ``rtol`` (the reference path; nonlinear plant only).
    substep : float
        Largest RK4 substep [s].
    solver : str
        ``solve_ivp`` method name ("DOP853", "LSODA", "Radau", ...).
    rtol : float
        ``solve_ivp`` relative tolerance; absolute tolerances are rtol times each state's scale.

    Returns
    -------
    OpenLoopResult

    Raises
    ------
    ParameterError
        For a non-positive ``dt``/``substep``, a ``duration`` shorter than one sample or of
        too many samples, an unknown ``plant``/``method``, or a negative delay or one that is
        not a whole number of samples.
    SimulationDivergedError
        If the state becomes non-finite (the message names the time and the state).
    """
    for name, value in (("dt", dt), ("substep", substep)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
            raise ParameterError(f"{name} must be a finite number > 0 s, got {value!r}")
    if plant not in ("nonlinear", "linear"):
        raise ParameterError(f"plant must be 'nonlinear' or 'linear', got {plant!r}")
    if method not in ("rk4", "solve_ivp"):
        raise ParameterError(f"method must be 'rk4' or 'solve_ivp', got {method!r}")
    if position is None:
        position = params.cylinder.stroke / 2.0
    t = time_grid(duration, dt)
    n = t.shape[0] - 1
    if delay is None:
        d = _delay_samples(params.delay.transport_delay, dt, "delay.transport_delay")
    else:
        d = _delay_samples(check_delay(delay), dt, "delay")
    u_cmd = command_samples(command, n, dt)
    tr = trim(params, position)
    u_valve = np.concatenate([np.full(d, tr.command), u_cmd])[:n]
    if plant == "linear":
        states = _run_linear(params, position, u_valve, dt)
        used = "zoh"
    elif method == "rk4":
        p = pack(params)
        n_sub = max(1, math.ceil(dt / substep - 1e-9))
        states = np.empty((n + 1, N_STATE))
        bad = _run_rk4(np.ascontiguousarray(tr.state), u_valve, p, dt, n_sub, states)
        if bad >= 0:
            check_finite(float(t[bad]), states[bad])
        used = "rk4"
    else:
        states = _run_solve_ivp(params, tr.state, u_valve, dt, solver, rtol)
        used = f"solve_ivp:{solver}"
    return OpenLoopResult(t=t, u=u_cmd, states=states, params=params, plant=plant, method=used)


def _state_scale(params: ServoParams) -> FloatArray:
    ps = params.supply.pressure
    return np.array([1.0, 1.0, params.valve.omega_v, ps, ps, params.cylinder.stroke,
                     params.velocity_gain])


def _run_solve_ivp(params: ServoParams, x0: FloatArray, u_valve: FloatArray, dt: float,
                   solver: str, rtol: float) -> FloatArray:
    p = pack(params)
    n = u_valve.shape[0]
    atol = rtol * _state_scale(params)
    out = np.empty((n + 1, N_STATE))
    out[0] = x0
    # integrate between the samples where the (delayed) command changes
    change = [0] + [k for k in range(1, n) if u_valve[k] != u_valve[k - 1]] + [n]
    x = np.array(x0, dtype=np.float64)
    for a, b in zip(change[:-1], change[1:], strict=True):
        uk = float(u_valve[a])

        def f(tt: float, xx: FloatArray, uk: float = uk) -> FloatArray:
            dx = np.empty(N_STATE)
            rhs(tt, np.ascontiguousarray(xx), uk, p, dx)
            return dx

        t_eval = np.arange(a + 1, b + 1) * dt
        sol = integrate.solve_ivp(f, (a * dt, b * dt), x, method=solver, t_eval=t_eval,
                                  rtol=rtol, atol=atol)
        if sol.status < 0 or sol.y.shape[1] != b - a:
            check_finite(float(sol.t[-1]) if sol.t.size else a * dt,
                         sol.y[:, -1] if sol.y.size else x)
            raise InputError(f"solve_ivp failed at t = {a * dt:.6g} s: {sol.message}")
        out[a + 1:b + 1] = sol.y.T
        x = sol.y[:, -1].copy()
        check_finite(b * dt, x)
    return out


def _run_linear(params: ServoParams, position: float, u_valve: FloatArray,
                dt: float) -> FloatArray:
    lin = linearize(params, position)
    keep = [STATE_NAMES.index(nm) for nm in lin.state_names]
    ns = len(keep)
    m = np.zeros((ns + 1, ns + 1))
    m[:ns, :ns] = lin.a
    m[:ns, ns] = lin.b
    e = linalg.expm(m * dt)
    ad, bd = e[:ns, :ns], e[:ns, ns]
    n = u_valve.shape[0]
    z = np.zeros(ns)
    out = np.empty((n + 1, N_STATE))
    x0 = lin.trim.state
    out[0] = x0
    du = np.clip(u_valve, -1.0, 1.0) - lin.trim.command
    lag = STATE_NAMES.index("spool_lag")
    for k in range(n):
        z = ad @ z + bd * du[k]
        row = x0.copy()
        row[keep] += z
        if lag not in keep:
            row[lag] = u_valve[k]
        out[k + 1] = row
    check_finite(n * dt, out[-1])
    return out
