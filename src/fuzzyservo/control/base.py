"""The discrete-time controller interface shared by every controller in :mod:`fuzzyservo.control`.

A controller is a frozen parameter object with a fixed sample period ``dt`` [s]. Its state is a
separate frozen dataclass; :meth:`Controller.step` is a pure function
``(state, r, y) -> (u, new_state)`` that never reads a clock (the simulator owns time).

Every controller's maths is one numba function, :func:`controller_step`, working on a packed
parameter vector ``p`` and a state vector ``s`` of :data:`STATE_SIZE` floats that it updates in
place. ``step`` packs the dataclasses, calls it, and unpacks; the batched closed-loop kernels in
:mod:`fuzzyservo.sim` call the very same function, so the two paths cannot drift apart.
"""

from __future__ import annotations

from typing import Protocol, TypeVar, runtime_checkable

import numba

from .._typing import FloatArray, IntArray
from .fuzzy_pi import SystemTable, fuzzy_pi_step, system_table
from .pid import pid_step

__all__ = [
    "KIND_COMMAND",
    "KIND_FUZZY_PI",
    "KIND_PID",
    "STATE_ALPHA",
    "STATE_SIZE",
    "Controller",
    "PackedController",
    "controller_step",
    "controller_tables",
]

#: Kind code of the PID family in packed form.
KIND_PID = 0
#: Kind code of the fuzzy PI (with or without self-tuning) in packed form.
KIND_FUZZY_PI = 1
#: Kind code of the open loop: the reference sample is the command (``control.command``).
KIND_COMMAND = 2
#: Length of every packed controller state vector.
STATE_SIZE = 5
#: Index of the gain-updating factor alpha in the packed state (NaN for the PID family).
STATE_ALPHA = 4

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
    """What the compiled simulators need from a controller: its packed form.

    ``kind`` selects the branch of :func:`controller_step`; ``pack()`` returns the parameter
    vector; ``gain_names`` names the gains a batch may vary, in column order, and
    ``pack_gains(gains)`` packs one parameter row per row of ``gains``.
    """

    @property
    def dt(self) -> float:
        """Sample period [s]."""

    @property
    def kind(self) -> int:
        """Kind code (:data:`KIND_PID`, :data:`KIND_FUZZY_PI`, :data:`KIND_COMMAND`)."""

    @property
    def gain_names(self) -> tuple[str, ...]:
        """Names of the gain columns of :meth:`pack_gains`."""

    def pack(self) -> FloatArray:
        """Return the packed parameter vector used by :func:`controller_step`."""
        ...

    def pack_gains(self, gains: FloatArray) -> FloatArray:
        """Return one packed parameter row per row of ``gains`` (columns ``gain_names``)."""
        ...

    def pack_state(self, state: object) -> FloatArray:
        """Return ``state`` as a packed vector of :data:`STATE_SIZE` floats."""
        ...

    def rest_states(self, packed: FloatArray, y0: float, u0: float) -> FloatArray:
        """Packed bumpless states (rows, STATE_SIZE) at rest at ``y0`` [m] holding ``u0``."""
        ...

    def tables(self) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
        """Rule tables passed to :func:`controller_step` (placeholders for the PID family)."""
        ...


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def controller_step(
    kind: int,
    p: FloatArray,
    s: FloatArray,
    r: float,
    y: float,
    du: SystemTable,
    alpha: SystemTable,
) -> float:
    """One controller sample: update ``s`` in place and return the command u [-].

    Inlined into the compiled loops, which pass ``p`` and ``s`` as data pointers
    (:func:`~fuzzyservo.fuzzy.kernels.data_pointer`; arrays work too) and the fuzzy systems
    as :func:`~fuzzyservo.control.fuzzy_pi.system_table` values, so nothing is
    reference-counted per sample (:func:`controller_tables` makes them from ``tables()``).

    Parameters
    ----------
    kind : int
        :data:`KIND_PID`, :data:`KIND_FUZZY_PI` or :data:`KIND_COMMAND` (``r`` is the
        command; the open loop).
    p, s : ndarray or data pointer
        Packed parameters and state (see the controller classes).
    r, y : float
        Reference and measurement at this sample [m].
    du, alpha : SystemTable
        The Δu and α systems (ignored by the PID family).
    """
    if kind == KIND_PID:
        return pid_step(p, s, r, y)
    if kind == KIND_COMMAND:
        return r
    return fuzzy_pi_step(p, s, r, y, du, alpha)


@numba.njit(cache=True, nogil=True, inline="always")
def controller_tables(du_rules: IntArray, du_lims: FloatArray, a_rules: IntArray,
                      a_lims: FloatArray) -> tuple[SystemTable, SystemTable]:
    """The ``du`` and ``alpha`` arguments of :func:`controller_step` from a controller's
    ``tables()`` (which must outlive them)."""
    return system_table(du_rules, du_lims), system_table(a_rules, a_lims)
