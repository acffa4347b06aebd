"""Two-mode linear least squares (the order-4 analogue of the single-mode equation (*) in
:mod:`.single_mode`), SIMO over the rows of the data:

    G (v^4 + c3 v^3 + c2 v^2 + c1 v + c0) = e3 v^3 + e2 v^2 + e1 v + e0

with shared ``c`` and per-FRF ``e`` (eliminated by Schur complements). The model-order check of
the Isolation Phase uses it to split a band that holds two close modes fitted as one.

Unchecked helper (plain numpy: only Python calls it): ``fit_two``. Checked wrapper:
:func:`fit_two_modes`.
"""

from __future__ import annotations

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels.linalg import gauss_solve, solve_normal
from ami_xr.kernels.modal_basis import Grid, as_dt, checked_omega, line_variable, pole_factor
from ami_xr.kernels.single_mode import (
    FIT_NOT_OSCILLATORY,
    FIT_OK,
    FIT_SINGULAR,
    FIT_UNSTABLE,
    FitLimits,
    check_frf,
    check_zeta_max,
    pole_code,
)


def _upper_poles(roots, dt, ws, limits, lam_out, vsel):
    """The poles of the roots ``v`` of the two-mode polynomial: exactly two eigenvalues in the
    upper half plane, both physical (:func:`~.single_mode.pole_code`), written to ``lam_out``
    with their roots in ``vsel``, in the order of ``roots``. Returns a FIT_* code."""
    cnt = 0
    for vr in roots:
        if dt > 0.0:
            q = 1.0 - dt * ws * vr
            if abs(q) == 0.0:
                return FIT_UNSTABLE
            lam = np.log(1.0 / q) / dt
        else:
            lam = ws * vr
        if lam.imag > 0.0:
            if cnt >= 2:
                return FIT_NOT_OSCILLATORY
            code = pole_code(complex(lam), limits)
            if code != FIT_OK:
                return code
            lam_out[cnt] = lam
            vsel[cnt] = vr
            cnt += 1
    return FIT_OK if cnt == 2 else FIT_NOT_OSCILLATORY


def fit_two(data, grid, lo, hi, ws, limits, wts, lam_out, res_out):
    """Two-mode linear least squares (order-4 analogue of (*)), SIMO over the rows of ``data``:
    ``G (v^4 + c3 v^3 + c2 v^2 + c1 v + c0) = e3 v^3 + e2 v^2 + e1 v + e0`` on lines
    ``lo..hi-1`` with shared ``c`` and per-FRF ``e`` (eliminated by Schur complements), row
    ``j`` weighted by ``wts[j]``. Used by the model-order check to split a band that holds two
    close modes fitted as one. Writes ``lam_out`` (2,), ``res_out`` (P, 2); returns a FIT_*
    code.

    Plain numpy (the isolation calls it from Python, and only when it tries a split: nothing to
    compile for a run that never does); the small solves are those of :mod:`.linalg`, the
    roots ``np.roots``'s.
    """
    x, dt, n_samples = grid.x, grid.dt, grid.n_samples
    m = 4
    # v of every line of the band: (1 - q) / (dt ws) (discrete) or i w / ws; vp[a] = v^a
    xb = x[lo:hi]
    v = (1.0 - xb) / (dt * ws) if dt > 0.0 else xb / ws
    vp = np.empty((m + 1, v.size), dtype=np.complex128)
    vp[0] = 1.0
    for a in range(1, m + 1):
        vp[a] = vp[a - 1] * v
    loc = vp[:m]
    nll = np.ascontiguousarray(np.einsum("al,bl->ab", loc.conj(), loc).real)
    nll_inv, ok = gauss_solve(nll, np.eye(m))
    if not ok:
        return FIT_SINGULAR
    g = data[:, lo:hi] * wts[:, None]
    rhs = g * vp[m]
    shared = -g[:, None, :] * loc[None, :, :]  # (P, 4, L)
    nss = np.einsum("pal,pbl->pab", shared.conj(), shared).real
    nsl = np.einsum("pal,bl->pab", shared.conj(), loc).real
    rs = np.einsum("pal,pl->pa", shared.conj(), rhs).real
    rl = np.einsum("al,pl->pa", loc.conj(), rhs).real
    # red = sum_j nss - nsl nll^-1 nsl^T; redr = sum_j rs - nsl nll^-1 rl
    t = nsl @ nll_inv
    red = np.ascontiguousarray(np.sum(nss - t @ nsl.transpose(0, 2, 1), axis=0))
    redr = np.ascontiguousarray(np.sum(rs - np.einsum("pab,pb->pa", t, rl), axis=0)[:, None])
    sol, ok = solve_normal(red, redr)
    if not ok:
        return FIT_SINGULAR
    coef = np.concatenate(([1.0], sol[::-1, 0])).astype(np.complex128)
    with np.errstate(all="ignore"):
        roots = np.roots(coef) if np.all(np.isfinite(coef)) else np.full(m, np.nan + 0j)
    roots = roots[np.lexsort((-roots.real, -roots.imag))]  # decreasing Im, then Re
    vsel = np.empty(2, dtype=np.complex128)
    code = _upper_poles(roots, dt, ws, limits, lam_out, vsel)
    if code != FIT_OK:
        return code
    e = (rl - nsl.transpose(0, 2, 1) @ sol[:, 0]) @ nll_inv.T  # (P, 4)
    for kk in range(2):
        vr = vsel[kk]
        num = e @ (vr ** np.arange(m))
        den = np.prod([vr - r for r in roots if r != vr])
        rr = num / den / wts
        if dt > 0.0:
            p, sc = pole_factor(complex(lam_out[kk]), dt, n_samples)
            res_out[:, kk] = p * dt * ws * rr / sc
        else:
            res_out[:, kk] = ws * rr
    return FIT_OK


def fit_two_modes(
    data: np.ndarray,
    omega: np.ndarray,
    dt: float | None = None,
    n_samples: int | None = None,
    *,
    scale: float | None = None,
    zeta_max: float = 1.0,
    w_lo: float = 0.0,
    w_hi: float = np.inf,
    weights: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Two-mode linear least squares, SIMO over the rows of ``data`` (the model-order check's
    split of a band that holds two close modes fitted as one).

    Parameters
    ----------
    data : ndarray of complex, shape (P, F)
        FRFs on the fit band.
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    dt, n_samples : optional
        Discrete model; None for the continuous one.
    scale : float, optional
        Frequency scale ``ws``; default the band centre ``omega[F // 2]``.
    zeta_max, w_lo, w_hi : float
        Limits of :class:`FitLimits`.
    weights : ndarray of float, shape (P,), optional
        Row weights (default 1).

    Returns
    -------
    lam : ndarray of complex, shape (2,)
    residues : ndarray of complex, shape (P, 2)
    code : int
        ``FIT_OK`` (0) when both poles are physical, else a ``FIT_*`` rejection code.
    """
    omega = checked_omega(omega)
    data = check_frf(np.atleast_2d(data), omega)
    if data.ndim != 2:
        raise AmiXrValueError(f"data: expected shape (P, {omega.size}), got {data.shape}")
    if omega.size < 5:
        raise AmiXrValueError(f"omega: the two-mode fit needs >= 5 lines, got {omega.size}")
    n_p = data.shape[0]
    wts = np.ones(n_p) if weights is None else np.ascontiguousarray(weights, dtype=np.float64)
    if wts.shape != (n_p,) or not np.all(wts > 0):
        raise AmiXrValueError(f"weights: expected {n_p} positive weights, got {wts!r}")
    ws = float(omega[omega.size // 2]) if scale is None else float(scale)
    if not ws > 0.0:
        raise AmiXrValueError(f"scale: expected a positive frequency scale, got {scale!r}")
    dt = as_dt(dt)
    grid = Grid(omega, line_variable(omega, dt), dt, int(n_samples or 0))
    limits = FitLimits(check_zeta_max(zeta_max), float(w_lo), float(w_hi))
    lam = np.full(2, complex(np.nan, np.nan))
    res = np.full((n_p, 2), complex(np.nan, np.nan))
    code = fit_two(data, grid, 0, omega.size, ws, limits, wts, lam, res)
    return lam, res, code
