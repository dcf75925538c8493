"""fuzzyservo: electro-hydraulic servo models and PID / fuzzy PI / self-tuning fuzzy PI control.

The package reproduces and extends Aly et al. (2012), "Intelligent PI fuzzy control of an
electro-hydraulic manipulator", IJISA 4(7):43-49, doi:10.5815/ijisa.2012.07.06.
Subpackages: ``fuzzy`` (Mamdani engine), ``plant`` (servo models), ``control`` (controllers),
``sim`` (closed loop), ``analysis`` (metrics, tuning), ``plots``, ``paper`` (published data).
"""

from __future__ import annotations

from .errors import (
    EmptyFuzzySetError,
    FuzzyServoError,
    InputError,
    OutputError,
    ParameterError,
    SimulationDivergedError,
)

__version__ = "0.1.0"

__all__ = [
    "EmptyFuzzySetError",
    "FuzzyServoError",
    "InputError",
    "OutputError",
    "ParameterError",
    "SimulationDivergedError",
    "__version__",
]
