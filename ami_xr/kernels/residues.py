"""Residues by linear least squares with the eigenvalues fixed (the paper's eq. 9).

The unknowns of each mode are ``A1 = Re A`` and ``A2 = Im A`` (columns ``b + conj-b`` and
``i (b - conj-b)``); with ``residual_kind >= 0`` a lower and an upper residual term follow, two
real unknowns each (``residual_kind`` 0 receptance, 1 mobility, 2 accelerance; the columns of
:func:`ami_xr.kernels.modal_basis.model_columns`). Every FRF shares the columns, so the normal
matrix is formed once and only the right sides are per FRF.

Plain numpy (only Python calls it, so nothing here is jitted: no first-run compilation), the
solve :func:`~.linalg.solve_normal` too. Checked
wrappers: :func:`residue_normal_equations`, :func:`residues_fixed`.
"""

from __future__ import annotations

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels.linalg import solve_normal
from ami_xr.kernels.modal_basis import as_dt, checked_omega, line_variable


def _residue_columns(omega, lam, dt, n_samples, use, residual_kind):
    """The model's columns (n_u, n_used) on the used lines: per mode ``b + conj-b`` and
    ``i (b - conj-b)`` (the arithmetic of :func:`~.modal_basis.add_mode`), then with
    ``residual_kind >= 0`` the residual terms ``lo, i lo, up, i up``: 0 receptance
    ``1/(i w)^2``, ``1``; 1 mobility ``1/(i w)``, ``i w``; 2 accelerance ``1``, ``(i w)^2`` (a
    term singular at 0 rad/s is 0 there)."""
    n_k = lam.shape[0]
    w = omega[use]
    x = line_variable(w, dt)[None, :]
    lam = lam[:, None]
    if dt > 0.0:
        p = np.exp(lam * dt)
        sc = (
            dt * (1.0 - np.exp(lam * (n_samples * dt)))
            if n_samples > 0
            else np.full(lam.shape, dt + 0j)
        )
        b = sc / (1.0 - p * x)
        bc = np.conj(sc) / (1.0 - np.conj(p) * x)
    else:
        b = 1.0 / (x - lam)
        bc = 1.0 / (x - np.conj(lam))
    n_u = 2 * n_k + (4 if residual_kind >= 0 else 0)
    cols = np.empty((n_u, w.size), dtype=np.complex128)
    cols[0 : 2 * n_k : 2] = b + bc
    cols[1 : 2 * n_k : 2] = 1j * (b - bc)
    if residual_kind >= 0:
        s = 1j * w
        nonzero = w != 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            lo = (1.0 / (s * s), 1.0 / s, np.ones_like(s))[residual_kind]
        up = (np.ones_like(s), s, s * s)[residual_kind]
        if residual_kind < 2:
            lo = np.where(nonzero, lo, 0.0j)
        cols[2 * n_k :] = (lo, 1j * lo, up, 1j * up)
    return cols


def _residue_normal_equations(data, omega, lam, dt, n_samples, use, residual_kind):
    """Normal matrix (n_u, n_u) shared by all FRFs, and right sides (n_u, P), of eq. 9:
    ``Re(C^H C)`` and ``Re(C^H g)`` of the columns ``C`` (:func:`_residue_columns`)."""
    cols = _residue_columns(omega, lam, dt, n_samples, use, residual_kind)
    stacked = np.concatenate((cols.real, cols.imag), axis=1)  # Re(conj a b) = a.re b.re + a.im b.im
    nmat = stacked @ stacked.T
    used = data if use.all() else data[:, use]
    rhs = np.empty((cols.shape[0], data.shape[0]))
    for j in range(data.shape[0]):
        # one product per FRF: its residues do not depend on the other rows given with it (a
        # matrix product's blocking does), so chunked and whole inputs agree to the bit
        rhs[:, j] = stacked @ np.concatenate((used[j].real, used[j].imag))
    return np.ascontiguousarray(nmat), rhs


def residues_fixed_kernel(data, omega, lam, dt, n_samples, use, residual_kind):
    """Residues (P, K) (and residual coefficients (P, 2) when ``residual_kind >= 0``) of eq. 9,
    all NaN when the normal equations are singular."""
    n_k = lam.shape[0]
    nmat, rhs = _residue_normal_equations(data, omega, lam, dt, n_samples, use, residual_kind)
    sol, ok = solve_normal(nmat, rhs)
    n_p = data.shape[0]
    n_r = 2 if residual_kind >= 0 else 0
    out = np.full((n_p, n_k + n_r), complex(np.nan, np.nan))
    if ok:
        out.real = sol[0::2].T
        out.imag = sol[1::2].T
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
