"""The discrete-time controller interface shared by every controller in :mod:`fuzzyservo.control`.

A controller is a frozen parameter object with a fixed sample period ``dt`` [s]. Its state is a
separate frozen dataclass; :meth:`Controller.step` is a pure function
``(state, r, y) -> (u, new_state)`` that never reads a clock (the simulator owns time).

Every controller's maths is one :class:`~fuzzyservo.control.law.Law`: a compiled step on a
packed parameter vector and a packed state, both laid out by name in the law's declaration.
``step`` packs the dataclasses and calls the law; the compiled loops in :mod:`fuzzyservo.sim`
call the very same function, so the two paths cannot drift apart.
"""

from __future__ import annotations

from typing import Any, Protocol, TypeVar, runtime_checkable

from .._typing import FloatArray
from .law import Law

__all__ = ["Controller", "PackedController"]

S = TypeVar("S")
S_co = TypeVar("S_co", covariant=True)


@runtime_checkable
class Controller(Protocol[S]):
    """A discrete-time controller with explicit state (STYLE section 3).

    Attributes
    ----------
    dt : float
        Sample period [s].
    """

    dt: float

    def initial_state(self) -> S:
        """Return the state of the controller at rest (zero command, zero error)."""
        ...

    def step(self, state: S, reference: float, measurement: float) -> tuple[float, S]:
        """Return the command [-] held over the next sample and the new state."""
        ...


@runtime_checkable
class PackedController(Protocol):
    """What the compiled simulators need from a controller: its law and packed form.

    ``law`` is the :class:`~fuzzyservo.control.law.Law` the loops run; ``pack()`` returns the
    parameter vector; ``gain_names`` names the gains a batch may vary, in column order, and
    ``pack_gains(gains)`` packs one parameter row per row of ``gains``.
    """

    @property
    def dt(self) -> float:
        """Sample period [s]."""

    @property
    def law(self) -> Law:
        """The control law."""

    @property
    def gain_names(self) -> tuple[str, ...]:
        """Names of the gain columns of :meth:`pack_gains`."""

    def pack(self) -> FloatArray:
        """Return the packed parameter vector of the law."""
        ...

    def pack_gains(self, gains: FloatArray) -> FloatArray:
        """Return one packed parameter row per row of ``gains`` (columns ``gain_names``)."""
        ...

    def pack_state(self, state: object) -> FloatArray:
        """Return ``state`` as the law's packed state vector."""
        ...

    def rest_states(self, packed: FloatArray, y0: float, u0: float) -> FloatArray:
        """Packed bumpless states (rows, len(law.state)) at rest at ``y0`` [m] holding ``u0``."""
        ...

    def tables(self) -> tuple[Any, ...]:
        """The arrays the law's ``prepare`` takes (its fuzzy systems)."""
        ...
