"""The paper's two systems (Fig. 3): analytic values, table symmetries, kernel arguments."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from fuzzyservo.fuzzy import FuzzySystem, evaluate, pack
from fuzzyservo.fuzzy.engine import grid_form
from fuzzyservo.fuzzy.kernels import eval_uniform_grid
from fuzzyservo.paper import alpha_system, du_system, paper_fuzzy_system
from fuzzyservo.paper.rulebases import ALPHA_LABELS, ALPHA_TABLE, DU_TABLE, LABELS


def _at(system: FuzzySystem, e: Any, de: Any) -> Any:
    """Output 0 at (e, de): a float for floats, an array for arrays."""
    if np.ndim(e) == 0 and np.ndim(de) == 0:
        return float(evaluate(system, [e, de])[0])
    return evaluate(system, np.column_stack([e, de]))[:, 0]


def test_the_systems() -> None:
    du, al = du_system(), alpha_system()
    assert (du.name, al.name) == ("paper_du", "paper_alpha")
    assert math.isnan(du.outputs[0].default) and math.isnan(al.outputs[0].default)
    assert [v.name for v in (*du.inputs, *du.outputs)] == ["e", "de", "du"]
    assert al.outputs[0].range == (0.0, 1.0)
    # the shipped files' form: the middle of the range when no rule fires (never used)
    assert paper_fuzzy_system("du").outputs[0].default == 0.0
    assert paper_fuzzy_system("alpha").outputs[0].default == 0.5
    assert dataclasses.replace(paper_fuzzy_system("du"), outputs=du.outputs) == du


def test_du_pb_pb_is_centroid_of_half_triangle() -> None:
    # only PB fires, at height 1; its right half is cut by the universe: centroid 1 - 1/9
    assert _at(du_system(), 1.0, 1.0) == pytest.approx(8 / 9, abs=1e-15)  # float rounding
    assert _at(du_system(), -1.0, -1.0) == pytest.approx(-8 / 9, abs=1e-15)  # float rounding


def test_alpha_zo_zo_is_one_eighteenth() -> None:
    # only ZO (peak 0, half-width 1/6) fires: centroid of the half triangle is (1/6) / 3
    assert _at(alpha_system(), 0.0, 0.0) == pytest.approx(1 / 18, abs=1e-15)  # rounding


def test_single_label_cells_give_the_label_centroid() -> None:
    # at a grid node only one rule fires at height 1: interior labels give their peak
    du = du_system()
    for i2, row in enumerate(DU_TABLE):
        for i1, label in enumerate(row):
            e, de = -1 + i1 / 3, -1 + i2 / 3
            k = LABELS.index(label)
            want = {0: -8 / 9, 6: 8 / 9}.get(k, -1 + k / 3)
            assert _at(du, e, de) == pytest.approx(want, abs=1e-12)  # rounding of node k/3


def test_tables_are_transcribed_with_the_published_symmetries() -> None:
    n = len(LABELS)
    for i2 in range(n):
        for i1 in range(n):
            du = LABELS.index(DU_TABLE[i2][i1])
            assert LABELS.index(DU_TABLE[n - 1 - i2][n - 1 - i1]) == n - 1 - du
            assert ALPHA_TABLE[n - 1 - i2][n - 1 - i1] == ALPHA_TABLE[i2][i1]
    assert set(a for row in ALPHA_TABLE for a in row) <= set(ALPHA_LABELS)


def test_surfaces_have_the_symmetries() -> None:
    rng = np.random.default_rng(1)
    e = rng.uniform(-1.3, 1.3, 5000)
    de = rng.uniform(-1.3, 1.3, 5000)
    du, al = du_system(), alpha_system()
    # mirror-symmetric memberships: equal up to rounding of the mirrored inputs
    np.testing.assert_allclose(_at(du, -e, -de), -_at(du, e, de), rtol=0, atol=1e-12)
    np.testing.assert_allclose(_at(al, -e, -de), _at(al, e, de), rtol=0, atol=1e-12)


def test_outputs_stay_inside_the_attainable_range() -> None:
    rng = np.random.default_rng(2)
    e, de = rng.uniform(-2, 2, (2, 20000))
    du = _at(du_system(), e, de)
    al = _at(alpha_system(), e, de)
    assert du.min() >= -8 / 9 - 1e-12 and du.max() <= 8 / 9 + 1e-12  # rounding
    assert al.min() >= 1 / 18 - 1e-12 and al.max() <= 17 / 18 + 1e-12  # rounding


def test_the_packed_grid_tables_drive_the_kernel() -> None:
    sys_ = alpha_system()
    packed = pack(sys_)
    assert packed.path == "uniform grid" and packed.compiled is None
    rules, lims = packed.kernel_args()
    assert rules.dtype == np.int64 and rules.shape == (7, 7)
    assert lims.dtype == np.float64 and lims.shape == (8,)
    assert rules[3, 3] == ALPHA_LABELS.index("ZO")
    assert eval_uniform_grid(0.3, -0.7, rules, lims) == _at(sys_, 0.3, -0.7)
    assert list(lims[:7]) == [-1, 1, -1, 1, 0, 1, 7]
    assert math.isnan(lims[7])  # no default
    assert list(pack(paper_fuzzy_system("alpha")).kernel_args()[1]) == [-1, 1, -1, 1, 0, 1, 7,
                                                                         0.5]
    # copies: the packed tables stay as they were
    rules[3, 3] = -1
    assert packed.kernel_args()[0][3, 3] == ALPHA_LABELS.index("ZO")


def test_other_operators_are_not_packed_for_the_grid() -> None:
    du = du_system()
    other = dataclasses.replace(du, and_op="product")
    assert grid_form(other) is None
    packed = pack(other)
    assert packed.path != "uniform grid" and packed.rules.shape[0] == 1


def test_exact_value_at_a_two_label_point_by_fractions() -> None:
    # e = 1/6, de = 0: ZO (1/2) and PS (1/2) in e, ZO (1) in de -> rules ZO and PS at 1/2.
    # The aggregate is 1/2 on [-1/6, 1/2] and the half edges outside: by symmetry about 1/6.
    assert _at(du_system(), 1 / 6, 0.0) == pytest.approx(1 / 6, abs=1e-15)  # rounding
    # e = 1/6, de = 1/6: rules (ZO,ZO)->ZO, (PS,ZO)->PS, (ZO,PS)->PS, (PS,PS)->PS, all 1/2
    # -> same clipped set
    assert _at(du_system(), 1 / 6, 1 / 6) == pytest.approx(1 / 6, abs=1e-15)  # rounding
