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
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._io import read_text, sha256_file, strict_json, write_bytes_atomic, write_text_atomic
from ..errors import InputError, OutputError

__all__ = [
    "FORMAT",
    "Manifest",
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


def read_manifest(out: Path) -> Manifest:
    """Read ``DIR/manifest.json``.

    Raises
    ------
    InputError
        No manifest, or one that is not a sweep's.
    """
    path = Path(out) / "manifest.json"
    if not path.is_file():
        raise InputError(f"{str(out)!r} is not a sweep folder (no manifest.json)")
    try:
        doc = json.loads(read_text(path, "sweep manifest"))
        if doc.get("format") != FORMAT:
            raise InputError(f"{str(path)!r} has layout format {doc.get('format')!r}; this "
                             f"fuzzyservo reads format {FORMAT}")
        return Manifest(digest=str(doc["digest"]), spec=dict(doc["spec"]),
                        n_points=int(doc["n_points"]), n_chunks=int(doc["n_chunks"]),
                        n_runs=int(doc["n_runs"]), columns=list(doc["columns"]),
                        chunks={str(k): dict(v) for k, v in doc["chunks"].items()},
                        version=str(doc.get("fuzzyservo_version", "")),
                        created=str(doc.get("created", "")), format=FORMAT)
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise InputError(f"{str(path)!r} is not a valid sweep manifest ({exc})") from None


def write_chunk(out: Path, c: int, table: Any) -> dict[str, Any]:
    """Write chunk ``c`` atomically; return its manifest entry (rows, sha256)."""
    pa = _pa()
    import pyarrow.parquet as pq

    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    data = sink.getvalue().to_pybytes()
    path = chunk_path(out, c)
    try:
        write_bytes_atomic(path, data)
    except OSError as exc:  # pragma: no cover - write_bytes_atomic raises OutputError
        raise OutputError(f"cannot write {str(path)!r}: {exc}") from None
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
