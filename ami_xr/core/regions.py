"""Levenberg-Marquardt inside regions, and the band screen of a model-completion trial (plain
arrays, no xarray).

:func:`fit_modes` runs the variable-projection Levenberg-Marquardt of the refinement and freezes
a mode that leaves its region around its reference eigenvalue. :func:`band_fit` fits a trial
of the model completion (:mod:`ami_xr.core.order`) on the lines around the modes it changes
only, the modes outside held at the present fit: a fraction of the lines of an FRF with tens of
modes, so that the trials are ranked cheaply before the best are fitted on all lines.
"""

from __future__ import annotations

import numpy as np

from ami_xr.core import varpro
from ami_xr.core.matching import match_by_distance
from ami_xr.core.policy import POLICY, OrderPolicy
from ami_xr.kernels.modal_basis import model_columns
from ami_xr.kernels.projection import project_points

FALLBACK_MESSAGE = "fallback: nothing could be fitted"  # FitResult.message of a fit given up


def _mode_codes(lam: np.ndarray, lam0: np.ndarray, max_shift: float, min_width: float):
    """0: fine; 1: outside its region; 2: impossible (unstable, not finite, merged).

    The region of a mode, around the AMI eigenvalue it matches: within ``max_shift`` half-power
    bandwidths, and a decay rate not below ``1 / (1 + max_shift)`` of AMI's (a damping that
    collapses means the mode is fitting a noise spike: the likelihood has no bound there).
    """
    width = np.maximum(2.0 * np.abs(lam0.real), min_width)
    code = np.zeros(lam.size, dtype=int)
    finite = np.isfinite(lam)
    code[~finite | (lam.real >= 0) | (lam.imag <= 0)] = 2
    if not finite.all():
        return code
    ref = lam0[match_by_distance(lam, lam0, width)]
    w = np.maximum(2.0 * np.abs(ref.real), min_width)
    outside = (np.abs(lam - ref) > max_shift * w) | (-lam.real < -ref.real / (1.0 + max_shift))
    code[(code == 0) & outside] = 1
    if lam.size > 1:  # merged: another mode within 1e-6 relative (all pairs at once)
        gap = np.abs(lam[:, None] - lam[None, :])
        np.fill_diagonal(gap, np.inf)
        code[np.min(gap, axis=1) < 1e-6 * np.abs(lam)] = 2
    return code


def fit_modes(
    prob,
    mu0,
    ref,
    *,
    decay,
    max_iter,
    tol,
    max_shift,
    min_width,
    free=None,
    trace=None,
    give_up=None,
):
    """Levenberg-Marquardt from ``mu0`` (data poles); a mode that leaves its region around
    ``ref`` (physical eigenvalues) is frozen at its start and the fit goes on without it.
    ``trace``: an :class:`ami_xr.progress.Iterations` counting the iterations (or None).
    ``give_up`` (K,) bool: modes whose freezing makes the fit useless to the caller; the fit
    stops when one of them freezes (``free`` says so; the fit is the last one run).

    Returns ``(fit, free, n_iter, start_cost)``.
    """
    n_mode = mu0.size
    free = np.ones(n_mode, bool) if free is None else np.array(free, bool)

    def check(mu):
        return _mode_codes(mu + decay, ref, max_shift, min_width)

    prob.n_fits += 1
    start_mu = mu0.copy()
    start_cost = None
    n_iter = 0
    if trace is not None:
        trace.modes = n_mode
    while True:
        fit = varpro.levenberg_marquardt(
            prob,
            start_mu,
            max_iter=max(max_iter - n_iter, 1),
            tol=tol,
            free=free,
            check=check,
            trace=trace,
        )
        n_iter += fit.n_iter
        start_cost = fit.start_cost if start_cost is None else start_cost
        if not np.isfinite(fit.cost):
            # nothing to fit: every mode stays at its start
            free[:] = False
            fit = varpro.levenberg_marquardt(prob, mu0, max_iter=0, free=free)
            fit.message = FALLBACK_MESSAGE
            break
        if fit.cost > start_cost:
            # Freezing a mode at its start made the others' fit worse than the start: refit
            # them from their starts with only the frozen modes held (a descent from the start
            # is never worse than it). The other modes keep their freedom: only the modes that
            # really left their region fall back (formerly every mode was frozen here).
            start_mu = mu0.copy()
            continue
        if fit.bad is None:  # the optimum must lie inside every free mode's region too
            final = np.where(free, _mode_codes(fit.lam + decay, ref, max_shift, min_width), 0)
            if not final.any():
                break
            fit.bad = final > 0
        # freeze the offending modes at their start values, go on from where the others are
        free &= ~fit.bad
        if give_up is not None and np.any(fit.bad & give_up):
            break
        start_mu = np.where(free, fit.lam, mu0)
    return fit, free, n_iter, start_cost


def residual_rows(prob, proj) -> np.ndarray:
    """Residuals ``y_j - Q Q' y_j`` of every point (P, 2L), real-stacked."""
    qty = project_points(prob.y, proj.q, proj.v)[0]
    return prob.y - qty @ proj.q.T


def residual_peaks(prob, proj, lam, n_candidates=2, screen_pfa=POLICY.screen_pfa):
    """Where a missing mode would be: peaks of the noise-normalised residual power of the
    projection ``proj`` at the eigenvalues ``lam``.

    ``S(w) = sum_j |r_j(w)|^2 / s_j^2`` is chi-square with 2P degrees of freedom per line when
    the model is complete; a missing mode adds a coherent bump about one bandwidth wide, so ``S``
    is smoothed over the typical bandwidth (in lines) of the modes found. Only peaks above the
    chi-square level of false-alarm probability ``screen_pfa`` over the band are returned (a cheap
    screen before the likelihood-ratio test), strongest first, at most ``n_candidates``:
    candidate data poles, damping the median of the modes found. Also returns ``S`` itself
    (unsmoothed): ``(candidates, S)``.
    """
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    omega = prob.omega
    n_line = omega.size
    resid = residual_rows(prob, proj)
    s2 = np.maximum(proj.rss, 1e-300) / max(prob.n_rows - proj.coef.shape[1], 1)
    power = np.sum((resid[:, :n_line] ** 2 + resid[:, n_line:] ** 2) / s2[:, None], axis=0)
    zeta = float(np.median(-lam.real / np.abs(lam))) if lam.size else 0.01
    dw = omega[1] - omega[0]
    width = 2.0 * float(np.median(np.abs(lam.real))) if lam.size else 4 * dw
    m = int(np.clip(round(width / dw), 1, max(n_line // 20, 1)))
    smooth = np.convolve(power, np.ones(m) / m, mode="same")
    smooth[: m + 1] = 0.0  # not at DC or Nyquist: no room for a resonance there
    smooth[-m - 1 :] = 0.0
    level = chi2.isf(screen_pfa / n_line, 2 * prob.n_points * m) / m
    out = []
    for _ in range(n_candidates):
        i = int(np.argmax(smooth))
        if smooth[i] <= level:
            break
        w = omega[i]
        out.append(complex(-zeta * w + 1j * w * np.sqrt(1.0 - zeta**2)))
        smooth[max(i - 3 * m, 0) : i + 3 * m + 1] = 0.0
    return out, power


def complex_rows(z: np.ndarray) -> np.ndarray:
    """Complex (P, L) from real-stacked rows (P, 2L)."""
    n_line = z.shape[1] // 2
    return z[:, :n_line] + 1j * z[:, n_line:]


def weighted_gain(before: np.ndarray, after: np.ndarray, var: np.ndarray) -> float:
    """Likelihood-ratio gain ``2 sum (|r_before|^2 - |r_after|^2) / v`` of complex residuals
    (P, L) whose lines have complex error variance ``v = E|e|^2`` (P, L): each real component
    has variance ``v / 2``."""
    return float(2.0 * np.sum((np.abs(before) ** 2 - np.abs(after) ** 2) / var))


def band_fit(
    prob,
    fit,
    trial,
    opts: dict,
    min_width: float,
    var: np.ndarray | None = None,
    policy: OrderPolicy = POLICY,
):
    """Fit one completion trial on its own band: the lines within ``local_widths`` half-power
    bandwidths of the modes it changes (moved, added or removed), the data less the present
    fit's far modes (residues held), the modes in the band free.

    ``var`` (P, L): the error variance ``E|e|^2`` of every point and line (noise and the model
    error of a peak, :func:`ami_xr.core.model_error.error_variance`) the gain is measured against;
    None: white noise at the present fit's level on all lines.

    Returns ``(likelihood-ratio gain on the band, the trial's start with its band modes at
    their fitted values, iterations of the band fit)``; the gain is ``None`` (then screen on
    all lines) when the band holds
    more than ``local_max_share`` of the lines or too few for its modes, or when the band fit
    fails or freezes a mode the trial changes.
    """
    start, ref, _, removed = trial
    lam, omega = fit.lam, prob.omega
    kept = np.delete(np.arange(lam.size), removed)
    n_old = kept.size
    changed = np.append(start[:n_old] != lam[kept], np.ones(start.size - n_old, bool))
    if not (changed.any() or removed.size):
        return None, start, 0
    poles = np.concatenate([start[changed], lam[removed]])
    margin = policy.local_widths * float(np.max(np.maximum(2.0 * np.abs(poles.real), min_width)))
    lo, hi = poles.imag.min() - margin, poles.imag.max() + margin
    sel = np.flatnonzero((omega >= lo) & (omega <= hi))
    # the old modes the band model holds: inside the band, changed or removed by the trial
    near = (lam.imag >= lo) & (lam.imag <= hi)
    near[kept[changed[:n_old]]] = True
    near[removed] = True
    entry = np.append(near[kept], np.ones(start.size - n_old, bool))  # trial entries in band
    n_col = 2 * max(int(entry.sum()), int(near.sum())) + 2 * len(prob.residual_terms)
    if sel.size > policy.local_max_share * omega.size or 2 * sel.size < 3 * n_col:
        return None, start, 0
    n_line = omega.size
    far = np.flatnonzero(~near)
    y = prob.y[:, np.concatenate([sel, n_line + sel])]
    if far.size:  # the far modes at the present fit, residues held
        kind = prob.residual_kind
        phi = model_columns(omega[sel], lam[far], prob.dt, prob.n_samples, (), kind)[0]
        cols = np.ravel(np.column_stack([2 * far, 2 * far + 1]))
        model = phi * prob.line_weight[sel, None]
        y = y - fit.proj.coef[:, cols] @ np.concatenate([model.real, model.imag]).T
    band = varpro.Problem(
        np.ascontiguousarray(y),
        omega[sel],
        prob.line_weight[sel],
        prob.dt,
        prob.n_samples,
        prob.residual_terms,
        prob.residual_kind,
    )
    if near.any() or band.residual_terms:
        proj0 = varpro.project(band, lam[near])
        before, r_before = proj0.rss, residual_rows(band, proj0) if proj0.ok else None
    else:  # nothing modelled on the band yet: the data are the residual
        before, r_before = np.sum(band.y**2, axis=1), band.y
    tried = changed[entry]
    # a tried mode frozen leaves the band unable to judge the trial: no fit beyond that
    local = fit_modes(band, start[entry], ref[entry], give_up=tried, **opts)
    refined = start.copy()
    refined[entry] = local[0].lam
    fine = np.all(np.isfinite(before)) and np.isfinite(local[0].cost) and local[1][tried].all()
    if not fine:
        return None, refined, local[2]  # the band cannot tell (a far mode's tail, a neighbour)
    if var is not None:
        r_after = complex_rows(residual_rows(band, local[0].proj))
        gain = weighted_gain(complex_rows(r_before), r_after, var[:, sel])
        return gain, refined, local[2]
    # the full likelihood's gain to first order: the band's drop of |r_j|^2 over the noise
    # variance of the present fit on all lines (a noise level profiled on the band alone holds
    # the misfit the trial removes: it understated strong modes several times)
    noise = np.maximum(fit.proj.rss, (varpro.RSS_FLOOR**2) * prob.y_norm2) / prob.n_rows
    return float(np.sum((before - local[0].proj.rss) / noise)), refined, local[2]
