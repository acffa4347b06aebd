"""Pole proposals where modes overlap: a local common-denominator fit over all points.

Plain numpy on arrays. The fit is linear (the classical least-squares complex-frequency
linearisation ``N_j(x) - H_j(x) D(x) ~ 0`` with one denominator shared by every point), so
its normal equations are a sum over points of small matrices.
"""

from __future__ import annotations

import numpy as np

from ami_xr.core.policy import POLICY, OrderPolicy


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


def cluster_band(lam, width, centre, half, policy: OrderPolicy = POLICY):
    """The band around ``centre`` grown to a cluster: every mode whose half-power band
    (``Im lam +- width``, ``width = 2 |Re lam|``) reaches the band joins, and the band then
    covers it with a margin of ``cluster_margin`` bandwidths: ``(lo, hi, inside)``. (Joining
    at three bandwidths let one strongly damped mode pull far-off modes into a wide band, on
    which the local fit's few poles no longer resolve the cluster.)"""
    lo, hi = centre - half, centre + half
    while True:
        inside = (lam.imag + width >= lo) & (lam.imag - width <= hi)
        reach = policy.cluster_margin * width[inside]
        new_lo = min(lo, float(np.min(lam.imag[inside] - reach, initial=lo)))
        new_hi = max(hi, float(np.max(lam.imag[inside] + reach, initial=hi)))
        if new_lo >= lo and new_hi <= hi:
            return lo, hi, inside
        lo, hi = new_lo, new_hi


def cluster_starts(
    data,
    omega,
    lam,
    free,
    lam0,
    decay: float,
    min_width: float,
    centres,
    policy: OrderPolicy = POLICY,
):
    """Start vectors that refit the modes of a cluster with a local multi-pole fit.

    Around each centre the band is grown to cover every mode within three half-power
    bandwidths (a cluster), and the data on that band, all points jointly, are refitted by a
    common-denominator rational fit (:func:`ami_xr.core.proposals.local_poles`) with one pole
    fewer than the cluster's refinable modes up to ``extra_poles`` more. The stable in-band
    poles of each fit replace the cluster's modes: each old mode (refinable ones first) takes
    the nearest new pole, old modes left over are removed, new poles left over appended.
    ``data`` (P, L) complex FRFs on the lines ``omega``; ``lam`` (K,) the present data poles,
    ``free`` which of them could be refined, ``lam0`` their reference eigenvalues.
    Returns ``(start data poles, reference eigenvalues, net modes added, removed indices)``.
    """
    width = np.maximum(2.0 * np.abs(lam.real), min_width)
    # the typical bandwidth of the modes that could be refined (a frozen mode may be a spike)
    ok = free if free.any() else np.ones(lam.size, bool)
    typical = max(float(np.median(width[ok])), 4.0 * min_width) if lam.size else 8 * min_width
    out, seen = [], set()
    for w0 in centres:
        lo, hi, inside = cluster_band(lam, width, w0, 3.0 * typical, policy)
        lo, hi = max(lo, omega[0]), min(hi, omega[-1])
        if (round(lo, 6), round(hi, 6)) in seen:
            continue
        seen.add((round(lo, 6), round(hi, 6)))
        idx = np.flatnonzero(inside)
        idx = idx[np.argsort(~free[idx], kind="stable")]  # refinable modes first
        n_ok = int(np.sum(free[idx]))
        counts = set()
        for order in range(max(n_ok - 1, 1), n_ok + policy.extra_poles + 1):
            poles = local_poles(data, omega, lo, hi, order)
            good = poles[
                (poles.real < 0)
                & (poles.imag > lo)
                & (poles.imag < hi)
                & (-poles.real < 0.5 * np.abs(poles))
            ]
            if good.size == 0 or good.size in counts:
                continue
            counts.add(good.size)
            start = lam.copy()
            ref = np.where(free, lam0, lam + decay)
            left = list(range(good.size))
            removed = []
            for k in idx:
                if not left:
                    removed.append(k)
                    continue
                j = min(left, key=lambda i, k=k: abs(good[i] - lam[k]))
                left.remove(j)
                start[k], ref[k] = good[j], good[j] + decay
            extra = good[left]
            start = np.append(np.delete(start, removed), extra)
            ref = np.append(np.delete(ref, removed), extra + decay)
            out.append((start, ref, extra.size - len(removed), np.array(removed, int)))
    return out
