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
- Every input file is opened by :func:`open_input`: a regular file only (a FIFO, a device, a
  folder is refused on one line; a FIFO without a writer does not block), and a file read
  whole (:func:`read_bytes`, :func:`read_text`) is read with a bounded read, at most
  :data:`MAX_INPUT_BYTES` (a device or a file still growing cannot make it read for ever).
- :func:`parse_toml` and :func:`parse_json` bound the nesting of arrays and tables to
  :data:`MAX_NESTING` levels before parsing (both parsers recurse) and after (TOML's dotted
  keys nest without brackets).
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
import re
import signal
import stat
import tempfile
import threading
import zipfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, Any, BinaryIO, Literal, overload

from .errors import InputError, OutputError

__all__ = [
    "MAX_INPUT_BYTES",
    "MAX_NESTING",
    "Terminated",
    "atomic_write",
    "check_output_path",
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
        standard output), its folder does not exist or is not writable, or it names one of
        ``inputs`` (files the same command reads).
    """
    p = Path(path)
    if _standard_stream(p):
        raise InputError(f"{option} {str(p)!r} is a standard stream, not a file: give a file "
                         f"name, or {option} - where the command writes to standard output")
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


# what may hold brackets without nesting: strings (TOML's four kinds, JSON's one) and comments
_TOML_SKIP = re.compile(r'"""(?:[^\\]|\\.)*?"""|\'\'\'.*?\'\'\'|"(?:[^"\\\n]|\\.)*"|'
                        r"'[^'\n]*'|#[^\n]*|[\[\]{}]", re.DOTALL)
_JSON_SKIP = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]', re.DOTALL)


def _check_brackets(text: str, pattern: re.Pattern[str], what: str) -> None:
    depth = 0
    for m in pattern.finditer(text):
        c = m.group()
        if c in "[{":
            depth += 1
            if depth > MAX_NESTING:
                raise InputError(f"{what} nests arrays or tables more than {MAX_NESTING} "
                                 f"levels deep (at character {m.start()}); at most "
                                 f"{MAX_NESTING} are read")
        elif c in "]}":
            depth = max(depth - 1, 0)


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

    _check_brackets(text, _TOML_SKIP, what)
    try:
        doc = tomllib.loads(text)
    except ValueError as exc:  # TOMLDecodeError, or an integer of > 4300 digits
        why = " ".join(str(exc).split())[:200]
        raise InputError(f"{what} is not valid TOML: {why}") from None
    except RecursionError:  # not reached with the bound above; never a traceback
        raise InputError(f"{what} nests too deep to be read") from None
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
    _check_brackets(text, _JSON_SKIP, what)
    try:
        return json.loads(text)
    except ValueError as exc:  # JSONDecodeError, or an integer of > 4300 digits
        why = " ".join(str(exc).split())[:200]
        raise InputError(f"{what} is not valid JSON: {why}") from None
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
