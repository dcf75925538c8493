"""``fuzzyservo simulate`` in closed loop: independent references, gains files, outputs, errors
(the open-loop path: test_simulate_open_loop.py)."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from fuzzyservo.cli import main
from fuzzyservo.files import read_gains_toml
from tests.helpers import printed_metrics

GAINS = Path(__file__).resolve().parents[2] / "src" / "fuzzyservo" / "data" / "gains"


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
    # y and r are absolute positions: the piston starts at mid-stroke (0.5 m) on every plant
    assert cols["y"][0] == 0.5 and cols["r"][0] == pytest.approx(0.6, abs=1e-15)
    # ZOH of eq. (8) by scipy (its own state-space realisation) vs the simulator: rounding
    assert np.max(np.abs(cols["y"] - 0.5 - y.ravel())) <= 1e-9 * 0.1
    assert np.all((cols["alpha"] >= 1 / 18 - 1e-12) & (cols["alpha"] <= 17 / 18 + 1e-12))


@pytest.mark.parametrize("plant", ["nonlinear", "linear", "small-signal"])
def test_metrics_flag_equals_metrics_command(tmp_path: Path, plant: str,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.csv"
    assert main(["simulate", "--plant", plant, "--controller", "pid2", "--gains",
                 "kp=20,ki=2,kd=0.1,b=0,c=0", "--duration", "0.5", "--delay", "hose",
                 "--out", str(out), "--metrics"]) == 0
    printed = capsys.readouterr().out
    assert main(["metrics", str(out)]) == 0
    assert capsys.readouterr().out == printed
    cols = _read(out)
    assert np.all(np.isnan(cols["alpha"])) and "x" in cols
    # absolute positions on every plant: starts at mid-stroke of the 1 m stroke
    assert cols["y"][0] == pytest.approx(0.5, abs=1e-9)
    assert cols["r"][-1] == pytest.approx(0.6, abs=1e-12)
    assert printed_metrics(printed)["peak"] > 0.5  # the peak is a position, absolute too


def test_metrics_without_out_and_csv_to_stdout(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["simulate", "--plant", "linear", "--controller", "p", "--gains", "kp=4",
            "--duration", "0.2"]
    assert main([*args, "--metrics"]) == 0
    metrics = printed_metrics(capsys.readouterr().out)
    assert set(metrics) >= {"rise_time", "overshoot", "itae"}
    assert main([*args, "--out", "-"]) == 0
    text = capsys.readouterr().out
    rows = list(csv.reader(io.StringIO(text)))
    assert rows[0][:5] == ["t", "r", "y", "u", "alpha"] and len(rows) == 1 + 201
    assert float(rows[1][3]) == pytest.approx(4 * 0.1, rel=1e-15)  # u_0 = kp e_0


@pytest.mark.parametrize("name", ["linear-pid", "linear-pid2", "linear-stfpi",
                                  "nonlinear-fpi-os0"])
def test_gains_file_runs_as_tuned(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    """``--gains FILE`` simulates what ``tune`` wrote: with the file's setup the printed
    metrics are the file's (same compiled loop; simulate prints 6 significant digits)."""
    path = GAINS / f"{name}.toml"
    rec = read_gains_toml(path)
    s = rec.setup
    assert main(["simulate", "--gains", str(path), "--plant", s.plant, "--reference",
                 f"step:{s.step}", "--duration", str(s.duration), "--metrics"]) == 0
    m = printed_metrics(capsys.readouterr().out)
    for key in ("rise_time", "settling_time", "overshoot", "itae", "u_max"):
        assert m[key] == pytest.approx(rec.metrics[key], rel=5e-6, abs=1e-12), key


@pytest.mark.parametrize("name", ["linear-stfpi", "nonlinear-pid2"])
def test_gains_file_alone_runs_as_tuned(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    """With only ``--gains FILE`` the file's plant, step, duration, delay and sample time are
    used (said on stderr), so the printed metrics are the tuned run's."""
    path = GAINS / f"{name}.toml"
    rec = read_gains_toml(path)
    assert main(["simulate", "--gains", str(path), "--metrics"]) == 0
    out, err = capsys.readouterr()
    m = printed_metrics(out)
    for key in ("rise_time", "settling_time", "overshoot", "itae"):
        assert m[key] == pytest.approx(rec.metrics[key], rel=5e-6, abs=1e-12), key
    assert err.count("\n") == 1 and f"as tuned, the {rec.setup.plant} plant" in err
    assert f"{rec.setup.duration:g} s" in err and "delay 0 s" in err


def test_a_run_unlike_the_tuning_says_so(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    path = GAINS / "linear-stfpi.toml"
    assert main(["simulate", "--gains", str(path), "--plant", "nonlinear", "--ts", "0.002",
                 "--delay", "hose", "--duration", "1", "--metrics"]) == 0
    err = capsys.readouterr().err
    assert "was tuned on the linear plant and with a delay of 0 s and at ts = 0.001 s" in err
    assert "kde is per sample" in err
    # a hand-written file: no record, nothing to say; the defaults apply
    mini = tmp_path / "p.toml"
    mini.write_text('controller = "p"\n[gains]\nkp = 4\n', encoding="utf-8")
    assert main(["simulate", "--gains", str(mini), "--plant", "linear", "--duration", "0.01",
                 "--out", str(tmp_path / "p.csv")]) == 0
    assert capsys.readouterr().err == ""
    assert float((tmp_path / "p.csv").read_text().splitlines()[1].split(",")[3]) == \
        pytest.approx(4 * 0.1, rel=1e-15)  # u_0 = kp e_0 with the default step of 0.1 m


def test_gains_file_and_controller_must_agree(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    path = GAINS / "linear-stfpi.toml"
    assert main(["simulate", "--controller", "stfpi", "--gains", str(path), "--plant",
                 "linear", "--duration", "0.1", "--metrics"]) == 0
    capsys.readouterr()
    assert main(["simulate", "--controller", "pid", "--gains", str(path), "--duration", "0.1",
                 "--metrics"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "is for controller stfpi, not --controller pid" in err


def test_plot_writes_a_figure(tmp_path: Path) -> None:
    fig = tmp_path / "run.png"
    assert main(["simulate", "--plant", "linear", "--gains", str(GAINS / "linear-stfpi.toml"),
                 "--duration", "3", "--plot", str(fig)]) == 0
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and fig.stat().st_size > 20_000


@pytest.mark.parametrize(
    ("args", "needle"),
    [(["--controller", "pid", "--gains", "kp=-1,ki=1,kd=0"], "kp"),
     (["--controller", "pi", "--gains", "kp=1,ki=nan"], "ki"),
     (["--controller", "pi", "--gains", "kp=1,ki=inf"], "ki"),
     (["--controller", "pi", "--gains", "kp=1,ki=1,b=0.5"], "has b = 1, got b = 0.5; use pid2"),
     (["--controller", "p", "--gains", "kp=1", "--ts", "0"], "ts"),
     (["--controller", "p", "--gains", "kp=1", "--ts", "-0.001"], "ts"),
     (["--controller", "p", "--gains", "kp=1", "--duration", "0.0005"], "duration"),
     (["--controller", "p", "--gains", "kp=1", "--delay", "-0.01"], "delay"),
     (["--controller", "lqr", "--gains", "kp=1"], "lqr"),
     (["--controller", "p", "--gains", "kp=1,kx=2"], "kx"),
     (["--controller", "fpi", "--gains", "ke=1,kde=1,kp=1"], "kp"),
     (["--controller", "stfpi", "--gains", "ke=1,kde=1"], "kdu"),
     (["--controller", "fpi", "--gains", "ke=1,kde=1,kdu=1", "--anti-windup", "none"],
      "--anti-windup does not apply to controller fpi"),
     (["--controller", "p", "--gains", "kp=1", "--reference", "step:inf"], "inf"),
     (["--controller", "p", "--gains", "kp=1", "--reference", "ramp:nan"], "nan"),
     (["--controller", "p", "--gains", "kp=1", "--plot", "x.jpg"], ".png or .svg"),
     (["--controller", "p", "--gains", "kp=1", "--plant", "spring"], "spring"),
     (["--gains", "missing.toml"], "missing.toml"),
     (["--gains", ""], "--gains is empty"),
     (["--gains", "nonexist"], "cannot read gains file 'nonexist'"),
     (["--open-loop", "--command", "0.1", "--reference", "step:0.1"], "belong to the closed loop"),
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
    assert err.startswith("fuzzyservo")
    assert not out.exists()


def test_nothing_to_do_is_an_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--controller", "p", "--gains", "kp=1"]) == 2
    assert "nothing to do" in capsys.readouterr().err


def test_gain_names_map_to_the_controller(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    assert main(["simulate", "--plant", "linear", "--controller", "p", "--gains", "kp=2",
                 "--duration", "0.01", "--out", str(out)]) == 0
    cols = _read(out)
    assert cols["u"][0] == pytest.approx(2 * 0.1, rel=1e-15)  # u_0 = kp e_0
    assert math.isnan(cols["alpha"][0])
