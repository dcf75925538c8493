"""``fuzzyservo simulate``: run the servo in closed or open loop; write a CSV, metrics, a figure.

Closed loop: ``--controller NAME --gains NAME=VALUE,...`` or ``--gains FILE.toml`` (a file
``fuzzyservo tune`` writes, or a hand-written ``controller`` and ``[gains]``), a
``--reference`` offset from the start position. A gains file with a tuning record runs as
tuned: its plant, parameter set and overrides, start, step, duration, delay and sample time
fill every option not given, and a note on standard error says which, and what differs.
Open loop: ``--open-loop --command U|FILE.csv`` (a constant, or a sequence of t, u such as
``fuzzyservo identify --design`` writes; ``--noise-std`` adds the transducer's noise to the
logged position). Any plant of the registry
(``--plant linear|small-signal|nonlinear``) in either. The hose delay is none unless
``--delay S`` or ``--delay hose`` asks for it, as in every other entry point.

Outputs (at least one): ``--out FILE.csv`` (``-`` for standard output), ``--metrics`` (step
metrics on standard output, closed loop), ``--plot FIG.png|.svg``. CSV columns, SI units, r and
y absolute positions in the stroke on every plant: closed loop ``t, r, y, u, alpha`` then the
plant states; open loop ``t, u, y`` then the plant states.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .._io import check_output_path
from ..analysis.autotune import TunedGains
from ..errors import InputError, ParameterError
from ..plant import ServoParams
from ..plots.runs import FIGURE_FORMATS, runs_figure, save_figure
from ..registry import build_plant, controller_kind, controller_options
from ..run import BuiltRun, RunSpec, check_start, run_default, servo_params
from ..sim import simulate_open_loop
from ..sim.open_loop import MAX_RHS_EVALUATIONS
from . import HELP
from ._plantargs import add_plant_arguments, overrides_from_args, params_given, set_name
from ._runargs import (
    ControllerChoice,
    add_controller_arguments,
    add_plant_choice,
    add_timing_arguments,
    controller_from_args,
    delay_from_args,
    simulated_time_progress,
    systems_record,
)
from .metrics import print_metrics

__all__ = ["ClosedLoop", "RunSettings", "closed_loop", "register", "run"]


def register(subparsers: Any) -> None:
    """Add the ``simulate`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "simulate",
        help=HELP["simulate"],
        description=(
            "Simulate the servo under a controller (--controller/--gains) or a constant "
            "command (--open-loop) and write the samples as CSV (--out), print the step "
            "metrics (--metrics) and/or plot the run (--plot). SI units; r and y are absolute "
            "positions in the stroke on every plant."),
        epilog=("CSV columns: closed loop t, r, y, u, alpha, then the plant's states; open "
                "loop t, u, y, then the plant's states. t [s]; r, y [m]; u [-], fraction of "
                "the rated valve input; alpha [-] (NaN for the PID family)."),
    )
    add_plant_choice(parser, None)
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="simulated time [s] (default: the gains file's, else "
                             f"{run_default('duration'):g})")
    add_timing_arguments(parser, ts_what="controller sample time and CSV step",
                         start_what="start position")
    out = parser.add_argument_group("outputs (at least one)")
    out.add_argument("--out", default=None, metavar="FILE.csv",
                     help="CSV to write ('-': standard output)")
    out.add_argument("--metrics", action="store_true",
                     help="print the step metrics (closed loop)")
    out.add_argument("--plot", type=Path, default=None, metavar="FIG.png|FIG.svg",
                     help="plot position, reference, command (and alpha) of the run")
    cl = parser.add_argument_group("closed loop")
    add_controller_arguments(cl)
    cl.add_argument("--reference", default=None, metavar="SPEC",
                    help="reference offset from the start position [m]: step:A[:T], "
                         "multistep:T1=A1,..., ramp:SLOPE[:T[:FINAL]], sine:A:F, "
                         "trapezoid:DIST:VMAX:AMAX[:T] (default: the gains file's step, "
                         f"else {run_default('reference')})")
    cl.add_argument("--noise-std", type=float, default=0.0, metavar="M",
                    help="measurement noise standard deviation [m] (default 0)")
    cl.add_argument("--seed", type=int, default=0, help="seed of the noise generator")
    cl.add_argument("--load-force", default=run_default("load_force"), metavar="SPEC",
                    help="load-force disturbance [N] added to the set's load.external_force, "
                         "> 0 opposing extension: step:F[:T] (F from T [s] on, 0 before), "
                         "pwl:T0:F0,T1:F1,... (piecewise linear, held at both ends) or "
                         "FILE.csv (columns t, F); sampled at the sample instants and held "
                         "over each sample; on every plant (the linear ones by "
                         "superposition; docs/model.md) (default: none)")
    ol = parser.add_argument_group("open loop")
    ol.add_argument("--open-loop", action="store_true",
                    help="apply a valve command (--command) instead of a controller")
    ol.add_argument("--command", default=None, metavar="U|FILE.csv",
                    help="open-loop valve command, fraction of rated input in [-1, 1]: a "
                         "constant, or a CSV with columns t, u (a sequence sampled every "
                         "--ts, e.g. what 'fuzzyservo identify --design' writes; its length "
                         "is the default --duration)")
    ol.add_argument("--pressure-noise-std", type=float, default=0.0, metavar="PA",
                    help="open loop: noise standard deviation added to the chamber pressures "
                         "written (p_f, p_n then read as logged by transducers) [Pa] "
                         "(default 0; --noise-std adds the position's to y)")
    ol.add_argument("--method", choices=("rk4", "solve_ivp"), default="rk4",
                    help="open loop on the nonlinear plant: the compiled loop (default) or "
                         "scipy's solve_ivp (DOP853), the reference")
    ol.add_argument("--max-evaluations", type=_count, default=MAX_RHS_EVALUATIONS,
                    metavar="N",
                    help=f"solve_ivp: stop with an error after N evaluations of the model "
                         f"(default {MAX_RHS_EVALUATIONS:g}; a stiff model can need millions)")
    add_plant_arguments(parser)
    parser.set_defaults(handler=run)


def _logged(result: Any, noise_std: float, pressure_noise_std: float, seed: int) -> Any:
    """The open-loop run as transducers would log it: seeded white noise of ``noise_std`` [m]
    on the position y, then of ``pressure_noise_std`` [Pa] on the chamber pressures (states
    p_f, p_n, when the plant has them)."""
    if noise_std == 0.0 and pressure_noise_std == 0.0:
        return result
    from dataclasses import replace

    import numpy as np

    rng = np.random.default_rng(seed)
    y = result.y + rng.normal(0.0, noise_std, result.y.size) if noise_std else result.y
    states = result.states
    if pressure_noise_std:
        states = states.copy()
        for name in ("p_f", "p_n"):
            if name in result.state_names:
                j = result.state_names.index(name)
                states[:, j] += rng.normal(0.0, pressure_noise_std, states.shape[0])
    return replace(result, y=y, states=states)


def _open_loop_command(text: str, ts: float | None) -> tuple[Any, float, float | None]:
    """``--command``: a constant, or a CSV file of t, u. Returns the command (a float, or the
    samples held from each t_k), the sample time [s] and the file's length [s] (None for a
    constant).

    Raises
    ------
    ParameterError, InputError
        A constant outside [-1, 1]; a file that cannot be read, lacks t or u, has uneven
        time steps, a step other than ``--ts``, or a value outside [-1, 1].
    """
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is not None:
        if not (math.isfinite(value) and -1.0 <= value <= 1.0):
            raise ParameterError(f"--command must be in [-1, 1] (fraction of rated input), "
                                 f"got {value!r}")
        return value, run_default("ts") if ts is None else ts, None
    import numpy as np

    from .._io import read_csv_columns

    cols = read_csv_columns(Path(text), ("t", "u"), what="command file", min_rows=2)
    t, u = cols["t"], cols["u"]
    steps = np.diff(t)
    # the decimal step the file was written with (a median of differences of decimals
    # carries their rounding: 0.0010000000000000009 for t = k * 0.001)
    step = float(f"{float(np.median(steps)):.12g}")
    if not (step > 0.0 and np.all(np.abs(steps - step) <= 1e-6 * step)):
        raise InputError(f"command file {text!r}: the times must be evenly spaced (found steps "
                         f"from {float(steps.min()):g} to {float(steps.max()):g} s)")
    if ts is not None and abs(ts - step) > 1e-9 * step:
        raise InputError(f"command file {text!r} is sampled every {step:g} s, not --ts "
                         f"{ts:g} s")
    bad = np.flatnonzero(np.abs(u) > 1.0)
    if bad.size:
        raise ParameterError(f"command file {text!r}: u = {float(u[bad[0]])!r} at t = "
                             f"{float(t[bad[0]]):g} s; it must be in [-1, 1] (fraction of "
                             f"rated input)")
    return np.ascontiguousarray(u), step, (t.size - 1) * step


def _count(text: str) -> int:
    """A whole number written as ``1000000`` or ``1e6``."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if not (math.isfinite(value) and value == int(value)):
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}")
    return int(value)


def _check_outputs(args: argparse.Namespace) -> None:
    if args.out is None and not args.metrics and args.plot is None:
        raise InputError("nothing to do: give --out FILE.csv ('-' for standard output), "
                         "--metrics or --plot FIG.png")
    if args.out == "-" and args.metrics:
        raise InputError("--out - and --metrics both write to standard output; give --out "
                         "a file name")
    if args.plot is not None and args.plot.suffix.lower() not in FIGURE_FORMATS:
        raise InputError(f"--plot {str(args.plot)!r}: the file name must end in "
                         f"{' or '.join(FIGURE_FORMATS)}")
    if args.open_loop and args.metrics:
        raise InputError("--metrics needs a closed loop (step metrics are measured against "
                         "the reference); plot or write the open-loop run instead")
    inputs = [args.param_file]
    if args.gains is not None and Path(args.gains).is_file():
        inputs.append(Path(args.gains))
    if args.out not in (None, "-"):
        check_output_path(args.out, option="--out", inputs=inputs)
    if args.plot is not None:
        check_output_path(args.plot, option="--plot", inputs=inputs)
        if args.out not in (None, "-") and Path(args.plot).resolve() == Path(args.out).resolve():
            raise InputError(f"--out and --plot name the same file {args.out!r}; give two "
                             f"names")


def _system_notes(built: BuiltRun, tuned: TunedGains | None) -> list[str]:
    """The scaling of each fuzzy system read from a file, and a gains file's systems that are
    not the ones of this run."""
    loaded = built.systems
    notes = list(built.notes())
    if tuned is not None:
        then = {role: (src, d) for role, src, d in tuned.setup.systems}
        now = {role: (src, d) for role, src, d in systems_record(loaded)}
        for role in sorted(set(then) | set(now)):
            if then.get(role, (None, None))[1] != now.get(role, (None, None))[1]:
                was = f"{role} system {then[role][0]}" if role in then else \
                    f"the paper's {role} system"
                is_ = f"{role} system {now[role][0]}" if role in now else \
                    f"the paper's {role} system"
                notes.append(f"the gains were tuned with {was}; this run uses {is_}"
                             + (f" (pass --{role}-system {then[role][0]})"
                                if role in then and role not in now else ""))
    return notes


def _write(result: Any, out: str | None) -> None:
    if out is None:
        return
    if out == "-":
        result.to_csv(sys.stdout)
        return
    result.to_csv(Path(out))  # atomic: a failed write leaves the previous file as it was




@dataclass(frozen=True, slots=True)
class RunSettings:
    """The run a command line asks for, after a gains file's record filled the gaps."""

    plant: str  #: registered plant name
    start: float  #: start position, fraction of the stroke [-]
    duration: float  #: simulated time [s]
    reference: str  #: reference spec (offset from the start) [m]
    delay: float  #: transport delay [s]
    params: ServoParams  #: servo parameters
    param_set: str  #: the named set they start from
    overrides: tuple[tuple[str, float], ...]  #: what replaces the set's values [SI]
    notes: tuple[str, ...]  #: what came from the gains file, and what differs from it


def _settings(args: argparse.Namespace, tuned: TunedGains | None, ts: float,
              path: str) -> RunSettings:
    """Options given win; a gains file's tuning record fills the others ("as tuned");
    the package defaults fill the rest (no delay, see docs/model.md)."""
    s = tuned.setup if tuned is not None else None
    from_file: list[str] = []

    def pick(name: str, given: Any, recorded: Any, shown: str) -> Any:
        if given is not None:
            return given
        if recorded is not None:
            from_file.append(shown.format(recorded))
            return recorded
        return run_default(name)  # RunSpec's

    plant = pick("plant", args.plant, s and s.plant, "the {} plant")
    start = pick("start", args.start, s and s.start, "start {:g}")
    duration = pick("duration", args.duration, s and s.duration, "{:g} s")
    reference = pick("reference", args.reference, s and f"step:{s.step!r}", "reference {}")
    if s is not None and not params_given(args):
        param_set, overrides = s.param_set, tuple(s.overrides)
        from_file.append(f"set {s.param_set}" + "".join(f", {k}={v!r}" for k, v in
                                                         s.overrides))
    else:
        param_set, overrides = set_name(args), tuple(overrides_from_args(args).items())
    params = servo_params(param_set, overrides)
    if args.delay is None and s is not None:
        delay = s.delay
        from_file.append(f"delay {delay:g} s")
    else:
        delay = delay_from_args(args.delay, params)
    if args.ts is None and s is not None:
        from_file.append(f"ts {s.ts:g} s")
    notes = []
    if from_file:
        notes.append(f"{path}: as tuned, " + ", ".join(from_file))
    if s is not None and s.robust is not None:
        notes.append(f"{path} was tuned on {s.robust.points} plants of {s.robust.source} "
                     f"({s.robust.statistic} {s.objective}); this run is their nominal plant")
    if s is not None:
        differs = []
        if plant != s.plant:
            differs.append(f"on the {s.plant} plant")
        if delay != s.delay:
            differs.append(f"with a delay of {s.delay:g} s")
        if ts != s.ts:
            differs.append(f"at ts = {s.ts:g} s")
        if differs:
            notes.append(f"{path} was tuned {' and '.join(differs)}; this run differs"
                         + (" (kde is per sample: the same gains act differently)"
                            if ts != s.ts and _per_sample(s.controller) else ""))
    check_start(start)
    return RunSettings(plant=plant, start=start, duration=duration, reference=reference,
                       delay=delay, params=params, param_set=param_set, overrides=overrides,
                       notes=tuple(notes))


def _per_sample(controller: str) -> bool:
    """Whether a gain of the kind is per sample (its meaning changes with the sample time)."""
    return any("per sample" in g.unit for g in controller_kind(controller).gains)


@dataclass(frozen=True, slots=True)
class ClosedLoop:
    """A closed-loop run as ``fuzzyservo simulate`` makes it: the command line resolved into
    a :class:`~fuzzyservo.run.RunSpec` (a gains file's record filling the gaps), built and
    run as every front end runs one."""

    spec: RunSpec  #: the run, as every front end describes one
    result: Any  #: the run (:class:`fuzzyservo.sim.SimResult`)
    settings: RunSettings  #: plant, start, duration, reference, delay, parameters
    choice: ControllerChoice  #: controller kind, gains, sample time, systems from files
    notes: tuple[str, ...]  #: the fuzzy systems' scaling and disagreements with a gains file
    title: str  #: a figure title


def closed_loop(args: argparse.Namespace) -> ClosedLoop:
    """Build and run the closed loop that ``args`` (of this command's parser) ask for.

    Raises
    ------
    ParameterError, InputError, FormatError
        Whatever the command line gets wrong (one line, as the CLI prints it).
    """
    if args.command is not None:
        raise InputError("--command is the open-loop command: add --open-loop, or drop it")
    choice = controller_from_args(args)
    run_ = _settings(args, choice.tuned, choice.ts, str(args.gains))
    spec = RunSpec(
        controller=choice.kind, gains=tuple(choice.gains.items()),
        options=tuple((o.name, getattr(args, o.name)) for o in controller_options()
                      if getattr(args, o.name, None) is not None),
        systems=tuple((role, str(path)) for role, path in
                      (("du", args.du_system), ("alpha", args.alpha_system))
                      if path is not None),
        no_rule_value=args.no_rule_value, plant=run_.plant, param_set=run_.param_set,
        overrides=run_.overrides, reference=run_.reference, duration=run_.duration,
        ts=choice.ts, delay=run_.delay, noise_std=args.noise_std, seed=args.seed,
        load_force=args.load_force, start=run_.start, substep=args.substep)
    built = spec.build()
    choice.systems = built.systems
    notes = _system_notes(built, choice.tuned)
    result = built.simulate()
    title = f"{choice.kind} on the {run_.plant} plant, reference {run_.reference}"
    return ClosedLoop(spec=spec, result=result, settings=run_, choice=choice,
                      notes=tuple(notes), title=title)


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo simulate``."""
    _check_outputs(args)
    if not (math.isfinite(args.substep) and args.substep > 0.0):
        raise ParameterError(f"--substep must be finite and > 0 s, got {args.substep!r}")
    extra_notes: list[str] = []
    if args.open_loop:
        if args.du_system is not None or args.alpha_system is not None:
            raise InputError("--du-system/--alpha-system belong to a fuzzy controller; the open "
                             "loop has none")
        if args.controller is not None or args.gains is not None:
            raise InputError("--open-loop applies --command, not a controller: drop "
                             "--controller/--gains or --open-loop")
        if args.command is None:
            raise InputError("--open-loop needs --command U (fraction of rated input in "
                             "[-1, 1]) or --command FILE.csv (columns t, u)")
        if args.reference is not None or args.load_force:
            raise InputError("--reference and --load-force belong to the closed loop; the "
                             "open loop applies --command")
        for flag, value, unit in (("--noise-std", args.noise_std, "m"),
                                  ("--pressure-noise-std", args.pressure_noise_std, "Pa")):
            if not (math.isfinite(value) and value >= 0.0):
                raise ParameterError(f"{flag} must be finite and >= 0 {unit}, got {value!r}")
        if args.pressure_noise_std and args.plant == "linear":
            raise InputError("--pressure-noise-std: the linear plant (eq. 8) has no chamber "
                             "pressures; use --plant nonlinear or small-signal")
        command, ts, length = _open_loop_command(args.command, args.ts)
        if args.duration is None and length is not None:
            args.duration = length
        run_ = _settings(args, None, ts, "")
        plant = build_plant(run_.plant, run_.params, run_.start * run_.params.cylinder.stroke,
                            substep=args.substep)
        if args.max_evaluations < 1:
            raise ParameterError(f"--max-evaluations must be a positive integer, got "
                                 f"{args.max_evaluations}")
        if not isinstance(command, float):
            n = int(round(run_.duration / ts))
            if n > command.size:
                raise InputError(f"--command {args.command!r} holds {command.size} samples "
                                 f"({command.size * ts:g} s); --duration {run_.duration:g} s "
                                 f"needs {n}")
            command = command[:n]
        with simulated_time_progress("solve_ivp",
                                     enabled=args.method == "solve_ivp") as progress:
            result: Any = simulate_open_loop(
                plant, command, duration=run_.duration, dt=ts, delay=run_.delay,
                method=args.method, progress=progress, max_rhs_evals=args.max_evaluations)
        result = _logged(result, args.noise_std, args.pressure_noise_std, args.seed)
        shown = f"{command:g}" if isinstance(command, float) else str(args.command)
        title = f"open loop, u = {shown}, {run_.plant} plant"
    else:
        if args.pressure_noise_std:
            raise InputError("--pressure-noise-std belongs to the open loop (--open-loop); a "
                             "closed loop takes the position's noise (--noise-std)")
        closed = closed_loop(args)
        result, run_, title = closed.result, closed.settings, closed.title
        extra_notes = list(closed.notes)
    for note in (*run_.notes, *extra_notes):
        print(f"fuzzyservo: note: {note}", file=sys.stderr)
    _write(result, args.out)
    if args.metrics:
        print_metrics(result.metrics().as_dict())
    if args.plot is not None:
        label = Path(args.out).stem if args.out not in (None, "-") else "run"
        save_figure(runs_figure([result], [label], metrics=not args.open_loop, title=title),
                    args.plot)
    return 0
