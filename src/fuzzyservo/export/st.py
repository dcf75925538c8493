"""IEC 61131-3 Structured Text of a registered controller: one FUNCTION_BLOCK, and an example
PROGRAM with a CONFIGURATION that runs it in a 1 ms cyclic task.

The block's sample is the law's ST port (:attr:`fuzzyservo.control.law.Law.st_source`, a file
beside the law's module: ``control/pid.st``, ``control/fuzzy_pi.st``, ..., a line-by-line port
of the one Python implementation and of its C port), pasted into the block after the law's
layout has been declared from its declaration as variables (``P_<NAME>`` the packed
parameters, ``S_<NAME>`` the state, ``G_<NAME>`` the gains, ``K_<NAME>`` the packing
constants), with the controller's fuzzy systems evaluated by the ST port of the exact
uniform-grid evaluator (:mod:`fuzzyservo.export.st_fuzzy`). The packed parameters the Python
packs (``controller.pack()``) are the variables' initial values, written exactly, so the
block starts from the very same bits; the gains are inputs with the exported values as
defaults, and a changed gain is packed again by the port's ``pack`` section (in the block's
type) on the next cycle. docs/export-st.md gives the interface, the guarantees and how to
import the file into TwinCAT, CODESYS and TIA Portal.

A port file has four sections, each opened by ``(*@ section NAME *)``: ``temps`` (declarations
of its working variables), ``step`` (one sample from ``R``, ``Y``, ``RD``, ``RDD`` to ``U``),
``rest`` (the state at rest at ``Y0`` holding ``U0``) and ``pack`` (``P_*`` from ``G_*`` and
``K_*``). ``FS_REAL`` stands for the type and ``FS_REAL#x`` for a literal of it. Directives:
``(*@ eval du(X1, X2) -> OUT *)`` and ``(*@ eval du alpha(X1, X2) -> OUT1, OUT2 *)`` evaluate
the systems; ``(*@ if system alpha *)`` / ``(*@ if gain NAME *)``, ``(*@ else *)``,
``(*@ end *)`` keep lines for a controller with that system or a law with that gain, and
``(*@ if constant NAME = VALUE *)`` for a controller whose packing constant has that value
(constants are fixed per block: the branch the block can never take is not written);
``(*@ inf-as-zero NAME *)`` declares that the port reads the gain ``NAME`` = 0 as infinity.
"""

from __future__ import annotations

import math
import re
import unicodedata
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..errors import ParameterError
from ..registry import ControllerKind
from ._st import StReal, check_st_name, st_comment, st_comment_text, st_literal, st_typed
from .controller_c import option_text, tables_digest
from .st_fuzzy import (
    GridSystem,
    PartitionSystem,
    grid_system,
    partition_system,
    st_eval,
    st_partition_consts,
    st_partition_eval,
    st_partition_tables,
    st_partition_temps,
    st_tables,
    st_temps,
)

System = GridSystem | PartitionSystem

__all__ = ["STController", "emit_st", "parse_port"]

#: The block's interface (besides the gains): inputs, in order, with their comments.
INPUTS = (
    ("SETPOINT", "reference position r [m]"),
    ("MEASUREMENT", "measured position y [m]"),
    ("SETPOINT_RATE", "reference velocity dr/dt [m/s] (feed-forward)"),
    ("SETPOINT_ACCEL", "reference acceleration d2r/dt2 [m/s^2] (feed-forward)"),
    ("HOLD_COMMAND", "command held while disabled, and from which a (re)start begins, "
                     "bumpless [-]: the valve's holding (null) command"),
)
_FIXED = {"ENABLE", "RESET", "COMMAND", "ALPHA", "GAIN_ERROR", "ACTIVE", "STARTED", "R", "Y",
          "RD", "RDD", "Y0", "U0", "U"}
#: The example program's variables (the block's name must differ from them).
_EXAMPLE_VARS = ("AXIS", "POSITION_SETPOINT", "POSITION", "VELOCITY_SETPOINT",
                 "ACCEL_SETPOINT", "NULL_COMMAND", "AXIS_ENABLE", "AXIS_RESET", "VALVE_COMMAND")


# --- the law's port -------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Port:
    """A law's ST port, parsed: its sections' lines and the gains read as 0 for infinity."""

    sections: dict[str, list[str]]
    inf_as_zero: frozenset[str]


_DIRECTIVE = re.compile(r"^\s*\(\*@\s*(.*?)\s*\*\)\s*$")
_EVAL = re.compile(r"^eval\s+([a-z_ ]+?)\s*\(\s*(.+?)\s*,\s*(.+?)\s*\)\s*->\s*(.+)$")


def parse_port(path: Path) -> Port:
    """Read a law's ST port into its sections (the directives other than ``section`` and
    ``inf-as-zero`` are kept, to be expanded per controller by :func:`_expand`).

    Raises
    ------
    ParameterError
        A missing section or an unknown directive (a port's error, named with its line).
    """
    sections: dict[str, list[str]] = {}
    current: list[str] | None = None
    inf: set[str] = set()
    for no, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        m = _DIRECTIVE.match(line)
        if m:
            words = m.group(1).split()
            if words[:1] == ["section"] and len(words) == 2:
                current = sections.setdefault(words[1], [])
                continue
            if words[:1] == ["inf-as-zero"]:
                inf.update(words[1:])
                continue
            if words[:1] not in (["eval"], ["if"], ["else"], ["end"]):
                raise ParameterError(f"{path.name}:{no}: unknown directive {m.group(1)!r}")
        if current is not None:
            current.append(line.rstrip())
    missing = [s for s in ("temps", "step", "rest", "pack") if s not in sections]
    if missing:
        raise ParameterError(f"{path.name}: the ST port has no section {missing[0]!r}")
    return Port(sections=sections, inf_as_zero=frozenset(inf))


_LITERAL = re.compile(r"FS_REAL#([0-9]+\.[0-9]+(?:E[+-]?[0-9]+)?)")
_TYPE = re.compile(r"\bFS_REAL\b")


def _typed(text: str, real: StReal) -> str:
    text = _LITERAL.sub(lambda m: st_typed(float(m.group(1)), real), text)
    return _TYPE.sub(real, text)


def _eval(systems: list[System], x1: str, x2: str, outs: list[str], real: StReal,
          ind: str) -> list[str]:
    """One evaluation site: a pair of uniform grids located once (``eval_uniform_pair``), or
    each system by its own path."""
    if all(isinstance(s, GridSystem) for s in systems):
        return st_eval([s for s in systems if isinstance(s, GridSystem)], x1, x2, outs, real,
                       ind)
    lines: list[str] = []
    for s, o in zip(systems, outs, strict=True):
        if isinstance(s, GridSystem):
            lines += st_eval([s], x1, x2, [o], real, ind)
        else:
            lines += st_partition_eval(s, x1, x2, o, real, ind)
    return lines


def _expand(lines: Sequence[str], *, systems: Mapping[str, System], gains: Sequence[str],
            real: StReal, indent: str, constants: Mapping[str, float]) -> list[str]:
    """The section's lines for this controller: conditionals resolved, evaluations written,
    the type and literals substituted, indented by ``indent``."""
    out: list[str] = []
    stack: list[tuple[bool, bool]] = []  # (this branch kept, the enclosing one kept)

    def keep() -> bool:
        return all(k for k, _ in stack)

    for line in lines:
        m = _DIRECTIVE.match(line)
        if m:
            words = m.group(1).split()
            if words[0] == "if":
                if len(words) < 3:
                    raise ParameterError(f"incomplete condition {m.group(1)!r} in an ST port")
                if words[1:2] == ["system"]:
                    cond = words[2] in systems
                elif words[1:2] == ["gain"]:
                    cond = words[2] in gains
                elif words[1:2] == ["constant"] and len(words) == 5 and words[3] == "=":
                    if words[2] not in constants:
                        raise ParameterError(f"an ST port tests the constant {words[2]!r}, "
                                             f"which the law does not have")
                    cond = constants[words[2]] == float(words[4])
                else:
                    raise ParameterError(f"unknown condition {m.group(1)!r} in an ST port")
                stack.append((cond, keep()))
            elif words[0] in ("else", "end") and not stack:
                raise ParameterError(f"an ST port's {words[0]!r} has no 'if'")
            elif words[0] == "else":
                cond, outer = stack.pop()
                stack.append((not cond, outer))
            elif words[0] == "end":
                stack.pop()
            elif words[0] == "eval" and keep():
                e = _EVAL.match(m.group(1))
                if e is None:
                    raise ParameterError(f"bad eval directive {m.group(1)!r} in an ST port")
                roles = e.group(1).split()
                outs = [o.strip() for o in e.group(4).split(",")]
                lead = line[:len(line) - len(line.lstrip())]
                missing = [r for r in roles if r not in systems]
                if missing:
                    raise ParameterError(f"the ST port evaluates the {missing[0]} system, "
                                         f"which this controller does not have")
                out += _eval([systems[r] for r in roles], e.group(2), e.group(3), outs, real,
                             indent + lead)
            continue
        if keep():
            out.append((indent + _typed(line, real)).rstrip())
    if stack:
        raise ParameterError("an ST port's 'if' has no 'end'")
    return out


def _declared(temps: Sequence[str]) -> list[str]:
    names: list[str] = []
    for line in temps:
        code = re.sub(r"\(\*.*?\*\)", "", line).strip()
        if not code:
            continue
        head = code.split(":")[0]
        names += [n.strip().upper() for n in head.split(",") if n.strip()]
    return names


# --- the result -----------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class STController:
    """Generated Structured Text of one controller.

    Attributes
    ----------
    name : str
        The function block's name (``NAME.st``; the example is ``NAME_example.st``).
    kind : str
        The registry's controller name.
    block, example : str
        Text of ``NAME.st`` (the FUNCTION_BLOCK) and ``NAME_example.st`` (a PROGRAM calling
        it and a CONFIGURATION with a 1 ms cyclic task).
    real : {"LREAL", "REAL"}
        The arithmetic type.
    gain_names : tuple of str
        The kind's gains, as the block's inputs (upper case) take them, in order.
    gains : tuple of float
        Their exported values (the inputs' defaults; infinity written as 0 where the law's
        port reads 0 as infinity).
    ts : float
        Sample time [s].
    self_tuning : bool
        The block has the output ``ALPHA``.
    feedforward : bool
        The law uses ``SETPOINT_RATE`` and ``SETPOINT_ACCEL``.
    digest : str
        SHA-256 of the fuzzy systems' packed tables ("" without fuzzy systems), as the C
        export's.
    inf_as_zero : tuple of str
        Gains whose input reads 0 as infinity.
    """

    name: str
    kind: str
    block: str
    example: str
    real: StReal
    gain_names: tuple[str, ...]
    gains: tuple[float, ...]
    ts: float
    self_tuning: bool
    feedforward: bool
    digest: str
    inf_as_zero: tuple[str, ...] = ()

    def files(self) -> dict[str, str]:
        """File name -> text of the two files."""
        return {f"{self.name}.st": self.block, f"{self.name}_example.st": self.example}


#: Greek letters and marks of the package's own field descriptions, as ASCII words (the
#: descriptions are ours; text from outside keeps :func:`st_comment_text`'s reversible escapes).
_ASCII = str.maketrans({"Δ": "Delta ", "α": "alpha", "β": "beta", "δ": "delta", "ζ": "zeta",
                        "λ": "lambda", "φ": "phi", "ψ": "psi", "ω": "omega", "σ": "sigma",
                        "ŷ": "y^", "ẋ": "x'", "ẍ": "x''", "ė": "e'", "ë": "e''", "∫": "int ",
                        "₀": "0", "²": "^2", "³": "^3", "≤": "<=", "≥": ">=", "−": "-",
                        "·": "*", "…": "..."})


def _greek(ch: str) -> str:
    name = unicodedata.name(ch, "")
    if name.startswith("GREEK SMALL LETTER "):
        return name.removeprefix("GREEK SMALL LETTER ").lower()
    if name.startswith("GREEK CAPITAL LETTER "):
        return name.removeprefix("GREEK CAPITAL LETTER ").capitalize()
    return ch


def _doc(text: str) -> str:
    """One of the package's own descriptions in an ST comment, readable in ASCII."""
    return st_comment_text("".join(_greek(c) for c in text.translate(_ASCII))
                           .replace("Delta  ", "Delta "))


def _value(v: float, gain: str, inf_zero: frozenset[str], where: str) -> float:
    if math.isinf(v) and v > 0 and gain in inf_zero:
        return 0.0
    if not math.isfinite(v):
        raise ParameterError(f"{where} = {v!r} has no Structured Text literal")
    return v


def emit_st(kind: ControllerKind, gains: Mapping[str, float], controller: Any, *, name: str,
            real: StReal = "LREAL", systems: Sequence[tuple[str, str, str]] = (),
            command: str = "") -> STController:
    """Structured Text of ``controller`` (built by the registry from ``kind`` and ``gains``).

    Parameters
    ----------
    kind : ControllerKind
        The registry's entry (names the gains the block takes as inputs).
    gains : mapping of str to float
        The kind's checked gains [their units].
    controller : LawController
        The controller built from them (its ``pack()`` gives the initial packed parameters;
        its ``law`` the layout and the ST port).
    name : str
        The block's name (:func:`fuzzyservo.export._st.check_st_name`).
    real : {"LREAL", "REAL"}
        Arithmetic type.
    systems : sequence of (role, source, sha256)
        Fuzzy systems read from files, recorded in the comment header.
    command : str
        The command line that made the code, recorded in the comment header.

    Raises
    ------
    ParameterError
        A law without an ST port, a general fuzzy system, a bad name or type, a value the
        type cannot hold, or a name of the law's layout that collides with the block's.
    """
    check_st_name(name)
    if real not in ("LREAL", "REAL"):
        raise ParameterError(f"real must be 'LREAL' or 'REAL', got {real!r}")
    law = controller.law
    if law.st_source is None:
        raise ParameterError(
            f"controller {kind.name} ({law.title}) has no Structured Text port: its law "
            f"{law.name} declares no st_source")
    port = parse_port(Path(law.st_source))
    inf_zero = port.inf_as_zero
    gain_names = kind.gain_names
    raw = {g: float(gains[g]) for g in gain_names}
    values = tuple(_value(raw[g], g, inf_zero, g) for g in gain_names)
    units = tuple(kind.gain(g).unit for g in gain_names)
    ts = float(controller.dt)
    merged = {**kind.implied, **raw}
    has_alpha = bool(law.trace == "alpha" and getattr(controller, "self_tuning", True))
    packed = np.asarray(controller.pack(), dtype=np.float64).reshape(-1)
    constants = [float(v) for v in controller.law_constants()]
    const_values = dict(zip(law.constant_names, constants, strict=True))

    # the fuzzy systems
    sys_tables = controller.systems() if hasattr(controller, "systems") else {}
    grids: dict[str, System] = {}
    tables: list[Any] = []
    for role, tab in sys_tables.items():
        if role not in law.systems:
            raise ParameterError(f"law {law.name} has no {role} system")
        rules = np.asarray(tab[0])
        if rules.ndim == 2 and rules.shape[0] > 1:
            grids[role] = grid_system(role.upper(), tab[0], tab[1])
        else:
            grids[role] = partition_system(role.upper(), tab[0], tab[1])
        tables += list(tab)
    parts = [s for s in grids.values() if isinstance(s, PartitionSystem)]
    digest = tables_digest(tables) if tables else ""

    # names: the block's interface, the layout, the port's and the evaluator's variables
    upper_gains = [g.upper() for g in gain_names]
    inputs = [n for n, _ in INPUTS]
    layout = ([f"P_{f.name.upper()}" for f in law.params]
              + [f"S_{f.name.upper()}" for f in law.state]
              + [f"G_{f.name.upper()}" for f in law.gains]
              + [f"K_{f.name.upper()}" for f in law.constants]
              + [f"GL_{g}" for g in upper_gains])
    temps = _declared(port.sections["temps"])
    tables_names = [f"{r.upper()}_{t}" for r in grids for t in ("RULES", "LIMS")]
    fz = _declared(st_temps(real) + (st_partition_temps(parts, real) if parts else []))
    every = [*inputs, *upper_gains, *_FIXED, *layout, *temps, *tables_names, *fz]
    seen: set[str] = set()
    for n in every:
        if n in seen:
            raise ParameterError(f"law {law.name}: the name {n} is used twice in the ST block "
                                 f"(a gain, a port variable or the block's interface)")
        seen.add(n)
    for n in [*upper_gains, *layout, *temps]:
        check_st_name(n, f"law {law.name}: ST variable")
    if name.upper() in seen or name.upper() in _EXAMPLE_VARS:
        raise ParameterError(f"--name {name!r} is also a variable of the block or of its "
                             f"example program; choose another name")

    def lit(v: float, where: str) -> str:
        return st_literal(v, real, where)

    # --- header
    options = ", ".join(
        f"{o} = {option_text(getattr(controller, o))}" for o in kind.option_names
        if hasattr(controller, o)) or "none"
    title = law.title if not has_alpha else f"{law.title}, self-tuning"
    info = [
        f"{name}.st: controller {kind.name} ({title}) as an IEC 61131-3 Structured Text "
        f"function block, generated by fuzzyservo {__version__}.",
        "Do not edit: regenerate with the command below.",
        "",
        f"command:     {command}" if command else "command:     (Python API)",
        f"controller:  {kind.name} ({kind.title})",
        f"law:         {law.name} (ST port {Path(law.st_source).name})",
        "gains:       " + ", ".join(f"{g} = {raw[g]!r} {u}" for g, u in
                                    zip(gain_names, units, strict=True)),
        f"options:     {options}",
        f"sample time: {ts!r} s (call the block once every sample, in a cyclic task of this "
        f"period)",
        f"arithmetic:  {real}",
    ]
    if tables:
        info.append(f"fuzzy systems ({', '.join(grids)}; SHA-256 of the packed tables, as the "
                    f"C export's): {digest}")
        for role, source, sha in systems:
            info.append(f"  {role} from {source} (file SHA-256 {sha})")
        if not systems:
            info.append("  the paper's (Aly et al. 2012, Fig. 3)")
    info += [
        "",
        "IEC 61131-3 Structured Text, no vendor library, no dynamic memory, no recursion;",
        "checked with MatIEC (iec2c) against the Python controller (docs/export-st.md).",
    ]
    if inf_zero & set(gain_names):
        info.append("Gain inputs " + ", ".join(g.upper() for g in gain_names if g in inf_zero)
                    + ": 0 stands for infinity (ST has no literal for it).")

    # --- declarations
    ind = "    "
    decl_in = [f"{ind}{n} : {real}; (* {st_comment_text(doc)} *)" for n, doc in INPUTS[:4]]
    decl_in += [
        f"{ind}ENABLE : BOOL; (* FALSE: the law does not run, COMMAND = HOLD_COMMAND; the next "
        f"enabled cycle starts bumpless *)",
        f"{ind}RESET : BOOL; (* TRUE: restart bumpless at this cycle: the state at rest at "
        f"MEASUREMENT holding HOLD_COMMAND, then the sample *)",
        f"{ind}{INPUTS[4][0]} : {real}; (* {st_comment_text(INPUTS[4][1])} *)",
    ]
    for g, u, v in zip(gain_names, units, values, strict=True):
        spec = kind.gain(g)
        extra = " (0: infinity)" if g in inf_zero else ""
        allowed = "finite and > 0" if spec.positive else "finite and >= 0"
        decl_in.append(f"{ind}{g.upper()} : {real} := {lit(v, 'gain ' + g)}; "
                       f"(* {_doc(spec.description)} [{_doc(u)}]{extra}; "
                       f"{allowed} *)")
    decl_out = [
        f"{ind}COMMAND : {real}; (* valve command [-], within the limits *)",
    ]
    if has_alpha:
        decl_out.append(f"{ind}ALPHA : {real}; (* gain-updating factor alpha of the last "
                        f"sample [-] *)")
    decl_out += [
        f"{ind}GAIN_ERROR : INT; (* 0, or i: the i-th gain input (1-based, in the order "
        f"above) is out of its range, and the block runs on the gains last accepted *)",
        f"{ind}ACTIVE : BOOL; (* the law ran this cycle *)",
    ]
    var = [f"{ind}STARTED : BOOL; (* the state is valid (set at rest since the last enable) *)",
           f"{ind}R, Y, RD, RDD, Y0, U0, U : {real}; (* the sample's inputs and command *)",
           f"{ind}(* packed parameters: the Python controller's pack(), exactly *)"]
    for i, f in enumerate(law.params):
        var.append(f"{ind}P_{f.name.upper()} : {real} := "
                   f"{lit(float(packed[i]), 'P_' + f.name.upper())}; "
                   f"(* {_doc(f.doc)} [{_doc(f.unit)}] *)")
    var.append(f"{ind}(* state *)")
    for f in law.state:
        var.append(f"{ind}S_{f.name.upper()} : {real}; (* {_doc(f.doc)} "
                   f"[{_doc(f.unit)}] *)")
    var.append(f"{ind}(* the gains last accepted (the packed parameters are theirs), and the "
               f"law's gains *)")
    for g, v in zip(gain_names, values, strict=True):
        var.append(f"{ind}GL_{g.upper()} : {real} := {lit(v, 'gain ' + g)};")
    const: list[str] = []
    for f in law.gains:
        if f.name in gain_names:
            var.append(f"{ind}G_{f.name.upper()} : {real}; (* {_doc(f.doc)} "
                       f"[{_doc(f.unit)}] *)")
        else:
            v = _value(float(merged[f.name]), f.name, inf_zero, f"gain {f.name}")
            const.append(f"{ind}G_{f.name.upper()} : {real} := {lit(v, 'gain ' + f.name)}; "
                         f"(* {_doc(f.doc)} [{_doc(f.unit)}], fixed by "
                         f"the controller {st_comment_text(kind.name)} *)")
    var.append(f"{ind}(* the law's working variables *)")
    var += [f"{ind}{_typed(ln.strip(), real)}" for ln in port.sections["temps"] if ln.strip()]
    if grids:
        var.append(f"{ind}(* the fuzzy evaluator's working variables *)")
        var += [f"{ind}{ln}" for ln in st_temps(real)]
    if parts:
        var += [f"{ind}{ln}" for ln in st_partition_temps(parts, real)]
    const.append(f"{ind}(* packing constants *)")
    for f, v in zip(law.constants, constants, strict=True):
        const.append(f"{ind}K_{f.name.upper()} : {real} := "
                     f"{lit(v, 'K_' + f.name.upper())}; (* {_doc(f.doc)} "
                     f"[{_doc(f.unit)}] *)")
    for grid in grids.values():
        if isinstance(grid, GridSystem):
            const += [f"{ind}{ln}" for ln in st_tables(grid, real)]
        else:
            const += [f"{ind}{ln}" for ln in st_partition_tables(grid, real)]
            const += [f"{ind}{ln}" for ln in st_partition_consts(grid, real)]

    # --- body
    zero = st_typed(0.0, real)
    body = ["(* 1. the gains: check each; re-pack when one differs from those last accepted *)",
            "GAIN_ERROR := 0;"]
    for i, g in enumerate(upper_gains):
        kw = "IF" if i == 0 else "ELSIF"
        op = ">" if kind.gain(g.lower()).positive else ">="
        body += [f"{kw} NOT ({g} {op} {zero} AND {g} - {g} = {zero}) THEN",
                 f"    GAIN_ERROR := {i + 1};"]
    if upper_gains:
        body.append("END_IF;")
        changed = " OR ".join(f"{g} <> GL_{g}" for g in upper_gains)
        body += [f"IF GAIN_ERROR = 0 AND ({changed}) THEN"]
        body += [f"    G_{g} := {g};" for g in upper_gains if g.lower() in law.gain_names]
        body += _expand(port.sections["pack"], systems=grids, gains=law.gain_names, real=real,
                        indent="    ", constants=const_values)
        body += [f"    GL_{g} := {g};" for g in upper_gains]
        body.append("END_IF;")
    body += [
        "(* 2. one sample *)",
        "IF NOT ENABLE THEN",
        "    COMMAND := HOLD_COMMAND;",
        "    STARTED := FALSE;",
        "    ACTIVE := FALSE;",
        "ELSE",
        "    IF RESET OR NOT STARTED THEN",
        "        (* bumpless start: the state at rest at the measurement, holding the command *)",
        "        Y0 := MEASUREMENT;",
        "        U0 := HOLD_COMMAND;",
        *_expand(port.sections["rest"], systems=grids, gains=law.gain_names, real=real,
                 indent="        ", constants=const_values),
        "        STARTED := TRUE;",
        "    END_IF;",
        "    R := SETPOINT;",
        "    Y := MEASUREMENT;",
        "    RD := SETPOINT_RATE;",
        "    RDD := SETPOINT_ACCEL;",
        *_expand(port.sections["step"], systems=grids, gains=law.gain_names, real=real,
                 indent="    ", constants=const_values),
        "    COMMAND := U;",
    ]
    if has_alpha:
        body.append("    ALPHA := S_ALPHA;")
    body += ["    ACTIVE := TRUE;", "END_IF;"]

    block = "\n".join([
        st_comment(info),
        f"FUNCTION_BLOCK {name}",
        "VAR_INPUT", *decl_in, "END_VAR",
        "VAR_OUTPUT", *decl_out, "END_VAR",
        "VAR", *var, "END_VAR",
        "VAR CONSTANT", *const, "END_VAR",
        "",
        *body,
        "END_FUNCTION_BLOCK",
        "",
    ])
    example = _example(name, real, ts, f"controller {kind.name}, {title}", law.feedforward,
                       info[3:10])
    return STController(name=name, kind=kind.name, block=block, example=example, real=real,
                        gain_names=tuple(upper_gains), gains=values, ts=ts,
                        self_tuning=has_alpha, feedforward=bool(law.feedforward),
                        digest=digest,
                        inf_as_zero=tuple(g.upper() for g in gain_names if g in inf_zero))


def _task_interval(ts: float) -> str:
    """``ts`` as an IEC TIME literal in milliseconds, with a fraction where needed (``T#1ms``,
    ``T#1.5ms``): the unit ``us`` is edition 3 only, and MatIEC refuses it in a task's
    interval; ``ts`` must be a whole number of microseconds."""
    us = round(ts * 1e6)
    if us < 1 or abs(us - ts * 1e6) > 1e-6 * max(1.0, ts * 1e6):
        raise ParameterError(f"sample time {ts!r} s is not a whole number of microseconds, "
                             f"which a task interval (TIME) needs")
    whole, frac = divmod(us, 1000)
    return f"T#{whole}ms" if frac == 0 else f"T#{whole}.{frac:03d}".rstrip("0") + "ms"


def _example(name: str, real: StReal, ts: float, what: str, feedforward: bool,
             record: Sequence[str] = ()) -> str:
    zero = st_literal(0.0, real)
    ff = ("the reference's velocity and acceleration from the motion profile (this law uses "
          "them)" if feedforward else "0 (this law ignores them)")
    info = [
        f"{name}_example.st: a PROGRAM running the block {name} ({what}) every {ts!r} s,",
        "and a CONFIGURATION with that cyclic task, as a PLC project starts from them. Map the",
        "variables marked I/O to the axis (docs/export-st.md).",
        "Compile it together with the block: iec2c needs both in one file or as a library.",
        "",
        *record,
    ]
    interval = _task_interval(ts)
    return "\n".join([
        st_comment(info),
        f"PROGRAM {name}_EXAMPLE",
        "VAR",
        f"    AXIS : {name};",
        f"    POSITION_SETPOINT : {real} := {zero}; (* I/O or motion profile: reference [m] *)",
        f"    POSITION : {real} := {zero}; (* I/O: measured position [m], from the transducer's "
        f"raw value scaled *)",
        f"    VELOCITY_SETPOINT : {real} := {zero}; (* {st_comment_text(ff)} [m/s] *)",
        f"    ACCEL_SETPOINT : {real} := {zero}; (* the same [m/s^2] *)",
        f"    NULL_COMMAND : {real} := {zero}; (* the valve's holding command [-] *)",
        "    AXIS_ENABLE : BOOL := TRUE; (* I/O: drive enabled, no fault *)",
        "    AXIS_RESET : BOOL := FALSE; (* restart bumpless *)",
        f"    VALVE_COMMAND : {real} := {zero}; (* I/O: to the valve amplifier, scaled from "
        f"[-1, 1] *)",
        "END_VAR",
        "    AXIS(SETPOINT := POSITION_SETPOINT, MEASUREMENT := POSITION,",
        "         SETPOINT_RATE := VELOCITY_SETPOINT, SETPOINT_ACCEL := ACCEL_SETPOINT,",
        "         ENABLE := AXIS_ENABLE, RESET := AXIS_RESET, HOLD_COMMAND := NULL_COMMAND);",
        "    VALVE_COMMAND := AXIS.COMMAND;",
        "END_PROGRAM",
        "",
        f"CONFIGURATION {name}_CONFIG",
        f"    RESOURCE {name}_RES ON PLC",
        f"        TASK {name}_TASK(INTERVAL := {interval}, PRIORITY := 1);",
        f"        PROGRAM {name}_MAIN WITH {name}_TASK : {name}_EXAMPLE;",
        "    END_RESOURCE",
        "END_CONFIGURATION",
        "",
    ])
