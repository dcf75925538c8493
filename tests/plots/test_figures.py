"""Fig. 3 figure data: computed from the systems, before rendering."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzyservo.errors import ParameterError
from fuzzyservo.paper import alpha_system, du_system
from fuzzyservo.plots.figures import (
    membership_data,
    render_memberships,
    render_surface,
    surface_data,
)


def test_membership_data_partitions_of_unity() -> None:
    data = membership_data(du_system(), n=301)
    assert data.names == ("e", "de", "du")
    for mu in data.mu:
        # uniform triangles with 50 % overlap sum to 1 on the universe: rounding only
        np.testing.assert_allclose(mu.sum(axis=0), 1.0, rtol=0, atol=1e-12)
    assert membership_data(alpha_system()).labels[2] == ("ZO", "VS", "S", "SB", "MB", "B", "VB")


def test_surface_data_matches_the_system() -> None:
    data = surface_data(alpha_system(), n=9)
    assert data.value.shape == (9, 9)
    assert data.value[4, 4] == pytest.approx(1 / 18, abs=1e-15)  # centre: (ZO, ZO) -> 1/18
    assert data.value[2, 6] == alpha_system().evaluate(data.e[6], data.de[2])


def test_renderers_return_figures() -> None:
    fig = render_surface(surface_data(du_system(), n=5, title="t"))
    assert len(fig.axes) == 3  # 3-D surface, contour map, colour bar
    assert len(render_memberships(membership_data(du_system())).axes) == 3


def test_bad_sizes() -> None:
    with pytest.raises(ParameterError, match="at least 2 x 2"):
        surface_data(du_system(), n=1)
    with pytest.raises(ParameterError, match="at least 2 points"):
        membership_data(du_system(), n=1)
