"""Robust tuning (``tune --robust SPEC``): the statistic over the set is numpy's, the returned
design meets the constraints on every plant when each is simulated again on its own, its worst
case is no worse than the nominal design's on the same set, a one-plant set reproduces the
nominal tuning bit for bit, and the command line's errors are one line with status 2."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import fuzzyservo.commands.tune as tune_cmd
from fuzzyservo.analysis.autotune import (
    TunedGains,
    TuningProgress,
    TuningSetup,
    make_evaluator,
    tune_controller,
)
from fuzzyservo.analysis.robust import (
    RobustRecord,
    aggregate,
    parse_statistic,
    statistic_over_plants,
)
from fuzzyservo.analysis.tuning import TuningConstraints, constraint_violation, penalised_cost
from fuzzyservo.cli import main
from fuzzyservo.errors import ParameterError
from fuzzyservo.files import checkpoint_path, read_gains_file
from fuzzyservo.plant import with_overrides
from fuzzyservo.registry import build_controller, build_plant
from fuzzyservo.sim import Step, simulate
from fuzzyservo.sim.stepinfo import SETTLE_HOLD_FRACTION
from fuzzyservo.sweep.robust import MAX_ROBUST_POINTS, robust_set, robust_setup, set_digest
from fuzzyservo.sweep.sampling import points
from fuzzyservo.sweep.spec import SweepSpec, load_spec

#: Four plants of the linear servo: load mass x0.5-2, a delay up to 10 ms and a little sensor
#: noise; 3 s runs of a 20 mm step keep a tuning to a second or two.
SPEC = """
[sweep]
name = "robust test set"
plant = "linear"
duration = 3.0
samples = 4
seed = 7

[reference]
spec = "step:0.02"

[[controllers]]
label = "a pid"
controller = "pid"
gains = { kp = 5.0, ki = 0.5, kd = 0.0 }

[[vary]]
name = "load.mass"
relative = true
distribution = "log-uniform"
low = 0.5
high = 2.0

[[vary]]
name = "delay"
distribution = "uniform"
low = 0.0
high = 0.01

[[vary]]
name = "noise_std"
distribution = "log-uniform"
low = 1e-7
high = 1e-6
"""

#: The constraints of the tests: overshoot <= 10 %, |error| over the last 10 % of the run
#: <= 1 % of the step (a search of 40 generations meets it on every plant), settled.
CONSTRAINTS = TuningConstraints(max_overshoot=10.0, max_steady_state_error=0.01)
SEARCH: dict[str, Any] = {"popsize": 4, "maxiter": 40, "restarts": 1}
FAST = ["--popsize", "4", "--maxiter", "6", "--restarts", "1", "--no-polish", "--quiet"]


def _write(folder: Path, text: str, name: str = "set.toml") -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def spec_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _write(tmp_path_factory.mktemp("robust"), SPEC)


@pytest.fixture(scope="module")
def spec(spec_path: Path) -> SweepSpec:
    return load_spec(spec_path)


def _setups(spec: SweepSpec, statistic: str) -> tuple[TuningSetup, TuningSetup, Any]:
    """The robust setup, the nominal one with the same options, and the set."""
    rset, record = robust_set(spec, source="set.toml", statistic=statistic)
    base = TuningSetup(controller="pid", constraints=CONSTRAINTS, **SEARCH)
    robust = robust_setup(spec, base, record)
    nominal = TuningSetup(controller="pid", constraints=CONSTRAINTS, step=0.02, duration=3.0,
                          **SEARCH)
    return robust, nominal, rset


@pytest.fixture(scope="module")
def worst(spec: SweepSpec) -> tuple[TunedGains, TunedGains, Any]:
    """The design tuned for the worst case over the set, the nominal design, and the set."""
    robust, nominal, rset = _setups(spec, "worst")
    return (tune_controller(robust, spec.nominal, robust=rset),
            tune_controller(nominal, spec.nominal), rset)


# ---- the statistic and the aggregates --------------------------------------------------------

def test_statistics_are_numpys_on_a_known_matrix() -> None:
    v = np.array([[1.0, 2.0, 3.0, 4.0, 5.0],
                  [5.0, 1.0, 4.0, 2.0, 3.0],    # the same values shuffled
                  [0.0, 0.0, 0.0, 0.0, 10.0],
                  [1.0, np.nan, 3.0, 4.0, 5.0]])
    assert statistic_over_plants(v, "worst")[:3].tolist() == [5.0, 5.0, 10.0]
    assert statistic_over_plants(v, "mean")[:3].tolist() == [3.0, 3.0, 2.0]
    # linear interpolation between the sorted values: p90 of 1..5 sits at rank 3.6 -> 4.6
    assert statistic_over_plants(v, "p90")[:2] == pytest.approx([4.6, 4.6], abs=1e-12)
    assert statistic_over_plants(v, "p50")[:3].tolist() == [3.0, 3.0, 0.0]
    for s, q in (("p90", 90.0), ("p97.5", 97.5), ("p10", 10.0)):
        np.testing.assert_array_equal(statistic_over_plants(v[:3], s),
                                      np.percentile(v[:3], q, axis=1))
    for s in ("worst", "mean", "p90"):
        assert math.isnan(statistic_over_plants(v, s)[3])  # a failed plant fails the row


@pytest.mark.parametrize(("text", "canonical"), [
    ("worst", "worst"), ("Mean", "mean"), ("p90", "p90"), ("P90.0", "p90"), ("p97.5", "p97.5")])
def test_statistic_names(text: str, canonical: str) -> None:
    assert parse_statistic(text) == canonical


@pytest.mark.parametrize("text", ["median", "p0", "p100", "p-5", "p", "90", "max"])
def test_bad_statistic_names(text: str) -> None:
    with pytest.raises(ParameterError, match="mean, worst or a percentile"):
        parse_statistic(text)


def test_aggregates_are_worst_cases_and_the_objectives_statistic() -> None:
    nan = math.nan
    per = {"overshoot": np.array([[2.0, nan, 7.0], [1.0, 3.0, 2.0]]),
           "peak": np.array([[0.52, 0.50, 0.57], [0.51, 0.53, 0.52]]),
           "settling_time": np.array([[1.0, 2.0, nan], [1.0, 2.0, 1.5]]),
           "steady_state_error": np.array([[1e-4, -3e-4, 2e-4], [0.0, 1e-5, -1e-6]]),
           "itae": np.array([[1.0, 2.0, 6.0], [3.0, 3.0, 3.0]]),
           "u_max": np.array([[0.2, 0.9, 0.5], [0.1, 0.1, 0.3]])}
    failed = np.zeros((2, 3), dtype=bool)
    out = aggregate(per, failed, "itae", "mean")
    assert out["overshoot"].tolist() == [7.0, 3.0]        # plants that do not step ignored
    assert out["peak"].tolist() == [0.57, 0.53]           # of the largest overshoot's plant
    assert math.isnan(out["settling_time"][0]) and out["settling_time"][1] == 2.0
    assert out["steady_state_error"].tolist() == [-3e-4, 1e-5]  # largest |.|, sign kept
    assert out["itae"].tolist() == [3.0, 3.0] and out["itae_worst"].tolist() == [6.0, 3.0]
    assert out["u_max"].tolist() == [0.9, 0.3]
    failed[1, 2] = True
    out = aggregate(per, failed, "itae", "mean")
    assert all(math.isnan(v[1]) and not math.isnan(out["itae"][0]) for v in out.values())
    # one plant: every aggregate is that plant's value, exactly
    one = {k: v[:, 1:2] for k, v in per.items()}
    for stat in ("mean", "worst", "p90"):
        got = aggregate(one, np.zeros((2, 1), dtype=bool), "itae", stat)
        for k, v in one.items():
            np.testing.assert_array_equal(got[k], v[:, 0])


# ---- the tuned design on its set -------------------------------------------------------------

def test_the_robust_design_meets_the_constraints_on_every_plant(
        spec: SweepSpec, worst: tuple[TunedGains, TunedGains, Any]) -> None:
    tuned = worst[0]
    assert tuned.feasible and tuned.setup.robust is not None
    ctl = build_controller("pid", tuned.gains, dt=spec.ts)
    pts = points(spec, 0, spec.n_points)
    nominal = spec.nominal
    step = 0.02
    itae = []
    for j in range(len(pts)):
        # each plant built and run on its own, with simulate (not the batch the tuner ran)
        params = with_overrides(nominal, {"load.mass": float(pts.values["load.mass"][j])})
        plant = build_plant("linear", params, 0.5 * params.cylinder.stroke)
        res = simulate(ctl, plant, Step(step), duration=spec.duration,
                       delay=float(pts.values["delay"][j]),
                       noise_std=float(pts.values["noise_std"][j]),
                       rng=np.random.default_rng(int(pts.noise_seed[j])))
        tail = res.t >= (1.0 - SETTLE_HOLD_FRACTION) * res.t[-1]
        assert res.metric("overshoot") <= 10.0
        assert math.isfinite(res.metric("settling_time"))
        assert np.max(np.abs(res.r[tail] - res.y[tail])) <= 0.01 * step
        itae.append(res.metric("itae"))
    # the record's worst case is the largest of the plants' (same compiled loop: to rounding)
    assert tuned.metrics["itae_worst"] == pytest.approx(max(itae), rel=1e-9)
    assert tuned.objective_value == pytest.approx(max(itae), rel=1e-9)


#: Overshoot alone: the nominal design meets it on every plant of the set too, so that the two
#: designs' worst-case ITAE compare as they are.
OVERSHOOT_ONLY = TuningConstraints(max_overshoot=10.0, max_steady_state_error=None,
                                   require_settled=False)


@pytest.mark.parametrize("loose", [False, True], ids=["constraints", "overshoot-only"])
def test_the_worst_case_design_is_no_worse_than_the_nominal_one_on_the_set(
        spec: SweepSpec, worst: tuple[TunedGains, TunedGains, Any], loose: bool) -> None:
    tuned, nominal, rset = worst
    constraints = CONSTRAINTS
    if loose:
        constraints = OVERSHOOT_ONLY
        robust_s, nominal_s, _ = _setups(spec, "worst")
        tuned = tune_controller(replace(robust_s, constraints=constraints), spec.nominal,
                                robust=rset)
        nominal = tune_controller(replace(nominal_s, constraints=constraints), spec.nominal)
    ev = make_evaluator(tuned.setup, spec.nominal, robust=rset)
    names = tuned.setup.search_bounds().names
    rows = np.array([[d.gains[n] for n in names] for d in (tuned, nominal)])
    m = ev(rows)
    assert m["itae"][0] == pytest.approx(tuned.objective_value, rel=1e-12)
    # what the search minimises: the statistic plus the penalty of a violation on any plant
    cost = penalised_cost(m, "itae", constraints, 0.02)
    assert cost[0] <= cost[1]
    violation = constraint_violation(m, constraints, 0.02)
    assert violation[0] == 0.0
    if loose:
        assert violation[1] == 0.0  # both feasible on every plant: the statistic itself
        assert m["itae_worst"][0] <= m["itae_worst"][1]
    else:
        assert violation[1] > 0.0  # the nominal design fails a constraint on some plant


@pytest.mark.parametrize("controller", ["pid", "stfpi"])
def test_a_one_plant_set_with_the_mean_is_the_nominal_tuning(tmp_path: Path,
                                                            controller: str) -> None:
    text = SPEC.split("[[vary]]")[0].replace("samples = 4", "samples = 1")
    spec = load_spec(_write(tmp_path, text))
    assert spec.n_points == 1
    rset, record = robust_set(spec, source="one.toml", statistic="mean")
    opts: dict[str, Any] = {"popsize": 4, "maxiter": 5, "restarts": 1, "patience": 3}
    base = TuningSetup(controller=controller, constraints=CONSTRAINTS, seed=3, **opts)
    robust = tune_controller(robust_setup(spec, base, record), spec.nominal, robust=rset)
    nominal = tune_controller(TuningSetup(controller=controller, constraints=CONSTRAINTS,
                                          seed=3, step=0.02, duration=3.0, **opts),
                              spec.nominal)
    assert robust.gains == nominal.gains  # bit for bit
    assert (robust.objective_value, robust.cost, robust.n_evaluations) == (
        nominal.objective_value, nominal.cost, nominal.n_evaluations)
    assert [s.gains for s in robust.stages] == [s.gains for s in nominal.stages]


def test_the_set_digest_ignores_the_compared_controllers(tmp_path: Path, spec: SweepSpec
                                                         ) -> None:
    more = SPEC.replace("[[vary]]", '[[controllers]]\nlabel = "another"\ncontroller = "p"\n'
                                    'gains = { kp = 3.0 }\n\n[[vary]]', 1)
    assert set_digest(load_spec(_write(tmp_path, more))) == set_digest(spec)
    other = SPEC.replace("seed = 7", "seed = 8")
    assert set_digest(load_spec(_write(tmp_path, other, "b.toml"))) != set_digest(spec)


# ---- the shipped robust designs --------------------------------------------------------------

ROOT = Path(__file__).resolve().parents[2]
GAINS = ROOT / "src" / "fuzzyservo" / "data" / "gains"


@pytest.mark.parametrize("plant", ["linear", "nonlinear"])
def test_a_shipped_robust_design_is_its_sets_and_meets_its_record(plant: str) -> None:
    """The committed robust self-tuning fuzzy PI was tuned on the shipped set its record names
    (the digest covers every drawn plant, so a change of the draws fails here), and running
    that set again gives the recorded worst case: feasible on every plant."""
    gf = read_gains_file(GAINS / f"{plant}-stfpi-robust.toml")
    assert gf.tuned is not None and gf.tuned.setup.robust is not None
    tuned, record = gf.tuned, gf.tuned.setup.robust
    assert record.source == f"src/fuzzyservo/data/sweeps/c8-robust-set-{plant}.toml"
    spec = load_spec(ROOT / record.source)
    assert record.digest == set_digest(spec) and record.points == spec.n_points
    assert record.statistic == "worst" and tuned.feasible
    rset, _ = robust_set(spec, source=record.source, statistic=record.statistic)
    ev = make_evaluator(tuned.setup, spec.nominal, robust=rset)
    names = tuned.setup.search_bounds().names
    m = ev(np.array([[tuned.gains[n] for n in names]]))
    assert constraint_violation(m, tuned.setup.constraints, tuned.setup.step)[0] == 0.0
    # the tuner's batch and this one are the same compiled loops: equal to rounding
    for name in ("itae", "itae_worst", "overshoot", "settling_time", "final_error_max"):
        assert m[name][0] == pytest.approx(tuned.metrics[name], rel=1e-9)


# ---- the command line ------------------------------------------------------------------------

def test_tune_robust_writes_a_record_that_simulate_runs(
        tmp_path: Path, spec_path: Path, spec: SweepSpec,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "g.toml"
    code = main(["tune", "--robust", str(spec_path), "--controller", "pid", "--statistic",
                 "p90", "--max-sse", "1", "--out", str(out), *FAST])
    assert code in (0, 1)  # 1: this short search is infeasible on some plant
    printed = capsys.readouterr().out
    assert "4 linear plants" in printed and "itae p90=" in printed and "itae worst=" in printed
    gf = read_gains_file(out)
    assert gf.tuned is not None
    s = gf.tuned.setup
    assert s.robust == RobustRecord(source=str(spec_path), digest=set_digest(spec), points=4,
                                    statistic="p90")
    assert (s.plant, s.step, s.duration, s.ts, s.delay) == ("linear", 0.02, 3.0, 0.001, 0.0)
    assert main(["simulate", "--gains", str(out), "--metrics"]) == 0
    assert "was tuned on 4 plants" in capsys.readouterr().err


def _spec_with(tmp_path: Path, old: str, new: str) -> str:
    return str(_write(tmp_path, SPEC.replace(old, new, 1), "changed.toml"))


@pytest.mark.parametrize(("args", "needle"), [
    (["--statistic", "median"], "mean, worst or a percentile"),
    (["--statistic", "p100"], "mean, worst or a percentile"),
    (["--plant", "linear"], "drop --plant"),
    (["--step", "0.1", "--duration", "2"], "drop --step, --duration"),
    (["--ts", "0.002", "--start", "0.4", "--delay", "hose"], "drop --ts, --start, --delay"),
    (["--set", "paper", "--param", "load.mass=100"], "drop --set, --param"),
])
def test_bad_robust_options_are_one_error_line(
        tmp_path: Path, spec_path: Path, capsys: pytest.CaptureFixture[str],
        args: list[str], needle: str) -> None:
    assert main(["tune", "--robust", str(spec_path), "--controller", "pid", *args,
                 "--out", str(tmp_path / "g.toml"), *FAST]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("fuzzyservo: error:")
    assert needle in err
    assert not (tmp_path / "g.toml").exists()


@pytest.mark.parametrize(("change", "needle"), [
    (("samples = 4", f"samples = {MAX_ROBUST_POINTS + 1}"),
     f"{MAX_ROBUST_POINTS + 1} points (grid cells x samples); at most {MAX_ROBUST_POINTS}"),
    (('spec = "step:0.02"', 'spec = "ramp:0.01"'), "needs a step reference"),
    (("[[vary]]", '[[vary]]\nname = "amplitude"\ndistribution = "uniform"\nlow = 0.01\n'
                  'high = 0.02\n\n[[vary]]'), "must not vary amplitude"),
    (("high = 0.01", "high = 4.0"), "of the robust set is invalid (delay"),
])
def test_bad_robust_sets_are_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            change: tuple[str, str], needle: str) -> None:
    path = _spec_with(tmp_path, *change)
    assert main(["tune", "--robust", path, "--controller", "pid",
                 "--out", str(tmp_path / "g.toml"), *FAST]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("fuzzyservo: error:")
    assert needle in err


def test_statistic_without_robust_is_refused(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tune", "--controller", "pid", "--statistic", "worst",
                 "--out", str(tmp_path / "g.toml"), *FAST]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "add --robust" in err


def _interrupt_at(monkeypatch: pytest.MonkeyPatch, generation: int) -> None:
    real = tune_cmd.tune_controller

    def interrupted(*a: Any, progress: Any, **kw: Any) -> Any:
        def stop(p: TuningProgress) -> None:
            progress(p)
            if p.generation == generation:
                raise KeyboardInterrupt

        return real(*a, progress=stop, **kw)

    monkeypatch.setattr(tune_cmd, "tune_controller", interrupted)


def _without_times(path: Path) -> str:
    return "\n".join(line for line in path.read_text().splitlines()
                     if not line.startswith(("elapsed = ", "date = ")))


def test_a_robust_tuning_resumes_and_refuses_another_set_or_statistic(
        tmp_path: Path, spec_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    real = tune_cmd.tune_controller
    args = ["tune", "--robust", str(spec_path), "--controller", "pid", "--max-sse", "1",
            *FAST]
    ref = tmp_path / "ref.toml"
    code = main([*args, "--out", str(ref)])
    out = tmp_path / "g.toml"
    _interrupt_at(monkeypatch, 3)
    assert main([*args, "--out", str(out)]) == 130
    monkeypatch.setattr(tune_cmd, "tune_controller", real)
    capsys.readouterr()
    other = _spec_with(tmp_path, "seed = 7", "seed = 8")
    refused = [
        (["--statistic", "mean"], "robust (--robust/--statistic)"),
        (["--robust", other], "robust (--robust/--statistic)"),
    ]
    for extra, needle in refused:
        assert main([*args, *extra, "--out", str(out), "--resume"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and needle in err and "partial.npz" in err
    assert main(["tune", "--controller", "pid", "--out", str(out), "--resume", *FAST]) == 2
    err = capsys.readouterr().err.strip()
    assert "was made by a robust tuning" in err and len(err.splitlines()) == 1
    assert checkpoint_path(out).exists()
    assert main([*args, "--out", str(out), "--resume"]) == code
    assert _without_times(out) == _without_times(ref)  # bit for bit
    assert not checkpoint_path(out).exists()
