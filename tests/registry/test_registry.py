"""One vocabulary: every front end offers exactly the registry's controllers and plants, and a
kind added to the registry (its maths already exists) is usable everywhere with no other change."""

from __future__ import annotations

import argparse
import ast
import math
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.analysis.autotune import TuningSetup, default_bounds, tune_controller
from fuzzyservo.cli import build_parser, main
from fuzzyservo.control import FuzzyPIController, PIDController, SelfTuningFuzzyPIController
from fuzzyservo.errors import ParameterError
from fuzzyservo.files import read_gains_toml
from fuzzyservo.paper import named_set, paper_params
from fuzzyservo.registry import (
    ControllerKind,
    GainSpec,
    build_controller,
    build_plant,
    controller_kind,
    controller_names,
    plant_names,
)
from fuzzyservo.registry import controllers as reg_controllers
from fuzzyservo.sim import Step, simulate
from fuzzyservo.study.paper_study import study_cases
from fuzzyservo.study.runner import PLANTS, default_gains_dir, load_tuned

SRC = Path(__file__).resolve().parents[2] / "src" / "fuzzyservo"


def _choices(command: str, option: str) -> tuple[str, ...]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    action = next(a for a in sub.choices[command]._actions if option in a.option_strings)
    assert action.choices is not None, f"{command} {option} has no choices"
    return tuple(action.choices)


def test_front_ends_offer_exactly_the_registry() -> None:
    assert _choices("simulate", "--controller") == controller_names()
    assert _choices("tune", "--controller") == controller_names()
    assert _choices("simulate", "--plant") == plant_names()
    assert _choices("tune", "--plant") == plant_names()
    # the study's plants and controllers are registry names
    assert set(PLANTS) <= set(plant_names())
    assert set(_choices("reproduce", "--plant")) == {*PLANTS, "both"}
    designs = {k: (v.controller, dict(v.gains))
               for k, v in load_tuned("linear", default_gains_dir()).items()}
    assert {c.kind for c in study_cases(designs)} <= set(controller_names())


#: Modules that may name controller classes: the maths and the registry; everyone else
#: builds controllers through the registry.
_MAY_IMPORT_CONTROLLERS = {"control", "registry"}
_CONTROLLER_CLASSES = {"PIDController", "FuzzyPIController", "SelfTuningFuzzyPIController",
                       "p_controller", "pi_controller"}


def test_only_the_registry_builds_controllers() -> None:
    bad = []
    for path in SRC.rglob("*.py"):
        pkg = path.relative_to(SRC).parts[0]
        if pkg in _MAY_IMPORT_CONTROLLERS:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                names = {a.name for a in node.names} & _CONTROLLER_CLASSES
                if names:
                    bad.append(f"{path.relative_to(SRC)} imports {sorted(names)}")
            elif isinstance(node, ast.Constant) and node.value in ("pid2", "stfpi", "fpi") \
                    and pkg in ("commands", "analysis", "files"):
                bad.append(f"{path.relative_to(SRC)}:{node.lineno} names {node.value!r}")
    assert not bad, "controller kinds named outside the registry:\n" + "\n".join(bad)


@pytest.fixture
def with_pd(monkeypatch: pytest.MonkeyPatch) -> ControllerKind:
    """A new kind, PD (the PID class with the integral fixed at 0), added to the registry
    only: nothing else in the package changes."""
    kp = GainSpec(name="kp", unit="1/m", description="proportional gain", search=(0.1, 100.0))
    kd = GainSpec(name="kd", unit="s/m", description="derivative gain", search=(1e-4, 1.0))
    kind = ControllerKind(name="pd", title="PD", cls=PIDController, gains=(kp, kd),
                          implied={"ki": 0.0, "n": 100.0, "b": 1.0, "c": 1.0},
                          options=("anti_windup", "u_min", "u_max"))
    monkeypatch.setitem(reg_controllers._CONTROLLERS, "pd", kind)
    return kind


def test_a_new_kind_reaches_every_front_end(with_pd: ControllerKind, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert "pd" in _choices("simulate", "--controller")
    assert "pd" in _choices("tune", "--controller")
    # simulate by name: u_0 = kp e_0 + kd N/(1 + N h) e_0 (backward-Euler filtered derivative)
    out = tmp_path / "pd.csv"
    assert main(["simulate", "--plant", "linear", "--controller", "pd", "--gains",
                 "kp=5,kd=0.01", "--duration", "0.5", "--out", str(out)]) == 0
    u0 = float(out.read_text().splitlines()[1].split(",")[3])
    h, n = 1e-3, 100.0
    expect = 5.0 * 0.1 + 0.01 * n / (1.0 + n * h) * 0.1
    assert u0 == pytest.approx(expect, rel=1e-12)  # one multiply-add of rounding
    # tune by name, write a gains file, run the file
    gains = tmp_path / "pd.toml"
    assert main(["tune", "--controller", "pd", "--plant", "linear", "--duration", "3",
                 "--popsize", "3", "--maxiter", "3", "--no-polish", "--quiet",
                 "--out", str(gains)]) in (0, 1)
    rec = read_gains_toml(gains)
    assert rec.controller == "pd" and set(rec.gains) == {"kp", "kd"}
    capsys.readouterr()
    assert main(["simulate", "--gains", str(gains), "--plant", "linear", "--duration", "3",
                 "--metrics"]) == 0
    itae = next(float(line.split()[1]) for line in capsys.readouterr().out.splitlines()
                if line.startswith("itae"))
    assert itae == pytest.approx(rec.metrics["itae"], rel=5e-6)  # 6 printed digits
    assert default_bounds("pd").names == ("kp", "kd")
    # export by name: C code whose set_gains takes the kind's gains (kp, kd)
    assert main(["export", "c", "--controller", "pd", "--gains", "kp=5,kd=0.01", "--out",
                 str(tmp_path / "pd_c")]) == 0
    header = (tmp_path / "pd_c" / "pd.h").read_text()
    assert "#define PD_N_GAINS 2" in header and "kd = 0.01 s/m" in header


def test_tuner_searches_what_the_registry_says() -> None:
    kind = controller_kind("pid2")
    box = default_bounds("pid2", 0.1)
    assert box.names == kind.searched == ("kp", "ki", "kd", "b")
    setup = TuningSetup(controller="pid2", plant="linear", duration=2.0, popsize=3, maxiter=1,
                        polish=False)
    tuned = tune_controller(setup, named_set("paper"))
    assert tuned.gains["c"] == 0.0 and tuned.gains["n"] == 100.0  # held while tuning
    ke = default_bounds("stfpi", 0.05)
    assert (ke.lower[0], ke.upper[0]) == pytest.approx((1 / 0.05, 10 / 0.05), rel=1e-15)


def test_registry_builds_the_classes_with_implied_gains() -> None:
    p = build_controller("p", {"kp": 3.0}, dt=1e-3)
    assert isinstance(p, PIDController) and (p.ki, p.kd, p.b, p.c) == (0.0, 0.0, 1.0, 1.0)
    pid = build_controller("pid", {"kp": 1.0, "ki": 2.0, "kd": 0.1, "b": 1.0}, dt=1e-3)
    assert (pid.n, pid.b, pid.c) == (100.0, 1.0, 1.0)
    ipd = build_controller("pid2", {"kp": 1.0, "ki": 2.0, "kd": 0.1, "b": 0.0, "c": 0.0},
                           dt=1e-3, options={"anti_windup": "back-calculation"})
    assert (ipd.b, ipd.c, ipd.anti_windup) == (0.0, 0.0, "back-calculation")
    assert type(build_controller("fpi", {"ke": 10, "kde": 5e3, "kdu": 0.01}, dt=1e-3)) \
        is FuzzyPIController
    st = build_controller("stfpi", {"ke": 10, "kde": 5e3, "kdu": 0.01}, dt=1e-3)
    assert type(st) is SelfTuningFuzzyPIController
    assert build_controller("pid", {"kp": 1, "ki": 0, "kd": 0, "n": math.inf}, dt=1e-3).n \
        == math.inf


@pytest.mark.parametrize(
    ("name", "gains", "options", "needle"),
    [("lqr", {}, None, "unknown controller 'lqr'; allowed: p, pi, pid, pid2, fpi, stfpi"),
     ("pid", {"kp": 1.0}, None, "controller pid needs gains ki, kd"),
     ("pid", {"kp": 1, "ki": 1, "kd": 0, "c": 0.0}, None, "has c = 1, got c = 0.0; use pid2"),
     ("pi", {"kp": 1, "ki": 1, "kx": 1}, None, "unknown gain 'kx' for controller pi"),
     ("fpi", {"ke": 1, "kde": 1, "kdu": -1}, None, "gain kdu must be finite and >= 0"),
     ("pid", {"kp": 1, "ki": 1, "kd": 1, "n": 0}, None, "gain n must be > 0 (inf: none)"),
     ("fpi", {"ke": 1, "kde": 1, "kdu": 1}, {"anti_windup": "none"},
      "controller fpi takes no option 'anti_windup'")],
)
def test_bad_requests_name_the_value_and_what_is_allowed(
        name: str, gains: dict[str, float], options: dict[str, str] | None,
        needle: str) -> None:
    with pytest.raises(ParameterError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        build_controller(name, gains, dt=1e-3, options=options)


def test_plants_start_at_rest_at_absolute_positions() -> None:
    p = paper_params()
    ctl = build_controller("pid", {"kp": 8.0, "ki": 0.1, "kd": 0.001}, dt=1e-3)
    for name in plant_names():
        plant = build_plant(name, p, 0.3)
        assert plant.y0 == pytest.approx(0.3, abs=1e-15)  # an absolute position [m]
        still = simulate(ctl, plant, np.zeros(50), duration=0.049)
        # at rest with zero error: nothing moves (trimmed nonlinear plant to 1e-9 m)
        assert np.max(np.abs(still.y - 0.3)) < 1e-9, name
        run = simulate(ctl, plant, Step(0.01), duration=1.0)
        assert run.r[-1] == pytest.approx(0.31, abs=1e-15) and run.y[-1] > 0.305, name
    with pytest.raises(ParameterError, match="unknown plant 'spring'; allowed: linear, "
                                             "small-signal, nonlinear"):
        build_plant("spring", p)
