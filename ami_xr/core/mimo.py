"""Multi-reference residue matrices: rank-one factors, drive-point scaling (plain numpy).

For a mode with eigenvalue ``lam`` the residues of the FRFs ``G_jr`` (response ``j``, force at
reference ``r``) form a matrix ``A`` (point x reference) that is rank one in theory,
``A = lam phi L^T``: the mode vector ``phi`` times the modal participation factors ``L``
(``L_r = phi_p`` when reference ``r`` acts on point ``p``: reciprocity, eq. 8 at every drive
point).
"""

from __future__ import annotations

import numpy as np


def rank_one(residue: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Best rank-one approximations ``s1 u w^T`` of residue matrices (SVD).

    Parameters
    ----------
    residue : ndarray of complex, shape (K, P, R)
        One residue matrix (point x reference) per mode.

    Returns
    -------
    u : ndarray (K, P)
        Unit left singular vectors (mode-vector directions).
    s1 : ndarray (K,)
        Largest singular values.
    w : ndarray (K, R)
        ``conj`` of the first right singular vectors, so that ``A ~ s1 u w^T``.
    ratio : ndarray (K,)
        ``s2 / s1`` (0 for a rank-one matrix); NaN when ``min(P, R) < 2`` (one reference
        cannot tell the rank).
    """
    a = np.asarray(residue, dtype=np.complex128)
    u_all, s, vh = np.linalg.svd(a, full_matrices=False)
    u = u_all[:, :, 0]
    w = vh[:, 0, :]
    s1 = s[:, 0]
    if s.shape[1] < 2:
        ratio = np.full(a.shape[0], np.nan)
    else:
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(s1 > 0, s[:, 1] / np.where(s1 > 0, s1, 1.0), np.nan)
    return u, s1, w, ratio


def drive_point_scales(
    u: np.ndarray, s1: np.ndarray, w: np.ndarray, lam: np.ndarray, pairs: list[tuple[int, int]]
) -> np.ndarray:
    """Scale ``c`` of ``phi = c u`` from each drive point (eq. 8 on the rank-one residues).

    With ``A1 = s1 u w^T`` the rank-one residues and drive point ``p`` of reference ``r``,
    ``phi_p = sqrt(A1_pr / lam)`` (principal branch, as eq. 8) gives ``c = phi_p / u_p``.

    Parameters
    ----------
    u, s1, w, lam :
        As returned by :func:`rank_one`; ``lam`` (K,) the eigenvalues.
    pairs : list of (point index, reference index)
        The drive points.

    Returns
    -------
    ndarray of complex, shape (K, D)
        One scale per mode and drive point (NaN where ``u_p`` is 0).
    """
    k = u.shape[0]
    out = np.full((k, len(pairs)), np.nan + 0j)
    for d, (p, r) in enumerate(pairs):
        a1 = s1 * u[:, p] * w[:, r]
        with np.errstate(invalid="ignore", divide="ignore"):
            out[:, d] = np.sqrt(a1 / lam) / u[:, p]
    return out


def aligned_spread(scales: np.ndarray, best: np.ndarray) -> np.ndarray:
    """Largest relative deviation ``|c_d - c_best| / |c_best|`` of each mode's drive-point
    scales (K, D) from the one used (``best``: index per mode), each scale's sign (the square
    root's branch) chosen to match; 0 with one drive point, NaN with none."""
    k, n = scales.shape
    if n == 0:
        return np.full(k, np.nan)
    ref = scales[np.arange(k), best][:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        dev = np.minimum(np.abs(scales - ref), np.abs(scales + ref)) / np.abs(ref)
    return np.max(dev, axis=1)


def participation(s1: np.ndarray, w: np.ndarray, lam: np.ndarray, scale: np.ndarray):
    """Modal participation factors (K, R): ``L = s1 w / (lam c)`` so that ``lam phi L^T`` with
    ``phi = c u`` is the rank-one residue matrix."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return (s1 / (lam * scale))[:, None] * w


def unit_scales(u: np.ndarray) -> np.ndarray:
    """``c`` with ``c u`` having its largest entry 1 (no drive point: unscaled vectors)."""
    jmax = np.argmax(np.abs(u), axis=1)
    return 1.0 / u[np.arange(u.shape[0]), jmax]
