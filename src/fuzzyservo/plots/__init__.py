"""fuzzyservo.plots: figures, each computed first and rendered second (matplotlib only here)."""

from __future__ import annotations

from .figures import (
    MembershipData,
    SurfaceData,
    fig3,
    membership_data,
    render_memberships,
    render_surface,
    surface_data,
)

__all__ = [
    "MembershipData",
    "SurfaceData",
    "fig3",
    "membership_data",
    "render_memberships",
    "render_surface",
    "surface_data",
]
