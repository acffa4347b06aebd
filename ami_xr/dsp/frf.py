"""FRF estimation from measured force and response histories: ``frf`` and ``convert_quantity``.

:func:`frf` turns a time Dataset into an FRF Dataset with H1, H2 or Hv, Welch averaging for
random (shaker) excitation or hit averaging for impact (hammer) tests, the ordinary coherence
(multiple coherence with several force channels) and the averaged auto- and cross-spectra.

Processing path (the same for data in memory and data opened lazily from a file)::

    time Dataset --(record by record, time block by time block)--> WelchAccumulator
                 --> Gff, Gfy, Gyy --(one xr.apply_ufunc, per frequency)--> H, coherence

A dask-backed Dataset is read one time chunk at a time (or ``chunk_samples`` at a time); the
samples of a segment that straddles a chunk border are carried to the next chunk, so memory is
bounded by the chunk size and the result equals the in-memory computation. Segments never span
two records. (The accumulation over time is a loop over blocks rather than an ``apply_ufunc``
over ``time``: its state, the carried samples and the running sums, crosses chunk borders, which
``dask="parallelized"`` cannot express; the per-frequency division is the ``apply_ufunc``.)

Impact tests (``excitation="impact"``): every record is one hit. Each hit is checked before use
(overload, double impact, weak force); rejected hits are listed with their reason in
``hit_rejected`` / ``hit_reject_reason`` and left out. The force channel gets a force (transient)
window times the exponential window, the responses the exponential window. Applying the
exponential window to the force as well makes the result exact: ``(h * f) e^(-beta t) =
(h e^(-beta t)) * (f e^(-beta t))``, so the estimated FRF is that of the system with every
eigenvalue shifted by ``-beta``. ``beta`` is stored as ``exponential_window_decay`` (1/s) and
identification adds it back.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr._coords import range_axis
from ami_xr._provenance import add_history
from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import impact as _ki
from ami_xr.kernels import spectral as _ks
from ami_xr.kernels import windows as _kw
from ami_xr.dsp.spectral import WelchAccumulator, check_segments, resolve_window

EXCITATIONS = ("random", "impact")
QUANTITIES = tuple(names.QUANTITY_TO_FRF_TYPE)
_POWER = {"displacement": 0, "velocity": 1, "acceleration": 2}
_REF2 = "reference_2"  # private second reference dim of the force cross-spectral matrix
_G = 9.80665  # m/s^2 per g


# --- input checks -------------------------------------------------------------------------------


def _sampling_rate(t: xr.DataArray, argument: str, block: int = 2**20) -> float:
    """1 / dt of a uniform time coordinate, checked block by block (no record-sized temporaries)."""
    n = t.size
    if t.ndim != 1 or n < 2:
        raise AmiXrValueError(f"{argument}: expected a 1-D time coordinate of >= 2 samples")
    axis = range_axis(t, names.TIME)
    if axis is not None:  # RangeIndex (a lazily opened file): uniform by construction, no reads
        return _check_rate(axis.step, axis.step, axis.step, math.isfinite(axis.start), argument)
    t0, t1 = (float(v) for v in np.asarray(t[[0, -1]].values, np.float64))
    dt = (t1 - t0) / (n - 1)
    lo, hi, finite = np.inf, -np.inf, math.isfinite(dt)
    for a in range(0, n - 1, block):
        part = np.asarray(t[a : a + block + 1].values, np.float64)
        step = np.diff(part)
        finite = finite and bool(np.all(np.isfinite(part)))
        lo, hi = min(lo, float(step.min())), max(hi, float(step.max()))
    return _check_rate(dt, lo, hi, finite, argument)


def _check_rate(dt: float, lo: float, hi: float, finite: bool, argument: str) -> float:
    """1 / dt after checking the steps (smallest ``lo``, largest ``hi``) are uniform."""
    finite = finite and math.isfinite(dt)
    if not finite or dt <= 0 or max(hi - dt, dt - lo) > 1e-6 * dt:
        raise AmiXrValueError(
            f"{argument}: expected uniformly spaced, increasing sample times (one sampling rate); "
            f"steps range from {lo!r} to {hi!r} s. Force and response sampled at different "
            "rates must be resampled to one time axis first"
        )
    return 1.0 / dt


def _is_lazy(da: xr.DataArray) -> bool:
    return da.chunks is not None


def _check_finite_now(da: xr.DataArray, argument: str) -> None:
    if not _is_lazy(da) and not np.all(np.isfinite(da.values)):
        bad = int(np.size(da.values) - np.count_nonzero(np.isfinite(da.values)))
        raise AmiXrValueError(f"{argument}: contains {bad} NaN or inf samples")


def _signals(ds: Any, force: xr.DataArray | None, fs: float | None):
    """Check the time Dataset and return (force, response, fs) as DataArrays
    force ([record,] [reference,] time), response ([record,] point, time)."""
    if not isinstance(ds, xr.Dataset):
        raise AmiXrValueError(
            f"ds: expected a time Dataset (xarray.Dataset), got {type(ds).__name__}"
        )
    if names.RESPONSE not in ds.data_vars:
        raise AmiXrValueError(
            f"ds: has no {names.RESPONSE!r} variable (response histories with dims "
            f"([record,] point, time)); has {sorted(map(str, ds.data_vars))}"
        )
    y = ds[names.RESPONSE]
    if (
        names.POINT not in y.dims
        or names.TIME not in y.dims
        or not set(y.dims) <= {names.RECORD, names.POINT, names.TIME}
    ):
        raise AmiXrValueError(f"response: expected dims ([record,] point, time), got {y.dims}")
    if force is None:
        if names.FORCE not in ds.data_vars:
            raise AmiXrValueError(
                f"force: the time Dataset has no {names.FORCE!r} variable (the measured force "
                "channel), which FRF estimation needs; impulse responses to a unit impulse go "
                "through ami_xr.impulse_to_frf instead"
            )
        f = ds[names.FORCE]
    else:
        if not isinstance(force, xr.DataArray):
            raise AmiXrValueError(
                f"force: expected an xarray.DataArray, got {type(force).__name__}"
            )
        f = force
    if names.TIME not in f.dims or not set(f.dims) <= {names.RECORD, names.REFERENCE, names.TIME}:
        raise AmiXrValueError(f"force: expected dims ([record,] [reference,] time), got {f.dims}")
    if f.sizes[names.TIME] != y.sizes[names.TIME]:
        raise AmiXrValueError(
            f"force: has {f.sizes[names.TIME]} samples but response has {y.sizes[names.TIME]}; "
            "force and response must be recorded over the same samples"
        )
    if (names.RECORD in f.dims) != (names.RECORD in y.dims) or (
        names.RECORD in f.dims and f.sizes[names.RECORD] != y.sizes[names.RECORD]
    ):
        raise AmiXrValueError(
            f"force: expected the same records as response, got dims {f.dims} with sizes "
            f"{dict(f.sizes)} against {dict(y.sizes)}"
        )
    # sampling rates: from the time coordinates, which must agree with each other and with fs
    rates = {}
    pairs = (("response", y), ("force", f)) if force is not None else (("response", y),)
    for argument, da in pairs:  # force from ds shares the response's time coordinate
        if names.TIME in da.coords:
            rates[argument] = _sampling_rate(
                da[names.TIME], f"{argument}.time" if force is not None else "time"
            )
    if "response" in rates and "force" in rates:
        if not math.isclose(rates["response"], rates["force"], rel_tol=1e-6):
            raise AmiXrValueError(
                f"force: sampled at {rates['force']:.9g} Hz but response at "
                f"{rates['response']:.9g} Hz; resample to one rate first"
            )
    coord_fs = rates.get("response", rates.get("force"))
    if fs is not None:
        if (
            isinstance(fs, bool)
            or not isinstance(fs, (int, float, np.number))
            or not (math.isfinite(fs) and fs > 0)
        ):
            raise AmiXrValueError(f"fs: expected a positive sampling rate in Hz, got {fs!r}")
        if coord_fs is not None and not math.isclose(float(fs), coord_fs, rel_tol=1e-6):
            raise AmiXrValueError(
                f"fs: given {fs!r} Hz but the time coordinate is sampled at {coord_fs:.9g} Hz"
            )
        coord_fs = float(fs)
    if coord_fs is None:
        raise AmiXrValueError("fs: the Dataset has no time coordinate; give fs (Hz)")
    _check_finite_now(y, "response")
    _check_finite_now(f, "force")
    # canonical layouts: force (record, reference, time), response (record, point, time)
    if names.RECORD not in y.dims:
        y = y.expand_dims(names.RECORD)
        f = f.expand_dims(names.RECORD)
    if names.REFERENCE not in f.dims:
        f = f.expand_dims(names.REFERENCE, axis=1)
    f = f.transpose(names.RECORD, names.REFERENCE, names.TIME)
    y = y.transpose(names.RECORD, names.POINT, names.TIME)
    return f, y, float(coord_fs)


def _choice(value, allowed, argument):
    if not isinstance(value, str) or value not in allowed:
        raise AmiXrValueError(f"{argument}: expected one of {allowed}, got {value!r}")
    return value


# --- impact hit checks ---------------------------------------------------------------------------


def check_hits(
    force: np.ndarray,
    response: np.ndarray,
    *,
    overload_samples: int = 3,
    double_impact_threshold: float = 0.1,
    min_force: float | None = None,
    weak_force_ratio: float = 0.1,
    min_snr: float = 10.0,
    point_labels: list | None = None,
) -> tuple[np.ndarray, list[str], np.ndarray, np.ndarray]:
    """Check impact hits; return (rejected, reasons, peak force, pulse (start, end) samples).

    ``force`` (hit, reference, time) and ``response`` (hit, point, time). A hit is rejected for

    * overload: some channel has ``overload_samples`` or more consecutive samples equal to its
      maximum or minimum (the converter's limit code, i.e. clipping);
    * double impact: a second force pulse, i.e. ``|f|`` above ``double_impact_threshold`` times
      the peak again after the first pulse has ended (quiet for at least the pulse's length);
    * weak force: peak ``|f|`` below ``min_force``, or below ``weak_force_ratio`` times the median
      peak of the hits, or below ``min_snr`` times the force noise (1.4826 * MAD of the hit).
    """
    nrec, nref, nt = force.shape
    labels = point_labels if point_labels is not None else list(range(response.shape[1]))
    reasons: list[list[str]] = [[] for _ in range(nrec)]
    # overload, per channel
    runs_f = _ki.extreme_run(force.reshape(nrec * nref, nt)).reshape(nrec, nref)
    runs_y = _ki.extreme_run(response.reshape(-1, nt)).reshape(nrec, -1)
    for r in range(nrec):
        for i in np.flatnonzero(runs_f[r] >= overload_samples):
            peak = force[r, i][np.argmax(np.abs(force[r, i]))]
            reasons[r].append(
                f"overload: force{'' if nref == 1 else f' {i}'} clipped at {peak:.6g} "
                f"({runs_f[r, i]} equal samples at its extreme)"
            )
        for p in np.flatnonzero(runs_y[r] >= overload_samples):
            peak = response[r, p][np.argmax(np.abs(response[r, p]))]
            reasons[r].append(
                f"overload: response at point {labels[p]!r} clipped at {peak:.6g} "
                f"({runs_y[r, p]} equal samples at its extreme)"
            )
    # force pulses (first force channel: the hammer)
    f0 = np.ascontiguousarray(force[:, 0, :])
    peak = np.max(np.abs(f0), axis=1)
    thr = double_impact_threshold * peak
    # quiet gap needed to call a new pulse: the first pulse's own length (at least 3 samples)
    first = _ki.force_pulses(f0, thr, 3)
    pulses = np.empty_like(first)
    for r in range(nrec):
        gap = max(3, int(first[r, 2] - first[r, 1] + 1))
        pulses[r] = _ki.force_pulses(f0[r : r + 1], thr[r : r + 1], gap)[0]
    overloaded = np.array([any(s.startswith("overload") for s in reasons[r]) for r in range(nrec)])
    clean_peaks = peak[~overloaded] if np.any(~overloaded) else peak
    median_peak = float(np.median(clean_peaks))
    noise = 1.4826 * np.median(np.abs(f0 - np.median(f0, axis=1, keepdims=True)), axis=1)
    for r in range(nrec):
        if pulses[r, 0] >= 2:
            delay = pulses[r, 3] - pulses[r, 1]
            reasons[r].append(
                f"double impact: a second force pulse {delay} samples after the first "
                f"(|force| > {double_impact_threshold:g} x peak again)"
            )
        if min_force is not None and peak[r] < min_force:
            reasons[r].append(f"force too weak: peak {peak[r]:.4g} < min_force={min_force:g}")
        elif nrec > 1 and peak[r] < weak_force_ratio * median_peak:
            reasons[r].append(
                f"force too weak: peak {peak[r]:.4g} < {weak_force_ratio:g} x the median peak "
                f"{median_peak:.4g} of the hits"
            )
        elif noise[r] > 0 and peak[r] < min_snr * noise[r]:
            reasons[r].append(
                f"force too weak: peak {peak[r]:.4g} < {min_snr:g} x the force noise {noise[r]:.3g}"
            )
    rejected = np.array([bool(x) for x in reasons])
    return rejected, ["; ".join(x) for x in reasons], peak, pulses[:, 1:3]


# --- the estimator -------------------------------------------------------------------------------


def _blocks(n: int, da: xr.DataArray, chunk_samples: int | None) -> list[tuple[int, int]]:
    """Time blocks: the dask chunks of ``da`` (or ``chunk_samples``), else the whole record."""
    if chunk_samples is not None:
        size = int(chunk_samples)
    elif _is_lazy(da):
        edges = np.cumsum((0,) + tuple(da.chunks[da.get_axis_num(names.TIME)]))
        return list(zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True))
    else:
        size = n
    return [(a, min(a + size, n)) for a in range(0, n, size)]


def _load(da: xr.DataArray, r: int, a: int, b: int, argument: str) -> np.ndarray:
    block = np.asarray(da.isel({names.RECORD: r, names.TIME: slice(a, b)}).values, np.float64)
    if _is_lazy(da) and not np.all(np.isfinite(block)):
        raise AmiXrValueError(
            f"{argument}: contains NaN or inf samples (record {r}, samples {a}..{b - 1})"
        )
    return block


def _feed_all(acc: WelchAccumulator, f_da, y_da, records, blocks) -> None:
    """Feed every block of every used record. A lazy Dataset's next block is read in a
    background thread while this one is processed (reads and the nogil kernels overlap); at
    most two blocks are in memory."""
    jobs = [(int(r), a, b) for r in records for a, b in blocks]

    def load(job):
        r, a, b = job
        return _load(f_da, r, a, b, "force"), _load(y_da, r, a, b, "response")

    def run(next_block):
        for i, (_, a, _) in enumerate(jobs):
            if a == 0 and i > 0:
                acc.end_record()  # segments never span two records
            acc.feed(*next_block(i))

    if not (_is_lazy(f_da) or _is_lazy(y_da)) or len(jobs) < 2:
        run(lambda i: load(jobs[i]))
        return
    with ThreadPoolExecutor(max_workers=1) as pool:
        pending = {0: pool.submit(load, jobs[0])}

        def next_block(i):
            data = pending.pop(i).result()
            if i + 1 < len(jobs):
                pending[i + 1] = pool.submit(load, jobs[i + 1])
            return data

        try:
            run(next_block)
        finally:
            for fut in pending.values():
                fut.cancel()


def _frf_kernel(gff, gfy, gyy, estimator):
    """apply_ufunc core: (ref, ref2, f), (ref, point, f), (point, f) -> H, coherence."""
    return _ks.frf_from_spectra(gff, gfy, gyy, estimator)


def frf(
    ds: xr.Dataset,
    estimator: str = "H1",
    *,
    force: xr.DataArray | None = None,
    fs: float | None = None,
    window: str | np.ndarray | None = None,
    nperseg: int | None = None,
    noverlap: int | None = None,
    nfft: int | None = None,
    detrend: str | bool | None = None,
    average: str = "linear",
    n_average: int = 8,
    excitation: str = "random",
    force_window: float | None = None,
    exponential_decay: float | None = None,
    exponential_end_value: float | None = None,
    hit_checks: bool = True,
    overload_samples: int = 3,
    double_impact_threshold: float = 0.1,
    min_force: float | None = None,
    weak_force_ratio: float = 0.1,
    chunk_samples: int | None = None,
    workers: int = 1,
    path: str | None = None,
) -> xr.Dataset:
    """Estimate FRFs (H1, H2 or Hv) and coherence from force and response time histories.

    Parameters
    ----------
    ds : xarray.Dataset
        Time Dataset: ``response`` ([record,] point, time), ``force`` ([record,] [reference,]
        time), ``time`` coordinate in s (uniform). May be dask-backed (opened lazily with
        :func:`ami_xr.open_dataset`); it is then read one time chunk at a time.
    estimator : {"H1", "H2", "Hv"}
        ``H1 = Gfy/Gff`` (unbiased by output noise), ``H2 = Gyy/Gyf`` (unbiased by input noise),
        ``Hv`` total least squares (between them). Several force channels: H1 only (MIMO).
    force : xarray.DataArray, optional
        Force histories recorded separately (replaces ``ds.force``); must have the same samples
        and sampling rate as the responses.
    fs : float, optional
        Sampling rate in Hz; checked against the time coordinate when both are present.
    window : str or ndarray, optional
        Welch window (random excitation): a name known to
        :func:`ami_xr.kernels.windows.get_window` or an array of ``nperseg`` samples; default
        ``"hann"``. Not used for impact tests (see ``force_window`` and ``exponential_*``).
    nperseg, noverlap, nfft : int, optional
        Segment length (default 256 samples for random excitation, the whole record for impact),
        overlap (default ``nperseg // 2``, impact 0) and FFT length (default ``nperseg``).
    detrend : {"constant", "linear", "none"} or False, optional
        Removed from each segment before windowing; default "constant" (random) or "none" (impact).
    average : {"linear", "exponential"}
        Linear: plain mean over all segments (hits). Exponential: running average with time
        constant ``n_average`` segments (linear over the first ``n_average``).
    n_average : int
        Time constant of exponential averaging, in segments.
    excitation : {"random", "impact"}
        ``"impact"``: every record is one hammer hit; hits are checked and rejected hits left out.
    force_window : float, optional
        Impact: width in s of the force window (1 from the record start to here, then a short
        half-cosine taper). Default: the end of the latest first force pulse of the accepted hits
        plus that pulse's length.
    exponential_decay, exponential_end_value : float, optional
        Impact: exponential window on force and response, by decay rate (1/s) or value at the
        record end; at most one. Default none. Stored as ``exponential_window_decay``.
    hit_checks : bool
        Impact: check hits (see :func:`check_hits`); False uses every hit.
    overload_samples, double_impact_threshold, min_force, weak_force_ratio
        Impact hit-check thresholds (see :func:`check_hits`).
    chunk_samples : int, optional
        Samples per block read from a lazy Dataset (default: its dask chunks along ``time``).
    workers : int
        Threads of ``scipy.fft``.
    path : str, optional
        Also write the result there (atomically, with :func:`ami_xr.to_netcdf`).

    Returns
    -------
    xarray.Dataset
        FRF Dataset: ``frf`` ([reference,] point, frequency) complex, ``coherence`` (point,
        frequency), ``force_autospectrum`` ([reference,] frequency), ``response_autospectrum``
        (point, frequency), ``cross_spectrum`` ([reference,] point, frequency) (one-sided
        densities), attrs ``frf_source="estimated"``, ``estimator``, ``n_averages``; impact:
        ``hit_rejected``, ``hit_reject_reason``, ``hit_peak_force`` (record) and, with an
        exponential window, ``exponential_window_decay`` (1/s).

    Raises
    ------
    AmiXrValueError
        Bad input, each naming the argument: missing force, different lengths or sampling
        rates, NaN samples, ``nperseg`` longer than the record, ``noverlap >= nperseg``, unknown
        window, estimator, detrend or average; every hit rejected.
    """
    code = _ks.estimator_code(estimator)
    estimator = _ks.ESTIMATORS[code - 1]
    excitation = _choice(excitation, EXCITATIONS, "excitation")
    average = _choice(average, ("linear", "exponential"), "average")
    if average == "exponential" and (
        isinstance(n_average, bool) or not isinstance(n_average, (int, np.integer)) or n_average < 1
    ):
        raise AmiXrValueError(f"n_average: expected an integer >= 1, got {n_average!r}")
    f_da, y_da, fs = _signals(ds, force, fs)
    nrec, nref, nt = f_da.shape
    npt = y_da.sizes[names.POINT]
    if estimator != "H1" and nref > 1:
        raise AmiXrValueError(
            f"estimator: {estimator!r} needs a single force channel, got {nref} along "
            f"{names.REFERENCE!r}; use 'H1'"
        )
    impact = excitation == "impact"
    if detrend is None:
        detrend = "none" if impact else "constant"
    _ks.detrend_code(detrend)
    if nperseg is None:
        nperseg = nt if impact else min(256, nt)
    if noverlap is None and impact:
        noverlap = 0
    nperseg, noverlap, nfft = check_segments(nt, nperseg, noverlap, nfft)
    if chunk_samples is not None and (
        isinstance(chunk_samples, bool)
        or not isinstance(chunk_samples, (int, np.integer))
        or chunk_samples < 1
    ):
        raise AmiXrValueError(f"chunk_samples: expected an integer >= 1, got {chunk_samples!r}")
    labels = list(y_da[names.POINT].values) if names.POINT in y_da.coords else list(range(npt))

    extra: dict[str, Any] = {}
    use = np.ones(nrec, bool)
    attrs_extra: dict[str, Any] = {}
    if impact:
        if window is not None:
            raise AmiXrValueError(
                "window: not used with excitation='impact' (the force gets a force window, "
                "both channels the exponential window); use force_window and exponential_decay "
                "or exponential_end_value"
            )
        if force_window is not None and not (
            isinstance(force_window, (int, float, np.number)) and force_window > 0
        ):
            raise AmiXrValueError(f"force_window: expected a width in s > 0, got {force_window!r}")
        beta = None
        if exponential_decay is not None or exponential_end_value is not None:
            beta = _kw.exponential_decay_rate(
                nperseg, fs=fs, decay=exponential_decay, end_value=exponential_end_value
            )
        fv = np.stack([_load(f_da, r, 0, nt, "force") for r in range(nrec)])
        yv = np.stack([_load(y_da, r, 0, nt, "response") for r in range(nrec)])
        if hit_checks:
            rejected, reasons, peak, pulse = check_hits(
                fv,
                yv,
                overload_samples=overload_samples,
                double_impact_threshold=double_impact_threshold,
                min_force=min_force,
                weak_force_ratio=weak_force_ratio,
                point_labels=labels,
            )
        else:
            rejected = np.zeros(nrec, bool)
            reasons = [""] * nrec
            peak = np.max(np.abs(fv[:, 0]), axis=1)
            pulse = _ki.force_pulses(
                np.ascontiguousarray(fv[:, 0]), double_impact_threshold * peak, 3
            )[:, 1:3]
        del fv, yv
        if rejected.all():
            lines = "; ".join(f"hit {r}: {reasons[r]}" for r in range(nrec))
            raise AmiXrValueError(f"ds: every impact hit was rejected ({lines})")
        use = ~rejected
        rec_dim = names.RECORD
        rec_coord = ds[names.RECORD].values if names.RECORD in ds.coords else np.arange(nrec)
        extra[names.HIT_REJECTED] = xr.DataArray(
            rejected, dims=[rec_dim], coords={rec_dim: rec_coord}
        )
        extra[names.HIT_REJECT_REASON] = xr.DataArray(
            np.array(reasons, dtype=str), dims=[rec_dim], coords={rec_dim: rec_coord}
        )
        extra[names.HIT_PEAK_FORCE] = xr.DataArray(
            peak,
            dims=[rec_dim],
            coords={rec_dim: rec_coord},
            attrs={names.ATTR_UNITS: ds.attrs.get(names.ATTR_FORCE_UNITS, "")},
        )
        # force window: default covers the first pulse of every accepted hit plus its length
        if force_window is None:
            ends = pulse[use, 1]
            lengths = pulse[use, 1] - pulse[use, 0] + 1
            width = int(min(nperseg, max(1, ends.max() + 1 + lengths.max())))
        else:
            width = int(min(nperseg, max(1, round(float(force_window) * fs))))
        wf = _kw.get_window("force", nperseg, width=width)
        if beta is not None:
            we = _kw.get_window("exponential", nperseg, fs=fs, decay=beta)
            # a window already applied to the time data (ami_xr.apply_window) adds up
            attrs_extra[names.ATTR_EXP_DECAY] = float(beta) + float(
                ds.attrs.get(names.ATTR_EXP_DECAY, 0.0) or 0.0
            )
        else:
            we = np.ones(nperseg)
        force_w, response_w = wf * we, we
        attrs_extra[names.ATTR_FORCE_WINDOW_WIDTH] = width / fs
        window_label = "force*exponential" if names.ATTR_EXP_DECAY in attrs_extra else "force"
    else:
        for arg, val in (
            ("force_window", force_window),
            ("exponential_decay", exponential_decay),
            ("exponential_end_value", exponential_end_value),
        ):
            if val is not None:
                raise AmiXrValueError(f"{arg}: only used with excitation='impact'")
        window = "hann" if window is None else window
        response_w = force_w = resolve_window(window, nperseg)
        window_label = window if isinstance(window, str) else "array"

    acc = WelchAccumulator(
        nref,
        npt,
        fs=fs,
        nperseg=nperseg,
        noverlap=noverlap,
        nfft=nfft,
        force_window=force_w,
        response_window=response_w,
        detrend=detrend,
        average=average,
        n_average=n_average,
        workers=workers,
    )
    _feed_all(acc, f_da, y_da, np.flatnonzero(use), _blocks(nt, y_da, chunk_samples))
    gff, gfy, gyy = acc.spectra()
    freq = acc.frequency

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
        kwargs={"estimator": estimator},
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
    ru = ds.attrs.get(names.ATTR_RESPONSE_UNITS, y_da.attrs.get(names.ATTR_UNITS, ""))
    fu = ds.attrs.get(names.ATTR_FORCE_UNITS, f_da.attrs.get(names.ATTR_UNITS, ""))
    gff_diag = xr.DataArray(np.real(np.einsum("iik->ik", gff)), dims=[names.REFERENCE, fdim])
    siso = names.REFERENCE not in (force if force is not None else ds[names.FORCE]).dims
    if siso:
        H, Gfy, gff_diag = (
            H.isel({names.REFERENCE: 0}),
            Gfy.isel({names.REFERENCE: 0}),
            gff_diag.isel({names.REFERENCE: 0}),
        )
    out = xr.Dataset(
        {
            names.FRF: H.assign_attrs({names.ATTR_UNITS: names.frf_units(ru, fu)}),
            names.COHERENCE: coh.assign_attrs({names.ATTR_UNITS: "1"}),
            names.FORCE_AUTOSPECTRUM: gff_diag.assign_attrs({names.ATTR_UNITS: f"{fu}^2/Hz"}),
            names.RESPONSE_AUTOSPECTRUM: Gyy.assign_attrs({names.ATTR_UNITS: f"({ru})^2/Hz"}),
            names.CROSS_SPECTRUM: Gfy.assign_attrs({names.ATTR_UNITS: f"{fu}*{ru}/Hz"}),
            **extra,
        },
        coords={
            names.POINT: labels,
            fdim: (fdim, freq, {names.ATTR_UNITS: names.FREQUENCY_UNITS}),
            **({} if siso else {names.REFERENCE: ref_coord}),
        },
    )
    out = out.transpose(
        *[d for d in (names.REFERENCE, names.POINT, fdim, names.RECORD) if d in out.dims]
    )
    quantity = ds.attrs.get(names.ATTR_QUANTITY)
    attrs = {k: ds.attrs[k] for k in (names.ATTR_DRIVE_POINT, names.ATTR_QUANTITY) if k in ds.attrs}
    if quantity in names.QUANTITY_TO_FRF_TYPE:
        attrs[names.ATTR_FRF_TYPE] = names.QUANTITY_TO_FRF_TYPE[quantity]
    if names.ATTR_EXP_DECAY in ds.attrs and names.ATTR_EXP_DECAY not in attrs_extra:
        attrs[names.ATTR_EXP_DECAY] = ds.attrs[names.ATTR_EXP_DECAY]
    attrs.update(
        {
            names.ATTR_RESPONSE_UNITS: ru,
            names.ATTR_FORCE_UNITS: fu,
            names.ATTR_SOURCE: names.SOURCE_ESTIMATED,
            names.ATTR_ESTIMATOR: estimator,
            names.ATTR_N_AVERAGES: int(acc.count),
            **attrs_extra,
        }
    )
    for key in (names.ATTR_HISTORY, names.ATTR_VERSION, names.ATTR_SOURCE_FILE):
        if key in ds.attrs:
            attrs[key] = ds.attrs[key]
    out.attrs = attrs
    params = {
        "estimator": estimator,
        "fs": fs,
        "window": window_label,
        "nperseg": nperseg,
        "noverlap": noverlap,
        "nfft": nfft,
        "detrend": detrend,
        "average": average,
        "n_average": n_average,
        "excitation": excitation,
        "n_records_used": int(use.sum()),
        **attrs_extra,
    }
    out = add_history(out, "ami_xr.frf", params)
    if path is not None:
        from ami_xr.io.netcdf import to_netcdf

        to_netcdf(out, path, function="ami_xr.frf", parameters=params)
    return out


# --- receptance / mobility / accelerance -------------------------------------------------------


def _convert_units(units: str, k_from: int, k_to: int) -> tuple[str, float]:
    """Response units after converting by ``(i w)^(k_to - k_from)``, and a scale (g -> m/s^2)."""
    scale = 1.0
    base = units
    if k_from == 2 and units == "g":
        base, scale = "m", _G
    else:
        suffix = ("", "/s", "/s^2")[k_from]
        if suffix and units.endswith(suffix):
            base = units[: -len(suffix)]
        elif suffix:
            raise AmiXrValueError(
                f"response_units: cannot convert {units!r} (expected units ending in {suffix!r})"
            )
    return base + ("", "/s", "/s^2")[k_to], scale


def convert_quantity(ds: xr.Dataset, to: str, *, dc: str = "nan") -> xr.Dataset:
    """Convert an FRF Dataset between receptance, mobility and accelerance.

    The FRF is multiplied by ``(i w)^k`` with ``k`` the difference of the derivative orders
    (displacement 0, velocity 1, acceleration 2); ``cross_spectrum`` and
    ``response_autospectrum`` follow (times ``(i w)^k`` and ``w^(2k)``).

    Parameters
    ----------
    ds : xarray.Dataset
        FRF Dataset with ``response_quantity`` and ``response_units`` attributes (units ending in
        ``"/s"`` or ``"/s^2"`` for velocity and acceleration; ``"g"`` is converted to m/s^2).
    to : {"displacement", "velocity", "acceleration"}
        Target response quantity (receptance, mobility, accelerance).
    dc : {"nan", "zero", "drop"}
        What integration (``k < 0``) does at 0 Hz, where dividing by ``i w`` is undefined: NaN,
        0, or drop the 0 Hz line. Differentiation gives 0 there.

    Returns
    -------
    xarray.Dataset
        A new Dataset. An FRF made from a sampled impulse response (``frf_source =
        "impulse_response"``) is no longer ``dt * DFT`` of a sampled impulse response after the
        conversion, so it becomes ``"measured"`` and loses ``sample_interval``/``record_samples``.
    """
    if not isinstance(ds, xr.Dataset) or names.FRF not in ds.data_vars:
        raise AmiXrValueError("ds: expected an FRF Dataset with an 'frf' variable")
    to = _choice(to, QUANTITIES, "to")
    dc = _choice(dc, ("nan", "zero", "drop"), "dc")
    src = ds.attrs.get(names.ATTR_QUANTITY)
    if src not in _POWER:
        raise AmiXrValueError(
            f"ds: attribute {names.ATTR_QUANTITY!r} must be one of {QUANTITIES}, got {src!r}"
        )
    k = _POWER[to] - _POWER[src]
    ru = ds.attrs.get(names.ATTR_RESPONSE_UNITS, "")
    new_units, scale = _convert_units(ru, _POWER[src], _POWER[to])
    f = ds[names.FREQUENCY]
    iw = xr.DataArray(2j * np.pi * f.values, dims=[names.FREQUENCY])
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = scale * iw**k if k >= 0 else scale / iw ** (-k)
    if k < 0:
        at0 = f.values == 0
        factor = factor.where(
            ~xr.DataArray(at0, dims=[names.FREQUENCY]), np.nan if dc == "nan" else 0.0
        )
    out = ds.copy()
    out[names.FRF] = ds[names.FRF] * factor
    fu = ds.attrs.get(names.ATTR_FORCE_UNITS, "")
    out[names.FRF].attrs = {**ds[names.FRF].attrs, names.ATTR_UNITS: names.frf_units(new_units, fu)}
    if names.CROSS_SPECTRUM in ds:
        out[names.CROSS_SPECTRUM] = ds[names.CROSS_SPECTRUM] * factor
        out[names.CROSS_SPECTRUM].attrs = {names.ATTR_UNITS: f"{fu}*{new_units}/Hz"}
    if names.RESPONSE_AUTOSPECTRUM in ds:
        out[names.RESPONSE_AUTOSPECTRUM] = ds[names.RESPONSE_AUTOSPECTRUM] * np.abs(factor) ** 2
        out[names.RESPONSE_AUTOSPECTRUM].attrs = {names.ATTR_UNITS: f"({new_units})^2/Hz"}
    out.attrs = dict(ds.attrs)
    out.attrs[names.ATTR_QUANTITY] = to
    out.attrs[names.ATTR_FRF_TYPE] = names.QUANTITY_TO_FRF_TYPE[to]
    out.attrs[names.ATTR_RESPONSE_UNITS] = new_units
    if out.attrs.get(names.ATTR_SOURCE) == names.SOURCE_IMPULSE and k != 0:
        out.attrs[names.ATTR_SOURCE] = names.SOURCE_MEASURED
        out.attrs.pop(names.ATTR_DT, None)
        out.attrs.pop(names.ATTR_NSAMPLES, None)
    if k < 0 and dc == "drop":
        out = out.sel({names.FREQUENCY: f.values[f.values > 0]})
    return add_history(out, "ami_xr.convert_quantity", {"to": to, "dc": dc, "from": src})
