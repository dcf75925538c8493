"""A warm ``reproduce`` keeps the figures and trace CSVs a previous run made from the same
inputs instead of making them again (issue 10, item 7); a changed input, a changed file or
``--force`` makes them again, and the folder is complete and its report embeds the figures
either way. A finished run removes its plants' stale cache entries."""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

import fuzzyservo.study.figures as study_figures_module
import fuzzyservo.study.reuse as reuse_module
import fuzzyservo.study.runner as runner
from fuzzyservo._io import sha256_file
from fuzzyservo.cli import main
from fuzzyservo.plots.figures import FIG3_STEMS
from fuzzyservo.sim import SimResult
from fuzzyservo.study.figures import FIGURE_STEMS, FREQUENCY_STEMS, TRACKING_STEMS
from fuzzyservo.study.runner import MANIFEST, folder_status
from tests.conftest import reproduce_argv

#: Every figure of one plant that reproduce draws (the tracking study and Bode figure too).
STEMS = FIGURE_STEMS + TRACKING_STEMS + FREQUENCY_STEMS


def _copy(reproduced: Path, tmp_path: Path) -> Path:
    out = tmp_path / "results"
    shutil.copytree(reproduced, out)  # the shared reproduction stays as it is
    return out


class _Spy:
    """Stands in for the drawing: records what would be drawn and writes placeholder files."""

    def __init__(self) -> None:
        self.stems: list[str] = []
        self.fig3_calls = 0

    def save(self, fig: object, stem: Path) -> list[Path]:
        self.stems.append(Path(stem).name)
        paths = [Path(f"{stem}.png"), Path(f"{stem}.svg")]
        for p in paths:
            p.write_bytes(b"drawn again")
        return paths

    def fig3(self, du: object, alpha: object, out_dir: Path, n: int = 81,
             formats: tuple[str, ...] = ("png",)) -> list[Path]:
        self.fig3_calls += 1
        paths = runner.fig3_files(out_dir, formats)
        for p in paths:
            p.write_bytes(b"drawn again")
        return paths


class _CsvSpy:
    """Records each trace a run writes with ``SimResult.to_csv``, then writes it; with
    ``forbid`` set, fails the test instead."""

    def __init__(self, real: Callable[..., None]) -> None:
        self.real = real
        self.names: list[str] = []
        self.forbid = False

    def to_csv(self, run: SimResult, dest: Path) -> None:
        assert not self.forbid, f"to_csv called for {dest}"
        self.names.append(Path(dest).name)
        self.real(run, dest)


@pytest.fixture
def csv_spy(monkeypatch: pytest.MonkeyPatch) -> _CsvSpy:
    s = _CsvSpy(SimResult.to_csv)

    def to_csv(run: SimResult, dest: Path) -> None:  # a function: bound to each run
        s.to_csv(run, dest)

    monkeypatch.setattr(SimResult, "to_csv", to_csv)
    return s


def _traces(out: Path, plant: str = "") -> dict[str, tuple[int, str]]:
    """Each trace file of ``plant`` (all with "") as (inode, SHA-256): a rewrite is a new
    inode (atomic write), even with the same bytes."""
    return {p.name: (p.stat().st_ino, sha256_file(p))
            for p in sorted((out / "traces").glob(f"{plant}*.csv"))}


def _runs(out: Path, plant: str) -> list[str]:
    """The run traces of ``plant`` (what to_csv writes; the delay sweep is not a run)."""
    return sorted(p.name for p in (out / "traces").glob(f"{plant}_*.csv")
                  if not p.name.endswith("_delay_sweep.csv"))


@pytest.fixture
def spy(monkeypatch: pytest.MonkeyPatch) -> _Spy:
    s = _Spy()
    monkeypatch.setattr(study_figures_module, "save", s.save)
    monkeypatch.setattr(runner, "fig3", s.fig3)
    # no figure is drawn: a PlannedFigure's draw() must not be called either
    monkeypatch.setattr(study_figures_module.PlannedFigure, "__init__", _no_draw(
        study_figures_module.PlannedFigure.__init__))
    return s


def _no_draw(init: Callable[..., None]) -> Callable[..., None]:
    def wrapped(self: object, stem: str, caption: str, draw: object) -> None:
        init(self, stem, caption, lambda: None)
    return wrapped


def _figure_files(out: Path) -> dict[str, str]:
    names = [f"{s}_{p}" for s in FIGURE_STEMS for p in ("linear", "nonlinear")]
    return {f"{n}.{x}": sha256_file(out / f"{n}.{x}") for n in [*names, *FIG3_STEMS]
            for x in ("png", "svg")}


def test_warm_run_draws_nothing_and_lists_every_figure(reproduced: Path, tmp_path: Path,
                                                       spy: _Spy) -> None:
    out = _copy(reproduced, tmp_path)
    before = _figure_files(out)
    assert main(reproduce_argv(out)) == 0
    assert spy.stems == [] and spy.fig3_calls == 0  # nothing drawn
    assert _figure_files(out) == before  # the files are the previous run's
    assert folder_status(out) == ("complete", [])
    doc = json.loads((out / MANIFEST).read_text())
    assert set(before) <= set(doc["outputs"])  # still outputs of this run
    assert set(doc["figures"]) == {"fig3", "linear", "nonlinear"}
    html = (out / "report.html").read_text()
    for name in ("fig4_linear.png", "robustness_nonlinear.png", "fig3a_rules_du.png"):
        assert base64.b64encode((out / name).read_bytes()).decode() in html, name
    assert "Fig. 8, linear plant: the self-tuning fuzzy PI without and with the 6 ms" in html


def test_a_changed_figure_file_is_drawn_again(reproduced: Path, tmp_path: Path,
                                              spy: _Spy) -> None:
    out = _copy(reproduced, tmp_path)
    (out / "fig5_nonlinear.png").write_bytes(b"tampered")
    assert main(reproduce_argv(out)) == 0
    # the nonlinear plant's figures, and only they, are drawn again
    assert spy.stems == [f"{s}_nonlinear" for s in STEMS] and spy.fig3_calls == 0
    assert (out / "fig5_nonlinear.png").read_bytes() == b"drawn again"
    assert folder_status(out) == ("complete", [])


def test_a_changed_input_or_force_draws_again(reproduced: Path, tmp_path: Path,
                                              spy: _Spy, csv_spy: _CsvSpy) -> None:
    out = _copy(reproduced, tmp_path)
    assert main([*reproduce_argv(out), "--plant", "linear", "--duration", "6"]) == 0
    assert spy.stems == [f"{s}_linear" for s in STEMS]  # another study: drawn
    assert spy.fig3_calls == 0  # Fig. 3 does not depend on the study
    assert sorted(csv_spy.names) == _runs(out, "linear")  # and its traces written
    spy.stems.clear()
    csv_spy.names.clear()
    before = _traces(out)
    assert main([*reproduce_argv(out), "--plant", "linear", "--duration", "6",
                 "--force"]) == 0
    assert spy.stems == [f"{s}_linear" for s in STEMS] and spy.fig3_calls == 1
    assert sorted(csv_spy.names) == _runs(out, "linear")
    after = _traces(out)
    assert all(after[n][0] != before[n][0] for n in before)  # the sweep's CSV too
    assert folder_status(out) == ("complete", [])


def test_warm_run_writes_no_trace(reproduced: Path, tmp_path: Path, spy: _Spy,
                                  csv_spy: _CsvSpy) -> None:
    """About 3 s of the warm run went into writing 92 MB of identical CSVs again."""
    out = _copy(reproduced, tmp_path)
    before = _traces(out)
    assert len(before) >= 2 * 9
    csv_spy.forbid = True
    assert main(reproduce_argv(out)) == 0
    assert _traces(out) == before  # the same files, not rewritten (same inodes)
    assert folder_status(out) == ("complete", [])
    doc = json.loads((out / MANIFEST).read_text())
    assert {f"traces/{n}" for n in before} <= set(doc["outputs"])  # outputs of this run
    assert set(doc["traces"]) == {"linear", "nonlinear"}
    assert sorted(f for g in doc["traces"].values() for f in g["files"]) == sorted(
        f"traces/{n}" for n in before)


def test_a_changed_trace_is_written_again(reproduced: Path, tmp_path: Path, spy: _Spy,
                                          csv_spy: _CsvSpy) -> None:
    out = _copy(reproduced, tmp_path)
    original = _traces(out)
    tampered = out / "traces" / "nonlinear_fpi.csv"
    with tampered.open("a") as fh:
        fh.write("0,0,0,0,0,0,0,0,0,0,0,0\n")
    linear = _traces(out, "linear")
    assert main(reproduce_argv(out)) == 0
    # the nonlinear plant's traces, and only they, are written again
    assert sorted(csv_spy.names) == _runs(out, "nonlinear")
    assert _traces(out, "linear") == linear
    after = _traces(out)
    assert {n: d for n, (_, d) in after.items()} == {n: d for n, (_, d) in original.items()}
    assert folder_status(out) == ("complete", [])


def test_traces_of_an_unfinished_run_are_written_again(reproduced: Path, tmp_path: Path,
                                                       spy: _Spy, csv_spy: _CsvSpy) -> None:
    out = _copy(reproduced, tmp_path)
    doc = json.loads((out / MANIFEST).read_text())
    (out / MANIFEST).write_text(json.dumps({**doc, "complete": False}))
    assert main(reproduce_argv(out)) == 0
    assert sorted(csv_spy.names) == sorted([*_runs(out, "linear"), *_runs(out, "nonlinear")])
    assert folder_status(out) == ("complete", [])


def test_a_figure_group_is_kept_only_from_a_finished_run_with_its_key(tmp_path: Path) -> None:
    files = [tmp_path / "a.png"]
    files[0].write_bytes(b"png")
    doc = {"complete": True, "outputs": {"a.png": sha256_file(files[0])},
           "figures": {"g": {"key": "k", "files": ["a.png"]}}}
    reusable = reuse_module.reusable
    assert reusable({**doc, "traces": doc["figures"]}, tmp_path, "g", "k", files,
                    section="traces")
    assert not reusable(doc, tmp_path, "g", "k", files, section="traces")
    assert reusable(doc, tmp_path, "g", "k", files)
    assert not reusable(doc, tmp_path, "g", "other key", files)
    assert not reusable(doc, tmp_path, "h", "k", files)
    assert not reusable({**doc, "complete": False}, tmp_path, "g", "k", files)
    assert not reusable(None, tmp_path, "g", "k", files)
    assert not reusable(doc, tmp_path, "g", "k", [*files, tmp_path / "b.png"])
    files[0].write_bytes(b"changed")
    assert not reusable(doc, tmp_path, "g", "k", files)
    files[0].unlink()
    assert not reusable(doc, tmp_path, "g", "k", files)


def test_warm_run_does_not_load_matplotlib(reproduced: Path, tmp_path: Path) -> None:
    """Importing matplotlib costs about a second of the warm run's budget (5 s), and
    scipy.integrate (only Gaussian outputs and the solve_ivp path need it) 0.1 s more."""
    out = _copy(reproduced, tmp_path)
    code = ("import sys; from fuzzyservo.cli import main; "
            f"rc = main({reproduce_argv(out)!r}); "
            "print(rc, 'matplotlib' in sys.modules, 'scipy.integrate' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False, timeout=300)
    assert done.stdout.split()[-3:] == ["0", "False", "False"], done.stderr


def test_digests_hash_a_file_again_once_it_is_replaced(tmp_path: Path) -> None:
    p = tmp_path / "a.csv"
    p.write_bytes(b"one")
    digests = reuse_module.Digests()
    assert digests(p) == sha256_file(p)
    replacement = tmp_path / "b.csv"
    replacement.write_bytes(b"two")
    replacement.replace(p)  # as an atomic write does
    assert digests(p) == sha256_file(p)
    with p.open("ab") as fh:  # written in place, same inode
        fh.write(b" more")
    assert digests(p) == sha256_file(p)


# --- the cache keeps the current entries only ----------------------------------------------

STALE = "0123456789abcdef"


def _plant_stale_entries(out: Path) -> dict[str, Path]:
    cache = out / ".cache"
    names = {"stale linear": f"linear-{STALE}.npz",
             "stale nonlinear": f"nonlinear-{STALE}.npz",  # a plant this run does not run
             "not a key": "linear-stale.npz", "other": "notes.txt",
             "another plant": f"linear2-{STALE}.npz"}
    paths = {k: cache / n for k, n in names.items()}
    for p in paths.values():
        p.write_bytes(b"old")
    return paths


def test_a_finished_run_removes_stale_entries_of_its_plants(reproduced: Path,
                                                           tmp_path: Path) -> None:
    out = _copy(reproduced, tmp_path)
    current = sorted((out / ".cache").glob("*.npz"))
    assert len(current) == 2
    paths = _plant_stale_entries(out)
    assert main([*reproduce_argv(out), "--plant", "linear"]) == 0
    assert not paths["stale linear"].exists()
    assert all(p.exists() for k, p in paths.items() if k != "stale linear")
    assert all(p.exists() for p in current)  # the entries in use, both plants'


def test_a_failing_run_removes_no_cache_entry(reproduced: Path, tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    out = _copy(reproduced, tmp_path)
    paths = _plant_stale_entries(out)

    def fail(*args: object, **kwargs: object) -> None:
        raise RuntimeError("write failed")

    monkeypatch.setattr(runner, "write_outputs", fail)
    with pytest.raises(RuntimeError, match="write failed"):
        main(reproduce_argv(out))
    assert all(p.exists() for p in paths.values())
