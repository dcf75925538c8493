"""Small dense linear algebra in plain IEEE arithmetic, in one fixed order: the same bits on
every machine.

numpy's ``@``, ``np.dot`` and ``np.linalg`` call OpenBLAS and LAPACK, whose kernels are
chosen when the process starts, by the processor or by ``OPENBLAS_CORETYPE``, and which
order their sums and use fused multiply-adds differently (Haswell, SkylakeX, Zen and
Sandybridge kernels give results that differ in their last bits). The plant's
linearisation (a root solve over eigenvalues of a 6×6 or 7×7 Jacobian) and its ZOH
discretisation (an 8×8 matrix exponential) go through the functions here instead, so the
derived parameter sets ``paper`` and ``stiff-oil`` and every trace downstream of them are
bit-identical whatever BLAS kernel or CPU runs them (docs/architecture.md,
"Machine-independent results").

Every operation is a Python ``float`` operation (IEEE 754 binary64, round to nearest, no
contraction into fused multiply-adds) or ``math.sqrt`` (correctly rounded), in an order the
code fixes. The matrices are small, so plain Python loops over lists cost microseconds to a
few milliseconds per call.

- :func:`matmul`: C = A B, each entry summed over k in increasing order.
- :func:`solve`: Gaussian elimination with partial pivoting (first largest pivot).
- :func:`eigvals`: balancing, reduction to Hessenberg form by stabilised elementary
  similarity transformations, and the Francis double-shift QR iteration (EISPACK's
  ``balanc``/``elmhes``/``hqr``; Wilkinson and Reinsch, *Handbook for Automatic Computation*
  II, 1971; Press et al., *Numerical Recipes*, 2nd ed., §11.5-11.6).
"""

from __future__ import annotations

import math

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..errors import ParameterError

__all__ = ["balance", "dot", "eigvals", "matmul", "solve"]

#: QR iterations allowed per eigenvalue before :func:`eigvals` gives up (EISPACK: 30).
_MAX_ITERATIONS = 30


def _rows(a: ArrayLike, what: str) -> list[list[float]]:
    m = np.asarray(a, dtype=np.float64)
    if m.ndim != 2:
        raise ParameterError(f"{what} must be a matrix (2-D), got shape {m.shape}")
    rows: list[list[float]] = m.tolist()
    return rows


def dot(x: ArrayLike, y: ArrayLike) -> float:
    """Σ x_i y_i for vectors of equal length, summed in increasing i."""
    xs = np.asarray(x, dtype=np.float64).reshape(-1).tolist()
    ys = np.asarray(y, dtype=np.float64).reshape(-1).tolist()
    if len(xs) != len(ys):
        raise ParameterError(f"dot needs vectors of equal length, got {len(xs)} and {len(ys)}")
    s = 0.0
    for xi, yi in zip(xs, ys, strict=True):
        s += xi * yi
    return s


def matmul(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """A B for A (n, k) and B (k, m) or (k,); each entry Σ_t a_it b_tj summed in increasing t.

    Raises
    ------
    ParameterError
        For shapes that do not conform.
    """
    ar = _rows(a, "matmul's A")
    bm = np.asarray(b, dtype=np.float64)
    vector = bm.ndim == 1
    br = bm.reshape(-1, 1).tolist() if vector else _rows(bm, "matmul's B")
    k = len(br)
    if any(len(row) != k for row in ar):
        raise ParameterError(f"matmul needs A (n, k) and B (k, m), got {np.shape(a)} and "
                             f"{bm.shape}")
    m = len(br[0]) if br else 0
    cols = [[br[t][j] for t in range(k)] for j in range(m)]
    out = []
    for row in ar:
        line = []
        for col in cols:
            s = 0.0
            for t in range(k):
                s += row[t] * col[t]
            line.append(s)
        out.append(line)
    c = np.array(out, dtype=np.float64).reshape(len(ar), m)
    return c[:, 0].copy() if vector else c


def solve(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """x with A x = b for a square A (n, n) and b (n,) or (n, m): Gaussian elimination with
    partial pivoting (the first row of largest |pivot|), then back substitution.

    Raises
    ------
    ParameterError
        For shapes that do not conform, or a singular A (a zero pivot).
    """
    ar = _rows(a, "solve's A")
    n = len(ar)
    if any(len(row) != n for row in ar):
        raise ParameterError(f"solve needs a square A, got shape {np.shape(a)}")
    bm = np.asarray(b, dtype=np.float64)
    vector = bm.ndim == 1
    br = bm.reshape(-1, 1).tolist() if vector else _rows(bm, "solve's b")
    if len(br) != n:
        raise ParameterError(f"solve needs b with {n} rows, got shape {bm.shape}")
    m = len(br[0]) if br else 0
    for col in range(n):
        piv = col
        big = abs(ar[col][col])
        for r in range(col + 1, n):
            if abs(ar[r][col]) > big:
                piv, big = r, abs(ar[r][col])
        if big == 0.0 or not math.isfinite(big):
            raise ParameterError(f"solve: the matrix is singular or not finite (pivot {col} "
                                 f"is {big!r})")
        if piv != col:
            ar[col], ar[piv] = ar[piv], ar[col]
            br[col], br[piv] = br[piv], br[col]
        pr, pb = ar[col], br[col]
        d = pr[col]
        for r in range(col + 1, n):
            row = ar[r]
            f = row[col] / d
            if f == 0.0:
                continue
            row[col] = 0.0
            for j in range(col + 1, n):
                row[j] -= f * pr[j]
            rb = br[r]
            for j in range(m):
                rb[j] -= f * pb[j]
    x = [[0.0] * m for _ in range(n)]
    for i in range(n - 1, -1, -1):
        row = ar[i]
        for j in range(m):
            s = br[i][j]
            for t in range(i + 1, n):
                s -= row[t] * x[t][j]
            x[i][j] = s / row[i]
    out = np.array(x, dtype=np.float64).reshape(n, m)
    return out[:, 0].copy() if vector else out


def _balance_rows(b: list[list[float]]) -> list[float]:
    """Balance ``b`` in place by a diagonal similarity of powers of two (exact), EISPACK's
    ``balanc`` without permutations; returns the diagonal D (B := D⁻¹ B D)."""
    n = len(b)
    d = [1.0] * n
    converged = False
    while not converged:
        converged = True
        for i in range(n):
            c = 0.0
            r = 0.0
            for j in range(n):
                if j != i:
                    c += abs(b[j][i])
                    r += abs(b[i][j])
            if c == 0.0 or r == 0.0:
                continue
            f = 1.0
            total = c + r
            while c < r / 2.0:
                c *= 2.0
                r /= 2.0
                f *= 2.0
            while c >= r * 2.0:
                c /= 2.0
                r *= 2.0
                f /= 2.0
            if c + r < 0.95 * total:
                converged = False
                d[i] *= f
                for j in range(n):
                    b[j][i] *= f
                    b[i][j] /= f
    return d


def balance(a: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """(B, d) with B = D⁻¹ A D, D = diag(d) of powers of two (so B is exact), and the row and
    column norms of B within a factor of two of each other (EISPACK's ``balanc``).

    Raises
    ------
    ParameterError
        For a matrix that is not square.
    """
    b = _rows(a, "balance's A")
    if any(len(row) != len(b) for row in b):
        raise ParameterError(f"balance needs a square matrix, got shape {np.shape(a)}")
    d = _balance_rows(b)
    return (np.array(b, dtype=np.float64).reshape(len(b), len(b)),
            np.array(d, dtype=np.float64))


def _hessenberg(a: list[list[float]]) -> None:
    """Reduce ``a`` (1-based, (n+1)×(n+1) with row and column 0 unused) to upper Hessenberg
    form in place by stabilised elementary similarities (EISPACK's ``elmhes``)."""
    n = len(a) - 1
    for m in range(2, n):
        x = 0.0
        i = m
        for j in range(m, n + 1):
            if abs(a[j][m - 1]) > abs(x):
                x = a[j][m - 1]
                i = j
        if i != m:
            for j in range(m - 1, n + 1):
                a[i][j], a[m][j] = a[m][j], a[i][j]
            for j in range(1, n + 1):
                a[j][i], a[j][m] = a[j][m], a[j][i]
        if x != 0.0:
            for i in range(m + 1, n + 1):
                y = a[i][m - 1]
                if y != 0.0:
                    y /= x
                    a[i][m - 1] = 0.0
                    for j in range(m, n + 1):
                        a[i][j] -= y * a[m][j]
                    for j in range(1, n + 1):
                        a[j][m] += y * a[j][i]


def _hqr(a: list[list[float]]) -> list[complex]:
    """Eigenvalues of the upper Hessenberg ``a`` (1-based, destroyed) by the Francis
    double-shift QR iteration with exceptional shifts (EISPACK's ``hqr``)."""
    n = len(a) - 1
    wr = [0.0] * (n + 1)
    wi = [0.0] * (n + 1)
    anorm = 0.0
    for i in range(1, n + 1):
        for j in range(max(i - 1, 1), n + 1):
            anorm += abs(a[i][j])
    nn = n
    t = 0.0
    p = q = r = x = y = z = w = 0.0
    while nn >= 1:
        its = 0
        while True:
            ll = 1
            for l_ in range(nn, 1, -1):
                s = abs(a[l_ - 1][l_ - 1]) + abs(a[l_][l_])
                if s == 0.0:
                    s = anorm
                if abs(a[l_][l_ - 1]) + s == s:
                    a[l_][l_ - 1] = 0.0
                    ll = l_
                    break
            x = a[nn][nn]
            if ll == nn:  # one root found
                wr[nn] = x + t
                wi[nn] = 0.0
                nn -= 1
                break
            y = a[nn - 1][nn - 1]
            w = a[nn][nn - 1] * a[nn - 1][nn]
            if ll == nn - 1:  # two roots found
                p = 0.5 * (y - x)
                q = p * p + w
                z = math.sqrt(abs(q))
                x += t
                if q >= 0.0:  # a real pair
                    z = p + math.copysign(z, p)
                    wr[nn - 1] = wr[nn] = x + z
                    if z != 0.0:
                        wr[nn] = x - w / z
                    wi[nn - 1] = wi[nn] = 0.0
                else:  # a complex pair
                    wr[nn - 1] = wr[nn] = x + p
                    wi[nn - 1] = z
                    wi[nn] = -z
                nn -= 2
                break
            if its == _MAX_ITERATIONS:
                raise ParameterError(f"eigvals: the QR iteration did not converge in "
                                     f"{_MAX_ITERATIONS} iterations (matrix of order {n})")
            if its in (10, 20):  # exceptional shift
                t += x
                for i in range(1, nn + 1):
                    a[i][i] -= x
                s = abs(a[nn][nn - 1]) + abs(a[nn - 1][nn - 2])
                x = y = 0.75 * s
                w = -0.4375 * s * s
            its += 1
            m = nn - 2
            while m >= ll:  # two consecutive small subdiagonal elements
                z = a[m][m]
                r = x - z
                s = y - z
                p = (r * s - w) / a[m + 1][m] + a[m][m + 1]
                q = a[m + 1][m + 1] - z - r - s
                r = a[m + 2][m + 1]
                s = abs(p) + abs(q) + abs(r)
                p /= s
                q /= s
                r /= s
                if m == ll:
                    break
                u = abs(a[m][m - 1]) * (abs(q) + abs(r))
                v = abs(p) * (abs(a[m - 1][m - 1]) + abs(z) + abs(a[m + 1][m + 1]))
                if u + v == v:
                    break
                m -= 1
            for i in range(m + 2, nn + 1):
                a[i][i - 2] = 0.0
                if i != m + 2:
                    a[i][i - 3] = 0.0
            for k in range(m, nn):  # double QR step on rows ll..nn, columns m..nn
                if k != m:
                    p = a[k][k - 1]
                    q = a[k + 1][k - 1]
                    r = a[k + 2][k - 1] if k != nn - 1 else 0.0
                    x = abs(p) + abs(q) + abs(r)
                    if x != 0.0:
                        p /= x
                        q /= x
                        r /= x
                s = math.copysign(math.sqrt(p * p + q * q + r * r), p)
                if s == 0.0:
                    continue
                if k == m:
                    if ll != m:
                        a[k][k - 1] = -a[k][k - 1]
                else:
                    a[k][k - 1] = -s * x
                p += s
                x = p / s
                y = q / s
                z = r / s
                q /= p
                r /= p
                for j in range(k, nn + 1):
                    p = a[k][j] + q * a[k + 1][j]
                    if k != nn - 1:
                        p += r * a[k + 2][j]
                        a[k + 2][j] -= p * z
                    a[k + 1][j] -= p * y
                    a[k][j] -= p * x
                for i in range(ll, min(nn, k + 3) + 1):
                    p = x * a[i][k] + y * a[i][k + 1]
                    if k != nn - 1:
                        p += z * a[i][k + 2]
                        a[i][k + 2] -= p * r
                    a[i][k + 1] -= p * q
                    a[i][k] -= p
    return [complex(wr[i], wi[i]) for i in range(1, n + 1)]


def modulus(lam: complex) -> float:
    """|λ| as sqrt(re² + im²): plain IEEE arithmetic (``abs`` of a complex calls the C
    library's ``hypot``)."""
    return math.sqrt(lam.real * lam.real + lam.imag * lam.imag)


def eigvals(a: ArrayLike) -> FloatArray:
    """Eigenvalues of a real square matrix, complex, in no particular order (a complex pair
    with its positive imaginary part first).

    Raises
    ------
    ParameterError
        For a matrix that is not square or not finite, or when the QR iteration does not
        converge.
    """
    rows = _rows(a, "eigvals' A")
    n = len(rows)
    if any(len(row) != n for row in rows):
        raise ParameterError(f"eigvals needs a square matrix, got shape {np.shape(a)}")
    if not all(math.isfinite(v) for row in rows for v in row):
        raise ParameterError("eigvals needs a finite matrix")
    if n == 0:
        return np.zeros(0, dtype=np.complex128)
    _balance_rows(rows)
    h = [[0.0] * (n + 1)] + [[0.0, *row] for row in rows]
    _hessenberg(h)
    lam = _hqr(h)
    return np.array(lam, dtype=np.complex128)
