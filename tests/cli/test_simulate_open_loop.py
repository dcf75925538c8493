"""``fuzzyservo simulate --open-loop``: every registered plant, SI columns, any delay."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from fuzzyservo.cli import main
from fuzzyservo.paper import paper_params
from fuzzyservo.plant import linearize
from fuzzyservo.registry import build_plant, plant_names
from fuzzyservo.sim.closed_loop import MAX_SAMPLES


def _read(path: Path) -> dict[str, list[float]]:
    # a plain DictReader: the first line must be the header (as in the closed-loop CSV)
    with open(path, encoding="utf-8", newline="") as fh:
        reader = csv.DictReader(fh)
        head = list(reader.fieldnames or [])
        rows = list(reader)
    return {h: [float(r[h]) for r in rows] for h in head}


OFF = ["--param", "valve.null_leakage=0", "--param", "cylinder.internal_leakage=0",
       "--param", "load.coulomb_friction=0", "--param", "load.static_friction=0",
       "--param", "load.viscous_damping=0"]


@pytest.mark.parametrize("plant", plant_names())
def test_open_loop_csv(tmp_path: Path, plant: str) -> None:
    out = tmp_path / "run.csv"
    argv = ["simulate", "--plant", plant, "--open-loop", "--command", "0.5", "--duration",
            "2", "--out", str(out)]
    assert main(argv + (OFF if plant == "nonlinear" else [])) == 0
    d = _read(out)
    p = paper_params()
    states = build_plant(plant, p).state_names
    assert list(d) == ["t", "u", "y", *states]
    assert len(d["t"]) == 2001 and d["t"][-1] == pytest.approx(2.0, abs=1e-12)  # 1 ms grid
    assert d["x"][0] == 0.5 and d["y"][0] == 0.5 and d["v"][0] == 0.0  # at rest, mid-stroke
    assert d["y"] == d["x"]  # no transducer noise or resolution: y is the position
    if plant == "nonlinear":
        # acceptance: 0.5 x rated flow / A_f within 3 %
        assert d["v"][-1] == pytest.approx(0.5 * 2.613e-3 / p.cylinder.piston_area, rel=0.03)
    elif plant == "linear":
        # eq. (8): v = K_o u at steady state, K_o = Q_rated/A_f (the δ = 0.1 ringing has
        # decayed to < 1 % after 2 s)
        assert d["v"][-1] == pytest.approx(0.5 * p.velocity_gain, rel=0.01)
        assert "p_f" not in d
    else:
        # small signal: its gain times the command step from the trim, 3 %
        lin = linearize(p, 0.5)
        assert d["v"][-1] == pytest.approx(lin.velocity_gain * (0.5 - lin.trim.command),
                                           rel=0.03)
        assert all(math.isfinite(v) for v in d["p_f"])


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--command", "1.5"], "--command must be in [-1, 1]"),
        ([], "--open-loop needs --command"),
        (["--command", "0.1", "--duration", "-2"], "duration must be finite and at least one"),
        (["--command", "0.1", "--duration", "1e-9"],
         "at least one sample (0.001 s), got 1e-09"),
        (["--command", "0.5", "--duration", "1e6"], f"at most {MAX_SAMPLES} are allowed"),
        (["--command", "0.1", "--delay", "-0.001"], "--delay must be a number of seconds"),
        (["--command", "0.1", "--delay", "long"], "or 'hose'"),
        (["--command", "0.1", "--metrics"], "--metrics needs a closed loop"),
        (["--command", "0.1", "--controller", "pid"], "drop --controller/--gains"),
        (["--command", "0.1", "--plant", "linear", "--method", "solve_ivp"],
         "solve_ivp' is the reference for the nonlinear plant"),
    ],
)
def test_open_loop_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                          extra: list[str], needle: str) -> None:
    out = tmp_path / "r.csv"
    assert main(["simulate", "--open-loop", "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err
    assert not out.exists()


def test_open_loop_delay_option(tmp_path: Path) -> None:
    """No delay by default; ``--delay hose`` is the set's delay.transport_delay (6 ms);
    any delay is a time shift, fractions of a sample included."""
    runs = {}
    for name, extra in (("default", []), ("none", ["--delay", "0"]),
                        ("hose", ["--delay", "hose"]), ("six", ["--delay", "0.006"]),
                        ("set", ["--delay", "hose", "--param", "delay.transport_delay=0.012"]),
                        ("twelve", ["--delay", "0.012"]), ("half", ["--delay", "0.0025"])):
        out = tmp_path / f"{name}.csv"
        assert main(["simulate", "--open-loop", "--command", "0.5", "--duration", "0.1",
                     "--out", str(out), *extra]) == 0
        runs[name] = _read(out)["x"]
    assert runs["default"] == runs["none"]  # same run: identical text
    assert runs["hose"] == runs["six"] and runs["set"] == runs["twelve"]
    # the valve holds the trim command for the delay, then steps: a pure shift of the run
    # without delay (rounding only: 1e-12 m)
    for name, d in (("six", 6), ("twelve", 12)):
        assert runs[name][d:] == pytest.approx(runs["none"][:-d], rel=0, abs=1e-12)
    assert runs["twelve"][12] != pytest.approx(runs["none"][12], rel=0, abs=1e-9)  # it moved
    # 2.5 samples: between the runs shifted by 2 and by 3 samples, strictly, once moving
    late = range(20, 100)
    assert all(runs["none"][k - 3] < runs["half"][k] < runs["none"][k - 2] for k in late)


def test_a_command_file_is_held_per_sample_and_logged_with_noise(tmp_path: Path) -> None:
    """--command FILE.csv: the same run as the array given to simulate_open_loop; the
    transducers' noise (seeded) goes on the logged y and pressures, not on the states x, v."""
    import numpy as np

    from fuzzyservo.sim import simulate_open_loop

    t = np.arange(501) * 1e-3
    u = np.where((t >= 0.1) & (t < 0.3), 0.2, -0.1)
    cmd = tmp_path / "cmd.csv"
    np.savetxt(cmd, np.column_stack([t, u]), delimiter=",", header="t,u", comments="")
    out = tmp_path / "run.csv"
    assert main(["simulate", "--open-loop", "--command", str(cmd), "--noise-std", "1e-4",
                 "--pressure-noise-std", "5e4", "--seed", "9", "--out", str(out)]) == 0
    d = _read(out)
    ref = simulate_open_loop(build_plant("nonlinear", paper_params()), u[:-1], duration=0.5)
    assert d["x"] == list(ref.x) and d["u"][:-1] == list(ref.u)  # bit for bit
    rng = np.random.default_rng(9)  # the noise: y first, then p_f, then p_n
    ny = rng.normal(0.0, 1e-4, t.size)
    npf = rng.normal(0.0, 5e4, t.size)
    assert np.array_equal(np.array(d["y"]), ref.y + ny)
    assert np.array_equal(np.array(d["p_f"]), ref.p_f + npf)


@pytest.mark.parametrize("rows, extra, match", [
    ([[0.0, 0.1], [1e-3, 0.1], [3e-3, 0.2]], [], "evenly spaced"),
    ([[0.0, 0.1], [1e-3, 1.5], [2e-3, 0.2]], [], "u = 1.5 at t = 0.001 s; it must be in"),
    ([[0.0, 0.1], [2e-3, 0.1], [4e-3, 0.2]], ["--ts", "0.001"], "not --ts 0.001 s"),
    ([[0.0, 0.1], [1e-3, 0.1], [2e-3, 0.2]], ["--duration", "1"], "holds 3 samples"),
    ([[0.0, 0.1], [1e-3, 0.1], [2e-3, 0.2]], ["--plant", "linear", "--pressure-noise-std",
                                               "1"], "has no chamber pressures"),
])
def test_bad_command_files_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                    rows: list[list[float]], extra: list[str],
                                    match: str) -> None:
    cmd = tmp_path / "cmd.csv"
    cmd.write_text("t,u\n" + "".join(f"{a!r},{b!r}\n" for a, b in rows))
    assert main(["simulate", "--open-loop", "--command", str(cmd), *extra, "--out",
                 str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0], err
