"""Systems with clusters of overlapping modes, built to a chosen modal overlap (issue 20).

Measured structures have clusters of three or four modes whose half-power bands overlap; the
paper's beam has one coupled pair. :func:`clustered_system` builds a physical ``M, C, K``
system whose undamped modes are placed on purpose, so its exact truth comes from
:func:`~ami_xr.simulate.modal_model` like every other simulated system here:

* **Frequencies.** Blocks from low to high: ``cluster_sizes`` clusters and isolated modes, in
  random order. Inside a cluster consecutive undamped frequencies are ``1 + 2 zeta / overlap``
  apart (ratio), i.e. the half-power bandwidth ``2 zeta w`` over the spacing is ``overlap``.
  Neighbouring blocks are separated by a ratio ``1 + 2 zeta_max / GAP_OVERLAP`` times a random
  factor 1-1.3 (their edge modes' overlap at most ``GAP_OVERLAP`` = 0.2). The whole spectrum is
  scaled so the highest mode lies at ``0.8 max_frequency_hz``.
* **Mode shapes.** ``M`` diagonal (masses 0.5-2), ``Phi = M^(-1/2) Q`` with ``Q`` a random
  orthogonal matrix (dense, every point moves in every mode), ``K = M Phi W^2 Phi^T M``.
* **Damping.** Cluster modes draw ``zeta`` from ``cluster_damping`` (default 2-8 %), isolated
  modes from ``damping`` (1-3 %). The modal damping matrix is ``diag(2 zeta w) + E`` with
  non-proportional coupling ``E_jk = non_proportional * s_jk sqrt(2 zeta_j w_j 2 zeta_k w_k)``,
  ``s_jk`` uniform in [-1, 1] (halved until the matrix is positive definite), and
  ``C = M Phi (diag + E) Phi^T M``. Coupling of the order of the spacing (a cluster at overlap
  1-2 with ``non_proportional`` 0.3) makes the modes strongly complex and moves the eigenvalues;
  the truth is exact whatever it does, and :func:`overlap_factor` measures the overlap reached.

The truth Dataset gets ``cluster`` (mode; 0 for an isolated mode, 1, 2, ... for the clusters in
order of frequency) and ``overlap_factor`` (mode). FRFs come as in
:func:`~ami_xr.simulate.random_system`: analytic (eq. 15 noise on the real and imaginary parts)
or ``dt * rfft`` of sampled impulse responses (eq. 15 noise on each response), the paper's form.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.provenance import add_history
from ami_xr.simulate.checks import check_int, check_positive, check_range, sampling_of
from ami_xr.simulate.modal import modal_model
from ami_xr.simulate.random import system_frfs

GAP_OVERLAP = 0.2  # overlap factor of the edge modes of two neighbouring blocks, at most
CLUSTER = "cluster"  # truth variable (mode): 0 isolated, 1.. cluster number
OVERLAP = "overlap_factor"  # truth variable (mode)
MAX_CLUSTER = 6


def overlap_factor(truth: xr.Dataset | Any) -> xr.DataArray | np.ndarray:
    """Modal overlap of every mode: its half-power bandwidth ``2 |Re lam_k|`` over the distance
    ``min_j |Im lam_k - Im lam_j|`` to the nearest other mode (damped natural frequencies).

    Below about 0.25 the mode stands alone; at 1 its half-power band reaches its neighbour's
    peak; above 1 the peaks merge. One mode alone has overlap 0.

    Parameters
    ----------
    truth : xarray.Dataset or array_like
        A Dataset with ``eigenvalue`` (mode), or the eigenvalues (rad/s, upper half plane).

    Returns
    -------
    xarray.DataArray (mode) for a Dataset, else an ndarray.
    """
    lam = truth[names.EIGENVALUE].values if isinstance(truth, xr.Dataset) else np.asarray(truth)
    lam = np.asarray(lam, dtype=np.complex128)
    if lam.ndim != 1 or not np.all(np.isfinite(lam)):
        raise AmiXrValueError("truth: expected a 1-D array of finite eigenvalues")
    w = np.abs(lam.imag)
    gap = np.abs(w[:, None] - w[None, :])
    np.fill_diagonal(gap, np.inf)
    near = gap.min(axis=1) if lam.size > 1 else np.array([np.inf])
    with np.errstate(divide="ignore"):
        out = np.where(np.isfinite(near), 2 * np.abs(lam.real) / near, 0.0)
    if isinstance(truth, xr.Dataset):
        return xr.DataArray(out, dims=[names.MODE], coords={names.MODE: truth[names.MODE].values})
    return out


def _layout(sizes, n_isolated, overlap, zc, zi, rng):
    """Undamped frequencies (ascending, highest 1), damping ratios and cluster numbers."""
    blocks = [("c", m) for m in sizes] + [("i", 1)] * n_isolated
    order = rng.permutation(len(blocks))
    w, zeta, cluster = [], [], []
    number = 0
    for b in order:
        kind, m = blocks[b]
        z = rng.uniform(*(zc if kind == "c" else zi), m)
        if w:  # a gap from the previous block's last mode
            zmax = max(zeta[-1], z[0])
            w.append(w[-1] * (1 + 2 * zmax / GAP_OVERLAP) * rng.uniform(1.0, 1.3))
        else:
            w.append(1.0)
        for k in range(1, m):  # consecutive modes of a cluster: overlap as asked
            w.append(w[-1] * (1 + (z[k - 1] + z[k]) / overlap))
        zeta += list(z)
        if kind == "c":
            number += 1
        cluster += [number if kind == "c" else 0] * m
    w = np.array(w)
    # clusters numbered in order of frequency
    cl = np.array(cluster)
    first = {c: np.flatnonzero(cl == c)[0] for c in set(cluster) if c}
    renumber = {c: i + 1 for i, c in enumerate(sorted(first, key=first.get))}
    cl = np.array([renumber.get(c, 0) for c in cl])
    return w / w[-1], np.array(zeta), cl


def _matrices(w, zeta, non_proportional, rng):
    n = w.size
    m = rng.uniform(0.5, 2.0, n)
    q, r = np.linalg.qr(rng.standard_normal((n, n)))
    q = q * np.sign(np.diag(r))  # Haar-distributed orthogonal matrix
    phi = q / np.sqrt(m)[:, None]  # Phi^T M Phi = I
    mphi = m[:, None] * phi
    k_mat = mphi @ np.diag(w**2) @ mphi.T
    d = 2 * zeta * w
    s = rng.uniform(-1.0, 1.0, (n, n))
    s = np.triu(s, 1)
    e = non_proportional * (s + s.T) * np.sqrt(np.outer(d, d))
    for _ in range(40):  # keep the damping matrix positive definite
        if np.linalg.eigvalsh(np.diag(d) + e).min() > 0.05 * d.min():
            break
        e *= 0.5
    c_mat = mphi @ (np.diag(d) + e) @ mphi.T
    sym = lambda a: 0.5 * (a + a.T)  # noqa: E731 - exact symmetry for modal_model's check
    return np.diag(m), sym(c_mat), sym(k_mat)


def clustered_system(
    n_points: int = 8,
    *,
    cluster_sizes: Sequence[int] = (3,),
    overlap: float = 1.0,
    n_modes: int | None = None,
    cluster_damping: tuple[float, float] = (0.02, 0.08),
    damping: tuple[float, float] = (0.01, 0.03),
    non_proportional: float = 0.3,
    noise: float = 0.0,
    noise_kind: str = "uniform",
    seed: int | None = 0,
    source: str = names.SOURCE_ANALYTIC,
    frequency: Any = None,
    max_frequency_hz: float = 50.0,
    n_frequencies: int = 4096,
    duration: float | None = None,
    n_samples: int | None = None,
) -> tuple[xr.Dataset, xr.Dataset]:
    """A system with clusters of modes at a chosen overlap: FRFs and the exact truth.

    See the module docstring for how the system is built.

    Parameters
    ----------
    n_points : int
        Measured points, 2..50 (the drive point is one of them, chosen at random).
    cluster_sizes : sequence of int
        Number of modes of each cluster (2..6 each; may be empty).
    overlap : float
        Target overlap factor inside the clusters (half-power bandwidth over spacing), > 0.
    n_modes : int, optional
        Degrees of freedom = modes (default ``max(n_points, sum(cluster_sizes) + 2)``); those
        not in a cluster are isolated modes.
    cluster_damping, damping : (float, float)
        Ranges of the damping ratios of cluster modes and of isolated modes (each < 0.3).
    non_proportional : float
        Strength of the off-diagonal modal damping, 0 (proportional) .. 1.
    noise, noise_kind, seed, source, frequency, max_frequency_hz, n_frequencies, duration,
    n_samples
        As in :func:`~ami_xr.simulate.random_system`.

    Returns
    -------
    frf : xarray.Dataset
        Receptance FRFs at the measured points (``frf_source`` analytic or impulse_response).
    truth : xarray.Dataset
        Exact modal parameters (:func:`~ami_xr.simulate.modal_model`) plus ``cluster`` and
        ``overlap_factor`` (mode).
    """
    n_points, sizes, overlap, n_modes = _check_clusters(n_points, cluster_sizes, overlap, n_modes)
    zc = check_range(cluster_damping, "cluster_damping", 0.3)
    zi = check_range(damping, "damping", 0.3)
    if (
        isinstance(non_proportional, bool)
        or not np.isscalar(non_proportional)
        or not 0 <= non_proportional <= 1
    ):
        raise AmiXrValueError(
            f"non_proportional: expected a number in [0, 1], got {non_proportional!r}"
        )
    sampling = sampling_of(locals())
    fmax, seed = sampling.max_frequency_hz, sampling.seed

    rng = np.random.default_rng(seed)
    noise_seed = None if seed is None else int(rng.integers(2**31))
    w, zeta, cluster = _layout(sizes, n_modes - sum(sizes), overlap, zc, zi, rng)
    w = w * 2 * np.pi * 0.8 * fmax
    M, C, K = _matrices(w, zeta, float(non_proportional), rng)
    points = sorted(int(i) for i in rng.choice(n_modes, size=n_points, replace=False))
    drive = int(rng.choice(points))
    truth = modal_model(
        M, C, K, output=np.eye(n_modes)[points], point_labels=points, drive_point=drive
    )
    truth[CLUSTER] = (names.MODE, cluster.astype(np.int64))
    truth[OVERLAP] = overlap_factor(truth)
    truth.attrs["cluster_sizes"] = np.array(sizes, dtype=np.int64)
    truth.attrs["target_overlap"] = overlap
    truth.attrs["seed"] = -1 if seed is None else seed
    params = {
        "n_points": n_points,
        "cluster_sizes": sizes,
        "overlap": overlap,
        "n_modes": n_modes,
        "non_proportional": float(non_proportional),
        "seed": seed,
    }
    truth = add_history(truth, "ami_xr.simulate.clustered_system", params)
    options = {**sampling.frf_options(), "noise": float(noise)}
    out = system_frfs(truth, drive, **options, noise_seed=noise_seed)
    out = add_history(
        out, "ami_xr.simulate.clustered_system", {"source": source, "noise": noise, "seed": seed}
    )
    return out, truth


def _check_clusters(n_points, cluster_sizes, overlap, n_modes) -> tuple[int, list[int], float, int]:
    """Checked ``n_points``, ``cluster_sizes`` (a list), ``overlap`` and ``n_modes`` (its
    default filled in)."""
    n_points = check_int(n_points, "n_points", 2, 50)
    try:
        sizes = [int(check_int(m, "cluster_sizes", 2, MAX_CLUSTER)) for m in cluster_sizes]
    except TypeError:
        raise AmiXrValueError(
            f"cluster_sizes: expected a sequence of integers, got {cluster_sizes!r}"
        ) from None
    overlap = check_positive(overlap, "overlap")
    default_modes = max(n_points, sum(sizes) + 2)
    n_modes = (
        default_modes if n_modes is None else check_int(n_modes, "n_modes", max(2, n_points), 200)
    )
    if n_modes < sum(sizes):
        raise AmiXrValueError(
            f"n_modes: expected at least the {sum(sizes)} modes of the clusters, got {n_modes}"
        )
    return n_points, sizes, overlap, n_modes


__all__: Sequence[str] = ("clustered_system", "overlap_factor")
