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
  eigenvalues, shared by all FRFs, follow by Levenberg-Marquardt on the Kaufman Jacobian. Steps
  are taken only when they lower the objective, so the result is never worse than the start.

Robustness: a mode that leaves the upper-left quadrant, moves more than ``max_shift`` half-power
bandwidths from its AMI value, or merges with another mode is frozen at its AMI eigenvalue and
the fit is repeated; such modes carry the flag ``refine_fallback``. A fit that stops at
``max_iter`` carries ``refine_not_converged``.

Standard errors (``eigenvalue_std``, ``natural_frequency_std``, ``damping_ratio_std``,
``residue_std``, ``mode_vector_std``) come from the Gauss-Newton covariance at the optimum with the
estimated noise levels; for an efficient estimator they are the spread over repeated noise.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
import xarray as xr
from scipy.optimize import linear_sum_assignment

from ami_xr import names
from ami_xr._provenance import add_history
from ami_xr.ami import _varpro
from ami_xr.errors import IdentificationError

QUALITY_FLAGS = getattr(names, "QUALITY_FLAGS", "quality_flags")
_QUANTITY_POWER = {"displacement": 0, "velocity": 1, "acceleration": 2}
_STATUS_OK, _STATUS_NOT_CONVERGED, _STATUS_FALLBACK = 0, 1, 2
_FLAG_SEPARATOR = ","


# ------------------------------------------------------------------------------------------
# array core (one call per Dataset; wrapped by xr.apply_ufunc below)
# ------------------------------------------------------------------------------------------
def _match(lam: np.ndarray, lam0: np.ndarray, width: np.ndarray) -> np.ndarray:
    """``perm[k]``: the start (AMI mode) that refined mode ``k`` belongs to.

    Two close modes may trade places during the fit (same optimum, labels swapped); matching by
    distance in bandwidths keeps each mode's label and flags with the right eigenvalue.
    """
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


def _refine_arrays(
    frf, freq, lam0, res0, *, dt, n_samples, residual_terms, drive_index, quantity_power,
    decay, max_iter, tol, max_shift,
):
    """Refine on plain arrays: frf (P, L), freq (L,) Hz, lam0 (K,), res0 (P, K)."""
    n_point = frf.shape[0]
    n_mode = lam0.shape[0]
    omega = 2.0 * np.pi * np.asarray(freq, dtype=np.float64)
    nyquist = np.pi / dt if dt else None
    prob = _varpro.make_problem(frf, omega, dt, n_samples, residual_terms, nyquist=nyquist)
    # An exponential window multiplies exp(lam t) by exp(-decay t): data poles are lam - decay.
    mu0 = np.asarray(lam0, dtype=np.complex128) - decay
    min_width = 2.0 * (omega[1] - omega[0]) if omega.size > 1 else 0.0
    free = np.ones(n_mode, bool)
    fit = None
    def check(mu):
        return _mode_codes(mu + decay, lam0, max_shift, min_width)

    start_mu = mu0.copy()
    start_cost = None
    n_iter = 0
    while True:
        fit = _varpro.levenberg_marquardt(prob, start_mu, max_iter=max(max_iter - n_iter, 1),
                                          tol=tol, free=free, check=check)
        n_iter += fit.n_iter
        start_cost = fit.start_cost if start_cost is None else start_cost
        if not np.isfinite(fit.cost) or fit.cost > start_cost:
            # nothing to fit, or worse than AMI's eigenvalues: fall back to them
            free[:] = False
            fit = _varpro.levenberg_marquardt(prob, mu0, max_iter=0, free=free)
            break
        if fit.bad is None:  # the optimum must lie inside every free mode's region too
            final = np.where(free, _mode_codes(fit.lam + decay, lam0, max_shift, min_width), 0)
            if not final.any():
                break
            fit.bad = final > 0
        # freeze the offending modes at their AMI values, go on from where the others are
        free &= ~fit.bad
        start_mu = np.where(free, fit.lam, mu0)
    status = np.full(n_mode, _STATUS_OK, dtype=np.int8)
    if not fit.converged:
        # flag the modes still moving (a mode wandering in noise must not flag the others)
        moving = fit.mode_step > 1e-6 if fit.mode_step is not None else np.ones(n_mode, bool)
        status[moving if moving[free].any() else np.ones(n_mode, bool)] = _STATUS_NOT_CONVERGED
    status[~free] = _STATUS_FALLBACK
    proj = fit.proj
    lam = fit.lam + decay
    n_coef = 2 * n_mode + 2 * len(residual_terms)
    if proj.ok:
        dof = max(prob.n_rows - n_coef - 2.0 * free.sum() / max(n_point, 1), 1.0)
        noise_var = np.maximum(proj.rss, 1e-300) / dof
        cov = _varpro.covariance(prob, proj, noise_var, drive_index,
                                 quantity_power=quantity_power, lam_shift=decay)
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
    var_re = np.diag(cov_theta)[0::2]
    var_im = np.diag(cov_theta)[1::2]
    eig_std = np.sqrt(np.maximum(var_re, 0.0)) + 1j * np.sqrt(np.maximum(var_im, 0.0))
    wn = np.abs(lam)
    fn_std = np.empty(n_mode)
    zeta_std = np.empty(n_mode)
    for k in range(n_mode):
        c = cov_theta[2 * k : 2 * k + 2, 2 * k : 2 * k + 2]
        g_wn = np.array([lam[k].real, lam[k].imag]) / wn[k]
        g_z = np.array([-lam[k].imag ** 2, lam[k].real * lam[k].imag]) / wn[k] ** 3
        fn_std[k] = np.sqrt(max(g_wn @ c @ g_wn, 0.0)) / (2.0 * np.pi)
        zeta_std[k] = np.sqrt(max(g_z @ c @ g_z, 0.0))
    if "mode_vector" in cov:
        mode_vector = cov["mode_vector"]
        mv_std = np.sqrt(np.maximum(cov["mode_vector_var"], 0.0))
    else:
        mode_vector = _mode_vectors(residue, lam, drive_index, quantity_power)
        mv_std = np.full((n_point, n_mode), np.nan)
    lower = np.full(n_point, np.nan + 0j)
    upper = np.full(n_point, np.nan + 0j)
    for r, term in enumerate(residual_terms):
        value = coef[:, 2 * n_mode + 2 * r] + 1j * coef[:, 2 * n_mode + 2 * r + 1]
        if term == "lower":
            lower = value
        else:
            upper = value
    # per-line complex noise std (E|e|^2 = 2 s^2 for the two real components)
    noise_std = np.sqrt(2.0 * noise_var)
    # Output mode c is the refined mode matched to AMI mode c (close modes may swap in the fit).
    if np.all(np.isfinite(lam)):
        width = np.maximum(2.0 * np.abs(lam0.real), min_width)
        order = np.argsort(_match(lam, lam0, width))
        lam, eig_std, fn_std, zeta_std, status = (
            a[order] for a in (lam, eig_std, fn_std, zeta_std, status))
        residue, res_std, mode_vector, mv_std = (
            a[:, order] for a in (residue, res_std, mode_vector, mv_std))
    return (
        lam, eig_std, fn_std, zeta_std, residue, res_std, mode_vector, mv_std, noise_std,
        lower, upper, status, np.int64(n_iter), np.float64(start_cost),
        np.float64(fit.cost),
    )


def _mode_vectors(residue, lam, drive_index, quantity_power):
    """Eq. 8 from (displacement) residues; unscaled ``A / lam`` when there is no drive point."""
    a_disp = residue / lam[None, :] ** quantity_power
    if drive_index is None:
        return a_disp / lam[None, :]
    phi_p = np.sqrt(a_disp[drive_index] / lam)
    phi = a_disp / (lam[None, :] * phi_p[None, :])
    phi[drive_index] = phi_p
    return phi


# ------------------------------------------------------------------------------------------
# labeled layer
# ------------------------------------------------------------------------------------------
def _check_inputs(ds, max_iter, tol, band, residual_terms, max_shift):
    problems = []
    if not isinstance(ds, xr.Dataset):
        raise IdentificationError(f"ds: expected an xarray.Dataset from global_fit, got {type(ds)}")
    if names.FRF not in ds:
        problems.append(f"variable {names.FRF!r} is missing (expected dims (point, frequency))")
    elif set(ds[names.FRF].dims) != {names.POINT, names.FREQUENCY}:
        problems.append(f"variable {names.FRF!r}: expected dims (point, frequency), "
                        f"got {ds[names.FRF].dims}")
    if names.EIGENVALUE not in ds:
        problems.append(f"variable {names.EIGENVALUE!r} is missing: run global_fit first")
    elif ds[names.EIGENVALUE].dims != (names.MODE,):
        problems.append(f"variable {names.EIGENVALUE!r}: expected dims (mode,), "
                        f"got {ds[names.EIGENVALUE].dims}")
    elif not np.all(np.isfinite(ds[names.EIGENVALUE].values)):
        problems.append(f"variable {names.EIGENVALUE!r}: contains NaN or inf")
    if names.RESIDUE in ds and set(ds[names.RESIDUE].dims) != {names.POINT, names.MODE}:
        problems.append(f"variable {names.RESIDUE!r}: expected dims (point, mode), "
                        f"got {ds[names.RESIDUE].dims}")
    if problems:
        raise IdentificationError("refine: " + "; ".join(problems))
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise IdentificationError(f"max_iter: expected a positive integer, got {max_iter!r}")
    if not (isinstance(tol, (int, float, np.floating)) and 0 < tol < 1):
        raise IdentificationError(f"tol: expected a number in (0, 1), got {tol!r}")
    if not (isinstance(max_shift, (int, float, np.floating)) and max_shift > 0):
        raise IdentificationError(f"max_shift: expected a positive number, got {max_shift!r}")
    if not (isinstance(band, str) and band == "all"):
        ok = (isinstance(band, Sequence) and not isinstance(band, str) and len(band) == 2)
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
        exact = source in (names.SOURCE_IMPULSE, names.SOURCE_ANALYTIC)
        terms = () if exact else ("lower", "upper")
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
        step (or when the objective can no longer decrease at rounding level).
    band : "all" or (f_min, f_max)
        Frequencies (Hz, inclusive) used by the fit; default the whole band.
    residual_terms : "auto" or subset of ("lower", "upper")
        Extra terms per FRF for modes outside the band: ``-R_L / w^2`` and a constant ``R_U``
        (complex). ``"auto"``: none for impulse-response and analytic FRFs (the modal model is
        exact there), both otherwise. Lines at 0 Hz are left out when ``"lower"`` is used.
    max_shift : float
        A mode that moves farther than this many half-power bandwidths ``2 |Re lam|`` from its
        AMI eigenvalue is frozen at the AMI value (flag ``refine_fallback``).
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
        line; ``residual_lower`` / ``residual_upper`` (point) when used; ``quality_flags`` with
        ``refine_not_converged`` / ``refine_fallback`` added where they apply; attributes
        ``refine_iterations``, ``refine_converged``, ``refine_cost_start``, ``refine_cost``
        (the objective ``sum_j (n/2) log |r_j|^2``), ``refine_model``.

    Raises
    ------
    IdentificationError
        Missing ``frf`` or ``eigenvalue``, bad parameters, or too few lines in ``band``.
    """
    _check_inputs(ds, max_iter, tol, band, residual_terms, max_shift)
    dt, n_samples, terms = _model_choice(ds, residual_terms)
    frf = ds[names.FRF].transpose(names.POINT, names.FREQUENCY)
    if band != "all":
        frf = frf.sel({names.FREQUENCY: slice(float(band[0]), float(band[1]))})
    if "lower" in terms:
        frf = frf.where(frf[names.FREQUENCY] > 0, drop=True)
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
    points = list(frf[names.POINT].values)
    drive_index = points.index(drive) if drive in points else None
    quantity = ds.attrs.get(names.ATTR_QUANTITY, "displacement")
    power = _QUANTITY_POWER.get(quantity, 0)
    decay = float(ds.attrs.get(names.ATTR_EXP_DECAY, 0.0) or 0.0)
    freq = frf[names.FREQUENCY].astype(np.float64)
    kwargs = dict(dt=dt, n_samples=n_samples, residual_terms=terms, drive_index=drive_index,
                  quantity_power=power, decay=decay, max_iter=int(max_iter), tol=float(tol),
                  max_shift=float(max_shift))
    P, F, M = names.POINT, names.FREQUENCY, names.MODE
    if n_mode == 0:
        outs = None
    else:
        outs = xr.apply_ufunc(
            _refine_arrays,
            frf,
            freq,
            lam0.astype(np.complex128),
            res0.astype(np.complex128),
            kwargs=kwargs,
            input_core_dims=[[P, F], [F], [M], [P, M]],
            output_core_dims=[[M], [M], [M], [M], [P, M], [P, M], [P, M], [P, M], [P], [P], [P],
                              [M], [], [], []],
            dask="parallelized",
            output_dtypes=[np.complex128, np.complex128, float, float, np.complex128, float,
                           np.complex128, float, float, np.complex128, np.complex128, np.int8,
                           np.int64, float, float],
            dask_gufunc_kwargs={"allow_rechunk": True},
            keep_attrs=False,
        )
        outs = [o.compute() if o.chunks else o for o in outs]
    new = {}
    for var in (names.EIGENVALUE, names.NATURAL_FREQUENCY, names.DAMPING_RATIO, names.RESIDUE,
                names.MODE_VECTOR):
        if var in ds:
            new[names.AMI_PREFIX + var] = ds[var]
    attrs = {}
    if outs is not None:
        (lam, eig_std, fn_std, zeta_std, residue, res_std, phi, phi_std, noise_std, lower, upper,
         status, n_iter, cost0, cost) = outs
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
            {names.ATTR_UNITS: units_frf} if units_frf else {})
        if "lower" in terms:
            new[names.RESIDUAL_LOWER] = lower
        if "upper" in terms:
            new[names.RESIDUAL_UPPER] = upper
        new[QUALITY_FLAGS] = _merge_flags(ds, status.values, lam0)
        attrs["refine_iterations"] = int(n_iter)
        attrs["refine_converged"] = int(bool(np.all(status.values != _STATUS_NOT_CONVERGED)))
        attrs["refine_cost_start"] = float(cost0)
        attrs["refine_cost"] = float(cost)
    # one assignment: the results share the input's point and mode coordinates
    out = ds.assign({k: v.variable if isinstance(v, xr.DataArray) else v for k, v in new.items()})
    out.attrs = {**ds.attrs, **attrs}
    out.attrs["refine_model"] = "discrete" if dt else "continuous"
    out.attrs["refine_residual_terms"] = ",".join(terms)
    params = {"max_iter": max_iter, "tol": tol, "band": band, "residual_terms": terms,
              "max_shift": max_shift}
    out = add_history(out, "ami_xr.refine", params)
    if path is not None:
        from ami_xr.io import to_netcdf

        to_netcdf(out, path)
    return out


def _merge_flags(ds, status, lam0):
    """AMI's flags per mode with the refinement's flags appended."""
    n_mode = status.shape[0]
    if QUALITY_FLAGS in ds and ds[QUALITY_FLAGS].dims == (names.MODE,):
        old = [str(v) for v in ds[QUALITY_FLAGS].values]
    else:
        old = [""] * n_mode
    new = []
    for k in range(n_mode):
        flags = [f for f in old[k].split(_FLAG_SEPARATOR) if f]
        if status[k] == _STATUS_NOT_CONVERGED:
            flags.append(names.FLAG_REFINE_NOT_CONVERGED)
        elif status[k] == _STATUS_FALLBACK:
            flags.append(names.FLAG_REFINE_FALLBACK)
        new.append(_FLAG_SEPARATOR.join(flags))
    return xr.DataArray(np.array(new, dtype=str), dims=(names.MODE,),
                        coords={names.MODE: lam0[names.MODE].values})
