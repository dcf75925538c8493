"""The sweep report: written atomically and self-contained, its numbers equal to counts made
independently from the dataset (pyarrow, numpy, plain Python), its worst runs the worst by
its stated criterion, its commands replaying their rows, and the odd sweeps (partial, one
controller, one varied quantity, no grid, invalid points, a controller whose every run fails
or diverges) reported without a crash or a warning.

Sweeps run on the linear plant with short runs; the three sweeps take a few seconds.
"""

from __future__ import annotations

import html
import math
import re
import shlex
import shutil
import warnings
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from fuzzyservo.analysis.outcome import OUTCOMES
from fuzzyservo.cli import main
from fuzzyservo.sweep import load_spec, read_table, run_sweep
from fuzzyservo.sweep.dataset import finished_files
from fuzzyservo.sweep.report import write_report
from tests.helpers import printed_metrics

# two grids (a grid map), noise drawn at random, three controllers: the last never settles
MAIN = """
[sweep]
name = "report test"
plant = "linear"
duration = 3.0
samples = 4
seed = 5
chunk = 7

[reference]
spec = "step:0.1"

[[controllers]]
label = "stfpi tuned"
gains = "linear-stfpi.toml"

[[controllers]]
label = "pid tuned"
gains = "linear-pid.toml"

[[controllers]]
label = "slow p"
controller = "p"
gains = { kp = 0.001 }

[[vary]]
name = "load.mass"
relative = true
grid = [0.5, 1.0, 2.0]

[[vary]]
name = "delay"
grid = [0.0, 0.02]

[[vary]]
name = "noise_std"
distribution = "uniform"
low = 0.0
high = 2e-5
"""

# no grid (binned maps), delays past the run's end (invalid points), two controllers
RANDOM = """
[sweep]
name = "random only"
plant = "linear"
duration = 1.5
samples = 60
seed = 9
chunk = 60

[[controllers]]
label = "stfpi tuned"
gains = "linear-stfpi.toml"

[[controllers]]
label = "pid tuned"
gains = "linear-pid.toml"

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
high = 2.0
"""

# one controller, one varied quantity
ONE = """
[sweep]
name = "one of each"
plant = "linear"
duration = 1.5
samples = 12
seed = 2
chunk = 12

[[controllers]]
label = "stfpi tuned"
gains = "linear-stfpi.toml"

[[vary]]
name = "amplitude"
distribution = "uniform"
low = 0.05
high = 0.12
"""


# ---- helpers ----------------------------------------------------------------------------------

class _Tables(HTMLParser):
    """Every <table> of a page as (caption, header, rows), cell text unescaped."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tables: list[tuple[str, list[str], list[list[str]]]] = []
        self._cell: list[str] | None = None
        self._row: list[str] | None = None
        self._caption: list[str] | None = None
        self._head = False

    def handle_starttag(self, tag: str, attrs: Any) -> None:
        if tag == "table":
            self.tables.append(("", [], []))
        elif tag == "caption":
            self._caption = []
        elif tag == "tr":
            self._row, self._head = [], False
        elif tag in ("td", "th"):
            self._cell = []
            self._head = tag == "th"

    def handle_endtag(self, tag: str) -> None:
        if tag == "caption" and self._caption is not None:
            cap, head, rows = self.tables[-1]
            self.tables[-1] = ("".join(self._caption).strip(), head, rows)
            self._caption = None
        elif tag in ("td", "th") and self._cell is not None and self._row is not None:
            self._row.append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "tr" and self._row is not None:
            cap, head, rows = self.tables[-1]
            if self._head:
                head.extend(self._row)
            else:
                rows.append(self._row)
            self._row = None

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)
        elif self._caption is not None:
            self._caption.append(data)


def tables(page: str) -> list[tuple[str, list[str], list[list[str]]]]:
    p = _Tables()
    p.feed(page)
    return p.tables


def table(page: str, caption: str) -> tuple[list[str], list[list[str]]]:
    """The one table whose caption starts with the regular expression ``caption``."""
    found = [(h, r) for c, h, r in tables(page) if re.match(caption, c)]
    assert len(found) == 1, f"one table captioned {caption!r}, found {len(found)}"
    return found[0]


def count_of(cell: str) -> int:
    """``12 (6.67 %)`` -> 12."""
    m = re.fullmatch(r"(\d+) \((?:[\d.e+-]+ %|n/a)\)", cell)
    assert m, cell
    return int(m.group(1))


def report(folder: Path, out: Path, worst: int = 10) -> str:
    """Write the report with every warning an error; return its text."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_report(folder, out, worst=worst)
    return out.read_text(encoding="utf-8")


def sweep(text: str, folder: Path, **kw: Any) -> Path:
    spec_file = folder.parent / f"{folder.name}.toml"
    spec_file.write_text(text, encoding="utf-8")
    # in this process: for sweeps this small, starting worker processes costs more than the runs
    run_sweep(load_spec(spec_file), folder, progress=False, processes=1, **kw)
    return folder


def rows_of(folder: Path) -> list[dict[str, Any]]:
    t = read_table(folder)
    return t.to_pylist()  # type: ignore[no-any-return]


# ---- fixtures ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def main_sweep(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return sweep(MAIN, tmp_path_factory.mktemp("main") / "sweep")


@pytest.fixture(scope="module")
def main_report_path(main_sweep: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("rep") / "report.html"
    report(main_sweep, out, worst=4)
    return out


@pytest.fixture(scope="module")
def main_report(main_report_path: Path) -> str:
    return main_report_path.read_text(encoding="utf-8")


# ---- tests ------------------------------------------------------------------------------------

def test_report_is_self_contained(main_report: str) -> None:
    assert main_report.startswith("<!DOCTYPE html>")
    refs = re.findall(r"""(?:src|href)\s*=\s*["']([^"']*)["']""", main_report)
    assert refs, "the report embeds its figures"
    assert all(r.startswith(("data:image/png;base64,", "#")) for r in refs), refs
    assert "http://" not in main_report and "https://" not in main_report
    assert "<script" not in main_report and "<link" not in main_report
    assert "url(" not in main_report and "@import" not in main_report  # no CSS fetch either
    n_img = len(re.findall(r"<img ", main_report))
    # outcomes, distributions, paired, 2 effects, 2 maps over the grid pair (+ maybe 2 more)
    assert n_img in (7, 9)


def test_report_is_written_atomically(main_sweep: Path, main_report_path: Path,
                                      tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # no temporary file is left beside a report
    assert [p.name for p in main_report_path.parent.iterdir()] == ["report.html"]
    out = tmp_path / "report.html"
    out.write_text("old report", encoding="utf-8")
    import fuzzyservo._io as io
    import fuzzyservo.sweep.report as rep

    def interrupt(*a: Any, **kw: Any) -> Any:
        raise KeyboardInterrupt

    # Ctrl-C while the report is computed, and while its file is renamed into place
    monkeypatch.setattr(rep, "_partial_section", interrupt)
    with pytest.raises(KeyboardInterrupt):
        write_report(main_sweep, out)
    monkeypatch.undo()
    real_replace = io.os.replace

    def replace(src: Any, dst: Any) -> None:
        if Path(dst).name == "report.html":
            raise KeyboardInterrupt
        real_replace(src, dst)

    monkeypatch.setattr(io.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        write_report(main_sweep, out)
    monkeypatch.undo()
    assert out.read_text(encoding="utf-8") == "old report"
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]


def test_outcome_table_equals_counts_from_the_table(main_sweep: Path, main_report: str) -> None:
    t = read_table(main_sweep, columns=["controller", "outcome"])
    t = t.set_column(0, "controller", t.column("controller").cast(pa.string()))
    t = t.set_column(1, "outcome", t.column("outcome").cast(pa.string()))
    counted = {(r["controller"], r["outcome"]): r["count_all"]
               for r in t.group_by(["controller", "outcome"]).aggregate(
                   [([], "count_all")]).to_pylist()}
    head, rows = table(main_report, "Runs per outcome")
    assert head[:3] == ["controller", "runs", "valid runs"]
    assert [r[0] for r in rows] == ["stfpi tuned", "pid tuned", "slow p"]
    for r in rows:
        lab = r[0]
        total = sum(v for (c, _), v in counted.items() if c == lab)
        invalid = counted.get((lab, "invalid"), 0)
        assert int(r[1]) == total and int(r[2]) == total - invalid
        for name in OUTCOMES[:-1]:
            cell = r[head.index(name)]
            n = counted.get((lab, name), 0)
            assert count_of(cell) == n
            # the share is of the valid runs, to 3 significant digits
            share = float(re.search(r"\(([\d.e+-]+) %\)", cell).group(1))  # type: ignore[union-attr]
            assert share == pytest.approx(100.0 * n / (total - invalid), rel=5e-3)
        fails = sum(counted.get((lab, o), 0) for o in ("not settled", "limit cycle", "diverged"))
        assert count_of(r[head.index("fails")]) == fails
        assert int(r[head.index("invalid")]) == invalid
    # the controller that never settles fails on every run; the others not
    assert count_of(rows[2][head.index("not settled")]) == int(rows[2][2])


def _worst_key(row: dict[str, Any]) -> tuple[int, float, int]:
    order = ["diverged", "limit cycle", "not settled", "overshoots", "settles"]
    itae = row["itae"]
    return (order.index(row["outcome"]), -(math.inf if itae is None or math.isnan(itae)
                                           else itae), row["point"])


def _worst_rows(page: str, label: str) -> list[list[str]]:
    head, rows = table(page, rf"{re.escape(label)}: the \d+ worst")
    assert head[:3] == ["#", "point", "outcome"]
    return rows


def _commands(page: str, label: str) -> list[str]:
    _, rows = table(page, rf"{re.escape(label)}: the commands that replay")
    return [html.unescape(r[1]) for r in rows]


def test_worst_runs_are_the_worst_by_the_stated_criterion(main_sweep: Path,
                                                          main_report: str) -> None:
    assert ("failures first (diverged, then limit cycle, then not settled), then overshoots, "
            "then the rest; within each outcome the largest ITAE first") in main_report
    rows = rows_of(main_sweep)
    for label in ("stfpi tuned", "pid tuned", "slow p"):
        mine = sorted((r for r in rows if r["controller"] == label
                       and r["outcome"] != "invalid"), key=_worst_key)
        listed = _worst_rows(main_report, label)
        assert len(listed) == 4
        assert [int(x[1]) for x in listed] == [r["point"] for r in mine[:4]]
        assert [x[2] for x in listed] == [r["outcome"] for r in mine[:4]]
    # the sweep has failures of two kinds, so the order of outcomes is exercised
    assert {"limit cycle", "not settled", "settles"} <= {r["outcome"] for r in rows}


def test_listed_commands_replay_their_rows(main_sweep: Path, main_report: str,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    rows = {(r["point"], r["controller"]): r for r in rows_of(main_sweep)}
    checked = noisy = 0
    for label in ("stfpi tuned", "pid tuned"):
        listed = _worst_rows(main_report, label)
        for x, cmd in zip(listed[:2], _commands(main_report, label), strict=False):
            row = rows[(int(x[1]), label)]
            argv = shlex.split(cmd)
            assert argv[0] == "fuzzyservo" and argv[-1] == "--metrics"
            capsys.readouterr()
            assert main(argv[1:]) == 0
            got = printed_metrics(capsys.readouterr().out)
            for name in ("rise_time", "settling_time", "overshoot", "iae", "itae",
                         "steady_state_error", "u_max"):
                want = float(f"{row[name]:.6g}")  # printed to 6 significant digits
                assert (math.isnan(got[name]) and math.isnan(want)) or got[name] == want, name
            checked += 1
            noisy += row["noise_std"] > 0.0 and f"--noise-std={row['noise_std']!r}" in argv
    assert checked >= 2 and noisy >= 1


def test_a_controller_whose_runs_all_diverge(main_sweep: Path, tmp_path: Path) -> None:
    """Every run of "slow p" rewritten as diverged, with NaN metrics: no crash, no warning,
    counted as failures and listed first among its worst."""
    folder = tmp_path / "sweep"
    shutil.copytree(main_sweep, folder)
    for path in finished_files(folder).values():
        t = pq.read_table(path)
        hit = pc.equal(t.column("controller").cast(pa.string()), "slow p")
        for name in t.column_names:
            if pa.types.is_floating(t.schema.field(name).type) and name not in (
                    "load.mass", "delay", "noise_std"):
                t = t.set_column(t.schema.get_field_index(name), name,
                                 pc.if_else(hit, pa.scalar(math.nan), t.column(name)))
        outcome = pc.if_else(hit, "diverged", t.column("outcome").cast(pa.string()))
        t = t.set_column(t.schema.get_field_index("outcome"), "outcome",
                         outcome.dictionary_encode())
        t = t.set_column(t.schema.get_field_index("diverged"), "diverged",
                         pc.or_(hit, t.column("diverged")))
        pq.write_table(t, path)
    page = report(folder, tmp_path / "r.html", worst=3)
    head, rows = table(page, "Runs per outcome")
    slow = next(r for r in rows if r[0] == "slow p")
    assert count_of(slow[head.index("diverged")]) == int(slow[2]) == 24
    assert count_of(slow[head.index("fails")]) == 24
    listed = _worst_rows(page, "slow p")
    assert [x[2] for x in listed] == ["diverged"] * 3
    assert [int(x[1]) for x in listed] == [0, 1, 2]  # all alike: by point
    _, itae = table(page, re.escape("ITAE [m s^2]"))
    assert next(r for r in itae if r[0] == "slow p")[1:] == ["0 (0 %)", "n/a", "n/a", "n/a",
                                                            "n/a"]


def test_partial_sweep_says_so(tmp_path: Path) -> None:
    class Stop(Exception):
        pass

    def stop(c: int) -> None:
        raise Stop

    with pytest.raises(Stop):
        sweep(MAIN, tmp_path / "sweep", on_chunk=stop)
    page = report(tmp_path / "sweep", tmp_path / "r.html")
    assert "PARTIAL SWEEP: 1 of 4 chunks" in page
    assert "This sweep is incomplete: 1 of 4 chunks are written (21 of 72 runs, 7 of 24 " \
           "points)" in page
    assert page.index("PARTIAL SWEEP") < page.index("Summary")
    head, rows = table(page, "Runs per outcome")
    assert sum(int(r[1]) for r in rows) == 21


def test_random_sweep_with_invalid_points(tmp_path: Path) -> None:
    folder = sweep(RANDOM, tmp_path / "sweep")
    page = report(folder, tmp_path / "r.html")
    rows = rows_of(folder)
    invalid_points = {r["point"] for r in rows if r["outcome"] == "invalid"}
    assert invalid_points  # the delays past the 1.5 s run
    assert min(r["delay"] for r in rows if r["outcome"] == "invalid") > \
        max(r["delay"] for r in rows if r["outcome"] != "invalid")
    head, tab = table(page, "Runs per outcome")
    for r in tab:
        assert int(r[head.index("invalid")]) == len(invalid_points)
        assert int(r[2]) == 60 - len(invalid_points)
    assert f"{len(invalid_points)} of the 60 points have no valid plant" in page
    reasons = [r for _, h, rr in tables(page) if h == ["reason", "points"] for r in rr]
    assert sum(int(r[1]) for r in reasons) == len(invalid_points)
    assert all("delay" in r[0] for r in reasons)
    # no grid: the maps are binned over the two quantities
    assert "Maps over load.mass and delay (the two quantities with the strongest effect" in page \
        or "Maps over delay and load.mass (the two quantities with the strongest effect" in page
    # the paired table compares the same valid points
    head, pairs = table(page, re.escape("Robust (settles within the overshoot limit) on the "
                                        "same point"))
    assert pairs[0][:3] == ["stfpi tuned", "pid tuned", str(60 - len(invalid_points))]


def test_one_controller_one_quantity(tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    folder = sweep(ONE, tmp_path / "sweep")
    out = tmp_path / "r.html"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["sweep-report", str(folder), "--out", str(out), "--worst", "50"]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {out}"
    page = out.read_text(encoding="utf-8")
    assert "Paired comparison" not in page
    assert "The sweep varies one quantity (with more than one value): no map over two" in page
    assert "per grid value or bin of each varied quantity" in page  # the 1-D plots
    listed = _worst_rows(page, "stfpi tuned")
    assert len(listed) == 12  # all of them, worst first
    assert len(re.findall(r"<img ", page)) == 4  # outcomes, distributions, 2 effects


def test_cli_not_a_sweep(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "empty").mkdir()
    for folder in (tmp_path / "missing", tmp_path / "empty"):
        assert main(["sweep-report", str(folder), "--out", str(tmp_path / "x.html")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("fuzzyservo: error: ")
        assert "is not a sweep folder" in err
    assert not (tmp_path / "x.html").exists()


def test_numbers_come_from_the_data(main_sweep: Path, main_report: str) -> None:
    """The distribution table's quantiles are numpy's over the defined values."""
    t = read_table(main_sweep, columns=["controller", "outcome", "itae"])
    ctl = np.array(t.column("controller").cast(pa.string()).to_pylist())
    itae = t.column("itae").to_numpy()
    _, rows = table(main_report, re.escape("ITAE [m s^2]"))
    for r in rows:
        v = itae[(ctl == r[0]) & np.isfinite(itae)]
        med, p90, p99 = np.quantile(v, (0.5, 0.9, 0.99))
        assert [float(x) for x in r[2:]] == pytest.approx([med, p90, p99, v.max()],
                                                          rel=5e-4)  # 4 digits shown
