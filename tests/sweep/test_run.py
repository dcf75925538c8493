"""Running a sweep: the same rows at once, after kills and resumes, and on a Dask cluster.

Each kill test compares the table's digest (sorted by point and controller, every column) with
an uninterrupted run of the same spec. Kills are SIGKILL: at chunk boundaries and inside a
chunk (during its computation, and between its temporary file and the rename), driven by a
child script so the test decides exactly where; and at a random moment of a real command-line
run, locally and on a 2-worker LocalCluster (127.0.0.1).
"""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.cli import main
from fuzzyservo.sweep import load_spec, read_manifest, read_table, run_sweep, table_digest
from fuzzyservo.sweep.dataset import chunk_path
from fuzzyservo.sweep.spec import SAMPLING_SCHEME, UNRECORDED_SCHEME, canonical_digest
from tests.helpers import default_sigint

SPEC = """
[sweep]
name = "test"
plant = "linear"
duration = 1.5
samples = 30
seed = 11
chunk = 6

[reference]
spec = "step:0.1"

[[controllers]]
label = "pid paper"
controller = "pid"
gains = { kp = 1.2, ki = 1.0, kd = 0.75 }

[[controllers]]
label = "stfpi"
gains = "linear-stfpi.toml"

[[vary]]
name = "noise_std"
grid = [0.0, 1e-5]

[[vary]]
name = "load.mass"
relative = true
distribution = "log-uniform"
low = 0.5
high = 2.0

[[vary]]
name = "delay"
distribution = "uniform"
low = 0.0
high = 0.03

[[vary]]
name = "amplitude"
distribution = "normal"
mean = 0.1
std = 0.02
low = 0.05
high = 0.15
"""


#: A heavier sweep (30 chunks, about 1 s on two cores) for kills at a random moment of
#: a real run: the kill comes up to 0.3 s after the first chunk, which with 10 chunks was
#: sometimes after the last on a fast machine (the run then ended before the kill).
KILL_SPEC = (SPEC.replace('plant = "linear"', 'plant = "nonlinear"')
             .replace("duration = 1.5", "duration = 4.0").replace("samples = 30", "samples = 300")
             .replace("chunk = 6", "chunk = 20")
             .replace('gains = "linear-stfpi.toml"', 'gains = "nonlinear-stfpi.toml"'))


@pytest.fixture(scope="module")
def kill_spec(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """The heavier spec and the digest of its uninterrupted run."""
    path = tmp_path_factory.mktemp("kspec") / "spec.toml"
    path.write_text(KILL_SPEC, encoding="utf-8")
    out = tmp_path_factory.mktemp("kref") / "sweep"
    run_sweep(load_spec(path), out, progress=False, processes=1)
    return path, table_digest(read_table(out))


@pytest.fixture(scope="module")
def spec_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "spec.toml"
    path.write_text(SPEC, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def reference_digest(spec_file: Path, tmp_path_factory: pytest.TempPathFactory) -> str:
    out = tmp_path_factory.mktemp("ref") / "sweep"
    run_sweep(load_spec(spec_file), out, progress=False, processes=1)
    return table_digest(read_table(out))


def _child(script: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    # default_sigint: the child handles Ctrl-C as in a terminal, whatever this process
    # inherited (a background job ignores SIGINT, and its children with it)
    return subprocess.run([sys.executable, "-c", textwrap.dedent(script)], cwd=cwd,
                          capture_output=True, text=True, timeout=300,
                          preexec_fn=default_sigint)


def _resume(spec_file: Path, out: Path) -> str:
    assert main(["sweep", str(spec_file), "--out", str(out), "--resume", "--no-progress",
                 "--processes", "1"]) == 0
    man = read_manifest(out)
    assert man.complete
    assert not list((out / "chunks").glob(".*.tmp"))
    return table_digest(read_table(out))


def test_table_has_every_run_once_with_its_outcome(spec_file: Path, tmp_path: Path,
                                                   reference_digest: str) -> None:
    spec = load_spec(spec_file)
    out = tmp_path / "s"
    man = run_sweep(spec, out, progress=False, processes=2)  # a pool of local processes
    t = read_table(out)
    assert table_digest(t) == reference_digest  # = in this process
    assert t.num_rows == spec.n_runs == 120
    assert man.complete and sum(v["rows"] for v in man.chunks.values()) == 120
    assert t.column_names == man.columns
    pairs = set(zip(t.column("point").to_pylist(), t.column("controller").to_pylist(),
                    strict=True))
    assert len(pairs) == 120
    outcome = np.array(t.column("outcome").to_pylist())
    assert set(outcome) <= {"settles", "overshoots", "not settled", "limit cycle", "diverged",
                            "invalid"}
    assert np.array_equal(np.array(t.column("robust").to_pylist()), outcome == "settles")
    # the manifest's hashes are the files'
    import hashlib

    for c, entry in man.chunks.items():
        data = chunk_path(out, int(c)).read_bytes()
        assert hashlib.sha256(data).hexdigest() == entry["sha256"]
    doc = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    assert doc["digest"] == spec.digest and doc["complete"] is True


def test_numba_threads_do_not_change_a_chunk(spec_file: Path) -> None:
    from fuzzyservo.sweep import compute_chunk

    spec = load_spec(spec_file)
    a = compute_chunk(spec, 3, threads=1)
    b = compute_chunk(spec, 3, threads=2)
    assert table_digest(a) == table_digest(b)
    assert a.num_rows == 12 and set(a.column("point").to_pylist()) == set(range(18, 24))


@pytest.mark.parametrize("where", ["boundary-1", "boundary-7", "compute-4", "rename-2",
                                   "rename-9"])
def test_sigkill_then_resume_gives_the_same_rows(where: str, spec_file: Path, tmp_path: Path,
                                                  reference_digest: str) -> None:
    out = tmp_path / "s"
    kind, k = where.split("-")
    script = f"""
        import os, signal
        import fuzzyservo.sweep.dataset as ds
        import fuzzyservo.sweep.run as run
        from fuzzyservo.sweep import load_spec, run_sweep
        kind, k = {kind!r}, {int(k)}
        die = lambda: os.kill(os.getpid(), signal.SIGKILL)
        calls = {{"compute": 0, "write": 0}}
        if kind == "compute":
            real = run.compute_chunk
            def compute(*a, **kw):
                calls["compute"] += 1
                if calls["compute"] == k:
                    die()
                return real(*a, **kw)
            run.compute_chunk = compute
        if kind == "rename":
            real_w = ds.write_bytes_atomic
            def write(path, data):
                calls["write"] += 1
                if calls["write"] == k:
                    tmp = path.parent / ("." + path.name + ".killed.tmp")
                    tmp.write_bytes(data[: len(data) // 2])
                    die()
                return real_w(path, data)
            ds.write_bytes_atomic = write
        def on_chunk(c):
            if kind == "boundary" and len(os.listdir({str(out / 'chunks')!r})) >= k:
                die()
        run_sweep(load_spec({str(spec_file)!r}), {str(out)!r}, progress=False,
                  on_chunk=on_chunk, processes=1)
    """
    proc = _child(script, tmp_path)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    done = read_manifest(out).done
    assert len(done) < 10
    assert _resume(spec_file, out) == reference_digest


def test_manifest_adopts_a_chunk_renamed_before_a_kill(spec_file: Path, tmp_path: Path,
                                                        reference_digest: str) -> None:
    out = tmp_path / "s"
    run_sweep(load_spec(spec_file), out, progress=False, processes=1)
    doc = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    for c in ("3", "9"):  # as if killed between the rename and the manifest's rewrite
        del doc["chunks"][c]
    (out / "manifest.json").write_text(json.dumps(doc), encoding="utf-8")
    mtime = chunk_path(out, 3).stat().st_mtime_ns
    assert _resume(spec_file, out) == reference_digest
    assert chunk_path(out, 3).stat().st_mtime_ns == mtime  # adopted, not recomputed


def _kill_when_started(argv: list[str], out: Path, seed: int) -> bool:
    """Start the CLI, wait for its first chunk, then SIGKILL its process group at a random
    moment (the Dask workers with it)."""
    proc = subprocess.Popen([sys.executable, "-m", "fuzzyservo", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    # SIGKILL the command alone for the local pool (its workers must die with it), the whole
    # process group for Dask (whose workers time out on their own)
    group = "--workers" in argv
    rng = random.Random(seed)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            if (out / "chunks").is_dir() and any((out / "chunks").glob("chunk-*.parquet")):
                break
            # sleep: polling for the first chunk file (no file-creation event in the stdlib)
            time.sleep(0.005)
        # sleep: a random moment of the running sweep is the test's input, not a wait
        time.sleep(rng.uniform(0.0, 0.3))
    finally:
        killed = proc.poll() is None
        if proc.poll() is None:
            if group:
                os.killpg(proc.pid, signal.SIGKILL)
            else:
                os.kill(proc.pid, signal.SIGKILL)
        proc.communicate(timeout=60)  # the pipes close only when every worker has ended
    return killed


@pytest.mark.parametrize("seed", [1, 2])
def test_random_kill_of_the_command_then_resume(seed: int, kill_spec: tuple[Path, str],
                                                tmp_path: Path) -> None:
    spec_file, digest = kill_spec
    out = tmp_path / "s"
    assert _kill_when_started(["sweep", str(spec_file), "--out", str(out), "--no-progress"],
                              out, seed)
    man = read_manifest(out)
    assert 1 <= len(man.done) < man.n_chunks
    assert _resume(spec_file, out) == digest


def test_dask_local_cluster_gives_the_same_rows_and_resumes(kill_spec: tuple[Path, str],
                                                            tmp_path: Path) -> None:
    spec_file, digest = kill_spec
    out = tmp_path / "dask"
    assert main(["sweep", str(spec_file), "--out", str(out), "--workers", "2",
                 "--no-progress"]) == 0
    assert table_digest(read_table(out)) == digest
    killed = tmp_path / "killed"
    assert _kill_when_started(["sweep", str(spec_file), "--out", str(killed), "--workers", "2",
                               "--no-progress"], killed, 3)
    man = read_manifest(killed)
    assert len(man.done) < man.n_chunks
    assert main(["sweep", str(spec_file), "--out", str(killed), "--resume", "--workers", "2",
                 "--no-progress"]) == 0
    assert table_digest(read_table(killed)) == digest


def test_an_interrupted_start_leaves_no_half_made_folder(spec_file: Path, tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch,
                                                         reference_digest: str) -> None:
    from fuzzyservo.sweep.dataset import Manifest

    spec = load_spec(spec_file)
    out = tmp_path / "s"
    real = Manifest.write

    def interrupted(self: Manifest, folder: Path) -> None:
        raise KeyboardInterrupt  # Ctrl-C while the new folder is being made

    monkeypatch.setattr(Manifest, "write", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(spec, out, progress=False, processes=1)
    assert not out.exists() and not list(tmp_path.glob(".s.new-*"))
    monkeypatch.setattr(Manifest, "write", real)
    # a sibling left by a killed sweep (its process is gone) is removed; an empty --out is
    # taken; the rows are those of an uninterrupted run
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    (tmp_path / f".s.new-{dead}" / "chunks").mkdir(parents=True)
    out.mkdir()
    run_sweep(spec, out, progress=False, processes=1)
    assert not list(tmp_path.glob(".s.new-*"))
    assert table_digest(read_table(out)) == reference_digest


def test_refusals_leave_the_folder_as_it_was(spec_file: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "s"
    assert main(["sweep", str(spec_file), "--out", str(out), "--no-progress",
                 "--processes", "1"]) == 0
    capsys.readouterr()
    assert (out / "spec.toml").read_text(encoding="utf-8") == SPEC  # provenance
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert main(["sweep", str(spec_file), "--out", str(out), "--no-progress"]) == 2
    assert "already holds a sweep (10 of 10 chunks): add --resume" in capsys.readouterr().err
    other = spec_file.parent / "other.toml"
    other.write_text(SPEC.replace("seed = 11", "seed = 12"), encoding="utf-8")
    assert main(["sweep", str(other), "--out", str(out), "--resume", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "holds a different sweep (its spec differs in seed)" in err
    assert len(err.strip().splitlines()) == 1
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    # a sweep drawn by another sampling scheme (another fuzzyservo) is never resumed into
    other_scheme = tmp_path / "other-scheme"
    shutil.copytree(out, other_scheme)
    doc = json.loads((other_scheme / "manifest.json").read_text(encoding="utf-8"))
    doc["spec"]["sampling"] = SAMPLING_SCHEME + 1
    (other_scheme / "manifest.json").write_text(json.dumps(doc), encoding="utf-8")
    kept = {p: p.read_bytes() for p in other_scheme.rglob("*") if p.is_file()}
    assert main(["sweep", str(spec_file), "--out", str(other_scheme), "--resume",
                 "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert (f"holds a sweep drawn by sampling scheme {SAMPLING_SCHEME + 1}; this fuzzyservo "
            f"draws scheme {SAMPLING_SCHEME}") in err
    assert len(err.strip().splitlines()) == 1
    assert {p: p.read_bytes() for p in other_scheme.rglob("*") if p.is_file()} == kept
    # one written before the scheme was recorded (no "sampling", its digest without it) drew
    # scheme 1's points: it is resumed, and gives the same rows
    unrecorded = tmp_path / "unrecorded"
    shutil.copytree(out, unrecorded)
    doc = json.loads((unrecorded / "manifest.json").read_text(encoding="utf-8"))
    del doc["spec"]["sampling"]
    doc["digest"] = canonical_digest(doc["spec"])
    first = sorted(doc["chunks"], key=int)[0]
    del doc["chunks"][first]  # one chunk to run again
    (unrecorded / "manifest.json").write_text(json.dumps(doc), encoding="utf-8")
    chunk_path(unrecorded, int(first)).unlink()
    assert UNRECORDED_SCHEME == SAMPLING_SCHEME  # else this folder must be refused
    assert main(["sweep", str(spec_file), "--out", str(unrecorded), "--resume",
                 "--no-progress", "--processes", "1"]) == 0
    capsys.readouterr()
    assert table_digest(read_table(unrecorded)) == table_digest(read_table(out))
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "x.txt").write_text("x", encoding="utf-8")
    assert main(["sweep", str(spec_file), "--out", str(tmp_path / "junk")]) == 2
    assert "not empty and holds no sweep" in capsys.readouterr().err
    assert main(["sweep", str(spec_file), "--out", str(tmp_path / "new"), "--resume"]) == 2
    assert "holds no sweep to resume" in capsys.readouterr().err
    assert main(["sweep", str(spec_file), "--out", str(tmp_path / "w"), "--workers", "0"]) == 2
    assert "--workers must be an integer in [1, 1024], got 0" in capsys.readouterr().err


def test_ctrl_c_keeps_finished_chunks_and_says_how_to_resume(spec_file: Path, tmp_path: Path,
                                                             reference_digest: str) -> None:
    out = tmp_path / "s"
    script = f"""
        import os, signal, sys
        import fuzzyservo.sweep.run as run
        real = run.compute_chunk
        n = {{"k": 0}}
        def compute(*a, **kw):
            n["k"] += 1
            if n["k"] == 5:
                os.kill(os.getpid(), signal.SIGINT)
            return real(*a, **kw)
        run.compute_chunk = compute
        from fuzzyservo.cli import main
        sys.exit(main(["sweep", {str(spec_file)!r}, "--out", {str(out)!r}, "--no-progress",
                       "--processes", "1"]))
    """
    proc = _child(script, tmp_path)
    assert proc.returncode == 130, proc.stderr
    assert "--resume" in proc.stderr and "interrupted" in proc.stderr
    assert 3 <= len(read_manifest(out).done) <= 5
    assert _resume(spec_file, out) == reference_digest


def test_scheduler_address_runs_on_that_cluster(kill_spec: tuple[Path, str],
                                                tmp_path: Path) -> None:
    from distributed import LocalCluster

    spec_file, digest = kill_spec
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None, silence_logs=40) as cluster:
        out = tmp_path / "s"
        assert main(["sweep", str(spec_file), "--out", str(out), "--scheduler",
                     cluster.scheduler_address, "--no-progress"]) == 0
    assert table_digest(read_table(out)) == digest


def test_unreachable_scheduler_is_one_line(spec_file: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sweep", str(spec_file), "--out", str(tmp_path / "s"), "--scheduler",
                 "tcp://127.0.0.1:9", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--scheduler 'tcp://127.0.0.1:9': cannot connect" in err


def test_resume_recomputes_a_chunk_missing_or_altered(spec_file: Path, tmp_path: Path,
                                                      reference_digest: str) -> None:
    out = tmp_path / "s"
    run_sweep(load_spec(spec_file), out, progress=False, processes=1)
    chunk_path(out, 2).unlink()
    data = bytearray(chunk_path(out, 5).read_bytes())
    data[-20] ^= 0xFF
    chunk_path(out, 5).write_bytes(bytes(data))
    assert _resume(spec_file, out) == reference_digest
    assert read_table(out).num_rows == 120


def test_a_second_sweep_on_the_folder_is_refused(spec_file: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    import fcntl

    out = tmp_path / "s"
    run_sweep(load_spec(spec_file), out, progress=False, processes=1)
    with (out / ".lock").open("a+") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        assert main(["sweep", str(spec_file), "--out", str(out), "--resume",
                     "--processes", "1"]) == 2
    assert "another fuzzyservo sweep is writing" in capsys.readouterr().err


def test_sigkill_while_the_pool_starts_leaves_no_worker(kill_spec: tuple[Path, str],
                                                        tmp_path: Path) -> None:
    spec_file, _ = kill_spec
    out = tmp_path / "s"
    proc = subprocess.Popen([sys.executable, "-m", "fuzzyservo", "sweep", str(spec_file),
                             "--out", str(out), "--no-progress", "--processes", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not (out / "manifest.json").is_file() and time.monotonic() < deadline:
        # sleep: polling for the manifest (no file-creation event in the stdlib)
        time.sleep(0.002)
    os.kill(proc.pid, signal.SIGKILL)  # the workers are being spawned, not yet serving
    # the workers hold the command's output pipes: they close once every worker has ended
    proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL
