"""Model-order tests of the joint refinement (plain arrays, no xarray).

The state the refinement works on (:class:`State`) and the order tests (:func:`order_tests`;
its fits: :func:`ami_xr.core.regions.fit_modes`, trials screened by
:func:`ami_xr.core.regions.band_fit`): drop modes that explain
nothing, add modes the residual shows -- one pole at a residual peak, or a cluster refitted with
more poles by a local multi-pole fit over all points (:mod:`ami_xr.core.proposals`) -- and test
every close pair. Noise-free data are handled by exactness instead of a likelihood ratio: an
exact fit (residual at rounding level) needs no more modes, and a mode whose removal keeps the
fit exact is not needed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ami_xr.core import varpro
from ami_xr.core.model_error import eigenvalue_scatter, error_variance, within_scatter
from ami_xr.core.policy import POLICY
from ami_xr.core.proposals import cluster_starts
from ami_xr.core.regions import band_fit, complex_rows, fit_modes, residual_rows, weighted_gain


@dataclass
class State:
    """The model being refined: the fit, which modes are free and their AMI references."""

    fit: varpro.FitResult
    free: np.ndarray  # (K,) bool
    lam0: np.ndarray  # (K,) AMI eigenvalue of each mode (refined value for added modes)
    res0: np.ndarray  # (P, K_ami) AMI residues of the AMI modes kept
    origin: np.ndarray  # (K_ami,) AMI index of each AMI mode kept
    n_iter: int
    at_ami: np.ndarray | None = None  # (K,) bool: frozen at its AMI eigenvalue (a fallback)
    changed: bool = False
    supported: np.ndarray | None = None  # (K,) bool: kept by the close-pair test
    merged_fn: np.ndarray | None = None  # (K,) Hz of a duplicate merged into the mode
    capped: bool = False  # the mode additions stopped at add_modes, not by the statistics


def _residual_candidates(prob, fit, n_candidates=2, screen_pfa=POLICY.screen_pfa):
    """Where a missing mode would be: peaks of the noise-normalised residual power.

    ``S(w) = sum_j |r_j(w)|^2 / s_j^2`` is chi-square with 2P degrees of freedom per line when
    the model is complete; a missing mode adds a coherent bump about one bandwidth wide, so ``S``
    is smoothed over the typical bandwidth (in lines) of the modes found. Only peaks above the
    chi-square level of false-alarm probability ``screen_pfa`` over the band are returned (a cheap
    screen before the likelihood-ratio test): candidate data poles, damping the median of the
    modes found. Also returns ``S`` itself (unsmoothed): ``(candidates, S)``.
    """
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    proj = fit.proj
    omega = prob.omega
    n_line = omega.size
    resid = residual_rows(prob, proj)
    s2 = np.maximum(proj.rss, 1e-300) / max(prob.n_rows - proj.coef.shape[1], 1)
    power = np.sum((resid[:, :n_line] ** 2 + resid[:, n_line:] ** 2) / s2[:, None], axis=0)
    lam = fit.lam
    zeta = float(np.median(-lam.real / np.abs(lam))) if lam.size else 0.01
    dw = omega[1] - omega[0]
    width = 2.0 * float(np.median(np.abs(lam.real))) if lam.size else 4 * dw
    m = int(np.clip(round(width / dw), 1, max(n_line // 20, 1)))
    smooth = np.convolve(power, np.ones(m) / m, mode="same")
    smooth[: m + 1] = 0.0  # not at DC or Nyquist: no room for a resonance there
    smooth[-m - 1 :] = 0.0
    n_point = prob.n_points
    level = chi2.isf(screen_pfa / n_line, 2 * n_point * m) / m
    out = []
    for _ in range(n_candidates):
        i = int(np.argmax(smooth))
        if smooth[i] <= level:
            break
        w = omega[i]
        out.append(-zeta * w + 1j * w * np.sqrt(1.0 - zeta**2))
        smooth[max(i - 3 * m, 0) : i + 3 * m + 1] = 0.0
    return out, power


def _costs_without_each_mode(prob, proj):
    """Objective with each mode left out, the other eigenvalues fixed and all residues refitted.

    The "extra sum of squares" of a linear fit: leaving out the two columns ``c`` of mode ``k``
    raises ``|r_j|^2`` by ``a_jc' [(R'R)^-1]_cc^-1 a_jc`` -- no new projection needed.
    """
    rinv = np.linalg.inv(proj.r)
    cov = rinv @ rinv.T
    floor = (varpro.RSS_FLOOR**2) * prob.y_norm2
    out = np.empty(proj.lam.size)
    for k in range(proj.lam.size):
        c = slice(2 * k, 2 * k + 2)
        a = proj.coef[:, c]
        extra = np.einsum("ja,ab,jb->j", a, np.linalg.inv(cov[c, c]), a)
        out[k] = 0.5 * prob.n_rows * np.sum(np.log(np.maximum(proj.rss + extra, floor)))
    return out


def set_stage(trace, stage: str) -> None:
    """Name the stage on the progress counter (when one listens)."""
    if trace is not None:
        trace.stage = stage  # shown with the next iteration's count


def order_tests(prob, state: State, settings, opts, n_point, chi2, min_width):
    """Model-order checks by likelihood ratio: a mode AMI missed (e.g. one of a close pair lost
    in noise) leaves a coherent residual; it is added when the likelihood gain is significant at
    false-alarm probability ``add_pfa`` over all lines (2 + 2P parameters per mode)."""
    fit = state.fit
    trace = opts["trace"]
    if not (fit.proj.ok and np.isfinite(fit.cost)):
        return
    threshold = chi2.isf(settings.add_pfa / max(prob.omega.size, 1), 2 + 2 * n_point)
    # Trial fits of the order tests stop early: an unfinished fit only overstates the cost of
    # the smaller model (conservative for dropping) and the kept model is polished at the end.
    trial_opts = dict(opts, max_iter=min(settings.max_iter, POLICY.trial_iterations))
    if settings.drop_modes:
        # on an exact fit the floored objective drops only modes that explain nothing
        set_stage(trace, "order test (drop)")
        _drop_insignificant(prob, state, threshold, trial_opts)
    set_stage(trace, "order test (add)")
    added = 0
    while not is_exact(prob, state.fit):
        if added == settings.add_modes:
            state.capped = settings.add_modes > 0  # 0: additions switched off
            break
        if not _add_missed(prob, state, threshold, opts["decay"], trial_opts, min_width):
            break
        added += 1
    if not settings.drop_modes:
        return
    if added:  # a cluster refit can leave another mode superfluous
        _drop_insignificant(prob, state, threshold, trial_opts)
    if is_exact(prob, state.fit):
        _drop_superfluous(prob, state, trial_opts)
        return  # an exact fit leaves no noise for the close-pair test to refer to
    set_stage(trace, "order test (close pairs)")
    _merge_split_pairs(prob, state, settings.add_pfa, opts["decay"], trial_opts, min_width)


def is_exact(prob, fit) -> bool:
    """The model explains the data to rounding (noise-free data and a complete model)."""
    return bool(fit.proj.ok and np.max(fit.proj.rss / prob.y_norm2) < POLICY.exact_rss)


def well_posed(prob, mu: np.ndarray) -> np.ndarray:
    """Which starting poles to keep so that the model columns can be projected on.

    Isolation may leave several almost coincident, almost undamped poles (a spike split many
    ways); their columns are numerically dependent and no fit can start. While the projection
    fails, the least damped pole of the closest pair (in units of the larger bandwidth) goes.
    """
    keep = np.ones(mu.size, bool)
    while keep.sum() > 1 and not varpro.project(prob, mu[keep]).ok:
        idx = np.flatnonzero(keep)
        m = mu[idx]
        width = np.maximum(2.0 * np.abs(m.real), 1e-300)
        dist = np.abs(m[:, None] - m[None, :]) / np.maximum(width[:, None], width[None, :])
        np.fill_diagonal(dist, np.inf)
        i, j = np.unravel_index(np.argmin(dist), dist.shape)
        keep[idx[i] if abs(m[i].real) < abs(m[j].real) else idx[j]] = False
    return keep


def _drop_insignificant(prob, state: State, threshold: float, trial_opts: dict) -> None:
    """Drop modes whose removal costs less likelihood than ``threshold`` (a spurious AMI mode
    fitting noise), refitting the others; at least one mode stays. Screened cheaply first:
    removing a mode without refitting the others costs at least as much as with refitting."""
    while state.fit.lam.size > 1 and state.fit.proj.ok and np.isfinite(state.fit.cost):
        fit = state.fit
        lr = 2.0 * (_costs_without_each_mode(prob, fit.proj) - fit.cost)
        k = int(np.argmin(lr))
        if not lr[k] < threshold:
            break
        trial = fit_modes(prob, np.delete(fit.lam, k), np.delete(state.lam0, k), **trial_opts)
        state.n_iter += trial[2]
        if not 2.0 * (trial[0].cost - fit.cost) < threshold:
            break
        state.fit, state.free = trial[0], np.delete(state.free, k) & trial[1]
        state.at_ami = np.delete(state.at_ami, k) & ~trial[1]  # refitted unless frozen
        _remove_reference(state, np.array([k]))  # k may be a mode the completion added


def _drop_superfluous(prob, state: State, trial_opts: dict, tries: int = 3) -> None:
    """On an exact fit, remove a mode when the others, refitted, still fit exactly: noise-free
    data leave no noise for a likelihood ratio, but an exact fit without the mode shows that it
    is not needed. The ``tries`` weakest modes are tried, weakest first, until none goes."""
    removed = True
    while removed and state.fit.lam.size > 1:
        removed = False
        fit = state.fit
        strength = [_peak_strength(fit.proj, k) for k in range(fit.lam.size)]
        for k in np.argsort(strength)[:tries]:
            opts = dict(trial_opts, max_iter=3 * trial_opts["max_iter"])
            trial = fit_modes(prob, np.delete(fit.lam, k), np.delete(state.lam0, k), **opts)
            state.n_iter += trial[2]
            if is_exact(prob, trial[0]) and trial[1].all():
                state.fit, state.free = trial[0], trial[1]
                state.at_ami = np.delete(state.at_ami, k) & ~trial[1]
                _remove_reference(state, np.array([k]))
                removed = True
                break


def _remove_reference(state: State, removed: np.ndarray) -> None:
    """Forget the AMI reference of removed modes (indices into the model before removal)."""
    state.lam0 = np.delete(state.lam0, removed)
    ami = removed[removed < state.origin.size]
    state.origin = np.delete(state.origin, ami)
    state.res0 = np.delete(state.res0, ami, 1)
    state.changed = True


def _add_missed(
    prob, state: State, threshold: float, decay: float, trial_opts: dict, min_width: float
) -> bool:
    """One step of model completion: try the residual's peaks as one extra pole each, and local
    multi-pole refits of the clusters around those peaks and around every mode; keep the trial
    with the largest likelihood gain less ``threshold`` per mode added (a penalised likelihood:
    a refit with fewer modes pays back), when that is positive and every mode tried stays free.
    Returns whether the model changed."""
    fit = state.fit
    if not (fit.proj.ok and np.isfinite(fit.cost)):
        return False
    peaks, power = _residual_candidates(prob, fit)
    ref0 = np.where(state.free, state.lam0, fit.lam + decay)
    trials = [
        (np.append(fit.lam, c), np.append(ref0, c + decay), 1, np.empty(0, int)) for c in peaks
    ]
    # Clusters are refitted around the peaks, around frozen modes (a mode that could not be
    # refined marks what the model misses) and around modes whose band holds more residual
    # power than noise would (a pole hidden in a cluster leaves no peak of its own): the sum of
    # S over the band against the chi-square quantile of 2P per line, at false-alarm
    # probability POLICY.screen_pfa over the modes
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    width = np.maximum(2.0 * np.abs(fit.lam.real), min_width)
    busy = np.zeros(fit.lam.size, bool)
    excess = np.zeros(fit.lam.size)  # residual power over its chi-square level, per mode band
    for k in range(fit.lam.size):
        band = np.abs(prob.omega - fit.lam[k].imag) <= 3.0 * width[k]
        dof = 2 * prob.n_points * int(band.sum())
        if dof > 0:
            excess[k] = power[band].sum() / chi2.isf(POLICY.screen_pfa / fit.lam.size, dof)
    busy = excess > 1.0
    suspect = ~state.free | busy
    # a mode of a cluster (its half-power band reaches another's) may stand for two: split.
    # The trials of one step are bounded (max_trials of each kind), the modes whose band holds
    # the most residual power first: with tens of modes, one trial per mode made every step
    # cost tens of fits (a 23-mode hammer FRF took minutes).
    gap = np.abs(fit.lam.imag[:, None] - fit.lam.imag[None, :])
    np.fill_diagonal(gap, np.inf)
    clustered = np.any(gap < width[:, None] + width[None, :], axis=1)
    split = np.flatnonzero(state.free & (clustered | busy))
    for k in split[np.argsort(-excess[split], kind="stable")][: POLICY.max_trials]:
        shift = 0.5 * abs(fit.lam[k].real)
        start = np.append(fit.lam, fit.lam[k] + 1j * shift)
        start[k] -= 1j * shift
        trials.append((start, np.append(ref0, start[-1] + decay), 1, np.empty(0, int)))
    # frozen modes first, then the busiest
    order = np.lexsort((-excess, state.free))
    centres = [c.imag for c in peaks] + list(fit.lam.imag[order][suspect[order]])
    data = complex_rows(prob.y) / prob.line_weight[None, :]
    trials += cluster_starts(
        data, prob.omega, fit.lam, state.free, state.lam0, decay, min_width, centres
    )[: 2 * POLICY.max_trials]
    # One acceptance rule for every trial: the likelihood-ratio gain against the error
    # variance of each line (noise plus the model error a typical measured peak shows,
    # error_variance), less ``threshold`` per mode added. Every trial is screened on its own
    # band (the modes outside held at the present fit). Only trials that pass the screen are
    # fitted on all lines, the first that passes again is taken: one full fit per accepted
    # change, at most POLICY.screen_keep in a step. Trials the band cannot judge (most of the lines,
    # or a mode it tries froze there) are screened with a few iterations on all lines, only
    # when no band-screened trial holds.
    r_now = complex_rows(residual_rows(prob, fit.proj))  # one projection for all the scores
    var = error_variance(prob, fit.proj, width, np.zeros(fit.lam.size, bool), True, r_now)[0]
    scatter = eigenvalue_scatter(prob, fit.proj, width, r_now)
    screened, deferred = [], []
    for i, (_, _, n_add, _) in enumerate(trials):
        gain, refined, n_it = band_fit(prob, fit, trials[i], trial_opts, min_width, var)
        state.n_iter += n_it
        if gain is None:  # the band cannot judge it: screened on all lines if need be
            deferred.append(i)
        elif gain - n_add * threshold > 0 and not within_scatter(refined, fit.lam, scatter):
            screened.append((gain - n_add * threshold, i))
    judge = (prob, state, fit, trials, threshold, r_now, var, scatter, trial_opts)
    # a trial that removes modes is screened on all lines at once (a simpler model that fits as
    # well wins); the others the band could not judge only when no band-screened trial holds
    fewer = [i for i in deferred if trials[i][2] < 0]
    deferred = [i for i in deferred if trials[i][2] >= 0]
    screened += _quick_screen(fewer, *judge)
    best = _take(screened, *judge)
    if best is None and deferred:
        best = _take(_quick_screen(deferred, *judge), *judge)
    if best is None:
        return False
    (state.fit, free, _, _), ref, removed, moved = best
    n_new = free.size - moved.size
    state.at_ami = np.append(np.delete(state.at_ami, removed) & ~moved, np.zeros(n_new, bool))
    state.at_ami &= ~free
    _remove_reference(state, removed)
    state.free, state.lam0 = free, ref
    return True


def _quick_screen(indices, prob, state, fit, trials, threshold, r_now, var, scatter, opts):
    """Screen trials with ``screen_iterations`` iterations on all lines: ``(score, index)`` of
    those whose gain against ``var`` beats ``threshold`` per mode added."""
    out = []
    for i in indices:
        start, ref, n_add, _ = trials[i]
        quick = fit_modes(prob, start, ref, **dict(opts, max_iter=POLICY.screen_iterations))
        state.n_iter += quick[2]
        score = _full_gain(prob, r_now, quick[0], var) - n_add * threshold
        if score > 0:
            out.append((score, i))
    return out


def _take(screened, prob, state, fit, trials, threshold, r_now, var, scatter, opts):
    """Fit the screened trials on all lines, at most ``screen_keep``, and return the first that
    holds (``(fit result, reference, removed, moved)``) or None. The best screen score first;
    then, should it fail on all lines, the fewest modes added first (a cluster refit that
    fails in full must not hide the single pole that explains a peak). A trial holds when its
    gain against ``var`` is above ``threshold`` per mode added, every mode it tries stays free
    (a mode already frozen may stay so) and it makes no pair within one mode's scatter. The
    full fit starts from the trial's own start, not from the band fit's end (the far modes held
    there made it a worse start in clusters and below-band tails)."""
    screened = sorted(screened, key=lambda s: -s[0])
    screened = screened[:1] + sorted(screened[1:], key=lambda s: (trials[s[1]][2], -s[0]))
    for _, i in screened[: POLICY.screen_keep]:
        start, ref, n_add, removed = trials[i]
        trial = fit_modes(prob, start, ref, **opts)
        state.n_iter += trial[2]
        score = _full_gain(prob, r_now, trial[0], var) - n_add * threshold
        kept_free = np.delete(state.free, removed)
        moved = start[: kept_free.size] != np.delete(fit.lam, removed)
        must = np.append(kept_free | moved, np.ones(start.size - kept_free.size, bool))
        changed = trial[0].lam.size != fit.lam.size or np.max(
            np.abs(trial[0].lam - fit.lam) / np.abs(fit.lam)
        ) > np.sqrt(opts["tol"])  # a restart that returns where it was changes nothing
        if (
            changed
            and trial[1][must].all()
            and score > 0
            and not within_scatter(trial[0].lam, fit.lam, scatter)
        ):
            return trial, ref, removed, moved
    return None


def _full_gain(prob, r_now: np.ndarray, trial, var: np.ndarray) -> float:
    """Gain of a trial fitted on all lines against the error variance ``var`` (P, L); the
    present residual is ``r_now`` (P, L). -inf when the trial could not be fitted."""
    if not (trial.proj.ok and np.isfinite(trial.cost)):
        return -np.inf
    return weighted_gain(r_now, complex_rows(residual_rows(prob, trial.proj)), var)


def _peak_strength(proj, k: int) -> float:
    """Size of mode ``k``'s resonance: sum over points of ``|A_jk| / |Re lam_k|``."""
    a = proj.coef[:, 2 * k] + 1j * proj.coef[:, 2 * k + 1]
    return float(np.sum(np.abs(a)) / max(abs(proj.lam[k].real), 1e-300))


def _close_pairs(lam: np.ndarray, width: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of modes closer than the larger of their half-power bandwidths, closest first."""
    pairs = []
    for i in range(lam.size):
        for j in range(i + 1, lam.size):
            sep = abs(lam[i].imag - lam[j].imag)
            if sep < max(width[i], width[j]):
                pairs.append((sep / max(width[i], width[j]), i, j))
    return [(i, j) for _, i, j in sorted(pairs)]


def _merge_split_pairs(prob, state: State, pfa: float, decay: float, trial_opts, min_width):
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

    Otherwise the pair is merged into the one-pole fit. Records ``state.supported`` and
    ``state.merged_fn`` per mode.
    """
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    n_point = prob.n_points
    n_mode = state.fit.lam.size
    state.supported = np.zeros(n_mode, bool)
    state.merged_fn = np.full(n_mode, np.nan)
    tested = set()
    while state.fit.proj.ok and np.isfinite(state.fit.cost) and state.fit.lam.size > 1:
        fit = state.fit
        lam = fit.lam
        width = np.maximum(2.0 * np.abs(lam.real), min_width)
        pairs = [p for p in _close_pairs(lam, width) if _pair_key(lam, p) not in tested]
        if not pairs:
            return
        i, j = pairs[0]
        tested.add(_pair_key(lam, (i, j)))
        weak = j if _peak_strength(fit.proj, j) < _peak_strength(fit.proj, i) else i
        strong = i + j - weak
        kept = strong - (strong > weak)
        # the merged pole's region: around the stronger pole's present value
        ref = np.delete(state.lam0, weak)
        ref[kept] = lam[strong] + decay
        trial = fit_modes(prob, np.delete(lam, weak), ref, **trial_opts)
        state.n_iter += trial[2]
        one = trial[0]
        if not (one.proj.ok and np.isfinite(one.cost)):
            continue
        centre = 0.5 * (lam[i].imag + lam[j].imag)
        half = 0.5 * abs(lam[i].imag - lam[j].imag) + 3.0 * max(width[i], width[j])
        band = np.abs(prob.omega - centre) <= half
        skip = np.abs(one.lam.imag - centre) <= half
        res1 = complex_rows(residual_rows(prob, one.proj))
        res2 = complex_rows(residual_rows(prob, fit.proj))
        var, rho, _ = error_variance(prob, one.proj, np.delete(width, weak), skip, resid=res1)
        # the other peaks' model error under the present model: with the weak pole removed the
        # neighbours in a cluster fit worse too and would hide the pair's excess
        near = np.abs(lam.imag - centre) <= half
        _, _, rho_max = error_variance(prob, fit.proj, width, near, resid=res2)
        var = var[:, band]
        r1 = np.abs(res1[:, band]) ** 2 / var
        r2 = np.abs(res2[:, band]) ** 2 / var
        # the one-pole fit is no better there than at the worst single-pole peak
        # by a factor POLICY.pair_excess: measured peaks' model errors spread over a decade
        # (measurement.uff), and one peak just above the others is no evidence of a second mode
        excess = rho[kept] >= POLICY.pair_excess * rho_max
        gain_j = 2.0 * (r1.sum(axis=1) - r2.sum(axis=1))
        gain = gain_j.sum() > chi2.isf(pfa, 2 + 2 * n_point)
        consistent = np.sum(gain_j > chi2.isf(pfa, 4)) >= min(2, n_point)
        if excess and gain and consistent:
            state.supported[[i, j]] = True
            continue
        # a split duplicate: merge it into the stronger pole
        fn_weak = abs(lam[weak] + decay) / (2.0 * np.pi)
        merged = np.delete(state.merged_fn, weak)
        merged[strong - (strong > weak)] = fn_weak
        state.fit = one
        state.free = np.delete(state.free, weak) & trial[1]
        state.free[kept] = trial[1][kept]  # the merged mode was refitted: frozen only if now
        state.at_ami = np.delete(state.at_ami, weak) & ~trial[1]
        state.lam0 = np.delete(state.lam0, weak)
        state.lam0[kept] = one.lam[kept] + decay  # the merged mode's region: its merged value
        state.supported = np.delete(state.supported, weak)
        state.merged_fn = merged
        if weak < state.origin.size:  # an AMI mode
            state.origin = np.delete(state.origin, weak)
            state.res0 = np.delete(state.res0, weak, 1)
        state.changed = True


def _pair_key(lam: np.ndarray, pair: tuple[int, int]) -> tuple[float, float]:
    """A pair identified by its eigenvalues (indices shift when a mode is merged)."""
    return tuple(sorted(round(abs(lam[k]), 6) for k in pair))
