"""What a warm ``reproduce`` may take from the previous run instead of writing it again.

The manifest of a finished run records, per group of derived files (Fig. 3, a plant's
figures, a plant's trace CSVs), the key of the inputs the group was made from and the
group's files; its ``outputs`` give each file's SHA-256. A group is kept when that run
finished, made it from the same inputs, and every file still has its recorded SHA-256
(:func:`reusable`); anything else writes it again. :class:`Digests` hashes each file once per
run however many times a run asks (the folder check, :func:`reusable`, the new manifest).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from .._io import sha256_file

__all__ = ["Digests", "reusable"]


class Digests:
    """SHA-256 of files, each hashed once while it stays as it was.

    A digest is remembered with the file's identity and change stamps (device, inode, size,
    modification and status-change times, in ns); a file replaced or written since (an
    atomic write renames a new inode over it) is hashed again. Meant for one run, which holds
    the folder's lock: no other ``reproduce`` writes the folder meanwhile.
    """

    def __init__(self) -> None:
        self._seen: dict[str, tuple[tuple[int, ...], str]] = {}

    def __call__(self, path: str | Path) -> str:
        """SHA-256 of ``path``'s bytes, as hex (``fuzzyservo._io.sha256_file``)."""
        key = os.fspath(Path(path).absolute())
        st = os.stat(key)
        stamp = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
        seen = self._seen.get(key)
        if seen is not None and seen[0] == stamp:
            return seen[1]
        digest = sha256_file(key)
        st = os.stat(key)
        if stamp == (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns):
            self._seen[key] = (stamp, digest)  # not changed while it was read
        return digest


def reusable(previous: Mapping[str, Any] | None, out: Path, group: str, key: str,
             files: Sequence[Path], *, section: str = "figures",
             digest: Callable[[Path], str] = sha256_file) -> bool:
    """Whether ``files`` (a group of derived files: a plant's figures or traces, Fig. 3) can
    be taken as they are from the run that wrote ``previous`` (its manifest): that run
    finished, recorded the group under ``previous[section][group]`` with the same inputs
    (``key``) and the same files, and every file still has the SHA-256 it recorded.
    """
    if not previous or previous.get("complete") is not True:
        return False
    groups = previous.get(section)
    record = groups.get(group) if isinstance(groups, dict) else None
    outputs = previous.get("outputs")
    if not isinstance(record, dict) or not isinstance(outputs, dict):
        return False
    rels = [p.relative_to(out).as_posix() for p in files]
    if record.get("key") != key or record.get("files") != rels:
        return False
    return all(p.is_file() and outputs.get(rel) == digest(p)
               for p, rel in zip(files, rels, strict=True))
