"""``fuzzyservo precompile``: it runs every closed-loop entry point it names, and refuses a bad
process count in one line."""

from __future__ import annotations

import subprocess
import sys

import pytest

from fuzzyservo.cli import main
from fuzzyservo.commands import precompile as cmd


def test_every_job_runs_in_this_process(capsys: pytest.CaptureFixture[str]) -> None:
    # make test has run it already, so this loads the cache; what it checks is that each
    # entry point it calls still takes the arguments it passes, and what it reports
    assert main(["precompile", "--processes", "1"]) == 0
    err = capsys.readouterr().err.splitlines()
    jobs = cmd.jobs()
    assert err[0].startswith(f"precompile: {len(jobs)} jobs in 1 process(es) into ")
    assert [line.split(" in ")[0] for line in err[1:-1]] == [
        f"precompile: [{i}/{len(jobs)}] {j.title}" for i, j in enumerate(jobs, 1)]
    assert err[-1].startswith("precompile: done in ")
    # every law of the registry, the general fuzzy systems' variant and the open loop, each
    # on both plants
    titles = {j.title for j in jobs}
    for law in ("PID", "the fuzzy PI", "the fuzzy PI (general systems)"):
        for target in ("the closed loop on the linear plant", "the closed loop on the "
                       "nonlinear plant", "the per-step API"):
            assert f"{target} for {law}" in titles


def test_a_warm_cache_is_loaded_by_a_new_process() -> None:
    # a process started after it compiles nothing: numba's cache holds every kernel it ran
    cmd.precompile(1)  # seconds when make test has run it; the whole compile otherwise
    script = ("from numba.core import event\n"
              "from fuzzyservo.commands.precompile import jobs, run_job\n"
              "with event.install_recorder('numba:compile') as rec:\n"
              "    for j in jobs(): run_job(j.law, j.target)\n"
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
    assert cmd.jobs()  # the jobs it would have run



def test_each_loop_is_compiled_for_one_signature() -> None:
    # simulate and the batch kernels call each law's loops with the same argument types; an
    # argument of another type (a slice with layout 'A' was one) compiles a loop a second
    # time, seconds of every fresh install's precompile. numba's cache index lists every
    # signature compiled from the current source (a changed source starts a new index)
    from fuzzyservo.sim import loops

    cmd.precompile(1)  # seconds when make test has run it
    counts = {}
    for name, (ctl, _title) in cmd.controllers().items():
        ks = loops.kernels(ctl.law)
        for fn in (ks.linear_chunk, ks.nonlinear_chunk):
            counts[f"{name}: {fn.py_func.__qualname__}"] = len(
                fn._cache._cache_file._load_index())
    assert len(counts) == 2 * len(cmd.controllers())
    assert set(counts.values()) == {1}, counts
