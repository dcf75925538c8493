"""Reference signals for the closed loop, as offsets [m] from the start position.

Each reference is a frozen dataclass with ``values(t) -> r`` (t [s] -> r [m], numpy arrays);
the simulator adds the plant's initial output y(0), so ``Step(0.1)`` moves the piston 0.1 m
from wherever it starts (0 on the linear plant, the start position on the nonlinear plant).
:func:`parse_reference` reads the CLI form (``step:0.1``, ``ramp:0.05``, ...).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..errors import InputError

__all__ = [
    "MultiStep",
    "Ramp",
    "Reference",
    "Sine",
    "Step",
    "Trapezoid",
    "UserReference",
    "check_reference",
    "check_reference_samples",
    "parse_reference",
    "sample_reference",
]


def _finite(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"reference {name} must be finite, got {value!r}")
    return v


def _time(name: str, value: float) -> float:
    """A time of a reference [s]: finite and >= 0 (the run starts at t = 0)."""
    v = _finite(name, value)
    if v < 0.0:
        raise InputError(f"reference {name} must be >= 0 s (the run starts at t = 0), "
                         f"got {value!r}")
    return v


class Reference(Protocol):
    """A reference signal r(t) [m], relative to the start position."""

    def values(self, t: FloatArray) -> FloatArray:
        """Return r [m] at the times ``t`` [s]."""
        ...


@dataclass(frozen=True, slots=True)
class Step:
    """Step of ``amplitude`` [m] at ``time`` [s] (default 0)."""

    amplitude: float  #: step height [m]
    time: float = 0.0  #: step instant [s]

    def __post_init__(self) -> None:
        _finite("step amplitude", self.amplitude)
        _time("step time", self.time)

    def values(self, t: FloatArray) -> FloatArray:
        """r(t) [m]."""
        return np.where(np.asarray(t) >= self.time, self.amplitude, 0.0)


@dataclass(frozen=True, slots=True)
class MultiStep:
    """Piecewise-constant reference: ``levels[i]`` [m] from ``times[i]`` [s] on, 0 before."""

    times: tuple[float, ...]  #: switching instants, increasing [s]
    levels: tuple[float, ...]  #: values from each instant on [m]

    def __post_init__(self) -> None:
        if len(self.times) != len(self.levels) or not self.times:
            raise InputError(
                f"multistep needs as many times as levels (>= 1), got {len(self.times)} "
                f"and {len(self.levels)}")
        for x in self.times:
            _time("multistep time", x)
        for x in self.levels:
            _finite("multistep level", x)
        if any(b <= a for a, b in zip(self.times, self.times[1:], strict=False)):
            raise InputError(f"multistep times must increase, got {self.times!r}")

    def values(self, t: FloatArray) -> FloatArray:
        """r(t) [m]."""
        idx = np.searchsorted(np.asarray(self.times), np.asarray(t), side="right") - 1
        levels = np.concatenate([[0.0], np.asarray(self.levels, dtype=np.float64)])
        return levels[idx + 1]


@dataclass(frozen=True, slots=True)
class Ramp:
    """Ramp of ``slope`` [m/s] from ``time`` [s], held at ``final`` [m] if given."""

    slope: float  #: ramp rate [m/s]
    time: float = 0.0  #: start of the ramp [s]
    final: float | None = None  #: value where the ramp stops [m]; None: never

    def __post_init__(self) -> None:
        _finite("ramp slope", self.slope)
        _time("ramp time", self.time)
        if self.final is not None:
            _finite("ramp final value", self.final)
            if self.final * self.slope < 0.0:
                raise InputError(f"ramp final value {self.final!r} m lies against the slope "
                                 f"{self.slope!r} m/s; give a final value of the slope's sign")

    def values(self, t: FloatArray) -> FloatArray:
        """r(t) [m]."""
        r = self.slope * np.maximum(np.asarray(t, dtype=np.float64) - self.time, 0.0)
        if self.final is not None:
            r = np.minimum(r, self.final) if self.slope >= 0 else np.maximum(r, self.final)
        return r


@dataclass(frozen=True, slots=True)
class Sine:
    """``amplitude`` sin(2π ``frequency`` t) [m]; a negative amplitude flips the phase.

    A run samples it every T_s: :func:`check_reference` refuses a frequency at or above half
    the sample rate (Nyquist), which the samples could not represent.
    """

    amplitude: float  #: amplitude [m]
    frequency: float  #: frequency [Hz], > 0

    def __post_init__(self) -> None:
        _finite("sine amplitude", self.amplitude)
        if not _finite("sine frequency", self.frequency) > 0.0:
            raise InputError(f"sine frequency must be > 0 Hz (a negative amplitude flips the "
                             f"phase), got {self.frequency!r}")

    def values(self, t: FloatArray) -> FloatArray:
        """r(t) [m]."""
        # the C library's sin per element, as the compiled kernels call it: numpy's vector
        # sin (AVX-512 processors) rounds differently (docs/architecture.md)
        w = 2.0 * np.pi * self.frequency * np.asarray(t, dtype=np.float64)
        s = np.array([math.sin(v) for v in w.ravel().tolist()], dtype=np.float64)
        return self.amplitude * s.reshape(w.shape)


@dataclass(frozen=True, slots=True)
class Trapezoid:
    """Trapezoidal motion profile: move ``distance`` [m] from ``time`` [s] with speed at most
    ``v_max`` [m/s] and acceleration ``a_max`` [m/s²] (triangular when too short to cruise)."""

    distance: float  #: travel [m]
    v_max: float  #: cruise speed [m/s], > 0
    a_max: float  #: acceleration and deceleration [m/s²], > 0
    time: float = 0.0  #: start of the move [s]

    def __post_init__(self) -> None:
        _finite("trapezoid distance", self.distance)
        _time("trapezoid start time", self.time)
        for name, v in (("v_max", self.v_max), ("a_max", self.a_max)):
            if not (_finite(f"trapezoid {name}", v) > 0.0):
                raise InputError(f"trapezoid {name} must be > 0, got {v!r}")

    def values(self, t: FloatArray) -> FloatArray:
        """r(t) [m]."""
        d = abs(self.distance)
        sign = 1.0 if self.distance >= 0 else -1.0
        v = min(self.v_max, math.sqrt(d * self.a_max))  # peak speed reached
        ta = v / self.a_max  # acceleration time
        tc = (d - v * ta) / v if v > 0 else 0.0  # cruise time
        tau = np.clip(np.asarray(t, dtype=np.float64) - self.time, 0.0, None)
        acc = 0.5 * self.a_max * tau**2
        cruise = 0.5 * v * ta + v * (tau - ta)
        td = tau - ta - tc
        dec = 0.5 * v * ta + v * tc + v * td - 0.5 * self.a_max * td**2
        r = np.where(tau < ta, acc, np.where(tau < ta + tc, cruise,
                                             np.where(td < ta, dec, d)))
        return sign * r


@dataclass(frozen=True, slots=True, eq=False)
class UserReference:
    """A user's samples ``(times [s], values [m])``, linearly interpolated, held at both ends."""

    times: FloatArray  #: sample times, increasing [s]
    samples: FloatArray  #: reference values [m]

    def __post_init__(self) -> None:
        t = np.asarray(self.times, dtype=np.float64)
        v = np.asarray(self.samples, dtype=np.float64)
        if t.ndim != 1 or t.shape != v.shape or t.size == 0:
            raise InputError(
                f"user reference needs 1-D times and values of equal length, got {t.shape} "
                f"and {v.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            bad = v[~np.isfinite(v)] if not np.all(np.isfinite(v)) else t[~np.isfinite(t)]
            raise InputError(f"user reference must be finite, got {bad[0]!r}")
        if np.any(np.diff(t) <= 0):
            raise InputError("user reference times must increase strictly")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "samples", v)

    def values(self, t: FloatArray) -> FloatArray:
        """r(t) [m]."""
        return np.interp(np.asarray(t, dtype=np.float64), self.times, self.samples)


def _numbers(spec: str, body: str, n_min: int, n_max: int) -> list[float]:
    parts = body.split(":") if body else []
    if not n_min <= len(parts) <= n_max:
        raise InputError(f"reference {spec!r}: expected {n_min}..{n_max} numbers, "
                         f"got {len(parts)}")
    out: list[float] = []
    for p in parts:
        try:
            out.append(float(p))
        except ValueError:
            raise InputError(f"reference {spec!r}: {p!r} is not a number") from None
    return out


def parse_reference(spec: str) -> Reference:
    """Parse the CLI form of a reference.

    ``step:A[:T]``, ``multistep:T1=A1,T2=A2,...``, ``ramp:SLOPE[:T[:FINAL]]``,
    ``sine:A:F``, ``trapezoid:DIST:VMAX:AMAX[:T]`` (m, s, m/s, m/s², Hz).
    """
    kind, _, body = spec.partition(":")
    kind = kind.strip().lower()
    if kind == "step":
        a = _numbers(spec, body, 1, 2)
        return Step(*a)
    if kind == "multistep":
        times: list[float] = []
        levels: list[float] = []
        for item in body.split(","):
            ts, eq, lv = item.partition("=")
            if not eq:
                raise InputError(f"reference {spec!r}: expected TIME=LEVEL, got {item!r}")
            times.append(_numbers(spec, ts, 1, 1)[0])
            levels.append(_numbers(spec, lv, 1, 1)[0])
        return MultiStep(tuple(times), tuple(levels))
    if kind == "ramp":
        a = _numbers(spec, body, 1, 3)
        return Ramp(a[0], a[1] if len(a) > 1 else 0.0, a[2] if len(a) > 2 else None)
    if kind == "sine":
        a = _numbers(spec, body, 2, 2)
        return Sine(a[0], a[1])
    if kind == "trapezoid":
        a = _numbers(spec, body, 3, 4)
        return Trapezoid(*a)
    raise InputError(
        f"unknown reference {spec!r}; allowed: step:A[:T], multistep:T1=A1,..., "
        f"ramp:SLOPE[:T[:FINAL]], sine:A:F, trapezoid:DIST:VMAX:AMAX[:T]")


def _first_change(reference: object) -> tuple[str, float] | None:
    """The instant a reference first departs from 0, with the name of that time; None when it
    has no such instant (a sine, user samples)."""
    if isinstance(reference, Step | Ramp | Trapezoid):
        return {Step: "step time", Ramp: "ramp time",
                Trapezoid: "trapezoid start time"}[type(reference)], reference.time
    if isinstance(reference, MultiStep):
        return "first multistep time", reference.times[0]
    return None


def check_reference(reference: Reference | ArrayLike, *, ts: float, duration: float) -> None:
    """Check a reference against the run that samples it, before the run.

    A sine must lie below half the sample rate, f < 1/(2 T_s): at or above it the samples
    alias (at f = 1/T_s every sample lands on the same phase, a flat reference). A step,
    ramp, multistep or trapezoid must start before the end of the run. Sampled references
    (arrays) have nothing to check here.

    Parameters
    ----------
    reference : Reference or array
        The reference (offset from the start position) [m].
    ts : float
        Sample time of the run [s].
    duration : float
        Simulated time [s].

    Raises
    ------
    InputError
        A sine at or above half the sample rate, or a reference that starts at or after the
        end of the run.
    """
    if isinstance(reference, Sine):
        nyquist = 0.5 / ts
        if reference.frequency >= nyquist:
            raise InputError(
                f"sine frequency {reference.frequency!r} Hz is at or above half the sample "
                f"rate, 1/(2 ts) = {nyquist:g} Hz at ts = {ts!r} s: the samples would alias; "
                f"give a frequency below {nyquist:g} Hz or a shorter sample time")
    first = _first_change(reference)
    if first is not None and first[1] >= duration:
        raise InputError(f"reference {first[0]} {first[1]!r} s is at or after the end of the "
                         f"run ({duration!r} s): nothing would happen; give a time below "
                         f"{duration!r} s or a longer --duration")


def check_reference_samples(r: FloatArray, t: FloatArray, *, start: float,
                            stroke: float | None = None, resolution: float = 0.0) -> None:
    """Check a sampled absolute reference against the plant, before the run.

    Parameters
    ----------
    r : array (n,)
        Absolute reference, start position plus offset [m].
    t : array (n,)
        Sample times [s].
    start : float
        Start position of the run [m].
    stroke : float, optional
        Stroke of the cylinder [m]: the reference must stay within [0, stroke]. None: not
        checked (a plant that does not know its stroke).
    resolution : float
        Transducer resolution [m] (0: exact): it must not be coarser than the reference's
        largest move from the start, which the measurement could not resolve.

    Raises
    ------
    InputError
        A reference outside the stroke, or a resolution coarser than the move.
    """
    if r.size == 0:
        return
    if stroke is not None:
        bad = np.nonzero((r < 0.0) | (r > stroke))[0]
        if bad.size:
            k = int(bad[0])
            raise InputError(
                f"the reference reaches {float(r[k]):.10g} m at t = {float(t[k]):.6g} s "
                f"(start {start:.10g} m + offset {float(r[k]) - start:.10g} m), outside the "
                f"stroke "
                f"[0, {stroke:g}] m; keep start + reference within the stroke")
    move = float(np.max(np.abs(r - start)))
    if resolution > 0.0 and move > 0.0 and resolution > move * (1.0 + 1e-9):  # rounding
        raise InputError(
            f"transducer.resolution {resolution!r} m is coarser than the reference's largest "
            f"move {move:.6g} m: the measurement could not resolve it; give a resolution of "
            f"at most {move:.6g} m")


def sample_reference(reference: Reference | ArrayLike, t: FloatArray) -> FloatArray:
    """``reference`` sampled at ``t`` [s]; an array is taken as already sampled (same length)."""
    if hasattr(reference, "values"):
        r = np.asarray(reference.values(t), dtype=np.float64)
    else:
        r = np.asarray(reference, dtype=np.float64)
        if r.shape != t.shape:
            raise InputError(
                f"a sampled reference needs one value per sample ({t.size}), got {r.shape}")
    if not np.all(np.isfinite(r)):
        raise InputError(f"reference must be finite, got {r[~np.isfinite(r)][0]!r}")
    return np.ascontiguousarray(r)


