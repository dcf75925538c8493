"""Discrete-time controllers with explicit state: PID family, fuzzy PI, self-tuning fuzzy PIs,
position control with feed-forward, sliding-mode control.

Each controller's maths is a :class:`Law` declared once in its module (``pid.py``,
``fuzzy_pi.py``, ``ffpd.py``, ``smc.py``; the self-tuning variants in ``self_tuning.py`` and
``woo.py`` are the fuzzy PI's law), with its C port beside it (``pid.c``, ``fuzzy_pi.c``,
``ffpd.c``, ``smc.c``).
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
    WOO_FPI_GENERAL_LAW,
    WOO_FPI_LAW,
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
from .smc import (
    SMC_GAIN_NAMES,
    SMC_LAW,
    SlidingModeController,
    SlidingModeState,
    smc_model_gains,
    smc_step,
)
from .woo import WooFuzzyPIController

__all__ = [
    "FFPD_GAIN_NAMES",
    "FFPD_LAW",
    "FUZZY_GAIN_NAMES",
    "FUZZY_PI_GENERAL_LAW",
    "FUZZY_PI_LAW",
    "PID_GAIN_NAMES",
    "PID_LAW",
    "SMC_GAIN_NAMES",
    "SMC_LAW",
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
    "SlidingModeController",
    "SlidingModeState",
    "WOO_FPI_GENERAL_LAW",
    "WOO_FPI_LAW",
    "WooFuzzyPIController",
    "indices",
    "kernel",
    "p_controller",
    "pi_controller",
    "pid_step",
    "smc_model_gains",
    "smc_step",
]
