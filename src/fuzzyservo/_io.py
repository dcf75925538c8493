"""File I/O every layer shares: atomic writes, checked output paths, strict UTF-8 and JSON.

Guarantees (docs/guarantees.md):

- :func:`atomic_write` writes to a temporary file in the target's folder, flushes and fsyncs
  it, and renames it over the target only when the block that writes it ends normally. An
  exception, a full disk, a file-size limit, Ctrl-C or SIGTERM (the CLI turns it into an
  exception) leaves the previous file byte-identical and removes the temporary file. Only
  SIGKILL can leave a temporary file behind; its name (``.NAME.XXXXXXXX.tmp``) never is the
  target's. A symbolic link is followed (the file it points at is replaced, the link kept);
  a target that is not a regular file (``/dev/null``, a FIFO) is written directly.
- Inside an output folder (:func:`confined`: a sweep's, a study's) nothing is followed: every
  folder below it is opened with ``O_NOFOLLOW``, the temporary file is created in the folder
  so opened and renamed onto the target's name there, and a target that is a symbolic link
  or not a regular file is refused (:class:`~fuzzyservo.errors.OutputError`), so no write
  lands outside the folder.
- :func:`check_output_path` refuses a path that would replace the data of a sweep or study
  folder it lies in (:func:`result_data_of`).
- :func:`read_text` refuses bytes that are not UTF-8 with the file name and the byte offset.
- Every input file is opened by :func:`open_input`: a regular file only (a FIFO, a device, a
  folder is refused on one line; a FIFO without a writer does not block), and a file read
  whole (:func:`read_bytes`, :func:`read_text`) is read with a bounded read, at most
  :data:`MAX_INPUT_BYTES` (a device or a file still growing cannot make it read for ever).
- :func:`parse_toml` and :func:`parse_json` bound the nesting of arrays and tables to
  :data:`MAX_NESTING` levels before parsing (both parsers recurse) and after (TOML's dotted
  keys nest without brackets).
- :func:`read_csv_columns` reads the numeric columns of a CSV with a header (run CSVs, points
  CSVs, load-force profiles) as a stream of strict UTF-8 lines, each line bounded.
- :func:`strict_json` writes NaN and infinities as ``null``: strict JSON parsers reject the
  ``NaN``/``Infinity`` tokens Python's ``json`` emits by default.
"""

from __future__ import annotations

import contextlib
import contextvars
import csv
import errno
import hashlib
import io
import json
import math
import os
import re
import secrets
import signal
import stat
import tempfile
import threading
import zipfile
from array import array
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, BinaryIO, Literal, overload

from .errors import InputError, OutputError

if TYPE_CHECKING:
    from ._typing import FloatArray

__all__ = [
    "MAX_INPUT_BYTES",
    "MAX_NESTING",
    "Terminated",
    "atomic_write",
    "check_output_path",
    "read_csv_columns",
    "confined",
    "refuse_links",
    "result_data_of",
    "fsync_folder",
    "npz_inflation",
    "open_input",
    "parse_json",
    "parse_toml",
    "read_bytes",
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


_STREAM = re.compile(r"/dev/(?:stdin|stdout|stderr|fd/\d+)|/proc/(?:self|thread-self|\d+)"
                     r"(?:/task/\d+)?/fd/\d+")


def _standard_stream(p: Path) -> bool:
    """Whether ``p`` names one of the process's open descriptors (``/dev/stdout``,
    ``/dev/fd/1``, ``/proc/self/fd/1``), directly or through symbolic links. Written as a
    file, such a path is whatever the descriptor is: a file that standard output is
    appended to (``>>``) would be replaced, a pipe does not exist by its link's name."""
    cur = os.path.abspath(p)
    for _ in range(40):  # the kernel's limit of links followed
        if _STREAM.fullmatch(cur):
            return True
        try:
            link = os.readlink(cur)
        except OSError:
            return False
        cur = os.path.normpath(os.path.join(os.path.dirname(cur), link))
    return False


def check_output_path(path: str | Path, *, option: str = "--out",
                      inputs: Iterable[str | Path | None] = ()) -> Path:
    """Check, before any work, that ``path`` can be written as a file, and return it.

    Raises
    ------
    InputError
        ``path`` is a folder or a standard stream (``/dev/stdout``, ``/dev/fd/1``: ``-`` is
        standard output), its folder does not exist or is not writable, it names one of
        ``inputs`` (files the same command reads), or it would replace the data of a sweep
        or study folder (:func:`result_data_of`).
    """
    p = Path(path)
    if _standard_stream(p):
        raise InputError(f"{option} {str(p)!r} is a standard stream, not a file: give a file "
                         f"name, or {option} - where the command writes to standard output")
    if p.is_dir():
        raise InputError(f"{option} {str(p)!r} is a folder; give a file name")
    why = result_data_of(p)
    if why is not None:
        raise InputError(f"{option} {str(p)!r} {why}")
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


#: Largest manifest :func:`result_data_of` reads to tell whose folder it is [bytes].
_MANIFEST_SNIFF = 16 << 20
#: What a sweep folder keeps (``fuzzyservo.sweep.dataset``): first components of a path in it.
_SWEEP_DATA = {"manifest.json": "its manifest", "spec.toml": "its spec",
               ".lock": "its lock", "chunks": "its chunks", "report.key": "its report stamp"}
#: What a study folder keeps besides the outputs its manifest lists (``fuzzyservo.study``).
_STUDY_DATA = {"manifest.json": "its manifest", ".lock": "its lock", ".cache": "its cache"}


def _manifest_doc(path: Path) -> dict[str, Any] | None:
    """The JSON object in ``path`` (a regular file, at most :data:`_MANIFEST_SNIFF` bytes),
    or None."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        with os.fdopen(fd, "rb", closefd=False) as fh:
            data = fh.read(_MANIFEST_SNIFF + 1)
    except OSError:
        return None
    finally:
        os.close(fd)
    if len(data) > _MANIFEST_SNIFF:
        return None
    try:
        doc = json.loads(data.decode("utf-8"))
    except (ValueError, RecursionError):  # not ours to judge here: the folder's reader says
        return None
    return doc if isinstance(doc, dict) else None


def result_data_of(path: str | Path,
                   kinds: tuple[str, ...] = ("sweep", "study")) -> str | None:
    """Why writing the file ``path`` would replace the data of a sweep or a study folder it
    lies in (as written, or with links resolved), or None.

    A folder is a sweep's when it holds ``manifest.json`` and ``chunks/``; its data are the
    manifest, ``spec.toml``, ``.lock``, ``report.key`` and everything in ``chunks/``. It is a
    study's when its ``manifest.json`` is a JSON object naming ``fuzzyservo`` (what
    ``reproduce`` writes); its data are the manifest, ``.lock``, ``.cache/`` and every output
    the manifest lists. Anything else in such a folder (``D/report.html`` beside a sweep) may
    be written. ``kinds`` limits the folders looked for (``("sweep",)``)."""
    seen: set[Path] = set()
    for target in (Path(os.path.abspath(path)), Path(os.path.realpath(path))):
        for folder in target.parents:
            if folder in seen:
                continue
            seen.add(folder)
            rel = target.relative_to(folder)
            man = folder / "manifest.json"
            try:
                if not stat.S_ISREG(os.lstat(man).st_mode):
                    continue
            except OSError:
                continue
            doc = _manifest_doc(man)
            if os.path.isdir(folder / "chunks") and (
                    doc is None or ("digest" in doc and "n_chunks" in doc)):
                kind, what = "sweep", _SWEEP_DATA.get(rel.parts[0])
            elif doc is not None and "fuzzyservo" in doc:
                outputs = doc.get("outputs")
                listed = isinstance(outputs, dict) and rel.as_posix() in outputs
                kind = "study"
                what = _STUDY_DATA.get(rel.parts[0]) or ("an output its manifest lists"
                                                         if listed else None)
            else:
                continue
            if what is not None and kind in kinds:
                return (f"would replace {what} (the {kind} folder {str(folder)!r}); write "
                        f"outside the {kind}'s own files")
    return None


def refuse_links(folder: str | Path, *, what: str,
                 entries: Iterable[str] | None = None) -> None:
    """Refuse a symbolic link, or a file that is not a regular file or a folder (a FIFO, a
    device, a socket), inside the output folder ``folder``: at ``entries`` (paths relative
    to it; a folder among them is looked through whole), or anywhere below it. ``folder``
    itself may be a link (the user's choice); nothing below it is followed.

    Raises
    ------
    OutputError
        The message names the entry; fuzzyservo neither reads nor writes through it.
    """
    root = Path(folder)
    todo: list[str] = list(entries) if entries is not None else [
        e.name for e in _scan(root)]
    while todo:
        rel = todo.pop()
        try:
            st = os.lstat(root / rel)
        except FileNotFoundError:
            continue
        except OSError as exc:
            raise OutputError(f"cannot read {what} {str(root)!r}: {_describe(exc)}") from None
        if stat.S_ISLNK(st.st_mode):
            raise OutputError(f"{what} {str(root)!r} holds a symbolic link, {rel!r}: "
                              f"fuzzyservo never writes or reads through a link in its "
                              f"output folders; remove it or give another folder")
        if stat.S_ISDIR(st.st_mode):
            todo.extend(f"{rel}/{e.name}" for e in _scan(root / rel))
        elif not stat.S_ISREG(st.st_mode):
            raise OutputError(f"{what} {str(root)!r} holds {rel!r}, which is not a regular "
                              f"file (a FIFO, device or socket); remove it or give another "
                              f"folder")


def _scan(folder: Path) -> list[os.DirEntry[str]]:
    try:
        with os.scandir(folder) as it:
            return list(it)
    except FileNotFoundError:
        return []
    except OSError as exc:
        raise OutputError(f"cannot read {str(folder)!r}: {_describe(exc)}") from None


_CONFINED: contextvars.ContextVar[tuple[Path, ...]] = contextvars.ContextVar(
    "fuzzyservo_confined", default=())


@contextlib.contextmanager
def confined(folder: str | Path) -> Iterator[None]:
    """While the block runs, every write of this module to a path inside ``folder`` (as
    written: ``folder`` itself may be a link) follows no link: see the module's docstring.
    A sweep and a study hold it over their output folder (scoped to the block and to the
    calling context, so other threads and later calls are as before)."""
    root = Path(os.path.abspath(folder))
    token = _CONFINED.set((*_CONFINED.get(), root))
    try:
        yield
    finally:
        _CONFINED.reset(token)


def _confined_parts(target: Path) -> tuple[Path, tuple[str, ...]] | None:
    """(root, components below it) of ``target`` in the outermost confined folder, or None."""
    a = Path(os.path.abspath(target))
    for root in sorted(_CONFINED.get(), key=lambda r: len(r.parts)):
        if a != root and a.is_relative_to(root):
            return root, a.relative_to(root).parts
    return None


def _open_confined(root: Path, parts: Sequence[str], shown: Path) -> int:
    """A descriptor of the folder ``root/parts[:-1]``, each folder below ``root`` opened
    without following a link."""
    flags = os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC
    try:
        fd = os.open(root, flags)
    except OSError as exc:
        raise OutputError(f"cannot write {str(shown)!r}: {_describe(exc)}") from None
    walked = root
    try:
        for part in parts[:-1]:
            try:
                nfd = os.open(part, flags | os.O_NOFOLLOW, dir_fd=fd)
            except OSError as exc:
                link = exc.errno in (errno.ELOOP, errno.ENOTDIR) and _is_link(part, fd)
                why = (f"{str(walked / part)!r} is a symbolic link inside the output folder "
                       f"{str(root)!r}; fuzzyservo never writes through one: remove it"
                       if link else _describe(exc))
                raise OutputError(f"cannot write {str(shown)!r}: {why}") from None
            os.close(fd)
            fd = nfd
            walked = walked / part
    except BaseException:
        os.close(fd)
        raise
    return fd


def _is_link(name: str, dir_fd: int) -> bool:
    try:
        return stat.S_ISLNK(os.lstat(name, dir_fd=dir_fd).st_mode)
    except OSError:
        return False


@contextlib.contextmanager
def _confined_file(root: Path, parts: Sequence[str], shown: Path,
                   binary: bool) -> Iterator[IO[Any]]:
    """:func:`_atomic_file` inside a confined folder: no link followed, none written through."""
    name = parts[-1]
    dfd = _open_confined(root, parts, shown)
    tmp: str | None = None
    done = False
    try:
        try:
            st: os.stat_result | None = os.lstat(name, dir_fd=dfd)
        except FileNotFoundError:
            st = None
        except OSError as exc:
            raise OutputError(f"cannot write {str(shown)!r}: {_describe(exc)}") from None
        if st is not None and stat.S_ISLNK(st.st_mode):
            raise OutputError(f"cannot write {str(shown)!r}: it is a symbolic link inside the "
                              f"output folder {str(root)!r}; fuzzyservo never writes through "
                              f"one: remove it")
        if st is not None and not stat.S_ISREG(st.st_mode):
            raise OutputError(f"cannot write {str(shown)!r}: it is not a regular file (a "
                              f"folder, FIFO or device) inside the output folder "
                              f"{str(root)!r}; remove it")
        if st is not None:
            mode = st.st_mode & 0o7777
        else:
            mask = os.umask(0)
            os.umask(mask)
            mode = 0o666 & ~mask
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
        while True:
            cand = f".{name}.{secrets.token_hex(4)}.tmp"
            try:
                fd = os.open(cand, flags, 0o600, dir_fd=dfd)
            except FileExistsError:
                continue
            except OSError as exc:
                raise OutputError(f"cannot write {str(shown)!r}: {_describe(exc)}") from None
            tmp = cand
            break
        try:
            fh: IO[Any] = (os.fdopen(fd, "wb") if binary
                           else os.fdopen(fd, "w", encoding="utf-8", newline=""))
            with fh:
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
                os.fchmod(fh.fileno(), mode)
            os.replace(tmp, name, src_dir_fd=dfd, dst_dir_fd=dfd)  # replaces a link put
            done = True                                             # there since: no write
            with contextlib.suppress(OSError):                      # goes through it
                os.fsync(dfd)
        except OSError as exc:
            raise OutputError(f"cannot write {str(shown)!r}: {_describe(exc)}; the previous "
                              f"file, if any, is unchanged") from None
    finally:
        if tmp is not None and not done:
            with contextlib.suppress(OSError):
                os.unlink(tmp, dir_fd=dfd)
        os.close(dfd)


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
    inside = _confined_parts(target)
    if inside is not None:
        with _confined_file(*inside, shown, binary) as out:
            yield out
        return
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


def _texts_target(path: Path) -> Path:
    """Where :func:`write_texts_atomic` writes ``path``: links resolved, except inside a
    confined folder, where a link below it is refused and the rename replaces the name."""
    inside = _confined_parts(path)
    if inside is None:
        return Path(os.path.realpath(path))
    root, parts = inside
    dfd = _open_confined(root, parts, path)
    try:
        if _is_link(parts[-1], dfd):
            raise OutputError(f"cannot write {str(path)!r}: it is a symbolic link inside the "
                              f"output folder {str(root)!r}; fuzzyservo never writes through "
                              f"one: remove it")
    finally:
        os.close(dfd)
    return root.joinpath(*parts)


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
            target = _texts_target(Path(path))
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
        for folder in dict.fromkeys(_texts_target(Path(p)).parent for p in files):
            fsync_folder(folder)
    except OutputError:  # already names the file: not "cannot write ...: cannot write"
        raise
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


#: Largest file read whole [bytes] (parameter, gains, spec, manifest and fuzzy-system files):
#: far above any of them, below anything pathological.
MAX_INPUT_BYTES = 16 * 1024 * 1024
#: Deepest nesting of arrays and tables in a TOML or JSON input: the files fuzzyservo reads
#: nest three or four levels; Python's TOML and JSON parsers recurse once or more a level and
#: fail near 1000 (RecursionError).
MAX_NESTING = 64


def _named(what: str, p: Path) -> str:
    return f"{what} {str(p)!r}" if what else repr(str(p))


def _file_kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def open_input(path: str | Path, what: str = "file") -> BinaryIO:
    """Open ``path``, a regular file, for reading in binary mode.

    The file is opened with ``O_NONBLOCK`` and checked with ``fstat`` on the open descriptor
    (no race with a rename), so a FIFO without a writer is refused at once instead of
    blocking; a regular file is then read normally. ``what`` names the file in messages.

    Raises
    ------
    InputError
        The file cannot be opened, or is a folder, a FIFO, a device or a socket (the message
        names it and what it is).
    """
    p = Path(path)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        raise InputError(f"cannot read {_named(what, p)}: {_describe(exc)}") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise InputError(f"{_named(what, p)} is {_file_kind(mode)}, not a regular file; "
                             f"give a file")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_bytes(path: str | Path, what: str = "file", limit: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of ``path`` (a regular file, :func:`open_input`), read with one bounded read
    of at most ``limit`` + 1 bytes.

    Raises
    ------
    InputError
        As :func:`open_input`, or the file is larger than ``limit`` bytes.
    """
    p = Path(path)
    try:
        with open_input(p, what) as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise InputError(f"cannot read {_named(what, p)}: {_describe(exc)}") from None
    if len(data) > limit:
        raise InputError(f"{_named(what, p)} is larger than the {limit}-byte limit of an "
                         f"input file")
    return data


def read_text(path: str | Path, what: str = "file", limit: int = MAX_INPUT_BYTES) -> str:
    """Read ``path`` as UTF-8 text (a UTF-8 byte-order mark is skipped), at most ``limit``
    bytes (:func:`read_bytes`).

    Raises
    ------
    InputError
        The file cannot be read, is not a regular file, is larger than ``limit``, or holds
        bytes that are not UTF-8 (the message names the file and the offset of the first bad
        byte) or NUL characters.
    """
    p = Path(path)
    data = read_bytes(p, what, limit)
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


def _check_brackets(text: str, what: str, toml: bool) -> None:
    """Refuse ``text`` if its arrays and tables (``[``, ``{``) nest deeper than
    :data:`MAX_NESTING`. Strings are skipped (JSON ``"..."`` with escapes; TOML also
    ``'...'``, ``\"\"\"...\"\"\"`` and ``'''...'''``), and TOML comments. Text that is not
    valid is left to the parser to refuse: the count is exact up to the first syntax error,
    and the parser does not read past it."""
    depth = 0
    i, n = 0, len(text)
    while i < n:
        ch = text[i]
        if ch in "[{":
            depth += 1
            if depth > MAX_NESTING:
                line = text.count("\n", 0, i) + 1
                raise InputError(f"{what} nests arrays or tables more than {MAX_NESTING} "
                                 f"levels deep (line {line}); at most {MAX_NESTING} are read")
        elif ch in "]}":
            depth = max(0, depth - 1)
        elif ch == "#" and toml:
            j = text.find("\n", i)
            i = n if j < 0 else j
            continue
        elif ch == '"' or (ch == "'" and toml):
            triple = toml and text.startswith(ch * 3, i)
            quote = ch * 3 if triple else ch
            j = i + len(quote)
            escapes = ch == '"'
            while j < n:
                if escapes and text[j] == "\\":
                    j += 2
                    continue
                if text.startswith(quote, j):
                    break
                if not triple and text[j] == "\n":  # an unclosed string: the parser says so
                    break
                j += 1
            if triple:  # a closing run of up to five quotes keeps one or two in the string
                while j + len(quote) < n and text[j + len(quote)] == ch:
                    j += 1
            i = j + len(quote)
            continue
        i += 1


def _check_depth(obj: Any, what: str) -> None:
    """Refuse a parsed value nested deeper than MAX_NESTING (iteratively: no recursion)."""
    stack: list[tuple[Any, int]] = [(obj, 0)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, dict | list):
            if depth > MAX_NESTING:
                raise InputError(f"{what} nests keys, arrays or tables more than "
                                 f"{MAX_NESTING} levels deep; at most {MAX_NESTING} are read")
            items = value.values() if isinstance(value, dict) else value
            stack.extend((v, depth + 1) for v in items)


def parse_toml(text: str, what: str) -> dict[str, Any]:
    """``text`` parsed as TOML, its nesting bounded (:data:`MAX_NESTING`) before parsing.

    ``what`` names the text in messages (``"gains file 'g.toml'"``).

    Raises
    ------
    InputError
        The text is not TOML (the parser's reason, on one line), or nests too deep.
    """
    import tomllib

    doc = _parse(tomllib.loads, text, what, "TOML")
    _check_depth(doc, what)
    return doc


def parse_json(text: str, what: str) -> Any:
    """``text`` parsed as JSON (as :func:`json.loads`), its nesting bounded
    (:data:`MAX_NESTING`) before parsing. ``what`` names the text in messages.

    Raises
    ------
    InputError
        The text is not JSON (the parser's reason, on one line), or nests too deep.
    """
    return _parse(json.loads, text, what, "JSON")


def _parse(loads: Callable[[str], Any], text: str, what: str, language: Literal["TOML", "JSON"]
           ) -> Any:
    """``loads(text)`` after the nesting check of ``language`` ("TOML" or "JSON"), its
    errors as one-line :class:`InputError` naming ``what``."""
    _check_brackets(text, what, toml=language == "TOML")
    try:
        return loads(text)
    except ValueError as exc:  # TOMLDecodeError, JSONDecodeError, an integer of > 4300 digits
        why = " ".join(str(exc).split())[:200]
        raise InputError(f"{what} is not valid {language}: {why}") from None
    except RecursionError:  # not reached with the bound above; never a traceback
        raise InputError(f"{what} nests too deep to be read") from None


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


# ---------------------------------------------------------------------------- CSV
# (here, below every layer, so that run/ can read a load-force profile as files/ reads run CSVs)

_CSV_BOMS = ((b"\xff\xfe\x00\x00", "UTF-32"), (b"\x00\x00\xfe\xff", "UTF-32"),
         (b"\xff\xfe", "UTF-16"), (b"\xfe\xff", "UTF-16"))


#: Longest line of a CSV read [bytes]: a run CSV's row is a few hundred bytes, a points CSV's
#: about 25 a column; a longer line (a file of zeros without a line end) is refused rather
#: than read whole into memory.
MAX_LINE_BYTES = 1024 * 1024


def _text_lines(fh: BinaryIO, path: Path, what: str) -> Iterator[str]:
    """The lines of a binary file as strict UTF-8 text, one at a time (a UTF-8 byte-order mark
    skipped); a bad byte or a NUL is an error naming the file and the byte offset, and so is
    a line longer than :data:`MAX_LINE_BYTES` (each line is one bounded read)."""
    offset = 0
    for n, raw in enumerate(iter(lambda: fh.readline(MAX_LINE_BYTES + 1), b"")):
        if len(raw) > MAX_LINE_BYTES and not raw.endswith(b"\n"):
            raise InputError(f"{what} {str(path)!r} line {n + 1} is longer than "
                             f"{MAX_LINE_BYTES} bytes (at offset {offset}); a CSV row is "
                             f"far shorter")
        if n == 0:
            for bom, name in _CSV_BOMS:
                if raw.startswith(bom):
                    raise InputError(f"{what} {str(path)!r} is {name} text (byte-order mark "
                                     f"at byte 0); save it as UTF-8")
            if raw.startswith(b"\xef\xbb\xbf"):  # UTF-8 byte-order mark: skipped
                raw = raw[3:]
                offset = 3
        try:
            line = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InputError(f"{what} {str(path)!r} is not UTF-8 text: byte "
                             f"0x{raw[exc.start]:02x} at offset {offset + exc.start}") from None
        nul = raw.find(b"\0")
        if nul >= 0:
            raise InputError(f"{what} {str(path)!r} is not text: NUL character at offset "
                             f"{offset + nul}")
        offset += len(raw)
        yield line


def read_csv_columns(path: str | Path, required: tuple[str, ...], *, what: str,
                     min_rows: int = 1,
                     keep: Iterable[str] | None = None) -> dict[str, FloatArray]:
    """The numeric columns of a CSV with a header row, as float arrays (``#`` lines ignored).

    ``required`` columns must be present and finite; another column is kept when every cell
    is a number (NaN allowed) and left out otherwise (a text column); ``what`` names the file
    in messages. ``keep``, if given, names the only other columns read: the rest are skipped
    unparsed (a rig log of fifty channels read for five costs the memory of five). The file
    is read as a stream (memory: the float columns kept, 8 bytes a value),
    as strict UTF-8, and every row must have one value per column of the header. Only a
    regular file is read (a FIFO or a device is refused), each line at most
    :data:`MAX_LINE_BYTES`.

    Raises
    ------
    InputError
        The file cannot be read or is not a regular file, has a line longer than
        :data:`MAX_LINE_BYTES`, is not UTF-8 (the message names the byte offset), has no
        header, names a column twice, lacks a required column, has a row with more or fewer
        values than the header names (a row cut short), has fewer than ``min_rows`` data
        rows, or holds a value that is not a number (the message names the line and column).
    """
    path = Path(path)
    want = ", ".join(required)
    header: list[str] | None = None
    values: list[array[float] | None] = []
    need: list[bool] = []
    rows = 0
    try:
        with open_input(path, what) as fh:  # a regular file (not a FIFO, not a device)
            reader = csv.reader(_text_lines(fh, path, what))
            for row in reader:
                if not row or row[0].lstrip().startswith("#"):
                    continue
                lineno = reader.line_num
                if header is None:
                    header = [name.strip() for name in row]
                    twice = sorted({h for h in header if header.count(h) > 1})
                    if twice:
                        raise InputError(f"{what} {str(path)!r} names column(s) "
                                         f"{', '.join(repr(h) for h in twice)} twice; name "
                                         f"each column once")
                    missing = [c for c in required if c not in header]
                    if missing:
                        raise InputError(
                            f"{what} {str(path)!r} lacks column(s) {', '.join(missing)}; "
                            f"expected {want} (found "
                            f"{', '.join(repr(h) for h in header) or 'none'})")
                    need = [h in required for h in header]
                    wanted = None if keep is None else {*keep, *required}
                    values = [array("d") if wanted is None or h in wanted else None
                              for h in header]
                    continue
                if len(row) != len(header):
                    raise InputError(
                        f"{what} {str(path)!r} line {lineno} has {len(row)} value(s), the "
                        f"header names {len(header)} columns"
                        + (" (a row cut short?)" if len(row) < len(header) else ""))
                rows += 1
                for j, cell in enumerate(row):
                    col = values[j]
                    if col is None:
                        continue  # a text column
                    try:
                        v = float(cell)
                    except ValueError:
                        if not need[j]:
                            values[j] = None
                            continue
                        raise InputError(f"{what} {str(path)!r} line {lineno}, column "
                                         f"{header[j]!r}: {cell.strip() or '(empty)'!r} is "
                                         f"not a number") from None
                    if need[j] and not math.isfinite(v):
                        raise InputError(f"{what} {str(path)!r} line {lineno}, column "
                                         f"{header[j]!r}: {cell.strip()!r} is not finite; "
                                         f"every value must be a number")
                    col.append(v)
    except OSError as exc:
        raise InputError(f"cannot read {what} {str(path)!r}: {exc.strerror or exc}") from None
    except csv.Error as exc:
        raise InputError(f"{what} {str(path)!r} is not a CSV file: {exc}") from None
    if header is None:
        raise InputError(f"{what} {str(path)!r} is empty; expected a header with {want}")
    if rows < min_rows:
        raise InputError(f"{what} {str(path)!r} has {rows} data row(s); at least "
                         f"{min_rows} needed")
    import numpy as np  # here: the command line's --version and --help import _io, not numpy

    return {name: np.frombuffer(col, dtype=np.float64)  # a view: no copy
            for name, col in zip(header, values, strict=True) if col is not None}
