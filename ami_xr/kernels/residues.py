"""Residues by linear least squares with the eigenvalues fixed (the paper's eq. 9).

The unknowns of each mode are ``A1 = Re A`` and ``A2 = Im A`` (columns ``b + conj-b`` and
``i (b - conj-b)``); with ``residual_kind >= 0`` a lower and an upper residual term follow, two
real unknowns each (``residual_kind`` 0 receptance, 1 mobility, 2 accelerance; the columns of
:func:`ami_xr.kernels.modal_basis.model_columns`). Every FRF shares the columns, so the normal
matrix is formed once and only the right sides are per FRF.

Jitted, unchecked helper for the other kernel modules: ``residues_fixed_kernel``. Checked
wrappers: :func:`residue_normal_equations`, :func:`residues_fixed`.
"""

from __future__ import annotations

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.linalg import solve_normal
from ami_xr.kernels.modal_basis import as_dt, checked_omega, line_variable, pole_factor


@jit(inline="always")
def _residue_normal_equations(data, omega, lam, dt, n_samples, use, residual_kind):
    """Normal matrix (n_u, n_u) shared by all FRFs, and right sides (n_u, P), of eq. 9.

    Unknowns per mode ``(A1, A2)``: complex columns ``b + conj-b`` and ``i (b - conj-b)`` on the
    used lines; with ``residual_kind >= 0`` two complex residual terms (lower, upper) follow, 2
    real unknowns each: 0 receptance ``1/(i w)^2``, ``1``; 1 mobility ``1/(i w)``, ``i w``;
    2 accelerance ``1``, ``(i w)^2`` (a term singular at 0 rad/s is 0 there).
    """
    n_k = lam.shape[0]
    n_f = omega.shape[0]
    n_used = 0
    for i in range(n_f):
        if use[i]:
            n_used += 1
    idx = np.empty(n_used, dtype=np.int64)
    m = 0
    for i in range(n_f):
        if use[i]:
            idx[m] = i
            m += 1
    n_u = 2 * n_k + (4 if residual_kind >= 0 else 0)
    cols = np.empty((n_u, n_used), dtype=np.complex128)
    x = line_variable(omega, dt)
    for k in range(n_k):
        p, sc = pole_factor(lam[k], dt, n_samples)
        pc = np.conj(p)
        scc = np.conj(sc)
        for m in range(n_used):
            xi = x[idx[m]]
            if dt > 0.0:
                b = sc / (1.0 - p * xi)
                bc = scc / (1.0 - pc * xi)
            else:
                b = 1.0 / (xi - p)
                bc = 1.0 / (xi - pc)
            cols[2 * k, m] = b + bc
            cols[2 * k + 1, m] = 1j * (b - bc)
    if residual_kind >= 0:
        for m in range(n_used):
            w = omega[idx[m]]
            s = 1j * w
            if residual_kind == 0:
                lo = 1.0 / (s * s) if w != 0.0 else 0.0j
                up = 1.0 + 0j
            elif residual_kind == 1:
                lo = 1.0 / s if w != 0.0 else 0.0j
                up = s
            else:
                lo = 1.0 + 0j
                up = s * s
            cols[2 * n_k, m] = lo
            cols[2 * n_k + 1, m] = 1j * lo
            cols[2 * n_k + 2, m] = up
            cols[2 * n_k + 3, m] = 1j * up
    n_p = data.shape[0]
    nmat = np.zeros((n_u, n_u))
    for a in range(n_u):
        for b in range(a, n_u):
            acc = 0.0
            for m in range(n_used):
                acc += (np.conj(cols[a, m]) * cols[b, m]).real
            nmat[a, b] = acc
            nmat[b, a] = acc
    rhs = np.zeros((n_u, n_p))
    for j in range(n_p):
        for a in range(n_u):
            acc = 0.0
            for m in range(n_used):
                acc += (np.conj(cols[a, m]) * data[j, idx[m]]).real
            rhs[a, j] = acc
    return nmat, rhs


@jit
def residues_fixed_kernel(data, omega, lam, dt, n_samples, use, residual_kind):
    """Residues (P, K) (and residual coefficients (P, 2) when ``residual_kind >= 0``) of eq. 9."""
    n_k = lam.shape[0]
    nmat, rhs = _residue_normal_equations(data, omega, lam, dt, n_samples, use, residual_kind)
    sol, ok = solve_normal(nmat, rhs)
    n_p = data.shape[0]
    n_r = 2 if residual_kind >= 0 else 0
    out = np.full((n_p, n_k + n_r), complex(np.nan, np.nan))
    if not ok:
        return out
    for j in range(n_p):
        for k in range(n_k + n_r):
            out[j, k] = complex(sol[2 * k, j], sol[2 * k + 1, j])
    return out


def _check_inputs(data, omega, lam, use, dt, n_samples, residual_kind):
    omega = checked_omega(omega)
    data = np.ascontiguousarray(np.atleast_2d(data), dtype=np.complex128)
    if data.ndim != 2 or data.shape[1] != omega.size:
        raise AmiXrValueError(f"data: expected shape (P, {omega.size}), got {data.shape}")
    lam = np.ascontiguousarray(np.atleast_1d(lam), dtype=np.complex128)
    if lam.ndim != 1:
        raise AmiXrValueError(f"lam: expected a 1-D array of eigenvalues, got shape {lam.shape}")
    if use is None:
        use = np.ones(omega.size, np.bool_)
    else:
        use = np.ascontiguousarray(use, np.bool_)
        if use.shape != omega.shape:
            raise AmiXrValueError(f"use: expected shape {omega.shape}, got {use.shape}")
    if residual_kind not in (-1, 0, 1, 2):
        raise AmiXrValueError(f"residual_kind: expected -1, 0, 1 or 2, got {residual_kind!r}")
    dt = as_dt(dt)
    n = int(n_samples or 0)
    if dt < 0.0 or n < 0:
        raise AmiXrValueError(f"dt, n_samples: expected >= 0 or None, got {dt!r}, {n_samples!r}")
    return data, omega, lam, use, dt, n, int(residual_kind)


def residue_normal_equations(
    data: np.ndarray,
    omega: np.ndarray,
    lam: np.ndarray,
    use: np.ndarray | None = None,
    dt: float | None = None,
    n_samples: int | None = None,
    residual_kind: int = -1,
) -> tuple[np.ndarray, np.ndarray]:
    """Normal matrix and right sides of eq. 9 (unknowns ``A1, A2`` per mode, then the residual
    terms' real and imaginary coefficients).

    Parameters
    ----------
    data : ndarray of complex, shape (P, F)
        FRFs.
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    lam : ndarray of complex, shape (K,)
        Fixed eigenvalues.
    use : ndarray of bool, shape (F,), optional
        Lines to fit (default all).
    dt, n_samples : optional
        Discrete model; None for the continuous one.
    residual_kind : {-1, 0, 1, 2}
        -1 no residual terms, else their kind (0 receptance, 1 mobility, 2 accelerance).

    Returns
    -------
    nmat : ndarray of float, shape (n_u, n_u)
    rhs : ndarray of float, shape (n_u, P)
    """
    data, omega, lam, use, dt, n, kind = _check_inputs(
        data, omega, lam, use, dt, n_samples, residual_kind
    )
    return _residue_normal_equations(data, omega, lam, dt, n, use, kind)


def residues_fixed(
    data: np.ndarray,
    omega: np.ndarray,
    lam: np.ndarray,
    use: np.ndarray | None = None,
    dt: float | None = None,
    n_samples: int | None = None,
    residual_kind: int = -1,
) -> np.ndarray:
    """Residues by linear least squares with the eigenvalues fixed (eq. 9).

    Parameters are those of :func:`residue_normal_equations`.

    Returns
    -------
    ndarray of complex, shape (P, K) or (P, K + 2)
        Residues, followed by the lower and upper residual coefficients when
        ``residual_kind >= 0``; all NaN when the system is singular (e.g. fewer used lines than
        unknowns).
    """
    data, omega, lam, use, dt, n, kind = _check_inputs(
        data, omega, lam, use, dt, n_samples, residual_kind
    )
    return residues_fixed_kernel(data, omega, lam, dt, n, use, kind)
