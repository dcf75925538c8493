"""The reduced C8 sweeps of ``fuzzyservo reproduce`` (study/c8.py): what a run without the
sweeps or an interruption leaves in their folder is started afresh; anything else is kept."""

from __future__ import annotations

from pathlib import Path

import pytest

from fuzzyservo.errors import OutputError
from fuzzyservo.study.c8 import run_c8
from fuzzyservo.sweep.dataset import read_manifest, read_table, table_digest


@pytest.fixture(scope="module")
def first(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("c8")
    run_c8(out, ["linear"], samples=1, progress=False)
    return out, table_digest(read_table(out / "c8-sweep-linear"))


def _copy(src: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(src, dst)
    return dst / "c8-sweep-linear"


def test_a_folder_emptied_by_a_run_without_the_sweeps_is_run_again(
        first: tuple[Path, str], tmp_path: Path) -> None:
    out, digest = first
    folder = _copy(out, tmp_path / "o")
    # what reproduce --params removes: the files the last run recorded (not the lock)
    for p in [folder / "manifest.json", folder / "report.key",
              *(folder / "chunks").iterdir()]:
        p.unlink()
    assert sorted(p.name for p in folder.rglob("*")) == [".lock", "chunks"]
    run_c8(tmp_path / "o", ["linear"], samples=1, progress=False)
    assert table_digest(read_table(folder)) == digest


def test_chunks_left_without_their_manifest_are_run_again(first: tuple[Path, str],
                                                         tmp_path: Path) -> None:
    out, digest = first
    folder = _copy(out, tmp_path / "o")
    (folder / "manifest.json").unlink()  # that removal interrupted after its first file
    (folder / "chunks" / ".chunk-000000.parquet.abcd1234.tmp").write_bytes(b"half")
    run_c8(tmp_path / "o", ["linear"], samples=1, progress=False)
    assert table_digest(read_table(folder)) == digest
    assert len(read_manifest(folder).done) == read_manifest(folder).n_chunks
    assert not list((folder / "chunks").glob(".*.tmp"))


def test_a_folder_holding_anything_else_is_kept(first: tuple[Path, str],
                                                tmp_path: Path) -> None:
    out, _ = first
    folder = _copy(out, tmp_path / "o")
    (folder / "manifest.json").unlink()
    (folder / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="exists and is not a sweep folder"):
        run_c8(tmp_path / "o", ["linear"], samples=1, progress=False)
    assert (folder / "notes.txt").read_text() == "mine"
    assert any((folder / "chunks").iterdir())
