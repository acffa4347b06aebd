"""Noise floors and detection thresholds of the AMI kernels.

The noise model: complex Gaussian noise, white and independent from line to line, so that
``|Y|^2 / sigma^2`` at a line without signal is Exp(1) and the SNR-weighted power of ``k`` FRFs
is Gamma(k, 1). Thresholds are set for a false-alarm probability ``pfa`` over all lines.

The thresholds are computed once per call, before any kernel runs (plain Python); the only
jitted helper is ``gamma_tail_kernel``, which the model-order check evaluates for windows of
varying size. Checked functions: :func:`noise_floor`, :func:`peak_threshold`,
:func:`sum_threshold`, :func:`gamma_tail`.
"""

from __future__ import annotations

import math

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit


@jit
def gamma_tail_kernel(k, t):
    """P(Gamma(k, 1) > t) for integer k: ``exp(-t) sum_{m<k} t^m / m!``."""
    term = 1.0
    acc = 1.0
    for m in range(1, k):
        term *= t / m
        acc += term
    return math.exp(-t) * acc


def _check_pfa(pfa: float) -> float:
    pfa = float(pfa)
    if not 0.0 < pfa < 1.0:
        raise AmiXrValueError(f"pfa: expected a probability in (0, 1), got {pfa!r}")
    return pfa


def _check_count(value: int, name: str) -> int:
    if int(value) != value or value < 1:
        raise AmiXrValueError(f"{name}: expected a positive integer, got {value!r}")
    return int(value)


def peak_threshold(n_lines: int, pfa: float) -> float:
    """Single-line detection threshold ``t`` on ``|Y|^2 / sigma^2``: the largest of ``n_lines``
    independent Exp(1) variables exceeds it with probability ``pfa``,
    ``t = -ln(1 - (1 - pfa)^(1/n))``."""
    n_lines = _check_count(n_lines, "n_lines")
    return -math.log(-math.expm1(math.log1p(-_check_pfa(pfa)) / n_lines))


def sum_threshold(k: int, n_lines: int, pfa: float) -> float:
    """Threshold on the sum of ``k`` Exp(1) variables (the SNR-weighted power of ``k`` FRFs),
    for false-alarm probability ``pfa`` over ``n_lines`` lines (bisection on
    :func:`gamma_tail`; ``k = 1`` gives :func:`peak_threshold`)."""
    k = _check_count(k, "k")
    n_lines = _check_count(n_lines, "n_lines")
    target = -math.expm1(math.log1p(-_check_pfa(pfa)) / n_lines)
    lo, hi = 0.0, 10.0 * k + 100.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if gamma_tail_kernel(k, mid) > target:
            lo = mid
        else:
            hi = mid
    return hi


def gamma_tail(k: int, t: float) -> float:
    """``P(Gamma(k, 1) > t)`` for a positive integer ``k`` (checked wrapper of
    ``gamma_tail_kernel``)."""
    return gamma_tail_kernel(_check_count(k, "k"), float(t))


def noise_floor(data: np.ndarray) -> np.ndarray:
    """Robust noise standard deviation of each FRF from adjacent-line differences.

    For noise that is complex Gaussian, white and independent from line to line (E|n|^2 =
    sigma^2), ``|n_{k+1} - n_k|^2`` is exponential with mean ``2 sigma^2`` and median
    ``2 ln(2) sigma^2``. Differencing cancels the smooth modal part, and the median ignores the
    few lines at resonances: ``sigma^2 = median |dY|^2 / (2 ln 2)``.

    Parameters
    ----------
    data : array_like of complex, shape (..., F)
        FRFs, frequency last (F >= 2).

    Returns
    -------
    ndarray of float, shape (...)
    """
    data = np.asarray(data, dtype=np.complex128)
    if data.ndim < 1 or data.shape[-1] < 2:
        raise AmiXrValueError(
            f"data: expected FRFs with at least 2 frequency lines last, got shape {data.shape}"
        )
    d = np.abs(np.diff(data, axis=-1)) ** 2
    return np.sqrt(np.median(d, axis=-1) / (2.0 * math.log(2.0)))
