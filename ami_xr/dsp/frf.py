"""FRF estimation from measured force and response histories: :func:`frf` and :func:`impact_frf`.

:func:`frf` estimates H1, H2 or Hv from random (continuous, shaker) excitation by Welch
averaging; :func:`impact_frf` from hammer hits, each checked (:mod:`ami_xr.dsp.hits`), windowed
with a force and an exponential window and averaged. Both return the ordinary coherence
(multiple coherence with several force channels) and the averaged auto- and cross-spectra, and
share one estimator, ``_spectra_to_frf``. :func:`frf_from_options` picks one of the two from an
``excitation`` option, for option dictionaries held as data (batch runs, the CLI).

Processing path (the same for data in memory and data opened lazily from a file)::

    time Dataset --(record by record, time block by time block)--> WelchAccumulator
                 --> Gff, Gfy, Gyy --(one xr.apply_ufunc, per frequency)--> H, coherence

A dask-backed Dataset is read one time chunk at a time (or ``chunk_samples`` at a time); the
samples of a segment that straddles a chunk border are carried to the next chunk, so memory is
bounded by the chunk size and the result equals the in-memory computation. Segments never span
two records. (The accumulation over time is a loop over blocks rather than an ``apply_ufunc``
over ``time``: its state, the carried samples and the running sums, crosses chunk borders, which
``dask="parallelized"`` cannot express; the per-frequency division is the ``apply_ufunc``.)
"""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.caller import warn
from ami_xr.core import frf_noise as _fn
from ami_xr.dsp.blocks import (
    check_live_channels,
    feed_all,
    load_block,
    time_blocks,
)
from ami_xr.dsp.hits import check_hits
from ami_xr.dsp.spectral import (
    AVERAGES,
    WelchAccumulator,
    check_choice,
    check_segments,
    resolve_window,
)
from ami_xr.dsp.timeseries import excitation_of, force_and_response, is_lazy
from ami_xr.errors import AmiXrValueError, AssumptionWarning
from ami_xr.kernels import impact as _ki
from ami_xr.kernels import spectral as _ks
from ami_xr.kernels import windows as _kw
from ami_xr.provenance import add_history

EXCITATIONS = ("random", "impact")
AUTO = "auto"  # excitation decided by ami_xr.dsp.timeseries.excitation_of
_REF2 = "reference_2"  # private second reference dim of the force cross-spectral matrix
_NOISE_LONG_NAME = "standard deviation of the FRF estimate per line"


# --- the estimator -------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Setup:
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


def _setup(
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
    return _Setup(
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


def _point_labels(y_da: xr.DataArray) -> list:
    return (
        list(y_da[names.POINT].values)
        if names.POINT in y_da.coords
        else list(range(y_da.sizes[names.POINT]))
    )


def _frf_kernel(gff, gfy, gyy, estimator):
    """apply_ufunc core: (ref, ref2, f), (ref, point, f), (point, f) -> H, coherence."""
    return _ks.frf_from_spectra(gff, gfy, gyy, estimator)


def _noise_std(h, coh, gff, gyy, acc, s: _Setup, window) -> tuple[np.ndarray | None, str]:
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


def _spectra_to_frf(
    ds: xr.Dataset,
    s: _Setup,
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
            names.POINT: _point_labels(y_da),
            fdim: (fdim, acc.frequency, {names.ATTR_UNITS: names.FREQUENCY_UNITS}),
            **({} if s.siso else {names.REFERENCE: ref_coord}),
        },
    )
    out = out.transpose(
        *[d for d in (names.REFERENCE, names.POINT, fdim, names.RECORD) if d in out.dims]
    )
    out.attrs = _frf_attrs(ds, s, ru, fu, int(acc.count), attrs_extra)
    return out


def _frf_attrs(ds, s: _Setup, ru: str, fu: str, n_averages: int, attrs_extra: dict) -> dict:
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


def _finish(out: xr.Dataset, s: _Setup, function: str, window: str, extra: dict) -> xr.Dataset:
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


def frf(
    ds: xr.Dataset,
    estimator: str = "H1",
    *,
    force: xr.DataArray | None = None,
    fs: float | None = None,
    window: str | np.ndarray = "hann",
    nperseg: int | None = None,
    noverlap: int | None = None,
    nfft: int | None = None,
    detrend: str | bool = "constant",
    average: str = "linear",
    n_average: int = 8,
    chunk_samples: int | None = None,
    workers: int = 1,
) -> xr.Dataset:
    """Estimate FRFs (H1, H2 or Hv) and coherence from random (continuous) excitation by Welch
    averaging. Hammer tests go through :func:`impact_frf`.

    Data that look like hammer hits (the force is a short pulse:
    :func:`ami_xr.dsp.timeseries.excitation_of`, the rule the CLI's ``--excitation auto`` uses)
    give an :class:`~ami_xr.errors.AssumptionWarning` naming the segments averaged and pointing
    to :func:`impact_frf`: Welch segments of a hit average mostly silence and use overloaded and
    double hits unchecked. A warning, not an error: Welch over whole hits (``nperseg`` = the
    record, ``noverlap=0``, ``window="boxcar"``, ``detrend="none"``) is a valid expert choice, and
    the random estimate stays reachable for every input. :func:`frf_from_options` without an
    ``excitation`` (and ``ami-xr frf``) picks :func:`impact_frf` for such data by the same rule.

    Parameters
    ----------
    ds : xarray.Dataset
        Time Dataset: ``response`` ([record,] point, time), ``force`` ``([record,] [reference,]
        time)``, ``time`` coordinate in s (uniform). May be dask-backed (opened lazily with
        :func:`ami_xr.open_dataset`); it is then read one time chunk at a time. Records are
        averaged together; no segment spans two records.
    estimator : {"H1", "H2", "Hv"}
        ``H1 = Gfy/Gff`` (unbiased by output noise), ``H2 = Gyy/Gyf`` (unbiased by input noise),
        ``Hv`` total least squares (between them). Several force channels: H1 only (MIMO).
    force : xarray.DataArray, optional
        Force histories recorded separately (replaces ``ds.force``); must have the same samples
        and sampling rate as the responses.
    fs : float, optional
        Sampling rate in Hz; checked against the time coordinate when both are present.
    window : str or ndarray
        Welch window: a name known to :func:`ami_xr.kernels.windows.get_window` or an array of
        ``nperseg`` samples (``None`` also means ``"hann"``).
    nperseg, noverlap, nfft : int, optional
        Segment length (default 256 samples, or the record if shorter), overlap (default
        ``nperseg // 2``) and FFT length (default ``nperseg``), as in ``scipy.signal.csd``.
    detrend : {"constant", "linear", "none"} or False
        Removed from each segment before windowing (``None`` also means ``"constant"``).
    average : {"linear", "exponential"}
        Linear: plain mean over all segments. Exponential: running average with time constant
        ``n_average`` segments (linear over the first ``n_average``). Not the ``average`` of
        ``scipy.signal.csd``/``welch`` (``"mean"`` or ``"median"`` of the segments): the name
        follows the averaging types of FFT analysers (linear, exponential); scipy's ``"mean"``
        is our ``"linear"``, and a median average is not offered.
    n_average : int
        Time constant of exponential averaging, in segments.
    chunk_samples : int, optional
        Samples per block read from a lazy Dataset (default: its dask chunks along ``time``).
    workers : int
        Threads of ``scipy.fft``.

    Returns
    -------
    xarray.Dataset
        FRF Dataset: ``frf`` ([reference,] point, frequency) complex, ``coherence`` (point,
        frequency; multiple coherence with several force channels), ``force_autospectrum``
        ([reference,] frequency), ``response_autospectrum`` (point, frequency),
        ``cross_spectrum`` ([reference,] point, frequency) (one-sided densities),
        ``frf_line_noise_std`` (dims of ``frf``, units of ``frf``: the standard deviation of the
        complex estimate per line from the coherence and the effective number of averages
        ``n_d``, ``sqrt((1 - coh) |H|^2 / (coh (n_d - q)))`` for ``q`` force channels, Bendat &
        Piersol's random error; with ``n_d < q + 1`` the roughness estimate of
        :func:`ami_xr.estimate_frf_noise`, left out below 5 lines; attr ``noise_model`` says
        which), attrs ``frf_source="estimated"``, ``estimator``, ``n_averages``. With several
        force channels the ``reference`` labels are those of the force's ``reference``
        coordinate (default 0, 1, ...): give the labels of the excitation points, so that a
        reference on a measured point marks its drive point; the ``drive_point`` attribute is
        then dropped.

    Raises
    ------
    AmiXrValueError
        Bad input, each naming the argument: missing force, different lengths or sampling
        rates, NaN samples, ``nperseg`` longer than the record, ``noverlap >= nperseg``, unknown
        window, estimator, detrend or average.
    """
    s = _setup(
        ds,
        estimator=estimator,
        force=force,
        fs=fs,
        segments=(nperseg, noverlap, nfft, 256),
        detrend="constant" if detrend is None else detrend,
        average=average,
        n_average=n_average,
        chunk_samples=chunk_samples,
        workers=workers,
    )
    window = "hann" if window is None else window
    w = resolve_window(window, s.nperseg)
    records = np.arange(s.force.sizes[names.RECORD])
    if excitation_of(ds if force is None else xr.Dataset({names.FORCE: force})) == "impact":
        n_seg = records.size * (1 + (s.force.sizes[names.TIME] - s.nperseg) // s.nperseg_step)
        warnings.warn(
            f"ds: the force is a short pulse (hammer hits), but ami_xr.frf averages Welch "
            f"segments of random excitation ({n_seg} segments of {s.nperseg} samples, no hit "
            "checks); use ami_xr.impact_frf (ami-xr frf --excitation impact)",
            AssumptionWarning,
            stacklevel=2,
        )
    if nperseg is None:
        _warn_few_lines(s.nperseg, s.nfft, s.force.sizes[names.TIME], s.fs)
    out = _spectra_to_frf(ds, s, (w, w), records, {}, {})
    label = window if isinstance(window, str) else "array"
    return _finish(out, s, "ami_xr.frf", label, {"n_records_used": records.size})


#: Fewer lines than this from the default segment length is said (issue 24 item 8): the
#: identification's bands then hold a handful of lines each.
FEW_LINES = 257
#: Welch segments the suggested ``nperseg`` keeps in a record (about twice that with the
#: default half overlap), so the averages still tame the noise.
SUGGESTED_SEGMENTS = 8


def _warn_few_lines(nperseg: int, nfft: int, n_time: int, fs: float) -> None:
    """The default ``nperseg`` leaves fewer than :data:`FEW_LINES` lines although the record
    holds :data:`SUGGESTED_SEGMENTS` segments of a longer power of two: say so and what to
    pass. (The damping is not known here: :func:`ami_xr.identify` gives the ``nperseg`` that
    resolves its lightest-damped mode, :mod:`ami_xr.ami.resolution`.)"""
    lines = nfft // 2 + 1
    suggested = 2 ** int(np.floor(np.log2(max(n_time / SUGGESTED_SEGMENTS, 1.0))))
    if lines >= FEW_LINES or suggested <= nperseg:
        return
    warn(
        f"frf: the default nperseg={nperseg} gives {lines} lines {fs / nfft:.4g} Hz apart from "
        f"a record of {n_time} samples ({n_time / fs:.4g} s); identification wants a few "
        f"hundred lines: pass nperseg={suggested} ({suggested // 2 + 1} lines "
        f"{fs / suggested:.4g} Hz apart, {SUGGESTED_SEGMENTS} segments or more; "
        "ami-xr frf --nperseg); identify then flags a mode whose half-power bandwidth spans "
        "fewer than 3 lines (under_resolved) and names the nperseg that resolves it",
        AssumptionWarning,
    )


def impact_frf(
    ds: xr.Dataset,
    estimator: str = "H1",
    *,
    force: xr.DataArray | None = None,
    fs: float | None = None,
    force_window: float | None = None,
    exponential_decay: float | None = None,
    exponential_end_value: float | None = None,
    hit_checks: bool = True,
    overload_samples: int = 3,
    double_impact_threshold: float = 0.1,
    min_force: float | None = None,
    weak_force_ratio: float = 0.1,
    nperseg: int | None = None,
    noverlap: int | None = 0,
    nfft: int | None = None,
    detrend: str | bool = "none",
    average: str = "linear",
    n_average: int = 8,
    chunk_samples: int | None = None,
    workers: int = 1,
) -> xr.Dataset:
    """Estimate FRFs (H1, H2 or Hv) and coherence from an impact (hammer) test.

    Every record is one hit. Each hit is checked before use (overload, double impact, weak force;
    see :func:`ami_xr.dsp.hits.check_hits`); rejected hits are listed with their reason and left
    out. The force channel gets a force (transient) window times the exponential window, the
    responses the exponential window. Applying the exponential window to the force as well makes
    the result exact: ``(h * f) e^(-beta t) = (h e^(-beta t)) * (f e^(-beta t))``, so the
    estimated FRF is that of the system with every eigenvalue shifted by ``-beta``; ``beta`` is
    stored as ``exponential_window_decay`` (1/s) and identification adds it back. The accepted
    hits are then averaged as Welch segments (by default one segment per hit).

    Long because the docstring documents the hit checks and the windows' options; the code is
    78 lines.

    Parameters
    ----------
    ds : xarray.Dataset
        Time Dataset: ``response`` ([record,] point, time), ``force`` ``([record,] [reference,]
        time)``, ``time`` coordinate in s (uniform); ``record`` is the hit.
    estimator, force, fs
        As for :func:`frf`.
    force_window : float, optional
        Width in s of the force window (1 from the record start to here, then a short
        half-cosine taper). Default: the end of the latest first force pulse of the accepted hits
        plus that pulse's length.
    exponential_decay, exponential_end_value : float, optional
        Exponential window on force and response, by decay rate (1/s) or value at the record
        end; at most one. Default none.
    hit_checks : bool
        Check hits; False uses every hit.
    overload_samples, double_impact_threshold, min_force, weak_force_ratio
        Hit-check thresholds (see :func:`ami_xr.dsp.hits.check_hits`).
    nperseg, noverlap, nfft : int, optional
        Segment length (default the whole hit), overlap (default 0; ``None`` also means 0) and FFT
        length (default ``nperseg``).
    detrend : {"none", "constant", "linear"} or False
        Removed from each segment before windowing (``None`` also means ``"none"``).
    average, n_average, chunk_samples, workers
        As for :func:`frf`; averaging runs over hits (segments).

    Returns
    -------
    xarray.Dataset
        The FRF Dataset of :func:`frf` plus ``hit_rejected``, ``hit_reject_reason`` and
        ``hit_peak_force`` (record), attrs ``force_window_width`` (s) and, with an exponential
        window, ``exponential_window_decay`` (1/s).

    Raises
    ------
    AmiXrValueError
        As for :func:`frf`; also a bad ``force_window`` or exponential window, and every hit
        rejected (the message lists each hit's reason).
    """
    s = _setup(
        ds,
        estimator=estimator,
        force=force,
        fs=fs,
        segments=(nperseg, 0 if noverlap is None else noverlap, nfft, None),
        detrend="none" if detrend is None else detrend,
        average=average,
        n_average=n_average,
        chunk_samples=chunk_samples,
        workers=workers,
    )
    if force_window is not None and not (
        isinstance(force_window, (int, float, np.number)) and force_window > 0
    ):
        raise AmiXrValueError(f"force_window: expected a width in s > 0, got {force_window!r}")
    beta = None
    if exponential_decay is not None or exponential_end_value is not None:
        beta = _kw.exponential_decay_rate(
            s.nperseg, fs=s.fs, decay=exponential_decay, end_value=exponential_end_value
        )
    nrec, n_time = s.force.sizes[names.RECORD], s.force.sizes[names.TIME]
    fv = np.stack([load_block(s.force, r, 0, n_time, "force") for r in range(nrec)])
    yv = np.stack([load_block(s.response, r, 0, n_time, "response") for r in range(nrec)])
    if hit_checks:
        rejected, reasons, peak, pulse = check_hits(
            fv,
            yv,
            overload_samples=overload_samples,
            double_impact_threshold=double_impact_threshold,
            min_force=min_force,
            weak_force_ratio=weak_force_ratio,
            point_labels=_point_labels(s.response),
        )
    else:
        rejected = np.zeros(nrec, bool)
        reasons = [""] * nrec
        peak = np.max(np.abs(fv[:, 0]), axis=1)
        pulse = _ki.force_pulses(np.ascontiguousarray(fv[:, 0]), double_impact_threshold * peak, 3)
        pulse = pulse[:, 1:3]
    del fv, yv
    if rejected.all():
        lines = "; ".join(f"hit {r}: {reasons[r]}" for r in range(nrec))
        raise AmiXrValueError(f"ds: every impact hit was rejected ({lines})")
    use = ~rejected
    rec = {names.RECORD: ds[names.RECORD].values if names.RECORD in ds.coords else np.arange(nrec)}
    force_units = {names.ATTR_UNITS: ds.attrs.get(names.ATTR_FORCE_UNITS, "")}
    extra = {
        names.HIT_REJECTED: xr.DataArray(rejected, dims=[names.RECORD], coords=rec),
        names.HIT_REJECT_REASON: xr.DataArray(
            np.array(reasons, dtype=str), dims=[names.RECORD], coords=rec
        ),
        names.HIT_PEAK_FORCE: xr.DataArray(
            peak, dims=[names.RECORD], coords=rec, attrs=force_units
        ),
    }
    # force window: default covers the first pulse of every accepted hit plus its length
    if force_window is None:
        ends = pulse[use, 1]
        lengths = pulse[use, 1] - pulse[use, 0] + 1
        width = int(min(s.nperseg, max(1, ends.max() + 1 + lengths.max())))
    else:
        width = int(min(s.nperseg, max(1, round(float(force_window) * s.fs))))
    wf = _kw.get_window("force", s.nperseg, width=width)
    attrs_extra: dict[str, Any] = {}
    if beta is not None:
        we = _kw.get_window("exponential", s.nperseg, fs=s.fs, decay=beta)
        # a window already applied to the time data (ami_xr.apply_window) adds up
        attrs_extra[names.ATTR_EXP_DECAY] = float(beta) + float(
            ds.attrs.get(names.ATTR_EXP_DECAY, 0.0) or 0.0
        )
    else:
        we = np.ones(s.nperseg)
    attrs_extra[names.ATTR_FORCE_WINDOW_WIDTH] = width / s.fs
    out = _spectra_to_frf(ds, s, (wf * we, we), np.flatnonzero(use), extra, attrs_extra)
    label = "force*exponential" if names.ATTR_EXP_DECAY in attrs_extra else "force"
    params = {"n_records_used": int(use.sum()), **attrs_extra}
    return _finish(out, s, "ami_xr.impact_frf", label, params)


def frf_from_options(ds: xr.Dataset, options: Mapping[str, Any]) -> xr.Dataset:
    """:func:`frf` or :func:`impact_frf` by ``options["excitation"]`` (``"random"``,
    ``"impact"``, or ``"auto"``, the default: :func:`~ami_xr.dsp.timeseries.excitation_of`
    decides from the force, the rule of ``ami-xr frf``), with the other options as keyword
    arguments.

    For option dictionaries held as data (``ami_xr.batch``'s ``frf_options``, the CLI): an option
    of the other function raises :class:`AmiXrValueError` naming it unless it is None (unset), and
    so does an option of neither.
    """
    options = dict(options)
    excitation = options.pop("excitation", AUTO)
    excitation = check_choice(excitation, "excitation", (*EXCITATIONS, AUTO))
    if excitation == AUTO:
        excitation = excitation_of(ds)
    function, other = (impact_frf, frf) if excitation == "impact" else (frf, impact_frf)
    own = set(inspect.signature(function).parameters) - {"ds"}
    foreign = set(inspect.signature(other).parameters) - own - {"ds"}
    kwargs = {}
    for name, value in options.items():
        if name in own:
            kwargs[name] = value
        elif name not in foreign:
            raise AmiXrValueError(f"{name}: not an option of ami_xr.{function.__name__}")
        elif value is not None:
            raise AmiXrValueError(
                f"{name}: not used with excitation={excitation!r} (an option of "
                f"ami_xr.{other.__name__})"
            )
    return function(ds, **kwargs)
