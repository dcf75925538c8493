"""``fuzzyservo simulate`` closed-loop cases (the open-loop path: test_cli_simulate_open_loop)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from fuzzyservo.cli import main


def _read(path: Path) -> dict[str, np.ndarray]:
    with path.open() as fh:
        rows = list(csv.reader(fh))
    return {name: np.array([float(r[j]) for r in rows[1:]]) for j, name in enumerate(rows[0])}


def test_linear_plant_follows_the_linearize_transfer_function(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.csv"
    assert main(["simulate", "--plant", "linear", "--controller", "stfpi", "--gains",
                 "ke=10,kde=5000,kdu=0.006", "--reference", "step:0.1", "--duration", "1",
                 "--ts", "0.001", "--delay", "0.006", "--out", str(out)]) == 0
    cols = _read(out)
    assert list(cols)[:5] == ["t", "r", "y", "u", "alpha"]
    assert main(["linearize", "--json"]) == 0
    lin = json.loads(capsys.readouterr().out)
    den = np.polymul(np.polymul([1 / lin["omega_v"] ** 2, 2 * lin["zeta_v"] / lin["omega_v"], 1],
                                [1 / lin["omega_0"] ** 2, 2 * lin["damping"] / lin["omega_0"], 1]),
                     [1.0, 0.0])
    if lin["tau_v"] > 0:
        den = np.polymul(den, [lin["tau_v"], 1.0])
    a, b, c, d, _ = signal.cont2discrete(signal.tf2ss([lin["K_o"]], den), 0.001, method="zoh")
    u_valve = np.concatenate([np.zeros(6), cols["u"][:-6]])  # 6 ms = 6 samples
    _, y, _ = signal.dlsim((a, b, c, d, 0.001), u_valve)
    # ZOH of eq. (8) by scipy (its own state-space realisation) vs the simulator: rounding
    assert np.max(np.abs(cols["y"] - y.ravel())) <= 1e-9 * 0.1
    assert np.all((cols["alpha"] >= 1 / 18 - 1e-12) & (cols["alpha"] <= 17 / 18 + 1e-12))


def test_metrics_flag_equals_metrics_command(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.csv"
    assert main(["simulate", "--plant", "nonlinear", "--controller", "pid", "--gains",
                 "kp=20,ki=2,kd=0.1,b=0,c=0", "--duration", "0.5", "--delay", "0.006",
                 "--out", str(out), "--metrics"]) == 0
    printed = capsys.readouterr().out
    assert main(["metrics", str(out)]) == 0
    assert capsys.readouterr().out == printed
    cols = _read(out)
    assert np.all(np.isnan(cols["alpha"])) and "x" in cols and "p_f" in cols
    assert cols["y"][0] == pytest.approx(0.5, abs=1e-9)  # starts at mid-stroke of 1 m


@pytest.mark.parametrize(
    ("args", "needle"),
    [(["--controller", "pid", "--gains", "kp=-1,ki=1,kd=0"], "kp"),
     (["--controller", "pi", "--gains", "kp=1,ki=nan"], "ki"),
     (["--controller", "pi", "--gains", "kp=1,ki=inf"], "ki"),
     (["--controller", "p", "--gains", "kp=1", "--ts", "0"], "ts"),
     (["--controller", "p", "--gains", "kp=1", "--ts", "-0.001"], "ts"),
     (["--controller", "p", "--gains", "kp=1", "--duration", "0.0005"], "duration"),
     (["--controller", "p", "--gains", "kp=1", "--delay", "-0.01"], "delay"),
     (["--controller", "lqr", "--gains", "kp=1"], "lqr"),
     (["--controller", "p", "--gains", "kp=1,kx=2"], "kx"),
     (["--controller", "fpi", "--gains", "ke=1,kde=1,kp=1"], "kp"),
     (["--controller", "stfpi", "--gains", "ke=1,kde=1"], "kdu"),
     (["--controller", "p", "--gains", "kp=1", "--reference", "step:inf"], "inf"),
     (["--controller", "p", "--gains", "kp=1", "--reference", "ramp:nan"], "nan"),
     (["--gains", "kp=1"], "--controller")],
)
def test_bad_input_is_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                     args: list[str], needle: str) -> None:
    out = tmp_path / "x.csv"
    status = main(["simulate", "--plant", "linear", "--duration", "0.1", *args,
                   "--out", str(out)])
    err = capsys.readouterr().err
    assert status == 2
    assert len(err.strip().splitlines()) == 1 and needle in err
    assert err.startswith("fuzzyservo: error:")
    assert not out.exists()


def test_gain_names_map_to_the_controller(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    assert main(["simulate", "--plant", "linear", "--controller", "p", "--gains", "kp=2",
                 "--duration", "0.01", "--out", str(out)]) == 0
    cols = _read(out)
    assert cols["u"][0] == pytest.approx(2 * 0.1, rel=1e-15)  # u_0 = kp e_0
    assert math.isnan(cols["alpha"][0])
