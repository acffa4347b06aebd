"""The close-pair test of the model-order step (plain arrays, no xarray): is a pair of modes
closer than their half-power bandwidth one mode split in two, or two modes the data support?
(:func:`merge_split_pairs`, run last by :func:`ami_xr.core.order.order_tests`.)"""

from __future__ import annotations

import numpy as np

from ami_xr.core.model_error import error_variance
from ami_xr.core.order_state import State
from ami_xr.core.policy import POLICY, OrderPolicy
from ami_xr.core.regions import complex_rows, fit_modes, residual_rows


def peak_strength(proj, k: int) -> float:
    """Size of mode ``k``'s resonance: sum over points of ``|A_jk| / |Re lam_k|``."""
    a = proj.coef[:, 2 * k] + 1j * proj.coef[:, 2 * k + 1]
    return float(np.sum(np.abs(a)) / max(abs(proj.lam[k].real), 1e-300))


def close_pairs(lam: np.ndarray, width: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of modes closer than the larger of their half-power bandwidths, closest first."""
    pairs = []
    for i in range(lam.size):
        for j in range(i + 1, lam.size):
            sep = abs(lam[i].imag - lam[j].imag)
            if sep < max(width[i], width[j]):
                pairs.append((sep / max(width[i], width[j]), i, j))
    return [(i, j) for _, i, j in sorted(pairs)]


def merge_split_pairs(
    prob,
    state: State,
    pfa: float,
    decay: float,
    trial_opts: dict,
    min_width: float,
    policy: OrderPolicy = POLICY,
) -> None:
    """Model-order test of every close pair (separation below the larger half-power bandwidth):
    a split duplicate of one mode is merged, a pair the data support stays resolved.

    For a pair, the weaker pole (smaller ``sum_j |A_j| / |Re lam|``) is removed and the rest
    refitted (the one-pole model). The pair is supported when all three hold:

    * the one-pole model's error at the pair is not typical of the data: its model error
      ``rho`` (the residual power beyond the noise over the model power, near the pair) is at
      least that of every other peak, each fitted by one pole. The model error differs from
      peak to peak (on measurement.uff by a factor 10) and a peak that one pole fits no worse
      than the worst single-pole peak gives no evidence of a second mode (distribution-free:
      among ``n + 1`` exchangeable peaks one exceeds all the others with probability
      ``1 / (n + 1)``). Without model error (all ``rho`` ~ 0) this test passes;
    * the second pole explains significantly more than noise and model error: on the lines
      within three bandwidths of the pair, with the variance ``v`` estimated from the one-pole
      model's residual (:func:`~ami_xr.core.model_error.error_variance`, the pair's own peak left
      out of the model-error estimate), ``2 sum (|r_1|^2 - |r_2|^2) / v`` exceeds the
      chi-square quantile with ``2 + 2P`` degrees of freedom (the second eigenvalue and its
      residues) at false-alarm probability ``pfa``;
    * its shape is consistent across points: that gain is significant (chi-square, 4 degrees of
      freedom, ``pfa``) at two points or more (at the one point of a single FRF).

    Otherwise the pair is merged into the one-pole fit. Records ``state.modes.supported`` and
    ``state.modes.merged_fn`` per mode.
    """
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    n_point = prob.n_points
    n_mode = state.fit.lam.size
    state.modes.supported = np.zeros(n_mode, bool)
    state.modes.merged_fn = np.full(n_mode, np.nan)
    tested = set()
    far = policy.pair_widths
    while state.fit.proj.ok and np.isfinite(state.fit.cost) and state.fit.lam.size > 1:
        fit = state.fit
        lam = fit.lam
        width = np.maximum(2.0 * np.abs(lam.real), min_width)
        pairs = [p for p in close_pairs(lam, width) if _pair_key(lam, p) not in tested]
        if not pairs:
            return
        i, j = pairs[0]
        tested.add(_pair_key(lam, (i, j)))
        weak = j if peak_strength(fit.proj, j) < peak_strength(fit.proj, i) else i
        strong = i + j - weak
        kept = strong - (strong > weak)
        # the merged pole's region: around the stronger pole's present value
        ref = np.delete(state.modes.lam0, weak)
        ref[kept] = lam[strong] + decay
        # the strong pole frozen in the one-pole fit decides the pair (below): no fit beyond
        need = None
        if state.modes.free[strong]:
            need = np.zeros(lam.size - 1, bool)
            need[kept] = True
        trial = fit_modes(prob, np.delete(lam, weak), ref, give_up=need, **trial_opts)
        state.n_iter += trial[2]
        one = trial[0]
        if not (one.proj.ok and np.isfinite(one.cost)):
            continue
        if state.modes.free[strong] and not trial[1][kept]:
            # without the weak pole the strong one leaves its region: the two do not share
            # one resonance (a narrow mode on a broad pole's band), it is no split duplicate
            state.modes.supported[[i, j]] = True
            continue
        centre = 0.5 * (lam[i].imag + lam[j].imag)
        half = 0.5 * abs(lam[i].imag - lam[j].imag) + far * max(width[i], width[j])
        band = np.abs(prob.omega - centre) <= half
        skip = np.abs(one.lam.imag - centre) <= half
        res1 = complex_rows(residual_rows(prob, one.proj))
        res2 = complex_rows(residual_rows(prob, fit.proj))
        var, rho, _ = error_variance(
            prob, one.proj, np.delete(width, weak), skip, resid=res1, policy=policy
        )
        # the other peaks' model error under the present model: with the weak pole removed the
        # neighbours in a cluster fit worse too and would hide the pair's excess
        near = np.abs(lam.imag - centre) <= half
        _, _, rho_max = error_variance(prob, fit.proj, width, near, resid=res2, policy=policy)
        var = var[:, band]
        r1 = np.abs(res1[:, band]) ** 2 / var
        r2 = np.abs(res2[:, band]) ** 2 / var
        # the one-pole fit is no better there than at the worst single-pole peak
        # by a factor policy.pair_excess: measured peaks' model errors spread over a decade
        # (measurement.uff), and one peak just above the others is no evidence of a second mode
        excess = rho[kept] >= policy.pair_excess * rho_max
        gain_j = 2.0 * (r1.sum(axis=1) - r2.sum(axis=1))
        gain = gain_j.sum() > chi2.isf(pfa, 2 + 2 * n_point)
        consistent = np.sum(gain_j > chi2.isf(pfa, 4)) >= min(2, n_point)
        if excess and gain and consistent:
            state.modes.supported[[i, j]] = True
            continue
        # a split duplicate: merge it into the stronger pole
        modes = state.modes.without([weak])
        modes.merged_fn[kept] = abs(lam[weak] + decay) / (2.0 * np.pi)
        modes.free &= trial[1]
        modes.free[kept] = trial[1][kept]  # the merged mode was refitted: frozen only if now
        modes.at_ami &= ~trial[1]
        modes.lam0[kept] = one.lam[kept] + decay  # the merged mode's region: its merged value
        state.accept(one, modes)


def _pair_key(lam: np.ndarray, pair: tuple[int, int]) -> tuple[float, float]:
    """A pair identified by its eigenvalues (indices shift when a mode is merged)."""
    return tuple(sorted(round(abs(lam[k]), 6) for k in pair))
