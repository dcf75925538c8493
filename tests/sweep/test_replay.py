"""Every row of a sweep replays with ``fuzzyservo simulate``: the command of
:func:`fuzzyservo.sweep.replay.simulate_command` writes a CSV (floats as repr) whose step
metrics equal the row's bit for bit. Every kind of variation is in play: parameter overrides
fixed and varied (relative), the load force, the delay, the amplitude and the noise, controller
options and a fuzzy system read from a file, on the nonlinear plant."""

from __future__ import annotations

import math
import shlex
from pathlib import Path

import numpy as np

from fuzzyservo.analysis import step_metrics
from fuzzyservo.cli import main
from fuzzyservo.files import read_run_csv
from fuzzyservo.sim.stepinfo import METRIC_NAMES
from fuzzyservo.sweep import load_spec, read_table, run_sweep
from fuzzyservo.sweep.replay import simulate_command

ROOT = Path(__file__).resolve().parents[2]

SPEC = f"""
[sweep]
plant = "nonlinear"
duration = 1.5
samples = 3
seed = 5
chunk = 4

[overrides]
"load.viscous_damping" = 5000.0

[[controllers]]
label = "fpi from a file"
controller = "fpi"
gains = {{ ke = 12.0, kde = 6000.0, kdu = 0.004 }}
du_system = "{ROOT / 'src/fuzzyservo/data/systems/paper-du.fis'}"
options = {{ initial_error = "first", filter_time = 0.002 }}

[[controllers]]
label = "pid2"
controller = "pid2"
gains = {{ kp = 15.0, ki = 2.0, kd = 0.05, b = 0.5, c = 0.0 }}
options = {{ anti_windup = "back-calculation" }}

[[vary]]
name = "noise_std"
grid = [0.0, 5e-6]

[[vary]]
name = "load.mass"
relative = true
distribution = "log-uniform"
low = 0.5
high = 2.0

[[vary]]
name = "load_force"
distribution = "uniform"
low = -1000.0
high = 1000.0

[[vary]]
name = "delay"
distribution = "uniform"
low = 0.0
high = 0.01

[[vary]]
name = "amplitude"
distribution = "normal"
mean = 0.1
std = 0.02
low = 0.05
high = 0.15
"""


def test_every_row_replays_bit_for_bit(tmp_path: Path) -> None:
    path = tmp_path / "spec.toml"
    path.write_text(SPEC, encoding="utf-8")
    spec = load_spec(path)
    run_sweep(spec, tmp_path / "s", progress=False, processes=1)
    rows = read_table(tmp_path / "s").to_pylist()
    assert len(rows) == 12
    assert {r["outcome"] for r in rows} != {"invalid"}
    for k, row in enumerate(rows):
        cmd = simulate_command(spec, row)
        csv = tmp_path / f"run{k}.csv"
        argv = shlex.split(cmd)[1:]
        argv.remove("--metrics")
        assert main([*argv, "--out", str(csv)]) == 0, cmd
        run = read_run_csv(csv)
        m = step_metrics(run).as_dict()
        for name in METRIC_NAMES:
            a, b = m[name], row[name]
            assert (math.isnan(a) and math.isnan(b)) or a == b, (name, a, b, cmd)
        assert np.isfinite(run.y).all()
