"""Array core of the joint maximum-likelihood refinement (plain arrays, no xarray).

:func:`refine_arrays` fits every eigenvalue and residue to every FRF at once by variable
projection (:mod:`ami_xr.core.varpro`), keeps each mode inside a region around its AMI value
(freezing it there otherwise), checks the model order by likelihood-ratio tests (drops
insignificant modes, adds modes AMI missed) and returns a :class:`RefineResult`. The labeled
wrapper is :func:`ami_xr.refine`; the method is described in :mod:`ami_xr.ami.refine`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np

from ami_xr.core import varpro
from ami_xr.core.matching import match_by_distance
from ami_xr.core.modal import modal_std, mode_vectors
from ami_xr.core.model import RESIDUAL_TERMS
from ami_xr.kernels.modal_basis import model_columns
from ami_xr.kernels.projection import project_points

# Status of each refined mode, decided here, where it is known: STATUS_FALLBACK only for a mode
# whose eigenvalue is still its AMI value (frozen there by the first fit, or nothing could be
# fitted); a mode frozen later, at a value an earlier stage refined, is STATUS_OK.
STATUS_OK, STATUS_NOT_CONVERGED, STATUS_FALLBACK = 0, 1, 2
TRIAL_ITERATIONS = 10  # cap of the trial fits of the model-order tests
FALLBACK_MESSAGE = "fallback: nothing could be fitted"  # FitResult.message of a fit given up


class RefineOptions(Protocol):
    """The settings :func:`refine_arrays` reads: the fields of
    :class:`ami_xr.ami.settings.RefineSettings` (read by attribute, so this array core does not
    import the labeled layer)."""

    max_iter: int
    tol: float
    max_shift: float
    add_modes: int
    add_pfa: float
    drop_modes: bool


class RefineModel(NamedTuple):
    """What the data say about the model: the basis (``dt = 0``: continuous; else the discrete
    basis of ``n_samples``), the residual terms (resolved) and their kind (0 receptance, 1
    mobility, 2 accelerance), the drive point's row (None: no drive point) and the decay rate
    (1/s) of an exponential window already corrected in the starting eigenvalues."""

    dt: float
    n_samples: int
    residual_terms: tuple[str, ...]
    residual_kind: int
    drive_index: int | None
    decay: float


class Trace(Protocol):
    """Progress counter the labeled layer may pass (:class:`ami_xr.progress.Iterations`)."""

    stage: str
    modes: int

    def append(self, item: object) -> None: ...

    def show(self) -> None: ...


@dataclass
class RefineResult:
    """What :func:`refine_arrays` returns, per output mode (K') and point (P).

    Output modes are the AMI modes that survive, in AMI order, then the added ones.
    """

    lam: np.ndarray  # (K',) complex eigenvalues, rad/s
    eig_std: np.ndarray  # (K',) complex: std(Re) + i std(Im)
    fn_std: np.ndarray  # (K',) Hz
    zeta_std: np.ndarray  # (K',)
    residue: np.ndarray  # (P, K') complex
    residue_std: np.ndarray  # (P, K') sqrt(E|dA|^2)
    mode_vector: np.ndarray  # (P, K') complex, eq. 8
    mode_vector_std: np.ndarray  # (P, K') sqrt(E|dPhi|^2)
    noise_std: np.ndarray  # (P,) complex noise std of one FRF line
    residual_coefficient: np.ndarray  # (P, 2) complex (lower, upper), NaN where not fitted
    status: np.ndarray  # (K',) int8: STATUS_OK, STATUS_NOT_CONVERGED or STATUS_FALLBACK
    origin: np.ndarray  # (K',) int64: AMI mode index of each output mode, -1 when added
    n_iter: np.int64  # Levenberg-Marquardt iterations in all
    cost_start: np.float64  # objective at the start
    cost: np.float64  # objective at the optimum
    pair_supported: np.ndarray  # (K',) bool: one of a close pair the order test kept
    merged_fn: np.ndarray  # (K',) Hz of a split duplicate merged into the mode, NaN if none


@dataclass
class _State:
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
    for k in range(lam.size):
        others = np.delete(lam, k)
        if others.size and np.min(np.abs(others - lam[k])) < 1e-6 * np.abs(lam[k]):
            code[k] = 2
    return code


def _fit_modes(
    prob, mu0, ref, *, decay, max_iter, tol, max_shift, min_width, free=None, trace=None
):
    """Levenberg-Marquardt from ``mu0`` (data poles); a mode that leaves its region around
    ``ref`` (physical eigenvalues) is frozen at its start and the fit goes on without it.
    ``trace``: an :class:`ami_xr.progress.Iterations` counting the iterations (or None).

    Returns ``(fit, free, n_iter, start_cost)``.
    """
    n_mode = mu0.size
    free = np.ones(n_mode, bool) if free is None else np.array(free, bool)

    def check(mu):
        return _mode_codes(mu + decay, ref, max_shift, min_width)

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
        start_mu = np.where(free, fit.lam, mu0)
    return fit, free, n_iter, start_cost


def _residual_candidates(prob, fit, n_candidates=2, screen_pfa=0.1):
    """Where a missing mode would be: peaks of the noise-normalised residual power.

    ``S(w) = sum_j |r_j(w)|^2 / s_j^2`` is chi-square with 2P degrees of freedom per line when
    the model is complete; a missing mode adds a coherent bump about one bandwidth wide, so ``S``
    is smoothed over the typical bandwidth (in lines) of the modes found. Only peaks above the
    chi-square level of false-alarm probability ``screen_pfa`` over the band are returned (a cheap
    screen before the likelihood-ratio test): candidate data poles, damping the median of the
    modes found.
    """
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    proj = fit.proj
    omega = prob.omega
    n_line = omega.size
    resid = _residual_rows(prob, proj)
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
    return out


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


def _residual_rows(prob, proj):
    """Residuals ``y_j - Q Q' y_j`` of every point (P, 2L)."""
    qty = project_points(prob.y, proj.q, proj.v)[0]
    return prob.y - qty @ proj.q.T


def refine_arrays(
    frf: np.ndarray,
    freq: np.ndarray,
    lam0: np.ndarray,
    res0: np.ndarray,
    settings: RefineOptions,
    model: RefineModel,
    trace: Trace | None = None,
) -> RefineResult:
    """Refine on plain arrays: frf (P, L), freq (L,) Hz, lam0 (K,), res0 (P, K).

    ``settings`` are those of :func:`ami_xr.refine` (a ``RefineSettings``), ``model`` what the
    data say (:class:`RefineModel`); ``trace`` counts the iterations and names the stage for a
    progress bar (None: nothing reported).
    """
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    n_point = frf.shape[0]
    decay = model.decay
    omega = 2.0 * np.pi * np.asarray(freq, dtype=np.float64)
    prob = varpro.make_problem(
        frf,
        omega,
        model.dt,
        model.n_samples,
        model.residual_terms,
        nyquist=np.pi / model.dt if model.dt else None,
        residual_kind=model.residual_kind,
    )
    # An exponential window multiplies exp(lam t) by exp(-decay t): data poles are lam - decay.
    lam0 = np.asarray(lam0, dtype=np.complex128)
    min_width = 2.0 * (omega[1] - omega[0]) if omega.size > 1 else 0.0
    opts = dict(
        decay=decay,
        max_iter=settings.max_iter,
        tol=settings.tol,
        max_shift=settings.max_shift,
        min_width=min_width,
        trace=trace,
    )
    _stage(trace, "fit")
    fit, free, n_iter, start_cost = _fit_modes(prob, lam0 - decay, lam0, **opts)
    # the first fit starts at AMI's values: a mode frozen there is a fallback
    state = _State(fit, free, lam0, res0, np.arange(lam0.size), n_iter, at_ami=~free)
    _order_tests(prob, state, settings, opts, n_point, chi2, min_width)
    n_ami = state.origin.size  # AMI modes kept (the added ones follow them)
    if state.changed and np.isfinite(state.fit.cost):  # polish the new model (frozen stay so)
        _stage(trace, "polish")
        fit, free = state.fit, state.free
        ref = np.where(free, state.lam0, fit.lam + decay)
        polish_opts = dict(opts, max_iter=max(settings.max_iter - state.n_iter, 5))
        polish = _fit_modes(prob, fit.lam, ref, free=free, **polish_opts)
        state.n_iter += polish[2]
        if polish[0].cost <= fit.cost:
            # a mode the polish froze stays at its start: at AMI's value only if it was there
            state.fit, state.free = polish[0], free & polish[1]
            state.at_ami = state.at_ami & ~polish[1]
    _stage(trace, "standard errors")
    return _result(prob, state, n_ami, start_cost, model.drive_index, decay, min_width)


def _stage(trace: Trace | None, stage: str) -> None:
    """Name the stage on the progress counter (when one listens)."""
    if trace is not None:
        trace.stage = stage
        trace.show()


def _order_tests(prob, state: _State, settings: RefineOptions, opts, n_point, chi2, min_width):
    """Model-order checks by likelihood ratio: a mode AMI missed (e.g. one of a close pair lost
    in noise) leaves a coherent residual; it is added when the likelihood gain is significant at
    false-alarm probability ``add_pfa`` over all lines (2 + 2P parameters per mode)."""
    fit = state.fit
    trace = opts["trace"]
    threshold = chi2.isf(settings.add_pfa / max(prob.omega.size, 1), 2 + 2 * n_point)
    # An exact fit (noise-free data) leaves no noise for the tests to refer to: order kept.
    exact = (
        not (fit.proj.ok and np.isfinite(fit.cost)) or np.max(fit.proj.rss / prob.y_norm2) < 1e-20
    )
    if exact:
        return
    # Trial fits of the order tests stop early: an unfinished fit only overstates the cost of
    # the smaller model (conservative for dropping) and the kept model is polished at the end.
    trial_opts = dict(opts, max_iter=min(settings.max_iter, TRIAL_ITERATIONS))
    if settings.drop_modes:
        _stage(trace, "order test (drop)")
        _drop_insignificant(prob, state, threshold, trial_opts)
    _stage(trace, "order test (add)")
    for _ in range(settings.add_modes):
        if not _add_missed(prob, state, threshold, opts["decay"], trial_opts):
            break
    if settings.drop_modes:
        _stage(trace, "order test (close pairs)")
        _merge_split_pairs(prob, state, settings.add_pfa, opts["decay"], trial_opts, min_width)


def _drop_insignificant(prob, state: _State, threshold: float, trial_opts: dict) -> None:
    """Drop modes whose removal costs less likelihood than ``threshold`` (a spurious AMI mode
    fitting noise), refitting the others; at least one mode stays. Screened cheaply first:
    removing a mode without refitting the others costs at least as much as with refitting."""
    while state.fit.lam.size > 1:
        fit = state.fit
        lr = 2.0 * (_costs_without_each_mode(prob, fit.proj) - fit.cost)
        k = int(np.argmin(lr))
        if not lr[k] < threshold:
            break
        trial = _fit_modes(prob, np.delete(fit.lam, k), np.delete(state.lam0, k), **trial_opts)
        state.n_iter += trial[2]
        if not 2.0 * (trial[0].cost - fit.cost) < threshold:
            break
        state.fit, state.free = trial[0], np.delete(state.free, k) & trial[1]
        state.at_ami = np.delete(state.at_ami, k) & ~trial[1]  # refitted unless frozen
        state.changed = True
        state.lam0 = np.delete(state.lam0, k)
        state.origin = np.delete(state.origin, k)
        state.res0 = np.delete(state.res0, k, 1)


def _add_missed(prob, state: _State, threshold: float, decay: float, trial_opts: dict) -> bool:
    """Try the residual's candidate peaks as an extra mode; keep the best one whose likelihood
    gain exceeds ``threshold`` and that stays free. Returns whether a mode was added."""
    fit = state.fit
    if not (fit.proj.ok and np.isfinite(fit.cost)):
        return False
    best = None
    for cand in _residual_candidates(prob, fit):
        ref = np.append(fit.lam + decay, cand + decay)
        trial = _fit_modes(prob, np.append(fit.lam, cand), ref, **trial_opts)
        state.n_iter += trial[2]
        gain = 2.0 * (fit.cost - trial[0].cost)
        if (
            trial[1][-1]
            and trial[1].all()
            and gain > threshold
            and (best is None or trial[0].cost < best[0].cost)
        ):
            best = trial
    if best is None:
        return False
    state.fit, trial_free, _, _ = best
    state.free = np.append(state.free, True) & trial_free
    state.at_ami = np.append(state.at_ami, False) & ~trial_free
    state.lam0 = np.append(state.lam0, state.fit.lam[-1] + decay)
    state.changed = True
    return True


def _complex_rows(z: np.ndarray) -> np.ndarray:
    """Complex (P, L) from real-stacked rows (P, 2L)."""
    n_line = z.shape[1] // 2
    return z[:, :n_line] + 1j * z[:, n_line:]


def _peak_strength(proj, k: int) -> float:
    """Size of mode ``k``'s resonance: sum over points of ``|A_jk| / |Re lam_k|``."""
    a = proj.coef[:, 2 * k] + 1j * proj.coef[:, 2 * k + 1]
    return float(np.sum(np.abs(a)) / max(abs(proj.lam[k].real), 1e-300))


def _error_variance(prob, proj, width: np.ndarray, skip: np.ndarray):
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

    Returns ``(variance (P, L), rho (K,), largest rho over the modes not in skip)``.
    """
    resid = _complex_rows(_residual_rows(prob, proj))
    model = _complex_rows(prob.y) - resid
    r2 = np.abs(resid) ** 2
    m2 = np.abs(model) ** 2
    s2 = np.maximum(np.median(r2, axis=1), 1e-300) / np.log(2.0)
    rho = np.zeros(proj.lam.size)
    for k in range(proj.lam.size):
        band = np.abs(prob.omega - proj.lam[k].imag) <= 3.0 * width[k]
        if band.any():
            # excess over the noise beyond its own spread (|e|^2 exponential: std = mean),
            # three standard deviations: pure noise gives rho ~ 0
            spread = np.sqrt(band.sum() * np.sum(s2**2))
            excess = np.sum(r2[:, band] - s2[:, None]) - 3.0 * spread
            rho[k] = max(excess, 0.0) / max(np.sum(m2[:, band]), 1e-300)
    others = rho[~skip]
    eps2 = float(np.median(others)) if others.size else 0.0
    return s2[:, None] + eps2 * m2, rho, float(np.max(others)) if others.size else 0.0


def _close_pairs(lam: np.ndarray, width: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of modes closer than the larger of their half-power bandwidths, closest first."""
    pairs = []
    for i in range(lam.size):
        for j in range(i + 1, lam.size):
            sep = abs(lam[i].imag - lam[j].imag)
            if sep < max(width[i], width[j]):
                pairs.append((sep / max(width[i], width[j]), i, j))
    return [(i, j) for _, i, j in sorted(pairs)]


def _merge_split_pairs(prob, state: _State, pfa: float, decay: float, trial_opts, min_width):
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
      model's residual (:func:`_error_variance`, the pair's own peak left out of the
      model-error estimate), ``2 sum (|r_1|^2 - |r_2|^2) / v`` exceeds the chi-square quantile
      with ``2 + 2P`` degrees of freedom (the second eigenvalue and its residues) at false-alarm
      probability ``pfa``;
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
        trial = _fit_modes(prob, np.delete(lam, weak), ref, **trial_opts)
        state.n_iter += trial[2]
        one = trial[0]
        if not (one.proj.ok and np.isfinite(one.cost)):
            continue
        centre = 0.5 * (lam[i].imag + lam[j].imag)
        half = 0.5 * abs(lam[i].imag - lam[j].imag) + 3.0 * max(width[i], width[j])
        band = np.abs(prob.omega - centre) <= half
        skip = np.abs(one.lam.imag - centre) <= half
        var, rho, rho_max = _error_variance(prob, one.proj, np.delete(width, weak), skip)
        var = var[:, band]
        r1 = np.abs(_complex_rows(_residual_rows(prob, one.proj))[:, band]) ** 2 / var
        r2 = np.abs(_complex_rows(_residual_rows(prob, fit.proj))[:, band]) ** 2 / var
        # the one-pole fit is no better there than at the worst single-pole peak
        excess = rho[kept] >= rho_max
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


def _result(
    prob, state: _State, n_ami: int, start_cost, drive_index, decay, min_width
) -> RefineResult:
    """Statuses, standard errors, mode vectors and residual terms of the final fit, with the
    output modes matched to their AMI modes."""
    fit, free, lam0 = state.fit, state.free, state.lam0
    n_point = prob.n_points
    residual_terms = prob.residual_terms
    n_mode = lam0.size
    res0 = np.concatenate([state.res0, np.full((n_point, n_mode - n_ami), np.nan + 0j)], axis=1)
    origin = np.concatenate([state.origin, np.full(n_mode - n_ami, -1)])
    supported = state.supported if state.supported is not None else np.zeros(n_mode, bool)
    merged_fn = state.merged_fn if state.merged_fn is not None else np.full(n_mode, np.nan)
    status = np.full(n_mode, STATUS_OK, dtype=np.int8)
    added = np.arange(n_mode) >= n_ami
    if not fit.converged:
        # flag the modes still moving (a mode wandering in noise must not flag the others)
        moving = fit.mode_step > 1e-4 if fit.mode_step is not None else np.ones(n_mode, bool)
        # (a frozen mode is not moving: it is a fallback or sits at a value refined before)
        status[free & (moving if moving[free].any() else True)] = STATUS_NOT_CONVERGED
    status[state.at_ami] = STATUS_FALLBACK  # frozen at a refined value: not a fallback
    proj = fit.proj
    lam = fit.lam + decay
    n_coef = 2 * n_mode + 2 * len(residual_terms)
    if proj.ok:
        dof = max(prob.n_rows - n_coef - 2.0 * free.sum() / max(n_point, 1), 1.0)
        noise_var = np.maximum(proj.rss, 1e-300) / dof
        cov = varpro.covariance(prob, proj, noise_var, drive_index, lam_shift=decay)
        residue = cov.residue
        cov_theta = cov.cov_theta
        res_std = np.sqrt(np.maximum(cov.residue_var, 0.0))
        coef = proj.coef
    else:  # nothing could be fitted: AMI values, no standard errors
        noise_var = np.full(n_point, np.nan)
        residue = np.array(res0, dtype=np.complex128)
        cov_theta = np.full((2 * n_mode, 2 * n_mode), np.nan)
        res_std = np.full((n_point, n_mode), np.nan)
        coef = np.full((n_point, n_coef), np.nan)
        status[:] = STATUS_FALLBACK
        cov = None
    # Frozen modes keep AMI's eigenvalue; their residues are the projection at that eigenvalue
    # (the least-squares residues given the other modes), unless nothing could be fitted.
    eig_std, fn_std, zeta_std = modal_std(lam, cov_theta)
    if cov is not None and cov.mode_vector is not None:
        mode_vector = cov.mode_vector
        mv_std = np.sqrt(np.maximum(cov.mode_vector_var, 0.0))
    else:
        mode_vector = mode_vectors(residue, lam, drive_index)
        mv_std = np.full((n_point, n_mode), np.nan)
    res_terms = np.full((n_point, 2), np.nan + 0j)  # (lower, upper)
    for r, term in enumerate(residual_terms):
        value = coef[:, 2 * n_mode + 2 * r] + 1j * coef[:, 2 * n_mode + 2 * r + 1]
        res_terms[:, RESIDUAL_TERMS.index(term)] = value
    # per-line complex noise std (E|e|^2 = 2 s^2 for the two real components)
    noise_std = np.sqrt(2.0 * noise_var)
    # Output mode c is the refined mode matched to AMI mode c (close modes may swap in the fit).
    if np.all(np.isfinite(lam)):
        width = np.maximum(2.0 * np.abs(lam0.real), min_width)
        order = np.argsort(match_by_distance(lam, lam0, width))
        lam, eig_std, fn_std, zeta_std, status, added, origin, supported, merged_fn = (
            a[order]
            for a in (lam, eig_std, fn_std, zeta_std, status, added, origin, supported, merged_fn)
        )
        residue, res_std, mode_vector, mv_std = (
            a[:, order] for a in (residue, res_std, mode_vector, mv_std)
        )
    return RefineResult(
        lam=lam,
        eig_std=eig_std,
        fn_std=fn_std,
        zeta_std=zeta_std,
        residue=residue,
        residue_std=res_std,
        mode_vector=mode_vector,
        mode_vector_std=mv_std,
        noise_std=noise_std,
        residual_coefficient=res_terms,
        status=status,
        origin=origin,
        n_iter=np.int64(state.n_iter),
        cost_start=np.float64(start_cost),
        cost=np.float64(fit.cost),
        pair_supported=supported,
        merged_fn=merged_fn,
    )


def synthesize(
    omega: np.ndarray,
    mu: np.ndarray,
    residue: np.ndarray,
    residual_coefficient: np.ndarray,
    residual_terms: tuple[str, ...],
    residual_kind: int,
    dt: float,
    n_samples: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The refined model on the lines ``omega``: ``(synth (P, L), columns (L, 2K + 2R))``.

    ``mu`` (K,) are the data's poles (eigenvalues minus any window decay), ``residue`` (P, K),
    ``residual_coefficient`` (P, 2) as in :class:`RefineResult`. The columns are those of
    :func:`ami_xr.kernels.modal_basis.model_columns` (the residue of mode ``k`` multiplies columns
    ``2k`` and ``2k + 1``).
    """
    cols, _ = model_columns(omega, mu, dt, n_samples, residual_terms, residual_kind)
    n_mode = mu.size
    coef = np.zeros((residue.shape[0], cols.shape[1]))
    coef[:, 0 : 2 * n_mode : 2] = residue.real
    coef[:, 1 : 2 * n_mode : 2] = residue.imag
    for r, term in enumerate(residual_terms):
        value = residual_coefficient[:, RESIDUAL_TERMS.index(term)]
        coef[:, 2 * n_mode + 2 * r] = value.real
        coef[:, 2 * n_mode + 2 * r + 1] = value.imag
    return coef @ cols.T, cols


def contribution_peaks(cols: np.ndarray, residue: np.ndarray) -> np.ndarray:
    """Peak ``|contribution|`` of each mode (K,) for one point's residues ``residue`` (K,), on
    the model columns ``cols`` of :func:`synthesize`."""
    n_mode = residue.size
    contribution = (
        cols[:, 0 : 2 * n_mode : 2] * residue.real + cols[:, 1 : 2 * n_mode : 2] * residue.imag
    )
    return np.max(np.abs(contribution), axis=0)
