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


def remedy(names: Sequence[str], *, pressures: bool, omega_0: float, omega_v: float,
           excited: float = 0.0) -> str:
    """The experiment that would tell ``names`` apart (or identify the one named); ``excited``
    is the band the data's excitation already covers [Hz] (99 % of its power below it), so
    that no excitation the data already have is suggested."""
    fams = {_family(n) for n in names}
    f_h = omega_0 / (2.0 * math.pi)
    f_v = omega_v / (2.0 * math.pi)
    more = ("log longer or with less noise (the standard errors shrink as one over the square "
            "root of the samples)")
    if fams & {"stiffness", "inertia"} and len(fams & {"stiffness", "inertia"}) == len(fams):
        if not pressures:
            return ("log the chamber pressures (p_f, p_n)" + (
                f" or excite above the hydraulic natural frequency ({f_h:.3g} Hz)"
                if excited < 1.5 * f_h else ""))
        if excited < 1.5 * f_h:
            return (f"excite above the hydraulic natural frequency ({f_h:.3g} Hz; the data "
                    f"reach {excited:.3g} Hz): a chirp to {2 * f_h:.3g} Hz (fuzzyservo "
                    f"identify --design)")
        return more
    if "valve" in fams:
        if excited < 0.5 * f_v:
            return (f"excite up to the valve's bandwidth ({f_v:.3g} Hz; the data reach "
                    f"{excited:.3g} Hz) with pressures logged at "
                    f"{max(1000.0, 10 * f_v):.0f} Hz or more (identify --design --f-max), or "
                    f"take omega_v from the datasheet")
        return more + ", or take the valve's dynamics from its datasheet"
    if "friction" in fams:
        return ("move at several constant speeds of both signs (slow ramps), so friction and "
                "viscous damping act at different velocities")
    if "leakage" in fams:
        return ("log the chamber pressures while the valve is held at null and while the "
                "axis pushes against a load or an end stop")
    if "gain" in fams:
        return ("log moves at several command amplitudes of both signs (the flow gain is the "
                "slope of velocity against command)")
    if excited < 1.5 * f_h:
        return ("excite more: steps of both signs and a chirp above the hydraulic natural "
                f"frequency ({f_h:.3g} Hz; fuzzyservo identify --design)")
    return more


def identifiability_warnings(names: Sequence[str], estimate: FloatArray, std_error: FloatArray,
                             correlation: FloatArray, *, channels: Sequence[str],
                             omega_0: float, omega_v: float,
                             excited: float = 0.0,
                             undetermined: Sequence[Sequence[int]] = ()) -> list[str]:
    """One line per parameter the data do not identify (standard error larger than the
    estimate) and per pair they do not separate (|correlation| > :data:`CORRELATION_LIMIT`),
    each naming the experiment that would (:func:`remedy`; ``omega_0``, ``omega_v`` [rad/s]
    of the identified axis, ``excited`` the band the data's excitation covers [Hz]). A pair's
    line gives both standard errors: they already include the correlation, so small ones mean
    the pair is determined all the same. ``undetermined`` lists groups of indices the data
    determine only in combination (a direction along which nothing changes): one line per
    group, which says to hold all but one of them, and no other line for them."""
    pressures = any(c in channels for c in ("p_f", "p_n"))
    out: list[str] = []
    grouped: set[int] = set()
    for group in undetermined:
        members = [names[k] for k in group]
        grouped.update(group)
        if len(members) == 1:
            out.append(f"{members[0]} does not act on these data at all (nothing the model "
                       f"logs changes with it): hold it at a known value, or log a signal it "
                       f"moves")
        else:
            out.append(f"{', '.join(members[:-1])} and {members[-1]} act on these data only "
                       f"together (a combination of them is determined, not each): fit one "
                       f"and hold the others at known values (a datasheet's)")
    for i, n in enumerate(names):
        if i in grouped:
            continue
        est, se = float(estimate[i]), float(std_error[i])
        if not math.isfinite(se) or se > abs(est):
            how = remedy([n], pressures=pressures, omega_0=omega_0, omega_v=omega_v,
                         excited=excited)
            out.append(f"{n} is not identifiable from these data ({est:.4g} ± {se:.2g}, the "
                       f"standard error exceeds the estimate): {how}")
    p = len(names)
    for i in range(p):
        for j in range(i + 1, p):
            if i in grouped or j in grouped:
                continue
            r = float(correlation[i, j])
            if abs(r) > CORRELATION_LIMIT:
                src = "position and pressures" if pressures else "position alone"
                rel = [float(std_error[k]) / abs(float(estimate[k])) * 100.0
                       if float(estimate[k]) else math.inf for k in (i, j)]
                out.append(f"{names[i]} and {names[j]} are not separable from {src} "
                           f"(correlation {r:+.3f}; standard errors {rel[0]:.2g} % and "
                           f"{rel[1]:.2g} %, which include it): "
                           + remedy([names[i], names[j]], pressures=pressures,
                                    omega_0=omega_0, omega_v=omega_v, excited=excited))
    return out


