"""Isolation Phase of the AMI (eq. 7) with the model-order check: the checked wrappers of the
isolation engine (:mod:`.engine`) for the per-FRF isolation (:func:`isolate_batch`, every FRF
its own group), the global SIMO isolation (:func:`isolate_simo`, all FRFs one group) and the
per-FRF estimates of given system modes (:func:`point_estimates`).

The wrappers check their inputs, bring the data to units of each FRF's noise floor and the
residues back, and build the per-call constants (:func:`~.peak.scene`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels.engine import (
    DONE,
    SPLIT_WANTED,
    STOP_FRACTION,
    IsolateParams,
    IsolateResult,
    new_work,
    point_estimates_kernel,
)
from ami_xr.kernels.groups import isolate_groups, new_result, new_resume, split_fit
from ami_xr.kernels.peak import check_inputs, scene
from ami_xr.kernels.residues import residues_fixed_kernel

__all__ = [
    "STOP_FRACTION",
    "IsolateParams",
    "IsolateResult",
    "isolate_batch",
    "isolate_simo",
    "point_estimates",
]


# ----------------------------------------------------------------------------------------------
# checked wrappers
# ----------------------------------------------------------------------------------------------
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


def _check_sigma(sigma: np.ndarray, n_p: int, data: np.ndarray) -> np.ndarray:
    """``sigma`` (one noise floor per FRF row of ``data``), checked: positive and finite. The
    message names the rows and the values at fault and why such a value comes about."""
    sigma = np.ascontiguousarray(sigma, dtype=np.float64)
    if sigma.shape != (n_p,):
        raise AmiXrValueError(
            f"sigma: expected one noise floor per FRF, shape ({n_p},), got shape {sigma.shape}"
        )
    bad = ~(np.isfinite(sigma) & (sigma > 0.0))
    if bad.any():
        raise AmiXrValueError(_sigma_message(sigma, bad, data))
    return sigma


def _sigma_message(sigma: np.ndarray, bad: np.ndarray, data: np.ndarray) -> str:
    rows = np.flatnonzero(bad)
    values = sorted({float(v) for v in sigma[rows]}, key=repr)
    shown = ", ".join(str(int(r)) for r in rows[:10]) + (", ..." if rows.size > 10 else "")
    text = (
        f"sigma: expected a positive, finite noise floor (noise standard deviation) for each of "
        f"the {sigma.size} FRFs, got {', '.join(f'{v:g}' for v in values)} at FRF "
        f"row{'s' if rows.size > 1 else ''} {shown} (0-based, in point order)"
    )
    why = []
    if np.any(sigma[rows] == 0.0):
        why.append(
            "a noise floor of 0 means the FRF shows no noise at all: constant or noise-free "
            "data, or values too small to represent next to the largest value of the data (the "
            "FRFs are scaled together to their largest value)"
        )
        magnitude = np.abs(data)
        if magnitude.size and np.isfinite(magnitude).all():
            row, line = np.unravel_index(int(np.argmax(magnitude)), magnitude.shape)
            peak = float(magnitude[row, line])
            typical = magnitude[magnitude > 0.0]
            typical = float(np.median(typical)) if typical.size else 0.0
            with np.errstate(divide="ignore", over="ignore"):
                ratio = peak / typical if typical > 0.0 else np.inf
            if peak > 0.0 and ratio >= SPIKE_RATIO:
                how = f"{ratio:.3g} times" if np.isfinite(ratio) else "far above"
                why.append(
                    f"line {line} (of the lines analysed) of FRF row {row} is {how} the median "
                    "magnitude of the data: a spike? remove or clip it, or identify that FRF "
                    "apart"
                )
    if np.any(np.isnan(sigma[rows])) or np.any(np.isinf(sigma[rows])):
        why.append(
            "a NaN or infinite noise floor comes from NaN or infinite FRF values, or values so "
            "large that their squares overflow"
        )
    if np.any(sigma[rows] < 0.0):
        why.append("a noise floor is a standard deviation and cannot be negative")
    return (text + "; " + "; ".join(why)) if why else text


#: Largest value / median magnitude from which :func:`_check_sigma` names a line a spike.
SPIKE_RATIO = 1e12

#: Work (sweeps x FRFs x lines) of the isolation between two calls of ``between`` (the kernel
#: returns only between restarts: at 1000 points x 4096 lines, 15 compressed FRFs, the first
#: restart takes ~0.45 s CPU, the later ones 0.01-0.1 s each).
BETWEEN_WORK = 500_000


def _isolate(data, lam_in, res_in, n0, where, params, between):
    """:func:`~.groups.isolate_groups` on ``data`` (G, P, F), with the two-mode fits it asks for
    (:func:`~.groups.split_fit`); with ``between`` the kernel also returns between its restarts
    every :data:`BETWEEN_WORK` and ``between()`` runs (a pending interrupt raised there). The
    results are those of one pass."""
    n_g, n_p, _ = data.shape
    m = int(params.max_modes)
    out = new_result(n_g, n_p, m)
    state = new_resume(data, m)
    budget = BETWEEN_WORK if between is not None else 0
    while True:
        status, iso = isolate_groups(data, lam_in, res_in, n0, where, params, out, state, budget)
        if status == DONE:
            return out
        if status == SPLIT_WANTED:
            split_fit(iso, where, state)
        elif between is not None:
            between()


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
    *,
    between: Callable[[], None] | None = None,
) -> IsolateResult:
    """Isolation Phase with the model-order check on every FRF separately (each FRF a group).

    Parameters
    ----------
    data, omega, dt, n_samples
        FRFs (P, F), their lines and data model: see :func:`~.peak.check_inputs`.
    lam0, res0 : ndarray of complex, shape (P, S)
        Starting eigenvalues and residues (the Subtraction Phase's candidates).
    n0 : ndarray of int, shape (P,)
        Number of starting modes of each FRF.
    sigma : ndarray of float, shape (P,)
        Noise floor of each FRF.
    params : IsolateParams
        Settings (``reweight`` has no effect on one FRF).
    between : callable, optional
        Called between pieces of the work (about 0.1 s apart), e.g. an interrupt checkpoint.

    Returns
    -------
    IsolateResult
        ``lam``, ``res`` of shape (P, max_modes) (NaN-padded); ``n_modes``, ``iterations``,
        ``converged`` of shape (P,).
    """
    data, omega, dt, n = check_inputs(data, omega, dt, n_samples)
    check_params(params)
    n_p = data.shape[0]
    m = int(params.max_modes)
    lam0 = np.ascontiguousarray(lam0, dtype=np.complex128)
    res0 = np.ascontiguousarray(res0, dtype=np.complex128)
    if lam0.ndim != 2 or lam0.shape[0] != n_p or res0.shape != lam0.shape:
        raise AmiXrValueError(
            f"lam0, res0: expected equal shapes ({n_p}, S), got {lam0.shape}, {res0.shape}"
        )
    n0 = np.ascontiguousarray(n0, dtype=np.int64)
    if n0.shape != (n_p,) or np.any(n0 < 0) or np.any(n0 > lam0.shape[1]):
        raise AmiXrValueError(f"n0: expected {n_p} counts in 0..{lam0.shape[1]}, got {n0!r}")
    sigma = _check_sigma(sigma, n_p, data)
    s = min(lam0.shape[1], m)
    lam_in = np.full((n_p, m), complex(np.nan, np.nan))
    res_in = np.full((n_p, 1, m), complex(np.nan, np.nan))
    lam_in[:, :s] = lam0[:, :s]
    res_in[:, 0, :s] = res0[:, :s] / sigma[:, None]
    where = scene(omega, dt, n, params.zeta_max, params.pfa, 1)
    scaled = (data / sigma[:, None])[:, None, :]
    out = _isolate(scaled, lam_in, res_in, np.minimum(n0, m), where, params, between)
    return out._replace(res=out.res[:, 0, :] * sigma[:, None])


def isolate_simo(
    data: np.ndarray,
    omega: np.ndarray,
    dt: float | None,
    n_samples: int | None,
    lam0: np.ndarray,
    n0: int,
    sigma: np.ndarray,
    params: IsolateParams,
    *,
    between: Callable[[], None] | None = None,
) -> IsolateResult:
    """Global SIMO isolation with the model-order check (all FRFs one group).

    ``data``, ``omega``, ``dt``, ``n_samples``, ``sigma``, ``params`` and ``between`` are those
    of :func:`isolate_batch`.

    Parameters
    ----------
    lam0 : ndarray of complex, shape (S,)
        Starting eigenvalues; the first ``n0`` are used (their starting residues: linear least
        squares with the eigenvalues fixed, over all lines).
    n0 : int
        Number of starting modes.

    Returns
    -------
    IsolateResult
        ``lam`` (max_modes,) and ``res`` (P, max_modes), NaN-padded; ``n_modes``,
        ``iterations`` (int) and ``converged`` (bool).
    """
    data, omega, dt, n = check_inputs(data, omega, dt, n_samples)
    check_params(params)
    n_p = data.shape[0]
    m = int(params.max_modes)
    lam0 = np.ascontiguousarray(lam0, dtype=np.complex128)
    if lam0.ndim != 1:
        raise AmiXrValueError(f"lam0: expected a 1-D array of eigenvalues, got {lam0.shape}")
    if int(n0) != n0 or not 0 <= n0 <= lam0.size:
        raise AmiXrValueError(f"n0: expected a count in 0..{lam0.size}, got {n0!r}")
    sigma = _check_sigma(sigma, n_p, data)
    scaled = data / sigma[:, None]  # noise units: the SNR weighting of the FRFs
    k = min(int(n0), m)
    lam_in = np.full((1, m), complex(np.nan, np.nan))
    res_in = np.full((1, n_p, m), complex(np.nan, np.nan))
    lam_in[0, :k] = lam0[:k]
    if k > 0:
        use = np.ones(omega.size, dtype=np.bool_)
        res_in[0, :, :k] = residues_fixed_kernel(scaled, omega, lam_in[0, :k], dt, n, use, -1)
    where = scene(omega, dt, n, params.zeta_max, params.pfa, n_p)
    n0_in = np.array([k], dtype=np.int64)
    out = _isolate(scaled[None], lam_in, res_in, n0_in, where, params, between)
    return IsolateResult(
        lam=out.lam[0],
        res=out.res[0] * sigma[:, None],
        n_modes=int(out.n_modes[0]),
        iterations=int(out.iterations[0]),
        converged=bool(out.converged[0]),
    )


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
    data, omega, dt, n_samples
        FRFs (P, F), their lines and data model: see :func:`~.peak.check_inputs`.
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
    data, omega, dt, n = check_inputs(data, omega, dt, n_samples)
    lam = np.ascontiguousarray(lam, dtype=np.complex128)
    res = np.ascontiguousarray(res, dtype=np.complex128)
    if lam.ndim != 1:
        raise AmiXrValueError(f"lam: expected a 1-D array of eigenvalues, got shape {lam.shape}")
    if res.shape != (data.shape[0], lam.size):
        raise AmiXrValueError(f"res: expected shape ({data.shape[0]}, {lam.size}), got {res.shape}")
    # the fit is invariant to the scale of each FRF: each scaled to a peak of 1 (no noise floor
    # needed, and no squares under- or overflow)
    peak = np.max(np.abs(data), axis=1) if data.size else np.ones(data.shape[0])
    peak = np.where(peak > 0.0, peak, 1.0)[:, None]
    where = scene(omega, dt, n, zeta_max, 0.5, 1)
    work = new_work(np.empty((1, data.shape[1]), dtype=np.complex128), max(lam.size, 1))
    return point_estimates_kernel(
        data / peak, lam, res / peak, where, float(delta), int(min_points), work
    )
