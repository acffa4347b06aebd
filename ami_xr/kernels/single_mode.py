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
kernel modules: ``fit_single`` (one eigenvalue from one or many FRFs: the fit step of the
isolation engine, :mod:`.isolate`, and of the peak trial, :mod:`.peak`) and ``pole_code``.
Checked wrappers: :func:`single_mode_rows`, :func:`fit_single_mode` (one FRF or many).
A fit returns one of the ``FIT_*`` codes below; ``FitLimits``
holds the limits a pole must meet.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit
from ami_xr.kernels.linalg import solve2
from ami_xr.kernels.modal_basis import Grid, as_dt, checked_omega, line_variable, pole_factor

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


@jit(inline="always")
def _single_mode_blocks(data, x, lo, hi, ws, dt, gscale, prev):
    """The normal equations of (*) on lines lo..hi-1 of one FRF, as scalars.

    Unknowns: shared ``s = (c0, c1)``, local ``l = (e0, e1)``. Columns of (*) written as
    ``G v^2 = -c0 G - c1 G v + e0 + e1 v``; the data is divided by ``gscale``.
    Returns ``(nss, nsl, nll, rs, rl)`` flattened, 16 floats: the 2x2 blocks ``nss``, ``nsl``,
    ``nll`` row by row, then the right sides ``rs`` and ``rl`` (2 each).
    When ``prev`` (a previous pole estimate) is not NaN every line is divided by
    ``|D_prev(v)| = |(v - v1)(v - conj(v1))|`` (Sanathanan-Koerner / Steiglitz-McBride): at a
    fixed point the equation error becomes the output error ``G - N/D``, which removes the
    damping bias that noise in the regressor columns gives the plain eqs. 11-12.
    Scalars, not small arrays: a quarter of the compiled code (first-run compile time).
    """
    ss00 = ss01 = ss10 = ss11 = 0.0
    sl00 = sl01 = sl10 = sl11 = 0.0
    ll00 = ll01 = ll10 = ll11 = 0.0
    rs0 = rs1 = rl0 = rl1 = 0.0
    use_w = not np.isnan(prev.real)
    # v of a line (and the root v1 of the previous pole): (1 - q) / (dt ws) or i w / ws
    discrete = dt > 0.0
    pv = 0j
    if use_w:
        pv = (1.0 - np.exp(-prev * dt)) / (dt * ws) if discrete else prev / ws
    for i in range(lo, hi):
        g = data[i] / gscale
        v = (1.0 - x[i]) / (dt * ws) if discrete else x[i] / ws
        wgt = 1.0
        if use_w:
            wgt = 1.0 / abs((v - pv) * (v - np.conj(pv)))
        c0 = -g * wgt
        c1 = -g * v * wgt
        c2 = complex(wgt, 0.0)
        c3 = v * wgt
        rhs = g * v * v * wgt
        k0 = np.conj(c0)
        k1 = np.conj(c1)
        k2 = np.conj(c2)
        k3 = np.conj(c3)
        ss00 += (k0 * c0).real
        ss01 += (k0 * c1).real
        ss10 += (k1 * c0).real
        ss11 += (k1 * c1).real
        sl00 += (k0 * c2).real
        sl01 += (k0 * c3).real
        sl10 += (k1 * c2).real
        sl11 += (k1 * c3).real
        ll00 += (k2 * c2).real
        ll01 += (k2 * c3).real
        ll10 += (k3 * c2).real
        ll11 += (k3 * c3).real
        rs0 += (k0 * rhs).real
        rs1 += (k1 * rhs).real
        rl0 += (k2 * rhs).real
        rl1 += (k3 * rhs).real
    return (
        ss00, ss01, ss10, ss11, sl00, sl01, sl10, sl11, ll00, ll01, ll10, ll11, rs0, rs1, rl0, rl1
    )  # fmt: skip


@jit
def fit_single(data, grid, lo, hi, ws, limits, prev, wts, res_out):
    """Single-mode fit on lines lo..hi-1 of the rows of ``data`` (P, F): one eigenvalue shared
    by all rows (P = 1: one FRF), one residue per row written to ``res_out`` (P,). Row ``j`` is
    weighted by ``wts[j]`` (its data divided by ``1 / wts[j]``); ``prev``: a previous pole
    estimate (NaN: none) that weights the lines by ``1 / |D_prev|``. Returns ``(lam, code)``.

    The per-row unknowns ``(e0, e1)`` are eliminated by their 2x2 Schur complements, so the cost
    is linear in the number of rows.
    """
    x, dt, n_samples = grid.x, grid.dt, grid.n_samples
    n_p = data.shape[0]
    nanc = complex(np.nan, np.nan)
    if hi - lo < 2:
        return nanc, FIT_SINGULAR
    red00 = red01 = red10 = red11 = 0.0
    redr0 = redr1 = 0.0
    keep = np.empty((n_p, 10))  # per row: nsl, nll (row by row), rl: for the residues
    for j in range(n_p):
        blocks = _single_mode_blocks(data[j], x, lo, hi, ws, dt, 1.0 / wts[j], prev)
        ss00, ss01, ss10, ss11, sl00, sl01, sl10, sl11 = blocks[:8]
        ll00, ll01, ll10, ll11, rs0, rs1, rl0, rl1 = blocks[8:]
        kj = keep[j]
        kj[0], kj[1], kj[2], kj[3], kj[4] = sl00, sl01, sl10, sl11, ll00
        kj[5], kj[6], kj[7], kj[8], kj[9] = ll01, ll10, ll11, rl0, rl1
        det = ll00 * ll11 - ll01 * ll10
        if not (det != 0.0 and np.isfinite(det)):
            return nanc, FIT_SINGULAR
        # red += nss - nsl nll^-1 nls ; redr += rs - nsl nll^-1 rl  (2x2 by hand: a BLAS call
        # per FRF cost more than the fit)
        t00 = (sl00 * ll11 - sl01 * ll10) / det
        t01 = (sl01 * ll00 - sl00 * ll01) / det
        t10 = (sl10 * ll11 - sl11 * ll10) / det
        t11 = (sl11 * ll00 - sl10 * ll01) / det
        red00 += ss00 - (t00 * sl00 + t01 * sl01)
        red01 += ss01 - (t00 * sl10 + t01 * sl11)
        red10 += ss10 - (t10 * sl00 + t11 * sl01)
        red11 += ss11 - (t10 * sl10 + t11 * sl11)
        redr0 += rs0 - (t00 * rl0 + t01 * rl1)
        redr1 += rs1 - (t10 * rl0 + t11 * rl1)
    c0, c1, ok = solve2(red00, red01, red10, red11, redr0, redr1)
    if not ok:
        return nanc, FIT_SINGULAR
    # the pole: root v1 (Im > 0) of v^2 + c1 v + c0
    disc = 4.0 * c0 - c1 * c1
    if not (disc > 0.0) or not np.isfinite(disc):
        return nanc, FIT_NOT_OSCILLATORY
    sq = math.sqrt(disc)
    v1 = complex(-0.5 * c1, 0.5 * sq)
    v2 = complex(-0.5 * c1, -0.5 * sq)
    if dt > 0.0:
        q1 = 1.0 - dt * ws * v1
        if abs(q1) == 0.0:
            return nanc, FIT_UNSTABLE
        lam = np.log(1.0 / q1) / dt
    else:
        lam = ws * v1
    code = pole_code(lam, limits)
    if code != FIT_OK:
        return lam, code
    # residues by partial fractions: r = (e1 v1 + e0) / (v1 - v2), A = ws r (continuous) or
    # p dt ws r / (dt (1 - exp(lam N dt))) (discrete)
    factor = ws / (v1 - v2)
    if dt > 0.0:
        p, sc = pole_factor(lam, dt, n_samples)
        factor = factor * p * dt / sc
    for j in range(n_p):
        sl00, sl01, sl10, sl11, ll00 = keep[j, 0], keep[j, 1], keep[j, 2], keep[j, 3], keep[j, 4]
        ll01, ll10, ll11, rl0, rl1 = keep[j, 5], keep[j, 6], keep[j, 7], keep[j, 8], keep[j, 9]
        b0 = rl0 - (sl00 * c0 + sl10 * c1)
        b1 = rl1 - (sl01 * c0 + sl11 * c1)
        det = ll00 * ll11 - ll01 * ll10
        e0 = (ll11 * b0 - ll01 * b1) / det
        e1 = (-ll10 * b0 + ll00 * b1) / det
        res_out[j] = (e1 * v1 + e0) * factor / wts[j]
    return lam, FIT_OK


@jit
def pole_code(lam, limits):
    """``FIT_OK``, or the ``FIT_*`` code of the first limit the pole ``lam`` breaks."""
    if not (lam.real < 0.0):
        return FIT_UNSTABLE
    wn = abs(lam)
    if -lam.real / wn > limits.zeta_max or lam.imag <= 0.0:
        return FIT_DAMPING
    if wn < limits.w_lo or wn > limits.w_hi:
        return FIT_OUT_OF_RANGE
    return FIT_OK


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


def single_mode_rows(
    data: np.ndarray, omega: np.ndarray, scale: float, dt: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Real least-squares rows and right side of the single-mode equation (*) (eqs. 11-12 when
    ``dt`` is None), unweighted, for tests and references.

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
    dt = as_dt(dt)
    x = line_variable(omega, dt)
    v = (1.0 - x) / (dt * scale) if dt > 0.0 else x / scale
    cols = np.stack([-data, -data * v, np.ones_like(data), v], axis=-1)
    rhs = data * v * v
    rows = np.empty((2 * omega.size, 4))
    rows[0::2], rows[1::2] = cols.real, cols.imag
    return rows, np.ravel(np.column_stack([rhs.real, rhs.imag]))


def fit_single_mode(
    data: np.ndarray,
    omega: np.ndarray,
    dt: float | None = None,
    n_samples: int | None = None,
    *,
    zeta_max: float = 1.0,
    prev: complex | None = None,
) -> tuple[complex, complex | np.ndarray, int]:
    """Linear least-squares single-mode fit over all given lines: of one FRF, or (global SIMO
    fit) one eigenvalue from all rows of ``data`` with one residue each (each row scaled by its
    largest magnitude, so the rows weigh alike).

    Parameters
    ----------
    data : ndarray of complex, shape (F,) or (P, F)
        One FRF, or P FRFs, on the fit band.
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
    lam : complex
    residue : complex, or ndarray of complex of shape (P,) for 2-D ``data``
    code : int
        ``FIT_OK`` (0) for a physical fit, else a ``FIT_*`` rejection code.
    """
    omega = checked_omega(omega)
    data = check_frf(data, omega)
    one = data.ndim == 1
    if data.ndim not in (1, 2):
        raise AmiXrValueError(
            f"data: expected shape ({omega.size},) or (P, {omega.size}), got {data.shape}"
        )
    rows = data[None, :] if one else data
    dt = as_dt(dt)
    res = np.full(rows.shape[0], complex(np.nan, np.nan))
    peak = np.max(np.abs(rows), axis=1) if rows.size else np.zeros(rows.shape[0])
    lam, code = complex(np.nan, np.nan), FIT_SINGULAR
    if np.all(peak > 0.0):  # an all-zero row: nothing to fit
        ws = float(np.mean(omega)) or 1.0
        limits = FitLimits(check_zeta_max(zeta_max), 0.0, np.inf)
        grid = Grid(omega, line_variable(omega, dt), dt, int(n_samples or 0))
        prev = complex(np.nan, np.nan) if prev is None else complex(prev)
        lam, code = fit_single(rows, grid, 0, omega.size, ws, limits, prev, 1.0 / peak, res)
    return lam, (res[0] if one else res), code
