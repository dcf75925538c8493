"""Time per controller sample of the exported C against the Python controller, in one run.

For each controller (the committed nonlinear-plant gains: PID, 2-DOF PID, fuzzy PI,
self-tuning fuzzy PI; and the self-tuning fuzzy PI with both systems read from files, the
general evaluator's path) the same recorded closed-loop samples (r_k, y_k) of a 2 s run are
fed to:

1. the generated C step (``fuzzyservo export c``), compiled with ``gcc -O2``, timed inside C
   over many passes (``clock_gettime``), double and float;
2. the Python per-step API, ``controller.step(state, r, y)``, one call per sample;
3. the compiled kernel's controller step (the law's ``step``, the function
   the batch simulators call), in a numba loop over the same samples.

The table gives ns per sample (best of repeats: the machine is shared) and the ratios
Python per-step / C and compiled kernel / C.

Run: ``python benchmarks/export_c.py`` (``make bench`` runs every benchmark).
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from fuzzyservo._jit import data_pointer, template
from fuzzyservo.export.targets import generate_c
from fuzzyservo.files import read_gains_file
from fuzzyservo.formats import read_system
from fuzzyservo.fuzzy.loop import loop_system
from fuzzyservo.paper.published import named_set
from fuzzyservo.registry import build_controller, build_plant
from fuzzyservo.sim import simulate

ROOT = Path(__file__).resolve().parents[1]
GAINS = ROOT / "src" / "fuzzyservo" / "data" / "gains"
SYSTEMS = ROOT / "src" / "fuzzyservo" / "data" / "systems"
TS = 1e-3

DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "NAME.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv)
{
    FILE *f = fopen(argv[1], "r");
    int passes = atoi(argv[2]), repeats = atoi(argv[3]), n = 0, i, p, rep;
    double y0, u0, *r, *y, best = 1e300, sink = 0.0;
    NAME_ctl c;
    (void)argc;
    if (f == NULL || fscanf(f, "%d %lf %lf", &n, &y0, &u0) != 3) {
        return 3;
    }
    r = malloc(sizeof(double) * (size_t)n);
    y = malloc(sizeof(double) * (size_t)n);
    for (i = 0; i < n; i++) {
        if (fscanf(f, "%lf %lf", &r[i], &y[i]) != 2) {
            return 4;
        }
    }
    fclose(f);
    for (rep = 0; rep < repeats; rep++) {
        double t0 = now(), dt;
        for (p = 0; p < passes; p++) {
            NAME_init(&c, (NAME_real)y0, (NAME_real)u0);
            for (i = 0; i < n; i++) {
                sink += (double)NAME_step(&c, (NAME_real)r[i], (NAME_real)y[i]);
            }
        }
        dt = (now() - t0) / ((double)passes * (double)n);
        if (dt < best) {
            best = dt;
        }
    }
    printf("%.6e %.17g\n", best, sink);
    free(r);
    free(y);
    return 0;
}
"""


LAW_STEP: Any = None
LAW_PREPARE: Any = None


@template(error_model="numpy")
def _kernel_loop(p: Any, s0: Any, r: Any, y: Any, tables: Any, passes: int) -> float:
    """The law's compiled step over (r, y), ``passes`` times (specialised per law)."""
    aux = LAW_PREPARE(tables)
    sink = 0.0
    for _ in range(passes):
        s = s0.copy()
        pp = data_pointer(p)
        sp = data_pointer(s)
        for i in range(r.shape[0]):
            sink += LAW_STEP(pp, sp, r[i], y[i], aux)
    return sink


def _best(fn: Any, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def _case(label: str, kind: str, gains: dict[str, float], systems: Any, tmp: Path,
          repeats: int) -> dict[str, Any]:
    params = named_set("paper")
    plant = build_plant("nonlinear", params, 0.5 * params.cylinder.stroke)
    ctl = build_controller(kind, gains, dt=TS, systems=systems)
    n = 2001
    res = simulate(ctl, plant, np.where(np.arange(n) < 1000, 0.1, -0.1), duration=2.0)
    slug = "".join(ch if ch.isalnum() else "_" for ch in label)
    data = tmp / f"{slug}.txt"
    data.write_text(f"{n} {float(plant.y0).hex()} {float(plant.u0).hex()}\n" + "".join(
        f"{float(a).hex()} {float(b).hex()}\n" for a, b in zip(res.r, res.y, strict=True)))
    row: dict[str, Any] = {"label": label}
    for real in ("double", "float"):
        name = f"b_{kind}_{real}"
        cc = generate_c(kind, gains, ts=TS, systems=systems, real=real,  # type: ignore[arg-type]
                        name=name)
        folder = tmp / f"{slug}-{real}"
        folder.mkdir()
        for fname, text in cc.files().items():
            (folder / fname).write_text(text)
        (folder / "main.c").write_text(DRIVER.replace("NAME", name))
        exe = folder / "bench"
        subprocess.run(["gcc", "-std=c99", "-O2", "-o", str(exe), str(folder / "main.c"),
                        str(folder / f"{name}.c"), "-lm"], check=True)
        out = subprocess.run([str(exe), str(data), "20", str(repeats)], check=True,
                             capture_output=True, text=True).stdout.split()
        row[f"c_{real}"] = float(out[0])
    # Python per-step API
    state0 = ctl.rest_states(ctl.pack()[None, :], plant.y0, plant.u0)[0]
    state = ctl.unpack_state(state0)
    m = 500

    def per_step() -> None:
        s = state
        for k in range(m):
            _u, s = ctl.step(s, float(res.r[k]), float(res.y[k]))

    per_step()
    row["python"] = _best(per_step, repeats) / m
    # compiled kernel step
    tables = ctl.tables()
    p = ctl.pack()
    loop = ctl.law.kernels("benchmarks-export-c", [_kernel_loop])._kernel_loop
    loop(p, state0, res.r, res.y, tables, 1)
    passes = 20
    row["kernel"] = _best(lambda: loop(p, state0, res.r, res.y, tables, passes),
                          repeats) / (passes * n)
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    cases: list[tuple[str, str, dict[str, float], Any]] = []
    for kind in ("pid", "pid2", "fpi", "stfpi"):
        cases.append((kind, kind, dict(read_gains_file(GAINS / f"nonlinear-{kind}.toml").gains),
                      None))
    cases.append(("stfpi, .fis/.fll files", "stfpi",
                  dict(read_gains_file(GAINS / "nonlinear-stfpi.toml").gains),
                  {"du": loop_system(read_system(SYSTEMS / "paper-du.fis")),
                   "alpha": loop_system(read_system(SYSTEMS / "paper-alpha.fll"))}))
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for label, kind, gains, systems in cases:
            rows.append(_case(label, kind, gains, systems, Path(d), args.repeats))
    print("Time per controller sample [ns] (best of repeats), the same recorded samples:")
    print(f"{'controller':<24} {'C double':>9} {'C float':>9} {'kernel':>9} {'Python':>9} "
          f"{'Python/C':>9} {'kernel/C':>9}")
    for r in rows:
        print(f"{r['label']:<24} {r['c_double'] * 1e9:9.1f} {r['c_float'] * 1e9:9.1f} "
              f"{r['kernel'] * 1e9:9.1f} {r['python'] * 1e9:9.0f} "
              f"{r['python'] / r['c_double']:9.0f} {r['kernel'] / r['c_double']:9.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
