"""Options shared by the commands that build a controller or a run: the registry's controller
and plant names, ``--gains`` (a gains file or NAME=VALUE pairs), ``--delay`` (seconds or
``hose``) and the controller options; a progress bar over simulated time."""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ..analysis.autotune import TunedGains
from ..errors import InputError, ParameterError
from ..files import GainsFile, read_gains_file
from ..registry import (
    DEFAULT_SUBSTEP,
    controller_kind,
    controller_names,
    controller_options,
    plant_names,
)
from ..run import load_systems, parse_delay, parse_gains_pairs, run_default, systems_record
from ..sim import DEFAULT_DELAY

__all__ = [
    "ControllerChoice",
    "add_controller_arguments",
    "add_system_arguments",
    "add_delay_argument",
    "add_plant_choice",
    "controller_from_args",
    "delay_from_args",
    "options_from_args",
    "parse_gains_pairs",
    "simulated_time_progress",
    "systems_from_args",
    "systems_record",
]

def add_plant_choice(parser: argparse.ArgumentParser | Any, default: str | None, *,
                     shown: str | None = None) -> None:
    """``--plant NAME``, one of the registry's plants (``default`` None: decided later, as
    ``shown`` says in the help; default "the gains file's, else nonlinear")."""
    names = plant_names()
    shown = default or shown or "the gains file's, else nonlinear"
    parser.add_argument("--plant", choices=names, default=default, metavar="NAME",
                        help=f"plant model: {', '.join(names)} (default {shown}; "
                             "docs/model.md, 'Plant models')")


def add_delay_argument(parser: argparse.ArgumentParser | Any) -> None:
    """``--delay S|hose``."""
    parser.add_argument("--delay", default=None, metavar="S|hose",
                        help="transport (hose) delay on the command [s], or 'hose' for the "
                             "parameter set's delay.transport_delay (6 ms for the paper set); "
                             f"default {DEFAULT_DELAY:g}, none, as everywhere in fuzzyservo")


def add_timing_arguments(parser: argparse.ArgumentParser | Any, *, ts_what: str,
                         start_what: str) -> None:
    """``--ts``, ``--start``, ``--delay`` and ``--substep`` of a command that builds one run
    (``simulate``, ``bode``); ``ts_what`` and ``start_what`` say what the sample time and the
    position are to the command, each default the gains file's, else the run's."""
    parser.add_argument("--ts", "--dt", dest="ts", type=float, default=None, metavar="S",
                        help=f"{ts_what} [s] (default: the gains file's, else "
                             f"{run_default('ts'):g})")
    parser.add_argument("--start", type=float, default=None, metavar="FRACTION",
                        help=f"{start_what} as a fraction of the stroke (default: the gains "
                             f"file's, else {run_default('start'):g})")
    add_delay_argument(parser)
    parser.add_argument("--substep", type=float, default=DEFAULT_SUBSTEP, metavar="S",
                        help=f"nonlinear plant: RK4 step bound [s] (default {DEFAULT_SUBSTEP:g})")


#: The delay [s] that ``--delay`` names (:func:`fuzzyservo.run.parse_delay`).
delay_from_args = parse_delay


@contextlib.contextmanager
def simulated_time_progress(desc: str, *, enabled: bool = True, file: Any = None
                            ) -> Iterator[Callable[[float, float], None] | None]:
    """A progress callback ``(t, duration)`` [s] drawing a tqdm bar on standard error over
    simulated time (rate in simulated seconds per second, and the time left), or None when
    not ``enabled`` or standard error is not a terminal (no bar in logs and pipes).

    Use as ``with simulated_time_progress("solve_ivp") as progress: simulate_open_loop(...,
    progress=progress)``; the bar is closed when the block ends, left on screen after a run
    and wiped after an error (whose message is then the only line).
    """
    stream = sys.stderr if file is None else file
    if not enabled or not (file is not None or stream.isatty()):
        yield None
        return
    from tqdm import tqdm

    bar: Any = None
    state = {"t": 0.0}

    def report(t: float, duration: float) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(total=duration, desc=desc, unit="s", file=stream, leave=True,
                       bar_format="{desc}: {n:.4g}/{total:.4g} s simulated |{bar}| "
                                  "[{elapsed}<{remaining}, {rate_fmt}]")
        step = min(max(t, state["t"]), duration) - state["t"]
        if step > 0.0:
            state["t"] += step
            bar.update(step)

    try:
        yield report
    except BaseException:
        if bar is not None:  # an error's one line stands alone: the bar is wiped
            bar.leave = False
        raise
    finally:
        if bar is not None:
            bar.close()


def add_controller_arguments(parser: argparse.ArgumentParser | Any) -> None:
    """``--controller``, ``--gains`` and the controller options."""
    names = controller_names()
    parser.add_argument("--controller", choices=names, default=None, metavar="NAME",
                        help=f"controller: {', '.join(names)} (default: the gains file's)")
    gains = "; ".join(
        f"{n}: " + ", ".join(f"{g.name}" + ("" if g.default is None else f"={g.default:g}")
                             for g in controller_kind(n).gains) for n in names)
    parser.add_argument("--gains", default=None, metavar="FILE.toml|NAME=VALUE,...",
                        help="a gains file (what 'fuzzyservo tune' writes, e.g. "
                             "src/fuzzyservo/data/gains/linear-stfpi.toml), or gains as "
                             f"NAME=VALUE pairs in SI units ({gains}; =default)")
    for o in controller_options():  # each kind's options, as the registry declares them
        parser.add_argument(o.flag, default=None, type=o.type, choices=o.choices or None,
                            metavar=o.metavar, help=o.help_text())
    add_system_arguments(parser)


def add_system_arguments(parser: argparse.ArgumentParser | Any) -> None:
    """``--du-system FILE``, ``--alpha-system FILE`` and ``--no-rule-value V``."""
    parser.add_argument("--du-system", type=Path, default=None, metavar="FILE",
                        help="fuzzy PIs: the Δu system from a .fis, .fcl or .fll file in place "
                             "of the paper's Fig. 3a: two inputs (e, Δe) evaluated at (K_e e, "
                             "K_Δe Δe) in the file's own universes, its first output scaled "
                             "by K_Δu (docs/fuzzy-files.md, 'In the loop')")
    parser.add_argument("--alpha-system", type=Path, default=None, metavar="FILE",
                        help="self-tuning fuzzy PI: the α system from a file in place of the "
                             "paper's Fig. 3b (same inputs; its first output is α)")
    parser.add_argument("--no-rule-value", type=float, default=None, metavar="V",
                        help="value of a system from a file when no rule fires, where the "
                             "file gives none (NaN default); needed unless its rules provably "
                             "cover every (e, Δe)")


def systems_from_args(args: argparse.Namespace, kind: str | None) -> dict[str, Any] | None:
    """The fuzzy systems of ``--du-system`` / ``--alpha-system`` for controller ``kind``
    (None: for every controller of the registry, as the study runs them), the paper's for a
    role not given; None when neither option is given (:func:`fuzzyservo.run.load_systems`).

    Raises
    ------
    ParameterError, InputError, FormatError
        A system option for a controller without that system, an unreadable or malformed
        file, a system that is not two-input or has no value when no rule fires.
    """
    files = {role: getattr(args, f"{role}_system", None) for role in ("du", "alpha")}
    return load_systems(kind, {r: p for r, p in files.items() if p is not None},
                        getattr(args, "no_rule_value", None))


class ControllerChoice:
    """What ``--controller``, ``--gains`` and ``--ts`` select."""

    def __init__(self, kind: str, gains: dict[str, float], ts: float,
                 source: GainsFile | None) -> None:
        self.kind = kind  #: registry name
        self.gains = gains  #: every gain of the kind, checked [SI]
        self.ts = ts  #: sample time [s]
        self.source = source  #: the gains file, if one was read
        self.systems: dict[str, Any] | None = None  #: fuzzy systems from files (once built)

    @property
    def tuned(self) -> TunedGains | None:
        """The tuning record of the gains file, if it has one."""
        return None if self.source is None else self.source.tuned


def options_from_args(args: argparse.Namespace, kind_name: str) -> dict[str, Any]:
    """The controller options given on the command line (the registry's
    :func:`~fuzzyservo.registry.controller_options`) for the registered controller
    ``kind_name``.

    Raises
    ------
    ParameterError
        An option the controller does not take.
    """
    kind = controller_kind(kind_name)
    options = {}
    for o in controller_options():
        value = getattr(args, o.name, None)
        if value is None:
            continue
        if o.name not in kind.option_names:
            raise ParameterError(f"{o.flag} does not apply to controller {kind_name} "
                                 f"({kind.title})")
        options[o.name] = value
    return options


def controller_from_args(args: argparse.Namespace) -> ControllerChoice:
    """The controller kind, gains and sample time selected on the command line.

    ``--gains`` is a gains file unless it holds ``NAME=VALUE`` pairs (a pair always has
    ``=``). With a file the controller is the file's (``--controller``, if given, must agree)
    and the sample time defaults to the file's ``tuning.ts`` (the fuzzy PIs' ``kde`` is per
    sample). ``--ts`` overrides it.

    Raises
    ------
    ParameterError, InputError
        No controller, disagreeing names, bad gains, a bad sample time or an unreadable file.
    """
    text = args.gains
    source: GainsFile | None = None
    if text is not None and not text.strip():
        raise InputError("--gains is empty: give a gains file or NAME=VALUE pairs")
    if text is not None and "=" not in text:
        source = read_gains_file(Path(text))
        if args.controller is not None and args.controller != source.controller:
            raise InputError(f"the gains file {text!r} is for controller {source.controller}, "
                             f"not --controller {args.controller}; drop --controller or give "
                             f"a file of that controller")
        name = source.controller
        gains = dict(source.gains)
        ts = args.ts if args.ts is not None else (source.ts or run_default("ts"))
    else:
        if args.controller is None:
            names = ", ".join(controller_names())
            raise ParameterError(f"a closed loop needs --controller ({names}) or --gains "
                                 f"FILE.toml, or --open-loop")
        name = args.controller
        gains = parse_gains_pairs(text or "")
        ts = run_default("ts") if args.ts is None else args.ts
    if not (isinstance(ts, float | int) and math.isfinite(ts) and ts > 0.0):
        raise ParameterError(f"--ts must be finite and > 0 s, got {ts!r}")
    checked = controller_kind(name).check_gains(gains)
    return ControllerChoice(name, checked, float(ts), source)
