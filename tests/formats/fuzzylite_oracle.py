"""fuzzylite 6's command-line tool as an independent reader and evaluator (tests only).

``apt-get install fuzzylite`` (the Makefile's ``oracles`` target does it). When the tool is
missing the tests that use it fail; they never skip (CI must not go green without the oracle).

fuzzylite samples the centroid (and the other integral defuzzifiers) on ``resolution`` points of
the output range. For .fis and .fcl files its importers fix the resolution at 100; this module
first has fuzzylite itself translate such a file to FLL, then raises the resolution in that FLL
text, so fuzzylite's own reader is still the one under test.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fuzzyservo._typing import FloatArray

__all__ = ["EXAMPLES", "fuzzylite_binary", "fuzzylite_eval", "fuzzylite_translate"]

#: fuzzylite's example systems as installed by the Debian package (LGPL-3+, read in place).
EXAMPLES = Path("/usr/share/doc/fuzzylite/examples")


def fuzzylite_binary() -> str:
    """Path of the ``fuzzylite`` CLI; AssertionError (a failure, not a skip) if missing."""
    exe = shutil.which("fuzzylite")
    assert exe is not None, (
        "the fuzzylite CLI is missing: run `make oracles` (apt-get install fuzzylite)")
    return exe


def _run(args: Sequence[str]) -> str:
    proc = subprocess.run([fuzzylite_binary(), *args], capture_output=True, text=True,
                          timeout=600, check=False)
    if proc.returncode != 0 or "error" in proc.stderr.lower():
        raise RuntimeError(f"fuzzylite {' '.join(args)} failed: {proc.stdout} {proc.stderr}")
    return proc.stdout


def fuzzylite_translate(text: str, fmt: str, to: str = "fll", decimals: int = 17) -> str:
    """fuzzylite's translation of a ``fmt`` file to ``to`` (its reader, then its writer, with
    ``decimals`` decimals: its default of 3 would round the parameters)."""
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / f"in.{fmt}"
        dst = Path(d) / f"out.{to}"
        src.write_text(text, encoding="utf-8")
        _run(["-i", str(src), "-if", fmt, "-o", str(dst), "-of", to, "-decimals",
              str(decimals)])
        return dst.read_text(encoding="utf-8")


_RES = re.compile(r"^(\s*defuzzifier:\s*(?:Centroid|Bisector|MeanOfMaximum|SmallestOfMaximum|"
                  r"LargestOfMaximum))(\s+\d+)?\s*$", re.MULTILINE)


def set_resolution(fll: str, resolution: int) -> str:
    """FLL text with every integral defuzzifier's resolution set to ``resolution``."""
    return _RES.sub(lambda m: f"{m.group(1)} {resolution}", fll)


def fuzzylite_eval(text: str, fmt: str, names: Sequence[str], x: FloatArray,
                   resolution: int | None = 1_000_000) -> tuple[list[str], FloatArray]:
    """Evaluate a system with fuzzylite at the points ``x`` (n, len(names)).

    Parameters
    ----------
    text, fmt : str
        The file's text and format ("fis", "fcl", "fll").
    names : sequence of str
        Input variable names, the columns of ``x``.
    x : ndarray (n, n_inputs)
        Points to evaluate.
    resolution : int or None
        Resolution of the integral defuzzifiers; None keeps the file's (or the importer's).

    Returns
    -------
    outputs : list of str
        Output variable names, in fuzzylite's order.
    y : ndarray (n, n_outputs)
        fuzzylite's values (NaN where it returns nan).
    """
    fll = text if fmt == "fll" else fuzzylite_translate(text, fmt, "fll")
    if resolution is not None:
        fll = set_resolution(fll, resolution)
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / "sys.fll"
        data = Path(d) / "in.fld"
        out = Path(d) / "out.fld"
        src.write_text(fll, encoding="utf-8")
        rows = [" ".join(names)] + [" ".join(repr(float(v)) for v in row) for row in x]
        data.write_text("\n".join(rows) + "\n", encoding="utf-8")
        _run(["-i", str(src), "-if", "fll", "-o", str(out), "-of", "fld", "-d", str(data),
              "-dheader", "true", "-dinputs", "true", "-decimals", "17"])
        lines = [ln.split() for ln in out.read_text(encoding="utf-8").splitlines() if ln.strip()]
    header, body = lines[0], lines[1:]
    n_in = len(names)
    assert header[:n_in] == list(names), f"fuzzylite reordered the inputs: {header}"
    y = np.array([[float(v) for v in row[n_in:]] for row in body], dtype=np.float64)
    return header[n_in:], y.reshape(len(body), len(header) - n_in)
