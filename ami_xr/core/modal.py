"""Modal quantities from eigenvalues and residues: mode vectors (eq. 8), MAC, standard errors,
quality indicators (MPC, MPD, complexity) and phase normalisation."""

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
    """Modal assurance criterion ``|phi_a^H phi_b|^2 / (|phi_a|^2 |phi_b|^2)`` of columns (P, K).

    The one MAC of the package (the plots use it too). A zero column has no direction: its
    row and column are NaN (undefined), as are those of a column holding NaN; every other entry
    lies in [0, 1].
    """
    phi = np.asarray(phi, dtype=np.complex128)
    num = np.abs(phi.conj().T @ phi) ** 2
    nrm = np.sum(np.abs(phi) ** 2, axis=0)
    den = np.outer(nrm, nrm)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)


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


# --- modal quality indicators of complex mode vectors (P, K); points that are not finite
# (e.g. NaN where a mode was not estimated) are left out; a mode with no finite non-zero entry
# gives NaN.


def _finite_columns(phi: np.ndarray) -> np.ndarray:
    """``phi`` as a complex (P, K) array with non-finite entries set to 0 (they then carry no
    weight in any of the indicators), each column divided by its largest magnitude (the
    indicators are scale-free; this keeps squares of tiny or huge mode vectors finite)."""
    phi = np.asarray(phi, dtype=np.complex128)
    if phi.ndim == 1:
        phi = phi[:, None]
    phi = np.where(np.isfinite(phi), phi, 0.0)
    big = np.max(np.abs(phi), axis=0, initial=0.0)
    return phi / np.where(big > 0, big, 1.0)[None, :]


def mpc(phi: np.ndarray) -> np.ndarray:
    """Modal phase collinearity of each column of ``phi`` (P, K), in [0, 1].

    Pappa, Elliott & Schenk (1993), "Consistent-mode indicator for the eigensystem realization
    algorithm", J. Guidance, Control, and Dynamics 16(5), 852-858: the eigenvalues
    ``l1 >= l2`` of the 2 x 2 scatter matrix of (Re phi_j, Im phi_j) give
    ``MPC = ((l1 - l2) / (l1 + l2))^2``. The scatter is taken about the origin (a mode vector
    is collinear when its points lie on one straight line *through the origin* of the complex
    plane), which is the closed form ``|sum phi_j^2|^2 / (sum |phi_j|^2)^2``.

    1 for a real (normal) mode, whatever its overall complex phase; 0 when the points split
    evenly between two directions 90 degrees apart.
    """
    phi = _finite_columns(phi)
    num = np.abs(np.sum(phi**2, axis=0)) ** 2
    den = np.sum(np.abs(phi) ** 2, axis=0) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, np.clip(num / np.where(den > 0, den, 1.0), 0.0, 1.0), np.nan)


def mpd(phi: np.ndarray) -> np.ndarray:
    """Mean phase deviation of each column of ``phi`` (P, K), in degrees (0 .. 90).

    The best straight line through the origin of the complex plane is the first right singular
    vector ``(v1, v2)`` of the P x 2 matrix ``[Re phi, Im phi]``; each point deviates from it by
    ``arccos(|Re phi_j v1 + Im phi_j v2| / |phi_j|)``, and MPD is the mean of these angles
    weighted by ``|phi_j|`` (as in Reynders, Houbrechts & De Roeck (2012), "Fully automated
    (operational) modal analysis", Mech. Syst. Signal Process. 29, 228-250). 0 for a real mode
    whatever its overall phase.
    """
    phi = _finite_columns(phi)
    out = np.full(phi.shape[1], np.nan)
    for k in range(phi.shape[1]):
        col = phi[:, k]
        mag = np.abs(col)
        if not np.any(mag > 0):
            continue
        _, _, vt = np.linalg.svd(np.column_stack([col.real, col.imag]), full_matrices=False)
        v1, v2 = vt[0]
        keep = mag > 0
        cos = np.abs(col.real[keep] * v1 + col.imag[keep] * v2) / mag[keep]
        angle = np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))
        out[k] = float(np.sum(mag[keep] * angle) / np.sum(mag[keep]))
    return out


def complexity(phi: np.ndarray) -> np.ndarray:
    """Mode complexity ``1 - MPC`` of each column of ``phi`` (P, K), in [0, 1].

    The modal complexity factor of Vacher, Jacquier & Bucharles (2010), "Extensions of the MAC
    criterion to complex modes", ISMA 2010: 0 for a real (normal) mode, 1 for the most complex.
    """
    return 1.0 - mpc(phi)


def phase_normalised(phi: np.ndarray, *, unit: bool = False) -> np.ndarray:
    """Mode vectors (P, K) rotated in phase, each column so that its largest component is real
    and positive (magnitudes and relative phases unchanged; NaN entries stay NaN). With
    ``unit``, each column is also divided by that magnitude: its largest component is 1."""
    phi = np.asarray(phi, dtype=np.complex128)
    mag = np.where(np.isfinite(phi), np.abs(phi), -1.0)
    if phi.shape[0] == 0:
        return phi.copy()
    cols = np.arange(phi.shape[1])
    jmax = np.argmax(mag, axis=0)
    big = phi[jmax, cols]
    ok = np.isfinite(big) & (np.abs(big) > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        rot = np.where(ok, np.conj(big) / np.abs(big), 1.0)
        if unit:
            rot = np.where(ok, rot / np.abs(big), 1.0)
    out = phi * rot[None, :]
    # the largest component exactly (rounding would leave ~1e-16 imaginary parts)
    out[jmax[ok], cols[ok]] = 1.0 if unit else np.abs(big[ok])
    return out
