"""Kernels of the Algorithm of Mode Isolation: single-mode linear least squares, modal synthesis,
the Subtraction and Isolation phases per FRF, the global SIMO isolation and the residue fit (eq. 9).

Plain arrays in, plain arrays out; batch dim (point) first, frequency last. Private ``_name``
functions are jitted and assume clean input; the public wrappers at the bottom check and raise.

Single-mode linear least squares in one variable ``v`` (both data models)
-------------------------------------------------------------------------
One mode's contribution is a ratio of real-coefficient polynomials in a frequency variable
``v``: monic quadratic denominator, numerator of degree <= 1::

    G(v) (v^2 + c1 v + c0) = e1 v + e0                                         (*)

* continuous time (eq. 4): ``v = i w / ws`` (``ws`` a scale, the band centre). Then
  ``c0 = |lam|^2 / ws^2``, ``c1 = -2 Re(lam) / ws``, ``e1 = 2 A1 / ws``,
  ``e0 = -2 (Re(lam) A1 + Im(lam) A2) / ws^2``: the real and imaginary parts of (*) are exactly
  the paper's eqs. 11 and 12 in its four unknowns ``|lam|^2, Re lam, A1, Re(lam) A1 + Im(lam) A2``.
* exact discrete time (FRF = dt * DFT of an impulse response sampled at dt): with
  ``q = exp(-i w dt)`` and ``p = exp(lam dt)`` one mode contributes
  ``B / (1 - p q) + conj(B) / (1 - conj(p) q)`` with ``B = dt A (1 - exp(lam N dt))``: a
  ratio of real polynomials in ``q`` with denominator ``(1 - p q)(1 - conj(p) q)``. Substituting
  ``v = (1 - q) / (dt ws)`` (which tends to ``i w / ws`` as ``dt -> 0``) gives (*) again, with
  ``v1 = (1 - 1/p) / (dt ws)`` the root of the denominator.

(*) is linear in ``c0, c1, e0, e1``; its real and imaginary parts over the lines of a band are
the rows of the least-squares problem (the "equation error" of eqs. 11-12). The roots ``v1``
(Im > 0) and ``v2`` give the pole (``lam = ws v1``, or ``lam = log(1 / (1 - dt ws v1)) / dt``), and
the partial-fraction residue ``r = (e1 v1 + e0) / (v1 - v2)`` gives ``A = ws r`` (continuous) or
``A = p dt ws r / (dt (1 - exp(lam N dt)))`` (discrete).

Normal equations are solved after Jacobi (diagonal) scaling, with one step of iterative
refinement, by Gaussian elimination with partial pivoting (small systems, no LAPACK call).
"""

from __future__ import annotations

import numpy as np

from ami_xr.kernels._numba import jit
from ami_xr.kernels.modal_basis import (
    add_mode,
    contribution_peak,
    line_variable,
    mode_basis,
    tolerance_envelope,
)
from ami_xr.kernels.noise import (
    band_around,
    band_energy_peak,
    local_peak,
    nearest_line,
    normalized_distance,
    peak_threshold_kernel,
    pole_band,
    split_target,
    sum_threshold_kernel,
)
from ami_xr.kernels.residues import residues_fixed_kernel
from ami_xr.kernels.single_mode import (
    FIT_NO_DROP,
    FIT_OK,
    FitLimits,
    band_energy_drop,
    fit_single,
    fit_single_simo,
    fit_two,
)

FREEZE_CHANGE = 1e-3  # a mode's fit band is kept fixed once its eigenvalue changes less than this


# ----------------------------------------------------------------------------------------------
# small dense solver
# ----------------------------------------------------------------------------------------------
# ----------------------------------------------------------------------------------------------
# modal basis and synthesis (eqs. 4, 6, 7)
# ----------------------------------------------------------------------------------------------
# ----------------------------------------------------------------------------------------------
# single-mode linear least squares (eqs. 10-12 and the discrete analogue)
# ----------------------------------------------------------------------------------------------
# ----------------------------------------------------------------------------------------------
# noise floor, thresholds, bands
# ----------------------------------------------------------------------------------------------
# ----------------------------------------------------------------------------------------------
# Subtraction Phase (eq. 6), one FRF
# ----------------------------------------------------------------------------------------------
# ----------------------------------------------------------------------------------------------
# Isolation Phase (eq. 7), one FRF at a time
# ----------------------------------------------------------------------------------------------
@jit
def _order_by_contribution(omega, x, lam, res, n, dt, n_samples):
    peaks = np.empty(n)
    for k in range(n):
        peaks[k] = contribution_peak(omega, x, lam[k], res[k], dt, n_samples)
    return np.argsort(-peaks)


@jit
def _isolate_sweeps(
    data,
    omega,
    x,
    dt,
    n_samples,
    lam,
    res,
    n,
    delta,
    tol,
    max_iter,
    min_points,
    zeta_max,
    reweight,
    model_band,
    model,
    fails,
):
    """Isolation sweeps until every eigenvalue's Re and Im change less than ``tol`` (relative).

    ``model`` (F) holds the current sum of all modes and is kept up to date.
    Returns ``(iterations, converged)``.
    """
    n_f = data.shape[0]
    dw = (omega[n_f - 1] - omega[0]) / (n_f - 1)
    w_lo = max(omega[0], dw)
    w_hi = omega[n_f - 1]
    limits = FitLimits(zeta_max, w_lo, w_hi)
    xn = np.empty(n_f, dtype=np.complex128)
    power = np.empty(n_f)
    band_lo = np.zeros(n, dtype=np.int64)
    band_hi = np.zeros(n, dtype=np.int64)
    frozen = np.zeros(n, dtype=np.bool_)
    it = 0
    order = _order_by_contribution(omega, x, lam, res, n, dt, n_samples)
    for it in range(1, max_iter + 1):
        change = 0.0
        for kk in range(n):
            k = order[kk]
            for i in range(n_f):
                xn[i] = data[i] - model[i]
            add_mode(xn, x, lam[k], res[k], dt, n_samples, 1.0, 0, n_f)
            for i in range(n_f):
                power[i] = abs(xn[i]) ** 2
            if (
                frozen[k]
                and omega[band_lo[k]] <= lam[k].imag
                and lam[k].imag <= omega[band_hi[k] - 1]
            ):
                # a settled mode keeps its band (while it stays inside): lines entering and
                # leaving a data-defined band make the iteration map discontinuous and can cause
                # limit cycles
                lo = band_lo[k]
                hi = band_hi[k]
                peak = (lo + hi) // 2
            elif model_band:
                lo, hi = pole_band(omega, lam[k], delta, min_points)
                peak = nearest_line(omega, lam[k].imag)
            else:
                peak = local_peak(power, omega, lam[k], dw)
                lo, hi = band_around(power, peak, delta * delta * power[peak])
            band_lo[k] = lo
            band_hi[k] = hi
            if hi - lo < min_points:
                fails[k] += 1
                continue
            ws = omega[peak] if omega[peak] > 0.0 else dw
            prev = complex(np.nan, np.nan)
            new, r, code = fit_single(xn, x, lo, hi, ws, dt, n_samples, limits, prev)
            if code != FIT_OK:
                fails[k] += 1
                continue
            ch = max(
                abs(new.real - lam[k].real) / abs(new.real),
                abs(new.imag - lam[k].imag) / abs(new.imag),
            )
            change = max(change, ch)
            frozen[k] = ch < FREEZE_CHANGE
            add_mode(model, x, lam[k], res[k], dt, n_samples, -1.0, 0, n_f)
            lam[k] = new
            res[k] = r
            add_mode(model, x, new, r, dt, n_samples, 1.0, 0, n_f)
        if change < tol:
            return it, True
    return it, False


@jit
def _remove_mode(lam, res, fails, n, k):
    for i in range(k, n - 1):
        lam[i] = lam[i + 1]
        res[i] = res[i + 1]
        fails[i] = fails[i + 1]
    lam[n - 1] = complex(np.nan, np.nan)
    res[n - 1] = complex(np.nan, np.nan)
    fails[n - 1] = 0
    return n - 1


@jit
def _isolate_one(
    data,
    omega,
    x,
    dt,
    n_samples,
    lam,
    res,
    n,
    sigma,
    delta,
    tol,
    max_iter,
    pfa,
    min_points,
    zeta_max,
    merge_tol,
    max_modes,
    reweight,
    model_band,
):
    """Isolation Phase with the model-order check on one FRF (``lam``/``res`` updated in place,
    length ``max_modes``). Returns ``(n_modes, iterations, converged)``."""
    n_f = data.shape[0]
    t = peak_threshold_kernel(n_f, pfa)
    dw = (omega[n_f - 1] - omega[0]) / (n_f - 1)
    w_lo = max(omega[0], dw)
    w_hi = omega[n_f - 1]
    limits = FitLimits(zeta_max, w_lo, w_hi)
    fails = np.zeros(max_modes, dtype=np.int64)
    total_it = 0
    converged = False
    model = np.zeros(n_f, dtype=np.complex128)
    power = np.empty(n_f)
    masked = np.zeros(n_f, dtype=np.bool_)
    for _restart in range(max_modes + 4):
        for i in range(n_f):
            model[i] = 0.0
        for k in range(n):
            add_mode(model, x, lam[k], res[k], dt, n_samples, 1.0, 0, n_f)
        it, converged = _isolate_sweeps(
            data,
            omega,
            x,
            dt,
            n_samples,
            lam,
            res,
            n,
            delta,
            tol,
            max_iter,
            min_points,
            zeta_max,
            reweight,
            model_band,
            model,
            fails,
        )
        total_it += it
        changed = False
        # duplicates merge: keep the stronger of two modes closer than merge_tol bandwidths
        k = 0
        while k < n:
            dup = -1
            for m in range(n):
                if m != k and normalized_distance(lam[k], lam[m]) < merge_tol:
                    dup = m
                    break
            if dup >= 0:
                pk = contribution_peak(omega, x, lam[k], res[k], dt, n_samples)
                pm = contribution_peak(omega, x, lam[dup], res[dup], dt, n_samples)
                drop = dup if pm <= pk else k
                n = _remove_mode(lam, res, fails, n, drop)
                changed = True
                continue
            k += 1
        # insignificant modes (contribution not above the noise floor, or never fitted) removed
        k = 0
        while k < n:
            pk = contribution_peak(omega, x, lam[k], res[k], dt, n_samples)
            if pk * pk / sigma**2 < t or fails[k] > max_iter // 2:
                n = _remove_mode(lam, res, fails, n, k)
                changed = True
                continue
            k += 1
        if changed:
            continue
        # model-order check: a significant, physical peak left in the residual adds a mode
        if n >= max_modes:
            break
        added = False
        env = tolerance_envelope(omega, lam, res, n, tol)
        stat = np.empty(n_f)
        for _try in range(8):
            best = -1.0
            peak = -1
            for i in range(n_f):
                power[i] = abs(data[i] - model[i]) ** 2
                stat[i] = power[i] / (sigma**2 + env[i] ** 2)
                if not masked[i] and stat[i] > best:
                    best = stat[i]
                    peak = i
            if peak < 0 or best < t:
                peak = band_energy_peak(stat, omega, lam, n, 1, pfa, min_points, masked)
                if peak < 0:
                    break
            best = power[peak]
            ks = split_target(omega, lam, n, peak, masked)
            if ks >= 0:
                # a coherent residual inside a mode's band: two close modes were probably fitted
                # as one. Fit two modes to that mode's isolated data over +-3 |Re lam|; if both
                # are physical they replace it. Each window is tried once.
                wl, wh = pole_band(omega, lam[ks], 0.31622776601683794, max(min_points, 6))
                for i in range(wl, wh):
                    masked[i] = True
                iso = np.empty((1, n_f), dtype=np.complex128)
                for i in range(n_f):
                    iso[0, i] = data[i] - model[i]
                add_mode(iso[0], x, lam[ks], res[ks], dt, n_samples, 1.0, 0, n_f)
                l2 = np.empty(2, dtype=np.complex128)
                r2 = np.empty((1, 2), dtype=np.complex128)
                code = fit_two(
                    iso,
                    x,
                    wl,
                    wh,
                    omega[(wl + wh) // 2],
                    dt,
                    n_samples,
                    limits,
                    np.ones(1),
                    l2,
                    r2,
                )
                if code == FIT_OK:
                    lam[ks] = l2[0]
                    res[ks] = r2[0, 0]
                    lam[n] = l2[1]
                    res[n] = r2[0, 1]
                    fails[n] = 0
                    n += 1
                    added = True
                    break
                continue
            lo, hi = band_around(power, peak, delta * delta * best)
            if hi - lo < min_points:
                for i in range(lo, hi):
                    masked[i] = True
                continue
            y = data - model
            ws = omega[peak] if omega[peak] > 0.0 else dw
            new, r, code = fit_single(
                y, x, lo, hi, ws, dt, n_samples, limits, complex(np.nan, np.nan)
            )
            # no duplicate test here: a coherent residual next to a mode (two close modes fitted
            # as one) must be able to split it; true duplicates merge after the restart
            if code == FIT_OK:
                drop = band_energy_drop(y, x, new, r, dt, n_samples, power, lo, hi, n_f)
                if drop / sigma**2 < t:
                    code = FIT_NO_DROP
            if code != FIT_OK:
                for i in range(lo, hi):
                    masked[i] = True
                continue
            lam[n] = new
            res[n] = r
            fails[n] = 0
            n += 1
            added = True
            break
        if not added:
            break
    return n, total_it, converged


@jit
def _isolate_batch(
    data,
    omega,
    dt,
    n_samples,
    lam0,
    res0,
    n0,
    sigma,
    delta,
    tol,
    max_iter,
    pfa,
    min_points,
    zeta_max,
    merge_tol,
    max_modes,
    reweight,
    model_band,
):
    n_p = data.shape[0]
    x = line_variable(omega, dt)
    lam = np.full((n_p, max_modes), complex(np.nan, np.nan))
    res = np.full((n_p, max_modes), complex(np.nan, np.nan))
    n_modes = np.zeros(n_p, dtype=np.int64)
    iters = np.zeros(n_p, dtype=np.int64)
    conv = np.zeros(n_p, dtype=np.bool_)
    for j in range(n_p):
        n = min(n0[j], max_modes)
        for k in range(n):
            lam[j, k] = lam0[j, k]
            res[j, k] = res0[j, k]
        if n == 0:
            conv[j] = True
            continue
        nn, it, c = _isolate_one(
            data[j],
            omega,
            x,
            dt,
            n_samples,
            lam[j],
            res[j],
            n,
            sigma[j],
            delta,
            tol,
            max_iter,
            pfa,
            min_points,
            zeta_max,
            merge_tol,
            max_modes,
            reweight,
            model_band,
        )
        n_modes[j] = nn
        iters[j] = it
        conv[j] = c
    return lam, res, n_modes, iters, conv


# ----------------------------------------------------------------------------------------------
# global SIMO isolation (Allen & Ginsberg): one eigenvalue per mode from all FRFs at once
# ----------------------------------------------------------------------------------------------
@jit
def _remove_simo(lam, res, fails, n, k):
    for j in range(res.shape[0]):
        for i in range(k, n - 1):
            res[j, i] = res[j, i + 1]
        res[j, n - 1] = complex(np.nan, np.nan)
    for i in range(k, n - 1):
        lam[i] = lam[i + 1]
        fails[i] = fails[i + 1]
    lam[n - 1] = complex(np.nan, np.nan)
    fails[n - 1] = 0
    return n - 1


@jit
def _simo_band(xw, omega, lam, dw, delta, wlo, whi):
    """Fit band of SIMO isolation on lines ``wlo..whi-1``: the SNR-weighted power
    ``sum_j |X_j|^2`` (data already divided by each noise floor), its largest line near the
    mode, and the contiguous lines around it with power ``>= delta^2`` times that peak."""
    n_p = xw.shape[0]
    n_f = xw.shape[1]
    power = np.zeros(n_f)
    for j in range(n_p):
        for i in range(wlo, whi):
            power[i] += abs(xw[j, i]) ** 2
    peak = local_peak(power, omega, lam, dw)
    lo, hi = band_around(power, peak, delta * delta * power[peak])
    return peak, max(lo, wlo), min(hi, whi)


@jit
def _isolated_lines(dw_data, res, br, bi, bcr, bci, n, k, a, b, xn, power, tr, ti):
    """eq. 7 on lines ``a..b-1`` of every FRF: ``xn = data - sum_{m != k}`` contributions and
    ``power[i] = sum_j |xn[j, i]|^2``. The products are numba's complex product written out
    (``(ac - bd) + i (ad + bc)``) in the order of :func:`add_mode`, so the values are the same;
    ``tr``, ``ti`` are scratch lines."""
    n_p = dw_data.shape[0]
    for i in range(a, b):
        power[i] = 0.0
    for j in range(n_p):
        for i in range(a, b):
            tr[i] = dw_data[j, i].real
            ti[i] = dw_data[j, i].imag
        for m in range(n):
            if m == k:
                continue
            rr = res[j, m].real
            ri = res[j, m].imag
            for i in range(a, b):
                tr[i] -= (rr * br[m, i] - ri * bi[m, i]) + (rr * bcr[m, i] + ri * bci[m, i])
                ti[i] -= (rr * bi[m, i] + ri * br[m, i]) + (rr * bci[m, i] - ri * bcr[m, i])
        for i in range(a, b):
            xn[j, i] = complex(tr[i], ti[i])
            power[i] += abs(xn[j, i]) ** 2


@jit
def _simo_band_lazy(
    dw_data, res, br, bi, bcr, bci, n, k, xn, power, tr, ti, omega, lam, dw, delta, wlo, whi
):
    """:func:`_simo_band` computing the isolated data only on the lines it looks at (the peak
    search range and the band grown from the peak) instead of the whole window; same result."""
    half = max(2.0 * abs(lam.real), 2.0 * dw)
    c = nearest_line(omega, lam.imag)
    plo = nearest_line(omega, lam.imag - half)
    phi = nearest_line(omega, lam.imag + half)
    clo = max(min(plo, c), wlo)
    chi = min(max(phi, c) + 1, whi)
    if chi < clo:
        chi = clo
    _isolated_lines(dw_data, res, br, bi, bcr, bci, n, k, clo, chi, xn, power, tr, ti)
    best = c
    pbest = power[c] if (c >= wlo and c < whi) else 0.0
    for i in range(plo, phi + 1):
        pi = power[i] if (i >= wlo and i < whi) else 0.0
        if pi > pbest:
            best = i
            pbest = pi
    level = delta * delta * pbest
    chunk = 16
    n_f = omega.shape[0]
    lo = best
    while lo > 0:
        i = lo - 1
        if i < wlo or i >= whi:
            pi = 0.0
        else:
            if i < clo:
                a = max(wlo, i - chunk + 1)
                _isolated_lines(dw_data, res, br, bi, bcr, bci, n, k, a, clo, xn, power, tr, ti)
                clo = a
            pi = power[i]
        if not (pi >= level):
            break
        lo -= 1
    hi = best + 1
    while hi < n_f:
        i = hi
        if i < wlo or i >= whi:
            pi = 0.0
        else:
            if i >= chi:
                bnd = min(whi, i + chunk)
                _isolated_lines(dw_data, res, br, bi, bcr, bci, n, k, chi, bnd, xn, power, tr, ti)
                chi = bnd
            pi = power[i]
        if not (pi >= level):
            break
        hi += 1
    return best, max(lo, wlo), min(hi, whi)


@jit
def _isolate_simo(
    data,
    omega,
    dt,
    n_samples,
    lam0,
    n0,
    sigma,
    delta,
    tol,
    max_iter,
    pfa,
    min_points,
    zeta_max,
    merge_tol,
    max_modes,
    reweight,
    model_band,
):
    """Global SIMO isolation with the model-order check.

    ``data`` (P, F); ``lam0`` (max_modes,) starting eigenvalues (first ``n0`` used); ``sigma`` (P)
    noise floors. Returns ``(lam (max_modes,), res (P, max_modes), n, iterations, converged)``.
    """
    n_p = data.shape[0]
    n_f = data.shape[1]
    x = line_variable(omega, dt)
    dw = (omega[n_f - 1] - omega[0]) / (n_f - 1)
    w_lo = max(omega[0], dw)
    w_hi = omega[n_f - 1]
    limits = FitLimits(zeta_max, w_lo, w_hi)
    t1 = peak_threshold_kernel(n_f, pfa)
    tsum = sum_threshold_kernel(n_p, n_f, pfa)
    # work in units of each FRF's noise floor (SNR weighting of the FRFs)
    dw_data = np.empty((n_p, n_f), dtype=np.complex128)
    for j in range(n_p):
        for i in range(n_f):
            dw_data[j, i] = data[j, i] / sigma[j]
    lam = np.full(max_modes, complex(np.nan, np.nan))
    res = np.full((n_p, max_modes), complex(np.nan, np.nan))
    n = min(n0, max_modes)
    for k in range(n):
        lam[k] = lam0[k]
    fails = np.zeros(max_modes, dtype=np.int64)
    model = np.zeros((n_p, n_f), dtype=np.complex128)
    xn = np.empty((n_p, n_f), dtype=np.complex128)
    rtmp = np.empty(n_p, dtype=np.complex128)
    wts = np.ones(n_p)
    wts_all = np.ones((max_modes, n_p))
    ones = np.ones(n_p)
    masked = np.zeros(n_f, dtype=np.bool_)
    br = np.empty((max_modes, n_f))
    bi = np.empty((max_modes, n_f))
    bcr = np.empty((max_modes, n_f))
    bci = np.empty((max_modes, n_f))
    tr = np.empty(n_f)
    ti = np.empty(n_f)
    power_w = np.zeros(n_f)
    total_it = 0
    converged = False
    # starting residues: linear LS with the eigenvalues fixed, over all lines
    if n > 0:
        r0 = residues_fixed_kernel(
            dw_data, omega, lam[:n], dt, n_samples, np.ones(n_f, np.bool_), -1
        )
        for j in range(n_p):
            for k in range(n):
                res[j, k] = r0[j, k]
    for _restart in range(max_modes + 4):
        it = 0
        converged = n == 0
        band_lo = np.zeros(max_modes, dtype=np.int64)
        band_hi = np.zeros(max_modes, dtype=np.int64)
        frozen = np.zeros(max_modes, dtype=np.bool_)
        # bases of the current modes (kept up to date after every fit in the sweeps)
        for k in range(n):
            mode_basis(x, lam[k], dt, n_samples, br[k], bi[k], bcr[k], bci[k])
        for it in range(1, max_iter + 1):
            if n == 0:
                break
            # order by total SNR of each mode's contribution
            tot = np.zeros(n)
            for k in range(n):
                for j in range(n_p):
                    tot[k] += contribution_peak(omega, x, lam[k], res[j, k], dt, n_samples) ** 2
            order = np.argsort(-tot)
            change = 0.0
            for kk in range(n):
                k = order[kk]
                # isolated data only where the fit can look: +- max(20 |Re lam|, 40 lines)
                wide = max(20.0 * abs(lam[k].real), 40.0 * dw)
                wlo = nearest_line(omega, lam[k].imag - wide)
                whi = nearest_line(omega, lam[k].imag + wide) + 1
                if band_hi[k] > 0:
                    wlo = min(wlo, band_lo[k])
                    whi = max(whi, band_hi[k])
                # eq. 7 (the other modes synthesised from their cached bases) only on the lines
                # the band choice and the fit look at: the cost grows with neither the number
                # of lines nor the window width
                if (
                    frozen[k]
                    and omega[band_lo[k]] <= lam[k].imag
                    and lam[k].imag <= omega[band_hi[k] - 1]
                ):
                    lo = band_lo[k]
                    hi = band_hi[k]
                    peak = (lo + hi) // 2
                    _isolated_lines(
                        dw_data, res, br, bi, bcr, bci, n, k, lo, hi, xn, power_w, tr, ti
                    )
                elif model_band:
                    lo, hi = pole_band(omega, lam[k], delta, min_points)
                    peak = nearest_line(omega, lam[k].imag)
                    _isolated_lines(
                        dw_data, res, br, bi, bcr, bci, n, k, lo, hi, xn, power_w, tr, ti
                    )
                else:
                    peak, lo, hi = _simo_band_lazy(
                        dw_data,
                        res,
                        br,
                        bi,
                        bcr,
                        bci,
                        n,
                        k,
                        xn,
                        power_w,
                        tr,
                        ti,
                        omega,
                        lam[k],
                        dw,
                        delta,
                        wlo,
                        whi,
                    )
                band_lo[k] = lo
                band_hi[k] = hi
                if hi - lo < min_points:
                    fails[k] += 1
                    continue
                ws = omega[peak] if omega[peak] > 0.0 else dw
                prev = complex(np.nan, np.nan)
                if reweight and it <= 3:
                    # weight each FRF by its SNR for this mode (frozen after 3 sweeps so the
                    # iteration has a fixed point), so FRFs where the mode is buried in noise
                    # do not bias the shared eigenvalue
                    for j in range(n_p):
                        wts_all[k, j] = max(
                            contribution_peak(omega, x, lam[k], res[j, k], dt, n_samples), 1.0
                        )
                for j in range(n_p):
                    wts[j] = wts_all[k, j] if reweight else 1.0
                new, code = fit_single_simo(
                    xn, x, lo, hi, ws, dt, n_samples, limits, prev, wts, rtmp
                )
                if code != FIT_OK:
                    fails[k] += 1
                    continue
                ch = max(
                    abs(new.real - lam[k].real) / abs(new.real),
                    abs(new.imag - lam[k].imag) / abs(new.imag),
                )
                change = max(change, ch)
                frozen[k] = ch < FREEZE_CHANGE
                for j in range(n_p):
                    res[j, k] = rtmp[j]
                lam[k] = new
                mode_basis(x, new, dt, n_samples, br[k], bi[k], bcr[k], bci[k])
            if change < tol:
                converged = True
                break
            if it == 3:
                # early pruning: once residues have been fitted, leave the sweeps to drop
                # insignificant modes (spurious candidates of single FRFs), so the remaining
                # sweeps do not carry them
                prune = False
                for k in range(n):
                    best = 0.0
                    for j in range(n_p):
                        best = max(
                            best, contribution_peak(omega, x, lam[k], res[j, k], dt, n_samples)
                        )
                    if best * best < t1:
                        prune = True
                if prune:
                    break
        total_it += it
        changed = False
        k = 0
        while k < n:
            dup = -1
            for m in range(n):
                if m != k and normalized_distance(lam[k], lam[m]) < merge_tol:
                    dup = m
                    break
            if dup >= 0:
                pk = 0.0
                pm = 0.0
                for j in range(n_p):
                    pk += contribution_peak(omega, x, lam[k], res[j, k], dt, n_samples) ** 2
                    pm += contribution_peak(omega, x, lam[dup], res[j, dup], dt, n_samples) ** 2
                drop = dup if pm <= pk else k
                n = _remove_simo(lam, res, fails, n, drop)
                changed = True
                continue
            k += 1
        k = 0
        while k < n:
            best = 0.0
            for j in range(n_p):
                best = max(best, contribution_peak(omega, x, lam[k], res[j, k], dt, n_samples))
            if best * best < t1 or fails[k] > max_iter // 2:
                n = _remove_simo(lam, res, fails, n, k)
                changed = True
                continue
            k += 1
        if changed:
            continue
        if n >= max_modes:
            break
        # the model of all modes (only needed here, after the model-order check left the modes
        # unchanged), synthesised from the cached bases in the order of add_mode
        den = np.empty((n, n_f))
        for k in range(n):
            mode_basis(x, lam[k], dt, n_samples, br[k], bi[k], bcr[k], bci[k])
            for i in range(n_f):
                d = 1j * omega[i] - lam[k]
                den[k, i] = d.real * d.real + d.imag * d.imag
        for j in range(n_p):
            for i in range(n_f):
                tr[i] = 0.0
                ti[i] = 0.0
            for k in range(n):
                rr = res[j, k].real
                ri = res[j, k].imag
                for i in range(n_f):
                    tr[i] += (rr * br[k, i] - ri * bi[k, i]) + (rr * bcr[k, i] + ri * bci[k, i])
                    ti[i] += (rr * bi[k, i] + ri * br[k, i]) + (rr * bci[k, i] - ri * bcr[k, i])
            for i in range(n_f):
                model[j, i] = complex(tr[i], ti[i])
        added = False
        power = np.zeros(n_f)
        stat = np.zeros(n_f)
        env = np.empty(n_f)
        for j in range(n_p):
            # tolerance_envelope with the denominators computed once for all FRFs
            for i in range(n_f):
                env[i] = 0.0
            for k in range(n):
                a = tol * abs(lam[k]) * abs(res[j, k])
                for i in range(n_f):
                    env[i] += a / den[k, i]
            for i in range(n_f):
                xn[j, i] = dw_data[j, i] - model[j, i]
                power[i] += abs(xn[j, i]) ** 2
                stat[i] += abs(xn[j, i]) ** 2 / (1.0 + env[i] ** 2)
        for _try in range(8):
            best = -1.0
            peak = -1
            for i in range(n_f):
                if not masked[i] and stat[i] > best:
                    best = stat[i]
                    peak = i
            if peak < 0 or best < tsum:
                peak = band_energy_peak(stat, omega, lam, n, n_p, pfa, min_points, masked)
                if peak < 0:
                    break
            best = power[peak]
            ks = split_target(omega, lam, n, peak, masked)
            if ks >= 0:
                # split a mode with a coherent residual in its band (see _isolate_one)
                wl, wh = pole_band(omega, lam[ks], 0.31622776601683794, max(min_points, 6))
                for i in range(wl, wh):
                    masked[i] = True
                iso = xn.copy()
                for j in range(n_p):
                    add_mode(iso[j], x, lam[ks], res[j, ks], dt, n_samples, 1.0, 0, n_f)
                    wts[j] = wts_all[ks, j] if reweight else 1.0
                l2 = np.empty(2, dtype=np.complex128)
                r2 = np.empty((n_p, 2), dtype=np.complex128)
                code = fit_two(
                    iso,
                    x,
                    wl,
                    wh,
                    omega[(wl + wh) // 2],
                    dt,
                    n_samples,
                    limits,
                    wts,
                    l2,
                    r2,
                )
                if code == FIT_OK:
                    lam[ks] = l2[0]
                    lam[n] = l2[1]
                    for j in range(n_p):
                        res[j, ks] = r2[j, 0]
                        res[j, n] = r2[j, 1]
                    fails[n] = 0
                    n += 1
                    added = True
                    break
                continue
            lo, hi = band_around(power, peak, delta * delta * best)
            if hi - lo < min_points:
                for i in range(lo, hi):
                    masked[i] = True
                continue
            ws = omega[peak] if omega[peak] > 0.0 else dw
            new, code = fit_single_simo(
                xn,
                x,
                lo,
                hi,
                ws,
                dt,
                n_samples,
                limits,
                complex(np.nan, np.nan),
                ones,
                rtmp,
            )
            # no duplicate test here: a coherent residual next to a mode (two close modes fitted
            # as one) must be able to split it; true duplicates merge after the restart
            if code == FIT_OK:
                e0 = 0.0
                e1 = 0.0
                trial = np.zeros(n_f, dtype=np.complex128)
                for j in range(n_p):
                    for i in range(lo, hi):
                        trial[i] = xn[j, i]
                    add_mode(trial, x, new, rtmp[j], dt, n_samples, -1.0, lo, hi)
                    for i in range(lo, hi):
                        e0 += abs(xn[j, i]) ** 2
                        e1 += abs(trial[i]) ** 2
                if e0 - e1 < tsum:
                    code = FIT_NO_DROP
            if code != FIT_OK:
                for i in range(lo, hi):
                    masked[i] = True
                continue
            lam[n] = new
            for j in range(n_p):
                res[j, n] = rtmp[j]
            fails[n] = 0
            n += 1
            added = True
            break
        if not added:
            break
    # residues back to data units
    for j in range(n_p):
        for k in range(n):
            res[j, k] = res[j, k] * sigma[j]
    return lam, res, n, total_it, converged


# ----------------------------------------------------------------------------------------------
# residue least squares with fixed eigenvalues (eq. 9)
# ----------------------------------------------------------------------------------------------
# ----------------------------------------------------------------------------------------------
# public wrappers (validate, then call the jitted kernels)
# ----------------------------------------------------------------------------------------------
# ----------------------------------------------------------------------------------------------
# per-point diagnostics
# ----------------------------------------------------------------------------------------------
@jit
def _point_estimates(data, omega, dt, n_samples, lam, res, delta, min_points, zeta_max):
    """Per-FRF single-mode estimates of each system mode on its isolated data (eq. 7 with the
    system eigenvalues and the per-FRF residues): ``(P, K)`` complex, NaN where the fit fails."""
    n_p = data.shape[0]
    n_f = data.shape[1]
    n_k = lam.shape[0]
    x = line_variable(omega, dt)
    dw = (omega[n_f - 1] - omega[0]) / (n_f - 1)
    w_lo = max(omega[0], dw)
    w_hi = omega[n_f - 1]
    limits = FitLimits(zeta_max, w_lo, w_hi)
    out = np.full((n_p, n_k), complex(np.nan, np.nan))
    xn = np.empty(n_f, dtype=np.complex128)
    power = np.empty(n_f)
    for j in range(n_p):
        model = np.zeros(n_f, dtype=np.complex128)
        for kk in range(n_k):
            add_mode(model, x, lam[kk], res[j, kk], dt, n_samples, 1.0, 0, n_f)
        for kk in range(n_k):
            for i in range(n_f):
                xn[i] = data[j, i] - model[i]
            add_mode(xn, x, lam[kk], res[j, kk], dt, n_samples, 1.0, 0, n_f)
            for i in range(n_f):
                power[i] = abs(xn[i]) ** 2
            peak = local_peak(power, omega, lam[kk], dw)
            lo, hi = band_around(power, peak, delta * delta * power[peak])
            if hi - lo < min_points:
                continue
            ws = omega[peak] if omega[peak] > 0.0 else dw
            new, r, code = fit_single(
                xn, x, lo, hi, ws, dt, n_samples, limits, complex(np.nan, np.nan)
            )
            if code == FIT_OK:
                out[j, kk] = new
    return out
