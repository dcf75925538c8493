"""Experiment design for identifying the servo: an open-loop command sequence to log on the rig.

``fuzzyservo identify --design`` writes the sequence that :func:`design_experiment` builds: the
valve's holding command plus

1. a rest (0.5 s): the operating point and the sensors' offsets;
2. pulse pairs of both signs, ``+a`` then ``-a`` and ``-a`` then ``+a``, each pulse long
   enough for the hydraulic mode to ring down, so the piston ramps out and back: the
   velocity gain in each direction (the asymmetric cylinder's two gains) and the step
   response of the hydraulic mode (ω_h, its damping);
3. a logarithmic chirp from ω_h/10 to above ω_h (default 3 ω_h), a whole number of cycles,
   faded in and out, with a small bias that makes it return to where it started on the
   nominal model: the frequency response around the resonance (mass, bulk modulus, damping);
4. a rest: the settling.

Everything is checked on the nominal nonlinear model (the project's simulator, with the hose
delay): the piston must stay inside ``[margin, 1 - margin]`` of the stroke and both chamber
pressures at least 1 bar above the cavitation floor. A segment whose prediction leaves these
limits has its amplitude scaled down (a note says so); no design the nominal model predicts
to reach an end stop or to cavitate is returned. The real rig differs from the nominal model
(that is why it is identified), so the stroke margin is also the allowance for its drift.

The design's notes say what to log (position and both chamber pressures: the position alone
sees ω_h = sqrt(β A²/(V M)), in which mass and bulk modulus trade off; the pressures see the
force M dv/dt) and how long. An optional sensitivity check (finite differences of the logged
signals with respect to ``load.mass``, ``fluid.oil_bulk_modulus`` and ``valve.omega_v``)
reports the condition number of the scaled sensitivity matrix.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._args import given, real
from .._io import atomic_write
from .._typing import FloatArray
from ..errors import ParameterError
from ..plant import COMMAND_LIMIT, ServoParams, linearize, with_overrides
from ..plant.dense import eigvals
from ..plant.nonlinear import PRESSURE_FLOOR_BAND
from ..registry import build_plant
from ..sim import OpenLoopResult, simulate_open_loop
from ..sim.closed_loop import NonlinearPlant
from .lsq import gram

__all__ = ["ExperimentDesign", "SENSITIVITY_FIELDS", "describe", "design_experiment"]

#: The rest before the first pulse [s].
START_REST = 0.5

#: Largest margin (fraction of the stroke kept clear at each end) [1].
MAX_MARGIN = 0.45

#: Most pulse-pair repeats.
MAX_REPEATS = 20

#: The chirp starts at ω_h / CHIRP_LOW_RATIO (the quasi-static end: the velocity gain).
CHIRP_LOW_RATIO = 10.0

#: Default top of the chirp as a multiple of ω_h.
CHIRP_HIGH_RATIO = 3.0

#: Fraction of the distance to the nearer margin that one pulse or the chirp's lowest
#: frequency may use on the linear model (the rest covers what the linear model leaves out).
EXCURSION_SHARE = 0.5

#: Factor applied to a segment's amplitude each time the nominal model leaves the limits.
SCALE_STEP = 0.7

#: Most rescalings before the design is refused.
MAX_RESCALES = 16

#: Relative step of the sensitivity check's central differences [1].
SENSITIVITY_STEP = 1.0e-3

#: The parameters of the sensitivity check (dotted ServoParams fields).
SENSITIVITY_FIELDS: tuple[str, ...] = ("load.mass", "fluid.oil_bulk_modulus", "valve.omega_v")

#: Measurement noise that weights the position in the sensitivity check [m].
NOISE_POSITION = 1.0e-5

#: Measurement noise that weights each chamber pressure in the sensitivity check [Pa].
NOISE_PRESSURE = 1.0e4

#: Lowest log rate to ask for [Hz]: ten samples a period up to ~100 Hz (the valve's band).
LOG_RATE = 1000.0


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class ExperimentDesign:
    """An open-loop identification experiment: the command sequence and what to log.

    ``u[k]`` is the command held from ``t[k]`` to ``t[k] + dt``. Before ``t = 0`` and after
    the sequence the valve holds ``hold``; the sequence ends with a rest at ``hold``.
    """

    t: FloatArray  #: sample times, k dt [s], (n,)
    u: FloatArray  #: valve command, fraction of rated input, open loop [-], (n,)
    dt: float  #: sample time of the command [s]
    duration: float  #: how long to log: the sequence including the final settling [s]
    omega_h: float  #: hydraulic natural frequency at the start position [rad/s]
    damping: float  #: hydraulic damping ratio at the start position [1]
    chirp_band: tuple[float, float]  #: the chirp's first and last frequency [Hz]
    predicted_min: float  #: lowest piston position on the nominal model [m]
    predicted_max: float  #: highest piston position on the nominal model [m]
    pressure_min: float  #: lowest chamber pressure on the nominal model (absolute) [Pa]
    pressure_max: float  #: highest chamber pressure on the nominal model (absolute) [Pa]
    position: float  #: start position [m]
    hold: float  #: the holding (trim) command at the start position [-]
    step_amplitude: float  #: the pulses' amplitude about ``hold`` [-]
    chirp_amplitude: float  #: the chirp's amplitude about ``hold`` (bias excluded) [-]
    chirp_bias: float  #: the chirp's bias about ``hold``, for no net drift [-]
    limits: tuple[float, float]  #: the positions the design must stay inside [m]
    #: (name, start, end) of each segment [s]
    segments: tuple[tuple[str, float, float], ...]
    #: condition number of the noise-weighted sensitivity matrix of the position and both
    #: pressures to relative changes of :data:`SENSITIVITY_FIELDS`; nan when not computed [1]
    condition: float
    #: the same for the position alone; nan when not computed [1]
    condition_position: float
    notes: tuple[str, ...]  #: what to log and why, one line each

    def to_csv(self, path: str | Path) -> None:
        """Write columns ``t, u`` (SI, shortest round-trip text) after ``#`` comment lines
        holding the notes, atomically.

        Parameters
        ----------
        path : str or Path
            Target file; replaced only when the whole file is written.

        Raises
        ------
        OutputError
            The file cannot be written; a previous file is left as it was.
        """
        with atomic_write(path) as fh:
            fh.write("# fuzzyservo identify --design: open-loop valve command\n")
            for line in self.notes:
                fh.write("# " + " ".join(line.split()) + "\n")
            fh.write("t,u\n")
            fh.writelines(f"{t!r},{u!r}\n" for t, u in zip(self.t.tolist(), self.u.tolist(),
                                                          strict=True))


def _count(value: Any, name: str, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) \
            or not low <= int(value) <= high:
        raise ParameterError(f"{name} must be an integer from {low} to {high}, "
                             f"got {given(value)}")
    return int(value)


def _samples(seconds: float, dt: float) -> int:
    return max(1, round(seconds / dt))


@dataclass(frozen=True, slots=True, kw_only=True)
class _Plan:
    """The design's timing, decided before the amplitudes."""

    pulse: int  #: samples of a +a pulse
    f0: float  #: chirp start [Hz]
    f1: float  #: chirp end [Hz]
    chirp_time: float  #: chirp length (whole cycles) [s]


def _chirp(plan: _Plan, dt: float) -> tuple[FloatArray, FloatArray]:
    """Unit log-sweep sin φ(t) over whole cycles and its raised-cosine fade envelope.

    The transcendentals are the C library's, per sample: numpy's vector ``expm1``, ``sin``
    and ``cos`` round differently on processors with AVX-512, and the excitation is a
    result (docs/architecture.md, "Machine-independent results")."""
    n = _samples(plan.chirp_time, dt)
    tc = np.arange(n, dtype=np.float64) * dt
    rate = math.log(plan.f1 / plan.f0) / plan.chirp_time
    scale = 2.0 * math.pi * plan.f0
    phase = [scale * math.expm1(rate * v) / rate for v in tc.tolist()]
    env = np.ones(n)
    for fade, where in ((min(2.0 / plan.f0, plan.chirp_time / 4.0), tc),
                        (min(10.0 / plan.f1, plan.chirp_time / 4.0), (n - 1) * dt - tc)):
        inside = where < fade
        ramp = np.array([0.5 - 0.5 * math.cos(math.pi * v / fade)
                         for v in where[inside].tolist()])
        env[inside] = np.minimum(env[inside], ramp)
    return np.array([math.sin(v) for v in phase]), env


def _nonlinear(params: ServoParams, x0: float) -> NonlinearPlant:
    plant = build_plant("nonlinear", params, x0)
    if not isinstance(plant, NonlinearPlant):  # the registry's "nonlinear" kind is this
        raise TypeError(f"build_plant('nonlinear') gave a {type(plant).__name__}")
    return plant


def _simulate(plant: NonlinearPlant, u: FloatArray, dt: float, delay: float) -> OpenLoopResult:
    return simulate_open_loop(plant, u, duration=u.shape[0] * dt, dt=dt, delay=delay)


def _drift(plant: NonlinearPlant, excitation: FloatArray, rest: int, dt: float,
           delay: float) -> float:
    """Net displacement [m] of ``excitation`` (about the hold) followed by ``rest`` samples."""
    u = np.concatenate([plant.u0 + excitation, np.full(rest, plant.u0)])
    res = _simulate(plant, u, dt, delay)
    return float(res.x[-1] - res.x[0])


def _pulses(plant: NonlinearPlant, a: float, plan: _Plan, dt: float, delay: float,
            rest: int, repeats: int) -> tuple[FloatArray, int]:
    """Pulse pairs (+a, -a) and (-a, +a) with rests; the -a pulse is lengthened (or cut) so
    that each pair returns on the nominal model. Returns the excitation and the -a length."""
    up = _drift(plant, np.full(plan.pulse, a), rest, dt, delay)
    down = _drift(plant, np.full(plan.pulse, -a), rest, dt, delay)
    if not (up > 0.0 and down < 0.0):
        raise ParameterError(f"the nominal model does not move under a pulse of {a:.3g} about "
                             f"the holding command (displacements {up:.3g} m, {down:.3g} m); "
                             f"no pulse design is possible for these parameters")
    n_down = _samples(plan.pulse * dt * up / -down, dt)
    gap = np.zeros(rest)
    pair = np.concatenate([np.full(plan.pulse, a), gap, np.full(n_down, -a), gap,
                           np.full(n_down, -a), gap, np.full(plan.pulse, a), gap])
    return np.tile(pair, repeats), n_down


def _check_args(params: Any, position: Any, dt: Any, amplitude: Any, margin: Any,
                f_max: Any, repeats: Any) -> tuple[float, float, float, float,
                                                   float | None, int]:
    if not isinstance(params, ServoParams):
        raise ParameterError(f"params must be a ServoParams, got {given(params)}")
    stroke = params.cylinder.stroke
    dt = real(dt, "dt", "s", positive=True)
    amplitude = real(amplitude, "amplitude")
    if not 0.0 < amplitude <= COMMAND_LIMIT:
        raise ParameterError(f"amplitude must be in (0, {COMMAND_LIMIT:g}] (a fraction of the "
                             f"valve's rated input), got {amplitude!r}")
    margin = real(margin, "margin")
    if not 0.0 <= margin < MAX_MARGIN:
        raise ParameterError(f"margin must be in [0, {MAX_MARGIN}) (the fraction of the stroke "
                             f"kept clear at each end), got {margin!r}")
    x0 = stroke / 2.0 if position is None else real(position, "position", "m")
    lo, hi = margin * stroke, (1.0 - margin) * stroke
    if not 0.0 < x0 < stroke:
        raise ParameterError(f"position must be inside the stroke (0, {stroke!r}) m, "
                             f"got {x0!r} m")
    if not lo < x0 < hi:
        raise ParameterError(f"position must be inside the margins ({lo!r}, {hi!r}) m "
                             f"(margin {margin!r} of the stroke {stroke!r} m), got {x0!r} m")
    fm = None if f_max is None else real(f_max, "f_max", "Hz", positive=True)
    return x0, dt, amplitude, margin, fm, _count(repeats, "repeats", 1, MAX_REPEATS)


def design_experiment(params: ServoParams, *, position: float | None = None, dt: float = 1e-3,
                      amplitude: float = 0.2, margin: float = 0.1, f_max: float | None = None,
                      repeats: int = 2, sensitivity: bool = True) -> ExperimentDesign:
    """Design an open-loop identification experiment that stays within stroke and valve limits.

    Parameters
    ----------
    params : ServoParams
        Nominal parameters: the experiment is planned and checked on them.
    position : float, optional
        Start position inside the margins [m]; default mid-stroke.
    dt : float
        Sample time of the command sequence [s], > 0. The chirp's top must stay below a
        fifth of the Nyquist frequency, 1/(10 dt).
    amplitude : float
        Largest excitation about the holding command, in (0, 1] [-]; it is further limited
        by the valve (|hold| + amplitude <= 1) and by the stroke.
    margin : float
        Fraction of the stroke to keep clear at each end, in [0, 0.45) [1].
    f_max : float, optional
        Top of the chirp [Hz], above the hydraulic natural frequency ω_h/2π and below 1/(10
        dt). Default 3 ω_h/2π, capped below the valve's band ω_v/2π (given explicitly it may
        exceed it).
    repeats : int
        Number of times the pulse pairs are repeated, 1 to 20.
    sensitivity : bool
        Compute the sensitivity check (six more runs of the nominal model) and report its
        condition numbers.

    Returns
    -------
    ExperimentDesign

    Raises
    ------
    ParameterError
        An argument out of its range (the message names the value and the range), a start
        position without an equilibrium, a ``dt`` too coarse to excite ω_h, or parameters
        for which even small amplitudes leave the limits on the nominal model.

    Notes
    -----
    The position excursion of a pulse of amplitude a and length T is about K_o a T (eq. (8),
    K_o = Q_rated/A_f); a sine of amplitude a at ω moves it by about K_o a/ω. The pulse length
    is the hydraulic mode's ring-down time, 4/(δ ω_h) (at least three periods, at most 10 s),
    and the chirp lasts 3 ln(f1/f0)/(2 δ² ω_h) (δ at least 0.05; 5 s to 60 s), so that it
    spends several time constants in the resonance's half-power band.
    """
    x0, dt, amplitude, margin, fm, repeats = _check_args(params, position, dt, amplitude,
                                                         margin, f_max, repeats)
    stroke = params.cylinder.stroke
    lo, hi = margin * stroke, (1.0 - margin) * stroke
    lin = linearize(params, x0)
    omega_h, zeta = lin.omega_0, lin.damping
    f_h = omega_h / (2.0 * math.pi)
    f_v = params.valve.omega_v / (2.0 * math.pi)
    f_cap = 1.0 / (10.0 * dt)  # a fifth of the Nyquist frequency
    notes: list[str] = []
    if fm is None:
        f1 = min(CHIRP_HIGH_RATIO * f_h, f_cap, f_v)
        if not f1 > f_h:
            raise ParameterError(
                f"dt = {dt!r} s is too coarse to excite the hydraulic mode at {f_h:.4g} Hz: "
                f"the chirp must stay below 1/(10 dt) = {f_cap:.4g} Hz; use dt <= "
                f"{1.0 / (10.0 * CHIRP_HIGH_RATIO * f_h):.3g} s")
    else:
        if not f_h < fm <= f_cap:
            raise ParameterError(f"f_max must be in ({f_h:.6g}, {f_cap:.6g}] Hz (above the "
                                 f"hydraulic natural frequency, at most 1/(10 dt)), "
                                 f"got {fm!r} Hz")
        f1 = fm
        if fm > f_v:
            notes.append(f"the chirp reaches {fm:.4g} Hz, above the valve's band "
                         f"{f_v:.4g} Hz (asked for)")
    plant = _nonlinear(params, x0)
    hold = float(plant.u0)
    delay = params.delay.transport_delay
    k_o = params.velocity_gain
    room = min(x0 - lo, hi - x0)
    a_valve = COMMAND_LIMIT - abs(hold)
    if not a_valve > 0.0:
        raise ParameterError(f"the holding command {hold:.4g} leaves the valve no range")

    settle = min(max(4.0 / (max(zeta, 1e-3) * omega_h), 3.0 * 2.0 * math.pi / omega_h), 10.0)
    pulse = _samples(settle, dt)
    z_eff = max(zeta, 0.05)
    a_limit = min(amplitude, a_valve)  # the excitation's largest value about the hold
    a_c = a_limit
    # the chirp's low end: the excursion K_o a/ω within the share of the room
    f0 = max(f_h / CHIRP_LOW_RATIO, k_o * a_c / (2.0 * math.pi * EXCURSION_SHARE * room))
    if f0 > f_h / 3.0:
        f0 = f_h / 3.0
        a_c = 2.0 * math.pi * f0 * EXCURSION_SHARE * room / k_o
        notes.append(f"chirp amplitude limited to {a_c:.3g} by the room to the margins")
    span = math.log(f1 / f0)
    t_c = min(max(3.0 * span / (2.0 * z_eff**2 * omega_h), 5.0), 60.0)
    cycles = max(3, math.ceil(t_c * (f1 - f0) / span))
    t_c = cycles * span / (f1 - f0)  # a whole number of cycles: φ(T) = 2π N
    plan = _Plan(pulse=pulse, f0=f0, f1=f1, chirp_time=t_c)

    # the pulses: K_o a (T + 2/ω_h) within the share of the room (the ramp plus its ringing)
    a_s = min(amplitude, a_valve,
              EXCURSION_SHARE * room / (k_o * (pulse * dt + 2.0 / omega_h)))
    if a_s < min(amplitude, a_valve):
        notes.append(f"pulse amplitude limited to {a_s:.3g} by the room to the margins "
                     f"(K_o a T <= {EXCURSION_SHARE:g} x {room:.3g} m)")
    rest = _samples(settle / 2.0, dt)  # between pulses: every step starts from rest
    tail = _samples(settle + delay, dt)
    sweep, env = _chirp(plan, dt)

    def chirp_part(a: float, b: float) -> FloatArray:
        return env * (b + a * sweep)

    def with_bias(a: float) -> tuple[float, float]:
        """The chirp's amplitude and the bias that cancels its net drift on the nominal
        model (a secant on two runs), the two within the excitation limit together."""
        d0 = _drift(plant, chirp_part(a, 0.0), tail, dt, delay)
        b1 = -0.05 * a
        d1 = _drift(plant, chirp_part(a, b1), tail, dt, delay)
        b = 0.0 if d1 == d0 else -d0 * b1 / (d1 - d0)
        if a + abs(b) > a_limit:  # the drift scales with the amplitude: shrink both
            shrink = a_limit / (a + abs(b))
            a, b = a * shrink, b * shrink
        return a, b

    rescaled: list[str] = []
    for _ in range(MAX_RESCALES):
        steps, n_down = _pulses(plant, a_s, plan, dt, delay, rest, repeats)
        a_c, b_c = with_bias(a_c)
        parts = [("rest", np.zeros(_samples(START_REST, dt))), ("pulses", steps),
                 ("chirp", chirp_part(a_c, b_c)), ("settle", np.zeros(tail))]
        u = hold + np.concatenate([p for _, p in parts])
        u = np.clip(u, -COMMAND_LIMIT, COMMAND_LIMIT)  # rounding only: a_s, a_c + |b| fit
        res = _simulate(plant, u, dt, delay)
        x = res.x
        pmin = np.minimum(res.p_f, res.p_n)
        floor = params.fluid.pressure_floor + PRESSURE_FLOOR_BAND
        bad = (x < lo) | (x > hi) | (pmin <= floor)
        if not bad.any():
            break
        k = int(np.argmax(bad))
        t_bad = k * dt
        edges = np.cumsum([0] + [p.shape[0] for _, p in parts])
        seg = parts[min(int(np.searchsorted(edges, k, side="right")) - 1, len(parts) - 1)][0]
        why = ("leaves the stroke margins" if (x[k] < lo or x[k] > hi)
               else "brings a chamber within 1 bar of the cavitation floor")
        if seg in ("chirp", "settle"):  # after the chirp: its drift
            rescaled.append(f"chirp amplitude {a_c:.3g} -> {a_c * SCALE_STEP:.3g}: at "
                            f"t = {t_bad:.4g} s it {why} on the nominal model")
            a_c *= SCALE_STEP
        else:
            rescaled.append(f"pulse amplitude {a_s:.3g} -> {a_s * SCALE_STEP:.3g}: at "
                            f"t = {t_bad:.4g} s it {why} on the nominal model")
            a_s *= SCALE_STEP
    else:
        raise ParameterError(
            f"no design stays inside the stroke margins ({lo:.4g}, {hi:.4g}) m and above the "
            f"cavitation floor on the nominal model at position {x0!r} m, even after "
            f"{MAX_RESCALES} reductions of the amplitude; try another start position or a "
            f"smaller margin")
    notes.extend(f"scaled down: {r}" for r in rescaled)
    n = u.shape[0]
    t = np.arange(n, dtype=np.float64) * dt
    starts = np.cumsum([0] + [p.shape[0] for _, p in parts])
    segments = tuple((name, float(starts[i] * dt), float(starts[i + 1] * dt))
                     for i, (name, _) in enumerate(parts))
    pressures = np.concatenate([res.p_f, res.p_n])
    cond, cond_y, weakest = (_conditions(params, x0, u, dt, delay) if sensitivity
                             else (math.nan, math.nan, ""))
    duration = n * dt
    design = ExperimentDesign(
        t=t, u=u, dt=dt, duration=duration, omega_h=omega_h, damping=zeta,
        chirp_band=(f0, f1), predicted_min=float(x.min()), predicted_max=float(x.max()),
        pressure_min=float(pressures.min()), pressure_max=float(pressures.max()),
        position=x0, hold=hold, step_amplitude=a_s, chirp_amplitude=a_c, chirp_bias=b_c,
        limits=(lo, hi), segments=segments, condition=cond, condition_position=cond_y,
        notes=())
    lines = _notes(design, params, pulse * dt, n_down * dt, repeats, k_o, cycles, weakest)
    object.__setattr__(design, "notes", tuple(lines + notes))
    return design


def _notes(d: ExperimentDesign, params: ServoParams, t_up: float, t_down: float,
           repeats: int, k_o: float, cycles: int, weakest: str) -> list[str]:
    rate = max(LOG_RATE, 1.0 / d.dt)
    f0, f1 = d.chirp_band
    f_h = d.omega_h / (2.0 * math.pi)
    floor = params.fluid.pressure_floor
    out = [
        f"log at least {math.ceil(d.duration)} s at >= {rate:g} Hz: t, u, position, p_f, p_n "
        f"(sequence {d.duration:.4g} s including {d.segments[-1][2] - d.segments[-1][1]:.3g} "
        f"s of settling)",
        f"command: open loop, hold {d.hold:.6g} (the trim that keeps the piston still at "
        f"{d.position:.6g} m) plus the excitation; hold the piston there before t = 0",
        "log both chamber pressures: they measure the force M dv/dt (mass) and the "
        "compression flows (bulk modulus) directly; from the position alone the two are told "
        "apart only through omega_h = sqrt(beta A^2/(V M)) and the damping, that is through "
        "the damping and leakage model",
        f"sample rate >= {rate:g} Hz: >= 10 samples a period up to {rate / 10:g} Hz "
        f"(the chirp ends at {f1:.4g} Hz)",
        f"rest {START_REST:g} s: operating point and sensor offsets",
        f"pulses: {repeats} x (+{d.step_amplitude:.3g} for {t_up:.4g} s, "
        f"-{d.step_amplitude:.3g} for {t_down:.4g} s, rest; then the reverse order), each "
        f"moving about K_o a T = {k_o * d.step_amplitude * t_up:.3g} m and back: velocity "
        f"gain each way, step response of the hydraulic mode (omega_h = {d.omega_h:.4g} "
        f"rad/s = {f_h:.4g} Hz, damping {d.damping:.3g})",
        f"chirp: log sweep {f0:.4g} -> {f1:.4g} Hz, {cycles} whole cycles, amplitude "
        f"{d.chirp_amplitude:.3g}, bias {d.chirp_bias:.3g} so it returns to the start on the "
        f"nominal model: frequency response through the resonance (mass, bulk modulus, "
        f"damping); low end K_o a/omega = "
        f"{k_o * d.chirp_amplitude / (2.0 * math.pi * f0):.3g} m",
        f"nominal model (with the hose delay {params.delay.transport_delay:g} s): position "
        f"{d.predicted_min:.4g} to {d.predicted_max:.4g} m (limits {d.limits[0]:.4g} to "
        f"{d.limits[1]:.4g} m), chamber pressures {d.pressure_min / 1e5:.4g} to "
        f"{d.pressure_max / 1e5:.4g} bar (cavitation floor {floor / 1e5:g} bar)",
        "the rig differs from the nominal model: watch the position for drift; the stroke "
        "margins are the allowance",
    ]
    if math.isfinite(d.condition):
        out.append(f"sensitivity to {', '.join(SENSITIVITY_FIELDS)} (central differences "
                   f"of ±{SENSITIVITY_STEP:g} relative on the nominal model, signals weighted "
                   f"by noise of {NOISE_POSITION:g} m and {NOISE_PRESSURE / 1e5:g} bar): "
                   f"condition number {d.condition:.3g} with both pressures, "
                   f"{d.condition_position:.3g} from the position alone; least seen: "
                   f"{weakest}")
    return out


def _conditions(params: ServoParams, x0: float, u: FloatArray, dt: float,
                delay: float) -> tuple[float, float, str]:
    """Condition numbers of the noise-weighted sensitivity matrix of (position, p_f, p_n) and
    of the position alone to relative changes of :data:`SENSITIVITY_FIELDS`, and the field
    the signals are least sensitive to."""
    weight = np.array([[1.0 / NOISE_POSITION], [1.0 / NOISE_PRESSURE], [1.0 / NOISE_PRESSURE]])

    def signals(p: ServoParams) -> FloatArray:
        r = _simulate(_nonlinear(p, x0), u, dt, delay)
        return np.stack([r.x, r.p_f, r.p_n]) * weight

    cols = []
    for name in SENSITIVITY_FIELDS:
        group, field = name.split(".")
        v = getattr(getattr(params, group), field)
        up = signals(with_overrides(params, {name: v * (1.0 + SENSITIVITY_STEP)}))
        down = signals(with_overrides(params, {name: v * (1.0 - SENSITIVITY_STEP)}))
        cols.append((up - down) / (2.0 * SENSITIVITY_STEP))
    jac = np.stack(cols, axis=-1)  # (signal, sample, parameter)
    full = jac.reshape(-1, len(SENSITIVITY_FIELDS))

    def gram_of(m: FloatArray) -> FloatArray:
        a, _ = gram(m, np.zeros(m.shape[0]))  # MᵀM, each entry summed over samples in order
        return a

    def cond(a: FloatArray) -> float:
        """κ(M) = sqrt(λ_max/λ_min) of MᵀM (symmetric: real eigenvalues), by plant.dense:
        no LAPACK, the same bits on every machine. M's condition numbers here are 1e1 to
        1e5, so MᵀM's (their squares) stay well inside double precision."""
        lam = [float(v.real) for v in eigvals(a)]
        top, low = max(lam), min(lam)
        return math.sqrt(top / low) if low > 0.0 else math.inf

    full_gram = gram_of(full)
    weakest = SENSITIVITY_FIELDS[int(np.argmin(np.diag(full_gram)))]  # least column norm
    return cond(full_gram), cond(gram_of(jac[0])), weakest


def describe(design: ExperimentDesign) -> list[str]:
    """Lines for the terminal: the segments, the limits, what to log.

    Parameters
    ----------
    design : ExperimentDesign
        A design from :func:`design_experiment`.

    Returns
    -------
    list of str
    """
    d = design
    lines = [f"experiment design: {d.duration:.4g} s at dt = {d.dt:g} s "
             f"({d.t.shape[0]} samples), start {d.position:.6g} m, hold {d.hold:.6g}"]
    lines += [f"  {name:<7} {a:8.3f} .. {b:8.3f} s" for name, a, b in d.segments]
    lines += [f"  {line}" for line in d.notes]
    return lines
