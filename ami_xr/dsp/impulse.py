"""FRFs from sampled impulse responses (the paper's processing): ``impulse_to_frf``."""

from __future__ import annotations

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.dsp.windows import (
    ATTR_AMPLITUDE_CORRECTION,
    ATTR_ENERGY_CORRECTION,
    ATTR_WINDOW,
    ATTR_WINDOW_PARAMETERS,
    sample_interval,
    window_and_record,
    window_attrs,
)
from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import fft as _kfft
from ami_xr.kernels import windows as _kw
from ami_xr.provenance import add_history
from ami_xr.schema import validate

_WINDOW_ATTRS = (
    ATTR_WINDOW,
    ATTR_WINDOW_PARAMETERS,
    ATTR_AMPLITUDE_CORRECTION,
    ATTR_ENERGY_CORRECTION,
)


def _frf_block(y, *force, dt, window):
    """Kernel call on one block: (..., n) -> (..., n // 2 + 1); ``force`` holds 0 or 1 arrays."""
    if force:
        return _kfft.frf_from_force(y, force[0], window=window, force_window=window)
    return _kfft.impulse_to_frf(y, dt, window=window)


def _is_lazy(ds: xr.Dataset) -> bool:
    return any(ds[v].chunks is not None for v in (names.RESPONSE, names.FORCE) if v in ds.data_vars)


def _check_input(ds: xr.Dataset) -> bool:
    """Raise on a Dataset impulse_to_frf cannot take; whether it has a ``force`` variable."""
    if not isinstance(ds, xr.Dataset):
        raise AmiXrValueError(
            f"ds: impulse_to_frf expects an xarray.Dataset, got {type(ds).__name__}"
        )
    validate(
        ds,
        kind="time",
        require_drive_point=names.ATTR_DRIVE_POINT in ds.attrs,
        check_values=not _is_lazy(ds),
    )
    resp = ds[names.RESPONSE]
    if set(resp.dims) != {names.POINT, names.TIME}:
        raise AmiXrValueError(
            f"{names.RESPONSE}: impulse_to_frf needs dims ({names.POINT}, {names.TIME}), got "
            f"{resp.dims}; select or average the {names.RECORD!r} dim first "
            f"(e.g. ds.isel({names.RECORD}=0))"
        )
    has_force = names.FORCE in ds.data_vars
    if has_force and ds[names.FORCE].dims != (names.TIME,):
        raise AmiXrValueError(
            f"{names.FORCE}: impulse_to_frf needs dims ({names.TIME},), got {ds[names.FORCE].dims}"
        )
    return has_force


def _window(ds: xr.Dataset, window, decay, end_value, sym: bool, dt: float, n: int):
    """The window applied before the FFT (None: none), the window attributes of ``frf`` and
    the total exponential decay (1/s; this one plus one applied before, None when neither)."""
    resp = ds[names.RESPONSE]
    w = None
    frf_attrs: dict = {k: resp.attrs[k] for k in _WINDOW_ATTRS if k in resp.attrs}
    decay_total = ds.attrs.get(names.ATTR_EXP_DECAY)
    if window is not None:
        if _kw.window_name(window) == "force":
            raise AmiXrValueError(
                "window: the force window belongs on the force record only; use "
                "apply_window(ds, 'force', width=..., variables=['force']) before impulse_to_frf"
            )
        w, record = window_and_record(
            window,
            n,
            fs=1.0 / dt,
            decay=decay,
            end_value=end_value,
            width=None,
            taper=None,
            sym=sym,
        )
        attrs = window_attrs(resp.attrs, names.RESPONSE, w, record)
        frf_attrs = {k: attrs[k] for k in _WINDOW_ATTRS}
        if record["name"] == "exponential":
            decay_total = float(decay_total or 0.0) + record["decay"]
    elif decay is not None or end_value is not None:
        raise AmiXrValueError("decay, end_value: only used with window='exponential'")
    return w, frf_attrs, decay_total


def _with_attrs(out: xr.Dataset, has_force: bool, dt: float, n: int) -> xr.Dataset:
    """``out`` with the FRF type and source attributes (and dt, N for impulse responses)."""
    quantity = out.attrs[names.ATTR_QUANTITY]
    out.attrs[names.ATTR_FRF_TYPE] = names.QUANTITY_TO_FRF_TYPE[quantity]
    if has_force:
        out.attrs[names.ATTR_SOURCE] = names.SOURCE_ESTIMATED
        out.attrs.pop(names.ATTR_DT, None)
        out.attrs.pop(names.ATTR_NSAMPLES, None)
    else:
        out.attrs[names.ATTR_SOURCE] = names.SOURCE_IMPULSE
        out.attrs[names.ATTR_DT] = dt
        out.attrs[names.ATTR_NSAMPLES] = n
    return out


def impulse_to_frf(
    ds: xr.Dataset,
    *,
    window: str | None = None,
    decay: float | None = None,
    end_value: float | None = None,
    sym: bool = False,
) -> xr.Dataset:
    """FRF Dataset from a time Dataset of impulse responses.

    Without a ``force`` variable (attribute ``excitation="unit_impulse"``) the FRF is
    ``dt * rfft(w * response)``, exactly the paper's processing: the result carries
    ``frf_source="impulse_response"``, ``sample_interval`` (dt) and ``record_samples`` (N) so an
    identification can use the exact discrete-time basis
    (:func:`ami_xr.kernels.modal_basis.mode_contribution` with ``dt`` and ``n_samples``).
    With a ``force`` variable (one measured hit, dims ``(time,)``) it is
    ``rfft(w * response) / rfft(w * force)``, ``frf_source="estimated"``, and no ``dt``/``N``
    attributes (the discrete basis does not model a measured force pulse).

    Sample 0 is taken as the instant of the impulse (``t = 0``) whatever the origin of the
    ``time`` coordinate: trim any pre-trigger first.

    Parameters
    ----------
    ds : xarray.Dataset
        Time Dataset: ``response`` dims ``(point, time)``, uniform ``time`` in s, attributes
        ``response_quantity``, ``response_units``, ``force_units`` and (optional, checked when
        present) ``drive_point``. Select or average a ``record`` dim first. May be dask-backed:
        chunks along ``point`` are kept; a ``time`` split into several chunks is rechunked to one
        (dask's ``allow_rechunk``), since the FFT needs whole records. Values are scanned for
        NaN/inf only when the data are in memory (a lazy Dataset stays lazy).
    window : str, optional
        ``"boxcar"``, ``"hann"``, ``"flattop"`` or ``"exponential"``, applied to ``response``
        (and ``force``) before the FFT; default none. For a force window on the force only, call
        :func:`ami_xr.apply_window` with ``variables=["force"]`` first.
    decay, end_value : float, optional
        Exponential window: decay rate in 1/s, or its value at the last sample in (0, 1).
    sym : bool, default False
        Cosine windows: periodic (``False``) or symmetric (``True``).

    Returns
    -------
    xarray.Dataset
        ``frf`` complex128 dims ``(point, frequency)``, units ``response_units/force_units``;
        ``frequency`` in Hz on the rfft grid ``k / (N dt)``, ``k = 0 .. N // 2``; attributes of
        ``ds`` carried over plus ``frf_type``, ``frf_source`` and, when an exponential window was
        applied here or before (Dataset attribute), ``exponential_window_decay`` (1/s, summed).
        Window attributes of ``response`` are copied to ``frf``.
    """
    has_force = _check_input(ds)
    dt = sample_interval(ds, names.TIME)
    n = int(ds.sizes[names.TIME])
    resp = ds[names.RESPONSE]
    w, frf_attrs, decay_total = _window(ds, window, decay, end_value, sym, dt, n)
    n_freq = n // 2 + 1
    inputs = [resp] + ([ds[names.FORCE]] if has_force else [])
    frf = xr.apply_ufunc(
        _frf_block,
        *inputs,
        kwargs={"dt": dt, "window": w},
        input_core_dims=[[names.TIME]] * len(inputs),
        output_core_dims=[[names.FREQUENCY]],
        exclude_dims={names.TIME},
        dask="parallelized",
        output_dtypes=[np.complex128],
        dask_gufunc_kwargs={"output_sizes": {names.FREQUENCY: n_freq}, "allow_rechunk": True},
        keep_attrs=False,
    )
    frequency = xr.DataArray(
        _kfft.rfft_frequencies(n, dt),
        dims=names.FREQUENCY,
        attrs={names.ATTR_UNITS: names.FREQUENCY_UNITS},
    )
    frf = frf.transpose(names.POINT, names.FREQUENCY).assign_coords({names.FREQUENCY: frequency})
    resp_units = ds.attrs[names.ATTR_RESPONSE_UNITS]
    force_units = ds.attrs[names.ATTR_FORCE_UNITS]
    frf.attrs = {**frf_attrs, names.ATTR_UNITS: names.frf_units(resp_units, force_units)}

    out = _with_attrs(xr.Dataset({names.FRF: frf}, attrs=dict(ds.attrs)), has_force, dt, n)
    if decay_total is not None:
        out.attrs[names.ATTR_EXP_DECAY] = float(decay_total)
    parameters = {
        "window": window,
        "decay": decay,
        "end_value": end_value,
        "sym": sym,
        "force_division": has_force,
        "sample_interval": dt,
        "record_samples": n,
    }
    return add_history(out, "impulse_to_frf", parameters)
