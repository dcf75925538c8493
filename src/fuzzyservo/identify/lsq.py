"""Bounded nonlinear least squares in a fixed order of operations: the same bits on every machine.

scipy's ``least_squares`` solves its steps with LAPACK and forms its products with BLAS,
whose kernels (chosen by the processor or ``OPENBLAS_CORETYPE``) order their sums differently:
estimates that differ in their last bits from machine to machine, against the project's rule
of no BLAS or LAPACK on a result's path (docs/architecture.md, "Machine-independent results").
The fits of :mod:`fuzzyservo.identify` use this module instead:

- :func:`gram`: JᵀJ and Jᵀr of a tall Jacobian, each entry one sequential sum over the rows,
  compiled (numba, no fast-math: no reassociation, no contraction into fused multiply-adds);
- :func:`levenberg_marquardt`: Marquardt's method with the diagonal scaling of JᵀJ
  (Marquardt 1963; Nielsen's damping update, IMM-REP-1999-05), on a box: variables at a bound
  whose gradient points out of the box are held, and every trial point is projected into the
  box (Kanzow, Yamashita and Fukushima, J. Comput. Appl. Math. 172, 2004). Each damped system
  is solved by :func:`fuzzyservo.plant.dense.solve` (Gaussian elimination in Python floats);
- :func:`covariance`: s² (JᵀJ)⁻¹ in the scaled (correlation) form, with the directions JᵀJ
  does not determine found (eigenvalues by :func:`~fuzzyservo.plant.dense.eigvals`, vectors by
  inverse iteration) and returned, so their variance can be reported unbounded.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .._jit import kernel
from .._typing import FloatArray
from ..plant.dense import eigvals, solve

__all__ = ["LsqResult", "covariance", "gram", "levenberg_marquardt", "sum_of_squares", "total"]


@kernel
def _gram(jac: FloatArray, r: FloatArray, a: FloatArray, g: FloatArray) -> None:
    m, p = jac.shape
    for i in range(p):
        acc = 0.0
        for k in range(m):
            acc += jac[k, i] * r[k]
        g[i] = acc
        for j in range(i + 1):
            acc = 0.0
            for k in range(m):
                acc += jac[k, i] * jac[k, j]
            a[i, j] = acc
            a[j, i] = acc


@kernel
def _total(x: FloatArray) -> float:
    acc = 0.0
    for k in range(x.shape[0]):
        acc += x[k]
    return acc


@kernel
def _sumsq(x: FloatArray) -> float:
    acc = 0.0
    for k in range(x.shape[0]):
        acc += x[k] * x[k]
    return acc


def gram(jac: FloatArray, r: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(JᵀJ, Jᵀr), each entry summed over the rows in order."""
    jac = np.ascontiguousarray(jac, dtype=np.float64)
    p = jac.shape[1]
    a = np.empty((p, p))
    g = np.empty(p)
    _gram(jac, np.ascontiguousarray(r, dtype=np.float64), a, g)
    return a, g


def total(x: FloatArray) -> float:
    """Σ x, summed in order."""
    return float(_total(np.ascontiguousarray(x, dtype=np.float64)))


def sum_of_squares(x: FloatArray) -> float:
    """Σ x², summed in order."""
    return float(_sumsq(np.ascontiguousarray(x, dtype=np.float64)))


#: Largest damping (relative to JᵀJ's diagonal): a step this damped moves nothing.
_MU_MAX = 1e20


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class LsqResult:
    """The end of a search."""

    x: FloatArray  #: the solution
    cost: float  #: ½ Σ r² there
    nfev: int  #: evaluations of the residuals
    njev: int  #: evaluations of the Jacobian
    status: str  #: why it stopped


def levenberg_marquardt(fun: Callable[[FloatArray], FloatArray],
                        jac: Callable[[FloatArray], FloatArray], x0: FloatArray,
                        lo: FloatArray, hi: FloatArray, *, max_nfev: int = 100,
                        ftol: float = 1e-10, xtol: float = 1e-10) -> LsqResult:
    """Minimise ½ Σ fun(x)² over lo <= x <= hi.

    The damped system is (JᵀJ + μ diag(JᵀJ)) δ = -Jᵀr with a dimensionless μ, 1e-3 at the
    start (so the first step is nearly Gauss-Newton's, whatever the residuals' scale),
    updated by the gain ratio (Nielsen). Stops when a step lowers the cost by at most
    ``ftol`` of it, when the step moves every variable by at most ``xtol`` (1 + |x|), when no
    damping finds a lower cost, or when ``max_nfev`` evaluations of ``fun`` are spent (the
    status says which). ``fun`` returns infinite values where it cannot evaluate: the step
    is refused like any that does not lower the cost.
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    x = np.minimum(np.maximum(np.asarray(x0, dtype=np.float64), lo), hi)
    r = fun(x)
    cost = 0.5 * sum_of_squares(r)
    nfev, njev = 1, 0
    mu = 1e-3  # damping relative to JᵀJ's diagonal (Marquardt's scaling)
    nu = 2.0
    p = x.size
    while True:
        if nfev >= max_nfev:
            return LsqResult(x=x, cost=cost, nfev=nfev, njev=njev, status="max_nfev")
        jm = jac(x)
        njev += 1
        a, g = gram(jm, r)
        diag = np.array([max(a[i, i], 0.0) for i in range(p)])
        big = float(max(diag)) if p else 0.0
        if big <= 0.0:
            return LsqResult(x=x, cost=cost, nfev=nfev, njev=njev, status="flat")
        scale = np.maximum(diag, 1e-12 * big)  # Marquardt's scaling, floored
        # held: at a bound with the descent direction (-g) pointing out of the box
        held = ((x <= lo) & (g > 0.0)) | ((x >= hi) & (g < 0.0))
        free = np.flatnonzero(~held)
        if free.size == 0:
            return LsqResult(x=x, cost=cost, nfev=nfev, njev=njev, status="bound")
        accepted = False
        while nfev < max_nfev:
            sub = [[float(a[i, j]) + (mu * float(scale[i]) if i == j else 0.0) for j in free]
                   for i in free]
            try:
                d_free = solve(sub, [-float(g[i]) for i in free])
            except (ValueError, ArithmeticError):
                mu *= nu
                nu *= 2.0
                if not mu < _MU_MAX:
                    return LsqResult(x=x, cost=cost, nfev=nfev, njev=njev,
                                     status="no descent")
                continue
            step = np.zeros(p)
            step[free] = d_free
            x_new = np.minimum(np.maximum(x + step, lo), hi)
            moved = np.abs(x_new - x)
            if bool(np.all(moved <= xtol * (1.0 + np.abs(x)))):
                return LsqResult(x=x, cost=cost, nfev=nfev, njev=njev, status="xtol")
            r_new = fun(x_new)
            nfev += 1
            cost_new = 0.5 * sum_of_squares(r_new)
            if math.isfinite(cost_new) and cost_new < cost:
                # gain ratio of the step against the linear model's prediction
                dx = x_new - x
                predicted = -(float(np.sum(dx * g)) + 0.5 * float(
                    sum(dx[i] * sum(a[i, j] * dx[j] for j in range(p)) for i in range(p))))
                rho = (cost - cost_new) / predicted if predicted > 0.0 else 1.0
                mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                drop = cost - cost_new
                x, r, cost = x_new, r_new, cost_new
                accepted = True
                if drop <= ftol * cost_new:
                    return LsqResult(x=x, cost=cost, nfev=nfev, njev=njev, status="ftol")
                break
            mu *= nu
            nu *= 2.0
            if not mu < _MU_MAX:
                return LsqResult(x=x, cost=cost, nfev=nfev, njev=njev, status="no descent")
        if not accepted:
            return LsqResult(x=x, cost=cost, nfev=nfev, njev=njev, status="max_nfev")


def _symmetric(a: FloatArray) -> list[list[float]]:
    p = a.shape[0]
    return [[0.5 * (float(a[i, j]) + float(a[j, i])) for j in range(p)] for i in range(p)]


def covariance(jac: FloatArray, r: FloatArray, dof: int, *, rcond: float = 1e-12
               ) -> tuple[FloatArray, float, FloatArray]:
    """The covariance s² (JᵀJ)⁺ of the least-squares estimate, the reduced chi-square
    s² = Σ r² / dof, and the unit vectors (rows) of the directions JᵀJ does not determine
    (eigenvalues of its correlation form below ``rcond`` of the largest): along them the
    variance is unbounded, and the pseudo-inverse leaves them out."""
    a, _ = gram(jac, r)
    p = a.shape[0]
    s2 = sum_of_squares(r) / max(1, dof)
    d = np.array([math.sqrt(a[i, i]) if a[i, i] > 0.0 else 0.0 for i in range(p)])
    dd = np.where(d > 0.0, d, 1.0)
    c = _symmetric(np.array([[a[i, j] / (dd[i] * dd[j]) for j in range(p)]
                             for i in range(p)]))
    lam = sorted(float(v.real) for v in eigvals(c))
    top = max(abs(v) for v in lam) if lam else 0.0
    n_null = sum(1 for v in lam if v <= rcond * top) if top > 0.0 else p
    null: list[FloatArray] = []
    shift = 1e-9 * (top if top > 0.0 else 1.0)
    for k in range(n_null):
        shifted = [[c[i][j] + (shift if i == j else 0.0) for j in range(p)] for i in range(p)]
        v = np.array([1.0 + 0.1 * ((i * 7 + k * 3) % 5) for i in range(p)])
        for _ in range(8):
            for u in null:
                v = v - float(np.sum(v * u)) * u
            v = np.array(solve(shifted, [float(x) for x in v]))
            for u in null:
                v = v - float(np.sum(v * u)) * u
            norm = math.sqrt(float(np.sum(v * v)))
            if norm == 0.0:
                break
            v = v / norm
        null.append(v)
    proj = np.zeros((p, p))
    for u in null:
        proj += np.outer(u, u)
    reg = [[c[i][j] + float(proj[i, j]) for j in range(p)] for i in range(p)]
    inv = np.empty((p, p))
    for j in range(p):
        inv[:, j] = solve(reg, [1.0 if i == j else 0.0 for i in range(p)])
    pinv = inv - proj
    cov = s2 * pinv / np.outer(dd, dd)
    vecs = np.array([u / dd for u in null]) if null else np.empty((0, p))
    if vecs.size:  # back to the unscaled variables, unit length
        vecs = np.array([v / math.sqrt(float(np.sum(v * v))) for v in vecs])
    return cov, s2, vecs
