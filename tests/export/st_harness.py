"""MatIEC, the outside checker of the exported Structured Text: translate, compile, run.

MatIEC (``iec2c``, the IEC 61131-3 compiler of Beremiz and OpenPLC) is built by ``make test``
(target ``matiec``) into ``.oracles/matiec`` of the checkout, from ``$MATIEC_SRC`` or
``../shared/oracles/matiec/``; ``$FUZZYSERVO_MATIEC`` names another install prefix. Without it
the helpers raise AssertionError: the tests that use them fail, never skip.

:class:`STBlock` translates a generated function block with ``iec2c``, compiles the C it
writes (with MatIEC's runtime headers) and a small shim into a shared library with gcc, and
runs the block over rows of inputs through ctypes: each row sets every input of the block
(the signals, ENABLE, RESET, HOLD_COMMAND and every gain), runs its body once (one PLC cycle)
and reads its outputs.
"""

from __future__ import annotations

import ctypes
import os
import subprocess
from pathlib import Path

import numpy as np

from fuzzyservo.export.st import INPUTS, STController
from tests.export.cbuild import gcc

__all__ = ["STBlock", "iec2c", "matiec_prefix", "translate"]

ROOT = Path(__file__).resolve().parents[2]


def matiec_prefix() -> Path:
    """MatIEC's install prefix (``bin/iec2c``, ``lib/``); AssertionError when missing."""
    prefix = Path(os.environ.get("FUZZYSERVO_MATIEC") or ROOT / ".oracles" / "matiec")
    assert (prefix / "bin" / "iec2c").is_file() and (prefix / "lib" / "C").is_dir(), (
        f"MatIEC (iec2c) is needed by the Structured Text tests and is not in {prefix}: "
        f"'make matiec' builds it (make test does) from $MATIEC_SRC or "
        f"../shared/oracles/matiec/matiec-src.tar.gz")
    return prefix


def iec2c() -> Path:
    return matiec_prefix() / "bin" / "iec2c"


def translate(text: str, folder: Path, name: str = "prog.st") -> subprocess.CompletedProcess[str]:
    """Run ``iec2c`` on ``text`` (written to ``folder/name``); C into ``folder/c``."""
    folder.mkdir(parents=True, exist_ok=True)
    src = folder / name
    src.write_text(text, encoding="utf-8")
    out = folder / "c"
    out.mkdir(exist_ok=True)
    return subprocess.run([str(iec2c()), "-I", str(matiec_prefix() / "lib"), "-T", str(out),
                           str(src)], capture_output=True, text=True, check=False, timeout=300)


_SHIM = """
#include "iec_std_lib.h"
#include "POUS.h"
#include "POUS.c"
#include <string.h>

/* one block instance, zeroed before its init (a stray flag bit makes writes no-ops) */
static @FB@ fb;

void st_init(void)
{
    memset(&fb, 0, sizeof fb);
    @FB@_init__(&fb, 0);
}

/* rows of inputs (n x @NIN@) -> rows of outputs (n x 4): COMMAND, ALPHA or NaN,
   GAIN_ERROR, ACTIVE; one body call (one PLC cycle) per row */
void st_run(long n, const double *in, double *out)
{
    long k;
    for (k = 0; k < n; k++) {
        const double *x = in + k * @NIN@;
        double *o = out + k * 4;
@SETS@
        @FB@_body__(&fb);
        o[0] = (double)fb.COMMAND.value;
        o[1] = @ALPHA@;
        o[2] = (double)fb.GAIN_ERROR.value;
        o[3] = fb.ACTIVE.value ? 1.0 : 0.0;
    }
}
"""


class STBlock:
    """One generated block, translated by MatIEC and compiled, driven from Python.

    Input columns (:attr:`columns`): ENABLE, RESET, SETPOINT, MEASUREMENT, SETPOINT_RATE,
    SETPOINT_ACCEL, HOLD_COMMAND, then the gains in the block's order.
    """

    def __init__(self, st: STController, folder: Path) -> None:
        self.st = st
        proc = translate(st.block, folder, f"{st.name}.st")
        assert proc.returncode == 0, f"iec2c refused {st.name}.st:\n{proc.stdout}{proc.stderr}"
        fb = st.name.upper()
        self.columns = ("ENABLE", "RESET", *(n for n, _ in INPUTS), *st.gain_names)
        sets = []
        for i, c in enumerate(self.columns):
            if c in ("ENABLE", "RESET"):
                sets.append(f"        fb.{c}.value = x[{i}] != 0.0;")
            else:
                sets.append(f"        fb.{c}.value = ({st.real})x[{i}];")
        alpha = "(double)fb.ALPHA.value" if st.self_tuning else "__builtin_nan(\"\")"
        shim = (_SHIM.replace("@FB@", fb).replace("@NIN@", str(len(self.columns)))
                .replace("@SETS@", "\n".join(sets)).replace("@ALPHA@", alpha))
        c_dir = folder / "c"
        (c_dir / "shim.c").write_text(shim, encoding="utf-8")
        lib = folder / f"lib{st.name}_st.so"
        cmd = [gcc(), "-std=gnu11", "-O2", "-ffp-contract=off", "-fPIC", "-shared",
               "-w", "-I", str(matiec_prefix() / "lib" / "C"), "-I", str(c_dir), "-o",
               str(lib), str(c_dir / "shim.c"), "-lm"]
        built = subprocess.run(cmd, capture_output=True, text=True, check=False, timeout=600)
        assert built.returncode == 0, f"gcc failed on MatIEC's C:\n{built.stderr}"
        self.dll = ctypes.CDLL(str(lib))
        self.dll.st_init.restype = None
        self.dll.st_run.restype = None
        self.dll.st_run.argtypes = [ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p]
        self.dll.st_init()

    def run(self, rows: np.ndarray) -> np.ndarray:
        """Outputs (n, 4) of the input rows (n, len(columns)), one cycle per row."""
        x = np.ascontiguousarray(rows, dtype=np.float64)
        assert x.ndim == 2 and x.shape[1] == len(self.columns), x.shape
        out = np.empty((x.shape[0], 4))
        self.dll.st_run(x.shape[0], x.ctypes.data, out.ctypes.data)
        return out

    def rows(self, r: np.ndarray, y: np.ndarray, *, rd: np.ndarray | None = None,
             rdd: np.ndarray | None = None, hold: float = 0.0, enable: np.ndarray | None = None,
             reset: np.ndarray | None = None, gains: np.ndarray | None = None) -> np.ndarray:
        """Input rows from signals (defaults: enabled, no reset, zero rates, the exported
        gains)."""
        n = len(r)
        g = np.tile(np.asarray(self.st.gains, dtype=np.float64), (n, 1)) if gains is None \
            else np.asarray(gains, dtype=np.float64)
        cols = [np.ones(n) if enable is None else enable,
                np.zeros(n) if reset is None else reset,
                r, y, np.zeros(n) if rd is None else rd, np.zeros(n) if rdd is None else rdd,
                np.full(n, hold)]
        return np.column_stack([*cols, g.reshape(n, -1)])
