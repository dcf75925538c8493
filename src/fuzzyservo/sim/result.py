"""Results of closed-loop simulations: one run (:class:`SimResult`), many (:class:`BatchResult`)."""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._typing import BoolArray, FloatArray

__all__ = ["BatchResult", "SimResult"]


@dataclass(frozen=True, slots=True, eq=False)
class SimResult:
    """One closed-loop run. Row k: time t_k, reference r_k, measurement y_k taken at t_k,
    command u_k computed from it and held over [t_k, t_k + ts), gain factor α_k, plant state.

    Attributes
    ----------
    t : ndarray
        Sample times [s], shape (n,).
    r : ndarray
        Reference [m] (absolute: the plant's start position plus the reference offset).
    y : ndarray
        Measured position [m] (including measurement noise, if any).
    u : ndarray
        Valve command [-], fraction of rated input.
    alpha : ndarray
        Self-tuning gain factor α_F [-]; 1 for the fuzzy PI, NaN for the PID family.
    x : ndarray
        Plant state at t_k, shape (n, len(state_names)) [SI units, see ``state_names``].
    state_names : tuple of str
        Names of the plant state columns.
    ts : float
        Controller sample time [s].
    delay : float
        Transport delay on the command [s].
    info : dict
        Controller, plant and options that produced the run.
    """

    t: FloatArray
    r: FloatArray
    y: FloatArray
    u: FloatArray
    alpha: FloatArray
    x: FloatArray
    state_names: tuple[str, ...]
    ts: float
    delay: float
    info: dict[str, Any] = field(default_factory=dict)

    def to_csv(self, path: str | Path) -> Path:
        """Write columns ``t, r, y, u, alpha`` then the plant states; return the path."""
        out = Path(path)
        header = ["t", "r", "y", "u", "alpha", *self.state_names]
        data = np.column_stack([self.t, self.r, self.y, self.u, self.alpha, self.x])
        with out.open("w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            w.writerows([[repr(float(v)) for v in row] for row in data])
        return out


@dataclass(frozen=True, slots=True, eq=False)
class BatchResult:
    """Many closed-loop runs.

    Attributes
    ----------
    metrics : ndarray
        Step metrics per run, shape (runs, len(metric_names)); NaN where undefined and for
        diverged runs.
    metric_names : tuple of str
        Column names of ``metrics`` (``fuzzyservo.sim.stepinfo.METRIC_NAMES``).
    diverged : ndarray of bool
        True for runs whose state became non-finite (they are not raised as errors).
    t : ndarray
        Sample times [s], shape (n,).
    r : ndarray
        Reference offset from the start position [m], shape (n,); run i tracks
        ``y0[i] + r``.
    y0 : ndarray
        Start position of each run [m], shape (runs,).
    y, u, alpha : ndarray or None
        Traces, shape (runs, n), kept only with ``keep_traces=True`` [m, -, -].
    """

    metrics: FloatArray
    metric_names: tuple[str, ...]
    diverged: BoolArray
    t: FloatArray
    r: FloatArray
    y0: FloatArray
    y: FloatArray | None = None
    u: FloatArray | None = None
    alpha: FloatArray | None = None

    def metric(self, name: str) -> FloatArray:
        """One metric for every run, by name (see ``metric_names``)."""
        return self.metrics[:, self.metric_names.index(name)]
