"""Two-mode linear least squares (the order-4 analogue of the single-mode equation (*) in
:mod:`.single_mode`), SIMO over the rows of the data:

    G (v^4 + c3 v^3 + c2 v^2 + c1 v + c0) = e3 v^3 + e2 v^2 + e1 v + e0

with shared ``c`` and per-FRF ``e`` (eliminated by Schur complements). The model-order check of
the Isolation Phase uses it to split a band that holds two close modes fitted as one.

Jitted, unchecked helper: ``fit_two``. Checked wrapper: :func:`fit_two_modes`.
"""

from __future__ import annotations

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.linalg import gauss_solve, poly_roots, solve_normal
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


@jit(inline="always")
def _upper_poles(roots, dt, ws, limits, lam_out, vsel):
    """The poles of the roots ``v`` of the two-mode polynomial: exactly two eigenvalues in the
    upper half plane, both physical (:func:`~.single_mode.pole_code`), written to ``lam_out``
    with their roots in ``vsel``, in the order of ``roots``. Returns a FIT_* code."""
    cnt = 0
    for r in range(roots.shape[0]):
        vr = roots[r]
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
            code = pole_code(lam, limits)
            if code != FIT_OK:
                return code
            lam_out[cnt] = lam
            vsel[cnt] = vr
            cnt += 1
    return FIT_OK if cnt == 2 else FIT_NOT_OSCILLATORY


@jit
def fit_two(data, grid, lo, hi, ws, limits, wts, lam_out, res_out):
    """Two-mode linear least squares (order-4 analogue of (*)), SIMO over the rows of ``data``:
    ``G (v^4 + c3 v^3 + c2 v^2 + c1 v + c0) = e3 v^3 + e2 v^2 + e1 v + e0`` with shared ``c`` and
    per-FRF ``e`` (eliminated by Schur complements). Used by the model-order check to split a
    band that holds two close modes fitted as one. Writes ``lam_out`` (2,), ``res_out`` (P, 2);
    returns a FIT_* code."""
    x, dt, n_samples = grid.x, grid.dt, grid.n_samples
    n_p = data.shape[0]
    m = 4
    nll = np.zeros((m, m))
    red = np.zeros((m, m))
    redr = np.zeros((m, 1))
    nsl_all = np.zeros((n_p, m, m))
    rl_all = np.zeros((n_p, m))
    vp = np.empty(m + 1, dtype=np.complex128)
    # v of every line of the band: (1 - q) / (dt ws) (discrete) or i w / ws
    v_band = np.empty(hi - lo, dtype=np.complex128)
    for i in range(lo, hi):
        v_band[i - lo] = (1.0 - x[i]) / (dt * ws) if dt > 0.0 else x[i] / ws
    for i in range(lo, hi):
        v = v_band[i - lo]
        vp[0] = 1.0
        for a in range(1, m + 1):
            vp[a] = vp[a - 1] * v
        for a in range(m):
            for b in range(m):
                nll[a, b] += (np.conj(vp[a]) * vp[b]).real
    eye = np.zeros((m, m))
    for a in range(m):
        eye[a, a] = 1.0
    nll_inv, ok = gauss_solve(nll, eye)
    if not ok:
        return FIT_SINGULAR
    nss = np.empty((m, m))
    t = np.empty((m, m))
    rs = np.empty(m)
    for j in range(n_p):
        nss[:] = 0.0
        rs[:] = 0.0
        nsl, rl = nsl_all[j], rl_all[j]  # zeros: accumulated in place
        for i in range(lo, hi):
            g = data[j, i] * wts[j]
            v = v_band[i - lo]
            vp[0] = 1.0
            for a in range(1, m + 1):
                vp[a] = vp[a - 1] * v
            rhs = g * vp[m]
            for a in range(m):
                ca = np.conj(-g * vp[a])
                for b in range(m):
                    nss[a, b] += (ca * (-g * vp[b])).real
                    nsl[a, b] += (ca * vp[b]).real
                rs[a] += (ca * rhs).real
                rl[a] += (np.conj(vp[a]) * rhs).real
        # red += nss - nsl nll^-1 nsl^T; redr += rs - nsl nll^-1 rl (4x4 loops: a BLAS call on
        # 4x4 costs more than it saves, and its first-run compilation more still)
        for a in range(m):
            for b in range(m):
                acc = 0.0
                for c in range(m):
                    acc += nsl[a, c] * nll_inv[c, b]
                t[a, b] = acc
        for a in range(m):
            for b in range(m):
                acc = 0.0
                for c in range(m):
                    acc += t[a, c] * nsl[b, c]
                red[a, b] += nss[a, b] - acc
            acc = 0.0
            for b in range(m):
                acc += t[a, b] * rl[b]
            redr[a, 0] += rs[a] - acc
    sol, ok = solve_normal(red, redr)
    if not ok:
        return FIT_SINGULAR
    coef = np.empty(m + 1, dtype=np.complex128)
    coef[0] = 1.0
    for a in range(m):
        coef[m - a] = sol[a, 0]
    roots = poly_roots(coef)  # by decreasing imaginary part, as np.roots orders them
    vsel = np.empty(2, dtype=np.complex128)
    code = _upper_poles(roots, dt, ws, limits, lam_out, vsel)
    if code != FIT_OK:
        return code
    b = np.empty(m)
    e = np.empty(m)
    for j in range(n_p):
        for a in range(m):
            acc = rl_all[j, a]
            for c in range(m):
                acc -= nsl_all[j, c, a] * sol[c, 0]
            b[a] = acc
        for a in range(m):
            acc = 0.0
            for c in range(m):
                acc += nll_inv[a, c] * b[c]
            e[a] = acc
        for kk in range(2):
            vr = vsel[kk]
            num = 0j
            vpow = 1.0 + 0j
            for a in range(m):
                num += e[a] * vpow
                vpow *= vr
            den = 1.0 + 0j
            for r in range(m):
                if roots[r] != vr:
                    den *= vr - roots[r]
            rr = num / den / wts[j]
            if dt > 0.0:
                p, sc = pole_factor(lam_out[kk], dt, n_samples)
                res_out[j, kk] = p * dt * ws * rr / sc
            else:
                res_out[j, kk] = ws * rr
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
