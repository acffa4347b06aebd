"""Compression of an FRF set to a few "virtual points" (numpy only, one chunk of points at a time).

The FRFs of ``P`` points on ``L`` lines form a complex matrix ``H`` (P, L). With shared poles,
every row is a combination of the same ``2 n`` functions of frequency (``n`` modes, each with
the real coefficients ``Re A_jk`` and ``Im A_jk`` of ``b_k + conj(b_k)`` and
``i (b_k - conj(b_k))``), so the real matrix ``Hr = [Re H, Im H]`` (P, 2L) has rank ``2 n`` plus
residual terms, plus noise. A REAL orthonormal basis ``Q`` (P, r) of its dominant column space
gives ``r`` virtual FRFs ``V = Q^T H``: real combinations of FRFs, hence FRFs of the same poles
with residues ``Q^T A`` (a complex combination would break the conjugate-pair structure).

The basis comes from a randomized range finder written as sums over chunks of points, so memory
is ``O(r (P_chunk + L))`` and every pass over the data is one map over chunks and one sum:

* pass ``i``: for each chunk ``c``, ``Y_c = Hr_c Z`` (``Z`` (2L, r): Gaussian in the first pass,
  the previous pass's ``B^T`` after it, i.e. a power iteration) and the partial sums
  ``G_c = Y_c^T Y_c`` (r, r) and ``S_c = Y_c^T Hr_c`` (r, 2L);
* client: ``G = sum G_c = V D V^T``, ``M = V D^-1/2`` so that ``Q = Y M`` is orthonormal, and
  ``B = Q^T Hr = M^T S`` (r, 2L), never forming ``Q`` or ``Y``;
* last: the SVD ``B = U s W^T`` orders the virtual FRFs by energy: ``V = s W^T`` in complex form.

Weighting: each FRF is divided by its noise scale (:func:`noise_scale`) before compression, so
that noise is about unit at every point and the compressed least-squares problem approximates
the weighted one (the noise of a virtual FRF is unit for a basis independent of the noise; the
basis found from the data leans towards directions where the noise happens to be larger, by at
most the Marchenko-Pastur factor ``(1 + sqrt(P / 2L))^2`` in energy). What is exact: for any
poles, the weighted residual cost
``||Hr_w P_perp||^2`` (``P_perp`` projecting out the modal basis) equals
``||B P_perp||^2 + ||(I - Q Q^T) Hr_w P_perp||^2``. What is approximate: the second term (the
part of the data outside the kept basis) is dropped; it holds noise, plus any signal whose
energy summed over all points is below the noise's largest singular value (about
``sqrt(P) + sqrt(2 L)`` in noise units), i.e. a mode seen at very few points may be lost.
"""

from __future__ import annotations

import numpy as np

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import noise as kn

__all__ = [
    "noise_scale",
    "real_form",
    "start_matrix",
    "pass_terms",
    "orthonormal_rows",
    "virtual_frfs",
    "signal_rank",
    "compress_array",
]


def noise_scale(h: np.ndarray) -> np.ndarray:
    """Per-FRF noise scale (P,): the robust noise floor of :func:`ami_xr.kernels.noise.
    noise_floor`; an FRF without measurable noise (noise-free simulation) falls back to
    ``1e-6`` times its RMS, and an all-zero FRF to 1, so every scale is positive."""
    h = np.asarray(h, dtype=np.complex128)
    sigma = kn.noise_floor(h)
    rms = np.sqrt(np.mean(np.abs(h) ** 2, axis=-1))
    floor = np.where(rms > 0, 1e-6 * rms, 1.0)
    return np.where(sigma > floor, sigma, floor)


def real_form(h: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
    """``[Re H/s, Im H/s]`` (P, 2L) float64 of complex FRFs ``h`` (P, L) weighted by ``1/scale``."""
    h = np.asarray(h, dtype=np.complex128)
    if scale is not None:
        h = h / np.asarray(scale, dtype=np.float64)[:, None]
    return np.concatenate([h.real, h.imag], axis=1)


def start_matrix(n_lines: int, rank: int, seed: int) -> np.ndarray:
    """The Gaussian test matrix (2 n_lines, rank) of the first pass (the same for a seed)."""
    return np.random.default_rng(seed).standard_normal((2 * n_lines, rank))


def pass_terms(h: np.ndarray, z: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
    """One chunk's partial sums of a pass, packed as ``[G_c | S_c]`` (r, r + 2L).

    ``h`` (p, L) complex; ``z`` (2L, r) the pass's test matrix; ``scale`` (p,): each FRF is
    weighted by ``1 / scale`` (None: as given). The products run on the complex data viewed
    as interleaved reals ``[Re h_0, Im h_0, Re h_1, ...]`` with ``z``'s rows in that order,
    and the weights are applied to the (p, r) products: nothing of the chunk's size is copied
    (a chunk of 1000 FRFs x 4096 lines is 65 MB)."""
    h = np.ascontiguousarray(h, dtype=np.complex128)
    n_lines = h.shape[1]
    hr = h.view(np.float64)  # (p, 2L) interleaved: no copy
    zi = np.empty_like(z, dtype=np.float64)
    zi[0::2], zi[1::2] = z[:n_lines], z[n_lines:]
    y = hr @ zi
    if scale is not None:
        y /= np.asarray(scale, dtype=np.float64)[:, None]  # y = Hr_w z
        s_i = (y / np.asarray(scale, dtype=np.float64)[:, None]).T @ hr  # Y^T Hr_w
    else:
        s_i = y.T @ hr
    s = np.concatenate([s_i[:, 0::2], s_i[:, 1::2]], axis=1)  # back to [Re | Im] columns
    return np.concatenate([y.T @ y, s], axis=1)


def orthonormal_rows(packed: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """``B = Q^T Hr`` (r', 2L) from the summed ``[G | S]`` of a pass (``r' <= r``: directions
    whose Gram eigenvalue is below ``rtol`` times the largest are dropped)."""
    r = packed.shape[0]
    gram, s = packed[:, :r], packed[:, r:]
    d, v = np.linalg.eigh(0.5 * (gram + gram.T))
    top = float(d[-1]) if d.size else 0.0  # no direction left (all-zero data): none kept
    keep = d > rtol * max(top, np.finfo(float).tiny)
    m = v[:, keep] / np.sqrt(d[keep])[None, :]
    return m.T @ s


def virtual_frfs(b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The virtual FRFs (r, L) complex, ordered by energy, and their singular values (r,)."""
    _, s, wt = np.linalg.svd(b, full_matrices=False)
    v = s[:, None] * wt
    n_lines = b.shape[1] // 2
    return np.ascontiguousarray(v[:, :n_lines] + 1j * v[:, n_lines:]), s


def signal_rank(s: np.ndarray, n_points: int, n_lines: int, extra: int = 4) -> int:
    """How many virtual FRFs to keep: those whose singular value exceeds the largest one
    unit-variance noise alone would give, ``sqrt(1/2) (sqrt(P) + sqrt(2 L))`` (real and
    imaginary parts of unit complex noise have variance 1/2; the edge of the Marchenko-Pastur
    law), times 1.05, plus ``extra`` (at least 3, at most all)."""
    edge = np.sqrt(0.5) * (np.sqrt(n_points) + np.sqrt(2.0 * n_lines))
    above = int(np.count_nonzero(s > 1.05 * edge))
    return int(min(s.size, max(3, above + int(extra))))


def compress_array(
    h: np.ndarray,
    rank: int,
    *,
    power_iterations: int = 1,
    seed: int = 0,
    chunk: int = 1024,
    weighted: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Virtual FRFs (r, L) and singular values of the FRFs ``h`` (P, L), in memory, by chunks
    of ``chunk`` points (the reference the labeled :mod:`ami_xr.ami.scale` follows)."""
    h = np.asarray(h, dtype=np.complex128)
    if h.ndim != 2 or h.shape[0] < 1 or h.shape[1] < 2:
        raise AmiXrValueError(f"h: expected FRFs of shape (P, L >= 2), got {h.shape}")
    rank = int(rank)
    if rank < 1:
        raise AmiXrValueError(f"rank: expected an integer >= 1, got {rank}")
    if not np.any(h):
        raise AmiXrValueError(f"h: every FRF is zero (shape {h.shape}); nothing to compress")
    scale = noise_scale(h) if weighted else np.ones(h.shape[0])
    z = start_matrix(h.shape[1], min(rank, h.shape[0]), seed)
    for _ in range(int(power_iterations) + 1):
        total = sum(
            pass_terms(h[lo : lo + chunk], z, scale[lo : lo + chunk])
            for lo in range(0, h.shape[0], chunk)
        )
        b = orthonormal_rows(total)
        z = b.T
    return virtual_frfs(b)
