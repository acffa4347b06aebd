"""The FRF estimator :func:`~ami_xr.dsp.frf.frf` and :func:`~ami_xr.dsp.hammer.impact_frf`
share: their checked setup (:func:`setup`), Welch spectra of the chosen records and windows, H
and coherence per frequency (one ``apply_ufunc``), the noise of the estimate, the lines where it
is undefined, and the FRF Dataset with its attributes (:func:`spectra_to_frf`, :func:`finish`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.caller import warn
from ami_xr.core import frf_noise as _fn
from ami_xr.dsp.blocks import check_live_channels, feed_all, time_blocks
from ami_xr.dsp.spectral import AVERAGES, WelchAccumulator, check_choice, check_segments
from ami_xr.dsp.timeseries import force_and_response, is_lazy
from ami_xr.errors import AmiXrValueError, AssumptionWarning
from ami_xr.kernels import spectral as _ks
from ami_xr.provenance import add_history

_REF2 = "reference_2"  # private second reference dim of the force cross-spectral matrix
_NOISE_LONG_NAME = "standard deviation of the FRF estimate per line"


@dataclass(frozen=True)
class Setup:
    """Checked input and Welch settings shared by :func:`frf` and :func:`impact_frf`."""

    force: xr.DataArray  # (record, reference, time)
    response: xr.DataArray  # (record, point, time)
    siso: bool  # the force has no reference dim: the output has none either
    fs: float
    estimator: str
    nperseg: int
    noverlap: int
    nfft: int
    detrend: str | bool
    average: str
    n_average: int
    chunk_samples: int | None
    workers: int

    @property
    def nperseg_step(self) -> int:
        """Samples between segment starts."""
        return self.nperseg - self.noverlap


def setup(
    ds, *, estimator, force, fs, segments, detrend, average, n_average, chunk_samples, workers
):
    """Check everything both estimators share. ``segments`` is ``(nperseg, noverlap, nfft,
    default_nperseg)``: a ``nperseg`` of None becomes ``default_nperseg`` samples, or the whole
    record where that is None or longer."""
    code = _ks.estimator_code(estimator)
    estimator = _ks.ESTIMATORS[code - 1]
    if average in ("mean", "median"):  # scipy.signal.csd/welch's values of the same name
        raise AmiXrValueError(
            f"average: expected one of {AVERAGES} (the averaging types of FFT analysers), got "
            f"{average!r}, scipy's meaning of 'average'; scipy's 'mean' is 'linear' here, and a "
            "median average is not offered"
        )
    average = check_choice(average, "average", AVERAGES)
    if average == "exponential" and (
        isinstance(n_average, bool) or not isinstance(n_average, (int, np.integer)) or n_average < 1
    ):
        raise AmiXrValueError(f"n_average: expected an integer >= 1, got {n_average!r}")
    f_da, y_da, fs = force_and_response(ds, force, fs)
    nref, nt = f_da.shape[1:]
    if estimator != "H1" and nref > 1:
        raise AmiXrValueError(
            f"estimator: {estimator!r} needs a single force channel, got {nref} along "
            f"{names.REFERENCE!r}; use 'H1'"
        )
    _ks.detrend_code(detrend)
    nperseg, noverlap, nfft, default_nperseg = segments
    if nperseg is None:
        nperseg = nt if default_nperseg is None else min(default_nperseg, nt)
    nperseg, noverlap, nfft = check_segments(nt, nperseg, noverlap, nfft)
    if chunk_samples is not None and (
        isinstance(chunk_samples, bool)
        or not isinstance(chunk_samples, (int, np.integer))
        or chunk_samples < 1
    ):
        raise AmiXrValueError(f"chunk_samples: expected an integer >= 1, got {chunk_samples!r}")
    if not (is_lazy(f_da) or is_lazy(y_da)):  # in memory: dead channels before any spectra
        f_all = np.asarray(f_da.values, np.float64)
        y_all = np.asarray(y_da.values, np.float64)
        check_live_channels(
            (f_all.min(axis=(0, 2)), f_all.max(axis=(0, 2))),
            (y_all.min(axis=(0, 2)), y_all.max(axis=(0, 2))),
            f_da,
            y_da,
        )
    siso = names.REFERENCE not in (force if force is not None else ds[names.FORCE]).dims
    return Setup(
        force=f_da,
        response=y_da,
        siso=siso,
        fs=fs,
        estimator=estimator,
        nperseg=nperseg,
        noverlap=noverlap,
        nfft=nfft,
        detrend=detrend,
        average=average,
        n_average=n_average,
        chunk_samples=chunk_samples,
        workers=workers,
    )


def point_labels(y_da: xr.DataArray) -> list:
    return (
        list(y_da[names.POINT].values)
        if names.POINT in y_da.coords
        else list(range(y_da.sizes[names.POINT]))
    )


def _frf_kernel(gff, gfy, gyy, estimator):
    """apply_ufunc core: (ref, ref2, f), (ref, point, f), (point, f) -> H, coherence."""
    return _ks.frf_from_spectra(gff, gfy, gyy, estimator)


def _noise_std(h, coh, gff, gyy, acc, s: Setup, window) -> tuple[np.ndarray | None, str]:
    """``frf_line_noise_std`` (ref, point, f) of the estimate: Bendat & Piersol's random error from
    the coherence and the effective number of averages (:mod:`ami_xr.core.frf_noise`); with
    too few averages for that (one hit, one segment) the roughness between adjacent lines;
    None where there are too few lines for that as well."""
    n_eff = _fn.effective_averages(window, s.nperseg_step, acc.count, s.average, s.n_average)
    q = gff.shape[0]
    if n_eff >= q + 1:
        std = _fn.coherence_noise_std(h, coh, gff, gyy, n_eff, s.estimator)
        model = _fn.coherence_model(s.estimator, q, n_eff, acc.count)
    elif h.shape[-1] <= _fn.ROUGHNESS_ORDER:
        return None, ""
    else:
        std = _fn.roughness_noise_std(h)
        model = _fn.roughness_model(
            reason=f"{acc.count} average(s) with {q} force channel(s): the coherence formula "
            "needs n_d > q"
        )
    return std, model


# Lines whose force cross-spectral matrix Gff has a condition number above this cannot be
# inverted for H1 (inputs fully correlated, or a silent input at that line).
MAX_INPUT_CONDITION = 1e10


def _check_input_conditioning(gff: np.ndarray, frequency: np.ndarray, f_da) -> np.ndarray:
    """Several inputs: the condition number of Gff (ref, ref, f) per line, before any FRF is
    computed. Some lines singular: an AssumptionWarning naming them (their FRF is NaN); every
    line singular: an error (the inputs are fully correlated, one MIMO FRF cannot be told
    from another)."""
    if gff.shape[0] < 2:
        return np.zeros(frequency.size, bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.linalg.cond(np.moveaxis(gff, -1, 0))
    bad = ~(cond <= MAX_INPUT_CONDITION)  # NaN and inf count as singular
    if not bad.any():
        return bad
    refs = f_da[names.REFERENCE].values.tolist() if names.REFERENCE in f_da.coords else None
    where = f"force channels {refs}" if refs is not None else "the force channels"
    if bad.all():
        raise AmiXrValueError(
            f"force: {where} are fully correlated (the force cross-spectral matrix Gff is "
            f"singular at every line, condition number > {MAX_INPUT_CONDITION:g}); the MIMO "
            "FRFs cannot be separated. Drive the inputs with independent signals, or estimate "
            "one reference at a time (select one force channel)"
        )
    lines = frequency[bad]
    shown = ", ".join(f"{x:g}" for x in lines[:10]) + (" ..." if lines.size > 10 else "")
    warn(
        f"frf: the force cross-spectral matrix is singular (condition number > "
        f"{MAX_INPUT_CONDITION:g}) at {lines.size} of {frequency.size} lines ({shown} Hz): "
        f"{where} are correlated there, and the FRF is NaN at those lines",
        AssumptionWarning,
    )
    return bad


#: Attributes of an estimated FRF Dataset that name the lines where the FRF is NaN (Hz, a float
#: array) and say why, one sentence; absent where every line is defined.
ATTR_UNDEFINED_LINES = "frf_undefined_frequencies"


ATTR_UNDEFINED_REASON = "frf_undefined_reason"


def _undefined_lines(
    h: np.ndarray,
    gff: np.ndarray,
    gyy: np.ndarray,
    frequency: np.ndarray,
    singular: np.ndarray,
    estimator: str,
) -> dict[str, Any]:
    """Lines where an estimate ``h`` (ref, point, f) is not finite, other than those the singular
    Gff warning already named: an AssumptionWarning that names them and says why, and the
    attributes that record them (empty dict where there are none).

    The usual cause is a line without force power: a clean pulse whose spectrum is exactly 0 at
    the Nyquist line (a two-sample pulse), the 0 Hz line of a detrended force. H1 = Gfy/Gff is
    then 0/0; H2 and Hv divide by Gyf or Gyy, 0 where the response carries no power.
    """
    bad = ~np.isfinite(h).all(axis=tuple(range(h.ndim - 1))) & ~singular
    if not bad.any():
        return {}
    power = np.real(np.einsum("iik->ik", gff))  # (ref, f)
    no_force = bad & (power <= 0.0).any(axis=0)
    no_response = bad & ~no_force & (np.real(gyy) <= 0.0).any(axis=0)
    other = bad & ~no_force & ~no_response
    why = []
    for mask, text in (
        (
            no_force,
            "the force autospectrum Gff is exactly 0 (no excitation at that line: the "
            "Nyquist line of a clean pulse, 0 Hz of a detrended force)",
        ),
        (no_response, f"the response autospectrum Gyy is exactly 0 ({estimator} divides by it)"),
        (other, "the spectra there are not finite or cancel exactly"),
    ):
        if mask.any():
            why.append(f"at {_lines_text(frequency[mask])} Hz {text}")
    lines = frequency[bad]
    reason = "; ".join(why)
    warn(
        f"frf: the FRF is NaN at {lines.size} of {frequency.size} lines: {reason}. Those lines "
        "carry no estimate; keep them out of the analysis band (ami-xr identify --fmin/--fmax) "
        f"or excite them. Recorded in the attributes {ATTR_UNDEFINED_LINES!r} and "
        f"{ATTR_UNDEFINED_REASON!r}",
        AssumptionWarning,
    )
    return {
        ATTR_UNDEFINED_LINES: np.asarray(lines, dtype=np.float64),
        ATTR_UNDEFINED_REASON: reason,
    }


def _lines_text(lines: np.ndarray) -> str:
    return ", ".join(f"{x:g}" for x in lines[:10]) + (" ..." if lines.size > 10 else "")


def spectra_to_frf(
    ds: xr.Dataset,
    s: Setup,
    windows: tuple[np.ndarray, np.ndarray],
    records: np.ndarray,
    extra: dict[str, Any],
    attrs_extra: dict[str, Any],
) -> xr.Dataset:
    """The estimator both public functions share: Welch spectra of the used ``records`` with the
    ``(force, response)`` windows, then H and coherence per frequency (one ``apply_ufunc``), and
    the FRF Dataset with ``extra`` variables and ``attrs_extra`` attributes."""
    f_da, y_da = s.force, s.response
    nref, nt = f_da.shape[1:]
    acc = WelchAccumulator(
        nref,
        y_da.sizes[names.POINT],
        fs=s.fs,
        nperseg=s.nperseg,
        noverlap=s.noverlap,
        nfft=s.nfft,
        force_window=windows[0],
        response_window=windows[1],
        detrend=s.detrend,
        average=s.average,
        n_average=s.n_average,
        workers=s.workers,
    )
    feed_all(acc, f_da, y_da, records, time_blocks(nt, y_da, s.chunk_samples))
    gff, gfy, gyy = acc.spectra()
    singular = _check_input_conditioning(gff, acc.frequency, f_da)

    fdim = names.FREQUENCY
    ref_coord = f_da[names.REFERENCE].values if names.REFERENCE in f_da.coords else np.arange(nref)
    Gff = xr.DataArray(gff, dims=[names.REFERENCE, _REF2, fdim])
    Gfy = xr.DataArray(gfy, dims=[names.REFERENCE, names.POINT, fdim])
    Gyy = xr.DataArray(gyy, dims=[names.POINT, fdim])
    H, coh = xr.apply_ufunc(
        _frf_kernel,
        Gff,
        Gfy,
        Gyy,
        kwargs={"estimator": s.estimator},
        input_core_dims=[
            [names.REFERENCE, _REF2, fdim],
            [names.REFERENCE, names.POINT, fdim],
            [names.POINT, fdim],
        ],
        output_core_dims=[[names.REFERENCE, names.POINT, fdim], [names.POINT, fdim]],
        dask="parallelized",
        output_dtypes=[np.complex128, np.float64],
        keep_attrs=False,
    )
    if singular.any():  # lines where Gff cannot be inverted: NaN, as the warning said
        H = H.where(~xr.DataArray(singular, dims=[fdim]))
    undefined = _undefined_lines(H.values, gff, gyy, acc.frequency, singular, s.estimator)
    if undefined:
        attrs_extra = {**attrs_extra, **undefined}
    ru = ds.attrs.get(names.ATTR_RESPONSE_UNITS, y_da.attrs.get(names.ATTR_UNITS, ""))
    fu = ds.attrs.get(names.ATTR_FORCE_UNITS, f_da.attrs.get(names.ATTR_UNITS, ""))
    std, noise_model = _noise_std(H.values, coh.values, gff, gyy, acc, s, windows[1])
    noise = xr.DataArray(np.zeros(H.shape) if std is None else std, dims=H.dims).assign_attrs(
        {
            names.ATTR_UNITS: names.frf_units(ru, fu),
            names.ATTR_LONG_NAME: _NOISE_LONG_NAME,
            names.ATTR_NOISE_MODEL: noise_model,
        }
    )
    gff_diag = xr.DataArray(np.real(np.einsum("iik->ik", gff)), dims=[names.REFERENCE, fdim])
    if s.siso:
        H, Gfy, gff_diag, noise = (
            H.isel({names.REFERENCE: 0}),
            Gfy.isel({names.REFERENCE: 0}),
            gff_diag.isel({names.REFERENCE: 0}),
            noise.isel({names.REFERENCE: 0}),
        )
    out = xr.Dataset(
        {
            names.FRF: H.assign_attrs({names.ATTR_UNITS: names.frf_units(ru, fu)}),
            names.COHERENCE: coh.assign_attrs({names.ATTR_UNITS: "1"}),
            names.FORCE_AUTOSPECTRUM: gff_diag.assign_attrs({names.ATTR_UNITS: f"{fu}^2/Hz"}),
            names.RESPONSE_AUTOSPECTRUM: Gyy.assign_attrs({names.ATTR_UNITS: f"({ru})^2/Hz"}),
            names.CROSS_SPECTRUM: Gfy.assign_attrs({names.ATTR_UNITS: f"{fu}*{ru}/Hz"}),
            **extra,
        }
        | ({} if std is None else {names.FRF_LINE_NOISE_STD: noise}),
        coords={
            names.POINT: point_labels(y_da),
            fdim: (fdim, acc.frequency, {names.ATTR_UNITS: names.FREQUENCY_UNITS}),
            **({} if s.siso else {names.REFERENCE: ref_coord}),
        },
    )
    out = out.transpose(
        *[d for d in (names.REFERENCE, names.POINT, fdim, names.RECORD) if d in out.dims]
    )
    out.attrs = _frf_attrs(ds, s, ru, fu, int(acc.count), attrs_extra)
    return out


def _frf_attrs(ds, s: Setup, ru: str, fu: str, n_averages: int, attrs_extra: dict) -> dict:
    """The estimated FRF Dataset's attributes: what the time Dataset says that still applies,
    the units, the estimator and the averages, and ``attrs_extra``."""
    quantity = ds.attrs.get(names.ATTR_QUANTITY)
    # Several force channels: the reference labels (the force's ``reference`` coordinate) name
    # the excitation locations, and those that are point labels are the drive points; the
    # time Dataset's single ``drive_point`` attribute does not apply.
    kept = (
        (names.ATTR_DRIVE_POINT, names.ATTR_DRIVE_POINT_ASSUMED, names.ATTR_QUANTITY)
        if s.siso
        else (names.ATTR_QUANTITY,)
    )
    attrs = {k: ds.attrs[k] for k in kept if k in ds.attrs}
    if quantity in names.QUANTITY_TO_FRF_TYPE:
        attrs[names.ATTR_FRF_TYPE] = names.QUANTITY_TO_FRF_TYPE[quantity]
    if names.ATTR_EXP_DECAY in ds.attrs and names.ATTR_EXP_DECAY not in attrs_extra:
        attrs[names.ATTR_EXP_DECAY] = ds.attrs[names.ATTR_EXP_DECAY]
    attrs.update(
        {
            names.ATTR_RESPONSE_UNITS: ru,
            names.ATTR_FORCE_UNITS: fu,
            names.ATTR_SOURCE: names.SOURCE_ESTIMATED,
            names.ATTR_ESTIMATOR: s.estimator,
            names.ATTR_N_AVERAGES: n_averages,
            **attrs_extra,
        }
    )
    for key in (names.ATTR_HISTORY, names.ATTR_VERSION, names.ATTR_SOURCE_FILE):
        if key in ds.attrs:
            attrs[key] = ds.attrs[key]
    return attrs


def finish(out: xr.Dataset, s: Setup, function: str, window: str, extra: dict) -> xr.Dataset:
    """Record the call in the history."""
    params = {
        "estimator": s.estimator,
        "fs": s.fs,
        "window": window,
        "nperseg": s.nperseg,
        "noverlap": s.noverlap,
        "nfft": s.nfft,
        "detrend": s.detrend,
        "average": s.average,
        "n_average": s.n_average,
        **extra,
    }
    return add_history(out, function, params)
