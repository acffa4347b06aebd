"""Global SIMO Isolation Phase (Allen & Ginsberg): one eigenvalue per mode from all FRFs at once,
with the model-order check.

The sweep, merge, prune and model-order logic follow the per-FRF :mod:`.isolate`; here each fit
is the SIMO single-mode fit over all FRFs, the data is in units of each FRF's noise floor (SNR
weighting of the FRFs), and eq. 7 is evaluated only on the lines a fit looks at, from cached
real/imaginary bases of every mode. The two variants are kept apart where their arithmetic
differs (sums of squares over FRFs, lazily isolated lines), so each stays bit-identical to its
reference results.

Settings travel as an :class:`~.isolate.IsolateParams` record, the modes as a
:class:`~.isolate.ModeSet` and the per-call arrays as a :class:`SimoWork` record. Checked
wrapper: :func:`isolate_simo`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.isolate import (
    FREEZE_CHANGE,
    SPLIT_DELTA,
    IsolateParams,
    ModeSet,
    check_frfs,
    check_model,
    check_params,
    fit_limits,
    relative_change,
)
from ami_xr.kernels.modal_basis import (
    Grid,
    add_mode,
    contribution_peak,
    line_variable,
    mode_basis,
    nearest_line,
)
from ami_xr.kernels.noise import (
    band_around,
    band_energy_peak,
    normalized_distance,
    peak_threshold_kernel,
    pole_band,
    split_target,
    sum_threshold_kernel,
)
from ami_xr.kernels.residues import residues_fixed_kernel
from ami_xr.kernels.single_mode import FIT_NO_DROP, FIT_OK, fit_single_simo
from ami_xr.kernels.two_mode import fit_two

STOP_FRACTION = 0.1
"""A sweep's step of an eigenvalue smaller than this fraction of its standard error counts as
converged (the change is far below what the data can resolve)."""

CYCLE_RATIO = 0.25
"""A step back to within this fraction of the step of the eigenvalue two sweeps before is a
two-state cycle (the mode then takes the mean of the two states and keeps its band)."""


class SimoWork(NamedTuple):
    """Arrays of one SIMO isolation, allocated once and reused by every sweep."""

    data: np.ndarray
    """(P, F) FRFs divided by their noise floors."""
    xn: np.ndarray
    """(P, F) isolated data (eq. 7) on the lines last computed."""
    rtmp: np.ndarray
    """(P,) residues of the last SIMO fit."""
    wts: np.ndarray
    """(P,) FRF weights of the current fit."""
    wts_all: np.ndarray
    """(max_modes, P) SNR weights of each mode (frozen after 3 sweeps)."""
    ones: np.ndarray
    """(P,) unit weights."""
    br: np.ndarray
    """(max_modes, F) Re b(lam) of every mode; ``bi``, ``bcr``, ``bci`` likewise."""
    bi: np.ndarray
    bcr: np.ndarray
    bci: np.ndarray
    tr: np.ndarray
    """(F,) scratch line (real part); ``ti`` the imaginary part."""
    ti: np.ndarray
    power: np.ndarray
    """(F,) SNR-weighted power ``sum_j |xn_j|^2`` on the lines last computed."""
    back: np.ndarray
    """(max_modes,) each mode's eigenvalue before its last update (two-state cycle test)."""
    pinned: np.ndarray
    """(max_modes,) bool: modes kept at their model-order-check fit (not re-fitted)."""


@jit
def _remove_simo(modes, n, k, pinned):
    lam, res, fails = modes
    for i in range(k, n - 1):
        pinned[i] = pinned[i + 1]
    pinned[n - 1] = False
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
def _isolated_lines(work, res, n, k, a, b):
    """eq. 7 on lines ``a..b-1`` of every FRF: ``xn = data - sum_{m != k}`` contributions and
    ``power[i] = sum_j |xn[j, i]|^2``. The products are numba's complex product written out
    (``(ac - bd) + i (ad + bc)``) in the order of ``add_mode``, so the values are the same."""
    dw_data, xn, power, tr, ti = work.data, work.xn, work.power, work.tr, work.ti
    br, bi, bcr, bci = work.br, work.bi, work.bcr, work.bci
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
def _simo_band_lazy(work, res, n, k, omega, lam, dw, delta, window):
    """Fit band of mode ``k`` (eigenvalue ``lam``) within ``window = (wlo, whi)``: the largest
    SNR-weighted power near the mode and the contiguous lines around it with power ``>= delta^2``
    times that peak. The isolated data is computed only on the lines looked at (the peak search
    range and the band grown from the peak). Returns ``(peak, lo, hi)``."""
    wlo, whi = window
    power = work.power
    half = max(2.0 * abs(lam.real), 2.0 * dw)
    c = nearest_line(omega, lam.imag)
    plo = nearest_line(omega, lam.imag - half)
    phi = nearest_line(omega, lam.imag + half)
    clo = max(min(plo, c), wlo)
    chi = min(max(phi, c) + 1, whi)
    if chi < clo:
        chi = clo
    _isolated_lines(work, res, n, k, clo, chi)
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
                _isolated_lines(work, res, n, k, a, clo)
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
                _isolated_lines(work, res, n, k, chi, bnd)
                chi = bnd
            pi = power[i]
        if not (pi >= level):
            break
        hi += 1
    return best, max(lo, wlo), min(hi, whi)


@jit
def _max_contribution(grid, lam, res, k):
    """Largest contribution peak of mode ``k`` over the FRFs."""
    omega, x, dt, n_samples = grid
    best = 0.0
    for j in range(res.shape[0]):
        best = max(best, contribution_peak(omega, x, lam[k], res[j, k], dt, n_samples))
    return best


@jit
def _eigenvalue_se(omega, x, lam, res, lo, hi, dt, n_samples):
    """Standard error (rad/s) of a SIMO single-mode eigenvalue fitted on lines ``lo..hi-1`` of
    data in noise units, with residues ``res`` (P,): ``1 / sqrt(J)`` with the Fisher information
    ``J = sum_j c_j^2 sum_i (Re lam)^2 / |i omega_i - lam|^4`` (``c_j`` the mode's peak
    contribution in FRF ``j``; the residues taken as known, so a slight under-estimate)."""
    cs = 0.0
    for j in range(res.shape[0]):
        cs += contribution_peak(omega, x, lam, res[j], dt, n_samples) ** 2
    a = lam.real * lam.real
    g = 0.0
    for i in range(lo, hi):
        d = 1j * omega[i] - lam
        q = d.real * d.real + d.imag * d.imag
        g += a / (q * q)
    info = cs * g
    return 1.0 / np.sqrt(info) if info > 0.0 else np.inf


@jit
def _near(lam, n, target, merge_tol):
    """Whether one of the first ``n`` modes lies within ``merge_tol`` of ``target``."""
    for k in range(n):
        if normalized_distance(lam[k], target) < merge_tol:
            return True
    return False


@jit
def _all_failed(failed, n, it):
    for k in range(n):
        if failed[k] < it:
            return False
    return True


@jit
def _mark_failed(fails, fit_failed, n, it, max_iter):
    """A mode whose single-mode fit failed (``fit_failed``: the fit ran and returned an error
    code) in every one of (at least 2) sweeps gets the failure count that the merge-and-prune
    step drops (the old rule reached it only after ``max_iter / 2`` sweeps, which the statistical
    stopping rule no longer runs).

    A mode whose band was too narrow to fit (fewer than ``min_points`` lines) is not counted
    here: a lightly damped mode on a coarse grid spans only 1-3 lines in every sweep (measured
    FRFs: ``measurement.uff`` loses 4 of its 6 modes when it is), it keeps its estimate from
    the subtraction or the order check, and the significance test of the merge-and-prune step
    still removes it when it is not above the noise floor."""
    if it < 2:
        return
    for k in range(n):
        if fit_failed[k] >= it:
            fails[k] = max(fails[k], max_iter // 2 + 1)


@jit
def _simo_sweeps(grid, params, modes, n, work, t1):
    """Isolation sweeps (SIMO fits) until every eigenvalue has settled, two modes collide, or
    the early pruning after 3 sweeps finds an insignificant mode.

    Stopping rule: a mode has settled in a sweep when its step ``|lam_new - lam_old|`` is below
    ``STOP_FRACTION`` of its standard error (:func:`_eigenvalue_se`, from the fit's residues and
    band) or its Re and Im change less than ``tol`` (relative); the sweeps have converged when
    every mode has settled in the same sweep. The standard error term makes the rule reachable
    at any noise level: close modes converge only linearly (each isolation sees the other's
    error), and asking for a relative change of ``tol`` there costs tens of sweeps that move the
    eigenvalues by a small fraction of their uncertainty.
    A mode that steps back to where it was two sweeps before (``|lam_new - lam_back| <
    CYCLE_RATIO |lam_new - lam_old|``) is in a two-state cycle (its fit band switching between
    two data-defined choices): it takes the mean of the two states and keeps its band, which
    makes the iteration map continuous so the cycle dies out.
    Modes flagged in ``work.pinned`` are not re-fitted (their eq.-7 contribution is kept).
    Returns ``(iterations, converged)``."""
    omega, x, dt, n_samples = grid
    lam, res, fails = modes
    delta = params.delta
    min_points = params.min_points
    reweight = params.reweight
    n_p = res.shape[0]
    limits, dw = fit_limits(omega, params.zeta_max)
    max_modes = lam.shape[0]
    it = 0
    converged = n == 0
    band_lo = np.zeros(max_modes, dtype=np.int64)
    band_hi = np.zeros(max_modes, dtype=np.int64)
    frozen = np.zeros(max_modes, dtype=np.bool_)
    back = work.back
    # sweeps in which a mode could not be updated (band too narrow, or the fit failed), and
    # those in which its fit ran and failed (only these prune at once, see _mark_failed)
    failed = np.zeros(max_modes, dtype=np.int64)
    fit_failed = np.zeros(max_modes, dtype=np.int64)
    # bases of the current modes (kept up to date after every fit in the sweeps)
    for k in range(n):
        mode_basis(x, lam[k], dt, n_samples, work.br[k], work.bi[k], work.bcr[k], work.bci[k])
        back[k] = complex(np.nan, np.nan)
    for it in range(1, params.max_iter + 1):
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
            if work.pinned[k]:
                continue
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
                _isolated_lines(work, res, n, k, lo, hi)
            else:
                peak, lo, hi = _simo_band_lazy(
                    work, res, n, k, omega, lam[k], dw, delta, (wlo, whi)
                )
            band_lo[k] = lo
            band_hi[k] = hi
            if hi - lo < min_points:
                fails[k] += 1
                failed[k] += 1
                continue
            ws = omega[peak] if omega[peak] > 0.0 else dw
            prev = complex(np.nan, np.nan)
            if reweight and it <= 3:
                # weight each FRF by its SNR for this mode (frozen after 3 sweeps so the
                # iteration has a fixed point), so FRFs where the mode is buried in noise
                # do not bias the shared eigenvalue
                for j in range(n_p):
                    work.wts_all[k, j] = max(
                        contribution_peak(omega, x, lam[k], res[j, k], dt, n_samples), 1.0
                    )
            for j in range(n_p):
                work.wts[j] = work.wts_all[k, j] if reweight else 1.0
            new, code = fit_single_simo(
                work.xn, grid, lo, hi, ws, limits, prev, work.wts, work.rtmp
            )
            if code != FIT_OK:
                fails[k] += 1
                failed[k] += 1
                fit_failed[k] += 1
                continue
            ch = relative_change(new, lam[k])
            step = abs(new - lam[k])
            cycle = abs(new - back[k]) < CYCLE_RATIO * step
            se = _eigenvalue_se(omega, x, new, work.rtmp, lo, hi, dt, n_samples)
            # settled: a relative change below tol, or a step below a fraction of the
            # standard error (score < 1)
            change = max(change, min(ch / params.tol, step / (STOP_FRACTION * se)))
            frozen[k] = ch < FREEZE_CHANGE or cycle
            if cycle:
                new = 0.5 * (new + lam[k])
            back[k] = lam[k]
            for j in range(n_p):
                res[j, k] = work.rtmp[j]
            lam[k] = new
            mode_basis(x, new, dt, n_samples, work.br[k], work.bi[k], work.bcr[k], work.bci[k])
        if change < 1.0:
            converged = True
            break
        if it >= 2 and _all_failed(failed, n, it):
            # no mode can be fitted any more: a sweep would change nothing
            break
        if it == 3:
            # early pruning: once residues have been fitted, leave the sweeps to drop
            # insignificant modes (spurious candidates of single FRFs), so the remaining
            # sweeps do not carry them
            prune = False
            for k in range(n):
                best = _max_contribution(grid, lam, res, k)
                if best * best < t1:
                    prune = True
            if prune:
                break
    _mark_failed(fails, fit_failed, n, it, params.max_iter)
    return it, converged


@jit
def _simo_merge_prune(grid, params, modes, n, t1, pinned):
    """Duplicates keep the mode with the larger total SNR; modes not above the noise floor in any
    FRF, or that failed too often, are removed. Returns ``(n, changed)``."""
    omega, x, dt, n_samples = grid
    lam, res, fails = modes
    n_p = res.shape[0]
    changed = False
    k = 0
    while k < n:
        dup = -1
        for m in range(n):
            if m != k and normalized_distance(lam[k], lam[m]) < params.merge_tol:
                dup = m
                break
        if dup >= 0:
            pk = 0.0
            pm = 0.0
            for j in range(n_p):
                pk += contribution_peak(omega, x, lam[k], res[j, k], dt, n_samples) ** 2
                pm += contribution_peak(omega, x, lam[dup], res[j, dup], dt, n_samples) ** 2
            drop = dup if pm <= pk else k
            n = _remove_simo(modes, n, drop, pinned)
            changed = True
            continue
        k += 1
    k = 0
    while k < n:
        best = _max_contribution(grid, lam, res, k)
        if best * best < t1 or fails[k] > params.max_iter // 2:
            n = _remove_simo(modes, n, k, pinned)
            changed = True
            continue
        k += 1
    return n, changed


@jit
def _simo_residual(grid, tol, modes, n, work):
    """The residual of all modes in every FRF (into ``work.xn``), its SNR-weighted power and the
    statistic ``sum_j |r_j|^2 / (1 + env_j^2)`` with the tolerance envelope of each FRF.
    Returns ``(power, stat)``, both (F,)."""
    omega, x, dt, n_samples = grid
    lam, res, _ = modes
    br, bi, bcr, bci, tr, ti = work.br, work.bi, work.bcr, work.bci, work.tr, work.ti
    n_p = res.shape[0]
    n_f = omega.shape[0]
    # the model of all modes, synthesised from the cached bases in the order of add_mode
    model = np.zeros((n_p, n_f), dtype=np.complex128)
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
            work.xn[j, i] = work.data[j, i] - model[j, i]
            power[i] += abs(work.xn[j, i]) ** 2
            stat[i] += abs(work.xn[j, i]) ** 2 / (1.0 + env[i] ** 2)
    return power, stat


@jit
def _simo_split(grid, params, modes, n, ks, work, masked, limits):
    """Split mode ``ks`` (a coherent residual in its band) by a two-mode SIMO fit over
    ``+- 3 |Re lam|``; the window is masked (each is tried once). Returns ``added``."""
    omega, x, dt, n_samples = grid
    lam, res, fails = modes
    n_p = res.shape[0]
    n_f = omega.shape[0]
    wl, wh = pole_band(omega, lam[ks], SPLIT_DELTA, max(params.min_points, 6))
    for i in range(wl, wh):
        masked[i] = True
    iso = work.xn.copy()
    for j in range(n_p):
        add_mode(iso[j], x, lam[ks], res[j, ks], dt, n_samples, 1.0, 0, n_f)
        work.wts[j] = work.wts_all[ks, j] if params.reweight else 1.0
    l2 = np.empty(2, dtype=np.complex128)
    r2 = np.empty((n_p, 2), dtype=np.complex128)
    ws = omega[(wl + wh) // 2]
    code = fit_two(iso, grid, wl, wh, ws, limits, work.wts, l2, r2)
    if code != FIT_OK:
        return False
    lam[ks] = l2[0]
    lam[n] = l2[1]
    for j in range(n_p):
        res[j, ks] = r2[j, 0]
        res[j, n] = r2[j, 1]
    fails[n] = 0
    return True


@jit
def _simo_order_check(grid, params, modes, n, work, masked, tsum):
    """Model-order check of SIMO isolation (see the per-FRF ``_order_check``): a significant
    SNR-weighted peak of the residual adds a mode, a coherent residual in a mode's band splits
    it. Returns ``(n, added, ks)``: ``ks`` the mode that was split, -1 for an added mode."""
    omega, x, dt, n_samples = grid
    lam, res, fails = modes
    n_p = res.shape[0]
    n_f = omega.shape[0]
    limits, dw = fit_limits(omega, params.zeta_max)
    xn = work.xn
    power, stat = _simo_residual(grid, params.tol, modes, n, work)
    for _try in range(8):
        best = -1.0
        peak = -1
        for i in range(n_f):
            if not masked[i] and stat[i] > best:
                best = stat[i]
                peak = i
        if peak < 0 or best < tsum:
            peak = band_energy_peak(stat, omega, lam, n, n_p, params.pfa, params.min_points, masked)
            if peak < 0:
                break
        best = power[peak]
        ks = split_target(omega, lam, n, peak, masked)
        if ks >= 0:
            if _simo_split(grid, params, modes, n, ks, work, masked, limits):
                return n + 1, True, ks
            continue
        lo, hi = band_around(power, peak, params.delta * params.delta * best)
        if hi - lo < params.min_points:
            for i in range(lo, hi):
                masked[i] = True
            continue
        ws = omega[peak] if omega[peak] > 0.0 else dw
        nan = complex(np.nan, np.nan)
        new, code = fit_single_simo(xn, grid, lo, hi, ws, limits, nan, work.ones, work.rtmp)
        # no duplicate test here: a coherent residual next to a mode (two close modes fitted
        # as one) must be able to split it; true duplicates merge after the restart
        if code == FIT_OK:
            e0 = 0.0
            e1 = 0.0
            trial = np.zeros(n_f, dtype=np.complex128)
            for j in range(n_p):
                for i in range(lo, hi):
                    trial[i] = xn[j, i]
                add_mode(trial, x, new, work.rtmp[j], dt, n_samples, -1.0, lo, hi)
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
            res[j, n] = work.rtmp[j]
        fails[n] = 0
        return n + 1, True, -1
    return n, False, -1


@jit
def _isolate_simo(data, omega, dt, n_samples, lam0, n0, sigma, params):
    """Global SIMO isolation with the model-order check.

    ``data`` (P, F); ``lam0`` (max_modes,) starting eigenvalues (first ``n0`` used); ``sigma`` (P)
    noise floors. Returns ``(lam (max_modes,), res (P, max_modes), n, iterations, converged)``:
    ``iterations`` the sweeps of all restarts, ``converged`` that the last sweeps met the stopping
    rule of :func:`_simo_sweeps` and the model-order check ended (no change pending).

    A restart follows every change of the model (merge, prune, added or split mode). A mode the
    order check adds and then loses (merged into a neighbour the sweeps ran it into, or pruned after
    its fits failed) is, when the check adds it again, kept at its order-check fit (pinned, not
    re-fitted) and the order check ends after the next sweeps: otherwise the loop cycles until
    the restart budget is spent.
    """
    n_p = data.shape[0]
    n_f = data.shape[1]
    max_modes = params.max_modes
    grid = Grid(omega, line_variable(omega, dt), dt, n_samples)
    t1 = peak_threshold_kernel(n_f, params.pfa)
    tsum = sum_threshold_kernel(n_p, n_f, params.pfa)
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
    modes = ModeSet(lam, res, np.zeros(max_modes, dtype=np.int64))
    work = SimoWork(
        dw_data,
        np.empty((n_p, n_f), dtype=np.complex128),
        np.empty(n_p, dtype=np.complex128),
        np.ones(n_p),
        np.ones((max_modes, n_p)),
        np.ones(n_p),
        np.empty((max_modes, n_f)),
        np.empty((max_modes, n_f)),
        np.empty((max_modes, n_f)),
        np.empty((max_modes, n_f)),
        np.empty(n_f),
        np.empty(n_f),
        np.zeros(n_f),
        np.full(max_modes, complex(np.nan, np.nan)),
        np.zeros(max_modes, dtype=np.bool_),
    )
    masked = np.zeros(n_f, dtype=np.bool_)
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
    tried = np.empty(max_modes + 4, dtype=np.complex128)
    n_tried = 0
    finished = False
    last = False
    for _restart in range(max_modes + 4):
        it, converged = _simo_sweeps(grid, params, modes, n, work, t1)
        total_it += it
        n, changed = _simo_merge_prune(grid, params, modes, n, t1, work.pinned)
        if changed:
            continue
        if n >= max_modes or last:
            finished = True
            break
        n_before = n
        n, grew, ks = _simo_order_check(grid, params, modes, n, work, masked, tsum)
        if not grew:
            finished = True
            break
        if ks < 0:
            # a mode the check added before, and lost since (the sweeps ran it into a
            # neighbour and the merge dropped it, or its fits failed and it was pruned: a
            # weak mode beside a strong one takes up the strong one's residual), is added
            # again: it is pinned at its fit (not re-fitted), and the order check ends after
            # the next sweeps (the residual next to a pinned mode holds the error of its fit,
            # not new modes; the refinement fits all modes jointly)
            for t in range(n_tried):
                if normalized_distance(lam[n_before], tried[t]) < params.merge_tol and not (
                    _near(lam, n_before, tried[t], params.merge_tol)
                ):
                    work.pinned[n_before] = True
                    last = True
                    break
            if n_tried < tried.shape[0]:
                tried[n_tried] = lam[n_before]
                n_tried += 1
    # the restart budget ran out with a change pending: the last model was not isolated
    converged = converged and finished
    # residues back to data units
    for j in range(n_p):
        for k in range(n):
            res[j, k] = res[j, k] * sigma[j]
    return lam, res, n, total_it, converged


def isolate_simo(
    data: np.ndarray,
    omega: np.ndarray,
    dt: float | None,
    n_samples: int | None,
    lam0: np.ndarray,
    n0: int,
    sigma: np.ndarray,
    params: IsolateParams,
) -> tuple[np.ndarray, np.ndarray, int, int, bool]:
    """Global SIMO isolation with the model-order check.

    Parameters
    ----------
    data : ndarray of complex, shape (P, F)
        FRFs.
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    dt, n_samples : float or None, int or None
        Discrete model; None (or 0) for the continuous one.
    lam0 : ndarray of complex, shape (S,)
        Starting eigenvalues; the first ``n0`` are used.
    n0 : int
        Number of starting modes.
    sigma : ndarray of float, shape (P,)
        Noise floor of each FRF.
    params : IsolateParams
        Settings.

    Returns
    -------
    lam : ndarray of complex, shape (max_modes,)
    res : ndarray of complex, shape (P, max_modes)
        NaN-padded.
    n_modes, iterations : int
    converged : bool
    """
    data, omega = check_frfs(data, omega)
    dt, n = check_model(dt, n_samples)
    check_params(params)
    n_p = data.shape[0]
    lam0 = np.ascontiguousarray(lam0, dtype=np.complex128)
    if lam0.ndim != 1:
        raise AmiXrValueError(f"lam0: expected a 1-D array of eigenvalues, got {lam0.shape}")
    if int(n0) != n0 or not 0 <= n0 <= lam0.size:
        raise AmiXrValueError(f"n0: expected a count in 0..{lam0.size}, got {n0!r}")
    sigma = np.ascontiguousarray(sigma, dtype=np.float64)
    if sigma.shape != (n_p,):
        raise AmiXrValueError(f"sigma: expected shape ({n_p},), got {sigma.shape}")
    return _isolate_simo(data, omega, dt, n, lam0, n0, sigma, params)
