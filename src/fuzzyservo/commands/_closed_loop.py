"""Closed-loop branch of ``fuzzyservo simulate`` (``--controller``, ``--gains``, ...).

``fuzzyservo simulate --plant linear|nonlinear --controller p|pi|pid|fpi|stfpi
--gains NAME=VALUE,... --reference step:0.1 --duration 5 --ts 0.001 [--delay 0.006]
--out run.csv [--metrics]``. Gain names: ``kp, ki, kd, n, b, c`` (PID family; P takes ``kp``
only, PI ``kp, ki, b``) and ``ke, kde, kdu`` (fuzzy PI and self-tuning fuzzy PI, all three
required). The linear plant is eq. (8) with the coefficients ``fuzzyservo linearize`` reports at
the start position; both plants start at rest there and the reference is an offset from it.
The CSV has the columns ``t, r, y, u, alpha`` and then the plant states (SI units).
"""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np

from ..analysis.step_metrics import step_metrics
from ..control import FuzzyPIController, PIDController, SelfTuningFuzzyPIController
from ..errors import InputError, ParameterError
from ..paper import alpha_system, du_system
from ..sim import make_plant, parse_reference, simulate
from ._plantargs import params_from_args
from .metrics import UNITS

__all__ = ["CONTROLLERS", "GAIN_NAMES", "add_closed_loop_arguments", "build_controller",
           "parse_gains", "run_closed_loop"]

#: Controllers of the CLI and the gain names each accepts.
GAIN_NAMES: dict[str, tuple[str, ...]] = {
    "p": ("kp",),
    "pi": ("kp", "ki", "b"),
    "pid": ("kp", "ki", "kd", "n", "b", "c"),
    "fpi": ("ke", "kde", "kdu"),
    "stfpi": ("ke", "kde", "kdu"),
}
CONTROLLERS: tuple[str, ...] = tuple(GAIN_NAMES)
_REQUIRED: dict[str, tuple[str, ...]] = {
    "p": ("kp",), "pi": ("kp", "ki"), "pid": ("kp", "ki", "kd"),
    "fpi": ("ke", "kde", "kdu"), "stfpi": ("ke", "kde", "kdu"),
}


def add_closed_loop_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the closed-loop options to the ``simulate`` parser."""
    g = parser.add_argument_group("closed loop")
    g.add_argument("--controller", default=None, metavar="NAME",
                   help=f"controller: {', '.join(CONTROLLERS)}")
    g.add_argument("--gains", default="", metavar="NAME=VALUE,...",
                   help="controller gains: kp, ki, kd, n, b, c (PID family) or ke, kde, kdu "
                        "(fuzzy), SI units")
    g.add_argument("--reference", default="step:0.1", metavar="SPEC",
                   help="reference offset from the start position [m]: step:A[:T], "
                        "multistep:T1=A1,..., ramp:SLOPE[:T[:FINAL]], sine:A:F, "
                        "trapezoid:DIST:VMAX:AMAX[:T] (default step:0.1)")
    g.add_argument("--delay", type=float, default=None, metavar="S",
                   help="transport (hose) delay on the command [s] (default: the parameter "
                        "set's delay.transport_delay, 6 ms for the paper set; 0 for none)")
    g.add_argument("--metrics", action="store_true", help="print the step metrics")
    g.add_argument("--noise-std", type=float, default=0.0, metavar="M",
                   help="measurement noise standard deviation [m] (default 0)")
    g.add_argument("--seed", type=int, default=0, help="seed of the noise generator")
    g.add_argument("--anti-windup", default="clamping",
                   choices=("clamping", "back-calculation", "none"),
                   help="PID anti-windup scheme (default clamping)")
    g.add_argument("--initial-error", default="zero", choices=("zero", "first"),
                   help="fuzzy PI: e(-1) = 0 or e(-1) = e(0) (default zero)")
    g.add_argument("--de-per", default="sample", choices=("sample", "second"),
                   help="fuzzy PI: Δe per sample or per second (default sample)")
    g.add_argument("--filter-time", type=float, default=0.0, metavar="S",
                   help="fuzzy PI: measurement filter time constant [s] (default 0: none)")


def parse_gains(text: str, controller: str) -> dict[str, float]:
    """Parse ``NAME=VALUE,...`` for ``controller``; names checked, values finite and >= 0."""
    allowed = GAIN_NAMES[controller]
    gains: dict[str, float] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        name, sep, value = item.partition("=")
        name = name.strip().lower()
        if not sep:
            raise ParameterError(f"--gains expects NAME=VALUE, got {item!r}")
        if name in gains:
            raise ParameterError(f"gain {name} is given twice in --gains; give each once")
        if name not in allowed:
            raise ParameterError(
                f"unknown gain {name!r} for controller {controller}; allowed: "
                f"{', '.join(allowed)}")
        try:
            number = float(value)
        except ValueError:
            raise ParameterError(f"gain {name}: {value.strip()!r} is not a number") from None
        if name == "n" and number == math.inf:
            gains[name] = number
            continue
        if not (math.isfinite(number) and number >= 0.0):
            raise ParameterError(f"gain {name} must be finite and >= 0, got {value.strip()}")
        gains[name] = number
    missing = [n for n in _REQUIRED[controller] if n not in gains]
    if missing:
        raise ParameterError(f"controller {controller} needs gains {', '.join(missing)} "
                             f"(--gains {','.join(f'{n}=...' for n in _REQUIRED[controller])})")
    return gains


def build_controller(args: argparse.Namespace) -> Any:
    """The controller selected by ``--controller`` and ``--gains``."""
    name = args.controller
    if name is None:
        raise ParameterError(f"closed loop needs --controller ({', '.join(CONTROLLERS)}), "
                             f"or --open-loop")
    if name not in GAIN_NAMES:
        raise ParameterError(
            f"unknown controller {name!r}; allowed: {', '.join(CONTROLLERS)}")
    gains = parse_gains(args.gains, name)
    ts = args.dt
    if not (math.isfinite(ts) and ts > 0.0):
        raise ParameterError(f"--ts must be finite and > 0 s, got {ts!r}")
    if name in ("p", "pi", "pid"):
        return PIDController(dt=ts, anti_windup=args.anti_windup, **gains)
    cls = SelfTuningFuzzyPIController if name == "stfpi" else FuzzyPIController
    return cls.from_systems(du_system(), alpha_system() if name == "stfpi" else None, dt=ts,
                            initial_error=args.initial_error, de_per=args.de_per,
                            filter_time=args.filter_time, **gains)


def run_closed_loop(args: argparse.Namespace) -> int:
    """Closed-loop branch of ``simulate``: run, write the CSV, print metrics if asked."""
    ctl = build_controller(args)
    reference = parse_reference(args.reference)
    if not 0.0 < args.start < 1.0:
        raise ParameterError(f"--start must be a fraction of the stroke in (0, 1), "
                             f"got {args.start!r}")
    params = params_from_args(args)
    position = args.start * params.cylinder.stroke
    plant = make_plant(args.plant, params, position)
    if args.seed < 0:
        raise ParameterError(f"--seed must be a non-negative integer, got {args.seed}")
    delay = params.delay.transport_delay if args.delay is None else args.delay
    res = simulate(ctl, plant, reference, duration=args.duration, delay=delay,
                   noise_std=args.noise_std, rng=np.random.default_rng(args.seed))
    try:
        res.to_csv(args.out)
    except OSError as exc:
        raise InputError(f"cannot write {str(args.out)!r}: {exc.strerror}") from exc
    if args.metrics:
        m = step_metrics(res.t, res.y, u=res.u, r=res.r).as_dict()
        width = max(len(k) for k in m)
        for key, value in m.items():
            print(f"{key:<{width}}  {value:.6g} {UNITS[key]}")
    return 0
