"""Checks of the time Datasets that FRF estimation reads: signals, sampling rate, finite samples."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.coords import range_axis
from ami_xr.errors import AmiXrValueError


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


def is_lazy(da: xr.DataArray) -> bool:
    """Whether ``da`` is dask-backed (read block by block)."""
    return da.chunks is not None


def _check_finite_now(da: xr.DataArray, argument: str) -> None:
    if not is_lazy(da) and not np.all(np.isfinite(da.values)):
        bad = int(np.size(da.values) - np.count_nonzero(np.isfinite(da.values)))
        raise AmiXrValueError(f"{argument}: contains {bad} NaN or inf samples")


def force_and_response(
    ds: Any, force: xr.DataArray | None, fs: float | None
) -> tuple[xr.DataArray, xr.DataArray, float]:
    """Check a time Dataset for FRF estimation; return ``(force, response, fs)``.

    ``force`` is ``ds.force`` unless given separately. Checks dims, equal lengths, one uniform
    sampling rate (agreeing with ``fs`` where both are given) and finite samples (those in
    memory; lazy blocks are checked as they are read). The DataArrays come back in canonical
    layout: force (record, reference, time), response (record, point, time).
    """
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


#: Samples of the first record that :func:`excitation_of` looks at (bounded: a lazily opened
#: file is read only this far), the level that counts as "force on" (fraction of the peak) and
#: the largest fraction of samples above it that still counts as a pulse.
PULSE_PROBE_SAMPLES = 2**16
PULSE_LEVEL = 0.1
PULSE_MAX_FRACTION = 0.05


def excitation_of(ds: Any) -> str:
    """``"impact"`` when the force of ``ds`` is a short pulse (hammer hits), else ``"random"``.

    The one rule that decides the excitation where the user did not say it: the CLI's
    ``--excitation auto``, :func:`ami_xr.dsp.frf.frf_from_options` without an ``excitation``
    and the warning of :func:`ami_xr.frf` on hammer data all call it, so Python and the command
    line treat a file alike.

    Rule: in the first record (its first :data:`PULSE_PROBE_SAMPLES` samples, first reference),
    after removing the median (a DC offset), fewer than :data:`PULSE_MAX_FRACTION` (5 %) of the
    samples exceed :data:`PULSE_LEVEL` (10 %) of the largest. A hammer hit is above that level
    for well under 1 % of a record (the shared hammer file: 0.006-0.06 %); random, burst-random
    or periodic-chirp force for tens of percent (Gaussian noise: about 70 %). The force itself
    decides, not a ``record`` dim: separate records can be blocks of a random test, and a single
    record can be one hit. A Dataset without a usable force is ``"random"`` (the estimator then
    reports what is missing).
    """
    if not isinstance(ds, xr.Dataset) or names.FORCE not in ds.data_vars:
        return "random"
    f = ds[names.FORCE]
    if names.TIME not in f.dims:
        return "random"
    f = f.isel({d: 0 for d in f.dims if d != names.TIME})
    x = np.asarray(f.isel({names.TIME: slice(0, PULSE_PROBE_SAMPLES)}).values, np.float64)
    x = x[np.isfinite(x)]
    if x.size < 16:
        return "random"
    x = np.abs(x - np.median(x))
    peak = float(x.max())
    if not peak > 0:
        return "random"
    return "impact" if np.mean(x > PULSE_LEVEL * peak) < PULSE_MAX_FRACTION else "random"
