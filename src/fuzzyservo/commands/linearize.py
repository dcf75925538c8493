"""``fuzzyservo linearize``: ω₀, δ, gains and eigenvalues of the servo at a stroke position.

Linearises the nonlinear model around its trimmed equilibrium (numerical Jacobian,
:func:`fuzzyservo.plant.linearize`) and prints the coefficients of the paper's eq. (8) with
their units; ``--json`` prints one object with the keys ``omega_0``, ``damping``, ``K_o``,
``omega_v``, ``zeta_v``, ``tau_v``, ``velocity_gain``, ``eigenvalues`` (``[re, im]`` pairs)
plus ``position``, ``trim_command``, ``p_f``, ``p_n`` and ``omega_0_range`` (min and max of ω₀
over 5-95 % of the stroke), as strict JSON (RFC 8259: NaN and infinities written as ``null``).
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from .._io import strict_json
from ..errors import ParameterError
from ..plant import ServoParams, linearize
from . import HELP
from ._plantargs import add_plant_arguments, params_from_args

__all__ = ["register", "run", "summary"]

#: Stroke fractions scanned for the ω₀ range.
SCAN = tuple(np.linspace(0.05, 0.95, 19))


def register(subparsers: Any) -> None:
    """Add the ``linearize`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "linearize",
        help=HELP["linearize"],
        description=(
            "Linearise the nonlinear servo model at rest at a stroke position (numerical "
            "Jacobian around the trimmed equilibrium; Coulomb friction left out) and print "
            "the coefficients of the paper's eq. (8)."
        ),
    )
    parser.add_argument("--position", type=float, default=0.5, metavar="FRACTION",
                        help="piston position as a fraction of the stroke (default 0.5)")
    parser.add_argument("--json", action="store_true",
                        help="print one strict JSON object (NaN and infinities as null)")
    add_plant_arguments(parser)
    parser.set_defaults(handler=run)


def summary(params: ServoParams, fraction: float) -> dict[str, Any]:
    """The figures ``linearize`` prints, as a JSON-ready dict (SI units)."""
    stroke = params.cylinder.stroke
    lin = linearize(params, fraction * stroke)
    scan = [linearize(params, s * stroke).omega_0 for s in SCAN]
    return {
        "omega_0": lin.omega_0,
        "damping": lin.damping,
        "K_o": params.velocity_gain,
        "omega_v": params.valve.omega_v,
        "zeta_v": params.valve.zeta_v,
        "tau_v": params.valve.tau_v,
        "velocity_gain": lin.velocity_gain,
        "eigenvalues": [[float(e.real), float(e.imag)] for e in lin.eigenvalues],
        "position": lin.trim.position,
        "trim_command": lin.trim.command,
        "p_f": lin.trim.p_f,
        "p_n": lin.trim.p_n,
        "omega_0_range": [min(scan), max(scan)],
    }


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo linearize``."""
    if not 0.0 < args.position < 1.0:
        raise ParameterError(
            f"--position must be a fraction of the stroke in (0, 1), got {args.position!r}")
    params = params_from_args(args)
    s = summary(params, args.position)
    if args.json:
        print(strict_json(s))
        return 0
    lo, hi = s["omega_0_range"]
    lines = [
        f"position        {s['position']:.6g} m (trimmed: command {s['trim_command']:.6g}, "
        f"p_f {s['p_f'] / 1e6:.4f} MPa, p_n {s['p_n'] / 1e6:.4f} MPa)",
        f"omega_0         {s['omega_0']:.6g} rad/s  (5-95 % of stroke: {lo:.4g} .. {hi:.4g})",
        f"damping         {s['damping']:.6g}",
        f"K_o             {s['K_o']:.6g} m/s per unit command (Q_rated / A_f, eq. 8)",
        f"velocity_gain   {s['velocity_gain']:.6g} m/s per unit command (small signal)",
        f"omega_v         {s['omega_v']:.6g} rad/s",
        f"zeta_v          {s['zeta_v']:.6g}",
        f"tau_v           {s['tau_v']:.6g} s",
        "eigenvalues     " + ", ".join(
            f"{re:.5g}{im:+.5g}j" for re, im in s["eigenvalues"]) + " 1/s",
    ]
    print("\n".join(lines))
    return 0
