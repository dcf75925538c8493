"""C99 code of a registered controller: one header and one source, no heap, no globals.

The generated step is a line-by-line port of the one Python implementation of each law
(:func:`fuzzyservo.control.pid.pid_step`, :func:`fuzzyservo.control.fuzzy_pi.fuzzy_pi_step`),
with the fuzzy systems evaluated by the C port of the exact evaluators
(:mod:`fuzzyservo.export.fuzzy_c`). The packed parameter vector the Python packs
(``controller.pack()``) is compiled in, written as C99 hexadecimal literals, so the C starts
from the very same bits; ``NAME_set_gains`` re-packs new gains in C (in double, as numpy does)
for a target or an FMU that tunes them. docs/export.md gives the API and the guarantees.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import __version__
from .._typing import FloatArray
from ..control import KIND_FUZZY_PI, KIND_PID
from ..errors import ParameterError
from ..registry import ControllerKind
from ._c import Real, c_array, c_comment, c_literal

__all__ = ["CController", "check_c_name", "emit_controller"]


_C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto if "
    "inline int long register restrict return short signed sizeof static struct switch "
    "typedef union unsigned void volatile while _Bool _Complex _Imaginary main".split())


def check_c_name(name: str) -> str:
    """``name`` if it can prefix C identifiers (letters, digits, _; not a keyword).

    Raises
    ------
    ParameterError
        Not a C identifier of at most 31 characters starting with a letter, a C keyword, or
        one of the generated code's own prefixes (``fs``, ``fsm``, ``fmi``). (The instance
        type is ``NAME_ctl``, not ``NAME_t``: C and POSIX reserve the ``_t`` suffix, and
        ``pid_t`` is POSIX's.)
    """
    low = name.lower() if isinstance(name, str) else ""
    if (not isinstance(name, str) or not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,30}", name)
            or name in _C_KEYWORDS
            or low in ("fs", "fsm") or low.startswith(("fs_", "fsm_", "fmi"))):
        raise ParameterError(
            f"--name must be a C identifier of at most 31 letters, digits and _ starting with "
            f"a letter, not a C keyword, and not fs, fsm or starting with fs_, fsm_ or fmi, "
            f"got {name!r}")
    return name


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

    def files(self) -> dict[str, str]:
        """File name -> text of the two files."""
        return {f"{self.name}.h": self.header, f"{self.name}.c": self.source}


def _tables_digest(tables: Sequence[Any]) -> str:
    h = hashlib.sha256()
    for a in tables:
        arr = np.ascontiguousarray(a)
        h.update(str(arr.dtype).encode() + str(arr.shape).encode() + arr.tobytes())
    return h.hexdigest()


def _array(name: str, values: FloatArray, real: Real) -> str:
    return c_array("fs_real", name, [c_literal(v, real, f"{name}[{i}]")
                                     for i, v in enumerate(values)])


# --- PID family ---------------------------------------------------------------------------

_PID_STEP = """\
/* One PID sample on packed parameters p and state s (updated in place): the Python
 * fuzzyservo.control.pid.pid_step line by line. p: kp, ki h, a_d, b_d, b, c, u_min, u_max,
 * anti-windup (0 none, 1 clamping, 2 back-calculation), h/T_t; s: I, D, ed_prev, 0, alpha. */
static fs_real fs_pid_step(const fs_real *p, fs_real *s, fs_real r, fs_real y)
{
    fs_real e = r - y;
    fs_real ed = p[5] * r - y;
    fs_real d = p[2] * s[1] + p[3] * (ed - s[2]);
    fs_real i_new = s[0] + p[1] * e;
    fs_real v = p[0] * (p[4] * r - y) + i_new + d;
    fs_real u = v;
    if (u < p[6]) {
        u = p[6];
    }
    if (p[7] < u) {
        u = p[7];
    }
    if (p[8] == 1) {
        if ((v > p[7] && e > 0) || (v < p[6] && e < 0)) {
            i_new = s[0];
        }
    } else if (p[8] == 2) {
        i_new += p[9] * (u - v);
    }
    s[0] = i_new;
    s[1] = d;
    s[2] = ed;
    return u;
}
"""

_PID_PACK = """\
/* Pack the class gains g (kp, ki, kd, n, b, c) as PIDController.pack_gains does, in double. */
static void fs_pid_pack(fs_real *p, const double *g, double h, double u_min, double u_max,
                        double aw, double tracking_time)
{
    double kp = g[0], ki = g[1], kd = g[2], n = g[3], b = g[4], c = g[5];
    double ad, bd, tt, kbh = 0.0;
    if (isinf(n)) {
        ad = 0.0;
        bd = kd / h;
    } else {
        ad = 1.0 / (1.0 + n * h);
        bd = kd * n / (1.0 + n * h);
    }
    if (ki > 0.0) {
        tt = tracking_time > 0.0 ? tracking_time : (kd > 0.0 ? sqrt(kd / ki) : kp / ki);
        if (tt > 0.0) {
            kbh = h / tt;
            if (!(kbh <= 1.0)) {
                kbh = isnan(kbh) ? 0.0 : 1.0;
            }
        }
    }
    p[0] = (fs_real)kp;
    p[1] = (fs_real)(ki * h);
    p[2] = (fs_real)ad;
    p[3] = (fs_real)bd;
    p[4] = (fs_real)b;
    p[5] = (fs_real)c;
    p[6] = (fs_real)u_min;
    p[7] = (fs_real)u_max;
    p[8] = (fs_real)aw;
    p[9] = (fs_real)kbh;
}
"""

# --- fuzzy PI -------------------------------------------------------------------------------

_FUZZY_STEP = """\
/* One fuzzy PI sample on packed parameters p and state s (updated in place): the Python
 * fuzzyservo.control.fuzzy_pi.fuzzy_pi_step line by line. p: K_e, K_de, K_du, u_min, u_max,
 * de scale (1 or 1/h), e(-1) rule (0: zero, 1: first), filter coefficient a, self-tuning;
 * s: u(k-1), e(k-1), y_f(k-1), started, alpha. */
static fs_real fs_fuzzy_pi_step(const fs_real *p, fs_real *s, fs_real r, fs_real y)
{
    fs_real yf, e, e_prev, de, en, den, dun, alpha, u;
    if (s[3] == 0) {
        yf = y;
        e = r - yf;
        e_prev = p[6] == 1 ? e : 0;
        s[3] = 1;
    } else {
        fs_real a = p[7];
        yf = a * s[2] + (1 - a) * y;
        e = r - yf;
        e_prev = s[1];
    }
    de = (e - e_prev) * p[5];
    en = p[0] * e;
    den = p[1] * de;
@SYSTEMS@
    u = s[0] + alpha * p[2] * dun;
    if (u < p[3]) {
        u = p[3];
    }
    if (p[4] < u) {
        u = p[4];
    }
    s[0] = u;
    s[1] = e;
    s[2] = yf;
    s[4] = alpha;
    return u;
}
"""


def _fuzzy_systems_code(ctl: Any, real: Real) -> tuple[str, str]:
    """Definitions of the systems (after the evaluators' code) and the lines of the step
    that evaluate them."""
    from .fuzzy_c import emit_pair, emit_system, fragment

    du = (ctl.du_rules, ctl.du_lims)
    if ctl.self_tuning:
        alpha = (ctl.alpha_rules, ctl.alpha_lims)
        defs = fragment() + "\n" + emit_pair("fs_sys", du, alpha, real=real)
        call = "    fs_sys(en, den, &dun, &alpha);"
    else:
        defs = fragment() + "\n" + emit_system("fs_sys_du", du[0], du[1], real=real)
        call = "    dun = fs_sys_du(en, den);\n    alpha = 1;"
    return defs, call


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
        The controller built from them (its ``pack()`` is compiled in); its packed ``kind``
        (the branch of ``fuzzyservo.control.controller_step``) selects the law, so the
        exporter names no controller class (the registry builds them).
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
    law_kind = getattr(controller, "kind", None)
    if law_kind not in (KIND_PID, KIND_FUZZY_PI):
        raise ParameterError(
            f"controller {kind.name} ({type(controller).__name__}) has no C code; the "
            f"exporter expresses the PID family and the fuzzy PIs")
    if real not in ("double", "float"):
        raise ParameterError(f"real must be 'double' or 'float', got {real!r}")
    gain_names = kind.gain_names
    values = tuple(float(gains[g]) for g in gain_names)
    units = tuple(kind.gain(g).unit for g in gain_names)
    ts = float(controller.dt)
    upper = name.upper()
    packed = np.asarray(controller.pack(), dtype=np.float64)
    n_p = packed.shape[0]

    # class gains from the kind's gains: the kind's own or a constant it fixes
    merged = {**kind.implied, **dict(zip(gain_names, values, strict=True))}
    class_gains = []
    for g in controller.gain_names:
        if g in gain_names:
            class_gains.append(f"g[{gain_names.index(g)}]")
        else:
            class_gains.append(c_literal(merged[g]))

    # the registry's check of each gain (GainSpec.check): finite and >= 0, or > 0 / inf
    checks = [f"    if (!(g[{i}] > 0.0)) {{\n        return {i + 1};\n    }}"
              if kind.gain(g).allow_inf else
              f"    if (!(g[{i}] >= 0.0 && g[{i}] <= DBL_MAX)) {{\n        return {i + 1};\n    }}"
              for i, g in enumerate(gain_names)]
    if law_kind == KIND_PID:
        law = "PID"
        tables: list[Any] = []
        sys_defs = ""
        laws = _PID_STEP + "\n" + _PID_PACK
        tt = controller.tracking_time if controller.tracking_time is not None else 0.0
        repack = (f"    fs_pid_pack(c->p, cg, {c_literal(ts)}, {c_literal(controller.u_min)}, "
                  f"{c_literal(controller.u_max)}, "
                  f"{c_literal(float(packed[8]))}, {c_literal(tt)});")
        step_call = "fs_pid_step(c->p, c->s, r, y)"
        init_body = ("    c->s[0] = u0 - c->p[0] * (c->p[4] - 1) * y0;\n"
                     "    c->s[1] = 0;\n"
                     "    c->s[2] = (c->p[5] - 1) * y0;\n"
                     "    c->s[3] = 0;\n"
                     "    c->s[4] = NAN;")
        self_tuning = False
    else:
        law = "self-tuning fuzzy PI" if controller.self_tuning else "fuzzy PI"
        self_tuning = bool(controller.self_tuning)
        tables = [controller.du_rules, controller.du_lims]
        if self_tuning:
            tables += [controller.alpha_rules, controller.alpha_lims]
        defs, call = _fuzzy_systems_code(controller, real)
        sys_defs = defs
        laws = _FUZZY_STEP.replace("@SYSTEMS@", call)
        repack = ("    c->p[0] = (fs_real)cg[0];\n    c->p[1] = (fs_real)cg[1];\n"
                  "    c->p[2] = (fs_real)cg[2];")
        step_call = "fs_fuzzy_pi_step(c->p, c->s, r, y)"
        init_body = ("    c->s[0] = u0;\n    c->s[1] = 0;\n    c->s[2] = 0;\n    c->s[3] = 0;\n"
                     "    c->s[4] = 1;\n    (void)y0;")
    digest = _tables_digest(tables) if tables else ""

    options = _options(controller)
    info = [
        f"{name}.h / {name}.c: controller {kind.name} ({law}) generated by fuzzyservo "
        f"{__version__}.",
        "Do not edit: regenerate with the command below.",
        "",
        f"command:     {command}" if command else "command:     (Python API)",
        f"controller:  {kind.name} ({kind.title})",
        "gains:       " + ", ".join(f"{g} = {v!r} {u}" for g, v, u in
                                    zip(gain_names, values, units, strict=True)),
        f"options:     {options}",
        f"sample time: {ts!r} s",
        f"arithmetic:  {real}",
    ]
    if tables:
        info.append(f"fuzzy systems (SHA-256 of the packed tables): {digest}")
        for role, source, sha in systems:
            info.append(f"  {role} from {source} (file SHA-256 {sha})")
        if not systems:
            info.append("  the paper's (Aly et al. 2012, Fig. 3)")
    info += [
        "",
        "C99, standard library only (math.h); no heap, no global state: each NAME_ctl is one",
        "instance, and instances run side by side. Compile with IEEE semantics (no",
        "-ffast-math; -ffp-contract=off, which -std=c99 implies with gcc) for results equal to",
        "the Python controller's; link with -lm.",
    ]
    header = _header(name, upper, real, info, gain_names, values, units, ts, n_p, self_tuning,
                     law)
    consts = [
        _array("fs_p0", packed, real),
        c_array("double", "fs_g0", [c_literal(v) for v in values]),
    ]
    source = _source(name, upper, real, info, sys_defs, laws, consts, class_gains, checks,
                     repack, step_call, init_body, len(gain_names), gain_names, self_tuning)
    stamp = hashlib.sha256((header + source).encode()).hexdigest()[:8]
    header = header.replace("@STAMP@", stamp)
    source = source.replace("@STAMP@", stamp)
    return CController(name=name, kind=kind.name, header=header, source=source, real=real,
                       gain_names=gain_names, gains=values, gain_units=units, ts=ts,
                       self_tuning=self_tuning, digest=digest)


def _options(controller: Any) -> str:
    if controller.kind == KIND_PID:
        tt = ("default" if controller.tracking_time is None
              else f"{controller.tracking_time!r} s")
        return (f"anti_windup = {controller.anti_windup}, tracking_time = {tt}, u in "
                f"[{controller.u_min!r}, {controller.u_max!r}]")
    return (f"initial_error = {controller.initial_error}, de_per = {controller.de_per}, "
            f"filter_time = {controller.filter_time!r} s, u in [{controller.u_min!r}, "
            f"{controller.u_max!r}]")


def _header(name: str, upper: str, real: Real, info: Sequence[str], gain_names: Sequence[str],
            values: Sequence[float], units: Sequence[str], ts: float, n_p: int,
            self_tuning: bool, law: str) -> str:
    if law == "PID":
        change = "the proportional and derivative terms change at once"
    else:
        change = "incremental: the command continues from the last one"
    allowed = "finite and >= 0" + ("; n: > 0 or infinity" if "n" in gain_names else "")
    gains_doc = "\n".join(f" *   g[{i}] = {g} [{u}] (exported: {v!r})"
                          for i, (g, v, u) in enumerate(zip(gain_names, values, units,
                                                            strict=True)))
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
    {name}_real s[5];
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

/* Replace the gains, keeping the state; the next sample uses them
 * ({change}):
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
            repack: str, step_call: str, init_body: str, n_g: int,
            gain_names: Sequence[str], self_tuning: bool) -> str:
    float_def = "#define FS_FLOAT 1\n" if real == "float" else ""
    names = ", ".join(f'"{g}"' for g in gain_names)
    alpha = ""
    if self_tuning:
        alpha = f"""
{name}_real {name}_alpha(const {name}_ctl *c)
{{
    return c->s[4];
}}
"""
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
/* The packed parameters of the exported controller (controller.pack() in Python), and its
 * gains. */
{consts[0]}
{consts[1]}

void {name}_init({name}_ctl *c, {name}_real y0, {name}_real u0)
{{
    memcpy(c->p, fs_p0, sizeof c->p);
    {name}_reset(c, y0, u0);
}}

void {name}_reset({name}_ctl *c, {name}_real y0, {name}_real u0)
{{
{init_body}
}}

{name}_real {name}_step({name}_ctl *c, {name}_real r, {name}_real y)
{{
    return {step_call};
}}

int {name}_set_gains({name}_ctl *c, const double g[{upper}_N_GAINS])
{{
    double cg[{len(class_gains)}];
{chr(10).join(checks)}
{chr(10).join(f"    cg[{i}] = {expr};" for i, expr in enumerate(class_gains))}
{repack}
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
