"""Results of closed-loop simulations: one run (:class:`SimResult`), many (:class:`BatchResult`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, TextIO

import numpy as np

from .._io import atomic_write
from .._typing import BoolArray, FloatArray
from .stepinfo import METRIC_NAMES, TAIL_NAMES, StepMetrics, metric_options, metrics_of

__all__ = ["BatchResult", "SimResult", "write_csv"]

#: Rows formatted per write call: bounds the text held in memory (about 10 MB for 12 columns).
_BLOCK = 8192


def write_csv(dest: str | Path | TextIO, header: Sequence[str],
              columns: Sequence[FloatArray]) -> None:
    """Write a header row and the ``columns`` to a path or an open text stream
    (``sys.stdout`` for ``--out -``).

    Floats are written with ``repr``, the shortest text that reads back to the same double
    (``nan``, ``inf`` and ``-inf`` for non-finite values). Rows are formatted in blocks
    straight from the arrays, so memory stays bounded whatever the length. A path is written
    atomically (``fuzzyservo._io.atomic_write``): an interrupted or failing write leaves the
    previous file as it was.
    """
    cols = [np.asarray(c, dtype=np.float64).reshape(-1) for c in columns]
    if len(cols) != len(header):
        raise ValueError(f"{len(header)} column names for {len(cols)} columns")
    n = cols[0].shape[0] if cols else 0
    if any(c.shape[0] != n for c in cols):
        raise ValueError("columns of different lengths: " + ", ".join(
            f"{h} {c.shape[0]}" for h, c in zip(header, cols, strict=True)))
    if isinstance(dest, str | Path):
        with atomic_write(dest) as fh:
            _write_rows(fh, header, cols, n)
    else:
        _write_rows(dest, header, cols, n)


def _write_rows(fh: IO[str] | TextIO, header: Sequence[str], cols: Sequence[FloatArray],
                n: int) -> None:
    fh.write(",".join(header) + "\n")
    for a in range(0, n, _BLOCK):
        text = [list(map(repr, c[a:a + _BLOCK].tolist())) for c in cols]
        fh.write("\n".join(map(",".join, zip(*text, strict=True))))
        fh.write("\n")


@dataclass(frozen=True, slots=True, eq=False)
class SimResult:
    """One closed-loop run. Row k: time t_k, reference r_k, measurement y_k taken at t_k,
    command u_k computed from it and held over [t_k, t_k + ts), gain factor α_k, plant state.

    Attributes
    ----------
    t : ndarray
        Sample times [s], shape (n,).
    r : ndarray
        Reference [m], an absolute position on every plant: the plant's start position plus
        the reference offset.
    y : ndarray
        Measured position [m], absolute (including measurement noise, if any).
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

    def to_csv(self, dest: str | Path | TextIO) -> None:
        """Write columns ``t, r, y, u, alpha`` then the plant states (SI units; r and y
        absolute positions) to a path or an open text stream."""
        write_csv(dest, ["t", "r", "y", "u", "alpha", *self.state_names],
                  [self.t, self.r, self.y, self.u, self.alpha, *self.x.T])

    def metrics(self, *, rise: tuple[float, float] = (0.1, 0.9), settle_band: float = 0.02,
                settle_band2: float = 0.05) -> StepMetrics:
        """Step metrics of the run (names :data:`~fuzzyservo.sim.METRIC_NAMES`), as
        ``fuzzyservo.analysis.step_metrics(result)`` and ``simulate --metrics`` give them:
        from y(0) to the final reference, e = r - y."""
        opts = metric_options(rise, settle_band, settle_band2)
        return metrics_of(self.t, self.y, self.u, self.r, y0=float(self.y[0]),
                          y_final=float(self.r[-1]), options=opts)

    def metric(self, name: str) -> float:
        """One step metric by name (see :meth:`metrics`)."""
        if name not in METRIC_NAMES:
            raise KeyError(f"no metric {name!r}; metrics: {', '.join(METRIC_NAMES)}")
        return self.metrics()[name]


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
        Reference offset from the start position [m], shape (n,) when shared (run i tracks
        ``y0[i] + r``) or (runs, n) when each run has its own (``y0[i] + r[i]``).
    y0 : ndarray
        Start position of each run [m], shape (runs,).
    tail : ndarray
        Oscillation of y over the end of each run, shape (runs, len(tail_names)):
        peak-to-peak [m], swings [-], period [s], sustain [-]
        (:func:`~fuzzyservo.sim.stepinfo.tail_oscillation_core`); NaN for diverged runs.
    tail_names : tuple of str
        Column names of ``tail`` (``fuzzyservo.sim.stepinfo.TAIL_NAMES``).
    y, u, alpha : ndarray or None
        Traces, shape (runs, n), kept only with ``keep_traces=True`` [m, -, -].
    """

    metrics: FloatArray
    metric_names: tuple[str, ...]
    diverged: BoolArray
    t: FloatArray
    r: FloatArray
    y0: FloatArray
    tail: FloatArray
    tail_names: tuple[str, ...] = TAIL_NAMES
    y: FloatArray | None = None
    u: FloatArray | None = None
    alpha: FloatArray | None = None

    def metric(self, name: str) -> FloatArray:
        """One metric for every run, by name (``metric_names`` or ``tail_names``)."""
        if name in self.tail_names:
            return self.tail[:, self.tail_names.index(name)]
        if name not in self.metric_names:
            raise KeyError(f"no metric {name!r}; metrics: "
                           f"{', '.join(self.metric_names + self.tail_names)}")
        return self.metrics[:, self.metric_names.index(name)]
