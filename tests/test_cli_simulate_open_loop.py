"""``fuzzyservo simulate --open-loop`` writes the issue's columns in SI units."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from fuzzyservo.cli import main
from fuzzyservo.commands.simulate import OPEN_LOOP_COLUMNS
from fuzzyservo.paper import paper_params
from fuzzyservo.plant import linearize
from fuzzyservo.sim.closed_loop import MAX_SAMPLES


def _read(path: Path) -> dict[str, list[float]]:
    # a plain DictReader: the first line must be the header (as in the closed-loop CSV)
    with open(path, encoding="utf-8", newline="") as fh:
        reader = csv.DictReader(fh)
        head = list(reader.fieldnames or [])
        rows = list(reader)
    return {h: [float(r[h]) for r in rows] for h in head}


@pytest.mark.parametrize("plant", ["nonlinear", "linear"])
def test_open_loop_csv(tmp_path: Path, plant: str) -> None:
    out = tmp_path / "run.csv"
    off = ["--param", "valve.null_leakage=0", "--param", "cylinder.internal_leakage=0",
           "--param", "load.coulomb_friction=0", "--param", "load.static_friction=0",
           "--param", "load.viscous_damping=0"]
    argv = ["simulate", "--plant", plant, "--open-loop", "--command", "0.5", "--duration",
            "2", "--out", str(out)]
    assert main(argv + (off if plant == "nonlinear" else [])) == 0
    d = _read(out)
    assert list(d) == list(OPEN_LOOP_COLUMNS)
    assert out.read_text(encoding="utf-8").splitlines()[0] == ",".join(OPEN_LOOP_COLUMNS)
    assert len(d["t"]) == 2001 and d["t"][-1] == pytest.approx(2.0, abs=1e-12)  # 1 ms grid
    assert d["x"][0] == 0.5 and d["v"][0] == 0.0  # at rest at mid-stroke
    if plant == "nonlinear":
        p = paper_params()
        # acceptance: 0.5 x rated flow / A_f within 3 %
        assert d["v"][-1] == pytest.approx(0.5 * 2.613e-3 / p.cylinder.piston_area, rel=0.03)
    else:
        # linear: small-signal gain times the command step from the trim, 3 % (ringing
        # of the δ = 0.1 mode has decayed to < 1 % after 2 s)
        lin = linearize(paper_params(), 0.5)
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
        (["--command", "0.1", "--dt", "0.004"],
         "delay.transport_delay = 0.006 s is not a whole number of samples"),
        (["--command", "0.1", "--delay", "0.0025"],
         "delay = 0.0025 s is not a whole number of samples of dt = 0.001 s"),
        (["--command", "0.1", "--delay", "-0.001"], "delay must be finite and >= 0 s"),
    ],
)
def test_open_loop_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                          extra: list[str], needle: str) -> None:
    assert main(["simulate", "--open-loop", "--out", str(tmp_path / "r.csv"), *extra]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err


def test_open_loop_delay_option(tmp_path: Path) -> None:
    """``--delay`` overrides the set's delay.transport_delay (6 ms), which is the default."""
    runs = {}
    for name, extra in (("set", []), ("six", ["--delay", "0.006"]), ("none", ["--delay", "0"]),
                        ("twelve", ["--delay", "0.012"])):
        out = tmp_path / f"{name}.csv"
        assert main(["simulate", "--open-loop", "--command", "0.5", "--duration", "0.1",
                     "--out", str(out), *extra]) == 0
        runs[name] = _read(out)["x"]
    assert runs["set"] == runs["six"]  # same run: identical text
    # the valve holds the trim command for the delay, then steps: a pure shift of the run
    # without delay (rounding only: 1e-12 m)
    for name, d in (("six", 6), ("twelve", 12)):
        assert runs[name][d:] == pytest.approx(runs["none"][:-d], rel=0, abs=1e-12)
    assert runs["twelve"][12] != pytest.approx(runs["none"][12], rel=0, abs=1e-9)  # it moved
