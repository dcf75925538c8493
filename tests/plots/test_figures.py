"""Fig. 3: data computed from the systems, then drawn: mathtext names, labels inside the axes,
ticks that do not run together, the paper's rule tables drawn as tables (issue 10, item 6)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox

from fuzzyservo.errors import ParameterError
from fuzzyservo.fuzzy import evaluate
from fuzzyservo.paper import alpha_system, du_system
from fuzzyservo.paper.rulebases import ALPHA_LABELS, ALPHA_TABLE, DU_TABLE, LABELS
from fuzzyservo.plots.figures import (
    FIG3_STEMS,
    fig3,
    fig3_files,
    membership_data,
    render_memberships,
    render_rule_table,
    render_surface,
    rule_table_data,
    surface_data,
)

PNG = b"\x89PNG\r\n\x1a\n"


def _plain_underscore(text: str) -> bool:
    """An underscore outside mathtext ($...$): drawn literally, the issue's complaint."""
    return "_" in re.sub(r"\$[^$]*\$", "", text)


def _texts(fig: Figure) -> list[str]:
    out = [fig.get_suptitle()] if fig.get_suptitle() else []
    for ax in fig.axes:
        out += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel()]
        out += [t.get_text() for t in ax.texts]
        if hasattr(ax, "get_zlabel"):
            out.append(ax.get_zlabel())
    return [t for t in out if t]


def _drawn(fig: Figure) -> tuple[Figure, RendererAgg]:
    """``fig`` drawn on an Agg canvas (laid out, so extents are final) and its renderer."""
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return fig, canvas.get_renderer()


def _inside(inner: Bbox, outer: Bbox, slack: float = 0.5) -> bool:
    """``inner`` within ``outer`` [pixels], up to ``slack`` of rounding."""
    return (inner.x0 >= outer.x0 - slack and inner.x1 <= outer.x1 + slack
            and inner.y0 >= outer.y0 - slack and inner.y1 <= outer.y1 + slack)


def test_membership_data_partitions_of_unity() -> None:
    data = membership_data(du_system(), n=301)
    assert data.names == ("e", "de", "du")
    for mu in data.mu:
        # uniform triangles with 50 % overlap sum to 1 on the universe: rounding only
        np.testing.assert_allclose(mu.sum(axis=0), 1.0, rtol=0, atol=1e-12)
    assert membership_data(alpha_system()).labels[2] == ALPHA_LABELS
    np.testing.assert_allclose(data.peaks[0], np.linspace(-1, 1, 7), atol=1e-12)  # k/3 - 1


def test_membership_data_of_named_variables() -> None:
    data = membership_data(alpha_system(), variables=("alpha",))
    assert data.names == ("alpha",) and data.labels == (ALPHA_LABELS,)
    with pytest.raises(ParameterError, match="the system has e, de, alpha"):
        membership_data(alpha_system(), variables=("beta",))


def test_membership_figure_uses_mathtext_and_keeps_labels_inside() -> None:
    """Issue 10: axes 'de' where titles say 'Δe', NB/PB clipped, x tick labels running
    together."""
    fig, renderer = _drawn(render_memberships(membership_data(du_system()), "t"))
    axes: list[Axes] = fig.axes
    assert [ax.get_xlabel() for ax in axes] == [r"$e_n$", r"$\Delta e_n$", r"$\Delta u_n$"]
    assert not any(_plain_underscore(t) for t in _texts(fig))
    for ax in axes:
        frame = ax.get_window_extent(renderer)
        labels = [t for t in ax.texts]
        assert [t.get_text() for t in labels] == list(LABELS)
        for t in labels:  # every term label, the end ones too, inside the axes
            assert _inside(t.get_window_extent(renderer), frame), t.get_text()
        ticks = [t.get_window_extent(renderer) for t in ax.get_xticklabels() if t.get_text()]
        assert 3 <= len(ticks) <= 5
        for a, b in zip(ticks, ticks[1:], strict=False):
            assert a.x1 < b.x0, "x tick labels overlap"


def test_rule_table_data_is_the_papers_table() -> None:
    du = rule_table_data(du_system())
    assert du.cells == DU_TABLE and du.row_labels == LABELS and du.column_labels == LABELS
    assert (du.row_name, du.column_name, du.output_name) == ("de", "e", "du")
    alpha = rule_table_data(alpha_system())
    assert alpha.cells == ALPHA_TABLE and alpha.output_labels == ALPHA_LABELS
    assert int(alpha.index[3, 3]) == ALPHA_LABELS.index("ZO")  # (e, Δe) = (ZO, ZO) -> ZO


@pytest.mark.parametrize(("system", "table"), [(du_system, DU_TABLE),
                                               (alpha_system, ALPHA_TABLE)])
def test_rule_table_is_drawn_as_a_table(system: object, table: tuple[tuple[str, ...], ...]
                                        ) -> None:
    fig = render_rule_table(rule_table_data(system(), "t"))  # type: ignore[operator]
    (ax,) = fig.axes
    (drawn,) = ax.tables
    cells = drawn.get_celld()
    for r, row in enumerate(table):
        assert cells[(r + 1, -1)].get_text().get_text() == LABELS[r]  # rows: Δe
        for c, label in enumerate(row):
            assert cells[(r + 1, c)].get_text().get_text() == label
    assert [cells[(0, c)].get_text().get_text() for c in range(7)] == list(LABELS)  # e
    assert cells[(0, -1)].get_text().get_text() == r"$\Delta e_n$ \ $e_n$"
    assert not any(_plain_underscore(t) for t in _texts(fig))


def test_surface_figure() -> None:
    fig = render_surface(surface_data(du_system(), n=5, title="t"))
    assert len(fig.axes) == 3  # 3-D surface, contour map, colour bar
    ax3, ax2, bar = fig.axes
    assert (ax3.get_xlabel(), ax3.get_ylabel()) == (r"$e_n$", r"$\Delta e_n$")
    assert ax3.get_zlabel() == bar.get_ylabel() == r"$\Delta u_n$"  # type: ignore[attr-defined]
    assert (ax2.get_xlabel(), ax2.get_ylabel()) == (r"$e_n$", r"$\Delta e_n$")
    assert len(ax2.get_xticks()) == 5  # -1, -0.5, 0, 0.5, 1: never crowded


def test_surface_data_matches_the_system() -> None:
    data = surface_data(alpha_system(), n=9)
    assert data.value.shape == (9, 9)
    assert data.value[4, 4] == pytest.approx(1 / 18, abs=1e-15)  # centre: (ZO, ZO) -> 1/18
    assert data.value[2, 6] == evaluate(alpha_system(), [data.e[6], data.de[2]])[0]


def test_fig3_writes_its_listed_files_rules_included(tmp_path: Path) -> None:
    written = fig3(du_system(), alpha_system(), tmp_path, n=9, formats=("png",))
    assert written == fig3_files(tmp_path, ("png",))
    assert [p.stem for p in written] == list(FIG3_STEMS)
    assert {"fig3a_rules_du", "fig3b_rules_alpha"} <= set(FIG3_STEMS)
    for p in written:
        assert p.read_bytes()[:8] == PNG, p.name


def test_bad_sizes() -> None:
    with pytest.raises(ParameterError, match="at least 2 x 2"):
        surface_data(du_system(), n=1)
    with pytest.raises(ParameterError, match="at least 2 points"):
        membership_data(du_system(), n=1)
