"""Windowing of labeled time records: ``apply_window``.

Each windowed variable records what was applied in its attributes:

* ``window``: the window names applied so far, joined by ``"*"`` (e.g. ``"exponential*force"``);
* ``window_parameters``: JSON list, one record per window (name, n, sym and its parameters;
  exponential windows store the resolved ``decay`` in 1/s and ``fs``);
* ``window_amplitude_correction`` ``n / sum(w)`` and ``window_energy_correction``
  ``sqrt(n / sum(w**2))`` of the product of all windows applied;
* ``exponential_window_decay`` (1/s), summed over the exponential windows applied.

The Dataset attribute ``exponential_window_decay`` follows the ``response`` variable: it grows by
``beta`` whenever ``response`` gets an exponential window, because that is what shifts every
identified eigenvalue by ``-beta`` (see :mod:`ami_xr.kernels.windows`).
"""

from __future__ import annotations

import json
from collections.abc import Hashable, Sequence

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.coords import range_axis
from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import windows as _kw
from ami_xr.provenance import add_history

# Variable attributes written by the windowing functions.
ATTR_WINDOW = "window"
ATTR_WINDOW_PARAMETERS = "window_parameters"
ATTR_AMPLITUDE_CORRECTION = "window_amplitude_correction"
ATTR_ENERGY_CORRECTION = "window_energy_correction"

_UNIFORM_RTOL = 1e-6  # relative spread of time steps accepted as uniform


def _check_dataset(ds, function: str) -> None:
    if not isinstance(ds, xr.Dataset):
        raise AmiXrValueError(f"ds: {function} expects an xarray.Dataset, got {type(ds).__name__}")


def sample_interval(ds: xr.Dataset, dim: Hashable = names.TIME) -> float:
    """Sample interval of the uniform coordinate ``dim`` (s for ``time``).

    Raises :class:`~ami_xr.errors.AmiXrValueError` naming ``dim`` when the coordinate is missing,
    not numeric, shorter than 2 samples, not increasing or not uniform (relative spread > 1e-6).
    """
    if dim not in ds.coords:
        raise AmiXrValueError(
            f"{dim}: the Dataset needs a {dim!r} coordinate to know the sample interval"
        )
    axis = range_axis(ds, dim)
    if axis is not None:  # RangeIndex (a lazily opened file): uniform by construction, no reads
        if axis.size < 2 or not (np.isfinite(axis.start) and np.isfinite(axis.step)):
            raise AmiXrValueError(
                f"{dim}: needs at least 2 finite samples to give a sample interval, got "
                f"{axis.size} from {axis.start} by {axis.step}"
            )
        if axis.step <= 0.0:
            raise AmiXrValueError(f"{dim}: expected strictly increasing values, step {axis.step}")
        return axis.step
    t = np.asarray(ds[dim].values)
    if t.ndim != 1 or not np.issubdtype(t.dtype, np.number) or np.iscomplexobj(t):
        raise AmiXrValueError(f"{dim}: expected a 1-D real coordinate (s), got dtype {t.dtype}")
    if t.shape[0] < 2:
        raise AmiXrValueError(
            f"{dim}: needs at least 2 samples to give a sample interval, got {t.shape[0]}"
        )
    t = t.astype(np.float64)
    dt = (t[-1] - t[0]) / (t.shape[0] - 1)
    if not np.isfinite(dt) or dt <= 0.0:
        raise AmiXrValueError(
            f"{dim}: expected strictly increasing values, got first {t[0]} last {t[-1]}"
        )
    if np.max(np.abs(np.diff(t) - dt)) > _UNIFORM_RTOL * dt:
        raise AmiXrValueError(
            f"{dim}: expected uniform spacing (sample interval {dt:g}), steps vary"
        )
    return float(dt)


def _select_variables(ds: xr.Dataset, dim: Hashable, variables) -> list[Hashable]:
    if variables is None:
        chosen = [v for v in ds.data_vars if dim in ds[v].dims]
        if not chosen:
            raise AmiXrValueError(f"variables: no data variable of the Dataset has the dim {dim!r}")
        return chosen
    chosen = [variables] if isinstance(variables, str) else list(variables)
    if not chosen:
        raise AmiXrValueError("variables: expected at least one variable name, got an empty list")
    for v in chosen:
        if v not in ds.data_vars:
            raise AmiXrValueError(f"variables: {v!r} is not a data variable of the Dataset")
        if dim not in ds[v].dims:
            raise AmiXrValueError(f"variables: {v!r} has dims {ds[v].dims}, not {dim!r}")
    return chosen


def _check_real(ds: xr.Dataset, variables: Sequence[Hashable]) -> None:
    for v in variables:
        dtype = ds[v].dtype
        if not np.issubdtype(dtype, np.number) or np.issubdtype(dtype, np.complexfloating):
            raise AmiXrValueError(f"{v}: expected real samples to window, got dtype {dtype}")


def window_and_record(
    window: str,
    n: int,
    *,
    fs: float | None,
    decay,
    end_value,
    width,
    taper,
    sym: bool,
) -> tuple[np.ndarray, dict]:
    """The window array and the JSON record that reproduces it (decay resolved to 1/s)."""
    name = _kw.window_name(window)
    w = _kw.get_window(
        name, n, fs=fs, decay=decay, end_value=end_value, width=width, taper=taper, sym=sym
    )
    record: dict = {"name": name, "n": n}
    if name in ("hann", "flattop", "boxcar"):
        record["sym"] = bool(sym)
    elif name == "exponential":
        record["decay"] = _kw.exponential_decay_rate(n, fs=fs, decay=decay, end_value=end_value)
        record["fs"] = float(fs)
        if end_value is not None:
            record["end_value"] = float(end_value)
    else:  # force
        record["width"] = int(width)
        record["taper"] = max(1, int(width) // 10) if taper is None else int(taper)
    return w, record


def _window_from_record(record: dict) -> np.ndarray:
    name = record["name"]
    if name == "exponential":
        return _kw.get_window(name, record["n"], fs=record["fs"], decay=record["decay"])
    if name == "force":
        return _kw.get_window(name, record["n"], width=record["width"], taper=record["taper"])
    return _kw.get_window(name, record["n"], sym=record.get("sym", False))


def window_attrs(old: dict, variable: Hashable, w: np.ndarray, record: dict) -> dict:
    """Variable attributes after applying window ``w`` (described by ``record``) on top of the
    windows listed in ``old``; the corrections are those of the product window."""
    raw = old.get(ATTR_WINDOW_PARAMETERS)
    try:
        records = json.loads(raw) if raw else []
    except (TypeError, ValueError):
        raise AmiXrValueError(
            f"{variable}: attribute {ATTR_WINDOW_PARAMETERS} is not valid JSON"
        ) from None
    product = np.array(w, dtype=np.float64)
    for previous in records:
        if previous.get("n") != record["n"]:
            raise AmiXrValueError(
                f"{variable}: was windowed ({previous.get('name')}) at {previous.get('n')} "
                "samples but "
                f"now has {record['n']}; window the record after cutting it, not before"
            )
        product = product * _window_from_record(previous)
    records = records + [record]
    attrs = dict(old)
    attrs[ATTR_WINDOW] = "*".join(r["name"] for r in records)
    attrs[ATTR_WINDOW_PARAMETERS] = json.dumps(records)
    attrs[ATTR_AMPLITUDE_CORRECTION] = _kw.amplitude_correction(product)
    attrs[ATTR_ENERGY_CORRECTION] = _kw.energy_correction(product)
    if record["name"] == "exponential":
        attrs[names.ATTR_EXP_DECAY] = float(old.get(names.ATTR_EXP_DECAY, 0.0)) + record["decay"]
    return attrs


def apply_window(
    ds: xr.Dataset,
    window: str = "hann",
    dim: Hashable = names.TIME,
    *,
    decay: float | None = None,
    end_value: float | None = None,
    width: int | None = None,
    taper: int | None = None,
    sym: bool = False,
    variables: str | Sequence[Hashable] | None = None,
) -> xr.Dataset:
    """Multiply time records by a window along ``dim``; returns a new Dataset.

    Parameters
    ----------
    ds : xarray.Dataset
        Time Dataset (numpy- or dask-backed). Chunks along other dims are kept; a ``dim`` split
        into several chunks is rechunked to one chunk (dask's ``allow_rechunk``).
    window : str, default "hann"
        ``"boxcar"``, ``"hann"``, ``"flattop"``, ``"exponential"`` or ``"force"``, see
        :func:`ami_xr.kernels.windows.get_window`.
    dim : hashable, default "time"
        Dimension along which to window; its coordinate must be uniform for ``"exponential"``
        (the sampling rate ``fs`` comes from it).
    decay, end_value : float, optional
        Exponential window: decay rate in 1/s, or value at the last sample in (0, 1).
    width, taper : int, optional
        Force window: samples of the pulse (required) and of the cosine taper after it.
    sym : bool, default False
        Cosine windows: periodic (``False``) or symmetric (``True``).
    variables : str or sequence of str, optional
        Variables to window; default every data variable with ``dim``. For a hammer test pass
        ``variables=["force"]`` with the force window; an exponential window normally goes on
        both ``response`` and ``force`` (the default).

    Returns
    -------
    xarray.Dataset
        Copy of ``ds`` with the chosen variables windowed and their window attributes set (see the
        module docstring); the Dataset attribute ``exponential_window_decay`` grows by the
        exponential window's decay rate when ``response`` is windowed.
    """
    _check_dataset(ds, "apply_window")
    if dim not in ds.dims:
        raise AmiXrValueError(
            f"dim: {dim!r} is not a dimension of the Dataset (dims: {tuple(ds.dims)})"
        )
    chosen = _select_variables(ds, dim, variables)
    _check_real(ds, chosen)
    n = int(ds.sizes[dim])
    fs = None
    if _kw.window_name(window) == "exponential":
        fs = 1.0 / sample_interval(ds, dim)
    w, record = window_and_record(
        window, n, fs=fs, decay=decay, end_value=end_value, width=width, taper=taper, sym=sym
    )
    new_attrs = {v: window_attrs(ds[v].attrs, v, w, record) for v in chosen}

    windowed = xr.apply_ufunc(
        _kw.apply_window,
        ds[chosen],
        kwargs={"w": w},
        input_core_dims=[[dim]],
        output_core_dims=[[dim]],
        dask="parallelized",
        output_dtypes=[np.float64],
        dask_gufunc_kwargs={"allow_rechunk": True},
        keep_attrs=True,
    )
    out = ds.copy()
    out.attrs = dict(ds.attrs)
    for v in chosen:
        da = windowed[v].transpose(*ds[v].dims)
        da.attrs = new_attrs[v]
        out[v] = da
    if record["name"] == "exponential" and names.RESPONSE in chosen:
        out.attrs[names.ATTR_EXP_DECAY] = (
            float(ds.attrs.get(names.ATTR_EXP_DECAY, 0.0)) + record["decay"]
        )
    parameters = {k: v for k, v in record.items() if k != "name"}
    parameters.update(window=record["name"], dim=str(dim), variables=[str(v) for v in chosen])
    return add_history(out, "apply_window", parameters)
