"""Fuzzy systems from files in the loop: ``--du-system`` / ``--alpha-system`` of simulate and
tune, the shipped paper files, and the checks of a system before a loop runs."""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.cli import main
from fuzzyservo.control import FuzzyPIController
from fuzzyservo.errors import ParameterError
from fuzzyservo.files import read_gains_file
from fuzzyservo.formats import dumps, loads, read_system
from fuzzyservo.fuzzy import evaluate, pack
from fuzzyservo.fuzzy.loop import always_fires, loop_system
from fuzzyservo.fuzzy.system import (
    And,
    Consequent,
    FuzzySystem,
    Is,
    Rule,
    Term,
    Variable,
)
from fuzzyservo.paper import (
    SYSTEM_FILES,
    alpha_system,
    du_system,
    paper_fuzzy_system,
    paper_params,
    system_file,
    write_system_files,
)
from fuzzyservo.registry import build_controller, build_plant
from fuzzyservo.sim import Step, simulate
from fuzzyservo.sim.batch import simulate_batch

GAINS = Path(__file__).resolve().parents[2] / "src" / "fuzzyservo" / "data" / "gains"
SYSTEMS = Path(__file__).resolve().parents[2] / "src" / "fuzzyservo" / "data" / "systems"

# The general evaluator and the uniform-grid kernel agree to ~1e-15 per evaluation (see
# tests/fuzzy/test_general.py); the incremental controller sums one increment per sample, so
# over N samples the commands may drift apart by N * 1e-15 (a 3 s run at 1 kHz: 3e-12).
PER_SAMPLE = 1e-15


def _read(path: Path) -> dict[str, np.ndarray]:
    with path.open() as fh:
        rows = list(csv.reader(line for line in fh if not line.startswith("#")))
    return {name: np.array([float(r[j]) for r in rows[1:]]) for j, name in enumerate(rows[0])}


def test_the_shipped_files_are_the_writers_output_and_read_back_as_the_paper_systems(
        tmp_path: Path) -> None:
    written = write_system_files(tmp_path)
    assert sorted(p.name for p in written) == sorted(SYSTEM_FILES)
    for p in written:
        shipped = SYSTEMS / p.name
        assert shipped.read_bytes() == p.read_bytes(), (
            f"{shipped} is stale: regenerate with write_system_files (fuzzyservo.paper)")
        role = p.name.split("-")[1].split(".")[0]
        assert read_system(shipped) == paper_fuzzy_system(role)
        assert system_file(role, p.suffix[1:]) == shipped


@pytest.mark.parametrize("role,maker", [("du", du_system), ("alpha", alpha_system)])
def test_the_paper_systems_from_files_evaluate_as_the_built_in_ones(role: str,
                                                                    maker: object) -> None:
    rng = np.random.default_rng(7)
    x = rng.uniform(-1.2, 1.2, (20_000, 2))
    built_in = pack(maker())  # type: ignore[operator]
    assert built_in.path == "uniform grid"
    ref = evaluate(built_in, x)[:, 0]
    for fmt in ("fis", "fcl", "fll"):
        system = read_system(system_file(role, fmt))
        got = evaluate(pack(system, grid=False), x)[:, 0]
        # two exact evaluators: rounding only (outputs within [-1, 1])
        assert np.max(np.abs(got - ref)) <= 1e-14
        # the file has the uniform-grid form: packed as the built-in system, the same bits
        assert pack(system).path == "uniform grid"
        np.testing.assert_array_equal(evaluate(system, x)[:, 0], ref)


def test_a_loop_with_the_paper_files_equals_the_built_in_loop() -> None:
    plant = build_plant("linear", paper_params())
    g = {"ke": 10.0, "kde": 5000.0, "kdu": 0.006}
    # the general evaluator on the files (grid=False), and the files as packed by default
    # (the uniform grid, as the built-in systems)
    general_files = {r: loop_system(read_system(system_file(r, "fcl")), source=r, grid=False)
                     for r in ("du", "alpha")}
    grid_files = {r: loop_system(read_system(system_file(r, "fcl")), source=r)
                  for r in ("du", "alpha")}
    assert all(f.packed.path == "partition" for f in general_files.values())
    assert all(f.packed.path == "uniform grid" for f in grid_files.values())
    for kind in ("fpi", "stfpi"):
        a = simulate(build_controller(kind, g, dt=1e-3), plant, Step(0.1), duration=3.0)
        b = simulate(build_controller(kind, g, dt=1e-3, systems=general_files), plant,
                     Step(0.1), duration=3.0)
        n = a.u.size
        assert np.max(np.abs(a.u - b.u)) <= n * PER_SAMPLE
        assert np.max(np.abs(a.y - b.y)) <= n * PER_SAMPLE * 0.1  # |y'| << |u|' here
        assert np.max(np.abs(a.u)) > 0.05  # the loop moved
        c = simulate(build_controller(kind, g, dt=1e-3, systems=grid_files), plant,
                     Step(0.1), duration=3.0)
        np.testing.assert_array_equal(c.u, a.u)  # the same tables, the same code
        np.testing.assert_array_equal(c.y, a.y)


def test_the_batch_kernel_runs_a_file_system_as_the_single_run_kernel() -> None:
    plant = build_plant("nonlinear", paper_params())
    files = {r: loop_system(read_system(system_file(r, "fll")), source=r, grid=False)
             for r in ("du", "alpha")}  # the general evaluator's loops
    ctl = build_controller("stfpi", {"ke": 10.0, "kde": 5000.0, "kdu": 0.006}, dt=1e-3,
                           systems=files)
    gains = np.array([[10.0, 5000.0, 0.006], [20.0, 2000.0, 0.003]])
    batch = simulate_batch(ctl, gains, plant=plant, reference=Step(0.1), duration=1.0,
                           keep_traces=True)
    for i, row in enumerate(gains):
        one = build_controller("stfpi", dict(zip(("ke", "kde", "kdu"), row, strict=True)),
                               dt=1e-3, systems=files)
        single = simulate(one, plant, Step(0.1), duration=1.0)
        # same compiled step, same plant integrator: identical to rounding of the order of
        # operations
        assert np.max(np.abs(batch.u[i] - single.u)) <= 1e-12


def _five_by_five() -> FuzzySystem:
    """A non-paper Δu system: trapezoid ends, unequal triangles, product AND, five labels."""
    labels = ("NB", "NS", "ZO", "PS", "PB")
    terms = (Term("NB", "trapezoid", (-math.inf, -1.0, -0.6, -0.2)),
             Term("NS", "triangle", (-0.7, -0.3, 0.0)), Term("ZO", "triangle", (-0.2, 0.0, 0.2)),
             Term("PS", "triangle", (0.0, 0.3, 0.7)),
             Term("PB", "trapezoid", (0.2, 0.6, 1.0, math.inf)))
    e = Variable("e", (-1.0, 1.0), terms)
    de = Variable("de", (-1.0, 1.0), terms)
    out = Variable("du", (-1.0, 1.0), terms, default=0.0)
    rules = []
    for i in range(5):
        for j in range(5):
            k = min(4, max(0, i + j - 2))
            rules.append(Rule(And((Is(0, i), Is(1, j))), (Consequent(0, k),)))
    del labels
    return FuzzySystem(name="five", inputs=(e, de), outputs=(out,), rules=tuple(rules),
                       and_op="product")


def test_a_non_paper_system_runs_in_the_loop_as_its_per_sample_evaluation() -> None:
    """The compiled loop vs a Python loop of the controller's equations calling the general
    evaluator per sample (the incremental fuzzy PI, eqs. 9-12 with α = 1)."""
    system = _five_by_five()
    ls = loop_system(system, source="five")
    ke, kde, kdu, dt = 8.0, 3000.0, 0.01, 1e-3
    ctl = FuzzyPIController.from_systems(ls, dt=dt, ke=ke, kde=kde, kdu=kdu)
    y = np.concatenate([np.linspace(0.0, 0.1, 50), 0.1 + 0.01 * np.sin(np.arange(150))])
    r = 0.12
    state = ctl.initial_state()
    u_prev, e_prev = 0.0, 0.0
    assert ls.packed.path != "uniform grid"
    for k, yk in enumerate(y):
        u, state = ctl.step(state, r, float(yk))
        e = r - yk
        de = e - (e_prev if k > 0 else 0.0)
        dun = evaluate(ls.packed, [ke * e, kde * de])[0]
        u_ref = min(max(u_prev + kdu * dun, -1.0), 1.0)
        assert u == pytest.approx(u_ref, abs=1e-15)
        u_prev, e_prev = u_ref, e


def test_loop_system_checks() -> None:
    five = _five_by_five()
    assert always_fires(paper_fuzzy_system("du"))
    assert always_fires(five)
    # a NaN default with a rule table that leaves a cell empty: refused, then accepted with a
    # value for "no rule fires", which the loop then uses
    holed = dataclasses.replace(
        five, rules=five.rules[1:],
        outputs=(dataclasses.replace(five.outputs[0], default=math.nan),))
    assert not always_fires(holed)
    with pytest.raises(ParameterError, match="no value for when no rule fires"):
        loop_system(holed, source="holed.fll")
    ok = loop_system(holed, source="holed.fll", no_rule_value=0.25)
    corner = evaluate(ok.packed, [-1.0, -1.0])[0]  # only the removed rule fires
    assert corner == 0.25
    three = dataclasses.replace(five, inputs=(*five.inputs, dataclasses.replace(
        five.inputs[0], name="x3")))
    with pytest.raises(ParameterError, match="takes two inputs"):
        loop_system(three, source="three.fll")


def test_simulate_with_system_files_equals_the_built_in_run(tmp_path: Path) -> None:
    base = ["simulate", "--gains", str(GAINS / "nonlinear-stfpi.toml"), "--duration", "2"]
    assert main([*base, "--out", str(tmp_path / "a.csv")]) == 0
    a = _read(tmp_path / "a.csv")
    for fmt in ("fis", "fcl", "fll"):
        out = tmp_path / f"b_{fmt}.csv"
        assert main([*base, "--du-system", str(system_file("du", fmt)), "--alpha-system",
                     str(system_file("alpha", fmt)), "--out", str(out)]) == 0
        b = _read(out)
        assert np.max(np.abs(a["u"] - b["u"])) <= a["u"].size * PER_SAMPLE
        assert np.max(np.abs(a["y"] - b["y"])) <= 1e-12


def test_simulate_system_options_refused_where_they_do_not_apply(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = str(tmp_path / "x.csv")
    cases = [
        (["--controller", "p", "--gains", "kp=1", "--du-system", str(system_file("du"))],
         "--du-system applies to controller fpi, stfpi or wfpi, not p"),
        (["--controller", "fpi", "--gains", "ke=1,kde=1,kdu=0.01", "--alpha-system",
          str(system_file("alpha"))], "--alpha-system applies to controller stfpi, not fpi"),
        (["--controller", "fpi", "--gains", "ke=1,kde=1,kdu=0.01", "--no-rule-value", "0"],
         "--no-rule-value applies to a system from a file"),
        (["--controller", "fpi", "--gains", "ke=1,kde=1,kdu=0.01", "--du-system",
          str(tmp_path / "missing.fis")], "missing.fis"),
        (["--controller", "fpi", "--gains", "ke=1,kde=1,kdu=0.01", "--du-system",
          str(tmp_path / "x.txt")], "cannot tell the format"),
    ]
    for extra, message in cases:
        assert main(["simulate", *extra, "--duration", "1", "--out", out]) == 2
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1
        assert not Path(out).exists()


def test_simulate_names_the_scaling_and_a_gains_file_tuned_with_other_systems(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    five = tmp_path / "five.fll"
    five.write_text(dumps(_five_by_five(), "fll"))
    assert loads(five.read_text(), "fll") == _five_by_five()
    assert main(["simulate", "--gains", str(GAINS / "linear-fpi.toml"), "--du-system",
                 str(five), "--duration", "1", "--out", str(tmp_path / "r.csv")]) == 0
    err = capsys.readouterr().err
    assert f"du system {five}: e in [-1, 1] = K_e e, de in [-1, 1] = K_de de" in err
    assert "the gains were tuned with the paper's du system; this run uses du system" in err
    # the shipped paper file is the paper's system: no such note
    assert main(["simulate", "--gains", str(GAINS / "linear-fpi.toml"), "--du-system",
                 str(system_file("du", "fis")), "--duration", "1", "--out",
                 str(tmp_path / "r.csv")]) == 0
    assert "tuned with" not in capsys.readouterr().err


FAST = ["--popsize", "4", "--maxiter", "4", "--duration", "3", "--no-polish", "--quiet",
        "--restarts", "1", "--plant", "linear"]


def test_tune_records_the_system_and_simulate_asks_for_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    five = tmp_path / "five.fcl"
    five.write_text(dumps(_five_by_five(), "fcl"))
    out = tmp_path / "g.toml"
    main(["tune", "--controller", "fpi", "--du-system", str(five), "--out", str(out), *FAST])
    capsys.readouterr()
    gf = read_gains_file(out)
    assert gf.tuned is not None
    (role, source, digest), = gf.tuned.setup.systems
    assert (role, source) == ("du", str(five))
    assert digest == loop_system(read_system(five)).digest
    assert main(["simulate", "--gains", str(out), "--duration", "1", "--out",
                 str(tmp_path / "r.csv")]) == 0
    assert f"(pass --du-system {five})" in capsys.readouterr().err


def test_tune_resume_with_another_system_is_refused(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    from fuzzyservo.analysis.autotune import TuningSetup
    from fuzzyservo.files import checkpoint_path
    from fuzzyservo.files.checkpoint import Checkpoint, save_checkpoint

    del TuningSetup, Checkpoint, save_checkpoint
    five = tmp_path / "five.fll"
    five.write_text(dumps(_five_by_five(), "fll"))
    out = tmp_path / "g.toml"
    # an interrupted run leaves a checkpoint; make one by interrupting at the first report
    import fuzzyservo.commands.tune as tune_cmd

    calls = {"n": 0}
    real = tune_cmd._Progress.__call__

    def interrupt(self: object, p: object) -> None:
        real(self, p)  # type: ignore[arg-type]
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt

    tune_cmd._Progress.__call__ = interrupt  # type: ignore[method-assign]
    try:
        assert main(["tune", "--controller", "fpi", "--du-system", str(five), "--out",
                     str(out), *FAST]) == 130
    finally:
        tune_cmd._Progress.__call__ = real  # type: ignore[method-assign]
    assert checkpoint_path(out).exists()
    capsys.readouterr()
    assert main(["tune", "--controller", "fpi", "--out", str(out), "--resume", *FAST]) == 2
    err = capsys.readouterr().err
    assert "made with fuzzy systems from files" in err and err.count("\n") == 1
    other = tmp_path / "other.fll"
    other.write_text(dumps(dataclasses.replace(_five_by_five(), and_op="min"), "fll"))
    assert main(["tune", "--controller", "fpi", "--du-system", str(other), "--out", str(out),
                 "--resume", *FAST]) == 2
    assert "systems (--du-system/--alpha-system)" in capsys.readouterr().err
