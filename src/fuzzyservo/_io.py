"""File I/O every layer shares: atomic writes, checked output paths, strict UTF-8 and JSON.

Guarantees (docs/guarantees.md):

- :func:`atomic_write` writes to a temporary file in the target's folder, flushes and fsyncs
  it, and renames it over the target only when the block that writes it ends normally. An
  exception, a full disk, a file-size limit, Ctrl-C or SIGTERM (the CLI turns it into an
  exception) leaves the previous file byte-identical and removes the temporary file. Only
  SIGKILL can leave a temporary file behind; its name (``.NAME.XXXXXXXX.tmp``) never is the
  target's. A symbolic link is followed (the file it points at is replaced, the link kept);
  a target that is not a regular file (``/dev/null``, a FIFO) is written directly.
- :func:`read_text` refuses bytes that are not UTF-8 with the file name and the byte offset.
- :func:`strict_json` writes NaN and infinities as ``null``: strict JSON parsers reject the
  ``NaN``/``Infinity`` tokens Python's ``json`` emits by default.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import os
import signal
import tempfile
import threading
import zipfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, Any, Literal, overload

from .errors import InputError, OutputError

__all__ = [
    "Terminated",
    "atomic_write",
    "check_output_path",
    "fsync_folder",
    "npz_inflation",
    "read_text",
    "sha256_file",
    "strict_json",
    "terminate_gracefully",
    "write_bytes_atomic",
    "write_text_atomic",
    "write_texts_atomic",
]


class Terminated(KeyboardInterrupt):
    """SIGTERM received while a file was being written, raised so the write is rolled back."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


_GRACEFUL = {"sigterm": False}


def terminate_gracefully(enabled: bool) -> None:
    """While ``enabled``, SIGTERM during an :func:`atomic_write` raises :class:`Terminated`
    (the write is rolled back) instead of ending the process at once. The CLI enables it; at
    any other moment SIGTERM keeps its default action, which also works while a compiled loop
    runs (a Python handler would wait for the loop to end)."""
    _GRACEFUL["sigterm"] = enabled


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated(signum)


def _describe(exc: OSError) -> str:
    return exc.strerror or type(exc).__name__


def check_output_path(path: str | Path, *, option: str = "--out",
                      inputs: Iterable[str | Path | None] = ()) -> Path:
    """Check, before any work, that ``path`` can be written as a file, and return it.

    Raises
    ------
    InputError
        ``path`` is a folder, its folder does not exist or is not writable, or it names one
        of ``inputs`` (files the same command reads).
    """
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{option} {str(p)!r} is a folder; give a file name")
    if p.exists() and not p.is_file():  # /dev/null, a FIFO: written directly
        return p
    parent = Path(os.path.realpath(p)).parent  # where the file really goes (links followed)
    shown = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"{option} {str(p)!r}: folder {str(shown)!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{option} {str(p)!r}: folder {str(shown)!r} is not writable")
    if p.exists() and not os.access(p, os.W_OK) and not os.access(parent, os.W_OK):
        raise InputError(f"{option} {str(p)!r} is not writable")
    for src in inputs:
        if src is None:
            continue
        s = Path(src)
        try:
            same = s.exists() and p.exists() and os.path.samefile(s, p)
        except OSError:
            same = False
        if same or s.resolve() == p.resolve():
            raise InputError(f"{option} {str(p)!r} is also an input of this command "
                             f"({str(s)!r}); writing it would destroy the input")
    return p


def _new_file_mode(target: Path) -> int:
    try:
        return target.stat().st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


@overload
def atomic_write(path: str | Path, *, binary: Literal[False] = ...) -> contextlib.AbstractContextManager[IO[str]]: ...  # noqa: E501


@overload
def atomic_write(path: str | Path, *, binary: Literal[True]) -> contextlib.AbstractContextManager[IO[bytes]]: ...  # noqa: E501


def atomic_write(path: str | Path, *, binary: bool = False) -> contextlib.AbstractContextManager[IO[Any]]:  # noqa: E501
    """Open ``path`` for writing so that it appears complete or not at all.

    Text mode is UTF-8 with ``\\n`` line ends. Use as ``with atomic_write(p) as fh: ...``;
    the target is replaced when the block ends without an exception.

    Raises
    ------
    OutputError
        The file cannot be written (missing folder, permission, full disk, size limit); the
        previous file, if any, is left as it was.
    """
    return _atomic(Path(path), binary)


@contextlib.contextmanager
def _atomic(target: Path, binary: bool) -> Iterator[IO[Any]]:
    previous: Any = None
    if _GRACEFUL["sigterm"] and threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        with _atomic_file(target, binary) as fh:
            yield fh
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def _direct(target: Path, binary: bool) -> Iterator[IO[Any]]:
    """Write straight into a target that is not a regular file (``/dev/null``, a FIFO, a
    terminal): there is no previous content to keep, and replacing it would be wrong."""
    try:
        fh: IO[Any] = (target.open("wb") if binary
                       else target.open("w", encoding="utf-8", newline=""))
        with fh:
            yield fh
    except OSError as exc:
        raise OutputError(f"cannot write {str(target)!r}: {_describe(exc)}") from None


def fsync_folder(folder: Path) -> None:
    """Make renames in ``folder`` durable (best effort: not every file system allows it)."""
    with contextlib.suppress(OSError):
        dfd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


@contextlib.contextmanager
def _atomic_file(target: Path, binary: bool) -> Iterator[IO[Any]]:
    shown = target  # the name the caller gave, for messages
    real = Path(os.path.realpath(target))  # a symbolic link keeps pointing at the new file
    if real.exists() and not real.is_file():
        with _direct(real, binary) as out:
            yield out
        return
    target = real
    folder = target.parent
    try:
        fd, tmp_name = tempfile.mkstemp(dir=folder, prefix=f".{target.name}.", suffix=".tmp")
    except OSError as exc:
        raise OutputError(f"cannot write {str(shown)!r}: {_describe(exc)}") from None
    tmp = Path(tmp_name)
    done = False
    try:
        fh: IO[Any]
        if binary:
            fh = os.fdopen(fd, "wb")
        else:
            fh = os.fdopen(fd, "w", encoding="utf-8", newline="")
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _new_file_mode(target))
        os.replace(tmp, target)
        done = True
        fsync_folder(folder)
    except OSError as exc:
        raise OutputError(f"cannot write {str(shown)!r}: {_describe(exc)}; "
                          f"the previous file, if any, is unchanged") from None
    finally:
        if not done:
            with contextlib.suppress(OSError):
                tmp.unlink()


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically and return the path."""
    with atomic_write(path) as fh:
        fh.write(text)
    return Path(path)


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back for the duration of the block (the main thread's
    handlers record them), then restore the handlers and deliver what arrived."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    saved = {sig: signal.signal(sig, lambda signum, frame: got.append(signum))
             for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
        for signum in dict.fromkeys(got):
            signal.raise_signal(signum)


def write_texts_atomic(files: dict[Path, str]) -> list[Path]:
    """Write several UTF-8 files as one: each to a temporary file in its folder, flushed and
    fsynced, then all renamed over their targets with Ctrl-C and SIGTERM held back until the
    last rename. An error or an interruption before the renames leaves every old file as it
    was; the renames themselves cannot be split by a signal (only SIGKILL or a crash can).

    Raises
    ------
    OutputError
        A file cannot be written (every old file is unchanged).
    """
    temps: list[tuple[Path, Path]] = []
    try:
        for path, text in files.items():
            target = Path(os.path.realpath(path))
            fd, tmp_name = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.",
                                            suffix=".tmp")
            temps.append((Path(tmp_name), target))
            with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
                fh.write(text)
                fh.flush()
                os.fsync(fh.fileno())
            os.chmod(tmp_name, _new_file_mode(target))
        with _signals_deferred():
            for tmp, target in temps:
                os.replace(tmp, target)
            temps = []
        for folder in dict.fromkeys(Path(os.path.realpath(p)).parent for p in files):
            fsync_folder(folder)
    except OSError as exc:
        shown = ", ".join(repr(str(p)) for p in files)
        raise OutputError(f"cannot write {shown}: {_describe(exc)}; the previous files, if "
                          f"any, are unchanged") from None
    finally:
        for tmp, _ in temps:
            with contextlib.suppress(OSError):
                tmp.unlink()
    return list(files)


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically and return the path."""
    with atomic_write(path, binary=True) as fh:
        fh.write(data)
    return Path(path)


_BOMS = ((b"\xff\xfe\x00\x00", "UTF-32"), (b"\x00\x00\xfe\xff", "UTF-32"),
         (b"\xff\xfe", "UTF-16"), (b"\xfe\xff", "UTF-16"))


def read_text(path: str | Path, what: str = "file") -> str:
    """Read ``path`` as UTF-8 text (a UTF-8 byte-order mark is skipped).

    Raises
    ------
    InputError
        The file cannot be read, or holds bytes that are not UTF-8 (the message names the file
        and the offset of the first bad byte) or NUL characters.
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {what} {str(p)!r}: {_describe(exc)}") from None
    for bom, name in _BOMS:
        if data.startswith(bom):
            raise InputError(f"{what} {str(p)!r} is {name} text (byte-order mark at byte 0); "
                             f"save it as UTF-8")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what} {str(p)!r} is not UTF-8 text: byte 0x{data[exc.start]:02x} "
                         f"at offset {exc.start}") from None
    nul = text.find("\0")
    if nul >= 0:
        raise InputError(f"{what} {str(p)!r} is not text: NUL character at offset "
                         f"{len(text[:nul].encode('utf-8'))}")
    return text


def _finite(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj


def strict_json(obj: Any, *, indent: int | None = None, sort_keys: bool = False) -> str:
    """``obj`` as strict JSON (RFC 8259): NaN and infinities become ``null``."""
    return json.dumps(_finite(obj), indent=indent, sort_keys=sort_keys, allow_nan=False)


def sha256_file(path: str | Path) -> str:
    """SHA-256 of a file's bytes, as hex."""
    h = hashlib.sha256()
    with Path(path).open("rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def npz_inflation(source: str | Path | bytes) -> str | None:
    """Why an ``.npz`` archive must not be loaded, or None.

    fuzzyservo writes its archives with ``np.savez`` (members stored, not compressed), so
    their arrays are never larger than the file. A crafted archive of a few MB whose members
    are compressed could unpack into gigabytes before any check of ours runs; it is refused
    here, from the archive's directory alone."""
    size = len(source) if isinstance(source, bytes) else Path(source).stat().st_size
    try:
        with zipfile.ZipFile(io.BytesIO(source) if isinstance(source, bytes) else source) as zf:
            members = zf.infolist()
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as exc:
        return f"not an .npz archive ({type(exc).__name__})"
    if any(m.compress_type != zipfile.ZIP_STORED for m in members):
        return "compressed members (fuzzyservo stores its arrays uncompressed)"
    if sum(m.file_size for m in members) > size:
        return "its members claim more bytes than the file holds"
    return None
