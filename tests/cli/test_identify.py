"""``fuzzyservo identify``: a rig log made by ``simulate`` from a hidden truth is fitted, the
axis file works with ``--params`` everywhere, the bootstrap resumes exactly, eq. (8) is fitted
from time and frequency data, the designer writes a sequence ``simulate`` runs, and bad input
gets one line and status 2."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.cli import main
from fuzzyservo.commands import identify as cmd
from fuzzyservo.identify import linear
from fuzzyservo.paper.published import named_set
from fuzzyservo.plant import LinearServo, linearize, load_toml

BASE = named_set("paper")
TRUE_MASS = 1.25 * BASE.load.mass


def _command_csv(path: Path, duration: float = 3.0, dt: float = 1e-3) -> Path:
    t = np.arange(int(round(duration / dt)) + 1) * dt
    hold = -0.038453951149160524  # the paper set's trim at mid-stroke (any value would do)
    u = np.full(t.size, hold)
    u[(t >= 0.3) & (t < 0.6)] += 0.15
    u[(t >= 0.6) & (t < 0.9)] -= 0.15
    m = t >= 1.2
    u[m] += 0.1 * np.sin(2 * np.pi * (1.0 * (t[m] - 1.2) + 2.5 * (t[m] - 1.2) ** 2))
    np.savetxt(path, np.column_stack([t, u]), delimiter=",", header="t,u", comments="")
    return path


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("rig")
    cmd_csv = _command_csv(d / "cmd.csv")
    out = d / "rig.csv"
    assert main(["simulate", "--open-loop", "--command", str(cmd_csv), "--param",
                 f"load.mass={TRUE_MASS!r}", "--delay", "hose", "--noise-std", "2e-5",
                 "--seed", "3", "--out", str(out)]) == 0
    return out


def test_a_rig_log_gives_the_truth_within_its_errors(rig: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    axis = tmp_path / "axis.toml"
    # the position only: the rig's pressures are noise-free (simulate adds noise to y), so
    # their residuals would measure the optimiser's tolerance, not the data's noise
    assert main(["identify", str(rig), "--fit", "load.mass,fluid.oil_bulk_modulus",
                 "--channels", "y", "--out", str(axis), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "load.mass" in printed and "residual RMS" in printed
    doc = tomllib.loads(axis.read_text())
    rec = doc["identification"]
    est = dict(zip(rec["fitted"], rec["estimate"], strict=True))
    se = dict(zip(rec["fitted"], rec["std_error"], strict=True))
    # the rig is the model itself with noise on the position only: the truth lies within
    # three standard errors (a 0.3 % chance of failing by noise, fixed seed)
    assert abs(est["load.mass"] - TRUE_MASS) <= 3 * se["load.mass"]
    assert abs(est["fluid.oil_bulk_modulus"] - BASE.fluid.oil_bulk_modulus) <= \
        3 * se["fluid.oil_bulk_modulus"]
    assert rec["data_digest"].startswith("sha256:") and rec["plant"] == "nonlinear"
    assert rec["channels"] == ["y"]
    # the file is a parameter file for every command, whatever --set it meets
    params = load_toml(axis, named_set("stiff-oil"))
    assert params.load.mass == est["load.mass"]
    run = tmp_path / "run.csv"
    assert main(["simulate", "--open-loop", "--command", "0.05", "--duration", "0.2",
                 "--params", str(axis), "--out", str(run)]) == 0


def test_an_interrupted_bootstrap_resumes_to_the_same_bits(rig: Path, tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch
                                                           ) -> None:
    argv = ["identify", str(rig), "--fit", "load.mass", "--channels", "y", "--bootstrap", "3",
            "--quiet"]
    whole = tmp_path / "whole.toml"
    assert main([*argv, "--out", str(whole)]) == 0
    assert not cmd.partial_path(whole).exists()
    axis = tmp_path / "axis.toml"
    save = cmd._save_partial

    def interrupted(path: Path, key: str, done: np.ndarray) -> None:
        save(path, key, done)
        if done.shape[0] == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(cmd, "_save_partial", interrupted)
    assert main([*argv, "--out", str(axis)]) == 130
    assert not axis.exists() and cmd.partial_path(axis).exists()
    monkeypatch.setattr(cmd, "_save_partial", save)
    assert main([*argv, "--out", str(axis), "--resume"]) == 0
    a = tomllib.loads(whole.read_text())["identification"]
    b = tomllib.loads(axis.read_text())["identification"]
    for key in ("estimate", "std_error", "interval_low", "interval_high"):
        assert a[key] == b[key]
    assert not cmd.partial_path(axis).exists()


def test_resume_refuses_another_command(rig: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    axis = tmp_path / "axis.toml"
    argv = ["identify", str(rig), "--fit", "load.mass", "--out", str(axis), "--quiet"]
    assert main([*argv, "--resume"]) == 2
    assert "nothing to resume" in capsys.readouterr().err
    cmd._save_partial(cmd.partial_path(axis), "another", np.zeros((1, 1)))
    assert main([*argv, "--bootstrap", "2", "--resume"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "written by another command or other data" in err[0]


def test_eq8_from_time_and_frequency_data(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    lin = linearize(BASE, 0.5)
    servo = LinearServo.from_params(BASE, lin)
    # time data: eq. (8) by scipy (independent of the project's simulator), a pulse pair
    from scipy import signal

    dt = 1e-3
    t = np.arange(3001) * dt
    u = np.where((t >= 0.3) & (t < 0.6), 0.1, 0.0) - np.where((t >= 0.6) & (t < 0.9), 0.1, 0.0)
    a, b, c, d = servo.state_space()
    ad, bd, cd, dd, _ = signal.cont2discrete((a, b, c, d), dt, method="zoh")
    y = 0.5 + signal.dlsim((ad, bd, cd, dd, dt), u, t=t)[1].ravel()
    data = tmp_path / "lin.csv"
    np.savetxt(data, np.column_stack([t, u, y]), delimiter=",", header="t,u,y", comments="")
    out = tmp_path / "eq8.toml"
    # the delay not fitted is held at the set's (6 ms): these data have none
    nodelay = ["--param", "delay.transport_delay=0"]
    assert main(["identify", str(data), "--plant", "linear", "--fit", "K_o,omega_h,zeta_h",
                 *nodelay, "--out", str(out), "--quiet"]) == 0
    rec = tomllib.loads(out.read_text())["identification"]
    got = {n: v["value"] for n, v in rec["fitted"].items()}
    np.testing.assert_allclose([got["K_o"], got["omega_h"], got["zeta_h"]],
                               [servo.K_o, lin.omega_0, lin.damping], rtol=1e-6)
    # frequency data: the analytic eq. (8)
    w = np.logspace(0, 2.5, 30)
    h = linear.eq8_response(w, servo, 0.0)
    frf = tmp_path / "frf.csv"
    np.savetxt(frf, np.column_stack([w / (2 * np.pi), np.abs(h), np.degrees(np.angle(h))]),
               delimiter=",", header="frequency [Hz],gain,phase [deg]", comments="")
    out2 = tmp_path / "frf.toml"
    assert main(["identify", "--frequency-response", str(frf), "--fit",
                 "K_o,omega_h,zeta_h", *nodelay, "--out", str(out2), "--quiet"]) == 0
    rec2 = tomllib.loads(out2.read_text())["identification"]
    got2 = {n: v["value"] for n, v in rec2["fitted"].items()}
    np.testing.assert_allclose([got2["K_o"], got2["omega_h"], got2["zeta_h"]],
                               [servo.K_o, lin.omega_0, lin.damping], rtol=1e-6)
    assert "load.mass" in capsys.readouterr().out


def test_the_design_runs_on_the_model(tmp_path: Path) -> None:
    design = tmp_path / "design.csv"
    assert main(["identify", "--design", "--out", str(design), "--quiet"]) == 0
    run = tmp_path / "run.csv"
    assert main(["simulate", "--open-loop", "--command", str(design), "--out", str(run)]) == 0
    cols = np.genfromtxt(run, delimiter=",", names=True)
    stroke = BASE.cylinder.stroke
    assert 0.1 * stroke <= cols["x"].min() and cols["x"].max() <= 0.9 * stroke


@pytest.mark.parametrize("extra, match", [
    (["--fit", "load.mass", "--channels", "y,y"], "names 'y' twice"),
    (["--fit", "load.mass", "--channels", ","], "--channels names no signal"),
    (["--fit", "load.mass", "--plot", "fig.pdf"], "must end in"),
    (["--fit", "load.mass", "--substep", "0"], "--substep must be finite and > 0 s"),
    (["--fit", "K_o,omega_h,zeta_h", "--plant", "linear", "--html", "x.html"],
     "does not take --html"),
    ([], "identify needs --fit"),
    (["--fit", "load.nope"], "cannot fit unknown parameter 'load.nope'"),
    (["--fit", "load.mass", "--bounds", "load.mass=1"], "expected NAME=LO:HI"),
    (["--fit", "load.mass", "--bounds", "load.mass=a:b"], "LO and HI must be numbers"),
    (["--fit", "K_o,load.mass", "--plant", "linear"], "fit one kind at a time"),
    (["--fit", "K_o,omega_h,zeta_h"], "give --plant linear"),
    (["--fit", "load.mass", "--columns", "y"], "--columns"),
    (["--fit", "load.mass", "--design"], "--design writes an experiment"),
])
def test_bad_input_one_line_status_2(rig: Path, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str], extra: list[str],
                                     match: str) -> None:
    out = tmp_path / "axis.toml"
    assert main(["identify", str(rig), *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0], err
    assert not out.exists()


def test_bad_data_one_line_status_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = tmp_path / "bad.csv"
    t = np.arange(2000) * 1e-3
    y = 0.5 + 0.01 * np.sin(t)
    y[700] = np.nan
    np.savetxt(data, np.column_stack([t, np.sin(t), y]), delimiter=",", header="t,u,y",
               comments="")
    out = tmp_path / "axis.toml"
    out.write_text("kept")
    assert main(["identify", str(data), "--fit", "load.mass", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "y" in err[0] and "0.7" in err[0], err
    assert out.read_text() == "kept"


def test_linear_names_agree_with_the_fit() -> None:
    assert cmd.LINEAR_NAMES == linear.LINEAR_NAMES


def test_a_closed_loop_log_is_fitted_through_its_controller(tmp_path: Path) -> None:
    gains = "kp=8,ki=1,kd=0.2"
    log = tmp_path / "closed.csv"
    assert main(["simulate", "--controller", "pid", "--gains", gains, "--reference",
                 "multistep:0.2=0.05,1.5=-0.02", "--duration", "3", "--delay", "hose",
                 "--param", f"load.mass={TRUE_MASS!r}", "--noise-std", "2e-5", "--seed", "4",
                 "--out", str(log)]) == 0
    axis = tmp_path / "axis.toml"
    assert main(["identify", str(log), "--controller", "pid", "--gains", gains, "--fit",
                 "load.mass", "--channels", "y", "--out", str(axis), "--quiet"]) == 0
    rec = tomllib.loads(axis.read_text())["identification"]
    assert rec["mode"] == "closed loop"
    # the logged noise fed the real loop's controller, not the model's: still within 3 SE
    assert abs(rec["estimate"][0] - TRUE_MASS) <= 3 * rec["std_error"][0]
