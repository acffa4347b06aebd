"""Constructors: build a valid FRF or time Dataset from plain arrays in one call.

:func:`make_frf_dataset` and :func:`make_time_dataset` assemble the Dataset, then check it with
:func:`ami_xr.io.schema.find_problems`; their errors name the argument (``points``) instead of
the Dataset part (coordinate ``point``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.caller import warn
from ami_xr.dsp.quantity import ATTR_QUANTITY_ASSUMED, resolve_quantity
from ami_xr.errors import AmiXrValueError, AssumptionWarning, SchemaError
from ami_xr.io.geometry import coordinate_arrays
from ami_xr.io.messages import is_positive_number, python_scalar
from ami_xr.io.schema import find_problems

__all__ = ["make_frf_dataset", "make_time_dataset", "select_reference"]


def _as_array(value: Any, argument: str) -> Any:
    """ndarray (or dask array, kept lazy) from array-like ``value``."""
    if isinstance(value, xr.DataArray):
        value = value.data
    if type(value).__module__.startswith("dask"):
        return value
    try:
        return np.asarray(value)
    except (TypeError, ValueError) as err:
        raise AmiXrValueError(f"{argument}: expected an array, got {type(value).__name__}") from err


def _labels(points: Any, n: int, argument: str = "points") -> np.ndarray:
    if points is None:
        return np.arange(n)
    labels = np.asarray(points)
    if labels.ndim != 1 or labels.shape[0] != n:
        raise AmiXrValueError(
            f"{argument}: expected {n} labels (one per point), got shape {labels.shape}"
        )
    return labels


def _std_attrs(
    drive_point: Any,
    response_quantity: str | None,
    response_units: str | None,
    force_units: str,
    frf_type: str | None = None,
    function: str = "make_frf_dataset",
) -> dict[str, Any]:
    """Standard attributes; the quantity rule of :func:`ami_xr.dsp.quantity.resolve_quantity`
    (an assumed quantity warns, at the caller of ``function``, and is recorded)."""
    quantity, units, assumed = resolve_quantity(response_quantity, frf_type, response_units)
    attrs: dict[str, Any] = {}
    if drive_point is not None:
        attrs[names.ATTR_DRIVE_POINT] = python_scalar(drive_point)
    attrs[names.ATTR_QUANTITY] = quantity
    attrs[names.ATTR_RESPONSE_UNITS] = units
    attrs[names.ATTR_FORCE_UNITS] = force_units
    if assumed is not None:
        attrs[ATTR_QUANTITY_ASSUMED] = assumed
        warn(f"{function}: {assumed}", AssumptionWarning)  # at the user's line
    return attrs


_ARGUMENTS = {
    names.FRF: "frf",
    names.RESPONSE: "response",
    names.FORCE: "force",
    names.FREQUENCY: "frequency",
    names.TIME: "time",
    names.POINT: "points",
    names.REFERENCE: "references",
    names.ATTR_DRIVE_POINT: "drive_point",
    names.ATTR_QUANTITY: "response_quantity",
    names.ATTR_RESPONSE_UNITS: "response_units",
    names.ATTR_FORCE_UNITS: "force_units",
    names.ATTR_SOURCE: "frf_source",
}


def _raise_problems(ds: xr.Dataset, kind: str, require_drive_point: bool, function: str) -> None:
    """Validate what a constructor built; messages name its arguments (:data:`_ARGUMENTS`)."""
    _, problems = find_problems(
        ds, kind, require_drive_point=require_drive_point, arguments=_ARGUMENTS
    )
    if problems:
        raise SchemaError(problems, what=f"{function} arguments")


def _frf_arrays(frf: Any, frequency: Any, references: Any) -> tuple[Any, Any]:
    """``(frf, frequency)`` as arrays of shapes that fit (a 1-D ``frf`` is one point)."""
    values = _as_array(frf, "frf")
    if values.ndim == 1:
        values = values[None, :]
    if values.ndim not in (2, 3):
        raise AmiXrValueError(
            "frf: expected shape (n_point, n_frequency), (n_frequency,) or "
            f"(n_reference, n_point, n_frequency), got {values.shape}"
        )
    if references is not None and values.ndim != 3:
        raise AmiXrValueError(
            f"references: given, but frf has shape {values.shape}; multi-reference FRFs have "
            "shape (n_reference, n_point, n_frequency)"
        )
    freq = _as_array(frequency, "frequency")
    if freq.ndim != 1 or freq.shape[0] != values.shape[-1]:
        raise AmiXrValueError(
            f"frequency: expected {values.shape[-1]} values (frf.shape[-1]), got shape {freq.shape}"
        )
    return values, freq


def make_frf_dataset(
    frf: Any,
    frequency: Any,
    points: Any = None,
    drive_point: Any = None,
    response_quantity: str | None = None,
    response_units: str | None = None,
    force_units: str = "N",
    frf_source: str = names.SOURCE_MEASURED,
    coordinates: Any = None,
    coordinate_units: str = names.COORDINATE_UNITS,
    references: Any = None,
    frf_type: str | None = None,
    **attrs: Any,
) -> xr.Dataset:
    """Build a valid FRF Dataset from plain arrays (validated; errors name the argument).

    Parameters
    ----------
    frf : array_like of complex, shape (n_point, n_frequency), (n_frequency,) or 3-D
        FRF values; a 1-D array is one point, a 3-D array ``(n_reference, n_point, n_frequency)``
        is multi-reference data (one row of FRFs per excitation location). Real input is
        rejected (not cast). A dask array stays lazy.
    frequency : array_like of float, shape (n_frequency,)
        Frequencies in Hz, non-negative and strictly increasing.
    points : array_like of int or str, optional
        Unique point labels; default ``0 .. n_point - 1``.
    drive_point : int or str, optional
        Label of the point where the force acts. ``None`` leaves the ``drive_point`` attribute
        out (AMI then leaves mode vectors unscaled).
    response_quantity : {"displacement", "velocity", "acceleration"}, optional
        Sets ``frf_type`` to receptance, mobility or accelerance. Not given (nor ``frf_type``,
        nor units that tell it): displacement is assumed, with an
        :class:`~ami_xr.errors.AssumptionWarning` and the reason in attribute
        ``response_quantity_assumed`` (as ``drive_point_assumed`` records an assumed drive
        point).
    response_units : str, optional
        One of ``names.RESPONSE_UNITS[response_quantity]``; default the SI units of the
        quantity (m, m/s, m/s^2), so ``response_quantity="velocity"`` alone means m/s.
    force_units : str
        One of ``names.FORCE_UNITS``; ``frf.attrs["units"]`` becomes
        ``"<response_units>/<force_units>"``.
    frf_source : str
        One of ``names.SOURCES``. For ``"impulse_response"`` pass ``sample_interval=dt`` and
        ``record_samples=N`` as keyword attributes; ``frequency`` must then be lines of the
        rfft grid ``k / (N * dt)`` Hz, ``0 <= k <= N // 2`` (all of them or a band).
    coordinates : array_like of shape (n_point, 2 or 3), or dict, optional
        Point coordinates (the measurement geometry): columns x, y[, z] (an (n_point,) array
        is x alone), or a dict ``{"x": ..., "y": ..., "z": ...}`` with any of the keys. Stored
        as the coordinates ``point_x``, ``point_y``, ``point_z`` on ``point``; used by
        :func:`ami_xr.plot.geometry.plot_mode_shapes`.
    coordinate_units : str
        Units of ``coordinates`` (default ``"m"``), their ``units`` attribute.
    references : array_like of int or str, optional
        Multi-reference only (3-D ``frf``): unique labels of the excitation locations, of the
        point labels' type; default ``0 .. n_reference - 1``. A reference whose label is a
        point label is that point's drive point (``drive_point`` must then be None).
    frf_type : str, optional
        Instead of (or agreeing with) ``response_quantity``: "receptance", "mobility",
        "accelerance" or a synonym ("compliance", "dynamic flexibility" = receptance;
        "admittance" = mobility; "inertance" = accelerance); stored as the canonical name.
    **attrs
        Further Dataset attributes (e.g. ``sample_interval``, ``record_samples``,
        ``exponential_window_decay``, ``title``).

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    AmiXrValueError
        Shapes that do not fit together.
    SchemaError
        Every other problem, each naming the argument.
    """
    values, freq = _frf_arrays(frf, frequency, references)
    multi = values.ndim == 3
    n_point = values.shape[-2]
    labels = _labels(points, n_point)
    geometry = (
        {} if coordinates is None else coordinate_arrays(coordinates, n_point, coordinate_units)
    )
    ref_coord = {}
    dims: tuple[str, ...] = (names.POINT, names.FREQUENCY)
    if multi:
        ref_coord = {names.REFERENCE: _labels(references, values.shape[0], "references")}
        dims = (names.REFERENCE, *dims)
    ds_attrs = _std_attrs(drive_point, response_quantity, response_units, force_units, frf_type)
    response_units = ds_attrs[names.ATTR_RESPONSE_UNITS]
    frf_type = names.QUANTITY_TO_FRF_TYPE.get(ds_attrs[names.ATTR_QUANTITY])
    if frf_type is not None:  # else the schema check names the bad quantity
        ds_attrs[names.ATTR_FRF_TYPE] = frf_type
    ds_attrs[names.ATTR_SOURCE] = frf_source
    ds_attrs.update(attrs)
    ds = xr.Dataset(
        {
            names.FRF: (
                dims,
                values,
                {names.ATTR_UNITS: names.frf_units(str(response_units), str(force_units))},
            )
        },
        coords={
            **ref_coord,
            names.POINT: labels,
            names.FREQUENCY: (names.FREQUENCY, freq, {names.ATTR_UNITS: names.FREQUENCY_UNITS}),
            **geometry,
        },
        attrs=ds_attrs,
    )
    _raise_problems(ds, "frf", drive_point is not None, "make_frf_dataset")
    return ds


def select_reference(ds: xr.Dataset, reference: Any) -> xr.Dataset:
    """The single-reference (SIMO) FRF Dataset of one reference of a multi-reference Dataset.

    Parameters
    ----------
    ds : xarray.Dataset
        FRF Dataset with dims ``(reference, point, frequency)``.
    reference : int or str
        Label of the reference to keep.

    Returns
    -------
    xarray.Dataset
        ``ds.sel(reference=reference, drop=True)``; every variable without the ``reference`` dim
        is kept. When the reference is a point label, ``drive_point`` is set to it; otherwise
        the attribute is left out (mode vectors then stay unscaled).

    Raises
    ------
    AmiXrValueError
        ``ds`` has no ``reference`` dim, or ``reference`` is not one of its labels.
    """
    if not isinstance(ds, xr.Dataset) or names.REFERENCE not in ds.dims:
        raise AmiXrValueError(
            f"ds: expected a multi-reference FRF Dataset with a {names.REFERENCE!r} dim"
        )
    refs = np.asarray(ds[names.REFERENCE].values).tolist()
    if python_scalar(reference) not in refs:
        raise AmiXrValueError(f"reference: {reference!r} is not one of the references {refs}")
    out = ds.sel({names.REFERENCE: reference}, drop=True)
    out.attrs = dict(ds.attrs)
    if python_scalar(reference) in np.asarray(ds[names.POINT].values).tolist():
        out.attrs[names.ATTR_DRIVE_POINT] = python_scalar(reference)
    else:
        out.attrs.pop(names.ATTR_DRIVE_POINT, None)
    return out


#: Attribute recording the channels converted from volts: ``"<channel>: <V per unit> V/<unit>"``.
ATTR_SENSITIVITY = "volt_sensitivity"


def _time_axis(time: Any, fs: float | None, n_time: int) -> np.ndarray:
    if (time is None) == (fs is None):
        raise AmiXrValueError(
            "time, fs: give exactly one of the time axis (s) or the sampling rate"
        )
    if fs is not None:
        if not is_positive_number(fs):
            raise AmiXrValueError(f"fs: expected a positive sampling rate in Hz, got {fs!r}")
        return np.arange(n_time) / float(fs)
    t = _as_array(time, "time")
    if t.ndim != 1 or t.shape[0] != n_time:
        raise AmiXrValueError(
            f"time: expected {n_time} values (response.shape[-1]), got shape {t.shape}"
        )
    return t


def _force_dims(f: Any, values: Any, references: Any) -> tuple[tuple[str, ...], dict[str, Any]]:
    """The dims of a force of shape ``([n_record,] [n_reference,] n_time)`` and the reference
    coordinate (several force channels)."""
    n_time = values.shape[-1]
    record = values.shape[:1] if values.ndim == 3 else ()
    lead: tuple[str, ...] = (names.RECORD,) if record else ()
    if references is None:
        shapes = {(n_time,): (names.TIME,), (*record, n_time): (*lead, names.TIME)}
        refs: dict[str, Any] = {}
    else:
        n_ref = len(references)
        shapes = {(*record, n_ref, n_time): (*lead, names.REFERENCE, names.TIME)}
        if record:
            shapes[(n_ref, n_time)] = (names.REFERENCE, names.TIME)
        refs = {names.REFERENCE: _labels(references, n_ref, "references")}
    if tuple(f.shape) not in shapes:
        raise AmiXrValueError(
            f"force: expected shape {' or '.join(map(str, shapes))}, got {tuple(f.shape)}"
            + ("" if references is None else f" ({len(references)} references)")
        )
    return shapes[tuple(f.shape)], refs


def _from_volts(
    data: dict[str, Any], coords: dict[str, Any], sensitivity: dict, units: dict[str, str]
) -> str:
    """Divide each channel named in ``sensitivity`` (``"force"``, a reference or a point label)
    by its volts per unit, in place; the record of what was converted."""
    done = []
    for channel, volts in sensitivity.items():
        if not is_positive_number(volts):
            raise AmiXrValueError(
                f"sensitivity: channel {channel!r}: expected volts per unit > 0, got {volts!r}"
            )
        key = python_scalar(channel)
        for var, dim in ((names.FORCE, names.REFERENCE), (names.RESPONSE, names.POINT)):
            dims = data[var][0] if var in data else ()
            if dim in dims and key in np.asarray(coords[dim]).tolist():
                at = np.asarray(coords[dim]).tolist().index(key)
                index = (slice(None),) * dims.index(dim) + (at,)
            elif var == names.FORCE and var in data and dim not in dims and key == "force":
                index = (slice(None),)
            else:
                continue
            values = np.array(data[var][1], dtype=np.float64)
            values[index] /= float(volts)
            data[var] = (dims, values, data[var][2])
            done.append(f"{channel}: {float(volts):g} V/{units[var]}")
            break
        else:
            raise AmiXrValueError(
                f"sensitivity: {channel!r} is no channel; expected 'force', a reference label "
                "or a point label"
            )
    return "; ".join(done)


def make_time_dataset(
    response: Any,
    time: Any = None,
    *,
    fs: float | None = None,
    force: Any = None,
    points: Any = None,
    drive_point: Any = None,
    response_quantity: str | None = None,
    response_units: str | None = None,
    force_units: str = "N",
    references: Any = None,
    sensitivity: dict | None = None,
    **attrs: Any,
) -> xr.Dataset:
    """Build a valid time Dataset from plain arrays (validated; errors name the argument).

    Parameters
    ----------
    response : array_like of float, shape (n_point, n_time), (n_record, n_point, n_time), (n_time,)
        Response histories; a 1-D array is one point. A dask array stays lazy.
    time : array_like of float, shape (n_time,), optional
        Sample times in s, uniformly spaced. Give exactly one of ``time`` and ``fs``.
    fs : float, optional
        Sampling rate in Hz; the time axis is then ``arange(n_time) / fs``.
    force : array_like of float, optional
        Shape (n_time,) or (n_reference, n_time), either with n_record first. Force history;
        with ``references``, one history per force channel. ``None`` means the
        responses are impulse responses to a unit impulse: the attribute
        ``excitation = "unit_impulse"`` is set.
    points, drive_point, response_quantity, response_units, force_units
        As for :func:`make_frf_dataset`.
    references : array_like of int or str, optional
        Labels of several force channels (a multi-reference test: :func:`ami_xr.frf` then
        gives FRFs with a ``reference`` dim); a label that is a point label marks that
        point's drive point.
    sensitivity : dict, optional
        Channels recorded in volts: ``{channel: volts per unit}`` with channel ``"force"``
        (one force), a reference label or a point label; the channel is divided by it, so
        ``force_units`` and ``response_units`` are the units after the conversion. Recorded
        in the attribute ``volt_sensitivity``.
    **attrs
        Further Dataset attributes.

    Returns
    -------
    xarray.Dataset
        ``response`` dims ``([record,] point, time)``, ``force`` dims
        ``([record,] [reference,] time)``, ``time`` coordinate with units ``"s"``.
    """
    values = _as_array(response, "response")
    if values.ndim == 1:
        values = values[None, :]
    if values.ndim not in (2, 3):
        raise AmiXrValueError(
            f"response: expected shape (n_point, n_time), (n_record, n_point, n_time) or "
            f"(n_time,), got {values.shape}"
        )
    t = _time_axis(time, fs, values.shape[-1])
    dims = (
        (names.POINT, names.TIME) if values.ndim == 2 else (names.RECORD, names.POINT, names.TIME)
    )
    ds_attrs = _std_attrs(
        drive_point, response_quantity, response_units, force_units, function="make_time_dataset"
    )
    response_units = ds_attrs[names.ATTR_RESPONSE_UNITS]
    data_vars: dict[str, Any] = {names.RESPONSE: (dims, values, {names.ATTR_UNITS: response_units})}
    coords: dict[str, Any] = {
        names.POINT: _labels(points, values.shape[-2]),
        names.TIME: (names.TIME, t, {names.ATTR_UNITS: names.TIME_UNITS}),
    }
    if values.ndim == 3:
        coords[names.RECORD] = np.arange(values.shape[0])
    if force is None:
        if references is not None:
            raise AmiXrValueError("references: given without a force")
        ds_attrs[names.ATTR_EXCITATION] = names.EXCITATION_UNIT_IMPULSE
    else:
        f = _as_array(force, "force")
        fdims, ref_coord = _force_dims(f, values, references)
        coords.update(ref_coord)
        data_vars[names.FORCE] = (fdims, f, {names.ATTR_UNITS: force_units})
    if sensitivity:
        units = {names.FORCE: force_units, names.RESPONSE: response_units}
        ds_attrs[ATTR_SENSITIVITY] = _from_volts(data_vars, coords, dict(sensitivity), units)
    ds_attrs.update(attrs)
    ds = xr.Dataset(data_vars, coords=coords, attrs=ds_attrs)
    _raise_problems(ds, "time", drive_point is not None, "make_time_dataset")
    return ds
