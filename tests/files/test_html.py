"""The offline HTML writer of the study's and the sweeps' reports (files/html.py)."""

from __future__ import annotations

from fuzzyservo.files.html import Details, Section, Table, Verdict, render_html


def test_render_links_verdict_cells_to_collapsible_details() -> None:
    html = render_html("t", [Section(
        "s", summary="One <b>. Two.", tables=[Table(["id", "p"], [
            ["C1", Verdict("does not hold", "does not hold", "claim-p-C1")]])],
        details=[Details("claim-p-C1", ["C1: ", Verdict("does not hold")],
                         paragraphs=[("Rule:", "a < b")], tables=[Table(["x"], [[1.23456]])])])])
    assert '<p class="summary">One &lt;b&gt;. Two.</p>' in html
    assert ('<td class="does-not-hold v-does-not-hold"><a href="#claim-p-C1">does not hold</a>'
            '</td>') in html
    assert '<details id="claim-p-C1"><summary>C1: <span class="does-not-hold">' in html
    assert "<p><b>Rule:</b> a &lt; b</p>" in html
    assert '<td class="num">1.235</td>' in html  # 4 significant digits
