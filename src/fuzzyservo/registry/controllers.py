"""The controller registry: every controller kind a user can name, registered once.

Each :class:`ControllerKind` names a controller, its class (the maths, in
:mod:`fuzzyservo.control`), its gains with units, defaults and tuning boxes, the class gains the
kind fixes, the options it takes and how it is tuned. The command line (``simulate``, ``tune``),
the tuner (:mod:`fuzzyservo.analysis.autotune`), the study, the gains files and every later
front end build controllers through :func:`build_controller` and offer the names of
:func:`controller_names`; none keeps a list of its own. Adding a kind is its maths plus one
entry of :data:`CONTROLLERS` (docs/architecture.md, "Registries").

Names follow MATLAB's ``pid`` / ``pid2`` objects: ``pid`` is the one-degree-of-freedom PID
(setpoint weights b = c = 1), ``pid2`` the two-degree-of-freedom PID with setpoint weights b and
c (I-PD is ``pid2`` with b = c = 0).

Examples
--------
>>> from fuzzyservo.registry import build_controller
>>> ctl = build_controller("pid2", {"kp": 20.0, "ki": 2.0, "kd": 0.1, "b": 0.0, "c": 0.0},
...                        dt=1e-3)
>>> (ctl.b, ctl.c, ctl.n)
(0.0, 0.0, 100.0)
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal

import numpy as np

from .._args import mapping, real
from .._typing import FloatArray
from ..control import (
    FFPDController,
    FuzzyPIController,
    PIDController,
    SelfTuningFuzzyPIController,
    SlidingModeController,
    WooFuzzyPIController,
)
from ..control.fuzzy_pi import KernelSystem
from ..control.smc import PAPER_MODEL_GAINS as SMC_PAPER_MODEL
from ..errors import ParameterError
from ..fuzzy.engine import pack
from ..paper import alpha_system, du_system
from ._table import lookup

__all__ = [
    "CONTROLLERS",
    "ControllerKind",
    "GainSpec",
    "OptionSpec",
    "build_controller",
    "controller_colour",
    "controller_options",
    "controller_kind",
    "controller_names",
    "default_systems",
    "register_controller",
    "unregister_controller",
]

Controller = PIDController | FuzzyPIController | FFPDController


@dataclass(frozen=True, slots=True, kw_only=True)
class GainSpec:
    """One gain of a controller kind.

    Parameters
    ----------
    name : str
        Gain name as written in ``--gains`` and gains files.
    unit : str
        Unit of the gain (u is a fraction of the rated command, e in metres).
    description : str
        What the gain does.
    default : float or None
        Value when not given; None makes the gain required.
    search : (float, float) or None
        Tuning box [lower, upper] in ``unit``, or in ``unit`` per metre of step for a
        ``per_step`` gain; None: not searched by the tuner.
    log : bool
        Search on a logarithmic scale.
    per_step : bool
        The box scales with 1/step (the error normalisation K_e: e_n = 1 at the step for
        K_e = 1/step).
    held : float or None
        Value while tuning when not searched; None holds the default.
    allow_inf : bool
        ``inf`` is allowed (the derivative filter n: no filter).
    positive : bool
        The gain must be > 0, not only >= 0 (a model gain the law divides by: smc's k_o and
        omega_0); the exported C and Structured Text check it too.
    zero : bool
        The tuner may also set the gain to exactly 0 (a log-scale gain: below the lower end of
        its box lies a region meaning 0, :data:`fuzzyservo.analysis.tuning.ZERO_DECADES` wide),
        so a search can switch the term off instead of stopping at the box's smallest value.
    slider : (float, float) or None
        Range of the gain's slider in the browser page (``fuzzyservo app``) [unit]; None: the
        tuning box (scaled by 1/step for a ``per_step`` gain). Either is required to show a
        slider; the page's number box takes any value the gain allows.
    """

    name: str
    unit: str
    description: str
    default: float | None = None
    search: tuple[float, float] | None = None
    log: bool = True
    per_step: bool = False
    held: float | None = None
    allow_inf: bool = False
    positive: bool = False
    zero: bool = False
    slider: tuple[float, float] | None = None

    def check(self, value: float, where: str) -> float:
        """``value`` as a float, validated (finite and >= 0; n: > 0 or inf)."""
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ParameterError(f"{where}gain {self.name}: {value!r:.60} is not a "
                                 f"number") from None
        except OverflowError:  # an int beyond the largest float (10**400)
            raise ParameterError(f"{where}gain {self.name}: {value!r:.40}... is too large for "
                                 f"a float (at most 1.8e308)") from None
        if self.allow_inf:
            if not (v > 0.0) or math.isnan(v):
                raise ParameterError(f"{where}gain {self.name} must be > 0 (inf: none), got "
                                     f"{v!r}")
            return v
        if self.positive:
            if not (math.isfinite(v) and v > 0.0):
                raise ParameterError(f"{where}gain {self.name} must be finite and > 0, got "
                                     f"{v!r}")
            return v
        if not (math.isfinite(v) and v >= 0.0):
            raise ParameterError(f"{where}gain {self.name} must be finite and >= 0, got {v!r}")
        return v

    def held_value(self) -> float:
        """The value held while tuning when the gain is not searched."""
        v = self.held if self.held is not None else self.default
        if v is None:
            raise ParameterError(f"gain {self.name} is neither searched nor has a value to hold")
        return v


@dataclass(frozen=True, slots=True, kw_only=True)
class OptionSpec:
    """One keyword option of a controller kind, declared once for every front end.

    The command line's flag (``--anti-windup``) and its help, the browser page's widget, the
    keys a sweep spec's ``options`` table takes and their validation are all made from this
    declaration (docs/architecture.md, "Registries").

    Parameters
    ----------
    name : str
        Keyword of the controller class (``anti_windup``); the flag is ``--anti-windup``.
    type : type
        ``str`` or ``float``: the type of the value.
    default : object
        The class's value when the option is not given (shown in help texts).
    choices : tuple of str
        The values a ``str`` option takes (empty: any text, or a number for ``float``).
    unit : str
        Unit of a ``float`` option ("s"); empty for a choice.
    help : str
        What the option does, starting with the kinds it applies to ("PID family: ...").
    offered : bool
        Offered by the front ends (a command-line flag, a widget of the page, a key of a
        sweep spec); False for an option only code sets (the command limits).
    """

    name: str
    type: type[Any] = str
    default: Any = None
    choices: tuple[str, ...] = ()
    unit: str = ""
    help: str = ""
    offered: bool = True

    @property
    def flag(self) -> str:
        """The command-line flag (``--anti-windup``)."""
        return "--" + self.name.replace("_", "-")

    @property
    def label(self) -> str:
        """The option's name in words (``anti windup``), as the page labels it."""
        return self.name.replace("_", " ")

    @property
    def metavar(self) -> str | None:
        """The flag's metavar: none for a choice (argparse lists the choices), the unit in
        capitals for a number (``S``)."""
        if self.choices:
            return None
        return (self.unit or "x").upper() if self.type is float else "TEXT"

    def default_text(self) -> str:
        """The default as help texts show it (``clamping``, ``0``)."""
        return f"{self.default:g}" if isinstance(self.default, float) else str(self.default)

    def help_text(self) -> str:
        """The flag's help: :attr:`help`, the unit in brackets, then the default."""
        unit = f" [{self.unit}]" if self.unit else ""
        return f"{self.help}{unit} (default {self.default_text()})"

    def parse(self, value: Any, where: str = "") -> Any:
        """``value`` as the option's type, checked against its choices.

        Raises
        ------
        ParameterError
            A value not among the choices, or not a number for a ``float`` option
            (``where`` prefixes the message).
        """
        if self.type is float:
            try:  # the class checks the range (its messages are the command line's)
                if isinstance(value, bool):
                    raise TypeError
                return float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"{where}option {self.name} must be a number, got "
                                     f"{value!r}") from None
        text = str(value) if not isinstance(value, str) else value
        if self.choices and text not in self.choices:
            raise ParameterError(f"{where}option {self.name} must be one of "
                                 f"{', '.join(self.choices)}, got {value!r}")
        return text

    def text(self, value: Any) -> str:
        """``value`` as the command line writes it (a number as its shortest repr)."""
        return repr(float(value)) if self.type is float else str(value)


#: Options of the package's kinds by name; a kind may also name one of these by its string.
ANTI_WINDUP = OptionSpec(name="anti_windup", choices=("clamping", "back-calculation", "none"),
                         default="clamping", help="PID family: anti-windup scheme")
TRACKING_TIME = OptionSpec(name="tracking_time", type=float, default=None, unit="s",
                           help="PID family: back-calculation time constant", offered=False)
U_MIN = OptionSpec(name="u_min", type=float, default=-1.0, unit="-",
                   help="lower command limit", offered=False)
U_MAX = OptionSpec(name="u_max", type=float, default=1.0, unit="-",
                   help="upper command limit", offered=False)
INITIAL_ERROR = OptionSpec(name="initial_error", choices=("zero", "first"), default="zero",
                           help="fuzzy PIs: e(-1) = 0 or e(-1) = e(0)")
DE_PER = OptionSpec(name="de_per", choices=("sample", "second"), default="sample",
                    help="fuzzy PIs: Δe per sample or per second")
FILTER_TIME = OptionSpec(name="filter_time", type=float, default=0.0, unit="s",
                         help="fuzzy PIs: measurement filter time constant")
INTEGRAL_ACTION = OptionSpec(name="integral_action", choices=("off", "on"), default="off",
                             help="SMC: integral term in the sliding surface (clamping "
                                  "anti-windup)")
REFERENCE_JERK = OptionSpec(name="reference_jerk", choices=("difference", "zero"),
                            default="difference",
                            help="SMC: reference jerk in the equivalent control (backward "
                                 "difference of the reference's acceleration, or 0)")
_KNOWN_OPTIONS = {o.name: o for o in (ANTI_WINDUP, TRACKING_TIME, U_MIN, U_MAX, INITIAL_ERROR,
                                      DE_PER, FILTER_TIME, INTEGRAL_ACTION, REFERENCE_JERK)}


def _option(o: OptionSpec | str) -> OptionSpec:
    """An option given by its declaration, or by name: one of :data:`_KNOWN_OPTIONS`, else a
    keyword that only code sets (not offered)."""
    if isinstance(o, OptionSpec):
        return o
    if not isinstance(o, str):
        raise ParameterError(f"a controller option is an OptionSpec or a keyword name, got "
                             f"{o!r}")
    return _KNOWN_OPTIONS.get(o) or OptionSpec(name=o, type=float, offered=False)


@dataclass(frozen=True, slots=True, kw_only=True)
class ControllerKind:
    """A controller a user can name: its maths (``cls``), gains, options and tuning.

    Parameters
    ----------
    name : str
        The name (``--controller NAME``, ``controller = "NAME"`` in gains files).
    title : str
        Short human name (legends, help).
    cls : type
        The controller class in :mod:`fuzzyservo.control`.
    gains : tuple of GainSpec
        The kind's gains, in the order they are written.
    implied : mapping of str to float
        Gains of ``cls`` that the kind fixes (``pid``: b = c = 1) [units of those gains].
    options : tuple of OptionSpec (or str)
        Keyword options of ``cls`` the kind takes (anti-windup, fuzzy PI conventions, limits),
        each declared once (:class:`OptionSpec`); a name alone is one of the package's
        declarations or, if none has that name, a keyword only code sets.
    systems : tuple of str
        Fuzzy systems the kind needs (``"du"``, ``"alpha"``).
    tuning : {"search", "paper-steps"}
        How :func:`fuzzyservo.analysis.autotune.tune_controller` tunes it: one search over
        the searched gains, or the paper's steps 1-3 (Sec. III A) through ``stage_kind``.
    stage_kind : str or None
        For ``"paper-steps"``: the kind tuned in step 1 (it searches the same gains).
    rise_gain : str or None
        For ``"paper-steps"``: the output gain raised in step 2 until the rise time of step 1
        is recovered.
    colour : str or None
        Colour of the kind's runs in the browser page and the study's figures (``#rrggbb``);
        None: one of a fallback palette by the kind's position in the registry.
    start_gains : str or None
        The kind whose shipped tuned gains (``data/gains/PLANT-KIND.toml``) the browser page
        starts this kind from (``p`` and ``pi``: the tuned PID's, of which they take ``kp``
        and ``ki``); None: the kind's own.
    """

    name: str
    title: str
    cls: type[Any]
    gains: tuple[GainSpec, ...]
    implied: Mapping[str, float] = field(default_factory=dict)
    options: tuple[OptionSpec, ...] = ()
    systems: tuple[str, ...] = ()
    tuning: Literal["search", "paper-steps"] = "search"
    stage_kind: str | None = None
    rise_gain: str | None = None
    colour: str | None = None
    start_gains: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "options", tuple(_option(o) for o in self.options))

    @property
    def option_names(self) -> tuple[str, ...]:
        """Keywords of the kind's options, in order."""
        return tuple(o.name for o in self.options)

    def option(self, name: str) -> OptionSpec:
        """The declaration of option ``name``."""
        for o in self.options:
            if o.name == name:
                return o
        raise ParameterError(f"controller {self.name} takes no option {name!r}; its "
                             f"options: {', '.join(self.option_names) or 'none'}")

    @property
    def gain_names(self) -> tuple[str, ...]:
        """Names of the kind's gains, in order."""
        return tuple(g.name for g in self.gains)

    @property
    def required(self) -> tuple[str, ...]:
        """Gains without a default."""
        return tuple(g.name for g in self.gains if g.default is None)

    @property
    def searched(self) -> tuple[str, ...]:
        """Gains the tuner searches."""
        return tuple(g.name for g in self.gains if g.search is not None)

    def gain(self, name: str) -> GainSpec:
        """The spec of gain ``name``."""
        for g in self.gains:
            if g.name == name:
                return g
        raise ParameterError(f"unknown gain {name!r} for controller {self.name}; allowed: "
                             f"{', '.join(self.gain_names)}")

    def check_gains(self, gains: Mapping[str, float], *, where: str = "") -> dict[str, float]:
        """Every gain of the kind from ``gains``: validated, defaults filled in.

        A gain the kind fixes (``implied``) is accepted when it has the fixed value, so a
        ``pid`` gains file may say b = c = 1.

        Raises
        ------
        ParameterError
            An unknown gain, a fixed one with another value, a bad value or a missing
            required gain (``where`` prefixes the message, e.g. the file name).
        """
        out: dict[str, float] = {}
        for name, value in gains.items():
            if name in self.implied:
                if float(value) != self.implied[name]:
                    raise ParameterError(
                        f"{where}controller {self.name} ({self.title}) has {name} = "
                        f"{self.implied[name]:g}, got {name} = {value!r}"
                        + ("; use pid2 for setpoint weights" if name in ("b", "c") else ""))
                continue
            if name not in self.gain_names:
                raise ParameterError(f"{where}unknown gain {name!r} for controller {self.name}; "
                                     f"allowed: {', '.join(self.gain_names)}")
            out[name] = self.gain(name).check(value, where)
        missing = [n for n in self.required if n not in out]
        if missing:
            raise ParameterError(
                f"{where}controller {self.name} needs gains {', '.join(missing)} "
                f"(--gains {','.join(f'{n}=...' for n in self.required)})")
        for g in self.gains:
            if g.name not in out:
                assert g.default is not None
                out[g.name] = g.default
        return {n: out[n] for n in self.gain_names}

    def class_row(self, gains: Mapping[str, float]) -> FloatArray:
        """One row of the class's gains (``cls.gain_names``, what batches take) from a
        complete mapping of the kind's gains."""
        merged = {**self.implied, **gains}
        return np.array([merged[n] for n in self.cls.gain_names], dtype=np.float64)

    def structure(self, gains: Mapping[str, float]) -> str:
        """What a design of this kind is, given its gains: for the PID family the terms in
        use ("P", "PI", "PD" or "PID", from the gains that are not 0, including those the
        kind fixes), else the kind's title. A tuned "PID" whose ki and kd end at 0 is a P
        controller and is named so (docs/model.md, "Tuning")."""
        if self.cls is not PIDController:
            return self.title
        merged = {**self.implied, **gains}
        terms = "P" + ("I" if merged.get("ki", 0.0) != 0.0 else "") + (
            "D" if merged.get("kd", 0.0) != 0.0 else "")
        return terms

    def search_box(self, step: float) -> tuple[tuple[str, float, float, bool, bool], ...]:
        """The tuner's default box for a step of ``step`` [m]: (name, lower, upper, log,
        may be 0)."""
        out = []
        for g in self.gains:
            if g.search is not None:
                scale = 1.0 / step if g.per_step else 1.0
                out.append((g.name, g.search[0] * scale, g.search[1] * scale, g.log, g.zero))
        return tuple(out)

    def held(self, overrides: Mapping[str, float] | None = None) -> dict[str, float]:
        """Values of the gains the tuner does not search (``overrides`` replace some)."""
        ov = dict(overrides or {})
        return {g.name: float(ov.get(g.name, g.held_value())) for g in self.gains
                if g.search is None}

    def build(self, gains: Mapping[str, float], *, dt: float,
              systems: Mapping[str, KernelSystem] | None = None,
              options: Mapping[str, Any] | None = None) -> Any:
        """The controller with ``gains`` (checked, defaults filled) at sample time ``dt`` [s].

        ``systems`` replaces the fuzzy systems (default :func:`default_systems`); ``options``
        are keyword options of the class that the kind takes (:attr:`options`).

        Raises
        ------
        ParameterError
            Gains, systems or options that are not mappings, a sample time that is not a
            positive number, bad gains, an option the kind does not take, or a missing fuzzy
            system (the message names the argument, the value and its type).
        """
        mapping(gains, "gains", "gain name to value, e.g. {'kp': 10.0}")
        dt = real(dt, "dt (the sample time)", "s", positive=True)
        if systems is not None:
            mapping(systems, "systems", "role to fuzzy system, e.g. {'du': ...}")
        options = dict(mapping(options, "options", "option name to value") if options
                       is not None else {})
        bad = [o for o in options if o not in self.option_names]
        if bad:
            raise ParameterError(f"controller {self.name} takes no option {bad[0]!r}; its "
                                 f"options: {', '.join(self.option_names) or 'none'}")
        g = dict(zip(self.cls.gain_names, self.class_row(self.check_gains(gains)).tolist(),
                     strict=True))
        if not self.systems:
            return self.cls(dt=dt, **g, **options)
        fs = dict(default_systems(self.systems)) if systems is None else dict(systems)
        missing = [s for s in self.systems if s not in fs]
        if missing:
            raise ParameterError(f"controller {self.name} needs the fuzzy system(s) "
                                 f"{', '.join(missing)}")
        alpha = fs.get("alpha") if "alpha" in self.systems else None
        return self.cls.from_systems(fs["du"], alpha, dt=dt, **g, **options)

    def template(self, *, dt: float, systems: Mapping[str, KernelSystem] | None = None,
                 options: Mapping[str, Any] | None = None) -> Any:
        """A controller of this kind whose gains a batch replaces row by row (required gains
        set to 0)."""
        return self.build({n: 0.0 for n in self.required}, dt=dt, systems=systems,
                          options=options)


def default_systems(names: tuple[str, ...] = ("du", "alpha")) -> dict[str, KernelSystem]:
    """The paper's fuzzy systems by role, packed: ``du`` (Fig. 3a) and ``alpha`` (Fig. 3b).

    Built once per process and shared: they are frozen, and building them (checking every
    output set) took 14 ms of each controller built, most of a browser-page run."""
    return {n: _paper_system(n) for n in names}


@functools.cache
def _paper_system(role: str) -> KernelSystem:
    return pack({"du": du_system, "alpha": alpha_system}[role]())


_PID_OPTIONS = (ANTI_WINDUP, TRACKING_TIME, U_MIN, U_MAX)
_FUZZY_OPTIONS = (INITIAL_ERROR, DE_PER, FILTER_TIME, U_MIN, U_MAX)

# Tuning boxes (docs/model.md, "Tuning"): PID gains span decades (log scale); the paper's PIDs
# (0.5-1.2) sit inside. ki reaches 1e3: the 2-DOF PID on the nonlinear plant ends at ki = 226
# with b = 0.35 (an upper end of 100 held it on its bound, 49 % worse in ITAE). ki and kd may
# also be exactly 0 (a P, PI or PD design is a PID the search may find). Fuzzy PI (model-notes
# §5.3): ke from 1/step (the paper's step 1: the error fills [-1, 1]; below it the fuzzy PI
# works in the linear middle of its rule base and is a linear PI) to 10/step, kde around the
# 4e3 that normalises a 0.26 m/s slew per 1 ms sample, two decades either side, kdu up to
# where kdu kde K_v stays below ~4 1/s.
_KP = GainSpec(name="kp", unit="1/m", description="proportional gain", search=(0.01, 100.0))
_KI = GainSpec(name="ki", unit="1/(m s)", description="integral gain", search=(1e-3, 1e3),
               zero=True)
_KD = GainSpec(name="kd", unit="s/m", description="derivative gain", search=(1e-4, 10.0),
               zero=True)
_N = GainSpec(name="n", unit="1/s", description="derivative filter coefficient (inf: none)",
              default=100.0, allow_inf=True, slider=(1.0, 1e4))
_KE = GainSpec(name="ke", unit="1/m", description="error scaling K_e", search=(1.0, 10.0),
               per_step=True)
_KDE = GainSpec(name="kde", unit="1/m per sample",
                description="error-change scaling K_Δe (per sample; s/m with de_per=second)",
                search=(10.0, 1e6))
_KDU = GainSpec(name="kdu", unit="-", description="output scaling K_Δu", search=(1e-5, 1.0))

# Colours: each kind's runs, on the page and in the study's figures (which draw each design in
# its kind's colour; study.paper_study.DESIGN_COLOURS names the few designs that share a kind
# with another): PID brown, 2-DOF PID purple, fuzzy PI green, self-tuning fuzzy PI blue,
# P red and PI orange (the colours of the paper's two PIDs in the study), Woo et al.'s
# self-tuning fuzzy PI olive.
_CONTROLLERS: dict[str, ControllerKind] = {
    "p": ControllerKind(
        name="p", title="P", cls=PIDController, gains=(_KP,),
        implied={"ki": 0.0, "kd": 0.0, "n": 100.0, "b": 1.0, "c": 1.0}, options=_PID_OPTIONS,
        colour="#d62728", start_gains="pid"),
    "pi": ControllerKind(
        name="pi", title="PI", cls=PIDController, gains=(_KP, _KI),
        implied={"kd": 0.0, "n": 100.0, "b": 1.0, "c": 1.0}, options=_PID_OPTIONS,
        colour="#ff7f0e", start_gains="pid"),
    "pid": ControllerKind(
        name="pid", title="PID, 1-DOF", cls=PIDController, gains=(_KP, _KI, _KD, _N),
        implied={"b": 1.0, "c": 1.0}, options=_PID_OPTIONS, colour="#8c564b"),
    "pid2": ControllerKind(
        name="pid2", title="PID, 2-DOF", cls=PIDController,
        gains=(_KP, _KI, _KD, _N,
               GainSpec(name="b", unit="-", description="setpoint weight, proportional path",
                        default=1.0, search=(0.0, 1.0), log=False),
               # c = 0 while tuning: no derivative kick, and c does not enter the integral of
               # e = kp (1 - b)/ki that decides the overshoot on this plant (model-notes §5.1)
               GainSpec(name="c", unit="-", description="setpoint weight, derivative path",
                        default=1.0, held=0.0, log=False, slider=(0.0, 1.0))),
        options=_PID_OPTIONS, colour="#9467bd"),
    "fpi": ControllerKind(
        name="fpi", title="fuzzy PI", cls=FuzzyPIController, gains=(_KE, _KDE, _KDU),
        options=_FUZZY_OPTIONS, systems=("du",), colour="#2ca02c"),
    "stfpi": ControllerKind(
        name="stfpi", title="self-tuning fuzzy PI", cls=SelfTuningFuzzyPIController,
        gains=(_KE, _KDE, _KDU), options=_FUZZY_OPTIONS, systems=("du", "alpha"),
        tuning="paper-steps", stage_kind="fpi", rise_gain="kdu", colour="#1f77b4"),
    # Position control with feed-forward, the industrial axis controller (control/ffpd.py;
    # docs/model.md, "Position control with feed-forward"). Defaults: ffpd_model_gains of the
    # paper's eq. (8) at mid-stroke (K_o = 0.2619 m/s, omega_0 = 19.6 rad/s, delta = 0.1), to 4
    # digits (tests/control/test_ffpd.py checks them); another axis: ffpd_model_gains(its
    # LinearServo). Boxes: kx from 1 1/m (loop gain K_v = kx K_o = 0.26 1/s, too slow to settle
    # in the 10 s tuning run) to 1000 1/m (K_v = 262 1/s = 13 omega_0, far past the P loop's
    # stability bound 2 delta' omega_0 at any damping the valve's lag allows); ki as the PID's,
    # may be 0; ka_fb from 1e-3 s^2/m (damping raised by K_o omega_0 ka_fb/2 = 0.003: none) to
    # 10 s^2/m (delta' = 26, far overdamped), may be 0. kv_ff, ka_ff and tf are held at the
    # model's values: a step has no reference velocity or acceleration (rd = rdd = 0 at every
    # sample), so the tuner cannot see the feed-forward gains, and tf is a filter choice.
    # Colour grey: pink is the study's self-tuning fuzzy PI tuned like the PIDs (DESIGN_COLOURS).
    "ffpd": ControllerKind(
        name="ffpd", title="position control with feed-forward (industrial axis)",
        cls=FFPDController,
        gains=(GainSpec(name="kx", unit="1/m", description="proportional position gain K_x",
                        default=24.94, search=(1.0, 1000.0)),
               GainSpec(name="ki", unit="1/(m s)", description="integral gain", default=0.0,
                        search=(1e-3, 1e3), zero=True),
               GainSpec(name="kv_ff", unit="s/m", description="velocity feed-forward gain "
                        "(the model's 1/K_o)", default=3.818, slider=(0.0, 10.0)),
               GainSpec(name="ka_ff", unit="s^2/m", description="acceleration feed-forward "
                        "gain (the model's 2 delta/(omega_0 K_o))", default=0.03896,
                        slider=(0.0, 0.2)),
               GainSpec(name="ka_fb", unit="s^2/m", description="acceleration feedback gain "
                        "(active damping, on the acceleration error)", default=0.1558,
                        search=(1e-3, 10.0), zero=True),
               GainSpec(name="tf", unit="s", description="time constant of the velocity and "
                        "acceleration estimate filters", default=0.005102,
                        slider=(0.0, 0.05))),
        options=(U_MIN, U_MAX), colour="#7f7f7f"),
    # Sliding-mode control (control/smc.py), cyan. Boxes: λ from 1 1/s (slower than every
    # design of the study: the tuned PIDs rise in ~0.75 s) to 100 1/s (the surface's double
    # pole at -λ then lies within a decade of the valve's 688 rad/s, which the law's model
    # neglects); k_s up to 2 b, twice the model's jerk authority b = K_o ω₀² = 100.6 m/s³ per
    # unit command: a reaching rate beyond it is one the valve cannot give, the switching
    # term alone then spans the command range outside the layer and only k_s/φ acts (a flat
    # direction of the cost: with an upper end of 1e4 two tunings ended at k_s = 2656 and
    # 4650 with the same k_s/φ = 39.3 1/s and cost), down to 1 m/s³; φ from 1e-3 m/s² (near
    # the ideal relay) to 1e3 m/s² (above s(0) = λ² x 0.1 m for every λ of the box up to 100:
    # a layer wider than the step's s is a linear law). The filter (ω_f = 200 rad/s, 10 x ω₀
    # and below the valve's mode; ζ_f = 1) is held: the tuner's cost sees no measurement
    # noise, so it would widen the filter without limit. The model's K_o, ω₀, δ are held at
    # the paper's linear model (smc_model_gains): the tuner fits a controller, not the model.
    "smc": ControllerKind(
        name="smc", title="sliding-mode control", cls=SlidingModeController,
        gains=(GainSpec(name="lam", unit="1/s", description="sliding-surface bandwidth λ",
                        default=5.0, search=(1.0, 100.0)),
               GainSpec(name="ks", unit="m/s^3",
                        description="switching gain k_s (reaching rate η)", default=10.0,
                        search=(1.0, 200.0)),
               GainSpec(name="phi", unit="m/s^2", description="boundary-layer width φ "
                        "(0: ideal relay)", default=1.0, search=(1e-3, 1e3)),
               GainSpec(name="omega_f", unit="rad/s",
                        description="derivative filter bandwidth ω_f", default=200.0,
                        slider=(20.0, 2000.0)),
               GainSpec(name="zeta_f", unit="-", description="derivative filter damping ζ_f",
                        default=1.0, log=False, slider=(0.3, 2.0)),
               GainSpec(name="k_o", unit="m/s", description="model velocity gain K_o",
                        default=SMC_PAPER_MODEL["k_o"], slider=(0.05, 1.0), positive=True),
               GainSpec(name="omega_0", unit="rad/s",
                        description="model hydraulic natural frequency ω₀",
                        default=SMC_PAPER_MODEL["omega_0"], slider=(5.0, 100.0), positive=True),
               GainSpec(name="delta", unit="-", description="model hydraulic damping ratio δ",
                        default=SMC_PAPER_MODEL["delta"], log=False, slider=(0.0, 1.0))),
        options=(INTEGRAL_ACTION, REFERENCE_JERK, U_MIN, U_MAX), colour="#17becf"),
    # Woo, Chung & Lin (2000)'s scaling functions on the fuzzy PI (control/woo.py; docs/
    # model.md, "Baselines beside the paper's controllers"): φ = a|e_n| + b scales K_Δe, ψ =
    # c(1 - |e_n|) + d scales K_Δu. b = d = 1 are held: with K_Δe and K_Δu searched, a free
    # offset would only rescale them (b K_Δe is one gain), so the searches could not agree;
    # a and c then say how many times larger φ is at full error and ψ at zero error than at
    # the other end. Their box [0, 9] (linear: 0, the plain fuzzy PI, is a candidate) allows
    # up to a tenfold change of each factor, the order of the paper's α (17:1 between its
    # extremes). Tuned by one search over all five gains ("search"): the paper's steps exist
    # for Mudi & Pal's α < 1, which lowers the gain (step 2 raises K_Δu to recover the rise
    # time); φ, ψ >= 1 raise it, and a and c must be searched with the gains they multiply.
    "wfpi": ControllerKind(
        name="wfpi", title="self-tuning fuzzy PI (Woo et al. 2000)", cls=WooFuzzyPIController,
        gains=(_KE, _KDE, _KDU,
               GainSpec(name="phi_a", unit="-", description="slope a of φ = a|e_n| + b, the "
                        "factor of K_Δe", default=0.0, search=(0.0, 9.0), log=False),
               GainSpec(name="phi_b", unit="-", description="offset b of φ", default=1.0,
                        log=False, slider=(0.0, 2.0)),
               GainSpec(name="psi_c", unit="-", description="slope c of ψ = c(1 - |e_n|) + d, "
                        "the factor of K_Δu", default=0.0, search=(0.0, 9.0), log=False),
               GainSpec(name="psi_d", unit="-", description="offset d of ψ", default=1.0,
                        log=False, slider=(0.0, 2.0))),
        options=_FUZZY_OPTIONS, systems=("du",), colour="#bcbd22"),
}

#: Every controller kind by name (read-only view of the registry).
CONTROLLERS: Mapping[str, ControllerKind] = MappingProxyType(_CONTROLLERS)
_BUILT_IN = frozenset(_CONTROLLERS)


#: Environment variable naming modules (comma-separated) that register controllers when the
#: registry is first asked (so the command line and worker processes see a user's laws).
PLUGINS_ENV = "FUZZYSERVO_PLUGINS"
#: Entry-point group of installed packages that register controllers the same way.
PLUGINS_GROUP = "fuzzyservo.controllers"
_PLUGINS = {"loaded": False}


def _load_plugins() -> None:
    """Import the modules of :data:`PLUGINS_ENV` and of the :data:`PLUGINS_GROUP` entry
    points once; each registers its kinds with :func:`register_controller` on import."""
    if _PLUGINS["loaded"]:
        return
    _PLUGINS["loaded"] = True
    import importlib
    import os
    from importlib.metadata import entry_points

    names = [n.strip() for n in os.environ.get(PLUGINS_ENV, "").split(",") if n.strip()]
    for name in names:
        try:
            importlib.import_module(name)
        except ImportError as exc:
            raise ParameterError(f"{PLUGINS_ENV}: cannot import module {name!r} ({exc})"
                                 ) from None
    for ep in entry_points(group=PLUGINS_GROUP):
        ep.load()


def register_controller(kind: ControllerKind, *, replace: bool = False) -> ControllerKind:
    """Register a controller kind, e.g. of a control law written in a user's own module.

    Every front end then takes it by name: simulate, simulate_batch, tune, sweeps, the page,
    ``export c`` and ``export fmu`` (its class is a :class:`fuzzyservo.control.LawController`
    whose ``law`` declares the layout and the C port; docs/architecture.md, "Control laws").
    For the command line and the worker processes of sweeps, name the module in
    ``$FUZZYSERVO_PLUGINS`` or as an entry point of the group ``fuzzyservo.controllers``.

    Parameters
    ----------
    kind : ControllerKind
        The kind; its ``cls`` must have a ``law`` and ``gain_names``.
    replace : bool
        Replace a kind of the same name (default: refuse).

    Returns
    -------
    ControllerKind
        ``kind``.

    Raises
    ------
    ParameterError
        A bad name, a name taken, or a class without a law.
    """
    if not isinstance(kind, ControllerKind):
        raise ParameterError(f"expected a ControllerKind, got {type(kind).__name__}")
    if not (kind.name and all(ch.isalnum() or ch in "-_" for ch in kind.name)
            and kind.name[0].isalpha() and kind.name == kind.name.lower()):
        raise ParameterError(f"a controller name is lower-case letters, digits, - and _, "
                             f"starting with a letter; got {kind.name!r}")
    if kind.name in _CONTROLLERS and not replace:
        raise ParameterError(f"controller {kind.name!r} is registered already (replace=True "
                             f"replaces it)")
    law = getattr(kind.cls, "law", None)
    if law is None or not hasattr(kind.cls, "gain_names"):
        raise ParameterError(f"controller {kind.name}: class {kind.cls.__name__} has no law "
                             f"(a fuzzyservo.control.LawController with law and gain_names)")
    for o in kind.options:
        if not o.offered:
            continue
        other = next((k for k in _CONTROLLERS.values() if k.name != kind.name
                      for p in k.options if p.offered and p.name == o.name and p != o), None)
        if other is not None:
            raise ParameterError(f"controller {kind.name}: option {o.name} is declared "
                                 f"otherwise by controller {other.name} (one flag, "
                                 f"{o.flag}, serves both: give the same OptionSpec)")
    _CONTROLLERS[kind.name] = kind
    return kind


def unregister_controller(name: str) -> None:
    """Remove a kind :func:`register_controller` added (the built-in ones stay)."""
    if name in _BUILT_IN:
        raise ParameterError(f"controller {name} is built in and cannot be removed")
    _CONTROLLERS.pop(name, None)


def controller_names() -> tuple[str, ...]:
    """The registered controller names, in registry order."""
    _load_plugins()
    return tuple(_CONTROLLERS)


#: Colours of kinds registered without one (e.g. by a user's module): the light half of
#: Category20, which no built-in kind or study design uses, by the kind's position among them.
FALLBACK_COLOURS = ("#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94")


def controller_colour(name: str) -> str:
    """The colour of the runs of kind ``name``: its own (:attr:`ControllerKind.colour`), else
    one of :data:`FALLBACK_COLOURS` by its position among the kinds without one (an unknown
    name takes the first)."""
    _load_plugins()
    kind = _CONTROLLERS.get(name)
    if kind is not None and kind.colour is not None:
        return kind.colour
    names = [n for n, k in _CONTROLLERS.items() if k.colour is None]
    i = names.index(name) if name in names else 0
    return FALLBACK_COLOURS[i % len(FALLBACK_COLOURS)]


def controller_options() -> tuple[OptionSpec, ...]:
    """The options the front ends offer (:attr:`OptionSpec.offered`) of every registered
    kind, each once, in the order of their first kind: the command line's flags, the page's
    widgets and the keys of a sweep spec's ``options``."""
    _load_plugins()
    out: dict[str, OptionSpec] = {}
    for kind in _CONTROLLERS.values():
        for o in kind.options:
            if o.offered:
                out.setdefault(o.name, o)
    return tuple(out.values())


def controller_kind(name: str) -> ControllerKind:
    """The kind registered as ``name``.

    Raises
    ------
    ParameterError
        Unknown name (the message lists the registered ones).
    """
    _load_plugins()
    return lookup(_CONTROLLERS, name, "controller")


def build_controller(name: str, gains: Mapping[str, float], *, dt: float,
                     systems: Mapping[str, KernelSystem] | None = None,
                     options: Mapping[str, Any] | None = None) -> Any:
    """Build the controller registered as ``name`` (see :meth:`ControllerKind.build`).

    Parameters
    ----------
    name : str
        Registered name (:func:`controller_names`).
    gains : mapping of str to float
        The kind's gains in their units; missing ones take their defaults.
    dt : float
        Sample period [s].
    systems : mapping, optional
        Fuzzy systems by role (``du``, ``alpha``); default the paper's.
    options : mapping, optional
        Keyword options of the controller class that the kind takes (``anti_windup``,
        ``initial_error``, ``de_per``, ``filter_time``, ``u_min``, ``u_max``, ...).

    Returns
    -------
    PIDController, FuzzyPIController or SelfTuningFuzzyPIController
    """
    return controller_kind(name).build(gains, dt=dt, systems=systems, options=options)
