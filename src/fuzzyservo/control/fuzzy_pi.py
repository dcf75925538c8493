"""Incremental (velocity-form) fuzzy PI controller, the paper's controller without self-tuning.

Per sample k (paper eqs. 9-12 with α_F ≡ 1; Mudi & Pal 1999)::

    y_f(k) = a y_f(k-1) + (1 - a) y(k)        optional first-order measurement filter
    e(k)   = r(k) - y_f(k),   Δe(k) = e(k) - e(k-1)  (or divided by h: "per second")
    e_n    = K_e e,   Δe_n = K_Δe Δe            (clipped to [-1, 1] by the fuzzy kernel)
    Δu(k)  = α K_Δu Δu_n(e_n, Δe_n)             α = 1 here, Fig. 3b in self_tuning.py
    u(k)   = sat(u(k-1) + Δu(k))                 saturated before it is stored (no windup)

The α source is a packed code (``self_tuning``): 0, α = 1 (this class); 1, the α rule base of
Mudi & Pal (:mod:`~fuzzyservo.control.self_tuning`); 2, Woo, Chung & Lin's functions of
m = min(|e_n|, 1): Δe_n is multiplied by φ = a m + b and α = ψ = c (1 - m) + d
(:mod:`~fuzzyservo.control.woo`, :data:`WOO_FPI_LAW`, whose gains add a, b, c, d).

The first sample uses e(-1) = 0 (``initial_error="zero"``, the default: Mudi & Pal's natural
start, so Δe_n saturates at the step) or e(-1) = e(0) (``"first"``, which makes the loop an
I-P structure on an integrating plant, model notes §5.1). The filter coefficient is
a = exp(-h/T_f), a = 0 (no filter) for T_f = 0, and the filter starts at y(0) (bumpless).

:func:`fuzzy_pi_step` is the one implementation, used by :meth:`FuzzyPIController.step`,
:class:`~fuzzyservo.control.self_tuning.SelfTuningFuzzyPIController` and the batch kernels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal, Protocol, Self

import numpy as np

from .._jit import kernel, specialize, template
from .._typing import FloatArray, IntArray
from ..errors import ParameterError
from ..fuzzy.engine import SystemTable, check_packed, eval_system, pack, system_table
from ..fuzzy.kernels import GridTable, grid_eval, grid_pair, grid_table
from ..fuzzy.system import FuzzySystem
from .law import Field, Law, LawController, indices

__all__ = [
    "FUZZY_GAIN_NAMES",
    "FUZZY_PI_GENERAL_LAW",
    "FUZZY_PI_LAW",
    "WOO_FPI_GENERAL_LAW",
    "WOO_FPI_LAW",
    "WOO_GAIN_NAMES",
    "FuzzyPIController",
    "FuzzyPIState",
    "KernelSystem",
]

#: The law's packed parameters (:data:`FUZZY_PI_LAW`).
PARAMS = (
    Field("ke", "1/m", "error scaling K_e"),
    Field("kde", "1/m", "error-change scaling K_Δe (per sample, or s/m per second)"),
    Field("kdu", "-", "output scaling K_Δu"),
    Field("u_min", "-", "lower command limit"),
    Field("u_max", "-", "upper command limit"),
    Field("de_scale", "1/s", "factor of the error difference: 1 (per sample) or 1/h"),
    Field("e_init", "-", "e(-1) rule: 0 zero, 1 the first error"),
    Field("filter_a", "-", "measurement filter coefficient exp(-h/T_f), 0 without filter"),
    Field("self_tuning", "-", "α source: 0 α = 1; 1 the α rule base (eq. 11, Mudi & Pal); "
          "2 Woo et al.'s functions of |e_n| (φ scales Δe_n, α = ψ)"),
    Field("phi_a", "-", "Woo et al.'s φ = a |e_n| + b: slope a (mode 2)"),
    Field("phi_b", "-", "Woo et al.'s φ: offset b (mode 2)"),
    Field("psi_c", "-", "Woo et al.'s ψ = c (1 - |e_n|) + d: slope c (mode 2)"),
    Field("psi_d", "-", "Woo et al.'s ψ: offset d (mode 2)"),
)
#: The law's packed state.
STATE = (
    Field("u_prev", "-", "previous command u(k-1)"),
    Field("e_prev", "m", "previous error e(k-1)"),
    Field("y_filtered", "m", "filtered measurement y_f(k-1)"),
    Field("started", "-", "1 once the first sample has set e(-1) and y_f"),
    Field("alpha", "-", "gain-updating factor α of the last sample"),
)
#: Gains a batch may vary for the fuzzy controllers, in column order.
GAINS = (
    Field("ke", "1/m", "error scaling K_e"),
    Field("kde", "1/m", "error-change scaling K_Δe"),
    Field("kdu", "-", "output scaling K_Δu"),
)
#: What the packing takes besides the gains.
CONSTANTS = (
    Field("u_min", "-", "lower command limit"),
    Field("u_max", "-", "upper command limit"),
    Field("de_scale", "1/s", "factor of the error difference: 1 (per sample) or 1/h"),
    Field("e_init", "-", "e(-1) rule: 0 zero, 1 the first error"),
    Field("filter_a", "-", "measurement filter coefficient exp(-h/T_f), 0 without filter"),
    Field("self_tuning", "-", "α source: 0 none (α = 1), 1 the α system, 2 Woo et al.'s "
          "functions"),
)
FUZZY_GAIN_NAMES: tuple[str, ...] = tuple(f.name for f in GAINS)
#: The gains of the fuzzy PI with Woo et al.'s scaling functions (:data:`WOO_FPI_LAW`): the
#: fuzzy PI's, then the coefficients of φ and ψ.
WOO_GAINS = GAINS + (
    Field("phi_a", "-", "slope a of φ(e_n) = a |e_n| + b, the factor of K_Δe"),
    Field("phi_b", "-", "offset b of φ"),
    Field("psi_c", "-", "slope c of ψ(e_n) = c (1 - |e_n|) + d, the factor of K_Δu"),
    Field("psi_d", "-", "offset d of ψ"),
)
WOO_GAIN_NAMES: tuple[str, ...] = tuple(f.name for f in WOO_GAINS)
#: The α sources (the packed ``self_tuning`` code).
ALPHA_NONE, ALPHA_RULES, ALPHA_WOO = 0.0, 1.0, 2.0

P = indices("FuzzyPIParams", PARAMS)
S = indices("FuzzyPIStateIndex", STATE)

# --- the two ways of evaluating the systems (one call site per system per sample) ----------


@kernel(inline=True)
def _grid_prepare(tables: Any) -> tuple[GridTable, GridTable]:
    return grid_table(tables[0], tables[1]), grid_table(tables[2], tables[3])


@kernel(inline=True, error_model="numpy")
def _grid_systems(en: float, den: float, aux: Any, self_tuning: bool) -> tuple[float, float]:
    """Δu_n and α of rule tables on uniform grids: the pair located once when self-tuning."""
    if self_tuning:
        return grid_pair(en, den, aux[0], aux[1])
    return grid_eval(en, den, aux[0]), 1.0


@kernel(inline=True)
def _general_prepare(tables: Any) -> tuple[SystemTable, SystemTable]:
    return system_table(tables[0], tables[1]), system_table(tables[2], tables[3])


@kernel(inline=True, error_model="numpy")
def _general_systems(en: float, den: float, aux: Any, self_tuning: bool
                     ) -> tuple[float, float]:
    """Δu_n and α when either system is a packed general system (e.g. read from a file)."""
    dun = eval_system(en, den, aux[0])
    if self_tuning:
        return dun, eval_system(en, den, aux[1])
    return dun, 1.0


SYSTEMS: Any = None


@template(inline=True, error_model="numpy")
def fuzzy_pi_step(p: Any, s: Any, r: float, y: float, aux: Any, rd: float,
                  rdd: float) -> float:
    """One fuzzy PI sample on packed ``p`` and state ``s`` (data pointers or arrays; ``s``
    updated in place); returns u. ``aux`` holds the Δu and α systems; the α source
    ``self_tuning`` is 0 (α = 1), 1 (the α system, eq. 11) or 2 (Woo et al.'s φ and ψ).
    Written once, compiled for the uniform-grid systems (the paper's) and for general ones
    (``SYSTEMS``)."""
    if s[S.started] == 0.0:
        yf = y
        e = r - yf
        e_prev = e if p[P.e_init] == 1.0 else 0.0
        s[S.started] = 1.0
    else:
        a = p[P.filter_a]
        yf = a * s[S.y_filtered] + (1.0 - a) * y
        e = r - yf
        e_prev = s[S.e_prev]
    de = (e - e_prev) * p[P.de_scale]
    en = p[P.ke] * e
    den = p[P.kde] * de
    if p[P.self_tuning] == 2.0:
        # Woo et al. (2000): |e_n| (clipped as the fuzzy kernel clips) sets the factor φ of
        # the Δe scaling and the factor ψ of the output scaling, in place of the α system
        m = min(abs(en), 1.0)
        den = den * (p[P.phi_a] * m + p[P.phi_b])
        dun, alpha_f = SYSTEMS(en, den, aux, False)
        alpha_f = p[P.psi_c] * (1.0 - m) + p[P.psi_d]
    else:
        dun, alpha_f = SYSTEMS(en, den, aux, p[P.self_tuning] == 1.0)
    u = s[S.u_prev] + alpha_f * p[P.kdu] * dun
    u = min(max(u, p[P.u_min]), p[P.u_max])
    s[S.u_prev] = u
    s[S.e_prev] = e
    s[S.y_filtered] = yf
    s[S.alpha] = alpha_f
    return u


_GRID_STEP = specialize([fuzzy_pi_step], {"SYSTEMS": _grid_systems}, key="grid",
                        title="the fuzzy PI").fuzzy_pi_step
_GENERAL_STEP = specialize([fuzzy_pi_step], {"SYSTEMS": _general_systems}, key="general",
                           title="the fuzzy PI").fuzzy_pi_step


def _pack(g: FloatArray, k: FloatArray) -> FloatArray:
    """Packed rows from gain rows (ke, kde, kdu) and the constants (u_min, u_max, Δe scale,
    e(-1) rule, filter coefficient, self-tuning), which are already in packed form."""
    out = np.empty((g.shape[0], len(PARAMS)))
    out[:, P.ke] = g[:, 0]
    out[:, P.kde] = g[:, 1]
    out[:, P.kdu] = g[:, 2]
    out[:, P.u_min] = k[0]
    out[:, P.u_max] = k[1]
    out[:, P.de_scale] = k[2]
    out[:, P.e_init] = k[3]
    out[:, P.filter_a] = k[4]
    out[:, P.self_tuning] = k[5]
    out[:, P.phi_a] = 0.0  # φ = ψ = 1: used only by the Woo mode, which packs its own
    out[:, P.phi_b] = 1.0
    out[:, P.psi_c] = 0.0
    out[:, P.psi_d] = 1.0
    return out


def _pack_woo(g: FloatArray, k: FloatArray) -> FloatArray:
    """Packed rows from gain rows (ke, kde, kdu, phi_a, phi_b, psi_c, psi_d) and the
    constants, as :func:`_pack` (the constants' α source is 2, Woo et al.'s functions)."""
    out = _pack(g[:, :3], k)
    out[:, P.phi_a] = g[:, 3]
    out[:, P.phi_b] = g[:, 4]
    out[:, P.psi_c] = g[:, 5]
    out[:, P.psi_d] = g[:, 6]
    return out


def _rest(packed: FloatArray, y0: float, u0: float) -> FloatArray:
    """States before the first sample, holding the command u0 [-] (y0 [m] is not needed:
    the first sample sets e(-1) and y_f)."""
    out = np.zeros((packed.shape[0], len(STATE)))
    out[:, S.u_prev] = u0
    out[:, S.alpha] = 1.0
    return out


_C_PORT = Path(__file__).with_name("fuzzy_pi.c")
_ST_PORT = Path(__file__).with_name("fuzzy_pi.st")

#: The fuzzy PI law (with and without self-tuning) for fuzzy systems on uniform grids (the
#: paper's): its layout, step, packing, C port (``fuzzy_pi.c``) and ST port (``fuzzy_pi.st``).
FUZZY_PI_LAW = Law(name="fuzzy_pi", title="the fuzzy PI", params=PARAMS, state=STATE,
                   gains=GAINS, constants=CONSTANTS, step=_GRID_STEP, prepare=_grid_prepare,
                   pack=_pack, rest=_rest, trace="alpha", c_source=_C_PORT, st_source=_ST_PORT,
                   systems=("du", "alpha"))
#: The same law, compiled for general fuzzy systems (read from files): the same layout,
#: packing and C port, the systems evaluated by the general exact evaluator.
FUZZY_PI_GENERAL_LAW = Law(name="fuzzy_pi_general", title="the fuzzy PI (general systems)",
                           params=PARAMS, state=STATE, gains=GAINS, constants=CONSTANTS,
                           step=_GENERAL_STEP, prepare=_general_prepare, pack=_pack,
                           rest=_rest, trace="alpha", c_source=_C_PORT, st_source=_ST_PORT,
                           systems=("du", "alpha"))
#: The same law with Woo et al.'s scaling functions as the α source (``control/woo.py``): the
#: same layout, step and C port; its gains add φ's and ψ's coefficients. Rule tables on
#: uniform grids, and general systems (:data:`WOO_FPI_GENERAL_LAW`).
WOO_FPI_LAW = Law(name="fuzzy_pi_woo", title="the fuzzy PI with Woo et al.'s scaling",
                  params=PARAMS, state=STATE, gains=WOO_GAINS, constants=CONSTANTS,
                  step=_GRID_STEP, prepare=_grid_prepare, pack=_pack_woo, rest=_rest,
                  trace="alpha", c_source=_C_PORT, st_source=_ST_PORT,
                  systems=("du",))
WOO_FPI_GENERAL_LAW = Law(name="fuzzy_pi_woo_general",
                          title="the fuzzy PI with Woo et al.'s scaling (general systems)",
                          params=PARAMS, state=STATE, gains=WOO_GAINS, constants=CONSTANTS,
                          step=_GENERAL_STEP, prepare=_general_prepare, pack=_pack_woo,
                          rest=_rest, trace="alpha", c_source=_C_PORT, st_source=_ST_PORT,
                          systems=("du",))


class KernelSystem(Protocol):
    """A two-input fuzzy system packed for the compiled loops: a
    :class:`~fuzzyservo.fuzzy.engine.PackedSystem` or a
    :class:`~fuzzyservo.fuzzy.loop.LoopSystem` (``fuzzyservo.fuzzy.loop_system``)."""

    def kernel_args(self) -> tuple[Any, Any]:
        """Return ``(rules, lims)`` for :func:`fuzzyservo.fuzzy.engine.eval_system`."""
        ...


@dataclass(frozen=True, slots=True)
class FuzzyPIState:
    """State of a fuzzy PI controller between samples."""

    u_prev: float  #: previous command u(k-1) [-]
    e_prev: float  #: previous error e(k-1) [m]
    y_filtered: float  #: filtered measurement y_f(k-1) [m]
    started: bool  #: False before the first sample (e(-1) and y_f not yet set)
    alpha: float = 1.0  #: last gain-updating factor α [-]


def _kernel_args(system: FuzzySystem | KernelSystem) -> tuple[Any, Any]:
    return (pack(system) if isinstance(system, FuzzySystem) else system).kernel_args()


def _empty_rules() -> IntArray:
    return np.full((2, 2), -1, dtype=np.int64)


def _empty_lims() -> FloatArray:
    return np.array([-1.0, 1.0, -1.0, 1.0, 0.0, 1.0, 2.0, 1.0])


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class FuzzyPIController(LawController):
    """Incremental fuzzy PI (paper Fig. 7: the self-tuning controller with α_F ≡ 1).

    Parameters
    ----------
    dt : float
        Sample period h [s].
    ke : float
        Error scaling K_e [1/m], >= 0.
    kde : float
        Error-change scaling K_Δe [1/m] per sample (or [s/m] with ``de_per="second"``), >= 0.
    kdu : float
        Output scaling K_Δu [-] (command increment per unit Δu_n), >= 0.
    du_rules, du_lims : ndarray
        The Δu system (Fig. 3a) in ``eval_uniform_grid`` form; see :meth:`from_systems`.
    alpha_rules, alpha_lims : ndarray
        The α system (Fig. 3b); used by the self-tuning subclass only.
    u_min, u_max : float
        Command limits [-].
    initial_error : {"zero", "first"}
        e(-1) = 0 or e(-1) = e(0).
    de_per : {"sample", "second"}
        Δe as a difference per sample, or divided by h.
    filter_time : float
        Time constant T_f of the first-order measurement filter [s]; 0 for none.
    """

    dt: float  #: sample period [s]
    ke: float  #: error scaling K_e [1/m]
    kde: float  #: error-change scaling K_Δe [1/m] (per sample) or [s/m] (per second)
    kdu: float  #: output scaling K_Δu [-]
    du_rules: IntArray  #: Δu rule table (rows Δe, columns e) [-]
    du_lims: FloatArray  #: Δu universes and output labels [-]
    alpha_rules: IntArray = field(default_factory=_empty_rules)  #: α rule table [-]
    alpha_lims: FloatArray = field(default_factory=_empty_lims)  #: α universes [-]
    u_min: float = -1.0  #: lower command limit [-]
    u_max: float = 1.0  #: upper command limit [-]
    initial_error: Literal["zero", "first"] = "zero"  #: e(-1) convention
    de_per: Literal["sample", "second"] = "sample"  #: Δe per sample or per second
    filter_time: float = 0.0  #: measurement filter time constant [s]

    state_class: ClassVar[type] = FuzzyPIState
    gain_names: ClassVar[tuple[str, ...]] = FUZZY_GAIN_NAMES
    self_tuning: ClassVar[bool] = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ParameterError(f"sample time dt must be finite and > 0 s, got {self.dt!r}")
        for name in FUZZY_GAIN_NAMES:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ParameterError(f"gain {name} must be finite and >= 0, got {value!r}")
        if not (math.isfinite(self.u_min) and math.isfinite(self.u_max)
                and self.u_min <= 0.0 <= self.u_max and self.u_min < self.u_max):
            raise ParameterError(
                f"need finite u_min <= 0 <= u_max, u_min < u_max, got [{self.u_min!r}, "
                f"{self.u_max!r}]")
        if self.initial_error not in ("zero", "first"):
            raise ParameterError(
                f"initial_error must be 'zero' or 'first', got {self.initial_error!r}")
        if self.de_per not in ("sample", "second"):
            raise ParameterError(f"de_per must be 'sample' or 'second', got {self.de_per!r}")
        if not (math.isfinite(self.filter_time) and self.filter_time >= 0.0):
            raise ParameterError(
                f"filter_time must be finite and >= 0 s, got {self.filter_time!r}")
        r, m = check_packed(self.du_rules, self.du_lims, "du")
        object.__setattr__(self, "du_rules", r)
        object.__setattr__(self, "du_lims", m)
        r, m = check_packed(self.alpha_rules, self.alpha_lims, "alpha")
        object.__setattr__(self, "alpha_rules", r)
        object.__setattr__(self, "alpha_lims", m)

    @classmethod
    def from_systems(cls, du_system: FuzzySystem | KernelSystem,
                     alpha_system: FuzzySystem | KernelSystem | None = None,
                     **options: Any) -> Self:
        """Build from two-input fuzzy systems: ``fuzzyservo.paper``'s ``du_system()`` and
        ``alpha_system()``, systems read from files, or either packed (:class:`KernelSystem`);
        a :class:`~fuzzyservo.fuzzy.system.FuzzySystem` is packed here
        (:func:`fuzzyservo.fuzzy.engine.pack`: the uniform grid when it has that form, the
        general evaluator otherwise); ``options`` are the other fields."""
        du_rules, du_lims = _kernel_args(du_system)
        if alpha_system is not None:
            a_rules, a_lims = _kernel_args(alpha_system)
            options = {**options, "alpha_rules": a_rules, "alpha_lims": a_lims}
        return cls(du_rules=du_rules, du_lims=du_lims, **options)

    def tables(self) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
        """``(du_rules, du_lims, alpha_rules, alpha_lims)`` as passed to the kernels."""
        return self.du_rules, self.du_lims, self.alpha_rules, self.alpha_lims

    def initial_state(self, *, u0: float = 0.0) -> FuzzyPIState:
        """State before the first sample, holding the command ``u0`` [-] (bumpless start)."""
        return FuzzyPIState(u_prev=u0, e_prev=0.0, y_filtered=0.0, started=False, alpha=1.0)

    @property
    def law(self) -> Law:  # type: ignore[override]
        """The law compiled for this controller's systems: :data:`FUZZY_PI_LAW` for rule
        tables on uniform grids, :data:`FUZZY_PI_GENERAL_LAW` when a system it uses is a
        packed general one."""
        general = self.du_rules.shape[0] == 1 or (self.self_tuning
                                                  and self.alpha_rules.shape[0] == 1)
        return FUZZY_PI_GENERAL_LAW if general else FUZZY_PI_LAW

    def law_constants(self) -> FloatArray:
        """The packing constants: u_min, u_max, Δe scale (1 or 1/h), e(-1) rule, filter
        coefficient exp(-h/T_f) (0 without filter), self-tuning."""
        return np.array([
            self.u_min, self.u_max, 1.0 if self.de_per == "sample" else 1.0 / self.dt,
            1.0 if self.initial_error == "first" else 0.0,
            math.exp(-self.dt / self.filter_time) if self.filter_time > 0 else 0.0,
            1.0 if self.self_tuning else 0.0])

    def systems(self) -> dict[str, tuple[IntArray, FloatArray]]:
        """The fuzzy systems the law evaluates, by role, in kernel form (the C export writes
        these): ``du``, and ``alpha`` when self-tuning."""
        out = {"du": (self.du_rules, self.du_lims)}
        if self.self_tuning:
            out["alpha"] = (self.alpha_rules, self.alpha_lims)
        return out
