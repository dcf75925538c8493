"""A C harness around the fuzzy evaluators' fragment (``csrc/fuzzy.c``), for the tests.

One source serves both ways of running it:

- a shared library loaded with ctypes (:class:`CFuzzy`): batch wrappers of ``fs_grid_eval``,
  ``fs_grid_pair``, ``fs_sys_eval``, ``fs_sys_eval2`` on tables passed from numpy, and of the
  functions :func:`~fuzzyservo.export.fuzzy_c.emit_system` / ``emit_pair`` generated;
- an executable (``-DFSH_MAIN``) that reads cases from a binary file and writes the outputs
  (:func:`run_cases`): the sanitizer builds run this way, through ``fs_sys_eval_s`` (and
  ``fs_sys_eval2`` for two inputs) with each scratch array ``malloc``'ed at exactly the size
  ``scratch_sizes`` claims (the library runs ``fs_sys_eval`` and ``fs_sys_eval2``).
"""

from __future__ import annotations

import ctypes
import struct
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fuzzyservo.export.fuzzy_c import emit_pair, emit_system, fragment, scratch_sizes

from .cbuild import compile_executable, compile_shared

#: Wrappers with external linkage (the fragment's functions are static), and the case-file
#: driver. @EMITTED@ is replaced by the emitted systems' dispatch.
HARNESS = r"""
void fsh_grid(int n, const fs_real *x1, const fs_real *x2, const int32_t *rules, int n2,
              int n1, const fs_real *lims, fs_real *out)
{
    int i;
    for (i = 0; i < n; ++i) out[i] = fs_grid_eval(x1[i], x2[i], rules, n2, n1, lims);
}

void fsh_pair(int n, const fs_real *x1, const fs_real *x2, const int32_t *ra, int n2a,
              int n1a, const fs_real *la, const int32_t *rb, int n2b, int n1b,
              const fs_real *lb, fs_real *out_a, fs_real *out_b)
{
    int i;
    for (i = 0; i < n; ++i)
        fs_grid_pair(x1[i], x2[i], ra, n2a, n1a, la, rb, n2b, n1b, lb, out_a + i, out_b + i);
}

void fsh_sys(int n, const fs_real *x, fs_real *out, const int32_t *ints, const fs_real *f,
             fs_real *work, int32_t *iwork)
{
    int i;
    for (i = 0; i < n; ++i)
        fs_sys_eval(x + (long)i * ints[FS_H_NIN], out + (long)i * ints[FS_H_NOUT], ints, f,
                    work, iwork);
}

void fsh_sys2(int n, const fs_real *x1, const fs_real *x2, fs_real *out, const int32_t *ints,
              const fs_real *f, fs_real *work, int32_t *iwork)
{
    int i;
    for (i = 0; i < n; ++i) out[i] = fs_sys_eval2(x1[i], x2[i], ints, f, work, iwork);
}

@EMITTED@

#ifdef FSH_MAIN
#include <stdio.h>
#include <stdlib.h>

static FILE *fsh_in, *fsh_out;

static void fsh_fail(const char *what)
{
    fprintf(stderr, "harness: %s\n", what);
    exit(3);
}

static int32_t fsh_int(void)
{
    int32_t v;
    if (fread(&v, sizeof v, 1, fsh_in) != 1) fsh_fail("short read");
    return v;
}

static int32_t *fsh_ints(long n)
{
    int32_t *p = (int32_t *)malloc((size_t)(n > 0 ? n : 1) * sizeof *p);
    if (!p || (n > 0 && fread(p, sizeof *p, (size_t)n, fsh_in) != (size_t)n)) fsh_fail("ints");
    return p;
}

/* n reals, read as doubles; exactly n allocated */
static fs_real *fsh_reals(long n)
{
    long i;
    fs_real *p = (fs_real *)malloc((size_t)(n > 0 ? n : 1) * sizeof *p);
    if (!p) fsh_fail("malloc");
    for (i = 0; i < n; ++i) {
        double v;
        if (fread(&v, sizeof v, 1, fsh_in) != 1) fsh_fail("reals");
        p[i] = (fs_real)v;
    }
    return p;
}

static void fsh_put(const fs_real *p, long n)
{
    long i;
    for (i = 0; i < n; ++i) {
        double v = (double)p[i];
        fwrite(&v, sizeof v, 1, fsh_out);
    }
}

static void fsh_grid_read(int32_t **rules, int *n2, int *n1, fs_real **lims)
{
    *n2 = fsh_int();
    *n1 = fsh_int();
    *rules = fsh_ints((long)*n2 * *n1);
    *lims = fsh_reals(8);
}

int main(int argc, char **argv)
{
    if (argc != 3) fsh_fail("usage: harness cases outputs");
    fsh_in = fopen(argv[1], "rb");
    fsh_out = fopen(argv[2], "wb");
    if (!fsh_in || !fsh_out) fsh_fail("open");
    for (;;) {
        int32_t kind = fsh_int();
        if (kind < 0) break;
        if (kind == 0 || kind == 1) {
            int32_t *ra, *rb = NULL;
            int n2a, n1a, n2b = 0, n1b = 0, n;
            fs_real *la, *lb = NULL, *x1, *x2, *oa, *ob;
            fsh_grid_read(&ra, &n2a, &n1a, &la);
            if (kind == 1) fsh_grid_read(&rb, &n2b, &n1b, &lb);
            n = fsh_int();
            x1 = fsh_reals(n);
            x2 = fsh_reals(n);
            oa = (fs_real *)malloc((size_t)(n > 0 ? n : 1) * sizeof *oa);
            ob = (fs_real *)malloc((size_t)(n > 0 ? n : 1) * sizeof *ob);
            if (!oa || !ob) fsh_fail("malloc");
            if (kind == 0) {
                fsh_grid(n, x1, x2, ra, n2a, n1a, la, oa);
                fsh_put(oa, n);
            } else {
                fsh_pair(n, x1, x2, ra, n2a, n1a, la, rb, n2b, n1b, lb, oa, ob);
                fsh_put(oa, n);
                fsh_put(ob, n);
            }
            free(ra); free(rb); free(la); free(lb); free(x1); free(x2); free(oa); free(ob);
        } else if (kind == 2) {
            long n_ints = fsh_int(), n_floats, n_work, n_iwork, n_smooth, n_single, n_in, n_out;
            long n, i;
            int32_t *ints = fsh_ints(n_ints), *iwork;
            fs_real *f, *work, *x, *out, *x1, *x2, *o2, *smooth = NULL;
            n_floats = fsh_int();
            f = fsh_reals(n_floats);
            n_work = fsh_int();
            n_iwork = fsh_int();
            n_smooth = fsh_int();
            n_single = fsh_int();
            n_in = fsh_int();
            n_out = fsh_int();
            n = fsh_int();
            x = fsh_reals(n * n_in);
            /* the _s functions, each scratch array exactly as large as claimed */
            work = (fs_real *)malloc((size_t)n_work * sizeof *work);
            iwork = (int32_t *)malloc((size_t)n_iwork * sizeof *iwork);
            if (n_smooth > 0) smooth = (fs_real *)malloc((size_t)n_smooth * sizeof *smooth);
            if (n_smooth > 0 && !smooth) fsh_fail("malloc");
            out = (fs_real *)malloc((size_t)(n * n_out > 0 ? n * n_out : 1) * sizeof *out);
            if (!work || !iwork || !out) fsh_fail("malloc");
            /* one point at a time, each in an array of exactly n_in (overreads are caught) */
            for (i = 0; i < n; ++i) {
                fs_real *xi = (fs_real *)malloc((size_t)(n_in > 0 ? n_in : 1) * sizeof *xi);
                fs_real *oi = (fs_real *)malloc((size_t)n_out * sizeof *oi);
                if (!xi || !oi) fsh_fail("malloc");
                memcpy(xi, x + i * n_in, (size_t)n_in * sizeof *xi);
                fs_sys_eval_s(xi, oi, ints, f, work, iwork, smooth);
                memcpy(out + i * n_out, oi, (size_t)n_out * sizeof *oi);
                free(xi);
                free(oi);
            }
            fsh_put(out, n * n_out);
            if (n_in == 2) {
                /* fs_sys_eval2: everything in one array of exactly n_single */
                fs_real *one = (fs_real *)malloc((size_t)n_single * sizeof *one);
                x1 = (fs_real *)malloc((size_t)(n > 0 ? n : 1) * sizeof *x1);
                x2 = (fs_real *)malloc((size_t)(n > 0 ? n : 1) * sizeof *x2);
                o2 = (fs_real *)malloc((size_t)(n > 0 ? n : 1) * sizeof *o2);
                if (!one || !x1 || !x2 || !o2) fsh_fail("malloc");
                for (i = 0; i < n; ++i) {
                    x1[i] = x[2 * i];
                    x2[i] = x[2 * i + 1];
                }
                for (i = 0; i < n; ++i) o2[i] = fs_sys_eval2(x1[i], x2[i], ints, f, one, iwork);
                fsh_put(o2, n);
                free(one); free(x1); free(x2); free(o2);
            }
            free(ints); free(f); free(work); free(iwork); free(smooth); free(x); free(out);
        } else if (kind == 3) {
            int k = fsh_int(), n = fsh_int();
            fs_real *x1 = fsh_reals(n), *x2 = fsh_reals(n), *oa, *ob;
            oa = (fs_real *)malloc((size_t)(n > 0 ? n : 1) * sizeof *oa);
            ob = (fs_real *)malloc((size_t)(n > 0 ? n : 1) * sizeof *ob);
            if (!oa || !ob) fsh_fail("malloc");
            fsh_emitted(k, n, x1, x2, oa, ob);
            fsh_put(oa, n);
            fsh_put(ob, n);
            free(x1); free(x2); free(oa); free(ob);
        } else {
            fsh_fail("unknown case");
        }
    }
    fclose(fsh_out);
    fclose(fsh_in);
    return 0;
}
#endif
"""


@dataclass
class Emitted:
    """Systems to emit into the harness: ``(name, rules, lims)`` singles and
    ``(name, du, alpha)`` pairs, evaluated through ``fsh_emitted(k, ...)`` in this order
    (singles first)."""

    singles: list[tuple[str, np.ndarray, np.ndarray]] = field(default_factory=list)
    pairs: list[tuple[str, tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]] = \
        field(default_factory=list)


def source(real: str, emitted: Emitted | None = None) -> str:
    """The harness's C text for ``real`` ("double" or "float")."""
    em = emitted or Emitted()
    head = "typedef double fs_real;\n" if real == "double" else \
        "typedef float fs_real;\n#define FS_FLOAT 1\n"
    defs = "".join(emit_system(n, r, m, real=real) for n, r, m in em.singles)  # type: ignore[arg-type]
    defs += "".join(emit_pair(n, du, al, real=real) for n, du, al in em.pairs)  # type: ignore[arg-type]
    cases = []
    for k, (n, _, _) in enumerate(em.singles):
        cases.append(f"    case {k}: for (i = 0; i < n; ++i) {{ oa[i] = {n}(x1[i], x2[i]); "
                     f"ob[i] = 0; }} break;")
    for k, (n, _, _) in enumerate(em.pairs, start=len(em.singles)):
        cases.append(f"    case {k}: for (i = 0; i < n; ++i) {n}(x1[i], x2[i], oa + i, ob + i);"
                     f" break;")
    dispatch = ("void fsh_emitted(int k, int n, const fs_real *x1, const fs_real *x2, "
                "fs_real *oa, fs_real *ob)\n{\n    int i;\n    switch (k) {\n"
                + "\n".join(cases) + "\n    default: (void)i; (void)x1; (void)x2; "
                "(void)oa; (void)ob; (void)n; break;\n    }\n}\n")
    return head + fragment() + "\n" + defs + HARNESS.replace("@EMITTED@", dispatch)


FLOAT_FLAGS = ("-O2", "-Wdouble-promotion", "-Wfloat-conversion")


def build_shared(real: str, out_dir: Path, emitted: Emitted | None = None,
                 flags: Sequence[str] | None = None) -> Path:
    """The harness as a shared library (strict flags; float builds also refuse any implicit
    double promotion or narrowing, so float mode does float maths)."""
    fl = flags if flags is not None else (FLOAT_FLAGS if real == "float" else ("-O2",))
    return compile_shared(source(real, emitted), out_dir, flags=fl, name=f"fsh_{real}")


def build_executable(real: str, out_dir: Path, emitted: Emitted | None = None, *,
                     sanitize: bool) -> Path:
    """The harness's case-file driver as an executable."""
    return compile_executable(source(real, emitted), out_dir, sanitize=sanitize,
                              flags=("-DFSH_MAIN",) + (() if sanitize else ("-O2",)),
                              name=f"fsh_{real}{'_san' if sanitize else ''}")


class CFuzzy:
    """The harness library through ctypes, on numpy arrays of its real type."""

    def __init__(self, lib: Path, real: str) -> None:
        self.dll = ctypes.CDLL(str(lib))
        self.dtype = np.float64 if real == "double" else np.float32

    def _r(self, a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(a, dtype=self.dtype)

    @staticmethod
    def _p(a: np.ndarray) -> ctypes.c_void_p:
        return ctypes.c_void_p(a.ctypes.data)

    def grid(self, x1: np.ndarray, x2: np.ndarray, rules: np.ndarray, lims: np.ndarray
             ) -> np.ndarray:
        """fs_grid_eval at each (x1, x2)."""
        a, b = self._r(x1), self._r(x2)
        r = np.ascontiguousarray(rules, dtype=np.int32)
        m = self._r(lims)
        out = np.empty(a.shape[0], dtype=self.dtype)
        self.dll.fsh_grid(ctypes.c_int(a.shape[0]), self._p(a), self._p(b), self._p(r),
                          ctypes.c_int(r.shape[0]), ctypes.c_int(r.shape[1]), self._p(m),
                          self._p(out))
        return out.astype(np.float64)

    def pair(self, x1: np.ndarray, x2: np.ndarray, ra: np.ndarray, la: np.ndarray,
             rb: np.ndarray, lb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """fs_grid_pair at each (x1, x2)."""
        a, b = self._r(x1), self._r(x2)
        ra_, rb_ = (np.ascontiguousarray(r, dtype=np.int32) for r in (ra, rb))
        la_, lb_ = self._r(la), self._r(lb)
        oa = np.empty(a.shape[0], dtype=self.dtype)
        ob = np.empty(a.shape[0], dtype=self.dtype)
        self.dll.fsh_pair(ctypes.c_int(a.shape[0]), self._p(a), self._p(b), self._p(ra_),
                          ctypes.c_int(ra_.shape[0]), ctypes.c_int(ra_.shape[1]), self._p(la_),
                          self._p(rb_), ctypes.c_int(rb_.shape[0]), ctypes.c_int(rb_.shape[1]),
                          self._p(lb_), self._p(oa), self._p(ob))
        return oa.astype(np.float64), ob.astype(np.float64)

    def _scratch(self, ints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sz = scratch_sizes(ints)  # fs_sys_eval(2): all in one array
        return np.empty(sz.single, dtype=self.dtype), np.empty(sz.iwork, dtype=np.int32)

    def sys(self, x: np.ndarray, ints: np.ndarray, floats: np.ndarray) -> np.ndarray:
        """fs_sys_eval at each row of x: (n, n_out)."""
        xi = self._r(x)
        i32 = np.ascontiguousarray(ints, dtype=np.int32)
        f = self._r(floats)
        work, iwork = self._scratch(ints)
        out = np.empty((xi.shape[0], int(ints[2])), dtype=self.dtype)
        self.dll.fsh_sys(ctypes.c_int(xi.shape[0]), self._p(xi), self._p(out), self._p(i32),
                         self._p(f), self._p(work), self._p(iwork))
        return out.astype(np.float64)

    def sys2(self, x1: np.ndarray, x2: np.ndarray, ints: np.ndarray, floats: np.ndarray
             ) -> np.ndarray:
        """fs_sys_eval2 at each (x1, x2)."""
        a, b = self._r(x1), self._r(x2)
        i32 = np.ascontiguousarray(ints, dtype=np.int32)
        f = self._r(floats)
        work, iwork = self._scratch(ints)
        out = np.empty(a.shape[0], dtype=self.dtype)
        self.dll.fsh_sys2(ctypes.c_int(a.shape[0]), self._p(a), self._p(b), self._p(out),
                          self._p(i32), self._p(f), self._p(work), self._p(iwork))
        return out.astype(np.float64)

    def emitted(self, k: int, x1: np.ndarray, x2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The k-th emitted function at each (x1, x2): (output, second output of a pair)."""
        a, b = self._r(x1), self._r(x2)
        oa = np.empty(a.shape[0], dtype=self.dtype)
        ob = np.empty(a.shape[0], dtype=self.dtype)
        self.dll.fsh_emitted(ctypes.c_int(k), ctypes.c_int(a.shape[0]), self._p(a), self._p(b),
                             self._p(oa), self._p(ob))
        return oa.astype(np.float64), ob.astype(np.float64)


# --- the case file of the executable --------------------------------------------------------


def _i(v: int) -> bytes:
    return struct.pack("<i", int(v))


def _ia(a: np.ndarray) -> bytes:
    return np.ascontiguousarray(a, dtype="<i4").tobytes()


def _da(a: np.ndarray) -> bytes:
    return np.ascontiguousarray(a, dtype="<f8").tobytes()


def grid_case(rules: np.ndarray, lims: np.ndarray, x: np.ndarray) -> bytes:
    """A case of fs_grid_eval at the rows of x (n, 2); n outputs."""
    return _i(0) + _i(rules.shape[0]) + _i(rules.shape[1]) + _ia(rules) + _da(lims) + \
        _i(x.shape[0]) + _da(x[:, 0]) + _da(x[:, 1])


def pair_case(ra: np.ndarray, la: np.ndarray, rb: np.ndarray, lb: np.ndarray, x: np.ndarray
              ) -> bytes:
    """A case of fs_grid_pair; 2 n outputs."""
    return _i(1) + _i(ra.shape[0]) + _i(ra.shape[1]) + _ia(ra) + _da(la) + _i(rb.shape[0]) + \
        _i(rb.shape[1]) + _ia(rb) + _da(lb) + _i(x.shape[0]) + _da(x[:, 0]) + _da(x[:, 1])


def sys_case(ints: np.ndarray, floats: np.ndarray, x: np.ndarray) -> bytes:
    """A case of fs_sys_eval at the rows of x (n, n_in): n n_out outputs, then (two inputs)
    n of fs_sys_eval2."""
    sz = scratch_sizes(ints)
    return _i(2) + _i(ints.size) + _ia(ints) + _i(floats.size) + _da(floats) + _i(sz.work) + \
        _i(sz.iwork) + _i(sz.smooth) + _i(sz.single) + _i(ints[1]) + _i(ints[2]) + \
        _i(x.shape[0]) + _da(x.reshape(-1))


def emitted_case(k: int, x: np.ndarray) -> bytes:
    """A case of the k-th emitted function; 2 n outputs."""
    return _i(3) + _i(k) + _i(x.shape[0]) + _da(x[:, 0]) + _da(x[:, 1])


def run_cases(exe: Path, cases: Sequence[bytes], folder: Path) -> np.ndarray:
    """Run the executable on the cases; all outputs, in order, as one float64 array."""
    cin, cout = folder / "cases.bin", folder / "outputs.bin"
    cin.write_bytes(b"".join(cases) + _i(-1))
    proc = subprocess.run([str(exe), str(cin), str(cout)], capture_output=True, text=True,
                          check=False, timeout=1200)
    assert proc.returncode == 0, f"harness exit {proc.returncode}:\n{proc.stderr[-4000:]}"
    return np.frombuffer(cout.read_bytes(), dtype="<f8")
