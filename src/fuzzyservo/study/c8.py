"""Claim C8 at scale in ``fuzzyservo reproduce``: the shipped C8 sweeps
(``data/sweeps/c8-{plant}.toml``), reduced to their first draws, and their reports.

The study's use of the sweeps (:mod:`fuzzyservo.sweep`, which knows nothing of the study): the
paper's claim, its spec files and its sample sizes are the study's.

A draw depends on its grid cell and its number there only (:mod:`fuzzyservo.sweep.sampling`),
so the reduced sweep runs the very plants the full one starts each noise level with. A later
run with the same inputs finds the sweep complete and only writes the report again; a folder
holding another sweep (other gains, another reduction) is replaced, since it is reproduce's own
output.
"""

from __future__ import annotations

import hashlib
import shutil
from collections.abc import Callable, Sequence
from dataclasses import replace
from importlib import resources
from pathlib import Path

from .._io import sha256_file, write_text_atomic
from ..errors import OutputError
from ..sweep.dataset import read_manifest
from ..sweep.run import run_sweep
from ..sweep.spec import SweepSpec, load_spec

__all__ = ["C8_SAMPLES", "c8_spec", "run_c8"]

#: Draws per noise level of each plant's C8 sweep that ``fuzzyservo reproduce`` runs by
#: default (the first draws of the full sweep's).
C8_SAMPLES: dict[str, int] = {"linear": 100, "nonlinear": 40}


def c8_spec(plant: str, samples: int | None = None) -> SweepSpec:
    """The shipped C8 sweep of ``plant``, reduced to the first ``samples`` draws of each grid
    cell (None: all)."""
    path = Path(str(resources.files("fuzzyservo") / "data" / "sweeps" / f"c8-{plant}.toml"))
    spec = load_spec(path)
    if samples is not None:
        spec = replace(spec, samples=int(samples), chunk=min(spec.chunk, 100),
                       name=f"{spec.name}, first {samples} draws per noise level")
    return spec


def _report_key(manifest: str) -> str:
    """What a sweep's report is made from: the sweep's manifest (spec, finished chunks and
    their SHA-256), the report's code and the package version."""
    from .. import __version__

    h = hashlib.sha256(manifest.encode())
    for mod in ("sweep/report.py", "plots/sweep_figures.py", "files/html.py",
                "analysis/outcome.py"):
        h.update((resources.files("fuzzyservo") / mod).read_bytes())
    h.update(__version__.encode())
    return h.hexdigest()


def _sweep_leftovers(folder: Path) -> bool:
    """Whether ``folder`` (no manifest) holds only what a sweep of :func:`run_c8` leaves: its
    lock, its report stamp, chunk files and temporary files. A reproduce run without the
    sweeps removes the files the last run recorded (manifest, stamp, chunks) but not the
    lock, and an interruption of that removal can leave chunks without their manifest; both
    are reproduce's own and start the sweep afresh. Anything else is someone's and is kept."""
    from ..sweep.dataset import finished_files

    ours = {folder / ".lock", folder / "report.key", *finished_files(folder).values()}
    for p in folder.rglob("*"):
        if p.is_dir():
            if p != folder / "chunks":
                return False
        elif p not in ours and not (p.name.startswith(".") and p.name.endswith(".tmp")
                                    and p.parent in (folder, folder / "chunks")):
            return False
    return True


def run_c8(out: Path, plants: Sequence[str], samples: int | None = None, *,
           progress: bool | None = None,
           tick: Callable[[str], None] | None = None) -> tuple[dict[str, Path], list[Path]]:
    """Run the reduced C8 sweeps into ``out/c8-sweep-{plant}`` and write
    ``out/c8-sweep-{plant}.html``; return the report paths by name and every file of the
    sweeps (for the study's manifest)."""
    from ..sweep.dataset import finished_files
    from ..sweep.report import write_report

    paths: dict[str, Path] = {}
    files: list[Path] = []
    for plant in plants:
        spec = c8_spec(plant, C8_SAMPLES.get(plant, 40) if samples is None else samples)
        folder = Path(out) / f"c8-sweep-{plant}"
        resume = False
        if (folder / "manifest.json").is_file():
            if read_manifest(folder).digest == spec.digest:
                resume = True
            else:
                shutil.rmtree(folder)
        elif folder.is_dir() and _sweep_leftovers(folder):
            shutil.rmtree(folder)  # emptied by a run without the sweeps: start it afresh
        elif folder.exists():
            raise OutputError(f"{str(folder)!r} exists and is not a sweep folder; move it "
                              f"away (fuzzyservo reproduce writes its C8 sweep there)")
        man = run_sweep(spec, folder, resume=resume, progress=progress)
        report = Path(out) / f"c8-sweep-{plant}.html"
        key = _report_key(man.to_json())
        stamp = folder / "report.key"
        if not (report.is_file() and stamp.is_file()
                and stamp.read_text(encoding="utf-8") == f"{key} {sha256_file(report)}\n"):
            write_report(folder, report)  # a warm run keeps an identical report
            write_text_atomic(stamp, f"{key} {sha256_file(report)}\n")
        files.append(stamp)
        paths[f"C8 sweep, {plant} plant"] = report
        files += [report, folder / "manifest.json",
                  *(p for _, p in sorted(finished_files(folder).items()))]
        if tick is not None:
            tick(f"{plant}: C8 sweep")
    return paths, files
