"""Pole proposals where modes overlap: a local common-denominator fit over all points.

Plain numpy on arrays. The fit is linear (the classical least-squares complex-frequency
linearisation ``N_j(x) - H_j(x) D(x) ~ 0`` with one denominator shared by every point), so
its normal equations are a sum over points of small matrices.
"""

from __future__ import annotations

import numpy as np


def local_poles(frf, omega, lo, hi, order, extra=2):
    """Eigenvalues of a rational fit of ``frf`` (P, L) on the lines ``lo <= omega <= hi``.

    The frequency is mapped to ``x = (omega - centre) / half`` in [-1, 1] (monomials stay well
    conditioned for the small orders used here); each point has its own numerator of degree
    ``order + extra`` (the extra degrees absorb the modes outside the band and the conjugate
    poles) and all share a monic denominator of degree ``order``. Returns the roots mapped to
    eigenvalues ``lam = i omega_r`` (all of them; the caller keeps the stable ones in band).
    """
    sel = (omega >= lo) & (omega <= hi)
    n_line = int(sel.sum())
    m = order + extra
    if n_line < m + order + 2:
        return np.empty(0, complex)
    w = omega[sel]
    h = frf[:, sel]
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    x = (w - centre) / half
    q, _ = np.linalg.qr(np.vander(x, m + 1, increasing=True).astype(complex))
    psi = np.vander(x, order + 1, increasing=True)
    scale = 1.0 / np.maximum(np.sqrt(np.mean(np.abs(h) ** 2, axis=1)), 1e-300)
    mat = np.zeros((order + 1, order + 1), complex)
    for j in range(h.shape[0]):
        b = (scale[j] * h[j])[:, None] * psi
        b = b - q @ (q.conj().T @ b)
        mat += b.conj().T @ b
    try:
        d = np.linalg.solve(mat[:order, :order], -mat[:order, order])
    except np.linalg.LinAlgError:
        return np.empty(0, complex)
    roots = np.roots(np.append(d, 1.0)[::-1])
    return 1j * (centre + half * roots)
