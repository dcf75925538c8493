"""Parameter objects of the electro-hydraulic servo, in SI units.

Every group is a frozen, slotted, keyword-only dataclass validated on construction; make
variants with :func:`dataclasses.replace` or :func:`with_overrides`. :class:`ServoParams`
groups them. Named sets (``"paper"``, ``"stiff-oil"``) live in
:mod:`fuzzyservo.paper.published`; this module does not import it.

Pressures are absolute with the tank at ``supply.tank_pressure`` (the paper assumes zero
return pressure, eqs. 2-3). The valve command ``u`` is a fraction of the rated input,
limited to [-1, 1]; ``valve.rated_flow`` is the no-load extension flow at ``u = 1`` and the
nominal supply pressure (docs/model.md, "Flow gain").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from .._io import parse_toml, read_text
from ..errors import ParameterError

__all__ = [
    "CylinderParams",
    "DelayParams",
    "FluidParams",
    "GROUPS",
    "LoadParams",
    "MIN_SUPPLY_PRESSURE",
    "RECORD_TABLE",
    "ServoParams",
    "SupplyParams",
    "TransducerParams",
    "ValveParams",
    "allowed_names",
    "field_unit",
    "load_toml",
    "read_overrides_toml",
    "to_dict",
    "with_overrides",
]


def _finite(owner: str, name: str, value: float) -> None:
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        raise ParameterError(f"{owner}.{name} must be a finite number, got {value!r}")


def _positive(owner: str, name: str, value: float) -> None:
    _finite(owner, name, value)
    if not value > 0.0:
        raise ParameterError(f"{owner}.{name} must be > 0, got {value!r}")


def _nonnegative(owner: str, name: str, value: float) -> None:
    _finite(owner, name, value)
    if not value >= 0.0:
        raise ParameterError(f"{owner}.{name} must be >= 0, got {value!r}")


@dataclass(frozen=True, slots=True, kw_only=True)
class CylinderParams:
    """Single-rod (asymmetric) cylinder with end-stop cushions. Source: paper Table A.1."""

    bore: float  #: piston diameter D [m]
    rod_diameter: float  #: rod diameter d, 0 < d < D [m]
    stroke: float  #: stroke L; the piston moves in [0, L] [m]
    dead_volume_f: float = 0.0  #: full-bore chamber volume at x = 0, excluding hose [m³]
    dead_volume_n: float = 0.0  #: annulus chamber volume at x = L, excluding hose [m³]
    internal_leakage: float = 0.0  #: cross-piston laminar leakage C_li [m³/(s·Pa)]
    stop_stiffness: float = 1.0e9  #: end-stop cushion spring beyond 0 and L [N/m]
    stop_damping: float = 0.0  #: end-stop cushion damper, acts only while in contact [N·s/m]

    def __post_init__(self) -> None:
        o = "cylinder"
        _positive(o, "bore", self.bore)
        _positive(o, "rod_diameter", self.rod_diameter)
        if not self.rod_diameter < self.bore:
            raise ParameterError(
                f"cylinder.rod_diameter must be smaller than cylinder.bore = {self.bore!r} m, "
                f"got {self.rod_diameter!r} m"
            )
        _positive(o, "stroke", self.stroke)
        for name in ("dead_volume_f", "dead_volume_n", "internal_leakage", "stop_damping"):
            _nonnegative(o, name, getattr(self, name))
        _positive(o, "stop_stiffness", self.stop_stiffness)

    @property
    def piston_area(self) -> float:
        """Full-bore area A_f = π D²/4 [m²]."""
        return math.pi / 4.0 * self.bore**2

    @property
    def ring_area(self) -> float:
        """Annulus area A_n = π (D² - d²)/4 [m²]."""
        return math.pi / 4.0 * (self.bore**2 - self.rod_diameter**2)

    @property
    def area_ratio(self) -> float:
        """r = A_n / A_f [1]."""
        return self.ring_area / self.piston_area


@dataclass(frozen=True, slots=True, kw_only=True)
class ValveParams:
    """4/3 critically lapped servo valve with symmetric ports, paper eqs. (1)-(3)."""

    rated_flow: float  #: no-load extension flow at u = 1 and nominal supply [m³/s]
    discharge_coefficient: float = 0.61  #: orifice discharge coefficient C_d, in (0, 1] [1]
    omega_v: float  #: spool natural frequency ω_v, eq. (1) [rad/s]
    zeta_v: float  #: spool damping ratio ζ_v, eq. (1) [1]
    tau_v: float = 0.0  #: optional first-order stage τ_v of eq. (1); 0 = absent [s]
    null_leakage: float = 0.0  #: laminar leakage of each of the 4 lands at null K_l0 [m³/(s·Pa)]
    laminar_pressure: float = 1.0e5  #: orifice laminar-transition pressure p_cr [Pa]

    def __post_init__(self) -> None:
        o = "valve"
        _positive(o, "rated_flow", self.rated_flow)
        _finite(o, "discharge_coefficient", self.discharge_coefficient)
        if not 0.0 < self.discharge_coefficient <= 1.0:
            raise ParameterError(
                f"valve.discharge_coefficient must be in (0, 1], got {self.discharge_coefficient!r}"
            )
        _positive(o, "omega_v", self.omega_v)
        _positive(o, "zeta_v", self.zeta_v)
        _nonnegative(o, "tau_v", self.tau_v)
        _nonnegative(o, "null_leakage", self.null_leakage)
        _positive(o, "laminar_pressure", self.laminar_pressure)


@dataclass(frozen=True, slots=True, kw_only=True)
class FluidParams:
    """Oil and line compliance; the compliances add in series (docs/model.md)."""

    density: float = 870.0  #: oil density ρ [kg/m³]
    oil_bulk_modulus: float = 1.5e9  #: bulk modulus of the oil itself [Pa]
    cylinder_wall_bulk_modulus: float = 31.5e9  #: cylinder-wall compliance as a modulus [Pa]
    hose_volume: float = 0.0  #: oil volume of the hose of each line [m³]
    hose_wall_bulk_modulus: float = 0.15e9  #: hose-wall compliance as a modulus [Pa]
    pressure_floor: float = 0.0  #: lowest absolute chamber pressure (cavitation floor) [Pa]

    def __post_init__(self) -> None:
        o = "fluid"
        for name in ("density", "oil_bulk_modulus", "cylinder_wall_bulk_modulus",
                     "hose_wall_bulk_modulus"):
            _positive(o, name, getattr(self, name))
        _nonnegative(o, "hose_volume", self.hose_volume)
        _nonnegative(o, "pressure_floor", self.pressure_floor)

    @property
    def cylinder_bulk_modulus(self) -> float:
        """Effective modulus of oil in the cylinder, 1/(1/β_oil + 1/β_wall) [Pa]."""
        return 1.0 / (1.0 / self.oil_bulk_modulus + 1.0 / self.cylinder_wall_bulk_modulus)

    @property
    def hose_bulk_modulus(self) -> float:
        """Effective modulus of oil in the hose, 1/(1/β_oil + 1/β_hose) [Pa]."""
        return 1.0 / (1.0 / self.oil_bulk_modulus + 1.0 / self.hose_wall_bulk_modulus)


@dataclass(frozen=True, slots=True, kw_only=True)
class LoadParams:
    """Mass-damper load of eq. (5) with Stribeck friction and an external force."""

    mass: float  #: effective moving mass M [kg]
    viscous_damping: float = 0.0  #: viscous coefficient B_p = B_l + K_vf [N·s/m]
    coulomb_friction: float = 0.0  #: Coulomb friction F_c [N]
    static_friction: float = 0.0  #: breakaway (Stribeck peak) friction F_s >= F_c [N]
    stribeck_velocity: float = 0.01  #: Stribeck velocity v_s [m/s]
    friction_smoothing_velocity: float = 1.0e-3  #: ε of tanh(v/ε) replacing sgn(v) [m/s]
    external_force: float = 0.0  #: load force F_L opposing extension [N]

    def __post_init__(self) -> None:
        o = "load"
        _positive(o, "mass", self.mass)
        for name in ("viscous_damping", "coulomb_friction", "static_friction"):
            _nonnegative(o, name, getattr(self, name))
        if self.static_friction < self.coulomb_friction:
            raise ParameterError(
                f"load.static_friction must be >= load.coulomb_friction = "
                f"{self.coulomb_friction!r} N, got {self.static_friction!r} N"
            )
        _positive(o, "stribeck_velocity", self.stribeck_velocity)
        _positive(o, "friction_smoothing_velocity", self.friction_smoothing_velocity)
        _finite(o, "external_force", self.external_force)


#: Lowest supply pressure [Pa]: 1 bar absolute, the atmosphere. ``pressure`` is absolute, so
#: below it the "supply" is a vacuum that drives no oil; the model would still integrate
#: (flows go as the square root of the pressure drop) and linearise to a servo of velocity
#: gain ~0 (``linearize --param supply.pressure=1e-300`` gave an eigenvalue of 0). Industrial
#: supplies are 20 to 350 bar; the paper's is 70 bar.
MIN_SUPPLY_PRESSURE = 1.0e5


@dataclass(frozen=True, slots=True, kw_only=True)
class SupplyParams:
    """Constant-pressure supply with optional sinusoidal ripple; tank at tank_pressure."""

    pressure: float  #: nominal supply pressure P_s (absolute), >= 1 bar [Pa]
    tank_pressure: float = 0.0  #: return pressure P_T (absolute) [Pa]
    ripple_amplitude: float = 0.0  #: supply ripple amplitude, paper's ±500 kPa [Pa]
    ripple_frequency: float = 225.0  #: supply ripple frequency [Hz]

    def __post_init__(self) -> None:
        o = "supply"
        _positive(o, "pressure", self.pressure)
        if not self.pressure >= MIN_SUPPLY_PRESSURE:
            raise ParameterError(
                f"supply.pressure must be at least {MIN_SUPPLY_PRESSURE:g} Pa (1 bar absolute: "
                f"below the atmosphere there is no supply), got {self.pressure!r} Pa")
        _nonnegative(o, "tank_pressure", self.tank_pressure)
        if not self.tank_pressure < self.pressure:
            raise ParameterError(
                f"supply.tank_pressure must be below supply.pressure = {self.pressure!r} Pa, "
                f"got {self.tank_pressure!r} Pa"
            )
        _nonnegative(o, "ripple_amplitude", self.ripple_amplitude)
        if not self.ripple_amplitude < self.pressure - self.tank_pressure:
            raise ParameterError(
                f"supply.ripple_amplitude must be below P_s - P_T = "
                f"{self.pressure - self.tank_pressure!r} Pa, got {self.ripple_amplitude!r} Pa"
            )
        _nonnegative(o, "ripple_frequency", self.ripple_frequency)


@dataclass(frozen=True, slots=True, kw_only=True)
class DelayParams:
    """Hose transport delay, applied to the valve command. Source: paper Table A.1."""

    transport_delay: float = 0.006  #: dead time between command and valve [s]

    def __post_init__(self) -> None:
        _nonnegative("delay", "transport_delay", self.transport_delay)


@dataclass(frozen=True, slots=True, kw_only=True)
class TransducerParams:
    """Position transducer: K_tr = 1 m/m, additive white noise, then quantisation."""

    noise_std: float = 0.0  #: standard deviation of the measurement noise [m]
    resolution: float = 0.0  #: quantisation step of the measurement; 0 = none [m]

    def __post_init__(self) -> None:
        _nonnegative("transducer", "noise_std", self.noise_std)
        _nonnegative("transducer", "resolution", self.resolution)


@dataclass(frozen=True, slots=True, kw_only=True)
class ServoParams:
    """All parameters of the servo: valve, cylinder, fluid, load, supply, delay, transducer."""

    cylinder: CylinderParams  #: cylinder geometry, leakage and end stops
    valve: ValveParams  #: servo valve
    fluid: FluidParams  #: oil and line compliance
    load: LoadParams  #: load mass, damping, friction, external force
    supply: SupplyParams  #: supply and tank pressures
    delay: DelayParams  #: hose transport delay
    transducer: TransducerParams  #: position transducer

    def __post_init__(self) -> None:
        for side, dead in (("f", self.cylinder.dead_volume_f), ("n", self.cylinder.dead_volume_n)):
            if dead + self.fluid.hose_volume <= 0.0:
                raise ParameterError(
                    f"cylinder.dead_volume_{side} + fluid.hose_volume must be > 0 (the chamber "
                    f"would have no oil at its end stop), got {dead!r} + "
                    f"{self.fluid.hose_volume!r} m³"
                )

    @property
    def orifice_coefficient(self) -> float:
        """G = C_d W x_v,max sqrt(2/ρ), so that Q = G u sqrt(Δp) [m³/(s·Pa^0.5)].

        Derived from the rated flow read as the no-load extension flow at u = 1:
        Q_rated = G sqrt((P_s - P_T)/(1 + r³)) (docs/model.md, "Flow gain").
        """
        r3 = self.cylinder.area_ratio**3
        return self.valve.rated_flow * math.sqrt((1.0 + r3) / (self.supply.pressure
                                                               - self.supply.tank_pressure))

    @property
    def spool_area_gradient(self) -> float:
        """W x_v,max, the fully open orifice area at u = 1 [m²]."""
        return self.orifice_coefficient / (self.valve.discharge_coefficient
                                           * math.sqrt(2.0 / self.fluid.density))

    @property
    def velocity_gain(self) -> float:
        """K_o = Q_rated / A_f, eq. (8) gain with K_a = K_tr = 1 [m/s per unit command]."""
        return self.valve.rated_flow / self.cylinder.piston_area


#: The table of a parameter file that records how it was made (``fuzzyservo identify``
#: writes the data's digest, the estimates and their uncertainty there); readers skip it.
RECORD_TABLE = "identification"

GROUPS: dict[str, type] = {
    "cylinder": CylinderParams,
    "valve": ValveParams,
    "fluid": FluidParams,
    "load": LoadParams,
    "supply": SupplyParams,
    "delay": DelayParams,
    "transducer": TransducerParams,
}


def allowed_names() -> list[str]:
    """All ``group.field`` names a parameter file or ``--param`` may set."""
    return [f"{g}.{f.name}" for g, cls in GROUPS.items() for f in fields(cls)]


def field_unit(name: str) -> str:
    """The unit of parameter ``group.field`` as its field's doc comment gives it (``#: ...
    [unit]``, e.g. ``kg`` for ``load.mass``), or "SI" when the comment names none.

    Raises
    ------
    ParameterError
        For an unknown name.
    """
    import inspect
    import re

    if name not in allowed_names():
        raise ParameterError(f"unknown parameter {name!r}; allowed names: "
                             f"{', '.join(allowed_names())}")
    group, fname = name.split(".", 1)
    try:
        src = inspect.getsource(GROUPS[group])
    except (OSError, TypeError):  # no source (a frozen install): no unit
        return "SI"
    m = re.search(rf"^\s*{re.escape(fname)}\s*:.*#:.*\[([^\]]+)\]\s*$", src, re.MULTILINE)
    return m.group(1) if m else "SI"


def to_dict(params: ServoParams) -> dict[str, dict[str, float]]:
    """Nested ``{group: {field: value}}`` of every parameter (the TOML file format)."""
    return {g: {f.name: float(getattr(getattr(params, g), f.name)) for f in fields(cls)}
            for g, cls in GROUPS.items()}


def with_overrides(params: ServoParams, overrides: Mapping[str, Any]) -> ServoParams:
    """Return ``params`` with ``{"group.field": value}`` replaced, validated once at the end.

    Raises
    ------
    ParameterError
        For an unknown name (the message lists the allowed ones) or an invalid value.
    """
    allowed = allowed_names()
    by_group: dict[str, dict[str, float]] = {}
    for name, value in overrides.items():
        if name not in allowed:
            raise ParameterError(
                f"unknown parameter {name!r}; allowed names: {', '.join(allowed)}"
            )
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ParameterError(f"parameter {name} must be a number, got {value!r}")
        group, field_name = name.split(".", 1)
        try:
            number = float(value)
        except OverflowError:
            raise ParameterError(f"parameter {name} is too large for a float, got "
                                 f"{value!r:.40}") from None
        by_group.setdefault(group, {})[field_name] = number
    new_groups = {g: replace(getattr(params, g), **kw) for g, kw in by_group.items()}
    return replace(params, **new_groups)


def read_overrides_toml(path: str | Path) -> dict[str, float]:
    """Read ``[group] field = value`` tables from a TOML file as ``{"group.field": value}``
    overrides, in file order (not yet applied or validated against a set; see
    :func:`with_overrides`).

    Raises
    ------
    InputError
        If the file cannot be read, is not UTF-8 text (the message names the byte offset) or is
        not valid TOML.
    ParameterError
        For an unknown group.
    """
    text = read_text(path, "parameter file")
    data = parse_toml(text, f"parameter file {str(path)!r}")
    flat: dict[str, Any] = {}
    for group, table in data.items():
        if group == RECORD_TABLE:
            continue  # how the file was made (``fuzzyservo identify``): not a parameter
        if group not in GROUPS:
            raise ParameterError(
                f"unknown parameter group {group!r} in {str(path)!r}; allowed groups: "
                f"{', '.join(GROUPS)}"
            )
        if not isinstance(table, dict):
            raise ParameterError(f"{group!r} in {str(path)!r} must be a table ([{group}] "
                                 f"with field = value lines), got {table!r:.40}")
        for name, value in table.items():
            flat[f"{group}.{name}"] = value
    return flat


def load_toml(path: str | Path, base: ServoParams) -> ServoParams:
    """Read ``[group] field = value`` tables from a TOML file as overrides of ``base``.

    A file listing every field fully defines a set; a partial file changes only what it names.

    Raises
    ------
    InputError
        If the file cannot be read, is not UTF-8 or is not valid TOML.
    ParameterError
        For an unknown group or field, or an invalid value.
    """
    return with_overrides(base, read_overrides_toml(path))
