"""Identify the servo model of a user's own axis from measured data (docs/identify.md).

:func:`identify` fits fields of the parameter set (``load.mass``, ``fluid.oil_bulk_modulus``,
``valve.omega_v``, ...) so that a plant of the registry, driven as the axis was (by the logged
command, or by a controller and the logged reference), reproduces the logged position and
chamber pressures; it reports standard errors, correlations, bootstrap intervals and warns
when the data cannot identify a parameter, naming the experiment that would.
"""

from .advice import CORRELATION_LIMIT, identifiability_warnings, remedy
from .data import Measurement, measurement_from_arrays, parse_mapping, read_measurement
from .design import ExperimentDesign, design_experiment
from .fit import (
    DEFAULT_STARTS,
    FIT_CHANNELS,
    FitSettings,
    Identification,
    ModelRunner,
    default_bounds,
    identify,
    noise_level,
)
from .record import record_document, render_axis_toml, write_axis_toml

__all__ = [
    "FIT_CHANNELS",
    "CORRELATION_LIMIT",
    "DEFAULT_STARTS",
    "ExperimentDesign",
    "FitSettings",
    "Identification",
    "Measurement",
    "ModelRunner",
    "default_bounds",
    "design_experiment",
    "identifiability_warnings",
    "identify",
    "measurement_from_arrays",
    "noise_level",
    "parse_mapping",
    "read_measurement",
    "record_document",
    "remedy",
    "render_axis_toml",
    "write_axis_toml",
]
