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
from .runs import FIGURE_FORMATS, RunCurve, run_curves, runs_figure, save_figure

__all__ = [
    "FIGURE_FORMATS",
    "MembershipData",
    "RunCurve",
    "SurfaceData",
    "fig3",
    "membership_data",
    "render_memberships",
    "render_surface",
    "run_curves",
    "runs_figure",
    "save_figure",
    "surface_data",
]
