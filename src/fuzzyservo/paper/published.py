"""Numbers quoted from the paper (Table A.1) and the parameter sets derived from them.

Aly, A. A. (2012), *Intelligent PI fuzzy control of an electro-hydraulic manipulator*,
IJISA 4(7):43-49, doi:10.5815/ijisa.2012.07.06, Appendix A, Table A.1.

:data:`TABLE_A1` holds the table as printed (with the paper's units), the readings the
project takes (70 MPa read as 7 MPa, the flow gain read as the rated no-load extension flow),
and :func:`paper_params` / :func:`stiff_oil_params` derive complete, consistent sets from it
plus documented physical choices (docs/model.md, "Default parameter sets"). Nothing here is a
result typed in: the mass follows from K_c, ω₀ and δ; the hose volume and the valve's null
leakage are solved so that the linearised model has ω₀ = 19.6 rad/s and δ = 0.1 at
mid-stroke, and the tests re-check that independently.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType

import numpy as np
from scipy import optimize

from ..errors import ParameterError
from ..plant.linearize import linearize
from ..plant.params import (
    CylinderParams,
    DelayParams,
    FluidParams,
    LoadParams,
    ServoParams,
    SupplyParams,
    TransducerParams,
    ValveParams,
)

__all__ = [
    "PAPER_PIDS",
    "PHYSICAL_CHOICES",
    "SET_NAMES",
    "TABLE_A1",
    "PaperPID",
    "PhysicalChoices",
    "TableA1",
    "named_set",
    "paper_params",
    "stiff_oil_params",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class TableA1:
    """Table A.1 of the paper, as printed, converted to SI where the unit is unambiguous."""

    piston_diameter: float = 112.7e-3  #: "Diameter of piston 112.7 mm" [m]
    rod_diameter: float = 70.4e-3  #: "Diameter of piston rod 70.4 mm" [m]
    stroke: float = 1000e-3  #: "Stroke 1000 mm" [m]
    natural_frequency: float = 19.6  #: "Load natural frequency 19.6 rad/s" (= ω₀) [rad/s]
    damping_ratio: float = 0.1  #: "Load damping ratio 0.1" (= δ) [1]
    flow_pressure_coefficient: float = 4.425e-11  #: "Total flow pressure coeff." K_c [m³/(s·Pa)]
    valve_flow_gain_printed: float = 2.613e-3  #: "Valve flow gain, no load" [m³/s per mA]
    omega_v: float = 688.7  #: "Natural frequency of servo valve" [rad/s]
    zeta_v: float = 0.3572  #: "Damping factor of servo valve" [1]
    supply_pressure_printed: float = 70e6  #: "Supply pressure 70 MPa" as printed [Pa]
    supply_ripple: float = 500e3  #: "± 500 kPa" [Pa]
    hose_delay: float = 0.006  #: "House - delay time 0.006 s" [s]

    @property
    def rated_flow(self) -> float:
        """Project reading: the flow gain is the no-load extension flow at rated input [m³/s]."""
        return self.valve_flow_gain_printed * 1.0

    @property
    def supply_pressure(self) -> float:
        """Project reading: "70 MPa" is 70 bar = 7 MPa (Moog's rating drop) [Pa]."""
        return self.supply_pressure_printed / 10.0


TABLE_A1 = TableA1()


@dataclass(frozen=True, slots=True, kw_only=True)
class PhysicalChoices:
    """Values the paper does not give, chosen from the literature (docs/model.md)."""

    density: float = 870.0  #: mineral oil [kg/m³]
    discharge_coefficient: float = 0.61  #: sharp-edged orifice [1]
    oil_bulk_modulus: float = 1.5e9  #: oil (Project Chrono default) [Pa]
    cylinder_wall_bulk_modulus: float = 31.5e9  #: steel tube (Chrono default) [Pa]
    hose_wall_bulk_modulus: float = 0.15e9  #: hose wall (Chrono default) [Pa]
    laminar_pressure: float = 1.0e5  #: orifice laminar transition, 1 bar [Pa]
    coulomb_friction: float = 1000.0  #: seal friction of a 113 mm cylinder [N]
    static_friction: float = 1300.0  #: breakaway = 1.3 F_c [N]
    stribeck_velocity: float = 0.01  #: [m/s]
    stop_stiffness: float = 1.0e9  #: end-stop cushion spring [N/m]
    ripple_frequency: float = 225.0  #: 9-piston pump at 1500 rpm [Hz]
    stiff_oil_bulk_modulus: float = 1.4e9  #: stiff-oil set: oil with no hose [Pa]
    stiff_oil_dead_volume: float = 0.3e-3  #: stiff-oil set: dead volume per side [m³]


PHYSICAL_CHOICES = PhysicalChoices()


def _areas(t: TableA1) -> tuple[float, float, float]:
    af = math.pi / 4.0 * t.piston_diameter**2
    an = math.pi / 4.0 * (t.piston_diameter**2 - t.rod_diameter**2)
    return af, an, 0.5 * (af + an)


def _base(t: TableA1, ch: PhysicalChoices, mass: float, *, hose_volume: float,
          dead_volume: float, oil_bulk_modulus: float) -> ServoParams:
    return ServoParams(
        cylinder=CylinderParams(
            bore=t.piston_diameter, rod_diameter=t.rod_diameter, stroke=t.stroke,
            dead_volume_f=dead_volume, dead_volume_n=dead_volume,
            stop_stiffness=ch.stop_stiffness,
            # critically damped cushion for this mass
            stop_damping=2.0 * math.sqrt(ch.stop_stiffness * mass),
        ),
        valve=ValveParams(
            rated_flow=t.rated_flow, discharge_coefficient=ch.discharge_coefficient,
            omega_v=t.omega_v, zeta_v=t.zeta_v, tau_v=0.0, laminar_pressure=ch.laminar_pressure,
        ),
        fluid=FluidParams(
            density=ch.density, oil_bulk_modulus=oil_bulk_modulus, hose_volume=hose_volume,
            cylinder_wall_bulk_modulus=ch.cylinder_wall_bulk_modulus,
            hose_wall_bulk_modulus=ch.hose_wall_bulk_modulus,
        ),
        load=LoadParams(
            mass=mass, coulomb_friction=ch.coulomb_friction, static_friction=ch.static_friction,
            stribeck_velocity=ch.stribeck_velocity,
        ),
        supply=SupplyParams(pressure=t.supply_pressure, ripple_frequency=ch.ripple_frequency),
        delay=DelayParams(transport_delay=t.hose_delay),
        transducer=TransducerParams(),
    )


def _solve_two(f: Callable[[float, float], tuple[float, float]], z0: tuple[float, float],
               what: str) -> tuple[float, float]:
    def res(z: np.ndarray) -> np.ndarray:
        return np.asarray(f(float(z[0]), float(z[1])))

    sol = optimize.root(res, np.asarray(z0), method="hybr", options={"xtol": 1e-12})
    if not sol.success or float(np.max(np.abs(res(sol.x)))) > 1e-9:
        raise ParameterError(f"cannot derive {what} from Table A.1: {sol.message}")
    return float(sol.x[0]), float(sol.x[1])


def paper_params(table: TableA1 = TABLE_A1,
                 choices: PhysicalChoices = PHYSICAL_CHOICES) -> ServoParams:
    """The default set ``"paper"`` ("Set A" of the model notes), derived from Table A.1.

    1. M = 2 A_e² δ / (K_c ω₀) with B_p = 0: the largest mass for which the Table's K_c alone
       gives δ (Merritt's δ = K_c ω₀ M/(2 A_e²) + B_p/(2 ω₀ M)).
    2. Hose volume per line and valve null leakage K_l0 solved together so that the
       numerical linearisation of the nonlinear model at mid-stroke has ω₀ and δ of the Table.

    Every Table A.1 value is kept; see docs/model.md for the readings of the flow gain and of
    the supply pressure.
    """
    af, an, ae = _areas(table)
    w0, d0 = table.natural_frequency, table.damping_ratio
    mass = 2.0 * ae**2 * d0 / (table.flow_pressure_coefficient * w0)
    base = _base(table, choices, mass, hose_volume=2.8e-3, dead_volume=0.0,
                 oil_bulk_modulus=choices.oil_bulk_modulus)

    def miss(hose_l: float, kl_e11: float) -> tuple[float, float]:
        p = replace(base, fluid=replace(base.fluid, hose_volume=abs(hose_l) * 1e-3),
                    valve=replace(base.valve, null_leakage=abs(kl_e11) * 1e-11))
        lin = linearize(p)
        return lin.omega_0 / w0 - 1.0, lin.damping / d0 - 1.0

    # start from the ideal-gas-free estimate β_h/V_t = ω₀ δ/(2 K_c), K_l0 = K_c/2 (2 lands/side)
    hose_l, kl = _solve_two(miss, (2.8, table.flow_pressure_coefficient / 2.0 * 1e11),
                            "hose volume and null leakage")
    return replace(base, fluid=replace(base.fluid, hose_volume=abs(hose_l) * 1e-3),
                   valve=replace(base.valve, null_leakage=abs(kl) * 1e-11))


def stiff_oil_params(table: TableA1 = TABLE_A1,
                     choices: PhysicalChoices = PHYSICAL_CHOICES) -> ServoParams:
    """The set ``"stiff-oil"`` ("Set B"): stiff oil, no hose, no leakage, damping by B_p.

    Oil at 1.4 GPa, 0.3 L dead volume per side, no hose and no leakage; the mass and the
    viscous damping are solved so that the linearisation at mid-stroke has the Table's ω₀ and
    δ. ω₀ then varies strongly along the stroke (robustness studies). The Table's K_c cannot
    hold in this set.
    """
    base = _base(table, choices, 1.0e5, hose_volume=0.0,
                 dead_volume=choices.stiff_oil_dead_volume,
                 oil_bulk_modulus=choices.stiff_oil_bulk_modulus)
    w0, d0 = table.natural_frequency, table.damping_ratio

    def with_mb(m_t: float, b_kn: float) -> ServoParams:
        m = abs(m_t) * 1e3
        return replace(base, load=replace(base.load, mass=m, viscous_damping=abs(b_kn) * 1e3),
                       cylinder=replace(base.cylinder,
                                        stop_damping=2.0 * math.sqrt(choices.stop_stiffness * m)))

    def miss(m_t: float, b_kn: float) -> tuple[float, float]:
        lin = linearize(with_mb(m_t, b_kn))
        return lin.omega_0 / w0 - 1.0, lin.damping / d0 - 1.0

    m_t, b_kn = _solve_two(miss, (100.0, 400.0), "mass and damping of the stiff-oil set")
    return with_mb(m_t, b_kn)


#: The named parameter sets (``--set NAME``), each a function of the published data.
_SETS: dict[str, Callable[[], ServoParams]] = {"paper": paper_params,
                                                "stiff-oil": stiff_oil_params}

#: Names accepted by :func:`named_set` and ``--set``.
SET_NAMES: tuple[str, ...] = tuple(_SETS)


@dataclass(frozen=True, slots=True, kw_only=True)
class PaperPID:
    """A PID of the paper (Sec. IV, Figs. 4-5), parallel form, gains as printed.

    The paper's gains were in volts of an unstated transducer and amplifier; used here as
    gains per metre of error on a command that is a fraction of rated input (docs/model.md).
    """

    kp: float  #: K_P [1/m]
    ki: float  #: K_I [1/(m s)]
    kd: float  #: K_D [s/m]


#: The paper's two PIDs, Sec. IV: "(K_P = 1.2, K_I = 1, K_D = 0.75)" (at most 10 % overshoot,
#: no steady-state error) and "(K_P = 0.8, K_I = .55, K_D = 0.5)" (zero overshoot).
PAPER_PIDS: Mapping[str, PaperPID] = MappingProxyType({
    "pid_paper_1": PaperPID(kp=1.2, ki=1.0, kd=0.75),
    "pid_paper_2": PaperPID(kp=0.8, ki=0.55, kd=0.5),
})


def named_set(name: str) -> ServoParams:
    """Build the named parameter set (``"paper"`` or ``"stiff-oil"``).

    Each set is derived once per process (a root solve over the linearised model) and the
    same frozen value returned after that.

    Raises
    ------
    ParameterError
        For an unknown name.
    """
    if not isinstance(name, str) or name not in _SETS:
        raise ParameterError(f"unknown parameter set {name!r}; allowed: "
                             f"{', '.join(SET_NAMES)}")
    return _derived(name)


@functools.cache
def _derived(name: str) -> ServoParams:
    """The set ``name`` of :data:`_SETS`: a frozen value of the frozen Table A.1 and
    physical choices, so computing it once is the same as computing it every time."""
    return _SETS[name]()
