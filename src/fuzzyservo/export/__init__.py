"""fuzzyservo.export: the controllers as dependency-free C99 code, the controllers and the servo
as FMI 2.0 co-simulation FMUs (docs/export.md).

The targets are registered once, in :mod:`fuzzyservo.export.targets`; the command line
(``fuzzyservo export c|fmu``) offers exactly those.
"""

from __future__ import annotations

from .targets import (
    EXPORT_TARGETS,
    ExportTarget,
    export_c,
    export_controller_fmu,
    export_servo_fmu,
    export_target_names,
)

__all__ = [
    "EXPORT_TARGETS",
    "ExportTarget",
    "export_c",
    "export_controller_fmu",
    "export_servo_fmu",
    "export_target_names",
]
