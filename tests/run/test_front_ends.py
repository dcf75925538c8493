"""The study, the tuner and the page make their runs through RunSpec: the command line of each
run they make gives the same samples and metrics, bit for bit, and what they are handed that
the run does not describe is refused."""

from __future__ import annotations

import copy
import dataclasses
import pickle
import re
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.analysis.autotune import TuningSetup, make_evaluator, tune_controller
from fuzzyservo.analysis.tuning import TuningConstraints
from fuzzyservo.app.settings import PAGE_RUN, PageSettings
from fuzzyservo.cli import main
from fuzzyservo.errors import ParameterError
from fuzzyservo.paper import named_set
from fuzzyservo.plant import with_overrides
from fuzzyservo.run import RunSpec, load_systems, overrides_of, systems_record
from fuzzyservo.study.paper_study import StudyConfig, run_plant_study
from fuzzyservo.study.runner import default_gains_dir, load_tuned, study_jobs

PAPER = named_set("paper")
HEAVY = with_overrides(PAPER, {"load.mass": 2.0 * PAPER.load.mass})


def _replayed(spec: RunSpec):  # type: ignore[no-untyped-def]
    """The run of the command line ``spec`` writes, read back as the CLI reads it."""
    back = RunSpec.from_argv(["simulate", *spec.to_argv()])
    assert back == spec
    return back.run()


def _same(a, b) -> None:  # type: ignore[no-untyped-def]
    for name in ("t", "r", "y", "u"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(np.asarray(a.alpha), np.asarray(b.alpha), equal_nan=True)


@pytest.fixture(scope="module")
def study():  # type: ignore[no-untyped-def]
    cfg = StudyConfig(params=PAPER, duration=2.0, delay_sweep=(0.0, 0.02))
    designs = {k: (v.controller, dict(v.gains))
               for k, v in load_tuned("linear", default_gains_dir()).items()}
    return cfg, run_plant_study("linear", cfg, designs,
                                changed_plants={"load mass x2": HEAVY})


def test_every_run_of_the_study_is_its_command_line(study) -> None:  # type: ignore[no-untyped-def]
    cfg, st = study
    for case in st.cases:
        spec = cfg.run_spec("linear", case)
        assert spec.overrides == () and spec.reference == "step:0.1"
        _same(_replayed(spec), st.runs[case.key])
    stfpi = next(c for c in st.cases if c.key == "stfpi")
    delayed = dataclasses.replace(cfg.run_spec("linear", stfpi), delay=cfg.fig8_delay)
    _same(_replayed(delayed), st.delayed)
    heavy = cfg.run_spec("linear", stfpi, params=HEAVY)
    assert heavy.overrides == (("load.mass", 2.0 * PAPER.load.mass),)
    _same(_replayed(heavy), st.variant_runs["load mass x2"])


def test_the_studys_batches_are_its_runs(study) -> None:  # type: ignore[no-untyped-def]
    """The delay sweep and the changed plants run as batches of the same RunSpec: each row's
    metrics are those of the single run its command line makes."""
    cfg, st = study
    for case in st.cases:
        spec = cfg.run_spec("linear", case)
        for i, d in enumerate(cfg.delay_sweep):
            one = _replayed(dataclasses.replace(spec, delay=d)).metrics()
            assert st.sweep[case.key]["iae"][i] == one.iae, (case.key, d)
            assert st.sweep[case.key]["overshoot"][i] == one.overshoot, (case.key, d)
        heavy = _replayed(cfg.run_spec("linear", case, params=HEAVY)).metrics()
        assert st.variant_metrics["load mass x2"][case.key]["iae"] == heavy.iae, case.key


def test_the_tuned_gains_are_what_their_run_spec_runs() -> None:
    setup = TuningSetup(controller="pid", duration=2.0, popsize=3, maxiter=2, restarts=1,
                        polish=False, overrides=(("load.mass", HEAVY.load.mass),))
    tuned = tune_controller(setup, HEAVY)
    spec = setup.run_spec(gains=tuned.gains)
    assert (spec.plant, spec.reference, spec.duration, spec.overrides) == (
        "linear", "step:0.1", 2.0, (("load.mass", HEAVY.load.mass),))
    m = _replayed(spec).metrics().as_dict()
    for name in ("itae", "overshoot", "settling_time", "u_max"):
        assert np.array_equal(tuned.metrics[name], m[name], equal_nan=True), name


def test_a_tuning_of_a_run_takes_its_fields() -> None:
    run = RunSpec(controller="stfpi", plant="nonlinear", param_set="stiff-oil",
                  overrides=(("load.mass", 900.0),), reference="step:0.05", duration=4.0,
                  ts=0.002, delay=0.006, start=0.4, gains=(("ke", 3.0),))
    setup = TuningSetup.for_run(run, objective="iae", seed=2)
    assert setup == TuningSetup(controller="stfpi", plant="nonlinear", param_set="stiff-oil",
                                overrides=(("load.mass", 900.0),), step=0.05, duration=4.0,
                                ts=0.002, delay=0.006, start=0.4, objective="iae", seed=2)
    assert setup.run_spec() == dataclasses.replace(run, gains=())


@pytest.mark.parametrize(("change", "needle"), [
    ({"reference": "sine:0.05:1"}, "tunes a step response from t = 0"),
    ({"reference": "step:0.1:0.5"}, "tunes a step response from t = 0"),
    ({"options": (("anti_windup", "none"),)}, "without controller options: drop anti_windup"),
    ({"noise_std": 1e-6}, "without measurement noise"),
])
def test_a_tuning_refuses_what_it_would_not_run(change: dict[str, object], needle: str) -> None:
    run = dataclasses.replace(RunSpec(controller="pid", plant="linear"), **change)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match=needle):
        TuningSetup.for_run(run)


def test_parameters_the_run_does_not_describe_are_refused() -> None:
    spec = RunSpec(controller="p", gains=(("kp", 1.0),), plant="linear")
    said = f"load.mass is {HEAVY.load.mass!r}, the run says {PAPER.load.mass!r}"
    with pytest.raises(ParameterError, match=re.escape(said)):
        spec.build(params=HEAVY)
    with pytest.raises(ParameterError, match=r"not the run's set 'paper'.*load\.mass"):
        spec.build_batch(params=HEAVY)
    described = dataclasses.replace(spec, overrides=overrides_of(HEAVY, "paper"))
    assert described.build(params=HEAVY).params is HEAVY
    assert described.params() == HEAVY
    # the tuner is held to its setup's parameters the same way
    with pytest.raises(ParameterError, match=r"load\.mass"):
        tune_controller(TuningSetup(controller="pid", duration=2.0, maxiter=1, popsize=2,
                                    restarts=1), HEAVY)


def test_the_studys_tunings_record_the_overrides_they_run_on() -> None:
    jobs = study_jobs("linear", "paper", overrides=overrides_of(HEAVY, "paper"))
    for _, setup in jobs:
        assert setup.overrides == (("load.mass", HEAVY.load.mass),)
        assert setup.run_spec().params() == HEAVY
    assert dict(jobs)["stfpi-os0"].constraints != TuningConstraints()  # the no-overshoot one
    assert [name for name, _ in jobs][-3:] == ["ffpd", "smc", "wfpi"]  # the baselines, last


def test_page_settings_hold_a_run_spec() -> None:
    s = PageSettings(controller="pid", gains=(("kp", 1.0),), seed=5, substep=1e-5)
    assert s.run == dataclasses.replace(PAGE_RUN, controller="pid", gains=(("kp", 1.0),))
    assert (s.controller, s.plant, s.duration, s.seed) == ("pid", "linear", 5.0, 0)
    noisy = s.replace(noise_std=1e-6, seed=5, plant="nonlinear", substep=1e-5)
    assert (noisy.seed, noisy.substep, noisy.run_spec()) == (5, 1e-5, noisy.run)
    assert PageSettings(noisy.run) == noisy and hash(PageSettings(noisy.run)) == hash(noisy)
    assert s.with_gain("kp", 2.0).gains == (("kp", 2.0),)
    with pytest.raises(AttributeError, match="immutable"):
        s.controller = "pi"  # type: ignore[misc]
    with pytest.raises(AttributeError, match="no attribute 'colour'"):
        s.colour  # noqa: B018


SYSTEMS = Path(__file__).resolve().parents[2] / "src" / "fuzzyservo" / "data" / "systems"


def test_a_tuning_with_the_papers_own_system_file_is_the_papers() -> None:
    """A file holding the paper's system is the paper's: not recorded, and the tuning of a
    run that names it is taken (the page's tuner refused it for a while)."""
    run = RunSpec(controller="stfpi", plant="linear", duration=10.0,
                  systems=(("du", str(SYSTEMS / "paper-du.fis")),))
    systems = load_systems("stfpi", dict(run.systems))
    assert systems_record(systems) == ()
    assert TuningSetup.for_run(run, systems=systems_record(systems)) == TuningSetup(
        controller="stfpi")
    with pytest.raises(ParameterError, match="systems must record fuzzy systems of the run"):
        TuningSetup.for_run(run, systems=(("alpha", "other.fis", "0" * 64),))
    with pytest.raises(ParameterError, match="default RK4 step bound"):
        TuningSetup.for_run(dataclasses.replace(run, plant="nonlinear", substep=1e-4))


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_tune_names_a_step_that_is_not_a_number(value: str, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "g.toml"
    assert main(["tune", "--controller", "pid", "--step", value, "--out", str(out)]) == 2
    assert not out.exists()
    assert capsys.readouterr().err.strip() == (
        f"fuzzyservo: error: TuningSetup.step must be finite and > 0, got {float(value)!r}")


def test_equal_parameters_in_another_type_are_the_runs() -> None:
    """An int where the set has the same double is the same parameter; no field differing
    is not an error."""
    as_int = dataclasses.replace(PAPER, load=dataclasses.replace(PAPER.load, mass=900))
    spec = RunSpec(controller="p", gains=(("kp", 1.0),), plant="linear",
                   overrides=(("load.mass", 900.0),))
    assert spec.build(params=as_int).params is as_int


def test_the_tuner_without_systems_runs_the_papers() -> None:
    """systems=None is the paper's, whatever files the setup records (the caller passes what
    it read; the record is by digest)."""
    ghost = TuningSetup(controller="fpi", duration=1.0, popsize=2, maxiter=1, restarts=1,
                        polish=False, systems=(("du", "/nonexistent/du.fis", "0" * 64),))
    paper = dataclasses.replace(ghost, systems=())
    rows = np.array([[10.0, 5e3, 1e-3]])
    assert make_evaluator(ghost, PAPER)(rows)["itae"] == make_evaluator(paper, PAPER)(rows)["itae"]


def test_page_settings_copy_and_pickle() -> None:
    s = PageSettings(controller="pid", gains=(("kp", 1.0),), noise_std=1e-6, seed=3)
    for other in (copy.copy(s), copy.deepcopy(s), pickle.loads(pickle.dumps(s))):
        assert other == s and other.run == s.run and other.seed == 3
