"""Issue 29, item 1: no text from outside reaches the generated C or XML unescaped.

Exports C code and FMUs through the command line with hostile output folders, gains-file
paths and fuzzy-system file paths (comment ends, newlines, a constructor with ``system()``,
quotes, ``#``, ``<``, trigraphs, control characters, non-ASCII, an undecodable byte), then
asks independent tools what came out: gcc compiles each file under the strict flags (where
``-Wcomment`` and ``-Wtrigraphs`` are errors), ``nm`` lists the symbols the objects and the
FMUs' libraries define (exactly those of the same export from a plain folder), the XML
parser reads the model description (the command verbatim), and the comment block read back
by the decoder below gives the command verbatim. Hostile ``--name`` values are refused in one
line.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest
from fmpy.validation import validate_fmu

from fuzzyservo import __version__
from fuzzyservo.cli import main
from fuzzyservo.formats import write_system
from fuzzyservo.fuzzy import FuzzySystem, Term, Variable
from fuzzyservo.paper import paper_fuzzy_system
from tests.export.cbuild import STRICT, gcc

ROOT = Path(__file__).resolve().parents[2]
GAINS = ROOT / "src" / "fuzzyservo" / "data" / "gains"

#: Folder names that end a C comment, start a line, or carry what C, XML or a shell treat
#: specially. Each must stay text.
HOSTILE = [
    "x*/ int INJECTED; /*",
    "y\n*/ __attribute__((constructor)) static void pwn(void) { system(\"id\"); } /*",
    "q\"uote's #define EVIL 1 <b>&amp;</b> ??/ \\",
    "\u00e9t\u00e9 \u6f22\u5b57 \U0001f600 \x01ctl\r\ttab",
    "bad\udcffbyte",  # a byte that is not UTF-8: argv and os decode it as a lone surrogate
]


def _nm(path: Path, *flags: str) -> set[str]:
    """The names of the symbols ``path`` defines (nm --defined-only)."""
    nm = shutil.which("nm")
    assert nm is not None, "nm (binutils) is needed with gcc"
    proc = subprocess.run([nm, "--defined-only", *flags, str(path)], capture_output=True,
                          text=True, check=True)
    return {ln.split()[-1] for ln in proc.stdout.splitlines() if ln.strip()}


def _compile(c_file: Path, out: Path) -> Path:
    proc = subprocess.run([gcc(), *STRICT, "-O2", "-c", str(c_file), "-o", str(out)],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    return out


def _unescape(text: str) -> str:
    """The comment's text read back, as docs/export.md gives the escapes: ``\\\\`` a
    backslash, ``\\/`` ``\\*`` ``\\?`` the broken ``*/``, ``/*``, ``??``, ``\\n`` ``\\r``
    ``\\t``, ``\\xNN`` ``\\uNNNN`` ``\\UNNNNNNNN`` a character (written independently of the
    package's escaper)."""
    simple = {"\\": "\\", "/": "/", "*": "*", "?": "?", "n": "\n", "r": "\r", "t": "\t"}
    out, i = [], 0
    while i < len(text):
        ch = text[i]
        if ch != "\\":
            out.append(ch)
            i += 1
            continue
        nxt = text[i + 1]
        if nxt in simple:
            out.append(simple[nxt])
            i += 2
        else:
            width = {"x": 2, "u": 4, "U": 8}[nxt]
            out.append(chr(int(text[i + 2:i + 2 + width], 16)))
            i += 2 + width
    return "".join(out)


def _command_line(text: str) -> str:
    """The ``command:`` line of a generated file's comment block, read back."""
    lines = [ln for ln in text.splitlines() if ln.startswith(" * command:")]
    assert len(lines) == 1, lines
    return _unescape(lines[0].removeprefix(" * command:").strip())


def _du_system(path: Path) -> Path:
    """The paper's du system with its output triangles as degenerate trapezoids (the same
    sets; not the paper's own system, so the export records its file)."""
    s = paper_fuzzy_system("du")
    o = s.outputs[0]
    out = Variable(o.name, o.range, tuple(
        Term(t.name, "trapezoid", (t.params[0], t.params[1], t.params[1], t.params[2]))
        for t in o.terms), o.default)
    write_system(FuzzySystem.from_table(
        [[o.terms[k].name for k in row] for row in s.rule_table()], columns=s.inputs[0],
        rows=s.inputs[1], output=out, name=s.name), path)
    return path


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same exports from plain paths: the symbols hostile ones must equal."""
    d = tmp_path_factory.mktemp("plain")
    assert main(["export", "c", "--gains", str(GAINS / "linear-stfpi.toml"), "--du-system",
                 str(_du_system(d / "du.fll")), "--out", str(d / "c")]) == 0
    assert main(["export", "fmu", "--gains", str(GAINS / "linear-stfpi.toml"), "--out",
                 str(d / "ctl.fmu")]) == 0
    assert main(["export", "fmu", "--plant", "linear", "--out", str(d / "servo.fmu")]) == 0
    return {"c": _compile(d / "c" / "stfpi.c", d / "c.o"), "ctl": d / "ctl.fmu",
            "servo": d / "servo.fmu"}


def _hostile_inputs(base: Path, hostile: str) -> tuple[Path, Path, Path]:
    """A folder of that name holding a gains file and a fuzzy system file whose names are
    hostile too."""
    folder = base / hostile
    folder.mkdir(parents=True)
    gains = folder / f"g {hostile}.toml"
    for stem in ("g", "s", "out", "ctl", "servo"):  # a "/" in the name makes folders
        (folder / f"{stem} {hostile}").parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(GAINS / "linear-stfpi.toml", gains)
    system = _du_system(folder / f"s {hostile}.fll")
    return folder, gains, system


@pytest.mark.parametrize("index", range(len(HOSTILE)))
def test_hostile_paths_stay_text_in_the_c_code(index: int, tmp_path: Path,
                                               plain: dict[str, Path]) -> None:
    hostile = HOSTILE[index]
    folder, gains, system = _hostile_inputs(tmp_path, hostile)
    out = folder / f"out {hostile}"
    argv = ["export", "c", "--gains", str(gains), "--du-system", str(system), "--out",
            str(out)]
    assert main(argv) == 0
    header = (out / "stfpi.h").read_bytes()
    source = (out / "stfpi.c").read_bytes()
    assert header.isascii() and source.isascii()
    for text in (header.decode(), source.decode()):
        assert _command_line(text) == "fuzzyservo " + shlex.join(argv[0:])
        # the fuzzy system's file is named (its path escaped the same way)
        line = next(ln for ln in text.splitlines() if ln.startswith(" *   du from "))
        assert _unescape(line.removeprefix(" *   du from ").split(" (file SHA-256")[0]) == \
            str(system)
    obj = _compile(out / "stfpi.c", tmp_path / "hostile.o")
    assert _nm(obj) == _nm(plain["c"])  # locals too: nothing added, no constructor
    assert {s for s in _nm(obj, "--extern-only")} == {
        "stfpi_init", "stfpi_reset", "stfpi_step", "stfpi_step_ff", "stfpi_set_gains",
        "stfpi_gain_name", "stfpi_gain_default", "stfpi_alpha"}


def _description(fmu: Path) -> str:
    with zipfile.ZipFile(fmu) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    return root.attrib["description"]


def _xml_expected(text: str) -> str:
    """What XML 1.0 can hold of ``text``: all but control characters other than tab, CR,
    LF and lone surrogates, which the export writes as their escapes (by hand here)."""
    def one(ch: str) -> str:
        o = ord(ch)
        if (o < 0x20 and ch not in "\t\n\r") or 0xD800 <= o <= 0xDFFF:
            return f"\\x{o:02x}" if o < 0x100 else f"\\u{o:04x}"
        return ch
    return "".join(one(ch) for ch in text)


def _library_symbols(fmu: Path, tmp: Path, dynamic: bool) -> set[str]:
    with zipfile.ZipFile(fmu) as zf:
        so = next(n for n in zf.namelist() if n.endswith(".so"))
        lib = tmp / f"lib{int(dynamic)}.so"
        lib.write_bytes(zf.read(so))
    return _nm(lib, "-D") if dynamic else _nm(lib)


@pytest.mark.parametrize("index", range(len(HOSTILE)))
def test_hostile_paths_stay_text_in_the_fmus(index: int, tmp_path: Path,
                                             plain: dict[str, Path]) -> None:
    hostile = HOSTILE[index]
    folder, gains, _system = _hostile_inputs(tmp_path, hostile)
    for key, argv in (("ctl", ["--gains", str(gains)]), ("servo", ["--plant", "linear"])):
        out = folder / f"{key} {hostile}.fmu"
        full = ["export", "fmu", *argv, "--out", str(out)]
        assert main(full) == 0
        assert validate_fmu(str(out)) == []
        command = "fuzzyservo " + shlex.join(full)
        expected = (f"self-tuning fuzzy PI controller exported by fuzzyservo {__version__} "
                    f"({command})" if key == "ctl" else f"linear servo exported by {command}")
        assert _description(out) == _xml_expected(expected)
        # the libraries define the very symbols of the plain export: the FMI functions
        # exported, nothing more (no constructor, no INJECTED), locals included
        assert _library_symbols(out, tmp_path, True) == _library_symbols(plain[key], tmp_path,
                                                                          True)
        assert _library_symbols(out, tmp_path, False) == _library_symbols(plain[key],
                                                                           tmp_path, False)
        with zipfile.ZipFile(out) as zf:
            for n in zf.namelist():
                if n.startswith("sources/"):
                    assert zf.read(n).isascii(), n
    assert _library_symbols(plain["ctl"], tmp_path, True) == FMI2_CS


#: The functions of the FMI 2.0 co-simulation API (the standard's fmi2Functions.h).
FMI2_CS = {"fmi2" + f for f in (
    "GetTypesPlatform GetVersion SetDebugLogging Instantiate FreeInstance SetupExperiment "
    "EnterInitializationMode ExitInitializationMode Terminate Reset GetReal GetInteger "
    "GetBoolean GetString SetReal SetInteger SetBoolean SetString GetFMUstate SetFMUstate "
    "FreeFMUstate SerializedFMUstateSize SerializeFMUstate DeSerializeFMUstate "
    "GetDirectionalDerivative SetRealInputDerivatives GetRealOutputDerivatives DoStep "
    "CancelStep GetStatus GetRealStatus GetIntegerStatus GetBooleanStatus "
    "GetStringStatus").split()}


@pytest.mark.parametrize("name", ["", "math", "stdint", "string", "stddef", "stdio", "stdlib",
                                  "Math", "STRING", "float", "int", "bool", "a*/b", "x\ny",
                                  "\u00e9t\u00e9", "x y", "#x", "x<y", "_x", "9x"])
def test_a_hostile_name_is_refused_in_one_line(name: str, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    for target, out in (("c", tmp_path / "code"), ("fmu", tmp_path / "ctl.fmu")):
        assert main(["export", target, "--controller", "pi", "--gains", "kp=1,ki=1",
                     "--name", name, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("fuzzyservo: error: --name"), err
        assert not out.exists()
    # the servo FMU takes the same check
    assert main(["export", "fmu", "--plant", "linear", "--name", name, "--out",
                 str(tmp_path / "s.fmu")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_a_header_name_says_what_it_would_shadow(capsys: pytest.CaptureFixture[str],
                                                 tmp_path: Path) -> None:
    assert main(["export", "c", "--controller", "pi", "--gains", "kp=1,ki=1", "--name",
                 "stdint", "--out", str(tmp_path / "c")]) == 2
    line = capsys.readouterr().err.strip()
    assert "'stdint'" in line and "<stdint.h>" in line


def test_an_undecodable_output_path_prints_one_line(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    out = os.fsdecode(os.fsencode(str(tmp_path)) + b"/\xff\nx")
    assert main(["export", "c", "--controller", "pi", "--gains", "kp=1,ki=1", "--out",
                 out]) == 0
    printed = capsys.readouterr().out
    assert len(printed.strip().splitlines()) == 1 and re.search(r"\\udcff\\nx", printed)
    assert (Path(out) / "pi.c").exists()
