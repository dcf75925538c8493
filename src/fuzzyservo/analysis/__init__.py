"""fuzzyservo.analysis: step metrics, tuning and sweeps."""

from __future__ import annotations

from .step_metrics import StepMetrics, step_metrics

__all__ = ["StepMetrics", "step_metrics"]
