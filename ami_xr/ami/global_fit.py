"""Global Mode Vector Phase: residues of all FRFs by linear least squares (eq. 9), eq. 8."""

from __future__ import annotations

import warnings

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import chunked as ch
from ami_xr.ami import common as c

# the mode-vector convention lives with the derived outputs; named here as before
from ami_xr.ami.derive import ATTR_MODE_VECTOR_CONVENTION as ATTR_MODE_VECTOR_CONVENTION
from ami_xr.ami.derive import MODE_VECTOR_CONVENTION as MODE_VECTOR_CONVENTION
from ami_xr.ami.derive import ResidueFit, derive
from ami_xr.ami.derive import mode_vector_units as mode_vector_units
from ami_xr.ami.derive import receptance_mode_vectors as receptance_mode_vectors
from ami_xr.ami.derive import receptance_residues as receptance_residues
from ami_xr.ami.derive import residue_units as residue_units
from ami_xr.ami.settings import (
    FrfAttributes,
    GlobalFitSettings,
    from_attrs,
    parameters,
    to_attrs,
)
from ami_xr.core import flags, rows
from ami_xr.core.model import resolve_model
from ami_xr.errors import AssumptionWarning, IdentificationError
from ami_xr.kernels import noise as kn

RESIDUAL_KIND = {"receptance": 0, "mobility": 1, "accelerance": 2}


def band_mask(omega: np.ndarray, lam: np.ndarray, band) -> np.ndarray:
    if isinstance(band, str):
        if band != "all":
            raise IdentificationError(f"band: expected a positive number or 'all', got {band!r}")
        return np.ones(omega.size, bool)
    h = c.check_positive(band, "band")
    use = np.zeros(omega.size, bool)
    for lk in lam:
        use |= np.abs(omega - lk.imag) <= h * 2.0 * abs(lk.real)
    return use


def _widened_band(omega, lam, band, use, n_unknown, kind):
    """The smallest ``band * 2**k`` (k <= 20) whose lines suffice for the fit, and its mask."""
    for k in range(1, 21):
        wider = band * 2.0**k
        use = band_mask(omega, lam, wider)
        if kind in (0, 1):
            use &= omega > 0
        if 2 * int(use.sum()) >= n_unknown + 1:
            return wider, use
    return band, use


def _fit_block(g, use, omega, lam, dt, n_samples, residual_kind):
    """Residues, synthesized FRFs and residual coefficients (zeros without residual terms) of
    the FRFs ``g`` (..., F): :func:`ami_xr.core.rows.fit_rows` and ``synthesize_rows``."""
    shape = g.shape[:-1]
    kw = dict(omega=omega, lam=lam, dt=dt, n_samples=n_samples, kind=residual_kind)
    coef = rows.fit_rows(g, use=use, **kw).reshape(-1, rows.n_coefficients(lam.size, residual_kind))
    synth = rows.synthesize_rows(coef, **kw)
    n_k = lam.size
    res = np.ascontiguousarray(coef[:, :n_k])
    rc = coef[:, n_k:] if residual_kind >= 0 else np.zeros((coef.shape[0], 2), np.complex128)
    return (
        res.reshape(shape + (n_k,)),
        synth.reshape(shape + (omega.size,)),
        rc.reshape(shape + (2,)),
    )


def _fit_lines(attrs: dict, omega, lam, band, residual_terms: bool):
    """The lines of the residue fit, the residual-term kind (-1: none) and the band used
    (``band``, or widened with a warning when too few lines lie in it)."""
    n_k = lam.size
    use = band_mask(omega, lam, band)
    kind = -1
    if residual_terms:
        kind = RESIDUAL_KIND.get(from_attrs(FrfAttributes, attrs).frf_type, 0)
        if kind in (0, 1):
            use &= omega > 0  # the lower residual is singular at 0 Hz
    n_unknown = 2 * n_k + (4 if kind >= 0 else 0)
    band_used = band
    if 2 * int(use.sum()) < n_unknown + 1 and not isinstance(band, str):
        # Modes damped below the line spacing leave too few lines in their bands: widen the band
        # (doubling) just enough for the fit, and say so, rather than fail.
        band_used, use = _widened_band(omega, lam, float(band), use, n_unknown, kind)
        if band_used != band:
            warnings.warn(
                f"global_fit: only {int(band_mask(omega, lam, band).sum())} lines lie within "
                f"band={band} half-power bandwidths of the {n_k} modes (damping below the line "
                f"spacing); widened to band={band_used:g} ({int(use.sum())} lines) for the "
                f"residue fit; see attribute {names.ATTR_AMI_BAND_USED}",
                AssumptionWarning,
                stacklevel=4,
            )
    if 2 * int(use.sum()) < n_unknown + 1:
        raise IdentificationError(
            f"band: {int(use.sum())} lines selected, the residue fit needs at least "
            f"{n_unknown // 2 + 1} ({n_k} modes{', residual terms' if kind >= 0 else ''}); "
            "widen band or use band='all'"
        )
    return use, kind, band_used


def _fit(frf: xr.DataArray, use, omega, lam, data_model, kind: int):
    """Residues (point, mode), synthesised FRFs (point, frequency) and residual coefficients
    (point, residual_term) of every FRF in memory."""
    g = np.asarray(frf.transpose(names.POINT, names.FREQUENCY).values)
    res, synth, rc = _fit_block(
        g, use, omega, lam, data_model.dt, data_model.n_samples, residual_kind=kind
    )
    return (
        res,
        xr.Variable((names.POINT, names.FREQUENCY), synth),
        xr.Variable((names.POINT, names.RESIDUAL_TERM), rc),
    )


_COEF = "coefficient"  # the residue fit's unknowns per FRF: residues, then residual terms


def _fit_lazy(frf: xr.DataArray, use, omega, lam, data_model, kind: int):
    """:func:`_fit` of a dask-backed ``frf``, chunk by chunk: the residues and residual
    coefficients are gathered (per point, small); the synthesized FRFs stay lazy, made again
    per chunk from them (nothing of the FRF's size is computed here)."""
    n_k = lam.size
    kw = dict(omega=omega, lam=lam, dt=data_model.dt, n_samples=data_model.n_samples, kind=kind)
    size = rows.n_coefficients(n_k, kind)
    coef = ch.fit_per_row(rows.fit_rows, frf, names.FREQUENCY, _COEF, size, use=use, **kw)
    synth = ch.made_from_rows(rows.synthesize_rows, [coef], [_COEF], frf, names.FREQUENCY, **kw)
    synth = synth.rename({names.FREQUENCY + "_out": names.FREQUENCY})
    res = coef.isel({_COEF: slice(0, n_k)}).rename({_COEF: names.MODE})
    if kind >= 0:
        rc = coef.isel({_COEF: slice(n_k, None)}).rename({_COEF: names.RESIDUAL_TERM})
    else:
        rc = xr.zeros_like(coef.isel({_COEF: slice(0, 2)})).rename({_COEF: names.RESIDUAL_TERM})
    return np.asarray(res.transpose(names.POINT, names.MODE).values), synth, rc


def isolation_flags(detected: np.ndarray | None, converged: np.ndarray | None, n_k: int):
    """The flag bits the isolation's detections (``detected`` (P, K), ``converged`` (P,);
    None: no isolation) decide: ``not_converged`` (it stopped at ``max_iter`` at a point that
    detected the mode) and ``single_frf``."""
    mask = np.zeros(n_k, np.int32)
    if detected is not None and converged is not None:
        det, conv = np.asarray(detected, bool), np.asarray(converged, bool)
        capped = np.any(det & ~conv[:, None], axis=0) | (~np.any(det, axis=0) & ~np.all(conv))
        mask = flags.set_where(mask, names.FLAG_NOT_CONVERGED, capped)
        mask = flags.set_where(mask, names.FLAG_SINGLE_FRF, det.sum(axis=0) == 1)
    return mask


def _isolation_flags(ds: xr.Dataset, n_k: int) -> np.ndarray:
    """:func:`isolation_flags` of the isolation's output ``ds``."""
    if names.DETECTED in ds and names.ISO_CONVERGED in ds:
        det = ds[names.DETECTED].transpose(names.POINT, names.MODE).values
        return isolation_flags(det, ds[names.ISO_CONVERGED].transpose(names.POINT).values, n_k)
    return isolation_flags(None, None, n_k)


def fit_residues(frf: xr.DataArray, attrs: dict, lam: np.ndarray, sigma, mask, settings, band):
    """The residue fit (eq. 9) of the FRFs ``frf`` (point, frequency; in memory or lazy) at the
    eigenvalues ``lam`` with :class:`GlobalFitSettings` ``settings``: the core of
    :func:`global_fit`, which :func:`ami_xr.identify` calls on its arrays. ``attrs``: the FRF
    Dataset's (data model, FRF type); ``sigma`` (P,): the noise floors (None: estimated);
    ``mask`` (K,): the flag bits the isolation decided; ``band``: ``settings.band`` as the user
    gave it (an int stays an int in the warning). Returns the :class:`ResidueFit` and the
    band used (``settings.band``, or widened with a warning)."""
    data_model = resolve_model(attrs, "auto")
    omega = 2.0 * np.pi * np.asarray(frf[names.FREQUENCY].values, dtype=np.float64)
    use, kind, band_used = _fit_lines(attrs, omega, lam, band, settings.residual_terms)
    # a lazy FRF is fitted chunk by chunk and only what is per point is gathered
    fit_frfs = _fit_lazy if ch.is_lazy(frf) else _fit
    res, synth_da, rc_da = fit_frfs(frf, use, omega, lam, data_model, kind)
    if sigma is None:
        sigma = ch.per_row(
            kn.noise_floor, frf.transpose(names.POINT, names.FREQUENCY), names.FREQUENCY
        )
    fit = ResidueFit(
        eigenvalue=lam,
        residue=res,
        synthesized=synth_da,
        residual_coefficient=rc_da if kind >= 0 else None,
        dt=data_model.dt,
        n_samples=data_model.n_samples,
        noise_floor=sigma,
        mask=mask,
        drive_snr_min=settings.drive_snr_min,
    )
    return fit, band_used


def fit_attrs(attrs: dict, settings: GlobalFitSettings, band_used) -> None:
    """The global fit's record in ``attrs``: its settings and the band used when widened."""
    to_attrs(settings, attrs)
    if band_used != settings.band:
        attrs[names.ATTR_AMI_BAND_USED] = float(band_used)
    else:
        attrs.pop(names.ATTR_AMI_BAND_USED, None)


def global_fit(
    ds: xr.Dataset,
    *,
    band: float | str = GlobalFitSettings.band,
    residual_terms: bool = GlobalFitSettings.residual_terms,
    drive_snr_min: float = GlobalFitSettings.drive_snr_min,
) -> xr.Dataset:
    """Global Mode Vector Phase: fixed eigenvalues, residues of every FRF by linear LS (eq. 9).

    The frequency set Omega is the union over modes of the lines with
    ``|w - Im lam_k| <= band * 2 |Re lam_k|`` (``band`` half-power bandwidths each side), or every
    line with ``band="all"``. The basis is the one the earlier phases used (exact discrete-time
    for impulse-response FRFs, eq. 4 otherwise). The normal matrix depends only on the
    eigenvalues, so it is formed and factorised once and solved for all FRFs.

    Mode vectors follow eq. 8 scaled at the drive point (the ``drive_point`` attribute), in the
    displacement convention whatever the FRF type (:func:`receptance_mode_vectors`: mobility
    and accelerance residues divided by ``lam`` and ``lam^2``; attribute ``convention``); the
    sign of the square root is the principal branch. If the drive point is not one of the
    points, each mode vector is normalised to a unit largest entry and flagged
    ``unscaled_no_drive_point``.

    Quality flags per mode (bits of the int32 ``quality_flags``, :data:`ami_xr.core.flags.TABLE`):
    ``low_drive_point_snr`` (the mode's peak contribution at the drive point is below
    ``drive_snr_min`` times the drive point's noise floor: its scale, and every entry, is
    unreliable, the paper's modes 1 and 2), ``unscaled_no_drive_point``, ``not_converged``
    (isolation did not converge at a point that detected it), ``single_frf`` (detected in one
    FRF only).

    On a dask-backed FRF (a lazily opened file) the residues are fitted chunk by chunk of
    points on whatever scheduler is active and only they are gathered; ``frf_synthesized`` and
    ``frf_residual`` stay lazy, made again per chunk from them.

    Parameters
    ----------
    ds : xarray.Dataset
        Output of :func:`ami_xr.isolate` (needs ``eigenvalue``).
    band : float or "all"
        Half-width of each band in half-power bandwidths ``2 |Re lam|``, or "all".
    residual_terms : bool
        Add lower and upper residual terms per FRF for out-of-band modes (for measured FRFs):
        receptance ``R_L / (i w)^2 + R_U``, mobility ``R_L / (i w) + R_U i w``, accelerance
        ``R_L + R_U (i w)^2``, complex coefficients.
    drive_snr_min : float
        Threshold of the ``low_drive_point_snr`` flag (kept in the attribute
        ``ami_drive_snr_min``, which :func:`ami_xr.refine` uses when it decides the flag again).

    Returns
    -------
    xarray.Dataset
        The input plus ``residue`` and ``mode_vector`` (point, mode), ``frf_synthesized`` and
        ``frf_residual`` (point, frequency), ``mac`` (mode, mode_2), ``drive_point_snr`` and
        ``quality_flags`` (mode), and ``residual_coefficient`` (point, residual_term) when
        ``residual_terms``.
    """
    c.check_frf(ds, "global_fit")
    coord_attrs = c.coordinate_attrs(ds)
    ds = ds.copy()  # own variables: old xarray clears coordinate attrs in apply_ufunc
    if names.EIGENVALUE not in ds:
        raise IdentificationError(
            f"ds: global_fit needs {names.EIGENVALUE!r}; run ami_xr.isolate first"
        )
    drive_snr_min = c.check_positive(drive_snr_min, "drive_snr_min")
    lam = np.ascontiguousarray(ds[names.EIGENVALUE].values, dtype=np.complex128)
    n_k = lam.size
    if n_k == 0:
        raise IdentificationError(f"{names.EIGENVALUE}: no modes to fit (isolate found none)")
    if not isinstance(band, str):
        c.check_positive(band, "band")
    settings = GlobalFitSettings(
        band if isinstance(band, str) else float(band), bool(residual_terms), drive_snr_min
    )
    sigma = None
    if names.SUB_NOISE_FLOOR in ds:
        sigma = np.asarray(ds[names.SUB_NOISE_FLOOR].transpose(names.POINT).values, float)
    mask = _isolation_flags(ds, n_k)
    fit, band_used = fit_residues(ds[names.FRF], ds.attrs, lam, sigma, mask, settings, band)
    out = derive(fit, c.drop_results(ds, (c.GLOBAL_VARS,)))
    out = c.restore_coordinate_attrs(out, coord_attrs)
    fit_attrs(out.attrs, settings, band_used)
    # the history records the band as given (an int stays an int there)
    params = dict(parameters(settings), band=band)
    return c.finish(out, "ami_xr.global_fit", "global_fit", params)
