"""Linguistic variables and rule bases: construction, text rules, and every error case."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzyservo.errors import ParameterError
from fuzzyservo.fuzzy import LinguisticVariable, RuleBase, Triangle
from fuzzyservo.paper.rulebases import DU_TABLE, LABELS

E = LinguisticVariable.uniform("e", (-1.0, 1.0), LABELS)
DE = LinguisticVariable.uniform("de", (-1.0, 1.0), LABELS)
DU = LinguisticVariable.uniform("du", (-1.0, 1.0), LABELS)


def test_uniform_partition_peaks() -> None:
    peaks = [mf.centre for _, mf in E.terms]
    np.testing.assert_allclose(peaks, np.linspace(-1, 1, 7), rtol=0, atol=1e-15)  # k * 1/3
    assert E.is_uniform_triangles()
    assert E.labels == LABELS


def test_text_rules_equal_the_table() -> None:
    text = "\n".join(
        f"if e is {LABELS[i1]} and de is {LABELS[i2]} then du is {cell}"
        for i2, row in enumerate(DU_TABLE) for i1, cell in enumerate(row)
    )
    from_text = RuleBase.from_text("# Fig. 3a\n\n" + text, inputs=(E, DE), output=DU)
    from_table = RuleBase.from_table(DU_TABLE, columns=E, rows=DE, output=DU)
    np.testing.assert_array_equal(from_text.as_table(), from_table.as_table())


def test_text_rule_may_name_one_input() -> None:
    rb = RuleBase.from_text("IF e IS PB THEN du IS PS", inputs=(E, DE), output=DU)
    assert rb.rules[0].antecedent == (6, -1) and rb.rules[0].consequent == 4


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("if e is XX and de is PS then du is NM", r"unknown label 'XX' for 'e'; allowed: NB"),
        ("if e is NB and de is PS then du is QQ", r"unknown label 'QQ' for 'du'"),
        ("if x is NB then du is NM", r"unknown input 'x'; allowed: e, de"),
        ("if e is NB and e is PS then du is NM", r"input 'e' named twice"),
        ("when e is NB then du is NM", r"is not 'if X is A"),
        ("if e is NB then y is NM", r"consequent must read 'du is LABEL'"),
        ("if e NB then du is NM", r"cannot read clause 'e NB'"),
    ],
)
def test_bad_rule_text(text: str, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        RuleBase.from_text(text, inputs=(E, DE), output=DU)


def test_wrong_table_shape() -> None:
    with pytest.raises(ParameterError, match=r"must have 7 rows \(de\) of 7 cells \(e\)"):
        RuleBase.from_table(DU_TABLE[:6], columns=E, rows=DE, output=DU)
    with pytest.raises(ParameterError, match=r"got 7 rows of lengths \[6, 7"):
        RuleBase.from_table([DU_TABLE[0][:6], *DU_TABLE[1:]], columns=E, rows=DE, output=DU)


def test_unknown_label_in_table() -> None:
    bad = [list(r) for r in DU_TABLE]
    bad[2][3] = "PX"
    with pytest.raises(ParameterError, match=r"unknown label 'PX' for 'du'"):
        RuleBase.from_table(bad, columns=E, rows=DE, output=DU)


@pytest.mark.parametrize("universe", [(1.0, 1.0), (1.0, -1.0), (0.0, float("inf"))])
def test_bad_universe(universe: tuple[float, float]) -> None:
    with pytest.raises(ParameterError, match="lo < hi"):
        LinguisticVariable.uniform("e", universe, LABELS)
    with pytest.raises(ParameterError, match="lo < hi"):
        LinguisticVariable(name="e", universe=universe,
                           terms=(("A", Triangle(a=0, b=0.5, c=1)),))


def test_bad_names_and_duplicates() -> None:
    t = Triangle(a=0, b=0.5, c=1)
    with pytest.raises(ParameterError, match="variable name 'a b'"):
        LinguisticVariable(name="a b", universe=(0, 1), terms=(("A", t),))
    with pytest.raises(ParameterError, match=r"repeats labels \['A'\]"):
        LinguisticVariable(name="x", universe=(0, 1), terms=(("A", t), ("A", t)))
    with pytest.raises(ParameterError, match="needs >= 2 labels"):
        LinguisticVariable.uniform("x", (0, 1), ["A"])
