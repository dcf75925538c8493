"""The reproduction's folder: a data-only cache that is checked before use, a manifest
written last, and a folder that is complete or says it is not, whatever point a run is
killed at (issue 9, rows 1, 2, 7 and 14)."""

from __future__ import annotations

import csv
import json
import pickle  # only to craft the hostile cache entry of row 1
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo import __version__
from fuzzyservo._io import sha256_file
from fuzzyservo.cli import main
from fuzzyservo.study.cache import CacheEntryError, load_study
from fuzzyservo.study.runner import GAIN_FILES, MANIFEST, default_gains_dir, folder_status
from tests.helpers import run_once, start_fuzzyservo, wait_for_temporary

MARKER = "/tmp/fuzzyservo-cache-ran-code"  # noqa: S108  (what the crafted pickle would create)


class _Hostile:
    def __reduce__(self) -> tuple[object, tuple[str]]:
        import os
        return (os.system, (f"touch {MARKER}",))


def _entry(folder: Path, plant: str) -> tuple[Path, str]:
    (path,) = (folder / ".cache").glob(f"{plant}-*.npz")
    return path, path.stem.split("-", 1)[1]


def _visible(out: Path) -> set[str]:
    return {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()
            and not any(part.startswith(".") for part in p.relative_to(out).parts)}


def test_make_reproduce_writes_a_manifest_that_covers_every_output(reproduced: Path) -> None:
    status, problems = folder_status(reproduced)
    assert (status, problems) == ("complete", [])
    doc = json.loads((reproduced / MANIFEST).read_text())
    assert doc["complete"] is True and doc["fuzzyservo"] == __version__
    assert doc["parameter_set"] == "paper" and doc["overrides"] == {}
    assert set(doc["outputs"]) == _visible(reproduced) - {MANIFEST}
    for rel, digest in doc["outputs"].items():
        assert sha256_file(reproduced / rel) == digest
    committed = {p.name: sha256_file(p) for p in default_gains_dir().glob("*.toml")
                 if p.stem.split("-", 1)[1] in GAIN_FILES}  # the study's (not the robust)
    assert {Path(k).name: v["sha256"] for k, v in doc["gains"].items()} == committed


def test_a_cache_entry_round_trips_to_the_published_metrics(reproduced: Path) -> None:
    path, key = _entry(reproduced, "linear")
    study = load_study(path, key=key, version=__version__)
    with (reproduced / "metrics.csv").open() as fh:
        rows = [r for r in csv.DictReader(fh)
                if r["plant"] == "linear" and float(r["delay [s]"]) == 0.0]  # nominal runs
    assert [r["controller"] for r in rows] == [c.key for c in study.cases]
    for r in rows:
        assert float(r["itae [m s^2]"]) == study.metrics[r["controller"]]["itae"]
    trace = np.loadtxt(reproduced / "traces" / "linear_stfpi.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(trace[:, 2], study.runs["stfpi"].y)


def _rewrite(src: Path, dst: Path, **change: np.ndarray) -> None:
    with np.load(src, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays.update(change)
    with dst.open("wb") as fh:
        np.savez(fh, **arrays)  # type: ignore[arg-type]


def test_unusable_cache_entries_are_refused_with_the_reason(reproduced: Path,
                                                            tmp_path: Path) -> None:
    path, key = _entry(reproduced, "linear")
    bad = tmp_path / "entry.npz"

    def reason(**kw: str) -> str:
        with pytest.raises(CacheEntryError) as err:
            load_study(bad, key=kw.get("key", key), version=kw.get("version", __version__))
        return str(err.value)

    bad.write_bytes(path.read_bytes()[:800])
    assert "not an .npz archive" in reason()  # row 11's twin: truncated
    bad.write_bytes(b"\x00garbage" * 100)
    assert "not an .npz archive" in reason()
    bad.write_bytes(pickle.dumps(_Hostile()))
    assert "a pickle, which fuzzyservo never loads" in reason()
    Path(MARKER).unlink(missing_ok=True)
    _rewrite(path, bad, meta=np.array([_Hostile()], dtype=object))  # pickled inside the npz
    assert "pickled" in reason() and not Path(MARKER).exists()
    shutil.copy(path, bad)
    assert "inputs differ" in reason(key="0" * 16)  # foreign: another study's entry
    assert "written by fuzzyservo" in reason(version="0.0.1")  # stale
    with np.load(path, allow_pickle=False) as z:
        y32 = z["runs/stfpi/y"].astype(np.float32)
    _rewrite(path, bad, **{"runs/stfpi/y": y32})
    assert "dtype float32" in reason()
    _rewrite(path, bad, **{"runs/stfpi/y": np.zeros(3)})
    assert "shape" in reason()
    _rewrite(path, bad, meta=np.array("{]"))
    assert "malformed" in reason()
    with bad.open("wb") as fh:  # a 60 kB archive that would unpack into 60 MB
        np.savez_compressed(fh, meta=np.array("{}"), bomb=np.zeros(7_500_000))
    assert bad.stat().st_size < 200_000 and "compressed members" in reason()


def test_a_crafted_cache_entry_runs_no_code_and_is_recomputed(
        reproduced: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Row 1 and row 2: a hostile pickle in OUT/.cache, then the same command again."""
    out = tmp_path / "results"
    shutil.copytree(reproduced, out)
    path, key = _entry(out, "linear")
    path.write_bytes(pickle.dumps(_Hostile()))
    Path(MARKER).unlink(missing_ok=True)
    assert main(["reproduce", "--out", str(out), "--plant", "linear", "--quiet"]) == 0
    assert not Path(MARKER).exists()
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("fuzzyservo: warning: ignoring cache entry")
    assert "pickle" in err[0] and "recomputing" in err[0]
    load_study(path, key=key, version=__version__)  # the recomputed entry is sound
    assert folder_status(out) == ("complete", [])
    doc = json.loads((out / MANIFEST).read_text())
    assert doc["plants"] == ["linear"]
    assert not any(p.startswith("traces/nonlinear") for p in _visible(out))  # no mix


def test_a_second_reproduce_on_the_same_folder_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two runs on one folder deleted each other's temporary files and interleaved their
    outputs (found in review); the folder's lock refuses the second, before any work."""
    import fcntl

    out = tmp_path / "rp"
    out.mkdir()
    with (out / ".lock").open("a+") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        held.write("12345\n")
        held.flush()
        assert main(["reproduce", "--out", str(out), "--plant", "linear", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "another fuzzyservo reproduce (pid 12345)" in err
    assert sorted(p.name for p in out.iterdir()) == [".lock"]  # nothing else touched


# --- killed at random points ---------------------------------------------------------------

BASE = ["reproduce", "--plant", "linear", "--duration", "5", "--quiet"]


def _check_folder(out: Path) -> str:
    """The folder is a complete set, or is marked incomplete where reproduce and a reader of
    the report look; never a silent mix."""
    status, problems = folder_status(out)
    doc = json.loads((out / MANIFEST).read_text())
    report = (out / "report.html").read_text()
    if status == "complete":
        assert set(doc["outputs"]) == _visible(out) - {MANIFEST}, "files of another run"
        shown = doc["overrides"]
        for name, value in shown.items():
            assert f"{name} = {value!r}" in report
        assert ("overrides in force" in report) == bool(shown)
        assert "INCOMPLETE" not in report
    else:
        assert status == "incomplete" and problems
        assert doc["complete"] is False or "INCOMPLETE" in report
    return status


def _configs(start: Path, out: Path) -> list[list[str]]:
    """The two parameter sets the kills alternate: the file's override, and none."""
    return [[*BASE, "--out", str(out), "--params", str(start / "sp.toml")],
            [*BASE, "--out", str(out)]]


@pytest.fixture(scope="session")
def two_sets(tmp_path_factory: pytest.TempPathFactory, worker_id: str) -> Path:
    """A folder ``rp`` written by a run with a parameter file and then by one without (the
    C8 sweep's files back), and the writes' duration; made once per session (conftest's
    tests.helpers.run_once), each test copies ``rp``."""
    def two_runs_timed(start: Path) -> None:
        start.mkdir(parents=True, exist_ok=True)
        (start / "sp.toml").write_text("[supply]\npressure = 7.5e6\n")
        out = start / "rp"
        configs = _configs(start, out)
        t0 = time.perf_counter()
        assert main(configs[0]) == 0  # row 14: the file's override is stated
        doc = json.loads((out / MANIFEST).read_text())
        assert doc["overrides"] == {"supply.pressure": 7.5e6}
        assert "supply.pressure = 7500000.0" in (out / "report.html").read_text()
        assert main(configs[1]) == 0
        (start / "write_time").write_text(repr(0.6 * (time.perf_counter() - t0) / 2))

    return run_once(tmp_path_factory, worker_id, "two-sets", two_runs_timed)


def _copy_of(start: Path, tmp_path: Path) -> Path:
    out = tmp_path / "rp"
    shutil.copytree(start / "rp", out, symlinks=True)
    assert _check_folder(out) == "complete"
    return out


def _kill_reproduce(sig: int, n: int, seed: int, start: Path, tmp_path: Path
                    ) -> list[tuple[int, str]]:
    out = _copy_of(start, tmp_path)
    configs = _configs(start, out)
    write_time = float((start / "write_time").read_text())
    rng = random.Random(seed)
    seen = []
    for i in range(n):
        proc = start_fuzzyservo(configs[i % 2])
        assert wait_for_temporary(out, ".*.tmp", proc)
        # sleep: a random point inside the writes is the test's input, not a wait
        time.sleep(rng.uniform(0.0, 1.0) * write_time)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=300)
        assert "Traceback" not in err, err
        seen.append((proc.returncode, _check_folder(out)))
    res = subprocess.run([sys.executable, "-m", "fuzzyservo", *configs[1]],
                         capture_output=True, text=True, check=False)
    assert res.returncode == 0
    if seen[-1][1] == "incomplete":
        assert "is incomplete" in res.stderr and "writing it again" in res.stderr
    assert _check_folder(out) == "complete"
    return seen


@pytest.mark.slow
def test_a_run_without_the_c8_sweeps_then_one_with_them(two_sets: Path, tmp_path: Path
                                                        ) -> None:
    # --params leaves the C8 sweeps out and removes their recorded files, not the sweep's
    # lock: the next run with them found a folder 'not a sweep folder' and stopped (the
    # copy's last run had them)
    out = _copy_of(two_sets, tmp_path)
    assert (out / "c8-sweep-linear.html").is_file()
    assert main([*BASE, "--out", str(out), "--params", str(two_sets / "sp.toml")]) == 0
    assert not (out / "c8-sweep-linear.html").exists()
    assert main([*BASE, "--out", str(out)]) == 0
    assert (out / "c8-sweep-linear.html").is_file()
    assert _check_folder(out) == "complete"


@pytest.mark.slow
def test_reproduce_killed_by_sigkill_at_random_points(two_sets: Path, tmp_path: Path) -> None:
    """Row 7: ``kill -9`` at 10 random points of the writing, alternating two parameter
    sets."""
    seen = _kill_reproduce(signal.SIGKILL, 10, 7, two_sets, tmp_path)
    assert sum(code == -signal.SIGKILL for code, _ in seen) >= 7, seen
    assert any(state == "incomplete" for _, state in seen), seen


@pytest.mark.slow
def test_reproduce_interrupted_by_ctrl_c_at_random_points(two_sets: Path, tmp_path: Path
                                                         ) -> None:
    seen = _kill_reproduce(signal.SIGINT, 10, 8, two_sets, tmp_path)
    assert all(code in (0, 130) for code, _ in seen), seen
    assert sum(code == 130 for code, _ in seen) >= 7, seen


@pytest.mark.parametrize("link", ["traces/fig4-linear.csv", "report.html", ".lock",
                                  ".cache"])
def test_a_link_inside_the_folder_is_refused_and_its_target_untouched(
        link: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 29: a symlinked traces/*.csv or report.html had its target overwritten (and
    the lock, opened "a+" and truncated, its target emptied). Refused before any work."""
    out = tmp_path / "rp"
    (out / "traces").mkdir(parents=True)
    victim = tmp_path / "victim"
    victim.write_text("victim\n", encoding="utf-8")
    if link == ".cache":
        victim.unlink()
        victim.mkdir()
        (victim / "keep.txt").write_text("victim\n", encoding="utf-8")
    (out / link).symlink_to(victim)
    assert main(["reproduce", "--out", str(out), "--plant", "linear", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"holds a symbolic link, {link!r}" in err, err
    kept = victim / "keep.txt" if link == ".cache" else victim
    assert kept.read_text(encoding="utf-8") == "victim\n"
    assert sorted(p.name for p in out.iterdir()) == sorted({"traces", link.split("/")[0]}
                                                           | ({".lock"} if link != ".lock"
                                                              else set()))
