"""Discrete-time controllers with explicit state: PID family, fuzzy PI, self-tuning fuzzy PI."""

from __future__ import annotations

from .base import (
    KIND_FUZZY_PI,
    KIND_PID,
    STATE_ALPHA,
    STATE_SIZE,
    Controller,
    PackedController,
    controller_step,
)
from .fuzzy_pi import FUZZY_GAIN_NAMES, FuzzyPIController, FuzzyPIState, fuzzy_pi_step
from .pid import (
    PID_GAIN_NAMES,
    PIDController,
    PIDState,
    p_controller,
    pi_controller,
    pid_step,
)
from .self_tuning import SelfTuningFuzzyPIController

__all__ = [
    "FUZZY_GAIN_NAMES",
    "KIND_FUZZY_PI",
    "KIND_PID",
    "PID_GAIN_NAMES",
    "STATE_ALPHA",
    "STATE_SIZE",
    "Controller",
    "FuzzyPIController",
    "FuzzyPIState",
    "PIDController",
    "PIDState",
    "PackedController",
    "SelfTuningFuzzyPIController",
    "controller_step",
    "fuzzy_pi_step",
    "p_controller",
    "pi_controller",
    "pid_step",
]
