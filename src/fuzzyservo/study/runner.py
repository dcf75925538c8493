"""Run the whole reproduction: load (or re-tune) gains, simulate each plant, write the outputs.

Each plant's results are cached in ``OUT/.cache`` (data only: ``fuzzyservo.study.cache``)
under a key made of everything that determines them (parameters, gains, settings, the
package's source and version), so a second run reuses them unless ``force`` is set, and an
interrupted run resumes from the plants already finished. An entry that cannot be used is
reported on one line and recomputed.

The output folder is complete or says it is not (docs/guarantees.md). ``OUT/manifest.json``
is written last and lists the package version, the parameter set with every override in force,
the gains files with their SHA-256, the settings, and the SHA-256 of each output. Before the
first output is touched, the report is replaced by a page saying the folder is incomplete and
the manifest is marked ``"complete": false``; a run interrupted after that point leaves a
folder that :func:`folder_status`, the next ``reproduce`` and the report all call incomplete.
Outputs that the previous manifest listed and this run does not write are removed, so the
folder never mixes two runs. Figures and trace CSVs that the previous, finished run made from
the same inputs, still with the SHA-256 it recorded, are kept instead of made again
(:mod:`fuzzyservo.study.reuse`); once the manifest is written, the cache entries of the
plants just run that other inputs wrote are removed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as _dt
import fcntl
import functools
import glob
import hashlib
import importlib.metadata
import json
import os
import re
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from .._io import (
    confined,
    parse_json,
    read_text,
    refuse_links,
    result_data_of,
    sha256_file,
    strict_json,
    write_text_atomic,
)
from ..analysis.autotune import (
    RESTART_TOLERANCE,
    TunedGains,
    TuningSetup,
    stage_as_tuned,
    tune_controller,
)
from ..analysis.tuning import TuningConstraints
from ..errors import InputError
from ..files import read_gains_toml, write_gains_toml
from ..files.html import Section, write_html
from ..paper import alpha_system, du_system, named_set
from ..plant import to_dict
from ..plots.figures import fig3, fig3_files
from ..registry import controller_kind
from ..run import flat_params, overrides_of
from .cache import CacheEntryError, load_study, save_study
from .claims import NO_OVERSHOOT_PCT
from .figures import figure_files
from .outputs import trace_files, write_outputs
from .paper_study import TUNED_DESIGNS, PlantStudy, StudyConfig, run_plant_study
from .reuse import Digests, reusable
from .tracking import BASELINE_DESIGNS

__all__ = ["GAIN_FILES", "MANIFEST", "PLANTS", "CacheWarning", "default_gains_dir",
           "folder_status", "load_tuned", "reproduce", "retune",
           "study_jobs"]

#: The output folder's manifest, written last.
MANIFEST = "manifest.json"


class CacheWarning(UserWarning):
    """A cache entry was ignored (corrupt, truncated, foreign or stale) and recomputed."""

#: Gain files of one plant, ``{plant}-{name}.toml``: the names :data:`TUNED_DESIGNS` uses.
GAIN_FILES: tuple[str, ...] = ("pid", "pid2", "fpi", "stfpi", "fpi-os0", "stfpi-os0",
                               *(name for name, _ in BASELINE_DESIGNS.values()))

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


def _gain_paths(plant: str, gains_dir: Path) -> list[Path]:
    return [Path(gains_dir) / f"{plant}-{name}.toml" for name in GAIN_FILES]


def study_jobs(plant: str, set_name: str,
               systems: tuple[tuple[str, str, str], ...] = (), *,
               overrides: tuple[tuple[str, float], ...] = ()
               ) -> list[tuple[str, TuningSetup]]:
    """The tunings behind the study's gain files of ``plant``: (file name, setup).

    PIDs (1-DOF, 2-DOF) and one self-tuning fuzzy PI are tuned like the paper's PID (ITAE,
    <= 10 % overshoot, no steady-state error); the self-tuning fuzzy PI of the figures is
    tuned for the behaviour the paper reports for it (no overshoot, read as
    <= NO_OVERSHOOT_PCT %), by the paper's steps 1-3 (step 1 gives the fuzzy PI's file).
    Default tuner settings (converged searches), seed 0. ``systems`` records fuzzy systems
    from files, (role, source, sha256), for the fuzzy designs; ``overrides`` the
    parameters that differ from the set (recorded in each gains file).
    """
    no_os = TuningConstraints(max_overshoot=NO_OVERSHOOT_PCT)

    def job(controller: str, **kw: Any) -> TuningSetup:
        return TuningSetup(controller=controller, plant=plant, param_set=set_name,
                           overrides=overrides, **kw)

    baselines = [(name, job(name, systems=systems if controller_kind(name).systems else ()))
                 for name, _ in BASELINE_DESIGNS.values()]
    return [("pid", job("pid")), ("pid2", job("pid2")),
            ("stfpi", job("stfpi", systems=systems)),
            ("stfpi-os0", job("stfpi", constraints=no_os, systems=systems)), *baselines]


def retune(plant: str, params: Any, set_name: str, gains_dir: Path, *,
           progress: Callable[[str], None] | None = None,
           systems: tuple[tuple[str, Any], ...] = ()) -> dict[str, TunedGains]:
    """Tune every design of the study on ``plant`` afresh (:func:`study_jobs`) and write
    the gain files (the fuzzy PI's is step 1 of the self-tuning run); ``systems``: fuzzy
    systems from files by role (StudyConfig.systems)."""
    gains_dir.mkdir(parents=True, exist_ok=True)
    out: dict[str, TunedGains] = {}
    record = tuple((role, s.source, s.digest) for role, s in systems)
    full = None
    if systems:
        from ..registry import default_systems

        given = dict(systems)
        full = {**default_systems(tuple(r for r in ("du", "alpha") if r not in given)),
                **given}
    jobs = study_jobs(plant, set_name, record, overrides=overrides_of(params, set_name))
    for name, setup in jobs:
        kind = controller_kind(setup.controller)
        use = None if full is None or not kind.systems else {r: full[r] for r in kind.systems}
        tuned = tune_controller(setup, params, systems=use)
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


@functools.cache
def _code_digest() -> str:
    """Digest of the package's source, so a code change invalidates cached results."""
    h = hashlib.sha256()
    root = Path(__file__).resolve().parents[1]
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


#: Formats of Fig. 3's files.
FIG3_FORMATS: tuple[str, ...] = ("png", "svg")


def _figure_key(group: str, version: str, cfg: StudyConfig | None = None,
                gains: Sequence[Path] = ()) -> str:
    """Digest of everything a figure group is drawn from: the package's source and version,
    matplotlib's version, and for a plant's figures the inputs of its study (parameters,
    settings, the gain files' contents), as :func:`_cache_key` has them."""
    blob: dict[str, Any] = {"group": group, "version": version, "code": _code_digest(),
                            "matplotlib": _matplotlib_version()}
    if cfg is not None:
        blob.update(params=to_dict(cfg.params), config=_settings(cfg),
                    gains={p.name: sha256_file(p) for p in gains})
    text = json.dumps(blob, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _matplotlib_version() -> str:
    """matplotlib's version, read from its metadata (importing it would cost a second)."""
    try:
        return importlib.metadata.version("matplotlib")
    except importlib.metadata.PackageNotFoundError:
        return "?"


def _settings(cfg: StudyConfig) -> dict[str, Any]:
    out = {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg)
           if f.name not in ("params", "systems", "no_rule_value")}
    out["tracking"] = (dataclasses.asdict(cfg.tracking) if cfg.tracking is not None
                       else None)
    out["frequency"] = (dataclasses.asdict(cfg.frequency) if cfg.frequency is not None
                        else None)
    if cfg.systems:  # a system by its values' digest (absent: the paper's, as before)
        out["systems"] = {role: s.digest for role, s in cfg.systems}
        out["no_rule_value"] = cfg.no_rule_value
    return out


def _cache_key(plant: str, cfg: StudyConfig, gains: Mapping[str, str], version: str) -> str:
    blob = json.dumps({
        "plant": plant, "version": version, "code": _code_digest(),
        "params": to_dict(cfg.params), "config": _settings(cfg), "gains": gains,
    }, sort_keys=True, default=repr)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _notes(plant: str, tuned: Mapping[str, TunedGains]) -> dict[str, str]:
    notes = {}
    for key, (name, _) in TUNED_DESIGNS.items():
        t = tuned[name]
        c = t.setup.constraints
        search = (f"{t.generations} generations, "
                  + ("converged" if t.converged else "NOT converged (generation limit)")
                  + f"; {t.setup.restarts} searches per stage "
                  + (f"agree within {100 * t.restart_spread:.2g} %"
                     if t.restart_spread <= RESTART_TOLERANCE else
                     f"DISAGREE by {100 * t.restart_spread:.3g} % (several optima: the best "
                     f"is kept, it may not be the global one)"))
        bound = (", on a bound: " + ", ".join(f"{g} ({side})" for g, side in
                                               t.at_bounds.items())) if t.at_bounds else ""
        notes[f"{plant}:{key}"] = (
            f"tuned: {t.setup.objective.upper()}, overshoot <= {c.max_overshoot} %, "
            f"|sse| <= {c.max_steady_state_error} of the step, seed {t.setup.seed}, "
            f"{t.setup.duration:g} s runs; {search}{bound}; {t.n_evaluations} runs")
    return notes


def _read_manifest(out: Path) -> dict[str, Any] | None:
    try:
        text = read_text(out / MANIFEST, "study manifest")  # regular, bounded
        doc = parse_json(text, f"{str(out / MANIFEST)!r}")
    except (OSError, ValueError):  # InputError of the nesting check included: unreadable
        return None
    return doc if isinstance(doc, dict) else None


def _listed(doc: Mapping[str, Any] | None) -> list[str]:
    outputs = doc.get("outputs") if doc else None
    if not isinstance(outputs, dict):
        return []
    return [str(k) for k in outputs]


def folder_status(out: str | Path) -> tuple[str, list[str]]:
    """Whether ``out`` holds a complete ``reproduce`` output set.

    Returns ``(status, problems)``: status ``"complete"`` (the manifest says so and every
    output it lists has its recorded SHA-256), ``"incomplete"`` (``problems`` says why) or
    ``"empty"`` (no manifest and no report).
    """
    return _folder_status(Path(out), sha256_file)


def _folder_status(out: Path, digest: Callable[[Path], str]) -> tuple[str, list[str]]:
    doc = _read_manifest(out)
    if doc is None:
        if (out / MANIFEST).exists():
            return "incomplete", [f"{MANIFEST} is unreadable"]
        if (out / "report.html").exists():
            return "incomplete", [f"no {MANIFEST}: the run that wrote this folder did not "
                                  f"finish"]
        return "empty", []
    if doc.get("complete") is not True:
        return "incomplete", [f"{MANIFEST} says a run started on {doc.get('started', '?')} "
                              f"did not finish"]
    problems = []
    outputs = doc.get("outputs")
    for rel, recorded in (outputs.items() if isinstance(outputs, dict) else ()):
        p = out / rel
        if not p.is_file():
            problems.append(f"{rel} is missing")
        elif digest(p) != recorded:
            problems.append(f"{rel} differs from the manifest")
    return ("complete" if not problems else "incomplete"), problems


def _clean_temporaries(out: Path) -> None:
    """Remove temporary files a killed run left (``.NAME.XXXXXXXX.tmp``, never a target)."""
    for folder in (out, out / "traces", out / "gains", out / ".cache"):
        if folder.is_dir():
            for p in folder.glob(".*.tmp"):
                p.unlink(missing_ok=True)


def _mark_incomplete(out: Path, previous: Sequence[str], started: str, version: str) -> None:
    """Say, before the first output is touched, that the folder is being rewritten: the
    report first (a reader sees it), then the manifest (the next run sees it)."""
    write_html(out / "report.html", "fuzzyservo: reproduction INCOMPLETE", [Section(
        "This folder is incomplete",
        paragraphs=[f"A fuzzyservo reproduce run started on {started} was writing this "
                    "folder and has not finished (interrupted, or still running). Its files "
                    "may mix two runs: do not use them. Run fuzzyservo reproduce again "
                    "with the same options to complete it."])])
    write_text_atomic(out / MANIFEST, strict_json({
        "fuzzyservo": version, "complete": False, "started": started,
        # every output of the previous run: the next run removes those it does not rewrite
        "outputs": {rel: None for rel in previous}}, indent=2) + "\n")


#: ``extra(out) -> (main paths by name, files written)`` of :func:`reproduce`.
Extra = Callable[[Path], tuple[dict[str, Path], list[Path]]]


def reproduce(out: Path, cfg: StudyConfig, *, gains_dir: Path | None = None,
              retune_gains: bool = False, force: bool = False,
              plants: Sequence[str] = PLANTS, version: str = "",
              progress: Callable[[str], None] | None = None,
              meta: Mapping[str, str] | None = None,
              warn: Callable[[str], None] | None = None,
              extra: Extra | None = None) -> dict[str, Path]:
    """Reproduce the paper's study into ``out`` and return the main output paths.

    ``warn(message)`` receives one-line warnings (a cache entry ignored, a folder left
    incomplete by an earlier run); by default they are issued as :class:`CacheWarning`.
    ``extra(out)`` writes further outputs once the study's are written and returns
    ``(main paths by name, every file it wrote or kept)``: they join the manifest like the
    study's own (the command line's C8 sweeps, :mod:`fuzzyservo.study.c8`).
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {str(out)!r} exists and is not a directory")
    if gains_dir is not None and not retune_gains and not Path(gains_dir).is_dir():
        raise InputError(f"--gains-dir {str(gains_dir)!r} is not a folder")
    why = result_data_of(out / MANIFEST, kinds=("sweep",))  # a sweep's folder, or in one
    if why is not None:
        raise InputError(f"--out {str(out)!r}: writing the study there {why}")
    out.mkdir(parents=True, exist_ok=True)
    refuse_links(out, what="output folder", entries=[".lock"])
    with _folder_lock(out):
        refuse_links(out, what="output folder")  # under the lock: nothing followed below
        with confined(out):
            return _reproduce(out, cfg, gains_dir=gains_dir, retune_gains=retune_gains,
                              force=force, plants=plants, version=version,
                              progress=progress, meta=meta, warn=warn, extra=extra)


@contextlib.contextmanager
def _folder_lock(out: Path) -> Iterator[None]:
    """Hold ``OUT/.lock`` for the run: a second run on the same folder would delete the
    first one's temporary files and interleave its outputs, so it is refused."""
    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
    try:
        fd = os.open(out / ".lock", flags, 0o666)  # never through a link: it is written
    except OSError as exc:
        raise InputError(f"cannot lock {str(out / '.lock')!r}: "
                         f"{exc.strerror or exc}") from None
    with os.fdopen(fd, "a+") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            who = fh.read().strip() or "?"
            raise InputError(f"another fuzzyservo reproduce (pid {who}) is writing "
                             f"{str(out)!r}; wait for it to finish or give another "
                             f"--out") from None
        fh.seek(0)
        fh.truncate()
        fh.write(f"{os.getpid()}\n")
        fh.flush()
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _reproduce(out: Path, cfg: StudyConfig, *, gains_dir: Path | None, retune_gains: bool,
               force: bool, plants: Sequence[str], version: str,
               progress: Callable[[str], None] | None, meta: Mapping[str, str] | None,
               warn: Callable[[str], None] | None, extra: Extra | None) -> dict[str, Path]:
    def say(message: str) -> None:
        if warn is not None:
            warn(message)
        else:
            warnings.warn(message, CacheWarning, stacklevel=4)

    _clean_temporaries(out)
    digests = Digests()  # each file hashed once: the check below, the reuse, the manifest
    status, problems = _folder_status(out, digests)
    if status == "incomplete":
        say(f"{str(out)!r} is incomplete ({problems[0]}); writing it again")
    previous = _listed(_read_manifest(out))
    started = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
    marked = False

    def begin_writing() -> None:
        nonlocal marked
        if not marked:
            _mark_incomplete(out, previous, started, version)
            marked = True

    cache = out / ".cache"
    cache.mkdir(exist_ok=True)
    studies: list[PlantStudy] = []
    notes: dict[str, str] = {}
    gains_used: dict[str, Path] = {}
    keys: dict[str, str] = {}  # each plant's cache key: the inputs of its study
    for plant in plants:
        if retune_gains:
            begin_writing()
            tuned = retune(plant, cfg.params, cfg.set_name, out / "gains", progress=progress,
                           systems=cfg.systems)
            gains_used.update({str(p.relative_to(out)): p
                               for p in _gain_paths(plant, out / "gains")})
        else:
            src = gains_dir or default_gains_dir()
            tuned = load_tuned(plant, src)
            gains_used.update({str(p): p for p in _gain_paths(plant, src)})
        notes.update(_notes(plant, tuned))
        designs = {name: (t.controller, dict(t.gains)) for name, t in tuned.items()}
        key = keys[plant] = _cache_key(plant, cfg, {n: repr(t) for n, t in tuned.items()},
                                       version)
        path = cache / f"{plant}-{key}.npz"
        study: PlantStudy | None = None
        if path.is_file() and not force:
            try:
                study = load_study(path, key=key, version=version)
            except CacheEntryError as exc:
                say(f"ignoring cache entry {str(path)!r}: "
                    f"{' '.join(str(exc).split())[:160]}; recomputing")
            else:
                if progress is not None:
                    progress(f"{plant}: reused cached results ({path.name})")
        if study is None:
            limit = tuned[TUNED_DESIGNS["stfpi"][0]].setup.constraints.max_overshoot
            study = run_plant_study(plant, cfg, designs, tick=progress,
                                    stfpi_overshoot_limit=limit)
            save_study(path, study, key=key, version=version)
        studies.append(study)

    overrides = dict(overrides_of(cfg.params, cfg.set_name))
    shown = dict(meta or {})
    shown["parameter set"] = cfg.set_name + (
        " with " + ", ".join(f"{k} = {v!r}" for k, v in overrides.items())
        if overrides else " (no override)")
    base = flat_params(named_set(cfg.set_name))
    notices = [f"Parameter set '{cfg.set_name}'" + (
        ", with these overrides in force (SI units): "
        + "; ".join(f"{k} = {v!r} (the set has {base[k]!r})" for k, v in overrides.items())
        if overrides else ", with no override.")]

    # figures and traces the previous run made from the same inputs are kept, not made
    # again: its manifest is read before begin_writing() replaces it (with --retune it
    # already has, and everything is written)
    before = _read_manifest(out)
    begin_writing()
    written: list[Path] = []
    gains_src = out / "gains" if retune_gains else Path(gains_dir or default_gains_dir())
    figure_keys = {"fig3": _figure_key("fig3", version)}
    figure_keys.update({plant: _figure_key(plant, version, cfg, _gain_paths(plant, gains_src))
                        for plant in plants})
    figure_groups = {"fig3": fig3_files(out, FIG3_FORMATS)}
    figure_groups.update({plant: figure_files(plant, out, tracking=cfg.tracking is not None,
                                              frequency=cfg.frequency is not None)
                          for plant in plants})
    kept = {g for g, files in figure_groups.items()
            if not force and reusable(before, out, g, figure_keys[g], files, digest=digests)}
    # a plant's traces are a function of its study, which its cache key names
    trace_groups = {s.plant: trace_files(s, out) for s in studies}
    kept_traces = {plant for plant, files in trace_groups.items()
                   if not force and reusable(before, out, plant, keys[plant], files,
                                             section="traces", digest=digests)}
    if "fig3" in kept:
        fig3_paths = figure_groups["fig3"]
    else:
        fig3_paths = fig3(du_system(), alpha_system(), out, formats=FIG3_FORMATS)
    if progress is not None:
        progress("figure 3" + (" (kept)" if "fig3" in kept else ""))
    paths = write_outputs(out, cfg, studies, fig3_paths, notes, shown, written=written,
                          notices=notices, figures_reused=kept,
                          traces_reused=kept_traces)
    if progress is not None:
        progress("figures, tables and report")
    if extra is not None:
        more, files = extra(out)
        paths.update(more)
        written.extend(files)
    rels = [p.relative_to(out).as_posix() for p in written]
    if retune_gains:
        rels.extend(rel for rel in gains_used if rel not in rels)
    for rel in previous:  # outputs of the previous run that this one did not rewrite
        if rel not in rels and rel != MANIFEST:
            p = out / rel
            if p.is_file() and p.resolve().is_relative_to(out.resolve()):
                p.unlink()
    manifest = {
        "fuzzyservo": version, "complete": True, "started": started,
        "finished": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC"),
        "parameter_set": cfg.set_name, "overrides": overrides,
        "parameters": to_dict(cfg.params), "plants": list(plants),
        "settings": _settings(cfg),
        "gains": {name: {"sha256": sha256_file(p)} for name, p in gains_used.items()},
        "outputs": {rel: digests(out / rel) for rel in rels},
        # the inputs each group of figures and traces was made from (a later run keeps the
        # group if they are equal and its files unchanged)
        "figures": {g: {"key": figure_keys[g],
                        "files": [p.relative_to(out).as_posix() for p in files]}
                    for g, files in figure_groups.items()},
        "traces": {plant: {"key": keys[plant],
                           "files": [p.relative_to(out).as_posix() for p in files]}
                   for plant, files in trace_groups.items()},
    }
    paths["manifest"] = write_text_atomic(out / MANIFEST, strict_json(manifest, indent=2)
                                          + "\n")
    _prune_cache(cache, keys)
    return paths


def _prune_cache(cache: Path, keys: Mapping[str, str]) -> None:
    """Remove the entries of ``cache`` of the plants just run, ``{plant}-{key}.npz``, whose
    key is not the plant's current one (stale: written from other inputs or by other code).
    Entries of other plants, and files not named like entries, are left alone. Called after
    the run's manifest is written: an interrupted or failing run removes nothing."""
    for plant, key in keys.items():
        entry = re.compile(re.escape(plant) + r"-[0-9a-f]{16}\.npz")
        for p in cache.glob(f"{glob.escape(plant)}-*.npz"):
            if entry.fullmatch(p.name) and p.name != f"{plant}-{key}.npz":
                with contextlib.suppress(OSError):  # a cache, not an output: best effort
                    p.unlink()
