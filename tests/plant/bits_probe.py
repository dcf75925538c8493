"""Print the bits of what the package derives and simulates, as JSON digests (run by
test_machine_independent.py in a fresh process for each BLAS kernel).

``package``: the derived parameter sets, a linearisation, a ZOH discretisation and short
closed loops on the nonlinear and linear plants (numpy's RNG noise included), and
identifications (``identify``: an open-loop fit of two fields of the nonlinear plant, and
eq. (8) fitted to time and to frequency data): what must not depend on the machine.
``blas``: the same linearisation's eigenvalues from numpy's LAPACK and a BLAS dot product,
which do depend on the kernel: the witness that the kernels differed.
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


def _identify() -> list[str]:
    """Digests of short identifications on data the package simulates, with seeded noise:
    load.mass and fluid.oil_bulk_modulus of the nonlinear plant (the paper set with a 20 %
    heavier load, 2 s at 1 kHz, four command pulses; position and both pressures), eq. (8)
    fitted to its own 2 s record, and eq. (8) fitted to a noisy frequency response."""
    from fuzzyservo.identify import FitSettings, identify, measurement_from_arrays
    from fuzzyservo.identify.linear import eq8_response, fit_linear_frequency, fit_linear_time
    from fuzzyservo.paper.published import named_set
    from fuzzyservo.plant import LinearServo, linearize, with_overrides
    from fuzzyservo.registry import build_plant
    from fuzzyservo.sim import LinearPlant, simulate_open_loop

    dt, n = 1e-3, 2000
    paper = named_set("paper")
    true = with_overrides(paper, {"load.mass": 1.2 * paper.load.mass})
    plant = build_plant("nonlinear", true, 0.5)
    u = np.full(n, plant.u0)
    for k0, amp in ((200, 0.08), (600, -0.08), (1000, 0.05), (1400, -0.05)):
        u[k0:k0 + 150] += amp
    res = simulate_open_loop(plant, u, duration=n * dt, dt=dt,
                             delay=true.delay.transport_delay)
    rng = np.random.default_rng(11)
    data = measurement_from_arrays(
        res.t, res.y + rng.normal(0.0, 2e-5, res.t.size), u=np.append(res.u, res.u[-1]),
        p_f=res.p_f + rng.normal(0.0, 5e3, res.t.size),
        p_n=res.p_n + rng.normal(0.0, 5e3, res.t.size), dt=dt)
    fit = identify(data, plant="nonlinear", params=paper,
                   fit=["load.mass", "fluid.oil_bulk_modulus"],
                   settings=FitSettings(starts=1, workers=1))
    lin = linearize(paper, 0.5)
    servo = LinearServo(K_o=paper.velocity_gain, omega_0=lin.omega_0, damping=lin.damping,
                        omega_v=paper.valve.omega_v, zeta_v=paper.valve.zeta_v)
    eq8 = LinearPlant.from_servo(servo, 0.5, stroke=paper.cylinder.stroke)
    drive = np.zeros(n)
    for k0, amp in ((100, 0.05), (500, -0.05), (900, 0.03), (1300, -0.03)):
        drive[k0:k0 + 150] = amp
    rec = simulate_open_loop(eq8, drive, duration=n * dt, dt=dt, delay=0.0063)
    y = rec.y + rng.normal(0.0, 1e-5, rec.y.size)
    time_fit = fit_linear_time(rec.t, np.append(drive, drive[-1]), y, params=paper,
                               position=0.5, dt=dt)
    w = np.array([1.0 * 1.2**k for k in range(30)])
    gain_noise = 1.0 + 0.01 * rng.standard_normal(w.size)  # per value: no complex vector loop
    h = np.array([v * g for v, g in zip(eq8_response(w, servo, 0.0063).tolist(),
                                         gain_noise.tolist(), strict=True)])
    freq_fit = fit_linear_frequency(w, h, params=paper)
    return [_digest(fit.estimate, fit.std_error, fit.correlation),
            _digest(time_fit.estimate, time_fit.std_error),
            _digest(freq_fit.estimate, freq_fit.std_error)]


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
                    "runs": runs,
                    "identify": _identify()},
        "blas": blas}))


if __name__ == "__main__":
    main()
