"""``fuzzyservo sweep`` and ``fuzzyservo sweep-report``: robustness sweeps at scale.

``fuzzyservo sweep SPEC.toml --out DIR [--workers N | --scheduler ADDRESS] [--resume]`` runs
every controller of the spec on every point (grid cells x random draws of plant parameters,
delay, reference amplitude, load force, sensor noise) into a Parquet dataset in ``DIR``, chunk
by chunk; ``fuzzyservo sweep --example`` prints a small complete spec to start from.
``fuzzyservo sweep-report DIR --out report.html`` writes the offline report of a sweep
(docs/sweep.md).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from importlib import resources
from pathlib import Path
from typing import Any

from ..errors import InputError
from . import HELP

__all__ = ["example_spec", "register"]


def example_spec() -> str:
    """The text of the example spec (``fuzzyservo sweep --example``)."""
    return (resources.files("fuzzyservo") / "data" / "sweeps" / "example.toml").read_text(
        encoding="utf-8")


def register(subparsers: Any) -> None:
    """Add the ``sweep`` and ``sweep-report`` subcommands."""
    p = subparsers.add_parser(
        "sweep", help=HELP["sweep"],
        description=(
            "Run every controller of SPEC.toml on every point of its variations (grids and "
            "random draws of any plant parameter, the delay, the reference amplitude, the load "
            "force and the sensor noise) and write each run's parameters, step metrics and "
            "outcome to a Parquet dataset in --out, chunk by chunk. Locally on every core by "
            "default; on a Dask cluster with --workers N or --scheduler ADDRESS. Ctrl-C or a "
            "kill loses at most the chunks in flight; --resume continues. Results depend only "
            "on the spec (docs/sweep.md)."))
    p.add_argument("spec", nargs="?", type=Path, metavar="SPEC.toml",
                   help="the sweep spec (fuzzyservo sweep --example prints one)")
    p.add_argument("--example", action="store_true",
                   help="print a small, complete spec that uses every kind of variation")
    p.add_argument("--out", type=Path, metavar="DIR",
                   help="folder of the dataset: new or empty (or, with --resume, the sweep's)")
    p.add_argument("--resume", action="store_true",
                   help="continue the sweep in --out: skip its finished chunks")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--processes", type=int, default=None, metavar="N",
                   help="without Dask: N local worker processes (default one per core; 1 runs "
                        "in this process on numba's threads)")
    g.add_argument("--workers", type=int, default=None, metavar="N",
                   help="run on a local Dask cluster of N single-threaded worker processes")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on the Dask scheduler at ADDRESS (e.g. tcp://10.0.0.5:8786); "
                        "the workers need fuzzyservo and the spec's files")
    p.add_argument("--no-progress", dest="progress", action="store_false", default=None,
                   help="no progress bar (default: shown when standard error is a terminal)")
    p.set_defaults(handler=_run_sweep)

    r = subparsers.add_parser(
        "sweep-report", help=HELP["sweep-report"],
        description=("Write the report of a sweep folder: per controller the distributions of "
                     "the metrics, the failure rates, robustness maps over two varied "
                     "quantities and the worst runs, each with the fuzzyservo simulate command "
                     "that replays it (figures embedded; docs/sweep.md)."))
    r.add_argument("folder", type=Path, metavar="DIR", help="the sweep's folder")
    r.add_argument("--out", type=Path, required=True, metavar="REPORT.html",
                   help="the report to write (replaced atomically)")
    r.add_argument("--worst", type=int, default=10, metavar="N",
                   help="worst runs listed per controller (default 10)")
    r.set_defaults(handler=_run_report)


def _run_sweep(args: argparse.Namespace) -> int:
    if args.example:
        if args.spec is not None or args.out is not None or args.resume:
            raise InputError("--example prints the example spec; give it alone")
        sys.stdout.write(example_spec())
        return 0
    if args.spec is None or args.out is None:
        raise InputError("sweep needs SPEC.toml and --out DIR (fuzzyservo sweep --example "
                         "prints a spec to start from)")
    from .._io import read_text
    from ..sweep import load_spec, read_table, run_sweep

    spec = load_spec(args.spec)
    text = read_text(args.spec, "sweep spec")

    def banner(man: Any, todo: int) -> None:
        print(f"sweep {spec.name!r}: {spec.n_points} points x {len(spec.controllers)} "
              f"controllers = {spec.n_runs} runs in {spec.n_chunks} chunks -> {args.out}"
              + (f" ({todo} to run)" if todo < spec.n_chunks else ""), file=sys.stderr)

    t0 = time.perf_counter()
    try:
        run_sweep(spec, args.out, resume=args.resume, processes=args.processes,
                        workers=args.workers, scheduler=args.scheduler,
                        progress=args.progress, spec_text=text, on_start=banner)
    except KeyboardInterrupt:
        print(f"fuzzyservo: note: finished chunks are kept in {str(args.out)!r}; continue with "
              f"fuzzyservo sweep {args.spec} --out {args.out} --resume", file=sys.stderr)
        raise
    elapsed = time.perf_counter() - t0
    table = read_table(args.out, columns=["controller", "outcome", "point"])
    groups = table.group_by(["controller", "outcome"]).aggregate([("point", "count")])
    counts: dict[str, Counter[str]] = {}
    for ctl, outcome, n in zip(*(groups.column(k).to_pylist()
                                 for k in ("controller", "outcome", "point_count")),
                               strict=True):
        counts.setdefault(str(ctl), Counter())[str(outcome)] += int(n)
    print(f"{table.num_rows} runs in {args.out} ({elapsed:.1f} s this session)")
    for e in spec.controllers:
        c = counts.get(e.label, Counter())
        total = sum(c.values()) or 1
        shown = ", ".join(f"{k} {100.0 * v / total:.1f} %" for k, v in c.most_common())
        print(f"  {e.label}: {shown}")
    return 0


def _run_report(args: argparse.Namespace) -> int:
    from .._io import check_output_path
    from ..sweep.report import write_report

    if args.worst < 1:
        raise InputError(f"--worst must be a positive integer, got {args.worst}")
    check_output_path(args.out)
    write_report(args.folder, args.out, worst=args.worst)
    print(f"wrote {args.out}")
    return 0
