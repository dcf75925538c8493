"""A control law, declared once: its packed parameters and state by name, its compiled step,
its packing and rest state, and its C port.

A law is what the compiled loops run each sample. It is declared by one :class:`Law` in the
module that implements it (``control/pid.py``, ``control/fuzzy_pi.py``, or a user's own
module), and everything that needs its layout reads that declaration:

- the compiled step ``step(p, s, r, y, aux, rd, rdd) -> u`` works on the packed parameter
  vector ``p`` and state ``s`` (data pointers, indexed by name through :meth:`Law.p` and
  :meth:`Law.s`: ``p[P.kp]``) and updates ``s`` in place; ``r`` [m] is the reference, ``y``
  [m] the measurement, ``rd`` [m/s] and ``rdd`` [m/s²] the reference's velocity and
  acceleration at the same instant (its feed-forward signals, exact for the package's
  references; a law without feed-forward ignores them); ``aux`` is what ``prepare(tables)``
  made of the controller's tables (its fuzzy systems) once per run;
- ``pack(gains, constants)`` makes packed rows from rows of the law's gains (the batch gain
  columns, :attr:`Law.gains`) and the controller's constants (:attr:`Law.constants`, e.g. the
  sample time and the limits); ``rest(packed, y0, u0)`` the states at rest;
- the closed loops of :mod:`fuzzyservo.sim` and the per-step API (:meth:`Law.step_arrays`) are
  compiled copies specialised to the law (:func:`fuzzyservo._jit.specialize`), so a law
  compiles only its own loops, and LLVM inlines it into them;
- the C export writes the layout as named constants (``FS_P_KP``, ``FS_S_INTEGRAL``,
  ``FS_G_KP``, ``FS_K_TS``) before the law's C port (``c_source``, a file beside the law's
  module defining ``fs_law_step(p, s, r, y, rd, rdd)``, ``fs_law_rest`` and
  ``fs_law_pack``), which indexes by those names only;
- the Structured Text export (IEC 61131-3) declares the same layout as named variables
  (``P_KP``, ``S_INTEGRAL``, ``G_KP``, ``K_TS``) of the function block and pastes the law's
  ST port (``st_source``, a file beside the law's module with the sections ``temps``,
  ``step``, ``rest`` and ``pack``; docs/export-st.md, "Writing a law's ST port").

:class:`LawController` gives a controller class the packing and per-step methods every front
end uses (``pack``, ``pack_gains``, ``rest_states``, ``pack_state``, ``step``...) from its
law. docs/architecture.md, "Control laws", shows a law written from scratch.
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
import re
from collections import namedtuple
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from .._jit import data_pointer, specialize, template
from .._typing import FloatArray
from ..errors import ParameterError

__all__ = ["Field", "Law", "LawController", "indices"]

_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


@dataclass(frozen=True, slots=True)
class Field:
    """One named entry of a law's packed parameters, state, gains or constants.

    Parameters
    ----------
    name : str
        Lower-case identifier (``kp``, ``u_prev``); the C export writes it upper-case.
    unit : str
        Its unit.
    doc : str
        What it is.
    """

    name: str
    unit: str
    doc: str = ""

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and _NAME.match(self.name)):
            raise ParameterError(f"a law's field name must be a lower-case identifier "
                                 f"(letters, digits, _), got {self.name!r}")


def indices(typename: str, fields: Sequence[Field]) -> Any:
    """A named tuple of the fields' positions (``indices("PIDParams", F).kp == 0``): the
    compiled step indexes its arrays through it, a compile-time constant."""
    cls = namedtuple(typename, [f.name for f in fields])  # type: ignore[misc]
    return cls(*range(len(fields)))


def _layout(what: str, fields: Sequence[Field]) -> tuple[Field, ...]:
    out = tuple(fields)
    names = [f.name for f in out]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise ParameterError(f"a law's {what} repeat {sorted(dup)[0]!r}")
    return out


@dataclass(frozen=True, eq=False, kw_only=True)
class Law:
    """A control law (see the module docstring).

    Parameters
    ----------
    name : str
        Identifier of the law (``pid``, ``fuzzy_pi``), lower-case.
    title : str
        What it is, for messages ("PID").
    params, state : tuple of Field
        The packed parameter vector and the packed state, in order.
    gains : tuple of Field
        The gain columns ``pack`` takes (what a batch varies), in order.
    constants : tuple of Field
        The other numbers ``pack`` takes (sample time, limits, options as codes), in order.
    step : compiled function
        ``step(p, s, r, y, aux, rd, rdd) -> u`` (a :func:`fuzzyservo._jit.kernel` with
        ``inline=True``): one sample, ``s`` updated in place; ``rd``, ``rdd`` the
        reference's velocity [m/s] and acceleration [m/s²].
    prepare : compiled function
        ``prepare(tables) -> aux``: what the step needs of the controller's tables, made once
        per run (the tables must outlive it).
    pack : callable
        ``pack(gains (rows, len(gains)), constants (len(constants),)) -> (rows, len(params))``.
    rest : callable
        ``rest(packed (rows, len(params)), y0, u0) -> (rows, len(state))``: the states before
        the first sample at rest at y0 [m] holding the command u0 [-].
    trace : str or None
        The state field recorded per sample as the run's α; None: α is NaN.
    c_source : Path or None
        The law's C port (defines ``fs_law_step``, ``fs_law_rest``, ``fs_law_pack``); None: no
        C export.
    st_source : Path or None
        The law's IEC 61131-3 Structured Text port (sections ``temps``, ``step``, ``rest``,
        ``pack``; :mod:`fuzzyservo.export.st`); None: no ST export.
    feedforward : bool
        The law uses the reference's velocity and acceleration (the C export then offers
        ``<name>_step_ff`` and the controller FMU their inputs; front ends say so).
    systems : tuple of str
        Roles of the fuzzy systems the controller's ``systems()`` may give (``du``,
        ``alpha``): the C export writes each as ``fs_sys_<role>(x1, x2)`` and defines
        ``FS_SYS_<ROLE>`` for the port.
    source : str
        Where the law is declared (set from the caller's module when empty); part of
        :attr:`key`, so editing a law outside the package recompiles its loops.
    """

    name: str
    title: str
    params: tuple[Field, ...]
    state: tuple[Field, ...]
    gains: tuple[Field, ...]
    constants: tuple[Field, ...]
    step: Any
    prepare: Any
    pack: Callable[[FloatArray, FloatArray], FloatArray]
    rest: Callable[[FloatArray, float, float], FloatArray]
    trace: str | None = None
    c_source: Path | None = None
    st_source: Path | None = None
    feedforward: bool = False
    systems: tuple[str, ...] = ()
    source: str = ""
    _kernels: dict[str, Any] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and _NAME.match(self.name)):
            raise ParameterError(f"a law's name must be a lower-case identifier, got "
                                 f"{self.name!r}")
        for what in ("params", "state", "gains", "constants"):
            object.__setattr__(self, what, _layout(what, getattr(self, what)))
        if self.trace is not None and self.trace not in self.state_names:
            raise ParameterError(f"law {self.name}: trace {self.trace!r} is not a state field "
                                 f"({', '.join(self.state_names)})")
        if not self.source:
            object.__setattr__(self, "source", _caller_file())

    @property
    def param_names(self) -> tuple[str, ...]:
        """Names of the packed parameters, in order."""
        return tuple(f.name for f in self.params)

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the packed state, in order."""
        return tuple(f.name for f in self.state)

    @property
    def gain_names(self) -> tuple[str, ...]:
        """Names of the gain columns, in order."""
        return tuple(f.name for f in self.gains)

    @property
    def constant_names(self) -> tuple[str, ...]:
        """Names of the packing constants, in order."""
        return tuple(f.name for f in self.constants)

    @property
    def trace_index(self) -> int:
        """Position of :attr:`trace` in the state, or -1."""
        return self.state_names.index(self.trace) if self.trace is not None else -1

    @property
    def key(self) -> str:
        """Names the law's compiled copies and their cache: the name and a digest of the
        source file that declares it (files of the package are covered by the cache folder's
        own digest)."""
        h = hashlib.sha256(self.name.encode())
        path = Path(self.source)
        if self.source and path.is_file():
            h.update(path.read_bytes())
        return f"{self.name}_{h.hexdigest()[:10]}"

    @property
    def cacheable(self) -> bool:
        """Whether the law's loops may be cached: it is declared in a file (a law made by
        ``exec`` of a string has no source the cache key could cover: compiled afresh in each
        process)."""
        return bool(self.source) and Path(self.source).is_file()

    def kernels(self, family: str, templates: Sequence[Callable[..., Any]],
                globals_: dict[str, Any] | None = None) -> Any:
        """The compiled copies of ``templates`` for this law (made once per process and
        family): their globals ``LAW_STEP``, ``LAW_PREPARE``, ``LAW_TRACE`` are the law's."""
        made = self._kernels.get(family)
        if made is None:
            ns = {"LAW_STEP": self.step, "LAW_PREPARE": self.prepare,
                  "LAW_TRACE": self.trace_index, **(globals_ or {})}
            made = specialize(templates, ns, key=self.key, title=self.title,
                              cache=self.cacheable)
            self._kernels[family] = made
        return made

    @property
    def step_arrays(self) -> Any:
        """The per-step API's compiled call: ``step_arrays(p, s, r, y, tables, rd, rdd) -> u``
        on the controller's arrays (``s`` updated in place)."""
        return self.kernels("per-step", [_step_arrays])._step_arrays

    def gain_rows(self, gains: FloatArray) -> FloatArray:
        """``gains`` as float64 rows of the law's gain columns (shape checked)."""
        g = np.asarray(gains, dtype=np.float64)
        if g.ndim != 2 or g.shape[1] != len(self.gains):
            raise ParameterError(
                f"{self.title} gains need shape (runs, {len(self.gains)}) with columns "
                f"{', '.join(self.gain_names)}, got {g.shape}")
        return g

    def pack_rows(self, gains: FloatArray, constants: FloatArray) -> FloatArray:
        """:attr:`pack` with the shapes checked."""
        g = self.gain_rows(gains)
        k = np.asarray(constants, dtype=np.float64)
        if k.shape != (len(self.constants),):
            raise ParameterError(f"{self.title} constants need {len(self.constants)} values "
                                 f"({', '.join(self.constant_names)}), got {k.shape}")
        out = np.ascontiguousarray(self.pack(g, k), dtype=np.float64)
        if out.shape != (g.shape[0], len(self.params)):
            raise ParameterError(f"law {self.name}: pack gave {out.shape}, expected "
                                 f"{(g.shape[0], len(self.params))}")
        return out

    def rest_rows(self, packed: FloatArray, y0: float, u0: float) -> FloatArray:
        """:attr:`rest` with the shape checked."""
        out = np.ascontiguousarray(self.rest(packed, float(y0), float(u0)), dtype=np.float64)
        if out.shape != (packed.shape[0], len(self.state)):
            raise ParameterError(f"law {self.name}: rest gave {out.shape}, expected "
                                 f"{(packed.shape[0], len(self.state))}")
        return out


def _caller_file() -> str:
    """The file of the module that declares a law (the first frame outside this module)."""
    for frame in inspect.stack()[2:]:
        name = frame.filename
        if name != __file__ and not name.startswith("<") and "dataclasses" not in name:
            return str(Path(name).resolve())
    return ""


# --- the per-step API's call, specialised per law ------------------------------------------

LAW_STEP: Any = None
LAW_PREPARE: Any = None


@template(error_model="numpy")
def _step_arrays(p: FloatArray, s: FloatArray, r: float, y: float, tables: Any, rd: float,
                 rdd: float) -> float:
    """One sample of the law on the controller's arrays (``s`` updated in place)."""
    return LAW_STEP(data_pointer(p), data_pointer(s), r, y, LAW_PREPARE(tables), rd, rdd)


# --- what a controller class gets from its law ----------------------------------------------


class LawController:
    """Mixin of a controller class whose maths is a :class:`Law` (``law``): the packed form the
    compiled loops take and the per-step API, from the law's declaration.

    The class provides ``dt``, ``law``, ``state_class`` (the frozen dataclass of its state,
    whose fields are the law's state names), :meth:`gain_row` (its own gains in the law's
    columns), :meth:`law_constants` and :meth:`tables`."""

    __slots__ = ()

    law: ClassVar[Law]
    state_class: ClassVar[type]
    dt: float

    def gain_row(self) -> FloatArray:
        """This controller's gains in the law's columns."""
        return np.array([float(getattr(self, n)) for n in self.law.gain_names])

    def law_constants(self) -> FloatArray:
        """The law's packing constants for this controller (one per ``law.constants``)."""
        raise NotImplementedError

    def check_gain_rows(self, gains: FloatArray) -> None:
        """Refuse gain rows the law cannot take (``ParameterError`` naming the value)."""
        bad = ~(np.isfinite(gains) & (gains >= 0.0))
        if np.any(bad):
            i, j = np.argwhere(bad)[0]
            raise ParameterError(
                f"gain {self.law.gain_names[j]} must be finite and >= 0, got {gains[i, j]!r}")

    def tables(self) -> tuple[Any, ...]:
        """The arrays the law's ``prepare`` takes (a placeholder when it needs none)."""
        return (np.zeros(1),)

    def pack(self) -> FloatArray:
        """The packed parameter vector of this controller."""
        return self.pack_gains(self.gain_row()[None, :])[0]

    def pack_gains(self, gains: FloatArray) -> FloatArray:
        """One packed parameter row per row of ``gains`` (columns :attr:`gain_names`), with
        this controller's constants."""
        g = self.law.gain_rows(gains)
        self.check_gain_rows(g)
        return self.law.pack_rows(g, self.law_constants())

    def rest_states(self, packed: FloatArray, y0: float, u0: float) -> FloatArray:
        """Packed states (rows, len(law.state)) before the first sample, at rest at ``y0``
        [m] holding ``u0`` [-]."""
        return self.law.rest_rows(np.asarray(packed, dtype=np.float64), y0, u0)

    def pack_state(self, state: object) -> FloatArray:
        """``state`` (a ``state_class``) as the law's packed state vector."""
        if not isinstance(state, self.state_class):
            raise ParameterError(f"expected a {self.state_class.__name__}, got "
                                 f"{type(state).__name__}")
        return np.array([float(getattr(state, n)) for n in self.law.state_names])

    def unpack_state(self, s: FloatArray) -> Any:
        """Inverse of :meth:`pack_state`."""
        kw: dict[str, Any] = {}
        types_ = {f.name: f.type for f in dataclasses.fields(self.state_class)}
        for i, n in enumerate(self.law.state_names):
            v = float(s[i])
            kw[n] = (v != 0.0) if types_.get(n) in (bool, "bool") else v
        return self.state_class(**kw)

    def step(self, state: Any, reference: float, measurement: float, *,
             reference_rate: float = 0.0, reference_acceleration: float = 0.0
             ) -> tuple[float, Any]:
        """One sample: command u [-] from reference and measurement [m] (and, for a law with
        feed-forward, the reference's velocity [m/s] and acceleration [m/s²]), and the new
        state."""
        s = self.pack_state(state)
        u = self.law.step_arrays(self.pack(), s, float(reference), float(measurement),
                                 self.tables(), float(reference_rate),
                                 float(reference_acceleration))
        return float(u), self.unpack_state(s)
