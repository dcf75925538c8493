"""One conformance test over every controller (STYLE section 3, like Gymnasium's check_env)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzyservo.control import (
    Controller,
    FuzzyPIController,
    PIDController,
    SelfTuningFuzzyPIController,
    p_controller,
    pi_controller,
)
from fuzzyservo.paper import alpha_system, du_system

H = 1e-3


def _fuzzy(cls: type[FuzzyPIController], **kw: Any) -> FuzzyPIController:
    return cls.from_systems(du_system(), alpha_system(), dt=H, ke=10.0, kde=5000.0, kdu=0.05,
                            **kw)


FACTORIES: dict[str, Callable[[], Any]] = {
    "p": lambda: p_controller(dt=H, kp=4.0),
    "pi": lambda: pi_controller(dt=H, kp=4.0, ki=2.0),
    "pid": lambda: PIDController(dt=H, kp=4.0, ki=2.0, kd=0.3, n=100.0),
    "i-pd": lambda: PIDController(dt=H, kp=4.0, ki=2.0, kd=0.3, b=0.0, c=0.0,
                                  anti_windup="back-calculation"),
    "pid-none": lambda: PIDController(dt=H, kp=4.0, ki=2.0, kd=0.3, anti_windup="none",
                                      u_min=-0.3, u_max=0.5),
    "fpi": lambda: _fuzzy(FuzzyPIController),
    "fpi-first-filtered": lambda: _fuzzy(FuzzyPIController, initial_error="first",
                                         filter_time=0.01, de_per="second"),
    "stfpi": lambda: _fuzzy(SelfTuningFuzzyPIController, u_min=-0.4, u_max=0.7),
}
NAMES = sorted(FACTORIES)
signals = st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1)), min_size=1, max_size=40)


def _run(ctl: Any, seq: list[tuple[float, float]]) -> tuple[list[float], Any]:
    s = ctl.initial_state()
    out = []
    for r, y in seq:
        u, s = ctl.step(s, r, y)
        out.append(u)
    return out, s


@pytest.mark.parametrize("name", NAMES)
def test_is_a_controller(name: str) -> None:
    assert isinstance(FACTORIES[name](), Controller)


@pytest.mark.parametrize("name", NAMES)
def test_zero_error_from_rest_gives_zero_command(name: str) -> None:
    u, _ = _run(FACTORIES[name](), [(0.0, 0.0)] * 50)
    assert u == [0.0] * 50


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=30, deadline=None)
@given(seq=signals)
def test_limits_hold_and_runs_are_deterministic(name: str, seq: list[tuple[float, float]]
                                                ) -> None:
    ctl = FACTORIES[name]()
    u1, s1 = _run(ctl, seq)
    u2, s2 = _run(ctl, seq)
    assert u1 == u2 and s1 == s2
    assert all(ctl.u_min <= u <= ctl.u_max for u in u1)


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=20, deadline=None)
@given(seq=signals)
def test_state_round_trips(name: str, seq: list[tuple[float, float]]) -> None:
    ctl = FACTORIES[name]()
    assert ctl.initial_state() == ctl.initial_state()
    _, s = _run(ctl, seq)
    assert ctl.unpack_state(ctl.pack_state(s)) == s
    # resuming from an unpacked copy continues identically
    tail = [(0.2, -0.1), (0.0, 0.05)]
    assert _run_from(ctl, s, tail) == _run_from(ctl, ctl.unpack_state(ctl.pack_state(s)), tail)


def _run_from(ctl: Any, s: Any, seq: list[tuple[float, float]]) -> list[float]:
    out = []
    for r, y in seq:
        u, s = ctl.step(s, r, y)
        out.append(u)
    return out


@pytest.mark.parametrize("name", NAMES)
def test_packed_gain_rows_equal_the_object(name: str) -> None:
    ctl = FACTORIES[name]()
    gains = np.array([[getattr(ctl, g) for g in ctl.gain_names]])
    assert np.array_equal(ctl.pack_gains(gains)[0], ctl.pack(), equal_nan=True)
