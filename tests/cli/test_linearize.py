"""``fuzzyservo linearize`` and the shared plant options (issue 3 acceptance)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fuzzyservo.cli import main

KEYS = {"omega_0", "damping", "K_o", "omega_v", "zeta_v", "tau_v", "velocity_gain",
        "eigenvalues"}


def _json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict:  # type: ignore[type-arg]
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_default_set_json(capsys: pytest.CaptureFixture[str]) -> None:
    d = _json(capsys, ["linearize", "--json"])
    assert KEYS <= set(d)
    # acceptance: ω₀ = 19.6 rad/s within 1 %, δ = 0.100 within 3 %
    assert d["omega_0"] == pytest.approx(19.6, rel=0.01)
    assert d["damping"] == pytest.approx(0.100, rel=0.03)
    # K_o = 2.613e-3 / 9.9756e-3 (exact up to the 5-digit area); Table A.1 valve values
    assert d["K_o"] == pytest.approx(0.26194, rel=1e-4)
    assert (d["omega_v"], d["zeta_v"], d["tau_v"]) == (688.7, 0.3572, 0.0)
    lo, hi = d["omega_0_range"]
    assert lo < d["omega_0"] < hi  # the variation over 5-95 % of the stroke is reported
    eig = [complex(re, im) for re, im in d["eigenvalues"]]
    pair = [e for e in eig if e.imag > 0 and abs(e) < 100]
    # the reported pair is the one ω₀ and δ are read from (same numbers, rounding only)
    assert abs(pair[0]) == pytest.approx(d["omega_0"], rel=1e-12)


def test_param_and_file_overrides(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    base = _json(capsys, ["linearize", "--json"])
    heavy = _json(capsys, ["linearize", "--json", "--param", "load.mass=59466.85"])
    # ω₀ ∝ 1/sqrt(M): 4x mass halves ω₀ (valve coupling and trim change it by < 1 %)
    assert heavy["omega_0"] == pytest.approx(base["omega_0"] / 2, rel=0.01)
    f = tmp_path / "p.toml"
    f.write_text("[load]\nmass = 59466.85\n")
    from_file = _json(capsys, ["linearize", "--json", "--params", str(f)])
    assert from_file["omega_0"] == heavy["omega_0"]


def test_text_output_has_units(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["linearize", "--set", "stiff-oil", "--position", "0.5"]) == 0
    out = capsys.readouterr().out
    for needle in ("omega_0", "rad/s", "K_o", "m/s per unit command", "tau_v", "eigenvalues"):
        assert needle in out


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--param", "valve.nul_leakage=0"], "unknown parameter 'valve.nul_leakage'"),
        (["--param", "load.mass"], "GROUP.FIELD=VALUE"),
        (["--param", "load.mass=heavy"], "must be a number"),
        (["--param", "cylinder.rod_diameter=0.2"], "cylinder.rod_diameter must be smaller"),
        (["--param", "valve.discharge_coefficient=1.5"], "(0, 1], got 1.5"),
        (["--param", "delay.transport_delay=-1"], "delay.transport_delay must be >= 0"),
        (["--set", "nope"], "unknown parameter set 'nope'"),
        (["--position", "1.5"], "--position must be a fraction of the stroke"),
        (["--params", "/nonexistent/p.toml"], "cannot read parameter file"),
    ],
)
def test_errors_one_line_status_2(capsys: pytest.CaptureFixture[str], argv: list[str],
                                  needle: str) -> None:
    assert main(["linearize", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fuzzyservo: error:")
    assert needle in err
