"""The modal model, written once: the basis b(lam, w) of one mode with unit residue, its
derivative, the residual terms, synthesis and per-mode contribution peaks.

Two models of the data:

* continuous time (the paper's eq. 4): ``1/(i w - lam)`` and, for the conjugate term,
  ``1/(i w - conj(lam))``;
* discrete time, for FRFs made as ``dt * DFT`` of an impulse response sampled at ``dt``: the
  exact contribution of ``A exp(lam t)`` is ``dt / (1 - exp((lam - i w) dt))`` (the rectangle rule
  plus all aliases), and likewise for the conjugate term. With the record length ``n`` known and
  ``w`` on the DFT grid, the truncation of the record multiplies it by ``1 - exp(lam n dt)``.

``dt <= 0`` (``dt=None`` in the wrappers) selects the continuous model everywhere. A mode with
residue ``A = A1 + i A2`` contributes ``A * b(lam) + conj(A) * b(conj(lam))``.

The jitted kernels (the AMI phases' per-line evaluation, ``pole_factor`` then
``scale / (1 - p q)``) and the numpy functions (whole arrays at once: :func:`_unit_basis` and
:func:`basis_and_derivative`) evaluate the same b(lam, w); only what the AMI kernels call from
nopython code is jitted, since every jitted function costs compile time on a first run.

The :class:`Grid` record carries ``(omega, x, dt, n_samples)`` between kernels. Jitted,
unchecked helpers for the other kernel modules: ``nearest_line``, ``line_variable``,
``pole_factor``, ``add_mode``, ``mode_basis``, ``contribution_peak``,
``tolerance_envelope``. Checked wrappers: :func:`pole_basis`,
:func:`mode_contribution`, :func:`basis_and_derivative`, :func:`model_columns`,
:func:`synthesize`, :func:`synthesize_residual_terms`, :func:`contribution_peaks`;
:func:`checked_omega` and :func:`as_dt` are the argument checks the other wrappers share.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit

RESIDUAL_TERMS = ("lower", "upper")
"""Names of the residual terms: ``lower`` (below the band) and ``upper`` (above it)."""


class Grid(NamedTuple):
    """The frequency lines of a kernel's FRFs and the data model, travelling together."""

    omega: np.ndarray
    """Angular frequencies in rad/s, (F,) strictly increasing."""
    x: np.ndarray
    """``line_variable(omega, dt)``, (F,) complex."""
    dt: float
    """Sample interval of the discrete model; 0.0 for the continuous one."""
    n_samples: int
    """Record length of the discrete model (0: no truncation factor)."""


# ----------------------------------------------------------------------------------------------
# one mode on a grid of lines: the AMI kernels' evaluation (eqs. 4, 6, 7)
# ----------------------------------------------------------------------------------------------
@jit
def nearest_line(omega, w):
    """Index of the line of the ascending grid ``omega`` nearest to ``w`` (the lower one on a
    tie; the first or last line outside the grid)."""
    n = omega.shape[0]
    lo = 0
    hi = n - 1
    if w <= omega[0]:
        return 0
    if w >= omega[n - 1]:
        return n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if omega[mid] <= w:
            lo = mid
        else:
            hi = mid
    return lo if (w - omega[lo]) <= (omega[hi] - w) else hi


def line_variable(omega, dt):
    """``q = exp(-i w dt)`` for the discrete model, ``i w`` for the continuous one (dt <= 0),
    (F,) complex. Plain numpy: only Python code calls it (the kernels get it in a :class:`Grid`),
    so it costs no compilation."""
    omega = np.asarray(omega, dtype=np.float64)
    return np.exp(-1j * omega * dt) if dt > 0.0 else 1j * omega


@jit
def pole_factor(lam, dt, n_samples):
    """``(p, scale)``: discrete ``p = exp(lam dt)``, ``scale = dt (1 - exp(lam N dt))``."""
    if dt > 0.0:
        scale = dt + 0j
        if n_samples > 0:
            scale = dt * (1.0 - np.exp(lam * (n_samples * dt)))
        return np.exp(lam * dt), scale
    return lam, 1.0 + 0j


@jit
def add_mode(out, x, lam, res, dt, n_samples, sign, lo, hi):
    """``out[lo:hi] += sign * (A b(lam) + conj(A) b(conj(lam)))`` on lines ``lo..hi-1``."""
    p, sc = pole_factor(lam, dt, n_samples)
    pc = np.conj(p)
    scc = np.conj(sc)
    rc = np.conj(res)
    for i in range(lo, hi):
        # the unit-residue basis at one line: scale / (1 - p q) or 1 / (i w - lam)
        if dt > 0.0:
            v = res * (sc / (1.0 - p * x[i])) + rc * (scc / (1.0 - pc * x[i]))
        else:
            v = res * (1.0 / (x[i] - p)) + rc * (1.0 / (x[i] - pc))
        out[i] += sign * v


@jit
def mode_basis(x, lam, dt, n_samples, br, bi, bcr, bci, lo, hi):
    """Unit-residue bases ``b(lam)``, ``b(conj lam)`` on lines ``lo..hi-1`` (as in
    :func:`add_mode`), real and imaginary parts apart, so the SIMO sweeps synthesise modes with
    (vectorisable) real multiplications only and identical values."""
    p, sc = pole_factor(lam, dt, n_samples)
    pc = np.conj(p)
    scc = np.conj(sc)
    for i in range(lo, hi):
        if dt > 0.0:
            v = sc / (1.0 - p * x[i])
            vc = scc / (1.0 - pc * x[i])
        else:
            v = 1.0 / (x[i] - p)
            vc = 1.0 / (x[i] - pc)
        br[i] = v.real
        bi[i] = v.imag
        bcr[i] = vc.real
        bci[i] = vc.imag


# ----------------------------------------------------------------------------------------------
# the reference evaluation and the refinement's basis with its derivative
# ----------------------------------------------------------------------------------------------
def _unit_basis(omega: np.ndarray, lam, dt: float, n_samples: int) -> np.ndarray:
    """``b(lam)`` on the lines ``omega`` (F,) for poles ``lam`` of any shape -> ``lam.shape +
    (F,)``: ``scale / (1 - p q)`` with ``p = exp(lam dt)``, ``q = exp(-i w dt)`` and ``scale =
    dt (1 - exp(lam n dt))`` (``dt`` when ``n_samples <= 0``), or ``1 / (i w - lam)`` for
    ``dt <= 0`` -- the arithmetic of :func:`add_mode`, on whole arrays."""
    lam = np.asarray(lam, dtype=np.complex128)[..., None]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if dt > 0.0:
            scale = dt * (1.0 - np.exp(lam * (n_samples * dt))) if n_samples > 0 else dt + 0j
            return scale / (1.0 - np.exp(lam * dt) * np.exp(-1j * omega * dt))
        return 1.0 / (1j * omega - lam)


# ----------------------------------------------------------------------------------------------
# residual terms (lower / upper) and contribution peaks
# ----------------------------------------------------------------------------------------------
def residual_columns(omega: np.ndarray, kind: int) -> tuple[np.ndarray, np.ndarray]:
    """The lower and upper residual terms on the lines ``omega``: ``kind`` 0 receptance
    (``1/(i w)^2``, ``1``), 1 mobility (``1/(i w)``, ``i w``), 2 accelerance (``1``,
    ``(i w)^2``); a term singular at 0 rad/s is 0 there."""
    s = 1j * omega
    with np.errstate(divide="ignore", invalid="ignore"):
        lower = (1.0 / s**2, 1.0 / s, np.ones_like(s))[kind]
    lower = np.where(omega == 0.0, 0.0, lower) if kind < 2 else lower
    upper = (np.ones_like(s), s, s**2)[kind]
    return lower, upper


@jit
def contribution_peak(omega, x, lam, res, dt, n_samples):
    """Largest |contribution| of one mode over the three lines nearest its damped frequency."""
    c = nearest_line(omega, lam.imag)
    lo = max(c - 1, 0)
    hi = min(c + 2, omega.shape[0])
    p, sc = pole_factor(lam, dt, n_samples)
    pc = np.conj(p)
    scc = np.conj(sc)
    rc = np.conj(res)
    best = 0.0
    for i in range(lo, hi):
        if dt > 0.0:
            v = res * (sc / (1.0 - p * x[i])) + rc * (scc / (1.0 - pc * x[i]))
        else:
            v = res * (1.0 / (x[i] - p)) + rc * (1.0 / (x[i] - pc))
        best = max(best, abs(v))
    return best


def _contribution_peaks(omega, dt, n_samples, lam, res):
    """Peak |contribution| of every (point, mode): ``lam`` (P or 1, K), ``res`` (P, K); the
    arithmetic of :func:`contribution_peak` on whole arrays (only Python calls it: no
    compilation)."""
    n_f = omega.shape[0]
    lam = np.broadcast_to(lam, res.shape)
    valid = ~(np.isnan(lam.real) | np.isnan(res.real))
    lam = np.where(valid, lam, 0.0j)  # placeholders, NaN again at the end
    # nearest line to Im lam (the lower on a tie), as nearest_line
    w = lam.imag
    lo = np.clip(np.searchsorted(omega, w, side="right") - 1, 0, n_f - 2)
    centre = np.where((w - omega[lo]) <= (omega[lo + 1] - w), lo, lo + 1)
    centre = np.where(w <= omega[0], 0, np.where(w >= omega[-1], n_f - 1, centre))
    x = line_variable(omega, dt)
    best = np.zeros(res.shape)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if dt > 0.0:  # pole_factor
            p = np.exp(lam * dt)
            sc = dt * (1.0 - np.exp(lam * (n_samples * dt))) if n_samples > 0 else dt + 0j
        else:
            p, sc = lam, 1.0 + 0j
        pc, scc, rc = np.conj(p), np.conj(sc), np.conj(res)
        for off in (-1, 0, 1):
            line = centre + off
            inside = (line >= 0) & (line < n_f)
            xi = x[np.clip(line, 0, n_f - 1)]
            if dt > 0.0:
                v = res * (sc / (1.0 - p * xi)) + rc * (scc / (1.0 - pc * xi))
            else:
                v = res * (1.0 / (xi - p)) + rc * (1.0 / (xi - pc))
            size = np.abs(v)
            best = np.where(inside & (size > best), size, best)  # max() as the kernel takes it
    return np.where(valid, best, np.nan)


@jit
def tolerance_envelope(omega, lam, res, n, tol):
    """Envelope of the residual that eigenvalue errors of relative size ``tol`` leave behind:
    ``tol |lam_k| |A_k| / |i w - lam_k|^2`` summed over modes (continuous-time approximation of
    ``|d contribution / d lam| tol |lam|``). A peak inside it is not evidence of a missing mode."""
    n_f = omega.shape[0]
    env = np.zeros(n_f)
    for k in range(n):
        lk = lam[k]
        a = tol * abs(lk) * abs(res[k])
        for i in range(n_f):
            d = 1j * omega[i] - lk
            env[i] += a / (d.real * d.real + d.imag * d.imag)
    return env


# ----------------------------------------------------------------------------------------------
# checked wrappers
# ----------------------------------------------------------------------------------------------
def checked_omega(omega: np.ndarray) -> np.ndarray:
    """``omega`` as a contiguous float64 array, checked 1-D, finite and strictly increasing
    (>= 2 lines).

    Raises :class:`~ami_xr.errors.AmiXrValueError` naming ``omega`` otherwise.
    """
    omega = np.ascontiguousarray(omega, dtype=np.float64)
    # isfinite too: an infinite first or last line still passes the diff test
    if (
        omega.ndim != 1
        or omega.size < 2
        or not np.all(np.isfinite(omega))
        or not np.all(np.diff(omega) > 0)
    ):
        raise AmiXrValueError(
            "omega: expected a 1-D, finite, strictly increasing array of angular frequencies"
        )
    return omega


def as_dt(dt: float | None) -> float:
    """The kernels' ``dt``: the sample interval, or 0.0 (continuous model) for None or 0."""
    return float(dt) if dt else 0.0


def _check_model(dt: float, n_samples: int | None) -> int:
    if dt < 0.0 or not np.isfinite(dt):
        raise AmiXrValueError(f"dt: expected a positive sample interval or None, got {dt!r}")
    n = int(n_samples or 0)
    if n < 0:
        raise AmiXrValueError(
            f"n_samples: expected a non-negative count or None, got {n_samples!r}"
        )
    return n


def pole_basis(
    omega: np.ndarray, lam: complex, dt: float | None = None, n_samples: int | None = None
) -> np.ndarray:
    """Contribution of ``exp(lam t)`` (unit residue) to the FRF at angular frequencies ``omega``.

    Parameters
    ----------
    omega : ndarray of float, shape (n,)
        Angular frequencies in rad/s.
    lam : complex
        Pole in rad/s.
    dt : float, optional
        Sample interval in s when the FRF is ``dt * DFT`` of a sampled impulse response;
        ``None`` for the continuous-time model.
    n_samples : int, optional
        Record length of that impulse response; includes the truncation factor
        ``1 - exp(lam n dt)``, exact when ``omega`` lies on the DFT grid ``2 pi k / (n dt)``.
    """
    omega = np.ascontiguousarray(omega, dtype=np.float64)
    if omega.ndim != 1:
        raise AmiXrValueError(
            f"omega: expected a 1-D array of angular frequencies, got shape {omega.shape}"
        )
    return _unit_basis(omega, complex(lam), float(dt) if dt else 0.0, int(n_samples or 0))


def mode_contribution(
    omega: np.ndarray,
    lam: complex,
    residue: complex,
    dt: float | None = None,
    n_samples: int | None = None,
) -> np.ndarray:
    """One mode's contribution ``A b(lam) + conj(A) b(conj(lam))`` (eq. 4 or its discrete form)."""
    return residue * pole_basis(omega, lam, dt, n_samples) + np.conj(residue) * pole_basis(
        omega, np.conj(lam), dt, n_samples
    )


def basis_and_derivative(
    omega: np.ndarray, lam: np.ndarray, dt: float | None = None, n_samples: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Modal basis ``b(lam_k, w)`` and its derivative with respect to ``lam_k``.

    Parameters
    ----------
    omega : ndarray of float, shape (L,)
        Angular frequencies in rad/s.
    lam : ndarray of complex, shape (K,)
        Poles in rad/s.
    dt, n_samples : optional
        Sample interval and record length of the impulse response when the FRF is
        ``dt * DFT`` of it (exact discrete basis); ``None`` for the continuous basis.

    Returns
    -------
    b, db : ndarray of complex, shape (K, L)
    """
    omega = np.ascontiguousarray(omega, dtype=np.float64)
    lam = np.ascontiguousarray(np.atleast_1d(lam), dtype=np.complex128)
    if omega.ndim != 1:
        raise AmiXrValueError(f"omega: expected a 1-D array, got shape {omega.shape}")
    if lam.ndim != 1:
        raise AmiXrValueError(f"lam: expected a 1-D array of poles, got shape {lam.shape}")
    dt = float(dt) if dt else 0.0
    return _basis_on_lines(line_variable(omega, dt)[None, :], lam[:, None], dt, int(n_samples or 0))


def _basis_on_lines(x: np.ndarray, lam: np.ndarray, dt: float, n: int):
    """``b(lam, w)`` and its derivative by ``lam`` for the line variable ``x``
    (:func:`line_variable`) and poles ``lam``, broadcast against each other."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if dt > 0.0:
            # b = dt s / (1 - e), e = exp((lam - i w) dt), s = 1 - exp(lam n dt) (1 if n <= 0);
            # d/dlam [dt s / (1 - e)] = dt (ds (1 - e) + s dt e) / (1 - e)^2
            s, ds = 1.0 + 0j, 0.0j
            if n > 0:
                e_n = np.exp(lam * (n * dt))
                s, ds = 1.0 - e_n, -(n * dt) * e_n
            e = np.exp(lam * dt) * x
            den = 1.0 - e
            return dt * s / den, dt * (ds * den + s * dt * e) / (den * den)
        den = x - lam
        return 1.0 / den, 1.0 / (den * den)


def model_columns(
    omega: np.ndarray,
    lam: np.ndarray,
    dt: float | None,
    n_samples: int | None,
    residual_terms: tuple[str, ...] = (),
    residual_kind: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Complex columns of the real-linear model and of its derivative.

    Returns ``phi`` (L, 2K + 2R) -- columns multiplying ``A1_k``, ``A2_k`` for each mode and the
    real and imaginary coefficient of each residual term (``residual_kind`` 0 receptance:
    lower ``1/(i w)^2``, upper ``1``; 1 mobility: ``1/(i w)``, ``i w``; 2 accelerance: ``1``,
    ``(i w)^2``; a term singular at 0 Hz is 0 there) -- and ``dphi`` (L, 2K) -- the vectors
    ``u_k = b'(lam) + b'(conj lam)`` and ``v_k = i (b'(lam) - b'(conj lam))``, so that the
    derivative of the model of a point with residue ``A1 + i A2`` is
    ``A1 u + A2 v`` with respect to ``Re lam`` and ``A1 v - A2 u`` with respect to ``Im lam``.
    """
    for term in residual_terms:
        if term not in RESIDUAL_TERMS:
            raise AmiXrValueError(
                f"residual_terms: expected entries in {RESIDUAL_TERMS}, got {term!r}"
            )
    lam = np.ascontiguousarray(np.atleast_1d(lam), dtype=np.complex128)
    omega = np.ascontiguousarray(omega, dtype=np.float64)
    n_mode = lam.shape[0]
    both = np.concatenate([lam, np.conj(lam)])
    b, db = basis_and_derivative(omega, both, dt, n_samples)
    b_l, b_c = b[:n_mode], b[n_mode:]
    d_l, d_c = db[:n_mode], db[n_mode:]
    n_res = len(residual_terms)
    phi = np.empty((omega.shape[0], 2 * n_mode + 2 * n_res), dtype=np.complex128)
    phi[:, 0 : 2 * n_mode : 2] = (b_l + b_c).T
    phi[:, 1 : 2 * n_mode : 2] = (1j * (b_l - b_c)).T
    lower, upper = residual_columns(omega, residual_kind)
    for r, term in enumerate(residual_terms):
        col = lower if term == "lower" else upper
        phi[:, 2 * n_mode + 2 * r] = col
        phi[:, 2 * n_mode + 2 * r + 1] = 1j * col
    dphi = np.empty((omega.shape[0], 2 * n_mode), dtype=np.complex128)
    dphi[:, 0::2] = (d_l + d_c).T
    dphi[:, 1::2] = (1j * (d_l - d_c)).T
    return phi, dphi


def synthesize(
    omega: np.ndarray,
    lam: np.ndarray,
    residue: np.ndarray,
    dt: float | None = None,
    n_samples: int | None = None,
) -> np.ndarray:
    """Sum of modal contributions (eq. 4 or its exact discrete form).

    Parameters
    ----------
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    lam : ndarray of complex, shape (K,), (1, K) or (P, K)
        Eigenvalues (one row shared by all FRFs, or one row per FRF).
    residue : ndarray of complex, shape (P, K)
        Residues. Modes whose eigenvalue or residue is NaN (padding) are skipped.
    dt, n_samples : optional
        Discrete model (see the module docstring); None for the continuous one.

    Returns
    -------
    ndarray of complex, shape (P, F)
    """
    omega = checked_omega(omega)
    dt = as_dt(dt)
    n_samples = _check_model(dt, n_samples)
    residue = np.ascontiguousarray(np.atleast_2d(residue), dtype=np.complex128)
    lam = np.ascontiguousarray(np.atleast_2d(lam), dtype=np.complex128)
    if residue.ndim != 2:
        raise AmiXrValueError(f"residue: expected shape (P, K), got {residue.shape}")
    if (
        lam.ndim != 2
        or lam.shape[-1] != residue.shape[-1]
        or lam.shape[0] not in (1, residue.shape[0])
    ):
        raise AmiXrValueError(
            f"lam: shape {lam.shape} does not match residue shape {residue.shape}"
        )
    out = np.zeros((residue.shape[0], omega.shape[0]), dtype=np.complex128)
    with np.errstate(invalid="ignore"):
        for k in range(residue.shape[1]):
            lk, rk = lam[:, k, None], residue[:, k, None]
            contribution = rk * _unit_basis(omega, lam[:, k], dt, n_samples) + np.conj(
                rk
            ) * _unit_basis(omega, np.conj(lam[:, k]), dt, n_samples)
            # NaN eigenvalues or residues are padding: skipped
            skip = np.isnan(lk.real) | np.isnan(rk.real)
            out += np.where(skip, 0.0, contribution)
    return out


def synthesize_residual_terms(
    omega: np.ndarray, coef: np.ndarray, residual_kind: int
) -> np.ndarray:
    """Sum of the lower and upper residual terms of each FRF.

    Parameters
    ----------
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    coef : ndarray of complex, shape (P, 2)
        Coefficients of the lower and upper term per FRF.
    residual_kind : {0, 1, 2}
        0 receptance (``1/(i w)^2``, ``1``), 1 mobility (``1/(i w)``, ``i w``), 2 accelerance
        (``1``, ``(i w)^2``); a term singular at 0 rad/s is 0 there, and for receptance the
        whole line at 0 rad/s (upper term included) is left at 0.

    Returns
    -------
    ndarray of complex, shape (P, F)
    """
    omega = checked_omega(omega)
    coef = np.ascontiguousarray(np.atleast_2d(coef), dtype=np.complex128)
    if coef.ndim != 2 or coef.shape[1] != 2:
        raise AmiXrValueError(f"coef: expected shape (P, 2), got {coef.shape}")
    if residual_kind not in (0, 1, 2):
        raise AmiXrValueError(f"residual_kind: expected 0, 1 or 2, got {residual_kind!r}")
    lower, upper = residual_columns(omega, int(residual_kind))
    out = coef[:, 0, None] * lower + coef[:, 1, None] * upper
    if residual_kind == 0:
        out[:, omega == 0.0] = 0.0  # receptance: the whole line at 0 rad/s is left at 0
    return out


def contribution_peaks(
    omega: np.ndarray,
    dt: float | None,
    n_samples: int | None,
    lam: np.ndarray,
    res: np.ndarray,
) -> np.ndarray:
    """Peak ``|contribution|`` of every (FRF, mode) over the three lines nearest its damped
    natural frequency.

    Parameters
    ----------
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, strictly increasing.
    dt, n_samples : float or None, int or None
        Discrete model (see the module docstring); None for the continuous one.
    lam : ndarray of complex, shape (1, K) or (P, K)
        Eigenvalues, shared by all FRFs or one row per FRF.
    res : ndarray of complex, shape (P, K)
        Residues.

    Returns
    -------
    ndarray of float, shape (P, K)
        NaN where the eigenvalue or the residue is NaN.
    """
    omega = checked_omega(omega)
    dt = as_dt(dt)
    n_samples = _check_model(dt, n_samples)
    res = np.ascontiguousarray(res, dtype=np.complex128)
    lam = np.ascontiguousarray(lam, dtype=np.complex128)
    if res.ndim != 2:
        raise AmiXrValueError(f"res: expected shape (P, K), got {res.shape}")
    if lam.ndim != 2 or lam.shape[1] != res.shape[1] or lam.shape[0] not in (1, res.shape[0]):
        raise AmiXrValueError(f"lam: shape {lam.shape} does not match res shape {res.shape}")
    return _contribution_peaks(omega, dt, n_samples, lam, res)
