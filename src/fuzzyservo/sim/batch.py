"""Batched closed-loop simulation: many runs differing in gains and plant parameters, compiled
and parallel across cores (numba ``prange``), with per-run step metrics.

This is what tuning (a differential-evolution population per call) and robustness sweeps call.
Each run is exactly :func:`fuzzyservo.sim.closed_loop.simulate` (the same compiled single-run
loops and the same controller and plant functions); traces are kept only on request, and the
metrics (``fuzzyservo.sim.stepinfo.METRIC_NAMES``) and the tail oscillation
(``TAIL_NAMES``) are computed inside the kernel on per-chunk buffers that are reused from run
to run. Runs may differ in gains, plant, delay, reference (one row per run) and measurement
noise (explicit rows, e.g. one seeded generator per run, or drawn from one ``rng``).

Example (``ctl`` a controller, ``gains`` one row per run, ``plant`` a LinearPlant)::

    res = simulate_batch(ctl, gains, plant=plant, reference=Step(0.1), duration=5.0)
    res.metric("overshoot")            # one value per row of gains
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..control.base import PackedController
from ..errors import InputError, ParameterError
from ..plant.zoh import split_delay
from .closed_loop import (
    DEFAULT_DELAY,
    LinearPlant,
    NonlinearPlant,
    Plant,
    check_delay,
    profile,
    time_grid,
)
from .closed_loop import (
    _noise as make_noise,
)
from .loops import LawRows, LinearRows, NonlinearRows, Outputs, Signals, kernels, run_chunks
from .references import Reference, reference_rates, sample_reference
from .result import BatchResult
from .stepinfo import METRIC_NAMES, N_METRICS, N_TAIL, TAIL_NAMES, metric_options

__all__ = ["simulate_batch"]


def _reference_rows(reference: Reference | ArrayLike, t: FloatArray) -> FloatArray:
    """The reference offsets as rows (1 or runs, len(t)) [m]."""
    if not hasattr(reference, "values"):
        arr = np.asarray(reference, dtype=np.float64)
        if arr.ndim == 2:
            if arr.shape[1] != t.size or arr.shape[0] == 0:
                raise InputError(
                    f"a reference per run needs shape (runs, {t.size}), got {arr.shape}")
            bad = ~np.isfinite(arr)
            if np.any(bad):
                i, k = np.argwhere(bad)[0]
                raise InputError(
                    f"reference must be finite, got {arr[i, k]!r} in row {i} at sample {k}")
            return np.ascontiguousarray(arr)
    return sample_reference(reference, t)[None, :]


def _noise_rows(noise: ArrayLike | None, noise_std: float, t: FloatArray) -> FloatArray | None:
    """Explicit measurement noise as rows (1 or runs, len(t)) [m], or None."""
    if noise is None:
        return None
    if not (math.isfinite(noise_std) and noise_std >= 0.0):
        raise ParameterError(f"noise_std must be finite and >= 0 m, got {noise_std!r}")
    if noise_std > 0.0:
        raise ParameterError(
            f"give measurement noise either as noise (explicit samples) or as noise_std "
            f"(drawn from rng), not both; got noise and noise_std = {noise_std!r}")
    arr = np.asarray(noise, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != t.size or arr.shape[0] == 0:
        raise InputError(f"noise needs shape (runs, {t.size}) or ({t.size},), got "
                         f"{np.shape(noise)}")
    bad = ~np.isfinite(arr)
    if np.any(bad):
        i, k = np.argwhere(bad)[0]
        raise InputError(f"noise must be finite, got {arr[i, k]!r} in row {i} at sample {k}")
    return np.ascontiguousarray(arr)


def _force_rows(disturbance: ArrayLike | None, t: FloatArray) -> FloatArray | None:
    """The total external force as rows (1 or runs, len(t)) [N], or None."""
    if disturbance is None:
        return None
    if callable(disturbance) or np.ndim(disturbance) != 2:
        return profile(disturbance, t, "disturbance")[None, :]
    arr = np.asarray(disturbance, dtype=np.float64)
    if arr.shape[1] != t.size or arr.shape[0] == 0:
        raise InputError(f"a disturbance per run needs shape (runs, {t.size}), got {arr.shape}")
    bad = ~np.isfinite(arr)
    if np.any(bad):
        i, k = np.argwhere(bad)[0]
        raise InputError(f"disturbance must be finite, got {arr[i, k]!r} in row {i} at "
                         f"sample {k}")
    return np.ascontiguousarray(arr)


def _runs(counts: dict[str, int]) -> int:
    """The number of runs: every count is 1 (repeated) or the same n."""
    sizes = {v for v in counts.values() if v != 1}
    if len(sizes) > 1:
        given = ", ".join(f"{v} {k}" for k, v in counts.items())
        raise ParameterError(f"simulate_batch: {given}; give equal counts or one")
    return sizes.pop() if sizes else 1


def simulate_batch(
    controller: PackedController,
    gains: ArrayLike | None = None,
    *,
    plant: Plant | Sequence[Plant],
    reference: Reference | ArrayLike,
    duration: float,
    delay: float | ArrayLike = DEFAULT_DELAY,
    disturbance: ArrayLike | None = None,
    noise_std: float = 0.0,
    rng: np.random.Generator | None = None,
    noise: ArrayLike | None = None,
    keep_traces: bool = False,
    rise: tuple[float, float] = (0.1, 0.9),
    settle_band: float = 0.02,
    settle_band_2: float = 0.05,
    tail_fraction: float = 0.25,
    rates: tuple[ArrayLike, ArrayLike] | None = None,
) -> BatchResult:
    """Run many closed loops in parallel and return their step metrics (and traces).

    Parameters
    ----------
    controller : PIDController, FuzzyPIController or SelfTuningFuzzyPIController
        Template: its ``dt`` (T_s [s]), limits, options and rule tables apply to every run.
    gains : array (runs, len(controller.gain_names)), optional
        One row of gains per run, columns ``controller.gain_names`` (``kp, ki, kd, n, b, c``
        or ``ke, kde, kdu``); None runs the template's own gains.
    plant : LinearPlant, NonlinearPlant, or a sequence of one of them
        One plant for all runs, or one per run (all of the same kind).
    reference : Reference or array
        Reference offset from each run's start position [m]: a reference object, one value
        per sample (n_samples,) shared by all runs, or one row per run (runs, n_samples).
    duration : float
        Simulated time per run [s].
    delay : float or array (runs,)
        Transport delay on the command [s], >= 0.
    disturbance : array or callable, optional
        Total external load force F_ext [N] per sample (> 0 opposes extension), held over
        each sample: (n_samples,) or a function of t shared by all runs, or one row per run
        (runs, n_samples). As :func:`~fuzzyservo.sim.simulate` takes it: the nonlinear
        plant in its force balance, a linear plant by superposition (its open-loop
        response to the force added to the measured output, through the noise row).
    noise_std : float
        Measurement noise standard deviation [m]; each run draws its own from ``rng``.
    rng : numpy.random.Generator, optional
        Noise source (required when ``noise_std > 0``).
    noise : array (runs, n_samples) or (n_samples,), optional
        Explicit measurement noise [m], added to the measured position as ``noise_std``'s
        draws are: one row per run, or one row shared by all. Not with ``noise_std > 0``.
        A row ``np.random.default_rng(seed).normal(0.0, std, size=n_samples)`` makes the run
        equal, bit for bit, to ``simulate(..., noise_std=std,
        rng=np.random.default_rng(seed))``.
    keep_traces : bool
        Keep y, u and α of every run (memory: 3 × runs × samples floats).
    rise : (float, float)
        Rise-time thresholds as fractions of the step [-].
    settle_band, settle_band_2 : float
        Settling bands as fractions of the step [-] (``settling_time``, ``settling_time_5``).
    tail_fraction : float
        Fraction of the run at its end over which ``BatchResult.tail`` measures the
        oscillation of y (:func:`~fuzzyservo.sim.stepinfo.tail_oscillation_core`), in (0, 1]
        [-].
    rates : (array, array), optional
        The reference's velocity [m/s] and acceleration [m/s²] per sample, each shaped like
        the reference rows, for laws with feed-forward; default: the reference's own
        (:func:`~fuzzyservo.sim.references.reference_rates`: closed form for a reference
        object, differences of samples).

    Returns
    -------
    BatchResult
        ``metrics`` (runs, len(METRIC_NAMES)), measured as ``SimResult.metrics()`` measures a
        single run (from the first measured sample y[0], noise and transducer rounding
        included, to the last reference sample), and ``tail`` (runs, len(TAIL_NAMES)); diverged
        runs are flagged in ``diverged`` with NaN metrics and tail rather than raised, so a
        search can penalise them.

    Raises
    ------
    ParameterError
        Bad gains, sample time, duration, delay, tail fraction or plant list; unequal run
        counts (gain rows, plants, delays, reference rows, noise rows); ``noise`` together
        with ``noise_std > 0``.
    InputError
        A non-finite reference, noise or disturbance, or one of the wrong shape.
    """
    ts = float(controller.dt)
    t = time_grid(duration, ts)
    roff = _reference_rows(reference, t)
    noise_rows = _noise_rows(noise, noise_std, t)
    if not (math.isfinite(tail_fraction) and 0.0 < tail_fraction <= 1.0):
        raise ParameterError(f"tail_fraction must be in (0, 1], got {tail_fraction!r}")
    g = (np.asarray(gains, dtype=np.float64) if gains is not None else None)
    if g is not None and g.ndim == 1:
        g = g[None, :]
    cps = controller.pack_gains(g) if g is not None else controller.pack()[None, :]
    plants = list(plant) if isinstance(plant, Sequence) else [plant]
    if not plants:
        raise ParameterError("need at least one plant")
    kinds = {type(p) for p in plants}
    if len(kinds) != 1:
        raise ParameterError("all plants of a batch must be of one kind (linear or nonlinear)")
    d_arr = np.asarray(delay, dtype=np.float64).reshape(-1)
    counts = {"gain rows": cps.shape[0], "plants": len(plants), "delays": d_arr.size,
              "reference rows": roff.shape[0]}
    if noise_rows is not None:
        counts["noise rows"] = noise_rows.shape[0]
    force_rows = _force_rows(disturbance, t)
    if force_rows is not None:
        counts["disturbance rows"] = force_rows.shape[0]
    n = _runs(counts)
    delays = np.broadcast_to(d_arr, (n,)).copy()
    for dv in delays:
        check_delay(float(dv))
    if cps.shape[0] == 1 and n > 1:
        cps = np.repeat(cps, n, axis=0)
    if len(plants) == 1 and n > 1:
        plants = plants * n
    y0s = np.array([p.y0 for p in plants], dtype=np.float64)
    u0s = np.array([p.u0 for p in plants], dtype=np.float64)
    cs0 = np.vstack([controller.rest_states(cps[i:i + 1], y0s[i], u0s[i]) for i in range(n)]) \
        if len(set(y0s.tolist())) > 1 or len(set(u0s.tolist())) > 1 \
        else controller.rest_states(cps, float(y0s[0]), float(u0s[0]))
    nz = make_noise(noise_std, rng, (n, t.size)) if noise_rows is None else noise_rows
    if nz.shape[0] == 0:
        nz = np.empty((0, 0))
    if force_rows is not None and force_rows.shape[0] > 1 and \
            isinstance(plants[0], NonlinearPlant):
        # the nonlinear loop takes one force row for all its runs: one batch per distinct
        # row, each run with the noise drawn above (the same bits as a batch of one)
        return _by_force(controller, g, plants, reference, roff, duration, delays, nz,
                         force_rows, keep_traces, rise, settle_band, settle_band_2,
                         tail_fraction, rates)
    if force_rows is not None and isinstance(plants[0], LinearPlant):
        nz = _with_force_response(nz, force_rows, plants, ts, n)
    keep = bool(keep_traces)
    shape = (n, t.size) if keep else (0, t.size)
    y_tr, u_tr, a_tr = np.empty(shape), np.empty(shape), np.empty(shape)
    metrics = np.empty((n, N_METRICS))
    tail = np.empty((n, N_TAIL))
    bad = np.empty(n, dtype=np.int64)
    mopts = np.array(metric_options(rise, settle_band, settle_band_2))
    law = LawRows(p=np.ascontiguousarray(cps), s=np.ascontiguousarray(cs0),
                  tables=tuple(controller.tables()))
    if rates is not None:
        rd, rdd = (np.ascontiguousarray(np.atleast_2d(np.asarray(v, dtype=np.float64)))
                   for v in rates)
        if rd.shape != roff.shape or rdd.shape != roff.shape or not (
                np.all(np.isfinite(rd)) and np.all(np.isfinite(rdd))):
            raise InputError(f"rates need two finite arrays shaped like the reference rows "
                             f"{roff.shape}, got {rd.shape} and {rdd.shape}")
    else:
        rd, rdd = reference_rates(reference if hasattr(reference, "values") else roff, t)
    sig = Signals(t=t, r=roff, rd=np.ascontiguousarray(np.atleast_2d(rd)),
                  rdd=np.ascontiguousarray(np.atleast_2d(rdd)), noise=nz, shift=True)
    out = Outputs(y=y_tr, u=u_tr, alpha=a_tr, x=np.empty((0, 1)), x_end=np.empty(0),
                  mopts=mopts, metrics=metrics, tail_fraction=float(tail_fraction),
                  tail=tail, bad=bad)
    loops = kernels(controller.law)
    if isinstance(plants[0], LinearPlant):
        rows = []
        cache: dict[tuple[int, float], FloatArray] = {}
        for p, dv in zip(plants, delays, strict=True):
            assert isinstance(p, LinearPlant)
            key = (id(p), float(dv))
            if key not in cache:
                cache[key] = p.discretize(ts, float(dv))
            rows.append(cache[key])
        width = max(r.size for r in rows)
        lps = np.zeros((n, width))
        for i, row in enumerate(rows):
            lps[i, :row.size] = row
        lin = LinearRows(lp=lps, y0=y0s, u0=u0s, x_op=np.zeros(1))
        run_chunks(loops.linear_chunk, n, law, lin, sig, out)
    else:
        nl = [p for p in plants if isinstance(p, NonlinearPlant)]
        force = force_rows[0] if force_rows is not None else np.empty(0)
        split = [split_delay(float(dv), ts) for dv in delays]
        rows_nl = NonlinearRows(
            p=np.vstack([p.packed for p in nl]), x0=np.vstack([p.x0 for p in nl]), y0=y0s,
            u0=u0s, d=np.array([s[0] for s in split], dtype=np.int64),
            f=np.array([s[1] for s in split], dtype=np.float64),
            n_sub=np.array([p.check_steps(ts, t.size) for p in nl], dtype=np.int64), ts=ts,
            force=force)
        run_chunks(loops.nonlinear_chunk, n, law, rows_nl, sig, out)
    return BatchResult(
        metrics=metrics, metric_names=METRIC_NAMES, diverged=bad >= 0, t=t,
        r=roff[0] if roff.shape[0] == 1 else roff, y0=y0s, tail=tail, tail_names=TAIL_NAMES,
        y=y_tr if keep else None, u=u_tr if keep else None, alpha=a_tr if keep else None)


def _with_force_response(nz: FloatArray, force_rows: FloatArray, plants: list[Plant],
                         ts: float, n: int) -> FloatArray:
    """The noise rows (runs, n_samples) with each run's open-loop response to its force
    added (:meth:`LinearPlant.force_response`; superposition), computed once per distinct
    plant and force row."""
    cache: dict[tuple[int, int], FloatArray] = {}
    out = np.empty((n, force_rows.shape[1]))
    for i, p in enumerate(plants):
        assert isinstance(p, LinearPlant)
        j = 0 if force_rows.shape[0] == 1 else i
        key = (id(p), j)
        if key not in cache:
            cache[key] = p.force_response(force_rows[j], ts)[0]
        y_f = cache[key]
        out[i] = y_f if nz.shape[0] == 0 else nz[min(i, nz.shape[0] - 1)] + y_f
    return out


def _by_force(controller: PackedController, g: FloatArray | None, plants: list[Plant],
              reference: Reference | ArrayLike, roff: FloatArray, duration: float,
              delays: FloatArray, nz: FloatArray, force_rows: FloatArray, keep: bool,
              rise: tuple[float, float], settle_band: float, settle_band_2: float,
              tail_fraction: float,
              rates: tuple[ArrayLike, ArrayLike] | None = None) -> BatchResult:
    """Runs with their own force rows on the nonlinear plant: one batch per distinct row,
    merged in run order."""
    n = len(plants)
    groups: dict[bytes, list[int]] = {}
    for i in range(n):
        groups.setdefault(force_rows[i].tobytes(), []).append(i)
    parts = []
    for idx in groups.values():
        sel = np.array(idx)
        ref = roff[sel] if roff.shape[0] > 1 else reference
        sub = None
        if rates is not None:
            r2 = [np.atleast_2d(np.asarray(v, dtype=np.float64)) for v in rates]
            sub = (r2[0][sel], r2[1][sel]) if roff.shape[0] > 1 else (r2[0], r2[1])
        gains = None if g is None else (g if g.shape[0] == 1 else g[sel])
        part = simulate_batch(
            controller, gains, plant=[plants[i] for i in idx], reference=ref,
            duration=duration, delay=delays[sel], disturbance=force_rows[idx[0]],
            noise=None if nz.shape[0] == 0 else nz[np.minimum(sel, nz.shape[0] - 1)],
            keep_traces=keep, rise=rise, settle_band=settle_band,
            settle_band_2=settle_band_2, tail_fraction=tail_fraction, rates=sub)
        parts.append((sel, part))
    first = parts[0][1]
    metrics = np.empty((n, first.metrics.shape[1]))
    tail = np.empty((n, first.tail.shape[1]))
    diverged = np.empty(n, dtype=bool)
    y0 = np.empty(n)
    traces = {name: np.empty((n, first.t.size)) for name in ("y", "u", "alpha")} \
        if keep else None
    for sel, part in parts:
        metrics[sel], tail[sel], diverged[sel], y0[sel] = (part.metrics, part.tail,
                                                           part.diverged, part.y0)
        if traces is not None:
            for name, arr in traces.items():
                arr[sel] = getattr(part, name)
    return BatchResult(
        metrics=metrics, metric_names=METRIC_NAMES, diverged=diverged, t=first.t,
        r=roff[0] if roff.shape[0] == 1 else roff, y0=y0, tail=tail, tail_names=TAIL_NAMES,
        y=None if traces is None else traces["y"], u=None if traces is None else traces["u"],
        alpha=None if traces is None else traces["alpha"])
