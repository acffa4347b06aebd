"""Subtraction Phase of the AMI (eq. 6): one FRF at a time, the strongest peak of the residual
is fitted by a single mode and subtracted, until no significant peak is left.

Checked wrapper: :func:`subtract_batch` (settings in a :class:`SubtractParams` record). The stop
reasons are ``STOP_*`` codes; :data:`STOP_REASONS` names them.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.modal_basis import Grid, add_mode, as_dt, checked_omega, line_variable
from ami_xr.kernels.noise import (
    band_around,
    noise_floor_kernel,
    normalized_distance,
    peak_threshold_kernel,
)
from ami_xr.kernels.single_mode import (
    FIT_NO_DROP,
    FIT_OK,
    FIT_OUT_OF_RANGE,
    FitLimits,
    band_energy_drop,
    fit_single,
)
from ami_xr.progress import by_rows

# Stop codes of the Subtraction Phase (mapped to strings in the labeled layer).
STOP_BELOW_FLOOR = 0
STOP_MAX_MODES = 1
STOP_MAX_ATTEMPTS = 2
STOP_REASONS = ("below_noise_floor", "max_modes", "max_rejected_peaks")
"""Names of the ``STOP_*`` codes, by code."""


class SubtractParams(NamedTuple):
    """Settings of the Subtraction Phase kernel (see :func:`ami_xr.subtract` for their meaning)."""

    delta: float
    """Fit band: contiguous lines with ``|Y| >= delta`` times the peak."""
    max_modes: int
    """Most candidate modes per FRF."""
    pfa: float
    """False-alarm probability of the peak test over all lines."""
    min_points: int
    """Fewest lines in a fit band."""
    zeta_max: float
    """Largest accepted damping ratio."""
    merge_tol: float
    """Candidates closer than this many half-power bandwidths merge."""


@jit
def _subtract_one(data, grid, params, lam_out, res_out, lo_out, hi_out):
    """Subtraction Phase on one FRF ``data`` (F,): candidates written to ``lam_out``,
    ``res_out`` and their band edges (rad/s) to ``lo_out``, ``hi_out`` (each ``max_modes``).
    Returns ``(n_modes, sigma, statistic, reason)``."""
    omega, x, dt, n_samples = grid
    delta, max_modes, pfa, min_points, zeta_max, merge_tol = params
    n_f = data.shape[0]
    sigma = noise_floor_kernel(data)
    scale_floor = 1e-14 * np.max(np.abs(data))
    sigma = max(sigma, scale_floor)
    t = peak_threshold_kernel(n_f, pfa)
    dw = (omega[n_f - 1] - omega[0]) / (n_f - 1)
    w_lo = max(omega[0], dw)
    w_hi = omega[n_f - 1]
    limits = FitLimits(zeta_max, w_lo, w_hi)
    y = data.copy()
    power = np.empty(n_f)
    masked = np.zeros(n_f, dtype=np.bool_)
    n_modes = 0
    stat = 0.0
    reason = STOP_MAX_ATTEMPTS
    max_attempts = 3 * max_modes + 10
    for _attempt in range(max_attempts):
        if n_modes >= max_modes:
            reason = STOP_MAX_MODES
            break
        peak = -1
        best = -1.0
        for i in range(n_f):
            power[i] = abs(y[i]) ** 2
            if not masked[i] and power[i] > best:
                best = power[i]
                peak = i
        if peak < 0:
            reason = STOP_BELOW_FLOOR
            stat = 0.0
            break
        stat = best / sigma**2
        if stat < t:
            reason = STOP_BELOW_FLOOR
            break
        lo, hi = band_around(power, peak, delta * delta * best)
        if hi - lo < min_points:
            for i in range(lo, hi):
                masked[i] = True
            continue
        ws = omega[peak] if omega[peak] > 0.0 else dw
        lam, res, code = fit_single(y, grid, lo, hi, ws, limits, complex(np.nan, np.nan))
        if code == FIT_OK:
            # natural frequency must lie near the band; the band energy must drop significantly
            bw = abs(lam.real)
            if lam.imag < omega[lo] - 2.0 * bw - dw or lam.imag > omega[hi - 1] + 2.0 * bw + dw:
                code = FIT_OUT_OF_RANGE
            else:
                drop = band_energy_drop(y, grid, lam, res, power, lo, hi)
                if drop / sigma**2 < t:
                    code = FIT_NO_DROP
        if code != FIT_OK:
            for i in range(lo, hi):
                masked[i] = True
            continue
        merged = False
        for k in range(n_modes):
            if normalized_distance(lam, lam_out[k]) < merge_tol:
                # a duplicate of an earlier candidate: the residual left near that pole; fold the
                # residue into the earlier candidate (poles this close add their residues)
                res_out[k] = res_out[k] + res
                merged = True
                break
        if not merged:
            lam_out[n_modes] = lam
            res_out[n_modes] = res
            lo_out[n_modes] = omega[lo]
            hi_out[n_modes] = omega[hi - 1]
            n_modes += 1
        # recompute the residual from the data (eq. 6 with the current candidates)
        for i in range(n_f):
            y[i] = data[i]
        for k in range(n_modes):
            add_mode(y, x, lam_out[k], res_out[k], dt, n_samples, -1.0, 0, n_f)
    return n_modes, sigma, stat, reason


@jit
def _subtract_batch(data, omega, dt, n_samples, params):
    """:func:`_subtract_one` on every row of ``data`` (P, F)."""
    n_p = data.shape[0]
    max_modes = params.max_modes
    grid = Grid(omega, line_variable(omega, dt), dt, n_samples)
    lam = np.full((n_p, max_modes), complex(np.nan, np.nan))
    res = np.full((n_p, max_modes), complex(np.nan, np.nan))
    blo = np.full((n_p, max_modes), np.nan)
    bhi = np.full((n_p, max_modes), np.nan)
    n_modes = np.zeros(n_p, dtype=np.int64)
    sigma = np.zeros(n_p)
    stat = np.zeros(n_p)
    reason = np.zeros(n_p, dtype=np.int64)
    for j in range(n_p):
        n, s, st, r = _subtract_one(
            data[j],
            grid,
            params,
            lam[j],
            res[j],
            blo[j],
            bhi[j],
        )
        n_modes[j] = n
        sigma[j] = s
        stat[j] = st
        reason[j] = r
    return lam, res, blo, bhi, sigma, stat, reason, n_modes


def subtract_batch(
    data: np.ndarray,
    omega: np.ndarray,
    dt: float | None,
    n_samples: int | None,
    params: SubtractParams,
) -> tuple[np.ndarray, ...]:
    """Subtraction Phase on every FRF.

    Parameters
    ----------
    data : ndarray of complex, shape (P, F)
        FRFs.
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    dt, n_samples : float or None, int or None
        Discrete model; None (or 0) for the continuous one.
    params : SubtractParams
        Settings.

    Returns
    -------
    lam, res : ndarray of complex, shape (P, max_modes)
        Candidate eigenvalues and residues, NaN-padded.
    band_lo, band_hi : ndarray of float, shape (P, max_modes)
        Edges of each candidate's fit band in rad/s.
    sigma, statistic : ndarray of float, shape (P,)
        Noise floor and the last peak statistic ``|Y|^2 / sigma^2``.
    reason : ndarray of int, shape (P,)
        ``STOP_*`` code.
    n_modes : ndarray of int, shape (P,)
    """
    omega = checked_omega(omega)
    data = np.ascontiguousarray(data, dtype=np.complex128)
    if data.ndim != 2 or data.shape[1] != omega.size:
        raise AmiXrValueError(f"data: expected shape (P, {omega.size}), got {data.shape}")
    dt = as_dt(dt)
    n = int(n_samples or 0)
    if dt < 0.0 or n < 0:
        raise AmiXrValueError(f"dt, n_samples: expected >= 0 or None, got {dt!r}, {n_samples!r}")
    if not isinstance(params, SubtractParams):
        raise AmiXrValueError(
            f"params: expected a SubtractParams record, got {type(params).__name__}"
        )
    if int(params.max_modes) < 1 or int(params.min_points) < 1:
        raise AmiXrValueError(
            f"params: max_modes and min_points must be >= 1, got {params.max_modes}, "
            f"{params.min_points}"
        )
    # FRFs counted on a progress bar when one listens (blocks of FRFs; same results)
    return by_rows(_subtract_batch, (data, omega, dt, n, params), rowwise=(0,))
