"""Single-mode linear least squares of the AMI (eqs. 10-12), per FRF and SIMO.

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

The two-mode analogue of (*) is in :mod:`.two_mode`. Jitted, unchecked helpers for the other
kernel modules: ``fit_single``, ``fit_single_simo``, ``band_energy_drop``, ``v_at``. Checked
wrappers: :func:`single_mode_rows`, :func:`fit_single_mode`, :func:`fit_single_mode_simo`. A fit
returns one of the ``FIT_*`` codes below; ``FitLimits`` holds the limits a pole must meet.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.linalg import solve_normal
from ami_xr.kernels.modal_basis import (
    Grid,
    add_mode,
    as_dt,
    checked_omega,
    line_variable,
    pole_factor,
)

FIT_OK = 0
FIT_SINGULAR = 1
FIT_NOT_OSCILLATORY = 2
FIT_UNSTABLE = 3
FIT_DAMPING = 4
FIT_OUT_OF_RANGE = 5
FIT_TOO_FEW_POINTS = 6
FIT_NO_DROP = 7
FIT_CODES = (
    "ok",
    "singular",
    "not_oscillatory",
    "unstable",
    "damping",
    "out_of_range",
    "too_few_points",
    "no_drop",
)
"""Names of the ``FIT_*`` codes, by code."""


class FitLimits(NamedTuple):
    """Limits a fitted pole must meet to be accepted (else a ``FIT_*`` rejection code)."""

    zeta_max: float
    """Largest damping ratio ``-Re(lam) / |lam|``."""
    w_lo: float
    """Smallest natural frequency ``|lam|`` in rad/s."""
    w_hi: float
    """Largest natural frequency ``|lam|`` in rad/s."""


@jit
def v_at(xi, ws, dt):
    """Jitted, unchecked: the variable ``v`` of (*) at line variable ``xi``."""
    if dt > 0.0:
        return (1.0 - xi) / (dt * ws)
    return xi / ws


@jit
def _v_of_pole(lam, ws, dt):
    """The root ``v1`` of (*) that belongs to pole ``lam``."""
    if dt > 0.0:
        return (1.0 - np.exp(-lam * dt)) / (dt * ws)
    return lam / ws


@jit
def _single_mode_blocks(data, x, lo, hi, ws, dt, gscale, prev, blocks):
    """Accumulate the normal equations of (*) on lines lo..hi-1 of one FRF.

    Unknowns: shared ``s = (c0, c1)``, local ``l = (e0, e1)``. Columns of (*) written as
    ``G v^2 = -c0 G - c1 G v + e0 + e1 v``; the data is divided by ``gscale``.
    ``blocks = (nss, nsl, nll, rs, rl)``: ``nss``, ``nsl``, ``nll`` (2x2) and right sides ``rs``,
    ``rl`` (2), accumulated in place.
    When ``prev`` (a previous pole estimate) is not NaN every line is divided by
    ``|D_prev(v)| = |(v - v1)(v - conj(v1))|`` (Sanathanan-Koerner / Steiglitz-McBride): at a
    fixed point the equation error becomes the output error ``G - N/D``, which removes the
    damping bias that noise in the regressor columns gives the plain eqs. 11-12.
    """
    nss, nsl, nll, rs, rl = blocks
    cols = np.empty(4, dtype=np.complex128)
    use_w = not np.isnan(prev.real)
    pv = _v_of_pole(prev, ws, dt) if use_w else 0j
    for i in range(lo, hi):
        g = data[i] / gscale
        v = v_at(x[i], ws, dt)
        wgt = 1.0
        if use_w:
            wgt = 1.0 / abs((v - pv) * (v - np.conj(pv)))
        cols[0] = -g * wgt
        cols[1] = -g * v * wgt
        cols[2] = wgt
        cols[3] = v * wgt
        rhs = g * v * v * wgt
        for a in range(2):
            ca = np.conj(cols[a])
            for b in range(2):
                nss[a, b] += (ca * cols[b]).real
                nsl[a, b] += (ca * cols[2 + b]).real
            rs[a] += (ca * rhs).real
            cla = np.conj(cols[2 + a])
            for b in range(2):
                nll[a, b] += (cla * cols[2 + b]).real
            rl[a] += (cla * rhs).real


@jit
def _single_mode_rows(data, omega, ws, dt):
    """Real rows and right side of (*) for every line: (2F, 4), (2F,) (for tests/references)."""
    n = data.shape[0]
    x = line_variable(omega, dt)
    rows = np.empty((2 * n, 4))
    rhs = np.empty(2 * n)
    for i in range(n):
        g = data[i]
        v = v_at(x[i], ws, dt)
        c = (-g, -g * v, 1.0 + 0j, v)
        r = g * v * v
        for a in range(4):
            rows[2 * i, a] = c[a].real
            rows[2 * i + 1, a] = c[a].imag
        rhs[2 * i] = r.real
        rhs[2 * i + 1] = r.imag
    return rows, rhs


@jit
def _poles_from_coefficients(c0, c1, ws, dt, n_samples, limits):
    """Pole and partial-fraction helpers from ``v^2 + c1 v + c0``.

    Returns ``(lam, v1, v2, code)``; ``code`` is FIT_OK or a rejection code.
    """
    disc = 4.0 * c0 - c1 * c1
    nanc = complex(np.nan, np.nan)
    if not (disc > 0.0) or not np.isfinite(disc):
        return nanc, nanc, nanc, FIT_NOT_OSCILLATORY
    sq = math.sqrt(disc)
    v1 = complex(-0.5 * c1, 0.5 * sq)
    v2 = complex(-0.5 * c1, -0.5 * sq)
    if dt > 0.0:
        q1 = 1.0 - dt * ws * v1
        if abs(q1) == 0.0:
            return nanc, v1, v2, FIT_UNSTABLE
        p = 1.0 / q1
        lam = np.log(p) / dt
    else:
        lam = ws * v1
    if not (lam.real < 0.0):
        return lam, v1, v2, FIT_UNSTABLE
    wn = abs(lam)
    if -lam.real / wn > limits.zeta_max or lam.imag <= 0.0:
        return lam, v1, v2, FIT_DAMPING
    if wn < limits.w_lo or wn > limits.w_hi:
        return lam, v1, v2, FIT_OUT_OF_RANGE
    return lam, v1, v2, FIT_OK


@jit
def _residue_from(e0, e1, v1, v2, lam, ws, dt, n_samples, gscale):
    r = (e1 * v1 + e0) / (v1 - v2) * gscale
    if dt > 0.0:
        p, sc = pole_factor(lam, dt, n_samples)
        return p * dt * ws * r / sc
    return ws * r


@jit
def band_energy_drop(y, grid, lam, res, power, lo, hi):
    """Band energy ``sum power[lo:hi]`` minus that of ``y`` with the mode (lam, res) removed."""
    x, dt, n_samples = grid.x, grid.dt, grid.n_samples
    n_f = y.shape[0]
    trial = y.copy()
    add_mode(trial, x, lam, res, dt, n_samples, -1.0, 0, n_f)
    e0 = 0.0
    e1 = 0.0
    for i in range(lo, hi):
        e0 += power[i]
        e1 += abs(trial[i]) ** 2
    return e0 - e1


@jit
def fit_single(data, grid, lo, hi, ws, limits, prev):
    """Single-mode fit of one FRF on lines lo..hi-1 with frequency scale ``ws``:
    ``(lam, residue, code)``. ``prev``: a previous pole estimate (NaN: none) that weights the
    rows by ``1 / |D_prev|``."""
    x, dt, n_samples = grid.x, grid.dt, grid.n_samples
    nss = np.zeros((2, 2))
    nsl = np.zeros((2, 2))
    nll = np.zeros((2, 2))
    rs = np.zeros(2)
    rl = np.zeros(2)
    gscale = 0.0
    for i in range(lo, hi):
        gscale = max(gscale, abs(data[i]))
    nanc = complex(np.nan, np.nan)
    if gscale == 0.0 or hi - lo < 2:
        return nanc, nanc, FIT_SINGULAR
    _single_mode_blocks(data, x, lo, hi, ws, dt, gscale, prev, (nss, nsl, nll, rs, rl))
    nmat = np.empty((4, 4))
    rhs = np.empty((4, 1))
    for a in range(2):
        for b in range(2):
            nmat[a, b] = nss[a, b]
            nmat[a, 2 + b] = nsl[a, b]
            nmat[2 + b, a] = nsl[a, b]
            nmat[2 + a, 2 + b] = nll[a, b]
        rhs[a, 0] = rs[a]
        rhs[2 + a, 0] = rl[a]
    sol, ok = solve_normal(nmat, rhs)
    if not ok:
        return nanc, nanc, FIT_SINGULAR
    lam, v1, v2, code = _poles_from_coefficients(sol[0, 0], sol[1, 0], ws, dt, n_samples, limits)
    if code != FIT_OK:
        return lam, nanc, code
    res = _residue_from(sol[2, 0], sol[3, 0], v1, v2, lam, ws, dt, n_samples, gscale)
    return lam, res, FIT_OK


@jit
def fit_single_simo(data, grid, lo, hi, ws, limits, prev, wts, res_out):
    """Global SIMO single-mode fit: one eigenvalue from all FRFs (rows of ``data``, already
    divided by each FRF's noise floor), one residue per FRF written to ``res_out``.

    The per-FRF unknowns ``(e0, e1)`` are eliminated by their 2x2 Schur complements, so the cost
    is linear in the number of FRFs. Returns ``(lam, code)``.
    """
    x, dt, n_samples = grid.x, grid.dt, grid.n_samples
    n_p = data.shape[0]
    red = np.zeros((2, 2))
    redr = np.zeros((2, 1))
    nll_all = np.zeros((n_p, 2, 2))
    nsl_all = np.zeros((n_p, 2, 2))
    rl_all = np.zeros((n_p, 2))
    nanc = complex(np.nan, np.nan)
    # scratch blocks reused for every FRF (no allocation per FRF)
    nss = np.empty((2, 2))
    nsl = np.empty((2, 2))
    nll = np.empty((2, 2))
    rs = np.empty(2)
    rl = np.empty(2)
    inv = np.empty((2, 2))
    t = np.empty((2, 2))
    for j in range(n_p):
        nss[:] = 0.0
        nsl[:] = 0.0
        nll[:] = 0.0
        rs[:] = 0.0
        rl[:] = 0.0
        # FRF weight wts[j]: rows scaled by it (1 / wts[j] as the data scale)
        _single_mode_blocks(data[j], x, lo, hi, ws, dt, 1.0 / wts[j], prev, (nss, nsl, nll, rs, rl))
        det = nll[0, 0] * nll[1, 1] - nll[0, 1] * nll[1, 0]
        if det == 0.0:
            return nanc, FIT_SINGULAR
        inv[0, 0] = nll[1, 1] / det
        inv[1, 1] = nll[0, 0] / det
        inv[0, 1] = -nll[0, 1] / det
        inv[1, 0] = -nll[1, 0] / det
        # red += nss - nsl inv nls ; redr += rs - nsl inv rl  (2x2 product by hand: a BLAS
        # call per FRF cost more than the fit)
        for a in range(2):
            for b in range(2):
                t[a, b] = nsl[a, 0] * inv[0, b] + nsl[a, 1] * inv[1, b]
        for a in range(2):
            for b in range(2):
                red[a, b] += nss[a, b] - (t[a, 0] * nsl[b, 0] + t[a, 1] * nsl[b, 1])
            redr[a, 0] += rs[a] - (t[a, 0] * rl[0] + t[a, 1] * rl[1])
        nll_all[j] = nll
        nsl_all[j] = nsl
        rl_all[j, 0] = rl[0]
        rl_all[j, 1] = rl[1]
    sol, ok = solve_normal(red, redr)
    if not ok:
        return nanc, FIT_SINGULAR
    c0 = sol[0, 0]
    c1 = sol[1, 0]
    lam, v1, v2, code = _poles_from_coefficients(c0, c1, ws, dt, n_samples, limits)
    if code != FIT_OK:
        return lam, code
    for j in range(n_p):
        # nll e = rl - nls s
        b0 = rl_all[j, 0] - (nsl_all[j, 0, 0] * c0 + nsl_all[j, 1, 0] * c1)
        b1 = rl_all[j, 1] - (nsl_all[j, 0, 1] * c0 + nsl_all[j, 1, 1] * c1)
        nll = nll_all[j]
        det = nll[0, 0] * nll[1, 1] - nll[0, 1] * nll[1, 0]
        e0 = (nll[1, 1] * b0 - nll[0, 1] * b1) / det
        e1 = (-nll[1, 0] * b0 + nll[0, 0] * b1) / det
        res_out[j] = _residue_from(e0, e1, v1, v2, lam, ws, dt, n_samples, 1.0 / wts[j])
    return lam, FIT_OK


def check_frf(data: np.ndarray, omega: np.ndarray, name: str = "data") -> np.ndarray:
    """``data`` as contiguous complex128, checked to have ``omega.size`` lines last."""
    data = np.ascontiguousarray(data, dtype=np.complex128)
    if data.shape[-1:] != omega.shape:
        raise AmiXrValueError(
            f"{name}: expected {omega.size} frequency lines last (like omega), got {data.shape}"
        )
    return data


def check_zeta_max(zeta_max: float) -> float:
    """``zeta_max`` as a float, checked positive."""
    zeta_max = float(zeta_max)
    if not zeta_max > 0.0:
        raise AmiXrValueError(f"zeta_max: expected a positive damping ratio, got {zeta_max!r}")
    return zeta_max


def _check_prev(prev: complex | None) -> complex:
    return complex(np.nan, np.nan) if prev is None else complex(prev)


def single_mode_rows(
    data: np.ndarray, omega: np.ndarray, scale: float, dt: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Real least-squares rows and right side of the single-mode equation (*) (eqs. 11-12 when
    ``dt`` is None).

    Parameters
    ----------
    data : ndarray of complex, shape (F,)
        One FRF.
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    scale : float
        The frequency scale ``ws`` of ``v``.
    dt : float, optional
        Sample interval of the discrete model; None for the continuous one.

    Returns
    -------
    rows : ndarray of float, shape (2F, 4)
    rhs : ndarray of float, shape (2F,)
    """
    omega = checked_omega(omega)
    data = check_frf(data, omega)
    if data.ndim != 1:
        raise AmiXrValueError(f"data: expected one FRF of shape {omega.shape}, got {data.shape}")
    if not float(scale) > 0.0:
        raise AmiXrValueError(f"scale: expected a positive frequency scale, got {scale!r}")
    return _single_mode_rows(data, omega, float(scale), as_dt(dt))


def fit_single_mode(
    data: np.ndarray,
    omega: np.ndarray,
    dt: float | None = None,
    n_samples: int | None = None,
    *,
    zeta_max: float = 1.0,
    prev: complex | None = None,
) -> tuple[complex, complex, int]:
    """Linear least-squares single-mode fit of one FRF over all given lines.

    Parameters
    ----------
    data : ndarray of complex, shape (F,)
        One FRF on the fit band.
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    dt, n_samples : optional
        Discrete model; None for the continuous one.
    zeta_max : float
        Largest accepted damping ratio.
    prev : complex, optional
        A previous pole estimate: weights the rows by ``1 / |D_prev|`` (Sanathanan-Koerner).

    Returns
    -------
    lam, residue : complex
    code : int
        ``FIT_OK`` (0) for a physical fit, else a ``FIT_*`` rejection code.
    """
    omega = checked_omega(omega)
    data = check_frf(data, omega)
    if data.ndim != 1:
        raise AmiXrValueError(f"data: expected one FRF of shape {omega.shape}, got {data.shape}")
    dt = as_dt(dt)
    grid = Grid(omega, line_variable(omega, dt), dt, int(n_samples or 0))
    ws = float(np.mean(omega)) or 1.0
    limits = FitLimits(check_zeta_max(zeta_max), 0.0, np.inf)
    return fit_single(data, grid, 0, omega.size, ws, limits, _check_prev(prev))


def fit_single_mode_simo(
    data: np.ndarray,
    omega: np.ndarray,
    dt: float | None = None,
    n_samples: int | None = None,
    *,
    zeta_max: float = 1.0,
    prev: complex | None = None,
) -> tuple[complex, np.ndarray, int]:
    """Global SIMO single-mode fit: one eigenvalue from all rows of ``data``, one residue each.

    Parameters are those of :func:`fit_single_mode`, with ``data`` of shape (P, F).

    Returns
    -------
    lam : complex
    residues : ndarray of complex, shape (P,)
    code : int
    """
    omega = checked_omega(omega)
    data = check_frf(np.atleast_2d(data), omega)
    if data.ndim != 2:
        raise AmiXrValueError(f"data: expected shape (P, {omega.size}), got {data.shape}")
    dt = as_dt(dt)
    x = line_variable(omega, dt)
    res = np.full(data.shape[0], complex(np.nan, np.nan))
    ws = float(np.mean(omega)) or 1.0
    limits = FitLimits(check_zeta_max(zeta_max), 0.0, np.inf)
    grid = Grid(omega, x, dt, int(n_samples or 0))
    lam, code = fit_single_simo(
        data, grid, 0, omega.size, ws, limits, _check_prev(prev), np.ones(data.shape[0]), res
    )
    return lam, res, code
