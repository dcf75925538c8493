"""Gains files: TOML round trip, the committed files, controllers built from a file, and one
clear error per bad file."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from fuzzyservo.analysis.autotune import TunedGains, TuningSetup, tune_controller
from fuzzyservo.errors import InputError, ParameterError
from fuzzyservo.files import load_controller, read_gains_file, read_gains_toml, write_gains_toml
from fuzzyservo.paper import named_set
from fuzzyservo.registry import build_plant, controller_kind
from fuzzyservo.sim import Step, simulate

PARAMS = named_set("paper")
GAINS_DIR = Path(__file__).resolve().parents[2] / "src" / "fuzzyservo" / "data" / "gains"


@pytest.fixture(scope="module")
def tuned_stfpi() -> TunedGains:
    setup = TuningSetup(controller="stfpi", plant="linear", duration=3.0, popsize=4,
                        maxiter=3)
    return tune_controller(setup, PARAMS)


def _same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == b


def test_toml_round_trip(tmp_path: Path, tuned_stfpi: TunedGains) -> None:
    path = write_gains_toml(tmp_path / "g.toml", tuned_stfpi)
    back = read_gains_toml(path)
    assert back.gains == tuned_stfpi.gains
    assert back.setup == dataclasses.replace(tuned_stfpi.setup,
                                             bounds=tuned_stfpi.setup.search_bounds())
    assert all(_same(back.metrics[k], v) for k, v in tuned_stfpi.metrics.items())
    assert [s.name for s in back.stages] == ["fpi", "rise", "refine"]
    assert back.stage("rise").gains == tuned_stfpi.stage("rise").gains
    assert (back.feasible, back.n_evaluations, back.version, back.date) == (
        tuned_stfpi.feasible, tuned_stfpi.n_evaluations, tuned_stfpi.version,
        tuned_stfpi.date)


def test_committed_gain_files_load() -> None:
    files = sorted(GAINS_DIR.glob("*.toml"))
    # 6 designs of the paper study (study.runner.GAIN_FILES) x 2 plants, and the self-tuning
    # fuzzy PI tuned on each plant's C8 robust set (tune --robust; tests/sweep/test_robust.py),
    # and the baselines beside them (issue 25: ffpd, smc) on each plant
    assert len(files) == 20
    for f in files:
        t = read_gains_toml(f)
        design = next((d for d in ("-os0", "-robust") if f.stem.endswith(d)), "")
        assert f.stem == f"{t.setup.plant}-{t.controller}{design}"
        assert (t.setup.robust is not None) == (design == "-robust")
        # the gains are exactly the registry kind's (a pid file's b = c = 1 are implied)
        assert tuple(t.gains) == controller_kind(t.controller).gain_names
        # "-os0": tuned for the paper's "no overshoot" (<= 0.5 %); the rest like its PID
        # (a robust file's overshoot is the largest over its set)
        limit = 0.5 if design == "-os0" else 10.0
        assert t.setup.objective == "itae" and t.setup.constraints.max_overshoot == limit
        assert t.feasible and t.metrics["overshoot"] <= limit + 1e-9


@pytest.mark.parametrize("name", ["linear-pid", "linear-pid2", "nonlinear-stfpi-os0",
                                  "nonlinear-ffpd"])
def test_controller_from_a_file_reproduces_its_tuned_run(name: str) -> None:
    ctl, gf = load_controller(GAINS_DIR / f"{name}.toml")
    rec = gf.tuned
    assert rec is not None and gf.gains == rec.gains
    assert ctl.dt == rec.setup.ts  # the file's sample time (kde is per sample)
    s = rec.setup
    plant = build_plant(s.plant, PARAMS, s.start * PARAMS.cylinder.stroke)
    run = simulate(ctl, plant, Step(s.step), duration=s.duration, delay=s.delay)
    # the tuner's batch and this single run are the same compiled loop; the linear plant
    # now reports absolute positions (0.5 m + offset), so allow a few ulps of the sum
    assert run.metric("itae") == pytest.approx(rec.metrics["itae"], rel=1e-12)
    assert run.metric("overshoot") == pytest.approx(rec.metrics["overshoot"], rel=1e-9,
                                                    abs=1e-9)


@pytest.mark.parametrize(
    ("edit", "needle"),
    [(lambda s: s.replace("kdu = ", "kdx = ", 1), "unknown gain 'kdx'"),
     (lambda s: s.replace('objective = "itae"\n', "", 1), "tuning.objective"),
     (lambda s: s.replace("seed = 0", 'seed = "zero"', 1), "tuning.seed"),
     (lambda s: s.replace("[result]", "[result_]", 1), "result"),
     (lambda s: s + "\n[[[", "not valid TOML"),
     (lambda s: s.replace("ke = ", "ke = -", 1), "gain ke must be finite and >= 0"),
     (lambda s: s.replace('controller = "stfpi"', 'controller = "lqr"', 1), "lqr")],
)
def test_bad_gains_file_names_the_key(tmp_path: Path, tuned_stfpi: TunedGains,
                                      edit: object, needle: str) -> None:
    path = write_gains_toml(tmp_path / "g.toml", tuned_stfpi)
    assert callable(edit)
    path.write_text(edit(path.read_text(encoding="utf-8")), encoding="utf-8")
    with pytest.raises(InputError, match=needle.replace("[", r"\[")) as info:
        read_gains_toml(path)
    assert str(path) in str(info.value)


def test_a_one_dof_pid_file_with_setpoint_weights_points_to_pid2(tmp_path: Path) -> None:
    text = (GAINS_DIR / "linear-pid.toml").read_text(encoding="utf-8")
    path = tmp_path / "w.toml"
    assert "\n[gains]\n" in text and "b = " not in text.split("[tuning]")[0]
    path.write_text(text.replace("\n[gains]\n", "\n[gains]\nb = 0.5\n", 1), encoding="utf-8")
    with pytest.raises(InputError, match="pid .*has b = 1, got b = 0.5; use pid2"):
        read_gains_toml(path)


def test_missing_gains_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="nothere"):
        read_gains_toml(tmp_path / "nothere.toml")


def test_a_hand_written_file_needs_controller_and_gains(tmp_path: Path) -> None:
    path = tmp_path / "ipd.toml"
    path.write_text('controller = "pid2"\n[gains]\nkp = 10\nki = 10.0\nkd = 0.1\nb = 0\n'
                    'c = 0\n', encoding="utf-8")
    gf = read_gains_file(path)
    assert (gf.controller, gf.tuned, gf.ts) == ("pid2", None, None)
    assert gf.gains == {"kp": 10.0, "ki": 10.0, "kd": 0.1, "n": 100.0, "b": 0.0, "c": 0.0}
    ctl, _ = load_controller(path, dt=2e-3)
    assert (ctl.dt, ctl.b, ctl.c, ctl.n) == (2e-3, 0.0, 0.0, 100.0)
    with pytest.raises(ParameterError, match="records no sample time .*give dt"):
        load_controller(path)


@pytest.mark.parametrize(
    ("text", "needle"),
    [('controller = "pid"\n[gains]\nkp = 1\n', "controller pid needs gains ki, kd"),
     ('controller = "pid"\n[gains]\nkp = 1\nki = 1\nkd = 0\n[extra]\n',
      "unknown key 'extra'"),
     ('[gains]\nkp = 1\n', "missing key 'controller'"),
     ('controller = "pd"\n[gains]\nkp = 1\n', "unknown controller 'pd'"),
     ('controller = "pid"\n[gains]\nkp = "one"\n', "key 'gains.kp' has the wrong type")],
)
def test_a_bad_hand_written_file_names_the_problem(tmp_path: Path, text: str,
                                                   needle: str) -> None:
    path = tmp_path / "g.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError, match=needle) as info:
        read_gains_file(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(("data", "needle"), [
    ("controller = 'pid'\n[gains]\nkp = 1.0\n".encode("utf-16"), "UTF-16 text"),
    (b"controller = 'pid'\n[gains]\nkp = 1\xff.0\n", "byte 0xff at offset 33"),
    (b"controller = 'pid'\n[gains]\nkp = 1" + b"0" * 400 + b"\n", "integer too large"),
])
def test_gains_file_read_strictly(tmp_path: Path, data: bytes, needle: str) -> None:
    """Issue 9, row 8: a gains file is strict UTF-8 (the offset of a bad byte named) and a
    number a float cannot hold is refused by key, not an OverflowError."""
    path = tmp_path / "g.toml"
    path.write_bytes(data)
    with pytest.raises(InputError, match=needle) as info:
        read_gains_file(path)
    assert "g.toml" in str(info.value) and "\n" not in str(info.value)


def test_gains_file_bounds_must_be_numbers(tmp_path: Path, tuned_stfpi: TunedGains) -> None:
    import tomllib

    import tomli_w

    path = write_gains_toml(tmp_path / "g.toml", tuned_stfpi)
    doc = tomllib.loads(path.read_text(encoding="utf-8"))
    first = next(iter(doc["tuning"]["bounds"]))
    doc["tuning"]["bounds"][first][1] = "ten"
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    with pytest.raises(InputError, match=f"'tuning.bounds.{first}.upper' has the wrong type"):
        read_gains_toml(path)


def test_a_layout_one_file_is_read_as_one_unconverged_search(tmp_path: Path) -> None:
    """Files written before the converged tuner (layout 1) are still read; they hold one
    scipy search of 40 generations, so they say restarts = 1 and not converged."""
    import tomllib

    import tomli_w

    doc = tomllib.loads((GAINS_DIR / "linear-pid2.toml").read_text(encoding="utf-8"))
    doc["format"] = 1
    del doc["structure"]
    for key in ("patience", "rtol", "spread", "restarts"):
        del doc["tuning"][key]
    doc["tuning"]["bounds"] = {k: v[:3] for k, v in doc["tuning"]["bounds"].items()}
    for table in (doc["result"], *doc["stages"]):
        for key in ("converged", "generations", "at_bounds", "restart_spread"):
            del table[key]
    path = tmp_path / "old.toml"
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    old = read_gains_toml(path)
    assert old.setup.restarts == 1 and not old.converged
    assert not any(s.converged for s in old.stages)
    assert old.gains == read_gains_toml(GAINS_DIR / "linear-pid2.toml").gains
    assert old.setup.search_bounds().zero == (False,) * 4  # layout 1 had no zero region
