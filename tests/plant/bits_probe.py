"""Print the bits of what the package derives and simulates, as JSON digests (run by
test_machine_independent.py in a fresh process for each BLAS kernel).

``package``: the derived parameter sets, a linearisation, a ZOH discretisation and short
closed loops on the nonlinear and linear plants (numpy's RNG noise included): what must not
depend on the machine. ``blas``: the same linearisation's eigenvalues from numpy's LAPACK and
a BLAS dot product, which do depend on the kernel: the witness that the kernels differed.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import fields, is_dataclass
from typing import Any

import numpy as np


def _floats(obj: Any) -> list[float]:
    out: list[float] = []
    for f in fields(obj):
        v = getattr(obj, f.name)
        if is_dataclass(v):
            out += _floats(v)
        elif isinstance(v, float):
            out.append(v)
    return out


def _digest(*arrays: Any) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(np.asarray(a, dtype=np.complex128)).tobytes())
    return h.hexdigest()


def main() -> None:
    from fuzzyservo.paper.published import named_set
    from fuzzyservo.plant import linearize
    from fuzzyservo.plant.zoh import discretize
    from fuzzyservo.registry import build_controller, build_plant
    from fuzzyservo.sim import Step, simulate

    sets = {name: _floats(named_set(name)) for name in ("paper", "stiff-oil")}
    paper = named_set("paper")
    lin = linearize(paper, 0.3 * paper.cylinder.stroke)
    zoh = discretize(lin.a, lin.b, 1e-3, 0.0063)
    runs = []
    for plant_name, kind, gains in (
            ("nonlinear", "stfpi", {"ke": 10.0, "kde": 5000.0, "kdu": 0.006}),
            ("nonlinear", "pid", {"kp": 8.0, "ki": 2.0, "kd": 0.1}),
            ("linear", "pid", {"kp": 8.0, "ki": 2.0, "kd": 0.1})):
        ctl = build_controller(kind, gains, dt=1e-3)
        res = simulate(ctl, build_plant(plant_name, named_set("stiff-oil" if kind == "pid"
                                                              else "paper")),
                       Step(0.05, time=0.01), duration=0.25, noise_std=1e-6,
                       rng=np.random.default_rng(7))
        runs.append(_digest(res.y, res.u))
    rng = np.random.default_rng(3)
    v = rng.standard_normal(1001)
    blas = _digest(np.sort_complex(np.linalg.eigvals(lin.a)), np.dot(v, v[::-1].copy()),
                   rng.standard_normal((9, 9)) @ rng.standard_normal((9, 9)))
    print(json.dumps({
        "package": {"sets": _digest(sets["paper"], sets["stiff-oil"]),
                    "linearize": _digest(lin.a, lin.b, lin.eigenvalues,
                                         [lin.omega_0, lin.damping, lin.velocity_gain]),
                    "zoh": _digest(zoh.phi, zoh.gamma0, zoh.gamma1),
                    "runs": runs},
        "blas": blas}))


if __name__ == "__main__":
    main()
