"""The peak trial shared by the Subtraction Phase and the isolation's model-order check, the
fit bands, and the input checks and per-call constants of both phases.

The peak trial (:func:`peak_trial`): the lines around a peak of the residual power above
``delta^2`` times the peak form the band; one mode is fitted there (shared by all rows of the
residual, one residue each); it is accepted when it is physical, its frequency lies near the
band, and removing it lowers the band's energy significantly; otherwise the band is masked so
the next trial looks elsewhere.

All data are in units of each FRF's noise floor, so one threshold serves every FRF: the
``|Y|^2`` of a noise line is Exp(1), the power summed over ``P`` FRFs Gamma(P, 1).

Jitted, unchecked helpers: ``pole_band``, ``band_energy_peak``,
``nearest_within``, ``peak_trial``. Checked helpers: :func:`check_inputs`, :func:`scene`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.modal_basis import (
    Grid,
    add_mode,
    as_dt,
    checked_omega,
    line_variable,
    nearest_line,
)
from ami_xr.kernels.noise import gamma_tail_kernel, peak_threshold, sum_threshold
from ami_xr.kernels.single_mode import (
    FIT_NO_DROP,
    FIT_OK,
    FIT_OUT_OF_RANGE,
    FIT_TOO_FEW_POINTS,
    FitLimits,
    fit_single,
)

SPLIT_DELTA = 0.31622776601683794
"""``delta`` of the ``+- 3 |Re lam|`` window (``sqrt(1/delta^2 - 1) = 3``) around a mode: the
band of a mode split, and of the model-order check near existing modes."""


class Scene(NamedTuple):
    """What every kernel of a call shares: the lines, the fit limits and the thresholds."""

    grid: Grid
    """Frequency lines and data model."""
    limits: FitLimits
    """Limits a fitted pole must meet: natural frequencies in ``[max(omega[0], dw), omega[-1]]``."""
    dw: float
    """Mean line spacing (rad/s)."""
    t_line: float
    """Threshold on ``|Y|^2`` (noise units) of the largest of the lines of one FRF."""
    t_sum: float
    """Threshold on the power summed over the FRFs of a group (``t_line`` for one FRF)."""
    line_w: np.ndarray
    """(F,) weight of each line's power: ``1 / shape^2`` of a noise std that varies along
    frequency as ``shape`` (ones: white noise)."""


@jit
def pole_band(omega, lam, delta, min_points):
    """Lines where a single mode with pole ``lam`` is at least ``delta`` times its peak:
    ``|w - Im lam| <= sqrt(1/delta^2 - 1) |Re lam|`` (the delta rule applied to the model, so the
    band does not depend on the noise of the data), widened to ``min_points`` lines."""
    half = math.sqrt(1.0 / (delta * delta) - 1.0) * abs(lam.real)
    n = omega.shape[0]
    c = nearest_line(omega, lam.imag)
    lo = c
    hi = c + 1
    while lo > 0 and omega[lo - 1] >= lam.imag - half:
        lo -= 1
    while hi < n and omega[hi] <= lam.imag + half:
        hi += 1
    while hi - lo < min_points and (lo > 0 or hi < n):
        if lo > 0 and (hi >= n or lam.imag - omega[lo - 1] <= omega[hi] - lam.imag):
            lo -= 1
        else:
            hi += 1
    return lo, hi


@jit
def band_energy_peak(stat, omega, lam, n, n_frf, pfa, min_points, masked):
    """Model-order check near the existing modes: the sum of ``stat`` (|residual|^2 in noise
    units, summed over ``n_frf`` FRFs) over the lines within ``+- 3 |Re lam_k|`` of each mode is
    Gamma(n_lines n_frf)-distributed under noise alone. Returns the largest-``stat`` line of the
    most significant window whose sum exceeds the threshold at ``pfa / n``, or -1.
    This catches a coherent residual spread over a bandwidth (e.g. two close modes fitted as
    one) that no single line shows."""
    best_p = 1.0
    best_line = -1
    for k in range(n):
        lo, hi = pole_band(omega, lam[k], SPLIT_DELTA, min_points)
        tot = 0.0
        peak = -1
        for i in range(lo, hi):
            tot += stat[i]
            if not masked[i] and (peak < 0 or stat[i] > stat[peak]):
                peak = i
        if peak < 0:
            continue
        pval = gamma_tail_kernel((hi - lo) * n_frf, tot)
        if pval < pfa / n and pval < best_p:
            best_p = pval
            best_line = peak
    return best_line


@jit
def nearest_within(lam, n, target, tol, skip):
    """Index of the first of the modes ``lam[:n]`` (other than ``skip``) within ``tol``
    half-power bandwidths of ``target`` (``|a - b| / (|Re a| + |Re b|)``), or -1."""
    for k in range(n):
        if k != skip and abs(lam[k] - target) / (abs(lam[k].real) + abs(target.real)) < tol:
            return k
    return -1


@jit
def peak_trial(y, power, scene, peak, delta, min_points, wts, res_out, masked):
    """Try one mode at line ``peak`` of the residual ``y`` (P, F), ``power`` its power summed
    over the rows: fit on the band above ``delta^2 power[peak]`` (at least ``min_points``
    lines; residues to ``res_out``), accepted when physical, near the band (+- 2 bandwidths and
    a line) and lowering the band's energy (lines weighted by ``scene.line_w``, as ``power``
    is) by at least ``scene.t_sum``. A rejected band is
    masked. Returns ``(lam, lo, hi, code)``."""
    omega, x, dt, n_samples = scene.grid
    n_p, n_f = y.shape
    dw = scene.dw
    # the band: contiguous lines around the peak with power >= delta^2 times the peak's, on
    # the data as given (a weighted power would lean the band towards the quieter side, where
    # the neighbours' tails bias the one-mode fit)
    line_w = scene.line_w
    level = delta * delta * power[peak] / line_w[peak]
    lo = peak
    while lo > 0 and power[lo - 1] >= level * line_w[lo - 1]:
        lo -= 1
    hi = peak + 1
    while hi < n_f and power[hi] >= level * line_w[hi]:
        hi += 1
    lam = complex(np.nan, np.nan)
    code = FIT_TOO_FEW_POINTS
    if hi - lo >= min_points:
        ws = omega[peak] if omega[peak] > 0.0 else dw
        lam, code = fit_single(y, scene.grid, lo, hi, ws, scene.limits, lam, wts, res_out)
    if code == FIT_OK:
        bw = abs(lam.real)
        if lam.imag < omega[lo] - 2.0 * bw - dw or lam.imag > omega[hi - 1] + 2.0 * bw + dw:
            code = FIT_OUT_OF_RANGE
    if code == FIT_OK:
        e0 = 0.0
        e1 = 0.0
        trial = np.empty(n_f, dtype=np.complex128)
        for j in range(n_p):
            for i in range(lo, hi):
                trial[i] = y[j, i]
            add_mode(trial, x, lam, res_out[j], dt, n_samples, -1.0, lo, hi)
            for i in range(lo, hi):
                e1 += abs(trial[i]) ** 2 * line_w[i]
        for i in range(lo, hi):
            e0 += power[i]
        if e0 - e1 < scene.t_sum:
            code = FIT_NO_DROP
    if code != FIT_OK:
        masked[lo:hi] = True
    return lam, lo, hi, code


# ----------------------------------------------------------------------------------------------
# checked helpers
# ----------------------------------------------------------------------------------------------
def check_inputs(
    data: np.ndarray, omega: np.ndarray, dt: float | None, n_samples: int | None
) -> tuple[np.ndarray, np.ndarray, float, int]:
    """``(data, omega, dt, n_samples)`` as the kernels take them (contiguous complex data, ``dt``
    a float, ``n_samples`` an int), checked.

    Parameters
    ----------
    data : ndarray of complex, shape (P, F)
        The FRFs, one a row.
    omega : ndarray of float, shape (F,)
        Their angular frequencies (rad/s), strictly increasing.
    dt, n_samples : float or None, int or None
        Discrete model (sampling interval and record length, finite and >= 0); None (or 0) for
        the continuous one.
    """
    omega = checked_omega(omega)
    data = np.ascontiguousarray(data, dtype=np.complex128)
    if data.ndim != 2 or data.shape[1] != omega.size:
        raise AmiXrValueError(f"data: expected shape (P, {omega.size}), got {data.shape}")
    dt = as_dt(dt)
    n = int(n_samples or 0)
    if dt < 0.0 or not np.isfinite(dt) or n < 0:
        raise AmiXrValueError(f"dt, n_samples: expected >= 0 or None, got {dt!r}, {n_samples!r}")
    return data, omega, dt, n


def scene(
    omega: np.ndarray,
    dt: float,
    n_samples: int,
    zeta_max: float,
    pfa: float,
    n_rows: int,
    line_w: np.ndarray | None = None,
) -> Scene:
    """The :class:`Scene` of checked inputs; ``n_rows`` FRFs share each fit; ``line_w`` the
    lines' power weights (None: ones)."""
    n_f = omega.size
    dw = (omega[-1] - omega[0]) / (n_f - 1)
    limits = FitLimits(float(zeta_max), max(float(omega[0]), dw), float(omega[-1]))
    grid = Grid(omega, line_variable(omega, dt), dt, n_samples)
    t_line = peak_threshold(n_f, pfa)
    t_sum = sum_threshold(n_rows, n_f, pfa) if n_rows > 1 else t_line
    w = np.ones(n_f) if line_w is None else np.ascontiguousarray(line_w, dtype=np.float64)
    return Scene(grid, limits, float(dw), t_line, t_sum, w)
