"""Closed loop (per-step and batched numba kernels), open loop, references, results, metrics."""

from __future__ import annotations

from .batch import simulate_batch
from .closed_loop import DEFAULT_DELAY, LinearPlant, NonlinearPlant, Plant, simulate
from .open_loop import OpenLoopResult, command_samples, simulate_open_loop
from .references import (
    Chirp,
    MultiStep,
    Ramp,
    Reference,
    SCurve,
    Sine,
    Step,
    Trapezoid,
    UserReference,
    parse_reference,
    reference_rates,
    sample_reference,
)
from .result import BatchResult, SimResult
from .stepinfo import METRIC_NAMES, N_METRICS, step_metrics_core

__all__ = [
    "DEFAULT_DELAY",
    "METRIC_NAMES",
    "N_METRICS",
    "BatchResult",
    "Chirp",
    "LinearPlant",
    "MultiStep",
    "NonlinearPlant",
    "OpenLoopResult",
    "Plant",
    "Ramp",
    "Reference",
    "SCurve",
    "SimResult",
    "Sine",
    "Step",
    "Trapezoid",
    "UserReference",
    "command_samples",
    "parse_reference",
    "reference_rates",
    "sample_reference",
    "simulate",
    "simulate_batch",
    "simulate_open_loop",
    "step_metrics_core",
]
