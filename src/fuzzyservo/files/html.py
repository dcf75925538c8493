"""A self-contained, offline HTML report: figures embedded as base64 PNG, tables as HTML.

The one writer of the study's report (``reproduce``'s ``report.html``) and a sweep's
(``fuzzyservo sweep-report``): the report opens without a network connection or any file
beside it. It is written from records already computed (no simulation happens here); a
:class:`Verdict` cell is coloured by :data:`VERDICT_CLASSES`, the verdicts of the study's
claims.
"""

from __future__ import annotations

import base64
import html
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .._io import write_text_atomic

__all__ = ["VERDICT_CLASSES", "Details", "Figure", "Section", "Table", "Verdict",
           "render_html", "write_html"]

#: CSS class of each verdict (the colour it is shown in).
VERDICT_CLASSES: dict[str, str] = {
    "holds": "holds",
    "does not hold": "does-not-hold",
    "holds under stated conditions": "holds-under-stated-conditions",
}


@dataclass(frozen=True, slots=True)
class Figure:
    """A PNG file to embed, with its caption."""

    png: Path
    caption: str


@dataclass(frozen=True, slots=True)
class Verdict:
    """A verdict shown in its colour: ``text`` (e.g. a short form of ``verdict``), linking to
    ``#href`` when given."""

    verdict: str
    text: str = ""
    href: str = ""


@dataclass(frozen=True, slots=True)
class Table:
    """A table: header and rows of cells (numbers are formatted with 4 significant digits;
    a :class:`Verdict` cell is coloured and may link)."""

    header: Sequence[str]
    rows: Sequence[Sequence[object]]
    caption: str = ""


@dataclass(frozen=True, slots=True)
class Details:
    """A collapsible block (HTML ``<details>``): a one-line summary of text and verdicts,
    opened to paragraphs (label, text) and tables; ``anchor`` is its id for links."""

    anchor: str
    summary: Sequence[str | Verdict]
    paragraphs: Sequence[tuple[str, str]] = ()
    tables: Sequence[Table] = ()


@dataclass(frozen=True, slots=True)
class Section:
    """A titled section: a highlighted ``summary`` paragraph, paragraphs, items, tables,
    collapsible details and figures, rendered in that order."""

    title: str
    paragraphs: Sequence[str] = ()
    tables: Sequence[Table] = ()
    figures: Sequence[Figure] = ()
    items: Sequence[str] = field(default=())
    details: Sequence[Details] = ()
    summary: str = ""


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1100px;
margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em}
h2{font-size:1.25em;border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:2em}
table{border-collapse:collapse;margin:.8em 0;font-size:.9em}
th,td{border:1px solid #ccc;padding:.25em .5em;text-align:left;vertical-align:top}
th{background:#f2f2f2}td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.9em;color:#555}.holds{color:#1a7f37;font-weight:600}
.does-not-hold{color:#b42318;font-weight:600}.holds-under-stated-conditions{color:#9a6700;font-weight:600}
caption{caption-side:top;text-align:left;font-weight:600;padding:.3em 0}
td.v-holds{background:#e7f5ea}td.v-does-not-hold{background:#fce8e6}
td.v-holds-under-stated-conditions{background:#fff4d6}td a{color:inherit}
details{border:1px solid #ddd;border-radius:4px;margin:.4em 0;padding:.3em .6em}
details[open]{background:#fafafa}summary{cursor:pointer}
details table{display:block;overflow-x:auto;max-width:100%}
p.summary{font-size:1.05em;background:#f4f6fa;border-left:4px solid #4a6fa5;padding:.6em .9em}
"""


# what HTML text may not hold (control characters but tab, line feed, form feed and carriage
# return; lone surrogates, from file names that are not UTF-8; noncharacters)
_NOT_HTML = re.compile("[\x00-\x08\x0b\x0e-\x1f\x7f-\x9f\ud800-\udfff\ufffe\uffff]")


def _esc(text: object) -> str:
    """``text`` as HTML text or a quoted attribute value: ``&``, ``<``, ``>`` and quotes
    escaped, and the characters HTML may not hold written as ``\\xNN`` or ``\\uNNNN``, so
    that no string from outside (a spec's name, a path, a label) adds markup or breaks the
    file's UTF-8."""
    def one(m: re.Match[str]) -> str:
        o = ord(m.group(0))
        return f"\\x{o:02x}" if o < 0x100 else f"\\u{o:04x}"
    return html.escape(_NOT_HTML.sub(one, str(text)))


def _fmt(value: object) -> tuple[str, bool]:
    """Cell text and whether it is numeric."""
    if isinstance(value, bool):
        return ("yes" if value else "no"), False
    if isinstance(value, int):
        return str(value), True
    if isinstance(value, float):
        if math.isnan(value):
            return "n/a", True
        if value == 0.0:
            return "0", True
        if abs(value) >= 1e5 or abs(value) < 1e-3:
            return f"{value:.4g}", True
        return f"{value:.4g}", True
    return str(value), False


def _verdict(v: Verdict, tag: str = "span") -> str:
    cls = VERDICT_CLASSES.get(v.verdict, "")
    text = _esc(v.text or v.verdict)
    if v.href:
        text = f'<a href="#{_esc(v.href)}">{text}</a>'
    if tag == "td":
        return f'<td class="{cls} v-{cls}">{text}</td>'
    return f'<span class="{cls}">{text}</span>'


def _details(d: Details) -> str:
    head = "".join(_verdict(p) if isinstance(p, Verdict) else _esc(p)
                   for p in d.summary)
    out = [f'<details id="{_esc(d.anchor)}"><summary>{head}</summary>']
    out.extend(f"<p><b>{_esc(label)}</b> {_esc(text)}</p>"
               for label, text in d.paragraphs)
    out.extend(_table(t) for t in d.tables)
    out.append("</details>")
    return "\n".join(out)


def _table(t: Table) -> str:
    out = ["<table>"]
    if t.caption:
        out.append(f"<caption>{_esc(t.caption)}</caption>")
    out.append("<tr>" + "".join(f"<th>{_esc(str(h))}</th>" for h in t.header) + "</tr>")
    for row in t.rows:
        cells = []
        for v in row:
            if isinstance(v, Verdict):
                cells.append(_verdict(v, "td"))
                continue
            text, num = _fmt(v)
            cls = ""
            if num:
                cls = ' class="num"'
            elif text in VERDICT_CLASSES:
                cls = f' class="{VERDICT_CLASSES[text]}"'
            cells.append(f"<td{cls}>{_esc(text)}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _figure(f: Figure) -> str:
    data = base64.b64encode(Path(f.png).read_bytes()).decode("ascii")
    return (f'<figure><img alt="{_esc(f.caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{_esc(f.caption)}</figcaption></figure>")


def render_html(title: str, sections: Sequence[Section],
                meta: Mapping[str, str] | None = None) -> str:
    """Render the report to one HTML string with everything embedded."""
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             f"<title>{_esc(title)}</title><style>{_CSS}</style></head><body>",
             f"<h1>{_esc(title)}</h1>"]
    if meta:
        parts.append("<p>" + "<br>".join(f"<b>{_esc(k)}</b>: {_esc(v)}"
                                         for k, v in meta.items()) + "</p>")
    for s in sections:
        parts.append(f"<h2>{_esc(s.title)}</h2>")
        if s.summary:
            parts.append(f'<p class="summary">{_esc(s.summary)}</p>')
        parts.extend(f"<p>{_esc(p)}</p>" for p in s.paragraphs)
        if s.items:
            parts.append("<ul>" + "".join(f"<li>{_esc(i)}</li>" for i in s.items)
                         + "</ul>")
        parts.extend(_table(t) for t in s.tables)
        parts.extend(_details(d) for d in s.details)
        parts.extend(_figure(f) for f in s.figures)
    parts.append("</body></html>")
    return "\n".join(parts)


def write_html(path: Path, title: str, sections: Sequence[Section],
               meta: Mapping[str, str] | None = None) -> Path:
    """Write :func:`render_html` to ``path`` atomically and return the path."""
    return write_text_atomic(path, render_html(title, sections, meta))
