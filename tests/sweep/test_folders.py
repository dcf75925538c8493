"""A sweep's folder under hostile conditions (issue 29): links inside it, a second sweep
started beside a running one, reports aimed at its data, corrupted manifests and specs, and
what the spec must refuse before anything runs."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
import textwrap
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.cli import main
from fuzzyservo.errors import InputError, OutputError, ParameterError
from fuzzyservo.sweep import load_spec, read_manifest, read_table, run_sweep, table_digest
from fuzzyservo.sweep.dataset import chunk_path, write_chunk
from fuzzyservo.sweep.report import write_report
from fuzzyservo.sweep.spec import LOG_TAIL_SCHEME, SAMPLING_SCHEME, Variation

SPEC = """
[sweep]
name = "folders"
plant = "linear"
duration = 0.5
samples = 4
seed = 3
chunk = 2

[reference]
spec = "step:0.1"

[[controllers]]
label = "pid"
controller = "pid"
gains = { kp = 1.2, ki = 1.0, kd = 0.75 }

[[vary]]
name = "load.mass"
relative = true
distribution = "log-uniform"
low = 0.5
high = 2.0
"""


@pytest.fixture(scope="module")
def spec_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "spec.toml"
    path.write_text(SPEC, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def finished(spec_file: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A finished sweep (copy it before changing it) and its table's digest."""
    out = tmp_path_factory.mktemp("done") / "s"
    run_sweep(load_spec(spec_file), out, progress=False, processes=1)
    return out, table_digest(read_table(out))


def _files(folder: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _one_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_a_chunk_that_is_a_link_is_refused_and_its_target_untouched(
        finished: tuple[Path, str], spec_file: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "s"
    shutil.copytree(finished[0], out)
    doc = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    del doc["chunks"]["1"]  # to be run again: it used to be written through the link
    (out / "manifest.json").write_text(json.dumps(doc), encoding="utf-8")
    victim = tmp_path / "victim.txt"
    victim.write_text("victim\n", encoding="utf-8")
    chunk_path(out, 1).unlink()
    chunk_path(out, 1).symlink_to(victim)
    before = (out / "manifest.json").read_bytes()
    assert main(["sweep", str(spec_file), "--out", str(out), "--resume", "--no-progress",
                 "--processes", "1"]) == 2
    err = _one_line(capsys)
    assert "holds a symbolic link, 'chunks/chunk-000001.parquet'" in err
    assert victim.read_text(encoding="utf-8") == "victim\n"
    assert (out / "manifest.json").read_bytes() == before
    assert main(["sweep-report", str(out), "--out", str(tmp_path / "r.html")]) == 2
    assert "holds a symbolic link" in _one_line(capsys)
    # the lock and the manifest: never opened through a link either
    other = tmp_path / "lock"
    shutil.copytree(finished[0], other)
    (other / ".lock").unlink()
    (other / ".lock").symlink_to(victim)
    assert main(["sweep", str(spec_file), "--out", str(other), "--resume", "--no-progress",
                 "--processes", "1"]) == 2
    assert "holds a symbolic link, '.lock'" in _one_line(capsys)
    assert victim.read_text(encoding="utf-8") == "victim\n"


def test_a_link_in_a_chunks_place_at_write_time_is_refused(
        finished: tuple[Path, str], tmp_path: Path) -> None:
    """After the folder's checks (a link made while the sweep runs): the chunk's write
    itself refuses it (one put there during the write is replaced: tests/test_io.py)."""
    from fuzzyservo._io import confined

    out = tmp_path / "s"
    shutil.copytree(finished[0], out)
    victim = tmp_path / "victim.txt"
    victim.write_text("victim\n", encoding="utf-8")
    chunk_path(out, 1).unlink()
    chunk_path(out, 1).symlink_to(victim)
    with confined(out), pytest.raises(OutputError, match="is a symbolic link inside the "
                                                         "output folder"):
        write_chunk(out, 1, read_table(finished[0]))
    assert victim.read_text(encoding="utf-8") == "victim\n"
    assert not list((out / "chunks").glob(".*.tmp"))


def test_a_failed_chunk_write_names_the_file_once(finished: tuple[Path, str],
                                                  tmp_path: Path) -> None:
    out = tmp_path / "s"
    out.mkdir()  # no chunks/ folder: the write fails
    with pytest.raises(OutputError) as info:
        write_chunk(out, 0, read_table(finished[0]))
    assert str(info.value).count("cannot write") == 1, str(info.value)


def test_a_resume_beside_a_running_sweep_is_refused_before_it_touches_the_folder(
        spec_file: Path, finished: tuple[Path, str], tmp_path: Path) -> None:
    """Issue 29: the resume's preparation ran before the lock and deleted the running
    sweep's temporary chunk, which then died with "cannot write ... cannot write". Two real
    processes; the first holds its write open (temporary file made, not yet renamed) until
    this test, having run the second to its end, tells it to go on."""
    out = tmp_path / "s"
    first = textwrap.dedent(f"""
        import sys
        import fuzzyservo._io as io
        import fuzzyservo.sweep.dataset as ds
        def held(path, data):
            with io.atomic_write(path, binary=True) as fh:
                fh.write(data)
                fh.flush()
                if path.name == "chunk-000001.parquet":
                    print("writing", flush=True)  # the temporary file exists
                    sys.stdin.readline()          # until the test says go on
            return path
        ds.write_bytes_atomic = held
        from fuzzyservo.cli import main
        sys.exit(main(["sweep", {str(spec_file)!r}, "--out", {str(out)!r}, "--no-progress",
                       "--processes", "1"]))
    """)
    a = subprocess.Popen([sys.executable, "-c", first], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert a.stdout is not None and a.stdin is not None
        assert a.stdout.readline() == "writing\n", a.communicate()[1]
        temps = sorted((out / "chunks").glob(".chunk-000001.parquet.*.tmp"))
        assert len(temps) == 1
        before = _files(out)
        b = subprocess.run([sys.executable, "-m", "fuzzyservo", "sweep", str(spec_file),
                            "--out", str(out), "--resume", "--no-progress",
                            "--processes", "1"], capture_output=True, text=True, timeout=300)
        assert b.returncode == 2, b.stderr
        lines = b.stderr.strip().splitlines()
        assert lines[-1] == (f"fuzzyservo: error: another fuzzyservo sweep is writing "
                             f"{str(out)!r}; wait for it to finish or give another --out")
        assert not any("Traceback" in ln for ln in lines)
        assert _files(out) == before and temps[0].exists()  # nothing touched
        a.stdin.write("go on\n")
        a.stdin.flush()
        _, err = a.communicate(timeout=300)
    finally:
        if a.poll() is None:
            a.kill()
            a.communicate()
    assert a.returncode == 0, err
    assert "cannot write" not in err
    assert read_manifest(out).complete
    assert table_digest(read_table(out)) == finished[1]


def test_a_report_over_the_sweeps_own_files_is_refused(
        finished: tuple[Path, str], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "s"
    shutil.copytree(finished[0], out)
    before = _files(out)
    for target in ("manifest.json", "spec.toml", "chunks/chunk-000000.parquet"):
        assert main(["sweep-report", str(out), "--out", str(out / target)]) == 2
        assert "would replace its" in _one_line(capsys)
        with pytest.raises(InputError, match="would replace its"):  # the API as the CLI
            write_report(out, out / target)
    assert _files(out) == before
    assert main(["reproduce", "--out", str(out), "--plant", "linear", "--quiet"]) == 2
    assert "writing the study there would replace its manifest (the sweep folder" in \
        _one_line(capsys)
    assert _files(out) == before


def _corrupt(doc: dict, how: str, out: Path) -> str | None:
    if how == "no digest":
        del doc["digest"]
    elif how == "wrong key":
        doc["digets"] = doc.pop("digest")
    elif how == "negative rows":
        doc["chunks"]["0"]["rows"] = -5
    elif how == "rows of another sweep":
        doc["chunks"]["0"]["rows"] = 3
    elif how == "digest of another spec":
        doc["digest"] = "0" * 64
    elif how == "deeply nested":
        text = json.dumps(doc)
        return text[:-1] + ', "x": ' + "[" * 5000 + "]" * 5000 + "}"
    elif how == "chunks is a file":
        shutil.rmtree(out / "chunks")
        (out / "chunks").write_text("x", encoding="utf-8")
    elif how == "a chunk is a folder":
        chunk_path(out, 0).unlink()
        chunk_path(out, 0).mkdir()
    return None


@pytest.mark.parametrize("how, message", [
    ("no digest", "is corrupted: it lacks 'digest'"),
    ("wrong key", "is corrupted: unknown key 'digets'"),
    ("negative rows", "is corrupted: chunk 0's rows must be a non-negative integer, got -5"),
    ("rows of another sweep", "is corrupted: chunk 0 has 3 rows, the spec gives it 2"),
    ("digest of another spec", "is corrupted: its digest is not that of the spec"),
    ("deeply nested", "is corrupted: its JSON nests arrays or tables more than 64 levels deep"),
    ("chunks is a file", "is corrupted: "),
    ("a chunk is a folder", "is corrupted: chunk 'chunk-000000.parquet' is not a file"),
])
def test_a_corrupted_folder_is_named_in_one_line(
        how: str, message: str, finished: tuple[Path, str], spec_file: Path,
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "s"
    shutil.copytree(finished[0], out)
    doc = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    text = _corrupt(doc, how, out)
    (out / "manifest.json").write_text(text or json.dumps(doc), encoding="utf-8")
    before = _files(out)
    assert main(["sweep", str(spec_file), "--out", str(out), "--resume", "--no-progress",
                 "--processes", "1"]) == 2
    assert message in _one_line(capsys)
    assert _files(out) == before
    if how not in ("rows of another sweep", "digest of another spec"):  # resume's checks
        assert main(["sweep-report", str(out), "--out", str(tmp_path / "r.html")]) == 2
        assert message in _one_line(capsys)
        assert not (tmp_path / "r.html").exists()


def test_a_spec_nested_5000_deep_is_one_line(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    for name, text in (("arrays.toml", "x = " + "[" * 5000 + "]" * 5000 + "\n"),
                       ("tables.toml", "x = " + "{a = " * 5000 + "1" + "}" * 5000 + "\n"),
                       ("dotted.toml", "[overrides]\n" + ".".join(["a"] * 5000) + " = 1\n")):
        (tmp_path / name).write_text(text, encoding="utf-8")
        assert main(["sweep", str(tmp_path / name), "--out", str(tmp_path / "o")]) == 2
        assert "more than 64 levels deep" in _one_line(capsys)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("vary, message", [
    ('grid = [-1.0, 1.0]', "vary[0].grid: -1.0 is not a value load.mass may take "
                           "(load.mass must be > 0, got -"),
    ('distribution = "uniform"\nlow = -0.5\nhigh = 2.0',
     "vary[0].low: -0.5 lets draws take values load.mass may not take (load.mass must be > 0"),
])
def test_a_grid_or_bound_outside_a_parameters_range_is_refused(
        vary: str, message: str, tmp_path: Path) -> None:
    text = SPEC.replace('distribution = "log-uniform"\nlow = 0.5\nhigh = 2.0', vary)
    (tmp_path / "s.toml").write_text(text, encoding="utf-8")
    with pytest.raises(ParameterError, match="^'.*s.toml': " + message.replace(
            "[", r"\[").replace("]", r"\]").replace("(", r"\(").replace(")", r"\)")):
        load_spec(tmp_path / "s.toml")
    # a relation to another parameter is left to each point (another varied one may help)
    ok = SPEC.replace('name = "load.mass"', 'name = "cylinder.rod_diameter"').replace(
        "high = 2.0", "high = 20.0")
    (tmp_path / "ok.toml").write_text(ok, encoding="utf-8")
    assert load_spec(tmp_path / "ok.toml").n_points == 4


@pytest.mark.parametrize("edit, message", [
    (('step:0.1', 'step:5'), "reference.spec: the reference reaches 5.5 m"),
    (('distribution = "log-uniform"\nlow = 0.5\nhigh = 2.0', 'grid = [0.1, 5.0]'),
     "vary[0].grid: amplitude 5.0: the reference reaches"),
    (('distribution = "log-uniform"\nlow = 0.5\nhigh = 2.0',
      'distribution = "uniform"\nlow = 0.05\nhigh = 3.0'),
     "vary[0].high: draws near high = 3.0: the reference reaches"),
])
def test_a_reference_that_leaves_the_stroke_is_refused(edit: tuple[str, str], message: str,
                                                        tmp_path: Path) -> None:
    text = SPEC.replace(*edit)
    if message.startswith("vary"):
        text = text.replace('name = "load.mass"\nrelative = true', 'name = "amplitude"')
    (tmp_path / "s.toml").write_text(text, encoding="utf-8")
    with pytest.raises(ParameterError) as info:
        load_spec(tmp_path / "s.toml")
    assert message in str(info.value) and "outside the stroke" in str(info.value)


def test_a_truncated_normal_far_in_its_tail_is_drawn_exactly(tmp_path: Path) -> None:
    """mean 0, std 1 truncated to [40, 41] put every draw on 41: Φ(-40) underflows. The
    draws are now scipy's truncnorm quantiles."""
    from scipy.stats import truncnorm

    from fuzzyservo.sweep.sampling import counter_uniform, transform

    u = counter_uniform(7, 1, np.arange(20000))
    for lo, hi, mean, std in ((40.0, 41.0, 0.0, 1.0), (-41.0, -40.0, 0.0, 1.0),
                              (0.5 + 45 * 0.01, 0.5 + 46 * 0.01, 0.5, 0.01)):
        var = Variation(name="load.mass", distribution="normal",
                        args=(("mean", mean), ("std", std), ("low", lo), ("high", hi)))
        got = transform(var, u)
        a, b = (lo - mean) / std, (hi - mean) / std
        want = mean + std * truncnorm.ppf(u, a, b)
        # both are inverse CDFs: they differ by rounding, a few ulps of the tail's log
        np.testing.assert_allclose(got, want, rtol=1e-13)
        assert np.all((got >= lo) & (got <= hi))
        assert not np.any((got == lo) | (got == hi))  # before: every draw on one bound
        assert np.unique(got).size > 0.99 * u.size
    # such a spec records its own scheme (a folder drawn by scheme 1 is not resumed into);
    # every other spec keeps scheme 1
    text = SPEC.replace('relative = true\ndistribution = "log-uniform"\nlow = 0.5\nhigh = 2.0',
                        'relative = true\ndistribution = "normal"\nmean = 1.0\nstd = 0.001\n'
                        'low = 1.04\nhigh = 1.041')
    (tmp_path / "tail.toml").write_text(text, encoding="utf-8")
    tail = load_spec(tmp_path / "tail.toml")
    assert tail.sampling_scheme == LOG_TAIL_SCHEME
    assert tail.canonical()["sampling"] == LOG_TAIL_SCHEME
    (tmp_path / "plain.toml").write_text(SPEC, encoding="utf-8")
    assert load_spec(tmp_path / "plain.toml").canonical()["sampling"] == SAMPLING_SCHEME


@pytest.fixture()
def foreign_server() -> Iterator[tuple[str, str]]:
    """Two local ports where something other than Dask answers: one sends an SSH banner on
    connect, one accepts and says nothing."""
    servers = []
    for banner in (b"SSH-2.0-OpenSSH_8.9p1 Ubuntu-3ubuntu0.6\r\n", b""):
        srv = socket.socket()
        srv.bind(("127.0.0.1", 0))
        srv.listen()
        conns: list[socket.socket] = []

        def serve(srv: socket.socket = srv, banner: bytes = banner,
                  conns: list[socket.socket] = conns) -> None:
            while True:
                try:
                    c, _ = srv.accept()
                except OSError:
                    return
                conns.append(c)
                if banner:
                    c.sendall(banner)

        threading.Thread(target=serve, daemon=True).start()
        servers.append((srv, conns))
    try:
        yield tuple(f"tcp://127.0.0.1:{s.getsockname()[1]}" for s, _ in servers)  # type: ignore[misc]
    finally:
        for srv, conns in servers:
            srv.close()
            for c in conns:
                c.close()


def test_a_scheduler_address_where_another_protocol_answers(
        foreign_server: tuple[str, str], spec_file: Path, tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import fuzzyservo.sweep.run as run

    monkeypatch.setattr(run, "SCHEDULER_TIMEOUT", 2.0)  # the silent peer: not 20 s in a test
    banner, silent = foreign_server
    for address, why in ((banner, "something accepted the connection and spoke another "
                                  "protocol"),
                         (silent, "no Dask handshake within 2 s")):
        assert main(["sweep", str(spec_file), "--out", str(tmp_path / "s"), "--scheduler",
                     address, "--no-progress"]) == 2
        err = _one_line(capsys)
        assert f"--scheduler {address!r}: no Dask scheduler answered at that address ({why})" \
            in err and "memory" not in err
    assert not (tmp_path / "s").exists()
