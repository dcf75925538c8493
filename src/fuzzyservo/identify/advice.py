"""What a fit's uncertainty says about the experiment: identifiability warnings, each naming
the experiment that would identify the parameter (docs/identify.md, "Identifiability")."""

from __future__ import annotations

import math
from collections.abc import Sequence

from .._typing import FloatArray

__all__ = ["CORRELATION_LIMIT", "identifiability_warnings", "remedy"]

#: A correlation of two estimates above this (in magnitude) means the data do not separate them.
CORRELATION_LIMIT = 0.95

_STIFFNESS = ("fluid.oil_bulk_modulus", "fluid.cylinder_wall_bulk_modulus",
              "fluid.hose_wall_bulk_modulus", "fluid.hose_volume", "cylinder.dead_volume_f",
              "cylinder.dead_volume_n")
_INERTIA = ("load.mass",)
_VALVE = ("valve.omega_v", "valve.zeta_v", "valve.tau_v")
_FRICTION = ("load.coulomb_friction", "load.static_friction", "load.stribeck_velocity",
             "load.viscous_damping", "load.friction_smoothing_velocity")
_LEAKAGE = ("valve.null_leakage", "cylinder.internal_leakage", "valve.laminar_pressure")
_GAIN = ("valve.rated_flow", "valve.discharge_coefficient", "supply.pressure")


def _family(name: str) -> str:
    for fam, members in (("stiffness", _STIFFNESS), ("inertia", _INERTIA), ("valve", _VALVE),
                         ("friction", _FRICTION), ("leakage", _LEAKAGE), ("gain", _GAIN)):
        if name in members:
            return fam
    return name.split(".")[0]


def remedy(names: Sequence[str], *, pressures: bool, omega_0: float, omega_v: float) -> str:
    """The experiment that would tell ``names`` apart (or identify the one named)."""
    fams = {_family(n) for n in names}
    f_h = omega_0 / (2.0 * math.pi)
    f_v = omega_v / (2.0 * math.pi)
    if fams & {"stiffness", "inertia"} and len(fams & {"stiffness", "inertia"}) == len(fams):
        if not pressures:
            return ("log the chamber pressures (p_f, p_n) or excite above the hydraulic natural "
                    f"frequency ({f_h:.3g} Hz)")
        return (f"excite above the hydraulic natural frequency ({f_h:.3g} Hz): a chirp to "
                f"{2 * f_h:.3g} Hz (fuzzyservo identify --design)")
    if "valve" in fams:
        return (f"excite up to the valve's bandwidth ({f_v:.3g} Hz) with pressures logged at "
                f"{max(1000.0, 10 * f_v):.0f} Hz or more, or take omega_v from the datasheet")
    if "friction" in fams:
        return ("move at several constant speeds of both signs (slow ramps), so friction and "
                "viscous damping act at different velocities")
    if "leakage" in fams:
        return ("log the chamber pressures while the valve is held at null and while the "
                "axis pushes against a load or an end stop")
    if "gain" in fams:
        return ("log moves at several command amplitudes of both signs (the flow gain is the "
                "slope of velocity against command)")
    return ("excite more: steps of both signs and a chirp above the hydraulic natural "
            "frequency (fuzzyservo identify --design)")


def identifiability_warnings(names: Sequence[str], estimate: FloatArray, std_error: FloatArray,
                             correlation: FloatArray, *, channels: Sequence[str],
                             omega_0: float, omega_v: float) -> list[str]:
    """One line per parameter the data do not identify (standard error larger than the
    estimate) and per pair they do not separate (|correlation| > :data:`CORRELATION_LIMIT`),
    each naming the experiment that would."""
    pressures = any(c in channels for c in ("p_f", "p_n"))
    out: list[str] = []
    for i, n in enumerate(names):
        est, se = float(estimate[i]), float(std_error[i])
        if not math.isfinite(se) or se > abs(est):
            out.append(f"{n} is not identifiable from these data ({est:.4g} ± {se:.2g}, the "
                       f"standard error exceeds the estimate): "
                       f"{remedy([n], pressures=pressures, omega_0=omega_0, omega_v=omega_v)}")
    p = len(names)
    for i in range(p):
        for j in range(i + 1, p):
            r = float(correlation[i, j])
            if abs(r) > CORRELATION_LIMIT:
                src = "position and pressures" if pressures else "position alone"
                out.append(f"{names[i]} and {names[j]} are not separable from {src} "
                           f"(correlation {r:+.3f}): "
                           + remedy([names[i], names[j]], pressures=pressures,
                                    omega_0=omega_0, omega_v=omega_v))
    return out


