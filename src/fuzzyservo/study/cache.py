"""The study's result cache: data only, stamped, checked on load.

One entry per plant, ``OUT/.cache/{plant}-{key}.npz``: a NumPy ``.npz`` archive of float64
arrays (every trace, the delay sweep) plus one entry ``meta``, a JSON document stored as a
unicode array (metrics, cases, claims, the stamp). It is read with ``allow_pickle=False``,
so nothing in it can run code: a crafted file is at worst wrong data, and then it fails the
checks below. An entry is used only if

- it opens as an ``.npz`` archive and every array has the dtype and shape the record needs;
- its stamp matches: the format version, the fuzzyservo version and the hash of every input
  of the study (``key``: parameters, gains, settings, the package's source).

Anything else (truncated, garbage, foreign, stale) is reported by :func:`load_study` as the
reason it was ignored, and the caller recomputes. The JSON inside uses Python's ``NaN`` token
for undefined metrics: it is internal to the cache, never handed to another program.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from .._io import atomic_write, npz_inflation
from .._typing import FloatArray
from ..sim import SimResult
from .claims import Claim, Value
from .frequency import FrequencyStudy
from .paper_study import ControllerCase, PlantStudy
from .tracking import TrackingStudy

__all__ = ["CACHE_FORMAT", "CacheEntryError", "load_study", "save_study"]

#: Version of the entry layout; an entry of another layout is stale. 2: claims carry their
#: rule, thresholds and data (issue 10); 3: the tracking study (issue 25).
CACHE_FORMAT = 3

_RUN_FIELDS = ("t", "r", "y", "u", "alpha", "x")


class CacheEntryError(Exception):
    """A cache entry that cannot be used; the message says why (internal to this module's
    callers, which recompute)."""


def _put_run(arrays: dict[str, FloatArray], prefix: str, run: SimResult) -> dict[str, Any]:
    for f in _RUN_FIELDS:
        arrays[f"{prefix}/{f}"] = np.ascontiguousarray(getattr(run, f), dtype=np.float64)
    return {"state_names": list(run.state_names), "ts": run.ts, "delay": run.delay}


def save_study(path: str | Path, study: PlantStudy, *, key: str, version: str) -> Path:
    """Write ``study`` to ``path`` atomically, stamped with ``key`` and ``version``."""
    arrays: dict[str, FloatArray] = {}
    runs = {k: _put_run(arrays, f"runs/{k}", r) for k, r in study.runs.items()}
    delayed = _put_run(arrays, "delayed", study.delayed)
    variants = [[name, _put_run(arrays, f"variant/{i}", r)]
                for i, (name, r) in enumerate(study.variant_runs.items())]
    arrays["delays"] = np.asarray(study.delays, dtype=np.float64)
    for k, sw in study.sweep.items():
        for m, v in sw.items():
            arrays[f"sweep/{k}/{m}"] = np.asarray(v, dtype=np.float64)
    meta = {
        "format": CACHE_FORMAT, "key": key, "version": version, "plant": study.plant,
        "cases": [[c.key, c.label, c.kind, c.gains] for c in study.cases],
        "runs": runs, "delayed": delayed, "variants": variants,
        "metrics": study.metrics, "delayed_metrics": study.delayed_metrics,
        "sweep": {k: list(sw) for k, sw in study.sweep.items()},
        "delay_margins": study.delay_margins, "delay_failures": study.delay_failures,
        "variant_metrics": study.variant_metrics,
        "claims": [c.as_dict() for c in study.claims],
        "tracking": None,
    }
    tr = study.tracking
    if tr is not None:
        meta["tracking"] = {
            "keys": list(tr.keys), "sine": tr.sine, "move": tr.move, "load": tr.load,
            "load_force": tr.load_force,
            "cases": [[c.key, c.label, c.kind, c.gains] for c in study.tracking_cases],
            "runs": [[name, _put_run(arrays, f"tracking/{i}", r)]
                     for i, (name, r) in enumerate(tr.runs.items())]}
    fq = study.frequency
    meta["frequency"] = None
    if fq is not None:
        arrays["frequency/f"] = np.asarray(fq.frequency, dtype=np.float64)
        arrays["frequency/fm"] = np.asarray(fq.measured_frequency, dtype=np.float64)
        for i, k in enumerate(fq.keys):
            arrays[f"frequency/{i}/mag"] = np.asarray(fq.magnitude_db[k], dtype=np.float64)
            arrays[f"frequency/{i}/phase"] = np.asarray(fq.phase_deg[k], dtype=np.float64)
            if k in fq.measured_db:
                arrays[f"frequency/{i}/mdb"] = np.asarray(fq.measured_db[k], dtype=np.float64)
                arrays[f"frequency/{i}/mph"] = np.asarray(fq.measured_phase_deg[k],
                                                          dtype=np.float64)
        meta["frequency"] = {"keys": list(fq.keys), "analytic_plant": fq.analytic_plant,
                             "margins": fq.margins, "amplitude": fq.amplitude,
                             "measured": sorted(fq.measured_db)}
    with atomic_write(path, binary=True) as fh:
        entries: dict[str, Any] = {"meta": np.array(json.dumps(meta)), **arrays}
        np.savez(fh, **entries)
    return Path(path)


def _array(z: Any, name: str, shape: tuple[int, ...] | None = None) -> FloatArray:
    if name not in z.files:
        raise CacheEntryError(f"array {name!r} is missing")
    a = z[name]
    if a.dtype != np.float64:
        raise CacheEntryError(f"array {name!r} has dtype {a.dtype}, not float64")
    if shape is not None and a.shape != shape:
        raise CacheEntryError(f"array {name!r} has shape {a.shape}, not {shape}")
    return np.asarray(a)


def _get_run(z: Any, prefix: str, m: dict[str, Any]) -> SimResult:
    t = _array(z, f"{prefix}/t")
    if t.ndim != 1:
        raise CacheEntryError(f"array {prefix}/t is not one-dimensional")
    n = t.shape[0]
    names = tuple(str(s) for s in m["state_names"])
    vec = {f: _array(z, f"{prefix}/{f}", (n,)) for f in ("r", "y", "u", "alpha")}
    x = _array(z, f"{prefix}/x", (n, len(names)))
    return SimResult(t=t, x=x, state_names=names, ts=float(m["ts"]), delay=float(m["delay"]),
                     info={"cached": True}, **vec)


def _floats(d: Any) -> dict[str, float]:
    return {str(k): float(v) for k, v in dict(d).items()}


def _value(v: Any) -> Value:
    """A value of a claim's data as JSON gave it back (number, text, bool, null, list)."""
    if v is None or isinstance(v, bool | str):
        return v
    if isinstance(v, int | float):
        return float(v) if isinstance(v, float) else int(v)
    if isinstance(v, list):
        return [float(x) for x in v]
    raise CacheEntryError(f"a claim's data holds a {type(v).__name__}")


def _claim(c: Any) -> Claim:
    return Claim(
        id=str(c["id"]), claim=str(c["claim"]), verdict=str(c["verdict"]),
        evidence=str(c["evidence"]), plant=str(c["plant"]), rule=str(c["rule"]),
        thresholds=_floats(c["thresholds"]),
        data={str(e): {str(k): _value(v) for k, v in dict(fields).items()}
              for e, fields in dict(c["data"]).items()})


def load_study(path: str | Path, *, key: str, version: str) -> PlantStudy:
    """Read an entry written by :func:`save_study`, checking its stamp and every array.

    Raises
    ------
    CacheEntryError
        The entry cannot be used; the message says why (for a one-line warning).
    """
    try:
        with Path(path).open("rb") as fh:
            magic = fh.read(4)
        if magic != b"PK\x03\x04":
            raise CacheEntryError("not an .npz archive" + (
                " (a pickle, which fuzzyservo never loads)" if magic[:1] == b"\x80" else ""))
        inflated = npz_inflation(Path(path))
        if inflated is not None:
            raise CacheEntryError(inflated)
        with np.load(Path(path), allow_pickle=False) as z:
            if "meta" not in z.files:
                raise CacheEntryError("no 'meta' entry (not a fuzzyservo cache entry)")
            raw = z["meta"]
            if raw.dtype.kind != "U" or raw.shape != ():
                raise CacheEntryError("'meta' is not a JSON text")
            meta = json.loads(str(raw))
            if not isinstance(meta, dict):
                raise CacheEntryError("'meta' is not a JSON object")
            if meta.get("format") != CACHE_FORMAT:
                raise CacheEntryError(f"layout {meta.get('format')!r}, this version reads "
                                      f"{CACHE_FORMAT}")
            if meta.get("version") != version:
                raise CacheEntryError(f"written by fuzzyservo {meta.get('version')!r}, this "
                                      f"is {version!r}")
            if meta.get("key") != key:
                raise CacheEntryError("its inputs differ from this run's (stale or foreign)")
            cases = tuple(ControllerCase(str(k), str(lab), str(kind), _floats(g))
                          for k, lab, kind, g in meta["cases"])
            runs = {str(k): _get_run(z, f"runs/{k}", m) for k, m in meta["runs"].items()}
            delayed = _get_run(z, "delayed", meta["delayed"])
            variant_runs = {str(name): _get_run(z, f"variant/{i}", m)
                            for i, (name, m) in enumerate(meta["variants"])}
            delays = _array(z, "delays")
            sweep = {str(k): {str(m): _array(z, f"sweep/{k}/{m}", delays.shape)
                              for m in ms} for k, ms in meta["sweep"].items()}
            tracking: TrackingStudy | None = None
            t_cases: tuple[ControllerCase, ...] = ()
            tm = meta.get("tracking")
            if tm is not None:
                t_cases = tuple(ControllerCase(str(k), str(lab), str(kind), _floats(g))
                                for k, lab, kind, g in tm["cases"])
                tracking = TrackingStudy(
                    plant=str(meta["plant"]), keys=tuple(str(k) for k in tm["keys"]),
                    sine={str(k): {str(f): _floats(m) for f, m in d.items()}
                          for k, d in tm["sine"].items()},
                    move={str(k): _floats(m) for k, m in tm["move"].items()},
                    load={str(k): _floats(m) for k, m in tm["load"].items()},
                    load_force=float(tm["load_force"]),
                    runs={str(name): _get_run(z, f"tracking/{i}", m)
                          for i, (name, m) in enumerate(tm["runs"])})
            frequency = None
            fm_ = meta.get("frequency")
            if fm_ is not None:
                f = _array(z, "frequency/f")
                fmeas = _array(z, "frequency/fm")
                fkeys = tuple(str(k) for k in fm_["keys"])
                measured = set(fm_["measured"])
                frequency = FrequencyStudy(
                    plant=str(meta["plant"]), analytic_plant=str(fm_["analytic_plant"]),
                    keys=fkeys, frequency=f,
                    magnitude_db={k: _array(z, f"frequency/{i}/mag", f.shape)
                                  for i, k in enumerate(fkeys)},
                    phase_deg={k: _array(z, f"frequency/{i}/phase", f.shape)
                               for i, k in enumerate(fkeys)},
                    margins={str(k): _floats(m) for k, m in fm_["margins"].items()},
                    measured_frequency=fmeas,
                    measured_db={k: _array(z, f"frequency/{i}/mdb", fmeas.shape)
                                 for i, k in enumerate(fkeys) if k in measured},
                    measured_phase_deg={k: _array(z, f"frequency/{i}/mph", fmeas.shape)
                                        for i, k in enumerate(fkeys) if k in measured},
                    amplitude=float(fm_["amplitude"]))
            study = PlantStudy(
                plant=str(meta["plant"]), cases=cases, runs=runs,
                metrics={str(k): _floats(v) for k, v in meta["metrics"].items()},
                delayed=delayed, delayed_metrics=_floats(meta["delayed_metrics"]),
                delays=delays, sweep=sweep, delay_margins=_floats(meta["delay_margins"]),
                delay_failures={str(k): [float(x) for x in v]
                                for k, v in meta["delay_failures"].items()},
                variant_metrics={str(v): {str(k): _floats(m) for k, m in d.items()}
                                 for v, d in meta["variant_metrics"].items()},
                variant_runs=variant_runs,
                claims=[_claim(c) for c in meta["claims"]], tracking=tracking,
                tracking_cases=t_cases, frequency=frequency)
    except CacheEntryError:
        raise
    except FileNotFoundError:
        raise CacheEntryError("missing") from None
    except MemoryError:
        raise CacheEntryError("its arrays do not fit in memory") from None
    except (OSError, EOFError, zipfile.BadZipFile) as exc:
        raise CacheEntryError(f"unreadable ({type(exc).__name__}: truncated or not an "
                              f".npz archive)") from None
    except (ValueError, KeyError, TypeError, AttributeError, IndexError) as exc:
        if "pickle" in str(exc):
            raise CacheEntryError("it holds pickled objects, which fuzzyservo never loads "
                                  "(not an entry it wrote)") from None
        raise CacheEntryError(f"malformed ({type(exc).__name__}: {exc})") from None
    missing = [c.key for c in cases if c.key not in runs]
    if missing:
        raise CacheEntryError(f"no runs for {', '.join(missing)}")
    return study
