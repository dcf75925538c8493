"""Robust tuning: one design for a fixed set of plants, a statistic of the objective over them,
and constraints that must hold on every one.

A robust tuning runs each candidate gain vector on every plant of a :class:`RobustSet` (a
fixed list of plants with their own delays and sensor-noise samples; the set a sweep spec's
points give, :mod:`fuzzyservo.sweep.robust`) and hands the search
(:func:`fuzzyservo.analysis.tuning.tune`) one row of metrics per candidate, aggregated over
the set by :func:`aggregate`:

- the objective (IAE, ITAE or ISE) is the chosen statistic over the plants (:data:`STATISTICS`:
  ``mean``, ``worst`` or a percentile ``pNN``);
- every other metric is its worst case over the plants, so that the tuner's constraints
  (:class:`fuzzyservo.analysis.tuning.TuningConstraints`) hold on every plant when they hold
  on the row: the largest overshoot, |steady-state error|, largest |error| over the end of
  the run and max |u|; a settling or rise time that is NaN (never settled, never rose) on any
  plant is NaN for the candidate;
- a candidate that diverges on any plant has every aggregated metric NaN: the search gives
  it the cost of an infeasible run.

This module is numpy only: it aggregates and describes; the closed loops are run by
:func:`fuzzyservo.analysis.autotune.tune_controller`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._typing import BoolArray, FloatArray
from ..errors import ParameterError
from .tuning import OBJECTIVES

__all__ = [
    "MAX_ROBUST_POINTS",
    "STATISTICS",
    "RobustRecord",
    "RobustSet",
    "aggregate",
    "parse_statistic",
    "statistic_over_plants",
    "worst_name",
]

#: Statistics of the objective over a robust set: the mean, the worst case (largest), or a
#: percentile ``pNN`` with 0 < NN < 100 (``p90``, ``p97.5``), by numpy's default (linear)
#: interpolation between the sorted values.
STATISTICS: tuple[str, ...] = ("mean", "worst", "pNN")

#: Most plants a robust set may have: a generation of a self-tuning fuzzy PI search at the
#: default population (30 candidates) is then 7680 closed loops.
MAX_ROBUST_POINTS = 256

_PERCENTILE = re.compile(r"p(\d+(?:\.\d+)?)")


def parse_statistic(text: str) -> str:
    """The statistic ``text`` names, in its canonical spelling (``P90`` -> ``p90``).

    Raises
    ------
    ParameterError
        Neither ``mean``, ``worst`` nor ``pNN`` with 0 < NN < 100.
    """
    s = str(text).strip().lower()
    if s in ("mean", "worst"):
        return s
    m = _PERCENTILE.fullmatch(s)
    if m is not None:
        q = float(m.group(1))
        if 0.0 < q < 100.0:
            return f"p{q:g}"
    raise ParameterError(f"statistic must be mean, worst or a percentile pNN with 0 < NN < 100 "
                         f"(p90: the value 90 % of the plants do not exceed; worst for p100), "
                         f"got {text!r}")


def statistic_over_plants(values: FloatArray, statistic: str) -> FloatArray:
    """The statistic of each row of ``values`` (candidates, plants) over its plants.

    ``worst`` is the largest value, ``mean`` the mean, ``pNN`` ``numpy.percentile(values, NN,
    axis=1)`` (linear interpolation between the sorted values). A NaN in a row gives NaN.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] == 0:
        raise ParameterError(f"values must be (candidates, plants) with at least one plant, "
                             f"got shape {v.shape}")
    s = parse_statistic(statistic)
    if s == "worst":
        return np.max(v, axis=1)
    if s == "mean":
        return np.mean(v, axis=1)
    out = np.percentile(v, float(s[1:]), axis=1)
    return np.where(np.any(np.isnan(v), axis=1), np.nan, out)


def worst_name(objective: str) -> str:
    """Name of the aggregated metric holding the objective's worst case (``itae_worst``)."""
    return f"{objective}_worst"


def aggregate(per_plant: Mapping[str, FloatArray], failed: BoolArray, objective: str,
              statistic: str) -> dict[str, FloatArray]:
    """One row of metrics per candidate from its metrics on every plant of a set.

    Parameters
    ----------
    per_plant : mapping
        Metric name -> array (candidates, plants), in the metric's unit.
    failed : array of bool (candidates, plants)
        Runs that diverged.
    objective : {"iae", "itae", "ise"}
        The objective: its column is the ``statistic`` over the plants.
    statistic : str
        ``mean``, ``worst`` or ``pNN`` (:func:`parse_statistic`).

    Returns
    -------
    dict
        Metric name -> array (candidates,): the objective's ``statistic``; ``overshoot`` the
        largest (plants that do not step, NaN, ignored); ``peak`` and ``peak_time`` those of
        the plant with the largest overshoot; ``steady_state_error`` the one of largest
        magnitude (sign kept); every other metric the largest, NaN if NaN on any plant
        (a settling time NaN on one plant is NaN); plus :func:`worst_name` (objective),
        the objective's largest value. Every metric of a candidate that failed on any plant
        is NaN.

    Notes
    -----
    With one plant every metric is that plant's, exactly (the maximum, the mean and any
    percentile of one value are the value).
    """
    if objective not in OBJECTIVES:
        raise ParameterError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    stat = parse_statistic(statistic)
    fail = np.asarray(failed, dtype=bool)
    if fail.ndim != 2:
        raise ParameterError(f"failed must be (candidates, plants), got shape {fail.shape}")
    bad_row = np.any(fail, axis=1)
    cols = {k: np.asarray(v, dtype=np.float64) for k, v in per_plant.items()}
    for k, v in cols.items():
        if v.shape != fail.shape:
            raise ParameterError(f"metric {k!r} has shape {v.shape}, failed has {fail.shape}")
    out: dict[str, FloatArray] = {}
    rows = np.arange(fail.shape[0])
    os_ = cols.get("overshoot", np.full(fail.shape, np.nan))
    os_key = np.where(np.isnan(os_), -np.inf, os_)
    at_os = np.argmax(os_key, axis=1)  # the plant of the largest overshoot (the first if none)
    for name, v in cols.items():
        if name == "overshoot":
            out[name] = np.where(np.all(np.isnan(os_), axis=1), np.nan, os_key[rows, at_os])
        elif name in ("peak", "peak_time"):
            out[name] = v[rows, at_os]
        elif name == "steady_state_error":
            at = np.argmax(np.where(np.isnan(v), np.inf, np.abs(v)), axis=1)
            out[name] = v[rows, at]
        elif name == objective:
            out[name] = statistic_over_plants(v, stat)
        else:
            out[name] = np.max(v, axis=1)  # NaN on any plant (never settled) gives NaN
    if objective in cols:
        out[worst_name(objective)] = np.max(cols[objective], axis=1)
    return {k: np.where(bad_row, np.nan, v) for k, v in out.items()}


@dataclass(frozen=True, slots=True, kw_only=True)
class RobustRecord:
    """What a robust tuning records of its set (a gains file's ``[tuning.robust]``; a resume
    with another set or statistic is refused).

    Parameters
    ----------
    source : str
        Where the set came from (the sweep spec's path, as given).
    digest : str
        SHA-256 of everything that defines the set's plants, delays, reference and noise
        (:func:`fuzzyservo.sweep.robust.set_digest`: the plant kind, nominal parameter
        values, run settings, and every point's values and noise seed).
    points : int
        Number of plants in the set.
    statistic : str
        Statistic of the objective over the set (:func:`parse_statistic`).
    """

    source: str
    digest: str
    points: int
    statistic: str

    def __post_init__(self) -> None:
        if not (isinstance(self.points, int) and self.points >= 1):
            raise ParameterError(f"RobustRecord.points must be an integer >= 1, got "
                                 f"{self.points!r}")
        if not re.fullmatch(r"[0-9a-f]{64}", str(self.digest)):
            raise ParameterError(f"RobustRecord.digest must be a SHA-256 (64 hex digits), got "
                                 f"{self.digest!r}")
        if parse_statistic(self.statistic) != self.statistic:
            raise ParameterError(f"RobustRecord.statistic must be written "
                                 f"{parse_statistic(self.statistic)!r}, got "
                                 f"{self.statistic!r}")

    def record(self) -> dict[str, Any]:
        """As plain values, in a fixed order (TOML/JSON)."""
        return {"spec": self.source, "set_sha256": self.digest, "points": self.points,
                "statistic": self.statistic}


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class RobustSet:
    """A fixed set of plants a design is tuned on.

    Parameters
    ----------
    plants : tuple
        The plants (:class:`fuzzyservo.sim.LinearPlant` or ``NonlinearPlant``, all of one kind).
    delays : array (plants,)
        Transport delay of each [s].
    noise : array (plants, samples) or None
        Sensor noise added to each plant's measured position, one row per plant, sampled
        on the run's time grid [m]; None: none.
    labels : tuple of int
        What each plant is (the sweep point's index).
    """

    plants: tuple[Any, ...]
    delays: FloatArray
    noise: FloatArray | None = None
    labels: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        m = len(self.plants)
        if not 1 <= m <= MAX_ROBUST_POINTS:
            raise ParameterError(f"a robust set needs 1 to {MAX_ROBUST_POINTS} plants, got {m}")
        d = np.asarray(self.delays, dtype=np.float64).reshape(-1)
        if d.size != m or not np.all(np.isfinite(d)) or np.any(d < 0.0):
            raise ParameterError(f"a robust set of {m} plants needs {m} finite delays >= 0 s, "
                                 f"got {np.asarray(self.delays).tolist()!r}")
        object.__setattr__(self, "delays", d)
        if self.noise is not None:
            nz = np.asarray(self.noise, dtype=np.float64)
            if nz.ndim != 2 or nz.shape[0] != m or not np.all(np.isfinite(nz)):
                raise ParameterError(f"a robust set's noise needs one finite row per plant "
                                     f"({m}), got shape {nz.shape}")
            object.__setattr__(self, "noise", nz)
        labels = tuple(int(v) for v in self.labels) or tuple(range(m))
        if len(labels) != m:
            raise ParameterError(f"a robust set of {m} plants needs {m} labels, got "
                                 f"{len(labels)}")
        object.__setattr__(self, "labels", labels)

    def __len__(self) -> int:
        return len(self.plants)
