"""The open loop as a controller: the command schedule passes through, the measurement is unused.

An open-loop run is a closed loop whose "controller" issues a given command sequence: the
simulator feeds the schedule in place of the reference, and the step of :data:`COMMAND_LAW`
returns it. So the open loop uses the very loops, hold, delay handling and plant
functions of the closed loop (:func:`fuzzyservo.sim.simulate_open_loop`). Not a controller a
user names: it is not in the registry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .._jit import kernel
from .._typing import FloatArray
from ..errors import ParameterError
from .law import Law, LawController

__all__ = ["COMMAND_LAW", "CommandSchedule", "CommandState"]


@kernel(inline=True)
def _pass_through(p: Any, s: Any, r: float, y: float, aux: Any, rd: float,
                  rdd: float) -> float:
    """The command is the schedule sample given as the reference."""
    return r


@kernel(inline=True)
def _no_aux(tables: Any) -> float:
    return 0.0


def _pack(g: FloatArray, k: FloatArray) -> FloatArray:
    return np.zeros((g.shape[0], 0))


def _rest(packed: FloatArray, y0: float, u0: float) -> FloatArray:
    return np.zeros((packed.shape[0], 0))


#: The open loop's "law": the command passes through; no parameters, no state.
COMMAND_LAW = Law(name="command", title="the open loop (a command schedule)", params=(),
                  state=(), gains=(), constants=(), step=_pass_through, prepare=_no_aux,
                  pack=_pack, rest=_rest)


@dataclass(frozen=True, slots=True)
class CommandState:
    """The open loop keeps no state."""


@dataclass(frozen=True, slots=True, kw_only=True)
class CommandSchedule(LawController):
    """Pass-through "controller": the command is the schedule sample given as the reference.

    Parameters
    ----------
    dt : float
        Sample period of the schedule [s].
    """

    dt: float  #: sample period [s]

    law: ClassVar[Law] = COMMAND_LAW
    state_class: ClassVar[type] = CommandState
    gain_names: ClassVar[tuple[str, ...]] = ()

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ParameterError(f"sample time dt must be finite and > 0 s, got {self.dt!r}")

    def initial_state(self) -> CommandState:
        """The (empty) state."""
        return CommandState()

    def law_constants(self) -> FloatArray:
        """None."""
        return np.zeros(0)

    def step(self, state: Any, reference: float, measurement: float, *,
             reference_rate: float = 0.0, reference_acceleration: float = 0.0
             ) -> tuple[float, Any]:
        """The command is the schedule sample ``reference`` [-]; ``measurement`` and the
        reference's rates are unused."""
        del measurement, reference_rate, reference_acceleration
        return float(reference), state
