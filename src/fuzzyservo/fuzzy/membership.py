"""Membership functions: pure broadcasting numpy functions and small frozen MF objects.

Behaviour at non-finite input is defined and tested: NaN gives NaN; -inf and +inf give the
limit of the function (0 for a triangle, trapezoid, Gaussian or bell; 1 on the open side of a
shoulder). Parameters are validated: an inverted or degenerate shape raises ``ParameterError``.

Piecewise-linear MFs (triangle, trapezoid, shoulders) expose ``vertices``: a tuple of (x, y)
points, constant beyond the first and last; a repeated x is a vertical edge (a jump). The exact
centroid integrates aggregates of these exactly; the smooth MFs (Gaussian, bell) have
``vertices = None`` and are integrated by adaptive quadrature.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..errors import ParameterError

__all__ = [
    "Bell",
    "Gaussian",
    "LeftShoulder",
    "MembershipFunction",
    "RightShoulder",
    "Trapezoid",
    "Triangle",
    "gauss",
    "gbell",
    "shoulder_left",
    "shoulder_right",
    "trap",
    "tri",
]


def _finite(**params: float) -> None:
    for name, value in params.items():
        if not math.isfinite(value):
            raise ParameterError(f"membership parameter {name} must be finite, got {value!r}")


def _check_ordered(kind: str, names: str, *values: float) -> None:
    _finite(**dict(zip(names.split(","), values, strict=True)))
    if any(b < a for a, b in zip(values, values[1:], strict=False)) or values[0] >= values[-1]:
        shown = ", ".join(f"{n}={v!r}" for n, v in zip(names.split(","), values, strict=True))
        raise ParameterError(
            f"{kind} needs {' <= '.join(names.split(','))} with "
            f"{names.split(',')[0]} < {names.split(',')[-1]}, got {shown}"
        )


def _rise(x: FloatArray, a: float, b: float) -> FloatArray:
    """0 below a, 1 above b, linear between (a step at a when a == b); NaN stays NaN."""
    if b > a:
        with np.errstate(invalid="ignore", over="ignore"):
            return np.clip((x - a) / (b - a), 0.0, 1.0)
    return np.where(np.isnan(x), np.nan, np.where(x >= a, 1.0, 0.0))


def _fall(x: FloatArray, a: float, b: float) -> FloatArray:
    """1 below a, 0 above b, linear between (a step at b when a == b); NaN stays NaN."""
    if b > a:
        with np.errstate(invalid="ignore", over="ignore"):
            return np.clip((b - x) / (b - a), 0.0, 1.0)
    return np.where(np.isnan(x), np.nan, np.where(x <= b, 1.0, 0.0))


def tri(x: ArrayLike, a: float, b: float, c: float) -> FloatArray:
    """Triangle with feet a, c and peak b (a <= b <= c, a < c).

    Parameters
    ----------
    x : array_like
        Points of the universe [same unit as a, b, c].
    a, b, c : float
        Left foot, peak, right foot; a == b or b == c gives a vertical edge.

    Returns
    -------
    ndarray of float64
        Membership in [0, 1], NaN where x is NaN, 0 at ±inf.
    """
    _check_ordered("triangle", "a,b,c", a, b, c)
    xx = np.asarray(x, dtype=np.float64)
    return np.minimum(_rise(xx, a, b), _fall(xx, b, c))


def trap(x: ArrayLike, a: float, b: float, c: float, d: float) -> FloatArray:
    """Trapezoid with feet a, d and plateau [b, c] (a <= b <= c <= d, a < d).

    Parameters
    ----------
    x : array_like
        Points of the universe [same unit as a..d].
    a, b, c, d : float
        Left foot, plateau start, plateau end, right foot.

    Returns
    -------
    ndarray of float64
        Membership in [0, 1], NaN where x is NaN, 0 at ±inf.
    """
    _check_ordered("trapezoid", "a,b,c,d", a, b, c, d)
    xx = np.asarray(x, dtype=np.float64)
    return np.minimum(_rise(xx, a, b), _fall(xx, c, d))


def shoulder_left(x: ArrayLike, a: float, b: float) -> FloatArray:
    """Left shoulder: 1 for x <= a, falling linearly to 0 at b (a < b).

    Parameters
    ----------
    x : array_like
        Points of the universe [same unit as a, b].
    a, b : float
        End of the plateau and right foot.

    Returns
    -------
    ndarray of float64
        Membership in [0, 1]; NaN at NaN, 1 at -inf, 0 at +inf.
    """
    _check_ordered("left shoulder", "a,b", a, b)
    return _fall(np.asarray(x, dtype=np.float64), a, b)


def shoulder_right(x: ArrayLike, a: float, b: float) -> FloatArray:
    """Right shoulder: 0 for x <= a, rising linearly to 1 at b and 1 beyond (a < b).

    Parameters
    ----------
    x : array_like
        Points of the universe [same unit as a, b].
    a, b : float
        Left foot and start of the plateau.

    Returns
    -------
    ndarray of float64
        Membership in [0, 1]; NaN at NaN, 0 at -inf, 1 at +inf.
    """
    _check_ordered("right shoulder", "a,b", a, b)
    return _rise(np.asarray(x, dtype=np.float64), a, b)


def gauss(x: ArrayLike, mean: float, sigma: float) -> FloatArray:
    """Gaussian exp(-(x - mean)^2 / (2 sigma^2)) (sigma > 0).

    Parameters
    ----------
    x : array_like
        Points of the universe [same unit as mean].
    mean : float
        Centre [same unit as x].
    sigma : float
        Standard deviation, > 0 [same unit as x].

    Returns
    -------
    ndarray of float64
        Membership in (0, 1]; NaN at NaN, 0 at ±inf.
    """
    _finite(mean=mean, sigma=sigma)
    if sigma <= 0.0:
        raise ParameterError(f"Gaussian sigma must be > 0, got {sigma!r}")
    with np.errstate(over="ignore"):
        z = (np.asarray(x, dtype=np.float64) - mean) / sigma
        return np.exp(-0.5 * z * z)


def gbell(x: ArrayLike, a: float, b: float, c: float) -> FloatArray:
    """Generalised bell 1 / (1 + |(x - c) / a|^(2 b)) (a > 0, b > 0).

    Parameters
    ----------
    x : array_like
        Points of the universe [same unit as c].
    a : float
        Half-width at membership 1/2, > 0 [same unit as x].
    b : float
        Slope exponent, > 0 [1].
    c : float
        Centre [same unit as x].

    Returns
    -------
    ndarray of float64
        Membership in (0, 1]; NaN at NaN, 0 at ±inf.
    """
    _finite(a=a, b=b, c=c)
    if a <= 0.0 or b <= 0.0:
        raise ParameterError(f"bell needs a > 0 and b > 0, got a={a!r}, b={b!r}")
    with np.errstate(over="ignore"):
        z = np.abs((np.asarray(x, dtype=np.float64) - c) / a)
        return 1.0 / (1.0 + z ** (2.0 * b))


@runtime_checkable
class MembershipFunction(Protocol):
    """A membership function object: callable on arrays, with its piecewise-linear vertices."""

    def __call__(self, x: ArrayLike) -> FloatArray: ...

    @property
    def vertices(self) -> tuple[tuple[float, float], ...] | None: ...

    @property
    def centre(self) -> float: ...


@dataclass(frozen=True, slots=True, kw_only=True)
class Triangle:
    """Triangle MF, see :func:`tri`."""

    a: float  #: left foot [unit of the universe]
    b: float  #: peak [unit of the universe]
    c: float  #: right foot [unit of the universe]

    def __post_init__(self) -> None:
        _check_ordered("triangle", "a,b,c", self.a, self.b, self.c)

    def __call__(self, x: ArrayLike) -> FloatArray:
        """Membership of ``x``."""
        return tri(x, self.a, self.b, self.c)

    @property
    def vertices(self) -> tuple[tuple[float, float], ...]:
        """(x, y) vertices; constant 0 beyond the feet."""
        return ((self.a, 0.0), (self.b, 1.0), (self.c, 0.0))

    @property
    def centre(self) -> float:
        """Peak position [unit of the universe]."""
        return self.b


@dataclass(frozen=True, slots=True, kw_only=True)
class Trapezoid:
    """Trapezoid MF, see :func:`trap`."""

    a: float  #: left foot [unit of the universe]
    b: float  #: plateau start [unit of the universe]
    c: float  #: plateau end [unit of the universe]
    d: float  #: right foot [unit of the universe]

    def __post_init__(self) -> None:
        _check_ordered("trapezoid", "a,b,c,d", self.a, self.b, self.c, self.d)

    def __call__(self, x: ArrayLike) -> FloatArray:
        """Membership of ``x``."""
        return trap(x, self.a, self.b, self.c, self.d)

    @property
    def vertices(self) -> tuple[tuple[float, float], ...]:
        """(x, y) vertices; constant 0 beyond the feet."""
        return ((self.a, 0.0), (self.b, 1.0), (self.c, 1.0), (self.d, 0.0))

    @property
    def centre(self) -> float:
        """Middle of the plateau [unit of the universe]."""
        return 0.5 * (self.b + self.c)


@dataclass(frozen=True, slots=True, kw_only=True)
class LeftShoulder:
    """Left-shoulder MF, see :func:`shoulder_left`."""

    a: float  #: end of the plateau (1 for x <= a) [unit of the universe]
    b: float  #: right foot [unit of the universe]

    def __post_init__(self) -> None:
        _check_ordered("left shoulder", "a,b", self.a, self.b)

    def __call__(self, x: ArrayLike) -> FloatArray:
        """Membership of ``x``."""
        return shoulder_left(x, self.a, self.b)

    @property
    def vertices(self) -> tuple[tuple[float, float], ...]:
        """(x, y) vertices; constant 1 left of a, 0 right of b."""
        return ((self.a, 1.0), (self.b, 0.0))

    @property
    def centre(self) -> float:
        """End of the plateau [unit of the universe]."""
        return self.a


@dataclass(frozen=True, slots=True, kw_only=True)
class RightShoulder:
    """Right-shoulder MF, see :func:`shoulder_right`."""

    a: float  #: left foot [unit of the universe]
    b: float  #: start of the plateau (1 for x >= b) [unit of the universe]

    def __post_init__(self) -> None:
        _check_ordered("right shoulder", "a,b", self.a, self.b)

    def __call__(self, x: ArrayLike) -> FloatArray:
        """Membership of ``x``."""
        return shoulder_right(x, self.a, self.b)

    @property
    def vertices(self) -> tuple[tuple[float, float], ...]:
        """(x, y) vertices; constant 0 left of a, 1 right of b."""
        return ((self.a, 0.0), (self.b, 1.0))

    @property
    def centre(self) -> float:
        """Start of the plateau [unit of the universe]."""
        return self.b


@dataclass(frozen=True, slots=True, kw_only=True)
class Gaussian:
    """Gaussian MF, see :func:`gauss`."""

    mean: float  #: centre [unit of the universe]
    sigma: float  #: standard deviation, > 0 [unit of the universe]

    def __post_init__(self) -> None:
        gauss(0.0, self.mean, self.sigma)

    def __call__(self, x: ArrayLike) -> FloatArray:
        """Membership of ``x``."""
        return gauss(x, self.mean, self.sigma)

    @property
    def vertices(self) -> None:
        """None: not piecewise linear."""
        return None

    @property
    def centre(self) -> float:
        """Centre [unit of the universe]."""
        return self.mean


@dataclass(frozen=True, slots=True, kw_only=True)
class Bell:
    """Generalised bell MF, see :func:`gbell`."""

    a: float  #: half-width at membership 1/2, > 0 [unit of the universe]
    b: float  #: slope exponent, > 0 [1]
    c: float  #: centre [unit of the universe]

    def __post_init__(self) -> None:
        gbell(0.0, self.a, self.b, self.c)

    def __call__(self, x: ArrayLike) -> FloatArray:
        """Membership of ``x``."""
        return gbell(x, self.a, self.b, self.c)

    @property
    def vertices(self) -> None:
        """None: not piecewise linear."""
        return None

    @property
    def centre(self) -> float:
        """Centre [unit of the universe]."""
        return self.c
