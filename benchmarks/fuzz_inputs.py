"""Fuzz every parser a user's input reaches: TOML, CSV and command-line arguments (issue 9).

Each input is either a valid one taken from the repository (the README's command lines, the
help texts' examples, ``src/fuzzyservo/data/gains/*.toml``, parameter files, run CSVs written by
``fuzzyservo simulate`` at start-up) mutated as a typo, a hostile file or a broken transfer
mutates it (a number swapped for NaN, inf, 1e308, a negative or a 400-digit integer; a name
swapped; a slice deleted, duplicated or cut; a BOM, NUL, newline, invalid byte or 140 kB field
inserted; another encoding), or random text or bytes. Every input runs, in-process, through
the library function the command line applies to it:

- ``reference``    ``parse_reference``                            (``--reference``)
- ``gains``        ``parse_gains_pairs`` + the registry's ``check_gains``  (``--gains k=v``)
- ``param``        ``parse_param`` + ``with_overrides``           (``--param``)
- ``delay``        ``delay_from_args``                            (``--delay``)
- ``params_toml``  ``read_overrides_toml`` + ``with_overrides``   (``--params FILE``)
- ``gains_toml``   ``read_gains_file`` and ``read_gains_toml``    (``--gains FILE``)
- ``run_csv``      ``read_run_csv`` (``plot``) and ``read_csv_columns(e, de)`` (``surface --at``)
- ``metrics``      the ``metrics --json`` handler; its output must be strict JSON
- ``argv``         ``build_parser().parse_args`` on mutated command lines, then the value
                   parsers the command applies (``params_from_args``, ``controller_from_args``,
                   ``parse_reference``, ``delay_from_args``)

An input passes when it is accepted or refused with a :class:`FuzzyServoError` (argparse: exit
status 2) whose message is one line; anything else fails: another exception, a message over
several lines, a warning that would reach standard error, non-strict JSON. Failures are
grouped by exception type and the place it was raised; each group is printed once with its
shortest input, and the exit status is 1.

Run: ``python benchmarks/fuzz_inputs.py [--count 100000] [--seed 0]``. Not part of ``make test``
or ``make bench`` (about two minutes for 10^5 inputs); the hypothesis properties in
``tests/cli/test_parsers_property.py`` run a small, fixed sample of the same in the suite.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import random
import re
import shlex
import sys
import tempfile
import time
import traceback
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomli_w
from tqdm import tqdm

from fuzzyservo.cli import build_parser
from fuzzyservo.cli import main as cli_main
from fuzzyservo.commands import metrics as metrics_command
from fuzzyservo.commands._plantargs import params_from_args, parse_param
from fuzzyservo.commands._runargs import controller_from_args, delay_from_args, parse_gains_pairs
from fuzzyservo.errors import FuzzyServoError
from fuzzyservo.files import read_csv_columns, read_gains_file, read_gains_toml, read_run_csv
from fuzzyservo.paper import named_set
from fuzzyservo.plant import read_overrides_toml, with_overrides
from fuzzyservo.plant.params import allowed_names, to_dict
from fuzzyservo.registry import controller_kind, controller_names
from fuzzyservo.sim import parse_reference

ROOT = Path(__file__).resolve().parents[1]
SRC = str(ROOT / "src" / "fuzzyservo")

# ---------------------------------------------------------------------------------------------
# valid inputs

REFERENCES = (
    "step:0.1", "step:0.1:0.5", "step:-0.05:0.01", "multistep:0=0.05,0.5=0.1,1=0.02",
    "ramp:0.05", "ramp:0.05:0.01", "ramp:0.5:0.01:0.1", "sine:0.01:2", "sine:0.05:10",
    "trapezoid:0.2:0.1:0.5", "trapezoid:0.2:0.1:0.5:0.01", "STEP: 0.1 ",
)
PARAMS = (
    "valve.null_leakage=0", "load.mass=40", "supply.pressure=7.5e6",
    "delay.transport_delay=0.006", "transducer.resolution=1e-6", "load.coulomb_friction=100",
    " fluid.oil_bulk_modulus = 1.4e9",
)
DELAYS = ("0", "0.006", "hose", " HOSE ", "1e-3", "0.5")
PARAM_FILES = (
    tomli_w.dumps(to_dict(named_set("paper"))),
    "[load]\nmass = 40.0\n",
    "[valve]\nnull_leakage = 0\n[supply]\npressure = 7.5e6\n",
    "# a comment\n[delay]\ntransport_delay = 0.006 # [s]\n\n[transducer]\nresolution = 1e-6\n",
)
POINTS_CSV = "e,de\n0.0,0.0\n0.5,-0.25\n-1.0,1.0\n"


def gain_pairs() -> tuple[str, ...]:
    out = ["kp=10", "kp=1,ki=0.1,kd=0.1", "ke=10,kde=5000,kdu=0.006",
           "kp=10,ki=10,kd=0.1,b=0,c=0", "kp=20,ki=2,kd=0.1", "KP = 10 , ki=1"]
    for n in controller_names():
        out.append(",".join(f"{g.name}={1.5 if g.default is None else g.default!r}"
                            for g in controller_kind(n).gains))
    return tuple(out)


def gains_files() -> tuple[str, ...]:
    files = [p.read_text(encoding="utf-8")
             for p in sorted((ROOT / "src/fuzzyservo/data/gains").glob("*.toml"))]
    for n in controller_names():
        files.append(f'controller = "{n}"\n[gains]\n' + "".join(
            f"{g.name} = {1.5 if g.default is None else g.default!r}\n"
            for g in controller_kind(n).gains))
    return tuple(files)


def run_csvs(folder: Path) -> tuple[str, ...]:
    """Run CSVs written by ``fuzzyservo simulate`` (closed and open loop, 40 ms)."""
    out = []
    for name, argv in (
            ("closed.csv", ["--plant", "linear", "--controller", "stfpi", "--gains",
                            "ke=10,kde=5000,kdu=0.006", "--duration", "0.04"]),
            ("open.csv", ["--plant", "nonlinear", "--open-loop", "--command", "0.5",
                          "--duration", "0.04"])):
        path = folder / name
        with contextlib.redirect_stdout(io.StringIO()), \
                contextlib.redirect_stderr(io.StringIO()) as err:
            status = cli_main(["simulate", *argv, "--out", str(path)])
        if status != 0:
            raise SystemExit(f"fuzz_inputs: cannot write a seed CSV: {err.getvalue()}")
        out.append(path.read_text(encoding="utf-8"))
    return tuple(out)


def readme_command_lines() -> list[list[str]]:
    """The README's ``fuzzyservo ...`` command lines, as argument lists."""
    text = (ROOT / "README.md").read_text(encoding="utf-8").replace("\\\n", " ")
    lines = []
    for line in text.splitlines():
        line = line.split("  #", 1)[0].strip()
        if line.startswith("fuzzyservo ") and " " in line:
            with contextlib.suppress(ValueError):
                argv = shlex.split(line)[1:]
                if argv and argv[0] in ("simulate", "plot", "metrics", "tune", "linearize",
                                        "surface", "reproduce"):
                    lines.append(argv)
    return lines


#: Names a mutation may put in place of a name.
WORDS = (
    *controller_names(), *(g.name for n in controller_names() for g in controller_kind(n).gains),
    *allowed_names(), *(n.split(".")[0] for n in allowed_names()),
    *(n.split(".")[1] for n in allowed_names()),
    "step", "multistep", "ramp", "sine", "trapezoid", "t", "r", "y", "u", "alpha", "e", "de",
    "controller", "gains", "tuning", "result", "metrics", "stages", "format", "overrides",
    "constraints", "bounds", "ts", "delay", "plant", "param_set", "popsize", "seed", "hose",
    "linear", "nonlinear", "small-signal", "paper", "stiff-oil",
    "", "x", "KP", "Kp", "kp ", "ä", "日本", "__class__", "nan", "inf", "true",
)
#: Numbers a mutation may put in place of a number.
NUMBERS = (
    "nan", "NaN", "-nan", "inf", "-inf", "+inf", "Infinity", "1e308", "-1e308", "1e309",
    "1e-320", "5e-324", "0", "-0", "-0.0", "-1", "-1e-9", "1e9", "1e15", "1" + "0" * 400,
    "-1" + "0" * 400, "9" * 40, "1_000", "0x1F", "0o7", "0b1", "1e", "1..0", "--1", "+", ".",
    "", " ", "١٢", "½", "true", '"1"', "[1]", "{}", "1,5", "1 2", "2025-01-01", "1e-9",
    "1e7", "100000", "0.5", "2",
)
#: Pieces a mutation may insert.
PIECES = (
    "\x00", "\ufeff", "\n", "\r\n", "\r", "\t", " ", "=", ",", ":", ".", "[", "]", "[[", "]]",
    '"', "'", '"""', "#", "\\", "\x85", "\u2028", "\udcff", "\x1b[31m", "{", "}", "=\n", "-",
    "--", "-h", "--help",
)
ALPHABETS = (
    "".join(map(chr, range(32, 127))),
    "0123456789.eE+-:=,_ ",
    "".join(map(chr, range(0, 32))) + "\x7f\x85\xa0\u2028\u2029\ufeff",
    "äöüßéñ日本語ИΩ١٢٣½²€\U0001f600",
    "\udc80\udcff\ud800",
)

#: What a command line cannot carry: NUL, and the surrogates Python's decoding of argv does
#: not produce (it maps undecodable bytes to \udc80-\udcff only).
_NOT_IN_ARGV = re.compile("[\x00\ud800-\udc7f]")
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
_WORD = re.compile(r"[A-Za-z_][A-Za-z_0-9-]*")


class Gen:
    """Inputs from one seeded ``random.Random``."""

    def __init__(self, rng: random.Random) -> None:
        self.rng = rng

    def number(self) -> str:
        r = self.rng.random()
        if r < 0.6:
            return self.rng.choice(NUMBERS)
        if r < 0.8:
            return repr(self.rng.choice((-1, 1)) * self.rng.random()
                        * 10.0 ** self.rng.randint(-323, 308))
        if r < 0.9:
            return str(self.rng.randint(-(10**30), 10**30))
        return repr(self.rng.uniform(-2, 2))

    def random_text(self, n: int = 40) -> str:
        alphabet = self.rng.choice(ALPHABETS)
        return "".join(self.rng.choice(alphabet) for _ in range(self.rng.randint(0, n)))

    def mutate(self, text: str) -> str:
        rng = self.rng
        for _ in range(rng.choice((0, 1, 1, 2, 2, 3))):
            op = rng.choice(("number", "number", "number", "word", "delete", "insert",
                             "duplicate", "truncate", "case"))
            if op in ("number", "word"):
                found = list((_NUMBER if op == "number" else _WORD).finditer(text))
                if found:
                    m = rng.choice(found)
                    new = self.number() if op == "number" else (
                        rng.choice(WORDS) if rng.random() < 0.8 else self.random_text(6))
                    text = text[:m.start()] + new + text[m.end():]
            elif op == "delete":
                i = rng.randint(0, len(text))
                text = text[:i] + text[min(len(text), i + rng.randint(1, 40)):]
            elif op == "insert":
                i = rng.randint(0, len(text))
                if rng.random() < 0.005:
                    piece = "9" * 140_000  # beyond the csv module's field limit
                else:
                    piece = rng.choice(PIECES) if rng.random() < 0.7 else self.random_text(8)
                text = text[:i] + piece + text[i:]
            elif op == "duplicate":
                i = rng.randint(0, len(text))
                j = min(len(text), i + rng.randint(1, 200))
                k = rng.randint(0, len(text))
                text = text[:k] + text[i:j] + text[k:]
            elif op == "truncate":
                text = text[:rng.randint(0, len(text))]
            else:
                text = text.upper() if rng.random() < 0.5 else text.swapcase()
        return text

    def text(self, seeds: tuple[str, ...]) -> str:
        if self.rng.random() < 0.8:
            return self.mutate(self.rng.choice(seeds))
        return self.random_text()

    def file_bytes(self, seeds: tuple[str, ...]) -> bytes:
        rng = self.rng
        r = rng.random()
        if r < 0.08:
            return rng.randbytes(rng.randint(0, 300))
        text = self.random_text(200) if r < 0.15 else self.mutate(rng.choice(seeds))
        encoding = rng.choice(("utf-8",) * 6 + ("utf-8-sig", "utf-16", "utf-16-le", "latin-1"))
        if encoding == "latin-1":
            data = text.encode("latin-1", errors="replace")
        elif "utf-16" in encoding:
            data = text.encode(encoding, errors="surrogatepass")
        elif any(0xD800 <= ord(c) < 0xDC80 for c in text):
            data = text.encode(encoding, errors="surrogatepass")
        else:  # "\udcff" becomes the invalid byte 0xff
            data = text.encode(encoding, errors="surrogateescape")
        if rng.random() < 0.1:  # cut, possibly inside a multi-byte character
            data = data[:rng.randint(0, len(data))]
        return data


# ---------------------------------------------------------------------------------------------
# checks


class BadOutcome(Exception):
    """A failure that is not an exception of the code under test: a message over several
    lines, non-strict JSON, a usage error not on one line. ``detail`` is what was printed or
    raised; ``origin`` the error of ours that carried it, if any."""

    def __init__(self, kind: str, detail: str, origin: BaseException | None = None) -> None:
        super().__init__(kind)
        self.kind, self.detail, self.origin = kind, detail, origin


#: What ends a line on a terminal or for a line-oriented tool.
LINE_BREAK = re.compile("[\n\r\v\f]")


def own_error(call: Callable[[], object]) -> bool:
    """Run ``call``: True if it succeeded, False if it refused with one of our errors (one
    line); anything else propagates."""
    try:
        call()
    except FuzzyServoError as exc:
        message = str(exc)
        if not message.strip():
            raise BadOutcome("error without a message", message, exc) from exc
        if LINE_BREAK.search(message):
            raise BadOutcome("message over several lines", message, exc) from exc
        return False
    return True


@dataclass
class Tally:
    """Outcomes of one parser's inputs, and its slowest input."""

    count: int = 0
    accepted: int = 0
    refused: int = 0
    failed: int = 0
    slowest: float = 0.0  #: [s]
    slowest_input: str = ""


@dataclass
class Failure:
    """A group of failing inputs: one exception type (or bad outcome) raised at one place."""

    kind: str  #: exception type, or what was wrong
    where: str  #: file:line (function) in fuzzyservo where it was raised
    message: str
    example: str  #: the shortest input of the group
    target: str
    n: int = 0
    trace: list[str] = field(default_factory=list)


def _where(exc: BaseException) -> tuple[str, list[str]]:
    """The innermost frame in fuzzyservo (else the innermost frame) of ``exc``."""
    frames = traceback.extract_tb(exc.__traceback__)
    ours = [f for f in frames if f.filename.startswith(SRC)]
    f = (ours or frames or [None])[-1]
    where = "?" if f is None else f"{os.path.relpath(f.filename, ROOT)}:{f.lineno} ({f.name})"
    return where, traceback.format_exception(exc)


# ---------------------------------------------------------------------------------------------
# the targets


class Targets:
    """One method per parser: each takes a ``Gen``, records the input it generated in
    ``last`` (as shown in the report) and returns whether the parser accepted it."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.paper = named_set("paper")
        self.gain_pairs = gain_pairs()
        self.gains_files = gains_files()
        self.run_csvs = run_csvs(folder)
        self.params_path = folder / "params.toml"
        self.gains_path = folder / "gains.toml"
        self.csv_path = folder / "run.csv"
        self.parser = build_parser()
        self.subparsers = self._subparsers()
        self.argv_seeds = self._argv_seeds()
        self.last = ""

    # strings -----------------------------------------------------------------------------
    def reference(self, g: Gen) -> bool:
        spec = g.text(REFERENCES)
        self.last = f"--reference {spec!r}"
        return own_error(lambda: parse_reference(spec))

    def gains(self, g: Gen) -> bool:
        text, kind = g.text(self.gain_pairs), g.rng.choice(controller_names())
        self.last = f"--controller {kind} --gains {text!r}"
        return own_error(lambda: controller_kind(kind).check_gains(parse_gains_pairs(text)))

    def param(self, g: Gen) -> bool:
        text = g.text(PARAMS)
        self.last = f"--param {text!r}"

        def call() -> None:
            name, value = parse_param(text)
            with_overrides(self.paper, {name: value})

        return own_error(call)

    def delay(self, g: Gen) -> bool:
        text = g.text(DELAYS)
        self.last = f"--delay {text!r}"
        return own_error(lambda: delay_from_args(text, self.paper))

    # files -------------------------------------------------------------------------------
    def params_toml(self, g: Gen) -> bool:
        data = g.file_bytes(PARAM_FILES)
        self.params_path.write_bytes(data)
        self.last = f"--params FILE, FILE's bytes {data!r}"
        return own_error(lambda: with_overrides(self.paper, read_overrides_toml(self.params_path)))

    def gains_toml(self, g: Gen) -> bool:
        data = g.file_bytes(self.gains_files)
        self.gains_path.write_bytes(data)
        self.last = f"--gains FILE, FILE's bytes {data!r}"
        a = own_error(lambda: read_gains_file(self.gains_path))
        b = own_error(lambda: read_gains_toml(self.gains_path))
        return a or b

    def run_csv(self, g: Gen) -> bool:
        data = g.file_bytes((*self.run_csvs, POINTS_CSV))
        self.csv_path.write_bytes(data)
        self.last = f"a CSV of bytes {data!r}"
        a = own_error(lambda: read_run_csv(self.csv_path))
        b = own_error(lambda: read_csv_columns(self.csv_path, ("e", "de"), what="points CSV"))
        return a or b

    def metrics(self, g: Gen) -> bool:
        data = g.file_bytes(self.run_csvs)
        self.csv_path.write_bytes(data)
        self.last = f"metrics --json FILE, FILE's bytes {data!r}"
        out = io.StringIO()

        def call() -> None:
            with contextlib.redirect_stdout(out):
                metrics_command.run(argparse.Namespace(csv=self.csv_path, json=True))

        def strict(name: str) -> float:
            raise BadOutcome(f"metrics --json printed {name}, which is not strict JSON",
                             out.getvalue())

        ok = own_error(call)
        if ok:
            json.loads(out.getvalue(), parse_constant=strict)
        return ok

    # command lines -----------------------------------------------------------------------
    def _subparsers(self) -> dict[str, argparse.ArgumentParser]:
        for action in self.parser._actions:  # argparse keeps its subparsers here
            if isinstance(action, argparse._SubParsersAction):
                return dict(action.choices)
        raise SystemExit("fuzz_inputs: no subcommands found")

    def _argv_seeds(self) -> list[list[str]]:
        seeds = readme_command_lines()
        seeds += [["simulate", "--plant", "linear", "--controller", "p", "--gains", "kp=10",
                   "--duration", "0.05", "--reference", r, "--out", "r.csv"]
                  for r in REFERENCES[:4]]
        seeds += [["linearize", "--params", "@PARAMS@", "--json"],
                  ["simulate", "--gains", "@GAINS@", "--params", "@PARAMS@", "--metrics"],
                  ["metrics", "@CSV@"], ["plot", "@CSV@", "--out", "x.png"],
                  ["simulate", "--plant", "linear", "--controller", "pid", "--gains",
                   "kp=1,ki=2,kd=0.1", "--delay", "hose", "--ts", "0.002", "--param",
                   "load.mass=40", "--param", "supply.pressure=7e6", "--out", "-"]]
        for argv in seeds:  # files named in the README are the fuzzed files of this run
            for i, a in enumerate(argv[:-1]):
                if argv[i] in ("--gains", "--params") and argv[i + 1].endswith(".toml"):
                    argv[i + 1] = "@GAINS@" if a == "--gains" else "@PARAMS@"
        return seeds

    def _options(self, command: str) -> list[str]:
        return [s for a in self.subparsers[command]._actions for s in a.option_strings]

    def argv(self, g: Gen) -> bool:
        rng = g.rng
        argv = list(rng.choice(self.argv_seeds))
        for _ in range(rng.choice((1, 1, 2, 3))):
            op = rng.choice(("value", "value", "value", "drop", "option", "swap", "dup",
                             "random"))
            i = rng.randrange(len(argv))
            if op == "value" and i > 0:
                argv[i] = g.mutate(argv[i])
            elif op == "drop":
                del argv[i]
            elif op == "option":
                command = argv[0] if argv and argv[0] in self.subparsers else "simulate"
                new = [rng.choice(self._options(command))]
                if rng.random() < 0.8:
                    new.append(g.text((*REFERENCES, *PARAMS, *self.gain_pairs, *DELAYS)))
                argv[i + 1:i + 1] = new
            elif op == "swap":
                argv[0] = rng.choice((*self.subparsers, "simulat", "", "--version"))
            elif op == "dup":
                argv.insert(i, argv[i])
            else:
                argv.insert(i, g.random_text(12))
            if not argv:
                argv = ["simulate"]
        files = []
        for tag, path, seeds in (("@PARAMS@", self.params_path, PARAM_FILES),
                                 ("@GAINS@", self.gains_path, self.gains_files),
                                 ("@CSV@", self.csv_path, self.run_csvs)):
            if any(tag in a for a in argv):
                data = g.file_bytes(seeds)
                path.write_bytes(data)
                files.append(f"{path.name}'s bytes {data!r}")
        argv = [_NOT_IN_ARGV.sub("", a.replace("@PARAMS@", self.params_path.name)
                                 .replace("@GAINS@", self.gains_path.name)
                                 .replace("@CSV@", self.csv_path.name))
                for a in argv]
        self.last = f"argv {argv!r}" + "".join(f"; {f}" for f in files)
        return self._parse(argv)

    def _parse(self, argv: list[str]) -> bool:
        err, out = io.StringIO(), io.StringIO()
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
                args = self.parser.parse_args(argv)
        except SystemExit as exc:
            text = err.getvalue()
            if exc.code not in (0, 2):
                raise BadOutcome(f"argparse exit status {exc.code!r}", text) from None
            if exc.code == 2:
                if not re.match(r"fuzzyservo( [a-z]+)?: error: \S", text):
                    raise BadOutcome("argparse error not 'fuzzyservo CMD: error: ...'",
                                     text) from None
                if text.count("\n") != 1 or not text.endswith("\n") or "\r" in text:
                    raise BadOutcome("argparse message over several lines", text) from None
            return exc.code == 0
        return own_error(lambda: self._apply(args))

    def _apply(self, args: argparse.Namespace) -> None:
        """The value parsers the command applies before it runs anything costly."""
        params = self.paper
        if hasattr(args, "param_overrides"):
            params = params_from_args(args)
        if args.command == "simulate":
            if not args.open_loop:
                controller_from_args(args)
            if args.reference is not None:
                parse_reference(args.reference)
            delay_from_args(args.delay, params)
        elif args.command == "tune" and getattr(args, "delay", None) is not None:
            delay_from_args(args.delay, params)


TARGETS = ("reference", "gains", "param", "delay", "params_toml", "gains_toml", "run_csv",
           "metrics", "argv")


def fuzz(count: int, seed: int, targets: list[str]
         ) -> tuple[dict[str, Tally], dict[tuple[str, str], Failure]]:
    """Run ``count`` inputs from ``random.Random(seed)``, the targets in turn."""
    gen = Gen(random.Random(seed))
    tallies = {t: Tally() for t in targets}
    failures: dict[tuple[str, str], Failure] = {}
    with tempfile.TemporaryDirectory(prefix="fuzz_inputs.") as tmp:
        fz = Targets(Path(tmp))
        cwd = os.getcwd()
        os.chdir(tmp)  # a --gains value without '=' is a file name: look in a scratch folder
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                # as fuzzyservo.cli.main: numpy floating-point warnings are not printed;
                # any other warning would reach standard error, and counts as a failure
                warnings.simplefilter("error")
                warnings.simplefilter("ignore", RuntimeWarning)
                for k in tqdm(range(count), unit="input", mininterval=0.5, smoothing=0.05,
                              file=sys.stderr):
                    name = targets[k % len(targets)]
                    tally = tallies[name]
                    tally.count += 1
                    t0 = time.perf_counter()
                    try:
                        ok = getattr(fz, name)(gen)
                    except Exception as exc:  # noqa: BLE001 - the point is to catch anything
                        tally.failed += 1
                        _record(failures, exc, name, fz.last)
                        continue
                    finally:
                        dt = time.perf_counter() - t0
                        if dt > tally.slowest:
                            tally.slowest, tally.slowest_input = dt, fz.last
                    if ok:
                        tally.accepted += 1
                    else:
                        tally.refused += 1
        finally:
            os.chdir(cwd)
    return tallies, failures


def _record(failures: dict[tuple[str, str], Failure], exc: Exception, target: str,
            example: str) -> None:
    where, trace = _where(exc)
    kind, message = type(exc).__name__, str(exc)
    if isinstance(exc, BadOutcome):
        kind, message, where = exc.kind, exc.detail, target
        if exc.origin is not None:
            where, trace = _where(exc.origin)
    f = failures.get((kind, where))
    if f is None or len(example) < len(f.example):
        n = 0 if f is None else f.n
        f = failures[kind, where] = Failure(kind, where, message[:300], example, target, n,
                                            trace)
    f.n += 1


def report(tallies: dict[str, Tally], failures: dict[tuple[str, str], Failure], seed: int,
           elapsed: float, trace_lines: int) -> int:
    """Print the summary and each failure group; return the exit status."""
    total = Tally()
    for t in tallies.values():
        total.count += t.count
        total.accepted += t.accepted
        total.refused += t.refused
        total.failed += t.failed
    print(f"\nfuzz_inputs: {total.count} inputs, seed {seed}, {elapsed:.1f} s "
          f"({total.count / elapsed:.0f} inputs/s)")
    print(f"{'parser':<12} {'inputs':>8} {'accepted':>9} {'refused':>9} {'other':>7} "
          f"{'slowest':>9}")
    for name, t in [*tallies.items(), ("total", total)]:
        slowest = f"{t.slowest * 1e3:.1f} ms" if name != "total" else ""
        print(f"{name:<12} {t.count:>8} {t.accepted:>9} {t.refused:>9} {t.failed:>7} "
              f"{slowest:>9}")
    print("(accepted: parsed; refused: a FuzzyServoError on one line, or argparse status 2 on "
          "one line; other: anything else)")
    name, t = max(tallies.items(), key=lambda kv: kv[1].slowest)
    print(f"slowest input ({name}, {t.slowest * 1e3:.1f} ms): {_clip(t.slowest_input, 300)}")
    if not failures:
        print("result: every input accepted or refused with fuzzyservo's own one-line error")
        return 0
    print(f"\nresult: {len(failures)} distinct failure(s) (exception type, where raised):")
    for f in sorted(failures.values(), key=lambda f: (f.target, -f.n)):
        print(f"\n[{f.target}] {f.kind} at {f.where}, {f.n} input(s)")
        print(f"  message: {f.message!r}")
        print(f"  shortest input: {_clip(f.example)}")
        if trace_lines and f.kind[0].isupper():  # an exception's name: show its traceback
            lines = "".join(f.trace).rstrip().splitlines()[-trace_lines:]
            print("  " + "\n  ".join(lines))
    return 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--count", type=int, default=100_000, help="inputs to try (default 10^5)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the generator (default 0)")
    ap.add_argument("--trace-lines", type=int, default=12, metavar="N",
                    help="last N lines of each failure's traceback (default 12; 0: none)")
    ap.add_argument("--only", choices=TARGETS, action="append", default=None,
                    help="fuzz only this parser (repeatable)")
    opts = ap.parse_args(argv)
    sys.stdout.reconfigure(errors="backslashreplace")  # type: ignore[union-attr]
    start = time.perf_counter()
    tallies, failures = fuzz(opts.count, opts.seed, opts.only or list(TARGETS))
    return report(tallies, failures, opts.seed, time.perf_counter() - start, opts.trace_lines)


def _clip(text: str, n: int = 1500) -> str:
    return text if len(text) <= n else f"{text[:n]}... ({len(text)} characters)"


if __name__ == "__main__":
    sys.exit(main())
