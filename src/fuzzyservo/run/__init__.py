"""One description of a closed-loop run (:class:`RunSpec`): its objects and its command line.

Sits above ``registry`` and ``sim`` and below every front end (the command line, the browser
page, sweeps, the study), which describe their runs with it (docs/architecture.md, "Runs").
"""

from __future__ import annotations

from .spec import (
    DEFAULT_SET,
    BatchRun,
    BuiltRun,
    ControllerParts,
    RunSpec,
    check_start,
    flat_params,
    load_systems,
    overrides_of,
    parse_delay,
    parse_gains_pairs,
    parse_param,
    run_default,
    servo_params,
    systems_record,
)

__all__ = [
    "DEFAULT_SET",
    "BatchRun",
    "BuiltRun",
    "RunSpec",
    "check_start",
    "flat_params",
    "ControllerParts",
    "load_systems",
    "overrides_of",
    "parse_delay",
    "parse_gains_pairs",
    "parse_param",
    "run_default",
    "servo_params",
    "systems_record",
]
