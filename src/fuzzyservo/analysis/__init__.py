"""fuzzyservo.analysis: step metrics, tuning, sweeps and the closed loop's frequency response."""

from __future__ import annotations

from .frequency import (
    BodeResult,
    LinearizedController,
    LoopModel,
    Margins,
    MeasuredResponse,
    closed_loop_bode,
    linearize_controller,
    loop_model,
    margins,
    measured_response,
)
from .step_metrics import StepMetrics, step_metrics

__all__ = [
    "BodeResult",
    "LinearizedController",
    "LoopModel",
    "Margins",
    "MeasuredResponse",
    "StepMetrics",
    "closed_loop_bode",
    "linearize_controller",
    "loop_model",
    "margins",
    "measured_response",
    "step_metrics",
]
