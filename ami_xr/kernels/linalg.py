"""Small dense solvers of the AMI kernels (no LAPACK call: the systems are 2x2 to ~40x40).

``gauss_solve`` and ``solve_normal`` are jitted and unchecked, for the other kernel modules;
:func:`solve_normal_equations` is the checked wrapper.

Normal equations are solved after Jacobi (diagonal) scaling, with one step of iterative
refinement, by Gaussian elimination with partial pivoting.
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
