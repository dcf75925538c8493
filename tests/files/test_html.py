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


def test_text_from_outside_adds_no_markup_and_stays_utf8() -> None:
    """Issue 29, item 1: every string reaches the page escaped. Hostile text in every field
    (markup, quotes that would end an attribute, a control character, a lone surrogate from
    a file name that is not UTF-8) parses, with the standard library's HTML parser, to the
    report's own elements only and to the text itself (the characters HTML cannot hold
    written as escapes); the page encodes as UTF-8."""
    from html.parser import HTMLParser

    evil = "x</p><script>alert(1)</script>\"'><img src=x onerror=y> \u00e9"
    page = render_html(evil, [Section(
        evil, summary=evil, paragraphs=[evil], items=[evil + "\x01"],
        tables=[Table([evil], [[evil, Verdict("holds", evil, evil)]], caption=evil)],
        details=[Details(evil, [evil, Verdict("holds", evil)], paragraphs=[(evil, evil)])])],
        meta={evil: evil + "\udcff"})
    page.encode("utf-8")  # no lone surrogate left

    class Collect(HTMLParser):
        def __init__(self) -> None:
            super().__init__()
            self.tags: set[str] = set()
            self.attrs: list[tuple[str, str | None]] = []
            self.text: list[str] = []

        def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
            self.tags.add(tag)
            self.attrs += attrs

        def handle_data(self, data: str) -> None:
            self.text.append(data)

    c = Collect()
    c.feed(page)
    assert c.tags <= {"html", "head", "meta", "title", "style", "body", "h1", "h2", "p", "b",
                      "br", "ul", "li", "table", "caption", "tr", "th", "td", "span", "a",
                      "details", "summary"}, c.tags
    assert {k for k, _ in c.attrs} <= {"lang", "charset", "class", "href", "id"}
    assert c.text.count(evil) >= 10
    assert evil + "\\x01" in c.text and evil + "\\udcff" in "".join(c.text)
