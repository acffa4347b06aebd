"""Kernels of the joint maximum-likelihood refinement (variable projection) of a modal model:
the Gauss-Newton normal equations of the eigenvalues and the per-point projections.

Plain arrays in, plain arrays out. The model of FRF ``j`` at angular frequencies ``omega`` is

    G_j(w) = sum_k A_jk b(lam_k, w) + conj(A_jk) b(conj(lam_k), w)  [+ residual terms]

with ``b`` the continuous (``1/(i w - lam)``) or exact discrete-time basis (see
:mod:`ami_xr.kernels.modal_basis`, which also builds the model's columns). Residues enter
real-linearly through ``A1 = Re A`` and ``A2 = Im A``; the eigenvalues enter nonlinearly.
Every FRF shares the same basis, so the projection onto the basis (one QR factorisation) is
shared by all points and only the data-dependent products are per point. The real parameter
vector of the eigenvalues is
``theta = [Re lam_1, Im lam_1, ..., Re lam_K, Im lam_K]``.

Real stacking: a complex vector ``z`` of length ``L`` is the real vector ``[Re z, Im z]``
of length ``2 L``, so real inner products are ``Re(conj(u) . v)``.

Checked wrappers: :func:`normal_equations`, :func:`gram`, :func:`matmul_small`,
:func:`project_points`.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels._numba import jit


@jit
def _normal_equations(coef, weight, s_mat, v_res, n_mode):
    """Gauss-Newton normal equations of the eigenvalue parameters, summed over points.

    ``coef`` (P, p): residue coefficients ``A1, A2`` of each mode (first ``2 K`` entries);
    ``weight`` (P,): weight of each point (1 / noise variance); ``s_mat`` (2K, 2K): the shared
    matrix ``V' (I - Q Q') V`` of the projected derivative columns; ``v_res`` (P, 2K): ``V' r_j``.
    Returns ``h`` (2K, 2K) = sum_j w_j M_j' S M_j and ``g`` (2K,) = -sum_j w_j M_j' V' r_j, the
    Hessian approximation and gradient of ``1/2 sum_j w_j |r_j|^2``, with ``M_j`` block diagonal,
    blocks ``[[A1, -A2], [A2, A1]]``.
    """
    n_par = 2 * n_mode
    h = np.zeros((n_par, n_par))
    g = np.zeros(n_par)
    m = np.zeros((n_par, n_par))
    for j in range(coef.shape[0]):
        w = weight[j]
        for k in range(n_mode):
            a1 = coef[j, 2 * k]
            a2 = coef[j, 2 * k + 1]
            m[2 * k, 2 * k] = a1
            m[2 * k, 2 * k + 1] = -a2
            m[2 * k + 1, 2 * k] = a2
            m[2 * k + 1, 2 * k + 1] = a1
        # block-diagonal M: (S M)[:, l-block] = S[:, l-block] @ B_l
        sm = np.zeros((n_par, n_par))
        for r in range(n_par):
            for b in range(n_mode):
                for c in range(2):
                    sm[r, 2 * b + c] = (
                        s_mat[r, 2 * b] * m[2 * b, 2 * b + c]
                        + s_mat[r, 2 * b + 1] * m[2 * b + 1, 2 * b + c]
                    )
        for k in range(n_mode):
            for a in range(2):
                row = 2 * k + a
                # (M' X)[row, :] = B_k[:, a]' X[k-block, :]
                m0 = m[2 * k, row]
                m1 = m[2 * k + 1, row]
                for col in range(n_par):
                    h[row, col] += w * (m0 * sm[2 * k, col] + m1 * sm[2 * k + 1, col])
                g[row] -= w * (m0 * v_res[j, 2 * k] + m1 * v_res[j, 2 * k + 1])
    return h, g


def normal_equations(
    coef: np.ndarray, weight: np.ndarray, s_mat: np.ndarray, v_res: np.ndarray, n_mode: int
) -> tuple[np.ndarray, np.ndarray]:
    """Validated wrapper of :func:`_normal_equations` (see there)."""
    coef = np.ascontiguousarray(coef, dtype=np.float64)
    weight = np.ascontiguousarray(weight, dtype=np.float64)
    s_mat = np.ascontiguousarray(s_mat, dtype=np.float64)
    v_res = np.ascontiguousarray(v_res, dtype=np.float64)
    n_point = coef.shape[0]
    if coef.ndim != 2 or coef.shape[1] < 2 * n_mode:
        raise AmiXrValueError(f"coef: expected shape (P, >= {2 * n_mode}), got {coef.shape}")
    if weight.shape != (n_point,):
        raise AmiXrValueError(f"weight: expected shape ({n_point},), got {weight.shape}")
    if s_mat.shape != (2 * n_mode, 2 * n_mode):
        raise AmiXrValueError(
            f"s_mat: expected shape ({2 * n_mode}, {2 * n_mode}), got {s_mat.shape}"
        )
    if v_res.shape != (n_point, 2 * n_mode):
        raise AmiXrValueError(f"v_res: expected shape ({n_point}, {2 * n_mode}), got {v_res.shape}")
    return _normal_equations(coef, weight, s_mat, v_res, int(n_mode))


@jit
def _project_points(y, q, v, lo, hi, qty, rss, vtr):
    """Points ``lo .. hi-1`` (rows of ``y``, (P, n)): ``Q' y_j``, ``|r_j|^2`` and ``V' r_j`` with
    ``r_j = y_j - Q Q' y_j``, for an orthonormal ``q`` (n, p) and derivative columns ``v``
    (n, d), into rows ``j`` of ``qty``, ``rss`` and ``vtr``. No BLAS call (BLAS threads contend
    badly on shared machines and the per-point work is small)."""
    n = y.shape[1]
    p = q.shape[1]
    d = v.shape[1]
    acc = np.empty(p)
    vacc = np.empty(d)
    for j in range(lo, hi):
        acc[:] = 0.0
        for i in range(n):
            yi = y[j, i]
            for c in range(p):
                acc[c] += q[i, c] * yi
        s = 0.0
        vacc[:] = 0.0
        for i in range(n):
            ri = y[j, i]
            for c in range(p):
                ri -= q[i, c] * acc[c]
            s += ri * ri
            for c in range(d):
                vacc[c] += v[i, c] * ri
        for c in range(p):
            qty[j, c] = acc[c]
        rss[j] = s
        for c in range(d):
            vtr[j, c] = vacc[c]


def gram(a: np.ndarray) -> np.ndarray:
    """``a' a`` of a real 2-D array (BLAS: ``numpy.einsum`` without ``optimize`` runs its own
    loops, ten times slower on the refinement's projections)."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.ndim != 2:
        raise AmiXrValueError(f"a: expected a 2-D array, got shape {a.shape}")
    return a.T @ a


def matmul_small(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` of real 2-D arrays (BLAS, as :func:`gram`)."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[0]:
        raise AmiXrValueError(
            f"a, b: expected 2-D arrays with matching inner size, got {a.shape}, {b.shape}"
        )
    return a @ b


#: Environment variable that caps the threads of the per-point projection (``ami-xr batch``
#: gives each worker process its share of the cores through it).
THREADS_ENV = "AMI_XR_THREADS"


def usable_cores() -> int:
    """The cores this process may run on: its CPU affinity, not the machine's count."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except (AttributeError, OSError):  # no affinity on this platform
        return os.cpu_count() or 1


def compute_threads() -> int:
    """Threads the per-point projection may use: :func:`usable_cores`, at most 8, or fewer when
    ``AMI_XR_THREADS`` says so."""
    cores = usable_cores()
    limit = os.environ.get(THREADS_ENV, "").strip()
    if limit.isdigit() and int(limit) > 0:
        cores = min(cores, int(limit))
    return max(1, min(cores, 8))


def project_points(y: np.ndarray, q: np.ndarray, v: np.ndarray):
    """``(Q' y_j, |r_j|^2, V' r_j)`` per row ``y_j`` of ``y`` (P, n), ``r_j = (I - Q Q') y_j``.

    Large problems run in blocks of points on a few threads (the kernel releases the GIL); no
    BLAS call (BLAS threads contend badly on shared machines and the per-point work is small).
    """
    y = np.ascontiguousarray(y, dtype=np.float64)
    q = np.ascontiguousarray(q, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    if y.ndim != 2 or q.ndim != 2 or v.ndim != 2:
        raise AmiXrValueError("y, q, v: expected 2-D arrays")
    if q.shape[0] != y.shape[1] or v.shape[0] != y.shape[1]:
        raise AmiXrValueError(
            f"q, v: expected {y.shape[1]} rows like y's columns, got {q.shape[0]}, {v.shape[0]}"
        )
    n_point = y.shape[0]
    qty = np.zeros((n_point, q.shape[1]))
    rss = np.zeros(n_point)
    vtr = np.zeros((n_point, v.shape[1]))
    small = n_point < 2 or y.size * (q.shape[1] + v.shape[1]) <= 5_000_000
    threads = 1 if small else compute_threads()  # the affinity is read only where it matters
    if threads < 2:
        _project_points(y, q, v, 0, n_point, qty, rss, vtr)
        return qty, rss, vtr
    edges = np.linspace(0, n_point, threads + 1).astype(np.int64)
    with ThreadPoolExecutor(threads) as pool:
        done = [
            pool.submit(_project_points, y, q, v, lo, hi, qty, rss, vtr)
            for lo, hi in zip(edges[:-1], edges[1:], strict=True)
            if hi > lo
        ]
        for future in done:
            future.result()
    return qty, rss, vtr
