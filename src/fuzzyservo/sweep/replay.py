"""Replay one run of a sweep: the ``fuzzyservo simulate`` command that computes it again.

Every number is written with ``repr`` (the shortest text that reads back as the same float),
the noise as its seed, the gains as NAME=VALUE pairs (a gains file's values, not its path, so
that its tuning record cannot fill in anything), and every option the spec sets: the command
gives the dataset's row to the last bit (tests/sweep/test_replay.py).
"""

from __future__ import annotations

import shlex
from collections.abc import Mapping
from typing import Any

from .spec import SweepSpec

__all__ = ["OPTION_FLAGS", "simulate_argv", "simulate_command"]

#: Controller options a spec may set, with the ``fuzzyservo simulate`` flag of each (the
#: command line's ``OPTION_FLAGS``; a test keeps them equal). A sweep takes no option that
#: the command cannot replay.
OPTION_FLAGS: dict[str, str] = {
    "anti_windup": "--anti-windup",
    "initial_error": "--initial-error",
    "de_per": "--de-per",
    "filter_time": "--filter-time",
}


def _num(x: float) -> str:
    return repr(float(x))


def simulate_argv(spec: SweepSpec, row: Mapping[str, Any]) -> list[str]:
    """Arguments of ``fuzzyservo simulate`` that replay the run of ``row`` (a dict with the
    dataset's ``controller``, ``noise_seed`` and varied columns)."""
    entry = next(e for e in spec.controllers if e.label == row["controller"])
    varied = {v.name: float(row[v.name]) for v in spec.vary}
    argv = ["simulate", "--plant", spec.plant, "--set", spec.param_set]
    params = dict(spec.overrides)
    params.update({k: v for k, v in varied.items() if "." in k})
    for name, value in params.items():
        argv += ["--param", f"{name}={_num(value)}"]
    argv += ["--start", _num(spec.start), "--ts", _num(spec.ts),
             "--duration", _num(spec.duration)]
    if spec.plant == "nonlinear":
        argv += ["--substep", _num(spec.substep)]
    argv += ["--delay", _num(varied.get("delay", spec.delay))]
    if "amplitude" in varied:
        from ..sim.references import Step, parse_reference

        ref = parse_reference(spec.reference)
        assert isinstance(ref, Step)
        argv += ["--reference", f"step:{_num(varied['amplitude'])}:{_num(ref.time)}"]
    else:
        argv += ["--reference", spec.reference]
    std = varied.get("noise_std", spec.noise_std)
    if std > 0.0:
        argv += ["--noise-std", _num(std), "--seed", str(int(row["noise_seed"]))]
    argv += ["--controller", entry.controller,
             "--gains", ",".join(f"{k}={_num(v)}" for k, v in entry.gains)]
    for key, value in entry.options:
        argv += [OPTION_FLAGS[key], _num(value) if isinstance(value, float) else str(value)]
    for role, path in entry.systems:
        argv += [f"--{role}-system", path]
    if entry.no_rule_value is not None:
        argv += ["--no-rule-value", _num(entry.no_rule_value)]
    return argv


def simulate_command(spec: SweepSpec, row: Mapping[str, Any]) -> str:
    """The shell command of :func:`simulate_argv` (``--metrics`` added)."""
    return "fuzzyservo " + shlex.join([*simulate_argv(spec, row), "--metrics"])
