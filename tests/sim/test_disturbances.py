"""Load-force profiles (sim/disturbances.py): parsing, values, sampling and bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.errors import InputError
from fuzzyservo.sim.disturbances import (
    LoadPoints,
    LoadStep,
    load_force_samples,
    parse_load_force,
)


def test_none_is_empty_text() -> None:
    assert parse_load_force("") is None
    assert parse_load_force("  ") is None


def test_step_is_zero_before_and_f_from_t_on() -> None:
    prof = parse_load_force("step:500:0.25")
    assert prof == LoadStep(500.0, 0.25)
    t = np.array([0.0, 0.249, 0.25, 1.0])
    assert prof.values(t).tolist() == [0.0, 0.0, 500.0, 500.0]  # exact: a step
    assert parse_load_force("step:-20") == LoadStep(-20.0, 0.0)
    assert parse_load_force(LoadStep(500.0, 0.25).text()) == prof


def test_pwl_interpolates_and_holds_both_ends() -> None:
    prof = parse_load_force("pwl:0.1:0,0.3:200,0.5:-100")
    assert isinstance(prof, LoadPoints)
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 2.0])
    # interpolation of exact binary fractions of the points: to rounding
    np.testing.assert_allclose(prof.values(t), [0, 0, 100, 200, 50, -100, -100], atol=1e-9)


def test_csv_profile_reads_like_pwl(tmp_path: Path) -> None:
    f = tmp_path / "load.csv"
    f.write_text("# a force profile\nt,F\n0.1,0\n0.3,200\n0.5,-100\n", encoding="utf-8")
    prof = parse_load_force(str(f))
    pwl = parse_load_force("pwl:0.1:0,0.3:200,0.5:-100")
    t = np.linspace(0.0, 1.0, 101)
    assert np.array_equal(prof.values(t), pwl.values(t))


def test_samples_add_the_sets_force_and_are_taken_at_the_instants() -> None:
    t = np.arange(5) * 0.1
    f = load_force_samples(parse_load_force("pwl:0:0,0.4:400"), t, base=50.0)
    np.testing.assert_allclose(f, [50, 150, 250, 350, 450], atol=1e-9)  # rounding only


@pytest.mark.parametrize(("spec", "words"), [
    ("step:inf:0.1", ["step F", "finite", "inf"]),
    ("step:nan", ["step F", "finite"]),
    ("step:100:-1", ["step time T", ">= 0", "-1"]),
    ("step:100:1:2", ["step:F[:T]"]),
    ("step:abc", ["'abc' is not a number", "allowed"]),
    ("pwl:0:0,0.5:10,0.2:5", ["increase strictly", "0.5", "0.2"]),
    ("pwl:0:0,0.5", ["a point is T:F"]),
    ("pwl:-1:0", ["point time", ">= 0"]),
    ("ramp:10", ["unknown --load-force", "step:F[:T], pwl:", "FILE.csv"]),
    ("500", ["unknown --load-force"]),
])
def test_bad_forms_are_one_line_naming_value_and_what_is_allowed(spec: str,
                                                                 words: list[str]) -> None:
    with pytest.raises(InputError) as info:
        parse_load_force(spec)
    msg = str(info.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


@pytest.mark.parametrize(("text", "words"), [
    ("t,G\n0,1\n", ["lacks column(s) F"]),
    ("t,F\n0,1\n0,2\n", ["increase strictly"]),
    ("t,F\n0,x\n", ["'x' is not a number"]),
    ("t,F\n0,inf\n", ["not finite"]),
    ("", ["is empty"]),
])
def test_bad_csv_files_are_one_line(tmp_path: Path, text: str, words: list[str]) -> None:
    f = tmp_path / "bad.csv"
    f.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as info:
        parse_load_force(str(f))
    msg = str(info.value)
    assert "\n" not in msg and "load-force CSV" in msg
    for w in words:
        assert w in msg, (w, msg)


def test_missing_csv_is_named(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="load-force CSV"):
        parse_load_force(str(tmp_path / "nope.csv"))
