"""``fuzzyservo identify``: the servo model of a user's own axis, from measured data.

Three forms (docs/identify.md):

``fuzzyservo identify DATA.csv --plant P --fit NAME[,NAME...] --out AXIS.toml``
    Fit fields of the parameter set (``--set``, ``--params``, ``--param``) so that the model,
    driven by the logged command (open loop) or by ``--controller``/``--gains`` and the logged
    reference (closed loop), reproduces the logged position and chamber pressures; write the
    identified set with its record. ``--fit K_o,omega_h,zeta_h[,delay]`` (with ``--plant
    linear``) fits eq. (8)'s coefficients directly and writes the physical parameters they
    imply.
``fuzzyservo identify --frequency-response FRF.csv --out AXIS.toml``
    Fit eq. (8) to a measured frequency response (frequency, gain, phase).
``fuzzyservo identify --design --out DESIGN.csv``
    Write an excitation (steps of both signs and a chirp above the hydraulic natural
    frequency, inside the stroke and the valve's limits) and say what to log and how long.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import shlex
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from .. import __version__
from .._io import check_output_path, sha256_file
from ..errors import InputError, ParameterError, UsageError
from ..registry import DEFAULT_SUBSTEP, build_controller, plant_names
from . import HELP
from ._plantargs import add_plant_arguments, params_from_args, set_name
from ._runargs import (
    add_controller_arguments,
    controller_from_args,
    options_from_args,
    systems_from_args,
)

__all__ = ["LINEAR_NAMES", "describe", "parse_bounds", "partial_path", "register", "run"]

#: The coefficients of eq. (8) that ``--fit`` may name instead of parameter fields
#: (:data:`fuzzyservo.identify.linear.LINEAR_NAMES`; a test keeps the two equal: this
#: module is imported for ``--help`` and stays light).
LINEAR_NAMES = ("K_o", "omega_h", "zeta_h", "delay", "omega_v", "zeta_v")


def register(subparsers: Any) -> None:
    """Add the ``identify`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "identify", help=HELP["identify"],
        description=(
            "Identify the servo model of your axis from measured data: fit parameter fields "
            "(--fit) so that the model driven by the logged command (open loop) or by the "
            "named controller and the logged reference (closed loop) reproduces the logged "
            "position and chamber pressures, and write the identified parameter set (--out "
            "AXIS.toml, for --params on every command) with estimates, standard errors, "
            "correlations and warnings. --design writes an experiment to log; "
            "--frequency-response fits eq. (8) to a measured frequency response. SI units "
            "unless --units or the CSV header say otherwise (docs/identify.md)."))
    parser.add_argument("data", nargs="?", type=Path, default=None, metavar="DATA.csv",
                        help="the logged experiment: a CSV with a time column and columns "
                             "u (command, fraction of rated), y (position), r (reference, "
                             "closed loop), p_f and p_n (chamber pressures), units in the "
                             "header ('y [mm]') or by --units")
    mode = parser.add_argument_group("what to do")
    mode.add_argument("--design", action="store_true",
                      help="write an identification experiment (a command sequence) to --out "
                           "instead of fitting")
    mode.add_argument("--frequency-response", type=Path, default=None, metavar="FRF.csv",
                      help="fit eq. (8) to a frequency response (columns frequency, gain, "
                           "phase) instead of time data")
    fit = parser.add_argument_group("the fit")
    fit.add_argument("--plant", choices=plant_names(), default="nonlinear", metavar="NAME",
                     help=f"model to fit: {', '.join(plant_names())} (default nonlinear)")
    fit.add_argument("--fit", default=None, metavar="NAME[,NAME...]",
                     help="parameter fields to fit (group.field, e.g. load.mass,"
                          "fluid.oil_bulk_modulus,valve.omega_v), or eq. (8)'s "
                          f"{','.join(LINEAR_NAMES)} with --plant linear")
    fit.add_argument("--bounds", action="append", default=[], metavar="NAME=LO:HI",
                     help="search interval of a fitted field [SI] (repeatable; default a "
                          "decade either side of the set's value)")
    fit.add_argument("--channels", default=None, metavar="y[,p_f,p_n]",
                     help="signals to fit (default every logged one the model has)")
    fit.add_argument("--command-offset", choices=("rest", "none"), default="rest",
                     help="open loop: 'rest' replaces the logged command's value at rest by "
                          "the model's holding command (a valve's null offset is not read "
                          "as drift); 'none' drives the model with the logged command as it "
                          "is (default rest)")
    fit.add_argument("--reference-rates", choices=("auto", "difference", "zero"),
                     default="auto",
                     help="closed loop, feed-forward laws (ffpd, smc): the reference's "
                          "velocity and acceleration from differences of the logged samples, "
                          "or zero (a step's exact rates); auto: zero when the reference is "
                          "piecewise constant (default auto)")
    fit.add_argument("--starts", type=int, default=3, metavar="N",
                     help="local searches: the set's values, then seeded draws (default 3)")
    fit.add_argument("--seed", type=int, default=0, metavar="SEED",
                     help="seed of the starts and the bootstrap (default 0)")
    fit.add_argument("--bootstrap", type=int, default=0, metavar="N",
                     help="percentile intervals from N refits to resampled residual blocks "
                          "(default 0: none)")
    fit.add_argument("--block", type=int, default=None, metavar="SAMPLES",
                     help="bootstrap block length (default two hydraulic periods)")
    fit.add_argument("--level", type=float, default=0.95, metavar="L",
                     help="coverage of the bootstrap intervals (default 0.95)")
    fit.add_argument("--substep", type=float, default=DEFAULT_SUBSTEP, metavar="S",
                     help=f"nonlinear plant: RK4 step bound [s] (default {DEFAULT_SUBSTEP:g})")
    data = parser.add_argument_group("reading the data")
    data.add_argument("--columns", default=None, metavar="OURS=THEIRS,...",
                      help="the file's column names for t, u, y, r, p_f, p_n, e.g. "
                           "y=pos_mm,u=cmd")
    data.add_argument("--units", default=None, metavar="NAME=UNIT,...",
                      help="units of the columns (t: s, ms, us; y, r: m, mm, um; p_f, p_n: "
                           "Pa, kPa, bar, MPa, psi; u: 1, %%), e.g. y=mm,p_f=bar")
    data.add_argument("--resample", "--dt", dest="resample", type=float, default=None,
                      metavar="S",
                      help="sample time to resample the data to [s] (default: the data's "
                           "median step; uneven stamps are resampled to it)")
    data.add_argument("--position-offset", type=float, default=None, metavar="M",
                      help="added to the logged position so that it is measured from the "
                           "retracted end [m]")
    data.add_argument("--pressure-offset", type=float, default=0.0, metavar="PA",
                      help="added to the logged pressures (gauge to the model's pressures) "
                           "[Pa] (default 0)")
    design = parser.add_argument_group("--design")
    design.add_argument("--start", type=float, default=0.5, metavar="FRACTION",
                        help="start position of the experiment (--design), or where a "
                             "frequency response was measured (--frequency-response), as a "
                             "fraction of the stroke (default 0.5)")
    design.add_argument("--amplitude", type=float, default=0.2, metavar="A",
                        help="largest excitation as a fraction of the rated command "
                             "(default 0.2)")
    design.add_argument("--f-max", type=float, default=None, metavar="HZ",
                        help="top of the designed chirp [Hz] (default 1.5 times the hydraulic "
                             "natural frequency; raise it toward the valve's band to identify "
                             "valve.omega_v)")
    design.add_argument("--margin", type=float, default=0.1, metavar="FRACTION",
                        help="stroke kept free at each end, as a fraction of the stroke "
                             "(default 0.1)")
    design.add_argument("--ts", type=float, default=None, metavar="S",
                        help="sample time of the designed sequence, and of a closed-loop "
                             "controller [s] (default 0.001, or the gains file's)")
    out = parser.add_argument_group("outputs")
    out.add_argument("--out", type=Path, required=True, metavar="AXIS.toml|DESIGN.csv",
                     help="the identified parameter file (or, with --design, the command "
                          "sequence)")
    out.add_argument("--plot", type=Path, default=None, metavar="FIG.png|FIG.svg",
                     help="figure: measured and fitted traces, residuals, estimates")
    out.add_argument("--html", type=Path, default=None, metavar="REPORT.html",
                     help="an offline HTML page of the identification")
    out.add_argument("--quiet", action="store_true", help="no progress lines")
    out.add_argument("--resume", action="store_true",
                     help="go on with the bootstrap of an interrupted run of the same command "
                          "(its refits are kept in OUT.partial.npz; the result is the "
                          "uninterrupted run's, bit for bit)")
    add_controller_arguments(parser)
    add_plant_arguments(parser)
    parser.set_defaults(handler=run)


def parse_bounds(items: list[str]) -> dict[str, tuple[float, float]]:
    """``NAME=LO:HI`` items as ``{name: (lo, hi)}``.

    Raises
    ------
    InputError
        Bad syntax, a number that is not one, or a name given twice.
    """
    out: dict[str, tuple[float, float]] = {}
    for item in items:
        name, eq, rng = item.partition("=")
        lo_s, colon, hi_s = rng.partition(":")
        if not (eq and colon and name.strip()):
            raise InputError(f"--bounds {item!r}: expected NAME=LO:HI, e.g. "
                             f"load.mass=1000:50000")
        try:
            lo, hi = float(lo_s), float(hi_s)
        except ValueError:
            raise InputError(f"--bounds {item!r}: LO and HI must be numbers") from None
        if name.strip() in out:
            raise InputError(f"--bounds names {name.strip()!r} twice")
        out[name.strip()] = (lo, hi)
    return out


def _command(args: argparse.Namespace) -> str:
    argv = getattr(args, "argv", None)
    return "fuzzyservo " + shlex.join(sys.argv[1:] if argv is None else argv)


def _say(args: argparse.Namespace, text: str) -> None:
    if not args.quiet:
        print(f"fuzzyservo identify: {text}", file=sys.stderr, flush=True)


@contextlib.contextmanager
def _progress(args: argparse.Namespace) -> Iterator[Callable[[str, int, int], None]]:
    """A progress callback ``(stage, done, total)``: a tqdm bar with rate and time left on a
    terminal, else one line per finished step."""
    import time

    bars: dict[str, Any] = {}
    tty = sys.stderr.isatty()
    last = [time.monotonic(), time.monotonic()]  # start, last line

    def report(stage: str, done: int, total: int) -> None:
        if args.quiet:
            return
        if total == 0:  # a new cost inside a search: a line at most every second
            now = time.monotonic()
            if now - last[1] >= 1.0:
                last[1] = now
                rate = done / max(now - last[0], 1e-9)
                text = (f"fuzzyservo identify: {stage}, {done} model runs "
                        f"({rate:.0f}/s)")
                if tty and not bars:
                    print(f"\r{text}\033[K", end="", file=sys.stderr, flush=True)
                elif not tty:
                    print(text, file=sys.stderr, flush=True)
            return
        if tty:
            print("\r\033[K", end="", file=sys.stderr, flush=True)
            from tqdm import tqdm

            bar = bars.get(stage)
            if bar is None:
                bar = bars[stage] = tqdm(total=total, desc=f"identify: {stage}",
                                         unit="fit", file=sys.stderr, leave=True)
            bar.update(done - bar.n)
        else:
            print(f"fuzzyservo identify: {stage} {done}/{total}", file=sys.stderr, flush=True)

    try:
        yield report
    finally:
        for bar in bars.values():
            bar.close()


def _channels(text: str) -> list[str]:
    """``--channels``: signals to fit, each once, at least one."""
    from ..identify import FIT_CHANNELS

    out = [c.strip() for c in text.split(",") if c.strip()]
    if not out:
        raise UsageError(f"--channels names no signal; give one or more of "
                         f"{', '.join(FIT_CHANNELS)}")
    for c in out:
        if c not in FIT_CHANNELS:
            raise UsageError(f"--channels: unknown signal {c!r}; allowed: "
                             f"{', '.join(FIT_CHANNELS)}")
        if out.count(c) > 1:
            raise UsageError(f"--channels names {c!r} twice (it would count twice); name each "
                             f"signal once")
    return out


def _names(text: str | None) -> list[str]:
    if text is None or not text.strip():
        raise UsageError("identify needs --fit NAME[,NAME...] (e.g. --fit load.mass,"
                         "fluid.oil_bulk_modulus,valve.omega_v), or --design, or "
                         "--frequency-response FRF.csv")
    return [n.strip() for n in text.split(",") if n.strip()]


def _check_outputs(args: argparse.Namespace) -> None:
    """Every output path, before any work: writable, not an input, each a different file,
    a figure's format known."""
    inputs: list[Path] = [p for p in (args.data, args.frequency_response, args.param_file,
                                      args.du_system, args.alpha_system) if p is not None]
    if args.gains is not None and "=" not in args.gains:
        inputs.append(Path(args.gains))
    seen: dict[Path, str] = {}
    for option in ("out", "plot", "html"):
        path = getattr(args, option)
        if path is None:
            continue
        check_output_path(path, option=f"--{option}", inputs=inputs)
        key = Path(path).resolve()
        if key in seen:
            raise UsageError(f"--{option} and --{seen[key]} name the same file "
                             f"{str(path)!r}; give each output its own")
        seen[key] = option
    if args.plot is not None:
        from ..plots import FIGURE_FORMATS

        if args.plot.suffix.lower() not in FIGURE_FORMATS:
            raise UsageError(f"--plot {str(args.plot)!r}: the file name must end in "
                             f"{' or '.join(FIGURE_FORMATS)}")


#: Options of the parameter fit that the eq. (8) fits and the designer do not take.
_FIT_ONLY: tuple[tuple[str, Any, str], ...] = (
             ("bootstrap", 0, "--bootstrap"), ("resume", False, "--resume"),
             ("channels", None, "--channels"), ("bounds", [], "--bounds"),
             ("controller", None, "--controller"), ("gains", None, "--gains"),
             ("plot", None, "--plot"), ("html", None, "--html"), ("block", None, "--block"),
             ("starts", 3, "--starts"))


def _refuse_fit_only(args: argparse.Namespace, what: str) -> None:
    given = [flag for name, default, flag in _FIT_ONLY if getattr(args, name) != default]
    if given:
        raise UsageError(f"{what} does not take {', '.join(given)} (options of the parameter "
                         f"fit, --fit group.field,...)")


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo identify``."""
    _check_outputs(args)
    if args.design:
        if args.data is not None or args.frequency_response is not None or args.fit:
            raise UsageError("--design writes an experiment; it takes no DATA.csv, "
                             "--frequency-response or --fit")
        _refuse_fit_only(args, "--design")
        return _design(args)
    if args.frequency_response is not None:
        if args.data is not None:
            raise UsageError("give DATA.csv or --frequency-response FRF.csv, not both")
        _refuse_fit_only(args, "--frequency-response")
        return _frequency(args)
    if args.data is None:
        raise UsageError("identify needs DATA.csv (or --design, or --frequency-response)")
    names = _names(args.fit)
    if any(n in LINEAR_NAMES for n in names):
        _refuse_fit_only(args, f"--fit {','.join(names)} (eq. (8) directly)")
        return _linear_time(args, names)
    return _fields(args, names)


def _read(args: argparse.Namespace, need: tuple[str, ...]) -> Any:
    from ..identify import parse_mapping, read_measurement

    return read_measurement(
        args.data, columns=parse_mapping(args.columns, "--columns") if args.columns else None,
        units=parse_mapping(args.units, "--units") if args.units else None,
        dt=args.resample, position_offset=args.position_offset,
        pressure_offset=args.pressure_offset, need=need)


def _controller(args: argparse.Namespace, dt: float) -> Any:
    """The closed loop's controller, or None for open-loop data."""
    if args.controller is None and args.gains is None:
        return None
    if args.ts is None:
        args.ts = dt
    choice = controller_from_args(args)
    options = options_from_args(args, choice.kind)
    systems = systems_from_args(args, choice.kind)
    return build_controller(choice.kind, choice.gains, dt=choice.ts, options=options,
                            systems=systems)


def _fields(args: argparse.Namespace, names: list[str]) -> int:
    from ..identify import FitSettings, identify, render_axis_toml
    from ..identify.fit import check_names

    check_names(names)  # the arguments first: one line before any file is read
    bounds = parse_bounds(args.bounds)
    channels = None if args.channels is None else _channels(args.channels)
    if not (math.isfinite(args.substep) and args.substep > 0.0):
        raise ParameterError(f"--substep must be finite and > 0 s, got {args.substep!r}")
    settings = FitSettings(starts=args.starts, seed=args.seed, bootstrap=args.bootstrap,
                           block=args.block, level=args.level)
    params = params_from_args(args)
    closed = args.controller is not None or args.gains is not None
    m = _read(args, ("r",) if closed else ("u",))
    for note in m.notes:
        _say(args, f"data: {note}")
    controller = _controller(args, m.dt)
    _say(args, f"fitting {', '.join(names)} on the {args.plant} model "
               f"({'closed' if closed else 'open'} loop, {m.t.size} samples at "
               f"{m.dt:g} s)")
    partial = partial_path(args.out)
    key = _run_key(args, m.digest)
    if args.bootstrap and not args.resume and partial.exists():
        raise InputError(f"{str(partial)!r} holds the refits of an interrupted bootstrap: add "
                         f"--resume to go on from them, or delete the file to start over")
    resume = _load_partial(partial, key) if args.resume else None
    if resume is not None:
        _say(args, f"resuming: {resume.shape[0]} bootstrap refits kept from {partial}")

    def save(done: Any) -> None:
        _save_partial(partial, key, done)

    with _progress(args) as progress:
        ident = identify(m, plant=args.plant, params=params, fit=names,
                         bounds=bounds, controller=controller,
                         substep=args.substep, command_offset=args.command_offset,
                         reference_rates=args.reference_rates, channels=channels,
                         settings=settings, progress=progress,
                         resume=resume, checkpoint=save if args.bootstrap else None)
    text = render_axis_toml(ident, data=str(args.data), digest=m.digest,
                            command=_command(args), base_set=set_name(args),
                            version=__version__)
    _write_outputs(args, ident, text, m.digest)
    partial.unlink(missing_ok=True)
    for line in describe(ident):
        print(line)
    for w in ident.warnings:
        print(f"fuzzyservo identify: warning: {w}", file=sys.stderr)
    return 0


def partial_path(out: Path) -> Path:
    """Where an interrupted bootstrap for the parameter file ``out`` keeps its refits."""
    return out.with_name(out.name + ".partial.npz")


def _run_key(args: argparse.Namespace, digest: str) -> str:
    """A digest of everything the bootstrap's refits depend on: the data and every option
    but --resume and --quiet (the parameter file's contents included)."""
    import hashlib
    import json

    opts = {k: str(v) for k, v in sorted(vars(args).items())
            if k not in ("resume", "quiet", "handler", "argv", "out", "plot", "html")}
    files = {"param_file": args.param_file, "du_system": args.du_system,
             "alpha_system": args.alpha_system,
             "gains": Path(args.gains) if args.gains is not None and "=" not in args.gains
             else None}
    for name, path in files.items():  # what the files hold, not only their names
        if path is not None:
            opts[f"{name}_digest"] = sha256_file(path)
    text = json.dumps({"data": digest, "options": opts, "version": __version__},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _load_partial(path: Path, key: str) -> Any:
    import numpy as np

    if not path.exists():
        raise InputError(f"--resume: {str(path)!r} does not exist (nothing to resume; run "
                         f"without --resume)")
    from .._io import read_bytes

    try:
        with np.load(io.BytesIO(read_bytes(path, "bootstrap checkpoint")),
                     allow_pickle=False) as z:
            saved_key = str(z["key"])
            done = np.array(z["done"], dtype=np.float64)
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"--resume: {str(path)!r} is not a bootstrap checkpoint: "
                         f"{exc}") from None
    if saved_key != key:
        raise InputError(f"--resume: {str(path)!r} was written by another command or other "
                         f"data (its options or the data's digest differ); run the same "
                         f"command, or delete it and run without --resume")
    return done


def _save_partial(path: Path, key: str, done: Any) -> None:
    import numpy as np

    from .._io import atomic_write

    with atomic_write(path, binary=True) as fh:
        np.savez(fh, key=np.array(key), done=np.asarray(done, dtype=np.float64))


def _write_outputs(args: argparse.Namespace, ident: Any, text: str, digest: str) -> None:
    """The figure, the page, then the parameter file (each written atomically)."""
    from ..identify import write_axis_toml

    if args.plot is not None:
        from ..plots.identification import save_identification_figure

        save_identification_figure(ident, args.plot)
    if args.html is not None:
        from ..identify.report import write_report

        png = args.plot if args.plot is not None and args.plot.suffix.lower() == ".png" \
            else None
        write_report(ident, args.html, command=_command(args), data=str(args.data),
                     digest=digest, figure_path=png)
    write_axis_toml(args.out, text)


def describe(ident: Any) -> list[str]:
    """The lines ``identify`` prints: one per estimate, the residuals and the fit's figures."""
    lines = [f"identified on the {ident.plant} model ({ident.mode}, start position "
             f"{ident.position:.6g} m):"]
    width = max(len(n) for n in ident.names)
    for i, n in enumerate(ident.names):
        est, se = float(ident.estimate[i]), float(ident.std_error[i])
        rel = f"{100 * se / abs(est):.2g} %" if est else "-"
        extra = ""
        if ident.interval is not None:
            lo, hi = ident.interval[i]
            extra = f"  {100 * ident.level:g} % interval [{lo:.6g}, {hi:.6g}]"
        lines.append(f"  {n:<{width}} = {est:.6g} ± {se:.2g} {ident.units[i]} "
                     f"(SE {rel}; start {float(ident.initial[i]):.6g}){extra}")
    scale = {"y": (1e3, "mm"), "p_f": (1e-5, "bar"), "p_n": (1e-5, "bar")}
    rms = ", ".join(f"{c} {ident.residual_rms[c] * scale[c][0]:.3g} {scale[c][1]}"
                    for c in ident.channels)
    lines.append(f"  residual RMS: {rms}; reduced chi-square {ident.chi2:.3g}; "
                 f"{ident.n_runs} model runs")
    p = len(ident.names)
    if p > 1:
        pairs = [(abs(float(ident.correlation[i, j])), ident.names[i], ident.names[j],
                  float(ident.correlation[i, j])) for i in range(p) for j in range(i + 1, p)]
        top = max(pairs)
        lines.append(f"  largest correlation: {top[1]} / {top[2]} {top[3]:+.3f}")
    for note in ident.notes:
        lines.append(f"  note: {note}")
    return lines


def _design(args: argparse.Namespace) -> int:
    from ..identify.design import describe as describe_design
    from ..identify.design import design_experiment

    params = params_from_args(args)
    if not 0.0 < args.start < 1.0:
        raise ParameterError(f"--start must be a fraction of the stroke in (0, 1), got "
                             f"{args.start!r}")
    ts = 1e-3 if args.ts is None else args.ts
    _say(args, "designing the experiment and checking it on the nominal model")
    design = design_experiment(params, position=args.start * params.cylinder.stroke, dt=ts,
                               amplitude=args.amplitude, margin=args.margin, f_max=args.f_max)
    design.to_csv(args.out)
    for line in describe_design(design):
        print(line)
    print(f"wrote {args.out}")
    return 0


def _linear_record(args: argparse.Namespace, fit: Any, implied: list[Any], params: Any,
                   digest: str, source: str) -> str:
    """The parameter file of an eq. (8) fit: the set with every implied parameter that the
    fit determines replaced, and the fit's record."""
    import math

    import tomli_w

    from ..identify.linear import to_record
    from ..plant import to_dict, with_overrides
    from ..plant.params import RECORD_TABLE

    chosen = {p.name: p.value for p in implied if math.isfinite(p.value)}
    identified = with_overrides(params, chosen) if chosen else params
    doc: dict[str, Any] = dict(to_dict(identified))
    rec = dict(to_record(fit, implied))
    rec.update({"version": __version__, "command": _command(args), "data": source,
                "data_digest": digest, "base_set": set_name(args),
                "written": sorted(chosen)})
    doc[RECORD_TABLE] = rec
    return ("# The parameter set eq. (8)'s fitted coefficients imply (SI units; every field). "
            "[identification]\n# records the fit; parameter readers skip it.\n"
            + tomli_w.dumps(doc))


def _linear_time(args: argparse.Namespace, names: list[str]) -> int:
    from ..identify import write_axis_toml
    from ..identify.linear import describe as describe_linear
    from ..identify.linear import fit_linear_time, implied_estimates

    bad = [n for n in names if n not in LINEAR_NAMES]
    if bad:
        raise UsageError(f"--fit mixes eq. (8)'s coefficients ({', '.join(LINEAR_NAMES)}) "
                         f"with parameter fields ({', '.join(bad)}); fit one kind at a time")
    if args.plant != "linear":
        raise UsageError(f"--fit {','.join(names)} fits eq. (8) directly: give --plant linear "
                         f"(got --plant {args.plant})")
    params = params_from_args(args)
    m = _read(args, ("u",))
    for note in m.notes:
        _say(args, f"data: {note}")
    rest = max(1, int(m.rest))
    position = float(m.y[:rest].mean())
    u_rest = float(m.u[:rest].mean())
    _say(args, f"fitting eq. (8)'s {', '.join(names)} ({m.t.size} samples at {m.dt:g} s)")
    fit = fit_linear_time(m.t, m.u, m.y, params=params, position=position, dt=m.dt,
                          fit=names, flagged=m.flagged, u_rest=u_rest,
                          delay=params.delay.transport_delay)
    implied = implied_estimates(fit, params, position)
    write_axis_toml(args.out, _linear_record(args, fit, implied, params, m.digest,
                                             str(args.data)))
    for line in describe_linear(fit, implied):
        print(line)
    return 0


def _frequency(args: argparse.Namespace) -> int:
    from ..identify import write_axis_toml
    from ..identify.linear import (
        DEFAULT_FIT,
        fit_linear_frequency,
        implied_estimates,
        read_frequency_response,
    )
    from ..identify.linear import describe as describe_linear

    names = list(DEFAULT_FIT) if args.fit is None else _names(args.fit)
    bad = [n for n in names if n not in LINEAR_NAMES]
    if bad:
        raise UsageError(f"--frequency-response fits eq. (8)'s {', '.join(LINEAR_NAMES)}; "
                         f"got --fit {args.fit}")
    if not 0.0 < args.start < 1.0:
        raise ParameterError(f"--start must be a fraction of the stroke in (0, 1), got "
                             f"{args.start!r}")
    params = params_from_args(args)
    position = args.start * params.cylinder.stroke
    w, h = read_frequency_response(args.frequency_response)
    _say(args, f"fitting eq. (8)'s {', '.join(names)} to {w.size} frequency points")
    fit = fit_linear_frequency(w, h, params=params, position=position, fit=names,
                               delay=params.delay.transport_delay)
    implied = implied_estimates(fit, params, position)
    write_axis_toml(args.out, _linear_record(args, fit, implied, params,
                                             "sha256:" + sha256_file(args.frequency_response),
                                             str(args.frequency_response)))
    for line in describe_linear(fit, implied):
        print(line)
    return 0
