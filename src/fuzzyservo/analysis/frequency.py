"""Frequency response of the closed loop: analytic on a linear plant, measured on any plant.

What is analysed is the loop the simulator runs (:func:`fuzzyservo.sim.simulate`), sample for
sample (docs/frequency.md):

- **the controller**, any registered kind (any :class:`~fuzzyservo.control.law.Law`), is
  linearised around its rest at the operating point, from one compiled step of its law (the
  same function the loops call) by central differences with Richardson extrapolation
  (:func:`linearize_controller`): a discrete state space from (r, y) to u;
- **the plant** is the linear plant's own ZOH discretisation with the exact (fractional)
  delay (:meth:`fuzzyservo.sim.LinearPlant.discretize`), the delayed commands u_{k-d} and
  u_{k-d-1} held as states (:func:`plant_state_space`);
- **the loop** (:class:`LoopModel`): y_k is measured, u_k computed from (r_k, y_k), the plant
  advanced; the closed loop T from r to y, and the loop transfer L = -C_y P broken at the
  plant input (negative feedback convention), whose gain and phase margins and crossovers,
  the modulus margin, the closed loop's bandwidth (-3 dB) and peak :func:`closed_loop_bode`
  gives.

:func:`measured_response` drives the closed loop with sampled sines around the operating point
(any plant, the nonlinear one included), discards whole periods of transient and fits the
amplitude and phase of y at the drive frequency by least squares over whole periods.

Frequencies are in Hz [1/s] throughout; phases in degrees (suffix ``_deg``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import brentq, minimize_scalar

from .._args import given, real
from .._typing import ArrayLike, FloatArray
from ..control.base import PackedController
from ..errors import InputError, ParameterError, SimulationDivergedError
from ..sim import DEFAULT_DELAY, LinearPlant, Plant, simulate_batch
from ..sim.closed_loop import check_run_arguments, plant_limits
from ..sim.references import check_reference_samples
from .tracking import harmonic_fit

__all__ = [
    "DEFAULT_SETTLE",
    "MAX_SETTLE",
    "BodeResult",
    "ComplexArray",
    "LinearizedController",
    "LoopModel",
    "Margins",
    "MeasuredResponse",
    "StateSpace",
    "closed_loop_bode",
    "frequency_grid",
    "linearize_controller",
    "loop_model",
    "margins",
    "measured_response",
    "plant_state_space",
    "settle_time",
    "spectral_radius",
    "transfer_at",
]

log = logging.getLogger(__name__)

ComplexArray = npt.NDArray[np.complex128]

#: Largest perturbation of the difference quotients, times max(1, |value|) in SI units [-]:
#: 1 mm on a position, 0.1 % of the rated command on u. The sequence halves it
#: :data:`_HALVINGS` times (down to about 2e-9), and the estimate whose Richardson
#: extrapolations agree best is taken (:func:`linearize_controller`).
_H0 = 1e-3
_HALVINGS = 20

#: The rest the controller is linearised around must repeat itself: u and the state after a
#: step at rest within this (times max(1, |value|)) of those before.
_REST_TOL = 1e-9

#: Transient left out before a measured sine is fitted on a plant without a linear model [s]
#: (on a linear one: :func:`settle_time`).
DEFAULT_SETTLE = 2.0
#: Longest transient :func:`settle_time` gives [s]: a slower mode of a stable loop is a
#: near-cancellation (a pole beside a zero), whose transient is small.
MAX_SETTLE = 60.0


# --- one step of the law: the one call site ---------------------------------------------------


def _law_step(controller: PackedController, p: FloatArray, s: FloatArray, r: float, y: float,
              tables: tuple[object, ...], rd: float = 0.0, rdd: float = 0.0) -> float:
    """One sample of the controller's law (``s`` updated in place), with the reference's
    rate ``rd`` [m/s] and acceleration ``rdd`` [m/s²]; returns u. The one place this module
    calls the law."""
    return float(controller.law.step_arrays(p, s, r, y, tables, rd, rdd))


# --- state spaces -----------------------------------------------------------------------------


def transfer_at(a: FloatArray, b: ComplexArray, c: FloatArray, d: ComplexArray,
                z: ComplexArray) -> ComplexArray:
    """C (z_i I - A)^-1 b_i + d_i for each point z_i, with a right-hand side b_i (rows of
    ``b``, (len(z), n)) and feedthrough d_i per point.

    Solved by Gaussian elimination with partial pivoting written in element-wise numpy
    operations over the points (no BLAS or LAPACK call, whose kernels differ from machine
    to machine in the last bits: docs/architecture.md), and C x summed in index order."""
    zz = np.asarray(z, dtype=np.complex128).reshape(-1)
    n = int(a.shape[0])
    dd = np.asarray(d, dtype=np.complex128).reshape(-1)
    if n == 0:
        return dd.copy()
    m = -np.broadcast_to(a.astype(np.complex128), (zz.size, n, n)).copy()
    for i in range(n):
        m[:, i, i] += zz
    x = np.array(b, dtype=np.complex128).reshape(zz.size, n).copy()
    rows = np.arange(zz.size)
    for k in range(n):
        piv = k + np.argmax(np.abs(m[:, k:, k]), axis=1)
        swap = piv != k
        if np.any(swap):
            r_s = rows[swap]
            p_s = piv[swap]
            top = m[r_s, k, :].copy()
            m[r_s, k, :] = m[r_s, p_s, :]
            m[r_s, p_s, :] = top
            xt = x[r_s, k].copy()
            x[r_s, k] = x[r_s, p_s]
            x[r_s, p_s] = xt
        for i in range(k + 1, n):
            f = m[:, i, k] / m[:, k, k]
            for j in range(k, n):
                m[:, i, j] = m[:, i, j] - f * m[:, k, j]
            x[:, i] = x[:, i] - f * x[:, k]
    for i in range(n - 1, -1, -1):
        acc = x[:, i]
        for j in range(i + 1, n):
            acc = acc - m[:, i, j] * x[:, j]
        x[:, i] = acc / m[:, i, i]
    out = dd.copy()
    for i in range(n):
        out = out + c[i] * x[:, i]
    return out


@dataclass(frozen=True, slots=True, eq=False)
class StateSpace:
    """A discrete single-input single-output system x_{k+1} = A x_k + B u_k, y_k = C x_k + D u_k.

    Attributes
    ----------
    a, b, c : ndarray
        A (n, n), B (n,), C (n,) [units of the signals they connect].
    d : float
        Direct feedthrough D.
    ts : float
        Sample time [s].
    """

    a: FloatArray  #: state matrix (n, n)
    b: FloatArray  #: input vector (n,)
    c: FloatArray  #: output vector (n,)
    d: float  #: feedthrough
    ts: float  #: sample time [s]

    @property
    def n_states(self) -> int:
        """Number of states."""
        return int(self.a.shape[0])

    def poles(self) -> ComplexArray:
        """Eigenvalues of A (complex) [-]."""
        if not self.n_states:
            return np.empty(0, dtype=np.complex128)
        return np.asarray(np.linalg.eigvals(self.a), dtype=np.complex128)

    def at(self, z: ArrayLike) -> ComplexArray:
        """The transfer function C (zI - A)^-1 B + D at the complex points ``z``
        (:func:`transfer_at`: the same bits on every machine)."""
        zz = np.atleast_1d(np.asarray(z, dtype=np.complex128))
        return transfer_at(self.a, np.broadcast_to(self.b.astype(np.complex128),
                                                   (zz.size, self.n_states)),
                           self.c, np.full(zz.size, complex(self.d)), zz)

    def response(self, freqs: ArrayLike) -> ComplexArray:
        """Frequency response at ``freqs`` [Hz]: the transfer function at z = e^{j 2π f ts}."""
        f = np.asarray(freqs, dtype=np.float64)
        return self.at(np.exp(2j * np.pi * f * self.ts))

    def simulate(self, u: ArrayLike) -> FloatArray:
        """Response y_k to the input samples ``u`` from the zero state."""
        uu = np.asarray(u, dtype=np.float64)
        x = np.zeros(self.n_states)
        y = np.empty(uu.size)
        for k, uk in enumerate(uu):
            y[k] = float(self.c @ x) + self.d * uk
            x = self.a @ x + self.b * uk
        return y


@dataclass(frozen=True, slots=True, eq=False)
class LinearizedController:
    """A controller's law linearised around its rest: deviations from the rest state s*, the
    reference r0 = y0 and the command u0::

        s_{k+1} = A s_k + B_r r_k + B_y y_k + B_rd ṙ_k + B_rdd r̈_k,
        u_k = C s_k + D_r r_k + D_y y_k + D_rd ṙ_k + D_rdd r̈_k

    (ṙ, r̈ the reference's rate and acceleration: the feed-forward inputs, zero columns for
    a law without feed-forward).

    Attributes
    ----------
    a : ndarray (m, m)
        State Jacobian of the step.
    b : ndarray (m, 4)
        Input Jacobians: columns r [1/m ·state unit], y, ṙ [s/m ·state unit] and r̈.
    c : ndarray (m,)
        Command's state Jacobian [1/state unit].
    d : ndarray (4,)
        Command's Jacobians in r, y [1/m], ṙ [s/m] and r̈ [s²/m].
    state_names : tuple of str
        The law's state fields kept (those u depends on, directly or through others).
    rest : ndarray
        The rest state s* of all the law's state fields [their units].
    y0, u0 : float
        Operating point: position [m] and command [-].
    ts : float
        Sample time [s].
    error : float
        Estimated error of the Jacobians, relative to each column's largest entry [-]: about
        1e-13 for a law linear near rest (the PID family); larger for a law whose rest is a
        kink of its nonlinearity (a fuzzy surface), where the model is the limit of the
        difference quotients (docs/frequency.md).
    """

    a: FloatArray  #: state Jacobian (m, m)
    b: FloatArray  #: input Jacobians (m, 4), columns r, y, ṙ, r̈
    c: FloatArray  #: command's state Jacobian (m,)
    d: FloatArray  #: command's input Jacobians (4,): r, y, ṙ, r̈
    state_names: tuple[str, ...]  #: kept state fields
    rest: FloatArray  #: rest state (all fields)
    y0: float  #: operating position [m]
    u0: float  #: operating command [-]
    ts: float  #: sample time [s]
    error: float  #: estimated relative error of the Jacobians [-]

    def from_measurement(self) -> StateSpace:
        """The transfer from y to u with r at rest (C_y)."""
        return StateSpace(self.a, self.b[:, 1].copy(), self.c, float(self.d[1]), self.ts)

    def from_reference(self) -> StateSpace:
        """The transfer from r to u with y at rest (C_r)."""
        return StateSpace(self.a, self.b[:, 0].copy(), self.c, float(self.d[0]), self.ts)


def linearize_controller(controller: PackedController, *, y0: float = 0.0, u0: float = 0.0
                         ) -> LinearizedController:
    """Linearise a controller's law around its rest at position ``y0`` holding ``u0``.

    The rest is the law's state after one step from its rest state
    (``controller.rest_states``) with r = y = y0, as the closed loop starts; it must repeat
    itself (another step returns u0 and the same state). Each column of the Jacobian of one
    step (next state and u, in the state fields, r and y) is a central difference
    (F(x + h e_j) - F(x - h e_j)) / 2h for h = 1e-3 max(1, |x_j|) halved 20 times, extrapolated
    twice (Richardson, removing the h and h² terms of the error: a piecewise-smooth law's
    quotients have both), and the h whose two last extrapolations agree best is taken: for a
    law linear near rest the largest (round-off 1e-13 relative), for a fuzzy surface a small
    one well inside its first membership function. State fields nothing reads (u depends on
    them neither directly nor through another) are dropped: their columns are exact zeros.

    Parameters
    ----------
    controller : PackedController
        Any controller of the registry (``fuzzyservo.registry.build_controller``).
    y0 : float
        Operating position [m].
    u0 : float
        Command holding the plant there [-].

    Returns
    -------
    LinearizedController

    Raises
    ------
    ParameterError
        Not a controller; non-finite operating point; a law that does not stay at rest there
        (u drifts, e.g. a fuzzy system whose output is not zero at zero inputs).
    """
    if not isinstance(controller, PackedController):
        raise ParameterError(f"controller must be a controller object "
                             f"(fuzzyservo.registry.build_controller), got {given(controller)}")
    y0 = real(y0, "y0", "m")
    u0 = real(u0, "u0", "-")
    law = controller.law
    p = np.ascontiguousarray(controller.pack(), dtype=np.float64)
    tables = tuple(controller.tables())
    s = controller.rest_states(p[None, :], y0, u0)[0].copy()
    u1 = _law_step(controller, p, s, y0, y0, tables)
    s2 = s.copy()
    u2 = _law_step(controller, p, s2, y0, y0, tables)
    drift = [abs(u1 - u0) / max(1.0, abs(u0)), abs(u2 - u1) / max(1.0, abs(u1))]
    drift += list(np.abs(s2 - s) / np.maximum(1.0, np.abs(s)))
    if not (np.all(np.isfinite(drift)) and max(drift) <= _REST_TOL):
        names = ("u", "u") + law.state_names
        k = int(np.argmax(np.nan_to_num(drift, nan=np.inf)))
        raise ParameterError(
            f"{law.title} does not rest at y0 = {y0!r} m with u0 = {u0!r}: {names[k]} moves "
            f"by {drift[k]:.3g} (relative) from one sample at rest to the next; the law has no "
            f"equilibrium there to linearise around (a fuzzy system whose output is not 0 at "
            f"zero error?)")
    n = s.size
    x0 = np.concatenate([s, [y0, y0, 0.0, 0.0]])

    def f(x: FloatArray) -> FloatArray:
        st = x[:n].copy()
        u = _law_step(controller, p, st, float(x[n]), float(x[n + 1]), tables,
                      float(x[n + 2]), float(x[n + 3]))
        return np.concatenate([st, [u]])

    jac = np.empty((n + 1, n + 4))
    worst = 0.0
    for j in range(n + 4):
        col, err = _column(f, x0, j)
        jac[:, j] = col
        worst = max(worst, err)
    # keep the state fields u depends on (directly or through kept fields) that r and y move
    # (directly or through kept fields): the others' deviations from rest are zero or never
    # reach u; a flag, a traced value, the integral of a P controller go
    keep = sorted(_closure(jac, n, {j for j in range(n) if jac[n, j] != 0.0}, read=True)
                  & _closure(jac, n, {j for j in range(n) if np.any(jac[j, n:] != 0.0)},
                             read=False))
    idx = np.array(keep, dtype=np.int64)
    a = jac[np.ix_(idx, idx)]
    b = jac[np.ix_(idx, [n, n + 1, n + 2, n + 3])]
    c = jac[n, idx]
    d = jac[n, [n, n + 1, n + 2, n + 3]]
    if worst > 1e-6:
        log.info("%s: the Jacobian at rest is uncertain to %.2g (relative); the law is not "
                 "smooth at rest, the linear model is the limit of small signals", law.title,
                 worst)
    return LinearizedController(a=a, b=b, c=c, d=d,
                                state_names=tuple(law.state_names[i] for i in keep), rest=s,
                                y0=y0, u0=u0, ts=float(controller.dt), error=worst)


def _closure(jac: FloatArray, n: int, start: set[int], *, read: bool) -> set[int]:
    """State fields reached from ``start`` through the state Jacobian: those a member reads
    (``read``), or those that read a member."""
    out = set(start)
    while True:
        more = {j for j in range(n) if j not in out
                and any((jac[i, j] if read else jac[j, i]) != 0.0 for i in out)}
        if not more:
            return out
        out |= more


def _column(f: Callable[[FloatArray], FloatArray], x0: FloatArray, j: int
            ) -> tuple[FloatArray, float]:
    """Column j of the Jacobian of ``f`` at ``x0`` and its estimated relative error."""
    scale = max(1.0, abs(float(x0[j])))
    quotients = []
    for i in range(_HALVINGS + 1):
        h = _H0 * scale / 2.0**i
        xp = x0.copy()
        xm = x0.copy()
        xp[j] += h
        xm[j] -= h
        quotients.append((f(xp) - f(xm)) / (xp[j] - xm[j]))
    q = np.array(quotients)
    r1 = 2.0 * q[1:] - q[:-1]  # removes the O(h) term
    r2 = (4.0 * r1[1:] - r1[:-1]) / 3.0  # removes the O(h²) term
    size = max(float(np.max(np.abs(q[-1]))), float(np.max(np.abs(q[0]))), 1e-300)
    linear = float(np.max(np.abs(q[0] - q[1]))) / size
    if linear <= 1e-10:  # q0's own error is 4/3 of this: the largest h has least round-off
        return q[0], 4.0 * linear / 3.0
    best, best_err = r2[0], math.inf
    for i in range(r2.shape[0] - 1):
        err = float(np.max(np.abs(r2[i + 1] - r2[i]))) / size
        if err < best_err:
            best, best_err = r2[i], err
    return best, best_err


def plant_state_space(plant: LinearPlant, ts: float, delay: float = DEFAULT_DELAY
                      ) -> StateSpace:
    """The linear plant as the closed loop advances it: deviations from its operating point,
    input u - u0, output y - y0, with the delay's commands as states.

    With :meth:`LinearPlant.discretize`'s Φ, Γ_0, Γ_1 and delay = d ts + f, the states are x
    and q_j = u_{k-j}, j = 1 .. d (+1 when f > 0)::

        x_{k+1} = Φ x_k + Γ_0 u_{k-d} + Γ_1 u_{k-d-1},   y_k = C x_k

    Parameters
    ----------
    plant : LinearPlant
        The plant.
    ts : float
        Sample time [s].
    delay : float
        Transport delay on the command [s], >= 0.

    Returns
    -------
    StateSpace
        From u [-] to y [m].
    """
    if not isinstance(plant, LinearPlant):
        raise ParameterError(f"the analytic response needs a LinearPlant (the linear or the "
                             f"small-signal model), got {type(plant).__name__}")
    lp = plant.discretize(real(ts, "ts", "s", positive=True),
                          real(delay, "delay", "s", nonnegative=True))
    n, d = int(lp[0]), int(lp[1])
    o = 2
    phi = lp[o:o + n * n].reshape(n, n)
    g0 = lp[o + n * n:o + n * n + n]
    g1 = lp[o + n * n + n:o + n * n + 2 * n]
    c = lp[o + n * n + 2 * n:o + n * n + 3 * n]
    m = d + (1 if np.any(g1 != 0.0) else 0)
    a = np.zeros((n + m, n + m))
    b = np.zeros(n + m)
    a[:n, :n] = phi
    if d == 0:
        b[:n] = g0
    else:
        a[:n, n + d - 1] = g0
    if m > d:
        a[:n, n + d] = g1
    if m:
        b[n] = 1.0
        for j in range(1, m):
            a[n + j, n + j - 1] = 1.0
    return StateSpace(a, b, np.concatenate([c, np.zeros(m)]), 0.0, float(ts))


@dataclass(frozen=True, slots=True, eq=False)
class LoopModel:
    """The linear closed loop: a linearised controller around a discretised plant.

    Attributes
    ----------
    controller : LinearizedController
        The controller's linear model.
    plant : StateSpace
        The plant's (:func:`plant_state_space`), u [-] to y [m].
    """

    controller: LinearizedController  #: the controller's linear model
    plant: StateSpace  #: the plant's, delay included

    @property
    def ts(self) -> float:
        """Sample time [s]."""
        return self.plant.ts

    def closed_loop(self) -> StateSpace:
        """T: reference r to position y (deviations [m/m]); states plant then controller."""
        p, k = self.plant, self.controller
        np_, nc = p.n_states, k.a.shape[0]
        a = np.zeros((np_ + nc, np_ + nc))
        a[:np_, :np_] = p.a + np.outer(p.b, p.c) * k.d[1]
        a[:np_, np_:] = np.outer(p.b, k.c)
        a[np_:, :np_] = np.outer(k.b[:, 1], p.c)
        a[np_:, np_:] = k.a
        b = np.concatenate([p.b * k.d[0], k.b[:, 0]])
        c = np.concatenate([p.c, np.zeros(nc)])
        return StateSpace(a, b, c, 0.0, self.ts)

    def closed_loop_response(self, freqs: ArrayLike) -> ComplexArray:
        """T at ``freqs`` [Hz], the reference's rate and acceleration included: a sampled
        sine r_k = Re(R e^{jωkT}) has the rates ṙ_k = Re(jω R e^{jωkT}) and r̈_k = Re(-ω² R
        e^{jωkT}) (exact, as the references give them), so the input column is
        B_r + jω B_rd - ω² B_rdd (the same as :meth:`closed_loop` for a law without
        feed-forward)."""
        f = np.asarray(freqs, dtype=np.float64).reshape(-1)
        cl = self.closed_loop()
        p, k = self.plant, self.controller
        w = 2.0 * np.pi * f
        weights = np.stack([np.ones_like(w) + 0j, 1j * w, -(w**2) + 0j], axis=1)  # r, ṙ, r̈
        cols = [0, 2, 3]
        b = np.zeros((f.size, cl.n_states), dtype=np.complex128)
        for i, col in enumerate(cols):
            b = b + weights[:, i:i + 1] * np.concatenate([p.b * k.d[col], k.b[:, col]])[None, :]
        z = np.exp(2j * np.pi * f * self.ts)
        return transfer_at(cl.a, b, cl.c, np.zeros(f.size, dtype=np.complex128), z)

    def loop_transfer(self) -> StateSpace:
        """L = -C_y P, the loop broken at the plant input (negative feedback: the loop is
        stable with margins when 1 + L has no zeros outside the unit circle)."""
        p, k = self.plant, self.controller
        np_, nc = p.n_states, k.a.shape[0]
        a = np.zeros((np_ + nc, np_ + nc))
        a[:np_, :np_] = p.a
        a[np_:, :np_] = np.outer(k.b[:, 1], p.c)
        a[np_:, np_:] = k.a
        b = np.concatenate([p.b, np.zeros(nc)])
        c = -np.concatenate([p.c * k.d[1], k.c])
        return StateSpace(a, b, c, 0.0, self.ts)


def loop_model(controller: PackedController, plant: LinearPlant, *,
               delay: float = DEFAULT_DELAY) -> LoopModel:
    """The linear closed loop of ``controller`` on ``plant`` with ``delay`` [s], linearised
    at the plant's rest (position ``plant.y0`` [m], command ``plant.u0`` [-])."""
    check_run_arguments(controller, plant, None)
    ps = plant_state_space(plant, float(controller.dt), delay)
    lin = linearize_controller(controller, y0=plant.y0, u0=plant.u0)
    return LoopModel(controller=lin, plant=ps)


# --- margins ----------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Margins:
    """Stability margins of the sampled loop L and figures of the closed loop T.

    A frequency a margin is measured at is one of (0, Nyquist] [Hz]; a margin the loop does
    not have (no phase crossover, no gain crossover) is ``inf`` with a NaN frequency, as
    python-control's ``margin`` gives; a bandwidth T never falls to is NaN.
    """

    gain_margin: float  #: 1/|L| at the phase crossover closest to |L| = 1 [-]
    phase_crossover: float  #: where ∠L = -180° [Hz]
    phase_margin_deg: float  #: 180° + ∠L at the gain crossover, in [-180, 180) [deg]
    gain_crossover: float  #: where |L| = 1 [Hz]
    modulus_margin: float  #: min |1 + L|, 1/(peak sensitivity) [-]
    bandwidth: float  #: lowest frequency where |T| = |T(1)|/√2, -3 dB [Hz]
    peak_db: float  #: max |T| [dB]
    peak_frequency: float  #: where it is [Hz]
    stable: bool  #: every closed-loop pole inside the unit circle
    spectral_radius: float  #: largest |pole| of the closed loop [-]

    @property
    def gain_margin_db(self) -> float:
        """The gain margin [dB]."""
        return 20.0 * math.log10(self.gain_margin) if self.gain_margin > 0 else -math.inf


def frequency_grid(lo: float, hi: float, n: int) -> FloatArray:
    """``n`` log-spaced frequencies from ``lo`` to ``hi`` [Hz] (``n`` >= 2, 0 < lo < hi)."""
    lo = real(lo, "lo", "Hz", positive=True)
    hi = real(hi, "hi", "Hz", positive=True)
    if not (isinstance(n, int) and n >= 2 and lo < hi):
        raise ParameterError(f"a frequency grid needs 0 < lo < hi and n >= 2 points, got "
                             f"{lo!r}:{hi!r}:{n!r}")
    return np.geomspace(lo, hi, n)


#: Points per decade of the scan the margins' crossings are bracketed on.
_SCAN_PER_DECADE = 400
#: Lowest frequency scanned, as a fraction of the Nyquist frequency [-].
_SCAN_LOW = 1e-6


def margins(model: LoopModel) -> Margins:
    """The margins, crossovers, bandwidth and peak of a linear loop.

    Crossings are bracketed on a scan of (1e-6, 1] times the Nyquist frequency (400 points
    per decade) and solved by Brent's method on ∠L's imaginary part, log |L|, and
    |T|² - |T(1)|²/2; the gain and phase margins are chosen as python-control's ``margin``
    chooses them (the gain margin closest to 1, the phase margin smallest in magnitude).
    """
    loop = model.loop_transfer()
    closed = model.closed_loop()
    ts = model.ts
    fn = 0.5 / ts
    f = np.geomspace(_SCAN_LOW * fn, fn, int(-math.log10(_SCAN_LOW) * _SCAN_PER_DECADE) + 1)
    f[-1] = fn

    def lf(x: float) -> complex:
        return complex(loop.response(np.array([x]))[0])

    lv = loop.response(f)
    # phase crossovers: Im L = 0 with Re L < 0 (Nyquist itself: L is real there)
    w180: list[float] = []
    im = lv.imag[:-1]
    for i in np.nonzero(np.sign(im[:-1]) * np.sign(im[1:]) < 0)[0]:
        x = float(brentq(lambda v: lf(v).imag, f[i], f[i + 1], xtol=1e-14 * f[i], rtol=1e-15))
        if lf(x).real < 0.0:
            w180.append(x)
    if lv[-1].real < 0.0:
        w180.append(fn)
    gms = [1.0 / abs(lf(x)) for x in w180]
    # gain crossovers: |L| = 1
    wc: list[float] = []
    g = np.log(np.abs(lv))
    for i in np.nonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0)[0]:
        wc.append(float(brentq(lambda v: math.log(abs(lf(v))), f[i], f[i + 1],
                               xtol=1e-14 * f[i], rtol=1e-15)))
    pms = [float(np.remainder(math.degrees(np.angle(lf(x))), 360.0) - 180.0) for x in wc]
    if gms:
        k = int(np.argmin(np.abs(np.log(gms))))
        gm, fg = gms[k], w180[k]
    else:
        gm, fg = math.inf, math.nan
    if pms:
        k = int(np.argmin(np.abs(pms)))
        pm, fp = pms[k], wc[k]
    else:
        pm, fp = math.inf, math.nan
    sm = _minimum(lambda v: abs(1.0 + lf(v)), f, np.abs(1.0 + lv))
    # closed loop
    poles = closed.poles()
    rho = float(np.max(np.abs(poles))) if poles.size else 0.0
    tv = np.abs(closed.response(f))
    dc = float(tv[0])  # the DC gain, at 1e-6 of Nyquist (T may have a cancelled pole at 1)
    bw = math.nan
    if math.isfinite(dc) and dc > 0.0:
        half = dc * dc / 2.0
        below = np.nonzero(tv * tv < half)[0]
        if below.size:
            first = int(below[0])
            if first == 0:
                bw = float(f[0])
            else:
                bw = float(brentq(lambda v: abs(complex(closed.response(np.array([v]))[0]))**2
                                  - half, f[first - 1], f[first], xtol=1e-14 * f[first],
                                  rtol=1e-15))
    neg = _minimum(lambda v: -abs(complex(closed.response(np.array([v]))[0])), f, -tv,
                   argument=True)
    peak_f = neg
    peak = abs(complex(closed.response(np.array([peak_f]))[0]))
    return Margins(gain_margin=gm, phase_crossover=fg, phase_margin_deg=pm, gain_crossover=fp,
                   modulus_margin=sm, bandwidth=bw, peak_db=20.0 * math.log10(peak),
                   peak_frequency=peak_f, stable=rho < 1.0, spectral_radius=rho)


def _minimum(fun: Callable[[float], float], f: FloatArray, values: FloatArray, *,
             argument: bool = False) -> float:
    """The minimum of ``fun`` over the scan ``f`` (``values`` = fun on it), refined between the
    neighbours of the least sample; its argument [Hz] if ``argument``."""
    i = int(np.argmin(values))
    lo, hi = f[max(i - 1, 0)], f[min(i + 1, f.size - 1)]
    best_x, best = float(f[i]), float(values[i])
    if hi > lo:
        res = minimize_scalar(fun, bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-12 * hi})
        if res.fun < best:
            best_x, best = float(res.x), float(res.fun)
    return best_x if argument else best


# --- the analytic response -------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class BodeResult:
    """The analytic frequency response of a closed loop (:func:`closed_loop_bode`)."""

    frequency: FloatArray  #: frequencies [Hz]
    closed_loop: ComplexArray  #: T(e^{j2πf ts}), r to y (complex) [m/m]
    loop: ComplexArray  #: L(e^{j2πf ts}) (complex) [-]
    margins: Margins  #: margins, crossovers, bandwidth, peak
    model: LoopModel  #: the linear loop

    @property
    def magnitude_db(self) -> FloatArray:
        """|T| [dB]."""
        out: FloatArray = 20.0 * np.log10(np.abs(self.closed_loop))
        return out

    @property
    def phase_deg(self) -> FloatArray:
        """∠T, unwrapped from the lowest frequency [deg]."""
        out: FloatArray = np.degrees(np.unwrap(np.angle(self.closed_loop)))
        return out


def closed_loop_bode(controller: PackedController, plant: LinearPlant,
                     frequencies: ArrayLike, *, delay: float = DEFAULT_DELAY) -> BodeResult:
    """The closed loop's frequency response and margins, analytic on a linear plant.

    Parameters
    ----------
    controller : PackedController
        Any registered controller (``fuzzyservo.registry.build_controller``); its ``dt`` is the
        sample time [s].
    plant : LinearPlant
        The linear (eq. 8) or small-signal model (``fuzzyservo.registry.build_plant``); the
        loop is linearised at its rest.
    frequencies : array_like
        Frequencies [Hz], in (0, Nyquist].
    delay : float
        Transport delay on the command [s], as :func:`fuzzyservo.sim.simulate` takes it.

    Returns
    -------
    BodeResult

    Raises
    ------
    ParameterError
        A controller or plant of the wrong kind, a bad delay, a law with no rest.
    InputError
        Frequencies not in (0, Nyquist].
    """
    model = loop_model(controller, plant, delay=delay)
    f = _frequencies(frequencies, model.ts, inclusive=True)
    return BodeResult(frequency=f, closed_loop=model.closed_loop_response(f),
                      loop=model.loop_transfer().response(f), margins=margins(model),
                      model=model)


def _frequencies(frequencies: ArrayLike, ts: float, *, inclusive: bool) -> FloatArray:
    try:
        f = np.asarray(frequencies, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"frequencies must be numbers [Hz], got {frequencies!r}") from None
    fn = 0.5 / ts
    ok = np.isfinite(f) & (f > 0.0) & ((f <= fn) if inclusive else (f < fn))
    if f.size == 0 or not np.all(ok):
        bad = f[~ok][0] if f.size else "none"
        raise InputError(f"frequencies must be > 0 and {'at most' if inclusive else 'below'} "
                         f"the Nyquist frequency {fn:g} Hz (ts = {ts:g} s), got {bad!r}")
    return f


# --- the measured response -------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class MeasuredResponse:
    """The closed loop's response to sines, measured by simulation (:func:`measured_response`).

    Per frequency, y - y0 over the fitted window is fitted by least squares as
    offset + G sin(2πft + φ); the response is G/amplitude at phase φ.
    """

    frequency: FloatArray  #: drive frequencies [Hz]
    amplitude: float  #: drive amplitude [m]
    gain: FloatArray  #: G / amplitude [-]
    phase_deg: FloatArray  #: φ [deg], in (-360, 0] when unwrapped from the lowest frequency
    offset: FloatArray  #: fitted offset of y from y0 [m]
    distortion: FloatArray  #: RMS of the fit's residual over G/√2 [-]: harmonics, rounding
    settle: FloatArray  #: transient left out, whole periods [s]
    window: FloatArray  #: fitted window, whole periods [s]

    @property
    def response(self) -> ComplexArray:
        """G/amplitude e^{jφ} (complex) [-]."""
        return np.asarray(self.gain * np.exp(1j * np.radians(self.phase_deg)),
                          dtype=np.complex128)

    @property
    def magnitude_db(self) -> FloatArray:
        """Gain [dB]."""
        out: FloatArray = 20.0 * np.log10(self.gain)
        return out


def measured_response(controller: PackedController, plant: Plant, frequencies: ArrayLike, *,
                      amplitude: float, delay: float = DEFAULT_DELAY, cycles: int = 4,
                      settle: float | None = None, batch: int = 8,
                      progress: Callable[[float, float], None] | None = None
                      ) -> MeasuredResponse:
    """The closed loop's response to sines around its rest, measured by simulation.

    Each frequency is one run of the compiled closed loop (:func:`fuzzyservo.sim.simulate_batch`,
    the runs of ``batch`` frequencies at a time) from rest with r = y0 + A sin(2πf t_k): the
    whole periods that cover ``settle`` are left out, and y - y0 over the next ``cycles``
    periods is fitted by least squares with an offset, sin and cos at f. On a linear plant the
    result is the analytic T; on the nonlinear plant it depends on the amplitude (valve
    saturation and rate limits, friction, the transducer's rounding; docs/frequency.md).

    Parameters
    ----------
    controller : PackedController
        Any registered controller; its ``dt`` is the sample time [s].
    plant : LinearPlant or NonlinearPlant
        Any plant of the registry, at rest at its start position.
    frequencies : array_like
        Drive frequencies [Hz], below the Nyquist frequency.
    amplitude : float
        Drive amplitude [m], > 0; the sine must stay within the stroke.
    delay : float
        Transport delay on the command [s].
    cycles : int
        Whole periods fitted, >= 1.
    settle : float, optional
        Transient left out [s] (rounded up to whole periods, at least one). Default: on a
        linear plant :func:`settle_time` of its loop, on others :data:`DEFAULT_SETTLE` (the
        command line passes the small-signal loop's :func:`settle_time`).
    batch : int
        Runs simulated together, >= 1.
    progress : callable, optional
        ``progress(done, total)``: simulated seconds of the runs done and of all of them [s],
        after each batch.

    Returns
    -------
    MeasuredResponse

    Raises
    ------
    ParameterError
        Wrong controller or plant, bad amplitude, delay, cycles, settle, batch.
    InputError
        Frequencies not below Nyquist; a sine leaving the stroke or finer than the
        transducer's resolution.
    SimulationDivergedError
        A run diverged (the message names its frequency).
    """
    check_run_arguments(controller, plant, None)
    amplitude = real(amplitude, "amplitude", "m", positive=True)
    delay = real(delay, "delay", "s", nonnegative=True)
    if not (isinstance(cycles, int) and not isinstance(cycles, bool) and cycles >= 1):
        raise ParameterError(f"cycles must be a whole number >= 1, got {cycles!r}")
    if not (isinstance(batch, int) and not isinstance(batch, bool) and batch >= 1):
        raise ParameterError(f"batch must be a whole number >= 1, got {batch!r}")
    ts = float(controller.dt)
    f = _frequencies(frequencies, ts, inclusive=False)
    if settle is None:
        if isinstance(plant, LinearPlant):
            settle = settle_time(loop_model(controller, plant, delay=delay))
        else:
            settle = DEFAULT_SETTLE
    settle = real(settle, "settle", "s", nonnegative=True)
    y0 = plant.y0
    stroke, resolution = plant_limits(plant)
    check_reference_samples(np.array([y0 - amplitude, y0 + amplitude]), np.zeros(2),
                            start=y0, stroke=stroke, resolution=resolution)
    skip: FloatArray = np.maximum(1.0, np.ceil(settle * f - 1e-9))
    ends = (skip + cycles) / f
    order = np.argsort(ends, kind="stable")
    gain = np.empty(f.size)
    phase = np.empty(f.size)
    offset = np.empty(f.size)
    distortion = np.empty(f.size)
    total = float(np.sum(ends))
    done = 0.0
    for lo in range(0, f.size, batch):
        idx = order[lo:lo + batch]
        duration = float(ends[idx].max()) + ts
        n_t = int(math.floor(duration / ts + 1e-9)) + 1
        t = np.arange(n_t) * ts
        rows = np.array([[amplitude * math.sin(2.0 * math.pi * f[i] * tk) for tk in t]
                         for i in idx])
        # the sines' exact rates, as a Sine reference gives them (laws with feed-forward)
        om = 2.0 * math.pi * f[idx]
        cos = np.array([[math.cos(w * tk) for tk in t] for w in om])
        rd = amplitude * om[:, None] * cos
        rdd = -(om[:, None] ** 2) * rows
        res = simulate_batch(controller, plant=plant, reference=rows, duration=duration,
                             delay=delay, keep_traces=True, rates=(rd, rdd))
        assert res.y is not None
        for row, i in enumerate(idx):
            if res.diverged[row]:
                raise SimulationDivergedError(
                    f"the closed loop diverged driven at {f[i]:g} Hz, amplitude "
                    f"{amplitude:g} m")
            t0, t1 = skip[i] / f[i], ends[i]
            sel = (t >= t0 - 1e-9 * ts) & (t < t1 - 1e-9 * ts)
            gain[i], phase[i], offset[i], distortion[i] = _fit(
                t[sel], res.y[row, sel] - y0, f[i], amplitude)
        done += float(np.sum(ends[idx]))
        if progress is not None:
            progress(done, total)
    # phases unwrapped from the lowest frequency, starting in (-360, 0]
    by_f = np.argsort(f, kind="stable")
    ph = np.unwrap(np.radians(phase[by_f]))
    ph -= 2.0 * np.pi * np.ceil(ph[0] / (2.0 * np.pi) - 1e-12)
    phase[by_f] = np.degrees(ph)
    return MeasuredResponse(frequency=f, amplitude=amplitude, gain=gain, phase_deg=phase,
                            offset=offset, distortion=distortion, settle=skip / f,
                            window=cycles / f)


def spectral_radius(model: LoopModel) -> float:
    """Largest |pole| of the closed loop [-] (its transient decays as that power of k)."""
    poles = model.closed_loop().poles()
    return float(np.max(np.abs(poles))) if poles.size else 0.0


def settle_time(model: LoopModel) -> float:
    """How long the linear loop's transient lasts [s]: 14 time constants of its slowest pole
    (a decay to 1e-6), at most :data:`MAX_SETTLE` (also for a loop that is not stable)."""
    rho = spectral_radius(model)
    if rho == 0.0:
        return 0.0
    if rho >= 1.0:
        return MAX_SETTLE
    return min(14.0 * model.ts / -math.log(rho), MAX_SETTLE)


def _fit(t: FloatArray, y: FloatArray, f: float, amplitude: float
         ) -> tuple[float, float, float, float]:
    """Least-squares offset + a sin + b cos at ``f`` [Hz]: (G/amplitude, phase [deg], offset
    [m], residual RMS / (G/√2)); summed exactly (:func:`~fuzzyservo.analysis.tracking.
    harmonic_fit`), so the same bits on every machine."""
    c, mean = harmonic_fit(t, y, f)
    w = 2.0 * math.pi * f
    g = abs(c)
    fitted = np.array([c.real * math.sin(w * tk) + c.imag * math.cos(w * tk) + mean
                       for tk in np.asarray(t).tolist()])
    resid = y - fitted
    rms = math.sqrt(math.fsum((resid * resid).tolist()) / max(resid.size, 1))
    dist = rms / (g / math.sqrt(2.0)) if g > 0.0 else math.inf
    return g / amplitude, math.degrees(math.atan2(c.imag, c.real)), float(mean), dist
