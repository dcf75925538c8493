"""Run every benchmark script in this folder, in one process tree, and print their tables.

Each script is self-contained (``python benchmarks/<name>.py``) and prints one table whose
figures are measured in the same run, with ratios against the peer libraries it names.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ORDER = ["compile.py", "fuzzy_engine.py", "fuzzy_files.py", "plant.py", "closed_loop.py",
         "tuning.py", "csv_write.py", "export_c.py", "sweep.py", "app_latency.py",
         "reproduce_time.py", "identify.py"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--fuzzylite-python", default=None,
                        help="python of an environment with pyfuzzylite (numpy<2)")
    args = parser.parse_args()
    status = 0
    for name in ORDER:
        script = HERE / name
        if not script.exists():
            print(f"== {name}: not present, skipped")
            continue
        cmd = [sys.executable, str(script)]
        if name in ("fuzzy_engine.py", "fuzzy_files.py") and args.fuzzylite_python:
            cmd += ["--fuzzylite-python", args.fuzzylite_python]
        print(f"== {name}", flush=True)
        status |= subprocess.call(cmd)
    return status


if __name__ == "__main__":
    sys.exit(main())
