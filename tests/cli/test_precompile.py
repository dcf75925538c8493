"""``fuzzyservo precompile``: it runs every closed-loop entry point it names, and refuses a bad
process count in one line."""

from __future__ import annotations

import subprocess
import sys

import pytest

from fuzzyservo.cli import main
from fuzzyservo.commands import precompile as cmd


def test_every_group_runs_in_this_process(capsys: pytest.CaptureFixture[str]) -> None:
    # make test has run it already, so this loads the cache; what it checks is that each
    # entry point it calls still takes the arguments it passes
    assert main(["precompile", "--processes", "1"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert [line.split(" in ")[0] for line in err[:-1]] == [
        "precompile: linear, small-signal plant loops",
        "precompile: nonlinear plant loops and the per-step API"]
    assert err[-1].startswith("precompile: done in ")


def test_a_warm_cache_is_loaded_by_a_new_process() -> None:
    # a process started after it compiles nothing: numba's cache holds every kernel it ran
    cmd.precompile(1)  # seconds when make test has run it; the whole compile otherwise
    script = ("from numba.core import event\n"
              "from fuzzyservo.commands.precompile import GROUPS, compile_group\n"
              "with event.install_recorder('numba:compile') as rec:\n"
              "    for g in GROUPS: compile_group(*g)\n"
              "names = sorted({e.data['dispatcher'].py_func.__qualname__ for _, e in rec.buffer\n"
              "                if e.is_start and e.data['dispatcher']._cache.__class__.__name__\n"
              "                != 'NullCache'})\n"
              "print(names)\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=600, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("n", ["0", "3"])
def test_bad_process_count_is_one_line(n: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["precompile", "--processes", n]) == 2
    err = capsys.readouterr().err
    assert err.strip() == f"fuzzyservo: error: --processes must be 1 or 2, got {n}"
    assert cmd.GROUPS  # the groups it would have run



def test_each_loop_is_compiled_for_one_signature() -> None:
    # simulate and the batch kernel call the single-run loops with the same argument types;
    # an argument of another type (a slice with layout 'A' was one) compiles a loop a second
    # time, a minute or more of every fresh install's precompile. numba's cache index lists
    # every signature compiled from the current source (a changed source starts a new index)
    from fuzzyservo.sim import closed_loop as cl

    cmd.precompile(1)  # seconds when make test has run it
    counts = {f.__name__: len(f._cache._cache_file._load_index())
              for f in (cl.run_linear, cl.run_linear_pair, cl.run_nonlinear)}
    assert counts == {"run_linear": 1, "run_linear_pair": 1, "run_nonlinear": 1}
