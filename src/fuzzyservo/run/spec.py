"""One description of a closed-loop run: :class:`RunSpec`, its objects and its command line.

A :class:`RunSpec` names everything that decides a run of ``fuzzyservo simulate`` in closed
loop: the controller (kind, gains, options, fuzzy systems read from files), the plant (kind,
parameter set, overrides, start, RK4 step bound) and the run (reference, duration, sample
time, delay, noise and its seed, load-force disturbance). :meth:`RunSpec.build` checks it
and makes the objects that run it (:class:`BuiltRun`), with the messages the command line
prints for each bad value; :meth:`RunSpec.to_argv` is the ``simulate`` command line that
makes the same run and :meth:`RunSpec.from_argv` reads one back. The command line
(``simulate``), the browser page and sweep replays all go through it, so the command a front
end shows reproduces its run bit for bit (docs/architecture.md, "Runs").

Examples
--------
>>> from fuzzyservo.run import RunSpec
>>> spec = RunSpec(controller="pi", gains=(("kp", 10.0), ("ki", 2.0)), plant="linear")
>>> spec.to_argv()[:6]
['--plant', 'linear', '--controller', 'pi', '--gains', 'kp=10.0,ki=2.0']
>>> RunSpec.from_argv(spec.to_argv()) == spec
True
"""

from __future__ import annotations

import argparse
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._args import seed as check_seed
from .._typing import FloatArray
from ..errors import ParameterError, UsageError
from ..paper.published import named_set
from ..plant import ServoParams, to_dict, with_overrides
from ..registry import (
    DEFAULT_SUBSTEP,
    build_plant,
    controller_kind,
    controller_names,
    controller_options,
    default_systems,
    plant_kind,
)
from ..sim import DEFAULT_DELAY, parse_reference, simulate, simulate_batch
from ..sim.disturbances import LOAD_FORCE_FORMS, load_force_samples, parse_load_force

__all__ = [
    "DEFAULT_SET",
    "BatchRun",
    "BuiltRun",
    "RunSpec",
    "check_start",
    "ControllerParts",
    "flat_params",
    "load_systems",
    "overrides_of",
    "parse_delay",
    "parse_gains_pairs",
    "parse_param",
    "run_default",
    "servo_params",
    "systems_record",
]

#: The parameter set of every command when ``--set`` is not given.
DEFAULT_SET = "paper"


def _num(v: float) -> str:
    """A float as the command line gets it: Python's shortest repr, which reads back to the
    same double (``inf`` for the PID's unfiltered derivative)."""
    return repr(float(v))


@dataclass(frozen=True, slots=True, kw_only=True)
class RunSpec:
    """A closed-loop run, as ``fuzzyservo simulate`` takes it (SI units).

    Parameters
    ----------
    controller : str
        Registered controller name.
    gains : tuple of (str, float)
        Gains as given, in the kind's units (missing ones take the registry's defaults when
        built; checked by :meth:`build`).
    options : tuple of (str, object)
        Controller options the front ends offer, as (keyword, value): ``anti_windup``,
        ``initial_error``, ``de_per``, ``filter_time`` [s], ... (the registry's
        :class:`~fuzzyservo.registry.OptionSpec`); only those set.
    systems : tuple of (str, str)
        Fuzzy systems read from files, as (role, path): ``du``, ``alpha``.
    no_rule_value : float or None
        Value of a system from a file where no rule fires (None: the file's, else NaN).
    plant : str
        Registered plant name.
    param_set : str
        Named parameter set.
    overrides : tuple of (str, float)
        ``group.field`` values replacing the set's, applied in order [SI].
    reference : str
        Reference spec, offset from the start position (``step:0.1``) [m, s].
    duration : float
        Simulated time [s].
    ts : float
        Controller sample time and sample step of the result [s].
    delay : float
        Transport (hose) delay on the command [s].
    noise_std : float
        Standard deviation of the measurement noise [m].
    seed : int
        Seed of the noise generator.
    load_force : str
        Load-force disturbance added to ``load.external_force`` [N, s], as ``--load-force``
        takes it (:func:`~fuzzyservo.sim.disturbances.parse_load_force`): ``step:F[:T]``,
        ``pwl:T0:F0,...`` or a CSV file; F > 0 opposes extension; ``""``: none.
    start : float
        Start position, fraction of the stroke [-].
    substep : float
        Nonlinear plant's RK4 step bound [s].
    """

    controller: str
    gains: tuple[tuple[str, float], ...] = ()
    options: tuple[tuple[str, Any], ...] = ()
    systems: tuple[tuple[str, str], ...] = ()
    no_rule_value: float | None = None
    plant: str = "nonlinear"
    param_set: str = DEFAULT_SET
    overrides: tuple[tuple[str, float], ...] = ()
    reference: str = "step:0.1"
    duration: float = 2.0
    ts: float = 1e-3
    delay: float = DEFAULT_DELAY
    noise_std: float = 0.0
    seed: int = 0
    load_force: str = ""
    start: float = 0.5
    substep: float = DEFAULT_SUBSTEP

    # ------------------------------------------------------------------ command line

    def gains_text(self) -> str:
        """The gains as ``--gains`` takes them: ``NAME=VALUE,...`` (values as repr)."""
        return ",".join(f"{k}={_num(v)}" for k, v in self.gains)

    def option_args(self) -> list[str]:
        """The controller options as ``--flag=value`` (what ``simulate``, ``tune`` and
        ``export`` take alike), each written as its declaration says."""
        out = []
        for name, value in self.options:
            decl = _offered(name)
            out.append(f"{decl.flag}={decl.text(value)}")
        return out

    def system_args(self) -> list[str]:
        """``--du-system``, ``--alpha-system``, ``--no-rule-value``: the fuzzy systems from
        files (what ``simulate``, ``tune`` and ``export`` take alike)."""
        out: list[str] = []
        for role, file in self.systems:
            out += [f"--{role}-system", file]
        if self.no_rule_value is not None:
            out += [f"--no-rule-value={_num(self.no_rule_value)}"]
        return out

    def controller_args(self) -> list[str]:
        """The run's controller as ``fuzzyservo export`` takes it: ``--controller``,
        ``--gains``, ``--ts``, the options and the fuzzy systems."""
        return ["--controller", self.controller, "--gains", self.gains_text(), "--ts",
                _num(self.ts), *self.option_args(), *self.system_args()]

    def parameter_args(self, *, explicit: bool = False) -> list[str]:
        """``--set`` (unless the default set, or ``explicit``) and ``--param``: the servo's
        parameters (``simulate`` and ``tune``)."""
        out = [] if self.param_set == DEFAULT_SET and not explicit else ["--set",
                                                                         self.param_set]
        for key, number in self.overrides:
            out += ["--param", f"{key}={_num(number)}"]
        return out

    def to_argv(self, *, explicit: bool = False) -> list[str]:
        """The arguments of ``fuzzyservo simulate`` that make this run (no output option).

        Numbers go as ``--flag=value`` (a negative one, a typo the command must name, would
        otherwise read as an option of its own) in their shortest repr. A setting at the
        command's default is left out (no delay, no noise, the default substep and set)
        unless ``explicit``: a record that must replay the same run whatever later defaults
        become (sweep replays) writes every one.
        """
        out = ["--plant", self.plant, "--controller", self.controller]
        if self.gains:
            out += ["--gains", self.gains_text()]
        out += ["--reference", self.reference, f"--duration={_num(self.duration)}",
                f"--ts={_num(self.ts)}", f"--start={_num(self.start)}"]
        if self.delay != 0.0 or explicit:
            out += [f"--delay={_num(self.delay)}"]
        if self.noise_std != 0.0:
            out += [f"--noise-std={_num(self.noise_std)}"]
        if self.noise_std != 0.0 or self.seed != 0:
            out += [f"--seed={self.seed}"]
        if self.load_force:
            out += [f"--load-force={self.load_force}"]
        if self.substep != DEFAULT_SUBSTEP or (explicit and self.plant == "nonlinear"):
            out += [f"--substep={_num(self.substep)}"]
        return [*out, *self.option_args(), *self.system_args(),
                *self.parameter_args(explicit=explicit)]

    def command(self) -> str:
        """The shell command of :meth:`to_argv` that also prints the step metrics."""
        import shlex

        return "fuzzyservo simulate " + shlex.join([*self.to_argv(), "--metrics"])

    @classmethod
    def from_argv(cls, argv: Sequence[str]) -> RunSpec:
        """The run of a ``fuzzyservo simulate`` command line (its first word ``simulate``
        may be left out): the command lines :meth:`to_argv` writes, or any closed-loop one
        whose gains are ``NAME=VALUE`` pairs and whose delay is a number.

        Raises
        ------
        UsageError
            An argument this reader does not take (an output, a gains file, ``--delay hose``,
            ``--params FILE``, the open loop): build those with the command itself.
        ParameterError
            Gains or ``--param`` values that are not numbers.
        """
        words = list(argv)
        if words[:1] == ["simulate"]:
            words = words[1:]
        args = _parser().parse_args(words)
        options = tuple((o.name, getattr(args, o.name)) for o in controller_options()
                        if getattr(args, o.name) is not None)
        systems = tuple((role, getattr(args, f"{role}_system")) for role in ("du", "alpha")
                        if getattr(args, f"{role}_system") is not None)
        overrides: dict[str, float] = {}
        for text in args.param:
            name, value = parse_param(text)
            overrides.pop(name, None)  # keep the order in which they take effect
            overrides[name] = value
        return cls(controller=args.controller,
                   gains=tuple(parse_gains_pairs(args.gains or "").items()),
                   options=options, systems=systems, no_rule_value=args.no_rule_value,
                   plant=args.plant, param_set=args.param_set or DEFAULT_SET,
                   overrides=tuple(overrides.items()), reference=args.reference,
                   duration=args.duration, ts=args.ts, delay=args.delay,
                   noise_std=args.noise_std, seed=args.seed, load_force=args.load_force,
                   start=args.start, substep=args.substep)

    # ------------------------------------------------------------------ objects

    def params(self) -> ServoParams:
        """The servo parameters: the set with the overrides."""
        return servo_params(self.param_set, self.overrides)

    def option_map(self) -> dict[str, Any]:
        """The options as keyword arguments of the controller class.

        Raises
        ------
        ParameterError
            An option the kind does not take (named by its flag), or a value its declaration
            refuses.
        """
        kind = controller_kind(self.controller)
        out = {}
        for name, value in self.options:
            decl = _offered(name)
            if name not in kind.option_names:
                raise ParameterError(f"{decl.flag} does not apply to controller "
                                     f"{self.controller} ({kind.title})")
            out[name] = decl.parse(value, f"{decl.flag}: ")
        return out

    def checked_params(self) -> ServoParams:
        """The servo parameters, each override checked as ``--param`` checks it.

        Raises
        ------
        ParameterError
            An unknown set, a malformed or non-finite override, or parameters the model
            refuses.
        """
        for key, value in self.overrides:
            parse_param(f"{key}={_num(value)}")
        return self.params()

    def checked_delay(self, params: ServoParams) -> float:
        """The delay [s], checked as ``--delay`` checks it."""
        return parse_delay(_num(self.delay), params)

    def build_controller(self, *, systems: Mapping[str, Any] | None = None
                         ) -> ControllerParts:
        """The controller and what it was built from: sample time, gains, options and fuzzy
        systems checked in that order (what ``export`` takes as well).

        ``systems`` (role -> packed system) are the fuzzy systems when the caller holds them
        already (the study and the tuner read each file once for many runs): they replace
        reading :attr:`systems` (and the paper's for the roles no file gives), so they hold
        every role the kind needs; one missing is refused.

        Raises
        ------
        ParameterError, InputError, FormatError
            A bad sample time, gains, an option the kind does not take, an unreadable system.
        """
        ts = self._checked_ts()
        kind = controller_kind(self.controller)
        gains = kind.check_gains(dict(self.gains))
        options = self.option_map()
        fuzzy = self._fuzzy(systems)
        controller = kind.build(gains, dt=ts, options=options, systems=fuzzy)
        return ControllerParts(controller=controller, gains=gains, options=options,
                               systems=fuzzy)

    def _checked_ts(self) -> float:
        """The sample time [s], checked as ``--ts`` checks it."""
        ts = self.ts
        if not (isinstance(ts, float | int) and math.isfinite(ts) and ts > 0.0):
            raise ParameterError(f"--ts must be finite and > 0 s, got {ts!r}")
        return float(ts)

    def _fuzzy(self, systems: Mapping[str, Any] | None) -> dict[str, Any] | None:
        """The fuzzy systems by role: ``systems``' roles of the kind, else those of
        :attr:`systems` read from their files (None: the paper's)."""
        if systems is None:
            return load_systems(self.controller, dict(self.systems), self.no_rule_value)
        needs = controller_kind(self.controller).systems
        if not needs:
            return None
        return {r: systems[r] for r in needs if r in systems}  # a missing one is refused

    def _resolved_params(self, params: ServoParams | None) -> ServoParams:
        """The servo parameters: :meth:`checked_params`, or ``params`` when the caller holds
        them already, refused unless they are the set with the overrides, value for value."""
        if params is None:
            return self.checked_params()
        named = self.checked_params()
        if params is named:
            return params
        mine, theirs = flat_params(named), flat_params(params)
        # each value as the double the model computes with (an int 900 is 900.0), NaN equal
        diff = next((k for k in mine if repr(mine[k]) != repr(theirs[k])), None)
        if diff is not None:
            raise ParameterError(
                f"the servo parameters given are not the run's set {self.param_set!r} with "
                f"its overrides: {diff} is {theirs[diff]!r}, the run says {mine[diff]!r} "
                f"(add it to the overrides)")
        return params

    def _check_substep(self) -> None:
        """The RK4 step bound, the command line's first check (the delay, start, reference
        and seed follow the controller and the parameters: :meth:`_loop`)."""
        if not (math.isfinite(self.substep) and self.substep > 0.0):
            raise ParameterError(f"--substep must be finite and > 0 s, got {self.substep!r}")

    def build(self, *, params: ServoParams | None = None,
              systems: Mapping[str, Any] | None = None) -> BuiltRun:
        """Check the run and make what runs it, in the command line's order and with its
        messages: substep, sample time, gains, options, fuzzy systems, controller,
        parameters, delay, start, reference, seed, plant.

        ``params`` and ``systems`` are the servo parameters and the fuzzy systems (role ->
        packed system, every role the kind needs) when the caller holds them already (the
        study's and the tuner's many runs of one description): ``params`` must be the set
        with the overrides, each value the same double (else :class:`ParameterError` names
        the first that differs), ``systems`` replace reading the files of :attr:`systems`.

        Raises
        ------
        ParameterError, InputError, FormatError
            Whatever ``fuzzyservo simulate`` would reject for this run (one line, as it
            prints it).
        """
        self._check_substep()
        ctl = self.build_controller(systems=systems)
        resolved, plant, reference = self._loop(params)
        return BuiltRun(spec=self, controller=ctl.controller, plant=plant, params=resolved,
                        reference=reference, gains=ctl.gains, options=ctl.options,
                        systems=ctl.systems, load=self.checked_load_force())

    def checked_load_force(self) -> Any:
        """The load-force profile (None: none), checked as ``--load-force`` checks it.

        Raises
        ------
        InputError
            A form :func:`~fuzzyservo.sim.disturbances.parse_load_force` does not take, or an
            unreadable profile file.
        """
        if not isinstance(self.load_force, str):
            raise ParameterError(f"--load-force must be text ({LOAD_FORCE_FORMS}), got "
                                 f"{self.load_force!r}")
        return parse_load_force(self.load_force)

    def _loop(self, params: ServoParams | None) -> tuple[ServoParams, Any, Any]:
        """The parameters, plant and reference, checked after the controller."""
        resolved = self._resolved_params(params)
        self.checked_delay(resolved)
        check_start(self.start)
        reference = parse_reference(self.reference)
        self.checked_load_force()
        check_seed(self.seed, "--seed")
        return resolved, self.plant_of(resolved), reference

    def plant_of(self, params: ServoParams) -> Any:
        """The run's plant (kind, start position, RK4 step bound) with ``params``: the plant
        of this run on changed parameters (the study's changed plants, a robust set)."""
        return _plant(self.plant, params, self.start * params.cylinder.stroke, self.substep)

    def build_batch(self, *, params: ServoParams | None = None,
                    systems: Mapping[str, Any] | None = None) -> BatchRun:
        """Check the run as :meth:`build` does, but for many runs that differ in gains (and
        plant, delay or noise): a template controller whose gains each row replaces, with
        the run's sample time, options and fuzzy systems. :attr:`gains` may be left out
        (they are the rows'); given, they are checked.

        Raises
        ------
        ParameterError, InputError, FormatError
            As :meth:`build`.
        """
        self._check_substep()
        ts = self._checked_ts()
        kind = controller_kind(self.controller)
        if self.gains:
            kind.check_gains(dict(self.gains))
        options = self.option_map()
        template = kind.template(dt=ts, systems=self._fuzzy(systems), options=options)
        resolved, plant, reference = self._loop(params)
        return BatchRun(spec=self, template=template, plant=plant, params=resolved,
                        reference=reference, load=self.checked_load_force())

    def run(self) -> Any:
        """Build and simulate the run (:meth:`BuiltRun.simulate`)."""
        return self.build().simulate()


@dataclass(frozen=True, slots=True)
class ControllerParts:
    """The controller of a :class:`RunSpec` and what it was built from."""

    controller: Any  #: the controller (a registry kind's class)
    gains: dict[str, float]  #: every gain of the kind, checked [SI]
    options: dict[str, Any]  #: the controller's options as keywords
    systems: dict[str, Any] | None  #: fuzzy systems by role, if any was read from a file


@dataclass(frozen=True, slots=True)
class BuiltRun:
    """The objects of a :class:`RunSpec`: what :func:`fuzzyservo.sim.simulate` takes."""

    spec: RunSpec  #: the run they make
    controller: Any  #: the controller (a registry kind's class)
    plant: Any  #: :class:`~fuzzyservo.sim.LinearPlant` or ``NonlinearPlant``
    params: ServoParams  #: the servo parameters
    reference: Any  #: the reference (offset from the start position) [m]
    gains: dict[str, float]  #: every gain of the kind, checked [SI]
    options: dict[str, Any]  #: the controller's options as keywords
    systems: dict[str, Any] | None = field(default=None)  #: fuzzy systems, if from files
    load: Any = None  #: the load-force profile (:mod:`fuzzyservo.sim.disturbances`), or None

    def disturbance(self) -> Any:
        """The total external force as :func:`~fuzzyservo.sim.simulate` takes it (a function
        of the sample times: ``load.external_force`` plus the profile, held over each
        sample), or None without a load force (the run is then bit for bit the run of
        before the load force existed)."""
        return _disturbance(self.load, self.params)

    def notes(self) -> tuple[str, ...]:
        """What the command prints as notes for the run: the scaling of each fuzzy system
        read from a file, and each override of a parameter the plant leaves out
        (``PlantKind.ignores``: the run is the same without it)."""
        from ..fuzzy.loop import LoopSystem

        systems = [f"{role} system {s.describe(role)}"
                   for role, s in sorted((self.systems or {}).items())
                   if isinstance(s, LoopSystem)]
        ignored = plant_kind(self.spec.plant).ignores
        base = to_dict(named_set(self.spec.param_set))
        unused = [f"parameter {key} = {value!r} has no effect on the {self.spec.plant} plant "
                  f"(only the nonlinear model has it); the run is the same without it"
                  for key, value in self.spec.overrides
                  if key in ignored and value != base[key.split(".")[0]][key.split(".")[1]]]
        return tuple(systems + unused)

    def rng(self) -> np.random.Generator:
        """The noise generator, seeded."""
        return np.random.default_rng(self.spec.seed)

    def simulate(self) -> Any:
        """The run (:class:`fuzzyservo.sim.SimResult`)."""
        s = self.spec
        return simulate(self.controller, self.plant, self.reference, duration=s.duration,
                        delay=s.delay, disturbance=self.disturbance(),
                        noise_std=s.noise_std, rng=self.rng())


@dataclass(frozen=True, slots=True)
class BatchRun:
    """The objects of a :class:`RunSpec` for many runs at once
    (:func:`fuzzyservo.sim.simulate_batch`): one row of gains per run, and per run
    optionally its own plant, delay and noise."""

    spec: RunSpec  #: the run they make (its gains, if any, are not used)
    template: Any  #: controller whose gains each row replaces (sample time, options, systems)
    plant: Any  #: the run's plant
    params: ServoParams  #: the servo parameters
    reference: Any  #: the reference (offset from the start position) [m]
    load: Any = None  #: the load-force profile, or None

    def row(self, gains: Mapping[str, float]) -> FloatArray:
        """One batch row: ``gains`` (checked, defaults filled) in the class's columns."""
        kind = controller_kind(self.spec.controller)
        return kind.class_row(kind.check_gains(dict(gains)))

    def simulate(self, rows: ArrayLike, *, plant: Any = None, delay: Any = None,
                 noise: Any = None, keep_traces: bool = False) -> Any:
        """The runs of ``rows`` (runs, gains of the class) on the run's plant, or
        ``plant`` (one, or one per run), with the run's delay or ``delay`` (one per run)
        [s] and measurement ``noise`` (runs, samples) [m], else the run's noise
        (:class:`fuzzyservo.sim.BatchResult`)."""
        s = self.spec
        extra: dict[str, Any] = {}
        if noise is not None:
            extra["noise"] = noise
        elif s.noise_std != 0.0:
            extra.update(noise_std=s.noise_std, rng=np.random.default_rng(s.seed))
        return simulate_batch(self.template, rows,
                              plant=self.plant if plant is None else plant,
                              reference=self.reference, duration=s.duration,
                              delay=s.delay if delay is None else delay,
                              disturbance=_disturbance(self.load, self.params),
                              keep_traces=keep_traces, **extra)


def _disturbance(load: Any, params: ServoParams) -> Any:
    """The total external force of a load-force profile on ``params`` (a function of t), or
    None for none."""
    if load is None:
        return None
    base = float(params.load.external_force)
    return lambda t: load_force_samples(load, t, base)


@functools.lru_cache(maxsize=64)
def _plant(name: str, params: ServoParams, position: float, substep: float) -> Any:
    """The registered plant, built once per process for equal arguments: plants are frozen
    and nothing writes into their arrays (the loops copy the initial state), and the study
    builds the same one for each of its runs (a linearisation and a matrix exponential
    each, 0.4 ms on the linear plant)."""
    return build_plant(name, params, position, substep=substep)


def _offered(name: str) -> Any:
    """The declaration of the offered option ``name`` (of any registered kind)."""
    for o in controller_options():
        if o.name == name:
            return o
    raise ParameterError(f"no controller offers an option {name!r}; the options: "
                         f"{', '.join(o.name for o in controller_options())}")


def parse_delay(text: str | None, params: ServoParams) -> float:
    """The delay [s] that ``--delay`` names: seconds, or ``hose`` for the parameter set's
    ``delay.transport_delay`` (``None``: the default, none).

    Raises
    ------
    ParameterError
        Neither a finite number >= 0 nor ``hose``.
    """
    if text is None:
        return DEFAULT_DELAY
    if text.strip().lower() == "hose":
        return float(params.delay.transport_delay)
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0.0):
        raise ParameterError(f"--delay must be a number of seconds >= 0 or 'hose' (the "
                             f"parameter set's delay.transport_delay), got {text!r}")
    return value


def check_start(start: float) -> None:
    """Refuse a start position outside the stroke (a fraction in (0, 1)).

    Raises
    ------
    ParameterError
        ``start`` not in (0, 1).
    """
    if not 0.0 < start < 1.0:
        raise ParameterError(f"--start must be a fraction of the stroke in (0, 1), "
                             f"got {start!r}")


def flat_params(params: ServoParams) -> dict[str, float]:
    """Every parameter as ``{"group.field": value}`` [SI]."""
    return {f"{g}.{k}": v for g, d in to_dict(params).items() for k, v in d.items()}


def overrides_of(params: ServoParams, param_set: str) -> tuple[tuple[str, float], ...]:
    """The overrides of the named set that make ``params``: every ``group.field`` whose
    value differs from the set's, in the parameters' order (whatever set them: a
    ``--params`` file, ``--param``, or code), so that ``RunSpec(param_set=...,
    overrides=...)`` describes them exactly."""
    base = flat_params(named_set(param_set))
    return tuple((name, v) for name, v in flat_params(params).items()
                 if repr(v) != repr(base[name]))


def servo_params(param_set: str, overrides: Sequence[tuple[str, float]] | Mapping[str, float]
                 ) -> ServoParams:
    """The named parameter set with ``{"group.field": value}`` overrides applied."""
    params = named_set(param_set)
    items = dict(overrides.items() if isinstance(overrides, Mapping) else overrides)
    return with_overrides(params, items) if items else params


def load_systems(kind: str | None, files: Mapping[str, Any],
                 no_rule_value: float | None = None) -> dict[str, Any] | None:
    """The fuzzy systems of controller ``kind`` (None: of every controller of the
    registry, as the study runs them) with those of ``files`` (role -> path) read from
    their files and the paper's for the other roles; None when no file is given.

    Raises
    ------
    ParameterError, InputError, FormatError
        A system for a controller without that role, ``no_rule_value`` without a file, an
        unreadable or malformed file, a system that is not two-input or has no value when
        no rule fires.
    """
    from ..formats import read_system
    from ..fuzzy.loop import loop_system

    given = {role: files.get(role) for role in ("du", "alpha")}
    if all(v is None for v in given.values()):
        if no_rule_value is not None:
            raise ParameterError("--no-rule-value applies to a system from a file: add "
                                 "--du-system or --alpha-system")
        return None
    needs = controller_kind(kind).systems if kind is not None else tuple(
        dict.fromkeys(r for n in controller_names() for r in controller_kind(n).systems))
    out: dict[str, Any] = {}
    for role, path in given.items():
        if path is None:
            continue
        if role not in needs:
            users = [n for n in controller_names() if role in controller_kind(n).systems]
            names = (", ".join(users[:-1]) + " or " + users[-1]) if len(users) > 1 \
                else users[0]
            raise ParameterError(f"--{role}-system applies to controller {names}, not {kind}")
        system = read_system(path)
        out[role] = loop_system(system, source=str(path), no_rule_value=no_rule_value)
    for role, default in default_systems(tuple(r for r in needs if r not in out)).items():
        out[role] = default
    return out


def systems_record(systems: Mapping[str, Any] | None) -> tuple[tuple[str, str, str], ...]:
    """(role, source, sha256) of the systems read from files, for records and cache keys; a
    file that holds the paper's system itself (e.g. the shipped ``paper-du.fis``) is the
    paper's and is not recorded."""
    from ..fuzzy.loop import LoopSystem, system_digest
    from ..paper import paper_fuzzy_system

    if not systems:
        return ()
    return tuple((role, s.source, s.digest) for role, s in sorted(systems.items())
                 if isinstance(s, LoopSystem)
                 and s.digest != system_digest(paper_fuzzy_system(role)))


def parse_gains_pairs(text: str) -> dict[str, float]:
    """Parse ``NAME=VALUE,...`` into floats (names lower-cased; each given once).

    Raises
    ------
    ParameterError
        An item without ``=``, a name given twice, or a value that is not a number.
    """
    gains: dict[str, float] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        name, sep, value = item.partition("=")
        name = name.strip().lower()
        if not sep or not name.isidentifier():
            raise ParameterError(f"--gains expects a gains file (.toml) or NAME=VALUE pairs "
                                 f"(a name is letters, digits and _), got {item!r}")
        if name in gains:
            raise ParameterError(f"gain {name} is given twice in --gains; give each once")
        try:
            gains[name] = float(value)
        except ValueError:
            raise ParameterError(f"gain {name}: {value.strip()!r} is not a number") from None
    return gains


def parse_param(text: str) -> tuple[str, float]:
    """Split ``group.field=value`` into the name and a finite float.

    Raises
    ------
    ParameterError
        If the text has no ``=`` or the value is not a finite number.
    """
    name, sep, value = text.partition("=")
    name = name.strip()
    if not sep or not name or not all(part.isidentifier() for part in name.split(".")):
        raise ParameterError(f"--param expects GROUP.FIELD=VALUE, got {text!r}")
    try:
        number = float(value)
    except ValueError:
        raise ParameterError(
            f"--param {name}: value must be a number in SI units, got {value.strip()!r}"
        ) from None
    if not math.isfinite(number):
        raise ParameterError(f"--param {name}: value must be finite, got {value.strip()!r}")
    return name, number


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        raise UsageError(f"fuzzyservo simulate: error: {' '.join(message.split())}")


def run_default(name: str) -> Any:
    """The default of the :class:`RunSpec` field ``name``: what a run that does not say takes
    (``fuzzyservo simulate`` after a gains file's record, and :meth:`RunSpec.from_argv`)."""
    return RunSpec.__dataclass_fields__[name].default


def _parser() -> argparse.ArgumentParser:
    """A reader of the closed-loop run's flags of ``simulate`` (the options as the registry
    declares them now; the defaults :class:`RunSpec`'s)."""
    p = _Parser(prog="fuzzyservo simulate", add_help=False, allow_abbrev=False)
    p.add_argument("--plant", default=run_default("plant"))
    p.add_argument("--controller", required=True)
    p.add_argument("--gains", default=None)
    p.add_argument("--reference", default=run_default("reference"))
    for name in ("duration", "ts", "start", "delay", "noise_std", "substep"):
        p.add_argument(f"--{name.replace('_', '-')}", type=float, default=run_default(name))
    p.add_argument("--seed", type=int, default=run_default("seed"))
    p.add_argument("--load-force", default=run_default("load_force"))
    for o in controller_options():
        p.add_argument(o.flag, default=None, type=o.type, choices=o.choices or None)
    p.add_argument("--du-system", default=None)
    p.add_argument("--alpha-system", default=None)
    p.add_argument("--no-rule-value", type=float, default=None)
    p.add_argument("--set", dest="param_set", default=None)
    p.add_argument("--param", action="append", default=[])
    return p
