"""C99 code of the servo plant (the FMU's model): constants and the ``fs_servo`` API.

The plant's maths is the fragment ``csrc/plant.c`` (:func:`plant_fragment`), a line-by-line
port of :mod:`fuzzyservo.plant.nonlinear` and of the plant half of the compiled loops
:func:`fuzzyservo.sim.loops.linear_one` and :func:`~fuzzyservo.sim.loops.nonlinear_one`
(ring buffer of delayed commands, ZOH update, RK4 split at the fractional delay, transducer
rounding). :func:`emit_servo` writes what goes after it: the plant's numbers, every one an
exact C99 hexadecimal literal of the double the Python uses, and the API::

    typedef struct { ... } fs_servo;                     /* the whole state */
    static void   fs_servo_init(fs_servo *s);            /* at rest, t_0 = 0 */
    static int    fs_servo_sample(fs_servo *s, double u);
    static double fs_servo_output(const fs_servo *s, int i);
    static double fs_servo_time(const fs_servo *s);
    static int    fs_servo_set_force(fs_servo *s, double f);   /* load force F_ext [N] */
    static double fs_servo_force(const fs_servo *s);

``fs_servo_sample(s, u)`` takes the command u_k issued at t_k = k ts and advances the plant to
t_{k+1}, exactly as one sample of the Python loops does, so a sequence of calls reproduces
``fuzzyservo simulate --open-loop`` (and, with a controller in the loop, ``fuzzyservo
simulate``) bit for bit. ``fs_servo_set_force(s, F)`` sets the total external load force the
following samples hold (the parameter set's ``load.external_force`` at init), as
``simulate(..., disturbance=)`` holds F_k over sample k: the nonlinear plant's force balance
takes it (``p[P_FEXT]``), a linear plant its response by superposition
(``LinearPlant.force_response``). docs/export-plant-c.md states the timing and the guarantees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from .. import __version__
from .._typing import FloatArray
from ..errors import ParameterError
from ..plant.nonlinear import N_PARAMS, N_STATE, P_FEXT, P_L, P_RES, STATE_NAMES
from ..plant.zoh import check_delay, discretize, split_delay
from ..sim.closed_loop import (
    MAX_RK4_STEPS,
    MAX_SAMPLES,
    LinearPlant,
    NonlinearPlant,
    substep_split,
)
from ._c import c_array, c_comment, c_literal

__all__ = ["ServoC", "emit_servo", "plant_fragment", "substep_split"]

_FRAGMENT = Path(__file__).resolve().parent / "csrc" / "plant.c"

#: Unit and description of every output name the registry's plants have (the measured
#: position ``y``, then the states of the nonlinear model, eq. (8) and the small-signal model).
_OUTPUT_INFO: dict[str, tuple[str, str]] = {
    "y": ("m", "measured piston position (transducer output, what a controller reads)"),
    "spool_lag": ("1", "output of the valve's first-order stage tau_v"),
    "spool": ("1", "spool opening x_v / x_v,max"),
    "spool_rate": ("1/s", "rate of the spool opening"),
    "p_f": ("Pa", "full-bore chamber pressure (absolute)"),
    "p_n": ("Pa", "annulus chamber pressure (absolute)"),
    "x": ("m", "piston position, 0 retracted, stroke extended"),
    "v": ("m/s", "piston velocity"),
    "a": ("m/s2", "piston acceleration (state of eq. (8))"),
}

#: Largest command ring the code may hold (a delay of MAX_SAMPLES samples, as the Python's
#: longest run): a bigger one is a typo in the delay or the sample time.
_MAX_RING = MAX_SAMPLES + 2


def plant_fragment() -> str:
    """The C99 fragment ``csrc/plant.c``, to be pasted before :attr:`ServoC.source`.

    Returns
    -------
    str
        Its text (static inline functions ``fs_nl_*``, ``fs_lin_*``, ``fs_delayed``,
        ``fs_ring_push``; it includes ``<math.h>``).
    """
    return _FRAGMENT.read_text(encoding="utf-8")


@dataclass(frozen=True, slots=True, kw_only=True)
class ServoC:
    """Generated C code of one servo plant, and what a model description needs to say of it.

    Attributes
    ----------
    source : str
        C99 text to paste after :func:`plant_fragment`: constants, ``fs_servo`` and its
        functions.
    kind : {"linear", "nonlinear"}
        Which loop the code mirrors: ``linear_one`` (eq. (8), small-signal) or
        ``nonlinear_one``.
    outputs : tuple of str
        Output names in the order of ``fs_servo_output``'s index: ``y`` (the measured
        position, after the transducer's resolution rounding), then the plant's states as in
        the CSV of ``fuzzyservo simulate --open-loop``.
    units : tuple of str
        Unit of each output (SI; ``1`` dimensionless).
    descriptions : tuple of str
        One line per output.
    start : tuple of float
        Each output at t_0, the plant at rest [its unit].
    u0 : float
        Command that holds the plant at rest, the value of every command before t_0 (the
        input's start value) [-].
    ts : float
        Sample time [s]: ``fs_servo_sample`` advances the plant by ts.
    delay : float
        Transport delay on the command [s].
    whole_samples : int
        d, the whole samples of the delay [-].
    fraction : float
        f, the rest of the delay, 0 <= f < ts [s] (delay = d ts + f).
    ring : int
        Commands held by the ring buffer, d + 2 [-].
    n_sub : int
        RK4 substeps per sample of the nonlinear plant; 0 for a linear one [-].
    n_split : tuple of int
        RK4 substeps over [t_k, t_k + f) and [t_k + f, t_{k+1}) when f > 0; ``(0, n_sub)``
        otherwise (and ``(0, 0)`` for a linear plant) [-].
    stroke : float or None
        Stroke of the cylinder [m]; None when the plant does not know it.
    force_input : bool
        Whether the plant takes a load force (``fs_servo_set_force``): the nonlinear plant,
        and a linear one with a force input ``e``. Without, only ``force_op`` is accepted.
    force_op : float
        The external load force at rest, the plant's at init [N] (the parameter set's
        ``load.external_force``).
    n_samples_max : int or None
        Most samples the code was checked for (delay and RK4 work); None: not limited.
    """

    source: str
    kind: Literal["linear", "nonlinear"]
    outputs: tuple[str, ...]
    units: tuple[str, ...]
    descriptions: tuple[str, ...]
    start: tuple[float, ...]
    u0: float
    ts: float
    delay: float
    whole_samples: int
    fraction: float
    ring: int
    n_sub: int
    n_split: tuple[int, int]
    stroke: float | None
    force_input: bool
    force_op: float
    n_samples_max: int | None


def _hex(value: float) -> str:
    """``value`` as an exact C99 hexadecimal double literal (finite only)."""
    v = float(value)
    if not math.isfinite(v):
        raise ParameterError(f"a non-finite number ({v!r}) cannot be compiled into the plant")
    return c_literal(v)


def _table(name: str, values: FloatArray) -> str:
    return c_array("double", name, [_hex(v) for v in np.asarray(values, dtype=np.float64)
                                    .ravel()])


def _output_info(names: tuple[str, ...]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    units = tuple(_OUTPUT_INFO.get(n, ("", f"state {n}"))[0] for n in names)
    desc = tuple(_OUTPUT_INFO.get(n, ("", f"state {n}"))[1] for n in names)
    return units, desc


_API = """\
/* Put the plant at rest at t_0 = 0: its start state, every command before t_0 the
 * holding command u0. */
static void fs_servo_init(fs_servo *s)
{
    int i;
@INIT@
    for (i = 0; i < FS_SERVO_RING; i++) {
        s->ubuf[i] = @U0@;
    }
    s->k = 0;
    s->w = 0;
}

/* The total external load force F [N] (> 0 opposes extension) held over the samples from
 * the next on, as the Python loops hold F_k over sample k; at init the parameter set's
 * load.external_force. Returns 0, or 1 when the plant has no load-force input (then only
 * that force is accepted). */
static int fs_servo_set_force(fs_servo *s, double f)
{
@SET_FORCE@
}

/* The load force set last [N]. */
static double fs_servo_force(const fs_servo *s)
{
@FORCE@
}

/* The command u_k [-] issued at t_k = k ts: advance the plant to t_{k+1}. Returns 0, or 1
 * when the state became non-finite (the state is then not usable). */
static int fs_servo_sample(fs_servo *s, double u)
{
    int bad = @SAMPLE@;
@SAMPLE_FORCE@
    s->k += 1;
    return bad;
}

/* Output i (0: the measured position y [m]; 1..FS_SERVO_NX: the states [SI]) at the current
 * sample time; NaN for another i. */
static double fs_servo_output(const fs_servo *s, int i)
{
    if (i == 0) {
@Y@
    }
    if (i >= 1 && i <= FS_SERVO_NX) {
@STATE@
    }
    return NAN;
}

/* The current sample time t_k = k ts [s], as the Python's grid has it. */
static double fs_servo_time(const fs_servo *s)
{
    return (double)s->k * @TS@;
}
"""


def _fill(template: str, **parts: str) -> str:
    for key, text in parts.items():
        template = template.replace(f"@{key}@", text)
    return template


def emit_servo(plant: LinearPlant | NonlinearPlant, *, ts: float, delay: float,
               n_samples_max: int | None = None) -> ServoC:
    """C99 code of ``plant`` sampled every ``ts`` with a transport ``delay`` on the command.

    Parameters
    ----------
    plant : LinearPlant or NonlinearPlant
        The plant at rest, as the registry builds it (``fuzzyservo.registry.build_plant``);
        a nonlinear plant's RK4 step bound is its ``substep`` [s].
    ts : float
        Sample time [s], finite and > 0.
    delay : float
        Transport delay on the command [s], finite and >= 0; any value, fractions of a
        sample exact (:func:`fuzzyservo.plant.zoh.split_delay`).
    n_samples_max : int, optional
        Most samples a run of the code will take. When given, the delay must not be longer
        than that run (as :func:`fuzzyservo.plant.zoh.check_delay` asks of a Python run) and
        a nonlinear plant's RK4 work is held to the Python's limit
        (:meth:`~fuzzyservo.sim.closed_loop.NonlinearPlant.check_steps`). The code does not
        depend on it: the command ring always holds d + 2 commands.

    Returns
    -------
    ServoC

    Raises
    ------
    ParameterError
        Not a plant, a bad ``ts``, ``delay`` or ``n_samples_max``, a delay of more than
        :data:`~fuzzyservo.sim.closed_loop.MAX_SAMPLES` samples, or more RK4 work than the
        Python allows.
    """
    if not isinstance(plant, LinearPlant | NonlinearPlant):
        raise ParameterError(f"emit_servo needs a LinearPlant or NonlinearPlant, got "
                             f"{type(plant).__name__}")
    if n_samples_max is not None and (isinstance(n_samples_max, bool)
                                      or not isinstance(n_samples_max, int)
                                      or n_samples_max < 1):
        raise ParameterError(f"n_samples_max must be an integer >= 1, got {n_samples_max!r}")
    d, f = split_delay(delay, ts)  # validates ts and delay
    delay = float(delay)
    ts = float(ts)
    if n_samples_max is not None:
        check_delay(delay, duration=n_samples_max * ts)
    ring = d + 2
    if ring > _MAX_RING:
        raise ParameterError(f"delay {delay!r} s is {d} samples of {ts!r} s; at most "
                             f"{MAX_SAMPLES} are allowed (the ring buffer holds d + 2 "
                             f"commands)")
    names = ("y", *plant.state_names)
    units, desc = _output_info(names)
    info = [
        f"Servo plant generated by fuzzyservo {__version__} (fuzzyservo.export.plant_c).",
        "Paste after the fragment csrc/plant.c. Do not edit: regenerate.",
        "",
        f"sample time ts = {ts!r} s; transport delay = {delay!r} s = {d} ts + {f!r} s",
        f"command ring: {ring} commands; outputs: {', '.join(names)}",
    ]
    if isinstance(plant, NonlinearPlant):
        if n_samples_max is not None:
            n_sub = plant.check_steps(ts, n_samples_max)
        else:
            n_sub = plant.n_sub(ts)
            if n_sub > MAX_RK4_STEPS:
                raise ParameterError(
                    f"substep {plant.substep!r} s at ts = {ts!r} s gives {n_sub} RK4 steps per "
                    f"sample; at most {MAX_RK4_STEPS:.0e} are allowed")
        n1, n0 = (int(v) for v in substep_split(n_sub, f, ts))
        kind: Literal["linear", "nonlinear"] = "nonlinear"
        n_p = int(np.asarray(plant.packed).size)
        if n_p != N_PARAMS:
            raise ParameterError(f"internal: the packed plant has {n_p} parameters, the C "
                                 f"fragment {N_PARAMS}")
        info += ["nonlinear two-chamber model (nonlinear_one): classical RK4, step bound "
                 f"{plant.substep!r} s,",
                 f"{n_sub} substeps per sample"
                 + (f" ({n1} before t_k + f, {n0} after)" if f > 0.0 else "")]
        consts = [
            f"enum {{ FS_SERVO_NX = {N_STATE}, FS_SERVO_RING = {ring} }};",
            _table("fs_servo_p", plant.packed),
            _table("fs_servo_x0", plant.x0),
            "typedef struct {\n"
            "    double x[FS_SERVO_NX];         /* plant state at t_k [SI] */\n"
            f"    double p[{n_p}];{' ' * (20 - len(str(n_p)))}/* fs_servo_p; p[FS_NL_P_FEXT]: "
            "the load force [N] */\n"
            "    double work[5 * FS_SERVO_NX];  /* RK4 scratch */\n"
            "    double ubuf[FS_SERVO_RING];    /* the last d + 2 commands [-] */\n"
            "    long long k;                   /* samples taken: the state is at t_k */\n"
            "    int w;                         /* ring slot of the next command */\n"
            "} fs_servo;",
        ]
        init = ("    for (i = 0; i < FS_SERVO_NX; i++) {\n"
                "        s->x[i] = fs_servo_x0[i];\n    }\n"
                f"    for (i = 0; i < {n_p}; i++) {{\n"
                "        s->p[i] = fs_servo_p[i];\n    }\n"
                "    for (i = 0; i < 5 * FS_SERVO_NX; i++) {\n"
                "        s->work[i] = 0.0;\n    }")
        sample = (f"fs_nl_sample(s->p, {_hex(ts)}, {d}, {_hex(f)},\n"
                  f"                       {n_sub}, {n1}, {n0}, {_hex(plant.u0)},\n"
                  f"                       s->ubuf, FS_SERVO_RING, &s->w, s->k, u, s->x, "
                  f"s->work)")
        y_expr = "        return fs_nl_measure(s->x, s->p);"
        state_expr = "        return s->x[i - 1];"
        # nonlinear_one: p[P_FEXT] = force[k] before the sample's substeps
        force_input = True
        force_op = float(plant.packed[P_FEXT])
        set_force = "    s->p[FS_NL_P_FEXT] = f;\n    return 0;"
        get_force = "    return s->p[FS_NL_P_FEXT];"
        sample_force = ""
        x_start = np.asarray(plant.x0, dtype=np.float64)
        res = float(plant.packed[P_RES])
        y_start = x_start[STATE_NAMES.index("x")]
        if res > 0.0:
            y_start = res * math.floor(y_start / res + 0.5)
        stroke: float | None = float(plant.packed[P_L])
        n_split = (n1, n0) if f > 0.0 else (0, n_sub)
    else:
        lp = plant.discretize(ts, delay)
        n = plant.n_states
        if int(lp[1]) != d:
            raise ParameterError(f"internal: the ZOH split the delay into {int(lp[1])} "
                                 f"samples, split_delay into {d}")
        o_g0 = 2 + n * n
        kind = "linear"
        n_sub = 0
        n_split = (0, 0)
        info += [f"linear plant (linear_one), {n} states, exact ZOH with the delay:",
                 "x_{k+1} = Phi x_k + G0 (u_{k-d} - u0) + G1 (u_{k-d-1} - u0), y = y0 + C x"]
        force_input = plant.e.size > 0
        force_op = plant.force_op
        fop = _hex(force_op)
        if force_input:
            info += ["load force F by superposition (LinearPlant.force_response), its ZOH:",
                     "xf_{k+1} = Phi_e xf_k + Ge (F_k - F_op), y += C xf, states += xf"]
            fm = discretize(plant.a, plant.e, ts, 0.0)
            force_consts = [_table("fs_servo_phie", fm.phi), _table("fs_servo_ge", fm.gamma0)]
        else:
            force_consts = []
        consts = [
            f"enum {{ FS_SERVO_NX = {n}, FS_SERVO_RING = {ring} }};",
            _table("fs_servo_phi", lp[2:o_g0]),
            _table("fs_servo_g0", lp[o_g0:o_g0 + n]),
            _table("fs_servo_g1", lp[o_g0 + n:o_g0 + 2 * n]),
            _table("fs_servo_c", lp[o_g0 + 2 * n:o_g0 + 3 * n]),
            _table("fs_servo_xop", plant.x_op),
            *force_consts,
            "typedef struct {\n"
            "    double x[FS_SERVO_NX];       /* deviation from the operating point at t_k */\n"
            "    double xn[FS_SERVO_NX];      /* scratch of the update */\n"
            "    double xf[FS_SERVO_NX];      /* the load force's part of the deviation */\n"
            "    double f;                    /* load force held over the samples [N] */\n"
            "    int forced;                  /* a force other than F_op was held */\n"
            "    double ubuf[FS_SERVO_RING];  /* the last d + 2 commands [-] */\n"
            "    long long k;                 /* samples taken: the state is at t_k */\n"
            "    int w;                       /* ring slot of the next command */\n"
            "} fs_servo;",
        ]
        init = ("    for (i = 0; i < FS_SERVO_NX; i++) {\n"
                "        s->x[i] = 0.0;\n        s->xn[i] = 0.0;\n        s->xf[i] = 0.0;\n"
                f"    }}\n    s->f = {fop};\n    s->forced = 0;")
        sample = (f"fs_lin_sample(FS_SERVO_NX, fs_servo_phi, fs_servo_g0, fs_servo_g1,\n"
                  f"                        {_hex(plant.u0)}, {d},\n"
                  f"                        s->ubuf, FS_SERVO_RING, &s->w, s->k, u, s->x, "
                  f"s->xn)")
        # run_loop adds y_F to the measurement and x_F to the kept states (superposition)
        y_expr = (f"        double y = fs_lin_output(FS_SERVO_NX, fs_servo_c, {_hex(plant.y0)}, "
                  f"s->x);\n"
                  "        return s->forced ? y + fs_lin_force_output(FS_SERVO_NX, fs_servo_c, "
                  "s->xf) : y;")
        state_expr = ("        double x = fs_servo_xop[i - 1] + s->x[i - 1];\n"
                      "        return s->forced ? x + s->xf[i - 1] : x;")
        if force_input:
            set_force = "    s->f = f;\n    return 0;"
            sample_force = (f"    if (s->f != {fop}) {{\n        s->forced = 1;\n    }}\n"
                            f"    if (s->forced) {{\n"
                            f"        bad |= fs_lin_force_sample(FS_SERVO_NX, fs_servo_phie, "
                            f"fs_servo_ge,\n"
                            f"                                   s->f - {fop}, s->xf, s->xn);"
                            f"\n    }}")
        else:
            set_force = f"    (void)s;\n    return f == {fop} ? 0 : 1;"
            sample_force = ""
        get_force = "    return s->f;"
        x_start = np.asarray(plant.x_op, dtype=np.float64)
        y_start = plant.y0
        stroke = plant.stroke
    api = _fill(_API, INIT=init, U0=_hex(plant.u0), SAMPLE=sample, Y=y_expr,
                STATE=state_expr, TS=_hex(ts), SET_FORCE=set_force, FORCE=get_force,
                SAMPLE_FORCE=sample_force)
    source = "\n\n".join([c_comment(info), *consts, api])
    return ServoC(source=source, kind=kind, outputs=names, units=units, descriptions=desc,
                  start=(float(y_start), *(float(v) for v in x_start)), u0=float(plant.u0),
                  ts=ts, delay=delay, whole_samples=d, fraction=f, ring=ring, n_sub=n_sub,
                  n_split=n_split, stroke=stroke, force_input=force_input,
                  force_op=float(force_op), n_samples_max=n_samples_max)
