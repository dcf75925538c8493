"""What the browser page shows, as a ``fuzzyservo simulate`` command line, and its run.

The page holds one :class:`PageSettings`; :meth:`PageSettings.argv` is the command line of
``fuzzyservo simulate`` that makes the same run, and :func:`run_page` makes the run by parsing
that command line with the CLI's own parser and running it through the command's own code
(:func:`fuzzyservo.commands.simulate.closed_loop`). So the command the page offers to copy
reproduces the run bit for bit, and every bad value is reported in the one line the CLI
prints for it (docs/app.md).

Units: every field here is SI, as on the command line; the page shows some in engineering
units (:data:`PHYSICAL`) and converts once, at its edge.
"""

from __future__ import annotations

import functools
import math
import shlex
import threading
import time
from dataclasses import dataclass, field, replace
from decimal import Decimal
from pathlib import Path
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..errors import FuzzyServoError, InputError
from ..registry import DEFAULT_SUBSTEP, controller_kind, controller_names

__all__ = [
    "MAX_PAGE_SAMPLES",
    "OPTION_CHOICES",
    "PHYSICAL",
    "PageRun",
    "PageSettings",
    "Physical",
    "default_gains",
    "error_line",
    "run_page",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class Physical:
    """A physical quantity the page lets a user change: a parameter field, or a run option."""

    key: str  #: ``group.field`` of :class:`~fuzzyservo.plant.ServoParams`, or a run option
    label: str  #: what the page calls it
    unit: str  #: unit shown in the page
    exponent: int  #: SI value = shown value x 10**exponent (a shift of the decimal point)
    low: float  #: slider's lower end [shown unit], or [x the set's value] when ``relative``
    high: float  #: slider's upper end, as ``low``
    relative: bool = False  #: the slider's ends are factors of the parameter set's value

    def to_si(self, shown: float) -> float:
        """The SI value of ``shown``: its decimal point shifted (2.5 µm is 2.5e-06 m, not the
        2.4999999999999998e-06 of a multiplication), so the command reads as typed."""
        return shift(shown, self.exponent)

    def from_si(self, si: float) -> float:
        """The value shown for ``si``."""
        return shift(si, -self.exponent)


def shift(value: float, exponent: int) -> float:
    """``value`` x 10**exponent, rounded once (decimal shift of its shortest repr)."""
    v = float(value)
    if not math.isfinite(v) or exponent == 0:
        return v
    return float(Decimal(repr(v)).scaleb(exponent))


#: The physical changes a user tries first, in the page's order; the sliders span the C8
#: robustness sweep's ranges (mass and bulk modulus x0.5 to x2, supply +-10 %, delay 0 to
#: 50 ms, docs/sweep.md) and beyond; the number boxes take any value the model allows.
#: ``delay`` and ``noise_std`` are run options (``--delay``, ``--noise-std``).
PHYSICAL: tuple[Physical, ...] = (
    Physical(key="load.mass", label="load mass", unit="kg", exponent=0, low=0.25, high=4.0,
             relative=True),
    Physical(key="fluid.oil_bulk_modulus", label="oil bulk modulus", unit="GPa", exponent=9,
             low=0.25, high=4.0, relative=True),
    Physical(key="supply.pressure", label="supply pressure", unit="bar", exponent=5, low=0.5,
             high=2.0, relative=True),
    Physical(key="delay", label="hose delay", unit="ms", exponent=-3, low=0.0, high=100.0),
    Physical(key="noise_std", label="sensor noise (std)", unit="µm", exponent=-6, low=0.0,
             high=100.0),
)

#: Controller options the page offers, by CLI flag: the choices (a float option has none).
OPTION_CHOICES: dict[str, tuple[str, ...]] = {
    "--anti-windup": ("clamping", "back-calculation", "none"),
    "--initial-error": ("zero", "first"),
    "--de-per": ("sample", "second"),
    "--filter-time": (),
}

#: Option key of the controller classes -> CLI flag.
_OPTION_KEYS = {"anti_windup": "--anti-windup", "initial_error": "--initial-error",
                "de_per": "--de-per", "filter_time": "--filter-time"}


#: Samples (duration / sample time) of a run the page draws: every sample of each series goes
#: to the browser on each redraw, 200,000 are ~8 MB and a 200 s run at 1 ms.
MAX_PAGE_SAMPLES = 200_000


def _num(v: float) -> str:
    """A float as the command line gets it: Python's shortest repr, which reads back to the
    same double (``inf`` for the PID's unfiltered derivative)."""
    return repr(float(v))


@dataclass(frozen=True, slots=True, kw_only=True)
class PageSettings:
    """Everything that decides the page's run (SI units, as on the command line).

    Parameters
    ----------
    controller : str
        Registered controller name.
    gains : tuple of (str, float)
        The controller's gains in the registry's order and units.
    plant : str
        Registered plant name.
    param_set : str
        Named parameter set.
    overrides : tuple of (str, float)
        ``group.field`` values that differ from the set [SI].
    delay : float
        Transport (hose) delay on the command [s].
    noise_std : float
        Standard deviation of the measurement noise [m].
    seed : int
        Seed of the noise.
    reference : str
        Reference spec, offset from the start position (``step:0.1``) [m, s].
    duration, ts : float
        Simulated time and controller sample time [s].
    start : float
        Start position, fraction of the stroke [-].
    substep : float
        Nonlinear plant's RK4 step bound [s].
    options : tuple of (str, str)
        Controller options as (CLI flag, value); only those set.
    systems : tuple of (str, str)
        Fuzzy systems read from files as (role, path).
    no_rule_value : float or None
        Value of a system from a file where no rule fires.
    """

    controller: str = "stfpi"
    gains: tuple[tuple[str, float], ...] = ()
    plant: str = "linear"
    param_set: str = "paper"
    overrides: tuple[tuple[str, float], ...] = ()
    delay: float = 0.0
    noise_std: float = 0.0
    seed: int = 0
    reference: str = "step:0.1"
    duration: float = 5.0
    ts: float = 1e-3
    start: float = 0.5
    substep: float = DEFAULT_SUBSTEP
    options: tuple[tuple[str, str], ...] = ()
    systems: tuple[tuple[str, str], ...] = ()
    no_rule_value: float | None = None

    def argv(self) -> list[str]:
        """The arguments of ``fuzzyservo simulate`` that make this run (no output option)."""
        gains = ",".join(f"{k}={_num(v)}" for k, v in self.gains)
        out = ["--plant", self.plant, "--controller", self.controller]
        if gains:
            out += ["--gains", gains]
        # numbers as --flag=value: a negative one (a typo the CLI must name) would otherwise
        # read as an option of its own
        out += ["--reference", self.reference, f"--duration={_num(self.duration)}",
                f"--ts={_num(self.ts)}", f"--start={_num(self.start)}"]
        if self.delay != 0.0:
            out += [f"--delay={_num(self.delay)}"]
        if self.noise_std != 0.0:
            out += [f"--noise-std={_num(self.noise_std)}", f"--seed={self.seed}"]
        if self.plant == "nonlinear" and self.substep != DEFAULT_SUBSTEP:
            out += [f"--substep={_num(self.substep)}"]
        for flag, text in self.options:
            out += [f"{flag}={text}"]
        return [*out, *self.system_args(), *self.parameter_args()]

    def system_args(self) -> list[str]:
        """``--du-system``, ``--alpha-system``, ``--no-rule-value``: the fuzzy systems from
        files (what ``simulate``, ``tune`` and ``export`` take alike)."""
        out: list[str] = []
        for role, file in self.systems:
            out += [f"--{role}-system", file]
        if self.no_rule_value is not None:
            out += [f"--no-rule-value={_num(self.no_rule_value)}"]
        return out

    def parameter_args(self) -> list[str]:
        """``--set`` and ``--param``: the servo's parameters (``simulate`` and ``tune``)."""
        out = [] if self.param_set == "paper" else ["--set", self.param_set]
        for key, number in self.overrides:
            out += ["--param", f"{key}={_num(number)}"]
        return out

    def command(self) -> str:
        """The ``fuzzyservo simulate`` command that reproduces the run and prints its step
        metrics (what the page shows beside the plots)."""
        return "fuzzyservo simulate " + shlex.join([*self.argv(), "--metrics"])

    def gain_map(self) -> dict[str, float]:
        """The gains as a mapping."""
        return dict(self.gains)

    def with_gain(self, name: str, value: float) -> PageSettings:
        """These settings with gain ``name`` set to ``value``."""
        return replace(self, gains=tuple((k, value if k == name else v)
                                         for k, v in self.gains))

    def option_map(self) -> dict[str, Any]:
        """The controller options as keyword arguments of the controller class."""
        back = {flag: key for key, flag in _OPTION_KEYS.items()}
        return {back[f]: (float(v) if f == "--filter-time" else v) for f, v in self.options}


@dataclass(frozen=True, slots=True)
class PageRun:
    """A run of the page: its samples, step metrics and what the command prints with it."""

    settings: PageSettings  #: what was run
    t: FloatArray  #: time [s]
    r: FloatArray  #: reference, absolute position [m]
    y: FloatArray  #: position, absolute [m]
    u: FloatArray  #: valve command, fraction of the rated input [-]
    alpha: FloatArray  #: self-tuning factor α [-] (NaN for controllers without one)
    metrics: dict[str, float]  #: step metrics, as ``simulate --metrics`` prints them
    notes: tuple[str, ...]  #: the notes the command prints on standard error
    seconds: float  #: wall time of parse, build and run [s]
    result: Any = field(repr=False)  #: the :class:`~fuzzyservo.sim.SimResult`


def run_page(settings: PageSettings) -> PageRun:
    """Run ``settings`` as ``fuzzyservo simulate`` would.

    Raises
    ------
    FuzzyServoError
        Anything the command line would reject; :func:`error_line` gives the line the CLI
        prints for it.
    """
    from ..commands.simulate import closed_loop

    started = time.perf_counter()
    samples = settings.duration / settings.ts
    if samples > MAX_PAGE_SAMPLES:  # (NaN passes on to the CLI's own message)
        raise InputError(f"the page draws at most {MAX_PAGE_SAMPLES:,} samples per run; "
                         f"duration / sample time is {samples:,.0f}: shorten the run or run "
                         f"it with the command")
    args = _parser().parse_args(["simulate", *settings.argv(), "--metrics"])
    if not (math.isfinite(args.substep) and args.substep > 0.0):
        raise InputError(f"--substep must be finite and > 0 s, got {args.substep!r}")
    closed = closed_loop(args)
    res = closed.result
    metrics = res.metrics().as_dict()
    return PageRun(settings=settings, t=res.t, r=res.r, y=res.y, u=res.u,
                   alpha=np.asarray(res.alpha, dtype=np.float64),
                   metrics={k: float(v) for k, v in metrics.items()},
                   notes=(*closed.settings.notes, *closed.notes),
                   seconds=time.perf_counter() - started, result=res)


#: Set once the page's loops are compiled (or loaded from the cache): :func:`warm_up`.
WARMED = threading.Event()


def warm_up() -> None:
    """Compile (or load from the cache) the loops the page runs first: the self-tuning fuzzy
    PI on the linear plant (the page's first run), then on the nonlinear plant; sets
    :data:`WARMED` after the first. ``fuzzyservo app`` runs it in a thread while the server
    already serves, and the page says it is warming up until it is done."""
    try:
        for plant in ("linear", "nonlinear"):
            run_page(PageSettings(plant=plant, gains=default_gains("stfpi", plant)))
            WARMED.set()
    finally:
        WARMED.set()  # a failed warm-up leaves the page's own run to report the error


def _parser() -> Any:
    """The CLI's parser, raising on a usage error; built once per set of registered
    controllers (8 ms), as parsing does not change it (a controller registered later, e.g.
    by a user's module, gets a parser that offers it)."""
    return _parser_for(controller_names())


@functools.cache
def _parser_for(names: tuple[str, ...]) -> Any:
    from ..cli import build_parser

    del names  # the cache key: the parser offers the registry's names as they are now
    return build_parser(raising=True, argv=["simulate"])


def error_line(exc: BaseException) -> str:
    """The one line the CLI prints for ``exc`` (``fuzzyservo: error: ...``; a usage error
    names the command: ``fuzzyservo simulate: error: ...``)."""
    from ..cli import UsageError

    text = " ".join(str(exc).split())
    if isinstance(exc, UsageError):
        return text
    if isinstance(exc, FuzzyServoError):
        return f"fuzzyservo: error: {text}"
    return f"fuzzyservo: error: {type(exc).__name__}: {text}"


def default_gains(controller: str, plant: str) -> tuple[tuple[str, float], ...]:
    """The gains the page starts a controller with: the shipped tuned gains of that plant
    (``data/gains/PLANT-KIND.toml``), for ``p`` and ``pi`` the tuned PID's kp (and ki), and
    the registry's default for a gain none of them gives."""
    from importlib import resources

    from ..files import read_gains_file

    kind = controller_kind(controller)
    source = {"p": "pid", "pi": "pid"}.get(controller, controller)
    folder = Path(str(resources.files("fuzzyservo") / "data" / "gains"))
    path = folder / f"{'nonlinear' if plant == 'nonlinear' else 'linear'}-{source}.toml"
    shipped = read_gains_file(path).gains if path.is_file() else {}
    out = []
    for g in kind.gains:
        value = shipped.get(g.name, g.default)
        if value is None:  # no shipped file: the geometric middle of the tuning box
            assert g.search is not None
            lo, hi = g.search
            value = math.sqrt(lo * hi) if g.log and lo > 0 else 0.5 * (lo + hi)
        out.append((g.name, float(value)))
    return tuple(out)
