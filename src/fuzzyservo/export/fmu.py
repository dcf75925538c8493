"""FMI 2.0 co-simulation FMUs of a controller and of the servo, built from the generated C.

An FMU is a zip archive: ``modelDescription.xml``, the shared library compiled here for 64-bit
Linux (``binaries/linux64``) with the system C compiler, and the C sources (``sources/``,
listed in the model description, so a tool can compile them for another platform). Nothing
in it needs Python at run time.

Timing (docs/export.md, "FMUs"): both FMUs are sampled systems with the sample time ``ts`` as
their default step.

- The controller samples its inputs r and y at the communication point that starts a step
  when a sample is due (t = t_0 + k ts) and outputs the command u computed there, held until
  the next sample; a step may be shorter than ts, but may not pass a sample instant. This is
  the simulator's order: u_k is computed from y_k at t_k and held over [t_k, t_k + ts).
- The servo takes the command u set before a step as the command issued at its start and
  advances by whole samples (a step is an integer multiple of ts), exactly as the simulator's
  loop: the same RK4 substeps (or exact zero-order hold for the linear plants), the same
  transport delay, the same transducer rounding of the output y.
"""

from __future__ import annotations

import errno
import hashlib
import os
import re
import shutil
import signal
import subprocess
import tempfile
import uuid
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from xml.sax.saxutils import escape
from xml.sax.saxutils import quoteattr as _quoteattr

from .. import __version__
from ..errors import FuzzyServoError, OutputError, ParameterError
from ..registry import controller_kind
from ._c import c_literal, escape_text
from .controller_c import CController

__all__ = [
    "FMU_PLATFORM",
    "CompilerError",
    "FmuVariable",
    "c_compiler",
    "compile_shared",
    "controller_fmu",
    "servo_fmu",
]

#: The FMI 2.0 platform folder of the binaries built here.
FMU_PLATFORM = "linux64"

#: Flags of every build: the C must compile without a warning under them. No fused
#: multiply-adds (clang contracts by default even in ISO C mode): the C then rounds as the
#: Python does, operation by operation.
STRICT_FLAGS: tuple[str, ...] = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic",
                                 "-ffp-contract=off")


class CompilerError(FuzzyServoError, RuntimeError):
    """The C compiler is missing or refused the generated code."""


def c_compiler() -> str:
    """The C compiler to use: ``$CC`` if set, else ``cc`` or ``gcc`` on the PATH.

    Raises
    ------
    CompilerError
        None found.
    """
    cc = os.environ.get("CC")
    if cc:
        return cc
    for name in ("cc", "gcc"):
        path = shutil.which(name)
        if path:
            return path
    raise CompilerError("building an FMU needs a C compiler: neither cc nor gcc is on the "
                        "PATH (install gcc, or set CC)")


def _which_compiler(cc: str) -> str:
    """``cc`` named for a message: where it came from."""
    shown = "'" + escape_text(cc) + "'"
    return f"{shown} (from $CC)" if os.environ.get("CC") == cc else shown


def _exit_text(code: int) -> str:
    """A process's return code as words: its exit status, or the signal that ended it."""
    if code >= 0:
        return f"exited with status {code}"
    try:
        name = signal.Signals(-code).name
    except ValueError:
        name = f"signal {-code}"
    if -code == getattr(signal, "SIGXFSZ", -1):
        return f"was killed by {name} (a file grew past the size limit, ulimit -f)"
    return f"was killed by {name}"


def _first_message(stderr: str) -> str:
    """The compiler's first error line (else its first line), escaped to one line."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    first = next((ln for ln in lines if "error" in ln), lines[0] if lines else "")
    return escape_text(first[:300])


def _run_compiler(cmd: list[str], cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    try:
        return subprocess.run(cmd, capture_output=True, text=True, errors="replace",
                              check=False, cwd=cwd)
    except OSError as exc:
        raise CompilerError(f"cannot run the C compiler {_which_compiler(cmd[0])}: "
                            f"{exc.strerror or exc}") from None


def _file_size_limit() -> int | None:
    """The soft limit on the size of a file this process writes [bytes], or None."""
    try:
        import resource
    except ImportError:  # not POSIX
        return None
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return None if soft == resource.RLIM_INFINITY else int(soft)


def _compiler_works(cc: str, folder: Path) -> bool:
    """Whether ``cc`` compiles a trivial C file into a shared library in ``folder``."""
    probe = folder / "fs_probe.c"
    try:
        probe.write_text("int fs_probe(void) { return 0; }\n", encoding="ascii")
    except OSError:
        return False
    proc = _run_compiler([cc, "-fPIC", "-shared", "-o", str(folder / "fs_probe.so"),
                          str(probe)])
    return proc.returncode == 0


def compile_shared(sources: Sequence[Path], out: Path, *, include: Sequence[Path] = (),
                   flags: Sequence[str] = ()) -> None:
    """Compile ``sources`` into the shared library ``out`` with :data:`STRICT_FLAGS`, ``-O2``
    and hidden symbols (only the FMI functions are exported).

    Raises
    ------
    CompilerError
        The compiler is missing, cannot run, was killed, or failed: one line naming the
        compiler and its exit status (or signal) and its first message. When it cannot
        compile a trivial file either the compiler is named as the cause; otherwise it is
        the generated code, which is the package's to fix (please report it).
    """
    cc = c_compiler()
    cmd = [cc, *STRICT_FLAGS, "-O2", "-fPIC", "-shared", "-fvisibility=hidden",
           *flags, *(f"-I{p}" for p in include), "-o", str(out), *map(str, sources), "-lm"]
    proc = _run_compiler(cmd)
    if proc.returncode == 0:
        return
    what = _exit_text(proc.returncode)
    msg = _first_message(proc.stderr)
    said = f": {msg}" if msg else " with no message"
    limit = _file_size_limit()
    if limit is not None:
        raise CompilerError(f"the C compiler {_which_compiler(cc)} {what}{said}; a file size "
                            f"limit of {limit} bytes is set (ulimit -f), which the build may "
                            f"exceed: raise it")
    if (proc.returncode < 0 or re.search(r"signal|killed", proc.stderr, re.IGNORECASE)
            or not _compiler_works(cc, out.parent)):
        raise CompilerError(f"the C compiler {_which_compiler(cc)} {what}{said}; it cannot "
                            f"build even a trivial shared library here: install gcc or set "
                            f"CC to a working C compiler")
    raise CompilerError(f"the C compiler {_which_compiler(cc)} {what} on the generated "
                        f"code{said}; please report it with the command that made it")


@dataclass(frozen=True, slots=True)
class FmuVariable:
    """One Real variable of a model description.

    Attributes
    ----------
    name, description, unit : str
        As written in the model description (unit "" for none).
    causality : {"input", "output", "parameter", "local"}
        FMI causality.
    variability : {"continuous", "discrete", "tunable", "fixed", "constant"}
        FMI variability.
    start : float or None
        Start value (required for inputs, parameters and constants).
    initial_deps : tuple of str
        For an output: the variables its value at initialisation depends on.
    """

    name: str
    description: str
    unit: str
    causality: str
    variability: str
    start: float | None = None
    initial_deps: tuple[str, ...] = ()


# characters XML 1.0 cannot hold, not even as a character reference
_NOT_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def xml_text(text: object) -> str:
    """``text`` as XML 1.0 can hold it: verbatim, but for the characters XML cannot carry at
    all (control characters other than tab and line breaks, lone surrogates from undecodable
    file names, U+FFFE, U+FFFF), written as their escapes (``\\x01``, ``\\udcff``; see
    :func:`fuzzyservo.export._c.escape_text`)."""
    return _NOT_XML.sub(lambda m: escape_text(m.group(0)), str(text))


def quoteattr(text: object) -> str:
    """``text`` as a quoted XML attribute value: :func:`xml_text`, then ``&``, ``<``, ``>``,
    quotes, tabs and line breaks escaped (``xml.sax.saxutils.quoteattr``)."""
    return _quoteattr(xml_text(text))


def _xml_real(v: float) -> str:
    """A float as XML Schema's xs:double writes it (INF, -INF, NaN; repr otherwise)."""
    if v != v:
        return "NaN"
    if v in (float("inf"), float("-inf")):
        return "INF" if v > 0 else "-INF"
    return repr(float(v))


# base-unit exponents of the units the FMUs use (FMI 2.0 <BaseUnit>)
_BASE_UNITS: dict[str, dict[str, int]] = {
    "m": {"m": 1}, "m/s": {"m": 1, "s": -1}, "m/s2": {"m": 1, "s": -2},
    "Pa": {"kg": 1, "m": -1, "s": -2}, "N": {"kg": 1, "m": 1, "s": -2}, "s": {"s": 1},
    "1/s": {"s": -1}, "1/m": {"m": -1}, "1/(m s)": {"m": -1, "s": -1},
    "s/m": {"s": 1, "m": -1}, "s2/m": {"s": 2, "m": -1}, "1": {}, "-": {},
    # K_delta_e scales the error's change over one sample: a count of samples has no unit
    "1/m per sample": {"m": -1},
}


def _unit_definitions(units: Sequence[str]) -> str:
    out = []
    for u in dict.fromkeys(u for u in units if u):
        base = _BASE_UNITS.get(u)
        if base is None:
            out.append(f"    <Unit name={quoteattr(u)}/>")
        else:
            attrs = " ".join(f'{k}="{v}"' for k, v in base.items())
            out.append(f"    <Unit name={quoteattr(u)}><BaseUnit {attrs}/></Unit>")
    if not out:
        return ""
    return "  <UnitDefinitions>\n" + "\n".join(out) + "\n  </UnitDefinitions>\n"


def model_description(*, model_name: str, identifier: str, guid: str, description: str,
                      variables: Sequence[FmuVariable], ts: float,
                      sources: Sequence[str], variable_steps: bool = True) -> str:
    """The FMI 2.0 ``modelDescription.xml`` of a co-simulation FMU whose Real variables have
    value references 0, 1, ... in the order of ``variables``; ``variable_steps``: whether
    communication steps may vary."""
    units = [v.unit for v in variables]
    rows = []
    for vr, v in enumerate(variables):
        attrs = [f"name={quoteattr(v.name)}", f'valueReference="{vr}"',
                 f"description={quoteattr(v.description)}", f'causality="{v.causality}"',
                 f'variability="{v.variability}"']
        if v.causality in ("parameter", "local") and v.start is not None:
            attrs.append('initial="exact"')
        real = "<Real"
        if v.unit:
            real += f" unit={quoteattr(v.unit)}"
        if v.start is not None:
            real += f' start="{_xml_real(v.start)}"'
        real += "/>"
        rows.append(f"    <ScalarVariable {' '.join(attrs)}>\n      {real}\n"
                    f"    </ScalarVariable>")
    index = {v.name: i + 1 for i, v in enumerate(variables)}
    outputs = [v for v in variables if v.causality == "output"]
    out_xml = "\n".join(f'      <Unknown index="{index[v.name]}" dependencies=""/>'
                        for v in outputs)
    init_xml = "\n".join(
        f'      <Unknown index="{index[v.name]}" dependencies="'
        f'{" ".join(str(index[d]) for d in v.initial_deps)}"/>' for v in outputs)
    files = "\n".join(f"      <File name={quoteattr(s)}/>" for s in sources)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription
  fmiVersion="2.0"
  modelName={quoteattr(model_name)}
  guid="{guid}"
  description={quoteattr(description)}
  generationTool="fuzzyservo {escape(__version__)}"
  variableNamingConvention="flat"
  numberOfEventIndicators="0">
  <CoSimulation
    modelIdentifier={quoteattr(identifier)}
    needsExecutionTool="false"
    canHandleVariableCommunicationStepSize="{"true" if variable_steps else "false"}"
    canInterpolateInputs="false"
    canBeInstantiatedOnlyOncePerProcess="false"
    canNotUseMemoryManagementFunctions="false"
    canGetAndSetFMUstate="true"
    canSerializeFMUstate="true"
    providesDirectionalDerivative="false">
    <SourceFiles>
{files}
    </SourceFiles>
  </CoSimulation>
{_unit_definitions(units)}  <LogCategories>
    <Category name="logStatusError" description="errors: a refused call or value, and why"/>
  </LogCategories>
  <DefaultExperiment startTime="0" stepSize="{ts!r}"/>
  <ModelVariables>
{chr(10).join(rows)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{out_xml}
    </Outputs>
    <InitialUnknowns>
{init_xml}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def _guid(*parts: str) -> str:
    h = hashlib.sha256("\0".join(parts).encode()).hexdigest()
    return "{" + str(uuid.UUID(h[:32])) + "}"


def _fmi2_headers() -> dict[str, str]:
    root = resources.files("fuzzyservo.export") / "csrc" / "fmi2"
    return {name: (root / name).read_text(encoding="utf-8")
            for name in ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")}


def _csrc(name: str) -> str:
    return (resources.files("fuzzyservo.export") / "csrc" / name).read_text(encoding="utf-8")


def _with_wrapper(model: str) -> str:
    """``model`` inside the FMI 2.0 wrapper (csrc/fmi2_cs.c): its head, the model, its body."""
    head, sep, body = _csrc("fmi2_cs.c").partition("/* @MODEL@ */")
    if not sep:
        raise AssertionError("csrc/fmi2_cs.c lost its @MODEL@ marker")
    return head + "\n" + model + "\n" + body


def _package(identifier: str, md: str, sources: Mapping[str, str], compiled: Sequence[str]
             ) -> bytes:
    """Compile ``compiled`` (names in ``sources``) and zip the FMU; returns its bytes.

    Raises
    ------
    CompilerError
        The compiler failed (:func:`compile_shared`).
    OutputError
        The build folder (in the temporary directory) cannot be written: a full disk, a
        file size limit (``ulimit -f``), no temporary directory.
    """
    try:
        with tempfile.TemporaryDirectory(prefix="fuzzyservo-fmu-") as tmp:
            return _build(Path(tmp), identifier, md, sources, compiled)
    except OSError as exc:
        if isinstance(exc, FuzzyServoError):
            raise
        where = ("'" + escape_text(exc.filename) + "'" if exc.filename else
                 "in the temporary directory")
        why = exc.strerror or str(exc)
        if exc.errno == errno.EFBIG:
            why += " (the file size limit, ulimit -f)"
        raise OutputError(f"cannot build the FMU: writing {where} failed: {why}; nothing "
                          f"was written") from None


def _build(root: Path, identifier: str, md: str, sources: Mapping[str, str],
           compiled: Sequence[str]) -> bytes:
    src = root / "sources"
    src.mkdir()
    for name, text in {**sources, **_fmi2_headers()}.items():
        try:
            (src / name).write_text(text, encoding="utf-8")
        except OSError as exc:  # write() does not name the file
            raise OSError(exc.errno, exc.strerror, str(src / name)) from None
    lib = root / f"{identifier}.so"
    compile_shared([src / c for c in compiled], lib, include=[src])
    out = root / "fmu.zip"
    entries = [("modelDescription.xml", md.encode("utf-8"), 0o644),
               (f"binaries/{FMU_PLATFORM}/{identifier}.so", lib.read_bytes(), 0o755)]
    entries += [(f"sources/{name}", (src / name).read_bytes(), 0o644) for name in sources]
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        for arcname, data, mode in entries:  # fixed dates: the same export, the same zip
            info = zipfile.ZipInfo(arcname, date_time=(1980, 1, 1, 0, 0, 0))
            info.external_attr = mode << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, data)
    return out.read_bytes()


# --- the controller FMU ------------------------------------------------------------------

_CTL_MODEL = """\
/* FMI 2.0 model of the controller @NAME@ (generated by fuzzyservo @VERSION@). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "@NAME@.h"

#define FSM_GUID "@GUID@"
#define FSM_TS @TS@

enum { FSM_VR_R, FSM_VR_Y, FSM_VR_U, FSM_VR_ALPHA, FSM_VR_U_START, FSM_VR_TS };
/* After the gains (their value references stay where they were): the reference's velocity
 * and acceleration, the feed-forward inputs of NAME_step_ff. */
enum { FSM_VR_R_RATE = @FIRST_GAIN@ + @UPPER@_N_GAINS, FSM_VR_R_ACCEL, FSM_N_VARS };

struct fsm_model {
    @NAME@_ctl c;
    double r, y, u, alpha, u_start, t0;
    double r_rate, r_accel; /* dr/dt [m/s], d2r/dt2 [m/s2] at the sample */
    double g[@UPPER@_N_GAINS];
    double n;     /* samples taken (a whole number; exact in a double up to 2^53) */
    double since; /* time since the last sample: the sum of the steps' sizes */
};

/* The value of alpha: the law's traced state field, as simulate records it (NAN for a law
 * that traces none). */
#define FSM_TRACE(m) (@TRACE@)

static void fsm_defaults(struct fsm_model *m)
{
    int i;
    memset(m, 0, sizeof *m);
    for (i = 0; i < @UPPER@_N_GAINS; i++) {
        m->g[i] = @NAME@_gain_default(i);
    }
    @NAME@_init(&m->c, 0, 0);
    m->alpha = FSM_TRACE(m);
}

/* Time since t0 as the samples count it: (n - 1) ts to the last sample, then the steps
 * since (the nominal grid, free of the rounding that accumulates in a master's t). */
static double fsm_elapsed(const struct fsm_model *m)
{
    return (m->n > 0.0 ? (m->n - 1.0) * FSM_TS : 0.0) + m->since;
}

static void fsm_gain_message(int bad, double v, char *msg)
{
    sprintf(msg, "gain %.20s = %g is out of range (finite and >= 0; n: > 0 or inf)",
            @NAME@_gain_name(bad - 1), v);
}

static int fsm_set(struct fsm_model *m, unsigned vr, double v, int phase, char *msg)
{
    double g[@UPPER@_N_GAINS];
    int bad;
    switch (vr) {
    case FSM_VR_R:
        m->r = v;
        return 0;
    case FSM_VR_Y:
        m->y = v;
        return 0;
    case FSM_VR_R_RATE:
        m->r_rate = v;
        return 0;
    case FSM_VR_R_ACCEL:
        m->r_accel = v;
        return 0;
    case FSM_VR_U_START:
        if (phase == FSM_STEP) {
            sprintf(msg, "u_start is fixed once initialised");
            return 1;
        }
        if (!(v >= -1.0 && v <= 1.0)) {
            sprintf(msg, "u_start = %g is not a command in [-1, 1]", v);
            return 1;
        }
        m->u_start = v;
        m->u = v;
        return 0;
    default:
        break;
    }
    if (vr < @FIRST_GAIN@ || vr >= FSM_VR_R_RATE) {
        sprintf(msg, "variable %u is not settable (an output or a constant)", vr);
        return 1;
    }
    memcpy(g, m->g, sizeof g);
    g[vr - @FIRST_GAIN@] = v;
    if (phase == FSM_STEP) {
        bad = @NAME@_set_gains(&m->c, g);
        if (bad != 0) {
            fsm_gain_message(bad, g[bad - 1], msg);
            return 1;
        }
    }
    memcpy(m->g, g, sizeof g);
    return 0;
}

static int fsm_get(const struct fsm_model *m, unsigned vr, double *v)
{
    switch (vr) {
    case FSM_VR_R:
        *v = m->r;
        return 0;
    case FSM_VR_Y:
        *v = m->y;
        return 0;
    case FSM_VR_U:
        *v = m->u;
        return 0;
    case FSM_VR_ALPHA:
        *v = m->alpha;
        return 0;
    case FSM_VR_U_START:
        *v = m->u_start;
        return 0;
    case FSM_VR_TS:
        *v = FSM_TS;
        return 0;
    case FSM_VR_R_RATE:
        *v = m->r_rate;
        return 0;
    case FSM_VR_R_ACCEL:
        *v = m->r_accel;
        return 0;
    default:
        break;
    }
    if (vr < @FIRST_GAIN@ || vr >= FSM_VR_R_RATE) {
        return 1;
    }
    *v = m->g[vr - @FIRST_GAIN@];
    return 0;
}

static int fsm_initialize(struct fsm_model *m, double t0, char *msg)
{
    int bad;
    bad = @NAME@_set_gains(&m->c, m->g);
    if (bad != 0) {
        fsm_gain_message(bad, m->g[bad - 1], msg);
        return 1;
    }
    @NAME@_reset(&m->c, (@NAME@_real)m->y, (@NAME@_real)m->u_start);
    m->u = m->u_start;
    m->alpha = FSM_TRACE(m);
    m->t0 = t0;
    m->n = 0.0;
    m->since = 0.0;
    return 0;
}

/* A sample is due at the start of the first step and whenever the steps since the last
 * sample add up to ts; a step may not pass the next sample. Counted from the steps' sizes,
 * not from t: a master's t + h drifts from t0 + k ts by rounding that grows with |t| and the
 * number of steps (1e-9 s after 334 s of 1 ms steps, 0.1 ms after 1e5 s). The tolerance is
 * 1e-6 ts plus the master's drift so far (its t against t0 plus the sum of its steps, at
 * most ts / 2), which a last step clipped to land on a stop time carries; what a step
 * passes a sample by counts towards the next (the samples stay on the steps' grid). */
static int fsm_do_step(struct fsm_model *m, double t, double h, char *msg)
{
    double drift = fabs(t - (m->t0 + fsm_elapsed(m)));
    double tol = 1e-6 * FSM_TS + (drift < 0.5 * FSM_TS ? drift : 0.5 * FSM_TS);
    int sample = m->n == 0.0 || m->since >= FSM_TS - tol;
    double since = m->n == 0.0 ? 0.0 : (sample ? m->since - FSM_TS : m->since);
    if (since + h > FSM_TS + tol) {
        sprintf(msg, "the step from t = %.17g s to %.17g s passes the next sample, due at "
                "%.17g s: a step may not be longer than the time to the next sample (ts = "
                "%g s)", t, t + h, t + (FSM_TS - since), FSM_TS);
        return 1;
    }
    if (sample) {
        m->u = (double)@NAME@_step_ff(&m->c, (@NAME@_real)m->r, (@NAME@_real)m->r_rate,
                                      (@NAME@_real)m->r_accel, (@NAME@_real)m->y);
        m->alpha = FSM_TRACE(m);
        m->n += 1.0;
    }
    m->since = since + h;
    return 0;
}
"""


def controller_fmu(cc: CController, *, kind_title: str, command: str = "") -> bytes:
    """The FMU (zip bytes) of the generated controller ``cc``: inputs ``r``, ``y``; output
    ``u`` (and ``alpha`` for the self-tuning controller); the gains as tunable parameters;
    ``u_start`` (the holding command the controller starts from, bumpless) fixed; after the
    gains, the inputs ``r_rate`` and ``r_accel`` (the reference's velocity and acceleration,
    passed to ``NAME_step_ff``; every controller has them, a law without feed-forward
    ignores them), numbered last so that the others keep their value references.

    Raises
    ------
    CompilerError
        No C compiler, or it failed.
    """
    identifier = cc.name
    first_gain = 6
    variables = [
        FmuVariable("r", "reference position", "m", "input", "continuous", 0.0),
        FmuVariable("y", "measured position", "m", "input", "continuous", 0.0),
        FmuVariable("u", "command, a fraction of the rated valve input, held between "
                    "samples", "1", "output", "discrete", initial_deps=("u_start",)),
        FmuVariable("alpha", "gain-updating factor of the last sample, as simulate records "
                    "it (1 without self-tuning; NaN for a law without one)" if cc.trace_index
                    is not None else "no gain-updating factor: NaN, as simulate records it",
                    "1", "output" if cc.self_tuning else "local", "discrete"),
        FmuVariable("u_start", "holding command at start (bumpless start from rest)", "1",
                    "parameter", "fixed", 0.0),
        FmuVariable("ts", "sample time", "s", "local", "constant", cc.ts),
    ]
    kind = controller_kind(cc.kind)
    for g, v, u in zip(cc.gain_names, cc.gains, cc.gain_units, strict=True):
        unit = "1" if u == "-" else u
        variables.append(FmuVariable(g, f"{kind.gain(g).description} [{u}]", unit,
                                     "parameter", "tunable", v))
    use = ("the law's feed-forward input" if cc.feedforward else
           "ignored by this law (it has no feed-forward)")
    variables += [
        FmuVariable("r_rate", f"reference velocity dr/dt at the sample: {use}", "m/s",
                    "input", "continuous", 0.0),
        FmuVariable("r_accel", f"reference acceleration d2r/dt2 at the sample: {use}",
                    "m/s2", "input", "continuous", 0.0),
    ]
    wrapper = f"{identifier}_fmi2.c"
    trace = "NAN" if cc.trace_index is None else f"(double)(m)->c.s[{cc.trace_index}]"
    model = (_CTL_MODEL.replace("@NAME@", cc.name).replace("@UPPER@", cc.name.upper())
             .replace("@TS@", c_literal(cc.ts))
             .replace("@FIRST_GAIN@", str(first_gain)).replace("@VERSION@", __version__)
             .replace("@TRACE@", trace))
    text = _with_wrapper(model)
    guid = _guid(cc.header, cc.source, text)  # the code: a state fits the same code only
    sources = {**cc.files(), wrapper: text.replace("@GUID@", guid)}
    md = model_description(
        model_name=f"fuzzyservo {cc.name}",
        identifier=identifier, guid=guid,
        description=f"{kind_title} controller exported by fuzzyservo {__version__}"
                    + (f" ({command})" if command else ""),
        variables=variables, ts=cc.ts, sources=[f"{cc.name}.c", wrapper])
    return _package(identifier, md, sources, [f"{cc.name}.c", wrapper])


# --- the servo FMU -----------------------------------------------------------------------

_SERVO_MODEL = """\
/* FMI 2.0 model of the servo (generated by fuzzyservo @VERSION@). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"

@PLANT@

#define FSM_GUID "@GUID@"
#define FSM_N_OUT @N_OUT@
#define FSM_HAS_FORCE @HAS_FORCE@
#define FSM_N_VARS (FSM_N_OUT + 4 + FSM_HAS_FORCE)
#define FSM_VR_FORCE (FSM_N_OUT + 4) /* the input load_force, after the constants */
#define FSM_TS @TS@
#define FSM_U_TRIM @U_TRIM@
#define FSM_DELAY @DELAY@

struct fsm_model {
    fs_servo s; /* at t0 + fs_servo_time(&s) */
    double u, t0;
    double force; /* the input load_force [N], held over each step as u is */
    double sum;   /* the sum of the steps' sizes */
};

static void fsm_defaults(struct fsm_model *m)
{
    memset(m, 0, sizeof *m);
    fs_servo_init(&m->s);
    m->u = FSM_U_TRIM;
    m->force = fs_servo_force(&m->s);
}

static int fsm_set(struct fsm_model *m, unsigned vr, double v, int phase, char *msg)
{
    (void)phase;
    if (vr == 0) {
        m->u = v;
        return 0;
    }
    if (FSM_HAS_FORCE && vr == FSM_VR_FORCE) {
        if (!isfinite(v)) {
            sprintf(msg, "load_force = %g is not a finite force [N]", v);
            return 1;
        }
        m->force = v;
        return 0;
    }
    sprintf(msg, "variable %u is not settable (only the inputs u%s are)", vr,
            FSM_HAS_FORCE ? " and load_force" : "");
    return 1;
}

static int fsm_get(const struct fsm_model *m, unsigned vr, double *v)
{
    if (vr == 0) {
        *v = m->u;
    } else if (FSM_HAS_FORCE && vr == FSM_VR_FORCE) {
        *v = m->force;
    } else if (vr <= FSM_N_OUT) {
        *v = fs_servo_output(&m->s, (int)vr - 1);
    } else if (vr == FSM_N_OUT + 1) {
        *v = FSM_TS;
    } else if (vr == FSM_N_OUT + 2) {
        *v = FSM_U_TRIM;
    } else if (vr == FSM_N_OUT + 3) {
        *v = FSM_DELAY;
    } else {
        return 1;
    }
    return 0;
}

static int fsm_initialize(struct fsm_model *m, double t0, char *msg)
{
    (void)msg;
    fs_servo_init(&m->s);
    m->t0 = t0;
    m->sum = 0.0;
    return 0;
}

/* Time since t0 as the samples count it. */
static double fsm_elapsed(const struct fsm_model *m)
{
    return fs_servo_time(&m->s);
}

/* A step is a whole number of samples, within 1e-6 ts plus the master's drift so far (its t
 * against t0 plus the sum of its steps, at most ts / 2; see the controller's FMU). */
static int fsm_do_step(struct fsm_model *m, double t, double h, char *msg)
{
    double drift = fabs(t - (m->t0 + m->sum));
    double tol = 1e-6 * FSM_TS + (drift < 0.5 * FSM_TS ? drift : 0.5 * FSM_TS);
    double n = floor(h / FSM_TS + 0.5);
    double tk = m->t0 + fs_servo_time(&m->s);
    long j;
    if (fabs(h - n * FSM_TS) > tol) {
        sprintf(msg, "the communication step %.17g s is not a whole number of samples of "
                "ts = %g s", h, FSM_TS);
        return 1;
    }
    if (fs_servo_set_force(&m->s, m->force) != 0) { /* held over the step's samples */
        sprintf(msg, "this plant takes no load force other than its own");
        return 1;
    }
    for (j = 0; j < (long)n; j++) {
        if (fs_servo_sample(&m->s, m->u) != 0) {
            sprintf(msg, "the servo state became non-finite between t = %.17g s and "
                    "%.17g s (command %g, load force %g N)", tk + (double)j * FSM_TS,
                    tk + (double)(j + 1) * FSM_TS, m->u, m->force);
            return 1;
        }
    }
    m->sum += h;
    return 0;
}
"""


def servo_fmu(servo: object, *, identifier: str, plant_name: str, description: str,
              units: Sequence[str], outputs: Sequence[str], descriptions: Sequence[str],
              ts: float, u_trim: float, delay: float, plant_code: str,
              force_op: float | None = None) -> bytes:
    """The FMU (zip bytes) of a servo whose C code (fragment and constants) is
    ``plant_code``: input ``u``; outputs ``outputs`` (``y``, the measured position, then the
    plant states); constants ``ts``, ``u_trim`` (the holding command) and ``delay``; then,
    unless ``force_op`` is None (a plant without a load-force input), the input
    ``load_force`` [N] starting at ``force_op`` (the parameter set's
    ``load.external_force``), numbered last so that the others keep their value references.

    Raises
    ------
    CompilerError
        No C compiler, or it failed.
    """
    del servo
    if len(outputs) != len(units) or len(outputs) != len(descriptions):
        raise ParameterError("servo FMU: outputs, units and descriptions differ in length")
    variables = [FmuVariable("u", "valve command, a fraction of the rated input (held over "
                             "each step)", "1", "input", "continuous", u_trim)]
    for name, unit, desc in zip(outputs, units, descriptions, strict=True):
        variables.append(FmuVariable(name, desc, "1" if unit == "-" else unit, "output",
                                     "continuous"))
    variables += [
        FmuVariable("ts", "sample time: communication steps are whole multiples", "s",
                    "local", "constant", ts),
        FmuVariable("u_trim", "command that holds the servo at rest at its start", "1",
                    "local", "constant", u_trim),
        FmuVariable("delay", "transport (hose) delay on the command", "s", "local",
                    "constant", delay),
    ]
    if force_op is not None:
        variables.append(FmuVariable(
            "load_force", "total external load force on the piston, > 0 opposes extension "
            "(the start value, the parameter set's load.external_force, holds the servo at "
            "rest; held over each step)", "N", "input", "continuous", float(force_op)))
    source = f"{identifier}.c"
    model = (_SERVO_MODEL.replace("@VERSION@", __version__).replace("@PLANT@", plant_code)
             .replace("@N_OUT@", str(len(outputs)))
             .replace("@HAS_FORCE@", "0" if force_op is None else "1")
             .replace("@TS@", c_literal(ts)).replace("@U_TRIM@", c_literal(u_trim))
             .replace("@DELAY@", c_literal(delay)))
    text = _with_wrapper(model)
    guid = _guid(text)
    md = model_description(model_name=f"fuzzyservo {plant_name} servo", identifier=identifier,
                           guid=guid, description=description, variables=variables, ts=ts,
                           sources=[source], variable_steps=False)
    return _package(identifier, md, {source: text.replace("@GUID@", guid)}, [source])
