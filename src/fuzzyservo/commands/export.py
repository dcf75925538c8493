"""``fuzzyservo export c|fmu|st``: a controller as C99 code, a controller or the servo as an FMU,
a controller as IEC 61131-3 Structured Text."""

from __future__ import annotations

import argparse
import shlex
import sys
from typing import Any

from ..errors import ParameterError
from ..export import EXPORT_TARGETS, export_target_names
from ..export._c import escape_text
from ..export._st import check_st_name
from ..export.targets import (
    check_c_folder,
    export_c,
    export_controller_fmu,
    export_servo_fmu,
    export_st,
    generate_c,
    generate_st,
)
from ..registry import DEFAULT_SUBSTEP, build_plant, controller_options
from ..run import run_default
from . import HELP
from ._plantargs import add_plant_arguments, params_from_args
from ._runargs import (
    add_controller_arguments,
    add_delay_argument,
    add_plant_choice,
    controller_from_args,
    delay_from_args,
    options_from_args,
    systems_from_args,
    systems_record,
)

__all__ = ["register"]


def _command(argv: list[str] | None) -> str:
    """The command line as recorded in the generated files."""
    return "fuzzyservo " + shlex.join(sys.argv[1:] if argv is None else argv)


def _controller_args(parser: argparse.ArgumentParser, st: bool = False) -> None:
    add_controller_arguments(parser)
    parser.add_argument("--ts", "--dt", dest="ts", type=float, default=None, metavar="S",
                        help="sample time [s] (default: the gains file's, else "
                             f"{run_default('ts'):g})")
    if st:
        parser.add_argument("--real", dest="real", action="store_const", const="REAL",
                            default="LREAL",
                            help="REAL (single-precision) arithmetic, for PLCs without LREAL "
                                 "(default LREAL; docs/export-st.md states the deviation "
                                 "from the Python controller)")
        parser.add_argument("--name", default=None, metavar="ID",
                            help="name of the function block and its files (default "
                                 "CONTROLLER_ctl)")
        return
    parser.add_argument("--float", dest="real", action="store_const", const="float",
                        default="double",
                        help="single-precision arithmetic (default double; docs/export.md "
                             "states the deviation from the Python controller)")
    parser.add_argument("--name", default=None, metavar="ID",
                        help="prefix of the C identifiers and file names (default the "
                             "controller's name)")


def register(subparsers: Any) -> None:
    """Add the ``export`` subcommand group to ``subparsers`` and set its handlers."""
    names = export_target_names()
    parser = subparsers.add_parser(
        "export", help=HELP["export"],
        description=(
            "Take a controller to hardware: C99 code with no dependency beyond the C "
            "standard library (export c), an FMI 2.0 co-simulation FMU of a controller or "
            "of the servo for 64-bit Linux (export fmu), or IEC 61131-3 Structured Text for "
            "a PLC (export st), computing what the Python controller and simulator compute "
            "(docs/export.md, docs/export-st.md)."))
    sub = parser.add_subparsers(dest="export_target", required=True,
                                metavar="{" + ",".join(names) + "}")
    handlers = {"c": _run_c, "fmu": _run_fmu, "st": _run_st}
    for name in names:
        target = EXPORT_TARGETS[name]
        p = sub.add_parser(name, help=target.title, description=f"Export {target.title}.")
        if name == "fmu":
            add_plant_choice_optional(p)
        _controller_args(p, st=name == "st")
        p.add_argument("--out", required=True, metavar=target.writes,
                       help=("folder for NAME.h and NAME.c: new, empty, or holding only an "
                             "earlier export of the same name" if name == "c" else
                             "folder for NAME.st and NAME_example.st: new, empty, or holding "
                             "only an earlier export of the same name" if name == "st" else
                             "the FMU to write (replaced atomically)"))
        p.set_defaults(handler=handlers[name])


def add_plant_choice_optional(p: argparse.ArgumentParser) -> None:
    """``--plant`` and the plant's options for the servo FMU."""
    group = p.add_argument_group(
        "the servo instead of a controller",
        "--plant exports the servo model (input u; outputs y, the measured position, and the "
        "plant's states, named as the CSV columns of 'fuzzyservo simulate'); communication "
        "steps are whole multiples of --ts")
    add_plant_choice(group, None)
    group.add_argument("--start", type=float, default=run_default("start"), metavar="FRACTION",
                       help=f"start position as a fraction of the stroke (default "
                            f"{run_default('start'):g})")
    add_delay_argument(group)
    group.add_argument("--substep", type=float, default=DEFAULT_SUBSTEP, metavar="S",
                       help=f"nonlinear plant: RK4 step bound [s] (default "
                            f"{DEFAULT_SUBSTEP:g})")
    add_plant_arguments(p)


def _generate(args: argparse.Namespace) -> Any:
    choice = controller_from_args(args)
    options = options_from_args(args, choice.kind)
    systems = systems_from_args(args, choice.kind)
    return generate_c(choice.kind, choice.gains, ts=choice.ts, systems=systems,
                      options=options, real=args.real, name=args.name,
                      systems_record=systems_record(systems),
                      command=_command(getattr(args, "argv", None)))


def _run_st(args: argparse.Namespace) -> int:
    if args.name is not None:
        check_st_name(args.name)
        check_c_folder(args.out, args.name,
                       files=(f"{args.name}.st", f"{args.name}_example.st"))
    choice = controller_from_args(args)
    options = options_from_args(args, choice.kind)
    systems = systems_from_args(args, choice.kind)
    st = generate_st(choice.kind, choice.gains, ts=choice.ts, systems=systems,
                     options=options, real=args.real, name=args.name,
                     systems_record=systems_record(systems),
                     command=_command(getattr(args, "argv", None)))
    block, example = export_st(st, args.out)
    print(f"wrote {escape_text(block)} and {escape_text(example)} ({st.kind}, {st.real}, "
          f"ts = {st.ts:g} s)")
    return 0


def _run_c(args: argparse.Namespace) -> int:
    if args.name is not None:
        check_c_folder(args.out, args.name)
    cc = _generate(args)
    hdr, src = export_c(cc, args.out)
    print(f"wrote {escape_text(hdr)} and {escape_text(src)} ({cc.kind}, {cc.real}, "
          f"ts = {cc.ts:g} s)")
    return 0


_PLANT_ONLY = ("start", "delay")
_CONTROLLER_ONLY = ("controller", "gains", "du_system", "alpha_system", "no_rule_value")


def _run_fmu(args: argparse.Namespace) -> int:
    if args.plant is None:
        if args.controller is None and args.gains is None:
            raise ParameterError("export fmu needs a controller (--controller/--gains) or the "
                                 "servo (--plant linear|small-signal|nonlinear)")
        if args.delay is not None:
            raise ParameterError("--delay applies to the servo FMU (--plant); a controller "
                                 "has no delay")
        cc = _generate(args)
        path = export_controller_fmu(cc, args.out, command=_command(getattr(args, "argv",
                                                                          None)))
        print(f"wrote {escape_text(path)} (controller {cc.kind}, {cc.real}, ts = {cc.ts:g} s)")
        return 0
    given = [k for k in (*_CONTROLLER_ONLY, *(o.name for o in controller_options()))
             if getattr(args, k, None) is not None]
    if given or args.real != "double":
        flag = "--float" if not given else "--" + given[0].replace("_", "-")
        raise ParameterError(f"{flag} applies to a controller FMU; --plant exports the servo "
                             f"alone")
    ts = run_default("ts") if args.ts is None else args.ts
    if not (0.0 < ts < float("inf")):
        raise ParameterError(f"--ts must be finite and > 0 s, got {ts!r}")
    if not 0.0 < args.start < 1.0:
        raise ParameterError(f"--start must be a fraction of the stroke in (0, 1), got "
                             f"{args.start!r}")
    params = params_from_args(args)
    delay = delay_from_args(args.delay, params)
    plant = build_plant(args.plant, params, args.start * params.cylinder.stroke,
                        substep=args.substep)
    path = export_servo_fmu(plant, args.out, plant_name=args.plant, ts=ts, delay=delay,
                            name=args.name,
                            description=f"{args.plant} servo exported by "
                                        f"{_command(getattr(args, 'argv', None))}")
    print(f"wrote {escape_text(path)} ({args.plant} servo, ts = {ts:g} s, delay {delay:g} s)")
    return 0
