"""The offline report of a sweep (``fuzzyservo sweep-report DIR --out report.html``).

The report reads only the columns it needs from the sweep's Parquet dataset, computes every
number with vectorised numpy (no Python loop over rows), draws its figures from binned
numbers (:mod:`fuzzyservo.plots.sweep_figures`) into a temporary folder, and writes one
self-contained HTML file in the study's look (:mod:`fuzzyservo.files.html`: figures
embedded as base64 PNG, nothing fetched). A sweep's controllers ran on the same points, so
every table and figure puts them side by side, and the paired comparisons compare them point
by point.

Sections: a banner when the sweep is partial (chunks written of the spec's); a summary;
outcomes and failure rates with the classification rules (:mod:`fuzzyservo.analysis.outcome`);
the distributions of the metrics; paired comparisons; the effect of each varied quantity; maps
of the failure rate and the ITAE over two varied quantities; the worst runs of each controller,
each with the ``fuzzyservo simulate`` command that replays it; invalid points; the sweep's
settings, variations and controllers.

Choices:

- rates count *valid* runs (a point without a valid plant is ``invalid`` for every controller
  and is left out of every rate, and counted apart);
- a run *fails* when it does not settle, ends in a limit cycle or diverges; it is *robust*
  when it settles with an overshoot within the limit (outcome ``settles``);
- a metric's statistics are over the runs where it is defined (finite): a run that never
  settles has no settling time, a diverged run no metric at all;
- paired comparisons rank a failing run's settling time, and an undefined metric, worse than
  any defined value; a tie is an equal value (two failures tie);
- worst runs: by outcome (diverged, limit cycle, not settled, overshoots, settles), then by
  the largest ITAE, then by point;
- the effect of a quantity is eta², the share of the variance (of failing, or of log10 ITAE)
  that its bins explain alone (a first-order sensitivity index); maps are drawn over the first
  two grid quantities, and over the two with the strongest effect on failing when they differ
  (with fewer than two grid quantities, only the latter);
- a grid quantity keeps its values; a drawn one is cut into equal bins between its smallest
  and largest valid value (logarithmic for log-uniform and log-normal draws), as many as
  leave about twice :data:`MIN_BIN_RUNS` runs in each; in the effect plots a bin of fewer
  than :data:`MIN_BIN_RUNS` runs is drawn hollow, in the maps such a cell is left out
  (hatched), and a map that would have no cell is not drawn.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._io import result_data_of
from .._typing import BoolArray, FloatArray, IntArray
from ..analysis.outcome import (
    LIMIT_CYCLE_MIN_PP,
    LIMIT_CYCLE_MIN_SUSTAIN,
    LIMIT_CYCLE_MIN_SWINGS,
    MAX_OVERSHOOT_PCT,
    OUTCOMES,
    TAIL_FRACTION,
)
from ..errors import InputError
from ..files.html import Figure, Section, Table, write_html
from ..plant.params import field_unit
from ..plots import sweep_figures as sf
from ..sim.stepinfo import SETTLE_HOLD_FRACTION
from .dataset import Manifest, finished_files, read_manifest, read_table
from .replay import simulate_command
from .spec import SweepSpec, Variation

__all__ = ["FAILURES", "METRICS", "MIN_BIN_RUNS", "WORST_ORDER", "SweepData", "load",
           "worst_runs", "write_report"]

#: Outcomes that count as a failure.
FAILURES: tuple[str, ...] = ("not settled", "limit cycle", "diverged")

#: Order of the worst runs: these outcomes first, worst first (then the largest ITAE).
WORST_ORDER: tuple[str, ...] = ("diverged", "limit cycle", "not settled", "overshoots",
                                "settles")

#: Metrics whose distributions the report shows: (column, name, unit).
METRICS: tuple[tuple[str, str, str], ...] = (
    ("settling_time", "settling time", "s"),
    ("overshoot", "overshoot", "%"),
    ("itae", "ITAE", "m s^2"),
    ("iae", "IAE", "m s"),
)

#: Fewest valid runs a bin (or map cell) of a drawn quantity needs to count as filled.
MIN_BIN_RUNS = 5

#: With more varied quantities than this, the worst runs' values are a table of their own.
_WORST_QUANTITIES_INLINE = 3

_COLUMNS_METRICS = ("settling_time", "overshoot", "itae", "iae", "tail_peak_to_peak")


# ---- reading ----------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class Quantity:
    """A varied quantity as the report shows it: ``display = SI value / scale``."""

    name: str  #: column name (as in the spec)
    label: str  #: axis and column label with unit
    scale: float  #: SI value per display unit
    log: bool  #: logarithmic axis
    var: Variation  #: the spec's variation


@dataclass(slots=True)
class SweepData:
    """The columns a report needs, as numpy arrays (one entry a row)."""

    spec: SweepSpec  #: the sweep's spec (from its manifest)
    manifest: Manifest  #: the manifest
    chunks_read: int  #: chunk files read
    labels: list[str]  #: controller labels, in the spec's order
    ctl: IntArray  #: controller index of each row
    outcome: IntArray  #: index into OUTCOMES of each row
    point: IntArray  #: point index of each row
    pos: IntArray  #: position of the row's point among the points read
    n_points: int  #: points read
    noise_seed: IntArray  #: noise seed of each row
    values: dict[str, FloatArray]  #: varied quantities [SI]
    metrics: dict[str, FloatArray]  #: metric columns [SI]
    error: Any  #: the ``error`` column (pyarrow), read for the invalid points only

    @property
    def n_rows(self) -> int:
        """Rows read."""
        return int(self.ctl.size)

    @property
    def valid(self) -> BoolArray:
        """Rows of valid points."""
        return np.asarray(self.outcome != OUTCOMES.index("invalid"))

    def is_outcome(self, *names: str) -> BoolArray:
        """Rows whose outcome is one of ``names``."""
        return np.isin(self.outcome, [OUTCOMES.index(n) for n in names])


def _codes(column: Any, names: Sequence[str], what: str) -> IntArray:
    """Index of each value of a (dictionary or string) column in ``names``."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if pa.types.is_dictionary(column.type):
        column = column.cast(pa.string())
    idx = pc.index_in(column, value_set=pa.array(list(names), type=pa.string()))
    if idx.null_count:
        bad = pc.filter(column, pc.is_null(idx))[0].as_py()
        raise InputError(f"the sweep's {what} column holds {bad!r}, which its spec does not "
                         f"know ({', '.join(names)})")
    return np.asarray(idx.to_numpy(zero_copy_only=False), dtype=np.int64)


def load(folder: str | Path) -> SweepData:
    """Read the columns the report needs from the sweep in ``folder``.

    Raises
    ------
    InputError
        ``folder`` is not a sweep folder, holds no finished chunk, or a chunk does not match
        its manifest's spec.
    """
    folder = Path(folder)
    man = read_manifest(folder)
    try:
        spec = SweepSpec.from_canonical(man.spec)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise InputError(f"{str(folder)!r}: the manifest's spec is not a sweep spec "
                         f"({exc})") from None
    names = [v.name for v in spec.vary]
    cols = ["point", "controller", "outcome", "noise_seed", *names, *_COLUMNS_METRICS]
    try:
        table = read_table(folder, columns=cols)
    except (KeyError, ValueError) as exc:  # pyarrow: a column missing from a chunk
        raise InputError(f"{str(folder)!r}: a chunk lacks a column the report reads "
                         f"({exc})") from None
    labels = [e.label for e in spec.controllers]
    ctl = _codes(table.column("controller"), labels, "controller")
    outcome = _codes(table.column("outcome"), OUTCOMES, "outcome")
    point = np.asarray(table.column("point").to_numpy(), dtype=np.int64)
    uniq, pos = np.unique(point, return_inverse=True)

    def floats(name: str) -> FloatArray:
        return np.asarray(table.column(name).to_numpy(), dtype=np.float64)

    invalid = outcome == OUTCOMES.index("invalid")
    error: Any = None
    if invalid.any():
        import pyarrow as pa

        keep = pa.array(invalid & (ctl == 0))
        error = read_table(folder, columns=["error"]).column("error").filter(keep)
    chunks_read = sum(1 for c in finished_files(folder) if c < man.n_chunks)
    return SweepData(
        spec=spec, manifest=man, chunks_read=chunks_read, labels=labels, ctl=ctl,
        outcome=outcome, point=point, pos=np.asarray(pos, dtype=np.int64).ravel(),
        n_points=int(uniq.size),
        noise_seed=np.asarray(table.column("noise_seed").to_numpy(), dtype=np.int64),
        values={n: floats(n) for n in names},
        metrics={n: floats(n) for n in _COLUMNS_METRICS}, error=error)


# ---- quantities -------------------------------------------------------------------------------

def _param_unit(name: str) -> str:
    """The unit of parameter ``group.field`` (:func:`fuzzyservo.plant.params.field_unit`)."""
    return field_unit(name)


def _quantity(spec: SweepSpec, var: Variation) -> Quantity:
    name = var.name
    if var.relative:
        nominal = spec.nominal_value(name)
        label, scale = f"{name}\n[× nominal {nominal:.4g} {_param_unit(name)}]", nominal
    elif name == "delay":
        label, scale = "delay [ms]", 1e-3
    elif name == "amplitude":
        label, scale = "step amplitude [mm]", 1e-3
    elif name == "noise_std":
        label, scale = "noise std [µm]", 1e-6
    elif name == "load_force_step":
        label, scale = "load-force step F [N]", 1.0
    else:
        label, scale = f"{name} [{_param_unit(name)}]", 1.0
    if var.is_grid:
        g = np.asarray(var.values, dtype=np.float64)
        log = bool(np.all(g > 0.0) and g.max() >= 10.0 * g.min())
    else:
        log = var.distribution in ("log-uniform", "log-normal")
    return Quantity(name=name, label=label, scale=scale, log=log, var=var)


@dataclass(frozen=True, slots=True)
class Binned:
    """A quantity cut into categories (grid values) or bins: ``index`` per row."""

    quantity: Quantity
    axis: sf.MapAxis
    index: IntArray

    @property
    def n(self) -> int:
        """Categories or bins."""
        return int(self.axis.centres.size)


def _bin(q: Quantity, si: FloatArray, bins: int, valid: BoolArray) -> Binned:
    """Grid values as categories; drawn values in ``bins`` equal bins (in log for a
    logarithmic quantity) between the smallest and the largest value of the ``valid`` rows
    (the others fall into the end bins and are never counted)."""
    x = si / q.scale
    empty = np.zeros(0)
    xv = x[valid]
    if q.var.is_grid:
        cats = np.unique(xv if xv.size else x)
        idx = np.clip(np.searchsorted(cats, x), 0, max(cats.size - 1, 0))
        return Binned(q, sf.MapAxis(label=q.label, centres=cats, edges=empty, log=q.log),
                      idx.astype(np.int64))
    lo, hi = (float(xv.min()), float(xv.max())) if xv.size else (0.0, 1.0)
    log = q.log and lo > 0.0
    if not hi > lo:
        bins = 1
        hi = lo + (abs(lo) or 1.0) * 1e-9
    if log:
        edges = np.geomspace(lo, hi, bins + 1)
        centres = np.sqrt(edges[:-1] * edges[1:])
    else:
        edges = np.linspace(lo, hi, bins + 1)
        centres = (edges[:-1] + edges[1:]) / 2.0
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)
    return Binned(q, sf.MapAxis(label=q.label, centres=centres, edges=edges, log=log),
                  idx.astype(np.int64))


# ---- statistics (vectorised) ------------------------------------------------------------------

def _quantiles(x: FloatArray, qs: Sequence[float]) -> list[float]:
    """Quantiles of the finite values of ``x`` (NaN for none)."""
    f = x[np.isfinite(x)]
    if f.size == 0:
        return [math.nan] * len(qs)
    return [float(v) for v in np.quantile(f, qs)]


def _finite_order(values: FloatArray) -> IntArray:
    """Indices of the finite ``values``, in increasing order of value (sorted once, then
    reused by every :func:`_group_median` of the same values)."""
    ok = np.flatnonzero(np.isfinite(values))
    return np.asarray(ok[np.argsort(values[ok], kind="stable")], dtype=np.int64)


def _group_median(groups: IntArray, values: FloatArray, n_groups: int,
                  order: IntArray | None = None) -> tuple[FloatArray, IntArray]:
    """Median of the finite ``values`` in each group 0..n_groups-1 (a negative group leaves
    a value out; NaN for a group without values), and the count of values per group.

    ``order`` is :func:`_finite_order` of ``values`` (computed here when not given): a stable
    sort of the groups in value order (a radix sort of small integers) leaves each group's
    values sorted, with no loop over groups.
    """
    if order is None:
        order = _finite_order(values)
    g = groups[order]
    keep = g >= 0
    rows, g = order[keep], g[keep]
    p = np.argsort(g, kind="stable")
    g, v = g[p], values[rows[p]]
    counts = np.bincount(g, minlength=n_groups).astype(np.int64)
    starts = np.cumsum(counts) - counts
    med = np.full(n_groups, np.nan)
    has = counts > 0
    lo = starts[has] + (counts[has] - 1) // 2
    hi = starts[has] + counts[has] // 2
    med[has] = (v[lo] + v[hi]) / 2.0
    return med, counts


def _shares(num: FloatArray | IntArray, den: FloatArray | IntArray, min_den: int = 1
            ) -> FloatArray:
    """num / den where den >= min_den (and > 0), NaN elsewhere."""
    num = np.asarray(num, dtype=np.float64)
    den = np.asarray(den, dtype=np.float64)
    out = np.full(np.broadcast(num, den).shape, np.nan)
    ok = den >= max(min_den, 1)
    np.divide(num, den, out=out, where=ok)
    return out


def _eta2(groups: IntArray, y: FloatArray, n_groups: int) -> float:
    """Share of the variance of ``y`` (finite values) explained by the group means (eta²;
    NaN when ``y`` does not vary: nothing to explain)."""
    ok = np.isfinite(y)
    g, v = groups[ok], y[ok]
    if v.size < 2:
        return math.nan
    mean = float(v.mean())
    total = float(np.sum((v - mean) ** 2))
    if not total > 0.0:
        return math.nan
    n = np.bincount(g, minlength=n_groups).astype(np.float64)
    s = np.bincount(g, weights=v, minlength=n_groups)
    means = _shares(s, n)
    between = float(np.nansum(n * (np.nan_to_num(means, nan=mean) - mean) ** 2))
    return min(1.0, between / total)


def _mean_finite(x: Sequence[float]) -> float:
    """Mean of the finite values (0 when there is none)."""
    a = np.asarray(x, dtype=np.float64)
    a = a[np.isfinite(a)]
    return float(a.mean()) if a.size else 0.0


def _log10_positive(x: FloatArray) -> FloatArray:
    out = np.full(x.shape, np.nan)
    ok = np.isfinite(x) & (x > 0.0)
    out[ok] = np.log10(x[ok])
    return out


# ---- text helpers -----------------------------------------------------------------------------

def _pct(x: float) -> str:
    return "n/a" if not math.isfinite(x) else f"{100.0 * x:.3g} %"


def _count_pct(n: int, total: int) -> str:
    return f"{n} ({_pct(n / total) if total else 'n/a'})"


def _plural(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"


def _num(x: float) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:.4g}"


def _rules(spec: SweepSpec) -> list[str]:
    """The classification rules (:mod:`fuzzyservo.analysis.outcome`), with this sweep's
    numbers."""
    band = 2.0  # the settling band, % of the step (sweeps use simulate's metric options)
    hold = SETTLE_HOLD_FRACTION * 100.0
    tail = TAIL_FRACTION * 100.0
    return [
        "diverged: the state became non-finite (no metric is defined).",
        f"limit cycle: the tail (last {tail:g} % of the run) swings at least "
        f"{LIMIT_CYCLE_MIN_SWINGS} times, peak to peak at least {LIMIT_CYCLE_MIN_PP * 100:g} % "
        f"of the step, and does not die out (the second half's peak-to-peak is at least "
        f"{LIMIT_CYCLE_MIN_SUSTAIN:g} of the first half's).",
        f"not settled: never inside the {band:g} % band for good (the response is outside it "
        f"in the last {hold:g} % of the run: no settling time).",
        f"overshoots: settles, but overshoots more than {MAX_OVERSHOOT_PCT:g} %.",
        f"settles: settles with an overshoot of at most {MAX_OVERSHOOT_PCT:g} %: the run is "
        f"robust.",
        "invalid: the point has no valid plant (a drawn parameter out of its range, no "
        "equilibrium, a delay longer than the run, a reference out of the stroke); left out "
        "of every rate and counted apart.",
        "A run takes the first of these that applies, in the order invalid, diverged, limit "
        "cycle, not settled, overshoots, settles. A run fails when it is not settled, in a "
        "limit cycle or diverged.",
    ]


def _variation_text(q: Quantity) -> str:
    v = q.var
    unit = " (× nominal)" if v.relative else " [SI]"
    if v.is_grid:
        return "grid: " + ", ".join(f"{x:.4g}" for x in v.values) + unit
    return v.distribution + ": " + ", ".join(f"{k} {x:.4g}" for k, x in v.args) + unit


# ---- sections ---------------------------------------------------------------------------------

@dataclass(slots=True)
class _Report:
    d: SweepData
    tmp: Path
    quantities: list[Quantity]
    itae_order: IntArray  #: :func:`_finite_order` of the ITAE column

    @property
    def labels(self) -> list[str]:
        return self.d.labels

    def fig(self, figure: Any, stem: str, caption: str) -> Figure:
        path = sf.save_png(figure, self.tmp / f"{stem}.png")
        return Figure(path, caption)

    # -- counts ----------------------------------------------------------------------------
    def outcome_counts(self) -> IntArray:
        """(controllers, outcomes) counts."""
        n_c, n_o = len(self.labels), len(OUTCOMES)
        flat = np.bincount(self.d.ctl * n_o + self.d.outcome, minlength=n_c * n_o)
        return flat.reshape(n_c, n_o).astype(np.int64)


def _partial_section(d: SweepData, folder: Path) -> Section | None:
    man = d.manifest
    if d.chunks_read >= man.n_chunks:
        return None
    spec_file = folder / "spec.toml"
    how = (f"Continue it with: fuzzyservo sweep {spec_file} --out {folder} --resume."
           if spec_file.is_file() else "Continue it with fuzzyservo sweep SPEC.toml --out "
                                       f"{folder} --resume.")
    return Section(
        f"PARTIAL SWEEP: {d.chunks_read} of {man.n_chunks} chunks",
        summary=(f"This sweep is incomplete: {d.chunks_read} of {man.n_chunks} chunks are "
                 f"written ({d.n_rows} of {man.n_runs} runs, {d.n_points} of "
                 f"{man.n_points} points). Every number and figure below covers only these "
                 f"runs."),
        paragraphs=[how])


def _summary_section(r: _Report, counts: IntArray, paired: dict[str, FloatArray],
                     ranked: list[tuple[Quantity, float, float]]) -> Section:
    d, spec = r.d, r.d.spec
    valid = counts[:, :OUTCOMES.index("invalid")].sum(axis=1)
    robust = counts[:, OUTCOMES.index("settles")]
    fails = counts[:, [OUTCOMES.index(o) for o in FAILURES]].sum(axis=1)
    n_ctl = len(r.labels)
    parts = [f"{d.n_rows} runs: {_plural(d.n_points, 'point')} x "
             f"{_plural(n_ctl, 'controller')} on the {spec.plant} plant, {spec.duration:g} s "
             f"each" + (f" (partial: {d.chunks_read} of {d.manifest.n_chunks} chunks)."
                        if d.chunks_read < d.manifest.n_chunks else ".")]
    n_invalid = int(counts[0, OUTCOMES.index("invalid")]) if n_ctl else 0
    if n_invalid:
        parts.append(f"{n_invalid} of the {d.n_points} points have no valid plant and are left "
                     f"out of every rate.")
    if int(valid.max(initial=0)) == 0:
        parts.append("No run is valid: there is nothing to compare.")
        return Section("Summary", summary=" ".join(parts))
    order = sorted(range(n_ctl), key=lambda k: (-robust[k] / max(valid[k], 1), k))
    parts.append("Robust runs (settles within the overshoot limit), of valid runs: "
                 + ", ".join(f"{r.labels[k]} {_pct(robust[k] / valid[k])}" for k in order)
                 + ".")
    parts.append("Failures (not settled, limit cycle or diverged): "
                 + ", ".join(f"{r.labels[k]} {_pct(fails[k] / valid[k])}" for k in order)
                 + ".")
    if n_ctl > 1:
        best = order[0]
        for k in order[1:]:
            parts.append(f"On the same points, {r.labels[best]} settles sooner than "
                         f"{r.labels[k]} on {_pct(paired['settling time'][best, k])} and has "
                         f"a lower ITAE on {_pct(paired['ITAE'][best, k])} (the reverse: "
                         f"{_pct(paired['settling time'][k, best])}, "
                         f"{_pct(paired['ITAE'][k, best])}).")
    if ranked and ranked[0][1] > 0.0:
        q, e_fail, _ = ranked[0]
        parts.append(f"Of the varied quantities, {q.name} has the strongest effect on failing "
                     f"(eta² = {e_fail:.2g}, the mean over the controllers whose failures "
                     f"vary; see 'Effect of each varied quantity').")
    return Section("Summary", summary=" ".join(parts))


def _outcome_section(r: _Report, counts: IntArray) -> Section:
    n_inv = OUTCOMES.index("invalid")
    valid = counts[:, :n_inv].sum(axis=1)
    fail_idx = [OUTCOMES.index(o) for o in FAILURES]
    rows: list[list[object]] = []
    for k, lab in enumerate(r.labels):
        v = int(valid[k])
        rows.append([lab, int(counts[k].sum()), v]
                    + [_count_pct(int(counts[k, j]), v) for j in range(n_inv)]
                    + [_count_pct(int(counts[k, fail_idx].sum()), v), int(counts[k, n_inv])])
    header = ["controller", "runs", "valid runs", *OUTCOMES[:n_inv], "fails", "invalid"]
    shares = _shares(counts[:, :n_inv], valid[:, None])
    figs = []
    if int(valid.sum()) > 0:
        figs.append(r.fig(
            sf.outcomes_figure(r.labels, OUTCOMES[:n_inv], np.nan_to_num(shares),
                               "Outcome of each run, per controller"),
            "outcomes", "Share of each outcome among each controller's valid runs (the same "
                        "points for every controller)."))
    return Section(
        "Outcomes and failure rates",
        paragraphs=["How each run is classified (fuzzyservo.sweep.run):"],
        items=_rules(r.d.spec),
        tables=[Table(header, rows, caption="Runs per outcome, count (share of the "
                                            "controller's valid runs); fails = not settled + "
                                            "limit cycle + diverged")],
        figures=figs)


def _distribution_section(r: _Report) -> Section:
    d = r.d
    valid = d.valid
    tables = []
    panels = []
    for col, name, unit in METRICS:
        x = d.metrics[col]
        rows: list[list[object]] = []
        xs, ys, defined = [], [], []
        for k, lab in enumerate(r.labels):
            sel = valid & (d.ctl == k)
            n = int(sel.sum())
            vals = x[sel]
            fin = np.sort(vals[np.isfinite(vals)])
            med, p90, p99 = _quantiles(fin, (0.5, 0.9, 0.99))
            mx = float(fin[-1]) if fin.size else math.nan
            rows.append([lab, _count_pct(int(fin.size), n), med, p90, p99, mx])
            # at most 400 steps of the empirical CDF, as fractions of all the valid runs
            if fin.size:
                take = np.unique(np.linspace(0, fin.size - 1, min(fin.size, 400)).astype(int))
                xs.append(fin[take])
                ys.append((take + 1.0) / n)
            else:
                xs.append(np.zeros(0))
                ys.append(np.zeros(0))
            defined.append(fin.size / n if n else 0.0)
        allv = np.concatenate(xs) if xs else np.zeros(0)
        log = bool(allv.size and allv.min() > 0.0 and allv.max() >= 100.0 * allv.min())
        panels.append(sf.Distribution(label=f"{name} [{unit}]", x=tuple(xs), y=tuple(ys),
                                      defined=tuple(defined), log=log))
        tables.append(Table(["controller", "defined in (of valid runs)", f"median [{unit}]",
                             f"p90 [{unit}]", f"p99 [{unit}]", f"max [{unit}]"], rows,
                            caption=f"{name} [{unit}]"))
    figs = []
    if int(valid.sum()) > 0:
        figs.append(r.fig(sf.distributions_figure(r.labels, panels,
                                                  "Distributions of the metrics"),
                          "distributions",
                          "Empirical CDFs: the share of each controller's valid runs at or "
                          "below a value. A curve ends below 100 % by the share of runs "
                          "where the metric is undefined (no settling time for a run that "
                          "does not settle, no metric for a diverged run)."))
    return Section(
        "Distributions of the metrics",
        paragraphs=["Statistics over the valid runs where the metric is defined (finite); "
                    "'defined in' counts them. Quantiles by linear interpolation."],
        tables=tables, figures=figs)


def _paired(r: _Report) -> tuple[dict[str, FloatArray], list[Table]]:
    """Win matrices (share of the valid points where row is better than column) and the
    pair tables."""
    d = r.d
    n_ctl, n_pts = len(r.labels), d.n_points
    fail = d.is_outcome(*FAILURES)
    robust = d.is_outcome("settles")

    def pivot(v: FloatArray | BoolArray, fill: float) -> FloatArray:
        m = np.full((n_ctl, n_pts), fill)
        m[d.ctl, d.pos] = v
        return m

    valid_pt = np.zeros(n_pts, dtype=bool)
    valid_pt[d.pos[d.valid]] = True
    settle = np.where(fail | ~np.isfinite(d.metrics["settling_time"]), np.inf,
                      d.metrics["settling_time"])
    itae = np.where(np.isfinite(d.metrics["itae"]), d.metrics["itae"], np.inf)
    mats = {"settling time": pivot(settle, np.inf)[:, valid_pt],
            "ITAE": pivot(itae, np.inf)[:, valid_pt]}
    rob = pivot(robust.astype(np.float64), 0.0)[:, valid_pt] > 0.5
    n_valid = int(valid_pt.sum())
    wins = {}
    for name, m in mats.items():
        w = np.full((n_ctl, n_ctl), np.nan)
        for i in range(n_ctl):
            for j in range(n_ctl):
                if i != j and n_valid:
                    w[i, j] = float(np.count_nonzero(m[i] < m[j])) / n_valid
        wins[name] = w
    pairs = [(i, j) for i in range(n_ctl) for j in range(i + 1, n_ctl)]
    rob_rows: list[list[object]] = []
    rows = {name: [] for name in mats}  # type: dict[str, list[list[object]]]
    for i, j in pairs:
        a, b = r.labels[i], r.labels[j]
        both = int(np.count_nonzero(rob[i] & rob[j]))
        only_a = int(np.count_nonzero(rob[i] & ~rob[j]))
        only_b = int(np.count_nonzero(~rob[i] & rob[j]))
        neither = n_valid - both - only_a - only_b
        rob_rows.append([a, b, n_valid] + [_count_pct(x, n_valid)
                                           for x in (both, only_a, only_b, neither)])
        for name, m in mats.items():
            better = int(np.count_nonzero(m[i] < m[j]))
            worse = int(np.count_nonzero(m[i] > m[j]))
            equal = n_valid - better - worse
            fin = np.isfinite(m[i]) & np.isfinite(m[j]) & (m[i] > 0.0)
            ratio = (float(np.median(m[j][fin] / m[i][fin])) if fin.any() else math.nan)
            rows[name].append([a, b, n_valid, _count_pct(better, n_valid),
                               _count_pct(equal, n_valid), _count_pct(worse, n_valid),
                               ratio, int(fin.sum())])
    tables = [Table(["A", "B", "valid points", "both robust", "only A robust",
                     "only B robust", "neither"], rob_rows,
                    caption="Robust (settles within the overshoot limit) on the same point")]
    words = {"settling time": ("A settles sooner", "equal", "B settles sooner"),
             "ITAE": ("A lower", "equal", "B lower")}
    for name, rr in rows.items():
        tables.append(Table(["A", "B", "valid points", *words[name],
                             "median B/A", "points with both defined"], rr,
                            caption=f"{name}: a failing run (not settled, limit cycle, "
                                    f"diverged) never settles; an undefined value is worse "
                                    f"than any" if name == "settling time" else
                            f"{name}: an undefined value (diverged) is worse than any; "
                            f"median B/A over the points where both are defined"))
    return wins, tables


def _paired_section(r: _Report, wins: dict[str, FloatArray], tables: list[Table]
                    ) -> Section:
    if not any(np.isfinite(w).any() for w in wins.values()):  # no valid point
        return Section("Paired comparison", paragraphs=["No valid point: nothing to compare."])
    figs = [r.fig(sf.paired_figure(r.labels, list(wins.items()),
                                   "Paired comparison on the same points"),
                  "paired", "Share of the valid points where the row's controller is better "
                            "than the column's (sooner settling; lower ITAE). The rest are "
                            "ties (e.g. both fail) or the column's wins.")]
    return Section(
        "Paired comparison",
        paragraphs=["Every controller ran on the same points (plant, delay, amplitude, noise "
                    "and its seed), so they are compared point by point: A and B are the "
                    "controllers of each row."],
        tables=tables, figures=figs)


def _bins_1d(n_valid_points: int) -> int:
    """Bins of a drawn quantity in the effect plots: about sqrt(n / 5), at most 20, and at
    least two :data:`MIN_BIN_RUNS` runs per bin on average (never fewer than 2 bins)."""
    n = max(n_valid_points, 1)
    return int(np.clip(min(round(math.sqrt(n / 5.0)), n // (2 * MIN_BIN_RUNS)), 2, 20))


def _map_bins(n_valid_points: int, n_categories: int | None) -> int:
    """Bins of a drawn quantity in a map beside a grid of ``n_categories`` values (None:
    beside another drawn quantity, cut into as many bins): two :data:`MIN_BIN_RUNS` runs per
    cell on average, at most 16; 0 when even 2 bins would have fewer."""
    per_cell = 2 * MIN_BIN_RUNS
    if n_categories is None:
        nb = int(math.isqrt(max(n_valid_points, 0) // per_cell))
    else:
        nb = max(n_valid_points, 0) // (per_cell * max(n_categories, 1))
    return min(nb, 16) if nb >= 2 else 0


def _effects(r: _Report) -> tuple[list[tuple[Quantity, float, float]], Section | None]:
    """eta² of each quantity (mean over controllers; fails, then log10 ITAE), ranked, and
    the effects section."""
    d = r.d
    valid = d.valid
    n_ctl = len(r.labels)
    qs = [q for q in r.quantities if np.unique(d.values[q.name][valid]).size > 1]
    if not qs:
        return [], None
    n_valid_pts = int(np.count_nonzero(valid & (d.ctl == 0)))
    fail = d.is_outcome(*FAILURES).astype(np.float64)
    litae = _log10_positive(d.metrics["itae"])
    scored = []
    axes, fail_vals, itae_vals, sparse = [], [], [], []
    eta_rows: list[list[object]] = []
    eta_itae_rows: list[list[object]] = []
    for q in qs:
        b = _bin(q, d.values[q.name], _bins_1d(n_valid_pts), valid)
        e_f, e_i = [], []
        fv = np.full((n_ctl, b.n), np.nan)
        for k in range(n_ctl):
            sel = valid & (d.ctl == k)
            g = b.index[sel]
            e_f.append(_eta2(g, fail[sel], b.n))
            e_i.append(_eta2(g, litae[sel], b.n))
            n = np.bincount(g, minlength=b.n)
            fv[k] = _shares(np.bincount(g, weights=fail[sel], minlength=b.n), n)
        groups = np.where(valid, d.ctl * b.n + b.index, -1)
        iv = _group_median(groups, d.metrics["itae"], n_ctl * b.n,
                           r.itae_order)[0].reshape(n_ctl, b.n)
        # the same points for every controller: the runs per bin are the first's
        runs = np.bincount(b.index[valid & (d.ctl == 0)], minlength=b.n)
        sparse.append(runs < (1 if q.var.is_grid else MIN_BIN_RUNS))
        scored.append((q, _mean_finite(e_f), _mean_finite(e_i)))
        eta_rows.append([q.name, *e_f])
        eta_itae_rows.append([q.name, *e_i])
        axes.append(b.axis)
        fail_vals.append(fv)
        itae_vals.append(iv)
    order = sorted(range(len(scored)), key=lambda i: (-scored[i][1], -scored[i][2], i))
    ranked = [scored[i] for i in order]
    figs = [
        r.fig(sf.effects_figure(r.labels, axes, [v * 100.0 for v in fail_vals],
                                sparse=sparse, ylabel="runs that fail [%]", ylim=(-3.0, 103.0),
                                title="Failures against each varied quantity"),
              "effects_fail",
              "Share of the valid runs that fail (not settled, limit cycle, diverged) per "
              "grid value or bin of each varied quantity, all other quantities varying as "
              f"drawn; a hollow marker is a bin of fewer than {MIN_BIN_RUNS} runs."),
        r.fig(sf.effects_figure(r.labels, axes, itae_vals, sparse=sparse,
                                ylabel="median ITAE [m s^2]", log_y=True,
                                title="ITAE against each varied quantity"),
              "effects_itae",
              "Median ITAE of the valid runs (where defined) per grid value or bin of each "
              f"varied quantity; a hollow marker is a bin of fewer than {MIN_BIN_RUNS} "
              f"runs."),
    ]
    sec = Section(
        "Effect of each varied quantity",
        paragraphs=["eta² is the share of the variance across a controller's valid runs (of "
                    "failing, or of log10 ITAE) that a quantity's grid values or bins explain "
                    "alone: 0 no effect, 1 it decides alone; n/a where the controller fails on "
                    "every run or on none (or its ITAE does not vary).",
                    "Quantities ranked by their effect on failing (eta², mean over the "
                    "controllers where it is defined; ties by the effect on ITAE): "
                    + ", ".join(f"{q.name} ({e:.2g})" for q, e, _ in ranked) + "."],
        tables=[Table(["quantity", *r.labels], eta_rows,
                      caption="Effect on failing (eta² per controller)"),
                Table(["quantity", *r.labels], eta_itae_rows,
                      caption="Effect on log10 ITAE (eta² per controller)")],
        figures=figs)
    return ranked, sec


def _map_figures(r: _Report, qx: Quantity, qy: Quantity, why: str
                 ) -> tuple[list[Figure], str]:
    """The failure and ITAE maps over ``qx`` and ``qy``, or none and why not."""
    d = r.d
    valid = d.valid
    n_ctl = len(r.labels)
    n_valid_pts = int(np.count_nonzero(valid & (d.ctl == 0)))
    grid_n = {q.name: int(np.unique(d.values[q.name][valid]).size) for q in (qx, qy)
              if q.var.is_grid}
    nb = 0
    if len(grid_n) < 2:
        nb = _map_bins(n_valid_pts, next(iter(grid_n.values()), None))
        if nb == 0:
            return [], (f"No map over {qx.name} and {qy.name}: {n_valid_pts} valid points are "
                        f"too few to fill its cells with {MIN_BIN_RUNS} runs each.")
    bx = _bin(qx, d.values[qx.name], nb, valid)
    by = _bin(qy, d.values[qy.name], nb, valid)
    min_runs = 1 if len(grid_n) == 2 else MIN_BIN_RUNS
    n_cells = bx.n * by.n
    cell = by.index * bx.n + bx.index
    g = d.ctl * n_cells + cell
    total = n_ctl * n_cells
    fail = d.is_outcome(*FAILURES)
    n = np.bincount(g[valid], minlength=total)
    nf = np.bincount(g[valid & fail], minlength=total)
    share = _shares(nf, n, min_runs).reshape(n_ctl, by.n, bx.n)
    med, cnt = _group_median(np.where(valid, g, -1), d.metrics["itae"], total, r.itae_order)
    med = np.where(cnt >= min_runs, med, np.nan).reshape(n_ctl, by.n, bx.n)
    stem = f"map_{qx.name}_{qy.name}".replace(".", "_")
    hatched = (f" Hatched: cells with fewer than {min_runs} valid runs." if min_runs > 1 else
               " Hatched: cells without a valid run.")
    figs = []
    if np.isfinite(share).any():
        figs.append(r.fig(
            sf.map_figure(r.labels, bx.axis, by.axis, share, label="runs that fail",
                          title=f"Failures over {qx.name} and {qy.name}", vmin=0.0, vmax=1.0,
                          cmap="Reds", percent=True),
            f"{stem}_fail",
            f"Share of the valid runs that fail (not settled, limit cycle, diverged) over "
            f"{qx.name} and {qy.name} ({why}), the other quantities varying as drawn; one "
            f"colour scale for all controllers.{hatched}"))
    positive = np.isfinite(med) & (med > 0.0)
    if positive.any():
        figs.append(r.fig(
            sf.map_figure(r.labels, bx.axis, by.axis, np.where(positive, med, np.nan),
                          label="median ITAE [m s^2]", log=True, cmap="viridis",
                          title=f"Median ITAE over {qx.name} and {qy.name}"),
            f"{stem}_itae",
            f"Median ITAE of the valid runs (where defined) over {qx.name} and {qy.name}; "
            f"one logarithmic colour scale for all controllers.{hatched}"))
    if not figs:
        return [], (f"No map over {qx.name} and {qy.name}: no cell holds {min_runs} valid "
                    f"runs.")
    return figs, ""


def _maps_section(r: _Report, ranked: list[tuple[Quantity, float, float]]) -> Section:
    grids = [q for q in r.quantities if q.var.is_grid
             and np.unique(r.d.values[q.name][r.d.valid]).size > 1]
    pairs: list[tuple[Quantity, Quantity, str]] = []
    if len(grids) >= 2:
        pairs.append((grids[0], grids[1], "the sweep's first two grid quantities"))
    if len(ranked) >= 2:
        strongest = (ranked[0][0], ranked[1][0])
        if not pairs or {q.name for q in strongest} != {pairs[0][0].name, pairs[0][1].name}:
            pairs.append((*strongest, "the two quantities with the strongest effect on "
                                      "failing"))
    if not r.d.valid.any():
        return Section("Robustness maps", paragraphs=["No valid run: nothing to map."])
    if not pairs:
        n = len(ranked)
        return Section("Robustness maps", paragraphs=[
            f"The sweep varies {'one quantity' if n == 1 else 'no quantity'} (with more than "
            f"one value): no map over two; "
            + ("its effect is drawn above." if n == 1 else "nothing to draw.")])
    figs: list[Figure] = []
    notes: list[str] = []
    for qx, qy, why in pairs:
        f, note = _map_figures(r, qx, qy, why)
        figs.extend(f)
        if note:
            notes.append(note)
    return Section(
        "Robustness maps",
        paragraphs=["Maps over " + "; ".join(f"{qx.name} and {qy.name} ({why})"
                                             for qx, qy, why in pairs)
                    + ". Grid quantities keep their values; drawn ones are cut into equal "
                      "bins (logarithmic for log-uniform and log-normal draws).", *notes],
        figures=figs)


def worst_runs(d: SweepData, k: int, n: int) -> IntArray:
    """Rows of the ``n`` worst valid runs of controller ``k``: by outcome
    (:data:`WORST_ORDER`), then the largest ITAE (an undefined ITAE first), then the point."""
    rows = np.flatnonzero((d.ctl == k) & d.valid)
    if rows.size == 0:
        return rows.astype(np.int64)
    rank = np.full(len(OUTCOMES), len(WORST_ORDER))
    for i, name in enumerate(WORST_ORDER):
        rank[OUTCOMES.index(name)] = i
    itae = d.metrics["itae"][rows]
    neg = -np.where(np.isfinite(itae), itae, np.inf)
    order = np.lexsort((d.point[rows], neg, rank[d.outcome[rows]]))
    return np.asarray(rows[order[:n]], dtype=np.int64)


def _worst_section(r: _Report, n_worst: int) -> Section:
    d, spec = r.d, r.d.spec
    n_ctl = len(r.labels)
    outcome_at = np.full((n_ctl, d.n_points), -1)
    outcome_at[d.ctl, d.pos] = d.outcome
    tables = []
    for k, lab in enumerate(r.labels):
        rows = worst_runs(d, k, n_worst)
        n_valid = int(np.count_nonzero((d.ctl == k) & d.valid))
        body: list[list[object]] = []
        where: list[list[object]] = []
        commands: list[list[object]] = []
        for rank, i in enumerate(rows, start=1):
            row: dict[str, Any] = {"controller": lab, "noise_seed": int(d.noise_seed[i])}
            row.update({q.name: float(d.values[q.name][i]) for q in r.quantities})
            others = "; ".join(f"{r.labels[j]}: {OUTCOMES[int(outcome_at[j, d.pos[i]])]}"
                               for j in range(n_ctl)
                               if j != k and outcome_at[j, d.pos[i]] >= 0)
            body.append([rank, int(d.point[i]), OUTCOMES[int(d.outcome[i])],
                         float(d.metrics["itae"][i]), float(d.metrics["overshoot"][i]),
                         float(d.metrics["settling_time"][i]),
                         float(d.metrics["tail_peak_to_peak"][i]) * 1e3,
                         *([others] if n_ctl > 1 else [])])
            where.append([rank, *[float(d.values[q.name][i]) / q.scale for q in r.quantities]])
            commands.append([rank, simulate_command(spec, row)])
        header = ["#", "point", "outcome", "ITAE [m s^2]", "overshoot [%]",
                  "settling time [s]", "tail peak-to-peak [mm]",
                  *(["other controllers at this point"] if n_ctl > 1 else [])]
        vary_header = [q.label for q in r.quantities]
        split = len(r.quantities) > _WORST_QUANTITIES_INLINE
        if not split:  # few quantities: one table
            header += vary_header
            body = [b + w[1:] for b, w in zip(body, where, strict=True)]
        tables.append(Table(header, body, caption=(
            f"{lab}: the {rows.size} worst of its {n_valid} valid runs" if rows.size else
            f"{lab}: no valid run")))
        if split and where:
            tables.append(Table(["#", *vary_header], where,
                                caption=f"{lab}: where these runs are (the varied quantities)"))
        if commands:
            tables.append(Table(["#", "replay (copy into a shell)"], commands,
                                caption=f"{lab}: the commands that replay these runs"))
    return Section(
        "Worst runs",
        paragraphs=[
            "Per controller, its worst valid runs: failures first (diverged, then limit "
            "cycle, then not settled), then overshoots, then the rest; within each outcome "
            "the largest ITAE first (an undefined ITAE before any), then the lowest point. "
            "Each command replays the run with fuzzyservo simulate and prints its metrics "
            "(6 significant digits); the values in the table are rounded to 4."],
        tables=tables)


def _invalid_section(d: SweepData) -> Section | None:
    if d.error is None or len(d.error) == 0:
        return None
    import pyarrow.compute as pc

    counts = pc.value_counts(d.error).to_pylist()
    counts.sort(key=lambda c: (-int(c["counts"]), str(c["values"])))
    rows: list[list[object]] = [[str(c["values"]), int(c["counts"])] for c in counts[:20]]
    more = (f" (the {len(counts) - 20} other reasons are not shown)" if len(counts) > 20
            else "")
    return Section("Invalid points", paragraphs=[
        f"{len(d.error)} of the {d.n_points} points have no valid plant; no controller ran "
        f"on them{more}."],
        tables=[Table(["reason", "points"], rows)])


def _sweep_section(r: _Report) -> Section:
    d, spec = r.d, r.d.spec
    settings: list[list[object]] = [
        ["plant", spec.plant], ["parameter set", spec.param_set],
        ["fixed overrides", ", ".join(f"{k} = {v:.6g}" for k, v in spec.overrides) or "none"],
        ["start [fraction of the stroke]", spec.start], ["controller sample time [s]", spec.ts],
        ["duration of a run [s]", spec.duration], ["reference", spec.reference],
        ["nominal delay [s]", spec.delay], ["nominal noise std [m]", spec.noise_std],
        ["samples per grid cell", spec.samples], ["seed", spec.seed],
        ["points per chunk", spec.chunk]]
    if spec.plant == "nonlinear":
        settings.insert(6, ["RK4 substep [s]", spec.substep])
    vrows: list[list[object]] = []
    for q in r.quantities:
        x = d.values[q.name] / q.scale
        vrows.append([q.name, _variation_text(q), q.label,
                      float(x.min()) if x.size else math.nan,
                      float(x.max()) if x.size else math.nan])
    crows: list[list[object]] = [
        [e.label, e.controller, ", ".join(f"{k} = {v:.6g}" for k, v in e.gains),
         ", ".join(f"{k} = {v}" for k, v in e.options) or "none",
         ", ".join(f"{role}: {Path(p).name}" for role, p in e.systems) or "default"]
        for e in spec.controllers]
    return Section("The sweep", tables=[
        Table(["setting", "value"], settings, caption="Settings"),
        Table(["quantity", "variation", "shown as", "smallest", "largest"], vrows,
              caption="Varied quantities (smallest and largest value among the runs read)")
        if vrows else Table(["quantity"], [["nothing is varied"]], caption="Varied quantities"),
        Table(["label", "controller", "gains", "options", "fuzzy systems"], crows,
              caption="Controllers, in the spec's order (the colour order of the figures)")])


# ---- entry point ------------------------------------------------------------------------------

def write_report(folder: str | Path, out: str | Path, *, worst: int = 10) -> Path:
    """Write the offline HTML report of the sweep in ``folder`` to ``out`` (atomically).

    Parameters
    ----------
    folder : path
        The sweep's folder (``fuzzyservo sweep --out``), complete or partial.
    out : path
        The report file.
    worst : int
        Worst runs listed per controller.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    InputError
        ``folder`` is not a sweep, or holds no finished chunk.
    OutputError
        ``out`` cannot be written.
    """
    if isinstance(worst, bool) or not isinstance(worst, int) or worst < 1:
        raise InputError(f"worst must be a positive integer, got {worst!r}")
    folder = Path(folder)
    # the API as the CLI: a report never replaces a sweep's own data (a study writes its
    # sweeps' reports among its own listed outputs: those the study's own checks guard)
    why = result_data_of(out, ("sweep",))
    if why is not None:
        raise InputError(f"report {str(out)!r} {why}")
    d = load(folder)
    spec = d.spec
    quantities = [_quantity(spec, v) for v in spec.vary]
    with tempfile.TemporaryDirectory(prefix="fuzzyservo-sweep-report-") as tmp:
        r = _Report(d, Path(tmp), quantities, _finite_order(d.metrics["itae"]))
        counts = r.outcome_counts()
        sections: list[Section] = []
        partial = _partial_section(d, folder)
        wins, pair_tables = _paired(r) if len(r.labels) > 1 else ({}, [])
        ranked, effects = _effects(r)
        sections.append(_summary_section(r, counts, wins, ranked))
        if partial is not None:
            sections.insert(0, partial)
        sections.append(_outcome_section(r, counts))
        sections.append(_distribution_section(r))
        if len(r.labels) > 1:
            sections.append(_paired_section(r, wins, pair_tables))
        if effects is not None:
            sections.append(effects)
        sections.append(_maps_section(r, ranked))
        sections.append(_worst_section(r, worst))
        inv = _invalid_section(d)
        if inv is not None:
            sections.append(inv)
        sections.append(_sweep_section(r))
        man = d.manifest
        meta = {
            "sweep": spec.name,
            "folder": str(folder),
            "chunks": (f"{d.chunks_read} of {man.n_chunks}"
                       + ("" if d.chunks_read >= man.n_chunks else " (PARTIAL)")),
            "runs read": f"{d.n_rows} of {man.n_runs} ({_plural(d.n_points, 'point')} x "
                         f"{_plural(len(r.labels), 'controller')})",
            "written by": f"fuzzyservo {man.version}, {man.created}",
            "spec digest": man.digest,
        }
        return write_html(Path(out), f"fuzzyservo sweep report: {spec.name}",
                          sections, meta)
