"""Run the whole reproduction: load (or re-tune) gains, simulate each plant, write the outputs.

Each plant's results are cached in ``OUT/.cache`` under a key made of everything that
determines them (parameters, gains, settings, fuzzyservo version), so a second run reuses them
unless ``force`` is set, and an interrupted run resumes from the plants already finished.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import pickle
from collections.abc import Callable, Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from ..analysis.autotune import TunedGains, TuningSetup, stage_as_tuned, tune_controller
from ..analysis.tuning import TuningConstraints
from ..errors import InputError
from ..files import read_gains_toml, write_gains_toml
from ..paper import alpha_system, du_system
from ..plant import to_dict
from ..plots.figures import fig3
from ..registry import controller_kind
from .claims import NO_OVERSHOOT_PCT
from .outputs import write_outputs
from .paper_study import TUNED_DESIGNS, PlantStudy, StudyConfig, run_plant_study

__all__ = ["GAIN_FILES", "PLANTS", "default_gains_dir", "load_tuned", "reproduce", "retune"]

#: Gain files of one plant, ``{plant}-{name}.toml``: the names :data:`TUNED_DESIGNS` uses.
GAIN_FILES: tuple[str, ...] = ("pid", "pid2", "fpi", "stfpi", "fpi-os0", "stfpi-os0")

PLANTS: tuple[str, ...] = ("linear", "nonlinear")


def default_gains_dir() -> Path:
    """The committed tuned gains shipped with the package."""
    return Path(str(resources.files("fuzzyservo") / "data" / "gains"))


def load_tuned(plant: str, gains_dir: Path) -> dict[str, TunedGains]:
    """Read every gain file of ``plant`` from ``gains_dir``."""
    out: dict[str, TunedGains] = {}
    for name in GAIN_FILES:
        path = Path(gains_dir) / f"{plant}-{name}.toml"
        if not path.is_file():
            raise InputError(f"gain file {str(path)!r} is missing; run with --retune to "
                             f"tune it, or point --gains-dir at a folder holding "
                             f"{plant}-{{{','.join(GAIN_FILES)}}}.toml")
        out[name] = read_gains_toml(path)
    return out


def retune(plant: str, params: Any, set_name: str, gains_dir: Path, *,
           progress: Callable[[str], None] | None = None) -> dict[str, TunedGains]:
    """Tune every design of the study on ``plant`` afresh and write the gain files.

    PIDs (1-DOF, 2-DOF) and one self-tuning fuzzy PI are tuned like the paper's PID (ITAE,
    <= 10 % overshoot, no steady-state error); the fuzzy PI and self-tuning fuzzy PI of the
    figures are tuned for the behaviour the paper reports for them (no overshoot, read as
    <= NO_OVERSHOOT_PCT %), by the paper's steps 1-3. Seed 0 throughout.
    """
    gains_dir.mkdir(parents=True, exist_ok=True)
    out: dict[str, TunedGains] = {}
    no_os = TuningConstraints(max_overshoot=NO_OVERSHOOT_PCT)
    jobs: list[tuple[str, TuningSetup]] = [
        ("pid", TuningSetup(controller="pid", plant=plant, param_set=set_name)),
        ("pid2", TuningSetup(controller="pid2", plant=plant, param_set=set_name)),
        ("stfpi", TuningSetup(controller="stfpi", plant=plant, param_set=set_name)),
        ("stfpi-os0", TuningSetup(controller="stfpi", plant=plant, param_set=set_name,
                                  constraints=no_os)),
    ]
    for name, setup in jobs:
        tuned = tune_controller(setup, params)
        out[name] = tuned
        write_gains_toml(gains_dir / f"{plant}-{name}.toml", tuned)
        first = controller_kind(setup.controller).stage_kind
        if first is not None:  # step 1 of the paper's procedure is a design of its own
            stage_name = name.replace(setup.controller, first)
            out[stage_name] = stage_as_tuned(tuned, first)
            write_gains_toml(gains_dir / f"{plant}-{stage_name}.toml", out[stage_name])
        if progress is not None:
            progress(f"{plant}: tuned {name}")
    return out


def _code_digest() -> str:
    """Digest of the package's source, so a code change invalidates cached results."""
    h = hashlib.sha256()
    root = Path(__file__).resolve().parents[1]
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def _cache_key(plant: str, cfg: StudyConfig, gains: Mapping[str, str], version: str) -> str:
    blob = json.dumps({
        "plant": plant, "version": version, "code": _code_digest(),
        "params": to_dict(cfg.params),
        "config": {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg)
                   if f.name != "params"},
        "gains": gains,
    }, sort_keys=True, default=repr)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _notes(plant: str, tuned: Mapping[str, TunedGains]) -> dict[str, str]:
    notes = {}
    for key, (name, _) in TUNED_DESIGNS.items():
        t = tuned[name]
        c = t.setup.constraints
        notes[f"{plant}:{key}"] = (
            f"tuned: {t.setup.objective.upper()}, overshoot <= {c.max_overshoot} %, "
            f"|sse| <= {c.max_steady_state_error} of the step, seed {t.setup.seed}, "
            f"{t.setup.duration:g} s runs, {t.n_evaluations} runs in {t.elapsed:.1f} s")
    return notes


def reproduce(out: Path, cfg: StudyConfig, *, gains_dir: Path | None = None,
              retune_gains: bool = False, force: bool = False,
              plants: Sequence[str] = PLANTS, version: str = "",
              progress: Callable[[str], None] | None = None,
              meta: Mapping[str, str] | None = None) -> dict[str, Path]:
    """Reproduce the paper's study into ``out`` and return the main output paths."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {str(out)!r} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    cache = out / ".cache"
    cache.mkdir(exist_ok=True)
    studies: list[PlantStudy] = []
    notes: dict[str, str] = {}
    for plant in plants:
        if retune_gains:
            tuned = retune(plant, cfg.params, cfg.set_name, out / "gains", progress=progress)
        else:
            tuned = load_tuned(plant, gains_dir or default_gains_dir())
        notes.update(_notes(plant, tuned))
        designs = {name: (t.controller, dict(t.gains)) for name, t in tuned.items()}
        key = _cache_key(plant, cfg, {n: repr(t) for n, t in tuned.items()}, version)
        path = cache / f"{plant}-{key}.pkl"
        if path.is_file() and not force:
            with path.open("rb") as fh:
                study: PlantStudy = pickle.load(fh)
            if progress is not None:
                progress(f"{plant}: reused cached results ({path.name})")
        else:
            limit = tuned[TUNED_DESIGNS["stfpi"][0]].setup.constraints.max_overshoot
            study = run_plant_study(plant, cfg, designs, tick=progress,
                                    stfpi_overshoot_limit=limit)
            tmp = path.with_suffix(".tmp")
            with tmp.open("wb") as fh:
                pickle.dump(study, fh, protocol=pickle.HIGHEST_PROTOCOL)
            tmp.replace(path)
        studies.append(study)
    fig3_paths = fig3(du_system(), alpha_system(), out, formats=("png", "svg"))
    if progress is not None:
        progress("figure 3")
    paths = write_outputs(out, cfg, studies, fig3_paths, notes, meta or {})
    if progress is not None:
        progress("figures, tables and report")
    return paths
