"""``fuzzyservo fis eval|convert|info|show``: fuzzy systems from MATLAB .fis, IEC 61131-7 FCL and
fuzzylite FLL files (the format is named by the file's extension, :mod:`fuzzyservo.formats`).

- ``fis eval FILE (--at POINTS.csv | --grid N) [--out OUT.csv] [--no-rule-value V]``: the
  system's exact outputs (:func:`fuzzyservo.fuzzy.evaluate`). POINTS.csv has a header
  with one column per input, named as in the file, in any order (other columns are ignored;
  lines starting with ``#`` too). ``--grid N`` evaluates N points over the input's range (one
  input) or an N x N grid over the inputs' ranges (two inputs; the first input varies fastest).
  The CSV written (standard output without ``--out`` or with ``--out -``) has the input columns
  in the system's order, then one column per output, named as in the file; every value is
  written with ``repr`` (reads back to the same float). Where no rule fires for an output,
  the value is the output's default: in a .fis file the middle of its range (MATLAB's
  convention, the only one .fis can state); in FCL and FLL the file's ``DEFAULT`` /
  ``default:``, NaN when absent (fuzzylite's convention), written ``nan``.
  ``--no-rule-value V`` replaces every NaN default by V (a default the file sets is kept).
- ``fis convert IN OUT``: read IN and write OUT in the format of OUT's extension, atomically.
  A system the target format cannot hold (a term shape, a height, a NaN default in .fis, ...)
  is refused on one line naming what, and nothing is written; OUT may not be IN. The reader's
  notes (names it had to change, values it ignored) are printed on standard error.
- ``fis info FILE [--json]``: name, kind, operators, every variable (range, default, clip,
  terms with their parameters named as in :data:`~fuzzyservo.fuzzy.shapes.SHAPES`), every rule
  as text and the reader's notes. ``--json`` prints one strict JSON object (RFC 8259): NaN and
  infinities are ``null`` (a NaN default is "no value"; an infinite parameter is a trapezoid
  shoulder's foot, ``a`` at -inf or ``d`` at +inf).
- ``fis show FILE --out FIG.png|svg [--grid N]``: the membership functions of every variable
  and the response (two inputs: each output's control surface on an N x N grid, 81 by
  default; one input: each output's curve, 401 points by default plus every vertex of the
  input's terms), :mod:`fuzzyservo.plots.systems`.

Every output path is checked before any work (:func:`fuzzyservo._io.check_output_path`: its
folder exists and is writable, it is not a folder, not an input) and written atomically.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import sys
from pathlib import Path
from typing import IO, Any

import numpy as np

from .._io import atomic_write, check_output_path, strict_json, write_text_atomic
from .._typing import FloatArray
from ..errors import InputError, ParameterError
from ..files import read_csv_columns
from ..formats import FORMATS, dumps, format_of, read_system
from ..fuzzy import evaluate
from ..fuzzy.shapes import SHAPES
from ..fuzzy.system import FuzzySystem, Term, Variable
from ..plots.runs import FIGURE_FORMATS
from . import HELP

__all__ = [
    "MAX_GRID",
    "MAX_SHOW_GRID",
    "describe",
    "describe_text",
    "param_names",
    "register",
    "run_convert",
    "run_eval",
    "run_info",
    "run_show",
    "with_no_rule_value",
]

#: Largest --grid of ``fis eval`` (points per input): a 1000 x 1000 grid is a million points
#: and a 60 MB CSV, about 10 s on a loaded two-core machine; 4000 (the former bound, 16
#: million points) took over 100 s (issue 29). More points: give them with --at.
MAX_GRID = 1000
#: Largest --grid of ``fis show`` (a figure of more points shows nothing more).
MAX_SHOW_GRID = 501

_EXTS = ", ".join(f".{f}" for f in FORMATS)
_NO_RULE = (
    "Where no rule fires for an output, its value is the output's default: in a .fis file the "
    "middle of its range (MATLAB's convention; .fis cannot state another), in FCL and FLL the "
    "file's DEFAULT / default:, NaN when the file gives none (fuzzylite's convention), written "
    "'nan'.")


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def register(subparsers: Any) -> None:
    """Add the ``fis`` subcommand group to ``subparsers`` and set its handlers."""
    parser = subparsers.add_parser(
        "fis",
        help=HELP["fis"],
        description=(
            "Fuzzy systems from MATLAB .fis, IEC 61131-7 FCL (.fcl) and fuzzylite FLL (.fll) "
            "files, the format named by the file's extension: evaluate them exactly (eval), "
            "convert between the formats (convert), describe them (info) and draw them (show)."
        ),
    )
    sub = parser.add_subparsers(dest="fis_command", required=True,
                                metavar="{eval,convert,info,show}")

    p = sub.add_parser(
        "eval", help="exact outputs at the points of a CSV or on a grid",
        description=(
            "Evaluate the system in FILE exactly at the points of POINTS.csv (a header with one "
            "column per input, named as in the file, in any order; other columns ignored) or "
            "on a grid over the inputs' ranges (one or two inputs), and write a CSV with the "
            "input columns in the system's order, then one column per output, values written "
            "to round-trip exactly. " + _NO_RULE),
    )
    p.add_argument("file", type=Path, metavar="FILE", help=f"the fuzzy system ({_EXTS})")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--at", type=Path, metavar="POINTS.csv",
                       help="CSV with one column per input, named as in FILE")
    where.add_argument("--grid", type=int, metavar="N",
                       help=f"N points over the input's range (one input) or an N x N grid "
                            f"(two inputs, the first varying fastest), 2 <= N <= {MAX_GRID}")
    p.add_argument("--out", metavar="OUT.csv",
                   help="CSV to write; without --out, or with '-', the CSV goes to standard "
                        "output")
    p.add_argument("--no-rule-value", type=_finite_float, metavar="V",
                   help="the value of an output whose default is NaN where no rule fires for "
                        "it (MATLAB returns the middle of the range, fuzzylite NaN); a "
                        "default the file sets is kept")
    p.set_defaults(handler=run_eval)

    p = sub.add_parser(
        "convert", help="convert between .fis, .fcl and .fll",
        description=(
            "Read IN and write OUT in the format of OUT's extension (.fis, .fcl or .fll), "
            "exactly: a system the target format cannot hold is refused, naming what, and "
            "nothing is written. OUT is written atomically and may not be IN. Notes of the "
            "reader (names it changed, values it ignored) go to standard error."),
    )
    p.add_argument("input", type=Path, metavar="IN", help=f"the fuzzy system to read ({_EXTS})")
    p.add_argument("output", type=Path, metavar="OUT", help=f"the file to write ({_EXTS})")
    p.add_argument("--clip-inputs", action="store_true",
                   help="clip every input to its range (MATLAB's and FCL's only behaviour) "
                        "where IN does not (FLL lock-range: false): a stated change of the "
                        "values outside the ranges, which .fis and .fcl cannot express "
                        "otherwise; listed on standard error")
    p.add_argument("--no-rule-value", default=None, metavar="V|middle",
                   help="give outputs without a value for when no rule fires (NaN default, "
                        "fuzzylite's) the value V, or the middle of their range (MATLAB's "
                        "behaviour, the only one .fis can hold); listed on standard error")
    p.set_defaults(handler=run_convert)

    p = sub.add_parser(
        "info", help="describe a fuzzy system: variables, terms, rules, notes",
        description=(
            "Print the system in FILE: name, kind, operators, each input and output with its "
            "range, default (outputs), clip and terms (shape and named parameters; the height "
            "when not 1), every rule, and the reader's notes. --json prints one strict JSON "
            "object instead: NaN and infinities are null (a null default is 'no value'; a null "
            "trapezoid foot is infinite: a shoulder). " + _NO_RULE),
    )
    p.add_argument("file", type=Path, metavar="FILE", help=f"the fuzzy system ({_EXTS})")
    p.add_argument("--json", action="store_true", help="print one strict JSON object")
    p.set_defaults(handler=run_info)

    suffixes = "|".join(f[1:] for f in FIGURE_FORMATS)
    p = sub.add_parser(
        "show", help="figure of the membership functions and the surface or curve",
        description=(
            "Draw the membership functions of every variable of FILE (piecewise-linear terms "
            "with their exact corners, singletons as stems, Sugeno output functions as text) "
            "and, for a two-input system, the control surface of each output on an N x N grid "
            "over the inputs' ranges (default 81), for a one-input system each output's curve "
            "(default 401 points plus every vertex of the input's terms). Points where no rule "
            "fires and the default is NaN are left blank. " + _NO_RULE),
    )
    p.add_argument("file", type=Path, metavar="FILE", help=f"the fuzzy system ({_EXTS})")
    p.add_argument("--out", type=Path, required=True, metavar=f"FIG.{suffixes}",
                   help="the figure to write (format by the suffix)")
    p.add_argument("--grid", type=int, metavar="N",
                   help=f"points per input of the surface or curve, 2 <= N <= {MAX_SHOW_GRID}")
    p.set_defaults(handler=run_show)


# ---------------------------------------------------------------------------------------------
# eval


def with_no_rule_value(system: FuzzySystem, value: float | None) -> FuzzySystem:
    """``system`` with every NaN output default replaced by ``value`` (None: unchanged)."""
    if value is None:
        return system
    outputs = tuple(dataclasses.replace(v, default=value) if math.isnan(v.default) else v
                    for v in system.outputs)
    return dataclasses.replace(system, outputs=outputs)


def _grid_points(system: FuzzySystem, n: int) -> FloatArray:
    if not 2 <= n <= MAX_GRID:
        raise InputError(f"--grid must be between 2 and {MAX_GRID}, got {n}")
    if len(system.inputs) == 1:
        return np.linspace(*system.inputs[0].range, n)[:, None]
    if len(system.inputs) == 2:
        g1, g2 = np.meshgrid(np.linspace(*system.inputs[0].range, n),
                             np.linspace(*system.inputs[1].range, n))
        return np.column_stack([g1.ravel(), g2.ravel()])
    raise InputError(f"--grid needs a system with one or two inputs; {system.name!r} has "
                     f"{len(system.inputs)} ({', '.join(v.name for v in system.inputs)}): "
                     f"give the points with --at")


def _write_table(fh: IO[str], names: list[str], x: FloatArray, y: FloatArray) -> None:
    w = csv.writer(fh, lineterminator="\n")
    w.writerow(names)
    for row in np.hstack([x, y]).tolist():
        w.writerow([repr(v) for v in row])


def run_eval(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo fis eval``."""
    if args.grid is not None and not 2 <= args.grid <= MAX_GRID:
        raise InputError(f"--grid must be between 2 and {MAX_GRID}, got {args.grid}")
    to_file = args.out not in (None, "-")
    if to_file:
        check_output_path(args.out, option="--out", inputs=(args.file, args.at))
    system = with_no_rule_value(read_system(args.file), args.no_rule_value)
    names = [v.name for v in system.inputs]
    if args.at is not None:
        cols = read_csv_columns(args.at, tuple(names), what="points CSV")
        x = np.column_stack([cols[n] for n in names])
    else:
        x = _grid_points(system, args.grid)
    y = evaluate(system, x, parallel=True)
    header = names + [v.name for v in system.outputs]
    if to_file:
        with atomic_write(args.out) as fh:
            _write_table(fh, header, x, y)
    else:
        _write_table(sys.stdout, header, x, y)
    return 0


# ---------------------------------------------------------------------------------------------
# convert


def run_convert(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo fis convert``."""
    fmt = format_of(args.output)
    format_of(args.input)
    check_output_path(args.output, option="OUT", inputs=(args.input,))
    system = read_system(args.input)
    changed: list[str] = []
    if args.clip_inputs:
        changed = [v.name for v in system.inputs if not v.clip]
        system = dataclasses.replace(system, inputs=tuple(
            dataclasses.replace(v, clip=True) for v in system.inputs))
    filled: list[str] = []
    if args.no_rule_value is not None:
        text_v = args.no_rule_value.strip().lower()
        value = None
        if text_v != "middle":
            try:
                value = float(text_v)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise ParameterError(f"--no-rule-value must be a finite number or 'middle', "
                                     f"got {args.no_rule_value!r}")
        outs = []
        for v in system.outputs:
            if math.isnan(v.default):
                d = 0.5 * (v.range[0] + v.range[1]) if value is None else value
                filled.append(f"{v.name} = {d!r}")
                v = dataclasses.replace(v, default=d)
            outs.append(v)
        system = dataclasses.replace(system, outputs=tuple(outs))
    try:
        text = dumps(system, fmt)
    except ParameterError as exc:
        raise ParameterError(f"cannot convert {str(args.input)!r} to .{fmt}: {exc}; nothing "
                             f"written") from None
    write_text_atomic(args.output, text)
    if filled:
        print(f"fuzzyservo: note: value when no rule fires set: {', '.join(filled)} "
              f"(--no-rule-value)", file=sys.stderr)
    if changed:
        print(f"fuzzyservo: note: inputs now clipped to their ranges: {', '.join(changed)} "
              f"(--clip-inputs)", file=sys.stderr)
    for note in system.notes:
        print(f"fuzzyservo: note: {str(args.input)!r}: {' '.join(note.split())}",
              file=sys.stderr)
    return 0


# ---------------------------------------------------------------------------------------------
# info


def param_names(term: Term, n_inputs: int) -> tuple[str, ...]:
    """Names of a term's parameters: :data:`SHAPES`, and for the variable-length shapes
    ``x0 y0 x1 y1 ...`` (discrete) or ``c1 .. cn c0`` (linear, one coefficient per input in
    the inputs' order, then the constant)."""
    names = SHAPES[term.shape]
    if names is not None:
        return names
    if term.shape == "discrete":
        return tuple(f"{c}{i}" for i in range(len(term.params) // 2) for c in ("x", "y"))
    return (*(f"c{i + 1}" for i in range(n_inputs)), "c0")


def _num(x: float) -> str:
    """Exact, short text of a float: ``repr`` without a trailing ``.0``."""
    s = repr(float(x))
    return s[:-2] if s.endswith(".0") else s


def _variable(v: Variable, output: bool, n_inputs: int) -> dict[str, Any]:
    d: dict[str, Any] = {"name": v.name, "range": list(v.range)}
    if output:
        d["default"] = v.default
    d["clip"] = v.clip
    d["terms"] = [{"name": t.name, "shape": t.shape,
                   "params": dict(zip(param_names(t, n_inputs), t.params, strict=True)),
                   "height": t.height} for t in v.terms]
    return d


def describe(system: FuzzySystem) -> dict[str, Any]:
    """The system as plain data (what ``fis info --json`` prints, before NaN and infinities
    become ``null``)."""
    n_in = len(system.inputs)
    return {
        "name": system.name,
        "kind": system.kind,
        "operators": {"and": system.and_op, "or": system.or_op,
                      "implication": system.implication, "aggregation": system.aggregation,
                      "defuzzifier": system.defuzzifier},
        "inputs": [_variable(v, False, n_in) for v in system.inputs],
        "outputs": [_variable(v, True, n_in) for v in system.outputs],
        "rules": [{"text": system.rule_text(r), "weight": r.weight} for r in system.rules],
        "notes": list(system.notes),
    }


def describe_text(system: FuzzySystem) -> str:
    """The system as readable text (what ``fis info`` prints)."""
    d = describe(system)
    unused = " (not used by a sugeno system)" if system.kind == "sugeno" else ""
    lines = [f"name:         {d['name']}", f"kind:         {d['kind']}"]
    ops = d["operators"]
    lines += [f"and:          {ops['and']}", f"or:           {ops['or']}",
              f"implication:  {ops['implication']}{unused}",
              f"aggregation:  {ops['aggregation']}{unused}",
              f"defuzzifier:  {ops['defuzzifier']}"]
    for role, key in (("input", "inputs"), ("output", "outputs")):
        lines.append(f"{key} ({len(d[key])}):")
        for v in d[key]:
            lo, hi = v["range"]
            head = f"  {role} {v['name']}: range [{_num(lo)}, {_num(hi)}]"
            if role == "output":
                head += f", default {_num(v['default'])}"
            head += f", clip {'yes' if v['clip'] else 'no'}, {len(v['terms'])} term(s)"
            lines.append(head)
            width = max((len(t["name"]) for t in v["terms"]), default=0)
            for t in v["terms"]:
                params = " ".join(f"{k}={_num(x)}" for k, x in t["params"].items())
                height = "" if t["height"] == 1.0 else f"  height={_num(t['height'])}"
                lines.append(f"    {t['name']:<{width}}  {t['shape']:<9}  {params}{height}")
    lines.append(f"rules ({len(d['rules'])}):")
    width = len(str(len(d["rules"])))
    lines += [f"  {k:>{width}}. {r['text']}" for k, r in enumerate(d["rules"], start=1)]
    lines.append(f"notes ({len(d['notes'])}):" if d["notes"] else "notes: none")
    lines += [f"  - {' '.join(n.split())}" for n in d["notes"]]
    return "\n".join(lines)


def run_info(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo fis info``."""
    system = read_system(args.file)
    print(strict_json(describe(system)) if args.json else describe_text(system))
    return 0


# ---------------------------------------------------------------------------------------------
# show


def run_show(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo fis show``."""
    from ..plots.runs import save_figure
    from ..plots.systems import render_system, system_figure_data

    if args.grid is not None and not 2 <= args.grid <= MAX_SHOW_GRID:
        raise InputError(f"--grid must be between 2 and {MAX_SHOW_GRID}, got {args.grid}")
    if args.out.suffix.lower() not in FIGURE_FORMATS:
        raise InputError(f"--out {str(args.out)!r}: the file name must end in "
                         f"{' or '.join(FIGURE_FORMATS)}, the figure formats supported")
    check_output_path(args.out, option="--out", inputs=(args.file,))
    system = read_system(args.file)
    if args.grid is not None and len(system.inputs) > 2:
        raise InputError(f"--grid: {system.name!r} has {len(system.inputs)} inputs; a surface "
                         f"or curve is drawn for one or two inputs only, leave --grid out")
    save_figure(render_system(system_figure_data(system, args.grid)), args.out)
    return 0
