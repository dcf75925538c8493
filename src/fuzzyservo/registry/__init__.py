"""fuzzyservo.registry: the one vocabulary of controllers and plants a user can name.

Every front end (command line, tuner, study, gains files, later export and sweeps) builds
controllers and plants here and offers exactly these names.
"""

from __future__ import annotations

from .controllers import (
    CONTROLLERS,
    ControllerKind,
    GainSpec,
    OptionSpec,
    build_controller,
    controller_colour,
    controller_kind,
    controller_names,
    controller_options,
    default_systems,
    register_controller,
    unregister_controller,
)
from .plants import DEFAULT_SUBSTEP, PLANTS, PlantKind, build_plant, plant_kind, plant_names

__all__ = [
    "CONTROLLERS",
    "DEFAULT_SUBSTEP",
    "PLANTS",
    "ControllerKind",
    "GainSpec",
    "OptionSpec",
    "PlantKind",
    "build_controller",
    "build_plant",
    "controller_colour",
    "controller_kind",
    "controller_names",
    "controller_options",
    "default_systems",
    "plant_kind",
    "plant_names",
    "register_controller",
    "unregister_controller",
]
