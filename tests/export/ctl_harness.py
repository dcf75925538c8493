"""Load generated controller C through ctypes, and the Python runs it is compared with.

The generated code is compiled with the flags the acceptance names (``-std=c99 -Wall -Wextra
-Werror -pedantic -O2``) into a shared library; ``NAME_init`` / ``NAME_step`` /
``NAME_set_gains`` are called on an instance buffer owned by Python.
"""

from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

from fuzzyservo.export.controller_c import CController
from tests.export.cbuild import SANITIZE, STRICT, gcc

__all__ = ["SANITIZE", "STRICT", "CStep", "build", "gcc", "write"]


def write(cc: CController, folder: Path) -> Path:
    """Write the two files of ``cc`` into ``folder``; returns the source's path."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in cc.files().items():
        (folder / name).write_text(text, encoding="utf-8")
    return folder / f"{cc.name}.c"


def build(cc: CController, folder: Path, *, extra: tuple[str, ...] = ()) -> Path:
    """Compile ``cc`` into a shared library in ``folder`` (strict flags, -O2)."""
    src = write(cc, folder)
    lib = folder / f"lib{cc.name}.so"
    proc = subprocess.run([gcc(), *STRICT, "-O2", "-fPIC", "-shared", *extra, "-o", str(lib),
                           str(src), "-lm"], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    return lib


class CStep:
    """One instance of a generated controller, driven from Python."""

    def __init__(self, lib: Path, cc: CController) -> None:
        self.cc = cc
        self.dll = ctypes.CDLL(str(lib))
        real = ctypes.c_double if cc.real == "double" else ctypes.c_float
        self.real = real
        n = cc.name
        self._init = getattr(self.dll, f"{n}_init")
        self._init.argtypes = [ctypes.c_void_p, real, real]
        self._init.restype = None
        self._step = getattr(self.dll, f"{n}_step")
        self._step.argtypes = [ctypes.c_void_p, real, real]
        self._step.restype = real
        self._step_ff = getattr(self.dll, f"{n}_step_ff")
        self._step_ff.argtypes = [ctypes.c_void_p, real, real, real, real]
        self._step_ff.restype = real
        self._reset = getattr(self.dll, f"{n}_reset")
        self._reset.argtypes = [ctypes.c_void_p, real, real]
        self._reset.restype = None
        self._set = getattr(self.dll, f"{n}_set_gains")
        self._set.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_double)]
        self._set.restype = ctypes.c_int
        self.buf = ctypes.create_string_buffer(4096)

    def init(self, y0: float, u0: float) -> None:
        self._init(self.buf, y0, u0)

    def reset(self, y0: float, u0: float) -> None:
        self._reset(self.buf, y0, u0)

    def step(self, r: float, y: float) -> float:
        return float(self._step(self.buf, r, y))

    def set_gains(self, gains: list[float]) -> int:
        arr = (ctypes.c_double * len(gains))(*gains)
        return int(self._set(self.buf, arr))

    def step_ff(self, r: float, rd: float, rdd: float, y: float) -> float:
        return float(self._step_ff(self.buf, r, rd, rdd, y))

    def replay(self, r: Any, y: Any, y0: float, u0: float, gains: list[float] | None = None,
               rates: tuple[Any, Any] | None = None) -> np.ndarray:
        """Commands for the measured samples (r_k, y_k) of a run, from the bumpless start
        with the exported gains, or with ``gains`` (set through NAME_set_gains); with
        ``rates`` (the run's rd_k, rdd_k) through NAME_step_ff."""
        self.init(y0, u0)
        if gains is not None:
            assert self.set_gains(gains) == 0
            self.reset(y0, u0)
        if rates is not None:
            return np.array([self.step_ff(float(a), float(v), float(w), float(b))
                             for a, v, w, b in zip(r, *rates, y, strict=True)])
        return np.array([self.step(float(a), float(b)) for a, b in zip(r, y, strict=True)])
