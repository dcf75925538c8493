"""1 mm step under P control: nonlinear model from its trim vs the linear model (issue 3)."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzyservo.paper import paper_params
from fuzzyservo.plant import LinearServo, NonlinearServo, linearize, with_overrides

DT = 1e-3
KP = 5.0  # [1/m]: loop gain K_p * 0.21 m/s ≈ 1 1/s, well inside the 3.9 1/s margin
N = 3000
DELAY = 6  # samples of the 6 ms hose delay


def _p_loop_linear(model: LinearServo, step: float) -> np.ndarray:
    m = model.discretize(DT)
    c = model.state_space()[2]
    z = np.zeros(m.phi.shape[0])
    fifo = [0.0] * DELAY
    y = np.empty(N)
    for k in range(N):
        y[k] = float(c[0] @ z)
        fifo.append(KP * (step - y[k]))
        z = m.phi @ z + m.gamma * fifo.pop(0)
    return y


def _p_loop_nonlinear(servo: NonlinearServo, x0: np.ndarray, u_trim: float,
                      step: float) -> np.ndarray:
    x = x0.copy()
    pos0 = x0[5]
    fifo = [u_trim] * DELAY
    y = np.empty(N)
    for k in range(N):
        y[k] = x[5] - pos0
        fifo.append(u_trim + KP * (step - y[k]))
        x = servo.step(k * DT, x, fifo.pop(0), DT)
    return y


@pytest.mark.parametrize("position", [0.5, 0.2])
def test_one_mm_step_nonlinear_matches_linear(position: float) -> None:
    # Coulomb friction has no linearisation (docs/model.md); leakage and the rest stay on
    p = with_overrides(paper_params(), {"load.coulomb_friction": 0.0,
                                        "load.static_friction": 0.0})
    lin = linearize(p, position)
    step = 1e-3
    y_lin = _p_loop_linear(LinearServo.from_linearization(lin), step)
    y_non = _p_loop_nonlinear(NonlinearServo(p), lin.trim.state, lin.trim.command, step)
    # acceptance: within 2 % of the step everywhere
    assert np.max(np.abs(y_non - y_lin)) < 0.02 * step
    # and the response is a real one: it reaches 90 % of the step
    assert y_non[-1] > 0.9 * step


def test_trim_holds_still() -> None:
    p = paper_params()
    lin = linearize(p, 0.5)
    servo = NonlinearServo(p)
    x = lin.trim.state.copy()
    for k in range(200):
        x = servo.step(k * DT, x, lin.trim.command, DT)
    # the trim is an equilibrium: drift over 0.2 s below 1e-9 m (solver tolerance 1e-13)
    assert abs(x[5] - 0.5) < 1e-9
    # model notes §4.3: holding needs u ≈ -0.045 with K_l0 = 4.68e-11; ours is the same sign
    # and order (the solved K_l0 differs), nonzero because A_f > A_n
    assert -0.06 < lin.trim.command < -0.02
