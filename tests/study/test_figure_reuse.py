"""A warm ``reproduce`` keeps the figures a previous run drew from the same inputs instead of
drawing them again (issue 10, item 7); a changed input, a changed file or ``--force`` draws
them again, and the folder is complete and its report embeds the figures either way."""

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
import fuzzyservo.study.runner as runner
from fuzzyservo._io import sha256_file
from fuzzyservo.cli import main
from fuzzyservo.plots.figures import FIG3_STEMS
from fuzzyservo.study.figures import FIGURE_STEMS
from fuzzyservo.study.runner import MANIFEST, folder_status
from tests.conftest import reproduce_argv


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
    assert spy.stems == [f"{s}_nonlinear" for s in FIGURE_STEMS] and spy.fig3_calls == 0
    assert (out / "fig5_nonlinear.png").read_bytes() == b"drawn again"
    assert folder_status(out) == ("complete", [])


def test_a_changed_input_or_force_draws_again(reproduced: Path, tmp_path: Path,
                                              spy: _Spy) -> None:
    out = _copy(reproduced, tmp_path)
    assert main([*reproduce_argv(out), "--plant", "linear", "--duration", "6"]) == 0
    assert spy.stems == [f"{s}_linear" for s in FIGURE_STEMS]  # another study: drawn
    assert spy.fig3_calls == 0  # Fig. 3 does not depend on the study
    spy.stems.clear()
    assert main([*reproduce_argv(out), "--plant", "linear", "--duration", "6",
                 "--force"]) == 0
    assert spy.stems == [f"{s}_linear" for s in FIGURE_STEMS] and spy.fig3_calls == 1


def test_a_figure_group_is_kept_only_from_a_finished_run_with_its_key(tmp_path: Path) -> None:
    files = [tmp_path / "a.png"]
    files[0].write_bytes(b"png")
    doc = {"complete": True, "outputs": {"a.png": sha256_file(files[0])},
           "figures": {"g": {"key": "k", "files": ["a.png"]}}}
    reusable = study_figures_module.reusable
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
    """Importing matplotlib costs about a second of the warm run's budget (5 s)."""
    out = _copy(reproduced, tmp_path)
    code = ("import sys; from fuzzyservo.cli import main; "
            f"rc = main({reproduce_argv(out)!r}); "
            "print(rc, 'matplotlib' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False, timeout=300)
    assert done.stdout.split()[-2:] == ["0", "False"], done.stderr
