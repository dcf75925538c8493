"""The same inputs give the same bits whatever BLAS kernel or vector unit runs them.

OpenBLAS picks its kernel when the process starts, from the processor or from
``OPENBLAS_CORETYPE``; numpy picks its own vector loops likewise (``NPY_DISABLE_CPU_FEATURES``
turns them off). tests/plant/bits_probe.py prints digests of the derived parameter sets, a
linearisation, a ZOH discretisation and short closed loops on both plants; here it runs in a
fresh process under each kernel this processor can execute, and every digest must be equal.
The probe also prints a witness computed with numpy's BLAS and LAPACK, which must take more
than one value: the kernels really differed, so a BLAS dependence would have been seen.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: OpenBLAS kernels and the processor flags (/proc/cpuinfo) each needs: a kernel the
#: processor cannot execute ends the process with SIGILL, so only those it can are run.
CORETYPES: dict[str, tuple[str, ...]] = {
    "Prescott": ("pni",),
    "Nehalem": ("sse4_2",),
    "Sandybridge": ("avx",),
    "Haswell": ("avx2", "fma"),
    "Zen": ("avx2", "fma"),
    "SkylakeX": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"),
    "Cooperlake": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl", "avx512_bf16"),
}


def _cpu_flags() -> set[str]:
    flags: set[str] = set()
    with open("/proc/cpuinfo", encoding="utf-8") as fh:
        for line in fh:
            if line.startswith("flags"):
                flags.update(line.split(":", 1)[1].split())
    return flags


def _variants() -> dict[str, dict[str, str]]:
    flags = _cpu_flags()
    out: dict[str, dict[str, str]] = {"OPENBLAS_CORETYPE unset": {}}
    for name, needs in CORETYPES.items():
        if set(needs) <= flags:
            out[f"OPENBLAS_CORETYPE={name}"] = {"OPENBLAS_CORETYPE": name}
    # numpy's own vector loops off (a processor without AVX2 or AVX-512)
    out["NPY_DISABLE_CPU_FEATURES=X86_V3 X86_V4"] = {"NPY_DISABLE_CPU_FEATURES":
                                                     "X86_V3 X86_V4"}
    return out


def _probe(extra: dict[str, str]) -> dict[str, object]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES")}
    env.update(extra)
    done = subprocess.run([sys.executable, "-m", "tests.plant.bits_probe"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, (extra, done.stderr[-3000:])
    result: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def test_results_are_the_same_bits_under_every_blas_kernel() -> None:
    variants = _variants()
    assert sum(k.startswith("OPENBLAS_CORETYPE=") for k in variants) >= 3, variants
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = dict(zip(variants, pool.map(_probe, variants.values()), strict=True))
    first = results["OPENBLAS_CORETYPE unset"]["package"]
    for name, res in results.items():
        assert res["package"] == first, name
    # the witness: numpy's own LAPACK eigenvalues and BLAS products did change with the kernel
    assert len({str(res["blas"]) for res in results.values()}) >= 2, results
