"""``fuzzyservo simulate``: run the servo in closed or open loop; write a CSV, metrics, a figure.

Closed loop: ``--controller NAME --gains NAME=VALUE,...`` or ``--gains FILE.toml`` (a file
``fuzzyservo tune`` writes; its controller and sample time are used), a ``--reference`` offset
from the start position. Open loop: ``--open-loop --command U``. Any plant of the registry
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
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, ParameterError
from ..plots.runs import FIGURE_FORMATS, runs_figure, save_figure
from ..registry import DEFAULT_SUBSTEP, build_plant
from ..sim import parse_reference, simulate, simulate_open_loop
from ._plantargs import add_plant_arguments, params_from_args
from ._runargs import (
    add_controller_arguments,
    add_delay_argument,
    add_plant_choice,
    controller_from_args,
    delay_from_args,
)
from .metrics import print_metrics

__all__ = ["register", "run"]


def register(subparsers: Any) -> None:
    """Add the ``simulate`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "simulate",
        help="simulate the servo in closed or open loop; CSV, metrics, figure",
        description=(
            "Simulate the servo under a controller (--controller/--gains) or a constant "
            "command (--open-loop) and write the samples as CSV (--out), print the step "
            "metrics (--metrics) and/or plot the run (--plot). SI units; r and y are absolute "
            "positions in the stroke on every plant."),
        epilog=("CSV columns: closed loop t, r, y, u, alpha, then the plant's states; open "
                "loop t, u, y, then the plant's states. t [s]; r, y [m]; u [-], fraction of "
                "the rated valve input; alpha [-] (NaN for the PID family)."),
    )
    add_plant_choice(parser, "nonlinear")
    parser.add_argument("--duration", type=float, default=2.0, metavar="S",
                        help="simulated time [s] (default 2)")
    parser.add_argument("--ts", "--dt", dest="ts", type=float, default=None, metavar="S",
                        help="controller sample time and CSV step [s] (default: the gains "
                             "file's, else 0.001)")
    parser.add_argument("--start", type=float, default=0.5, metavar="FRACTION",
                        help="start position as a fraction of the stroke (default 0.5)")
    add_delay_argument(parser)
    parser.add_argument("--substep", type=float, default=DEFAULT_SUBSTEP, metavar="S",
                        help="nonlinear plant: RK4 step bound [s] (default "
                             f"{DEFAULT_SUBSTEP:g})")
    out = parser.add_argument_group("outputs (at least one)")
    out.add_argument("--out", default=None, metavar="FILE.csv",
                     help="CSV to write ('-': standard output)")
    out.add_argument("--metrics", action="store_true",
                     help="print the step metrics (closed loop)")
    out.add_argument("--plot", type=Path, default=None, metavar="FIG.png|FIG.svg",
                     help="plot position, reference, command (and alpha) of the run")
    cl = parser.add_argument_group("closed loop")
    add_controller_arguments(cl)
    cl.add_argument("--reference", default="step:0.1", metavar="SPEC",
                    help="reference offset from the start position [m]: step:A[:T], "
                         "multistep:T1=A1,..., ramp:SLOPE[:T[:FINAL]], sine:A:F, "
                         "trapezoid:DIST:VMAX:AMAX[:T] (default step:0.1)")
    cl.add_argument("--noise-std", type=float, default=0.0, metavar="M",
                    help="measurement noise standard deviation [m] (default 0)")
    cl.add_argument("--seed", type=int, default=0, help="seed of the noise generator")
    ol = parser.add_argument_group("open loop")
    ol.add_argument("--open-loop", action="store_true",
                    help="apply a constant valve command instead of a controller")
    ol.add_argument("--command", type=float, default=None, metavar="U",
                    help="open-loop valve command, fraction of rated input in [-1, 1]")
    ol.add_argument("--method", choices=("rk4", "solve_ivp"), default="rk4",
                    help="open loop on the nonlinear plant: the compiled loop (default) or "
                         "scipy's solve_ivp (DOP853), the reference")
    add_plant_arguments(parser)
    parser.set_defaults(handler=run)


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


def _write(result: Any, out: str | None) -> None:
    if out is None:
        return
    if out == "-":
        result.to_csv(sys.stdout)
        return
    try:
        result.to_csv(Path(out))
    except OSError as exc:
        raise InputError(f"cannot write {out!r}: {exc.strerror or exc}") from exc


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo simulate``."""
    _check_outputs(args)
    if not 0.0 < args.start < 1.0:
        raise ParameterError(f"--start must be a fraction of the stroke in (0, 1), "
                             f"got {args.start!r}")
    if not (math.isfinite(args.substep) and args.substep > 0.0):
        raise ParameterError(f"--substep must be finite and > 0 s, got {args.substep!r}")
    params = params_from_args(args)
    delay = delay_from_args(args.delay, params)
    if args.open_loop:
        if args.controller is not None or args.gains is not None:
            raise InputError("--open-loop applies --command, not a controller: drop "
                             "--controller/--gains or --open-loop")
        if args.command is None:
            raise InputError("--open-loop needs --command U (fraction of rated input in "
                             "[-1, 1])")
        if not (math.isfinite(args.command) and -1.0 <= args.command <= 1.0):
            raise ParameterError(f"--command must be in [-1, 1] (fraction of rated input), "
                                 f"got {args.command!r}")
        ts = 1e-3 if args.ts is None else args.ts
        plant = build_plant(args.plant, params, args.start * params.cylinder.stroke,
                            substep=args.substep)
        result: Any = simulate_open_loop(plant, args.command, duration=args.duration, dt=ts,
                                         delay=delay, method=args.method)
        title = f"open loop, u = {args.command:g}, {args.plant} plant"
    else:
        if args.command is not None:
            raise InputError("--command is the open-loop command: add --open-loop, or drop it")
        choice = controller_from_args(args)
        ctl = choice.build(args)
        reference = parse_reference(args.reference)
        if args.seed < 0:
            raise ParameterError(f"--seed must be a non-negative integer, got {args.seed}")
        plant = build_plant(args.plant, params, args.start * params.cylinder.stroke,
                            substep=args.substep)
        result = simulate(ctl, plant, reference, duration=args.duration, delay=delay,
                          noise_std=args.noise_std, rng=np.random.default_rng(args.seed))
        title = f"{choice.kind} on the {args.plant} plant, reference {args.reference}"
    _write(result, args.out)
    if args.metrics:
        print_metrics(result.metrics().as_dict())
    if args.plot is not None:
        label = Path(args.out).stem if args.out not in (None, "-") else "run"
        save_figure(runs_figure([result], [label], metrics=not args.open_loop, title=title),
                    args.plot)
    return 0
