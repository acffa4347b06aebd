"""The model error of a measured peak, estimated the same way at every peak (plain arrays, no
xarray): what the model-order step (:mod:`ami_xr.core.order`) must not take for another mode.

* :func:`error_variance`: the variance of each line -- a noise level that follows the frequency
  (running median of the residual's second difference) plus a model error proportional to the
  response (the median over the peaks of the residual power beyond the noise).
* :func:`eigenvalue_scatter`: how far each FRF would move a mode's eigenvalue on its own (mass
  loading of a roving accelerometer, drift between measurements), and :func:`within_scatter`,
  whether a proposed pole sits closer to another than that scatter explains.
"""

from __future__ import annotations

import numpy as np

from ami_xr.core.policy import POLICY, OrderPolicy
from ami_xr.core.regions import complex_rows, residual_rows


def _block_median(x: np.ndarray, size: int) -> np.ndarray:
    """A running median of the rows of ``x`` (P, L) over about ``size`` lines, cheaply: the
    median of consecutive blocks of ``size`` lines, interpolated linearly between the block
    centres (constant beyond the first and the last). O(L), where a sliding median is
    O(L size)."""
    n_line = x.shape[1]
    n_block = max(n_line // max(size, 1), 1)
    edges = np.linspace(0, n_line, n_block + 1).astype(int)
    centres = 0.5 * (edges[:-1] + edges[1:] - 1)
    med = np.stack(
        [np.median(x[:, a:b], axis=1) for a, b in zip(edges[:-1], edges[1:], strict=True)], 1
    )
    if n_block == 1:
        return np.repeat(med, n_line, axis=1)
    lines = np.arange(n_line)
    return np.stack([np.interp(lines, centres, m) for m in med])


def _white_part(resid: np.ndarray) -> np.ndarray:
    """``|e|^2`` estimates (P, L) from the second difference of complex residuals (P, L):
    ``r_i - (r_(i-1) + r_(i+1)) / 2`` has 1.5 times the variance of white noise and removes
    what is smooth from line to line (the edges repeat their neighbour)."""
    if resid.shape[1] < 3:
        return np.abs(resid) ** 2
    d = resid[:, 1:-1] - 0.5 * (resid[:, :-2] + resid[:, 2:])
    d2 = np.abs(d) ** 2 / 1.5
    return np.concatenate([d2[:, :1], d2, d2[:, -1:]], axis=1)


def error_variance(
    prob,
    proj,
    width: np.ndarray,
    skip: np.ndarray,
    local: bool = False,
    resid: np.ndarray | None = None,
    policy: OrderPolicy = POLICY,
):
    """Variance ``E|e|^2`` (P, L) of noise and model error on each line, from the residual.

    ``s_j^2 + eps^2 |H_j(w)|^2``: a noise level per FRF from the median of ``|r_j|^2`` (for
    complex Gaussian noise ``|e|^2`` is exponential, its median ``ln 2 E|e|^2``: robust to the
    model error at the peaks) plus a model error proportional to the model ``H`` (mass loading,
    slight nonlinearity, leakage grow with the response). The model error of mode ``k`` is
    ``rho_k``, the residual power in excess of the noise (beyond three standard deviations of
    its sum, so that pure noise gives ~0) over the model power within three half-power
    bandwidths ``width[k]`` of it; ``eps^2`` is the median of ``rho_k`` over the modes not in
    ``skip`` (the typical model error of a peak; robust to one peak with a missed mode). The
    nominal noise floor is not used; with white noise and an exact model ``eps^2`` is ~0.
    ``local``: the noise level of each line is the median of the residual's second difference
    over blocks of ``noise_widths`` median bandwidths, interpolated between blocks and never
    below the FRF's overall level, instead of one level per FRF (measured FRFs are noisier near
    antiresonances and where the coherence drops; a missed mode's bump is smooth and cancels in
    the second difference). ``resid``: the complex residual rows (P, L) of ``proj``, when the
    caller has them (otherwise projected here).

    Returns ``(variance (P, L), rho (K,), largest rho over the modes not in skip)``.
    """
    resid = complex_rows(residual_rows(prob, proj)) if resid is None else resid
    model = complex_rows(prob.y) - resid
    r2 = np.abs(resid) ** 2
    m2 = np.abs(model) ** 2
    if local:
        # the noise level along frequency: a block median over noise_widths typical bandwidths
        # of the residual's second difference (noise is white from line to line,
        # a missed mode or a peak's model error is smooth there and cancels; a missed mode's
        # tails no longer count as noise on noise-free data)
        dw = prob.omega[1] - prob.omega[0] if prob.omega.size > 1 else 1.0
        size = int(np.clip(policy.noise_widths * np.median(width) / dw, 21, prob.omega.size)) | 1
        s2 = _block_median(_white_part(resid), size)
        # never below the FRF's overall level: the fits minimise the residual with one weight
        # per FRF, and a gain weighted by levels far below it (noise-free data, where the
        # second difference is at rounding level) would not rank what they found
        s2 = np.maximum(s2, np.median(r2, axis=1)[:, None])
    else:
        s2 = np.broadcast_to(np.median(r2, axis=1)[:, None], r2.shape)
    s2 = np.maximum(s2, 1e-300) / np.log(2.0)
    rho = np.zeros(proj.lam.size)
    for k in range(proj.lam.size):
        band = np.abs(prob.omega - proj.lam[k].imag) <= 3.0 * width[k]
        if band.any():
            # excess over the noise beyond its own spread (|e|^2 exponential: std = mean),
            # three standard deviations: pure noise gives rho ~ 0
            spread = np.sqrt(np.sum(s2[:, band] ** 2))
            excess = np.sum(r2[:, band] - s2[:, band]) - 3.0 * spread
            rho[k] = max(excess, 0.0) / max(np.sum(m2[:, band]), 1e-300)
    others = rho[~skip]
    eps2 = float(np.median(others)) if others.size else 0.0
    return s2 + eps2 * m2, rho, float(np.max(others)) if others.size else 0.0


def eigenvalue_scatter(
    prob,
    proj,
    width: np.ndarray,
    resid: np.ndarray | None = None,
    policy: OrderPolicy = POLICY,
) -> np.ndarray:
    """FRF-to-FRF scatter of each mode's eigenvalue, relative to ``|lam_k|`` (K,): the model
    error of a measured peak as a number, estimated the same way at every peak.

    Each FRF ``j`` is let to shift mode ``k``'s eigenvalue on its own: the shift ``d_jk`` is the
    least-squares fit of the residual ``r_j`` on the eigenvalue derivative of the mode's
    contribution ``A_jk b(lam_k)`` projected off the model's columns (the residual is
    orthogonal to them), over the lines within three half-power bandwidths. The
    scatter is the weighted spread of ``d_jk`` over the points (weights: each shift's Fisher
    information ``w_j``), less what the noise alone gives (``sum w |d - mean|^2`` is chi-square
    with ``2 (P - 1)`` degrees of freedom for a mode every FRF sees at the same eigenvalue;
    its mean and three standard deviations are taken off). NaN with fewer than
    ``scatter_points`` points, and where the shifts explain less than ``shift_share`` of the
    residual power beyond the noise (that misfit is something else: a missed mode).
    ``resid``: the complex residual rows (P, L) of ``proj``, when the caller has them.
    """
    n_point, n_mode = prob.n_points, proj.lam.size
    out = np.full(n_mode, np.nan)
    if n_point < policy.scatter_points or not proj.ok:
        return out
    resid = complex_rows(residual_rows(prob, proj)) if resid is None else resid
    s2 = np.maximum(np.median(np.abs(resid) ** 2, axis=1), 1e-300) / np.log(2.0)  # E|e|^2
    # u_k, v_k of model_columns (line-weighted), less what the model's columns already
    # represent: the fitted residues absorbed that part of any shift, the residual holds the rest
    deriv = complex_rows((proj.v - proj.q @ proj.qtv).T).T  # (L, 2K)
    for k in range(n_mode):
        band = np.abs(prob.omega - proj.lam[k].imag) <= 3.0 * width[k]
        if band.sum() < 4:
            continue
        u, v = deriv[band, 2 * k], deriv[band, 2 * k + 1]
        a1, a2 = proj.coef[:, 2 * k], proj.coef[:, 2 * k + 1]
        d_re = a1[:, None] * u + a2[:, None] * v  # (P, n): d model / d Re lam
        d_im = a1[:, None] * v - a2[:, None] * u  # d model / d Im lam
        r = resid[:, band]
        g = np.empty((n_point, 2, 2))
        g[:, 0, 0] = np.sum(np.abs(d_re) ** 2, axis=1)
        g[:, 1, 1] = np.sum(np.abs(d_im) ** 2, axis=1)
        g[:, 0, 1] = g[:, 1, 0] = np.sum((d_re.conj() * d_im).real, axis=1)
        b = np.stack([np.sum((d_re.conj() * r).real, 1), np.sum((d_im.conj() * r).real, 1)], 1)
        ok = np.linalg.det(g) > 1e-12 * np.maximum(g[:, 0, 0] * g[:, 1, 1], 1e-300)
        if ok.sum() < policy.scatter_points:
            continue
        shift = np.linalg.solve(g[ok], b[ok][..., None])[..., 0]
        # only a misfit that shifts explain is a peak's model error (a missed mode beside it is
        # not): the shifts must explain POLICY.shift_share of the residual power beyond the noise
        explained = np.sum(shift * b[ok])
        beyond = np.sum(np.abs(r) ** 2) - band.sum() * np.sum(s2)
        if explained < policy.shift_share * beyond:
            continue
        d = shift[:, 0] + 1j * shift[:, 1]
        w = 0.5 * (g[ok, 0, 0] + g[ok, 1, 1]) / (0.5 * s2[ok])  # information of one component
        mean = np.sum(w * d) / np.sum(w)
        stat = np.sum(w * np.abs(d - mean) ** 2)
        dof = 2 * (d.size - 1)
        excess = max(stat - dof - 3.0 * np.sqrt(2.0 * dof), 0.0)
        out[k] = np.sqrt(excess / np.sum(w) * d.size / max(d.size - 1, 1)) / abs(proj.lam[k])
    return out


def within_scatter(trial_lam, old_lam, scatter: np.ndarray, policy: OrderPolicy = POLICY) -> bool:
    """Whether a trial puts a new or moved pole closer to another than ``scatter_range`` times
    the typical FRF-to-FRF scatter of a peak (``scatter`` of the present modes, its lower
    quartile over the modes away from the pole, at least ``scatter_peaks`` of them): a split of
    one mode that no pole fits at every FRF. The lower quartile, not the median: the model
    error of measured data moves every mode, while an unresolved close pair inflates only its
    own peak's "scatter", and pairs can be most of the peaks (the measured-like plate of
    ``scripts/benchmark_mimo.py``: three pairs and two single modes)."""
    if not np.isfinite(scatter).any():
        return False
    fresh = ~np.isin(trial_lam, old_lam)
    for k in np.flatnonzero(fresh):
        others = np.delete(trial_lam, k)
        if not others.size:
            continue
        gap = np.min(np.abs(others.imag - trial_lam[k].imag))
        away = np.abs(old_lam.imag - trial_lam[k].imag) > gap + 1e-12
        typical = scatter[away & np.isfinite(scatter)]
        # a typical value needs several peaks
        if typical.size < policy.scatter_peaks:
            continue
        level = np.quantile(typical, policy.scatter_quantile)
        if gap < policy.scatter_range * level * abs(trial_lam[k]):
            return True
    return False
