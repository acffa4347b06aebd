"""Joint maximum-likelihood refinement of all eigenvalues and residues (beyond the paper).

AMI estimates each eigenvalue from single-mode fits near its peak and each residue from a fit over
bands near the natural frequencies (eq. 9). Both steps discard information: the fits are
band-limited, and noise biases the single-mode fits. :func:`refine` starts from AMI's result and
fits the whole model -- every eigenvalue and every residue -- to every FRF over the whole band at
once, by maximum likelihood:

* the model of the data is exact: for FRFs made as ``dt * DFT`` of a sampled impulse response
  (``frf_source="impulse_response"`` with ``sample_interval`` and ``record_samples``) each mode
  contributes ``A b(lam) + conj(A) b(conj lam)`` with the discrete-time basis
  ``b(lam, w) = dt (1 - exp(lam N dt)) / (1 - exp((lam - i w) dt))``; otherwise the continuous
  basis ``1 / (i w - lam)`` of eq. 4, optionally with lower and upper residual terms
  (``-R_L / w^2`` and ``R_U``, complex) for modes outside the band;
* noise: white noise of variance ``s_j^2`` on the samples of impulse response ``j`` becomes noise
  of variance ``N dt^2 s_j^2`` on every FRF line, independent between lines (half of it in the
  real part, half in the imaginary part; all of it in the real part at DC and Nyquist, which are
  weighted accordingly). Each FRF's variance is unknown and profiled out, so the objective is
  ``sum_j (n / 2) log |r_j|^2``: every FRF is weighted by its own estimated noise level;
* variable projection: for given eigenvalues the residues of FRF ``j`` follow from FRF ``j`` alone
  by linear least squares on a basis all FRFs share (one QR factorisation per evaluation); the
  eigenvalues, shared by all FRFs, follow by Levenberg-Marquardt on the Kaufman Jacobian (with a
  secant correction of the curvature). Steps are taken only when they lower the objective, so
  the result is never worse than the start.

Robustness: a mode that leaves the upper-left quadrant, moves more than ``max_shift`` half-power
bandwidths from its AMI value, lets its damping collapse (it is then fitting a noise spike) or
merges with another mode is frozen at its AMI eigenvalue and the fit goes on without it; such
modes carry the flag ``refine_fallback``. A mode still moving when the fit stops at
``max_iter`` carries ``refine_not_converged``. Two close modes that trade places keep their AMI
labels (matched by distance).

Model order: a mode AMI missed (typically one of a close pair lost in the noise) leaves a
coherent residual. Peaks of the noise-normalised residual power are tried as extra modes and
kept when the likelihood-ratio statistic is significant (``add_modes``, ``add_pfa``); they are
flagged ``added_by_refine``. An AMI mode that fails the same test is dropped (``drop_modes``).
The global-fit outputs that depend on the residues
(``frf_synthesized``, ``frf_residual``, ``mac``, ``drive_point_snr`` and its
``low_drive_point_snr`` flag) are recomputed from the refined model.

Standard errors (``eigenvalue_std``, ``natural_frequency_std``, ``damping_ratio_std``,
``residue_std``, ``mode_vector_std``) come from the Gauss-Newton covariance at the optimum with the
estimated noise levels; for an efficient estimator they are the spread over repeated noise.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr._provenance import add_history, history
from ami_xr.ami import _varpro
from ami_xr.ami.global_fit import FLAG_LOW_DRIVE_SNR, RESIDUAL_KIND, mac_matrix, mode_vectors
from ami_xr.errors import IdentificationError
from ami_xr.kernels.refine import model_columns, project_points

QUALITY_FLAGS = names.QUALITY_FLAGS
DRIVE_SNR_MIN = 3.0  # global_fit's default threshold of the low_drive_point_snr flag
_STATUS_OK, _STATUS_NOT_CONVERGED, _STATUS_FALLBACK = 0, 1, 2
TRIAL_ITERATIONS = 10  # cap of the trial fits of the model-order tests
FLAG_ADDED = "added_by_refine"  # a mode AMI missed, added by the likelihood-ratio check
_FLAG_SEPARATOR = ","


# ------------------------------------------------------------------------------------------
# array core (one call per Dataset; wrapped by xr.apply_ufunc below)
# ------------------------------------------------------------------------------------------
def _match(lam: np.ndarray, lam0: np.ndarray, width: np.ndarray) -> np.ndarray:
    """``perm[k]``: the start (AMI mode) that refined mode ``k`` belongs to.

    Two close modes may trade places during the fit (same optimum, labels swapped); matching by
    distance in bandwidths keeps each mode's label and flags with the right eigenvalue.
    """
    from scipy.optimize import linear_sum_assignment  # lazy: keeps `import ami_xr` fast

    cost = np.abs(lam[:, None] - lam0[None, :]) / width[None, :]
    cost = np.where(np.isfinite(cost), cost, 1e300)
    rows, cols = linear_sum_assignment(cost)
    perm = np.empty(lam.size, dtype=int)
    perm[rows] = cols
    return perm


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
    ref = lam0[_match(lam, lam0, width)]
    w = np.maximum(2.0 * np.abs(ref.real), min_width)
    outside = (np.abs(lam - ref) > max_shift * w) | (-lam.real < -ref.real / (1.0 + max_shift))
    code[(code == 0) & outside] = 1
    for k in range(lam.size):
        others = np.delete(lam, k)
        if others.size and np.min(np.abs(others - lam[k])) < 1e-6 * np.abs(lam[k]):
            code[k] = 2
    return code


def _fit_modes(prob, mu0, ref, *, decay, max_iter, tol, max_shift, min_width, free=None):
    """Levenberg-Marquardt from ``mu0`` (data poles); a mode that leaves its region around
    ``ref`` (physical eigenvalues) is frozen at its start and the fit goes on without it.

    Returns ``(fit, free, n_iter, start_cost)``.
    """
    n_mode = mu0.size
    free = np.ones(n_mode, bool) if free is None else np.array(free, bool)

    def check(mu):
        return _mode_codes(mu + decay, ref, max_shift, min_width)

    start_mu = mu0.copy()
    start_cost = None
    n_iter = 0
    while True:
        fit = _varpro.levenberg_marquardt(
            prob, start_mu, max_iter=max(max_iter - n_iter, 1), tol=tol, free=free, check=check
        )
        n_iter += fit.n_iter
        start_cost = fit.start_cost if start_cost is None else start_cost
        if not np.isfinite(fit.cost) or fit.cost > start_cost:
            # nothing to fit, or worse than the start: fall back to it
            free[:] = False
            fit = _varpro.levenberg_marquardt(prob, mu0, max_iter=0, free=free)
            break
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
    floor = (_varpro.RSS_FLOOR**2) * prob.y_norm2
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


def modal_std(lam: np.ndarray, cov_theta: np.ndarray):
    """Standard deviations of the eigenvalues, natural frequencies (Hz) and damping ratios.

    ``cov_theta`` (2K, 2K) is the covariance of ``(Re lam_1, Im lam_1, Re lam_2, ...)``; the
    frequency and damping ratio follow by the delta method (``wn = |lam|``,
    ``zeta = -Re lam / wn``). Variances that rounding makes slightly negative count as 0.
    """
    var_re = np.diag(cov_theta)[0::2]
    var_im = np.diag(cov_theta)[1::2]
    eig_std = np.sqrt(np.maximum(var_re, 0.0)) + 1j * np.sqrt(np.maximum(var_im, 0.0))
    wn = np.abs(lam)
    fn_std = np.empty(lam.size)
    zeta_std = np.empty(lam.size)
    for k in range(lam.size):
        c = cov_theta[2 * k : 2 * k + 2, 2 * k : 2 * k + 2]
        g_wn = np.array([lam[k].real, lam[k].imag]) / wn[k]
        g_z = np.array([-(lam[k].imag ** 2), lam[k].real * lam[k].imag]) / wn[k] ** 3
        fn_std[k] = np.sqrt(max(g_wn @ c @ g_wn, 0.0)) / (2.0 * np.pi)
        zeta_std[k] = np.sqrt(max(g_z @ c @ g_z, 0.0))
    return eig_std, fn_std, zeta_std


def _refine_arrays(
    frf,
    freq,
    lam0,
    res0,
    *,
    dt,
    n_samples,
    residual_terms,
    residual_kind,
    drive_index,
    decay,
    max_iter,
    tol,
    max_shift,
    add_modes,
    add_pfa,
    drop_modes,
):
    """Refine on plain arrays: frf (P, L), freq (L,) Hz, lam0 (K,), res0 (P, K).

    Returns per output mode (AMI modes that survive, in AMI order, then added ones) and
    ``origin``: the AMI mode index of each output mode, -1 for an added one.
    """
    from scipy.stats import chi2  # lazy: scipy.stats is slow to import

    n_point = frf.shape[0]
    omega = 2.0 * np.pi * np.asarray(freq, dtype=np.float64)
    nyquist = np.pi / dt if dt else None
    prob = _varpro.make_problem(
        frf, omega, dt, n_samples, residual_terms, nyquist=nyquist, residual_kind=residual_kind
    )
    # An exponential window multiplies exp(lam t) by exp(-decay t): data poles are lam - decay.
    lam0 = np.asarray(lam0, dtype=np.complex128)
    mu0 = lam0 - decay
    min_width = 2.0 * (omega[1] - omega[0]) if omega.size > 1 else 0.0
    opts = dict(decay=decay, max_iter=max_iter, tol=tol, max_shift=max_shift, min_width=min_width)
    # Trial fits of the order tests stop early: an unfinished fit only overstates the cost of
    # the smaller model (conservative for dropping) and the kept model is polished at the end.
    trial_opts = dict(opts, max_iter=min(max_iter, TRIAL_ITERATIONS))
    fit, free, n_iter, start_cost = _fit_modes(prob, mu0, lam0, **opts)
    changed = False
    n_ami = lam0.size
    # Model-order check by likelihood ratio: a mode AMI missed (e.g. one of a close pair lost in
    # noise) leaves a coherent residual; add it when the likelihood gain is significant at
    # false-alarm probability add_pfa over all lines (2 + 2P parameters per mode).
    threshold = chi2.isf(add_pfa / max(omega.size, 1), 2 + 2 * n_point)
    origin = np.arange(n_ami)
    # An exact fit (noise-free data) leaves no noise for the tests to refer to: order kept.
    exact = (
        not (fit.proj.ok and np.isfinite(fit.cost)) or np.max(fit.proj.rss / prob.y_norm2) < 1e-20
    )
    # A mode whose removal costs less likelihood than that level is not significant (a spurious
    # AMI mode fitting noise): dropped, the others refitted. Screened cheaply first: removing a
    # mode without refitting the others costs at least as much as with refitting.
    while drop_modes and not exact and fit.lam.size > 1:
        lr = 2.0 * (_costs_without_each_mode(prob, fit.proj) - fit.cost)
        k = int(np.argmin(lr))
        if not lr[k] < threshold:
            break
        trial = _fit_modes(prob, np.delete(fit.lam, k), np.delete(lam0, k), **trial_opts)
        n_iter += trial[2]
        if not 2.0 * (trial[0].cost - fit.cost) < threshold:
            break
        fit, free = trial[0], np.delete(free, k) & trial[1]
        changed = True
        lam0, origin, res0 = np.delete(lam0, k), np.delete(origin, k), np.delete(res0, k, 1)
    n_ami = lam0.size
    for _ in range(add_modes if not exact else 0):
        if not (fit.proj.ok and np.isfinite(fit.cost)):
            break
        best = None
        for cand in _residual_candidates(prob, fit):
            ref = np.append(fit.lam + decay, cand + decay)
            trial = _fit_modes(prob, np.append(fit.lam, cand), ref, **trial_opts)
            n_iter += trial[2]
            gain = 2.0 * (fit.cost - trial[0].cost)
            if (
                trial[1][-1]
                and trial[1].all()
                and gain > threshold
                and (best is None or trial[0].cost < best[0].cost)
            ):
                best = trial
        if best is None:
            break
        fit, trial_free, _, _ = best
        free = np.append(free, True) & trial_free
        lam0 = np.append(lam0, fit.lam[-1] + decay)
        changed = True
    if changed and np.isfinite(fit.cost):  # polish the new model (frozen modes stay frozen)
        ref = np.where(free, lam0, fit.lam + decay)
        polish = _fit_modes(
            prob, fit.lam, ref, free=free, **dict(opts, max_iter=max(max_iter - n_iter, 5))
        )
        n_iter += polish[2]
        if polish[0].cost <= fit.cost:
            fit, free = polish[0], free & polish[1]
    n_mode = lam0.size
    res0 = np.concatenate([res0, np.full((n_point, n_mode - n_ami), np.nan + 0j)], axis=1)
    origin = np.concatenate([origin, np.full(n_mode - n_ami, -1)])
    status = np.full(n_mode, _STATUS_OK, dtype=np.int8)
    added = np.arange(n_mode) >= n_ami
    if not fit.converged:
        # flag the modes still moving (a mode wandering in noise must not flag the others)
        moving = fit.mode_step > 1e-4 if fit.mode_step is not None else np.ones(n_mode, bool)
        status[moving if moving[free].any() else np.ones(n_mode, bool)] = _STATUS_NOT_CONVERGED
    status[~free] = _STATUS_FALLBACK
    proj = fit.proj
    lam = fit.lam + decay
    n_coef = 2 * n_mode + 2 * len(residual_terms)
    if proj.ok:
        dof = max(prob.n_rows - n_coef - 2.0 * free.sum() / max(n_point, 1), 1.0)
        noise_var = np.maximum(proj.rss, 1e-300) / dof
        cov = _varpro.covariance(prob, proj, noise_var, drive_index, lam_shift=decay)
        residue = cov["residue"]
        cov_theta = cov["cov_theta"]
        res_std = np.sqrt(np.maximum(cov["residue_var"], 0.0))
        coef = proj.coef
    else:  # nothing could be fitted: AMI values, no standard errors
        noise_var = np.full(n_point, np.nan)
        residue = np.array(res0, dtype=np.complex128)
        cov_theta = np.full((2 * n_mode, 2 * n_mode), np.nan)
        res_std = np.full((n_point, n_mode), np.nan)
        coef = np.full((n_point, n_coef), np.nan)
        status[:] = _STATUS_FALLBACK
        cov = {}
    # Frozen modes keep AMI's eigenvalue; their residues are the projection at that eigenvalue
    # (the least-squares residues given the other modes), unless nothing could be fitted.
    eig_std, fn_std, zeta_std = modal_std(lam, cov_theta)
    if "mode_vector" in cov:
        mode_vector = cov["mode_vector"]
        mv_std = np.sqrt(np.maximum(cov["mode_vector_var"], 0.0))
    else:
        mode_vector = mode_vectors(residue, lam, drive_index)
        mv_std = np.full((n_point, n_mode), np.nan)
    res_terms = np.full((n_point, 2), np.nan + 0j)  # (lower, upper)
    for r, term in enumerate(residual_terms):
        value = coef[:, 2 * n_mode + 2 * r] + 1j * coef[:, 2 * n_mode + 2 * r + 1]
        res_terms[:, 0 if term == "lower" else 1] = value
    # per-line complex noise std (E|e|^2 = 2 s^2 for the two real components)
    noise_std = np.sqrt(2.0 * noise_var)
    # Output mode c is the refined mode matched to AMI mode c (close modes may swap in the fit).
    if np.all(np.isfinite(lam)):
        width = np.maximum(2.0 * np.abs(lam0.real), min_width)
        order = np.argsort(_match(lam, lam0, width))
        lam, eig_std, fn_std, zeta_std, status, added, origin = (
            a[order] for a in (lam, eig_std, fn_std, zeta_std, status, added, origin)
        )
        residue, res_std, mode_vector, mv_std = (
            a[:, order] for a in (residue, res_std, mode_vector, mv_std)
        )
    return (
        lam,
        eig_std,
        fn_std,
        zeta_std,
        residue,
        res_std,
        mode_vector,
        mv_std,
        noise_std,
        res_terms,
        status,
        origin,
        np.int64(n_iter),
        np.float64(start_cost),
        np.float64(fit.cost),
    )


# ------------------------------------------------------------------------------------------
# labeled layer
# ------------------------------------------------------------------------------------------
def _as(da: xr.DataArray, dtype) -> xr.DataArray:
    """``da`` in ``dtype`` (no copy when it already is)."""
    return da if da.dtype == dtype else da.astype(dtype)


def _check_inputs(ds, max_iter, tol, band, residual_terms, max_shift):
    problems = []
    if not isinstance(ds, xr.Dataset):
        raise IdentificationError(f"ds: expected an xarray.Dataset from global_fit, got {type(ds)}")
    if names.FRF not in ds:
        problems.append(f"variable {names.FRF!r} is missing (expected dims (point, frequency))")
    elif set(ds[names.FRF].dims) != {names.POINT, names.FREQUENCY}:
        problems.append(
            f"variable {names.FRF!r}: expected dims (point, frequency), got {ds[names.FRF].dims}"
        )
    if names.EIGENVALUE not in ds:
        problems.append(f"variable {names.EIGENVALUE!r} is missing: run global_fit first")
    elif ds[names.EIGENVALUE].dims != (names.MODE,):
        problems.append(
            f"variable {names.EIGENVALUE!r}: expected dims (mode,), got {ds[names.EIGENVALUE].dims}"
        )
    elif not np.all(np.isfinite(ds[names.EIGENVALUE].values)):
        problems.append(f"variable {names.EIGENVALUE!r}: contains NaN or inf")
    if names.RESIDUE in ds and set(ds[names.RESIDUE].dims) != {names.POINT, names.MODE}:
        problems.append(
            f"variable {names.RESIDUE!r}: expected dims (point, mode), got {ds[names.RESIDUE].dims}"
        )
    if problems:
        raise IdentificationError("refine: " + "; ".join(problems))
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise IdentificationError(f"max_iter: expected a positive integer, got {max_iter!r}")
    if not (isinstance(tol, (int, float, np.floating)) and 0 < tol < 1):
        raise IdentificationError(f"tol: expected a number in (0, 1), got {tol!r}")
    if not (isinstance(max_shift, (int, float, np.floating)) and max_shift > 0):
        raise IdentificationError(f"max_shift: expected a positive number, got {max_shift!r}")
    if not (isinstance(band, str) and band == "all"):
        ok = isinstance(band, Sequence) and not isinstance(band, str) and len(band) == 2
        if ok:
            try:
                lo, hi = float(band[0]), float(band[1])
                ok = lo < hi
            except (TypeError, ValueError):
                ok = False
        if not ok:
            raise IdentificationError(
                f"band: expected 'all' or (f_min, f_max) in Hz with f_min < f_max, got {band!r}"
            )
    if residual_terms != "auto":
        terms = (residual_terms,) if isinstance(residual_terms, str) else residual_terms
        try:
            terms = tuple(terms)
        except TypeError:
            terms = (residual_terms,)
        bad = [t for t in terms if t not in ("lower", "upper")]
        if bad or len(set(terms)) != len(terms):
            raise IdentificationError(
                "residual_terms: expected 'auto' or a subset of ('lower', 'upper'), "
                f"got {residual_terms!r}"
            )


def _model_choice(ds, residual_terms):
    source = ds.attrs.get(names.ATTR_SOURCE)
    dt = ds.attrs.get(names.ATTR_DT)
    n = ds.attrs.get(names.ATTR_NSAMPLES)
    discrete = source == names.SOURCE_IMPULSE and dt is not None and n is not None
    if residual_terms == "auto":
        # as global_fit did; otherwise none where the modal model is exact
        exact = source in (names.SOURCE_IMPULSE, names.SOURCE_ANALYTIC)
        terms = () if exact and names.RESIDUAL_COEFFICIENT not in ds else ("lower", "upper")
    elif isinstance(residual_terms, str):
        terms = (residual_terms,)
    else:
        terms = tuple(residual_terms)
    terms = tuple(t for t in ("lower", "upper") if t in terms)  # canonical order
    return (float(dt) if discrete else None), (int(n) if discrete else None), terms


def refine(
    ds: xr.Dataset,
    *,
    max_iter: int = 50,
    tol: float = 1e-10,
    band: str | tuple[float, float] = "all",
    residual_terms: str | Sequence[str] = "auto",
    max_shift: float = 3.0,
    add_modes: int = 2,
    add_pfa: float = 1e-3,
    drop_modes: bool = True,
    path: str | os.PathLike | None = None,
) -> xr.Dataset:
    """Maximum-likelihood joint refinement of all eigenvalues and residues over all FRFs.

    Parameters
    ----------
    ds : xarray.Dataset
        Output of :func:`ami_xr.global_fit` (or any Dataset with ``frf`` (point, frequency) and
        starting ``eigenvalue`` (mode); ``residue`` (point, mode) is used only as the fallback).
    max_iter : int
        Cap on Levenberg-Marquardt iterations (a capped fit is flagged, never an error).
    tol : float
        Converged when every eigenvalue changes by less than ``tol`` times its modulus in one
        step, when the next step would be below 1 % of the standard errors (statistically
        nothing left to gain), or when the objective can no longer decrease at rounding level.
    band : "all" or (f_min, f_max)
        Frequencies (Hz, inclusive) used by the fit; default the whole band.
    residual_terms : "auto" or subset of ("lower", "upper")
        Extra terms per FRF for modes outside the band, complex coefficients, as in
        :func:`ami_xr.global_fit`: for receptance ``R_L / (i w)^2`` and a constant ``R_U``
        (mobility ``1/(i w)``, ``i w``; accelerance ``1``, ``(i w)^2``; a term singular at 0 Hz
        is zero there). ``"auto"``: none for impulse-response and analytic FRFs (the modal model
        is exact there), both otherwise.
    max_shift : float
        A mode that moves farther than this many half-power bandwidths ``2 |Re lam|`` from its
        AMI eigenvalue is frozen at the AMI value (flag ``refine_fallback``).
    add_modes : int
        At most this many modes AMI missed are added (0: never). After the fit, the peaks of the
        noise-normalised residual power, smoothed over a typical bandwidth, are tried as extra
        modes; one is kept when the likelihood-ratio statistic ``2 (f_K - f_K+1)`` exceeds the
        chi-square quantile with ``2 + 2 P`` degrees of freedom at ``add_pfa / L`` (a false
        alarm probability ``add_pfa`` over ``L`` lines). Added modes come last, flagged
        ``added_by_refine``, with NaN AMI values.
    add_pfa : float
        False-alarm probability of that test, in (0, 1).
    drop_modes : bool
        Drop AMI modes that fail the same test (removing the mode and refitting the others
        lowers the likelihood by less than that level: a spurious mode fitting noise). Their
        labels go to the attribute ``refine_removed_modes``; at least one mode stays.
    path : str or path-like, optional
        Write the result there atomically (netCDF, :func:`ami_xr.to_netcdf`).

    Returns
    -------
    xarray.Dataset
        A new Dataset: the input with ``eigenvalue``, ``natural_frequency``, ``damping_ratio``,
        ``residue`` and ``mode_vector`` replaced by the refined values; the input values kept as
        ``ami_eigenvalue`` etc.; standard errors ``eigenvalue_std`` (complex, std of the real
        part + i std of the imaginary part, rad/s), ``natural_frequency_std`` (Hz),
        ``damping_ratio_std``, ``residue_std`` and ``mode_vector_std`` (point, mode: root mean
        square of the complex error); ``frf_noise_std`` (point): the estimated noise per FRF
        line; ``residual_coefficient`` (point, residual_term) when used; ``quality_flags`` with
        ``refine_not_converged`` / ``refine_fallback`` added where they apply; attributes
        ``refine_iterations``, ``refine_converged``, ``refine_cost_start``, ``refine_cost``
        (the objective ``sum_j (n/2) log |r_j|^2``), ``refine_model``.

    Raises
    ------
    IdentificationError
        Missing ``frf`` or ``eigenvalue``, bad parameters, or too few lines in ``band``.
    """
    _check_inputs(ds, max_iter, tol, band, residual_terms, max_shift)
    if isinstance(add_modes, bool) or not isinstance(add_modes, (int, np.integer)) or add_modes < 0:
        raise IdentificationError(f"add_modes: expected an integer >= 0, got {add_modes!r}")
    if not (isinstance(add_pfa, (int, float, np.floating)) and 0 < add_pfa < 1):
        raise IdentificationError(f"add_pfa: expected a number in (0, 1), got {add_pfa!r}")
    dt, n_samples, terms = _model_choice(ds, residual_terms)
    frf = ds[names.FRF].transpose(names.POINT, names.FREQUENCY)
    if band != "all":
        frf = frf.sel({names.FREQUENCY: slice(float(band[0]), float(band[1]))})
    # The eigenvalues are shared by all points: this step gathers, so dask data are loaded.
    frf = frf.compute() if frf.chunks else frf
    lam0 = ds[names.EIGENVALUE]
    lam0 = lam0.compute() if lam0.chunks else lam0
    n_mode = lam0.sizes[names.MODE]
    n_line = frf.sizes[names.FREQUENCY]
    n_coef = 2 * n_mode + 2 * len(terms)
    if 2 * n_line <= n_coef + 2 * n_mode:
        raise IdentificationError(
            f"band: {n_line} frequency lines, but refining {n_mode} modes needs more than "
            f"{(n_coef + 2 * n_mode) // 2 + 1}"
        )
    if names.RESIDUE in ds:
        res0 = ds[names.RESIDUE].transpose(names.POINT, names.MODE)
        res0 = res0.compute() if res0.chunks else res0
    else:
        res0 = xr.zeros_like(frf.isel({names.FREQUENCY: 0}, drop=True)) * xr.zeros_like(
            lam0, dtype=np.complex128
        )
        res0 = res0.transpose(names.POINT, names.MODE)
    drive = ds.attrs.get(names.ATTR_DRIVE_POINT)
    idx = np.flatnonzero(frf[names.POINT].values.astype(str) == str(drive))
    drive_index = int(idx[0]) if drive is not None and idx.size else None
    kind = RESIDUAL_KIND.get(ds.attrs.get(names.ATTR_FRF_TYPE, "receptance"), 0)
    # identify() corrects the eigenvalues for an exponential window after refine; if they were
    # corrected already (attr set), the data's poles are lam - beta.
    decay = float(ds.attrs.get(names.ATTR_EXP_CORRECTED, 0.0) or 0.0)
    freq = _as(frf[names.FREQUENCY], np.float64)
    kwargs = dict(
        dt=dt,
        n_samples=n_samples,
        residual_terms=terms,
        residual_kind=kind,
        drive_index=drive_index,
        decay=decay,
        max_iter=int(max_iter),
        tol=float(tol),
        max_shift=float(max_shift),
        add_modes=int(add_modes),
        add_pfa=float(add_pfa),
        drop_modes=bool(drop_modes),
    )
    P, F, M = names.POINT, names.FREQUENCY, names.MODE
    if n_mode == 0:
        outs = None
    else:
        outs = xr.apply_ufunc(
            _refine_arrays,
            frf,
            freq,
            _as(lam0, np.complex128),
            _as(res0, np.complex128),
            kwargs=kwargs,
            input_core_dims=[[P, F], [F], [M], [P, M]],
            output_core_dims=[
                [M],
                [M],
                [M],
                [M],
                [P, M],
                [P, M],
                [P, M],
                [P, M],
                [P],
                [P, names.RESIDUAL_TERM],
                [M],
                [M],
                [],
                [],
                [],
            ],
            exclude_dims={M},  # modes may be added
            dask="parallelized",
            output_dtypes=[
                np.complex128,
                np.complex128,
                float,
                float,
                np.complex128,
                float,
                np.complex128,
                float,
                float,
                np.complex128,
                np.int8,
                np.int64,
                np.int64,
                float,
                float,
            ],
            dask_gufunc_kwargs={"allow_rechunk": True, "output_sizes": {names.RESIDUAL_TERM: 2}},
            keep_attrs=False,
        )
        outs = [o.compute() if o.chunks else o for o in outs]
    new = {}
    attrs = {}
    if outs is not None:
        (
            lam,
            eig_std,
            fn_std,
            zeta_std,
            residue,
            res_std,
            phi,
            phi_std,
            noise_std,
            res_terms,
            status,
            origin,
            n_iter,
            cost0,
            cost,
        ) = outs
        origin = origin.values
        added = origin < 0
        kept = origin[~added]
        if kept.size < n_mode:  # insignificant AMI modes dropped
            removed = [ds[names.MODE].values[k].item() for k in range(n_mode) if k not in kept]
            attrs["refine_removed_modes"] = ",".join(str(r) for r in removed)
            ds = _select_modes(ds, kept)
            lam0 = ds[names.EIGENVALUE]
        if added.any():
            ds, lam0 = _with_added_modes(ds, int(added.sum()))
        for var in (
            names.EIGENVALUE,
            names.NATURAL_FREQUENCY,
            names.DAMPING_RATIO,
            names.RESIDUE,
            names.MODE_VECTOR,
        ):
            if var in ds:
                new[names.AMI_PREFIX + var] = ds[var]
        units_frf = ds[names.FRF].attrs.get(names.ATTR_UNITS)
        hz = {names.ATTR_UNITS: names.FREQUENCY_UNITS}
        new[names.EIGENVALUE] = lam.assign_attrs(units="rad/s")
        new[names.NATURAL_FREQUENCY] = (np.abs(lam) / (2 * np.pi)).assign_attrs(hz)
        new[names.DAMPING_RATIO] = (-lam.real / np.abs(lam)).assign_attrs(units="1")
        new[names.RESIDUE] = residue.transpose(P, M)
        new[names.MODE_VECTOR] = phi.transpose(P, M)
        new[names.EIGENVALUE_STD] = eig_std.assign_attrs(units="rad/s")
        new[names.NATURAL_FREQUENCY_STD] = fn_std.assign_attrs(hz)
        new[names.DAMPING_RATIO_STD] = zeta_std.assign_attrs(units="1")
        new[names.RESIDUE_STD] = res_std.transpose(P, M)
        new[names.MODE_VECTOR_STD] = phi_std.transpose(P, M)
        new[names.FRF_NOISE_STD] = noise_std.assign_attrs(
            {names.ATTR_UNITS: units_frf} if units_frf else {}
        )
        if terms:
            new[names.RESIDUAL_COEFFICIENT] = res_terms.assign_coords(
                {names.RESIDUAL_TERM: ["lower", "upper"]}
            )
        low_snr = _refresh_global_outputs(
            ds,
            new,
            lam.values - decay,
            residue.transpose(P, M).values,
            res_terms.values,
            phi.transpose(P, M).values,
            noise_std.values,
            terms,
            kind,
            dt,
            n_samples,
            drive_index,
        )
        new[QUALITY_FLAGS] = _merge_flags(ds, status.values, lam0, low_snr, added)
        attrs["refine_iterations"] = int(n_iter)
        attrs["refine_converged"] = int(bool(np.all(status.values != _STATUS_NOT_CONVERGED)))
        attrs["refine_cost_start"] = float(cost0)
        attrs["refine_cost"] = float(cost)
    # one assignment: the results share the input's point and mode coordinates
    if terms:
        ds = ds.assign_coords({names.RESIDUAL_TERM: ["lower", "upper"]})
    out = ds.assign({k: v.variable if isinstance(v, xr.DataArray) else v for k, v in new.items()})
    out.attrs = {**ds.attrs, **attrs}
    if outs is not None and added.any():
        # added modes take their place in frequency order; AMI's labels 1..K become 1..K'
        perm = np.argsort(out[names.NATURAL_FREQUENCY].values, kind="stable")
        out = out.isel({names.MODE: perm})
        if names.MODE_2 in out.dims:
            out = out.isel({names.MODE_2: perm})
        old = ds[names.MODE].values[: ds.sizes[names.MODE] - int(added.sum())]
        if np.issubdtype(old.dtype, np.integer) and np.array_equal(old, np.arange(1, old.size + 1)):
            labels = np.arange(1, out.sizes[names.MODE] + 1)
            out = out.assign_coords({names.MODE: labels})
            if names.MODE_2 in out.dims:
                out = out.assign_coords({names.MODE_2: labels})
    out.attrs["refine_model"] = "discrete" if dt else "continuous"
    out.attrs["refine_residual_terms"] = ",".join(terms)
    params = {
        "max_iter": max_iter,
        "tol": tol,
        "band": band,
        "residual_terms": terms,
        "max_shift": max_shift,
        "add_modes": add_modes,
        "add_pfa": add_pfa,
        "drop_modes": drop_modes,
    }
    out = add_history(out, "ami_xr.refine", params)
    if path is not None:
        from ami_xr.io import to_netcdf

        to_netcdf(out, path)
    return out


def _refresh_global_outputs(
    ds, new, mu, residue, res_terms, phi, noise_std, terms, kind, dt, n_samples, drive_index
):
    """Recompute what global_fit derived from the residues: the synthesised FRFs and their
    residual (whole band), the MAC matrix and the drive-point SNR. Returns the new
    ``low_drive_point_snr`` decision per mode (None when there is no drive point)."""
    omega = 2 * np.pi * ds[names.FREQUENCY].values.astype(float)
    cols, _ = model_columns(omega, mu, dt, n_samples, terms, kind)
    n_mode = mu.size
    coef = np.zeros((residue.shape[0], cols.shape[1]))
    coef[:, 0 : 2 * n_mode : 2] = residue.real
    coef[:, 1 : 2 * n_mode : 2] = residue.imag
    for r, term in enumerate(terms):
        value = res_terms[:, 0 if term == "lower" else 1]
        coef[:, 2 * n_mode + 2 * r] = value.real
        coef[:, 2 * n_mode + 2 * r + 1] = value.imag
    P, F, M = names.POINT, names.FREQUENCY, names.MODE
    frf = ds[names.FRF].transpose(P, F)
    units = frf.attrs.get(names.ATTR_UNITS, "")
    if names.FRF_SYNTHESIZED in ds or names.FRF_RESIDUAL in ds:
        synth = coef @ cols.T
        new[names.FRF_SYNTHESIZED] = xr.Variable((P, F), synth, {names.ATTR_UNITS: units})
        new[names.FRF_RESIDUAL] = xr.Variable((P, F), frf.values - synth, {names.ATTR_UNITS: units})
    if names.MAC in ds and names.MODE_2 in ds.dims:
        new[names.MAC] = xr.Variable((M, names.MODE_2), mac_matrix(phi))
    if drive_index is None:
        return None
    a = residue[drive_index]
    contribution = cols[:, 0 : 2 * n_mode : 2] * a.real + cols[:, 1 : 2 * n_mode : 2] * a.imag
    peak = np.max(np.abs(contribution), axis=0)
    if names.SUB_NOISE_FLOOR in ds:
        sigma = float(ds[names.SUB_NOISE_FLOOR].transpose(P).values[drive_index])
    else:
        sigma = float(noise_std[drive_index])
    snr = peak / sigma if sigma > 0 else np.full(n_mode, np.inf)
    new[names.DRIVE_POINT_SNR] = xr.Variable((M,), snr)
    threshold = DRIVE_SNR_MIN
    for record in history(ds):
        if record.get("function") == "ami_xr.global_fit":
            threshold = float(record.get("parameters", {}).get("drive_snr_min", threshold))
    return ~(snr >= threshold)


def _select_modes(ds, keep):
    """``ds`` restricted to the modes at positions ``keep`` (and the MAC's second mode dim)."""
    out = ds.isel({names.MODE: keep})
    if names.MODE_2 in out.dims:
        out = out.isel({names.MODE_2: keep})
    return out


def _with_added_modes(ds, n_added):
    """``ds`` extended along ``mode`` by ``n_added`` modes (AMI values missing: NaN, False, "")."""
    labels = ds[names.MODE].values
    if np.issubdtype(labels.dtype, np.integer):
        extra = np.arange(labels.max() + 1, labels.max() + 1 + n_added)
    else:
        extra = np.array([f"added_{i + 1}" for i in range(n_added)])
    new_labels = np.concatenate([labels, extra])
    fill = {}
    for name, var in ds.data_vars.items():
        if names.MODE in var.dims:
            if var.dtype == bool:
                fill[name] = False
            elif var.dtype.kind in "US":
                fill[name] = ""
            elif var.dtype.kind in "iu":
                fill[name] = -1
    drop = [v for v in ds.data_vars if names.MODE_2 in ds[v].dims]
    out = ds.drop_vars(drop).drop_vars(names.MODE_2, errors="ignore")
    if fill:
        out = out.reindex({names.MODE: new_labels}, fill_value=fill)
    else:
        out = out.reindex({names.MODE: new_labels})
    if drop:
        out = out.assign_coords({names.MODE_2: new_labels})
        for v in drop:  # placeholders, recomputed by _refresh_global_outputs
            out[v] = ((names.MODE, names.MODE_2), np.full((new_labels.size,) * 2, np.nan))
    return out, out[names.EIGENVALUE]


def _merge_flags(ds, status, lam0, low_snr=None, added=None):
    """AMI's flags per mode with the refinement's flags appended (and the drive-point SNR flag
    decided again from the refined residues)."""
    n_mode = status.shape[0]
    if QUALITY_FLAGS in ds and ds[QUALITY_FLAGS].dims == (names.MODE,):
        old = [str(v) for v in ds[QUALITY_FLAGS].values]
    else:
        old = [""] * n_mode
    new = []
    for k in range(n_mode):
        flags = [f for f in old[k].split(_FLAG_SEPARATOR) if f]
        if low_snr is not None:
            flags = [f for f in flags if f != FLAG_LOW_DRIVE_SNR]
            if low_snr[k]:
                flags.insert(0, FLAG_LOW_DRIVE_SNR)
        if added is not None and added[k]:
            flags.append(FLAG_ADDED)
        if status[k] == _STATUS_NOT_CONVERGED:
            flags.append(names.FLAG_REFINE_NOT_CONVERGED)
        elif status[k] == _STATUS_FALLBACK:
            flags.append(names.FLAG_REFINE_FALLBACK)
        new.append(_FLAG_SEPARATOR.join(flags))
    return xr.DataArray(
        np.array(new, dtype=str), dims=(names.MODE,), coords={names.MODE: lam0[names.MODE].values}
    )
