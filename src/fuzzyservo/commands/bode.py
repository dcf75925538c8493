"""``fuzzyservo bode``: the closed loop's frequency response, margins and bandwidth.

Analytic on the linear model (:func:`fuzzyservo.analysis.closed_loop_bode`): the controller
linearised at rest, the plant's ZOH discretisation with the delay; on ``--plant nonlinear``
the analytic model is the small-signal one at the same start. ``--measured`` adds the response
measured by simulation with sines of ``--amplitude`` on the plant itself
(:func:`fuzzyservo.analysis.measured_response`; on the nonlinear plant it depends on the
amplitude). The margins are printed as a table (``--json``: one strict JSON object with the
margins and the response); ``--out FILE.csv`` writes the response, ``--out FIG.png|.svg`` draws
it. docs/frequency.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from .._io import check_output_path, strict_json, write_text_atomic
from ..analysis.frequency import (
    BodeResult,
    MeasuredResponse,
    closed_loop_bode,
    frequency_grid,
    measured_response,
    settle_time,
)
from ..errors import InputError, ParameterError
from ..registry import controller_colour, controller_options
from ..run import RunSpec, check_start, run_default, servo_params
from . import HELP
from ._plantargs import add_plant_arguments, overrides_from_args, params_given, set_name
from ._runargs import (
    add_controller_arguments,
    add_plant_choice,
    add_timing_arguments,
    controller_from_args,
    delay_from_args,
    simulated_time_progress,
)

__all__ = ["parse_frequencies", "register", "run"]

#: ``--freq`` when not given: LO:HI:N [Hz].
DEFAULT_FREQ = "0.1:100:40"
#: Points of the analytic line on a figure.
FIGURE_POINTS = 400


def register(subparsers: Any) -> None:
    """Add the ``bode`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "bode", help=HELP["bode"],
        description=(
            "Frequency response of the closed loop from reference to position: analytic on "
            "the linear model (the controller linearised at rest; on --plant nonlinear the "
            "small-signal model), with gain, phase and modulus margins, bandwidth and peak; "
            "with --measured also measured by sine sweeps on the plant itself "
            "(docs/frequency.md)."))
    add_plant_choice(parser, None)
    add_timing_arguments(parser, ts_what="controller sample time",
                         start_what="operating position")
    parser.add_argument("--freq", default=DEFAULT_FREQ, metavar="LO:HI:N",
                        help=f"N log-spaced frequencies from LO to HI [Hz], below Nyquist "
                             f"(default {DEFAULT_FREQ})")
    parser.add_argument("--measured", action="store_true",
                        help="also measure the response by simulation, one sine per frequency")
    parser.add_argument("--amplitude", type=float, default=5e-3, metavar="M",
                        help="measured: sine amplitude around the operating position [m] "
                             "(default 0.005)")
    parser.add_argument("--cycles", type=int, default=4, metavar="N",
                        help="measured: whole periods fitted per frequency (default 4)")
    parser.add_argument("--out", default=None, metavar="FILE.csv|FIG.png|FIG.svg",
                        help="write the response as CSV, or draw it")
    parser.add_argument("--json", action="store_true",
                        help="print one strict JSON object instead of the table")
    add_controller_arguments(parser)
    add_plant_arguments(parser)
    parser.set_defaults(handler=run)


def parse_frequencies(text: str) -> np.ndarray:
    """``LO:HI:N`` as N log-spaced frequencies [Hz].

    Raises
    ------
    InputError
        Not three fields, numbers out of range.
    """
    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise InputError(f"--freq must be LO:HI:N (Hz, Hz, a whole number), got "
                         f"{text!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi and 2 <= n <= 10_000):
        raise InputError(f"--freq needs 0 < LO < HI and 2 <= N <= 10000, got {text!r}")
    return frequency_grid(lo, hi, n)


def _spec(args: argparse.Namespace) -> tuple[RunSpec, list[str]]:
    """The run the command line describes (a gains file's record filling plant, start, set
    and delay, as ``simulate`` does) and the notes saying what came from it."""
    choice = controller_from_args(args)
    tuned = choice.tuned
    s = tuned.setup if tuned is not None else None
    notes: list[str] = []
    plant = args.plant or (s.plant if s is not None else run_default("plant"))
    start = args.start if args.start is not None else (
        s.start if s is not None else run_default("start"))
    if s is not None and not params_given(args):
        param_set, overrides = s.param_set, tuple(s.overrides)
    else:
        param_set, overrides = set_name(args), tuple(overrides_from_args(args).items())
    params = servo_params(param_set, overrides)
    if args.delay is None and s is not None:
        delay = s.delay
    else:
        delay = delay_from_args(args.delay, params)
    if s is not None:
        notes.append(f"{args.gains}: as tuned, the {plant} plant, start {start:g}, set "
                     f"{param_set}, delay {delay:g} s (options given win)")
    check_start(start)
    spec = RunSpec(
        controller=choice.kind, gains=tuple(choice.gains.items()),
        options=tuple((o.name, getattr(args, o.name)) for o in controller_options()
                      if getattr(args, o.name, None) is not None),
        systems=tuple((role, str(path)) for role, path in
                      (("du", args.du_system), ("alpha", args.alpha_system))
                      if path is not None),
        no_rule_value=args.no_rule_value, plant=plant, param_set=param_set,
        overrides=overrides, ts=choice.ts, delay=delay, start=start, substep=args.substep)
    return spec, notes


def _check(args: argparse.Namespace) -> np.ndarray:
    f = parse_frequencies(args.freq)
    if not (math.isfinite(args.amplitude) and args.amplitude > 0.0):
        raise ParameterError(f"--amplitude must be finite and > 0 m, got {args.amplitude!r}")
    if args.cycles < 1:
        raise ParameterError(f"--cycles must be at least 1, got {args.cycles!r}")
    if args.out is not None:
        if Path(args.out).suffix.lower() not in (".csv", ".png", ".svg"):
            raise InputError(f"--out {args.out!r}: the file name must end in .csv, .png or "
                             f".svg")
        inputs = [args.param_file]
        if args.gains is not None and Path(args.gains).is_file():
            inputs.append(Path(args.gains))
        check_output_path(args.out, option="--out", inputs=inputs)
    return f


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo bode``."""
    f = _check(args)
    spec, notes = _spec(args)
    built = spec.build()
    analytic_spec = (dataclasses.replace(spec, plant="small-signal")
                     if spec.plant == "nonlinear" else spec)
    lin_plant = built.plant if analytic_spec is spec else analytic_spec.build().plant
    ts = float(built.controller.dt)
    if f[-1] >= 0.5 / ts:
        raise InputError(f"--freq reaches {f[-1]:g} Hz; the frequencies must be below the "
                         f"Nyquist frequency {0.5 / ts:g} Hz (ts = {ts:g} s)")
    bode = closed_loop_bode(built.controller, lin_plant, f, delay=spec.delay)
    for note in notes:
        print(f"fuzzyservo: note: {note}", file=sys.stderr)
    measured: MeasuredResponse | None = None
    if args.measured:
        settle = settle_time(bode.model)
        with simulated_time_progress("sine sweep") as progress:
            measured = measured_response(built.controller, built.plant, f,
                                         amplitude=args.amplitude, delay=spec.delay,
                                         cycles=args.cycles, settle=settle,
                                         progress=progress)
    title = (f"{spec.controller} on the {spec.plant} plant"
             + (" (analytic: small-signal model)" if analytic_spec is not spec else ""))
    if args.json:
        print(strict_json(_json(bode, measured, title)))
    else:
        print(_table(bode, title, measured))
    if args.out is not None:
        _write(args.out, bode, measured, spec, built.controller, lin_plant)
    return 0


def _table(bode: BodeResult, title: str, measured: MeasuredResponse | None) -> str:
    m = bode.margins
    k = bode.model.controller
    rows = [
        f"closed loop     {title}, ts {bode.model.ts:g} s",
        f"gain margin     {m.gain_margin:.6g} ({m.gain_margin_db:.4g} dB) at "
        f"{m.phase_crossover:.6g} Hz",
        f"phase margin    {m.phase_margin_deg:.6g} deg at {m.gain_crossover:.6g} Hz",
        f"modulus margin  {m.modulus_margin:.6g} (peak sensitivity "
        f"{-20.0 * math.log10(m.modulus_margin):.4g} dB)",
        f"bandwidth       {m.bandwidth:.6g} Hz (-3 dB)",
        f"peak            {m.peak_db:.4g} dB at {m.peak_frequency:.6g} Hz",
        f"stable          {'yes' if m.stable else 'no'} (largest |pole| "
        f"{m.spectral_radius:.8g})",
        f"linearisation   controller states {', '.join(k.state_names) or 'none'}; "
        f"Jacobian uncertain to {k.error:.1g} (relative)",
    ]
    if measured is not None:
        err = np.abs(measured.response - bode.closed_loop)
        rows.append(f"measured        amplitude {measured.amplitude:g} m: |measured - "
                    f"analytic| up to {float(np.max(err)):.3g}, distortion up to "
                    f"{float(np.max(measured.distortion)):.3g}")
    return "\n".join(rows)


def _json(bode: BodeResult, measured: MeasuredResponse | None, title: str) -> dict[str, Any]:
    m = bode.margins
    out: dict[str, Any] = {
        "title": title,
        "ts": bode.model.ts,
        "margins": {**{f.name: getattr(m, f.name) for f in dataclasses.fields(m)},
                    "gain_margin_db": m.gain_margin_db},
        "linearisation_error": bode.model.controller.error,
        "frequency": bode.frequency.tolist(),
        "magnitude_db": bode.magnitude_db.tolist(),
        "phase_deg": bode.phase_deg.tolist(),
    }
    if measured is not None:
        out["measured"] = {
            "amplitude": measured.amplitude,
            "magnitude_db": measured.magnitude_db.tolist(),
            "phase_deg": measured.phase_deg.tolist(),
            "distortion": measured.distortion.tolist(),
        }
    return out


def _write(out: str, bode: BodeResult, measured: MeasuredResponse | None, spec: RunSpec,
           controller: Any, lin_plant: Any) -> None:
    if Path(out).suffix.lower() == ".csv":
        buf = io.StringIO()
        cols = ["f", "magnitude_db", "phase_deg"]
        data = [bode.frequency, bode.magnitude_db, bode.phase_deg]
        if measured is not None:
            cols += ["measured_db", "measured_phase_deg", "distortion"]
            data += [measured.magnitude_db, measured.phase_deg, measured.distortion]
        buf.write(",".join(cols) + "\n")
        for row in np.column_stack(data):
            buf.write(",".join(repr(float(v)) for v in row) + "\n")
        write_text_atomic(out, buf.getvalue())
        return
    from ..plots.frequency import bode_curve, bode_figure
    from ..plots.runs import save_figure

    f = bode.frequency
    dense = frequency_grid(float(f[0]), float(f[-1]), FIGURE_POINTS)
    line = closed_loop_bode(controller, lin_plant, dense, delay=spec.delay)
    curve = bode_curve(spec.controller, line, measured,
                       colour=controller_colour(spec.controller))
    save_figure(bode_figure([curve], title=f"{spec.controller} on the {spec.plant} plant"), out)
