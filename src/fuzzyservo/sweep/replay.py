"""Replay one run of a sweep: the ``fuzzyservo simulate`` command that computes it again.

The run is a :class:`~fuzzyservo.run.RunSpec` and the command its ``to_argv``: every number is
written with ``repr`` (the shortest text that reads back as the same float), the noise as its
seed, the gains as NAME=VALUE pairs (a gains file's values, not its path, so that its tuning
record cannot fill in anything), and every option the spec sets: the command gives the
dataset's row to the last bit (tests/sweep/test_replay.py).
"""

from __future__ import annotations

import shlex
from collections.abc import Mapping
from typing import Any

from ..run import RunSpec
from .spec import SweepSpec

__all__ = ["run_spec", "simulate_argv", "simulate_command"]


def _num(x: float) -> str:
    return repr(float(x))


def run_spec(spec: SweepSpec, row: Mapping[str, Any]) -> RunSpec:
    """The run of ``row`` (a dict with the dataset's ``controller``, ``noise_seed`` and
    varied columns) as a :class:`~fuzzyservo.run.RunSpec`."""
    entry = next(e for e in spec.controllers if e.label == row["controller"])
    varied = {v.name: float(row[v.name]) for v in spec.vary}
    params = dict(spec.overrides)
    params.update({k: v for k, v in varied.items() if "." in k})
    reference = spec.reference
    if "amplitude" in varied:
        from ..sim.references import Step, parse_reference

        ref = parse_reference(spec.reference)
        assert isinstance(ref, Step)
        reference = f"step:{_num(varied['amplitude'])}:{_num(ref.time)}"
    load_force = spec.load_force
    if "load_force_step" in varied:
        step = spec.load_step
        assert step is not None
        load_force = f"step:{_num(varied['load_force_step'])}:{_num(step.time)}"
    std = varied.get("noise_std", spec.noise_std)
    return RunSpec(controller=entry.controller, gains=entry.gains, options=entry.options,
                   systems=entry.systems, no_rule_value=entry.no_rule_value, plant=spec.plant,
                   param_set=spec.param_set, overrides=tuple(params.items()),
                   reference=reference, duration=spec.duration, ts=spec.ts,
                   delay=varied.get("delay", spec.delay), noise_std=std if std > 0.0 else 0.0,
                   seed=int(row["noise_seed"]) if std > 0.0 else 0, load_force=load_force,
                   start=spec.start,
                   substep=spec.substep)


def simulate_argv(spec: SweepSpec, row: Mapping[str, Any]) -> list[str]:
    """Arguments of ``fuzzyservo simulate`` that replay the run of ``row``: its
    :func:`run_spec`'s command line, every setting written (``explicit``), so a later change
    of a default cannot change the replay."""
    return ["simulate", *run_spec(spec, row).to_argv(explicit=True)]


def simulate_command(spec: SweepSpec, row: Mapping[str, Any]) -> str:
    """The shell command of :func:`simulate_argv` (``--metrics`` added)."""
    return "fuzzyservo " + shlex.join([*simulate_argv(spec, row), "--metrics"])
