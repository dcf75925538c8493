"""Uniform variables and rule tables (Variable.uniform, FuzzySystem.from_table, rule_table):
construction and every error case."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzyservo.errors import ParameterError
from fuzzyservo.fuzzy import And, Consequent, FuzzySystem, Is, Rule, Term, Variable
from fuzzyservo.fuzzy.engine import grid_form
from fuzzyservo.fuzzy.system import uniform_triangles
from fuzzyservo.paper.rulebases import DU_TABLE, LABELS

E = Variable.uniform("e", (-1.0, 1.0), LABELS)
DE = Variable.uniform("de", (-1.0, 1.0), LABELS)
DU = Variable.uniform("du", (-1.0, 1.0), LABELS)


def test_uniform_partition_peaks() -> None:
    peaks = [t.params[1] for t in E.terms]
    np.testing.assert_allclose(peaks, np.linspace(-1, 1, 7), rtol=0, atol=1e-15)  # k * 1/3
    assert all(t.shape == "triangle" and t.height == 1.0 for t in E.terms)
    assert E.terms == uniform_triangles((-1.0, 1.0), LABELS)
    assert tuple(t.name for t in E.terms) == LABELS
    # neighbours share their floats: a foot is the neighbour's peak
    for left, right in zip(E.terms, E.terms[1:], strict=False):
        assert left.params[1:] == right.params[:2]
    # a symmetric range keeps symmetric peaks, and 0 exactly
    assert peaks[3] == 0.0 and all(peaks[k] == -peaks[6 - k] for k in range(7))
    assert peaks[0] == -1.0 and peaks[6] == 1.0
    assert np.isnan(E.default) and Variable.uniform("x", (0, 1), "AB", default=0.5).default == 0.5


def test_explicit_rules_equal_the_table() -> None:
    rules = [Rule(And((Is(0, i1), Is(1, i2))), (Consequent(0, LABELS.index(cell)),))
             for i2, row in enumerate(DU_TABLE) for i1, cell in enumerate(row)]
    listed = FuzzySystem(inputs=(E, DE), outputs=(DU,), rules=tuple(rules[::-1]))
    from_table = FuzzySystem.from_table(DU_TABLE, columns=E, rows=DE, output=DU)
    assert listed.rule_table() == from_table.rule_table()
    want = [[LABELS.index(c) for c in row] for row in DU_TABLE]
    assert from_table.rule_table() == want
    assert (from_table.inputs, from_table.outputs) == ((E, DE), (DU,))
    assert (from_table.and_op, from_table.implication, from_table.aggregation,
            from_table.defuzzifier) == ("min", "min", "max", "centroid")
    rules_, lims = grid_form(from_table)  # type: ignore[misc]
    np.testing.assert_array_equal(rules_, want)


def test_empty_cells_are_minus_one() -> None:
    table = [list(r) for r in DU_TABLE]
    table[0][0] = None  # type: ignore[call-overload]
    table[6][2] = "-"
    s = FuzzySystem.from_table(table, columns=E, rows=DE, output=DU)
    assert len(s.rules) == 47
    got = s.rule_table()
    assert got[0][0] == -1 and got[6][2] == -1 and got[0][1] == LABELS.index("NB")


def test_rule_table_refuses_what_is_not_a_table() -> None:
    one_input = FuzzySystem(inputs=(E, DE), outputs=(DU,),
                            rules=(Rule(Is(0, 6), (Consequent(0, 4),)),))
    with pytest.raises(ParameterError, match=r"rule 1 \(if e is PB then du is PS\) is not a "
                                             r"cell of a rule table"):
        one_input.rule_table()
    cell = Rule(And((Is(0, 1), Is(1, 2))), (Consequent(0, 3),))
    twice = FuzzySystem(inputs=(E, DE), outputs=(DU,), rules=(cell, cell))
    with pytest.raises(ParameterError, match="two rules on one cell"):
        twice.rule_table()
    swapped = FuzzySystem(inputs=(E, DE), outputs=(DU,),
                          rules=(Rule(And((Is(1, 2), Is(0, 1))), (Consequent(0, 3),)),))
    with pytest.raises(ParameterError, match="is not a cell"):
        swapped.rule_table()
    weighted = FuzzySystem(inputs=(E, DE), outputs=(DU,), rules=(
        Rule(And((Is(0, 1), Is(1, 2))), (Consequent(0, 3),), weight=0.5),))
    with pytest.raises(ParameterError, match="is not a cell"):
        weighted.rule_table()
    three = FuzzySystem(inputs=(E, DE, Variable.uniform("w", (0, 1), "AB")), outputs=(DU,),
                        rules=(cell,))
    with pytest.raises(ParameterError, match="a rule table needs 2 inputs"):
        three.rule_table()


def test_wrong_table_shape() -> None:
    with pytest.raises(ParameterError, match=r"must have 7 rows \(de\) of 7 cells \(e\)"):
        FuzzySystem.from_table(DU_TABLE[:6], columns=E, rows=DE, output=DU)
    with pytest.raises(ParameterError, match=r"got 7 rows of lengths \[6, 7"):
        FuzzySystem.from_table([DU_TABLE[0][:6], *DU_TABLE[1:]], columns=E, rows=DE,
                               output=DU)


def test_unknown_label_in_table() -> None:
    bad = [list(r) for r in DU_TABLE]
    bad[2][3] = "PX"
    with pytest.raises(ParameterError, match=r"variable 'du' has no term 'PX'; it has NB"):
        FuzzySystem.from_table(bad, columns=E, rows=DE, output=DU)


@pytest.mark.parametrize("universe", [(1.0, 1.0), (1.0, -1.0), (0.0, float("inf"))])
def test_bad_universe(universe: tuple[float, float]) -> None:
    with pytest.raises(ParameterError, match="lo < hi"):
        Variable.uniform("e", universe, LABELS)
    with pytest.raises(ParameterError, match="lo < hi"):
        Variable("e", universe, (Term("A", "triangle", (0, 0.5, 1)),))


def test_bad_names_and_duplicates() -> None:
    t = Term("A", "triangle", (0, 0.5, 1))
    with pytest.raises(ParameterError, match="variable name 'a b'"):
        Variable("a b", (0, 1), (t,))
    with pytest.raises(ParameterError, match="term name 'A B'"):
        Variable.uniform("x", (0, 1), ["A B", "C"])
    with pytest.raises(ParameterError, match=r"repeats terms \['A'\]"):
        Variable("x", (0, 1), (t, t))
    with pytest.raises(ParameterError, match=r"repeats terms \['A'\]"):
        Variable.uniform("x", (0, 1), ["A", "A"])
    with pytest.raises(ParameterError, match="needs >= 2 labels"):
        Variable.uniform("x", (0, 1), ["A"])
