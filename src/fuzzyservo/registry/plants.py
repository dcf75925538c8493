"""The plant registry: every plant model a user can name, registered once.

Three models of the servo, each usable in open and in closed loop, all started at rest at a
stroke position and all reporting absolute positions [m] (docs/model.md, "Plant models"):

``linear``
    The paper's eq. (8): valve (second order, optional lag), hydraulic second order with the
    ω₀ and δ of the linearisation at the start position, integrator, and the large-signal
    velocity gain K_o = Q_rated/A_f. States spool, spool_rate, v, a, x. No chamber pressures.
``small-signal``
    The numerical Jacobian of the nonlinear model around its trim at the start position
    (Coulomb friction left out): the nonlinear model's states, chamber pressures included,
    and its small-signal velocity gain (0.2095 m/s per unit command for the paper set, against
    eq. (8)'s 0.2619).
``nonlinear``
    The two-chamber model with orifice flows, leakage, friction, end stops, supply ripple and
    transducer resolution, integrated by RK4.

The command line's ``--plant`` choices, the tuner, the study and every later front end build
plants through :func:`build_plant`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

from .._args import given, real
from ..errors import ParameterError
from ..paper.published import SET_NAMES, named_set
from ..plant import LinearServo, ServoParams, linearize
from ..sim import LinearPlant, NonlinearPlant, Plant
from ._table import lookup

__all__ = [
    "DEFAULT_SUBSTEP",
    "PLANTS",
    "PlantKind",
    "build_plant",
    "plant_kind",
    "plant_names",
]

#: RK4 step bound of the nonlinear plant [s]: two steps per 1 ms sample (ω_v h = 0.34);
#: positions within 1e-6 of the step of a 25 µs-step run (tests/sim/test_closed_loop.py).
DEFAULT_SUBSTEP = 5.0e-4


@dataclass(frozen=True, slots=True, kw_only=True)
class PlantKind:
    """A plant model a user can name.

    Parameters
    ----------
    name : str
        The name (``--plant NAME``).
    title : str
        Short description.
    make : callable
        ``make(params, position, substep) -> Plant``: the model at rest at ``position`` [m]
        (``substep`` [s] is the RK4 step bound of a nonlinear plant, unused by linear ones).
    force_input : bool
        Whether the model's own force balance takes the external force (the nonlinear
        model; a sweep varies ``load.external_force`` only there). Every registered plant
        takes a load-force *disturbance* (``--load-force``): the linear ones through their
        force input, by superposition (``LinearPlant.force_response``).
    supply_ripple : bool
        Whether a supply-pressure ripple (``supply.ripple_amplitude``) reaches the model (the
        linearisations leave it out).
    ignores : tuple of str
        Parameters (``group.field``) the model leaves out: a run on it is the same whatever
        their values (``fuzzyservo simulate`` notes an override of one).
    start_gains : str or None
        The plant whose shipped tuned gains (``data/gains/PLANT-KIND.toml``) the browser page
        starts a run on this plant from (``small-signal``: the linear plant's, the model it
        refines); None: the plant's own.
    """

    name: str
    title: str
    make: Callable[[ServoParams, float, float], Plant]
    force_input: bool = False
    supply_ripple: bool = False
    ignores: tuple[str, ...] = ()
    start_gains: str | None = None


#: What the linearisations leave out: the measurement's rounding (only the nonlinear loop
#: rounds, sim.closed_loop.plant_limits) and the supply ripple.
_LINEAR_IGNORES = ("transducer.resolution", "supply.ripple_amplitude",
                   "supply.ripple_frequency")


def _linear(params: ServoParams, position: float, substep: float) -> Plant:
    del substep
    servo = LinearServo.from_params(params, linearize(params, position))
    return LinearPlant.from_servo(servo, position, stroke=params.cylinder.stroke,
                                  force_op=params.load.external_force)


def _small_signal(params: ServoParams, position: float, substep: float) -> Plant:
    del substep
    return LinearPlant.from_linearization(linearize(params, position))


def _nonlinear(params: ServoParams, position: float, substep: float) -> Plant:
    return NonlinearPlant.from_params(params, position, substep=substep)


_PLANTS: dict[str, PlantKind] = {
    "linear": PlantKind(name="linear", title="eq. (8), linearised at the start position",
                        make=_linear, ignores=_LINEAR_IGNORES),
    "small-signal": PlantKind(name="small-signal",
                              title="small-signal linearisation of the nonlinear model",
                              make=_small_signal, ignores=_LINEAR_IGNORES,
                              start_gains="linear"),
    "nonlinear": PlantKind(name="nonlinear", title="nonlinear two-chamber model (RK4)",
                           make=_nonlinear, force_input=True, supply_ripple=True),
}

#: Every plant kind by name (read-only view of the registry).
PLANTS: Mapping[str, PlantKind] = MappingProxyType(_PLANTS)


def plant_names() -> tuple[str, ...]:
    """The registered plant names, in registry order."""
    return tuple(_PLANTS)


def plant_kind(name: str) -> PlantKind:
    """The plant kind registered as ``name``.

    Raises
    ------
    ParameterError
        Unknown name (the message lists the registered ones).
    """
    return lookup(_PLANTS, name, "plant")


def build_plant(name: str, params: ServoParams | str, position: float | None = None, *,
                substep: float = DEFAULT_SUBSTEP) -> Plant:
    """Build the plant registered as ``name``, at rest at ``position``.

    Parameters
    ----------
    name : str
        Registered name (:func:`plant_names`): ``linear``, ``small-signal``, ``nonlinear``.
    params : ServoParams or str
        Servo parameters, or the name of a set (``"paper"``, ``"stiff-oil"``:
        :func:`fuzzyservo.paper.published.named_set`).
    position : float, optional
        Start position inside the stroke [m]; default mid-stroke.
    substep : float
        RK4 step bound of the nonlinear plant [s], > 0.

    Returns
    -------
    LinearPlant or NonlinearPlant

    Raises
    ------
    ParameterError
        Unknown name or set, parameters of another type, a position or substep that is not a
        number, a position outside the stroke, or no equilibrium there.
    """
    kind = plant_kind(name)
    if isinstance(params, str):
        params = named_set(params)
    if not isinstance(params, ServoParams):
        raise ParameterError(f"params must be a ServoParams or the name of a set "
                             f"({', '.join(SET_NAMES)}), got {given(params)}")
    pos = (0.5 * params.cylinder.stroke if position is None
           else real(position, "position", "m"))
    return kind.make(params, pos, real(substep, "substep", "s", positive=True))
