"""Incremental (velocity-form) fuzzy PI controller, the paper's controller without self-tuning.

Per sample k (paper eqs. 9-12 with α_F ≡ 1; Mudi & Pal 1999)::

    y_f(k) = a y_f(k-1) + (1 - a) y(k)        optional first-order measurement filter
    e(k)   = r(k) - y_f(k),   Δe(k) = e(k) - e(k-1)  (or divided by h: "per second")
    e_n    = K_e e,   Δe_n = K_Δe Δe            (clipped to [-1, 1] by the fuzzy kernel)
    Δu(k)  = α K_Δu Δu_n(e_n, Δe_n)             α = 1 here, Fig. 3b in self_tuning.py
    u(k)   = sat(u(k-1) + Δu(k))                 saturated before it is stored (no windup)

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
from typing import Any, ClassVar, Literal, Protocol, Self

import numba
import numpy as np
from numba.np.numpy_support import carray

from .._typing import FloatArray, IntArray
from ..errors import ParameterError
from ..fuzzy.general import MAGIC, eval_first2
from ..fuzzy.kernels import GridTable, data_pointer, grid_eval, grid_pair, grid_table

__all__ = [
    "FUZZY_GAIN_NAMES",
    "FuzzyPIController",
    "FuzzyPIState",
    "KernelSystem",
    "SystemTable",
    "eval_system",
    "fuzzy_pi_step",
    "fuzzy_pi_step_arrays",
    "system_table",
]

#: Gains a batch may vary for the fuzzy controllers, in column order.
FUZZY_GAIN_NAMES: tuple[str, ...] = ("ke", "kde", "kdu")

# packed parameter layout
_KE, _KDE, _KDU, _UMIN, _UMAX, _DESCALE, _EINIT, _FILT, _ST = range(9)
_NP = 9
# packed state layout
_UPREV, _EPREV, _YF, _STARTED, _ALPHA = range(5)

#: A fuzzy system as the inlined step takes it (:func:`system_table`).
SystemTable = tuple[int, GridTable, Any, int, Any, int]


@numba.njit(cache=True, nogil=True, inline="always")
def system_table(rules: IntArray, lims: FloatArray) -> SystemTable:
    """A fuzzy system in kernel form as one value the inlined step takes (the arrays must
    outlive it): ``(general, grid table, packed integers, their count, packed floats, their
    count)``; ``general`` is 1 for a packed system (rules (1, N), C-contiguous, as
    ``_tables`` makes them), whose grid table is a placeholder, else 0."""
    rp = data_pointer(rules)
    lp = data_pointer(lims)
    if rules.shape[0] == 1:
        return (1, (rp, 2, 2, 0, 0, -1.0, 1.0, -1.0, 1.0, 0.0, 1.0, 2, 0.0), rp,
                rules.shape[1], lp, lims.shape[0])
    return (0, grid_table(rules, lims), rp, 0, lp, 0)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def eval_system(x1: float, x2: float, tab: SystemTable) -> float:
    """A fuzzy system (:func:`system_table`) at (x1, x2): the uniform-grid fast path for a
    rule table, the general evaluator for a packed system (:meth:`fuzzyservo.fuzzy.general.
    CompiledSystem.kernel_args`)."""
    if tab[0] == 1:
        return eval_first2(x1, x2, carray(tab[2], tab[3]), carray(tab[4], tab[5]))
    return grid_eval(x1, x2, tab[1])


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def fuzzy_pi_step(p: FloatArray, s: FloatArray, r: float, y: float, du: SystemTable,
                  alpha: SystemTable) -> float:
    """One fuzzy PI sample on packed ``p`` and state ``s`` (updated in place); returns u.

    ``p`` and ``s`` are arrays or their :func:`~fuzzyservo.fuzzy.kernels.data_pointer`
    (the compiled loops pass pointers: no reference counting in the inlined step); ``du``
    and ``alpha`` are :func:`system_table` values. With ``p[8] == 1`` the output gain is
    scaled by α from the ``alpha`` system (self-tuning, eq. 11), otherwise α = 1.
    """
    if s[_STARTED] == 0.0:
        yf = y
        e = r - yf
        e_prev = e if p[_EINIT] == 1.0 else 0.0
        s[_STARTED] = 1.0
    else:
        a = p[_FILT]
        yf = a * s[_YF] + (1.0 - a) * y
        e = r - yf
        e_prev = s[_EPREV]
    de = (e - e_prev) * p[_DESCALE]
    en = p[_KE] * e
    den = p[_KDE] * de
    if p[_ST] == 1.0:
        if du[0] == 1 or alpha[0] == 1:
            dun = eval_system(en, den, du)
            alpha_f = eval_system(en, den, alpha)
        else:
            dun, alpha_f = grid_pair(en, den, du[1], alpha[1])
    else:
        dun = eval_system(en, den, du)
        alpha_f = 1.0
    u = s[_UPREV] + alpha_f * p[_KDU] * dun
    u = min(max(u, p[_UMIN]), p[_UMAX])
    s[_UPREV] = u
    s[_EPREV] = e
    s[_YF] = yf
    s[_ALPHA] = alpha_f
    return u


@numba.njit(cache=True, nogil=True)
def fuzzy_pi_step_arrays(p: FloatArray, s: FloatArray, r: float, y: float,
                         du_rules: IntArray, du_lims: FloatArray, a_rules: IntArray,
                         a_lims: FloatArray) -> float:
    """:func:`fuzzy_pi_step` on the controller's arrays (the per-step API's call)."""
    return fuzzy_pi_step(data_pointer(p), data_pointer(s), r, y,
                         system_table(du_rules, du_lims), system_table(a_rules, a_lims))


class KernelSystem(Protocol):
    """A two-input fuzzy system the compiled loops can evaluate: a
    :class:`~fuzzyservo.fuzzy.MamdaniSystem` (``fuzzyservo.paper``'s) or a compiled
    :class:`~fuzzyservo.fuzzy.system.FuzzySystem` (e.g. read from a file)."""

    def kernel_args(self) -> tuple[Any, Any]:
        """Return ``(rules, lims)`` for :func:`eval_system`."""
        ...


@dataclass(frozen=True, slots=True)
class FuzzyPIState:
    """State of a fuzzy PI controller between samples."""

    u_prev: float  #: previous command u(k-1) [-]
    e_prev: float  #: previous error e(k-1) [m]
    y_filtered: float  #: filtered measurement y_f(k-1) [m]
    started: bool  #: False before the first sample (e(-1) and y_f not yet set)
    alpha: float = 1.0  #: last gain-updating factor α [-]


def _tables(rules: Any, lims: Any, what: str) -> tuple[IntArray, FloatArray]:
    r = np.ascontiguousarray(rules, dtype=np.int64)
    m = np.ascontiguousarray(lims, dtype=np.float64)
    if r.ndim == 2 and r.shape[0] == 1:
        if r.shape[1] < 2 or r[0, 0] != MAGIC or r[0, 1] != 2 or m.ndim != 1:
            raise ParameterError(f"{what}: a packed fuzzy system for a loop needs two inputs "
                                 f"(e, de) (fuzzyservo.fuzzy.general.compile_system)")
        return r, m
    if r.ndim != 2 or min(r.shape) < 2 or m.shape != (8,) or not np.all(np.isfinite(m[:7])):
        raise ParameterError(
            f"{what} tables need rules (n2, n1 >= 2) and 8 lims (first 7 finite), "
            f"got rules {r.shape}, lims {m.shape}")
    n_out = int(m[6])
    if np.any((r < -1) | (r >= n_out)):
        raise ParameterError(f"{what} rules must be -1 or 0..{n_out - 1}")
    return r, m


def _empty_rules() -> IntArray:
    return np.full((2, 2), -1, dtype=np.int64)


def _empty_lims() -> FloatArray:
    return np.array([-1.0, 1.0, -1.0, 1.0, 0.0, 1.0, 2.0, 1.0])


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class FuzzyPIController:
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

    kind: ClassVar[int] = 1
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
        r, m = _tables(self.du_rules, self.du_lims, "du")
        object.__setattr__(self, "du_rules", r)
        object.__setattr__(self, "du_lims", m)
        r, m = _tables(self.alpha_rules, self.alpha_lims, "alpha")
        object.__setattr__(self, "alpha_rules", r)
        object.__setattr__(self, "alpha_lims", m)

    @classmethod
    def from_systems(cls, du_system: KernelSystem, alpha_system: KernelSystem | None = None,
                     **options: Any) -> Self:
        """Build from two-input fuzzy systems (:class:`KernelSystem`): ``fuzzyservo.paper``'s
        ``du_system()`` and ``alpha_system()`` (the uniform-grid fast path), or systems read
        from files and compiled (the general evaluator); ``options`` are the other fields."""
        du_rules, du_lims = du_system.kernel_args()
        if alpha_system is not None:
            a_rules, a_lims = alpha_system.kernel_args()
            options = {**options, "alpha_rules": a_rules, "alpha_lims": a_lims}
        return cls(du_rules=du_rules, du_lims=du_lims, **options)

    def tables(self) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
        """``(du_rules, du_lims, alpha_rules, alpha_lims)`` as passed to the kernels."""
        return self.du_rules, self.du_lims, self.alpha_rules, self.alpha_lims

    def initial_state(self, *, u0: float = 0.0) -> FuzzyPIState:
        """State before the first sample, holding the command ``u0`` [-] (bumpless start)."""
        return FuzzyPIState(u_prev=u0, e_prev=0.0, y_filtered=0.0, started=False, alpha=1.0)

    def pack(self) -> FloatArray:
        """Packed parameter vector for :func:`fuzzy_pi_step`."""
        return self.pack_gains(np.array([[self.ke, self.kde, self.kdu]]))[0]

    def pack_gains(self, gains: FloatArray) -> FloatArray:
        """Pack one parameter row per row of ``gains`` (columns ``ke, kde, kdu``)."""
        g = np.asarray(gains, dtype=np.float64)
        if g.ndim != 2 or g.shape[1] != len(FUZZY_GAIN_NAMES):
            raise ParameterError(
                f"fuzzy gains need shape (runs, 3) with columns ke, kde, kdu, got {g.shape}")
        bad = ~(np.isfinite(g) & (g >= 0.0))
        if np.any(bad):
            i, j = np.argwhere(bad)[0]
            raise ParameterError(
                f"gain {FUZZY_GAIN_NAMES[j]} must be finite and >= 0, got {g[i, j]!r}")
        out = np.empty((g.shape[0], _NP))
        out[:, _KE] = g[:, 0]
        out[:, _KDE] = g[:, 1]
        out[:, _KDU] = g[:, 2]
        out[:, _UMIN] = self.u_min
        out[:, _UMAX] = self.u_max
        out[:, _DESCALE] = 1.0 if self.de_per == "sample" else 1.0 / self.dt
        out[:, _EINIT] = 1.0 if self.initial_error == "first" else 0.0
        out[:, _FILT] = math.exp(-self.dt / self.filter_time) if self.filter_time > 0 else 0.0
        out[:, _ST] = 1.0 if self.self_tuning else 0.0
        return out

    def rest_states(self, packed: FloatArray, y0: float, u0: float) -> FloatArray:
        """Packed states before the first sample, one per packed parameter row, holding the
        command ``u0`` [-] (``y0`` [m] is not needed: the first sample sets e(-1), y_f)."""
        out = np.zeros((packed.shape[0], 5))
        out[:, _UPREV] = u0
        out[:, _ALPHA] = 1.0
        return out

    def pack_state(self, state: object) -> FloatArray:
        """Packed state vector (u_prev, e_prev, y_filtered, started, alpha)."""
        if not isinstance(state, FuzzyPIState):
            raise ParameterError(f"expected a FuzzyPIState, got {type(state).__name__}")
        return np.array([state.u_prev, state.e_prev, state.y_filtered,
                         1.0 if state.started else 0.0, state.alpha])

    def unpack_state(self, s: FloatArray) -> FuzzyPIState:
        """Inverse of :meth:`pack_state`."""
        return FuzzyPIState(u_prev=float(s[_UPREV]), e_prev=float(s[_EPREV]),
                            y_filtered=float(s[_YF]), started=bool(s[_STARTED] != 0.0),
                            alpha=float(s[_ALPHA]))

    def step(self, state: FuzzyPIState, reference: float, measurement: float
             ) -> tuple[float, FuzzyPIState]:
        """One sample: command u [-] from reference and measurement [m], and the new state."""
        s = self.pack_state(state)
        u = fuzzy_pi_step_arrays(self.pack(), s, float(reference), float(measurement),
                                 self.du_rules, self.du_lims, self.alpha_rules,
                                 self.alpha_lims)
        return float(u), self.unpack_state(s)
