"""RunSpec: one description of a run; its command line round-trips, and the command, the page
and the sweep take exactly the options the registry declares."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzyservo.cli import build_parser, main
from fuzzyservo.errors import ParameterError, UsageError
from fuzzyservo.registry import (
    DEFAULT_SUBSTEP,
    ControllerKind,
    OptionSpec,
    controller_colour,
    controller_kind,
    controller_names,
    controller_options,
    register_controller,
    unregister_controller,
)
from fuzzyservo.run import RunSpec

_FLOATS = st.floats(allow_nan=False, allow_infinity=False, width=64)
_POSITIVE = st.floats(min_value=1e-9, max_value=1e3, allow_nan=False)


@st.composite
def run_specs(draw: st.DrawFn) -> RunSpec:
    name = draw(st.sampled_from(controller_names()))
    kind = controller_kind(name)
    gains = tuple((g.name, draw(st.floats(min_value=0.0, max_value=1e6) | st.just(math.inf)))
                  for g in kind.gains if draw(st.booleans()))
    options = []
    for o in kind.options:
        if o.offered and draw(st.booleans()):
            options.append((o.name, draw(st.sampled_from(o.choices)) if o.choices
                            else draw(_FLOATS)))
    systems = tuple((role, draw(st.sampled_from(["a.fis", "dir/b c.fll"])))
                    for role in kind.systems if draw(st.booleans()))
    noise = draw(st.sampled_from([0.0, 1e-6, -2e-6]))
    return RunSpec(
        controller=name, gains=gains, options=tuple(options), systems=systems,
        no_rule_value=draw(st.none() | _FLOATS),
        plant=draw(st.sampled_from(["linear", "small-signal", "nonlinear"])),
        param_set=draw(st.sampled_from(["paper", "stiff-oil"])),
        overrides=tuple(draw(st.dictionaries(st.sampled_from(["load.mass", "supply.pressure"]),
                                             _FLOATS, max_size=2)).items()),
        reference=draw(st.sampled_from(["step:0.1", "sine:0.05:0.5", "multistep:0=0.05,2=0.1"])),
        duration=draw(_POSITIVE), ts=draw(_POSITIVE), delay=draw(_FLOATS),
        noise_std=noise, seed=draw(st.integers(0, 2**31)), start=draw(_FLOATS),
        load_force=draw(st.sampled_from(["", "step:500:0.1", "pwl:0:0,1:-20", "-x.csv"])),
        substep=draw(st.just(DEFAULT_SUBSTEP) | _POSITIVE))


@settings(max_examples=200, deadline=None)
@given(spec=run_specs(), explicit=st.booleans())
def test_the_command_line_round_trips(spec: RunSpec, explicit: bool) -> None:
    assert RunSpec.from_argv(spec.to_argv(explicit=explicit)) == spec
    assert RunSpec.from_argv(["simulate", *spec.to_argv()]) == spec


@settings(max_examples=100, deadline=None)
@given(spec=run_specs())
def test_the_simulate_command_reads_the_same_run(spec: RunSpec) -> None:
    """The CLI's parser takes every command line to_argv writes, with the same values."""
    args = build_parser(raising=True, argv=["simulate"]).parse_args(
        ["simulate", *spec.to_argv(), "--metrics"])
    assert args.controller == spec.controller and args.plant == spec.plant
    assert (args.duration, args.ts, args.start, args.substep) == (
        spec.duration, spec.ts, spec.start, spec.substep)
    assert float(args.delay or 0.0) == spec.delay
    assert (args.noise_std, args.seed) == (spec.noise_std, spec.seed)
    assert args.load_force == spec.load_force
    for name, value in spec.options:
        assert getattr(args, name) == value
    assert (args.param_set or "paper") == spec.param_set


def test_from_argv_refuses_what_it_cannot_describe() -> None:
    with pytest.raises(UsageError, match="unrecognized arguments: --out"):
        RunSpec.from_argv(["--controller", "pid", "--out", "x.csv"])
    with pytest.raises(UsageError, match="--delay"):
        RunSpec.from_argv(["--controller", "pid", "--delay", "hose"])


def test_a_run_spec_runs_as_the_command(capsys: pytest.CaptureFixture[str]) -> None:

    spec = RunSpec(controller="pi", gains=(("kp", 20.0), ("ki", 2.0)), plant="linear",
                   duration=0.5, noise_std=1e-6, seed=4, options=(("anti_windup", "none"),))
    result = spec.run()
    assert main(["simulate", *spec.to_argv(), "--metrics"]) == 0
    shown = dict(ln.split()[:2] for ln in capsys.readouterr().out.splitlines())
    assert shown == {k: f"{v:.6g}" for k, v in result.metrics().as_dict().items()}


def test_build_names_the_flag_as_the_command_does() -> None:
    with pytest.raises(ParameterError, match=r"^--de-per does not apply to controller pid "):
        RunSpec(controller="pid", gains=(("kp", 1.0), ("ki", 0.0), ("kd", 0.0)),
                options=(("de_per", "second"),)).build()
    with pytest.raises(ParameterError, match=r"^--start must be a fraction"):
        RunSpec(controller="p", gains=(("kp", 1.0),), start=2.0).build()


# ---------------------------------------------------------------- options declared once


def _cli_flags() -> set[str]:
    parser = build_parser(argv=["simulate"])
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    sim = sub.choices["simulate"]
    return {s for a in sim._actions for s in a.option_strings}


def test_the_cli_the_page_and_the_sweep_take_exactly_the_declared_options(
        tmp_path: Path) -> None:
    declared = {o.name for n in controller_names() for o in controller_kind(n).options
                if o.offered}
    assert {o.name for o in controller_options()} == declared
    flags = _cli_flags()
    assert {o.flag for o in controller_options()} <= flags
    # no flag of the command looks like an option the registry does not declare
    known = {"--anti-windup", "--initial-error", "--de-per", "--filter-time",
             "--integral-action", "--reference-jerk"}
    assert known == {o.flag for o in controller_options()}
    pytest.importorskip("panel")
    from fuzzyservo.app.page import ServoPage

    page = ServoPage(workdir=tmp_path)
    assert set(page.w_options) == declared
    from fuzzyservo.sweep import parse_spec

    for name in controller_names():
        kind = controller_kind(name)
        gains = {g: 1.0 for g in kind.required}
        for o in kind.options:
            value = o.choices[-1] if o.choices else 0.001
            doc = {"sweep": {}, "controllers": [{"controller": name, "gains": gains,
                                                 "options": {o.name: value}}]}
            if o.offered:
                parse_spec(doc)
            else:
                with pytest.raises(ParameterError, match="cannot be set in a sweep"):
                    parse_spec(doc)


def test_a_user_option_reaches_every_front_end() -> None:
    base = controller_kind("pid")
    extra = OptionSpec(name="tracking_mode", choices=("a", "b"), default="a",
                       help="test law: a made-up option")
    register_controller(ControllerKind(
        name="pidx", title="PID with an extra option", cls=base.cls, gains=base.gains,
        implied=base.implied, options=(*base.options, extra)))
    try:
        assert "--tracking-mode" in _cli_flags()
        assert controller_colour("pidx").startswith("#")
        spec = RunSpec(controller="pidx", options=(("tracking_mode", "b"),))
        assert "--tracking-mode=b" in spec.to_argv()
        assert RunSpec.from_argv(spec.to_argv()) == spec
        clash = OptionSpec(name="tracking_mode", type=float, default=0.0)
        with pytest.raises(ParameterError, match="declared otherwise by controller pidx"):
            register_controller(ControllerKind(
                name="pidy", title="clash", cls=base.cls, gains=base.gains,
                implied=base.implied, options=(clash,)))
    finally:
        unregister_controller("pidx")
        unregister_controller("pidy")
    assert "--tracking-mode" not in _cli_flags()


def test_the_study_draws_each_design_in_its_kinds_colour() -> None:
    """The kinds' colours are declared once, in the registry: the study draws a design in its
    kind's colour, and only a design that shares its kind with another has one of its own;
    no two designs of the study (the tracking study's baselines included) share a colour."""
    from fuzzyservo.registry import controller_names
    from fuzzyservo.study.paper_study import DESIGN_COLOURS, baseline_cases, study_cases
    from fuzzyservo.study.runner import default_gains_dir, load_tuned

    designs = {k: (v.controller, dict(v.gains))
               for k, v in load_tuned("linear", default_gains_dir()).items()}
    cases = [*study_cases(designs), *baseline_cases(designs)]  # the tracking study's
    kinds = [c.kind for c in cases]
    for c in cases:
        if c.key in DESIGN_COLOURS:
            assert kinds.count(c.kind) > 1, c.key  # its own colour only beside its kind's
        else:
            assert c.colour == controller_colour(c.kind)
    drawn = [c.colour for c in cases] + [DESIGN_COLOURS["stfpi_delay"]]  # + Fig. 8's
    assert len(set(drawn)) == len(drawn)
    assert len({controller_colour(n) for n in controller_names()}) == len(controller_names())
    assert controller_colour("no-such-kind") == "#aec7e8"  # the fallback's first


@pytest.mark.parametrize("controller", ["pid2", "stfpi"])
def test_export_takes_the_runs_controller(controller: str, tmp_path: Path) -> None:
    """RunSpec.controller_args is the run's controller as ``export`` reads it: the export's
    header records that controller, its gains, options and sample time (the page's C and
    FMU downloads are made with it)."""
    gains = {"pid2": (("kp", 3.5), ("ki", 0.25), ("kd", 0.125), ("n", 50.0), ("b", 0.5),
                      ("c", 0.0)),
             "stfpi": (("ke", 10.0), ("kde", 5000.0), ("kdu", 0.006))}[controller]
    options = {"pid2": (("anti_windup", "back-calculation"),),
               "stfpi": (("de_per", "second"), ("filter_time", 0.01))}[controller]
    spec = RunSpec(controller=controller, gains=gains, options=options, ts=0.002)
    out = tmp_path / "c"
    assert main(["export", "c", *spec.controller_args(), "--out", str(out)]) == 0
    header = (out / f"{controller}.h").read_text()
    kind = controller_kind(controller)
    recorded = {g.name: g for g in kind.gains}
    assert f" * controller:  {controller} (" in header
    assert " * gains:       " + ", ".join(
        f"{k} = {v!r} {recorded[k].unit}" for k, v in gains) + "\n" in header
    for name, value in options:
        assert f"{name} = {value}" in header
    assert " * sample time: 0.002 s\n" in header

