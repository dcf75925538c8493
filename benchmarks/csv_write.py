"""Run-CSV writing: memory above the arrays and speed, fuzzyservo's streaming writer against
numpy.savetxt and the writer it replaced (issue 9: 10 million samples with at most 200 MB
above the arrays; floats as the shortest text that reads back exactly).

Each writer runs in a fresh child process that allocates the columns (9 float64 columns, as
a nonlinear closed-loop run: t, r, y, u, alpha, x, v, p_f, p_n), notes its resident memory,
writes the CSV to a temporary folder, and reports the peak resident memory (VmHWM) above that
baseline and the wall time. Ratios are against numpy.savetxt measured in the same run.

    python benchmarks/csv_write.py [--rows 10000000] [--peer-rows 1000000]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r"""
import json, sys, time, csv
import numpy as np
from pathlib import Path

def rss(field):
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) * 1024
    raise RuntimeError(field)

kind, n, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
rng = np.random.default_rng(0)
t = np.arange(n) * 1e-3
cols = [t] + [rng.normal(size=n) for _ in range(8)]
names = ["t", "r", "y", "u", "alpha", "x", "v", "p_f", "p_n"]
if kind == "fuzzyservo":
    from fuzzyservo.sim.result import write_csv
base = rss("VmRSS")
t0 = time.perf_counter()
if kind == "fuzzyservo":
    write_csv(out, names, cols)
elif kind == "savetxt":
    np.savetxt(out, np.column_stack(cols), fmt="%.17g", delimiter=",",
               header=",".join(names), comments="")
elif kind == "previous":  # fuzzyservo 0.1.0 before issue 9: one block of repr lists
    data = np.column_stack(cols)
    with open(out, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(names)
        for a in range(0, n, 4096):
            w.writerows([[repr(v) for v in row] for row in data[a:a + 4096].tolist()])
elapsed = time.perf_counter() - t0
peak = rss("VmHWM")
ok = None
if kind == "fuzzyservo" and n <= 2_000_000:
    back = np.loadtxt(out, delimiter=",", skiprows=1)
    ok = all(np.array_equal(back[:, j], c) for j, c in enumerate(cols))
print(json.dumps({"elapsed": elapsed, "above": peak - base, "bytes": Path(out).stat().st_size,
                  "exact": ok}))
"""


def _measure(kind: str, n: int, folder: Path) -> dict[str, float]:
    out = folder / f"{kind}-{n}.csv"
    res = subprocess.run([sys.executable, "-c", CHILD, kind, str(n), str(out)],
                         capture_output=True, text=True, check=True)
    out.unlink(missing_ok=True)
    result: dict[str, float] = json.loads(res.stdout)
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rows", type=int, default=10_000_000)
    parser.add_argument("--peer-rows", type=int, default=1_000_000)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        peer = _measure("savetxt", args.peer_rows, folder)
        for kind, n in (("savetxt", args.peer_rows), ("previous", args.peer_rows),
                        ("fuzzyservo", args.peer_rows), ("fuzzyservo", args.rows)):
            m = peer if (kind, n) == ("savetxt", args.peer_rows) else _measure(kind, n, folder)
            rows.append((kind, n, m))
    print(f"{'writer':<12} {'rows':>10} {'s per 1M rows':>14} {'vs savetxt':>10} "
          f"{'MB above arrays':>16} {'file MB':>8} {'exact':>6}")
    per_m_peer = peer["elapsed"] / (args.peer_rows / 1e6)
    for kind, n, m in rows:
        per_m = m["elapsed"] / (n / 1e6)
        print(f"{kind:<12} {n:>10} {per_m:>14.2f} {per_m / per_m_peer:>10.2f} "
              f"{m['above'] / 1e6:>16.1f} {m['bytes'] / 1e6:>8.0f} {str(m['exact']):>6}")
    big = rows[-1][2]
    verdict = big["above"] <= 200e6
    print(f"target: {args.rows} rows with <= 200 MB above the arrays: "
          f"{'met' if verdict else 'MISSED'} ({big['above'] / 1e6:.0f} MB)")
    return 0 if verdict else 1


if __name__ == "__main__":
    sys.exit(main())
