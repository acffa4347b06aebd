"""Isolation Phase of the AMI (eq. 7) with the model-order check: the checked wrappers of the
isolation engine (:mod:`.engine`) for the per-FRF isolation (:func:`isolate_batch`, every FRF
its own group), the global SIMO isolation (:func:`isolate_simo`, all FRFs one group) and the
per-FRF estimates of given system modes (:func:`point_estimates`).

The wrappers check their inputs, bring the data to units of each FRF's noise floor and the
residues back, and build the per-call constants (:func:`~.peak.scene`).
"""

from __future__ import annotations

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels.engine import (
    STOP_FRACTION,
    IsolateParams,
    IsolateResult,
    isolate_groups,
    point_estimates_kernel,
)
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


def _check_sigma(sigma: np.ndarray, n_p: int) -> np.ndarray:
    sigma = np.ascontiguousarray(sigma, dtype=np.float64)
    if sigma.shape != (n_p,) or not np.all(np.isfinite(sigma) & (sigma > 0.0)):
        raise AmiXrValueError(
            f"sigma: expected {n_p} positive noise floors (shape ({n_p},)), got shape {sigma.shape}"
        )
    return sigma


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
    sigma = _check_sigma(sigma, n_p)
    s = min(lam0.shape[1], m)
    lam_in = np.full((n_p, m), complex(np.nan, np.nan))
    res_in = np.full((n_p, 1, m), complex(np.nan, np.nan))
    lam_in[:, :s] = lam0[:, :s]
    res_in[:, 0, :s] = res0[:, :s] / sigma[:, None]
    where = scene(omega, dt, n, params.zeta_max, params.pfa, 1)
    out = isolate_groups(
        (data / sigma[:, None])[:, None, :], lam_in, res_in, np.minimum(n0, m), where, params
    )
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
) -> IsolateResult:
    """Global SIMO isolation with the model-order check (all FRFs one group).

    ``data``, ``omega``, ``dt``, ``n_samples``, ``sigma`` and ``params`` are those of
    :func:`isolate_batch`.

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
    sigma = _check_sigma(sigma, n_p)
    scaled = data / sigma[:, None]  # noise units: the SNR weighting of the FRFs
    k = min(int(n0), m)
    lam_in = np.full((1, m), complex(np.nan, np.nan))
    res_in = np.full((1, n_p, m), complex(np.nan, np.nan))
    lam_in[0, :k] = lam0[:k]
    if k > 0:
        use = np.ones(omega.size, dtype=np.bool_)
        res_in[0, :, :k] = residues_fixed_kernel(scaled, omega, lam_in[0, :k], dt, n, use, -1)
    where = scene(omega, dt, n, params.zeta_max, params.pfa, n_p)
    out = isolate_groups(scaled[None], lam_in, res_in, np.array([k]), where, params)
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
    return point_estimates_kernel(
        data / peak, lam, res / peak, where, float(delta), int(min_points)
    )
