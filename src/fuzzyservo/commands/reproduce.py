"""``fuzzyservo reproduce [--out results/paper]``: the paper's study, on both plants.

Loads the committed tuned gains (``--retune`` tunes afresh), simulates Figs. 4-8, the delay
sweep and the changed plants on the linear and the nonlinear plant, tests the paper's claims
and writes PNG and SVG figures, trace CSVs, ``metrics.csv``, ``claims.json`` and an offline
``report.html``. A second run reuses the cached results unless ``--force``.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import sys
import time
from pathlib import Path
from typing import Any

from tqdm import tqdm

from .. import __version__
from ..errors import InputError, OutputError, ParameterError
from ..study.frequency import FrequencyConfig
from ..study.paper_study import TRACKING_KEYS, StudyConfig
from ..study.runner import GAIN_FILES, PLANTS, reproduce
from ..study.tracking import TrackingConfig
from . import HELP
from ._plantargs import add_plant_arguments, params_from_args, params_given, set_name
from ._runargs import add_system_arguments, systems_from_args, systems_record

__all__ = ["MIN_DURATION", "register", "run"]

#: Shortest run the study accepts [s]: the tuned controllers settle in about 2-3 s, and C4
#: looks at the last quarter of the run, so shorter runs would judge unsettled responses.
MIN_DURATION = 5.0


def register(subparsers: Any) -> None:
    """Add the ``reproduce`` subcommand to ``subparsers`` and set its handler."""
    parser = subparsers.add_parser(
        "reproduce",
        help=HELP["reproduce"],
        description="Reproduce Aly et al. (2012) on the linear and nonlinear plant: figures "
                    "(PNG, SVG), traces (CSV), metrics.csv, claims.json and report.html.",
    )
    parser.add_argument("--out", type=Path, default=Path("results/paper"), metavar="DIR",
                        help="output directory (default: results/paper)")
    parser.add_argument("--retune", action="store_true",
                        help="tune every controller afresh instead of loading the committed "
                             "gains (written to OUT/gains)")
    parser.add_argument("--gains-dir", type=Path, default=None, metavar="DIR",
                        help="folder of gain files {plant}-{name}.toml (default: the "
                             "committed ones)")
    parser.add_argument("--force", action="store_true",
                        help="recompute even what is cached in OUT/.cache")
    parser.add_argument("--plant", choices=(*PLANTS, "both"), default="both",
                        help=f"which plant(s) of the study to run: {', '.join(PLANTS)} or "
                             f"both (default both)")
    parser.add_argument("--duration", type=float, default=20.0, metavar="S",
                        help="length of each run [s], at least 5 (default 20)")
    parser.add_argument("--c8-samples", type=int, default=None, metavar="N",
                        help="draws per noise level of each plant's C8 sweep (claim C8 at "
                             "scale, docs/sweep.md; default 100 linear, 40 nonlinear; the "
                             "full sweeps have 3334; 0: none)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_system_arguments(parser)
    add_plant_arguments(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo reproduce``."""
    if not args.duration >= MIN_DURATION:
        raise ParameterError(
            f"--duration must be at least {MIN_DURATION:g} s so that the claims can be judged "
            f"on settled responses, got {args.duration!r}")
    params = params_from_args(args)
    systems = systems_from_args(args, None)  # for every fuzzy controller of the study
    record = systems_record(systems)
    from_files = tuple((role, systems[role]) for role, _, _ in record) if systems else ()
    cfg = StudyConfig(params=params, set_name=set_name(args), duration=args.duration,
                      systems=from_files,
                      no_rule_value=getattr(args, "no_rule_value", None) if from_files else None,
                      tracking=TrackingConfig(), frequency=FrequencyConfig())
    plants = PLANTS if args.plant == "both" else (args.plant,)
    if args.c8_samples is not None and not 0 <= args.c8_samples <= 100_000:
        raise ParameterError(f"--c8-samples must be an integer in [0, 100000], got "
                             f"{args.c8_samples}")
    # the shipped C8 sweeps run the committed gains on the paper's set: with other gains, set
    # or systems they would not be this study's controllers, so they are left out (a note)
    custom = bool(args.retune or args.gains_dir is not None or params_given(args) or from_files)
    sweeps = args.c8_samples != 0 and not custom
    # stages per plant: nominal runs, delay sweep, changed plants, two per design of the
    # tracking study (its runs, its frequency response); the tunings with --retune; C8's
    # sweep; then figure 3 and the report
    n_track = 2 * len(TRACKING_KEYS)
    total = len(plants) * (3 + n_track + (len(GAIN_FILES) - 2 if args.retune else 0)
                           + int(sweeps)) + 2
    quiet = args.quiet
    bar = tqdm(total=total, desc="reproduce", unit="stage", file=sys.stderr,
               disable=quiet, mininterval=0.0 if os.environ.get("CI") else 0.1)

    def progress(stage: str) -> None:
        bar.set_postfix_str(stage, refresh=False)
        bar.update(3 + n_track if "reused" in stage else 1)

    meta = {
        "fuzzyservo": __version__,
        "generated": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "gains": "re-tuned in this run" if args.retune else
                 str(args.gains_dir or "committed tuned gains (fuzzyservo/data/gains)"),
        "plants": ", ".join(plants),
    }
    if sweeps:
        meta["claim C8 at scale"] = ", ".join(f"c8-sweep-{p}.html" for p in plants) + (
            " (the first points of the shipped C8 sweeps: the paper's controllers, the tuned "
            "ones and the robust design on plants drawn from the whole spread; "
            "docs/sweep.md)")
    if from_files:
        meta["fuzzy systems"] = "; ".join(
            f"{role}: {s.source} (sha256 {s.digest[:12]})" for role, s in from_files)

    def warn(message: str) -> None:
        tqdm.write(f"fuzzyservo: warning: {message}", file=sys.stderr)

    if from_files and not args.retune:
        warn("the gains (" + ("committed" if args.gains_dir is None else str(args.gains_dir))
             + ") were tuned with the paper's fuzzy systems, this study runs "
             + ", ".join(f"{role} system {s.source}" for role, s in from_files)
             + ": add --retune to tune for them")
    if custom and args.c8_samples != 0:
        warn("the C8 sweeps (docs/sweep.md) run the committed gains on the paper's set and "
             "systems; with --retune, --gains-dir, other parameters or systems they are left "
             "out (fuzzyservo sweep runs them on any spec)")
    t0 = time.perf_counter()
    try:
        extra = None
        if sweeps:  # claim C8 at scale: the shipped sweeps, reduced (docs/sweep.md)
            from ..study.c8 import run_c8

            def extra(out: Path) -> tuple[dict[str, Path], list[Path]]:
                return run_c8(out, plants, args.c8_samples, progress=False, tick=progress)

        paths = reproduce(args.out, cfg, gains_dir=args.gains_dir, retune_gains=args.retune,
                          force=args.force, plants=plants, version=__version__,
                          progress=progress, meta=meta, warn=warn, extra=extra)
    except OutputError:
        raise
    except OSError as exc:
        raise InputError(f"cannot write into {str(args.out)!r}: "
                         f"{exc.strerror or exc}") from exc
    finally:
        bar.close()
    print(f"reproduced in {time.perf_counter() - t0:.1f} s")
    for name, path in paths.items():
        print(f"{name}: {path}")
    return 0
