"""The closed loops' frequency responses in the study (docs/frequency.md, docs/model.md,
"Tracking and load disturbances").

For every design of the tracking study on a plant: the analytic closed loop T (reference to
position) and its margins (:func:`fuzzyservo.analysis.closed_loop_bode`: the controller
linearised at rest, its feed-forward included, on the linear model the plant is or, for the
nonlinear plant, on its small-signal model at the same start), and on the nonlinear plant the
response measured by simulation with small sines (:func:`fuzzyservo.analysis.
measured_response`), which shows where the small-signal model stops describing the loop.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..analysis.frequency import closed_loop_bode, frequency_grid, measured_response
from ..errors import ParameterError, SimulationDivergedError
from ..run import RunSpec

__all__ = ["MARGIN_FIELDS", "FrequencyConfig", "FrequencyStudy", "run_frequency_study"]

#: The margins and closed-loop figures kept per design, with units.
MARGIN_FIELDS: tuple[tuple[str, str], ...] = (
    ("gain_margin", "-"), ("phase_crossover", "Hz"), ("phase_margin_deg", "deg"),
    ("gain_crossover", "Hz"), ("modulus_margin", "-"), ("bandwidth", "Hz"),
    ("peak_db", "dB"), ("stable", "-"))


@dataclass(frozen=True, slots=True, kw_only=True)
class FrequencyConfig:
    """The frequency responses of the study.

    Parameters
    ----------
    f_min, f_max : float
        Range of the analytic curves [Hz] (at most the Nyquist frequency).
    n : int
        Points of the analytic curves, log-spaced.
    measured : tuple of float
        Frequencies measured by simulation on the nonlinear plant [Hz].
    amplitude : float
        Amplitude of the measuring sines [m]: small (5 mm, a tenth of the tracking study's
        sines), so the valve stays below its speed limit up to the highest frequency
        (A 2π f = 0.16 m/s at 5 Hz).
    cycles : int
        Whole periods fitted per frequency, after the transient.
    """

    f_min: float = 0.05
    f_max: float = 20.0
    n: int = 241
    measured: tuple[float, ...] = (0.2, 0.5, 1.0, 2.0, 3.0, 5.0)
    amplitude: float = 0.005
    cycles: int = 3

    def __post_init__(self) -> None:
        if not (0.0 < self.f_min < self.f_max and math.isfinite(self.f_max)):
            raise ParameterError(f"FrequencyConfig needs 0 < f_min < f_max, got "
                                 f"{self.f_min!r}, {self.f_max!r}")
        if not (isinstance(self.n, int) and self.n >= 2):
            raise ParameterError(f"FrequencyConfig.n must be an integer >= 2, got {self.n!r}")
        if not all(math.isfinite(f) and f > 0.0 for f in self.measured):
            raise ParameterError(f"FrequencyConfig.measured must be > 0 Hz, got "
                                 f"{self.measured!r}")
        if not (math.isfinite(self.amplitude) and self.amplitude > 0.0):
            raise ParameterError(f"FrequencyConfig.amplitude must be > 0 m, got "
                                 f"{self.amplitude!r}")


@dataclass(frozen=True, slots=True, kw_only=True)
class FrequencyStudy:
    """The frequency responses of one plant's designs (NaN where a design has none: a law
    with no rest to linearise around, or a measured run that diverged)."""

    plant: str
    analytic_plant: str  #: the linear model the analytic curves are on
    keys: tuple[str, ...]
    frequency: FloatArray  #: analytic frequencies [Hz]
    magnitude_db: dict[str, FloatArray]  #: key -> |T| [dB]
    phase_deg: dict[str, FloatArray]  #: key -> ∠T, unwrapped [deg]
    margins: dict[str, dict[str, float]]  #: key -> MARGIN_FIELDS
    measured_frequency: FloatArray = field(default_factory=lambda: np.empty(0))  #: [Hz]
    measured_db: dict[str, FloatArray] = field(default_factory=dict)  #: key -> gain [dB]
    measured_phase_deg: dict[str, FloatArray] = field(default_factory=dict)  #: [deg]
    amplitude: float = math.nan  #: amplitude of the measuring sines [m]


def run_frequency_study(kind: str, base: Callable[[str], RunSpec], keys: Sequence[str],
                        fcfg: FrequencyConfig, *, params: Any, systems: Any = None,
                        tick: Callable[[str], None] | None = None) -> FrequencyStudy:
    """The frequency responses of the designs ``keys`` on plant ``kind`` (``base(key)``: the
    design's step run, whose controller, plant, start and delay are used)."""
    analytic_plant = "small-signal" if kind == "nonlinear" else kind
    ts = base(keys[0]).ts
    f = frequency_grid(fcfg.f_min, min(fcfg.f_max, 0.5 / ts), fcfg.n)
    n = f.size
    mag: dict[str, FloatArray] = {}
    ph: dict[str, FloatArray] = {}
    margins: dict[str, dict[str, float]] = {}
    fm = np.asarray(fcfg.measured, dtype=np.float64) if kind == "nonlinear" else np.empty(0)
    mdb: dict[str, FloatArray] = {}
    mph: dict[str, FloatArray] = {}
    for key in keys:
        spec = base(key)
        built = replace(spec, plant=analytic_plant).build(params=params, systems=systems)
        try:
            bode = closed_loop_bode(built.controller, built.plant, f, delay=spec.delay)
        except ParameterError:  # no rest to linearise around
            mag[key] = np.full(n, math.nan)
            ph[key] = np.full(n, math.nan)
            margins[key] = {name: math.nan for name, _ in MARGIN_FIELDS}
        else:
            mag[key] = np.ascontiguousarray(bode.magnitude_db)
            ph[key] = np.ascontiguousarray(bode.phase_deg)
            m = bode.margins
            margins[key] = {name: float(getattr(m, name)) for name, _ in MARGIN_FIELDS}
        if fm.size:
            run = spec.build(params=params, systems=systems)
            try:
                meas = measured_response(run.controller, run.plant, fm,
                                         amplitude=fcfg.amplitude, delay=spec.delay,
                                         cycles=fcfg.cycles)
            except SimulationDivergedError:
                mdb[key] = np.full(fm.size, math.nan)
                mph[key] = np.full(fm.size, math.nan)
            else:
                mdb[key] = np.ascontiguousarray(meas.magnitude_db)
                mph[key] = np.ascontiguousarray(meas.phase_deg)
        if tick is not None:
            tick(f"{kind}: frequency response, {key}")
    return FrequencyStudy(plant=kind, analytic_plant=analytic_plant, keys=tuple(keys),
                          frequency=f, magnitude_db=mag, phase_deg=ph, margins=margins,
                          measured_frequency=fm, measured_db=mdb, measured_phase_deg=mph,
                          amplitude=fcfg.amplitude if fm.size else math.nan)
