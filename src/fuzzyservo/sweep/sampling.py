"""The points of a sweep: grid cells and random draws, a pure function of the spec, the seed and
the point's index.

Every random number is computed from (seed, variation, grid cell, draw number in the cell) by a
counter-based generator (SplitMix64's finaliser; Steele, Lea & Flood 2014), not drawn from a
stream: a point gets the same values whether it is computed alone, in any chunk, after a resume
or on any Dask worker, and draw s of cell c is the same in a sweep with fewer or more
``samples`` (a reduced sweep runs the first plants of the full one, cell by cell). A uniform u
in (0, 1) becomes a value by the distribution's inverse CDF, so truncation to bounds is exact
(no rejection loop, no clipping):

- ``uniform``: low + (high - low) u
- ``log-uniform``: exp(ln low + (ln high - ln low) u)
- ``normal``: mean + std Φ⁻¹(Φ(a) + u (Φ(b) - Φ(a))), a, b the bounds in standard units
- ``log-normal``: median exp(sigma z), z the truncated standard normal of
  ln(bounds/median)/sigma

A relative variation multiplies the nominal value by the draw. The sensor noise of a point is
``numpy.random.default_rng(noise_seed).normal(0, noise_std, n)``, the very sequence
``fuzzyservo simulate --noise-std STD --seed noise_seed`` draws, so every run can be replayed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import log_ndtr, ndtr, ndtri, ndtri_exp

from .._typing import FloatArray, IntArray
from .spec import _LOG_TAIL, SweepSpec, Variation, _standard_bounds, in_log_tail

__all__ = ["Points", "counter_uniform", "in_log_tail", "points", "transform"]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
#: Stream number of the noise seeds (variations use 1, 2, ... in spec order).
_NOISE_STREAM = 0
#: A draw's counter is cell * _CELL_STRIDE + sample: draw s of cell c is the same whatever
#: ``samples`` is, so a sweep with fewer samples runs a subset of the plants of one with more.
_CELL_STRIDE = 2**32


def _mix(x: np.ndarray) -> np.ndarray:
    """SplitMix64's output function on uint64 (wrapping arithmetic)."""
    z = x + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


def _key(seed: int, stream: int) -> np.ndarray:
    return _mix(_mix(np.array([seed], dtype=np.uint64)) ^ np.array([stream], dtype=np.uint64))


def _bits(seed: int, stream: int, index: IntArray) -> np.ndarray:
    return _mix(_key(seed, stream) ^ _mix(index.astype(np.uint64)))


def counter_uniform(seed: int, stream: int, index: IntArray) -> FloatArray:
    """Uniform numbers in the open interval (0, 1), one per ``index``: 53 random bits plus half
    an ulp, so neither 0 nor 1 occurs (an inverse CDF stays finite)."""
    b = _bits(seed, stream, np.asarray(index, dtype=np.int64))
    return ((b >> np.uint64(11)).astype(np.float64) + 0.5) * 2.0 ** -53


def noise_seeds(seed: int, index: IntArray) -> IntArray:
    """The noise seed of each point (non-negative, below 2**63)."""
    b = _bits(seed, _NOISE_STREAM, np.asarray(index, dtype=np.int64))
    return (b >> np.uint64(1)).astype(np.int64)


def _exp(x: FloatArray) -> FloatArray:
    """e**x per element through the C library's ``exp``, as the compiled kernels call it:
    numpy's own vector exp (AVX-512 processors) rounds differently, and the draws of a sweep
    must not depend on the processor (docs/architecture.md, "Machine-independent results")."""
    return np.array([math.exp(v) for v in np.asarray(x, dtype=np.float64).ravel().tolist()],
                    dtype=np.float64).reshape(np.shape(x))




def _tail_in_logs(q: FloatArray, a: float, b: float) -> FloatArray:
    """The standard normal truncated to [a, b], b <= 0 far in the lower tail, at the
    quantiles 1 - ``q``, in logarithms: p = Φ(b) (1 - q (1 - Φ(a)/Φ(b))), log p from log Φ
    and ``log1p``, z = Φ⁻¹(exp(log p)) by ``ndtri_exp``. Every step keeps its relative
    precision however small Φ(b) is."""
    la, lb = float(log_ndtr(a)), float(log_ndtr(b))
    width = -math.expm1(la - lb)  # 1 - Φ(a)/Φ(b), in (0, 1]
    with np.errstate(divide="ignore"):  # q (1 - Φ(a)/Φ(b)) = 1: z = -inf, clipped to a
        return np.asarray(ndtri_exp(lb + np.log1p(-q * width)), dtype=np.float64)


def _truncated_std_normal(u: FloatArray, a: float, b: float) -> FloatArray:
    """The standard normal truncated to [a, b] at the quantiles ``u``. In the upper tail
    (a > 0) Φ rounds to 1 and the interval would vanish: there the lower tail's
    Φ(-x) = 1 - Φ(x) is used, which keeps its digits; an interval so far out that even the
    tail's Φ underflows (beyond about 37 standard deviations) is drawn in logarithms
    (:func:`_tail_in_logs`; the draws of every other interval are as before, bit for
    bit)."""
    if a > 0.0:
        lo, hi = float(ndtr(-b)), float(ndtr(-a))
        if hi < _LOG_TAIL:
            z = -_tail_in_logs(u, -b, -a)  # the mirror image, at 1 - u
        else:
            z = -ndtri(hi - u * (hi - lo))
    else:
        lo, hi = float(ndtr(a)), float(ndtr(b))
        if hi < _LOG_TAIL:
            z = _tail_in_logs(1.0 - u, a, b)
        else:
            z = ndtri(lo + u * (hi - lo))
    return np.clip(z, a, b)  # rounding of Φ⁻¹ near the bounds: stay inside them


def transform(var: Variation, u: FloatArray) -> FloatArray:
    """Values of a random variation (factors when relative) from uniforms ``u``."""
    lo, hi = var.arg("low", -math.inf), var.arg("high", math.inf)
    if var.distribution == "uniform":
        return lo + (hi - lo) * u
    if var.distribution == "log-uniform":
        a, b = math.log(lo), math.log(hi)
        return _exp(a + (b - a) * u)
    if var.distribution == "normal":
        mean, std = var.arg("mean"), var.arg("std")
        return mean + std * _truncated_std_normal(u, *_standard_bounds(var))
    if var.distribution == "log-normal":
        med, sig = var.arg("median"), var.arg("sigma")
        return med * _exp(sig * _truncated_std_normal(u, *_standard_bounds(var)))
    raise AssertionError(var.distribution)


@dataclass(frozen=True, slots=True)
class Points:
    """Points [lo, hi) of a sweep."""

    index: IntArray  #: point index
    cell: IntArray  #: grid cell
    sample: IntArray  #: draw within the cell
    values: dict[str, FloatArray]  #: every varied quantity, absolute SI value per point
    noise_seed: IntArray  #: seed of each point's sensor noise

    def __len__(self) -> int:
        return int(self.index.size)


def points(spec: SweepSpec, lo: int, hi: int) -> Points:
    """The points [lo, hi) of ``spec``."""
    index = np.arange(lo, hi, dtype=np.int64)
    cell = index // spec.samples
    sample = index % spec.samples
    values: dict[str, FloatArray] = {}
    grid = spec.grid
    sizes = [len(v.values) for v in grid]
    stride = math.prod(sizes)
    for var, size in zip(grid, sizes, strict=True):
        stride //= size
        k = (cell // stride) % size
        values[var.name] = np.asarray(var.values, dtype=np.float64)[k]
    key = cell * _CELL_STRIDE + sample  # the draw's counter: its cell and its number there
    for stream, var in enumerate(spec.vary, start=1):
        if var.is_grid:
            continue
        values[var.name] = transform(var, counter_uniform(spec.seed, stream, key))
    for var in spec.vary:
        if var.relative:
            values[var.name] = spec.nominal_value(var.name) * values[var.name]
    ordered = {v.name: values[v.name] for v in spec.vary}
    return Points(index=index, cell=cell, sample=sample, values=ordered,
                  noise_seed=noise_seeds(spec.seed, key))
