"""fuzzyservo.export: the controllers as dependency-free C99 code, the controllers and the servo
as FMI 2.0 co-simulation FMUs (docs/export.md), the controllers as IEC 61131-3 Structured Text
for PLCs (docs/export-st.md).

The targets are registered once, in :mod:`fuzzyservo.export.targets`; the command line
(``fuzzyservo export c|fmu|st``) offers exactly those.
"""

from __future__ import annotations

from .targets import (
    EXPORT_TARGETS,
    ExportTarget,
    export_c,
    export_controller_fmu,
    export_servo_fmu,
    export_st,
    export_target_names,
    generate_st,
)

__all__ = [
    "EXPORT_TARGETS",
    "ExportTarget",
    "export_c",
    "export_controller_fmu",
    "export_servo_fmu",
    "export_st",
    "export_target_names",
    "generate_st",
]
