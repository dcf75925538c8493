"""The compiled core's machinery: one decorator, a cache that cannot go stale, specialised
copies of the loops for each control law, and a notice whenever something is compiled.

Every compiled function of the package is declared with :func:`kernel` (numba's ``njit``
with ``cache=True`` and ``nogil=True``). Inlining is LLVM's, never numba's IR-level
``inline="always"`` (which re-runs and deep-copies the callee's pipeline at every call site:
the cost that made a cold start take two minutes): ``kernel(inline=True)`` marks the function
``alwaysinline`` for LLVM, and ``forceinline`` is always set explicitly because numba lets a
callee inherit its caller's value (docs/architecture.md, "Compiled kernels").

**The cache.** numba invalidates a cached function only when its own file changes, not when a
function it calls in another file does. Here the cache of every function of the package lives
in a folder named by a digest of all the package's Python sources and of the numba, llvmlite
and Python versions (:func:`cache_dir`), so an edit anywhere compiles afresh what depends on
it, and nothing stale can run. The folder is ``$FUZZYSERVO_CACHE_DIR``, else under
``$NUMBA_CACHE_DIR``, else the user's cache folder (``$XDG_CACHE_HOME`` or ``~/.cache``), so a
read-only install works; when none is writable, a folder in the temporary directory.

**Specialisation.** A loop that runs a control law is written once, as a template that calls
the law through module globals (``LAW_STEP`` ...); :func:`specialize` makes a compiled copy of
a family of templates with those globals bound to one law's functions, named (and cached) by
the law's key. So each law compiles only its own loops, a law added later costs nothing to
the others, and LLVM inlines the law into its loops.

**Never silent.** A compile of a package function that lasts more than half a second prints
one line on standard error saying what is being compiled, that it happens once per install,
and about how long it takes, then its progress; runs that load the cache print nothing.
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import tempfile
import threading
import time
import types
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar, cast

import numba
import numba.extending
from numba.core import caching, event
from numba.np.arrayobj import make_array

__all__ = [
    "PACKAGE_DIR",
    "cache_dir",
    "data_pointer",
    "describe",
    "kernel",
    "source_digest",
    "specialize",
    "template",
]

F = TypeVar("F", bound=Callable[..., Any])

#: The package's folder: the functions whose cache this module places.
PACKAGE_DIR = Path(__file__).resolve().parent


# ---------------------------------------------------------------------------------------------
# the cache folder, keyed by the sources


@functools.cache
def source_digest() -> str:
    """SHA-256 (hex, 16 characters) of every Python source of the package (path and bytes, in
    path order) and of the numba, llvmlite and Python versions: the key of the cache folder.
    Computed once per process (about 5 ms)."""
    import llvmlite

    h = hashlib.sha256()
    h.update(f"numba {numba.__version__} llvmlite {llvmlite.__version__} "
             f"python {sys.version}".encode())
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        rel = path.relative_to(PACKAGE_DIR).as_posix()
        h.update(rel.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def _writable(path: Path) -> bool:
    try:
        path.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError:
        return False
    return True


@functools.cache
def cache_dir() -> Path:
    """The folder of this install's compiled kernels (created): ``BASE/<source digest>``.

    BASE is ``$FUZZYSERVO_CACHE_DIR``; else ``$NUMBA_CACHE_DIR/fuzzyservo``; else
    ``$XDG_CACHE_HOME/fuzzyservo`` or ``~/.cache/fuzzyservo``; the first of them that can be
    written, else ``<tmp>/fuzzyservo-<uid>``."""
    bases: list[Path] = []
    if os.environ.get("FUZZYSERVO_CACHE_DIR"):
        bases.append(Path(os.environ["FUZZYSERVO_CACHE_DIR"]))
    elif os.environ.get("NUMBA_CACHE_DIR"):
        bases.append(Path(os.environ["NUMBA_CACHE_DIR"]) / "fuzzyservo")
    else:
        xdg = os.environ.get("XDG_CACHE_HOME")
        bases.append(Path(xdg) / "fuzzyservo" if xdg else Path.home() / ".cache" / "fuzzyservo")
    uid = os.getuid() if hasattr(os, "getuid") else 0
    bases.append(Path(tempfile.gettempdir()) / f"fuzzyservo-{uid}")
    digest = source_digest()
    for base in bases:
        folder = base / digest
        if _writable(folder):
            return folder
    raise OSError(f"no writable folder for the compiled kernels among {bases}")


class _Locator(caching._CacheLocator):
    """numba cache locator of the package's functions: ``cache_dir()/<subpackage>``, the
    source stamp numba's (the file's hash)."""

    def __init__(self, py_func: Any, py_file: str) -> None:
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        rel = Path(py_file).resolve().parent.relative_to(PACKAGE_DIR)
        self._path = str(cache_dir().joinpath(*rel.parts))

    def get_cache_path(self) -> str:
        return self._path

    def get_source_stamp(self) -> Any:
        st = os.stat(self._py_file)
        return caching._hash_source_file(self._py_file, st.st_mtime, st.st_size)

    def get_disambiguator(self) -> str:
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> _Locator | None:
        try:
            Path(py_file).resolve().relative_to(PACKAGE_DIR)
        except ValueError:
            return None  # not ours: numba's own locators
        try:
            self = cls(py_func, py_file)
            self.ensure_cache_path()  # type: ignore[no-untyped-call]
        except OSError:
            return None
        return self


if _Locator not in caching.CacheImpl._locator_classes:
    caching.CacheImpl._locator_classes.insert(0, _Locator)


# ---------------------------------------------------------------------------------------------
# declaring compiled functions


def kernel(fn: F | None = None, *, inline: bool = False, error_model: str = "python",
           parallel: bool = False, cache: bool | None = None) -> Any:
    """``numba.njit(cache=True, nogil=True)`` with LLVM-level inlining when ``inline``.

    ``error_model`` is numba's (``"numpy"``: a division by zero gives inf/NaN, no check).
    ``forceinline`` is always passed explicitly, so a callee never inherits its caller's.
    ``cache`` None: cached when the function comes from a file (or a notebook cell), not when
    it was made by ``exec`` of a string (which numba cannot cache)."""
    def wrap(f: F) -> F:
        use_cache = _cacheable(f) if cache is None else cache
        njit: Any = numba.njit
        return cast(F, njit(cache=use_cache, nogil=not parallel, forceinline=inline,
                            error_model=error_model, parallel=parallel)(f))
    return wrap(fn) if fn is not None else wrap


def _cacheable(f: Callable[..., Any]) -> bool:
    name = f.__code__.co_filename
    return os.path.isfile(name) or name.startswith("<ipython-input")


def template(fn: F | None = None, *, inline: bool = False, error_model: str = "python",
             about: str = "", seconds: float = 0.0) -> Any:
    """Mark a plain function as a template of :func:`specialize` (it stays uncompiled): its
    compile options, and for a top-level kernel what it is (``about``, e.g. "the closed loop on
    the linear plant") and about how long it compiles [s]."""
    def mark(f: F) -> F:
        f.__jit_options__ = {"inline": inline, "error_model": error_model}  # type: ignore
        f.__jit_about__ = (about, seconds)  # type: ignore[attr-defined]
        return f
    return mark(fn) if fn is not None else mark


#: What a specialised kernel is, by its qualname: (description, seconds to compile).
_ABOUT: dict[str, tuple[str, float]] = {}


def describe(qualname: str) -> tuple[str, float] | None:
    """What the kernel ``qualname`` is and about how long it compiles [s], if declared."""
    return _ABOUT.get(qualname)


def specialize(templates: Iterable[Callable[..., Any]], globals_: Mapping[str, Any], *,
               key: str, title: str, cache: bool = True) -> types.SimpleNamespace:
    """Compiled copies of ``templates`` (functions of one module, marked with
    :func:`template`) whose module globals are overridden by ``globals_``.

    The copies see each other under their template names, so a family of templates that call
    one another is copied as a whole. Each copy is named ``<name>__<key>`` (``key``: letters,
    digits and _), which names its numba cache files, so the copies of different keys never
    share a cache entry; ``title`` (e.g. "the self-tuning fuzzy PI") completes the
    description of the compile notice. ``cache`` False: the copies are not cached (what they
    call has no file the key could cover).

    Returns
    -------
    types.SimpleNamespace
        The compiled copies by template name.
    """
    tpls = list(templates)
    if not tpls:
        return types.SimpleNamespace()
    if not key.replace("_", "").isalnum():
        raise ValueError(f"specialization key must be letters, digits and _, got {key!r}")
    module_globals = tpls[0].__globals__
    ns: dict[str, Any] = dict(module_globals)
    ns.update(globals_)
    out: dict[str, Any] = {}
    for tpl in tpls:
        if tpl.__globals__ is not module_globals:
            raise ValueError("templates of one specialization come from one module")
        copy = types.FunctionType(tpl.__code__, ns, tpl.__name__, tpl.__defaults__,
                                  tpl.__closure__)
        copy.__qualname__ = f"{tpl.__name__}__{key}"
        copy.__module__ = tpl.__module__
        copy.__doc__ = tpl.__doc__
        opts = getattr(tpl, "__jit_options__", {"inline": False, "error_model": "python"})
        about, seconds = getattr(tpl, "__jit_about__", ("", 0.0))
        if about:
            _ABOUT[copy.__qualname__] = (f"{about} for {title}", seconds)
        out[tpl.__name__] = ns[tpl.__name__] = kernel(copy, **opts, cache=None if cache else False)
    return types.SimpleNamespace(**out)


# ---------------------------------------------------------------------------------------------
# data pointers


@numba.extending.intrinsic
def _data_pointer(typingctx: Any, arr: Any) -> Any:
    """The data pointer of an array (``CPointer(dtype)``), indexed as ``ptr[i]``.

    Compiled code passes pointers, not arrays, to the functions it calls per sample: an array
    argument is reference-counted with an atomic operation per call, which cost more than the
    fuzzy evaluation itself; a pointer is a plain value. The array must outlive the pointer
    and be indexed within its bounds (no check is made).
    """
    if not isinstance(arr, numba.types.Array):
        return None
    sig = numba.types.CPointer(arr.dtype)(arr)  # type: ignore[no-untyped-call]

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        ary = make_array(signature.args[0])(  # type: ignore[no-untyped-call]
            context, builder, value=args[0])
        return ary.data

    return sig, codegen


#: The intrinsic as a plain callable for the type checker (numba sees the same object).
data_pointer = cast(Callable[[Any], Any], _data_pointer)


# ---------------------------------------------------------------------------------------------
# the compile notice


#: A compile shorter than this says nothing [s].
QUIET_BELOW = 0.5
#: Seconds between two progress lines on a terminal [s] (elsewhere: one line per kernel).
_TICK = 1.0


class _Notice(event.Listener):
    """Prints, on standard error, what numba is compiling of the package once a compile has
    lasted :data:`QUIET_BELOW` seconds, then its progress, then how long it took."""

    def __init__(self) -> None:
        self._depth = 0
        self._active = False
        self._t0 = 0.0
        self._name = ""
        self._module = ""
        self._current = ""
        self._announced = False
        self._said_header = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @staticmethod
    def _ours(ev: event.Event) -> str | None:
        disp = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
        func = getattr(disp, "py_func", None)
        if func is None:
            return None
        mod = getattr(func, "__module__", "") or ""
        return func.__qualname__ if mod.startswith("fuzzyservo") else None

    def on_start(self, ev: event.Event) -> None:
        name = self._ours(ev) if os.environ.get("FUZZYSERVO_COMPILE_NOTICE") != "0" else None
        with self._lock:
            if name is not None:
                self._current = name
            self._depth += 1
            if self._depth != 1:
                return
            self._active = name is not None  # a compile not of the package: nothing said
            if not self._active:
                return
            self._t0 = time.perf_counter()
            self._name = name or ""
            disp = ev.data.get("dispatcher")
            self._module = getattr(getattr(disp, "py_func", None), "__module__", "") or ""
            self._announced = False
            self._stop.clear()
            self._thread = threading.Thread(target=self._watch, daemon=True)
            self._thread.start()

    def on_end(self, ev: event.Event) -> None:
        with self._lock:
            self._depth -= 1
            if self._depth != 0 or not self._active:
                return
            self._stop.set()
            announced = self._announced
            secs = time.perf_counter() - self._t0
            thread, self._thread = self._thread, None
        if thread is not None:
            thread.join()
        if announced:
            _say(f"fuzzyservo: compiled {self._what()} in {secs:.0f} s", end_line=True)

    def _what(self) -> str:
        about = describe(self._name)
        if about:
            return about[0]
        return f"{self._name.split('__')[0]} ({self._module})"

    def _watch(self) -> None:
        if self._stop.wait(QUIET_BELOW):
            return
        with self._lock:
            self._announced = True
            about = describe(self._name)
            first = not self._said_header
            self._said_header = True
        if first:
            _say("fuzzyservo: compiling the simulation kernels (numba; once per install, then "
                 f"they load from {cache_dir()})", end_line=True)
        est = f", about {about[1]:.0f} s" if about and about[1] else ""
        _say(f"fuzzyservo: compiling {self._what()}{est}", end_line=True)
        tty = sys.stderr.isatty()
        while not self._stop.wait(_TICK):
            if tty:
                secs = time.perf_counter() - self._t0
                _say(f"  ... {secs:.0f} s, now {self._current.split('__')[0]}", end_line=False)


def _say(text: str, *, end_line: bool) -> None:
    stream = sys.stderr
    try:
        if stream.isatty():
            stream.write("\r\033[K" + text + ("\n" if end_line else ""))
        elif end_line:
            stream.write(text + "\n")
        stream.flush()
    except (OSError, ValueError):  # a closed or full stderr: compile on, silently
        pass


_NOTICE = _Notice()
event.register("numba:compile", _NOTICE)  # type: ignore[no-untyped-call]
