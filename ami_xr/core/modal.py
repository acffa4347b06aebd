"""Modal quantities from eigenvalues and residues: mode vectors (eq. 8), MAC, standard errors."""

from __future__ import annotations

import numpy as np


def natural_frequency(lam: np.ndarray) -> np.ndarray:
    """Natural frequency in Hz, ``|lam| / (2 pi)``."""
    return np.abs(lam) / (2 * np.pi)


def damping_ratio(lam: np.ndarray) -> np.ndarray:
    """Damping ratio ``-Re(lam) / |lam|``."""
    return -np.real(lam) / np.abs(lam)


def mode_vectors(residue: np.ndarray, lam: np.ndarray, drive_index: int | None) -> np.ndarray:
    """Mode vectors (P, K) from residues (P, K) and eigenvalues (K,), eq. 8.

    ``Phi_P = sqrt(A_P / lam)``, ``Phi_j = A_j / (lam Phi_P)`` with ``P = drive_index``; without a
    drive point each column is ``A_j / A_jmax`` (unit largest entry, unscaled).
    """
    if drive_index is None:
        jmax = np.argmax(np.abs(residue), axis=0)
        return residue / residue[jmax, np.arange(residue.shape[1])][None, :]
    phi_p = np.sqrt(residue[drive_index] / lam)
    return residue / (lam * phi_p)[None, :]


def mac_matrix(phi: np.ndarray) -> np.ndarray:
    """Modal assurance criterion ``|phi_a^H phi_b|^2 / (|phi_a|^2 |phi_b|^2)`` of columns (P, K)."""
    num = np.abs(phi.conj().T @ phi) ** 2
    nrm = np.sum(np.abs(phi) ** 2, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return num / np.outer(nrm, nrm)


def modal_std(lam: np.ndarray, cov_theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Standard deviations of the eigenvalues, natural frequencies (Hz) and damping ratios.

    ``cov_theta`` (2K, 2K) is the covariance of ``(Re lam_1, Im lam_1, Re lam_2, ...)``; the
    frequency and damping ratio follow by the delta method (``wn = |lam|``,
    ``zeta = -Re lam / wn``). Variances that rounding makes slightly negative count as 0.

    Returns
    -------
    eig_std : ndarray of complex (K,)
        ``std(Re lam) + i std(Im lam)``, rad/s.
    fn_std : ndarray (K,)
        Hz.
    zeta_std : ndarray (K,)
    """
    var_re = np.diag(cov_theta)[0::2]
    var_im = np.diag(cov_theta)[1::2]
    eig_std = np.sqrt(np.maximum(var_re, 0.0)) + 1j * np.sqrt(np.maximum(var_im, 0.0))
    wn = np.abs(lam)
    fn_std = np.empty(lam.size)
    zeta_std = np.empty(lam.size)
    for k in range(lam.size):
        c = cov_theta[2 * k : 2 * k + 2, 2 * k : 2 * k + 2]
        g_wn = np.array([lam[k].real, lam[k].imag]) / wn[k]
        g_z = np.array([-(lam[k].imag ** 2), lam[k].real * lam[k].imag]) / wn[k] ** 3
        fn_std[k] = np.sqrt(max(g_wn @ c @ g_wn, 0.0)) / (2.0 * np.pi)
        zeta_std[k] = np.sqrt(max(g_z @ c @ g_z, 0.0))
    return eig_std, fn_std, zeta_std
