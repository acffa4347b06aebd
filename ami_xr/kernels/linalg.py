"""Small dense solvers of the AMI kernels (no LAPACK call: the systems are 2x2 to ~40x40).

``gauss_solve``, ``solve_normal`` and ``poly_roots`` are jitted and unchecked, for the other
kernel modules; :func:`solve_normal_equations` and :func:`polynomial_roots` are the checked
wrappers.

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


@jit
def gauss_solve(a, b):
    """Solve ``a x = b`` (n x n, n x m) by Gaussian elimination with partial pivoting.

    Returns ``(x, ok)``; ``ok`` is False when a pivot is zero. ``a`` and ``b`` are not modified.
    """
    n = a.shape[0]
    m = b.shape[1]
    a = a.copy()
    x = b.copy()
    for col in range(n):
        piv = col
        big = abs(a[col, col])
        for r in range(col + 1, n):
            if abs(a[r, col]) > big:
                big = abs(a[r, col])
                piv = r
        if big == 0.0 or not np.isfinite(big):
            return x, False
        if piv != col:
            for c in range(n):
                tmp = a[col, c]
                a[col, c] = a[piv, c]
                a[piv, c] = tmp
            for c in range(m):
                tmp = x[col, c]
                x[col, c] = x[piv, c]
                x[piv, c] = tmp
        for r in range(col + 1, n):
            f = a[r, col] / a[col, col]
            if f != 0.0:
                for c in range(col, n):
                    a[r, c] -= f * a[col, c]
                for c in range(m):
                    x[r, c] -= f * x[col, c]
    for col in range(n - 1, -1, -1):
        for c in range(m):
            s = x[col, c]
            for k in range(col + 1, n):
                s -= a[col, k] * x[k, c]
            x[col, c] = s / a[col, col]
    return x, True


@jit
def solve_normal(nmat, rhs):
    """Solve symmetric normal equations ``nmat x = rhs`` (rhs n x m) with Jacobi scaling and one
    step of iterative refinement. Returns ``(x, ok)``."""
    n = nmat.shape[0]
    m = rhs.shape[1]
    d = np.empty(n)
    for i in range(n):
        d[i] = 1.0 / math.sqrt(nmat[i, i]) if nmat[i, i] > 0.0 else 1.0
    s = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            s[i, j] = nmat[i, j] * d[i] * d[j]
    sr = np.empty((n, m))
    for i in range(n):
        for c in range(m):
            sr[i, c] = rhs[i, c] * d[i]
    y, ok = gauss_solve(s, sr)
    if not ok:
        return y, False
    # one refinement step on the scaled system
    res = sr.copy()
    for i in range(n):
        for c in range(m):
            acc = 0.0
            for j in range(n):
                acc += s[i, j] * y[j, c]
            res[i, c] -= acc
    dy, ok2 = gauss_solve(s, res)
    if ok2:
        for i in range(n):
            for c in range(m):
                y[i, c] += dy[i, c]
    x = np.empty((n, m))
    for i in range(n):
        for c in range(m):
            x[i, c] = y[i, c] * d[i]
        for c in range(m):
            if not np.isfinite(x[i, c]):
                return x, False
    return x, True


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
