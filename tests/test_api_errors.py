"""The Python API's public functions take wrong types with the package's one-line errors
(issue 29): a ParameterError (a FuzzyServoError and a ValueError) naming the argument, the value
given and its type, and what is allowed; never an AttributeError, TypeError or OverflowError
from deep inside. A value with a sensible meaning is taken instead (a set's name, a reference
in its command-line form)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from fuzzyservo.errors import FuzzyServoError, InputError, ParameterError
from fuzzyservo.paper.published import named_set
from fuzzyservo.registry import build_controller, build_plant
from fuzzyservo.sim import LinearPlant, SimResult, Step, simulate

PAPER = named_set("paper")
LIN = build_plant("linear", PAPER)
GAINS = {"kp": 10.0, "ki": 1.0, "kd": 0.1}
CTL = build_controller("pid", GAINS, dt=1e-3)

#: call -> the start of the message (argument, what is allowed) and the value as shown
REFUSED: dict[str, tuple[Callable[[], Any], str]] = {
    "plant-params-None": (lambda: build_plant("linear", None),  # type: ignore[arg-type]
                          "params must be a ServoParams or the name of a set (paper, "
                          "stiff-oil), got None (NoneType)"),
    "plant-params-dict": (lambda: build_plant("linear", {"load": 1}),  # type: ignore[arg-type]
                          "params must be a ServoParams or the name of a set (paper, "
                          "stiff-oil), got {'load': 1} (dict)"),
    "plant-set-unknown": (lambda: build_plant("linear", "papr"), "'papr'"),
    "plant-substep-str": (lambda: build_plant("nonlinear", PAPER, substep="x"),  # type: ignore[arg-type]
                          "substep must be a finite real number > 0 [s], got 'x' (str)"),
    "plant-substep-0": (lambda: build_plant("nonlinear", PAPER, substep=0.0),
                        "substep must be a finite real number > 0 [s], got 0.0"),
    "plant-position-str": (lambda: build_plant("linear", PAPER, "mid"),  # type: ignore[arg-type]
                           "position must be a finite real number [m], got 'mid' (str)"),
    "controller-gains-None": (lambda: build_controller("pid", None, dt=1e-3),  # type: ignore[arg-type]
                              "gains must be a mapping (gain name to value, e.g. {'kp': "
                              "10.0}), got None (NoneType)"),
    "controller-gains-list": (lambda: build_controller("pid", [1, 2, 3], dt=1e-3),  # type: ignore[arg-type]
                              "gains must be a mapping (gain name to value, e.g. {'kp': "
                              "10.0}), got [1, 2, 3] (list)"),
    "controller-gain-10**400": (lambda: build_controller("pid", {**GAINS, "kp": 10**400},
                                                         dt=1e-3),
                                "gain kp: 1000000000000000000000000000000000000000... is "
                                "too large for a float (at most 1.8e308)"),
    "controller-gain-str": (lambda: build_controller("pid", {**GAINS, "kp": "ten"}, dt=1e-3),
                            "gain kp: 'ten' is not a number"),
    "controller-dt-str": (lambda: build_controller("pid", GAINS, dt="1e-3"),  # type: ignore[arg-type]
                          "dt (the sample time) must be a finite real number > 0 [s], got "
                          "'1e-3' (str)"),
    "controller-dt-None": (lambda: build_controller("pid", GAINS, dt=None),  # type: ignore[arg-type]
                           "dt (the sample time) must be a finite real number > 0 [s], got "
                           "None (NoneType)"),
    "controller-options-list": (lambda: build_controller("pid", GAINS, dt=1e-3,
                                                         options=["clamp"]),  # type: ignore[arg-type]
                                "options must be a mapping (option name to value), got "
                                "['clamp'] (list)"),
    "controller-systems-int": (lambda: build_controller("fpi", {"ke": 1.0, "kde": 1.0,
                                                                "kdu": 1.0}, dt=1e-3,
                                                        systems=3),  # type: ignore[arg-type]
                               "systems must be a mapping (role to fuzzy system, e.g. "
                               "{'du': ...}), got 3 (int)"),
    "simulate-duration-str": (lambda: simulate(CTL, LIN, Step(0.1), duration="1"),  # type: ignore[arg-type]
                              "duration must be a finite real number > 0 [s], got '1' (str)"),
    "simulate-delay-str": (lambda: simulate(CTL, LIN, Step(0.1), duration=1, delay="0"),  # type: ignore[arg-type]
                           "delay must be a finite real number >= 0 [s], got '0' (str)"),
    "simulate-noise-str": (lambda: simulate(CTL, LIN, Step(0.1), duration=1,
                                            noise_std="1e-6"),  # type: ignore[arg-type]
                           "noise_std must be a finite real number >= 0 [m], got '1e-6' (str)"),
    "simulate-rng-str": (lambda: simulate(CTL, LIN, Step(0.1), duration=1, rng="seed"),  # type: ignore[arg-type]
                         "rng must be a numpy.random.Generator (numpy.random.default_rng("
                         "seed)) or None, got 'seed' (str)"),
    "simulate-rng-int": (lambda: simulate(CTL, LIN, Step(0.1), duration=1, noise_std=1e-6,
                                          rng=7),  # type: ignore[arg-type]
                         "rng must be a numpy.random.Generator (numpy.random.default_rng("
                         "seed)) or None, got 7 (int)"),
    "simulate-controller-str": (lambda: simulate("notactl", LIN, Step(0.1), duration=1),  # type: ignore[arg-type]
                                "controller must be a controller object (fuzzyservo.registry"
                                ".build_controller('pid', gains, dt=...)), got 'notactl' "
                                "(str)"),
    "simulate-plant-str": (lambda: simulate(CTL, "linear", Step(0.1), duration=1),  # type: ignore[arg-type]
                           "plant must be a LinearPlant or NonlinearPlant (fuzzyservo."
                           "registry.build_plant('linear', 'paper')), got 'linear' (str)"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_wrong_arguments_are_the_packages_errors(case: str) -> None:
    call, message = REFUSED[case]
    with pytest.raises(FuzzyServoError) as info:
        call()
    assert isinstance(info.value, ParameterError | InputError)
    assert isinstance(info.value, ValueError)  # what callers catching ValueError expect
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_a_set_name_is_taken_for_the_parameters() -> None:
    by_name = build_plant("linear", "paper")
    assert isinstance(by_name, LinearPlant)
    for field in ("a", "b", "c", "x_op"):
        np.testing.assert_array_equal(getattr(by_name, field), getattr(LIN, field))
    assert (by_name.u0, by_name.stroke) == (LIN.u0, LIN.stroke)


def test_a_reference_string_is_read_as_the_command_line_reads_it() -> None:
    from_text = simulate(CTL, LIN, "step:0.1", duration=0.05)
    from_object = simulate(CTL, LIN, Step(0.1), duration=0.05)
    assert isinstance(from_text, SimResult)
    np.testing.assert_array_equal(from_text.y, from_object.y)  # the same run, bit for bit
    np.testing.assert_array_equal(from_text.r, from_object.r)


def test_a_bad_reference_string_is_one_line() -> None:
    with pytest.raises(InputError, match=r"^unknown reference 'stp:0.1'; allowed: step:A"):
        simulate(CTL, LIN, "stp:0.1", duration=0.05)


def test_numpy_numbers_are_numbers() -> None:
    """The checks take what numpy gives: float64 and int64 scalars."""
    ctl = build_controller("pid", {k: np.float64(v) for k, v in GAINS.items()},
                           dt=np.float64(1e-3))
    a = simulate(ctl, build_plant("linear", PAPER, np.float64(0.5), substep=np.float64(5e-4)),
                 Step(0.1), duration=np.int64(1), delay=np.float64(0.0))
    b = simulate(CTL, build_plant("linear", PAPER, 0.5), Step(0.1), duration=1.0)
    np.testing.assert_array_equal(a.y, b.y)
