"""gcc for the export tests: compile C texts into a shared library or an executable.

gcc is required: without it the helpers raise AssertionError, so the tests that use them fail
(never skip). Every build uses the strict flags the export promises to pass
(:data:`STRICT`); a failed build raises with gcc's messages.
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

__all__ = ["SANITIZE", "STRICT", "compile_executable", "compile_objects", "compile_shared",
           "gcc"]

#: The flags generated code must compile cleanly under (docs/export.md).
STRICT = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic")
#: AddressSanitizer and UndefinedBehaviorSanitizer, any report fatal, at the -O2 the
#: acceptance names.
SANITIZE = ("-O2", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all")


def gcc() -> str:
    """Path of gcc; AssertionError (a failure, not a skip) when it is missing."""
    path = shutil.which("gcc") or ("/usr/bin/gcc" if Path("/usr/bin/gcc").exists() else None)
    assert path is not None, "gcc is needed by the export tests (make test installs it)"
    return path


def _write(sources: Sequence[str] | str, out_dir: Path, stem: str) -> list[Path]:
    texts = [sources] if isinstance(sources, str) else list(sources)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for k, text in enumerate(texts):
        p = out_dir / f"{stem}_{k}.c"
        p.write_text(text, encoding="utf-8")
        paths.append(p)
    return paths


def _run(cmd: list[str], cwd: Path | None = None) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False, timeout=600,
                          cwd=cwd)
    if proc.returncode != 0:
        raise AssertionError(f"gcc failed ({' '.join(cmd)}):\n{proc.stderr}")


def compile_shared(sources: Sequence[str] | str, out_dir: Path, *,
                   flags: Sequence[str] = ("-O2",), sanitize: bool = False,
                   name: str = "harness") -> Path:
    """Compile C source texts (each one translation unit) into ``out_dir/lib{name}.so``.

    ``flags`` are added to :data:`STRICT`; ``sanitize`` adds :data:`SANITIZE` (a sanitized
    library loaded into Python needs libasan preloaded: prefer :func:`compile_executable`
    for sanitizer runs). Returns the library's path; AssertionError with gcc's stderr on
    failure.
    """
    paths = _write(sources, out_dir, name)
    lib = out_dir / f"lib{name}.so"
    _run([gcc(), *STRICT, *flags, *(SANITIZE if sanitize else ()), "-fPIC", "-shared",
          "-o", str(lib), *map(str, paths), "-lm"])
    return lib


def compile_executable(sources: Sequence[str] | str, out_dir: Path, *,
                       flags: Sequence[str] = ("-O2",), sanitize: bool = False,
                       name: str = "harness") -> Path:
    """As :func:`compile_shared`, into the executable ``out_dir/name``."""
    paths = _write(sources, out_dir, name)
    exe = out_dir / name
    _run([gcc(), *STRICT, *flags, *(SANITIZE if sanitize else ()), "-o", str(exe),
          *map(str, paths), "-lm"])
    return exe


def compile_objects(sources: Sequence[str] | str, out_dir: Path, *,
                    flags: Sequence[str] = ("-O2",), name: str = "unit") -> list[Path]:
    """Compile each C source text on its own (a translation unit each, ``-c``, no link) in
    one gcc run; returns the object files. For checks that a text compiles alone: with one
    caller per unit the compiler inlines and propagates constants across everything."""
    paths = _write(sources, out_dir, name)
    _run([gcc(), *STRICT, *flags, "-c", *map(str, paths)], cwd=out_dir)
    return [p.with_suffix(".o") for p in paths]
