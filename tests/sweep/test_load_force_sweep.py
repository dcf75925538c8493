"""A sweep's load force (``[sweep] load_force``) and its axis ``load_force_step`` (the step's
F [N]): every row replays bit for bit with ``fuzzyservo simulate --load-force``, on a linear
and on the nonlinear plant; bad specs are one message naming the key."""

from __future__ import annotations

import math
import shlex
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.analysis import step_metrics
from fuzzyservo.cli import main
from fuzzyservo.errors import ParameterError
from fuzzyservo.files import read_run_csv
from fuzzyservo.sim.stepinfo import METRIC_NAMES
from fuzzyservo.sweep import load_spec, read_table, run_sweep
from fuzzyservo.sweep.replay import simulate_command
from fuzzyservo.sweep.spec import parse_spec

SPEC = """
[sweep]
plant = "{plant}"
duration = 0.6
samples = 2
seed = 3
load_force = "step:500:0.3"

[[controllers]]
label = "pi"
controller = "pi"
gains = {{ kp = 10.0, ki = 2.0 }}

[[vary]]
name = "load_force_step"
grid = [-2000.0, 0.0, 3000.0]

[[vary]]
name = "noise_std"
distribution = "uniform"
low = 0.0
high = 2e-6
"""


@pytest.mark.parametrize("plant", ["small-signal", "nonlinear"])
def test_rows_replay_bit_for_bit(tmp_path: Path, plant: str) -> None:
    path = tmp_path / "spec.toml"
    path.write_text(SPEC.format(plant=plant), encoding="utf-8")
    spec = load_spec(path)
    run_sweep(spec, tmp_path / "s", progress=False, processes=1)
    rows = read_table(tmp_path / "s").to_pylist()
    assert len(rows) == 6 and {r["outcome"] for r in rows} != {"invalid"}
    iae = {}
    for k, row in enumerate(rows):
        cmd = simulate_command(spec, row)
        assert f"--load-force=step:{row['load_force_step']!r}:0.3" in cmd
        argv = shlex.split(cmd)[1:]
        argv.remove("--metrics")
        csv = tmp_path / f"run{k}.csv"
        assert main([*argv, "--out", str(csv)]) == 0, cmd
        m = step_metrics(read_run_csv(csv)).as_dict()
        for name in METRIC_NAMES:
            a, b = m[name], row[name]
            assert (math.isnan(a) and math.isnan(b)) or a == b, (name, a, b, cmd)
        iae.setdefault(row["load_force_step"], []).append(row["iae"])
    assert len({np.mean(v) for v in iae.values()}) == 3  # the force changes the runs


def _doc(**sweep: object) -> dict[str, object]:
    return {"sweep": {"plant": "linear", "duration": 0.5, **sweep},
            "controllers": [{"controller": "pi", "gains": {"kp": 10.0, "ki": 2.0}}],
            "vary": [{"name": "load_force_step", "grid": [1.0, 2.0]}]}


@pytest.mark.parametrize(("sweep", "words"), [
    ({}, ["vary[0]", "load_force_step", "step:F:T"]),
    ({"load_force": "pwl:0:0,1:5"}, ["vary[0]", "load_force_step"]),
    ({"load_force": "step:nan"}, ["sweep.load_force", "finite"]),
    ({"load_force": 5}, ["sweep.load_force", "must be text"]),
    ({"load_force": "nope.csv"}, ["sweep.load_force", "no file"]),
])
def test_bad_specs_name_the_key(sweep: dict[str, object], words: list[str]) -> None:
    with pytest.raises(ParameterError) as info:
        parse_spec(_doc(**sweep))
    for w in words:
        assert w in str(info.value), (w, str(info.value))


def test_a_spec_without_a_load_force_keeps_its_digest() -> None:
    doc = _doc()
    doc["vary"] = []
    assert "load_force" not in parse_spec(doc).canonical()
