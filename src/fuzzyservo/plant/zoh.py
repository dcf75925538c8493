"""Zero-order-hold discretisation with an exact transport delay: the one linear-model path.

Every linear model of the package is discretised here: eq. (8) (:class:`LinearServo`), the
small-signal linearisation, in open and in closed loop. A command sampled every ``ts`` and
held (ZOH) reaches the plant ``delay`` seconds late. With ``delay = d ts + f``, 0 <= f < ts
(:func:`split_delay`), the plant input over [t_k, t_k + ts) is u_{k-d-1} on [t_k, t_k + f) and
u_{k-d} on [t_k + f, t_k + ts), so (Åström & Wittenmark, *Computer-Controlled Systems*,
3rd ed., sec. 2.3)::

    x_{k+1} = Φ x_k + Γ_0 u_{k-d} + Γ_1 u_{k-d-1}
    Φ   = e^{A ts}
    Γ_0 = ∫_0^{ts-f} e^{As} ds B
    Γ_1 = e^{A (ts-f)} ∫_0^f e^{As} ds B

Each integral comes from one matrix exponential of the block matrix [[A, B], [0, 0]] (Van
Loan, IEEE TAC 23(3), 1978); the exponential is :func:`expm`, balancing plus Higham's [13/13]
Padé scaling and squaring, written here because scipy's LAPACK threads stalled for
milliseconds per call on a busy two-core machine (tests hold it to scipy's ``expm`` at 1e-13),
and computed with :mod:`.dense`'s products and solve, not numpy's BLAS, so that its bits do
not depend on the machine's BLAS kernel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..errors import ParameterError
from .dense import balance, matmul, solve

__all__ = ["DiscreteModel", "check_delay", "discretize", "expm", "split_delay"]

#: Relative slack when a delay is read as whole samples: a delay within 1e-9 samples of a
#: multiple of ts is that multiple (so 0.006 s at ts = 0.001 s is 6 samples despite rounding).
_WHOLE_SAMPLE_TOL = 1e-9


def check_delay(delay: float, *, duration: float | None = None) -> float:
    """A transport delay [s], validated: finite, >= 0 and, when the run's ``duration`` [s] is
    given, at most that long.

    A command delayed past the end of the run never reaches the plant, so a longer delay
    only describes a run in which nothing happens (and, unchecked, sized buffers by it).

    Raises
    ------
    ParameterError
        Otherwise.
    """
    try:
        value = float(delay)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value >= 0.0):
        raise ParameterError(f"delay must be finite and >= 0 s, got {delay!r}")
    if duration is not None and math.isfinite(duration) and 0.0 < duration < value:
        raise ParameterError(f"delay {value!r} s is longer than the run ({duration!r} s); at "
                             f"most the run's duration is allowed (a command delayed past the "
                             f"end never reaches the plant)")
    return value


def split_delay(delay: float, ts: float) -> tuple[int, float]:
    """Split ``delay`` [s] into whole samples and a fraction: ``(d, f)``, delay = d ts + f.

    ``0 <= f < ts`` [s]; a fraction below 1e-9 of a sample counts as zero.

    Raises
    ------
    ParameterError
        ``ts`` is not finite and > 0, or ``delay`` is not finite and >= 0.
    """
    if not (isinstance(ts, int | float) and math.isfinite(ts) and ts > 0.0):
        raise ParameterError(f"sample time ts must be finite and > 0 s, got {ts!r}")
    delay = check_delay(delay)
    d = int(math.floor(delay / ts + _WHOLE_SAMPLE_TOL))
    f = delay - d * ts
    return d, (0.0 if f < _WHOLE_SAMPLE_TOL * ts else f)


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class DiscreteModel:
    """ZOH discretisation of dx/dt = A x + B u with a transport delay on u.

    x_{k+1} = Φ x_k + Γ_0 u_{k-d} + Γ_1 u_{k-d-1} (module docstring).
    """

    ts: float  #: sample time [s]
    delay: float  #: transport delay [s]
    d: int  #: whole samples of the delay [-]
    f: float  #: fraction of a sample, 0 <= f < ts [s]
    phi: FloatArray  #: Φ (n, n) [-]
    gamma0: FloatArray  #: Γ_0 (n,) [state unit per unit input]
    gamma1: FloatArray  #: Γ_1 (n,), zero when f = 0 [state unit per unit input]

    @property
    def gamma(self) -> FloatArray:
        """Γ_0 + Γ_1: the input vector of the model without delay (or when u is constant)."""
        out: FloatArray = self.gamma0 + self.gamma1
        return out


def _van_loan(a: FloatArray, b: FloatArray, tau: float) -> tuple[FloatArray, FloatArray]:
    """(e^{A tau}, ∫_0^tau e^{As} ds B) from one matrix exponential."""
    n = a.shape[0]
    m = np.zeros((n + 1, n + 1))
    m[:n, :n] = a * tau
    m[:n, n] = b * tau
    e = expm(m)
    return e[:n, :n], e[:n, n].copy()


def discretize(a: ArrayLike, b: ArrayLike, ts: float, delay: float = 0.0) -> DiscreteModel:
    """ZOH discretisation of a single-input model with an exact (fractional) input delay.

    Parameters
    ----------
    a : array_like (n, n)
        State matrix [1/s].
    b : array_like (n,) or (n, 1)
        Input vector [state unit per unit input per s].
    ts : float
        Sample time [s], > 0.
    delay : float
        Transport delay on the input [s], >= 0; any value, not only whole samples.

    Returns
    -------
    DiscreteModel

    Raises
    ------
    ParameterError
        Bad shapes, non-finite matrices, ``ts`` or ``delay``.
    """
    am = np.atleast_2d(np.asarray(a, dtype=np.float64))
    bv = np.asarray(b, dtype=np.float64).reshape(-1)
    n = am.shape[0]
    if n == 0 or am.shape != (n, n) or bv.shape != (n,):
        raise ParameterError(f"discretize needs A (n, n) and B (n,), got {am.shape} and "
                             f"{np.shape(b)}")
    if not (np.all(np.isfinite(am)) and np.all(np.isfinite(bv))):
        raise ParameterError("discretize needs finite A and B")
    d, f = split_delay(delay, ts)
    phi_hf, g0 = _van_loan(am, bv, ts - f)
    if f > 0.0:
        phi_f, gf = _van_loan(am, bv, f)
        phi = matmul(phi_hf, phi_f)
        g1 = matmul(phi_hf, gf)
    else:
        phi, g1 = phi_hf, np.zeros(n)
    return DiscreteModel(ts=float(ts), delay=float(delay), d=d, f=f, phi=phi, gamma0=g0,
                         gamma1=g1)


_PADE13 = (64764752532480000.0, 32382376266240000.0, 7771770303897600.0,
           1187353796428800.0, 129060195264000.0, 10559470521600.0, 670442572800.0,
           33522128640.0, 1323241920.0, 40840800.0, 960960.0, 16380.0, 182.0, 1.0)
_THETA13 = 5.371920351148152


def expm(a: FloatArray) -> FloatArray:
    """Matrix exponential: balancing, then scaling and squaring with the [13/13] Padé
    approximant (Higham, SIAM J. Matrix Anal. Appl. 26(4), 2005).

    Balancing matters here: eq. (8)'s matrix mixes ω_v² ≈ 5e5 with O(1) entries, and without
    it the extra squarings cost three digits.
    """
    n = a.shape[0]
    bal, d = balance(np.asarray(a, dtype=np.float64))
    norm = float(np.max(np.sum(np.abs(bal), axis=0))) if n else 0.0
    s = 0
    if norm > _THETA13:  # the least s with norm / 2**s <= θ13, exactly (no libm log2)
        mant, s = math.frexp(norm / _THETA13)
        s -= 1 if mant == 0.5 else 0
    x = bal / 2.0**s
    b = _PADE13
    ident = np.eye(n)
    x2 = matmul(x, x)
    x4 = matmul(x2, x2)
    x6 = matmul(x4, x2)
    u = matmul(x, matmul(x6, b[13] * x6 + b[11] * x4 + b[9] * x2)
               + b[7] * x6 + b[5] * x4 + b[3] * x2 + b[1] * ident)
    v = (matmul(x6, b[12] * x6 + b[10] * x4 + b[8] * x2)
         + b[6] * x6 + b[4] * x4 + b[2] * x2 + b[0] * ident)
    r = solve(v - u, v + u)
    for _ in range(s):
        r = matmul(r, r)
    out: FloatArray = r * d[:, None] / d[None, :]
    return out
