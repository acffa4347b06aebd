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


def sqrt_2x2(m: np.ndarray) -> np.ndarray | None:
    """A symmetric square root ``R`` (``R @ R = m``) of a 2x2 complex matrix (closed form
    ``(m + s I) / sqrt(tr m + 2 s)``, ``s = +-sqrt(det m)`` whichever keeps the denominator
    away from 0); None for a singular ``m``."""
    s = np.sqrt(complex(np.linalg.det(m)))
    if s == 0:
        return None
    tr = complex(np.trace(m))
    if abs(tr - 2 * s) > abs(tr + 2 * s):
        s = -s
    t = np.sqrt(tr + 2 * s)
    return (m + s * np.eye(2)) / t


def split_repeated(
    residue: np.ndarray, lam: complex, pairs: list[tuple[int, int]], max_cond: float = 1e6
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Two modes at one eigenvalue from a rank-two residue matrix (a repeated root).

    ``A = lam Phi L^T`` with ``Phi`` (P, 2) and ``L`` (R, 2), and reciprocity at the drive
    points (``L_r = Phi_p``). With ``A2`` the best rank-two approximation (SVD) and two drive
    points ``(p1, r1), (p2, r2)``, ``Phi_D = Phi[[p1, p2]]`` satisfies
    ``Phi_D Phi_D^T = A2[[p1, p2]][:, [r1, r2]] / lam = H``; at an exactly repeated root no data
    fix the pair's rotation in its plane, so ``Phi_D`` is taken as the symmetric square root of
    ``H`` (real shapes stay real: ``H`` is then a real matrix times one complex constant), then
    ``Phi = A2[:, [r1, r2]] Phi_D^-T / lam`` and ``L^T = Phi^+ A2 / lam``. The two drive points
    used are those with the best-conditioned ``H``.

    Parameters
    ----------
    residue : ndarray (P, R)
        The mode's residue matrix.
    lam : complex
        Its eigenvalue.
    pairs : list of (point index, reference index)
        The drive points; at least two.
    max_cond : float
        Largest condition number of ``H`` accepted.

    Returns
    -------
    (phi, participation, misfit) or None
        ``phi`` (P, 2), ``participation`` (R, 2) and the reciprocity misfit: the largest
        ``|L_r - Phi_p|`` over the drive points relative to the largest ``|Phi|`` (each mode);
        None when no two drive points separate the pair.
    """
    if len(pairs) < 2 or min(residue.shape) < 2:
        return None
    u, s, vh = np.linalg.svd(np.asarray(residue, dtype=np.complex128), full_matrices=False)
    a2 = (u[:, :2] * s[:2]) @ vh[:2]
    best, best_cond = None, max_cond
    for i in range(len(pairs)):
        for j in range(i + 1, len(pairs)):
            (p1, r1), (p2, r2) = pairs[i], pairs[j]
            h = a2[np.ix_([p1, p2], [r1, r2])] / lam
            cond = np.linalg.cond(h)
            if cond < best_cond:
                best, best_cond = (p1, p2, r1, r2, h), cond
    if best is None:
        return None
    p1, p2, r1, r2, h = best
    root = sqrt_2x2((h + h.T) / 2)
    if root is None or not np.linalg.cond(root) < max_cond:
        return None
    phi = a2[:, [r1, r2]] @ np.linalg.inv(root).T / lam
    part = (np.linalg.pinv(phi) @ a2 / lam).T
    scale = np.abs(phi).max(axis=0)
    misfit = max(float(np.max(np.abs(part[r] - phi[p]) / scale)) for p, r in pairs)
    return phi, part, misfit


def band_rank(
    residual: np.ndarray,
    noise_std: np.ndarray,
    basis: np.ndarray,
    residue: np.ndarray,
    use: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Singular values of each mode's own part of the data within its band: is it one mode?

    Within a mode's half-power band the data less every other term of the fitted model is
    ``D = residual + A b(lam)`` (point x line): one mode makes it rank one (the mode vector times
    ``b(lam, w)``) plus noise; two poles whose shapes differ (a repeated root split by less
    than the bandwidth, which one reference sees as one mode) make the shape vary across the
    band, and ``D`` rank two. Each row is divided by its FRF's noise standard deviation, so that
    pure noise gives singular values up to about ``sqrt(P) + sqrt(n)`` (P rows, n lines).

    Parameters
    ----------
    residual : ndarray of complex (P, F)
        Data minus the fitted model.
    noise_std : ndarray (P,)
        Per-line noise standard deviation of each FRF (complex).
    basis : ndarray of complex (K, F)
        ``b(lam_k, w)`` of each mode's positive pole (unit residue).
    residue : ndarray of complex (P, K)
        The fitted residues.
    use : ndarray of bool (K, F)
        The lines of each mode's band.

    Returns
    -------
    ratio : ndarray (K,)
        ``s2 / s1`` of the whitened ``D`` (NaN with fewer than two rows or lines).
    excess : ndarray (K,)
        ``s2 / (sqrt(P) + sqrt(n))``: above about 1, the second direction is more than noise.
    """
    n_k = basis.shape[0]
    ratio = np.full(n_k, np.nan)
    excess = np.full(n_k, np.nan)
    sd = np.asarray(noise_std, dtype=float)
    ok = np.isfinite(sd) & (sd > 0)
    for k in range(n_k):
        cols = np.flatnonzero(use[k])
        if cols.size < 2 or ok.sum() < 2:
            continue
        d = residual[np.ix_(ok, cols)] + np.outer(residue[ok, k], basis[k, cols])
        s = np.linalg.svd(d / sd[ok, None], compute_uv=False)
        if s[0] > 0:
            ratio[k] = s[1] / s[0]
            excess[k] = s[1] / (np.sqrt(ok.sum()) + np.sqrt(cols.size))
    return ratio, excess
