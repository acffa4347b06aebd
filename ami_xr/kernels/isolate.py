"""Isolation Phase of the AMI (eq. 7) with the model-order check, one FRF at a time, and the
per-FRF single-mode estimates of given system modes.

Each sweep takes the modes in order of decreasing contribution, isolates one mode's data by
subtracting all the others (eq. 7), re-fits it on the band around its peak and replaces it, until
every eigenvalue's real and imaginary parts change less than ``tol`` (relative). After the sweeps,
duplicates merge and insignificant modes are dropped; when nothing changed, the model-order check
looks at the residual for a significant peak (or a coherent residual inside a mode's band, which
splits that mode in two) and restarts the sweeps with one mode more.

Settings travel as an :class:`IsolateParams` record (shared with :mod:`.isolate_simo`), the
current modes as a :class:`ModeSet` (arrays updated in place). Checked wrappers:
:func:`isolate_batch`, :func:`point_estimates`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.modal_basis import (
    Grid,
    add_mode,
    as_dt,
    checked_omega,
    contribution_peak,
    line_variable,
    tolerance_envelope,
)
from ami_xr.kernels.noise import (
    band_around,
    band_energy_peak,
    local_peak,
    normalized_distance,
    peak_threshold_kernel,
    pole_band,
    split_target,
)
from ami_xr.kernels.single_mode import (
    FIT_NO_DROP,
    FIT_OK,
    FitLimits,
    band_energy_drop,
    fit_single,
)
from ami_xr.kernels.two_mode import fit_two

FREEZE_CHANGE = 1e-3
"""A mode's fit band is kept fixed once its eigenvalue changes less than this (relative)."""

SPLIT_DELTA = 0.31622776601683794
"""``delta`` of the ``+- 3 |Re lam|`` window (``sqrt(1/delta^2 - 1) = 3``) of a mode split."""


class IsolateParams(NamedTuple):
    """Settings of the Isolation Phase kernels (see :func:`ami_xr.isolate` for their meaning)."""

    delta: float
    """Fit band: contiguous lines with ``|Y| >= delta`` times the peak."""
    tol: float
    """Convergence: relative change of Re and Im of every eigenvalue in a sweep (SIMO: or a step
    below ``STOP_FRACTION`` of the eigenvalue's standard error, see :mod:`.isolate_simo`)."""
    max_iter: int
    """Most sweeps per restart."""
    pfa: float
    """False-alarm probability of the model-order check."""
    min_points: int
    """Fewest lines in a fit band."""
    zeta_max: float
    """Largest accepted damping ratio."""
    merge_tol: float
    """Modes closer than this many half-power bandwidths merge."""
    max_modes: int
    """Most modes (the length of the output slots)."""
    reweight: bool
    """SIMO only: weight each FRF by its SNR for the mode (frozen after 3 sweeps)."""


class ModeSet(NamedTuple):
    """The modes being isolated; arrays of ``max_modes`` slots, updated in place."""

    lam: np.ndarray
    """Eigenvalues (max_modes,) complex, NaN past the current count."""
    res: np.ndarray
    """Residues: (max_modes,) per FRF, (P, max_modes) in SIMO isolation."""
    fails: np.ndarray
    """Failed fits of each mode (max_modes,) int."""


@jit
def fit_limits(omega, zeta_max):
    """Jitted, unchecked: the :class:`FitLimits` of the Isolation Phase and the line spacing
    ``dw``: natural frequencies between ``max(omega[0], dw)`` and ``omega[-1]``."""
    n_f = omega.shape[0]
    dw = (omega[n_f - 1] - omega[0]) / (n_f - 1)
    w_lo = max(omega[0], dw)
    w_hi = omega[n_f - 1]
    return FitLimits(zeta_max, w_lo, w_hi), dw


@jit
def relative_change(new, old):
    """Jitted, unchecked: ``max(|dRe| / |Re new|, |dIm| / |Im new|)`` of an eigenvalue update."""
    return max(
        abs(new.real - old.real) / abs(new.real),
        abs(new.imag - old.imag) / abs(new.imag),
    )


@jit
def _order_by_contribution(omega, x, lam, res, n, dt, n_samples):
    peaks = np.empty(n)
    for k in range(n):
        peaks[k] = contribution_peak(omega, x, lam[k], res[k], dt, n_samples)
    return np.argsort(-peaks)


@jit
def _isolate_sweeps(data, grid, params, modes, n, model):
    """Isolation sweeps until every eigenvalue's Re and Im change less than ``tol`` (relative).

    ``model`` (F) holds the current sum of all modes and is kept up to date.
    Returns ``(iterations, converged)``.
    """
    omega, x, dt, n_samples = grid
    lam, res, fails = modes
    delta = params.delta
    min_points = params.min_points
    n_f = data.shape[0]
    limits, dw = fit_limits(omega, params.zeta_max)
    xn = np.empty(n_f, dtype=np.complex128)
    power = np.empty(n_f)
    band_lo = np.zeros(n, dtype=np.int64)
    band_hi = np.zeros(n, dtype=np.int64)
    frozen = np.zeros(n, dtype=np.bool_)
    it = 0
    order = _order_by_contribution(omega, x, lam, res, n, dt, n_samples)
    for it in range(1, params.max_iter + 1):
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
            new, r, code = fit_single(xn, grid, lo, hi, ws, limits, prev)
            if code != FIT_OK:
                fails[k] += 1
                continue
            ch = relative_change(new, lam[k])
            change = max(change, ch)
            frozen[k] = ch < FREEZE_CHANGE
            add_mode(model, x, lam[k], res[k], dt, n_samples, -1.0, 0, n_f)
            lam[k] = new
            res[k] = r
            add_mode(model, x, new, r, dt, n_samples, 1.0, 0, n_f)
        if change < params.tol:
            return it, True
    return it, False


@jit
def _remove_mode(modes, n, k):
    lam, res, fails = modes
    for i in range(k, n - 1):
        lam[i] = lam[i + 1]
        res[i] = res[i + 1]
        fails[i] = fails[i + 1]
    lam[n - 1] = complex(np.nan, np.nan)
    res[n - 1] = complex(np.nan, np.nan)
    fails[n - 1] = 0
    return n - 1


@jit
def _merge_and_prune(grid, params, modes, n, sigma, t):
    """Duplicates (closer than ``merge_tol`` bandwidths) keep the stronger mode; modes whose
    contribution is not above the noise floor, or that failed too often, are removed.
    Returns ``(n, changed)``."""
    omega, x, dt, n_samples = grid
    lam, res, fails = modes
    changed = False
    k = 0
    while k < n:
        dup = -1
        for m in range(n):
            if m != k and normalized_distance(lam[k], lam[m]) < params.merge_tol:
                dup = m
                break
        if dup >= 0:
            pk = contribution_peak(omega, x, lam[k], res[k], dt, n_samples)
            pm = contribution_peak(omega, x, lam[dup], res[dup], dt, n_samples)
            drop = dup if pm <= pk else k
            n = _remove_mode(modes, n, drop)
            changed = True
            continue
        k += 1
    k = 0
    while k < n:
        pk = contribution_peak(omega, x, lam[k], res[k], dt, n_samples)
        if pk * pk / sigma**2 < t or fails[k] > params.max_iter // 2:
            n = _remove_mode(modes, n, k)
            changed = True
            continue
        k += 1
    return n, changed


@jit
def _split_mode(data, model, grid, limits, modes, n, ks, masked, min_points):
    """Fit two modes to mode ``ks``'s isolated data over ``+- 3 |Re lam|``; if both are
    physical they replace it. The window is masked (each is tried once). Returns ``added``."""
    omega, x, dt, n_samples = grid
    lam, res, fails = modes
    n_f = data.shape[0]
    wl, wh = pole_band(omega, lam[ks], SPLIT_DELTA, max(min_points, 6))
    for i in range(wl, wh):
        masked[i] = True
    iso = np.empty((1, n_f), dtype=np.complex128)
    for i in range(n_f):
        iso[0, i] = data[i] - model[i]
    add_mode(iso[0], x, lam[ks], res[ks], dt, n_samples, 1.0, 0, n_f)
    l2 = np.empty(2, dtype=np.complex128)
    r2 = np.empty((1, 2), dtype=np.complex128)
    ws = omega[(wl + wh) // 2]
    code = fit_two(iso, grid, wl, wh, ws, limits, np.ones(1), l2, r2)
    if code != FIT_OK:
        return False
    lam[ks] = l2[0]
    res[ks] = r2[0, 0]
    lam[n] = l2[1]
    res[n] = r2[0, 1]
    fails[n] = 0
    return True


@jit
def _order_check(data, model, grid, params, modes, n, sigma, masked):
    """Model-order check: a significant, physical peak left in the residual adds a mode (or a
    coherent residual inside a mode's band splits it). Returns ``(n, added)``."""
    omega, x, dt, n_samples = grid
    lam, res, fails = modes
    delta = params.delta
    min_points = params.min_points
    n_f = data.shape[0]
    t = peak_threshold_kernel(n_f, params.pfa)
    limits, dw = fit_limits(omega, params.zeta_max)
    power = np.empty(n_f)
    env = tolerance_envelope(omega, lam, res, n, params.tol)
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
            peak = band_energy_peak(stat, omega, lam, n, 1, params.pfa, min_points, masked)
            if peak < 0:
                break
        best = power[peak]
        ks = split_target(omega, lam, n, peak, masked)
        if ks >= 0:
            # a coherent residual inside a mode's band: two close modes were probably fitted
            # as one
            if _split_mode(data, model, grid, limits, modes, n, ks, masked, min_points):
                return n + 1, True
            continue
        lo, hi = band_around(power, peak, delta * delta * best)
        if hi - lo < min_points:
            for i in range(lo, hi):
                masked[i] = True
            continue
        y = data - model
        ws = omega[peak] if omega[peak] > 0.0 else dw
        new, r, code = fit_single(y, grid, lo, hi, ws, limits, complex(np.nan, np.nan))
        # no duplicate test here: a coherent residual next to a mode (two close modes fitted
        # as one) must be able to split it; true duplicates merge after the restart
        if code == FIT_OK:
            drop = band_energy_drop(y, grid, new, r, power, lo, hi)
            if drop / sigma**2 < t:
                code = FIT_NO_DROP
        if code != FIT_OK:
            for i in range(lo, hi):
                masked[i] = True
            continue
        lam[n] = new
        res[n] = r
        fails[n] = 0
        return n + 1, True
    return n, False


@jit
def _isolate_one(data, grid, params, modes, n, sigma):
    """Isolation Phase with the model-order check on one FRF (``modes`` updated in place).
    Returns ``(n_modes, iterations, converged)``."""
    x, dt, n_samples = grid.x, grid.dt, grid.n_samples
    lam, res, _ = modes
    max_modes = params.max_modes
    n_f = data.shape[0]
    t = peak_threshold_kernel(n_f, params.pfa)
    total_it = 0
    converged = False
    model = np.zeros(n_f, dtype=np.complex128)
    masked = np.zeros(n_f, dtype=np.bool_)
    for _restart in range(max_modes + 4):
        for i in range(n_f):
            model[i] = 0.0
        for k in range(n):
            add_mode(model, x, lam[k], res[k], dt, n_samples, 1.0, 0, n_f)
        it, converged = _isolate_sweeps(data, grid, params, modes, n, model)
        total_it += it
        n, changed = _merge_and_prune(grid, params, modes, n, sigma, t)
        if changed:
            continue
        if n >= max_modes:
            break
        n, added = _order_check(data, model, grid, params, modes, n, sigma, masked)
        if not added:
            break
    return n, total_it, converged


@jit
def _isolate_batch(data, omega, dt, n_samples, lam0, res0, n0, sigma, params):
    """:func:`_isolate_one` on every row of ``data`` (P, F)."""
    n_p = data.shape[0]
    max_modes = params.max_modes
    grid = Grid(omega, line_variable(omega, dt), dt, n_samples)
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
        modes = ModeSet(lam[j], res[j], np.zeros(max_modes, dtype=np.int64))
        nn, it, c = _isolate_one(data[j], grid, params, modes, n, sigma[j])
        n_modes[j] = nn
        iters[j] = it
        conv[j] = c
    return lam, res, n_modes, iters, conv


@jit
def _point_estimates(data, grid, lam, res, delta, min_points, zeta_max):
    """Per-FRF single-mode estimates of each system mode on its isolated data (eq. 7 with the
    system eigenvalues and the per-FRF residues): ``(P, K)`` complex, NaN where the fit fails."""
    omega, x, dt, n_samples = grid
    n_p = data.shape[0]
    n_f = data.shape[1]
    n_k = lam.shape[0]
    limits, dw = fit_limits(omega, zeta_max)
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
            new, r, code = fit_single(xn, grid, lo, hi, ws, limits, complex(np.nan, np.nan))
            if code == FIT_OK:
                out[j, kk] = new
    return out


# ----------------------------------------------------------------------------------------------
# checked wrappers
# ----------------------------------------------------------------------------------------------
def check_model(dt: float | None, n_samples: int | None) -> tuple[float, int]:
    """``(dt, n_samples)`` as the kernels take them, checked non-negative."""
    dt = as_dt(dt)
    n = int(n_samples or 0)
    if dt < 0.0 or not np.isfinite(dt) or n < 0:
        raise AmiXrValueError(f"dt, n_samples: expected >= 0 or None, got {dt!r}, {n_samples!r}")
    return dt, n


def check_params(params: IsolateParams) -> None:
    """Raise unless ``params`` is an :class:`IsolateParams` with positive counts."""
    if not isinstance(params, IsolateParams):
        raise AmiXrValueError(
            f"params: expected an IsolateParams record, got {type(params).__name__}"
        )
    if int(params.max_modes) < 1 or int(params.min_points) < 1 or int(params.max_iter) < 1:
        raise AmiXrValueError(
            "params: max_modes, min_points and max_iter must be >= 1, got "
            f"{params.max_modes}, {params.min_points}, {params.max_iter}"
        )


def check_frfs(data: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(data, omega)`` checked: FRFs (P, F) complex and F strictly increasing frequencies."""
    omega = checked_omega(omega)
    data = np.ascontiguousarray(data, dtype=np.complex128)
    if data.ndim != 2 or data.shape[1] != omega.size:
        raise AmiXrValueError(f"data: expected shape (P, {omega.size}), got {data.shape}")
    return data, omega


def isolate_batch(
    data: np.ndarray,
    omega: np.ndarray,
    dt: float | None,
    n_samples: int | None,
    lam0: np.ndarray,
    res0: np.ndarray,
    n0: np.ndarray,
    sigma: np.ndarray,
    params: IsolateParams,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Isolation Phase with the model-order check on every FRF separately.

    Parameters
    ----------
    data : ndarray of complex, shape (P, F)
        FRFs.
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    dt, n_samples : float or None, int or None
        Discrete model; None (or 0) for the continuous one.
    lam0, res0 : ndarray of complex, shape (P, S)
        Starting eigenvalues and residues (the Subtraction Phase's candidates).
    n0 : ndarray of int, shape (P,)
        Number of starting modes of each FRF.
    sigma : ndarray of float, shape (P,)
        Noise floor of each FRF.
    params : IsolateParams
        Settings (``reweight`` is not used per FRF).

    Returns
    -------
    lam, res : ndarray of complex, shape (P, max_modes)
        NaN-padded.
    n_modes, iterations : ndarray of int, shape (P,)
    converged : ndarray of bool, shape (P,)
    """
    data, omega = check_frfs(data, omega)
    dt, n = check_model(dt, n_samples)
    check_params(params)
    n_p = data.shape[0]
    lam0 = np.ascontiguousarray(lam0, dtype=np.complex128)
    res0 = np.ascontiguousarray(res0, dtype=np.complex128)
    if lam0.ndim != 2 or lam0.shape[0] != n_p or res0.shape != lam0.shape:
        raise AmiXrValueError(
            f"lam0, res0: expected equal shapes ({n_p}, S), got {lam0.shape}, {res0.shape}"
        )
    n0 = np.ascontiguousarray(n0, dtype=np.int64)
    sigma = np.ascontiguousarray(sigma, dtype=np.float64)
    if n0.shape != (n_p,) or np.any(n0 < 0) or np.any(n0 > lam0.shape[1]):
        raise AmiXrValueError(f"n0: expected {n_p} counts in 0..{lam0.shape[1]}, got {n0!r}")
    if sigma.shape != (n_p,):
        raise AmiXrValueError(f"sigma: expected shape ({n_p},), got {sigma.shape}")
    return _isolate_batch(data, omega, dt, n, lam0, res0, n0, sigma, params)


def point_estimates(
    data: np.ndarray,
    omega: np.ndarray,
    dt: float | None,
    n_samples: int | None,
    lam: np.ndarray,
    res: np.ndarray,
    *,
    delta: float,
    min_points: int,
    zeta_max: float,
) -> np.ndarray:
    """Per-FRF single-mode estimate of each system mode on its isolated data (eq. 7 with the
    system eigenvalues ``lam`` and the per-FRF residues ``res``).

    Parameters
    ----------
    data : ndarray of complex, shape (P, F)
        FRFs.
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    dt, n_samples : float or None, int or None
        Discrete model; None (or 0) for the continuous one.
    lam : ndarray of complex, shape (K,)
        System eigenvalues.
    res : ndarray of complex, shape (P, K)
        Residues.
    delta, min_points, zeta_max
        Fit band and limits, as in :class:`IsolateParams`.

    Returns
    -------
    ndarray of complex, shape (P, K)
        NaN where the fit fails.
    """
    data, omega = check_frfs(data, omega)
    dt, n = check_model(dt, n_samples)
    lam = np.ascontiguousarray(lam, dtype=np.complex128)
    res = np.ascontiguousarray(res, dtype=np.complex128)
    if lam.ndim != 1:
        raise AmiXrValueError(f"lam: expected a 1-D array of eigenvalues, got shape {lam.shape}")
    if res.shape != (data.shape[0], lam.size):
        raise AmiXrValueError(f"res: expected shape ({data.shape[0]}, {lam.size}), got {res.shape}")
    grid = Grid(omega, line_variable(omega, dt), dt, n)
    return _point_estimates(data, grid, lam, res, delta, min_points, zeta_max)
