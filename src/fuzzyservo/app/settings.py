"""What the browser page shows, as a run (:class:`~fuzzyservo.run.RunSpec`), and its run.

The page holds one :class:`PageSettings`; :meth:`PageSettings.run_spec` is the run it
describes, whose :meth:`~fuzzyservo.run.RunSpec.to_argv` is the command line of ``fuzzyservo
simulate`` that makes the same run, and :func:`run_page` builds and runs it as that command
does (the command resolves its command line into the same ``RunSpec``). So the command the
page offers to copy reproduces the run bit for bit, and every bad value is reported in the
one line the CLI prints for it (docs/app.md).

Units: every field here is SI, as on the command line; the page shows some in engineering
units (:data:`PHYSICAL`) and converts once, at its edge.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field, replace
from decimal import Decimal
from pathlib import Path
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..errors import FuzzyServoError, InputError, UsageError
from ..registry import (
    DEFAULT_SUBSTEP,
    OptionSpec,
    controller_kind,
    controller_options,
    plant_kind,
)
from ..run import RunSpec

__all__ = [
    "MAX_PAGE_SAMPLES",
    "PAGE_RUN",
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

#: Samples (duration / sample time) of a run the page draws: every sample of each series goes
#: to the browser on each redraw, 200,000 are ~8 MB and a 200 s run at 1 ms.
MAX_PAGE_SAMPLES = 200_000


#: The run the page opens with: the self-tuning fuzzy PI on the linear plant, a 5 s step of
#: 0.1 m (its gains are the shipped tuned ones, :func:`default_gains`).
PAGE_RUN = RunSpec(controller="stfpi", plant="linear", duration=5.0)


class PageSettings:
    """Everything that decides the page's run: a :class:`~fuzzyservo.run.RunSpec` (SI units,
    as on the command line), held as the command line would write it.

    ``PageSettings(controller="pid", gains=...)`` is :data:`PAGE_RUN` with those fields of
    the run changed; ``PageSettings(run)`` holds ``run``. The run is kept normalised: the
    noise seed only with noise, the RK4 step bound only on the nonlinear plant (what the
    command line then leaves out). The run's fields read as the settings' own
    (``settings.controller`` is ``settings.run.controller``); the settings are immutable,
    :meth:`replace` gives changed ones.
    """

    __slots__ = ("run",)
    run: RunSpec

    def __init__(self, run: RunSpec | None = None, /, **fields: Any) -> None:
        spec = replace(PAGE_RUN if run is None else run, **fields)
        if spec.noise_std == 0.0 and spec.seed != 0:
            spec = replace(spec, seed=0)
        if spec.plant != "nonlinear" and spec.substep != DEFAULT_SUBSTEP:
            spec = replace(spec, substep=DEFAULT_SUBSTEP)
        object.__setattr__(self, "run", spec)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_") or name == "run":  # (copying, pickling: not a run field)
            raise AttributeError(name)
        if name in RunSpec.__dataclass_fields__:
            return getattr(self.run, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"PageSettings are immutable: use .replace({name}=...)")

    def __eq__(self, other: object) -> bool:
        return isinstance(other, PageSettings) and other.run == self.run

    def __hash__(self) -> int:
        return hash(self.run)

    def __repr__(self) -> str:
        return f"PageSettings({self.run!r})"

    def __reduce__(self) -> tuple[Any, tuple[RunSpec]]:
        # copy, deepcopy and pickle rebuild the settings from their run
        return (PageSettings, (self.run,))

    def replace(self, **changes: Any) -> PageSettings:
        """These settings with ``changes`` to fields of the run."""
        return PageSettings(self.run, **changes)

    def run_spec(self) -> RunSpec:
        """The run these settings describe."""
        return self.run

    def argv(self) -> list[str]:
        """The arguments of ``fuzzyservo simulate`` that make this run (no output option):
        :meth:`RunSpec.to_argv <fuzzyservo.run.RunSpec.to_argv>`."""
        return self.run.to_argv()

    def command(self) -> str:
        """The ``fuzzyservo simulate`` command that reproduces the run and prints its step
        metrics (what the page shows beside the plots)."""
        return self.run.command()

    def gain_map(self) -> dict[str, float]:
        """The gains as a mapping."""
        return dict(self.run.gains)

    def with_gain(self, name: str, value: float) -> PageSettings:
        """These settings with gain ``name`` set to ``value``."""
        return self.replace(gains=tuple((k, value if k == name else v)
                                        for k, v in self.run.gains))

    def option_flags(self) -> list[str]:
        """The command-line flags of the options set."""
        return [option(name).flag for name, _ in self.run.options]


def option(name: str) -> OptionSpec:
    """The declaration of the offered controller option ``name`` (the registry's)."""
    return next(o for o in controller_options() if o.name == name)


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
    started = time.perf_counter()
    samples = settings.duration / settings.ts
    if samples > MAX_PAGE_SAMPLES:  # (NaN passes on to the run's own message)
        raise InputError(f"the page draws at most {MAX_PAGE_SAMPLES:,} samples per run; "
                         f"duration / sample time is {samples:,.0f}: shorten the run or run "
                         f"it with the command")
    built = settings.run_spec().build()
    res = built.simulate()
    metrics = res.metrics().as_dict()
    return PageRun(settings=settings, t=res.t, r=res.r, y=res.y, u=res.u,
                   alpha=np.asarray(res.alpha, dtype=np.float64),
                   metrics={k: float(v) for k, v in metrics.items()},
                   notes=built.notes(), seconds=time.perf_counter() - started, result=res)


#: Set once the page's loops are compiled (or loaded from the cache): :func:`warm_up`.
WARMED = threading.Event()


def warm_up() -> None:
    """Compile (or load from the cache) the loops the page runs first: its first run's
    (:data:`PAGE_RUN`: the self-tuning fuzzy PI on the linear plant), then the same
    controller on the nonlinear plant; sets
    :data:`WARMED` after the first. ``fuzzyservo app`` runs it in a thread while the server
    already serves, and the page says it is warming up until it is done."""
    try:
        for plant in (PAGE_RUN.plant, "nonlinear"):
            run_page(PageSettings(plant=plant, gains=default_gains(PAGE_RUN.controller, plant)))
            WARMED.set()
    finally:
        WARMED.set()  # a failed warm-up leaves the page's own run to report the error


def error_line(exc: BaseException) -> str:
    """The one line the CLI prints for ``exc`` (``fuzzyservo: error: ...``; a usage error
    names the command: ``fuzzyservo simulate: error: ...``)."""
    text = " ".join(str(exc).split())
    if isinstance(exc, UsageError):
        return text
    if isinstance(exc, FuzzyServoError):
        return f"fuzzyservo: error: {text}"
    return f"fuzzyservo: error: {type(exc).__name__}: {text}"


def default_gains(controller: str, plant: str) -> tuple[tuple[str, float], ...]:
    """The gains the page starts a controller with: the shipped tuned gains
    (``data/gains/PLANT-KIND.toml``) of the kind and plant the registry names for it
    (:attr:`~fuzzyservo.registry.ControllerKind.start_gains`,
    :attr:`~fuzzyservo.registry.PlantKind.start_gains`: ``p`` and ``pi`` take the tuned
    PID's kp and ki, the small-signal plant the linear plant's), and the registry's default
    for a gain the file does not give."""
    from importlib import resources

    from ..files import read_gains_file

    kind = controller_kind(controller)
    source = kind.start_gains or kind.name
    on = plant_kind(plant)
    folder = Path(str(resources.files("fuzzyservo") / "data" / "gains"))
    path = folder / f"{on.start_gains or on.name}-{source}.toml"
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
