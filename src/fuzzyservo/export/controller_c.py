"""C99 code of a registered controller: one header and one source, no heap, no globals.

The generated step is the law's C port (:attr:`fuzzyservo.control.law.Law.c_source`, a file
beside the law's module: ``control/pid.c``, ``control/fuzzy_pi.c``, a line-by-line port of the
one Python implementation), pasted after the law's layout written from its declaration
(``FS_P_<NAME>``, ``FS_S_<NAME>``, ``FS_G_<NAME>``, ``FS_K_<NAME>``: the port indexes by these
names only), with the controller's fuzzy systems evaluated by the C port of the exact
evaluators (:mod:`fuzzyservo.export.fuzzy_c`). The packed parameter vector the Python packs
(``controller.pack()``) is compiled in, written as C99 hexadecimal literals, so the C starts
from the very same bits; ``NAME_set_gains`` re-packs new gains in C (``fs_law_pack``, in double
as numpy does) for a target or an FMU that tunes them. docs/export.md gives the API and the
guarantees.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .._typing import FloatArray
from ..errors import ParameterError
from ..registry import ControllerKind
from ._c import (
    Real,
    c_array,
    c_comment,
    c_comment_text,
    c_literal,
    c_string,
    check_identifier,
)

__all__ = ["CController", "check_c_name", "emit_controller", "option_text", "tables_digest"]


def check_c_name(name: str) -> str:
    """``name`` if it can prefix C identifiers and name the files
    (:func:`fuzzyservo.export._c.check_identifier`).

    Raises
    ------
    ParameterError
        Empty, not a C identifier of at most 31 characters starting with a letter, a C
        keyword, the name of a C standard header (``math``, ``stdint``, ``string``, ...: its
        ``NAME.h`` would shadow the library's), or one of the generated code's own prefixes
        (``fs``, ``fsm``, ``fmi``). (The instance type is ``NAME_ctl``, not ``NAME_t``: C and
        POSIX reserve the ``_t`` suffix, and ``pid_t`` is POSIX's.)
    """
    return check_identifier(name, "--name")


@dataclass(frozen=True, slots=True)
class CController:
    """Generated code of one controller.

    Attributes
    ----------
    name : str
        Prefix of every public identifier (``NAME_ctl``, ``NAME_init``, ``NAME_step``, ...).
    kind : str
        The registry's controller name.
    header, source : str
        Text of ``NAME.h`` and ``NAME.c``.
    real : {"double", "float"}
        Floating-point type of the arithmetic.
    gain_names : tuple of str
        The kind's gains, in the order ``NAME_set_gains`` takes them.
    gains : tuple of float
        Their exported values [units of the registry's gains].
    gain_units : tuple of str
        Their units.
    ts : float
        Sample time [s].
    self_tuning : bool
        The controller has a gain-updating factor α (``NAME_alpha``).
    digest : str
        SHA-256 of the fuzzy systems' packed tables ("" without fuzzy systems).
    trace_index : int or None
        Position in the state ``NAME_ctl.s`` of the field the law traces as the run's α
        (what ``simulate`` records), or None: the law traces none (``simulate`` writes NaN).
    feedforward : bool
        The law uses the reference's velocity and acceleration (``NAME_step_ff``'s rd, rdd;
        :attr:`fuzzyservo.control.law.Law.feedforward`); otherwise it ignores them.
    """

    name: str
    kind: str
    header: str
    source: str
    real: Real
    gain_names: tuple[str, ...]
    gains: tuple[float, ...]
    gain_units: tuple[str, ...]
    ts: float
    self_tuning: bool
    digest: str
    trace_index: int | None = None
    feedforward: bool = False

    def files(self) -> dict[str, str]:
        """File name -> text of the two files."""
        return {f"{self.name}.h": self.header, f"{self.name}.c": self.source}


def tables_digest(tables: Sequence[Any]) -> str:
    h = hashlib.sha256()
    for a in tables:
        arr = np.ascontiguousarray(a)
        h.update(str(arr.dtype).encode() + str(arr.shape).encode() + arr.tobytes())
    return h.hexdigest()


def _array(name: str, values: FloatArray, real: Real) -> str:
    return c_array("fs_real", name, [c_literal(v, real, f"{name}[{i}]")
                                     for i, v in enumerate(values)])


def _c_text(text: object) -> str:
    """``text`` safe inside a C block comment (:func:`fuzzyservo.export._c.c_comment_text`)."""
    return c_comment_text(text)


def _layout(law: Any) -> str:
    """The law's layout as named constants, from its declaration (the names are checked
    identifiers, :class:`fuzzyservo.control.law.Field`)."""
    lines = [f"/* Layout of the law {_c_text(law.name)} ({_c_text(law.title)}), from its "
             f"declaration. */"]
    for prefix, what, fields in (("P", "packed parameters", law.params),
                                 ("S", "state", law.state),
                                 ("G", "gains (NAME_set_gains, in this order)", law.gains),
                                 ("K", "packing constants", law.constants)):
        lines.append(f"/* {what} */")
        lines.append(f"#define FS_N{prefix} {len(fields)}")
        for i, f in enumerate(fields):
            lines.append(f"#define FS_{prefix}_{f.name.upper()} {i} /* {_c_text(f.doc)} "
                         f"[{_c_text(f.unit)}] */")
    return "\n".join(lines) + "\n"


def _systems_code(controller: Any, law: Any, real: Real) -> tuple[str, list[Any], str]:
    """The controller's fuzzy systems as C (after the evaluators' fragment): one system is
    ``fs_sys_<role>``, two are ``fs_sys`` (both at once, as the Python's pair) with
    ``fs_sys_<role>`` each; ``FS_SYS_<ROLE>`` is defined for each. Returns the code, the
    tables (for the digest) and a description."""
    from .fuzzy_c import emit_pair, emit_system, fragment

    systems = controller.systems() if hasattr(controller, "systems") else {}
    if not systems:
        return "", [], ""
    roles = list(systems)
    bad = [r for r in roles if r not in law.systems]
    if bad or len(roles) > 2 or (len(roles) == 2 and roles != ["du", "alpha"]):
        raise ParameterError(f"law {law.name}: the C export writes one system, or the pair "
                             f"du and alpha; got {roles}")
    tables: list[Any] = []
    for r in roles:
        tables += list(systems[r])
    defs = "".join(f"#define FS_SYS_{r.upper()} 1\n" for r in roles)
    if len(roles) == 1:
        code = emit_system(f"fs_sys_{roles[0]}", *systems[roles[0]], real=real)
    else:
        code = emit_pair("fs_sys", systems["du"], systems["alpha"], real=real)
    return fragment() + "\n" + defs + code, tables, ", ".join(roles)


# --- the files ------------------------------------------------------------------------------


def emit_controller(kind: ControllerKind, gains: Mapping[str, float], controller: Any, *,
                    name: str, real: Real = "double",
                    systems: Sequence[tuple[str, str, str]] = (),
                    command: str = "") -> CController:
    """C99 header and source of ``controller`` (built by the registry from ``kind`` and
    ``gains``).

    Parameters
    ----------
    kind : ControllerKind
        The registry's entry (names the gains ``NAME_set_gains`` takes).
    gains : mapping of str to float
        The kind's checked gains (:meth:`ControllerKind.check_gains`) [their units].
    controller : PIDController or FuzzyPIController
        The controller built from them (its ``pack()`` is compiled in); its ``law`` gives the
        layout and the C port, so the exporter names no controller class (the registry
        builds them).
    name : str
        Prefix of the public identifiers (:func:`check_c_name`).
    real : {"double", "float"}
        Arithmetic type.
    systems : sequence of (role, source, sha256)
        Fuzzy systems read from files, recorded in the comment block.
    command : str
        The command line that made the code, recorded in the comment block.

    Raises
    ------
    ParameterError
        A controller class without C code, a bad name, or tables C cannot hold.
    """
    check_c_name(name)
    law = controller.law
    if law.c_source is None:
        raise ParameterError(
            f"controller {kind.name} ({law.title}) has no C port: its law {law.name} declares "
            f"no c_source")
    if real not in ("double", "float"):
        raise ParameterError(f"real must be 'double' or 'float', got {real!r}")
    gain_names = kind.gain_names
    values = tuple(float(gains[g]) for g in gain_names)
    units = tuple(kind.gain(g).unit for g in gain_names)
    ts = float(controller.dt)
    upper = name.upper()
    packed = np.asarray(controller.pack(), dtype=np.float64)
    n_p = max(packed.shape[0], 1)
    n_s = max(len(law.state), 1)

    # the law's gains from the kind's gains: the kind's own or a constant it fixes
    merged = {**kind.implied, **dict(zip(gain_names, values, strict=True))}
    class_gains = []
    for g in law.gain_names:
        if g in gain_names:
            class_gains.append(f"g[{gain_names.index(g)}]")
        else:
            class_gains.append(c_literal(merged[g]))

    # the registry's check of each gain (GainSpec.check): finite and >= 0, or > 0 / inf
    checks = [f"    if (!(g[{i}] > 0.0)) {{\n        return {i + 1};\n    }}"
              if kind.gain(g).allow_inf else
              f"    if (!(g[{i}] > 0.0 && g[{i}] <= DBL_MAX)) {{\n        return {i + 1};\n    }}"
              if kind.gain(g).positive else
              f"    if (!(g[{i}] >= 0.0 && g[{i}] <= DBL_MAX)) {{\n        return {i + 1};\n    }}"
              for i, g in enumerate(gain_names)]
    sys_defs, tables, roles = _systems_code(controller, law, real)
    port = Path(law.c_source).read_text(encoding="utf-8")
    laws = _layout(law) + "\n" + port
    has_alpha = bool(law.trace == "alpha" and getattr(controller, "self_tuning", True))
    digest = tables_digest(tables) if tables else ""

    options = ", ".join(
        f"{o} = {option_text(getattr(controller, o))}" for o in kind.option_names
        if hasattr(controller, o)) or "none"
    title = law.title if not has_alpha else f"{law.title}, self-tuning"
    info = [
        f"{name}.h / {name}.c: controller {kind.name} ({title}) generated by "
        f"fuzzyservo {__version__}.",
        "Do not edit: regenerate with the command below.",
        "",
        f"command:     {command}" if command else "command:     (Python API)",
        f"controller:  {kind.name} ({kind.title})",
        f"law:         {law.name} (C port {Path(law.c_source).name})",
        "gains:       " + ", ".join(f"{g} = {v!r} {u}" for g, v, u in
                                    zip(gain_names, values, units, strict=True)),
        f"options:     {options}",
        f"sample time: {ts!r} s",
        f"arithmetic:  {real}",
    ]
    if tables:
        info.append(f"fuzzy systems ({roles}; SHA-256 of the packed tables): {digest}")
        for role, source, sha in systems:
            info.append(f"  {role} from {source} (file SHA-256 "
                        f"{sha})")
        if not systems:
            info.append("  the paper's (Aly et al. 2012, Fig. 3)")
    info += [
        "",
        "C99, standard library only (math.h); no heap, no global state: each NAME_ctl is one",
        "instance, and instances run side by side. Compile with IEEE semantics (no",
        "-ffast-math; -ffp-contract=off, which -std=c99 implies with gcc) for results equal to",
        "the Python controller's; link with -lm.",
    ]
    header = _header(name, upper, real, info, gain_names, values, units, ts, n_p, n_s,
                     has_alpha, _c_text(title), law.feedforward,
                     positive=[g for g in gain_names if kind.gain(g).positive])
    consts = [
        _array("fs_p0", packed, real) if packed.size else
        "static const fs_real fs_p0[1] = {0};",
        c_array("double", "fs_g0", [c_literal(v) for v in values]),
        c_array("double", "fs_k0", [c_literal(float(v)) for v in controller.law_constants()])
        if len(law.constants) else "static const double fs_k0[1] = {0};",
    ]
    source = _source(name, upper, real, info, sys_defs, laws, consts, class_gains, checks,
                     len(gain_names), gain_names, has_alpha)
    stamp = hashlib.sha256((header + source).encode()).hexdigest()[:8]
    header = header.replace("@STAMP@", stamp)
    source = source.replace("@STAMP@", stamp)
    return CController(name=name, kind=kind.name, header=header, source=source, real=real,
                       gain_names=gain_names, gains=values, gain_units=units, ts=ts,
                       self_tuning=has_alpha, digest=digest,
                       trace_index=law.state_names.index(law.trace) if law.trace else None,
                       feedforward=bool(law.feedforward))


def option_text(v: Any) -> str:
    if v is None:
        return "default"
    if isinstance(v, str):
        return v
    return repr(v)


def _header(name: str, upper: str, real: Real, info: Sequence[str], gain_names: Sequence[str],
            values: Sequence[float], units: Sequence[str], ts: float, n_p: int, n_s: int,
            self_tuning: bool, law: str, feedforward: bool = False,
            positive: Sequence[str] = ()) -> str:
    allowed = "finite and >= 0" + ("; n: > 0 or infinity" if "n" in gain_names else "") + (
        "; " + ", ".join(positive) + ": finite and > 0" if positive else "")
    gains_doc = "\n".join(f" *   g[{i}] = {_c_text(g)} [{_c_text(u)}] (exported: {v!r})"
                          for i, (g, v, u) in enumerate(zip(gain_names, values, units,
                                                            strict=True)))
    ff_note = ("this law uses them (feed-forward): give them from the motion profile."
               if feedforward else "this law does not use them.")
    alpha = ""
    if self_tuning:
        alpha = f"""
/* The gain-updating factor alpha of the last sample [-] (1 before the first). */
{name}_real {name}_alpha(const {name}_ctl *c);
"""
    return f"""{c_comment(info)}
#ifndef {upper}_H
#define {upper}_H

#ifdef __cplusplus
extern "C" {{
#endif

/* Identifies this export: NAME.c refuses to compile with a header of another one. */
#define {upper}_CODE_ID 0x@STAMP@UL

/* Arithmetic type of this controller. */
typedef {real} {name}_real;

/* Sample time [s]: call {name}_step once every {name.upper()}_TS seconds. */
#define {upper}_TS {c_literal(ts)}

/* Number of gains {name}_set_gains takes. */
#define {upper}_N_GAINS {len(gain_names)}

/* One controller instance ({law}): packed parameters and state. Treat as opaque. */
typedef struct {{
    {name}_real p[{n_p}];
    {name}_real s[{n_s}];
}} {name}_ctl;

/* Start at rest, bumpless, as the simulator starts: the exported gains, measurement y0 [m]
 * with the reference equal to it, holding command u0 [-]; the first {name}_step with
 * r = y = y0 returns u0. */
void {name}_init({name}_ctl *c, {name}_real y0, {name}_real u0);

/* The same start with the gains the instance has now (after {name}_set_gains). */
void {name}_reset({name}_ctl *c, {name}_real y0, {name}_real u0);

/* One sample: reference r [m], measurement y [m] -> command u [-], limited; hold it until
 * the next sample. */
{name}_real {name}_step({name}_ctl *c, {name}_real r, {name}_real y);

/* One sample with the reference's feed-forward signals: reference r [m], its velocity rd
 * [m/s] and acceleration rdd [m/s^2] at the same instant, measurement y [m] -> command u
 * [-]. {name}_step is this call with rd = rdd = 0; {ff_note} */
{name}_real {name}_step_ff({name}_ctl *c, {name}_real r, {name}_real rd,
    {name}_real rdd, {name}_real y);

/* Replace the gains, keeping the state; the next sample uses them:
{gains_doc}
 * Returns 0, or i + 1 when g[i] is out of range ({allowed}), leaving the gains as they
 * were. */
int {name}_set_gains({name}_ctl *c, const double g[{upper}_N_GAINS]);

/* Name of gain i (0 <= i < {upper}_N_GAINS), or NULL. */
const char *{name}_gain_name(int i);

/* The exported value of gain i, or NAN. */
double {name}_gain_default(int i);
{alpha}
#ifdef __cplusplus
}}
#endif

#endif /* {upper}_H */
"""


def _source(name: str, upper: str, real: Real, info: Sequence[str], sys_defs: str, laws: str,
            consts: Sequence[str], class_gains: Sequence[str], checks: Sequence[str],
            n_g: int, gain_names: Sequence[str], self_tuning: bool) -> str:
    float_def = "#define FS_FLOAT 1\n" if real == "float" else ""
    names = ", ".join(c_string(g) for g in gain_names)
    alpha = ""
    if self_tuning:
        alpha = f"""
{name}_real {name}_alpha(const {name}_ctl *c)
{{
    return c->s[FS_S_ALPHA];
}}
"""
    n_cg = max(len(class_gains), 1)
    return f"""{c_comment(info)}
#include "{name}.h"

#if !defined({upper}_CODE_ID) || {upper}_CODE_ID != 0x@STAMP@UL
#error "{name}.h comes from another export than {name}.c: export both again"
#endif

#include <float.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

typedef {name}_real fs_real;
{float_def}
{sys_defs}
{laws}
/* The packed parameters of the exported controller (controller.pack() in Python), its
 * gains, and the constants the law packs new gains with. */
{consts[0]}
{consts[1]}
{consts[2]}

void {name}_init({name}_ctl *c, {name}_real y0, {name}_real u0)
{{
    memcpy(c->p, fs_p0, sizeof c->p);
    {name}_reset(c, y0, u0);
}}

void {name}_reset({name}_ctl *c, {name}_real y0, {name}_real u0)
{{
    fs_law_rest(c->p, c->s, y0, u0);
}}

{name}_real {name}_step({name}_ctl *c, {name}_real r, {name}_real y)
{{
    return fs_law_step(c->p, c->s, r, y, 0, 0);
}}

{name}_real {name}_step_ff({name}_ctl *c, {name}_real r, {name}_real rd,
    {name}_real rdd, {name}_real y)
{{
    return fs_law_step(c->p, c->s, r, y, rd, rdd);
}}

int {name}_set_gains({name}_ctl *c, const double g[{upper}_N_GAINS])
{{
    double cg[{n_cg}];
{chr(10).join(checks)}
{chr(10).join(f"    cg[{i}] = {expr};" for i, expr in enumerate(class_gains))}
    fs_law_pack(c->p, cg, fs_k0);
    return 0;
}}

const char *{name}_gain_name(int i)
{{
    static const char *const names[{n_g}] = {{{names}}};
    return (i >= 0 && i < {n_g}) ? names[i] : NULL;
}}

double {name}_gain_default(int i)
{{
    return (i >= 0 && i < {n_g}) ? fs_g0[i] : NAN;
}}
{alpha}"""
