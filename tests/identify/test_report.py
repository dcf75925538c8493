"""The identification's HTML page: every estimate with the digits its error supports, the
warnings one a line, the residuals in display units and SI, the figure embedded, everything
from outside escaped, and written atomically."""

from __future__ import annotations

import base64
import dataclasses
import hashlib
import html
import math
import re
from pathlib import Path

import numpy as np
import pytest

import fuzzyservo._io as io
from fuzzyservo.errors import OutputError
from fuzzyservo.identify import Identification
from fuzzyservo.identify.report import format_estimate, render_report, write_report
from tests.identify.simulated import identification

PNG = b"\x89PNG\r\n\x1a\n"
EVIL = "<script>alert(1)</script>"


@pytest.fixture(scope="module")
def ident() -> Identification:
    return identification()


@pytest.fixture(scope="module")
def page(ident: Identification) -> str:
    return render_report(ident, command="fuzzyservo identify log.csv --fit load.mass",
                         data="log.csv", digest="ab" * 32, figure=None)


def _row(page: str, first_cell: str) -> list[str]:
    """The cells (unescaped text) of the table row whose first cell is ``first_cell``."""
    m = re.search(rf"<tr><td>{re.escape(html.escape(first_cell))}</td>(.*?)</tr>", page)
    assert m is not None, first_cell
    return [html.unescape(c) for c in re.findall(r"<td[^>]*>(.*?)</td>", m.group(1))]


@pytest.mark.parametrize("value, se", [(10008.05, 6.34), (1.503984e9, 3.98e6),
                                       (0.0123456, 1.0e-7), (-42.0, 30.0), (5.0, 0.0),
                                       (2.5e-3, math.nan)])
def test_format_estimate_keeps_the_digits_the_error_supports(value: float, se: float) -> None:
    text = format_estimate(value, se)
    if math.isfinite(se) and se > 0.0:
        # rounded at or below the error's second significant digit: off by at most half a
        # unit there, 0.05 of the error (or a 4-digit rounding when that is finer)
        assert abs(float(text) - value) <= max(0.05 * se, 5e-4 * abs(value))
        # and not far below it: no more than 3 digits past the error's first
        mant = text.split("e")[0].lstrip("-").replace(".", "").lstrip("0")
        assert len(mant) <= max(4, math.floor(math.log10(abs(value)))
                                - math.floor(math.log10(se)) + 2)
    else:
        assert float(text) == pytest.approx(value, rel=5e-4)  # 4 significant digits


def test_every_estimate_is_shown_with_its_error_and_interval(ident: Identification,
                                                            page: str) -> None:
    assert ident.interval is not None
    for i, (name, unit) in enumerate(zip(ident.names, ident.units, strict=True)):
        cells = _row(page, name)
        est, se = float(ident.estimate[i]), float(ident.std_error[i])
        assert cells[0] == unit
        assert float(cells[1]) == pytest.approx(ident.initial[i], rel=5e-6)  # 6 digits
        assert cells[2] == format_estimate(est, se)
        assert float(cells[3]) == pytest.approx(se, rel=0.05)  # 2 significant digits
        assert float(cells[4]) == pytest.approx(100.0 * se / est, rel=0.05)
        lo, hi = (float(x) for x in cells[5].split(" to "))
        assert lo == pytest.approx(ident.interval[i, 0], abs=0.05 * se)
        assert hi == pytest.approx(ident.interval[i, 1], abs=0.05 * se)
        assert float(cells[6]) == pytest.approx(ident.bounds[i, 0], rel=5e-4)  # 4 digits
        assert float(cells[7]) == pytest.approx(ident.bounds[i, 1], rel=5e-4)
    assert "bootstrap 95% interval" in page


def test_correlation_residuals_and_fit_numbers(ident: Identification, page: str) -> None:
    assert "Correlation of the estimates" in page
    for c, unit, scale, si in (("y", "mm", 1e3, "m"), ("p_f", "bar", 1e-5, "Pa"),
                               ("p_n", "bar", 1e-5, "Pa")):
        cells = _row(page, c)
        rms = ident.residual_rms[c]
        assert float(cells[0]) == pytest.approx(rms * scale, rel=5e-4)  # 4 digits
        assert cells[1] == unit and cells[3] == si
        assert float(cells[2]) == pytest.approx(rms, rel=5e-4)
    assert float(_row(page, "reduced chi-square")[0]) == pytest.approx(ident.chi2, rel=5e-4)
    n_used = int(np.count_nonzero(ident.used))
    assert int(_row(page, "samples used (not flagged)")[0]) == n_used
    assert "ab" * 32 in page  # the digest as given


def test_warnings_each_on_its_own_line_and_notes(ident: Identification) -> None:
    warned = dataclasses.replace(
        ident, warnings=("load.mass and fluid.oil_bulk_modulus correlate: r = 0.99 > 0.95",
                         f"a warning quoting {EVIL}"),
        notes=("1 of 3 starts ended in a worse local minimum; the best was kept",))
    page = render_report(warned, command="c", data="d", figure=None)
    items = re.findall(r"<li>(.*?)</li>", page)
    assert [html.unescape(i) for i in items] == [*warned.warnings, *warned.notes]
    assert "2 warning(s)" in page
    assert "<script" not in page


def test_no_warning_is_said(ident: Identification, page: str) -> None:
    assert not ident.warnings
    assert "None: the data determine every fitted parameter." in page
    items = re.findall(r"<li>(.*?)</li>", page)
    assert [html.unescape(i) for i in items] == list(ident.notes)  # the notes only


def test_outside_text_is_escaped_and_the_digest_is_the_files(ident: Identification,
                                                             tmp_path: Path) -> None:
    data = tmp_path / f"{EVIL}.csv"  # a folder "<script>alert(1)<" and a file "script>.csv"
    assert EVIL in str(data)
    data.parent.mkdir()
    data.write_bytes(b"t,y,u\n0,0.5,0\n")
    out = write_report(ident, tmp_path / "page.html", command=f"fuzzyservo identify '{data}'",
                       data=str(data))
    page = out.read_text(encoding="utf-8")
    assert "<script" not in page  # neither the file name nor the command adds markup
    assert html.escape(str(data)) in page
    assert hashlib.sha256(data.read_bytes()).hexdigest() in page


def _images(page: str) -> list[bytes]:
    return [base64.b64decode(b) for b in re.findall(r'src="data:image/png;base64,([^"]+)"',
                                                   page)]


def test_the_figure_is_drawn_and_embedded(ident: Identification, tmp_path: Path) -> None:
    out = write_report(ident, tmp_path / "page.html", command="c", data="nowhere.csv")
    page = out.read_text(encoding="utf-8")
    (png,) = _images(page)
    assert png.startswith(PNG)
    assert "data digest (SHA-256)</b>: not recorded" in page  # no file to digest
    assert [p.name for p in tmp_path.iterdir()] == ["page.html"]  # the PNG was temporary


def test_a_given_png_is_embedded_as_it_is(ident: Identification, tmp_path: Path) -> None:
    fig = tmp_path / "fit.png"
    fig.write_bytes(PNG + b"not really drawn")
    out = write_report(ident, tmp_path / "page.html", command="c", data="d", figure_path=fig)
    assert _images(out.read_text(encoding="utf-8")) == [fig.read_bytes()]


def test_without_a_figure_no_image(page: str) -> None:
    assert "<img" not in page
    assert "http://" not in page and "https://" not in page  # offline


def test_a_failing_write_leaves_the_old_page(ident: Identification, tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "page.html"
    out.write_text("old page", encoding="utf-8")
    fig = tmp_path / "fit.png"
    fig.write_bytes(PNG)

    def refuse(src: object, dst: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(io.os, "replace", refuse)
    with pytest.raises(OutputError, match="unchanged"):
        write_report(ident, out, command="c", data="d", figure_path=fig)
    assert out.read_text(encoding="utf-8") == "old page"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fit.png", "page.html"]
