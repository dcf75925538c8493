"""Bad input found in review: each is one error line with status 2 (or 1 where noted)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fuzzyservo.cli import main

STFPI = ["simulate", "--plant", "linear", "--controller", "stfpi", "--gains",
         "ke=10,kde=5000,kdu=0.006", "--duration", "1"]


def _err(argv: list[str], capsys: pytest.CaptureFixture[str], status: int = 2) -> str:
    assert main(argv) == status
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


def test_duplicate_gain_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = _err(["simulate", "--plant", "linear", "--controller", "pid", "--gains",
                "kp=1,ki=0.1,kd=0.1,kp=8", "--out", str(tmp_path / "r.csv")], capsys)
    assert "kp is given twice" in err and err.count("\n") == 1


def test_negative_seed_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = _err([*STFPI, "--seed", "-1", "--out", str(tmp_path / "r.csv")], capsys)
    assert "--seed" in err and "-1" in err


def test_run_too_long_for_memory_is_rejected(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    err = _err(["simulate", "--plant", "nonlinear", "--controller", "p", "--gains", "kp=10",
                "--ts", "1e-9", "--duration", "1", "--out", str(tmp_path / "r.csv")], capsys)
    assert "samples" in err and "at most" in err


def test_delay_is_none_unless_asked(tmp_path: Path) -> None:
    """--delay omitted is no delay, whatever the set's delay.transport_delay; --delay hose
    takes delay.transport_delay; an explicit --delay S is S."""
    outs = {}
    for tag, extra in (("default", ["--param", "delay.transport_delay=0.05"]),
                       ("hose", ["--delay", "hose", "--param", "delay.transport_delay=0.05"]),
                       ("explicit", ["--delay", "0.05"]), ("none", ["--delay", "0"])):
        out = tmp_path / f"{tag}.csv"
        assert main([*STFPI, "--out", str(out), *extra]) == 0
        outs[tag] = out.read_text()
    assert outs["default"] == outs["none"] != outs["explicit"] == outs["hose"]


def test_tune_seed_must_be_non_negative(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    err = _err(["tune", "--controller", "pid", "--plant", "linear", "--seed", "-3",
                "--out", str(tmp_path / "g.toml")], capsys)
    assert "seed" in err


def test_tune_that_cannot_meet_its_constraints_says_so(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "g.toml"
    err = _err(["tune", "--controller", "pid", "--plant", "linear", "--max-u", "0",
                "--popsize", "3", "--maxiter", "2", "--no-polish", "--duration", "2",
                "--quiet", "--out", str(out)], capsys, status=1)
    assert "meet the constraints" in err
    assert out.is_file()  # the best found is kept, not lost


def test_reproduce_refuses_runs_too_short_to_judge(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    err = _err(["reproduce", "--out", str(tmp_path / "r"), "--plant", "linear",
                "--duration", "0.01", "--quiet"], capsys)
    assert "--duration" in err and "0.01" in err


def test_reproduce_into_a_path_below_a_file(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "afile"
    f.write_text("x")
    err = _err(["reproduce", "--out", str(f / "sub"), "--plant", "linear", "--duration", "5",
                "--quiet"], capsys)
    assert "cannot write" in err


# ------------------------------------------------------------------------------------------
# issue 29, "What to build" item 4: each case ends in one line and status 2 (or works)

SYSTEMS = Path(__file__).resolve().parents[2] / "src" / "fuzzyservo" / "data" / "systems"
PID = ["--controller", "pid", "--gains", "kp=20,ki=2,kd=0.1"]
LINEAR = ["simulate", "--plant", "linear", *PID, "--duration", "0.05"]
RUN_CSV = "t,r,y,u\n0,0.1,0,0\n0.01,0.1,0.05,0.5\n0.02,0.1,0.09,0.1\n0.03,0.1,0.1,0\n"


def _one_line(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``argv`` in-process: status 2, one line on stderr (the error), no traceback; before
    it only the notices of a first compile of the kernels (a run after an edit)."""
    assert main(argv) == 2
    lines = capsys.readouterr().err.splitlines(keepends=True)
    assert lines and all(ln.startswith("fuzzyservo: compil") for ln in lines[:-1]), lines
    err = lines[-1]
    assert err.startswith("fuzzyservo: error: ") and err.endswith("\n"), lines
    return err


def _run_csv(tmp_path: Path) -> Path:
    p = tmp_path / "run.csv"
    p.write_text(RUN_CSV)
    return p


@pytest.mark.parametrize("argv", [
    ["linearize", "--json"],
    ["linearize"],
    ["metrics", "{run}"],
    ["metrics", "--json", "{run}"],
    [*LINEAR, "--metrics"],
    [*LINEAR, "--out", "-"],
    ["fis", "info", str(SYSTEMS / "paper-du.fis")],
    ["fis", "info", "--json", str(SYSTEMS / "paper-du.fis")],
    ["fis", "eval", str(SYSTEMS / "paper-du.fis"), "--grid", "3"],
    ["sweep", "--example"],
], ids=lambda a: " ".join(a[:3]))
def test_issue29_a_full_standard_output_is_one_line(tmp_path: Path, argv: list[str]) -> None:
    """``> /dev/full``: every write fails with ENOSPC; status 2, one error line naming it."""
    argv = [a.replace("{run}", str(_run_csv(tmp_path))) for a in argv]
    with open("/dev/full", "w") as full:  # noqa: PTH123 - a device, written by the child
        proc = subprocess.run([sys.executable, "-m", "fuzzyservo", *argv], stdout=full,
                              stderr=subprocess.PIPE, text=True, timeout=600, check=False)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr
    errors = [ln for ln in proc.stderr.splitlines() if "error" in ln]
    assert errors == ["fuzzyservo: error: cannot write standard output: No space left on "
                      "device"], proc.stderr
    lines = proc.stderr.splitlines()
    assert lines[-1] == errors[0]  # before it, at most the notices of a first compile
    assert all(ln.startswith("fuzzyservo: compil") for ln in lines[:-1]), proc.stderr


@pytest.mark.parametrize("option", ["--label", "--title"])
@pytest.mark.parametrize("text", [r"$\alpha^{$", r"$\nosuchsymbol$", "$$"])
def test_issue29_broken_mathtext_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                          option: str, text: str) -> None:
    fig = tmp_path / "fig.png"
    err = _one_line(["plot", str(_run_csv(tmp_path)), "--out", str(fig), option, text],
                    capsys)
    assert f"{option} '{text}' is not valid mathtext (" in err
    assert "write a literal dollar sign as \\$" in err
    assert not fig.exists()


def test_issue29_valid_mathtext_and_lone_dollars_are_drawn(tmp_path: Path) -> None:
    fig = tmp_path / "fig.png"
    assert main(["plot", str(_run_csv(tmp_path)), "--out", str(fig), "--label",
                 "costs $5 or 6$ or more", "--title", r"$\alpha_F$ and \$"]) == 0
    assert fig.stat().st_size > 0


def _fcl(first_term: str, singletons: tuple[str, str] = ("-1", "1")) -> str:
    return f"""FUNCTION_BLOCK big
VAR_INPUT
  x : REAL;
END_VAR
VAR_OUTPUT
  y : REAL;
END_VAR
FUZZIFY x
  TERM lo := {first_term};
  TERM hi := (0, 0) (1, 1);
END_FUZZIFY
DEFUZZIFY y
  TERM a := {singletons[0]};
  TERM b := {singletons[1]};
  METHOD : COGS;
  DEFAULT := 0;
END_DEFUZZIFY
RULEBLOCK r
  RULE 1 : IF x IS lo THEN y IS a;
  RULE 2 : IF x IS hi THEN y IS b;
END_RULEBLOCK
END_FUNCTION_BLOCK
"""


@pytest.mark.parametrize("value", ["1e308", "1.7976931348623157e308", "8e307"])
def test_issue29_fis_show_of_huge_singletons_is_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str) -> None:
    f = tmp_path / "huge.fcl"
    f.write_text(_fcl("(0, 1) (1, 0)", (f"-{value}", value)))
    fig = tmp_path / "fig.png"
    err = _one_line(["fis", "show", str(f), "--out", str(fig)], capsys)
    lo, hi = -float(value), float(value)
    assert f"cannot draw output 'y': its range [{lo!r}, {hi!r}] reaches beyond +-1e+300" in err
    assert not fig.exists()
    assert main(["fis", "eval", str(f), "--grid", "3", "--out", str(tmp_path / "o.csv")]) == 0


def test_issue29_fis_show_draws_ranges_up_to_its_bound(tmp_path: Path) -> None:
    f = tmp_path / "wide.fcl"
    f.write_text(_fcl("(0, 1) (1, 0)", ("-1e300", "1e300")))
    fig = tmp_path / "fig.png"
    assert main(["fis", "show", str(f), "--out", str(fig)]) == 0
    assert fig.stat().st_size > 0


def _points(n: int) -> str:
    return " ".join(f"({k / n!r}, {k % 2})" for k in range(n))


@pytest.mark.parametrize("argv", [
    ["fis", "info", "{f}"],
    ["fis", "eval", "{f}", "--grid", "3"],
    ["fis", "show", "{f}", "--out", "{d}/fig.png"],
    [*LINEAR[:2], "linear", "--controller", "fpi", "--gains", "ke=10,kde=5000,kdu=0.006",
     "--duration", "0.05", "--du-system", "{f}", "--out", "{d}/r.csv"],
], ids=["info", "eval", "show", "simulate"])
def test_issue29_an_fcl_term_of_200000_points_is_refused_at_once(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    f = tmp_path / "many.fcl"
    f.write_text(_fcl(_points(200_000)))
    err = _one_line([a.replace("{f}", str(f)).replace("{d}", str(tmp_path)) for a in argv],
                    capsys)
    assert "many.fcl:9:" in err and "term 'lo' has 200000 points; a term takes at most 512" \
        in err


def test_issue29_fcl_terms_of_512_points_are_read(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "ok.fcl"
    f.write_text(_fcl(_points(512)))
    assert main(["fis", "info", "--json", str(f)]) == 0
    assert '"lo"' in capsys.readouterr().out
    f.write_text(_fcl(_points(513)))
    assert "term 'lo' has 513 points" in _one_line(["fis", "info", str(f)], capsys)


def test_issue29_fis_discretemf_points_are_capped_like_fcl(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = (SYSTEMS / "paper-du.fis").read_text()
    head, sep, rest = text.partition("MF1=")
    line, nl, tail = rest.partition("\n")
    name = line.split(":")[0]
    values = " ".join(f"{k / 600!r} {k % 2}" for k in range(600))
    f = tmp_path / "many.fis"
    f.write_text(f"{head}{sep}{name}:'discretemf',[{values}]{nl}{tail}")
    err = _one_line(["fis", "info", str(f)], capsys)
    assert "discretemf has 600 points; a term takes at most 512" in err


@pytest.mark.parametrize("argv", [
    ["fis", "eval", str(SYSTEMS / "paper-du.fis"), "--grid", "4000"],
    ["fis", "eval", str(SYSTEMS / "paper-du.fis"), "--grid", "1001"],
    ["surface", "du", "--grid", "4000", "--out", "o.csv"],
], ids=["fis-4000", "fis-1001", "surface-4000"])
def test_issue29_grids_are_bounded(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                   monkeypatch: pytest.MonkeyPatch, argv: list[str]) -> None:
    monkeypatch.chdir(tmp_path)
    err = _one_line(argv, capsys)
    assert f"--grid must be between 2 and 1000, got {argv[argv.index('--grid') + 1]}" in err


def test_issue29_the_largest_grid_is_evaluated(tmp_path: Path) -> None:
    out = tmp_path / "o.csv"
    assert main(["fis", "eval", str(SYSTEMS / "paper-alpha.fcl"), "--grid", "1000", "--out",
                 str(out)]) == 0
    assert out.read_text().count("\n") == 1 + 1000 * 1000


@pytest.mark.parametrize("argv", [
    [*LINEAR, "--seed", "123456789012345678901234567", "--noise", "1e-6"],
    [*LINEAR, "--seed", str(2**63), "--noise", "1e-6"],
    ["tune", "--controller", "pid", "--plant", "linear", "--quiet", "--seed",
     "123456789012345678901234567"],
], ids=["simulate-27-digits", "simulate-2**63", "tune"])
def test_issue29_seeds_are_bounded(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                   argv: list[str]) -> None:
    out = tmp_path / ("g.toml" if argv[0] == "tune" else "r.csv")
    err = _one_line([*argv, "--out", str(out)], capsys)
    assert "seed must be an integer from 0 to 9223372036854775807 (2**63 - 1), got " in err
    assert argv[argv.index("--seed") + 1] in err
    assert not out.exists()


def test_issue29_the_largest_seed_is_taken(tmp_path: Path) -> None:
    out = tmp_path / "r.csv"
    assert main([*LINEAR, "--seed", str(2**63 - 1), "--noise", "1e-6", "--out", str(out)]) == 0


@pytest.mark.parametrize("plant", ["linear", "small-signal"])
@pytest.mark.parametrize("param", ["transducer.resolution=1e-3", "supply.ripple_amplitude=5e5"])
def test_issue29_a_parameter_the_plant_leaves_out_is_noted(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], plant: str, param: str) -> None:
    """The note says the run is the same without the parameter: it is, byte for byte."""
    argv = ["simulate", "--plant", plant, *PID, "--duration", "0.05"]
    plain, with_it = tmp_path / "plain.csv", tmp_path / "with.csv"
    assert main([*argv, "--out", str(plain)]) == 0
    capsys.readouterr()
    assert main([*argv, "--param", param, "--out", str(with_it)]) == 0
    err = capsys.readouterr().err
    key, value = param.split("=")
    assert (f"fuzzyservo: note: parameter {key} = {float(value)!r} has no effect on the "
            f"{plant} plant (only the nonlinear model has it); the run is the same without "
            f"it") in err
    assert with_it.read_bytes() == plain.read_bytes()


def test_issue29_the_nonlinear_plant_takes_the_transducer_without_a_note(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["simulate", "--plant", "nonlinear", *PID, "--duration", "0.05"]
    plain, with_it = tmp_path / "plain.csv", tmp_path / "with.csv"
    assert main([*argv, "--out", str(plain)]) == 0
    assert main([*argv, "--param", "transducer.resolution=1e-3", "--out", str(with_it)]) == 0
    assert "note" not in capsys.readouterr().err
    assert with_it.read_bytes() != plain.read_bytes()  # it rounds the measurement


@pytest.mark.parametrize("value", ["1e-300", "0.5", "99999"])
def test_issue29_an_unphysical_supply_pressure_is_refused(
        capsys: pytest.CaptureFixture[str], value: str) -> None:
    err = _one_line(["linearize", "--param", f"supply.pressure={value}"], capsys)
    assert (f"supply.pressure must be at least 100000 Pa (1 bar absolute: below the "
            f"atmosphere there is no supply), got {float(value)!r} Pa") in err


def test_issue29_a_supply_of_one_bar_is_allowed(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["linearize", "--param", "supply.pressure=1e5", "--param",
                 "supply.tank_pressure=0"]) == 0


@pytest.mark.parametrize("tuned", [False, True], ids=["plain", "tuned"])
def test_issue29_a_gains_file_of_an_unknown_layout_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], tuned: bool) -> None:
    g = tmp_path / "g.toml"
    if tuned:
        shipped = Path(SYSTEMS.parent / "gains" / "linear-pid.toml").read_text()
        assert shipped.startswith("format = 2\n")
        g.write_text(shipped.replace("format = 2\n", "format = 99\n", 1))
    else:
        g.write_text('format = 99\ncontroller = "pid"\n[gains]\nkp = 10.0\nki = 1.0\n'
                     'kd = 0.1\n')
    out = tmp_path / "r.csv"
    err = _one_line(["simulate", "--plant", "linear", "--gains", str(g), "--duration", "0.05",
                     "--out", str(out)], capsys)
    assert f"'{g}': gains file layout 99 is not one this version reads (1 or 2)" in err
    assert not out.exists()


@pytest.mark.parametrize("target", ["/dev/stdout", "/dev/fd/1", "/proc/self/fd/1",
                                    "/dev/stderr", "link"])
def test_issue29_out_naming_standard_output_points_to_dash(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], target: str) -> None:
    if target == "link":
        target = str(tmp_path / "out.csv")
        os.symlink("/dev/stdout", target)
    err = _one_line([*LINEAR, "--out", target], capsys)
    assert (f"--out '{target}' is a standard stream, not a file: give a file name, or --out - "
            f"where the command writes to standard output") in err


def test_issue29_out_dev_stdout_appended_to_a_file_leaves_it(tmp_path: Path) -> None:
    """``--out /dev/stdout >> log``: refused, and the file stdout is appended to is kept."""
    log = tmp_path / "log.txt"
    log.write_text("earlier lines\n")
    with log.open("a") as fh:
        proc = subprocess.run([sys.executable, "-m", "fuzzyservo", *LINEAR, "--out",
                               "/dev/stdout"], stdout=fh, stderr=subprocess.PIPE, text=True,
                              timeout=600, check=False)
    assert proc.returncode == 2 and "--out '/dev/stdout' is a standard stream" in proc.stderr
    assert log.read_text() == "earlier lines\n"
