"""``fuzzyservo export``: the registry's targets, what it writes, and bad input (one line,
status 2, nothing written or overwritten)."""

from __future__ import annotations

import argparse
import subprocess
import zipfile
from pathlib import Path

import pytest

from fuzzyservo.cli import build_parser, main
from fuzzyservo.control.command import CommandSchedule
from fuzzyservo.errors import ParameterError
from fuzzyservo.export import export_target_names
from fuzzyservo.export.controller_c import emit_controller
from fuzzyservo.registry import controller_kind, controller_names
from tests.export.cbuild import STRICT, gcc

GAINS = Path(__file__).resolve().parents[2] / "src" / "fuzzyservo" / "data" / "gains"


def _error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def _subparsers(parser: argparse.ArgumentParser, *path: str) -> dict[str, argparse.ArgumentParser]:
    for name in path:
        action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = action.choices[name]
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_export_offers_exactly_the_registered_targets_and_controllers() -> None:
    targets = _subparsers(build_parser(), "export")
    assert tuple(targets) == export_target_names() == ("c", "fmu", "st")
    for p in targets.values():
        ctl = next(a for a in p._actions if a.dest == "controller")
        assert tuple(ctl.choices) == controller_names()


@pytest.mark.parametrize("name", controller_names())
def test_export_c_writes_code_that_compiles_without_a_warning(
        name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gains = ",".join(f"{g}=0.5" for g in controller_kind(name).gain_names)
    out = tmp_path / "code"
    assert main(["export", "c", "--controller", name, "--gains", gains, "--out",
                 str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [f"{name}.c", f"{name}.h"]
    header = (out / f"{name}.h").read_text()
    assert f"controller:  {name}" in header and "0.5" in header
    assert "fuzzyservo export c --controller" in header  # the command is recorded
    proc = subprocess.run([gcc(), *STRICT, "-O2", "-c", str(out / f"{name}.c"), "-o",
                           str(tmp_path / "x.o")], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    # an export of the same name into the same folder replaces its two files
    assert main(["export", "c", "--controller", name, "--gains", gains, "--float", "--out",
                 str(out)]) == 0
    assert "arithmetic:  float" in (out / f"{name}.h").read_text()


def test_mixed_header_and_source_refuse_to_compile(tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["export", "c", "--controller", "pi", "--gains", "kp=1,ki=1", "--out",
                 str(a)]) == 0
    assert main(["export", "c", "--controller", "pi", "--gains", "kp=2,ki=1", "--out",
                 str(b)]) == 0
    (a / "pi.h").write_bytes((b / "pi.h").read_bytes())  # an interrupted re-export
    proc = subprocess.run([gcc(), *STRICT, "-c", str(a / "pi.c"), "-o", str(tmp_path / "x.o")],
                          capture_output=True, text=True, check=False)
    assert proc.returncode != 0 and "another export" in proc.stderr


def test_a_folder_with_other_files_is_refused_and_left_alone(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "code"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    (out / "pid.c").write_text("old")
    status = main(["export", "c", "--controller", "pid", "--gains", "kp=1,ki=1,kd=0",
                   "--out", str(out)])
    assert status == 2
    line = _error_line(capsys)
    assert "notes.txt" in line and "new or empty folder" in line
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "pid.c"]
    assert (out / "pid.c").read_text() == "old"


@pytest.mark.parametrize("argv, words", [
    (["--controller", "pid", "--gains", "kp=-1,ki=1,kd=0"], ("gain kp", ">= 0", "-1")),
    (["--controller", "pid", "--gains", "kp=1,ki=1,kd=0,n=0"], ("gain n", "> 0", "0")),
    (["--controller", "fpi", "--gains", "ke=nan,kde=1,kdu=1"], ("gain ke", "nan")),
    (["--controller", "fpi", "--gains", "ke=1,kde=1"], ("needs gains kdu",)),
    (["--controller", "pi", "--gains", "kp=1,ki=1,q=3"], ("unknown gain 'q'",)),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--name", "int"], ("--name", "'int'")),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--name", "9x"], ("--name",)),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--name", "fs"], ("--name", "'fs'")),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--name", "fsm_x"], ("--name",)),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--name", "_x"], ("--name",)),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--ts", "0"], ("--ts", "0")),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--initial-error", "first"],
     ("--initial-error", "pi")),
    (["--controller", "pid", "--gains", "kp=1,ki=1,kd=0", "--du-system", "x.fis"],
     ("--du-system", "fpi")),
])
def test_bad_controller_input_is_one_line_and_writes_nothing(
        argv: list[str], words: tuple[str, ...], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    for target, out in (("c", tmp_path / "code"), ("fmu", tmp_path / "ctl.fmu")):
        assert main(["export", target, *argv, "--out", str(out)]) == 2
        line = _error_line(capsys)
        assert all(w in line for w in words), line
        assert not out.exists()


@pytest.mark.parametrize("argv, words", [
    (["--controller", "pid", "--gains", "kp=-1,ki=1,kd=0"], ("gain kp", ">= 0", "-1")),
    (["--controller", "fpi", "--gains", "ke=nan,kde=1,kdu=1"], ("gain ke", "nan")),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--name", "PID"],
     ("--name", "'PID'", "reserved")),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--name", "int"], ("--name", "'int'")),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--name", "a__b"], ("--name", "'a__b'")),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--name", "REAL_TO_INT"], ("--name",)),
    (["--controller", "pi", "--gains", "kp=1e39,ki=1", "--real"], ("gain kp", "REAL")),
    (["--controller", "pi", "--gains", "kp=1,ki=1", "--name", "AXIS"],
     ("--name", "'AXIS'", "example program")),
    (["--controller", "smc", "--gains", "k_o=0"], ("gain k_o", "> 0")),
    (["--controller", "fpi", "--gains", "ke=1,kde=1,kdu=1", "--du-system",
      str(Path(__file__).resolve().parents[1] / "formats" / "data" / "fis" / "all_mfs.fis")],
     ("uniform triangular partitions",)),
])
def test_export_st_bad_input_is_one_line_and_writes_nothing(
        argv: list[str], words: tuple[str, ...], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plc"
    assert main(["export", "st", *argv, "--out", str(out)]) == 2
    line = _error_line(capsys)
    assert all(w in line for w in words), line
    assert not out.exists()


@pytest.mark.parametrize("name", controller_names())
def test_export_st_writes_blocks_that_matiec_translates(
        name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """export st of every kind: the two files, the command recorded, iec2c translates the
    block with its example configuration; a second export of the same name replaces them."""
    from tests.export.st_harness import translate

    gains = ",".join(f"{g}=0.5" for g in controller_kind(name).gain_names)
    out = tmp_path / "plc"
    argv = ["export", "st", "--controller", name, "--gains", gains, "--out", str(out)]
    assert main(argv) == 0
    block, example = out / f"{name}_ctl.st", out / f"{name}_ctl_example.st"
    assert sorted(p.name for p in out.iterdir()) == sorted([block.name, example.name])
    text = block.read_text()
    assert f"FUNCTION_BLOCK {name}_ctl\n" in text and "fuzzyservo export st --controller" in text
    proc = translate(text + "\n" + example.read_text(), tmp_path / "matiec")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert main([*argv, "--real"]) == 0
    assert "REAL" in block.read_text() and "LREAL" not in block.read_text()
    proc = translate(block.read_text() + "\n" + example.read_text(), tmp_path / "matiec32")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "wrote" in capsys.readouterr().out


def test_export_st_refuses_a_folder_with_other_files(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plc"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["export", "st", "--controller", "pi", "--gains", "kp=1,ki=1", "--name", "ax",
                 "--out", str(out)]) == 2
    line = _error_line(capsys)
    assert "notes.txt" in line and "ax.st and ax_example.st" in line
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


def test_fmu_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    old = tmp_path / "old.fmu"
    old.write_bytes(b"previous")
    cases = [
        (["--plant", "linear", "--gains", "kp=1"], "--gains applies to a controller FMU"),
        (["--plant", "linear", "--float"], "--float applies to a controller FMU"),
        (["--controller", "pi", "--gains", "kp=1,ki=1", "--delay", "hose"], "--delay"),
        (["--plant", "nonlinear", "--start", "1.5"], "--start"),
        (["--plant", "nonlinear", "--delay", "-1"], "--delay"),
        (["--plant", "linear", "--param", "valve.natural_frequency=-3"], "natural_frequency"),
        ([], "needs a controller"),
    ]
    for argv, words in cases:
        assert main(["export", "fmu", *argv, "--out", str(old)]) == 2, argv
        assert words in _error_line(capsys)
        assert old.read_bytes() == b"previous"
    assert main(["export", "fmu", "--plant", "linear", "--out", str(tmp_path / "x.zip")]) == 2
    assert ".fmu" in _error_line(capsys)


def test_no_compiler_is_one_line_and_leaves_the_old_fmu(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    old = tmp_path / "ctl.fmu"
    old.write_bytes(b"previous")
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    assert main(["export", "fmu", "--controller", "pi", "--gains", "kp=1,ki=1", "--out",
                 str(old)]) == 2
    assert "C compiler" in _error_line(capsys)
    assert old.read_bytes() == b"previous"


def test_the_fmu_is_the_same_zip_for_the_same_export(tmp_path: Path) -> None:
    out = tmp_path / "a.fmu"
    argv = ["export", "fmu", "--controller", "pi", "--gains", "kp=1,ki=1", "--out", str(out)]
    assert main(argv) == 0
    first = tmp_path / "first.fmu"
    first.write_bytes(out.read_bytes())
    assert main(argv) == 0  # the same export again replaces the file
    with zipfile.ZipFile(first) as za, zipfile.ZipFile(out) as zb:
        assert za.namelist() == zb.namelist()
        assert sorted(za.namelist()) == sorted([
            "modelDescription.xml", "binaries/linux64/pi.so", "sources/pi.h", "sources/pi.c",
            "sources/pi_fmi2.c"])
        for n in za.namelist():
            if not n.endswith(".so"):  # the linker may stamp a build id into the library
                assert za.read(n) == zb.read(n), n


def test_a_controller_without_c_code_is_refused_by_name() -> None:
    # the open loop's pass-through "controller" is not a registered kind and has no C port
    with pytest.raises(ParameterError, match="has no C port: its law command declares no "
                                             "c_source"):
        emit_controller(controller_kind("p"), {"kp": 1.0}, CommandSchedule(dt=1e-3), name="x")


def test_a_failing_compiler_is_named_with_its_exit_status(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 29: with CC=/bin/false, ``export fmu`` said the generated code failed and asked
    for a report. It names the compiler and its status, and blames the compiler when it
    cannot build a trivial file either; a compiler that builds a trivial file but not the
    generated code is the package's to fix (please report it)."""
    old = tmp_path / "ctl.fmu"
    old.write_bytes(b"previous")
    argv = ["export", "fmu", "--controller", "pi", "--gains", "kp=1,ki=1", "--out", str(old)]
    monkeypatch.setenv("CC", "/bin/false")
    assert main(argv) == 2
    line = _error_line(capsys)
    assert "'/bin/false' (from $CC) exited with status 1" in line, line
    assert "report" not in line and "set CC to a working C compiler" in line
    assert old.read_bytes() == b"previous"
    picky = tmp_path / "picky-cc"  # fails on the FMU's build only (its -fvisibility flag)
    picky.write_text(f'#!/bin/sh\ncase "$*" in *-fvisibility=hidden*) echo "x.c:1: error: '
                     f'no" >&2; exit 3;; esac\nexec {gcc()} "$@"\n')
    picky.chmod(0o755)
    monkeypatch.setenv("CC", str(picky))
    assert main(argv) == 2
    line = _error_line(capsys)
    assert f"'{picky}' (from $CC) exited with status 3 on the generated code: x.c:1: " \
           f"error: no; please report it" in line, line
    assert old.read_bytes() == b"previous"


@pytest.mark.parametrize("limit_kib", [8, 40])
def test_a_file_size_limit_is_one_line(limit_kib: int, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 29: ``export fmu`` under ``ulimit -f 8`` ended in a traceback (EFBIG writing
    the build's sources). With the limit set on this process (Python ignores SIGXFSZ and
    gets EFBIG; the compiler, which does not, is killed by it): 8 KiB stops the sources,
    40 KiB the compiler's output; both are one line naming the limit, status 2."""
    import resource

    out = tmp_path / "ctl.fmu"
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit_kib * 1024, hard))
    try:
        status = main(["export", "fmu", "--controller", "pid", "--gains", "kp=1,ki=1,kd=0",
                       "--out", str(out)])
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert status == 2
    line = _error_line(capsys)
    assert "size limit" in line and "ulimit -f" in line, line
    if limit_kib == 8:
        assert "File too large" in line and "sources/" in line, line
    assert not out.exists()
