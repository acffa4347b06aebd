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
Two modes closer than the larger of their half-power bandwidths (a split duplicate from the
isolation, or a second pole the addition put next to a mode) go through one more order test
(with ``drop_modes``): the weaker pole is removed and the rest refitted; the pair stays only when,
against noise plus a model error proportional to the response (both estimated from the residual,
see :func:`ami_xr.core.refine._merge_split_pairs`), the single pole leaves a significant excess,
the second pole removes a significant part of it, and it does so at two points or more. Merged
duplicates are listed in the attribute ``refine_merged_modes`` ("F_dropped Hz into F_kept Hz"),
the modes of supported pairs in ``refine_close_pairs_supported``.
The global-fit outputs that depend on the residues
(``frf_synthesized``, ``frf_residual``, ``mac``, ``drive_point_snr`` and its
``low_drive_point_snr`` flag) are recomputed from the refined model.

Standard errors (``eigenvalue_std``, ``natural_frequency_std``, ``damping_ratio_std``,
``residue_std``, ``mode_vector_std``) come from the Gauss-Newton covariance at the optimum with the
estimated noise levels; for an efficient estimator they are the spread over repeated noise.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import chunked as ch
from ami_xr.ami import common as c
from ami_xr.ami.global_fit import RESIDUAL_KIND, receptance_mode_vectors, residue_units
from ami_xr.ami.line_noise import line_noise_shape
from ami_xr.ami.settings import (
    FrfAttributes,
    GlobalFitSettings,
    RefineSettings,
    from_attrs,
    parameters,
    to_attrs,
)
from ami_xr.ami.subtract import add_capped
from ami_xr.core import flags, rows
from ami_xr.core.modal import damping_ratio, mac_matrix, natural_frequency
from ami_xr.core.model import resolve_model, resolve_residual_terms
from ami_xr.core.refine import (
    STATUS_FALLBACK,
    STATUS_NOT_CONVERGED,
    STATUS_OK,
    RefineModel,
    RefineResult,
    contribution_peaks,
    refine_arrays,
    synthesize,
)
from ami_xr.core.threads import single_blas_thread
from ami_xr.errors import ConvergenceWarning, IdentificationError
from ami_xr.progress import Iterations, active, detail
from ami_xr.provenance import record_history

_LOWER_UPPER = list(names.RESIDUAL_TERM_LABELS)  # coordinate of the residual_term dim
P, F, M = names.POINT, names.FREQUENCY, names.MODE
# Outputs of refine_arrays: RefineResult field -> (dims, dtype). The block's tuple and the labels
# of its results both follow this table, so no output is matched by position.
_OUTPUTS = {
    "lam": ([M], np.complex128),
    "eig_std": ([M], np.complex128),
    "fn_std": ([M], float),
    "zeta_std": ([M], float),
    "residue": ([P, M], np.complex128),
    "residue_std": ([P, M], float),
    "mode_vector": ([P, M], np.complex128),
    "mode_vector_std": ([P, M], float),
    "noise_std": ([P], float),
    "residual_coefficient": ([P, names.RESIDUAL_TERM], np.complex128),
    "status": ([M], np.int8),
    "origin": ([M], np.int64),
    "n_iter": ([], np.int64),
    "n_full_fits": ([], np.int64),
    "cost_start": ([], float),
    "cost": ([], float),
    "pair_supported": ([M], bool),
    "merged_fn": ([M], float),
    "capped": ([], bool),
}


def _refine_block(frf, freq, lam0, res0, *, settings, model, trace) -> tuple[np.ndarray, ...]:
    """:func:`refine_arrays` with its result as a tuple in the order of ``_OUTPUTS``."""
    with single_blas_thread():  # also where a dask worker runs the block
        result = refine_arrays(frf, freq, lam0, res0, settings, model, trace)
    if trace is not None:
        detail(f"standard errors, {result.lam.size} modes, {int(result.n_iter)} iterations")
    return tuple(getattr(result, name) for name in _OUTPUTS)


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
        bad = [t for t in terms if t not in names.RESIDUAL_TERM_LABELS]
        if bad or len(set(terms)) != len(terms):
            raise IdentificationError(
                "residual_terms: expected 'auto' or a subset of ('lower', 'upper'), "
                f"got {residual_terms!r}"
            )


def _start_values(ds: xr.Dataset, band, n_terms: int):
    """The FRFs in ``band`` and the starting eigenvalues and residues, in memory (the
    eigenvalues are shared by all points: this step gathers, so dask data are loaded); raises
    when the band has too few lines for the modes."""
    frf = ds[names.FRF].transpose(P, F)
    if band != "all":
        frf = frf.sel({F: slice(float(band[0]), float(band[1]))})
    frf = ch.loaded(frf, "refine")  # the joint fit holds every FRF
    lam0 = ds[names.EIGENVALUE]
    lam0 = lam0.compute() if lam0.chunks else lam0
    n_mode = lam0.sizes[M]
    n_line = frf.sizes[F]
    n_coef = 2 * n_mode + 2 * n_terms
    if 2 * n_line <= n_coef + 2 * n_mode:
        raise IdentificationError(
            f"band: {n_line} frequency lines, but refining {n_mode} modes needs more than "
            f"{(n_coef + 2 * n_mode) // 2 + 1}"
        )
    if names.RESIDUE in ds:
        res0 = ds[names.RESIDUE].transpose(P, M)
        res0 = res0.compute() if res0.chunks else res0
    else:
        res0 = xr.zeros_like(frf.isel({F: 0}, drop=True)) * xr.zeros_like(lam0, dtype=np.complex128)
        res0 = res0.transpose(P, M)
    return frf, lam0, res0


def _refined(ds: xr.Dataset, start, settings: RefineSettings, model, data_model) -> xr.Dataset:
    """``ds`` with the refined values of one block over the start values ``start``
    (FRFs, eigenvalues, residues); a capped mode completion is recorded and warned about."""
    frf, lam0, res0 = start
    trace = Iterations() if active() else None  # counts on a progress bar, when one listens
    # the start values are in memory (_start_values gathers them): the block on their arrays,
    # its results labeled by the dims in _OUTPUTS (no apply_ufunc and no copy of ds for it)
    arrays = _refine_block(
        frf.transpose(P, F).values,
        np.asarray(frf[F].values, dtype=np.float64),
        np.asarray(lam0.values, dtype=np.complex128),
        np.asarray(res0.transpose(P, M).values, dtype=np.complex128),
        settings=settings,
        model=model,
        trace=trace,
    )
    fields = {  # Variables: a DataArray each would build a Dataset for its coordinates
        k: xr.Variable(dims, a) for (k, (dims, _)), a in zip(_OUTPUTS.items(), arrays, strict=True)
    }
    out = _with_results(ds, fields, model, data_model)
    if bool(fields["capped"]):
        add_capped(out.attrs, ["refine:add_modes"])
        warnings.warn(
            f"refine: stopped adding modes at the cap add_modes={settings.add_modes} while "
            "the residual still showed structure; raise add_modes to go on",
            ConvergenceWarning,
            stacklevel=3,
        )
    return out


def refine(
    ds: xr.Dataset,
    *,
    max_iter: int = RefineSettings.max_iter,
    tol: float = RefineSettings.tol,
    band: str | tuple[float, float] = RefineSettings.band,
    residual_terms: str | Sequence[str] = RefineSettings.residual_terms,
    max_shift: float = RefineSettings.max_shift,
    add_modes: int = RefineSettings.add_modes,
    add_pfa: float = RefineSettings.add_pfa,
    drop_modes: bool = RefineSettings.drop_modes,
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
        Safety cap on the completion steps (0: none). Each step tries one extra pole at the
        peaks of the noise-normalised residual power and local multi-pole refits of the
        clusters where the residual shows structure (:mod:`ami_xr.core.order`), and keeps the
        trial whose likelihood-ratio gain less the chi-square quantile (``2 + 2 P`` degrees
        of freedom at ``add_pfa / L``) per added mode is largest and positive; steps stop when
        none gains (noise-free data: when the fit is exact). Reaching the cap is reported
        (``ami_capped``: ``refine:add_modes``, ConvergenceWarning). Added modes come last,
        flagged ``added_by_refine``, with NaN AMI values.
    add_pfa : float
        False-alarm probability of that test, in (0, 1).
    drop_modes : bool
        Drop AMI modes that fail the same test (removing the mode and refitting the others
        lowers the likelihood by less than that level: a spurious mode fitting noise). Their
        labels go to the attribute ``refine_removed_modes``; at least one mode stays.

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
    coord_attrs = c.coordinate_attrs(ds)
    if isinstance(add_modes, bool) or not isinstance(add_modes, (int, np.integer)) or add_modes < 0:
        raise IdentificationError(f"add_modes: expected an integer >= 0, got {add_modes!r}")
    if not (isinstance(add_pfa, (int, float, np.floating)) and 0 < add_pfa < 1):
        raise IdentificationError(f"add_pfa: expected a number in (0, 1), got {add_pfa!r}")
    data_model = resolve_model(ds.attrs, "exact")
    terms = resolve_residual_terms(residual_terms, ds.attrs, names.RESIDUAL_COEFFICIENT in ds)
    settings = RefineSettings(
        max_iter=int(max_iter),
        tol=float(tol),
        band=band,
        residual_terms=terms,
        max_shift=float(max_shift),
        add_modes=int(add_modes),
        add_pfa=float(add_pfa),
        drop_modes=bool(drop_modes),
    )
    frf, lam0, res0 = _start_values(ds, band, len(terms))
    n_mode = lam0.sizes[M]
    data = from_attrs(FrfAttributes, ds.attrs)
    # identify() corrects the eigenvalues for an exponential window after refine; if they were
    # corrected already (attr set), the data's poles are lam - beta.
    model = RefineModel(
        dt=data_model.dt,
        n_samples=data_model.n_samples,
        residual_terms=terms,
        residual_kind=RESIDUAL_KIND.get(data.frf_type, 0),
        drive_index=c.drive_index(ds),
        decay=float(data.exponential_window_corrected),
    )
    shape, group = line_noise_shape(ds, frf)
    model = model._replace(line_noise=shape, line_group=group)
    if n_mode == 0:
        out = ds.assign_coords({names.RESIDUAL_TERM: _LOWER_UPPER}) if terms else ds.copy()
    else:
        out = _refined(ds, (frf, lam0, res0), settings, model, data_model)
    out.attrs[names.ATTR_REFINE_MODEL] = data_model.name
    if ch.is_lazy(ds[names.FRF]):  # _start_values loaded it
        ch.note_loaded(out.attrs, "refine")
    to_attrs(settings, out.attrs)
    out = c.restore_coordinate_attrs(out, coord_attrs)
    record_history(out.attrs, "ami_xr.refine", parameters(settings))  # out is refine's own
    return out


def _with_results(ds, fields, model: RefineModel, data_model) -> xr.Dataset:
    """``ds`` with the refined values of :class:`RefineResult` ``fields`` (Variables by field
    name): AMI's values kept with the ``ami_`` prefix, modes dropped or added, the global-fit
    outputs recomputed, flags and attributes updated; built once, from ``ds``'s Variables
    (modes selected, added and relabelled on them)."""
    n_mode = ds.sizes[M]
    terms, drive_index = model.residual_terms, model.drive_index
    r = RefineResult(**fields)
    lam = r.lam
    origin = r.origin.values
    added = origin < 0
    kept = origin[~added]
    attrs = {}
    variables = dict(ds.variables)
    if kept.size < n_mode:  # insignificant AMI modes dropped
        removed = [ds[M].values[k].item() for k in range(n_mode) if k not in kept]
        attrs[names.ATTR_REFINE_REMOVED_MODES] = ",".join(str(x) for x in removed)
        variables = _modes_at(variables, kept)
    if added.any():
        variables = _with_added_modes(variables, set(ds.coords), int(added.sum()))
    new = {}
    for var in (
        names.EIGENVALUE,
        names.NATURAL_FREQUENCY,
        names.DAMPING_RATIO,
        names.RESIDUE,
        names.MODE_VECTOR,
    ):
        if var in variables:
            new[names.AMI_PREFIX + var] = variables[var]
    units_frf = ds[names.FRF].attrs.get(names.ATTR_UNITS)
    hz = {names.ATTR_UNITS: names.FREQUENCY_UNITS}
    new[names.EIGENVALUE] = _var(lam, {names.ATTR_UNITS: names.ANGULAR_UNITS})
    # on the arrays: the modal helpers on a DataArray go through temporary Datasets
    new[names.NATURAL_FREQUENCY] = xr.Variable((M,), natural_frequency(lam.values), hz)
    new[names.DAMPING_RATIO] = xr.Variable(
        (M,), damping_ratio(lam.values), {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}
    )
    res_units = residue_units(units_frf or "")
    new[names.RESIDUE] = _var(r.residue.transpose(P, M), res_units)
    # one mode-vector convention (displacement) whatever the FRF type: global_fit's helper
    phi, phi_attrs = receptance_mode_vectors(
        r.residue.transpose(P, M).values, lam.values, drive_index, ds.attrs, units_frf or ""
    )
    new[names.MODE_VECTOR] = xr.Variable((P, M), phi, phi_attrs)
    phi_units = {k: v for k, v in phi_attrs.items() if k == names.ATTR_UNITS}
    new[names.EIGENVALUE_STD] = _var(r.eig_std, {names.ATTR_UNITS: names.ANGULAR_UNITS})
    new[names.NATURAL_FREQUENCY_STD] = _var(r.fn_std, hz)
    new[names.DAMPING_RATIO_STD] = _var(r.zeta_std, {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS})
    new[names.RESIDUE_STD] = _var(r.residue_std.transpose(P, M), res_units)
    # the convention scales each mode by one complex factor; the std follows its magnitude
    old = np.linalg.norm(r.mode_vector.transpose(P, M).values, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(old > 0, np.linalg.norm(phi, axis=0) / old, 1.0)
    phi_std = r.mode_vector_std.transpose(P, M) * ratio[None, :]
    new[names.MODE_VECTOR_STD] = _var(phi_std, phi_units)
    new[names.FRF_NOISE_STD] = _var(r.noise_std, {names.ATTR_UNITS: units_frf} if units_frf else {})
    if terms:
        new[names.RESIDUAL_COEFFICIENT] = r.residual_coefficient  # labels: assign_coords below
    low_snr = _refresh_global_outputs(ds, new, r, lam.values - model.decay, model, data_model)
    before = variables.get(names.QUALITY_FLAGS)
    if before is not None and before.dims == (M,):
        before = flags.decode(before.values)
    else:
        before = np.zeros(lam.size, np.int32)
    mask = _merge_flags(before, r.status.values, low_snr, added)
    new[names.QUALITY_FLAGS] = xr.Variable((M,), mask)
    attrs[names.ATTR_REFINE_ITERATIONS] = int(r.n_iter)
    attrs[names.ATTR_REFINE_FULL_FITS] = int(r.n_full_fits)
    attrs[names.ATTR_REFINE_CONVERGED] = int(bool(np.all(r.status.values != STATUS_NOT_CONVERGED)))
    attrs[names.ATTR_REFINE_COST_START] = float(r.cost_start)
    attrs[names.ATTR_REFINE_COST] = float(r.cost)
    attrs.update(_pair_attrs(natural_frequency(lam.values), r.pair_supported.values, r.merged_fn))
    # one build: the results share the input's point and mode coordinates
    coords = set(ds.coords)
    if terms:
        variables[names.RESIDUAL_TERM] = xr.Variable((names.RESIDUAL_TERM,), _LOWER_UPPER)
        coords.add(names.RESIDUAL_TERM)
    variables.update(new)
    if added.any():
        variables = _relabel_added(variables, kept.size)
    return c.built(variables, coords, {**ds.attrs, **attrs}, like=ds)


def _var(v: xr.Variable, attrs: dict) -> xr.Variable:
    """The refined values ``v`` with the attributes ``attrs`` (a new Variable)."""
    return xr.Variable(v.dims, v.data, dict(attrs))


def _pair_attrs(fn: np.ndarray, supported: np.ndarray, merged_fn: xr.Variable) -> dict:
    """Attributes of the close-pair order test, by natural frequency (labels change later):
    ``refine_merged_modes`` (each split duplicate and the mode it was merged into) and
    ``refine_close_pairs_supported`` (modes of close pairs the data support)."""
    out = {}
    merged = np.asarray(merged_fn.values, float)
    done = [f"{m:.4f} Hz into {f:.4f} Hz" for f, m in zip(fn, merged, strict=True) if m == m]
    if done:
        out[names.ATTR_REFINE_MERGED_MODES] = ", ".join(done)
    kept = [f"{f:.4f} Hz" for f, ok in zip(fn, supported, strict=True) if ok]
    if kept:
        out[names.ATTR_REFINE_CLOSE_PAIRS_SUPPORTED] = ", ".join(kept)
    return out


def _relabel_added(variables: dict, n_old: int) -> dict:
    """Added modes take their place in frequency order; AMI's labels 1..K become 1..K'
    (``variables`` by name, the ``mode`` labels among them; a new dict)."""
    labels = np.asarray(variables[M].values)
    perm = np.argsort(variables[names.NATURAL_FREQUENCY].values, kind="stable")
    out = _modes_at(variables, perm)
    old = labels[:n_old]
    if np.issubdtype(old.dtype, np.integer) and np.array_equal(old, np.arange(1, old.size + 1)):
        new_labels = np.arange(1, labels.size + 1)
        for d in (M, names.MODE_2):
            if d in out:
                out[d] = xr.Variable((d,), new_labels, out[d].attrs)
    return out


def _refresh_global_outputs(ds, new, r: RefineResult, mu, model: RefineModel, data_model):
    """Recompute what global_fit derived from the residues: the synthesised FRFs and their
    residual (whole band), the MAC matrix and the drive-point SNR. Returns the new
    ``low_drive_point_snr`` decision per mode (None when there is no drive point), with the
    threshold global_fit used (attribute ``ami_drive_snr_min``)."""
    residue = r.residue.transpose(P, M).values
    phi = r.mode_vector.transpose(P, M).values
    drive_index = model.drive_index
    omega = 2 * np.pi * ds[F].values.astype(float)
    frf = ds[names.FRF].transpose(P, F)
    lazy = ch.is_lazy(frf)  # the model FRFs then made per chunk of points, lazily
    rc = r.residual_coefficient.transpose(P, names.RESIDUAL_TERM)
    model_kw = dict(
        residual_terms=model.residual_terms,
        residual_kind=model.residual_kind,
        dt=data_model.dt,
        n_samples=data_model.n_samples,
    )
    some = slice(0, 0) if lazy else slice(None)
    synth, cols = synthesize(omega, mu, residue[some], rc.values[some], **model_kw)
    n_mode = mu.size
    units = frf.attrs.get(names.ATTR_UNITS, "")
    if names.FRF_SYNTHESIZED in ds or names.FRF_RESIDUAL in ds:
        if lazy:
            small = [xr.DataArray(r.residue.transpose(P, M)), xr.DataArray(rc)]
            args = (small, [M, names.RESIDUAL_TERM], frf, F)
            made = ch.made_from_rows(rows.refined_rows, *args, omega=omega, mu=mu, **model_kw)
            synth = made.data
        new[names.FRF_SYNTHESIZED] = xr.Variable((P, F), synth, {names.ATTR_UNITS: units})
        new[names.FRF_RESIDUAL] = xr.Variable((P, F), frf.data - synth, {names.ATTR_UNITS: units})
    if names.MAC in ds and names.MODE_2 in ds.dims:
        new[names.MAC] = xr.Variable(
            (M, names.MODE_2), mac_matrix(phi), {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}
        )
    if drive_index is None:
        return None
    peak = contribution_peaks(cols, residue[drive_index])
    if names.SUB_NOISE_FLOOR in ds:
        sigma = float(ds[names.SUB_NOISE_FLOOR].transpose(P).values[drive_index])
    else:
        sigma = float(r.noise_std.values[drive_index])
    snr = peak / sigma if sigma > 0 else np.full(n_mode, np.inf)
    new[names.DRIVE_POINT_SNR] = xr.Variable(
        (M,), snr, {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}
    )
    return ~(snr >= from_attrs(GlobalFitSettings, ds.attrs).drive_snr_min)


def _modes_at(variables: dict, index) -> dict:
    """``variables`` (by name) at the modes of positions ``index`` on ``mode`` and ``mode_2``
    (a new dict)."""
    out = {}
    for k, v in variables.items():
        at = {d: index for d in (M, names.MODE_2) if d in v.dims}
        out[k] = v.isel(at) if at else v
    return out


def _with_added_modes(variables: dict, coords: set, n_added: int) -> dict:
    """``variables`` (by name; ``coords``: the coordinates' names) extended along ``mode`` by
    ``n_added`` modes (AMI values missing: NaN, False, ""); the ``mode_2`` outputs become NaN
    placeholders, recomputed by :func:`_refresh_global_outputs`. A new dict."""
    labels = variables[M].values
    if np.issubdtype(labels.dtype, np.integer):
        extra = np.arange(labels.max() + 1, labels.max() + 1 + n_added)
    else:
        extra = np.array([f"added_{i + 1}" for i in range(n_added)])
    new_labels = np.concatenate([labels, extra])
    square = [k for k, v in variables.items() if names.MODE_2 in v.dims and k not in coords]
    out = {}
    for name, var in variables.items():
        if name in square or name == names.MODE_2:
            continue
        if name == M:
            out[name] = xr.Variable((M,), new_labels, var.attrs)
        elif M in var.dims:
            out[name] = var.pad({M: (0, n_added)}, constant_values=_fill(name, var, coords))
        else:
            out[name] = var
    if square:
        out[names.MODE_2] = xr.Variable((names.MODE_2,), new_labels)
        for v in square:  # placeholders, recomputed by _refresh_global_outputs
            out[v] = xr.Variable((M, names.MODE_2), np.full((new_labels.size,) * 2, np.nan))
    return out


def _fill(name, var: xr.Variable, coords: set):
    """What an added mode holds in ``var`` (AMI's value missing): False, "", no flag, -1 for
    other integers, NaN otherwise (and for every coordinate)."""
    if name in coords:
        return None
    if var.dtype == bool:
        return False
    if var.dtype.kind in "US":
        return ""
    if name == names.QUALITY_FLAGS:
        return 0  # an added mode has no flag yet (its own are set below)
    if var.dtype.kind in "iu":
        return -1
    return None


def _merge_flags(mask, status, low_snr=None, added=None) -> np.ndarray:
    """The flags (int32) of each mode after the refinement, from its flags ``mask`` before and
    its status (set in :mod:`ami_xr.core.refine`, where it is known): ``refine_not_converged``
    and ``refine_fallback`` as the status says; the isolation's ``not_converged`` no longer
    applies to a mode the refinement moved to its converged estimate (status ok);
    ``added_by_refine``; ``low_drive_point_snr`` decided again from the refined residues."""
    ok = status == STATUS_OK
    mask = flags.set_where(mask, names.FLAG_REFINE_NOT_CONVERGED, status == STATUS_NOT_CONVERGED)
    mask = flags.set_where(mask, names.FLAG_REFINE_FALLBACK, status == STATUS_FALLBACK)
    mask = flags.set_where(
        mask, names.FLAG_NOT_CONVERGED, ~ok & flags.has(mask, names.FLAG_NOT_CONVERGED)
    )
    if added is not None:
        mask = flags.set_where(mask, names.FLAG_ADDED_BY_REFINE, added)
    if low_snr is not None:
        mask = flags.set_where(mask, names.FLAG_LOW_DRIVE_SNR, low_snr)
    return np.asarray(mask, np.int32)
