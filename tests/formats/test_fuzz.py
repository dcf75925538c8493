"""Fuzzing the three readers and writers together (issue: "parsers that fail well").

The per-format tests (test_fis.py, test_fcl.py, test_fll.py) fuzz each reader with its own
small mutations; these properties are the cross-format ones, on the generators of
``tests/formats/strategies.py`` (shared with ``benchmarks/fuzz_formats.py``, which runs 10^5
cases and more):

1. any text (random, decoded random bytes, and mostly mutated valid files: the shipped
   systems, the format tests' data and writer output of random systems) parses, or raises
   exactly ``FormatError`` on one line ``f.FMT:LINE:COL: what``, located inside the text;
   nothing in it is run as code (an audit hook sees no ``compile``, ``exec`` or process
   start, the payloads' marker file never appears); no case takes more than a few seconds;
2. a random valid system is refused by a writer with a one-line ParameterError naming the
   format, or written to a text that reads back equal (``.fis``: with each rule's clauses
   in input order, the writer's documented layout) and writes again to the same text; a
   system restricted to what a format says it holds is never refused;
3. a system read from one format and written as another reads back equal, or is refused;
4. the evaluator gives finite outputs (NaN only for an output whose default is NaN) on
   systems read from mutated files, at points inside the ranges.

Hypothesis runs derandomised (the same examples on every run) without a deadline; the
``@example`` cases and the plain tests below them are inputs the fuzzers found.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from fuzzyservo.errors import ParameterError
from fuzzyservo.formats.io import dumps, loads
from fuzzyservo.fuzzy import evaluate
from fuzzyservo.fuzzy.system import And, Consequent, FuzzySystem, Is, Rule, Term, Variable
from tests.formats.strategies import (
    CODE_PAYLOADS,
    FORMATS,
    MARKER,
    SEED_FILES,
    Broken,
    CodeWatch,
    DrawRand,
    EvalWorker,
    check_parse,
    check_round_trip,
    mutate,
    name_spans,
    number_spans,
    points,
    random_system,
    systems,
    texts,
)
from tests.helpers import count_lines

#: Most Python lines a reader may run per character of its text, plus a constant (counted
#: by tests.helpers.count_lines, never timed): the fixtures in tests/formats/data take 5-12 a
#: character; a reader quadratic in the text (a scan per token) takes thousands on a few kB.
LINES_PER_CHAR = 200
LINES_BASE = 50_000
FUZZ = settings(derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.large_base_example])

WATCH = CodeWatch()


def _watched_parse(text: str, fmt: str) -> FuzzySystem | None:
    """``check_parse`` with the code watch on and the work bounded (lines executed)."""
    MARKER.unlink(missing_ok=True)
    WATCH.start()
    try:
        s, _ = count_lines(check_parse, text, fmt,
                           limit=LINES_PER_CHAR * len(text) + LINES_BASE)
    finally:
        try:
            WATCH.stop()
        except Broken as exc:
            pytest.fail(f"{exc.kind} while reading: {exc.detail}")
    assert not MARKER.exists(), "a code payload was run"
    return s


@pytest.fixture(scope="module")
def evaluator() -> Iterator[EvalWorker]:
    worker = EvalWorker()
    yield worker
    worker.close()


# -------------------------------------------------------------------------- 1. any text


@pytest.mark.parametrize("fmt", FORMATS)
@settings(FUZZ, max_examples=300)
@given(data=st.data())
def test_any_text_parses_or_fails_on_one_located_line(fmt: str, data: st.DataObject) -> None:
    text = data.draw(texts(fmt), label="text")
    _watched_parse(text, fmt)


@pytest.mark.parametrize("fmt", FORMATS)
def test_seed_files_parse(fmt: str) -> None:
    assert SEED_FILES[fmt]
    for text in SEED_FILES[fmt]:
        assert isinstance(_watched_parse(text, fmt), FuzzySystem)


@pytest.mark.parametrize("fmt", FORMATS)
def test_code_in_a_file_is_never_run(fmt: str) -> None:
    # every payload in place of every name and every number of one seed file, and appended
    base = SEED_FILES[fmt][0]
    spans = name_spans(base)[:40] + number_spans(base)[:40] + [(len(base), len(base))]
    tried = 0
    for payload in CODE_PAYLOADS:
        for a, b in spans:
            text = base[:a] + payload + base[b:]
            assert _watched_parse(text, fmt) is None  # nothing of it is a valid name/number
            tried += 1
    assert tried >= 200


@pytest.mark.parametrize("fmt", FORMATS)
def test_deep_nesting_and_huge_numbers_fail_well(fmt: str) -> None:
    base = SEED_FILES[fmt][0]
    for piece in ("(" * 100_000, "not " * 20_000, "NOT " * 20_000, "[" * 50_000,
                  "9" * 100_000, "1e" + "9" * 5000, "-" * 10_000 + "1"):
        for at in (0, len(base) // 3, 2 * len(base) // 3, len(base)):
            _watched_parse(base[:at] + piece + base[at:], fmt)


# -------------------------------------------------------------------------- 2. round trips


@pytest.mark.parametrize("fmt", FORMATS)
@settings(FUZZ, max_examples=150)
@given(s=systems())
def test_any_system_round_trips_or_is_refused_by_name(fmt: str, s: FuzzySystem) -> None:
    check_round_trip(s, fmt)


@pytest.mark.parametrize("fmt", FORMATS)
@settings(FUZZ, max_examples=100)
@given(data=st.data())
def test_systems_a_format_holds_are_written_exactly(fmt: str, data: st.DataObject) -> None:
    s = data.draw(systems(fit=fmt), label="system")
    assert check_round_trip(s, fmt) is not None, "refused"


def _input_default_system(default: float) -> FuzzySystem:
    x = Variable("x", (0.0, 1.0), (Term("a", "triangle", (0.0, 0.5, 1.0)),), default=default)
    y = Variable("y", (0.0, 1.0), (Term("b", "triangle", (0.0, 0.5, 1.0)),), default=0.5)
    return FuzzySystem(inputs=(x,), outputs=(y,), rules=(Rule(Is(0, 0), (Consequent(0, 0),)),))


@pytest.mark.parametrize("fmt", FORMATS)
def test_an_input_default_is_refused_not_dropped(fmt: str) -> None:
    # found by the fuzzer: .fis and FCL wrote an input's default nowhere, so it read back NaN
    s = _input_default_system(0.25)
    with pytest.raises(ParameterError, match=r"default 0\.25 of input 'x'"):
        dumps(s, fmt)
    assert check_round_trip(_input_default_system(math.nan), fmt) is not None


# -------------------------------------------------------------------------- 3. conversions


@pytest.mark.parametrize("source", FORMATS)
@settings(FUZZ, max_examples=80)
@given(data=st.data())
def test_conversions_are_exact_or_refused(source: str, data: st.DataObject) -> None:
    s = data.draw(systems(fit=source), label="system")
    read = loads(dumps(s, source), source, f"a.{source}")
    for target in FORMATS:
        check_round_trip(read, target)


# -------------------------------------------------------------------------- 4. evaluation


@st.composite
def parsed_systems(draw: st.DrawFn, fmt: str) -> FuzzySystem:
    """A system read from a mutated file (the first of ten mutants that parses; else the
    unmutated file)."""
    r = DrawRand(draw)
    s = random_system(r, fmt)
    text = dumps(s, fmt)
    for _ in range(10):
        read = check_parse(mutate(r, text, fmt), fmt)
        if read is not None:
            return read
    return loads(text, fmt)


@pytest.mark.parametrize("fmt", FORMATS)
@settings(FUZZ, max_examples=60, phases=[Phase.explicit, Phase.generate])
@given(data=st.data())
def test_parsed_mutants_evaluate_to_finite_values(fmt: str, data: st.DataObject,
                                                   evaluator: EvalWorker) -> None:
    s = data.draw(parsed_systems(fmt), label="system")
    x = data.draw(points(s), label="points")
    try:
        evaluator(s, x)
    except Broken as exc:
        pytest.fail(f"{exc.kind}: {exc.detail}")


def test_evaluator_worker_reports_a_crash_as_a_failure(evaluator: EvalWorker) -> None:
    s = _input_default_system(math.nan)
    evaluator(s, np.array([[0.5]]))  # a healthy call
    with pytest.raises(Broken, match="not finite|died|Error"):
        evaluator(s, np.array([[math.inf]]))  # the evaluator's InputError, reported


def _one_rule(out: Variable, term: Term, aggregation: str = "max", weight: float = 1.0
              ) -> FuzzySystem:
    x = Variable("x", (0.0, 1.0), (Term("a", "triangle", (0.0, 0.5, 1.0)),))
    y = Variable(out.name, out.range, (term,), default=out.default)
    return FuzzySystem(inputs=(x,), outputs=(y,), rules=(
        Rule(Is(0, 0), (Consequent(0, 0),), weight),), aggregation=aggregation)  # type: ignore[arg-type]


#: Systems on which the fuzzer found the evaluator aborting ("double free or corruption"):
#: with NUMBA_DISABLE_JIT=1 each raised IndexError at ``acc_a[n_acc] = a`` in
#: ``general._smooth``: once ``n_acc`` reached the buffer's capacity every interval still on
#: the stack was accepted and written past its end (now the record grows).
SMOOTH_OVERFLOW = {
    "huge range, probor": _one_rule(Variable("y", (-1e300, 1e300), ()), Term(
        "b", "triangle", (-1e300, 0.0, 1e300)), "probor"),
    "tiny range, s term": _one_rule(Variable("y", (-1e-300, 1e-300), (), default=0.0), Term(
        "b", "s", (-1.2168660655856767e-300, -7.5e-301)), "sum", 1.0 / 3.0),
}


@pytest.mark.parametrize("case", sorted(SMOOTH_OVERFLOW))
def test_smooth_quadrature_stays_in_its_buffer(case: str, evaluator: EvalWorker) -> None:
    evaluator(SMOOTH_OVERFLOW[case], np.array([[0.25], [0.5]]))


def test_centroid_of_a_symmetric_set_on_a_huge_range() -> None:
    # analytic: the centroid of a triangle symmetric about 0 is 0, whatever the scale; the
    # tolerance is the rounding of a value of the range's size
    for big in (1e100, 1e160, 1e300):
        s = _one_rule(Variable("y", (-big, big), ()), Term("b", "triangle", (-big, 0.0, big)))
        y = evaluate(s, [[0.25]])[0, 0]
        assert abs(y) <= 1e-12 * big, (big, y)




def _many_rules(n_terms: int, n_rules: int) -> FuzzySystem:
    terms = tuple(Term(f"t{i}", "triangle", (i, i + 1.0, i + 2.0)) for i in range(n_terms))
    top = n_terms + 2.0
    inputs = tuple(Variable(f"x{k}", (0.0, top), terms) for k in range(3))
    out = Variable("y", (0.0, top), terms, default=top / 2)
    rules = tuple(Rule(And((Is(0, r % n_terms), Is(1, 7 * r % n_terms), Is(2, 13 * r % n_terms))),
                       (Consequent(0, r % n_terms),)) for r in range(n_rules))
    return FuzzySystem(inputs=(*inputs,), outputs=(out,), rules=rules)


def _read_lines(text: str, fmt: str) -> int:
    """Python lines run to read ``text`` (tests.helpers.count_lines: the work, not the time,
    which the suite's other processes share), after one read that fills the caches (the
    regular expressions compiled on first use)."""
    loads(text, fmt)
    return count_lines(loads, text, fmt)[1]


@pytest.mark.parametrize("fmt", FORMATS)
def test_reading_a_rule_does_not_scan_the_terms(fmt: str) -> None:
    # found by a large-file check: FCL and FLL looked each clause's term up by a scan of
    # the variable's terms, so 10^5 rules over 1000-term variables took about a minute, and
    # FCL compared each new term name with all before it. Counted, not timed (issue 29: the
    # timed version failed under load): 500 rules over 1000-term variables must run about
    # the lines of 500 rules over 10-term ones (measured: a factor 1.02-1.09, from the longer
    # names; a scan per clause makes it about 100), and 1000 terms about 100 times the lines
    # of 10 (measured 83-91; comparing each new name with those before makes it about 10^4).
    many, few = (dumps(_many_rules(n, 500), fmt) for n in (1000, 10))
    many_0, few_0 = (dumps(_many_rules(n, 0), fmt) for n in (1000, 10))
    rules_many = _read_lines(many, fmt) - _read_lines(many_0, fmt)
    rules_few = _read_lines(few, fmt) - _read_lines(few_0, fmt)
    assert rules_many < 1.5 * rules_few, (rules_many, rules_few)
    assert _read_lines(many_0, fmt) < 1.5 * 100 * _read_lines(few_0, fmt)
