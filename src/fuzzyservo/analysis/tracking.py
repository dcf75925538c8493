"""Tracking and disturbance metrics of a run: how closely y follows a moving reference, and
how far and how long a load force pushes the piston off its position.

Three kinds of experiment, each with its own figures (docs/model.md, "Tracking and load
disturbances"):

- :func:`sine_metrics`: a sine reference of frequency f. Over a window of whole periods at
  the end of the run (the transient excluded), the RMS and the largest |e| of e = r - y, and
  the first harmonic of r and y, fitted by least squares on [sin, cos, 1] at f: the amplitude
  ratio |Y|/|R| and the phase lag arg R - arg Y [deg] (positive: y lags).
- :func:`move_metrics`: a point-to-point move of ``distance`` that ends at ``t_end``: the
  largest following error |e| during the move, the overshoot beyond the target after it [%
  of the distance], the settling time after ``t_end`` to a band of ``band`` x distance (the
  last instant |e| leaves the band, measured from t_end; NaN when it has not settled by the
  end of the run), and |e| at the end of the run.
- :func:`disturbance_metrics`: a load-force step at ``t_step`` with the reference at rest:
  the largest deviation |y - y(t_step)|, the recovery time (from the step to the last instant
  the deviation exceeds ``band`` x the largest deviation; NaN when it has not recovered by the
  end of the run) and the remaining deviation at the end of the run (mean over its last
  ``tail`` seconds, so a limit cycle shows its offset, not a phase).

Everything is measured on the samples as recorded (the measurement y, noise included).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..errors import InputError

__all__ = [
    "DisturbanceMetrics",
    "MoveMetrics",
    "SineMetrics",
    "disturbance_metrics",
    "harmonic",
    "harmonic_fit",
    "move_metrics",
    "sine_metrics",
]


def _arrays(t: ArrayLike, *xs: ArrayLike) -> tuple[FloatArray, ...]:
    tt = np.asarray(t, dtype=np.float64)
    out = [tt]
    for x in xs:
        a = np.asarray(x, dtype=np.float64)
        if a.shape != tt.shape:
            raise InputError(f"a trace needs one value per sample ({tt.size}), got {a.shape}")
        out.append(a)
    if tt.ndim != 1 or tt.size < 2 or np.any(np.diff(tt) <= 0):
        raise InputError("the sample times must be a 1-D increasing array of >= 2 samples")
    return tuple(out)


def harmonic(t: FloatArray, x: FloatArray, frequency: float) -> complex:
    """See :func:`harmonic_fit`: the complex amplitude a + j b only."""
    return harmonic_fit(t, x, frequency)[0]


def harmonic_fit(t: FloatArray, x: FloatArray, frequency: float) -> tuple[complex, float]:
    """The first harmonic of ``x`` at ``frequency`` [Hz]: the complex amplitude c = a + j b of
    the least-squares fit x ≈ a sin(ωt) + b cos(ωt) + m, so x's fundamental is
    |c| sin(ωt + arg c), and the mean m.

    The normal equations are summed exactly (:func:`math.fsum`) with the C library's sin and
    cos per sample and solved by Cramer's rule, so the result is the same on every machine
    (no BLAS or LAPACK kernel, no vector sin whose rounding depends on the processor)."""
    w = (2.0 * math.pi * frequency * np.asarray(t, dtype=np.float64)).tolist()
    xs = np.asarray(x, dtype=np.float64).tolist()
    sn = [math.sin(v) for v in w]
    cs = [math.cos(v) for v in w]
    one = [1.0] * len(w)
    cols = (sn, cs, one)
    g = [[math.fsum(a * b for a, b in zip(ci, cj, strict=True)) for cj in cols] for ci in cols]
    rhs = [math.fsum(a * b for a, b in zip(ci, xs, strict=True)) for ci in cols]

    def det(m: list[list[float]]) -> float:
        return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))

    d = det(g)
    if d == 0.0:
        return complex(math.nan, math.nan), math.nan
    sol = []
    for j in range(3):
        m = [row[:] for row in g]
        for i in range(3):
            m[i][j] = rhs[i]
        sol.append(det(m) / d)
    return complex(sol[0], sol[1]), sol[2]


@dataclass(frozen=True, slots=True)
class SineMetrics:
    """Tracking of a sine (see the module docstring)."""

    rms_error: float  #: RMS of e over the window [m]
    max_error: float  #: largest |e| over the window [m]
    amplitude_ratio: float  #: |Y|/|R| of the fundamentals [-]
    phase_lag: float  #: arg R - arg Y, in (-180, 180] [deg]; positive: y lags r
    window: float  #: length of the window: whole periods at the end of the run [s]


def sine_metrics(t: ArrayLike, r: ArrayLike, y: ArrayLike, frequency: float, *,
                 periods: int = 2) -> SineMetrics:
    """Metrics of a sine run over its last ``periods`` whole periods.

    Raises
    ------
    InputError
        A frequency that is not > 0, or a run shorter than the window.
    """
    tt, rr, yy = _arrays(t, r, y)
    if not (math.isfinite(frequency) and frequency > 0.0):
        raise InputError(f"frequency must be > 0 Hz, got {frequency!r}")
    span = periods / frequency
    if tt[-1] - tt[0] < span:
        raise InputError(f"the run ({tt[-1] - tt[0]:g} s) is shorter than {periods} periods "
                         f"of {frequency:g} Hz ({span:g} s)")
    h = float(np.median(np.diff(tt)))
    n = int(round(span / h))  # samples in the window: whole periods on the sample grid
    sel = slice(tt.size - n, tt.size)
    e = rr[sel] - yy[sel]
    cr = harmonic(tt[sel], rr[sel], frequency)
    cy = harmonic(tt[sel], yy[sel], frequency)
    lag = math.degrees(math.atan2(cr.imag, cr.real) - math.atan2(cy.imag, cy.real))
    lag = (lag + 180.0) % 360.0 - 180.0
    if lag == -180.0:
        lag = 180.0
    return SineMetrics(rms_error=float(np.sqrt(np.mean(e * e))),
                       max_error=float(np.max(np.abs(e))),
                       amplitude_ratio=abs(cy) / abs(cr) if abs(cr) > 0 else math.nan,
                       phase_lag=lag, window=n * h)


@dataclass(frozen=True, slots=True)
class MoveMetrics:
    """Following of a point-to-point move (see the module docstring)."""

    max_following_error: float  #: largest |e| until the end of the move [m]
    overshoot: float  #: largest travel past the target after the move [% of the distance]
    settling_time: float  #: from the end of the move into the band for good [s]; NaN: never
    final_error: float  #: |e| at the end of the run [m]


def move_metrics(t: ArrayLike, r: ArrayLike, y: ArrayLike, *, distance: float, t_end: float,
                 band: float = 0.02) -> MoveMetrics:
    """Metrics of a move of ``distance`` [m] (signed) ending at ``t_end`` [s].

    Raises
    ------
    InputError
        A distance of 0, a band not in (0, 1), or a move that does not end inside the run.
    """
    tt, rr, yy = _arrays(t, r, y)
    if not (math.isfinite(distance) and distance != 0.0):
        raise InputError(f"the move's distance must be finite and non-zero, got {distance!r}")
    if not 0.0 < band < 1.0:
        raise InputError(f"band must be in (0, 1), got {band!r}")
    if not tt[0] <= t_end < tt[-1]:
        raise InputError(f"the move ends at {t_end!r} s, outside the run "
                         f"[{tt[0]:g}, {tt[-1]:g}] s")
    e = rr - yy
    during = tt <= t_end
    after = ~during
    sign = 1.0 if distance > 0 else -1.0
    past = np.max(sign * (yy[after] - rr[after])) if np.any(after) else 0.0
    outside = np.nonzero(after & (np.abs(e) > band * abs(distance)))[0]
    if outside.size == 0:
        settle = 0.0
    elif outside[-1] == tt.size - 1:
        settle = math.nan
    else:
        settle = float(tt[outside[-1] + 1] - t_end)
    return MoveMetrics(max_following_error=float(np.max(np.abs(e[during]))),
                       overshoot=max(float(past), 0.0) / abs(distance) * 100.0,
                       settling_time=settle, final_error=float(abs(e[-1])))


@dataclass(frozen=True, slots=True)
class DisturbanceMetrics:
    """Response to a load-force step at rest (see the module docstring)."""

    max_deviation: float  #: largest |y - y(t_step)| after the step [m]
    recovery_time: float  #: from the step to within band x max deviation for good [s]
    remaining: float  #: mean deviation y - y(t_step) over the run's last ``tail`` s [m]


def disturbance_metrics(t: ArrayLike, y: ArrayLike, *, t_step: float, band: float = 0.02,
                        tail: float = 0.5) -> DisturbanceMetrics:
    """Metrics of a load-force step at ``t_step`` [s] applied with the reference at rest.

    Raises
    ------
    InputError
        A step outside the run, a band not in (0, 1), or a tail not in (0, run after step].
    """
    tt, yy = _arrays(t, y)
    if not tt[0] <= t_step < tt[-1]:
        raise InputError(f"the load step at {t_step!r} s is outside the run "
                         f"[{tt[0]:g}, {tt[-1]:g}] s")
    if not 0.0 < band < 1.0:
        raise InputError(f"band must be in (0, 1), got {band!r}")
    if not 0.0 < tail <= tt[-1] - t_step:
        raise InputError(f"tail must be in (0, {tt[-1] - t_step:g}] s, got {tail!r}")
    k0 = int(np.searchsorted(tt, t_step, side="left"))
    dev = yy[k0:] - yy[k0]
    peak = float(np.max(np.abs(dev)))
    if peak == 0.0:
        return DisturbanceMetrics(max_deviation=0.0, recovery_time=0.0, remaining=0.0)
    outside = np.nonzero(np.abs(dev) > band * peak)[0]
    if outside.size == 0:
        rec = 0.0
    elif outside[-1] == dev.size - 1:
        rec = math.nan
    else:
        rec = float(tt[k0 + outside[-1] + 1] - t_step)
    last = tt >= tt[-1] - tail
    return DisturbanceMetrics(max_deviation=peak, recovery_time=rec,
                              remaining=float(np.mean(yy[last] - yy[k0])))
