"""Full-size exactness check of the paper's fuzzy systems (issue 2's acceptance, at full size).

10^5 random points of [-1.2, 1.2]^2 (seed 2012); each system's exact centroid against a
brute-force centroid with 10^6 samples of the output universe (trapezoid rule), and against
the proven error bound of that brute force (tests/fuzzy/fuzzy_exact_reference.py). About 1e11
samples per system: minutes, hence a script and not a unit test (make test runs the same check
on all points at 10^4 samples and on 1000 points at 10^6 samples).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fuzzyservo.fuzzy import evaluate, pack  # noqa: E402
from fuzzyservo.paper import alpha_system, du_system  # noqa: E402

# the same module name as in the tests, so numba's on-disk cache serves both
from tests.fuzzy.fuzzy_exact_reference import (  # noqa: E402
    brute_uniform,
    trapezoid_error_bound,
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--samples", type=int, default=1_000_000)
    args = parser.parse_args()
    rng = np.random.default_rng(2012)
    e, de = rng.uniform(-1.2, 1.2, (2, args.points))
    print(f"exact centroid vs brute force ({args.samples} samples, trapezoid rule), "
          f"{args.points} points")
    print(f"{'system':<7} {'max |exact - brute|':>20} {'brute-force bound':>18} "
          f"{'within':>7} {'seconds':>8}")
    ok = True
    for name, build in (("du", du_system), ("alpha", alpha_system)):
        packed = pack(build())
        assert packed.path == "uniform grid"
        rules, lims = packed.kernel_args()
        exact = evaluate(packed, np.column_stack([e, de]))[:, 0]
        t0 = time.perf_counter()
        brute = brute_uniform(e, de, rules, lims, args.samples)
        dt = time.perf_counter() - t0
        bound = trapezoid_error_bound(exact, rules, lims, args.samples)
        within = bool(np.all(np.abs(exact - brute) <= bound))
        ok &= within
        print(f"{name:<7} {np.max(np.abs(exact - brute)):>20.3g} {np.min(bound):>18.3g} "
              f"{str(within):>7} {dt:>8.1f}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
