"""The eigensolution of ``M q'' + C q' + K q = f`` with arbitrary damping: the state-space
(first-order) form ``[[C, M], [M, 0]] x' + [[K, 0], [0, -M]] x = [f, 0]``, its ``n``
upper-half-plane eigenvalues sorted by natural frequency, each polished on its own quadratic
problem, and the mode vectors normalised so that the paper's residues hold exactly (see
:mod:`ami_xr.simulate.modal`), repeated roots made state-space orthogonal."""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.linalg

from ami_xr.errors import AmiXrValueError


def _square_matrix(value: Any, name: str, n: int | None = None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise AmiXrValueError(f"{name}: expected a real square matrix, got {value!r}") from exc
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        raise AmiXrValueError(f"{name}: expected a non-empty square matrix, got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise AmiXrValueError(f"{name}: expected shape ({n}, {n}) like M, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise AmiXrValueError(f"{name}: contains NaN or inf")
    if not np.allclose(arr, arr.T, rtol=1e-10, atol=1e-12 * max(1.0, np.abs(arr).max())):
        raise AmiXrValueError(f"{name}: expected a symmetric matrix")
    return arr


# --------------------------------------------------------------------------------------------
# eigensolution
# --------------------------------------------------------------------------------------------
def state_space_modes(M: np.ndarray, C: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (upper half plane, by natural frequency) and normalised mode vectors.

    Parameters
    ----------
    M, C, K : ndarray, shape (n, n)
        Symmetric mass, damping and stiffness matrices (M positive definite).

    Returns
    -------
    lam : ndarray of complex, shape (n,)
        Eigenvalues ``-zeta w + i w sqrt(1 - zeta^2)`` in rad/s.
    phi : ndarray of complex, shape (n, n)
        Mode vectors as columns, scaled so that ``lam_k phi_k^T (2 lam_k M + C) phi_k = 1``.

    Raises
    ------
    AmiXrValueError
        If a mode is not underdamped (real eigenvalue) or M is singular.
    """
    M = _square_matrix(M, "M")
    n = M.shape[0]
    C = _square_matrix(C, "C", n)
    K = _square_matrix(K, "K", n)
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError as exc:
        raise AmiXrValueError("M: expected a symmetric positive definite mass matrix") from exc
    Z = np.zeros((n, n))
    a_mat = np.block([[C, M], [M, Z]])
    b_mat = np.block([[K, Z], [Z, -M]])
    lam, vec = scipy.linalg.eig(-b_mat, a_mat)
    if not np.all(np.isfinite(lam)):
        raise AmiXrValueError("M, C, K: the state-space eigenproblem has infinite eigenvalues")
    scale = np.abs(lam).max()
    upper = lam.imag > 1e-12 * scale
    if upper.sum() != n:
        raise AmiXrValueError(
            f"C: every mode must be underdamped; found {n - int(upper.sum())} of {n} modes "
            "with real eigenvalues (overdamped or rigid-body)"
        )
    lam = lam[upper]
    phi = vec[:n, upper]
    # The QZ eigenvalues carry absolute errors ~ eps * (largest eigenvalue)^2 / |lam|, which
    # spoils low modes when the spectrum is wide (many Ritz terms). Polish every mode on its own
    # quadratic problem D(lam) = lam^2 M + lam C + K: a Rayleigh-quotient root of
    # phi^T D(lam) phi = 0 (the problem is complex symmetric, so phi^T is the left vector) and
    # one inverse-iteration step; cubically convergent, a few sweeps suffice.
    # Only modes whose backward error on their own scale is above a few eps need it.
    Mp, Cp, Kp = M @ phi, C @ phi, K @ phi
    resid = np.linalg.norm(Mp * lam**2 + Cp * lam + Kp, axis=0)
    scale = (
        np.abs(lam) ** 2 * np.linalg.norm(Mp, axis=0)
        + np.abs(lam) * np.linalg.norm(Cp, axis=0)
        + np.linalg.norm(Kp, axis=0)
    )
    for k in np.flatnonzero(resid > 1e-14 * scale):
        lam[k], phi[:, k] = _polish(M, C, K, lam[k], phi[:, k])
    order = np.lexsort((lam.imag, np.abs(lam)))
    lam = lam[order]
    phi = phi[:, order]
    phi = _orthogonalise_repeated(M, C, lam, phi)
    a = np.einsum("ik,ij,jk->k", phi, M, phi) * (2 * lam) + np.einsum("ik,ij,jk->k", phi, C, phi)
    phi = phi / np.sqrt(lam * a)
    # Deterministic sign: Re(lam Phi) > 0 at the largest entry.
    big = np.argmax(np.abs(phi), axis=0)
    flip = (lam * phi[big, np.arange(n)]).real < 0
    phi[:, flip] *= -1
    return lam, phi


# Eigenvalues closer than this (relative) are one repeated root (see _orthogonalise_repeated).
REPEATED_RTOL = 1e-8


def _orthogonalise_repeated(
    M: np.ndarray, C: np.ndarray, lam: np.ndarray, phi: np.ndarray, rtol: float = REPEATED_RTOL
) -> np.ndarray:
    """Make the mode vectors of each repeated eigenvalue orthogonal (``phi_i^T B phi_j = 0``).

    Eigenvectors of distinct eigenvalues satisfy ``phi_i^T (C + (lam_i + lam_j) M) phi_j = 0``
    (state-space orthogonality), which eqs. 4-5 need. For an exactly repeated eigenvalue the
    eigensolver returns an arbitrary basis of its eigenspace, not orthogonal in that sense, and
    the residues ``lam phi_j phi_P`` of the pair would then not sum to the true FRF. Within
    every group of eigenvalues (sorted, consecutive) closer than ``rtol * |lam|`` the vectors
    are made orthogonal with respect to ``B = 2 lam_mean M + C`` by a complex-symmetric
    Gram-Schmidt with pivoting (the vector of largest ``|phi^T B phi|`` first; a pair of
    nearly isotropic vectors, ``phi^T B phi ~ 0``, is first replaced by their sum). Columns of
    groups of one are returned unchanged; ``phi`` is modified in place and returned.
    """
    n = lam.size
    k = 0
    while k < n:
        end = k + 1
        while end < n and abs(lam[end] - lam[k]) <= rtol * abs(lam[k]):
            end += 1
        if end - k > 1:
            b_mat = 2 * lam[k:end].mean() * M + C
            phi[:, k:end] = _b_orthogonal(phi[:, k:end], b_mat)
        k = end
    return phi


def _b_orthogonal(v: np.ndarray, b_mat: np.ndarray) -> np.ndarray:
    """Columns of ``v`` spanning the same space with ``v_i^T B v_j = 0`` for ``i != j``."""
    rest = [v[:, j] / np.linalg.norm(v[:, j]) for j in range(v.shape[1])]
    tiny = 1e-6 * np.linalg.norm(b_mat, 2)
    out = []
    while rest:
        g = np.array([abs(u @ b_mat @ u) for u in rest])
        j = int(np.argmax(g))
        if g[j] < tiny and len(rest) > 1:  # all nearly isotropic: mix the most coupled two
            cross = np.abs(np.array([[x @ b_mat @ y for y in rest] for x in rest]))
            np.fill_diagonal(cross, -1.0)
            a, b = np.unravel_index(int(np.argmax(cross)), cross.shape)
            w = rest[a] + rest[b]
            rest[a] = w / np.linalg.norm(w)
            j = int(a)
        p = rest.pop(j)
        d = p @ b_mat @ p
        for i, u in enumerate(rest):
            u = u - (p @ b_mat @ u) / d * p
            rest[i] = u / np.linalg.norm(u)
        out.append(p)
    return np.stack(out, axis=1)


def _polish(M, C, K, lam, phi, sweeps: int = 4):
    """Refine one eigenpair of the quadratic problem (Rayleigh quotient + inverse iteration)."""
    phi = phi / np.linalg.norm(phi)
    for _ in range(sweeps):
        m = phi @ M @ phi
        c = phi @ C @ phi
        k = phi @ K @ phi
        if m == 0:
            break
        disc = np.sqrt(c * c - 4 * m * k + 0j)
        roots = np.array([(-c + disc) / (2 * m), (-c - disc) / (2 * m)])
        new_lam = roots[np.argmin(np.abs(roots - lam))]
        try:
            v = np.linalg.solve(new_lam**2 * M + new_lam * C + K, (2 * new_lam * M + C) @ phi)
        except np.linalg.LinAlgError:  # exactly singular: phi is already an eigenvector
            lam = new_lam
            break
        if not np.all(np.isfinite(v)) or not np.any(v):
            lam = new_lam
            break
        v = v / np.linalg.norm(v)
        # keep the phase of the previous vector so convergence can be judged
        v = v * np.exp(-1j * np.angle(np.vdot(phi, v)))
        done = abs(new_lam - lam) <= 4e-16 * abs(new_lam) and np.linalg.norm(v - phi) < 1e-14
        lam, phi = new_lam, v
        if done:
            break
    return lam, phi
