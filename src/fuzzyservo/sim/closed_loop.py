"""Closed-loop simulation: a discrete controller at sample time T_s driving the servo model.

Timing (row k of every result): at t_k = k T_s the measurement y_k is taken, the controller
computes u_k from (r_k, y_k), and u_k is held (zero-order hold) over [t_k, t_k + T_s). The hose
transport delay τ acts on the command, so the plant sees u(t - τ); commands before t_0 equal
the initial (trim) command. With τ = d T_s + f, 0 <= f < T_s, the plant input over
[t_k, t_k + T_s) is u_{k-d-1} on [t_k, t_k + f) and u_{k-d} on [t_k + f, t_k + T_s).

Plants:

- :class:`LinearPlant`: continuous state space (A, B, C) about an operating point,
  discretised exactly by zero-order hold with the fractional delay handled exactly by
  :func:`fuzzyservo.plant.zoh.discretize` (the package's one ZOH):
  x_{k+1} = Φ x_k + Γ_0 u_{k-d} + Γ_1 u_{k-d-1}.
- :class:`NonlinearPlant`: the two-chamber model of :mod:`fuzzyservo.plant.nonlinear`,
  integrated with its RK4 (``rk4_steps``) between samples, the interval split at t_k + f
  so the delayed command switches exactly; the load force F_ext may follow a profile.

The compiled loops are :mod:`fuzzyservo.sim.loops`' ``linear_chunk`` and ``nonlinear_chunk``,
one copy per control law: :func:`simulate` (one run, with plant states) and
:func:`fuzzyservo.sim.batch.simulate_batch` (many runs in parallel) both call them, and they
call the law's step, the same function the controllers' per-step ``step()`` uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._args import given, real
from .._typing import ArrayLike, FloatArray
from ..control.base import PackedController
from ..errors import InputError, ParameterError, SimulationDivergedError
from ..plant.dense import dot
from ..plant.nonlinear import (
    N_PARAMS,
    P_L,
    P_RES,
    STATE_NAMES,
    pack,
)
from ..plant.zoh import check_delay, discretize, split_delay
from .loops import (
    LawRows,
    LinearRows,
    NonlinearRows,
    Outputs,
    Signals,
    kernels,
    ring_size,
    substep_split,
)
from .references import (
    Reference,
    check_reference,
    check_reference_samples,
    parse_reference,
    reference_rates,
    sample_reference,
)
from .result import SimResult
from .stepinfo import N_METRICS, N_TAIL

__all__ = [
    "DEFAULT_DELAY",
    "MAX_RK4_STEPS",
    "MAX_SAMPLES",
    "LinearPlant",
    "NonlinearPlant",
    "Plant",
    "run_loop",
    "check_delay",
    "plant_limits",
    "ring_size",
    "simulate",
    "substep_split",
    "time_grid",
]

_S_X = STATE_NAMES.index("x")


@dataclass(frozen=True, slots=True, eq=False)
class LinearPlant:
    """Linear plant about an operating point, starting at rest there.

    dx/dt = A dx + B (u - u0) and y = y0 + C dx, where dx is the deviation of the state from
    the operating point ``x_op`` and y0 = C x_op. Results carry the absolute state
    x_op + dx and the absolute output, as the nonlinear plant's do.

    Attributes
    ----------
    a, b, c : ndarray
        State matrices: A (n, n) [1/s], B (n,) [state unit per unit command per s],
        C (n,) [m per state unit].
    state_names : tuple of str
        Names of the states (CSV columns).
    x_op : ndarray
        Operating point, the state at rest (n,) [state units]; zeros when empty (default).
    u0 : float
        Command that holds the operating point [-]; 0 by default.
    stroke : float or None
        Stroke of the cylinder the model stands for [m]: :func:`simulate` keeps references
        within [0, stroke]. None (default): not known, not checked.
    e : ndarray
        Load-force input vector E (n,) [state unit / s per N]: dx/dt gains E (F - F_op) for
        an external force F opposing extension; empty (default): the model has no force
        input and refuses a load-force disturbance.
    force_op : float
        External force at the operating point, F_op [N] (the parameter set's
        ``load.external_force``, which the operating point already holds).

    Notes
    -----
    A load force enters by superposition (:meth:`force_response`): the plant is linear, so
    the closed loop on it is the loop driven by u plus the open-loop response y_F of the
    plant to the force alone, which does not depend on u; the loops add y_F to the measured
    output through their measurement-noise row (docs/model.md, "Load force on the linear
    models").
    """

    a: FloatArray  #: state matrix [1/s]
    b: FloatArray  #: input vector [state unit / s per unit command]
    c: FloatArray  #: output vector [m per state unit]
    state_names: tuple[str, ...] = ()  #: state names
    x_op: FloatArray = field(default_factory=lambda: np.empty(0))  #: operating point [SI]
    u0: float = 0.0  #: holding command [-]
    stroke: float | None = None  #: stroke of the cylinder [m]; None: unknown
    e: FloatArray = field(default_factory=lambda: np.empty(0))  #: force input [SI per N]
    force_op: float = 0.0  #: external force at the operating point [N]

    def __post_init__(self) -> None:
        if self.stroke is not None and not (math.isfinite(self.stroke) and self.stroke > 0.0):
            raise ParameterError(f"stroke must be finite and > 0 m, got {self.stroke!r}")
        a = np.atleast_2d(np.asarray(self.a, dtype=np.float64))
        b = np.asarray(self.b, dtype=np.float64).reshape(-1)
        c = np.asarray(self.c, dtype=np.float64).reshape(-1)
        n = a.shape[0]
        if a.shape != (n, n) or b.shape != (n,) or c.shape != (n,) or n == 0:
            raise ParameterError(
                f"linear plant needs A (n, n), B (n,), C (n,), got {a.shape}, {b.shape}, "
                f"{c.shape}")
        x_op = np.asarray(self.x_op, dtype=np.float64).reshape(-1)
        if x_op.size == 0:
            x_op = np.zeros(n)
        if x_op.shape != (n,):
            raise ParameterError(f"operating point x_op needs {n} values, got {x_op.shape}")
        if not all(np.all(np.isfinite(m)) for m in (a, b, c, x_op)) or \
                not math.isfinite(self.u0):
            raise ParameterError("linear plant matrices, operating point and u0 must be finite")
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "c", c)
        object.__setattr__(self, "x_op", x_op)
        object.__setattr__(self, "u0", float(self.u0))
        e = np.asarray(self.e, dtype=np.float64).reshape(-1)
        if e.size not in (0, n) or not np.all(np.isfinite(e)) or \
                not math.isfinite(self.force_op):
            raise ParameterError(f"the force input e needs {n} finite values (or none) and "
                                 f"force_op a finite force, got {e.shape} and "
                                 f"{self.force_op!r}")
        object.__setattr__(self, "e", e)
        object.__setattr__(self, "force_op", float(self.force_op))
        if not self.state_names:
            object.__setattr__(self, "state_names", tuple(f"x{i}" for i in range(n)))
        elif len(self.state_names) != n:
            raise ParameterError(f"need {n} state names, got {len(self.state_names)}")

    @classmethod
    def from_state_space(cls, a: ArrayLike, b: ArrayLike, c: ArrayLike, d: ArrayLike = 0.0,
                         **kw: Any) -> LinearPlant:
        """From (A, B, C, D) of a single-input single-output system; D must be 0."""
        if np.any(np.asarray(d, dtype=np.float64) != 0.0):
            raise ParameterError(
                f"the closed loop needs a strictly proper plant (D = 0), got D = {d!r}")
        return cls(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64),
                   np.asarray(c, dtype=np.float64), **kw)

    @classmethod
    def from_servo(cls, servo: Any, position: float = 0.0, *,
                   stroke: float | None = None, force_op: float = 0.0) -> LinearPlant:
        """From a :class:`fuzzyservo.plant.LinearServo` (eq. 8) at rest at ``position`` [m]:
        its block states, the position state ``x`` absolute, the others 0 at rest; ``stroke``
        [m] and ``force_op`` [N] as the class's attributes; its force input
        (:meth:`~fuzzyservo.plant.LinearServo.force_input`) when the servo has one."""
        a, b, c, d = servo.state_space()
        names: tuple[str, ...] = servo.state_names
        x_op = np.zeros(len(names))
        x_op[names.index("x")] = float(position)
        e = servo.force_input() if servo.has_force_input else np.empty(0)
        return cls.from_state_space(a, np.ravel(b), np.ravel(c), d, state_names=names,
                                    x_op=x_op, stroke=stroke, e=e, force_op=force_op)

    @classmethod
    def from_linearization(cls, lin: Any) -> LinearPlant:
        """From a :class:`fuzzyservo.plant.Linearization`: the small-signal model around its
        trim (states as the nonlinear model's, spool_lag dropped when τ_v = 0; chamber
        pressures included), holding the trim command."""
        keep = [STATE_NAMES.index(n) for n in lin.state_names]
        return cls(np.asarray(lin.a), np.asarray(lin.b), np.asarray(lin.c),
                   state_names=tuple(lin.state_names),
                   x_op=np.asarray(lin.trim.state, dtype=np.float64)[keep],
                   u0=float(lin.trim.command), stroke=float(lin.params.cylinder.stroke),
                   e=np.asarray(lin.e), force_op=float(lin.params.load.external_force))

    @property
    def n_states(self) -> int:
        """Number of states."""
        return int(self.a.shape[0])

    @property
    def y0(self) -> float:
        """Output at rest [m]: C x_op."""
        return dot(self.c, self.x_op)

    def force_response(self, force: FloatArray, ts: float) -> tuple[FloatArray, FloatArray]:
        """The plant's open-loop response to an external force alone, from rest.

        The force samples ``force`` [N] (total external force, F_op included) are held over
        each sample, as the nonlinear loop holds them, and the model is discretised by the
        package's one ZOH (:func:`fuzzyservo.plant.zoh.discretize`, no delay: the force acts
        on the piston directly): x_F[0] = 0, x_F[k+1] = Φ x_F[k] + Γ_E (F_k - F_op),
        y_F[k] = C x_F[k]. Sums in a fixed order, element by element (no BLAS:
        docs/architecture.md, "Machine-independent results").

        Returns
        -------
        y_F : ndarray (n_t,)
            Output deviation due to the force [m].
        x_F : ndarray (n_t, n)
            State deviation due to the force [state units].

        Raises
        ------
        ParameterError
            The plant has no force input.
        """
        if self.e.size == 0:
            raise ParameterError("this linear plant has no load-force input (e); build it "
                                 "with fuzzyservo.registry.build_plant")
        f = np.asarray(force, dtype=np.float64) - self.force_op
        m = discretize(self.a, self.e, ts, 0.0)
        phi, gam = m.phi, m.gamma0
        n, n_t = self.n_states, f.size
        xs = np.zeros((n_t, n))
        x = np.zeros(n)
        for k in range(n_t - 1):
            nxt = gam * f[k]
            for j in range(n):
                nxt = nxt + phi[:, j] * x[j]
            x = nxt
            xs[k + 1] = x
        ys = np.zeros(n_t)
        for i in range(n):
            ys = ys + self.c[i] * xs[:, i]
        return ys, xs

    def discretize(self, ts: float, delay: float) -> FloatArray:
        """Packed ZOH discretisation with delay (:func:`fuzzyservo.plant.zoh.discretize`):
        [n, d, Φ (n·n), Γ0 (n), Γ1 (n), C (n)]."""
        m = discretize(self.a, self.b, ts, delay)
        return np.concatenate([[self.n_states, m.d], m.phi.ravel(), m.gamma0, m.gamma1,
                               self.c])


@dataclass(frozen=True, slots=True, eq=False)
class NonlinearPlant:
    """Nonlinear two-chamber servo (:mod:`fuzzyservo.plant.nonlinear`) starting at rest.

    Attributes
    ----------
    packed : ndarray
        Parameter vector from ``fuzzyservo.plant.nonlinear.pack`` (N_PARAMS,).
    x0 : ndarray
        Initial state (``STATE_NAMES``), usually the trim equilibrium [SI].
    u0 : float
        Command that holds ``x0`` at rest (the trim command) [-].
    substep : float
        Upper bound of the RK4 step inside a sample [s]. The default 0.5 ms (two RK4 steps
        per 1 ms sample, ω_v h = 0.34) keeps closed-loop positions within 1e-6 of the step
        of a 25 µs-step run (tests/sim/test_closed_loop.py); use 1e-4 s for open-loop-grade
        accuracy.
    """

    packed: FloatArray  #: packed parameters [SI]
    x0: FloatArray  #: initial state [SI]
    u0: float = 0.0  #: trim command [-]
    substep: float = 5.0e-4  #: RK4 step bound [s]
    state_names: tuple[str, ...] = STATE_NAMES  #: state names

    def __post_init__(self) -> None:
        p = np.ascontiguousarray(self.packed, dtype=np.float64)
        x0 = np.ascontiguousarray(self.x0, dtype=np.float64)
        if p.shape != (N_PARAMS,) or x0.shape != (len(STATE_NAMES),):
            raise ParameterError(
                f"nonlinear plant needs packed ({N_PARAMS},) and x0 ({len(STATE_NAMES)},), got "
                f"{p.shape} and {x0.shape}")
        if not (math.isfinite(self.substep) and self.substep > 0.0):
            raise ParameterError(f"substep must be finite and > 0 s, got {self.substep!r}")
        if not (np.all(np.isfinite(x0)) and math.isfinite(self.u0)):
            raise ParameterError("initial state and trim command must be finite")
        object.__setattr__(self, "packed", p)
        object.__setattr__(self, "x0", x0)

    @classmethod
    def from_params(cls, params: Any, position: float | None = None, *,
                    substep: float = 5.0e-4) -> NonlinearPlant:
        """From ``ServoParams``, at rest at ``position`` [m] (default mid-stroke), trimmed."""
        from ..plant.linearize import trim

        pos = 0.5 * params.cylinder.stroke if position is None else float(position)
        tr = trim(params, pos)
        return cls(pack(params), np.array(tr.state, dtype=np.float64), float(tr.command),
                   substep=substep)

    @property
    def y0(self) -> float:
        """Output at rest [m]."""
        return float(self.x0[_S_X])

    def n_sub(self, ts: float) -> int:
        """RK4 substeps per sample."""
        return max(1, math.ceil(ts / self.substep - 1e-9))

    def check_steps(self, ts: float, n: int) -> int:
        """RK4 substeps per sample for a run of ``n`` samples at ``ts`` [s], refused when the
        run would take more than :data:`MAX_RK4_STEPS` steps (a compiled loop cannot be
        interrupted, so it must not run for minutes on a typo in ``substep``)."""
        ratio = ts / self.substep
        total = n * ratio
        if not math.isfinite(total) or total > MAX_RK4_STEPS:
            raise ParameterError(
                f"substep {self.substep!r} s at ts = {ts!r} s gives {total:.3g} RK4 steps for "
                f"{n} samples; at most {MAX_RK4_STEPS:.0e} are allowed (about half a minute): "
                f"raise the substep (the default is 5e-4 s) or shorten the run")
        return self.n_sub(ts)


Plant = LinearPlant | NonlinearPlant


def plant_limits(plant: Plant) -> tuple[float | None, float]:
    """``(stroke, resolution)`` of a plant [m]: the stroke a reference must stay in (None when
    the plant does not know it) and the transducer resolution its measurement is rounded to
    (0: exact; only the nonlinear plant rounds)."""
    if isinstance(plant, NonlinearPlant):
        return float(plant.packed[P_L]), float(plant.packed[P_RES])
    return plant.stroke, 0.0

#: The transport delay every entry point uses when none is given [s]: none. The paper's
#: Figs. 4-7 and its tuning are without the hose delay; Fig. 8 adds it as a robustness test.
#: A run with the parameter set's hose delay asks for it (``delay.transport_delay``, or
#: ``--delay hose`` on the command line). docs/model.md, "The hose delay".
DEFAULT_DELAY = 0.0


#: Most samples one run may have: 1e7 samples of a few signals is already ~1 GB of results.
MAX_SAMPLES = 10_000_000

#: Most RK4 steps one nonlinear run may take (samples x substeps per sample): about 30 s at
#: the 3.3 million steps per second measured here.
MAX_RK4_STEPS = 100_000_000


def time_grid(duration: float, ts: float) -> FloatArray:
    """Sample times 0, ts, ..., up to ``duration`` [s].

    Validated: ts > 0, duration >= ts, and at most :data:`MAX_SAMPLES` samples.
    """
    if not (isinstance(ts, int | float) and math.isfinite(ts) and ts > 0.0):
        raise ParameterError(f"sample time ts must be finite and > 0 s, got {ts!r}")
    if not (math.isfinite(duration) and duration >= ts):
        raise ParameterError(
            f"duration must be finite and at least one sample ({ts!r} s), got {duration!r}")
    ratio = duration / ts  # inf for a subnormal ts
    n: int | float = int(math.floor(ratio + 1e-9)) + 1 if math.isfinite(ratio) else math.inf
    if n > MAX_SAMPLES:
        raise ParameterError(
            f"duration {duration!r} s at sample time {ts!r} s needs "
            f"{f'{n:.3g}' if math.isfinite(n) else 'more than 1e308'} samples; at most "
            f"{MAX_SAMPLES} are allowed (lengthen the sample time or shorten the run)")
    n = int(n)
    return np.arange(n, dtype=np.float64) * ts


def profile(values: ArrayLike | None, t: FloatArray, what: str) -> FloatArray:
    """A signal given per sample (array of len(t)) or as a callable of t; empty if None."""
    if values is None:
        return np.empty(0)
    arr = np.asarray(values(t) if callable(values) else values, dtype=np.float64)
    if arr.shape != t.shape:
        raise InputError(f"{what} needs one value per sample ({t.size}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{what} must be finite, got {arr[~np.isfinite(arr)][0]!r}")
    return np.ascontiguousarray(arr)


@dataclass(frozen=True, slots=True, eq=False)
class RawRun:
    """The arrays of one compiled run (internal: :func:`simulate` and the open loop)."""

    y: FloatArray  #: measurement per sample [m]
    u: FloatArray  #: command per sample [-]
    alpha: FloatArray  #: α per sample [-]
    x: FloatArray  #: plant state per sample (absolute) [SI]


def run_loop(controller: PackedController, plant: Plant, r: FloatArray, *, delay: float,
             disturbance: ArrayLike | None, noise: FloatArray, t: FloatArray,
             what: str = "closed loop",
             rates: tuple[FloatArray, FloatArray] | None = None) -> RawRun:
    """Run the compiled loop of ``plant`` (validated inputs; ``r`` absolute [m]; ``rates``
    the reference's velocity [m/s] and acceleration [m/s²] per sample, None: zeros; ``what``
    names the run in a divergence message).

    Raises
    ------
    SimulationDivergedError
        The plant state became non-finite.
    """
    ts = float(controller.dt)
    cp = controller.pack()[None, :]
    rows = LawRows(p=cp, s=controller.rest_states(cp, plant.y0, plant.u0),
                   tables=tuple(controller.tables()))
    loops = kernels(controller.law)
    n = t.size
    y, u, a = np.empty((1, n)), np.empty((1, n)), np.empty((1, n))
    rd, rdd = rates if rates is not None else (np.zeros(n), np.zeros(n))
    sig = Signals(t=t, r=r[None, :], rd=np.ascontiguousarray(rd, dtype=np.float64)[None, :],
                  rdd=np.ascontiguousarray(rdd, dtype=np.float64)[None, :],
                  noise=noise[None, :] if noise.size else np.empty((0, 0)), shift=False)
    x_force: FloatArray | None = None
    if isinstance(plant, LinearPlant):
        if disturbance is not None:  # by superposition, through the measurement's row
            y_force, x_force = plant.force_response(profile(disturbance, t, "disturbance"), ts)
            noise = y_force if noise.size == 0 else noise + y_force
            sig = sig._replace(noise=noise[None, :])
        nx = plant.n_states
        x_end = np.empty(nx)
        xs = np.empty((n, nx))
        out = _outputs(y, u, a, xs, x_end)
        lp = plant.discretize(ts, delay)
        lin = LinearRows(lp=lp[None, :], y0=np.array([plant.y0]), u0=np.array([plant.u0]),
                         x_op=plant.x_op)
        loops.linear_chunk(0, 1, rows, lin, sig, out)
    else:
        force = profile(disturbance, t, "disturbance")
        d, f = split_delay(delay, ts)
        nx = plant.x0.size
        x_end = np.empty(nx)
        xs = np.empty((n, nx))
        out = _outputs(y, u, a, xs, x_end)
        nl = NonlinearRows(p=plant.packed[None, :], x0=plant.x0[None, :],
                           y0=np.array([plant.y0]), u0=np.array([plant.u0]),
                           d=np.array([d], dtype=np.int64), f=np.array([f]),
                           n_sub=np.array([plant.check_steps(ts, n)], dtype=np.int64),
                           ts=ts, force=force)
        loops.nonlinear_chunk(0, 1, rows, nl, sig, out)
    bad = int(out.bad[0])
    x = x_end
    if bad >= 0:
        raise_diverged(bad * ts, x, plant.state_names, what)
    if x_force is not None:  # the kept states include the force's part
        xs += x_force
    return RawRun(y=y[0], u=u[0], alpha=a[0], x=xs)


def _outputs(y: FloatArray, u: FloatArray, a: FloatArray, xs: FloatArray,
             x_end: FloatArray) -> Outputs:
    """What a single run writes: its traces and states, no metrics."""
    return Outputs(y=y, u=u, alpha=a, x=xs, x_end=x_end, mopts=np.zeros(4),
                   metrics=np.empty((0, N_METRICS)), tail_fraction=1.0,
                   tail=np.empty((0, N_TAIL)), bad=np.empty(1, dtype=np.int64))


def simulate(
    controller: PackedController,
    plant: Plant,
    reference: Reference | ArrayLike,
    *,
    duration: float,
    delay: float = DEFAULT_DELAY,
    disturbance: ArrayLike | None = None,
    noise_std: float = 0.0,
    rng: np.random.Generator | None = None,
) -> SimResult:
    """Simulate one closed loop; the controller's ``dt`` is the sample time.

    Parameters
    ----------
    controller : PIDController, FuzzyPIController or SelfTuningFuzzyPIController
        The controller (its ``dt`` is T_s [s]); ``fuzzyservo.registry.build_controller``
        builds any registered kind by name.
    plant : LinearPlant or NonlinearPlant
        The plant, starting at rest (``fuzzyservo.registry.build_plant`` by name).
    reference : Reference, str or array
        Reference offset from the start position [m]: a reference object, its command-line
        form (``"step:0.1"``, :func:`~fuzzyservo.sim.references.parse_reference`) or one
        value per sample.
    duration : float
        Simulated time [s], at least one sample.
    delay : float
        Transport delay on the command [s], >= 0 (any value, not only multiples of T_s);
        default :data:`DEFAULT_DELAY` (none).
    disturbance : array or callable, optional
        Total external load force F_ext [N] per sample (> 0 opposes extension; the
        parameter set's ``load.external_force`` is the plant's at rest), or a function of t,
        held over each sample. The nonlinear plant takes it in its force balance; a linear
        plant adds its open-loop response to F_ext - F_op (:meth:`LinearPlant.force_response`)
        to the measured output, and to the states (superposition). A load-force profile of
        :mod:`fuzzyservo.sim.disturbances` gives it with
        :func:`~fuzzyservo.sim.disturbances.load_force_samples`.
    noise_std : float
        Standard deviation of white measurement noise [m], drawn from ``rng``.
    rng : numpy.random.Generator, optional
        Source of the noise (required when ``noise_std > 0``).

    Returns
    -------
    SimResult
        ``r`` and ``y`` are absolute positions [m] on every plant (start position plus the
        reference offset; the measured position).

    Raises
    ------
    ParameterError
        A controller, plant or ``rng`` of the wrong type, a duration, delay or noise level
        that is not a number; bad sample time, duration, noise level, or a delay longer than
        the run.
    InputError
        A reference string that does not parse; a non-finite reference or disturbance; a
        reference that leaves the stroke, starts after the end of the run, or (a sine)
        aliases at the sample time; a transducer
        resolution coarser than the reference's move
        (:func:`~fuzzyservo.sim.references.check_reference`,
        :func:`~fuzzyservo.sim.references.check_reference_samples`).
    SimulationDivergedError
        The plant state became non-finite; the message names the time and state.
    """
    check_run_arguments(controller, plant, rng)
    reference = as_reference(reference)
    duration = real(duration, "duration", "s", positive=True)
    delay = real(delay, "delay", "s", nonnegative=True)
    noise_std = real(noise_std, "noise_std", "m", nonnegative=True)
    ts = float(controller.dt)
    delay = check_delay(delay, duration=duration)
    t = time_grid(duration, ts)
    check_reference(reference, ts=ts, duration=duration)
    r = sample_reference(reference, t) + plant.y0
    stroke, resolution = plant_limits(plant)
    check_reference_samples(r, t, start=plant.y0, stroke=stroke, resolution=resolution)
    noise = _noise(noise_std, rng, (t.size,))
    run = run_loop(controller, plant, r, delay=delay, disturbance=disturbance, noise=noise, t=t,
                   rates=reference_rates(reference, t))
    info: dict[str, Any] = {"controller": controller, "plant": plant, "noise_std": noise_std}
    return SimResult(t=t, r=r, y=run.y, u=run.u, alpha=run.alpha, x=run.x,
                     state_names=plant.state_names, ts=ts, delay=delay, info=info)


def check_run_arguments(controller: object, plant: object, rng: object) -> None:
    """Refuse a controller, plant or ``rng`` of the wrong type, naming the argument, the
    value, its type and what is allowed (ParameterError)."""
    if not isinstance(controller, PackedController):
        raise ParameterError(f"controller must be a controller object "
                             f"(fuzzyservo.registry.build_controller('pid', gains, dt=...)), "
                             f"got {given(controller)}")
    if not isinstance(plant, LinearPlant | NonlinearPlant):
        raise ParameterError(f"plant must be a LinearPlant or NonlinearPlant "
                             f"(fuzzyservo.registry.build_plant('linear', 'paper')), got "
                             f"{given(plant)}")
    if rng is not None and not isinstance(rng, np.random.Generator):
        raise ParameterError(f"rng must be a numpy.random.Generator "
                             f"(numpy.random.default_rng(seed)) or None, got {given(rng)}")


def as_reference(reference: Any) -> Any:
    """A reference as :func:`simulate` takes it: a string is read as the command line's
    ``--reference`` (:func:`~fuzzyservo.sim.references.parse_reference`); anything else is
    passed on unchanged (a reference object, or one value per sample)."""
    return parse_reference(reference) if isinstance(reference, str) else reference


def _noise(std: float, rng: np.random.Generator | None, shape: tuple[int, ...]) -> FloatArray:
    if not (math.isfinite(std) and std >= 0.0):
        raise ParameterError(f"noise_std must be finite and >= 0 m, got {std!r}")
    if std == 0.0:
        return np.empty((0,) * len(shape))
    if rng is None:
        raise ParameterError("measurement noise needs a numpy.random.Generator (rng=...)")
    return rng.normal(0.0, std, size=shape)


def raise_diverged(t: float, x: FloatArray, names: tuple[str, ...],
                   what: str = "closed loop") -> None:
    """Raise :class:`SimulationDivergedError` naming the run, the time and the state."""
    state = ", ".join(f"{n}={float(v):.6g}" for n, v in zip(names, x, strict=False))
    raise SimulationDivergedError(f"{what} diverged at t = {t:.6g} s: state {state}")
