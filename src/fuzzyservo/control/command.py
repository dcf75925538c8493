"""The open loop as a controller: the command schedule passes through, the measurement is unused.

An open-loop run is a closed loop whose "controller" issues a given command sequence: the
simulator feeds the schedule in place of the reference, and :func:`controller_step` returns it
(kind ``KIND_COMMAND``). So the open loop uses the very loops, hold, delay handling and plant
functions of the closed loop (:func:`fuzzyservo.sim.simulate_open_loop`). Not a controller a
user names: it is not in the registry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import ParameterError
from .pid import no_tables

__all__ = ["CommandSchedule", "CommandState"]


@dataclass(frozen=True, slots=True)
class CommandState:
    """The open loop keeps no state."""


@dataclass(frozen=True, slots=True, kw_only=True)
class CommandSchedule:
    """Pass-through "controller": the command is the schedule sample given as the reference.

    Parameters
    ----------
    dt : float
        Sample period of the schedule [s].
    """

    dt: float  #: sample period [s]

    kind: ClassVar[int] = 2
    gain_names: ClassVar[tuple[str, ...]] = ()

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ParameterError(f"sample time dt must be finite and > 0 s, got {self.dt!r}")

    def initial_state(self) -> CommandState:
        """The (empty) state."""
        return CommandState()

    def step(self, state: CommandState, reference: float, measurement: float
             ) -> tuple[float, CommandState]:
        """The command is the schedule sample ``reference`` [-]; ``measurement`` is unused."""
        del measurement
        return float(reference), state

    def pack(self) -> FloatArray:
        """Packed parameters (none; one placeholder entry)."""
        return np.zeros(1)

    def pack_gains(self, gains: FloatArray) -> FloatArray:
        """One placeholder row per row of ``gains`` (there are no gains)."""
        return np.zeros((np.atleast_2d(gains).shape[0], 1))

    def pack_state(self, state: object) -> FloatArray:
        """Packed state (placeholders; alpha NaN)."""
        return np.array([0.0, 0.0, 0.0, 0.0, np.nan])

    def rest_states(self, packed: FloatArray, y0: float, u0: float) -> FloatArray:
        """Packed states, one per row of ``packed``."""
        out = np.zeros((packed.shape[0], 5))
        out[:, 4] = np.nan
        return out

    def tables(self) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
        """Placeholder rule tables."""
        return no_tables()
