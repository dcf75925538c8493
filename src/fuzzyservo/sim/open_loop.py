"""Open-loop simulation of the servo: a command schedule through the closed loop's machinery.

The command is a sequence sampled every ``dt`` and held in between (zero-order hold). An
open-loop run is the closed loop of :mod:`fuzzyservo.sim.closed_loop` with the pass-through
"controller" :class:`~fuzzyservo.control.command.CommandSchedule`: the same compiled loops, the
same transport-delay handling (any delay, fractional ones exact), the same sample grid and
limits, on any plant the registry builds (eq. (8), the small-signal linearisation, the
nonlinear model). Before t = 0 the valve sees the plant's holding command, so a run starts at
rest (:func:`fuzzyservo.plant.trim`).

``method="solve_ivp"`` is the reference path for the nonlinear plant: scipy's adaptive
integrators between the instants where the (delayed) command switches. It is bounded: at most
``max_rhs_evals`` evaluations of the model's right-hand side (default
:data:`MAX_RHS_EVALUATIONS`), so a stiff model (a tiny load mass, a huge bulk modulus) stops
with an error in seconds instead of running for hours; ``progress`` reports the simulated
time reached.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, TextIO

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..control.command import CommandSchedule
from ..errors import InputError, ParameterError
from ..plant import COMMAND_LIMIT, N_STATE, rhs
from ..plant.nonlinear import P_AF, P_G, P_L, P_PS, P_RES, P_WV, check_finite
from ..plant.zoh import split_delay
from .closed_loop import DEFAULT_DELAY, NonlinearPlant, Plant, check_delay, run_loop, time_grid
from .result import write_csv

__all__ = ["MAX_RHS_EVALUATIONS", "OpenLoopResult", "command_samples", "simulate_open_loop"]

Method = Literal["rk4", "solve_ivp"]

#: Default limit of right-hand-side evaluations of one ``solve_ivp`` run. A 1 s run of the
#: paper's servo under a constant command takes about 3e3 (DOP853, rtol 1e-10), one whose
#: command changes every 1 ms sample 2e4 to 7e4 per simulated second; the limit leaves room
#: for minutes of the former and about 15 s of the latter. The model evaluates 1e5 to 1.6e5
#: times per second of wall time, so a stiff model stops after 6-10 s, where unlimited it ran
#: for hours (1 s with ``load.mass = 1e-6`` needs ~1e12 evaluations).
MAX_RHS_EVALUATIONS = 1_000_000

#: Right-hand-side evaluations between two progress reports of ``solve_ivp``.
_PROGRESS_EVERY = 2000


class _BudgetSpent(Exception):
    """Raised inside solve_ivp's right-hand side when the evaluation limit is reached."""

    def __init__(self, t: float) -> None:
        super().__init__(t)
        self.t = t


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class OpenLoopResult:
    """Samples of an open-loop run at t_k = k dt, k = 0..N."""

    t: FloatArray  #: sample times [s], (N+1,)
    u: FloatArray  #: command issued at t_k, held to t_{k+1} (before the delay) [-], (N,)
    y: FloatArray  #: measured position (transducer) [m], (N+1,)
    states: FloatArray  #: (N+1, len(state_names)) absolute plant states [SI]
    state_names: tuple[str, ...]  #: names of the state columns
    plant: Plant  #: the plant simulated
    delay: float  #: transport delay on the command [s]
    method: str  #: "rk4" (nonlinear), "zoh" (linear plants) or "solve_ivp:<solver>"

    def state(self, name: str) -> FloatArray:
        """One state column by name [SI unit of that state].

        Raises
        ------
        ParameterError
            The plant has no state ``name`` (eq. (8) has no chamber pressures).
        """
        if name not in self.state_names:
            raise ParameterError(f"this plant has no state {name!r}; its states: "
                                 f"{', '.join(self.state_names)}")
        return self.states[:, self.state_names.index(name)]

    def to_csv(self, dest: str | Path | TextIO) -> None:
        """Write columns ``t, u, y`` then the plant states (SI units; y and the position
        absolute) to a path or an open text stream; u at t_k is the command held from t_k
        (the last one repeated on the final row)."""
        u = np.append(self.u, self.u[-1])
        write_csv(dest, ["t", "u", "y", *self.state_names], [self.t, u, self.y, *self.states.T])

    @property
    def r(self) -> None:
        """No reference in open loop (for code that handles closed and open runs alike)."""
        return None

    @property
    def alpha(self) -> None:
        """No self-tuning factor in open loop."""
        return None

    @property
    def x(self) -> FloatArray:
        """Piston position [m]."""
        return self.state("x")

    @property
    def v(self) -> FloatArray:
        """Piston velocity [m/s]."""
        return self.state("v")

    @property
    def p_f(self) -> FloatArray:
        """Full-bore chamber pressure [Pa]."""
        return self.state("p_f")

    @property
    def p_n(self) -> FloatArray:
        """Annulus chamber pressure [Pa]."""
        return self.state("p_n")


def command_samples(command: float | ArrayLike | Callable[[float], float], n: int,
                    dt: float) -> FloatArray:
    """The command held over each of the ``n`` sample intervals, as a float64 array.

    ``command`` is a constant, a sequence of ``n`` values, or a function of time [s] sampled
    at k dt; every value is a fraction of the rated input in [-1, 1].

    Raises
    ------
    InputError
        For a wrong length, a non-finite value or one outside [-1, 1].
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
    if np.any(np.abs(u) > COMMAND_LIMIT):
        k = int(np.argmax(np.abs(u) > COMMAND_LIMIT))
        raise InputError(f"command at t = {k * dt:.6g} s is {float(u[k])}; it must be a "
                         f"fraction of the rated input in [-1, 1]")
    return u


def simulate_open_loop(
    plant: Plant,
    command: float | ArrayLike | Callable[[float], float],
    *,
    duration: float,
    dt: float = 1.0e-3,
    delay: float = DEFAULT_DELAY,
    method: Method = "rk4",
    solver: str = "DOP853",
    rtol: float = 1e-10,
    max_rhs_evals: int | None = None,
    progress: Callable[[float, float], None] | None = None,
) -> OpenLoopResult:
    """Simulate a plant in open loop from rest, under a held command schedule.

    Parameters
    ----------
    plant : LinearPlant or NonlinearPlant
        The plant at rest (``fuzzyservo.registry.build_plant``: ``linear`` eq. (8),
        ``small-signal``, ``nonlinear``). The nonlinear plant's RK4 step bound is its
        ``substep``.
    command : float, array or callable
        Valve command, fraction of rated input in [-1, 1], held over each sample (see
        :func:`command_samples`) [-].
    duration : float
        Simulated time [s], at least one sample and at most
        :data:`fuzzyservo.sim.closed_loop.MAX_SAMPLES` samples; cut to whole samples (the
        grid of :func:`fuzzyservo.sim.closed_loop.time_grid`).
    dt : float
        Sample time of the command and of the output [s].
    delay : float
        Transport delay on the command [s], >= 0, any value (fractions of a sample exact);
        default :data:`~fuzzyservo.sim.closed_loop.DEFAULT_DELAY` (none).
    method : {"rk4", "solve_ivp"}
        The compiled loop (RK4 on the nonlinear plant, exact ZOH on the linear ones), or
        scipy's ``solve_ivp`` with ``solver`` and ``rtol`` (the reference path; nonlinear
        plant only).
    solver : str
        ``solve_ivp`` method name ("DOP853", "LSODA", "Radau", ...).
    rtol : float
        ``solve_ivp`` relative tolerance; absolute tolerances are rtol times each state's scale.
    max_rhs_evals : int, optional
        ``solve_ivp``: most evaluations of the model's right-hand side, >= 1; default
        :data:`MAX_RHS_EVALUATIONS`. Reaching it is an error (a stiff model; use ``rk4``).
    progress : callable, optional
        ``solve_ivp``: called as ``progress(t, duration)`` [s] with the simulated time reached,
        every few thousand evaluations and at each command switch (for a progress bar).

    Returns
    -------
    OpenLoopResult

    Raises
    ------
    ParameterError
        A non-positive ``dt``, a ``duration`` shorter than one sample or of too many samples,
        an unknown ``method``, ``solve_ivp`` on a linear plant, a negative delay or one
        longer than the run, a bad ``max_rhs_evals``, or ``solve_ivp`` reaching it.
    InputError
        A command of the wrong length, not finite, or outside [-1, 1].
    SimulationDivergedError
        If the state becomes non-finite (the message names the time and the state).
    """
    if method not in ("rk4", "solve_ivp"):
        raise ParameterError(f"method must be 'rk4' or 'solve_ivp', got {method!r}")
    delay = check_delay(delay, duration=duration)
    limit = MAX_RHS_EVALUATIONS if max_rhs_evals is None else max_rhs_evals
    if isinstance(limit, bool) or not isinstance(limit, int | np.integer) or limit < 1:
        raise ParameterError(f"max_rhs_evals must be an integer >= 1, got {max_rhs_evals!r}")
    t = time_grid(duration, dt)
    n = t.shape[0] - 1
    u_cmd = command_samples(command, n, dt)
    if method == "solve_ivp":
        if not isinstance(plant, NonlinearPlant):
            raise ParameterError("method 'solve_ivp' is the reference for the nonlinear plant; "
                                 "the linear plants are discretised exactly (method 'rk4')")
        states = _run_solve_ivp(plant, u_cmd, dt, delay, solver, rtol, int(limit), progress)
        y = states[:, plant.state_names.index("x")].copy()
        res = float(plant.packed[P_RES])
        if res > 0.0:  # the transducer's quantisation, as the compiled loop applies it
            y = res * np.floor(y / res + 0.5)
        used = f"solve_ivp:{solver}"
    else:
        # the schedule is the "reference"; the last command is repeated for the final row
        sched = np.append(u_cmd, u_cmd[-1])
        run = run_loop(CommandSchedule(dt=dt), plant, sched, delay=delay, disturbance=None,
                       noise=np.empty(0), t=t, what="open loop")
        states, y = run.x, run.y
        used = "rk4" if isinstance(plant, NonlinearPlant) else "zoh"
    return OpenLoopResult(t=t, u=u_cmd, y=y, states=states, state_names=plant.state_names,
                          plant=plant, delay=delay, method=used)


def _state_scale(p: FloatArray) -> FloatArray:
    """Typical magnitude of each nonlinear state, for absolute tolerances [SI]."""
    ps = p[P_PS]
    q = p[P_G] * math.sqrt(ps)  # orifice flow scale [m³/s]
    return np.array([1.0, 1.0, p[P_WV], ps, ps, p[P_L], max(q / p[P_AF], 1e-6)])


def _segments(u_cmd: FloatArray, u_hold: float, dt: float, delay: float
              ) -> list[tuple[float, float, float, list[int]]]:
    """Piecewise-constant valve input: (start [s], end [s], command, sample indices ending in
    the segment), merging neighbours with equal commands."""
    d, f = split_delay(delay, dt)
    n = u_cmd.shape[0]

    def held(j: int) -> float:
        return float(u_cmd[j]) if j >= 0 else u_hold

    pieces: list[tuple[float, float, float, list[int]]] = []
    for k in range(n):
        t0, t1 = k * dt, (k + 1) * dt
        parts: list[tuple[float, float, float, list[int]]] = (
            [(t0, t0 + f, held(k - d - 1), [])] if f > 0.0 else [])
        parts.append((t0 + f, t1, held(k - d), [k + 1]))
        for a, b, u, ends in parts:
            if pieces and pieces[-1][2] == u:
                pieces[-1] = (pieces[-1][0], b, u, pieces[-1][3] + ends)
            else:
                pieces.append((a, b, u, list(ends)))
    return pieces


def _run_solve_ivp(plant: NonlinearPlant, u_cmd: FloatArray, dt: float, delay: float,
                   solver: str, rtol: float, limit: int,
                   progress: Callable[[float, float], None] | None) -> FloatArray:
    from scipy import integrate  # only this reference path needs it: 0.5 s to import

    p = plant.packed
    n = u_cmd.shape[0]
    end = n * dt
    atol = rtol * _state_scale(p)
    out = np.empty((n + 1, N_STATE))
    out[0] = plant.x0
    x = plant.x0.copy()
    count = [0]
    for a, b, uk, ends in _segments(u_cmd, plant.u0, dt, delay):

        def f(tt: float, xx: FloatArray, uk: float = uk) -> FloatArray:
            count[0] += 1
            if count[0] > limit:
                raise _BudgetSpent(tt)
            if progress is not None and count[0] % _PROGRESS_EVERY == 0:
                progress(min(tt, end), end)
            dx = np.empty(N_STATE)
            rhs(tt, np.ascontiguousarray(xx), uk, p, dx)
            return dx

        times = [j * dt for j in ends]
        if times and abs(times[-1] - b) <= 1e-9 * dt:
            times[-1] = b  # the segment ends on that sample: no rounding past the span
        else:
            times.append(b)  # the state at the switch, where the next segment starts
        try:
            sol = integrate.solve_ivp(f, (a, b), x, method=solver, t_eval=np.array(times),
                                      rtol=rtol, atol=atol)
        except _BudgetSpent as stop:
            raise ParameterError(
                f"solve_ivp stopped at t = {stop.t:.6g} s of {end:g} s after {limit} "
                f"right-hand-side evaluations, its limit (max_rhs_evals): the model is too "
                f"stiff for {solver} (a tiny load.mass or a huge stiffness makes it so); use "
                f"method rk4 (--method rk4, with a small --substep), an implicit solver "
                f"(solver='Radau' in the Python API), or raise max_rhs_evals "
                f"(--max-evaluations)"
            ) from None
        if sol.status < 0 or sol.y.shape[1] != len(times):
            check_finite(float(sol.t[-1]) if sol.t.size else a,
                         sol.y[:, -1] if sol.y.size else x)
            raise InputError(f"solve_ivp failed at t = {a:.6g} s: {sol.message}")
        if ends:
            out[ends] = sol.y[:, :len(ends)].T
        x = sol.y[:, -1].copy()
        check_finite(b, x)
        if progress is not None:
            progress(b, end)
    return out
