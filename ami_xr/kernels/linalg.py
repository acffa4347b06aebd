"""Small dense solvers of the AMI kernels (no LAPACK call: the systems are 2x2 to ~40x40).

Unchecked helpers for the other kernel modules: ``gauss_solve`` and ``solve_normal`` (plain
numpy: only Python calls them, so they cost no compilation on a first run), ``solve2`` (the
same solve of a 2 x 2 system in scalars, inlined into the jitted single-mode fit) and
``poly_roots`` (jitted). :func:`solve_normal_equations` and :func:`polynomial_roots` are the
checked wrappers.

Normal equations are solved after Jacobi (diagonal) scaling, with one step of iterative
refinement, by Gaussian elimination with partial pivoting. Roots of a low-degree polynomial come
from the Aberth-Ehrlich iteration (simultaneous Newton steps with a repulsion term that keeps
the estimates of close roots apart), each root kept once its residual is at the rounding level
of the polynomial's evaluation there: the accuracy of ``np.roots`` (a backward-stable companion
eigensolve) without compiling numba's LAPACK eigenvalue wrappers on a first run.
"""

from __future__ import annotations

import math

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit


def gauss_solve(a, b):
    """Solve ``a x = b`` (n x n, n x m) by Gaussian elimination with partial pivoting.
    Returns ``(x, ok)``; ``ok`` is False when a pivot is zero. ``a`` and ``b`` are not modified.

    Plain numpy (only Python calls it: nothing to compile on a first run), vectorised over the
    rows of a column and over the right sides; every element sees the arithmetic, in the order,
    of the scalar loops (pivot: the first row of the largest ``|a[r, col]|``).
    """
    n = a.shape[0]
    a = np.array(a, dtype=np.float64)
    x = np.array(b, dtype=np.float64)
    for col in range(n):
        piv = col
        column = np.abs(a[:, col]).tolist()
        big = column[col]
        for r in range(col + 1, n):
            if column[r] > big:  # NaN never wins, as in a scalar loop
                big = column[r]
                piv = r
        if big == 0.0 or not math.isfinite(big):
            return x, False
        if piv != col:
            a[[col, piv]] = a[[piv, col]]
            x[[col, piv]] = x[[piv, col]]
        f = a[col + 1 :, col] / a[col, col]
        if np.all(f != 0.0):  # the common case: slices, no fancy indexing
            a[col + 1 :, col:] -= f[:, None] * a[col, col:]
            x[col + 1 :] -= f[:, None] * x[col]
            continue
        rows = np.flatnonzero(f != 0.0) + col + 1
        if rows.size:
            f = f[rows - col - 1, None]
            a[rows, col:] -= f * a[col, col:]
            x[rows] -= f * x[col]
    for col in range(n - 1, -1, -1):
        s = x[col].copy()
        for k in range(col + 1, n):
            s -= a[col, k] * x[k]
        x[col] = s / a[col, col]
    return x, True


def solve_normal(nmat, rhs):
    """Solve symmetric normal equations ``nmat x = rhs`` (rhs n x m) with Jacobi scaling and one
    step of iterative refinement. Returns ``(x, ok)``. Plain numpy (see :func:`gauss_solve`);
    the jitted kernels solve their 2 x 2 systems with :func:`solve2`."""
    nmat = np.asarray(nmat, dtype=np.float64)
    rhs = np.asarray(rhs, dtype=np.float64)
    n = nmat.shape[0]
    diag = np.diagonal(nmat).copy()
    pos = diag > 0.0
    d = np.ones(n)
    d[pos] = 1.0 / np.sqrt(diag[pos])
    s = nmat * d[:, None] * d[None, :]
    sr = rhs * d[:, None]
    y, ok = gauss_solve(s, sr)
    if not ok:
        return y, False
    # one refinement step on the scaled system (sums over j in order, as a scalar loop)
    acc = np.zeros_like(sr)
    for j in range(n):
        acc += s[:, j, None] * y[None, j, :]
    dy, ok2 = gauss_solve(s, sr - acc)
    if ok2:
        y += dy
    x = y * d[:, None]
    return x, bool(np.all(np.isfinite(x)))


@jit(inline="always")
def solve2(a00, a01, a10, a11, b0, b1):
    """:func:`solve_normal` of a 2 x 2 system with one right side, in scalars (the same
    arithmetic, in the same order: Jacobi scaling, elimination with partial pivoting, one
    refinement step). Returns ``(x0, x1, ok)``. Inlined: no arrays, no separate compilation."""
    d0 = 1.0 / math.sqrt(a00) if a00 > 0.0 else 1.0
    d1 = 1.0 / math.sqrt(a11) if a11 > 0.0 else 1.0
    s00 = a00 * d0 * d0
    s01 = a01 * d0 * d1
    s10 = a10 * d1 * d0
    s11 = a11 * d1 * d1
    r0 = b0 * d0
    r1 = b1 * d1
    y0, y1, ok = _gauss2(s00, s01, s10, s11, r0, r1)
    if not ok:
        return y0, y1, False
    acc0 = 0.0
    acc0 += s00 * y0
    acc0 += s01 * y1
    acc1 = 0.0
    acc1 += s10 * y0
    acc1 += s11 * y1
    e0, e1, ok2 = _gauss2(s00, s01, s10, s11, r0 - acc0, r1 - acc1)
    if ok2:
        y0 += e0
        y1 += e1
    x0 = y0 * d0
    x1 = y1 * d1
    return x0, x1, math.isfinite(x0) and math.isfinite(x1)


@jit(inline="always")
def _gauss2(a00, a01, a10, a11, x0, x1):
    """:func:`gauss_solve` of a 2 x 2 system with one right side, in scalars."""
    big = abs(a00)
    if abs(a10) > big:
        big = abs(a10)
        a00, a01, a10, a11, x0, x1 = a10, a11, a00, a01, x1, x0
    if big == 0.0 or not math.isfinite(big):
        return x0, x1, False
    f = a10 / a00
    if f != 0.0:
        a11 -= f * a01
        x1 -= f * x0
    big = abs(a11)
    if big == 0.0 or not math.isfinite(big):
        return x0, x1, False
    x1 = x1 / a11
    s = x0
    s -= a01 * x1
    return s / a00, x1, True


_EPS = float(np.finfo(np.float64).eps)

ROOT_ITERATIONS = 200
"""Most Aberth sweeps of :func:`poly_roots` (degree 4 needs fewer than 10 for simple roots;
close roots converge linearly, a multiple root only to its conditioning)."""


@jit(inline="always")
def poly_roots(coef):
    """Roots of ``coef[0] v^n + coef[1] v^(n-1) + ... + coef[n]`` (complex, ``coef[0] != 0``),
    ordered by decreasing imaginary part (then decreasing real part).

    Aberth-Ehrlich iteration from ``n`` points on a circle (radius: the largest
    ``|coef[k] / coef[0]|^(1/k)``, at angles ``2 pi k / n + pi / (2 n)``, none real); a root
    stops moving once ``|p(z)| <= 4 eps sum_k |coef[k]| |z|^(n-k)`` (its backward error at the
    rounding level: the accuracy of a backward-stable eigensolve of the companion matrix, as in
    ``np.roots``). The ordering is the one numba's ``np.roots`` gives two conjugate pairs of
    nearby roots; a zero ``coef[n]`` gives a root exactly 0.
    """
    n = coef.shape[0] - 1
    a = np.empty(n + 1, dtype=np.complex128)
    for k in range(n + 1):
        a[k] = coef[k] / coef[0]
    z = np.zeros(n, dtype=np.complex128)
    n_zero = 0  # trailing zero coefficients: roots exactly 0 (as np.roots gives them)
    while n_zero < n and a[n - n_zero] == 0.0:
        n_zero += 1
    m = n - n_zero
    radius = 0.0
    for k in range(1, m + 1):
        radius = max(radius, abs(a[k]) ** (1.0 / k))
    done = np.zeros(n, dtype=np.bool_)
    for k in range(m):
        angle = 2.0 * np.pi * k / m + 0.5 * np.pi / m
        z[k] = radius * complex(np.cos(angle), np.sin(angle))
    eps = _EPS
    for _sweep in range(ROOT_ITERATIONS if m > 0 else 0):
        moving = False
        for k in range(m):
            if done[k]:
                continue
            zk = z[k]
            p = 1.0 + 0j
            dp = 0j
            bound = 1.0
            for j in range(1, m + 1):
                dp = dp * zk + p
                p = p * zk + a[j]
                bound = bound * abs(zk) + abs(a[j])
            if p == 0.0:
                done[k] = True
                continue
            # at the rounding level: one last correction (it can only polish), then kept
            done[k] = abs(p) <= 4.0 * eps * bound
            moving = True
            ratio = p / dp
            s = 0j
            for j in range(m):
                if j != k:
                    s += 1.0 / (zk - z[j])
            step = ratio / (1.0 - ratio * s)
            if not (np.isfinite(step.real) and np.isfinite(step.imag)):
                step = ratio if np.isfinite(ratio.real) and np.isfinite(ratio.imag) else 0j
            z[k] = zk - step
        if not moving:
            break
    # decreasing imaginary part, then decreasing real part (insertion sort of n values)
    for i in range(1, n):
        v = z[i]
        j = i
        while j > 0 and (
            v.imag > z[j - 1].imag or (v.imag == z[j - 1].imag and v.real > z[j - 1].real)
        ):
            z[j] = z[j - 1]
            j -= 1
        z[j] = v
    return z


def polynomial_roots(coef: np.ndarray) -> np.ndarray:
    """Roots of the polynomial with coefficients ``coef`` (highest power first), as ``np.roots``
    (checked wrapper of ``poly_roots``).

    Parameters
    ----------
    coef : ndarray of complex, shape (n + 1,)
        Coefficients, ``coef[0] != 0``, all finite, ``n >= 1``.

    Returns
    -------
    ndarray of complex, shape (n,)
        The roots, by decreasing imaginary part (then decreasing real part).
    """
    coef = np.ascontiguousarray(coef, dtype=np.complex128)
    if coef.ndim != 1 or coef.size < 2:
        raise AmiXrValueError(f"coef: expected a 1-D array of >= 2 coefficients, got {coef.shape}")
    if coef[0] == 0 or not np.all(np.isfinite(coef)):
        raise AmiXrValueError("coef: expected finite coefficients with coef[0] != 0")
    return poly_roots(coef)


def solve_normal_equations(nmat: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, bool]:
    """Solve symmetric normal equations ``nmat x = rhs`` (checked wrapper of ``solve_normal``).

    Parameters
    ----------
    nmat : ndarray of float, shape (n, n)
        Symmetric normal matrix.
    rhs : ndarray of float, shape (n,) or (n, m)
        Right side(s).

    Returns
    -------
    x : ndarray of float, shape (n, m)
        The solution (``(n, 1)`` for a 1-D ``rhs``).
    ok : bool
        False when a pivot is zero or the solution is not finite.
    """
    nmat = np.ascontiguousarray(nmat, dtype=np.float64)
    rhs = np.ascontiguousarray(rhs, dtype=np.float64)
    if rhs.ndim == 1:
        rhs = rhs[:, None]
    if nmat.ndim != 2 or nmat.shape[0] != nmat.shape[1] or nmat.shape[0] == 0:
        raise AmiXrValueError(f"nmat: expected a square 2-D array, got shape {nmat.shape}")
    if rhs.ndim != 2 or rhs.shape[0] != nmat.shape[0]:
        raise AmiXrValueError(f"rhs: expected {nmat.shape[0]} rows, got shape {rhs.shape}")
    x, ok = solve_normal(nmat, rhs)
    return x, bool(ok)
