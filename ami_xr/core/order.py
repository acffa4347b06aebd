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

from typing import NamedTuple

import numpy as np

from ami_xr.core import varpro
from ami_xr.core.model_error import eigenvalue_scatter, error_variance, within_scatter
from ami_xr.core.order_state import Fitted, Modes, State, Trial
from ami_xr.core.pairs import merge_split_pairs, peak_strength
from ami_xr.core.policy import POLICY, OrderPolicy
from ami_xr.core.proposals import cluster_starts
from ami_xr.core.regions import (
    band_fit,
    complex_rows,
    fit_modes,
    residual_peaks,
    residual_rows,
    weighted_gain,
)

__all__ = ["Modes", "State", "Trial", "fit_modes", "is_exact", "order_tests", "set_stage"]


class Judge(NamedTuple):
    """What every trial of one completion step is judged against: the present model, its
    residual ``r_now`` (P, L), the error variance ``var`` (P, L) of each line, the eigenvalue
    scatter of its peaks, the penalty per mode added and the trial fits' options."""

    prob: object
    state: State
    fit: varpro.FitResult
    trials: list
    threshold: float
    r_now: np.ndarray
    var: np.ndarray
    scatter: np.ndarray
    opts: dict
    policy: OrderPolicy
    # per present mode, the full fits of trials far from it in which it froze (filled by
    # _take): after two, the model, not the trials, moves it out of its region, and every
    # trial that leaves it alone would fail the same way -- it is not fitted (the hammer FRF:
    # one mode froze in every trial of its last two steps; full fits 22 -> 14, same modes)
    stuck: np.ndarray


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


def order_tests(
    prob,
    state: State,
    settings,
    opts: dict,
    n_point: int,
    chi2,
    min_width: float,
    policy: OrderPolicy = POLICY,
) -> None:
    """Model-order checks by likelihood ratio: a mode AMI missed (e.g. one of a close pair lost
    in noise) leaves a coherent residual; it is added when the likelihood gain is significant at
    false-alarm probability ``add_pfa`` over all lines (2 + 2P parameters per mode).

    ``settings``: the user's choices (``add_pfa``, ``add_modes``, ``drop_modes``, ``max_iter``);
    ``policy``: the step's own numbers (:class:`ami_xr.core.policy.OrderPolicy`)."""
    fit = state.fit
    trace = opts["trace"]
    if not (fit.proj.ok and np.isfinite(fit.cost)):
        return
    threshold = chi2.isf(settings.add_pfa / max(prob.omega.size, 1), 2 + 2 * n_point)
    # Trial fits of the order tests stop early: an unfinished fit only overstates the cost of
    # the smaller model (conservative for dropping) and the kept model is polished at the end.
    trial_opts = dict(opts, max_iter=min(settings.max_iter, policy.trial_iterations))
    if settings.drop_modes:
        # on an exact fit the floored objective drops only modes that explain nothing
        set_stage(trace, "order test (drop)")
        _drop_insignificant(prob, state, threshold, trial_opts)
    set_stage(trace, "order test (add)")
    added = 0
    while not is_exact(prob, state.fit, policy):
        if added == settings.add_modes:
            state.capped = settings.add_modes > 0  # 0: additions switched off
            break
        if not _add_missed(prob, state, threshold, opts["decay"], trial_opts, min_width, policy):
            break
        added += 1
    if not settings.drop_modes:
        return
    if added:  # a cluster refit can leave another mode superfluous
        _drop_insignificant(prob, state, threshold, trial_opts)
    if is_exact(prob, state.fit, policy):
        _drop_superfluous(prob, state, trial_opts, policy)
        return  # an exact fit leaves no noise for the close-pair test to refer to
    set_stage(trace, "order test (close pairs)")
    merge_split_pairs(prob, state, settings.add_pfa, opts["decay"], trial_opts, min_width, policy)


def is_exact(prob, fit, policy: OrderPolicy = POLICY) -> bool:
    """The model explains the data to rounding (noise-free data and a complete model)."""
    return bool(fit.proj.ok and np.max(fit.proj.rss / prob.y_norm2) < policy.exact_rss)


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
        start, ref = np.delete(fit.lam, k), np.delete(state.modes.lam0, k)
        trial = Fitted(*fit_modes(prob, start, ref, **trial_opts))
        state.n_iter += trial.n_iter
        if not 2.0 * (trial.fit.cost - fit.cost) < threshold:
            break
        modes = state.modes.without([k])  # k may be a mode the completion added
        modes.free &= trial.free
        modes.at_ami &= ~trial.free  # refitted unless frozen
        state.accept(trial.fit, modes)


def _drop_superfluous(prob, state: State, trial_opts: dict, policy: OrderPolicy = POLICY) -> None:
    """On an exact fit, remove a mode when the others, refitted, still fit exactly: noise-free
    data leave no noise for a likelihood ratio, but an exact fit without the mode shows that it
    is not needed. The ``superfluous_tries`` weakest modes are tried, weakest first, until none
    goes."""
    removed = True
    while removed and state.fit.lam.size > 1:
        removed = False
        fit = state.fit
        strength = [peak_strength(fit.proj, k) for k in range(fit.lam.size)]
        for k in np.argsort(strength)[: policy.superfluous_tries]:
            opts = dict(trial_opts, max_iter=3 * trial_opts["max_iter"])
            start, ref = np.delete(fit.lam, k), np.delete(state.modes.lam0, k)
            trial = Fitted(*fit_modes(prob, start, ref, **opts))
            state.n_iter += trial.n_iter
            if is_exact(prob, trial.fit, policy) and trial.free.all():
                modes = state.modes.without([k])
                modes.free = trial.free
                modes.at_ami &= ~trial.free
                state.accept(trial.fit, modes)
                removed = True
                break


def _proposals(prob, state: State, decay: float, min_width: float, policy: OrderPolicy):
    """The trials of one completion step and the residual power they were drawn from:
    ``(trials, power)``. One extra pole at each of the residual's peaks; a split of each
    clustered or busy mode (its band holds more residual power than noise would); local
    multi-pole refits of the clusters around the peaks and around frozen or busy modes."""
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    fit = state.fit
    peaks, power = residual_peaks(prob, fit.proj, fit.lam, policy.residual_peaks, policy.screen_pfa)
    ref0 = np.where(state.modes.free, state.modes.lam0, fit.lam + decay)
    none = np.empty(0, int)
    trials = [Trial(np.append(fit.lam, c), np.append(ref0, c + decay), 1, none) for c in peaks]
    # Clusters are refitted around the peaks, around frozen modes (a mode that could not be
    # refined marks what the model misses) and around modes whose band holds more residual
    # power than noise would (a pole hidden in a cluster leaves no peak of its own): the sum of
    # S over the band against the chi-square quantile of 2P per line, at false-alarm
    # probability policy.screen_pfa over the modes
    width = np.maximum(2.0 * np.abs(fit.lam.real), min_width)
    excess = np.zeros(fit.lam.size)  # residual power over its chi-square level, per mode band
    for k in range(fit.lam.size):
        band = np.abs(prob.omega - fit.lam[k].imag) <= 3.0 * width[k]
        dof = 2 * prob.n_points * int(band.sum())
        if dof > 0:
            excess[k] = power[band].sum() / chi2.isf(policy.screen_pfa / fit.lam.size, dof)
    busy = excess > 1.0
    suspect = ~state.modes.free | busy
    # a mode of a cluster (its half-power band reaches another's) may stand for two: split.
    # The trials of one step are bounded (max_trials of each kind), the modes whose band holds
    # the most residual power first: with tens of modes, one trial per mode made every step
    # cost tens of fits (a 23-mode hammer FRF took minutes).
    gap = np.abs(fit.lam.imag[:, None] - fit.lam.imag[None, :])
    np.fill_diagonal(gap, np.inf)
    clustered = np.any(gap < width[:, None] + width[None, :], axis=1)
    split = np.flatnonzero(state.modes.free & (clustered | busy))
    for k in split[np.argsort(-excess[split], kind="stable")][: policy.max_trials]:
        shift = policy.split_shift * abs(fit.lam[k].real)
        start = np.append(fit.lam, fit.lam[k] + 1j * shift)
        start[k] -= 1j * shift
        trials.append(Trial(start, np.append(ref0, start[-1] + decay), 1, none))
    # frozen modes first, then the busiest
    order = np.lexsort((-excess, state.modes.free))
    centres = [c.imag for c in peaks] + list(fit.lam.imag[order][suspect[order]])
    data = complex_rows(prob.y) / prob.line_weight[None, :]
    clusters = cluster_starts(
        data,
        prob.omega,
        fit.lam,
        state.modes.free,
        state.modes.lam0,
        decay,
        min_width,
        centres,
        policy,
    )
    trials += [Trial(*c) for c in clusters[: 2 * policy.max_trials]]
    return trials, power


def _add_missed(
    prob,
    state: State,
    threshold: float,
    decay: float,
    trial_opts: dict,
    min_width: float,
    policy: OrderPolicy = POLICY,
) -> bool:
    """One step of model completion: try the residual's peaks as one extra pole each, and local
    multi-pole refits of the clusters around those peaks and around every mode; keep the trial
    with the largest likelihood gain less ``threshold`` per mode added (a penalised likelihood:
    a refit with fewer modes pays back), when that is positive and every mode tried stays free.
    Returns whether the model changed."""
    fit = state.fit
    if not (fit.proj.ok and np.isfinite(fit.cost)):
        return False
    trials, _ = _proposals(prob, state, decay, min_width, policy)
    # One acceptance rule for every trial: the likelihood-ratio gain against the error
    # variance of each line (noise plus the model error a typical measured peak shows,
    # error_variance), less ``threshold`` per mode added. Every trial is screened on its own
    # band (the modes outside held at the present fit). Only trials that pass the screen are
    # fitted on all lines, the first that passes again is taken: one full fit per accepted
    # change, at most policy.screen_keep in a step. Trials the band cannot judge (most of the
    # lines, or a mode it tries froze there) are screened with a few iterations on all lines,
    # only when no band-screened trial holds.
    width = np.maximum(2.0 * np.abs(fit.lam.real), min_width)
    r_now = complex_rows(residual_rows(prob, fit.proj))  # one projection for all the scores
    no_skip = np.zeros(fit.lam.size, bool)
    var = error_variance(prob, fit.proj, width, no_skip, True, r_now, policy=policy)[0]
    scatter = eigenvalue_scatter(prob, fit.proj, width, r_now, policy=policy)
    screened, deferred = [], []
    for i, trial in enumerate(trials):
        gain, refined, n_it = band_fit(prob, fit, trial, trial_opts, min_width, var, policy)
        state.n_iter += n_it
        if gain is None:  # the band cannot judge it: screened on all lines if need be
            deferred.append(i)
        elif gain - trial.n_add * threshold > 0 and not within_scatter(
            refined, fit.lam, scatter, policy
        ):
            screened.append((gain - trial.n_add * threshold, i))
    stuck = np.zeros(fit.lam.size, int)
    judge = Judge(
        prob, state, fit, trials, threshold, r_now, var, scatter, trial_opts, policy, stuck
    )
    # a trial that removes modes is screened on all lines at once (a simpler model that fits as
    # well wins); the others the band could not judge only when no band-screened trial holds
    fewer = [i for i in deferred if trials[i].n_add < 0]
    deferred = [i for i in deferred if trials[i].n_add >= 0]
    screened += _quick_screen(fewer, judge)
    best = _take(screened, judge)
    if best is None and deferred:
        best = _take(_quick_screen(deferred, judge), judge)
    if best is None:
        return False
    trial, fitted, moved = best
    modes = state.modes.without(trial.removed)
    modes.at_ami &= ~moved
    modes = modes.appended(np.zeros(fitted.free.size - moved.size, complex))
    modes.at_ami &= ~fitted.free
    modes.free, modes.lam0 = fitted.free, trial.ref
    state.accept(fitted.fit, modes)
    return True


def _quick_screen(indices, judge: Judge) -> list:
    """Screen trials with ``screen_iterations`` iterations on all lines: ``(score, index)`` of
    those whose gain against ``var`` beats ``threshold`` per mode added. A trial that
    :func:`_take` would not fit (it leaves a stuck mode alone) is not screened either."""
    out = []
    opts = dict(judge.opts, max_iter=judge.policy.screen_iterations)
    for i in indices:
        trial = judge.trials[i]
        if _spared(judge, _reach(judge, trial)[0]):
            continue
        quick = Fitted(*fit_modes(judge.prob, trial.start, trial.ref, **opts))
        judge.state.n_iter += quick.n_iter
        score = _full_gain(judge.prob, judge.r_now, quick.fit, judge.var)
        score -= trial.n_add * judge.threshold
        if score > 0:
            out.append((score, i))
    return out


def _holds(judge: Judge, trial: Trial, fitted: Fitted) -> tuple[bool, np.ndarray]:
    """Whether a trial fitted on all lines holds, and which present modes it moved: its gain
    against ``var`` beats ``threshold`` per mode added, it changed the model, every mode it
    tries stays free (a mode already frozen may stay so) and it makes no pair within one
    mode's scatter."""
    fit, opts = judge.fit, judge.opts
    score = _full_gain(judge.prob, judge.r_now, fitted.fit, judge.var)
    score -= trial.n_add * judge.threshold
    kept_free = np.delete(judge.state.modes.free, trial.removed)
    moved = trial.start[: kept_free.size] != np.delete(fit.lam, trial.removed)
    must = np.append(kept_free | moved, np.ones(trial.start.size - kept_free.size, bool))
    changed = fitted.fit.lam.size != fit.lam.size or np.max(
        np.abs(fitted.fit.lam - fit.lam) / np.abs(fit.lam)
    ) > np.sqrt(opts["tol"])  # a restart that returns where it was changes nothing
    ok = (
        changed
        and fitted.free[must].all()
        and score > 0
        and not within_scatter(fitted.fit.lam, fit.lam, judge.scatter, judge.policy)
    )
    return bool(ok), moved


def _take(screened, judge: Judge):
    """Fit the screened trials on all lines, at most ``screen_keep``, and return the first that
    holds (``(trial, its fit, moved present modes)``) or None. The best screen score first;
    then, should it fail on all lines, the fewest modes added first (a cluster refit that
    fails in full must not hide the single pole that explains a peak); see :func:`_holds`.
    The full fit starts from the trial's own start, not from the band fit's end (the far modes
    held there made it a worse start in clusters and below-band tails)."""
    trials = judge.trials
    screened = sorted(screened, key=lambda s: -s[0])
    screened = screened[:1] + sorted(screened[1:], key=lambda s: (trials[s[1]].n_add, -s[0]))
    for _, i in screened[: judge.policy.screen_keep]:
        trial = trials[i]
        touched, far = _reach(judge, trial)
        if _spared(judge, touched):
            continue  # a mode the model moves out of its region would freeze here too
        fitted = Fitted(*fit_modes(judge.prob, trial.start, trial.ref, **judge.opts))
        judge.state.n_iter += fitted.n_iter
        ok, moved = _holds(judge, trial, fitted)
        if ok:
            return trial, fitted, moved
        # present modes free now that froze in this fit (far excludes what the trial touched)
        kept = np.delete(np.arange(judge.fit.lam.size), trial.removed)
        froze = np.zeros(judge.fit.lam.size, bool)
        froze[kept] = ~fitted.free[: kept.size]
        judge.stuck[froze & judge.state.modes.free & far] += 1
    return None


def _spared(judge: Judge, touched: np.ndarray) -> bool:
    """A trial that touches only ``touched`` leaves alone a mode that froze, far from them, in
    two earlier trials' fits."""
    return bool(((judge.stuck >= 2) & ~touched).any())


def _reach(judge: Judge, trial: Trial) -> tuple[np.ndarray, np.ndarray]:
    """Which present modes a trial moves or removes, and which lie beyond its band (more than
    ``local_widths`` half-power bandwidths of its changed poles from every one of them)."""
    lam = judge.fit.lam
    kept = np.delete(np.arange(lam.size), trial.removed)
    n_old = kept.size
    moved = trial.start[:n_old] != lam[kept]
    touched = np.zeros(lam.size, bool)
    touched[kept[moved]] = True
    touched[trial.removed] = True
    poles = np.concatenate([trial.start[:n_old][moved], trial.start[n_old:], lam[trial.removed]])
    if poles.size == 0:
        return touched, ~touched
    min_width = judge.opts["min_width"]
    margin = judge.policy.local_widths * np.max(np.maximum(2.0 * np.abs(poles.real), min_width))
    far = np.min(np.abs(lam.imag[:, None] - poles.imag[None, :]), axis=1) > margin
    return touched, far & ~touched


def _full_gain(prob, r_now: np.ndarray, trial, var: np.ndarray) -> float:
    """Gain of a trial fitted on all lines against the error variance ``var`` (P, L); the
    present residual is ``r_now`` (P, L). -inf when the trial could not be fitted."""
    if not (trial.proj.ok and np.isfinite(trial.cost)):
        return -np.inf
    return weighted_gain(r_now, complex_rows(residual_rows(prob, trial.proj)), var)
