"""A sweep's folder: a Parquet dataset written chunk by chunk, each chunk atomically, and a
manifest.

Layout of ``DIR``::

    manifest.json        the spec (canonical), its digest, sizes, columns, finished chunks
    spec.toml            the spec file as given (provenance)
    chunks/chunk-000000.parquet, chunk-000001.parquet, ...

A chunk file exists only complete: it is written to a temporary file in ``chunks/``, fsynced
and renamed (:func:`fuzzyservo._io.write_bytes_atomic`), so Ctrl-C or ``kill -9`` loses at most
the chunks being computed, never one already written. The manifest lists each finished chunk
with its rows and SHA-256; it is rewritten atomically after each chunk, and a chunk file that a
kill left out of the manifest (renamed, manifest not yet rewritten) is adopted on resume after
its rows are checked. ``pyarrow.dataset.dataset(DIR / "chunks")`` reads the whole table.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._io import (
    parse_json,
    read_text,
    refuse_links,
    sha256_file,
    strict_json,
    write_bytes_atomic,
    write_text_atomic,
)
from ..errors import InputError

__all__ = [
    "FOLDER_ENTRIES",
    "FORMAT",
    "Manifest",
    "check_folder_entries",
    "chunk_path",
    "read_manifest",
    "read_table",
    "table_digest",
    "write_chunk",
]

#: Version of the folder layout and manifest.
FORMAT = 1

_CHUNK_RE = re.compile(r"^chunk-(\d{6,})\.parquet$")


def _pa() -> Any:
    try:
        import pyarrow as pa
        import pyarrow.parquet  # noqa: F401
    except ImportError:  # pragma: no cover - the package's extra installs it
        raise InputError("sweeps write Parquet through pyarrow, which is not installed: "
                         "pip install 'fuzzyservo[sweep]'") from None
    return pa


def chunk_path(out: Path, c: int) -> Path:
    """File of chunk ``c``."""
    return out / "chunks" / f"chunk-{c:06d}.parquet"


@dataclass(slots=True)
class Manifest:
    """What ``manifest.json`` holds."""

    digest: str  #: SHA-256 of the canonical spec
    spec: dict[str, Any]  #: the canonical spec
    n_points: int  #: points of the sweep
    n_chunks: int  #: chunks of the sweep
    n_runs: int  #: runs (points x controllers)
    columns: list[str]  #: column names of every chunk
    chunks: dict[str, dict[str, Any]] = field(default_factory=dict)  #: "c" -> rows, sha256
    version: str = ""  #: fuzzyservo version that created it
    created: str = ""  #: ISO date of creation
    format: int = FORMAT  #: layout version

    @property
    def done(self) -> set[int]:
        """Indices of the finished chunks."""
        return {int(c) for c in self.chunks}

    @property
    def complete(self) -> bool:
        """Whether every chunk is written."""
        return len(self.chunks) == self.n_chunks

    def to_json(self) -> str:
        """The manifest as JSON text."""
        doc = {"format": self.format, "fuzzyservo_version": self.version,
               "created": self.created, "digest": self.digest, "n_points": self.n_points,
               "n_chunks": self.n_chunks, "n_runs": self.n_runs,
               "complete": self.complete, "columns": self.columns,
               "chunks": {k: self.chunks[k] for k in sorted(self.chunks, key=int)},
               "spec": self.spec}
        return strict_json(doc, indent=1) + "\n"

    def write(self, out: Path) -> None:
        """Write ``manifest.json`` atomically."""
        write_text_atomic(out / "manifest.json", self.to_json())

    @classmethod
    def new(cls, digest: str, spec: dict[str, Any], n_points: int, n_chunks: int,
            n_runs: int, columns: list[str]) -> Manifest:
        """A manifest for a new sweep."""
        from .. import __version__

        return cls(digest=digest, spec=spec, n_points=n_points, n_chunks=n_chunks,
                   n_runs=n_runs, columns=columns, version=__version__,
                   created=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"))


#: Keys of ``manifest.json`` (``complete`` is derived, the rest are :class:`Manifest`'s).
_MANIFEST_KEYS = ("format", "fuzzyservo_version", "created", "digest", "n_points",
                  "n_chunks", "n_runs", "complete", "columns", "chunks", "spec")
_SHA256_RE = re.compile(r"^[0-9a-f]{64}$")


def _count(doc: dict[str, Any], key: str) -> int:
    v = doc.get(key)
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise ValueError(f"{key} must be a non-negative integer, got {v!r}")
    return v


def _parse_manifest(doc: Any) -> Manifest:
    """A :class:`Manifest` from parsed JSON; ValueError naming the first field that is not
    what fuzzyservo writes."""
    if not isinstance(doc, dict):
        raise ValueError(f"it holds {type(doc).__name__}, not a JSON object")
    if doc.get("format") != FORMAT:
        raise _FormatMismatch(doc.get("format"))
    extra = sorted(set(doc) - set(_MANIFEST_KEYS))
    if extra:
        raise ValueError(f"unknown key {extra[0][:80]!r}; a manifest has "
                         f"{', '.join(_MANIFEST_KEYS)}")
    missing = [k for k in _MANIFEST_KEYS if k not in doc and k != "complete"]
    if missing:
        raise ValueError(f"it lacks {missing[0]!r}")
    digest = doc["digest"]
    if not isinstance(digest, str) or not _SHA256_RE.match(digest):
        raise ValueError(f"digest must be 64 hex digits (a SHA-256), got {digest!r:.80}")
    n_points, n_chunks, n_runs = (_count(doc, k) for k in ("n_points", "n_chunks", "n_runs"))
    columns = doc["columns"]
    if not isinstance(columns, list) or not all(isinstance(c, str) for c in columns):
        raise ValueError("columns must be a list of names")
    spec = doc["spec"]
    if not isinstance(spec, dict):
        raise ValueError(f"spec must be a JSON object, got {type(spec).__name__}")
    for key in ("fuzzyservo_version", "created"):
        if not isinstance(doc[key], str):
            raise ValueError(f"{key} must be a string, got {doc[key]!r:.80}")
    raw = doc["chunks"]
    if not isinstance(raw, dict):
        raise ValueError(f"chunks must be a JSON object, got {type(raw).__name__}")
    chunks: dict[str, dict[str, Any]] = {}
    for k, v in raw.items():
        if not (len(k) <= 12 and k.isascii() and k.isdigit() and str(int(k)) == k
                and int(k) < n_chunks):
            raise ValueError(f"chunk {k[:40]!r} is not a chunk number in [0, {n_chunks})")
        if not isinstance(v, dict) or set(v) != {"rows", "sha256"}:
            raise ValueError(f"chunk {k} must be {{\"rows\": N, \"sha256\": ...}}, got "
                             f"{v!r:.80}")
        try:
            rows = _count(v, "rows")
        except ValueError as exc:
            raise ValueError(f"chunk {k}'s {exc}") from None
        if not isinstance(v["sha256"], str) or not _SHA256_RE.match(v["sha256"]):
            raise ValueError(f"chunk {k}'s sha256 must be 64 hex digits, got "
                             f"{v['sha256']!r:.80}")
        chunks[k] = {"rows": rows, "sha256": v["sha256"]}
    return Manifest(digest=digest, spec=spec, n_points=n_points, n_chunks=n_chunks,
                    n_runs=n_runs, columns=columns, chunks=chunks,
                    version=doc["fuzzyservo_version"], created=doc["created"], format=FORMAT)


class _FormatMismatch(Exception):
    def __init__(self, found: Any) -> None:
        super().__init__(found)
        self.found = found


#: What of a sweep folder fuzzyservo reads and writes (nothing in it may be a link).
FOLDER_ENTRIES = ("manifest.json", "spec.toml", ".lock", "chunks", "report.key")


def check_folder_entries(out: Path) -> None:
    """Refuse a sweep folder whose own files are links, special files, or whose ``chunks``
    is not a folder (:func:`fuzzyservo._io.refuse_links`).

    Raises
    ------
    OutputError
        A link or a special file among them.
    InputError
        ``chunks`` is not a folder: the folder is corrupted.
    """
    refuse_links(out, what="sweep folder", entries=FOLDER_ENTRIES)
    chunks = Path(out) / "chunks"
    if not chunks.is_dir():
        raise InputError(f"sweep folder {str(out)!r} is corrupted: {str(chunks)!r} is "
                         + ("missing" if not chunks.exists() else "not a folder")
                         + "; give another folder (its chunks cannot be trusted)")
    with os.scandir(chunks) as it:
        for e in it:
            if _CHUNK_RE.match(e.name) and not e.is_file(follow_symlinks=False):
                raise InputError(f"sweep folder {str(out)!r} is corrupted: chunk "
                                 f"{e.name!r} is not a file; give another folder")


def read_manifest(out: Path) -> Manifest:
    """Read ``DIR/manifest.json``: nesting bounded before parsing, every field checked.

    Raises
    ------
    InputError
        No manifest, or one that is not a sweep's (the message names the field), or a
        folder that is corrupted (``chunks`` not a folder).
    OutputError
        A link or a special file among the folder's own files.
    """
    path = Path(out) / "manifest.json"
    if not os.path.lexists(path):
        raise InputError(f"{str(out)!r} is not a sweep folder (no manifest.json)")
    check_folder_entries(Path(out))
    text = read_text(path, "sweep manifest")
    try:
        return _parse_manifest(parse_json(text, "its JSON"))  # nesting bounded
    except _FormatMismatch as exc:
        raise InputError(f"{str(path)!r} has layout format {exc.found!r:.40}; this "
                         f"fuzzyservo reads format {FORMAT}") from None
    except ValueError as exc:  # parse_json's InputError included
        why = " ".join(str(exc).split())[:200]
        raise InputError(f"sweep manifest {str(path)!r} is corrupted: {why}; give another "
                         f"folder, or start the sweep afresh in a new one") from None


def write_chunk(out: Path, c: int, table: Any) -> dict[str, Any]:
    """Write chunk ``c`` atomically; return its manifest entry (rows, sha256)."""
    pa = _pa()
    import pyarrow.parquet as pq

    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    data = sink.getvalue().to_pybytes()
    write_bytes_atomic(chunk_path(out, c), data)  # its OutputError names the file once
    return {"rows": int(table.num_rows), "sha256": hashlib.sha256(data).hexdigest()}


def finished_files(out: Path) -> dict[int, Path]:
    """Chunk files present in ``DIR/chunks`` (each complete: they are renamed into place)."""
    folder = Path(out) / "chunks"
    found: dict[int, Path] = {}
    if folder.is_dir():
        for p in folder.iterdir():
            m = _CHUNK_RE.match(p.name)
            if m:
                found[int(m.group(1))] = p
    return found


def adopt(out: Path, manifest: Manifest, c: int, rows: int) -> bool:
    """Add a chunk file that a kill left out of the manifest, if its row count is right."""
    import pyarrow.parquet as pq

    path = chunk_path(out, c)
    try:
        n = pq.ParquetFile(path).metadata.num_rows
    except Exception:  # noqa: BLE001 - an unreadable file is recomputed
        return False
    if n != rows:
        return False
    manifest.chunks[str(c)] = {"rows": int(n), "sha256": sha256_file(path)}
    return True


def read_table(out: str | Path, columns: list[str] | None = None) -> Any:
    """The sweep's rows as one ``pyarrow.Table`` (chunks in order; ``columns`` to read only
    those).

    Raises
    ------
    InputError
        Not a sweep folder.
    """
    _pa()
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = Path(out)
    man = read_manifest(out)
    files = finished_files(out)
    parts = [pq.read_table(files[c], columns=columns) for c in sorted(files) if c < man.n_chunks]
    if not parts:
        raise InputError(f"{str(out)!r} holds no finished chunk yet")
    # chunks encode controller and outcome each with its own dictionary: one for the table
    return pa.concat_tables(parts).unify_dictionaries()


def table_digest(table: Any) -> str:
    """SHA-256 of a sweep table sorted by (point, controller): equal for equal rows, whatever
    the chunking, the order of writing, or the executor (NaN equals NaN; floats by their
    bits)."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc

    cols = {}
    for name in table.column_names:
        col = table.column(name)
        if pa.types.is_dictionary(col.type):
            col = col.cast(col.type.value_type)
        cols[name] = col
    plain = pa.table(cols)
    idx = pc.sort_indices(plain, sort_keys=[("point", "ascending"),
                                            ("controller", "ascending")])
    t = plain.take(idx)
    h = hashlib.sha256()
    for name in sorted(t.column_names):
        col = t.column(name).combine_chunks()
        h.update(f"{name}:{col.type}:".encode())
        if pa.types.is_string(col.type) or pa.types.is_large_string(col.type):
            for v in col.to_pylist():
                h.update(b"\x00" if v is None else v.encode() + b"\x01")
        else:
            h.update(np.ascontiguousarray(col.to_numpy(zero_copy_only=False)).tobytes())
            h.update(np.asarray(col.is_null().to_numpy(zero_copy_only=False)).tobytes())
    return h.hexdigest()
