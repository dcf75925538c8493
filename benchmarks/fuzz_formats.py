"""Fuzz the fuzzy-system file readers and writers: MATLAB .fis, IEC 61131-7 FCL, fuzzylite FLL.

The generators and checks are those of ``tests/formats/test_fuzz.py`` (written once, in
``tests/formats/strategies.py``), driven here by a plain ``numpy.random.Generator`` instead of
hypothesis, so that 10^5 cases take minutes. Cases go round the three formats; four in five
are texts, one in five a random system:

- a text (mostly a valid file, shipped, from the tests' data, fuzzylite's installed examples
  or a writer's output of a random system, mutated: lines deleted, repeated or swapped,
  keywords, names and numbers such as 1e309, nan, -0 or 400-digit integers inserted or
  swapped in, deep nesting, truncation, CRLF, BOM, code; else random text or decoded random
  bytes) must parse, or raise exactly ``FormatError`` with one line ``f.FMT:LINE:COL: what``
  located inside the text. A parsed system is then evaluated at four points inside its
  ranges (finite outputs; NaN only where the output's default is NaN) and written as each
  format (the conversions): the writer refuses it with a one-line ParameterError naming the
  format, or the text reads back to the same system and writes again to the same text;
- a random valid system (``random_system``: every shape, operator and defuzzifier, nested
  rules, defaults, keyword names; a quarter of each kind restricted to what one format can
  hold, which that writer must then accept) is evaluated and written as each format, with the
  same round-trip checks.

Nothing may be run as code: a sys.audit hook fails any case during which ``compile``,
``os.system``, a process start or an ``exec`` other than an import's happens, and the code
payloads' marker file must never appear. A case slower than ``--slow`` seconds fails.

Failures are grouped by stage, kind and the place they were raised; each group is printed
once with its smallest input, which is also written under ``--out`` (the text as a file of
its format, a system as its ``repr``) with its traceback; the exit status is then 1. The
evaluator runs in a child process (a crash or a hang of its compiled code, e.g. an
out-of-bounds write, is a failure of the stage ``evaluate``; ``NUMBA_DISABLE_JIT=1`` on the
reproducer shows the line); its time is not counted in a case's.

Run: ``python benchmarks/fuzz_formats.py [--count 100000] [--seed 0]``. Not part of
``make test`` (which runs about 2,000 hypothesis cases of the same generators).
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
import traceback
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fuzzyservo.errors import ParameterError  # noqa: E402
from fuzzyservo.formats.io import dumps  # noqa: E402
from fuzzyservo.fuzzy.system import FuzzySystem  # noqa: E402
from tests.formats.strategies import (  # noqa: E402
    FORMATS,
    MARKER,
    Broken,
    CodeWatch,
    EvalWorker,
    NumpyRand,
    check_parse,
    check_round_trip,
    choice,
    random_system,
    random_text,
    sample_points,
)

ROOT = Path(__file__).resolve().parents[1]
SRC = str(ROOT / "src" / "fuzzyservo")
EXAMPLES = Path("/usr/share/doc/fuzzylite/examples")

@dataclass
class Tally:
    """Outcomes for one format."""

    texts: int = 0
    parsed: int = 0
    refused: int = 0
    other: int = 0  #: parse raised something else or failed a check
    systems: int = 0  #: random systems written as this format
    written: int = 0  #: round trips (systems and parsed texts) that held
    writer_refused: int = 0
    rt_failed: int = 0
    evaluated: int = 0
    eval_failed: int = 0
    slowest: float = 0.0  #: slowest case of this format [s]
    slowest_what: str = ""
    refusals: Counter[str] = field(default_factory=Counter)


@dataclass
class Failure:
    """One group of failures: a stage, a kind and where it was raised."""

    stage: str
    kind: str
    where: str
    message: str
    example: str  #: smallest input (a text, or a system's repr)
    suffix: str  #: file suffix of the reproducer
    trace: str
    n: int = 0


def _where(exc: BaseException) -> str:
    frames = traceback.extract_tb(exc.__traceback__)
    ours = [f for f in frames if f.filename.startswith(SRC)]
    if not (ours or frames):
        return "?"
    f = (ours or frames)[-1]
    return f"{os.path.relpath(f.filename, ROOT)}:{f.lineno} ({f.name})"


def _template(msg: str) -> str:
    """A refusal message with its names and numbers blanked, to count the reasons."""
    return re.sub(r"'[^']*'|-?\d[\w.+-]*|\([^)]*\)", "_", msg)[:90]


def _examples() -> dict[str, tuple[str, ...]]:
    out: dict[str, list[str]] = {f: [] for f in FORMATS}
    if EXAMPLES.is_dir():
        for p in sorted(EXAMPLES.rglob("*")):
            if p.suffix[1:] in out and p.is_file():
                out[p.suffix[1:]].append(p.read_text(encoding="utf-8", errors="replace"))
    return {f: tuple(v) for f, v in out.items()}


class Fuzzer:
    """Runs the cases and keeps the tallies and failure groups."""

    def __init__(self, seed: int, formats: list[str], examples: bool, slow: float) -> None:
        self.r = NumpyRand(np.random.default_rng(seed))
        self.formats = formats
        self.extra = _examples() if examples else {f: () for f in FORMATS}
        self.slow = slow
        self.tallies = {f: Tally() for f in formats}
        self.convert: Counter[tuple[str, str, str]] = Counter()
        self.failures: dict[tuple[str, str, str], Failure] = {}
        self.audit = CodeWatch()
        self.evaluator = EvalWorker()

    def fail(self, stage: str, exc: BaseException, example: str, suffix: str) -> None:
        if isinstance(exc, Broken):
            kind, where = exc.kind, stage
            message = exc.detail
        else:
            kind, where, message = type(exc).__name__, _where(exc), str(exc)
        key = (stage, kind, where)
        f = self.failures.get(key)
        trace = "".join(traceback.format_exception(exc))
        if f is None or len(example) < len(f.example):
            n = 0 if f is None else f.n
            f = self.failures[key] = Failure(stage, kind, where, message[:2000], example,
                                             suffix, trace, n)
        f.n += 1

    def round_trips(self, s: FuzzySystem, source: str, origin: str) -> None:
        """``s`` written as each format (a conversion when it was read from ``source``)."""
        for fmt in self.formats:
            t = self.tallies[fmt]
            try:
                text = check_round_trip(s, fmt)
            except Exception as exc:  # noqa: BLE001 - anything else is a failure
                t.rt_failed += 1
                self.convert[source, fmt, "failed"] += 1
                self.fail(f"write {fmt}", exc, repr(s), ".py")
                continue
            if text is None:
                t.writer_refused += 1
                self.convert[source, fmt, "refused"] += 1
                try:
                    dumps(s, fmt)
                except ParameterError as exc:
                    t.refusals[_template(str(exc))] += 1
                if origin == fmt:
                    t.rt_failed += 1
                    self.fail(f"write {fmt}", Broken(
                        "a system the format can hold was refused",
                        str(_refusal(s, fmt))), repr(s), ".py")
            else:
                t.written += 1
                self.convert[source, fmt, "equal"] += 1

    def evaluate(self, s: FuzzySystem, fmt: str) -> None:
        t = self.tallies[fmt]
        t.evaluated += 1
        try:
            self.evaluator(s, sample_points(self.r, s))
        except Exception as exc:  # noqa: BLE001
            t.eval_failed += 1
            self.fail("evaluate", exc, repr(s), ".py")

    def text_case(self, fmt: str) -> None:
        t = self.tallies[fmt]
        t.texts += 1
        text = random_text(self.r, fmt, self.extra[fmt])
        start = time.perf_counter()
        try:
            self.audit.start()
            try:
                s = check_parse(text, fmt)
            finally:
                self.audit.stop()
        except Exception as exc:  # noqa: BLE001
            t.other += 1
            self.fail(f"read {fmt}", exc, text, f".{fmt}")
            return
        finally:
            self._timed(t, start, f"read {fmt} ({len(text)} characters)", text, fmt)
        if s is None:
            t.refused += 1
            return
        t.parsed += 1
        self.evaluate(s, fmt)
        start = time.perf_counter()
        self.round_trips(s, fmt, "")
        self._timed(t, start, "writing a parsed system", text, f".{fmt}")

    def system_case(self, fmt: str) -> None:
        fit = choice(self.r, (None, *FORMATS))
        s = random_system(self.r, fit)
        self.tallies[fmt].systems += 1
        self.evaluate(s, fmt)
        start = time.perf_counter()
        self.round_trips(s, "system", fit or "")
        self._timed(self.tallies[fmt], start, "writing a random system", repr(s), ".py")

    def _timed(self, t: Tally, start: float, what: str, example: str, suffix: str) -> None:
        dt = time.perf_counter() - start
        if dt > t.slowest:
            t.slowest, t.slowest_what = dt, what
        if dt > self.slow:
            self.fail("time", Broken(f"slower than {self.slow} s", f"{dt:.2f} s: {what}"),
                      example, suffix if suffix.startswith(".") else f".{suffix}")

    def run(self, count: int) -> None:
        MARKER.unlink(missing_ok=True)
        for k in tqdm(range(count), unit="case", mininterval=1.0, smoothing=0.05,
                      file=sys.stderr):
            fmt = self.formats[k % len(self.formats)]
            if (k // len(self.formats)) % 5 == 4:
                self.system_case(fmt)
            else:
                self.text_case(fmt)
            if MARKER.exists():
                MARKER.unlink()
                self.fail("read", Broken("code was run", f"{MARKER} was created"), "", ".txt")


def _refusal(s: FuzzySystem, fmt: str) -> str:
    try:
        dumps(s, fmt)
    except ParameterError as exc:
        return str(exc)
    return "not refused"


def report(fz: Fuzzer, count: int, seed: int, elapsed: float, out: Path,
           trace_lines: int) -> int:
    """Print the summary and the failure groups; write the reproducers; the exit status."""
    print(f"\nfuzz_formats: {count} cases, seed {seed}, {elapsed:.0f} s "
          f"({count / elapsed:.0f} cases/s); seeds: repository files"
          + (f" and {sum(map(len, fz.extra.values()))} fuzzylite examples"
             if any(fz.extra.values()) else ""))
    print("\nreading texts (parsed: a system; refused: FormatError on one located line; "
          "other: anything else)")
    print(f"{'format':<7}{'texts':>8}{'parsed':>8}{'refused':>9}{'other':>7}"
          f"{'slowest case':>14}")
    for fmt, t in fz.tallies.items():
        print(f"{fmt:<7}{t.texts:>8}{t.parsed:>8}{t.refused:>9}{t.other:>7}"
              f"{t.slowest * 1e3:>11.1f} ms  ({t.slowest_what})")
    print("\nwriting (random systems and parsed texts, written as the format and read back)")
    print(f"{'format':<7}{'systems':>8}{'equal':>8}{'refused':>9}{'failed':>8}"
          f"{'evaluated':>11}{'eval failed':>13}")
    for fmt, t in fz.tallies.items():
        print(f"{fmt:<7}{t.systems:>8}{t.written:>8}{t.writer_refused:>9}{t.rt_failed:>8}"
              f"{t.evaluated:>11}{t.eval_failed:>13}")
    print("\nconversions of parsed texts (from -> to: equal / refused / failed)")
    for a in fz.formats:
        cells = [f"{b}: {fz.convert[a, b, 'equal']}/{fz.convert[a, b, 'refused']}/"
                 f"{fz.convert[a, b, 'failed']}" for b in fz.formats]
        print(f"  {a} -> " + "   ".join(cells))
    print("\nmost frequent refusals by the writers")
    for fmt, t in fz.tallies.items():
        for msg, n in t.refusals.most_common(5):
            print(f"  {fmt} {n:>6}  {msg}")
    if not fz.failures:
        print("\nresult: no failure (every text parsed or refused with one located "
              "FormatError; every round trip equal or refused by name; every evaluation "
              "finite or NaN by default; no code run)")
        return 0
    out.mkdir(parents=True, exist_ok=True)
    print(f"\nresult: {len(fz.failures)} distinct failure(s); reproducers in {out}")
    for i, f in enumerate(sorted(fz.failures.values(), key=lambda f: (f.stage, -f.n)), 1):
        path = out / f"failure{i}{f.suffix}"
        path.write_text(f.example, encoding="utf-8", errors="surrogateescape")
        (out / f"failure{i}.traceback.txt").write_text(f.trace, encoding="utf-8",
                                                       errors="backslashreplace")
        print(f"\n[{f.stage}] {f.kind} at {f.where}: {f.n} case(s); input {path}")
        print(f"  message: {f.message[:500]!r}")
        if trace_lines and not f.kind[0].islower():
            lines = f.trace.rstrip().splitlines()[-trace_lines:]
            print("  " + "\n  ".join(lines))
    return 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--count", type=int, default=100_000, help="cases (default 10^5)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the generator (default 0)")
    ap.add_argument("--only", choices=FORMATS, action="append", default=None,
                    help="fuzz only this format (repeatable)")
    ap.add_argument("--no-examples", action="store_true",
                    help="do not use fuzzylite's installed examples as seeds")
    ap.add_argument("--slow", type=float, default=5.0, metavar="S",
                    help="a case slower than S seconds fails (default 5)")
    ap.add_argument("--out", type=Path, default=Path("/tmp/fuzz_formats"),
                    help="folder for the failures' reproducers (default /tmp/fuzz_formats)")
    ap.add_argument("--trace-lines", type=int, default=10, metavar="N",
                    help="last N lines of each failure's traceback (default 10)")
    opts = ap.parse_args(argv)
    sys.stdout.reconfigure(errors="backslashreplace")  # type: ignore[union-attr]
    fz = Fuzzer(opts.seed, opts.only or list(FORMATS), not opts.no_examples, opts.slow)
    # warm up (first imports, numba's compilation) with another seed, outside the tallies
    fz.r = NumpyRand(np.random.default_rng(opts.seed + 1_000_003))
    with np.errstate(all="ignore"):
        for k in range(30 * len(fz.formats)):
            fmt = fz.formats[k % len(fz.formats)]
            fz.system_case(fmt) if k % 10 == 0 else fz.text_case(fmt)
    warm = dict(fz.failures)
    fz.r = NumpyRand(np.random.default_rng(opts.seed))
    fz.tallies = {f: Tally() for f in fz.formats}
    fz.convert.clear()
    fz.failures = {k: f for k, f in warm.items() if f.stage != "time"}
    start = time.perf_counter()
    with np.errstate(all="ignore"):
        fz.run(opts.count)
    fz.evaluator.close()
    return report(fz, opts.count, opts.seed, time.perf_counter() - start, opts.out,
                  opts.trace_lines)


if __name__ == "__main__":
    sys.exit(main())
