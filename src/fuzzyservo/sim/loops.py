"""The compiled closed loops, written once and compiled per control law.

Timing and plants as in :mod:`fuzzyservo.sim.closed_loop`. Each plant has one top-level
kernel, :func:`linear_chunk` / :func:`nonlinear_chunk`, which runs the runs ``lo:hi`` of a
batch: one run with its states kept (``simulate``), or many with traces or only their step
metrics (``simulate_batch``, one chunk per thread). The kernels are templates: the law's step
(``LAW_STEP``), its preparation of the tables (``LAW_PREPARE``) and the state field recorded as
α (``LAW_TRACE``) are globals that :meth:`fuzzyservo.control.law.Law.kernels` binds to one law
(:func:`kernels`), so each law compiles its own loops, with its step inlined by LLVM, and a
new law costs the others nothing.

Arguments come as records (named tuples): the controller rows (:class:`LawRows`), the plants
(:class:`LinearRows`, :class:`NonlinearRows`), the signals (:class:`Signals`) and what is
written (:class:`Outputs`).

On the linear plant a chunk advances its runs two at a time, sample by sample
(:func:`linear_two`: the same functions as :func:`linear_one`, each run on its own arrays, in
the same order), so the processor overlaps one run's long chains of divisions and sums with
the other's work; the two give the same bits (tests/sim/test_bit_identity.py).
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from typing import Any, NamedTuple

import numba
import numpy as np

from .._jit import data_pointer, kernel, template
from .._typing import FloatArray, IntArray
from ..plant.nonlinear import P_FEXT, P_RES, STATE_NAMES, rk4_steps
from .stepinfo import N_TAIL, TAIL_WORK, step_metrics_core, tail_oscillation_work

__all__ = [
    "LawRows",
    "LinearRows",
    "NonlinearRows",
    "Outputs",
    "Signals",
    "kernels",
    "linear_advance",
    "linear_output",
    "ring_size",
    "run_chunks",
    "substep_split",
]

_S_X = STATE_NAMES.index("x")


class LawRows(NamedTuple):
    """The controller side of a batch."""

    p: FloatArray  #: packed parameters (runs, len(law.params))
    s: FloatArray  #: states at rest (runs, len(law.state))
    tables: Any  #: the controller's tables (a tuple of arrays)


class LinearRows(NamedTuple):
    """Linear plants, one per run."""

    lp: FloatArray  #: packed discretisations (runs, width): ``LinearPlant.discretize``
    y0: FloatArray  #: outputs at rest (runs,) [m]
    u0: FloatArray  #: commands holding the operating points (runs,) [-]
    x_op: FloatArray  #: operating point of the run whose states are kept (n,) [SI]


class NonlinearRows(NamedTuple):
    """Nonlinear plants, one per run."""

    p: FloatArray  #: packed parameters (runs, N_PARAMS) [SI]
    x0: FloatArray  #: initial states (runs, N_STATE) [SI]
    y0: FloatArray  #: outputs at rest (runs,) [m]
    u0: FloatArray  #: trim commands (runs,) [-]
    d: IntArray  #: whole samples of delay (runs,)
    f: FloatArray  #: fractional delay (runs,) [s]
    n_sub: IntArray  #: RK4 substeps per sample (runs,)
    ts: float  #: sample time [s]
    force: FloatArray  #: external force per sample (n_t,) or empty [N]


class Signals(NamedTuple):
    """What every run is driven by."""

    t: FloatArray  #: sample times (n_t,) [s]
    r: FloatArray  #: reference offsets from each start position (1 or runs, n_t) [m]
    rd: FloatArray  #: reference velocity ṙ (1 or runs, n_t) [m/s]
    rdd: FloatArray  #: reference acceleration r̈ (1 or runs, n_t) [m/s²]
    noise: FloatArray  #: measurement noise (1 or runs, n_t) or (0, 0) [m]
    shift: bool  #: True: ``r`` is offset from each run's start y0; False: as it is


class Outputs(NamedTuple):
    """What the kernels write (arrays of zero rows are not written)."""

    y: FloatArray  #: measurements (runs, n_t) or (0, n_t) [m]
    u: FloatArray  #: commands (runs, n_t) or (0, n_t) [-]
    alpha: FloatArray  #: the law's traced state (runs, n_t) or (0, n_t) [-]
    x: FloatArray  #: states of a single run, absolute (n_t, n) or (0, n) [SI]
    x_end: FloatArray  #: state at the end of a single run (n,) or (0,) [SI]
    mopts: FloatArray  #: metric options (:func:`~fuzzyservo.sim.stepinfo.metric_options`)
    metrics: FloatArray  #: step metrics (runs, N_METRICS) or (0, N_METRICS)
    tail_fraction: float  #: fraction of the run the tail oscillation is measured over
    tail: FloatArray  #: tail oscillation (runs, N_TAIL) or (0, N_TAIL)
    bad: IntArray  #: first non-finite sample of each run, or -1 (runs,)


@kernel
def ring_size(d: int, n: int) -> int:
    """Length of the command ring buffer for a delay of ``d`` whole samples in a run of ``n``
    samples: d + 2, but never more than the run needs (a command delayed past the end of the
    run never reaches the plant)."""
    return min(d, n) + 2


@kernel(inline=True)
def _delayed(ubuf: Any, w: int, k: int, d: int, n: int, u_init: float) -> tuple[float, float]:
    """Commands u_{k-d} and u_{k-d-1} from the ring buffer (pointer ``ubuf`` of ``n`` slots)
    whose slot ``w`` holds u_k (``u_init`` before t_0); no integer division in the loop. The
    ring holds d + 2 commands (the loops cap d at the run length, :func:`ring_size`)."""
    j0 = w - d
    if j0 < 0:
        j0 += n
    j1 = j0 - 1
    if j1 < 0:
        j1 += n
    u0 = ubuf[j0] if k - d >= 0 else u_init
    u1 = ubuf[j1] if k - d - 1 >= 0 else u_init
    return u0, u1


@kernel(inline=True, error_model="numpy")
def _output_n(lp: Any, x: Any, y0: float, n: int) -> float:
    """y0 + C x of a packed linear plant (pointers ``lp``, ``x``), summed in index order."""
    o_c = 2 + n * n + 2 * n
    y = y0
    for i in range(n):
        y += lp[o_c + i] * x[i]
    return y


@kernel(inline=True, error_model="numpy")
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


@kernel(inline=True, error_model="numpy")
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


@kernel(inline=True, error_model="numpy")
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


@kernel
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


@kernel
def _finish_run(i: int, bad: int, t: FloatArray, yv: FloatArray, uv: FloatArray,
                av: FloatArray, rbuf: FloatArray, out: Outputs, tbuf: FloatArray,
                twork: FloatArray) -> None:
    """Run i's metrics and tail when they are measured (NaN, and NaN traces from sample
    ``bad`` on, if it diverged)."""
    n_t = t.shape[0]
    if bad >= 0:
        for k in range(bad, n_t):
            yv[k] = np.nan
            uv[k] = np.nan
            av[k] = np.nan
    if out.metrics.shape[0] == 0:
        return
    if bad >= 0:
        for m in range(out.metrics.shape[1]):
            out.metrics[i, m] = np.nan
        for m in range(N_TAIL):
            out.tail[i, m] = np.nan
    else:
        mo = out.mopts
        step_metrics_core(t, yv, uv, rbuf, yv[0], rbuf[n_t - 1], mo[0], mo[1], mo[2], mo[3],
                          out.metrics[i])
        tail_oscillation_work(t, yv, out.tail_fraction, tbuf, twork)
        for m in range(N_TAIL):
            out.tail[i, m] = tbuf[m]


# ---------------------------------------------------------------------------------------------
# the templates: globals bound per law by kernels()

LAW_STEP: Any = None
LAW_PREPARE: Any = None
LAW_TRACE: int = -1


@template(inline=True, error_model="numpy")
def linear_one(pp: Any, sp: Any, aux: Any, lp: Any, n: int, d: int, u_op: float, x_op: Any,
               r: Any, rd: Any, rdd: Any, noise: Any, has_noise: bool, y0: float, x: Any,
               xn: Any, ubuf: Any, n_ring: int, y_out: Any, u_out: Any, a_out: Any,
               x_out: FloatArray, n_t: int) -> int:
    """One closed loop on a packed linear plant (pointer ``lp``; see
    ``LinearPlant.discretize``), all arrays as data pointers but the kept states ``x_out``.

    The plant propagates the deviation ``x`` from its operating point (start value, updated
    in place) under the input u - ``u_op``; y = ``y0`` + C x; commands before t_0 are
    ``u_op``; rows of ``x_out`` are the absolute states ``x_op`` + x (not written when it has
    no rows). ``sp`` (the law's state) is updated in place; ``ubuf`` is a ring of ``n_ring``
    commands. The plant is not advanced past the last sample. Returns the index of the first
    sample with a non-finite state, or -1.
    """
    keep_x = x_out.shape[0] > 0
    last = n_t - 1
    w = 0
    for k in range(n_t):
        y = linear_output(lp, x, y0, n)
        if keep_x:
            for i in range(n):
                x_out[k, i] = x_op[i] + x[i]
        if not math.isfinite(y):
            return k
        if has_noise:
            y += noise[k]
        u = LAW_STEP(pp, sp, r[k], y, aux, rd[k], rdd[k])
        y_out[k] = y
        u_out[k] = u
        a_out[k] = sp[LAW_TRACE] if LAW_TRACE >= 0 else np.nan
        if k == last:
            break
        ubuf[w] = u
        u0, u1 = _delayed(ubuf, w, k, d, n_ring, u_op)
        w += 1
        if w == n_ring:
            w = 0
        linear_advance(lp, x, xn, u0 - u_op, u1 - u_op, n)
    return -1


@template(inline=True, error_model="numpy")
def linear_two(pa: Any, sa: Any, pb: Any, sb: Any, aux: Any, la: Any, lb: Any, n_a: int,
               n_b: int, d_a: int, d_b: int, u_op_a: float, u_op_b: float, r_a: Any, r_b: Any,
               rd_a: Any, rdd_a: Any, rd_b: Any, rdd_b: Any,
               noise_a: Any, noise_b: Any, noisy_a: bool, noisy_b: bool, y0_a: float,
               y0_b: float, xa: Any, xna: Any, xb: Any, xnb: Any, ubuf_a: Any, ubuf_b: Any,
               n_ring: int, y_a: Any, u_a: Any, al_a: Any, y_b: Any, u_b: Any, al_b: Any,
               n_t: int) -> tuple[int, int]:
    """Two runs of :func:`linear_one` (no states kept) in one loop, sample by sample.

    Each run is exactly its :func:`linear_one` (the same functions on its own arrays, in the
    same order); they only share the loop. Returns each run's first non-finite sample or -1;
    a run that diverged is no longer advanced (its outputs from that sample on are not
    written).
    """
    last = n_t - 1
    bad_a = -1
    bad_b = -1
    w_a = 0
    w_b = 0
    for k in range(n_t):
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
            ua = LAW_STEP(pa, sa, r_a[k], ya, aux, rd_a[k], rdd_a[k])
            y_a[k] = ya
            u_a[k] = ua
            al_a[k] = sa[LAW_TRACE] if LAW_TRACE >= 0 else np.nan
        if live_b:
            ub = LAW_STEP(pb, sb, r_b[k], yb, aux, rd_b[k], rdd_b[k])
            y_b[k] = yb
            u_b[k] = ub
            al_b[k] = sb[LAW_TRACE] if LAW_TRACE >= 0 else np.nan
        if k == last:
            break
        if live_a:
            ubuf_a[w_a] = ua
            a0, a1 = _delayed(ubuf_a, w_a, k, d_a, n_ring, u_op_a)
            w_a += 1
            if w_a == n_ring:
                w_a = 0
            linear_advance(la, xa, xna, a0 - u_op_a, a1 - u_op_a, n_a)
        if live_b:
            ubuf_b[w_b] = ub
            b0, b1 = _delayed(ubuf_b, w_b, k, d_b, n_ring, u_op_b)
            w_b += 1
            if w_b == n_ring:
                w_b = 0
            linear_advance(lb, xb, xnb, b0 - u_op_b, b1 - u_op_b, n_b)
    return bad_a, bad_b


@template(error_model="numpy", about="the closed loop on the linear plant", seconds=8.0)
def linear_chunk(lo: int, hi: int, law: LawRows, plant: LinearRows, sig: Signals,
                 out: Outputs) -> None:
    """Runs ``lo:hi`` on linear plants: two at a time (:func:`linear_two`) unless a run's
    states are kept, then one (:func:`linear_one`); traces, metrics and the tail as
    :class:`Outputs` asks."""
    n_t = sig.t.shape[0]
    nx_max = 0
    d_max = 0
    for i in range(lo, hi):
        nx_max = max(nx_max, int(plant.lp[i, 0]))
        d_max = max(d_max, int(plant.lp[i, 1]))
    n_ring = ring_size(d_max, n_t)
    keep = out.y.shape[0] > 0
    keep_x = out.x.shape[0] > 0
    ybuf = np.empty((2, n_t))
    ubuf_tr = np.empty((2, n_t))
    abuf = np.empty((2, n_t))
    rbuf = np.empty((2, n_t))
    x = np.empty((2, max(nx_max, 1)))
    xn = np.empty((2, max(nx_max, 1)))
    ring = np.empty((2, n_ring))
    cs = np.empty((2, max(law.s.shape[1], 1)))
    no_noise = np.zeros(1)
    tbuf = np.empty(N_TAIL + 1)
    twork = np.empty((TAIL_WORK, 3))
    aux = LAW_PREPARE(law.tables)
    n_nz = sig.noise.shape[0]
    n_r = sig.r.shape[0]
    n_rd = sig.rd.shape[0]
    i = lo
    while i < hi:
        m = 1 if keep_x else min(2, hi - i)  # runs in this step: a pair, or one
        for b in range(m):
            for j in range(nx_max):
                x[b, j] = 0.0
            for j in range(law.s.shape[1]):
                cs[b, j] = law.s[i + b, j]
            rrow = sig.r[min(i + b, n_r - 1)]
            y0 = plant.y0[i + b]
            for k in range(n_t):
                rbuf[b, k] = rrow[k] + y0 if sig.shift else rrow[k]
        ya = out.y[i] if keep else ybuf[0]
        ua = out.u[i] if keep else ubuf_tr[0]
        aa = out.alpha[i] if keep else abuf[0]
        nza = data_pointer(sig.noise[min(i, n_nz - 1)]) if n_nz > 0 else data_pointer(no_noise)
        na = int(plant.lp[i, 0])
        da = min(int(plant.lp[i, 1]), n_t)
        if m == 2:
            yb = out.y[i + 1] if keep else ybuf[1]
            ub = out.u[i + 1] if keep else ubuf_tr[1]
            ab = out.alpha[i + 1] if keep else abuf[1]
            nzb = (data_pointer(sig.noise[min(i + 1, n_nz - 1)]) if n_nz > 0
                   else data_pointer(no_noise))
            nb = int(plant.lp[i + 1, 0])
            db = min(int(plant.lp[i + 1, 1]), n_t)
            bad_a, bad_b = linear_two(
                data_pointer(law.p[i]), data_pointer(cs[0]), data_pointer(law.p[i + 1]),
                data_pointer(cs[1]), aux, data_pointer(plant.lp[i]),
                data_pointer(plant.lp[i + 1]), na, nb, da, db, plant.u0[i], plant.u0[i + 1],
                data_pointer(rbuf[0]), data_pointer(rbuf[1]),
                data_pointer(sig.rd[min(i, n_rd - 1)]), data_pointer(sig.rdd[min(i, n_rd - 1)]),
                data_pointer(sig.rd[min(i + 1, n_rd - 1)]),
                data_pointer(sig.rdd[min(i + 1, n_rd - 1)]), nza, nzb, n_nz > 0, n_nz > 0,
                plant.y0[i], plant.y0[i + 1], data_pointer(x[0]), data_pointer(xn[0]),
                data_pointer(x[1]), data_pointer(xn[1]), data_pointer(ring[0]),
                data_pointer(ring[1]), n_ring, data_pointer(ya), data_pointer(ua),
                data_pointer(aa), data_pointer(yb), data_pointer(ub), data_pointer(ab), n_t)
            out.bad[i] = bad_a
            out.bad[i + 1] = bad_b
            _finish_run(i + 1, bad_b, sig.t, yb, ub, ab, rbuf[1], out, tbuf, twork)
        else:
            out.bad[i] = linear_one(
                data_pointer(law.p[i]), data_pointer(cs[0]), aux, data_pointer(plant.lp[i]),
                na, da, plant.u0[i], data_pointer(plant.x_op), data_pointer(rbuf[0]),
                data_pointer(sig.rd[min(i, n_rd - 1)]), data_pointer(sig.rdd[min(i, n_rd - 1)]),
                nza,
                n_nz > 0, plant.y0[i], data_pointer(x[0]), data_pointer(xn[0]),
                data_pointer(ring[0]), n_ring, data_pointer(ya), data_pointer(ua),
                data_pointer(aa), out.x, n_t)
            if out.x_end.shape[0] > 0:
                for j in range(na):
                    out.x_end[j] = plant.x_op[j] + x[0, j]
        _finish_run(i, out.bad[i], sig.t, ya, ua, aa, rbuf[0], out, tbuf, twork)
        i += m


@template(inline=True, error_model="numpy")
def nonlinear_one(pp: Any, sp: Any, aux: Any, p: FloatArray, ts: float, d: int, f: float,
                  n_sub: int, u_init: float, r: Any, rd: Any, rdd: Any, noise: Any,
                  has_noise: bool,
                  force: FloatArray, x: FloatArray, work: FloatArray, ubuf: Any, n_ring: int,
                  y_out: Any, u_out: Any, a_out: Any, x_out: FloatArray, n_t: int) -> int:
    """One closed loop on the nonlinear plant with packed parameters ``p`` (a private copy:
    its external-force entry follows ``force`` when that is not empty).

    Delay τ = d ts + f; ``n_sub`` RK4 substeps per sample (split in proportion at f);
    ``work`` is a (5, N_STATE) scratch array. Other arguments as :func:`linear_one`; the
    plant's :func:`~fuzzyservo.plant.nonlinear.rk4_steps` gets data pointers.
    Returns the index of the first sample whose state is non-finite, or -1.
    """
    keep_x = x_out.shape[0] > 0
    has_force = force.shape[0] > 0
    res = p[P_RES]
    n1, n0 = substep_split(n_sub, f, ts)
    nx = x.shape[0]
    last = n_t - 1
    xp = data_pointer(x)
    plp = data_pointer(p)
    k1 = data_pointer(work[0])
    k2 = data_pointer(work[1])
    k3 = data_pointer(work[2])
    k4 = data_pointer(work[3])
    xt = data_pointer(work[4])
    w = 0
    for k in range(n_t):
        t = k * ts
        if keep_x:
            for i in range(nx):
                x_out[k, i] = x[i]
        y = x[_S_X]
        if has_noise:
            y += noise[k]
        if res > 0.0:
            y = res * math.floor(y / res + 0.5)
        u = LAW_STEP(pp, sp, r[k], y, aux, rd[k], rdd[k])
        y_out[k] = y
        u_out[k] = u
        a_out[k] = sp[LAW_TRACE] if LAW_TRACE >= 0 else np.nan
        if k == last:
            break
        ubuf[w] = u
        u0, u1 = _delayed(ubuf, w, k, d, n_ring, u_init)
        w += 1
        if w == n_ring:
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


@template(error_model="numpy", about="the closed loop on the nonlinear plant", seconds=8.0)
def nonlinear_chunk(lo: int, hi: int, law: LawRows, plant: NonlinearRows, sig: Signals,
                    out: Outputs) -> None:
    """Runs ``lo:hi`` on nonlinear plants, one after the other (:func:`nonlinear_one`)."""
    n_t = sig.t.shape[0]
    nx = plant.x0.shape[1]
    d_max = 0
    for i in range(lo, hi):
        d_max = max(d_max, plant.d[i])
    n_ring = ring_size(d_max, n_t)
    keep = out.y.shape[0] > 0
    ybuf = np.empty(n_t)
    ubuf_tr = np.empty(n_t)
    abuf = np.empty(n_t)
    rbuf = np.empty(n_t)
    x = np.empty(nx)
    p = np.empty(plant.p.shape[1])
    work = np.empty((5, nx))
    ring = np.empty(n_ring)
    cs = np.empty(max(law.s.shape[1], 1))
    no_noise = np.zeros(1)
    tbuf = np.empty(N_TAIL + 1)
    twork = np.empty((TAIL_WORK, 3))
    aux = LAW_PREPARE(law.tables)
    n_nz = sig.noise.shape[0]
    n_r = sig.r.shape[0]
    n_rd = sig.rd.shape[0]
    for i in range(lo, hi):
        for j in range(nx):
            x[j] = plant.x0[i, j]
        for j in range(p.shape[0]):
            p[j] = plant.p[i, j]
        for j in range(law.s.shape[1]):
            cs[j] = law.s[i, j]
        rrow = sig.r[min(i, n_r - 1)]
        y0 = plant.y0[i]
        for k in range(n_t):
            rbuf[k] = rrow[k] + y0 if sig.shift else rrow[k]
        yv = out.y[i] if keep else ybuf
        uv = out.u[i] if keep else ubuf_tr
        av = out.alpha[i] if keep else abuf
        nz = data_pointer(sig.noise[min(i, n_nz - 1)]) if n_nz > 0 else data_pointer(no_noise)
        d = min(plant.d[i], n_t)  # a command delayed past the run never arrives
        out.bad[i] = nonlinear_one(
            data_pointer(law.p[i]), data_pointer(cs), aux, p, plant.ts, d, plant.f[i],
            plant.n_sub[i], plant.u0[i], data_pointer(rbuf),
            data_pointer(sig.rd[min(i, n_rd - 1)]), data_pointer(sig.rdd[min(i, n_rd - 1)]), nz,
            n_nz > 0, plant.force, x,
            work, data_pointer(ring), n_ring, data_pointer(yv), data_pointer(uv),
            data_pointer(av), out.x, n_t)
        if out.x_end.shape[0] > 0:
            for j in range(nx):
                out.x_end[j] = x[j]
        _finish_run(i, out.bad[i], sig.t, yv, uv, av, rbuf, out, tbuf, twork)


_TEMPLATES = (linear_one, linear_two, linear_chunk, nonlinear_one, nonlinear_chunk)


def kernels(law: Any) -> Any:
    """The loops compiled for ``law`` (a :class:`~fuzzyservo.control.law.Law`), made once per
    process: ``linear_chunk`` and ``nonlinear_chunk``."""
    return law.kernels("loops", _TEMPLATES)


def run_chunks(fn: Any, n: int, *args: Any) -> None:
    """``fn(lo, hi, *args)`` over ``n`` runs: in this thread for one chunk, else in
    ``4 x numba.get_num_threads()`` chunks on that many threads (the kernels release the
    GIL). The chunks' boundaries do not change any run's bits."""
    threads = max(1, int(numba.get_num_threads()))
    n_chunks = max(1, min(n, 4 * threads))
    if threads == 1 or n_chunks == 1:
        fn(0, n, *args)
        return
    bounds = [(c * n // n_chunks, (c + 1) * n // n_chunks) for c in range(n_chunks)]
    with ThreadPoolExecutor(max_workers=min(threads, n_chunks)) as pool:
        for fut in [pool.submit(fn, lo, hi, *args) for lo, hi in bounds]:
            fut.result()
