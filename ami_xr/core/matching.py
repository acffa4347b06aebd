"""Matching eigenvalue estimates into modes, and averaging the estimates of each mode.

Distances are in half-power bandwidths: ``|lam_a - lam_b| / (|Re lam_a| + |Re lam_b|)``.
"""

from __future__ import annotations

import numpy as np


def match_modes(lam: np.ndarray, snr: np.ndarray, match_tol: float) -> np.ndarray:
    """Assign per-FRF eigenvalues (P, S) to system modes.

    Points are taken in order of decreasing number of estimates; each point's estimates are
    assigned to the current modes by the Hungarian algorithm on the normalised distance
    ``|lam_a - lam_b| / (|Re lam_a| + |Re lam_b|)`` (half-power bandwidths), accepting a pair only
    when it is below ``match_tol``; unassigned estimates start new modes. Two estimates of the
    same FRF therefore never share a mode. A mode's centre is the ``snr^2``-weighted mean of its
    members.

    Returns
    -------
    ndarray of int (P, S)
        The mode index of every estimate, -1 for NaN slots; modes are numbered by increasing
        natural frequency.
    """
    n_p, n_s = lam.shape
    label = np.full((n_p, n_s), -1, dtype=np.int64)
    centres: list[complex] = []
    members: list[list[tuple[int, int]]] = []
    sum_w: list[float] = []
    sum_wv: list[complex] = []
    counts = np.sum(np.isfinite(lam), axis=1)
    from scipy.optimize import linear_sum_assignment  # keeps scipy.optimize out of import

    for j in np.argsort(-counts, kind="stable"):
        slots = np.flatnonzero(np.isfinite(lam[j]))
        if slots.size == 0:
            continue
        if centres:
            cen = np.asarray(centres)
            a = lam[j, slots][:, None]
            cost = np.abs(a - cen[None, :]) / (np.abs(a.real) + np.abs(cen.real)[None, :])
            big = 1e6
            rows, cols = linear_sum_assignment(np.where(cost < match_tol, cost, big))
            taken = {}
            for r, col in zip(rows, cols, strict=True):
                if cost[r, col] < match_tol:
                    taken[r] = col
        else:
            taken = {}
        for r, s in enumerate(slots):
            if r in taken:
                m = taken[r]
                members[m].append((j, s))
            else:
                members.append([(j, s)])
                centres.append(0j)
                sum_w.append(0.0)
                sum_wv.append(0j)
                m = len(members) - 1
            label[j, s] = m
            # running weighted sums: recomputing them over all members made this O(points^2)
            w = max(snr[j, s], 1e-12) ** 2
            sum_w[m] += w
            sum_wv[m] += w * lam[j, s]
            centres[m] = complex(sum_wv[m] / sum_w[m])
    if not centres:
        return label
    order = np.argsort(np.abs(np.asarray(centres)))
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    label[label >= 0] = rank[label[label >= 0]]
    return label


def n_labels(label: np.ndarray) -> int:
    """Number of modes in a ``match_modes`` labelling."""
    return int(label.max()) + 1 if np.any(label >= 0) else 0


def gather(values: np.ndarray, label: np.ndarray, n_modes: int) -> np.ndarray:
    """(P, K) array of the per-point ``values`` (P, S) of each mode, NaN where not detected."""
    n_p = values.shape[0]
    out = np.full((n_p, n_modes), np.nan + 0j)
    for j in range(n_p):
        for s in np.flatnonzero(label[j] >= 0):
            out[j, label[j, s]] = values[j, s]
    return out


def weighted_average(point_lam: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean per mode of (P, K) estimates and their spread ``std(Re) + i std(Im)``.

    NaN estimates are left out; the spread is NaN for a mode with fewer than two estimates.
    """
    det = np.isfinite(point_lam)
    w = np.where(det, weight, 0.0)
    z = np.where(det, point_lam, 0.0)
    cnt = det.sum(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (w * z).sum(0) / w.sum(0)
        plain = z.sum(0) / cnt
        var_re = (np.where(det, (z.real - plain.real[None, :]) ** 2, 0.0)).sum(0) / (cnt - 1)
        var_im = (np.where(det, (z.imag - plain.imag[None, :]) ** 2, 0.0)).sum(0) / (cnt - 1)
    spread = np.where(cnt >= 2, np.sqrt(var_re) + 1j * np.sqrt(var_im), np.nan + 0j)
    return mean, spread


def match_by_distance(lam: np.ndarray, lam0: np.ndarray, width: np.ndarray) -> np.ndarray:
    """``perm[k]``: the start ``lam0[perm[k]]`` that eigenvalue ``lam[k]`` belongs to.

    A one-to-one assignment minimising the distances in units of ``width`` (K,). Two close modes
    may trade places during a fit (same optimum, labels swapped); this keeps each mode's label.
    """
    from scipy.optimize import linear_sum_assignment  # lazy: keeps `import ami_xr` fast

    cost = np.abs(lam[:, None] - lam0[None, :]) / width[None, :]
    cost = np.where(np.isfinite(cost), cost, 1e300)
    rows, cols = linear_sum_assignment(cost)
    perm = np.empty(lam.size, dtype=int)
    perm[rows] = cols
    return perm


def match_nearest(
    lam: np.ndarray, lam_ref: np.ndarray, tolerance: float
) -> tuple[np.ndarray, np.ndarray]:
    """Match eigenvalues ``lam`` to reference eigenvalues ``lam_ref`` nearest first.

    A pair ``(i, k)`` may match when ``|lam_i - lam_ref_k| < tolerance |Re lam_ref_k|``; pairs
    are taken in order of that distance, each eigenvalue at most once; NaN matches nothing.

    Returns
    -------
    ref_index, index : ndarray of int
        The matched pairs ``(k, i)``, sorted by ``k``.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        dist = np.abs(lam[:, None] - lam_ref[None, :]) / np.abs(lam_ref.real)[None, :]
    dist = np.where(np.isfinite(dist), dist, np.inf)
    used = np.zeros(lam.size, bool)
    found = np.zeros(lam_ref.size, bool)
    pairs = []
    for flat in np.argsort(dist, axis=None, kind="stable"):
        i, k = divmod(int(flat), lam_ref.size)
        if dist[i, k] >= tolerance:
            break
        if not used[i] and not found[k]:
            used[i] = found[k] = True
            pairs.append((k, i))
    pairs.sort()
    return (
        np.array([k for k, _ in pairs], dtype=np.int64),
        np.array([i for _, i in pairs], dtype=np.int64),
    )
