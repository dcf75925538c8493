"""Reference signals for the closed loop, as offsets [m] from the start position.

Each reference is a frozen dataclass with ``values(t) -> r`` (t [s] -> r [m], numpy arrays)
and ``rates(t) -> (ṙ, r̈)`` [m/s, m/s²], its velocity and acceleration, computed in closed form
at the sample instants (the feed-forward signals of controllers such as ``ffpd``; a jump of a
step or of a trapezoid's acceleration is not sampled as an impulse: at a discontinuity the
value from the right is taken). The simulator adds the plant's initial output y(0), so
``Step(0.1)`` moves the piston 0.1 m from wherever it starts (0 on the linear plant, the start
position on the nonlinear plant). :func:`parse_reference` reads the CLI form (``step:0.1``,
``ramp:0.05``, ``scurve:0.2:0.25:2:40``, ``chirp:0.005:0.5:20:10``...).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..errors import InputError

__all__ = [
    "Chirp",
    "MultiStep",
    "Ramp",
    "Reference",
    "SCurve",
    "Sine",
    "Step",
    "Trapezoid",
    "UserReference",
    "check_reference",
    "check_reference_samples",
    "parse_reference",
    "reference_rates",
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

    def rates(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Return ṙ [m/s] and r̈ [m/s²] at the times ``t`` [s]."""
        ...


def _zeros(t: FloatArray) -> tuple[FloatArray, FloatArray]:
    z = np.zeros(np.shape(t))
    return z, z.copy()


def _libm(fn: object, w: FloatArray) -> FloatArray:
    """The C library's sin or cos per element, as the compiled kernels call it: numpy's
    vector functions (AVX-512 processors) round differently (docs/architecture.md)."""
    out = np.array([fn(v) for v in np.asarray(w).ravel().tolist()],  # type: ignore[operator]
                   dtype=np.float64)
    return out.reshape(np.shape(w))


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

    def rates(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """ṙ = r̈ = 0 (the jump is not sampled as an impulse)."""
        return _zeros(t)


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

    def rates(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """ṙ = r̈ = 0 (the jumps are not sampled as impulses)."""
        return _zeros(t)


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

    def rates(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """ṙ = slope from the start until the final value is reached, else 0; r̈ = 0."""
        tt = np.asarray(t, dtype=np.float64)
        moving = tt >= self.time
        if self.final is not None:
            moving &= np.abs(self.slope * (tt - self.time)) < abs(self.final)
        return np.where(moving, self.slope, 0.0), np.zeros(tt.shape)


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
        w = 2.0 * np.pi * self.frequency * np.asarray(t, dtype=np.float64)
        return self.amplitude * _libm(math.sin, w)

    def rates(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """ṙ = A ω cos(ωt), r̈ = -A ω² sin(ωt), ω = 2π f."""
        om = 2.0 * np.pi * self.frequency
        w = om * np.asarray(t, dtype=np.float64)
        return self.amplitude * om * _libm(math.cos, w), -self.amplitude * om**2 * _libm(
            math.sin, w)


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

    def rates(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """ṙ and r̈ of the profile (the acceleration's jumps taken from the right)."""
        d = abs(self.distance)
        sign = 1.0 if self.distance >= 0 else -1.0
        v = min(self.v_max, math.sqrt(d * self.a_max))
        ta = v / self.a_max
        tc = (d - v * ta) / v if v > 0 else 0.0
        raw = np.asarray(t, dtype=np.float64) - self.time
        tau = np.clip(raw, 0.0, None)
        td = tau - ta - tc
        vel = np.where(tau < ta, self.a_max * tau, np.where(
            tau < ta + tc, v, np.where(td < ta, v - self.a_max * td, 0.0)))
        acc = np.where(raw < 0.0, 0.0, np.where(tau < ta, self.a_max, np.where(
            tau < ta + tc, 0.0, np.where(td < ta, -self.a_max, 0.0))))
        return sign * np.where(raw < 0.0, 0.0, vel), sign * acc


@dataclass(frozen=True, slots=True)
class SCurve:
    """Jerk-limited (S-curve) point-to-point move of ``distance`` [m] from ``time`` [s]: speed
    at most ``v_max`` [m/s], acceleration at most ``a_max`` [m/s²], jerk ``j_max`` [m/s³].

    The time-optimal seven-phase profile under these limits (jerk +j, 0, -j, cruise, -j, 0,
    +j; Biagiotti & Melchiorri, *Trajectory Planning for Automatic Machines and Robots*,
    Springer 2008, sec. 3.4, with zero speed and acceleration at both ends): the acceleration
    phase reaches a_lim = min(a_max, sqrt(v_lim j)), the peak speed v_lim is v_max or, for a
    short move, the largest speed the distance allows. Position, velocity and acceleration
    are exact polynomials of time, evaluated at the sample instants.
    """

    distance: float  #: travel [m]
    v_max: float  #: speed limit [m/s], > 0
    a_max: float  #: acceleration limit [m/s²], > 0
    j_max: float  #: jerk limit [m/s³], > 0
    time: float = 0.0  #: start of the move [s]

    def __post_init__(self) -> None:
        _finite("scurve distance", self.distance)
        _time("scurve start time", self.time)
        for name, v in (("v_max", self.v_max), ("a_max", self.a_max), ("j_max", self.j_max)):
            if not (_finite(f"scurve {name}", v) > 0.0):
                raise InputError(f"scurve {name} must be > 0, got {v!r}")

    def phases(self) -> tuple[float, float, float, float]:
        """(T_j, T_a, T_v, v_lim): jerk time, acceleration phase (T_a >= 2 T_j... T_a = 2 T_j
        + constant-acceleration time), cruise time [s] and peak speed [m/s]."""
        d = abs(self.distance)
        j, a, vm = self.j_max, self.a_max, self.v_max
        if d == 0.0:
            return 0.0, 0.0, 0.0, 0.0

        def accel_phase(v: float) -> tuple[float, float]:
            # time to reach speed v from rest: jerk time tj and whole phase ta
            if v * j >= a * a:
                tj = a / j
                return tj, tj + v / a
            tj = math.sqrt(v / j)
            return tj, 2.0 * tj

        tj, ta = accel_phase(vm)
        if d >= ta * vm:  # cruise at v_max: the acceleration phase covers v ta / 2 each way
            return tj, ta, d / vm - ta, vm
        # no cruise: the largest v with v ta(v) = d (monotone in v), by bisection to the last
        # bit of a double
        lo, hi = 0.0, vm
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                break
            if mid * accel_phase(mid)[1] <= d:
                lo = mid
            else:
                hi = mid
        tj, ta = accel_phase(lo)
        return tj, ta, max(d / lo - ta, 0.0) if lo > 0 else 0.0, lo

    @property
    def duration(self) -> float:
        """Length of the move [s]."""
        tj, ta, tv, _ = self.phases()
        return 2.0 * ta + tv

    def _profile(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        tj, ta, tv, vl = self.phases()
        j = self.j_max
        al = j * tj  # acceleration reached
        d = abs(self.distance)
        raw = np.asarray(t, dtype=np.float64) - self.time
        tau = np.clip(raw, 0.0, None)
        n = tau.shape
        pos, vel, acc = np.zeros(n), np.zeros(n), np.zeros(n)

        def accel(x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
            """Acceleration phase from rest, x in [0, ta]."""
            p1 = j * x**3 / 6.0
            v1 = 0.5 * j * x**2
            a1 = j * x
            xm = x - tj
            p2 = j * tj**3 / 6.0 + 0.5 * j * tj**2 * xm + 0.5 * al * xm**2
            v2 = 0.5 * j * tj**2 + al * xm
            xe = ta - x  # time left in the phase
            p3 = vl * ta / 2.0 - (vl * xe - j * xe**3 / 6.0)
            v3 = vl - 0.5 * j * xe**2
            a3 = j * xe
            first = x < tj
            last = x >= ta - tj
            return (np.where(first, p1, np.where(last, p3, p2)),
                    np.where(first, v1, np.where(last, v3, v2)),
                    np.where(first, a1, np.where(last, a3, al)))

        if vl == 0.0:
            return pos, vel, acc
        t_dec = ta + tv  # start of the deceleration
        p_a, v_a, a_a = accel(np.minimum(tau, ta))
        back = np.clip(2.0 * ta + tv - tau, 0.0, ta)  # time to the end, inside the phase
        p_d, v_d, a_d = accel(back)
        in_acc = tau < ta
        in_cruise = (tau >= ta) & (tau < t_dec)
        pos = np.where(in_acc, p_a, np.where(in_cruise, vl * ta / 2.0 + vl * (tau - ta),
                                             d - p_d))
        vel = np.where(in_acc, v_a, np.where(in_cruise, vl, v_d))
        acc = np.where(in_acc, a_a, np.where(in_cruise, 0.0, -a_d))
        done = tau >= 2.0 * ta + tv
        pos = np.where(done, d, pos)
        vel = np.where(done | (raw < 0.0), 0.0, vel)
        acc = np.where(done | (raw < 0.0), 0.0, acc)
        return pos, vel, acc

    def values(self, t: FloatArray) -> FloatArray:
        """r(t) [m]."""
        sign = 1.0 if self.distance >= 0 else -1.0
        return sign * self._profile(t)[0]

    def rates(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """ṙ [m/s] and r̈ [m/s²]."""
        sign = 1.0 if self.distance >= 0 else -1.0
        _, v, a = self._profile(t)
        return sign * v, sign * a


@dataclass(frozen=True, slots=True)
class Chirp:
    """Linear sine sweep ``amplitude`` sin(φ(t)) [m] from ``f0`` to ``f1`` [Hz] over
    ``duration`` [s], φ(t) = 2π (f0 t + (f1 - f0) t² / (2 T)); after T it goes on at f1.

    A run samples it every T_s: :func:`check_reference` refuses an end frequency at or above
    half the sample rate.
    """

    amplitude: float  #: amplitude [m]
    f0: float  #: start frequency [Hz], > 0
    f1: float  #: end frequency [Hz], > 0
    duration: float  #: sweep time T [s], > 0

    def __post_init__(self) -> None:
        _finite("chirp amplitude", self.amplitude)
        for name, v in (("start frequency", self.f0), ("end frequency", self.f1),
                        ("duration", self.duration)):
            if not (_finite(f"chirp {name}", v) > 0.0):
                raise InputError(f"chirp {name} must be > 0, got {v!r}")

    def _phase(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """φ [rad], φ' [rad/s] and φ'' [rad/s²] at t."""
        tt = np.asarray(t, dtype=np.float64)
        k = (self.f1 - self.f0) / self.duration  # sweep rate [Hz/s]
        tc = np.minimum(tt, self.duration)
        sweeping = tt < self.duration
        phi = 2.0 * np.pi * (self.f0 * tc + 0.5 * k * tc**2 + self.f1 * (tt - tc))
        dphi = 2.0 * np.pi * np.where(sweeping, self.f0 + k * tt, self.f1)
        ddphi = np.where(sweeping, 2.0 * np.pi * k, 0.0)
        return phi, dphi, ddphi

    def values(self, t: FloatArray) -> FloatArray:
        """r(t) [m]."""
        return self.amplitude * _libm(math.sin, self._phase(t)[0])

    def rates(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """ṙ = A φ' cos φ, r̈ = A (φ'' cos φ - φ'² sin φ)."""
        phi, d1, d2 = self._phase(t)
        c, s = _libm(math.cos, phi), _libm(math.sin, phi)
        return self.amplitude * d1 * c, self.amplitude * (d2 * c - d1**2 * s)


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

    def rates(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """ṙ: the slope of the interpolating segment (from the right at a sample, 0 outside
        the samples); r̈ = 0 (the kinks are not sampled as impulses)."""
        tt = np.asarray(t, dtype=np.float64)
        slopes = np.diff(self.samples) / np.diff(self.times)
        seg = np.searchsorted(self.times, tt, side="right") - 1
        inside = (seg >= 0) & (seg < slopes.size)
        v = np.where(inside, slopes[np.clip(seg, 0, max(slopes.size - 1, 0))]
                     if slopes.size else 0.0, 0.0)
        return np.asarray(v, dtype=np.float64), np.zeros(tt.shape)


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
    ``sine:A:F``, ``trapezoid:DIST:VMAX:AMAX[:T]``, ``scurve:DIST:VMAX:AMAX:JMAX[:T]``,
    ``chirp:A:F0:F1:DURATION`` (m, s, m/s, m/s², m/s³, Hz).
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
    if kind == "scurve":
        a = _numbers(spec, body, 4, 5)
        return SCurve(*a)
    if kind == "chirp":
        a = _numbers(spec, body, 4, 4)
        return Chirp(*a)
    raise InputError(
        f"unknown reference {spec!r}; allowed: step:A[:T], multistep:T1=A1,..., "
        f"ramp:SLOPE[:T[:FINAL]], sine:A:F, trapezoid:DIST:VMAX:AMAX[:T], "
        f"scurve:DIST:VMAX:AMAX:JMAX[:T], chirp:A:F0:F1:DURATION")


def _first_change(reference: object) -> tuple[str, float] | None:
    """The instant a reference first departs from 0, with the name of that time; None when it
    has no such instant (a sine, user samples)."""
    if isinstance(reference, Step | Ramp | Trapezoid | SCurve):
        return {Step: "step time", Ramp: "ramp time", Trapezoid: "trapezoid start time",
                SCurve: "scurve start time"}[type(reference)], reference.time
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
    if isinstance(reference, Sine | Chirp):
        nyquist = 0.5 / ts
        f = reference.frequency if isinstance(reference, Sine) else max(reference.f0,
                                                                         reference.f1)
        what = "sine frequency" if isinstance(reference, Sine) else "chirp frequency"
        if f >= nyquist:
            raise InputError(
                f"{what} {f!r} Hz is at or above half the sample "
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




def reference_rates(reference: Reference | ArrayLike, t: FloatArray
                    ) -> tuple[FloatArray, FloatArray]:
    """The reference's velocity ṙ [m/s] and acceleration r̈ [m/s²] at ``t`` [s]: in closed
    form for a reference object (its ``rates``); for samples (an array, one per sample or a
    row per run) by second-order differences along time (:func:`numpy.gradient`, over the
    sample time of a uniform grid), the one estimate samples allow: a jump in the samples
    is a spike of ṙ (give a reference object, or ``simulate_batch(rates=...)``, for exact
    rates); zeros for fewer than 3 samples."""
    if hasattr(reference, "values"):
        rates = getattr(reference, "rates", None)
        if rates is None:  # a user's reference object with values() only
            r = np.asarray(reference.values(t), dtype=np.float64)
            return reference_rates(r, t)
        v, a = rates(t)
        return (np.ascontiguousarray(v, dtype=np.float64),
                np.ascontiguousarray(a, dtype=np.float64))
    r = np.asarray(reference, dtype=np.float64)
    tt = np.asarray(t, dtype=np.float64)
    if tt.size < 3 or r.shape[-1] != tt.size:
        return np.zeros(r.shape), np.zeros(r.shape)
    # the run's grid is uniform (k ts): differences over the step ts itself, not over the
    # rounded sample times, so constant samples have exactly zero rates
    h = float(tt[1] - tt[0]) if np.allclose(np.diff(tt), tt[1] - tt[0], rtol=1e-9, atol=0) \
        else None
    v = np.gradient(r, h if h is not None else tt, axis=-1, edge_order=2)
    a = np.gradient(v, h if h is not None else tt, axis=-1, edge_order=2)
    return np.ascontiguousarray(v), np.ascontiguousarray(a)
