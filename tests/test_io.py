"""fuzzyservo._io: atomic writes, checked output paths, strict UTF-8 and JSON
(docs/guarantees.md)."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo._io import (
    MAX_INPUT_BYTES,
    MAX_NESTING,
    atomic_write,
    check_output_path,
    open_input,
    parse_json,
    parse_toml,
    read_bytes,
    read_text,
    strict_json,
    write_text_atomic,
    write_texts_atomic,
)
from fuzzyservo.errors import InputError, OutputError
from fuzzyservo.sim.result import write_csv

SRC = Path(__file__).resolve().parents[1] / "src" / "fuzzyservo"


def _visible(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_an_exception_inside_the_block_leaves_the_old_file_and_no_temporary(
        tmp_path: Path) -> None:
    target = tmp_path / "keep.csv"
    target.write_bytes(b"old contents\n")
    with pytest.raises(KeyError), atomic_write(target) as fh:
        fh.write("new, half written")
        raise KeyError("boom")
    assert target.read_bytes() == b"old contents\n"
    assert _visible(tmp_path) == ["keep.csv"]  # the temporary file is gone


def test_a_keyboard_interrupt_inside_the_block_leaves_the_old_file(tmp_path: Path) -> None:
    target = tmp_path / "keep.toml"
    target.write_bytes(b"a = 1\n")
    with pytest.raises(KeyboardInterrupt), atomic_write(target) as fh:
        fh.write("a = 2\n")
        raise KeyboardInterrupt
    assert target.read_bytes() == b"a = 1\n"
    assert _visible(tmp_path) == ["keep.toml"]


def test_the_file_size_limit_is_an_output_error_and_the_old_file_survives(
        tmp_path: Path) -> None:
    """RLIMIT_FSIZE set in a child process: the write fails half-way (EFBIG)."""
    target = tmp_path / "keep.bin"
    old = os.urandom(300_000)
    target.write_bytes(old)
    code = (
        "import resource, sys\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (50_000, 50_000))\n"
        "from fuzzyservo._io import write_bytes_atomic\n"
        "from fuzzyservo.errors import OutputError\n"
        "try:\n"
        f"    write_bytes_atomic({str(target)!r}, b'x' * 200_000)\n"
        "except OutputError as exc:\n"
        "    print(exc); sys.exit(3)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=False)
    assert res.returncode == 3, res.stderr
    assert "File too large" in res.stdout and "keep.bin" in res.stdout
    assert target.read_bytes() == old
    assert _visible(tmp_path) == ["keep.bin"]


def test_a_missing_folder_is_an_output_error(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match="nodir"):
        write_text_atomic(tmp_path / "nodir" / "x.txt", "x")


def test_new_files_get_the_umask_mode_and_old_files_keep_theirs(tmp_path: Path) -> None:
    mask = os.umask(0o022)
    try:
        new = write_text_atomic(tmp_path / "new.txt", "x")
        assert new.stat().st_mode & 0o777 == 0o644  # not mkstemp's 0600
        old = tmp_path / "old.txt"
        old.write_text("x")
        old.chmod(0o640)
        write_text_atomic(old, "y")
        assert old.stat().st_mode & 0o777 == 0o640 and old.read_text() == "y"
    finally:
        os.umask(mask)


def test_output_paths_are_checked_before_any_work(tmp_path: Path) -> None:
    (tmp_path / "adir").mkdir()
    with pytest.raises(InputError, match="is a folder"):
        check_output_path(tmp_path / "adir", option="--plot")
    with pytest.raises(InputError, match="does not exist"):
        check_output_path(tmp_path / "nodir" / "x.toml")
    src = tmp_path / "in.toml"
    src.write_text("[load]\n")
    with pytest.raises(InputError, match="also an input"):
        check_output_path(tmp_path / "." / "in.toml", inputs=[None, src])
    link = tmp_path / "link.toml"
    link.symlink_to(src)
    with pytest.raises(InputError, match="also an input"):
        check_output_path(link, inputs=[src])
    assert check_output_path(tmp_path / "out.toml", inputs=[src]) == tmp_path / "out.toml"


@pytest.mark.parametrize(("data", "needle"), [
    (b"[load]\nmass = 1\n\xff\xfe rest", "byte 0xff at offset 16"),
    ("[load]\n".encode("utf-16"), "UTF-16"),
    (b"ok = 1\n\x00", "NUL character at offset 7"),
])
def test_text_that_is_not_utf8_is_refused_with_the_offset(tmp_path: Path, data: bytes,
                                                          needle: str) -> None:
    p = tmp_path / "bin.toml"
    p.write_bytes(data)
    with pytest.raises(InputError) as err:
        read_text(p, "parameter file")
    assert needle in str(err.value) and "bin.toml" in str(err.value)
    assert "\n" not in str(err.value)


def test_a_utf8_byte_order_mark_is_skipped(tmp_path: Path) -> None:
    p = tmp_path / "bom.toml"
    p.write_bytes(b"\xef\xbb\xbf[load]\n")
    assert read_text(p) == "[load]\n"


def test_strict_json_writes_null_for_nan_and_infinities() -> None:
    text = strict_json({"a": math.nan, "b": [math.inf, -math.inf, 1.5], "c": np.float64(2.0)})

    def refuse(token: str) -> None:
        raise AssertionError(f"non-standard JSON token {token}")

    assert json.loads(text, parse_constant=refuse) == {"a": None, "b": [None, None, 1.5],
                                                       "c": 2.0}


def test_csv_floats_are_the_shortest_text_that_reads_back_exactly(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    t = np.arange(20_000) * 1e-3  # k * ts: 2445 * 0.001 is 2.4450000000000003 in binary
    cols = [t, rng.normal(size=t.size) * 1e-3, np.full(t.size, 2.445),
            np.where(t > 10, np.nan, -np.inf)]
    out = tmp_path / "r.csv"
    write_csv(out, ["t", "a", "b", "c"], cols)
    lines = out.read_text().splitlines()
    assert lines[0] == "t,a,b,c" and len(lines) == t.size + 1
    assert lines[1 + 2445].split(",")[2] == "2.445"  # no 2.4450000000000003 noise
    back = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    for j, c in enumerate(cols):
        np.testing.assert_array_equal(back[:, j], c)  # bit-exact, NaN and inf included


def test_csv_writer_memory_does_not_grow_with_the_run(tmp_path: Path) -> None:
    """The writer formats fixed-size blocks straight from the arrays: the memory it takes
    above the arrays is the same for 10 000 and 80 000 rows (the issue's bound is 200 MB
    above the arrays at 10 million rows; benchmarks/bench_csv.py measures that)."""
    peaks = []
    for n in (10_000, 80_000):
        cols = [np.linspace(0.0, 1.0, n) for _ in range(8)]
        tracemalloc.start()
        write_csv(tmp_path / "big.csv", [f"c{i}" for i in range(8)], cols)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        peaks.append(peak)
    assert peaks[1] < 1.5 * peaks[0] and peaks[1] < 30e6, peaks


def test_no_pickle_anywhere_in_the_package() -> None:
    hits = [f"{p.relative_to(SRC)}:{i}" for p in SRC.rglob("*.py")
            for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
            if re.search(r"\b(import\s+(c?pickle|dill|shelve|marshal)|from\s+(c?pickle|dill|"
                         r"shelve|marshal)\s+import|allow_pickle\s*=\s*True)", line)]
    assert not hits, hits


def test_a_symbolic_link_is_followed_and_kept(tmp_path: Path) -> None:
    (tmp_path / "real").mkdir()
    target = tmp_path / "real" / "data.csv"
    target.write_text("old\n")
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    write_text_atomic(link, "new\n")
    assert link.is_symlink() and target.read_text() == "new\n"
    assert sorted(p.name for p in (tmp_path / "real").iterdir()) == ["data.csv"]


def test_a_fifo_is_written_into_not_replaced(tmp_path: Path) -> None:
    """Like /dev/null or /dev/stdout: a target that is not a regular file has nothing to keep
    and must not be replaced by one (as root, --out /dev/null would have replaced the
    device)."""
    import threading

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    write_csv(fifo, ["t", "y"], [np.array([0.0, 0.001]), np.array([0.5, 0.25])])
    reader.join(timeout=10)
    assert got == [b"t,y\n0.0,0.5\n0.001,0.25\n"]
    assert fifo.is_fifo()
    assert check_output_path(fifo) == fifo


def test_several_files_are_written_as_one(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                          ) -> None:
    a, b = tmp_path / "x.c", tmp_path / "x.h"
    a.write_text("old c")
    b.write_text("old h")
    # an error before the renames (the second file's folder is gone): both old files stay
    with pytest.raises(OutputError, match="previous files, if any, are unchanged"):
        write_texts_atomic({a: "new c", tmp_path / "gone" / "x.h": "new h"})
    assert a.read_text() == "old c" and sorted(p.name for p in tmp_path.iterdir()) == [
        "x.c", "x.h"]
    # Ctrl-C between the two renames is held back until both are done, then delivered
    real = os.replace
    done: list[str] = []

    def replace(src: str | Path, dst: str | Path) -> None:
        real(src, dst)
        done.append(str(dst))
        if len(done) == 1:
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(os, "replace", replace)
    # Python's Ctrl-C handler, whatever this process inherited (started in the background, a
    # process ignores SIGINT, and so would the signal raised here)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            write_texts_atomic({a: "new c", b: "new h"})
    finally:
        signal.signal(signal.SIGINT, previous)
    assert (a.read_text(), b.read_text()) == ("new c", "new h") and len(done) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.c", "x.h"]  # no temporaries


# --------------------------------------------- issue 29: bounded reads and bounded nesting


def test_a_fifo_without_a_writer_is_refused_without_blocking(tmp_path: Path) -> None:
    """In a child process with a timeout: a read that blocked would fail the test."""
    fifo = tmp_path / "spec.toml"
    os.mkfifo(fifo)
    code = ("from fuzzyservo._io import read_text\nfrom fuzzyservo.errors import InputError\n"
            f"try:\n    read_text({str(fifo)!r}, 'sweep spec')\n"
            "except InputError as e:\n    print(e)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, check=True)
    assert proc.stdout == (f"sweep spec '{fifo}' is a FIFO (named pipe), not a regular file; "
                           f"give a file\n")


@pytest.mark.parametrize(("path", "kind"), [("/dev/zero", "a character device"),
                                            ("/dev/null", "a character device"),
                                            (".", "a folder")])
def test_only_regular_files_are_read(path: str, kind: str) -> None:
    with pytest.raises(InputError, match=re.escape(f"file '{path}' is {kind}, not a regular")):
        read_bytes(path)


def test_reads_are_bounded(tmp_path: Path) -> None:
    f = tmp_path / "f.txt"
    f.write_bytes(b"x" * 10)
    assert read_bytes(f, limit=10) == b"x" * 10
    assert read_text(f, limit=10) == "x" * 10
    with pytest.raises(InputError, match=f"^spec '{re.escape(str(f))}' is larger than the "
                                         f"9-byte limit of an input file$"):
        read_bytes(f, "spec", limit=9)
    assert MAX_INPUT_BYTES == 16 * 1024 * 1024
    with open_input(f) as fh:
        assert fh.read() == b"x" * 10


def _nested_toml(depth: int) -> str:
    return "a = " + "[" * depth + "]" * depth + "\n"


def test_toml_nesting_is_bounded_before_parsing() -> None:
    assert MAX_NESTING == 64
    value = parse_toml(_nested_toml(64), "t")["a"]
    for _ in range(63):
        (value,) = value
    assert value == []
    for text in (_nested_toml(65), _nested_toml(5000),
                 "a = " + "{b = " * 5000 + "1" + "}" * 5000,
                 "a" + ".b" * 65 + " = 1",
                 "[" + ".".join(["t"] * 5000) + "]\nx = 1"):
        with pytest.raises(InputError, match=r"^spec 's.toml' nests .*more than 64 levels"):
            parse_toml(text, "spec 's.toml'")


def test_brackets_in_toml_strings_and_comments_do_not_count() -> None:
    deep = "[" * 5000
    text = (f'a = "{deep}"\nb = \'{deep}\'\nc = """\n{deep}\n"""\nd = \'\'\'{deep}\'\'\'\n'
            f'# {deep}\ne = "\\"{deep}"\n[t]\nf = [[1, 2], {{g = [3]}}]\n')
    doc = parse_toml(text, "t")
    assert doc["a"] == doc["b"] == doc["d"] == deep and doc["c"] == deep + "\n"
    assert doc["e"] == '"' + deep and doc["t"] == {"f": [[1, 2], {"g": [3]}]}


def test_toml_errors_are_one_line() -> None:
    with pytest.raises(InputError, match=r"^gains file 'g.toml' is not valid TOML: [^\n]+$"):
        parse_toml("a = [\n\n", "gains file 'g.toml'")


def test_json_nesting_is_bounded_before_parsing() -> None:
    assert parse_json("[" * 64 + "]" * 64, "j") is not None
    assert parse_json('{"a": "' + "[" * 5000 + '", "b": [1, {"c": 2}]}', "j")["b"] == [
        1, {"c": 2}]
    for text in ("[" * 65 + "]" * 65, "[" * 5000 + "]" * 5000, '{"a": ' * 5000 + "1" +
                 "}" * 5000):
        with pytest.raises(InputError, match=r"^manifest 'm.json' nests .*more than 64"):
            parse_json(text, "manifest 'm.json'")
    with pytest.raises(InputError, match=r"^j is not valid JSON: Expecting"):
        parse_json("[1,", "j")


# ---- output folders: no link followed, their data never replaced (issue 29) --------------

from fuzzyservo._io import confined, refuse_links, result_data_of  # noqa: E402


def test_inside_a_confined_folder_a_link_is_refused_not_written_through(
        tmp_path: Path) -> None:
    out, victim = tmp_path / "out", tmp_path / "victim.txt"
    (out / "sub").mkdir(parents=True)
    victim.write_text("victim\n", encoding="utf-8")
    (out / "link.csv").symlink_to(victim)
    (out / "linked").symlink_to(tmp_path, target_is_directory=True)
    with confined(out):
        with pytest.raises(OutputError, match="link.csv.* is a symbolic link inside the "
                                              "output folder"):
            write_text_atomic(out / "link.csv", "new\n")
        with pytest.raises(OutputError, match="linked.* is a symbolic link inside"):
            write_text_atomic(out / "linked" / "victim.txt", "new\n")
        with pytest.raises(OutputError, match="is a symbolic link"):
            write_texts_atomic({out / "link.csv": "new\n"})
        write_text_atomic(out / "sub" / "x.csv", "x\n")  # real folders: written as usual
    assert victim.read_text(encoding="utf-8") == "victim\n"
    assert (out / "link.csv").is_symlink()
    assert (out / "sub" / "x.csv").read_text(encoding="utf-8") == "x\n"
    assert _visible(out / "sub") == ["x.csv"] and _visible(out) == ["link.csv", "linked", "sub"]
    write_text_atomic(out / "link.csv", "followed\n")  # outside the block: as documented
    assert victim.read_text(encoding="utf-8") == "followed\n"


def test_a_confined_write_replaces_a_link_put_in_its_place_while_it_writes(
        tmp_path: Path) -> None:
    out, victim = tmp_path / "out", tmp_path / "victim.txt"
    out.mkdir()
    victim.write_text("victim\n", encoding="utf-8")
    with confined(out), atomic_write(out / "a.csv") as fh:
        fh.write("ours\n")
        (out / "a.csv").symlink_to(victim)  # after the check, before the rename
    assert victim.read_text(encoding="utf-8") == "victim\n"
    assert not (out / "a.csv").is_symlink()
    assert (out / "a.csv").read_text(encoding="utf-8") == "ours\n"


def test_refuse_links_names_a_link_or_a_fifo_anywhere_below(tmp_path: Path) -> None:
    out = tmp_path / "out"
    (out / "traces").mkdir(parents=True)
    (out / "traces" / "a.csv").write_text("a\n", encoding="utf-8")
    refuse_links(out, what="output folder")
    (out / "traces" / "b.csv").symlink_to(tmp_path / "elsewhere.csv")
    with pytest.raises(OutputError, match="holds a symbolic link, 'traces/b.csv'"):
        refuse_links(out, what="output folder")
    refuse_links(out, what="output folder", entries=["manifest.json"])  # only those
    (out / "traces" / "b.csv").unlink()
    os.mkfifo(out / "traces" / "c.csv")
    with pytest.raises(OutputError, match="'traces/c.csv', which is not a regular file"):
        refuse_links(out, what="output folder")


def test_an_output_path_that_would_replace_a_sweep_or_study_file_is_refused(
        tmp_path: Path) -> None:
    sweep = tmp_path / "sweep"
    (sweep / "chunks").mkdir(parents=True)
    (sweep / "manifest.json").write_text(json.dumps({"digest": "0" * 64, "n_chunks": 1}),
                                         encoding="utf-8")
    for rel, what in (("manifest.json", "its manifest"), ("spec.toml", "its spec"),
                      ("chunks/chunk-000000.parquet", "its chunks")):
        with pytest.raises(InputError, match=f"would replace {what} \\(the sweep folder"):
            check_output_path(sweep / rel)
    assert check_output_path(sweep / "report.html") == sweep / "report.html"
    study = tmp_path / "study"
    (study / "traces").mkdir(parents=True)
    (study / "manifest.json").write_text(json.dumps(
        {"fuzzyservo": "1", "complete": True, "outputs": {"traces/fig4.csv": "ab"}}),
        encoding="utf-8")
    with pytest.raises(InputError, match="would replace an output its manifest lists"):
        check_output_path(study / "traces" / "fig4.csv")
    with pytest.raises(InputError, match="would replace its cache"):
        check_output_path(study / ".cache" / "x.npz")
    assert result_data_of(study / "notes.txt") is None
    # a link into the folder is judged where it leads
    (tmp_path / "m.json").symlink_to(sweep / "manifest.json")
    assert result_data_of(tmp_path / "m.json") is not None
    # a manifest.json of some other program makes no folder a result folder
    other = tmp_path / "web"
    other.mkdir()
    (other / "manifest.json").write_text('{"name": "app"}', encoding="utf-8")
    assert result_data_of(other / "manifest.json") is None


def test_nesting_is_bounded_before_parsing_and_strings_do_not_count() -> None:
    import tomllib

    deep = "[" * 5000 + "]" * 5000
    with pytest.raises(InputError, match="nests arrays or tables more than 64 levels deep"):
        parse_json(deep, "x")
    with pytest.raises(RecursionError):  # what the check spares the parser
        json.loads(deep)
    with pytest.raises(InputError, match=r"\(line 2\)"):
        parse_toml("x = 1\ny = " + "{a = " * 65 + "1" + "}" * 65, "x")
    brackets = '"' + "[" * 100 + '\\"' + "{" * 100 + '"'
    assert parse_json("[" + brackets + "]", "x") == ["[" * 100 + '"' + "{" * 100]
    toml = ("a = '" + "[" * 100 + "'\nb = '''" + "[" * 100 + "''''\n# " + "[" * 100
            + "\nc = \"\"\"" + "{" * 100 + "\"\"\"\"\"\n")
    assert parse_toml(toml, "x")["b"] == tomllib.loads(toml)["b"] == "[" * 100 + "'"
    nested = ".".join(["a"] * 100) + " = 1"  # dotted keys: no bracket; the parsed depth
    with pytest.raises(InputError, match="more than 64 levels deep"):
        parse_toml(nested, "x")
    assert parse_toml("a = [[1, {b = 2}]]", "x") == {"a": [[1, {"b": 2}]]}
