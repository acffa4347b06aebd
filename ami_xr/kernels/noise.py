"""Noise floors, detection thresholds and fit bands of the AMI kernels.

The noise model: complex Gaussian noise, white and independent from line to line, so that
``|Y|^2 / sigma^2`` at a line without signal is Exp(1) and the SNR-weighted power of ``k`` FRFs
is Gamma(k, 1). Thresholds are set for a false-alarm probability ``pfa`` over all lines.

Jitted, unchecked helpers for the other kernel modules: ``noise_floor_kernel``,
``peak_threshold_kernel``, ``gamma_tail_kernel``, ``sum_threshold_kernel``, ``band_around``,
``local_peak``, ``pole_band``, ``band_energy_peak``, ``split_target``,
``normalized_distance``. Checked wrappers: :func:`noise_floor`, :func:`peak_threshold`,
:func:`sum_threshold`, :func:`gamma_tail`.
"""

from __future__ import annotations

import math

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.modal_basis import nearest_line


@jit
def noise_floor_kernel(data):
    """Robust noise standard deviation of one FRF from first differences of adjacent lines.

    For noise that is complex Gaussian, white and independent from line to line (E|n|^2 =
    sigma^2), ``|n_{k+1} - n_k|^2`` is exponential with mean ``2 sigma^2`` and median
    ``2 ln(2) sigma^2``. Differencing cancels the smooth modal part, and the median ignores the
    few lines at resonances: ``sigma^2 = median |dY|^2 / (2 ln 2)``.
    """
    n = data.shape[0]
    d = np.empty(n - 1)
    for i in range(n - 1):
        d[i] = abs(data[i + 1] - data[i]) ** 2
    return math.sqrt(np.median(d) / (2.0 * math.log(2.0)))


@jit
def peak_threshold_kernel(n_lines, pfa):
    """Threshold ``t`` on ``|Y|^2 / sigma^2`` so that the largest of ``n_lines`` independent
    Exp(1) variables exceeds it with probability ``pfa``: ``t = -ln(1 - (1 - pfa)^(1/n))``."""
    return -math.log(-math.expm1(math.log1p(-pfa) / n_lines))


@jit
def gamma_tail_kernel(k, t):
    """P(Gamma(k, 1) > t) for integer k: ``exp(-t) sum_{m<k} t^m / m!``."""
    term = 1.0
    acc = 1.0
    for m in range(1, k):
        term *= t / m
        acc += term
    return math.exp(-t) * acc


@jit
def sum_threshold_kernel(k, n_lines, pfa):
    """Threshold on the sum of ``k`` Exp(1) variables (the SNR-weighted power of ``k`` FRFs),
    for false-alarm probability ``pfa`` over ``n_lines`` lines (bisection)."""
    target = -math.expm1(math.log1p(-pfa) / n_lines)
    lo = 0.0
    hi = 10.0 * k + 100.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if gamma_tail_kernel(k, mid) > target:
            lo = mid
        else:
            hi = mid
    return hi


@jit
def band_around(power, peak, level):
    """Contiguous lines around ``peak`` with ``power >= level``: ``(lo, hi)`` half-open."""
    n = power.shape[0]
    lo = peak
    while lo > 0 and power[lo - 1] >= level:
        lo -= 1
    hi = peak + 1
    while hi < n and power[hi] >= level:
        hi += 1
    return lo, hi


@jit
def local_peak(power, omega, lam, dw):
    """Index of the largest ``power`` within ``Im(lam) +- max(2 |Re lam|, 2 dw)``."""
    half = max(2.0 * abs(lam.real), 2.0 * dw)
    c = nearest_line(omega, lam.imag)
    lo = nearest_line(omega, lam.imag - half)
    hi = nearest_line(omega, lam.imag + half)
    best = c
    for i in range(lo, hi + 1):
        if power[i] > power[best]:
            best = i
    return best


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
    """Model-order check near the existing modes: the sum of ``stat`` (|residual|^2 over the
    noise variance, summed over ``n_frf`` FRFs) over the lines within ``+- 3 |Re lam_k|`` of each
    mode is Gamma(n_lines n_frf)-distributed under noise alone. Returns the largest-``stat`` line
    of the most significant window whose sum exceeds the threshold at ``pfa / n``, or -1.
    This catches a coherent residual spread over a bandwidth (e.g. two close modes fitted as
    one) that no single line shows."""
    best_p = 1.0
    best_line = -1
    for k in range(n):
        lo, hi = pole_band(omega, lam[k], 0.31622776601683794, min_points)  # +-3 |Re lam|
        tot = 0.0
        peak = -1
        for i in range(lo, hi):
            tot += stat[i]
            if not masked[i] and (peak < 0 or stat[i] > stat[peak]):
                peak = i
        if peak < 0:
            continue
        dof = (hi - lo) * n_frf
        pval = gamma_tail_kernel(dof, tot)
        if pval < pfa / n and pval < best_p:
            best_p = pval
            best_line = peak
    return best_line


@jit
def split_target(omega, lam, n, peak, masked):
    """Index of the mode whose +-3 |Re lam| window holds line ``peak`` (not yet tried), or -1."""
    best = -1
    for k in range(n):
        if abs(omega[peak] - lam[k].imag) <= 3.0 * abs(lam[k].real):
            if best < 0 or abs(omega[peak] - lam[k].imag) < abs(omega[peak] - lam[best].imag):
                best = k
    return best


@jit
def normalized_distance(a, b):
    """|a - b| / (|Re a| + |Re b|): eigenvalue distance in units of half-power bandwidths."""
    return abs(a - b) / (abs(a.real) + abs(b.real))


def _check_pfa(pfa: float) -> float:
    pfa = float(pfa)
    if not 0.0 < pfa < 1.0:
        raise AmiXrValueError(f"pfa: expected a probability in (0, 1), got {pfa!r}")
    return pfa


def _check_count(value: int, name: str) -> int:
    if int(value) != value or value < 1:
        raise AmiXrValueError(f"{name}: expected a positive integer, got {value!r}")
    return int(value)


def sum_threshold(k: int, n_lines: int, pfa: float) -> float:
    """Threshold on the sum of ``k`` Exp(1) variables for false-alarm probability ``pfa`` over
    ``n_lines`` lines (checked wrapper of ``sum_threshold_kernel``)."""
    return sum_threshold_kernel(
        _check_count(k, "k"), _check_count(n_lines, "n_lines"), _check_pfa(pfa)
    )


def gamma_tail(k: int, t: float) -> float:
    """``P(Gamma(k, 1) > t)`` for a positive integer ``k`` (checked wrapper of
    ``gamma_tail_kernel``)."""
    return gamma_tail_kernel(_check_count(k, "k"), float(t))


def noise_floor(data: np.ndarray) -> np.ndarray:
    """Robust noise standard deviation of each FRF from adjacent-line differences.

    Parameters
    ----------
    data : array_like of complex, shape (..., F)
        FRFs, frequency last (F >= 2).

    Returns
    -------
    ndarray of float, shape (...)
        ``sqrt(median |dY|^2 / (2 ln 2))`` per FRF (see ``noise_floor_kernel``).
    """
    data = np.ascontiguousarray(data, dtype=np.complex128)
    if data.ndim < 1 or data.shape[-1] < 2:
        raise AmiXrValueError(
            f"data: expected FRFs with at least 2 frequency lines last, got shape {data.shape}"
        )
    flat = data.reshape(-1, data.shape[-1])
    return np.array([noise_floor_kernel(row) for row in flat]).reshape(data.shape[:-1])


def peak_threshold(n_lines: int, pfa: float) -> float:
    """Single-line detection threshold on ``|Y|^2 / sigma^2``: the largest of ``n_lines``
    Exp(1) variables exceeds it with probability ``pfa`` (checked wrapper of
    ``peak_threshold_kernel``)."""
    return peak_threshold_kernel(_check_count(n_lines, "n_lines"), _check_pfa(pfa))
