"""Run CSVs read back (issue 9, rows 3, 8 and 23): streamed, strict UTF-8 with the offset of a
bad byte, one value per column on every row, each column named once."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.errors import InputError
from fuzzyservo.files import read_csv_columns, read_run_csv
from fuzzyservo.paper import paper_params
from fuzzyservo.registry import build_plant
from fuzzyservo.sim import simulate_open_loop


def test_a_written_run_reads_back_exactly(tmp_path: Path) -> None:
    res = simulate_open_loop(build_plant("linear", paper_params(), 0.5), 0.3, duration=0.05)
    res.to_csv(tmp_path / "run.csv")
    back = read_run_csv(tmp_path / "run.csv")
    assert list(back.columns) == ["t", "u", "y", *res.state_names]
    assert np.array_equal(back.t, res.t) and np.array_equal(back.y, res.y)  # repr round-trip


def test_comments_blank_lines_bom_crlf_and_text_columns(tmp_path: Path) -> None:
    path = tmp_path / "r.csv"
    path.write_bytes(b"\xef\xbb\xbf# made by hand\r\nt,r,y,u,note\r\n\r\n0,0,0,0,start\r\n"
                     b"# a comment\r\n0.1,1,0.5,0.25,end\r\n")
    cols = read_csv_columns(path, ("t", "r", "y", "u"), what="run CSV")
    assert list(cols) == ["t", "r", "y", "u"]  # the text column left out
    assert cols["u"].tolist() == [0.0, 0.25]


def test_only_the_columns_kept_are_read(tmp_path: Path) -> None:
    path = tmp_path / "r.csv"
    path.write_bytes(b"t,a,b,y,c\n0,1,x,2,3\n0.1,4,y,5,oops\n")
    cols = read_csv_columns(path, ("t",), what="rig log", keep=("y", "b"))
    assert list(cols) == ["t", "y"]  # 'b' holds text; 'a' and 'c' skipped unparsed
    assert cols["y"].tolist() == [2.0, 5.0]


@pytest.mark.parametrize(("data", "needle"), [
    (b"t,r,y,u\n0,0,0,0\n0.1,1,1,1\n\xe9\n", r"not UTF-8 text: byte 0xe9 at offset 26"),
    (b"\xef\xbb\xbft,r,y,u\n\x80", r"byte 0x80 at offset 11"),
    (b"\xfe\xfft,r", r"UTF-16 text \(byte-order mark at byte 0\)"),
    (b"t,r,y,u\n0,0,0,0\n0.1,1,1,1\n\x00\n", r"NUL character at offset 26"),
    (b"t,y,r,y,u\n", r"names column\(s\) 'y' twice"),
    (b"t,r,y,u\n0,0,0,0\n0.1,1,1\n", r"line 3 has 3 value\(s\), the header names 4 columns "
                                     r"\(a row cut short\?\)"),
    (b"t,r,y,u\n0,0,0,0\n0.1,1,1,1,\n", r"line 3 has 5 value\(s\)"),
    (b"t,r,y,u,note\n0,0,0,0\n", r"line 2 has 4 value\(s\), the header names 5"),
    (b"t,r,y,u\n0,0,0,0\n", r"has 1 data row\(s\); at least 2 needed"),
    (b"t,r,y,\"u\nv\"\n0,0,0,0\n", r"lacks column\(s\) u; .*found 't', 'r', 'y', 'u\\nv'"),
])
def test_malformed_run_csv_is_one_line(tmp_path: Path, data: bytes, needle: str) -> None:
    path = tmp_path / "r.csv"
    path.write_bytes(data)
    with pytest.raises(InputError, match=needle) as info:
        read_run_csv(path, ("t", "r", "y", "u"))
    assert "r.csv" in str(info.value) and "\n" not in str(info.value)
