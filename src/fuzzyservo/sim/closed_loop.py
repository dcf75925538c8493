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

:func:`run_linear` and :func:`run_nonlinear` are the compiled single-run loops; :func:`simulate`
(one run, with plant states) and :func:`fuzzyservo.sim.batch.simulate_batch` (many runs in
parallel) both call them, and they call :func:`fuzzyservo.control.controller_step`, the same
function the controllers' per-step ``step()`` uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ..control.base import STATE_ALPHA, PackedController, controller_step, controller_tables
from ..errors import InputError, ParameterError, SimulationDivergedError
from ..fuzzy.kernels import data_pointer
from ..plant.nonlinear import (
    N_PARAMS,
    P_FEXT,
    P_L,
    P_RES,
    STATE_NAMES,
    pack,
    rk4_steps,
)
from ..plant.zoh import check_delay, discretize, split_delay
from .references import (
    Reference,
    check_reference,
    check_reference_samples,
    sample_reference,
)
from .result import SimResult

__all__ = [
    "DEFAULT_DELAY",
    "MAX_RK4_STEPS",
    "MAX_SAMPLES",
    "LinearPlant",
    "NonlinearPlant",
    "Plant",
    "run_linear",
    "run_linear_pair",
    "run_loop",
    "run_nonlinear",
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
    """

    a: FloatArray  #: state matrix [1/s]
    b: FloatArray  #: input vector [state unit / s per unit command]
    c: FloatArray  #: output vector [m per state unit]
    state_names: tuple[str, ...] = ()  #: state names
    x_op: FloatArray = field(default_factory=lambda: np.empty(0))  #: operating point [SI]
    u0: float = 0.0  #: holding command [-]
    stroke: float | None = None  #: stroke of the cylinder [m]; None: unknown

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
                   stroke: float | None = None) -> LinearPlant:
        """From a :class:`fuzzyservo.plant.LinearServo` (eq. 8) at rest at ``position`` [m]:
        its block states, the position state ``x`` absolute, the others 0 at rest; ``stroke``
        [m] as the class's attribute."""
        a, b, c, d = servo.state_space()
        names: tuple[str, ...] = servo.state_names
        x_op = np.zeros(len(names))
        x_op[names.index("x")] = float(position)
        return cls.from_state_space(a, np.ravel(b), np.ravel(c), d, state_names=names,
                                    x_op=x_op, stroke=stroke)

    @classmethod
    def from_linearization(cls, lin: Any) -> LinearPlant:
        """From a :class:`fuzzyservo.plant.Linearization`: the small-signal model around its
        trim (states as the nonlinear model's, spool_lag dropped when τ_v = 0; chamber
        pressures included), holding the trim command."""
        keep = [STATE_NAMES.index(n) for n in lin.state_names]
        return cls(np.asarray(lin.a), np.asarray(lin.b), np.asarray(lin.c),
                   state_names=tuple(lin.state_names),
                   x_op=np.asarray(lin.trim.state, dtype=np.float64)[keep],
                   u0=float(lin.trim.command), stroke=float(lin.params.cylinder.stroke))

    @property
    def n_states(self) -> int:
        """Number of states."""
        return int(self.a.shape[0])

    @property
    def y0(self) -> float:
        """Output at rest [m]: C x_op."""
        return float(self.c @ self.x_op)

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


@numba.njit(cache=True, nogil=True)
def ring_size(d: int, n: int) -> int:
    """Length of the command ring buffer for a delay of ``d`` whole samples in a run of ``n``
    samples: d + 2, but never more than the run needs (a command delayed past the end of the
    run never reaches the plant)."""
    return min(d, n) + 2


# The sample step below (controller, record, ring buffer) is written out in run_linear,
# run_linear_pair (twice, one per run) and run_nonlinear: moving it into one shared
# inline="always" function cost 25 % of the batched PID rate on the linear plant
# (benchmarks/closed_loop.py, 30 -> 23 M steps/s).
@numba.njit(cache=True, nogil=True)
def _delayed(ubuf: FloatArray, w: int, k: int, d: int, u_init: float) -> tuple[float, float]:
    """Commands u_{k-d} and u_{k-d-1} from the ring buffer whose slot ``w`` holds u_k
    (``u_init`` before t_0); no integer division in the loop. The ring holds d + 2 commands
    (the loops cap d at the run length, :func:`ring_size`)."""
    n = ubuf.shape[0]
    j0 = w - d
    if j0 < 0:
        j0 += n
    j1 = j0 - 1
    if j1 < 0:
        j1 += n
    u0 = ubuf[j0] if k - d >= 0 else u_init
    u1 = ubuf[j1] if k - d - 1 >= 0 else u_init
    return u0, u1


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _output_n(lp: Any, x: Any, y0: float, n: int) -> float:
    """y0 + C x of a packed linear plant (pointers ``lp``, ``x``), summed in index order."""
    o_c = 2 + n * n + 2 * n
    y = y0
    for i in range(n):
        y += lp[o_c + i] * x[i]
    return y


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _advance_n(lp: Any, x: Any, xn: Any, u0: float, u1: float, n: int) -> None:
    """x <- Φ x + Γ0 u0 + Γ1 u1 of a packed linear plant (pointers; ``xn`` scratch), each
    row summed as Γ0 u0 + Γ1 u1 + Φ_i0 x_0 + Φ_i1 x_1 + ... in that order."""
    o_g0 = 2 + n * n
    o_g1 = o_g0 + n
    for i in range(n):
        acc = lp[o_g0 + i] * u0 + lp[o_g1 + i] * u1
        row = 2 + i * n
        for j in range(n):
            acc += lp[row + j] * x[j]
        xn[i] = acc
    for i in range(n):
        x[i] = xn[i]


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def linear_output(lp: Any, x: Any, y0: float, n: int) -> float:
    """:func:`_output_n` with the loop unrolled for n <= 8 states (the same sums)."""
    if n == 1:
        return _output_n(lp, x, y0, 1)
    if n == 2:
        return _output_n(lp, x, y0, 2)
    if n == 3:
        return _output_n(lp, x, y0, 3)
    if n == 4:
        return _output_n(lp, x, y0, 4)
    if n == 5:
        return _output_n(lp, x, y0, 5)
    if n == 6:
        return _output_n(lp, x, y0, 6)
    if n == 7:
        return _output_n(lp, x, y0, 7)
    if n == 8:
        return _output_n(lp, x, y0, 8)
    return _output_n(lp, x, y0, n)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def linear_advance(lp: Any, x: Any, xn: Any, u0: float, u1: float, n: int) -> None:
    """:func:`_advance_n` with the loops unrolled for n <= 8 states (the same sums)."""
    if n == 1:
        _advance_n(lp, x, xn, u0, u1, 1)
    elif n == 2:
        _advance_n(lp, x, xn, u0, u1, 2)
    elif n == 3:
        _advance_n(lp, x, xn, u0, u1, 3)
    elif n == 4:
        _advance_n(lp, x, xn, u0, u1, 4)
    elif n == 5:
        _advance_n(lp, x, xn, u0, u1, 5)
    elif n == 6:
        _advance_n(lp, x, xn, u0, u1, 6)
    elif n == 7:
        _advance_n(lp, x, xn, u0, u1, 7)
    elif n == 8:
        _advance_n(lp, x, xn, u0, u1, 8)
    else:
        _advance_n(lp, x, xn, u0, u1, n)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def run_linear(
    kind: int, cp: FloatArray, cs: FloatArray,
    du_rules: IntArray, du_lims: FloatArray, a_rules: IntArray, a_lims: FloatArray,
    lp: FloatArray, u_op: float, x_op: FloatArray, r: FloatArray, noise: FloatArray,
    y0: float, x: FloatArray, xn: FloatArray, ubuf: FloatArray,
    y_out: FloatArray, u_out: FloatArray, a_out: FloatArray, x_out: FloatArray,
) -> int:
    """One closed loop on a packed linear plant ``lp`` (see ``LinearPlant.discretize``).

    The plant propagates the deviation ``x`` from its operating point (start value, updated
    in place) under the input u - ``u_op``; y = ``y0`` + C x; commands before t_0 are
    ``u_op``; rows of ``x_out`` are the absolute states ``x_op`` + x. ``cs`` (controller
    state) is updated in place; ``ubuf`` is a ring buffer of :func:`ring_size` commands;
    ``noise`` is empty or one value per sample; ``x_out`` is (len(r), n) to keep states or
    (0, n) not to. The plant is not advanced past the last sample. Returns the index of the
    first sample with a non-finite state, or -1.

    The controller (:func:`~fuzzyservo.control.controller_step`) and the plant's update are
    inlined, on data pointers (nothing reference-counted per sample); the plant's sums are
    unrolled for up to 8 states, in the same order as for more.
    """
    n = int(lp[0])
    d = min(int(lp[1]), r.shape[0])  # a command delayed past the run never arrives
    keep_x = x_out.shape[0] > 0
    has_noise = noise.shape[0] > 0
    last = r.shape[0] - 1
    pp = data_pointer(cp)
    sp = data_pointer(cs)
    lpp = data_pointer(lp)
    xp = data_pointer(x)
    xnp = data_pointer(xn)
    du, alpha = controller_tables(du_rules, du_lims, a_rules, a_lims)
    w = 0
    for k in range(r.shape[0]):
        y = linear_output(lpp, xp, y0, n)
        if keep_x:
            for i in range(n):
                x_out[k, i] = x_op[i] + x[i]
        if not math.isfinite(y):
            return k
        if has_noise:
            y += noise[k]
        u = controller_step(kind, pp, sp, r[k], y, du, alpha)
        y_out[k] = y
        u_out[k] = u
        a_out[k] = sp[STATE_ALPHA]
        if k == last:
            break
        ubuf[w] = u
        u0, u1 = _delayed(ubuf, w, k, d, u_op)
        w += 1
        if w == ubuf.shape[0]:
            w = 0
        linear_advance(lpp, xp, xnp, u0 - u_op, u1 - u_op, n)
    return -1


@numba.njit(cache=True, nogil=True, error_model="numpy")
def run_linear_pair(
    kind: int, cp_a: FloatArray, cs_a: FloatArray, cp_b: FloatArray, cs_b: FloatArray,
    du_rules: IntArray, du_lims: FloatArray, a_rules: IntArray, a_lims: FloatArray,
    lp_a: FloatArray, lp_b: FloatArray, u_op_a: float, u_op_b: float,
    r_a: FloatArray, r_b: FloatArray, noise_a: FloatArray, noise_b: FloatArray,
    y0_a: float, y0_b: float, x_a: FloatArray, xn_a: FloatArray, x_b: FloatArray,
    xn_b: FloatArray, ubuf_a: FloatArray, ubuf_b: FloatArray,
    y_a: FloatArray, u_a: FloatArray, al_a: FloatArray,
    y_b: FloatArray, u_b: FloatArray, al_b: FloatArray,
) -> tuple[int, int]:
    """Two runs of :func:`run_linear` (no states kept) in one loop, sample by sample.

    Each run is exactly its :func:`run_linear` (the same functions on its own arrays, in the
    same order); they only share the loop, so the processor overlaps one run's long chains
    (the fuzzy evaluation's divisions and sums) with the other's work: about 10 % more
    samples per second in the batch kernel. ``r_a`` and ``r_b`` have the same length.
    Returns each run's first non-finite sample or -1; a run that diverged is no longer
    advanced (its outputs from that sample on are not written).
    """
    n_a = int(lp_a[0])
    n_b = int(lp_b[0])
    d_a = min(int(lp_a[1]), r_a.shape[0])
    d_b = min(int(lp_b[1]), r_b.shape[0])
    noisy_a = noise_a.shape[0] > 0
    noisy_b = noise_b.shape[0] > 0
    last = r_a.shape[0] - 1
    pa = data_pointer(cp_a)
    sa = data_pointer(cs_a)
    pb = data_pointer(cp_b)
    sb = data_pointer(cs_b)
    la = data_pointer(lp_a)
    lb = data_pointer(lp_b)
    xa = data_pointer(x_a)
    xna = data_pointer(xn_a)
    xb = data_pointer(x_b)
    xnb = data_pointer(xn_b)
    du, alpha = controller_tables(du_rules, du_lims, a_rules, a_lims)
    bad_a = -1
    bad_b = -1
    w_a = 0
    w_b = 0
    for k in range(r_a.shape[0]):
        live_a = bad_a < 0
        live_b = bad_b < 0
        ya = 0.0
        yb = 0.0
        ua = 0.0
        ub = 0.0
        if live_a:
            ya = linear_output(la, xa, y0_a, n_a)
            if not math.isfinite(ya):
                bad_a = k
                live_a = False
            elif noisy_a:
                ya += noise_a[k]
        if live_b:
            yb = linear_output(lb, xb, y0_b, n_b)
            if not math.isfinite(yb):
                bad_b = k
                live_b = False
            elif noisy_b:
                yb += noise_b[k]
        if not (live_a or live_b):
            break
        if live_a:
            ua = controller_step(kind, pa, sa, r_a[k], ya, du, alpha)
            y_a[k] = ya
            u_a[k] = ua
            al_a[k] = sa[STATE_ALPHA]
        if live_b:
            ub = controller_step(kind, pb, sb, r_b[k], yb, du, alpha)
            y_b[k] = yb
            u_b[k] = ub
            al_b[k] = sb[STATE_ALPHA]
        if k == last:
            break
        if live_a:
            ubuf_a[w_a] = ua
            a0, a1 = _delayed(ubuf_a, w_a, k, d_a, u_op_a)
            w_a += 1
            if w_a == ubuf_a.shape[0]:
                w_a = 0
            linear_advance(la, xa, xna, a0 - u_op_a, a1 - u_op_a, n_a)
        if live_b:
            ubuf_b[w_b] = ub
            b0, b1 = _delayed(ubuf_b, w_b, k, d_b, u_op_b)
            w_b += 1
            if w_b == ubuf_b.shape[0]:
                w_b = 0
            linear_advance(lb, xb, xnb, b0 - u_op_b, b1 - u_op_b, n_b)
    return bad_a, bad_b


@numba.njit(cache=True, nogil=True)
def substep_split(n_sub: int, f: float, ts: float) -> tuple[int, int]:
    """RK4 substeps (n1, n0) before and after the delayed command's switch at t_k + ``f``
    [s] inside a sample of ``ts`` [s] with ``n_sub`` substeps: n1 = round(n_sub f / ts)
    (half to even), at least 1 and below n_sub when n_sub > 1; n0 = n_sub - n1, at least 1;
    n1 = 0 when f = 0. The one rule of the loops and of the exported servo's C."""
    n1 = 0
    if f > 0.0:
        n1 = max(1, int(round(n_sub * f / ts)))
        if n1 >= n_sub:
            n1 = n_sub - 1 if n_sub > 1 else 1
    n0 = max(1, n_sub - n1)
    return n1, n0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def run_nonlinear(
    kind: int, cp: FloatArray, cs: FloatArray,
    du_rules: IntArray, du_lims: FloatArray, a_rules: IntArray, a_lims: FloatArray,
    p: FloatArray, ts: float, d: int, f: float, n_sub: int, u_init: float,
    r: FloatArray, noise: FloatArray, force: FloatArray,
    x: FloatArray, work: FloatArray, ubuf: FloatArray,
    y_out: FloatArray, u_out: FloatArray, a_out: FloatArray, x_out: FloatArray,
) -> int:
    """One closed loop on the nonlinear plant with packed parameters ``p`` (a private copy:
    its external-force entry follows ``force`` when that is not empty).

    Delay τ = d ts + f; ``n_sub`` RK4 substeps per sample (split in proportion at f);
    ``work`` is a (5, N_STATE) scratch array. Other arguments as :func:`run_linear`. The
    plant's :func:`~fuzzyservo.plant.nonlinear.rk4_steps` gets data pointers, the controller
    is inlined as in :func:`run_linear`.
    Returns the index of the first sample whose state is non-finite, or -1.
    """
    keep_x = x_out.shape[0] > 0
    has_noise = noise.shape[0] > 0
    has_force = force.shape[0] > 0
    d = min(d, r.shape[0])  # a command delayed past the run never arrives
    res = p[P_RES]
    n1, n0 = substep_split(n_sub, f, ts)
    nx = x.shape[0]
    last = r.shape[0] - 1
    pp = data_pointer(cp)
    sp = data_pointer(cs)
    du, alpha = controller_tables(du_rules, du_lims, a_rules, a_lims)
    # the plant's arrays as pointers for the RK4 (a call passes 3 values, not 7 per array)
    xp = data_pointer(x)
    plp = data_pointer(p)
    k1 = data_pointer(work[0])
    k2 = data_pointer(work[1])
    k3 = data_pointer(work[2])
    k4 = data_pointer(work[3])
    xt = data_pointer(work[4])
    w = 0
    for k in range(r.shape[0]):
        t = k * ts
        if keep_x:
            for i in range(nx):
                x_out[k, i] = x[i]
        y = x[_S_X]
        if has_noise:
            y += noise[k]
        if res > 0.0:
            y = res * math.floor(y / res + 0.5)
        u = controller_step(kind, pp, sp, r[k], y, du, alpha)
        y_out[k] = y
        u_out[k] = u
        a_out[k] = sp[STATE_ALPHA]
        if k == last:
            break
        ubuf[w] = u
        u0, u1 = _delayed(ubuf, w, k, d, u_init)
        w += 1
        if w == ubuf.shape[0]:
            w = 0
        if has_force:
            p[P_FEXT] = force[k]
        ok = True
        if f > 0.0:
            ok = rk4_steps(t, xp, u1, plp, f, n1, k1, k2, k3, k4, xt)
            ok = ok and rk4_steps(t + f, xp, u0, plp, ts - f, n0, k1, k2, k3, k4, xt)
        else:
            ok = rk4_steps(t, xp, u0, plp, ts, n_sub, k1, k2, k3, k4, xt)
        if not ok:
            return k + 1
    return -1


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
             what: str = "closed loop") -> RawRun:
    """Run the compiled loop of ``plant`` (validated inputs; ``r`` absolute [m]; ``what``
    names the run in a divergence message).

    Raises
    ------
    SimulationDivergedError
        The plant state became non-finite.
    """
    ts = float(controller.dt)
    cp = controller.pack()
    cs = controller.rest_states(cp[None, :], plant.y0, plant.u0)[0]
    tabs = controller.tables()
    n = t.size
    y, u, a = np.empty(n), np.empty(n), np.empty(n)
    if isinstance(plant, LinearPlant):
        if disturbance is not None:
            raise ParameterError("a load-force disturbance needs the nonlinear plant")
        lp = plant.discretize(ts, delay)
        nx = plant.n_states
        x = np.zeros(nx)
        xs = np.empty((n, nx))
        ubuf = np.zeros(ring_size(int(lp[1]), n))
        bad = run_linear(controller.kind, cp, cs, *tabs, lp, plant.u0, plant.x_op, r, noise,
                         plant.y0, x, np.empty(nx), ubuf, y, u, a, xs)
        x = plant.x_op + x
    else:
        force = profile(disturbance, t, "disturbance")
        d, f = split_delay(delay, ts)
        x = plant.x0.copy()
        xs = np.empty((n, x.size))
        bad = run_nonlinear(controller.kind, cp, cs, *tabs, plant.packed.copy(), ts, d, f,
                            plant.check_steps(ts, n), plant.u0, r, noise, force, x,
                            np.empty((5, x.size)), np.zeros(ring_size(d, n)), y, u, a, xs)
    if bad >= 0:
        raise_diverged(bad * ts, x, plant.state_names, what)
    return RawRun(y=y, u=u, alpha=a, x=xs)


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
    reference : Reference or array
        Reference offset from the start position [m]: a reference object or one value per
        sample.
    duration : float
        Simulated time [s], at least one sample.
    delay : float
        Transport delay on the command [s], >= 0 (any value, not only multiples of T_s);
        default :data:`DEFAULT_DELAY` (none).
    disturbance : array or callable, optional
        External load force [N] per sample (nonlinear plant only), or a function of t.
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
        Bad sample time, duration, noise level, or a delay longer than the run.
    InputError
        A non-finite reference or disturbance; a reference that leaves the stroke, starts
        after the end of the run, or (a sine) aliases at the sample time; a transducer
        resolution coarser than the reference's move
        (:func:`~fuzzyservo.sim.references.check_reference`,
        :func:`~fuzzyservo.sim.references.check_reference_samples`).
    SimulationDivergedError
        The plant state became non-finite; the message names the time and state.
    """
    ts = float(controller.dt)
    delay = check_delay(delay, duration=duration)
    t = time_grid(duration, ts)
    check_reference(reference, ts=ts, duration=duration)
    r = sample_reference(reference, t) + plant.y0
    stroke, resolution = plant_limits(plant)
    check_reference_samples(r, t, start=plant.y0, stroke=stroke, resolution=resolution)
    noise = _noise(noise_std, rng, (t.size,))
    run = run_loop(controller, plant, r, delay=delay, disturbance=disturbance, noise=noise, t=t)
    info: dict[str, Any] = {"controller": controller, "plant": plant, "noise_std": noise_std}
    return SimResult(t=t, r=r, y=run.y, u=run.u, alpha=run.alpha, x=run.x,
                     state_names=plant.state_names, ts=ts, delay=delay, info=info)


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
