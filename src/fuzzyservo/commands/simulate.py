"""``fuzzyservo simulate``: run the servo and write the samples to a CSV file.

Open loop (``--open-loop``): a constant valve command from rest at a stroke position,
``fuzzyservo simulate --plant nonlinear|linear --open-loop --command 0.5 --duration 2
--out run.csv``. The CSV has a header line and the columns ``t, u, x, v,
p_f, p_n, spool, spool_rate`` in SI units (u as a fraction of rated input, before the hose
delay). The closed-loop branch dispatches on ``args.open_loop``.
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, ParameterError
from ..sim.open_loop import simulate_open_loop
from ._closed_loop import add_closed_loop_arguments, run_closed_loop
from ._plantargs import add_plant_arguments, params_from_args

__all__ = ["OPEN_LOOP_COLUMNS", "register", "run", "run_open_loop"]

#: Columns of an open-loop CSV, in order (SI units).
OPEN_LOOP_COLUMNS: tuple[str, ...] = ("t", "u", "x", "v", "p_f", "p_n", "spool", "spool_rate")


def register(subparsers: Any) -> None:
    """Add the ``simulate`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "simulate",
        help="simulate the servo and write a CSV",
        description="Simulate the servo and write the samples to a CSV file (SI units).",
    )
    parser.add_argument("--plant", choices=("nonlinear", "linear"), default="nonlinear",
                        help="nonlinear two-chamber model (default) or a linear one. "
                             "'linear' is two models: with --open-loop the small-signal "
                             "linearisation around the trim (all states, chamber pressures "
                             "included; velocity gain 0.2095 m/s per unit command for the paper "
                             "set), in closed loop eq. (8) with K_o = Q_rated/A_f (0.2619); "
                             "eq. (8) has no chamber pressures, which the open-loop CSV needs")
    parser.add_argument("--open-loop", action="store_true",
                        help="apply a constant valve command instead of a controller")
    parser.add_argument("--command", type=float, default=None, metavar="U",
                        help="open-loop valve command, fraction of rated input in [-1, 1]")
    parser.add_argument("--duration", type=float, default=2.0, metavar="S",
                        help="simulated time [s] (default 2)")
    parser.add_argument("--dt", "--ts", type=float, default=1e-3, metavar="S",
                        help="sample time of the command and of the CSV [s] (default 0.001)")
    parser.add_argument("--start", type=float, default=0.5, metavar="FRACTION",
                        help="initial position as a fraction of the stroke (default 0.5)")
    parser.add_argument("--method", choices=("rk4", "solve_ivp"), default="rk4",
                        help="compiled fixed-step RK4 (default) or scipy solve_ivp (DOP853)")
    parser.add_argument("--out", type=Path, required=True, metavar="FILE.csv",
                        help="CSV file to write")
    add_plant_arguments(parser)
    add_closed_loop_arguments(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo simulate``: dispatch on ``--open-loop``."""
    if args.open_loop:
        return run_open_loop(args)
    return run_closed_loop(args)


def run_open_loop(args: argparse.Namespace) -> int:
    """Open-loop branch of ``simulate``."""
    if args.command is None:
        raise InputError("--open-loop needs --command U (fraction of rated input in [-1, 1])")
    if not (math.isfinite(args.command) and -1.0 <= args.command <= 1.0):
        raise ParameterError(f"--command must be in [-1, 1] (fraction of rated input), "
                             f"got {args.command!r}")
    if not 0.0 < args.start < 1.0:
        raise ParameterError(f"--start must be a fraction of the stroke in (0, 1), "
                             f"got {args.start!r}")
    params = params_from_args(args)
    res = simulate_open_loop(params, args.command, duration=args.duration, dt=args.dt,
                             position=args.start * params.cylinder.stroke, delay=args.delay,
                             plant=args.plant, method=args.method)
    # u at t_k is the command issued for the interval that starts there (last one repeated)
    u_col = np.append(res.u, res.u[-1])
    cols = [res.t, u_col, res.x, res.v, res.p_f, res.p_n, res.states[:, 1], res.states[:, 2]]
    try:
        with open(args.out, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(OPEN_LOOP_COLUMNS)
            for k in range(res.t.shape[0]):
                w.writerow([repr(float(c[k])) for c in cols])
    except OSError as exc:
        raise InputError(f"cannot write {str(args.out)!r}: {exc.strerror}") from exc
    return 0
