"""fuzzyservo.plant: parameters, linear model (eq. 8) and nonlinear two-chamber model."""

from .linear import LinearServo
from .linearize import Linearization, Trim, linearize, trim
from .nonlinear import (
    COMMAND_LIMIT,
    N_PARAMS,
    N_STATE,
    STATE_NAMES,
    STATE_UNITS,
    NonlinearServo,
    pack,
    rhs,
    rk4_advance,
    rk4_advance_ws,
)
from .params import (
    CylinderParams,
    DelayParams,
    FluidParams,
    LoadParams,
    ServoParams,
    SupplyParams,
    TransducerParams,
    ValveParams,
    allowed_names,
    load_toml,
    to_dict,
    with_overrides,
)
from .zoh import DiscreteModel, discretize, split_delay

__all__ = [
    "COMMAND_LIMIT",
    "CylinderParams",
    "DelayParams",
    "DiscreteModel",
    "FluidParams",
    "LinearServo",
    "Linearization",
    "LoadParams",
    "N_PARAMS",
    "N_STATE",
    "NonlinearServo",
    "STATE_NAMES",
    "STATE_UNITS",
    "ServoParams",
    "SupplyParams",
    "TransducerParams",
    "Trim",
    "ValveParams",
    "allowed_names",
    "discretize",
    "linearize",
    "load_toml",
    "pack",
    "rhs",
    "rk4_advance",
    "rk4_advance_ws",
    "split_delay",
    "to_dict",
    "trim",
    "with_overrides",
]
