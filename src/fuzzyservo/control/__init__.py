"""Discrete-time controllers with explicit state: PID family, fuzzy PI, self-tuning fuzzy PI,
position control with feed-forward.

Each controller's maths is a :class:`Law` declared once in its module (``pid.py``,
``fuzzy_pi.py``, ``ffpd.py``), with its C port beside it (``pid.c``, ``fuzzy_pi.c``,
``ffpd.c``).
"""

from __future__ import annotations

from .._jit import kernel
from .base import Controller, PackedController
from .ffpd import (
    FFPD_GAIN_NAMES,
    FFPD_LAW,
    FFPDController,
    FFPDState,
    ffpd_model_gains,
    ffpd_step,
)
from .fuzzy_pi import (
    FUZZY_GAIN_NAMES,
    FUZZY_PI_GENERAL_LAW,
    FUZZY_PI_LAW,
    FuzzyPIController,
    FuzzyPIState,
)
from .law import Field, Law, LawController, indices
from .pid import (
    PID_GAIN_NAMES,
    PID_LAW,
    PIDController,
    PIDState,
    p_controller,
    pi_controller,
    pid_step,
)
from .self_tuning import SelfTuningFuzzyPIController

__all__ = [
    "FFPD_GAIN_NAMES",
    "FFPD_LAW",
    "FUZZY_GAIN_NAMES",
    "FUZZY_PI_GENERAL_LAW",
    "FUZZY_PI_LAW",
    "PID_GAIN_NAMES",
    "PID_LAW",
    "Controller",
    "FFPDController",
    "FFPDState",
    "Field",
    "FuzzyPIController",
    "FuzzyPIState",
    "Law",
    "LawController",
    "PIDController",
    "PIDState",
    "PackedController",
    "SelfTuningFuzzyPIController",
    "ffpd_model_gains",
    "ffpd_step",
    "indices",
    "kernel",
    "p_controller",
    "pi_controller",
    "pid_step",
]
