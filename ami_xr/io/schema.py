"""Schema validation of ami_xr Datasets.

:func:`validate` checks a Dataset against the data model (see ``ami_xr.names`` and the README's
"Data model" section) and reports every problem at once in one :class:`~ami_xr.errors.SchemaError`.
:func:`find_problems` returns the same list without raising, phrased in the caller's argument names
if asked (the constructors of :mod:`ami_xr.io.datasets` use it).
"""

from __future__ import annotations

from collections.abc import Mapping
from numbers import Integral, Real
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.coords import RangeAxis, range_axis
from ami_xr.errors import AmiXrValueError, SchemaError
from ami_xr.io.geometry import coordinate_problems
from ami_xr.io.messages import Namer, is_positive_number, python_scalar, shorten

__all__ = [
    "validate",
    "find_problems",
    "is_positive_number",
    "python_scalar",
    "KINDS",
    "UNIFORM_RTOL",
    "IMPULSE_GRID_RTOL",
    "impulse_grid_problem",
    "drive_points",
    "MULTI_REFERENCE_DIMS",
]

KINDS = ("frf", "time")

# Dataset attribute of impulse-response time Datasets that carry no force record.

# Time steps may differ from their mean by this fraction of the step (float rounding of t = i*dt).
UNIFORM_RTOL = 1e-6

_MULTI_REFERENCE = (
    f"has a leading {names.REFERENCE!r} dim: multi-reference not supported yet "
    f"(select one reference first, e.g. ds.isel({names.REFERENCE}=0))"
)
# dims of a multi-reference FRF: one row of FRFs (point, frequency) per excitation location
MULTI_REFERENCE_DIMS = (names.REFERENCE, names.POINT, names.FREQUENCY)


# --- small checks, each appends to ``problems`` -------------------------------------------------


def _check_finite(da: xr.DataArray, subject: str, problems: list[str]) -> None:
    """Report NaN and inf values of ``da`` (one pass over the data; locations only if bad):
    counted per point when ``da`` has the ``point`` dim, else the first index."""
    if da.size == 0 or not (
        np.issubdtype(da.dtype, np.floating) or np.issubdtype(da.dtype, np.complexfloating)
    ):
        return
    bad = ~np.isfinite(np.asarray(da.values))
    n_bad = int(bad.sum())
    if n_bad == 0:
        return
    if names.POINT in da.dims:
        axis = da.dims.index(names.POINT)
        counts = np.moveaxis(bad, axis, 0).reshape(bad.shape[axis], -1).sum(axis=1)
        where = np.flatnonzero(counts)
        labels = np.asarray(da[names.POINT].values) if names.POINT in da.coords else where
        listed = [f"{python_scalar(labels[i])!r}: {int(counts[i])}" for i in where]
        more = f", ... ({where.size} in all)" if where.size > 8 else ""
        problems.append(
            f"{subject}: expected finite values, found {n_bad} NaN or inf value(s) at "
            f"{where.size} point(s) (point: count) {', '.join(listed[:8])}{more}"
        )
        return
    n_nan = int(np.isnan(da.values).sum())
    first = np.unravel_index(int(np.argmax(bad)), bad.shape)
    at = ", ".join(f"{dim}={i}" for dim, i in zip(da.dims, first, strict=True))
    problems.append(
        f"{subject}: expected finite values, found {n_nan} NaN and {n_bad - n_nan} inf "
        f"(first at index {at})"
    )


def _check_axis(
    ds: xr.Dataset,
    dim: str,
    units: str,
    namer: Namer,
    problems: list[str],
    *,
    uniform: bool = False,
    nonnegative: bool = False,
    metadata: bool = True,
) -> None:
    """Check a frequency or time coordinate: present, real, finite, strictly increasing."""
    subject = namer.coord(dim)
    if dim not in ds.coords:
        problems.append(f"{subject}: missing (expected 1-D values in {units} along dim {dim!r})")
        return
    coord = ds.coords[dim]
    if coord.dims != (dim,):
        problems.append(f"{subject}: expected dims ({dim!r},), got {coord.dims}")
        return
    if not (np.issubdtype(coord.dtype, np.floating) or np.issubdtype(coord.dtype, np.integer)):
        problems.append(f"{subject}: expected real numbers in {units}, got dtype {coord.dtype}")
        return
    if metadata and coord.attrs.get(names.ATTR_UNITS) != units:
        problems.append(
            f"{namer.var_attr(dim, names.ATTR_UNITS)}: expected {units!r}, "
            f"got {coord.attrs.get(names.ATTR_UNITS)!r}"
        )
    axis = range_axis(ds, dim)
    if axis is not None:  # RangeIndex (a lazily opened file): check start/step, read no values
        _check_range_axis(axis, dim, subject, problems, nonnegative=nonnegative)
        return
    values = np.asarray(coord.values, dtype=np.float64)
    if values.size == 0:
        return  # reported as an empty variable
    if not np.all(np.isfinite(values)):
        problems.append(f"{subject}: expected finite values, found NaN or inf")
        return
    if nonnegative and np.any(values < 0):
        problems.append(
            f"{subject}: expected non-negative frequencies, got {int((values < 0).sum())} "
            f"negative (smallest {values.min()!r})"
        )
    steps = np.diff(values)
    dup = np.flatnonzero(steps == 0)
    if dup.size:
        problems.append(
            f"{subject}: expected strictly increasing values, found duplicate {dim} values "
            f"{shorten(values[dup])}"
        )
    down = np.flatnonzero(steps < 0)
    if down.size:
        i = down[0]
        problems.append(
            f"{subject}: expected strictly increasing values, not increasing at {down.size} "
            f"place(s) (first: index {i} = {values[i]!r} then {values[i + 1]!r})"
        )
    if uniform and steps.size > 1 and not dup.size and not down.size:
        dt = (values[-1] - values[0]) / steps.size
        tol = UNIFORM_RTOL * dt + 8 * np.finfo(np.float64).eps * np.abs(values).max()
        worst = int(np.argmax(np.abs(steps - dt)))
        if abs(steps[worst] - dt) > tol:
            problems.append(
                f"{subject}: expected uniform steps, step {worst} is {steps[worst]!r} s "
                f"but the mean step is {dt!r} s (relative tolerance {UNIFORM_RTOL})"
            )


def _check_range_axis(
    axis: RangeAxis, dim: str, subject: str, problems: list[str], *, nonnegative: bool
) -> None:
    """``_check_axis`` for a coordinate backed by a ``RangeIndex``: values ``start + i * step``
    are uniform by construction, so finiteness, order and sign follow from start, step, size."""
    if axis.size == 0:
        return  # reported as an empty variable
    last = axis.start + (axis.size - 1) * axis.step
    if not (np.isfinite(axis.start) and np.isfinite(axis.step) and np.isfinite(last)):
        problems.append(f"{subject}: expected finite values, found NaN or inf")
        return
    if nonnegative and min(axis.start, last) < 0:
        problems.append(
            f"{subject}: expected non-negative frequencies, got a range starting at "
            f"{axis.start!r} with step {axis.step!r}"
        )
    if axis.size > 1 and axis.step <= 0:
        problems.append(
            f"{subject}: expected strictly increasing values, got a range with step "
            f"{axis.step!r} along {dim!r}"
        )


def _check_points(ds: xr.Dataset, namer: Namer, problems: list[str]) -> np.ndarray | None:
    """Check the point labels; return them when usable, else None."""
    subject = namer.coord(names.POINT)
    if names.POINT not in ds.coords:
        problems.append(f"{subject}: missing (expected unique int or str labels along dim 'point')")
        return None
    labels = np.asarray(ds.coords[names.POINT].values)
    if labels.ndim != 1:
        problems.append(f"{subject}: expected a 1-D coordinate, got shape {labels.shape}")
        return None
    is_int = np.issubdtype(labels.dtype, np.integer)
    is_str = labels.dtype.kind == "U" or (
        labels.dtype == object and all(isinstance(v, str) for v in labels)
    )
    if not (is_int or is_str):
        problems.append(f"{subject}: expected int or str labels, got dtype {labels.dtype}")
        return None
    uniq, counts = np.unique(labels.astype(str) if is_str else labels, return_counts=True)
    if np.any(counts > 1):
        problems.append(
            f"{subject}: expected unique labels, duplicates {shorten(uniq[counts > 1])}"
        )
    return labels


def _check_references(
    ds: xr.Dataset,
    labels: np.ndarray | None,
    require: bool,
    namer: Namer,
    problems: list[str],
) -> None:
    """Check the ``reference`` labels of a multi-reference FRF Dataset.

    References name excitation locations in the same label space as the points: a reference
    whose label equals a point label is that point's drive point. The ``drive_point``
    attribute is not used (it would say one drive point where there may be several).
    """
    subject = namer.coord(names.REFERENCE)
    if names.ATTR_DRIVE_POINT in ds.attrs:
        problems.append(
            f"{namer.attr(names.ATTR_DRIVE_POINT)}: not used with a {names.REFERENCE!r} dim "
            f"(got {python_scalar(ds.attrs[names.ATTR_DRIVE_POINT])!r}); the drive points are "
            "the references whose label is a point label -- remove the attribute"
        )
    if names.REFERENCE not in ds.coords:
        problems.append(
            f"{subject}: missing (expected unique int or str labels of the excitation "
            f"locations along dim {names.REFERENCE!r})"
        )
        return
    refs = np.asarray(ds.coords[names.REFERENCE].values)
    if refs.ndim != 1:
        problems.append(f"{subject}: expected a 1-D coordinate, got shape {refs.shape}")
        return
    is_int = np.issubdtype(refs.dtype, np.integer)
    is_str = refs.dtype.kind == "U" or (
        refs.dtype == object and all(isinstance(v, str) for v in refs)
    )
    if not (is_int or is_str):
        problems.append(f"{subject}: expected int or str labels, got dtype {refs.dtype}")
        return
    uniq, counts = np.unique(refs.astype(str) if is_str else refs, return_counts=True)
    if np.any(counts > 1):
        problems.append(
            f"{subject}: expected unique labels, duplicates {shorten(uniq[counts > 1])}"
        )
    if labels is None:
        return
    points_int = np.issubdtype(labels.dtype, np.integer)
    if points_int != is_int:
        problems.append(
            f"{subject}: expected {'int' if points_int else 'str'} labels like the point "
            f"labels (a reference whose label is a point label is its drive point), got "
            f"{'int' if is_int else 'str'} labels {shorten(refs)}"
        )
        return
    if require and not np.isin(refs, labels).any():
        problems.append(
            f"{subject}: no reference {shorten(refs)} is a point label {shorten(labels)} "
            "(expected at least one drive point, where the force acts on a measured point; "
            "pass require_drive_point=False to accept unscaled mode vectors)"
        )


def drive_points(ds: xr.Dataset) -> list:
    """The drive points of an FRF Dataset: the references that are point labels, in reference
    order (multi-reference), or ``[drive_point]`` when that attribute names a point (SIMO).

    Parameters
    ----------
    ds : xarray.Dataset
        An FRF Dataset.

    Returns
    -------
    list
        Point labels (Python scalars); empty when no force acts on a measured point.
    """
    points = np.asarray(ds[names.POINT].values).tolist() if names.POINT in ds.coords else []
    if names.REFERENCE in ds.dims and names.REFERENCE in ds.coords:
        return [r for r in np.asarray(ds[names.REFERENCE].values).tolist() if r in points]
    dp = ds.attrs.get(names.ATTR_DRIVE_POINT)
    return [python_scalar(dp)] if dp is not None and python_scalar(dp) in points else []


def _check_drive_point(
    ds: xr.Dataset, labels: np.ndarray | None, require: bool, namer: Namer, problems: list[str]
) -> None:
    subject = namer.attr(names.ATTR_DRIVE_POINT)
    if names.ATTR_DRIVE_POINT not in ds.attrs:
        if require:
            problems.append(
                f"{subject}: missing (expected the label of the point where the force acts; "
                "pass require_drive_point=False to accept unscaled mode vectors)"
            )
        return
    if not require or labels is None:
        return
    dp = ds.attrs[names.ATTR_DRIVE_POINT]
    if np.issubdtype(labels.dtype, np.integer):
        ok_type = isinstance(dp, Integral) and not isinstance(dp, (bool, np.bool_))
        kind = "int"
    else:
        ok_type = isinstance(dp, str)
        kind = "str"
    if not ok_type:
        problems.append(
            f"{subject}: expected a point label of type {kind}, got {python_scalar(dp)!r} "
            f"({type(dp).__name__})"
        )
    elif not np.any(labels == dp):
        problems.append(
            f"{subject}: {python_scalar(dp)!r} is not among the point labels {shorten(labels)}"
        )


def _check_quantity_units(
    ds: xr.Dataset, namer: Namer, problems: list[str], *, need_frf_type: bool
) -> tuple[str | None, str | None]:
    """Check quantity, frf_type and units attrs; return the (response, force) units if valid."""
    quantities = tuple(names.RESPONSE_UNITS)
    q = ds.attrs.get(names.ATTR_QUANTITY)
    if q not in quantities:
        got = "missing" if q is None else f"got {q!r}"
        problems.append(f"{namer.attr(names.ATTR_QUANTITY)}: expected one of {quantities}, {got}")
        q = None
    if need_frf_type:
        want = names.QUANTITY_TO_FRF_TYPE.get(q) if q else None
        got_type = ds.attrs.get(names.ATTR_FRF_TYPE)
        allowed = (want,) if want else tuple(names.FRF_TYPE_TO_QUANTITY)
        if got_type not in allowed:
            got = "missing" if got_type is None else f"got {got_type!r}"
            expected = f"{want!r} (response_quantity is {q!r})" if want else f"one of {allowed}"
            problems.append(f"{namer.attr(names.ATTR_FRF_TYPE)}: expected {expected}, {got}")
    resp_units = ds.attrs.get(names.ATTR_RESPONSE_UNITS)
    allowed_units = (
        names.RESPONSE_UNITS[q]
        if q
        else tuple(u for us in names.RESPONSE_UNITS.values() for u in us)
    )
    if resp_units not in allowed_units:
        got = "missing" if resp_units is None else f"got {resp_units!r}"
        of = f" for {q}" if q else ""
        problems.append(
            f"{namer.attr(names.ATTR_RESPONSE_UNITS)}: expected one of {allowed_units}{of}, {got}"
        )
        resp_units = None
    force_units = ds.attrs.get(names.ATTR_FORCE_UNITS)
    if force_units not in names.FORCE_UNITS:
        got = "missing" if force_units is None else f"got {force_units!r}"
        problems.append(
            f"{namer.attr(names.ATTR_FORCE_UNITS)}: expected one of {names.FORCE_UNITS}, {got}"
        )
        force_units = None
    return resp_units, force_units


# How far a frequency may sit from the rfft grid k / (N dt), as a fraction of its own value
# (and of one line spacing at k = 0). k / (N dt) computed in float64 -- by rfftfreq, by
# arange(k) / (N dt) or by k * (1 / (N dt)) -- differs from the exact value by a few ulp
# (~1e-15 relative), and dt read back from a text file written with 7 or more significant
# digits by less than 1e-6; an axis that disagrees with dt or N (a wrong dt, a padded FFT, Hz
# multiplied by 2 pi) is off by a whole fraction of a line at most lines, far above this.
IMPULSE_GRID_RTOL = 1e-6


def impulse_grid_problem(ds: xr.Dataset, namer: Namer | None = None) -> str | None:
    """Why the frequency axis of an impulse-response FRF Dataset is not its rfft grid, or None.

    An FRF with ``frf_source == "impulse_response"`` is ``dt * rfft`` of ``record_samples``
    samples, so its lines are ``k / (record_samples * sample_interval)`` Hz with
    ``0 <= k <= record_samples // 2`` (a band of them is fine). The discrete modal model uses
    ``sample_interval`` and the axis together: when they disagree its modes are wrong.

    Parameters
    ----------
    ds : xarray.Dataset
        FRF Dataset; only checked when ``frf_source`` is ``"impulse_response"`` and the
        frequency axis, ``sample_interval`` and ``record_samples`` are usable (their own
        problems are reported by :func:`validate`).
    namer : optional
        How the message names the frequency coordinate (default "coordinate 'frequency'").

    Returns
    -------
    str or None
        One message naming ``frequency`` and the expected spacing, or None when the axis fits.
    """
    namer = namer or Namer()
    attrs = ds.attrs
    dt, n = attrs.get(names.ATTR_DT), attrs.get(names.ATTR_NSAMPLES)
    if attrs.get(names.ATTR_SOURCE) != names.SOURCE_IMPULSE or names.FREQUENCY not in ds.coords:
        return None
    if not (is_positive_number(dt) and is_positive_number(n) and isinstance(n, Integral)):
        return None
    coord = ds.coords[names.FREQUENCY]
    if coord.ndim != 1 or coord.size == 0 or coord.dtype.kind not in "fiu":
        return None
    axis = range_axis(ds, names.FREQUENCY)
    if axis is not None:  # uniform by construction: its first, second and last lines suffice
        idx = np.unique(np.array([0, 1, axis.size - 1]).clip(0, axis.size - 1))
        freq = axis.start + idx * axis.step
    else:
        idx = np.arange(coord.size)
        freq = np.asarray(coord.values, dtype=np.float64)
    if not np.all(np.isfinite(freq)):
        return None
    df = 1.0 / (float(n) * float(dt))
    lines = freq / df
    k = np.rint(lines)
    off = (np.abs(lines - k) > IMPULSE_GRID_RTOL * np.maximum(np.abs(lines), 1.0)) | (k < 0)
    off |= k > int(n) // 2
    if not off.any():
        return None
    first = int(np.argmax(off))
    units = coord.attrs.get(names.ATTR_UNITS)
    return (
        f"{namer.coord(names.FREQUENCY)}: expected the rfft grid of an impulse response, "
        f"k / (record_samples * sample_interval) = k * {df!r} Hz with 0 <= k <= "
        f"{int(n) // 2} (frf_source {names.SOURCE_IMPULSE!r}, sample_interval {float(dt)!r} s, "
        f"record_samples {int(n)}), but {int(off.sum())} of {off.size} checked lines are off "
        f"it (first: index {int(idx[first])} = {float(freq[first])!r} {units}, {lines[first]:.6g} "
        "line spacings); are the frequencies in Hz (not rad/s), and are sample_interval and "
        "record_samples those of the record?"
    )


def _check_empty(da: xr.DataArray, subject: str, problems: list[str]) -> bool:
    if da.size == 0:
        problems.append(f"{subject}: empty (expected at least one value, got shape {da.shape})")
        return True
    return False


def _check_noise_std(
    std: xr.DataArray, frf: xr.DataArray, check_values: bool, namer: Namer, problems: list[str]
) -> None:
    """``frf_line_noise_std`` beside ``frf``: its dims, real values, finite and >= 0."""
    subject = namer.var(names.FRF_LINE_NOISE_STD)
    if std.dims != frf.dims:
        problems.append(f"{subject}: expected the dims of {names.FRF!r} {frf.dims}, got {std.dims}")
        return
    if not np.issubdtype(std.dtype, np.floating):
        problems.append(f"{subject}: expected real float values, got dtype {std.dtype}")
        return
    if check_values and std.size:
        _check_finite(std, subject, problems)
        n_neg = int((std < 0).sum())
        if n_neg:
            problems.append(f"{subject}: expected standard deviations >= 0, found {n_neg} < 0")


# --- the two kinds of Dataset -------------------------------------------------------------------


def _frf_problems(
    ds: xr.Dataset,
    require_drive_point: bool,
    check_values: bool,
    namer: Namer,
    metadata: bool = True,
) -> list[str]:
    problems: list[str] = []
    want_dims = (names.POINT, names.FREQUENCY)
    multi = False
    if names.FRF not in ds.data_vars:
        problems.append(
            f"{namer.var(names.FRF)}: missing (expected complex FRF with dims {want_dims})"
        )
        frf = None
    else:
        frf = ds[names.FRF]
        subject = namer.var(names.FRF)
        multi = names.REFERENCE in frf.dims
        if multi:
            if frf.dims != MULTI_REFERENCE_DIMS:
                problems.append(
                    f"{subject}: expected dims {MULTI_REFERENCE_DIMS} (multi-reference) or "
                    f"{want_dims}, got {frf.dims}"
                )
        elif names.COMPLEX in frf.dims:
            problems.append(
                f"{subject}: has the on-disk dim {names.COMPLEX!r} (real, imag); "
                "open the file with ami_xr.open_dataset to decode it"
            )
        elif frf.dims != want_dims:
            problems.append(f"{subject}: expected dims {want_dims}, got {frf.dims}")
        if not np.issubdtype(frf.dtype, np.complexfloating):
            problems.append(
                f"{subject}: expected complex values (complex128), got dtype {frf.dtype}"
            )
        empty = _check_empty(frf, subject, problems)
        if check_values and not empty:
            _check_finite(frf, subject, problems)
        if names.FRF_LINE_NOISE_STD in ds.data_vars:
            _check_noise_std(ds[names.FRF_LINE_NOISE_STD], frf, check_values, namer, problems)
    _check_axis(
        ds,
        names.FREQUENCY,
        names.FREQUENCY_UNITS,
        namer,
        problems,
        nonnegative=True,
        metadata=metadata,
    )
    labels = _check_points(ds, namer, problems)
    problems += coordinate_problems(ds, namer)
    if metadata:
        _frf_metadata_problems(ds, frf, labels, multi, require_drive_point, namer, problems)
    source = ds.attrs.get(names.ATTR_SOURCE)
    if source == names.SOURCE_IMPULSE:
        _impulse_problems(ds, source, namer, problems)
    if names.ATTR_EXP_DECAY in ds.attrs:
        decay = ds.attrs[names.ATTR_EXP_DECAY]
        if not (is_positive_number(decay) or (isinstance(decay, Real) and decay == 0)):
            problems.append(
                f"{namer.attr(names.ATTR_EXP_DECAY)}: expected a finite decay rate >= 0 in 1/s, "
                f"got {python_scalar(decay)!r}"
            )
    return problems


def _frf_metadata_problems(ds, frf, labels, multi, require_drive_point, namer, problems):
    """The drive point(s), quantity, units and source attributes of an FRF Dataset."""
    if multi:
        _check_references(ds, labels, require_drive_point, namer, problems)
    else:
        _check_drive_point(ds, labels, require_drive_point, namer, problems)
    resp_units, force_units = _check_quantity_units(ds, namer, problems, need_frf_type=True)
    if frf is not None and resp_units and force_units:
        want = names.frf_units(resp_units, force_units)
        got = frf.attrs.get(names.ATTR_UNITS)
        if got != want:
            problems.append(
                f"{namer.var_attr(names.FRF, names.ATTR_UNITS)}: expected {want!r} "
                f"(response_units/force_units), got {got!r}"
            )
    source = ds.attrs.get(names.ATTR_SOURCE)
    if source not in names.SOURCES:
        got = "missing" if source is None else f"got {source!r}"
        problems.append(f"{namer.attr(names.ATTR_SOURCE)}: expected one of {names.SOURCES}, {got}")


def _impulse_problems(ds: xr.Dataset, source: str, namer: Namer, problems: list[str]) -> None:
    """An impulse-response FRF's sample interval and record length, and its rfft grid."""
    dt = ds.attrs.get(names.ATTR_DT)
    if not is_positive_number(dt):
        got = "missing" if dt is None else f"got {python_scalar(dt)!r}"
        problems.append(
            f"{namer.attr(names.ATTR_DT)}: expected a positive sample interval in s "
            f"because frf_source is {source!r}, {got}"
        )
    n = ds.attrs.get(names.ATTR_NSAMPLES)
    if not (is_positive_number(n) and isinstance(n, Integral)):
        got = "missing" if n is None else f"got {python_scalar(n)!r}"
        problems.append(
            f"{namer.attr(names.ATTR_NSAMPLES)}: expected a positive integer record length "
            f"because frf_source is {source!r}, {got}"
        )
    elif is_positive_number(dt):
        grid = impulse_grid_problem(ds, namer)
        if grid:
            problems.append(grid)


def _signal_problems(
    ds: xr.Dataset,
    var: str,
    allowed: tuple[tuple[str, ...], ...],
    check_values: bool,
    namer: Namer,
) -> list[str]:
    problems: list[str] = []
    da = ds[var]
    subject = namer.var(var)
    if names.REFERENCE in da.dims:
        problems.append(f"{subject}: {_MULTI_REFERENCE}")
    elif da.dims not in allowed:
        problems.append(f"{subject}: expected dims {' or '.join(map(str, allowed))}, got {da.dims}")
    if not np.issubdtype(da.dtype, np.floating):
        problems.append(f"{subject}: expected real float values (float64), got dtype {da.dtype}")
    empty = _check_empty(da, subject, problems)
    if check_values and not empty:
        _check_finite(da, subject, problems)
    return problems


def _time_problems(ds: xr.Dataset, require_drive_point: bool, check_values: bool, namer: Namer):
    problems: list[str] = []
    p, t, r = names.POINT, names.TIME, names.RECORD
    if names.RESPONSE not in ds.data_vars:
        problems.append(
            f"{namer.var(names.RESPONSE)}: missing (expected float responses with dims "
            f"{(p, t)} or {(r, p, t)})"
        )
    else:
        problems += _signal_problems(ds, names.RESPONSE, ((p, t), (r, p, t)), check_values, namer)
    if names.FORCE in ds.data_vars:
        problems += _signal_problems(ds, names.FORCE, ((t,), (r, t)), check_values, namer)
    elif ds.attrs.get(names.ATTR_EXCITATION) != names.EXCITATION_UNIT_IMPULSE:
        problems.append(
            f"{namer.var(names.FORCE)}: missing (expected float force with dims {(t,)} or "
            f"{(r, t)}, or attribute {names.ATTR_EXCITATION}="
            f"{names.EXCITATION_UNIT_IMPULSE!r} for impulse responses)"
        )
    _check_axis(ds, t, names.TIME_UNITS, namer, problems, uniform=True)
    labels = _check_points(ds, namer, problems)
    problems += coordinate_problems(ds, namer)
    _check_drive_point(ds, labels, require_drive_point, namer, problems)
    resp_units, force_units = _check_quantity_units(ds, namer, problems, need_frf_type=False)
    for var, units in ((names.RESPONSE, resp_units), (names.FORCE, force_units)):
        if var in ds.data_vars and units and names.ATTR_UNITS in ds[var].attrs:
            got = ds[var].attrs[names.ATTR_UNITS]
            if got != units:
                problems.append(
                    f"{namer.var_attr(var, names.ATTR_UNITS)}: expected {units!r} "
                    f"(the Dataset's {'response' if var == names.RESPONSE else 'force'}_units), "
                    f"got {got!r}"
                )
    return problems


def find_problems(
    ds: Any,
    kind: str | None = None,
    *,
    require_drive_point: bool = True,
    check_values: bool = True,
    arguments: Mapping[str, str] | None = None,
    metadata: bool = True,
) -> tuple[str, list[str]]:
    """What :func:`validate` checks, without raising: a description of ``ds`` and its problems.

    Parameters
    ----------
    ds, kind, require_drive_point, check_values
        As for :func:`validate`.
    arguments : mapping of str to str, optional
        Dataset names (variables, coordinates, attributes, or ``"var.attr"``) to the argument
        names a constructor took them from; messages then say "argument 'points'" rather than
        "coordinate 'point'".
    metadata : bool, default True
        FRF Datasets: also check the attributes that describe the data (units, quantity,
        source, drive point). False checks what an analysis needs (structure, labels, the
        frequency axis and its agreement with an impulse-response grid, finite values): the
        AMI phases validate their input so.

    Returns
    -------
    what : str
        ``"FRF Dataset"``, ``"Time Dataset"`` or ``"Dataset"`` (kind not recognised).
    problems : list of str
        Every problem found, each naming the part and what was expected; empty when ``ds``
        conforms.

    Raises
    ------
    AmiXrValueError
        If ``ds`` is not a Dataset or ``kind`` is unknown.
    """
    namer = Namer(arguments)
    if not isinstance(ds, xr.Dataset):
        hint = " (e.g. da.to_dataset(name='frf'))" if isinstance(ds, xr.DataArray) else ""
        raise AmiXrValueError(f"ds: expected an xarray.Dataset{hint}, got {type(ds).__name__}")
    if kind is not None and kind not in KINDS:
        raise AmiXrValueError(f"kind: expected None or one of {KINDS}, got {kind!r}")
    if kind is None:
        if names.FRF in ds.data_vars:
            kind = "frf"
        elif names.RESPONSE in ds.data_vars:
            kind = "time"
        else:
            return "Dataset", [
                f"{namer.var(names.FRF)} or {namer.var(names.RESPONSE)}: missing (expected "
                f"{names.FRF!r} for an FRF Dataset or {names.RESPONSE!r} for a time Dataset; "
                f"has {sorted(map(str, ds.data_vars))})"
            ]
    if kind == "frf":
        return "FRF Dataset", _frf_problems(
            ds, require_drive_point, check_values, namer, metadata=metadata
        )
    return "Time Dataset", _time_problems(ds, require_drive_point, check_values, namer)


def validate(
    ds: xr.Dataset,
    kind: str | None = None,
    *,
    require_drive_point: bool = True,
    check_values: bool = True,
) -> xr.Dataset:
    """Check ``ds`` against the ami_xr data model and return it unchanged when it conforms.

    Every problem found is reported at once in one :class:`~ami_xr.errors.SchemaError` whose
    ``problems`` list names, for each, the variable, coordinate or attribute and what was
    expected. Besides structure, units and finite values, the parts must agree: an FRF with
    ``frf_source="impulse_response"`` must have its lines on the rfft grid
    ``k / (record_samples * sample_interval)`` Hz (see :func:`impulse_grid_problem`).

    Parameters
    ----------
    ds : xarray.Dataset
        An FRF Dataset (``frf`` complex, dims ``(point, frequency)``, or
        ``(reference, point, frequency)`` for multi-reference data: one row per excitation
        location, labelled by the ``reference`` coordinate in the point labels' type; a
        reference whose label is a point label is that point's drive point, and the
        ``drive_point`` attribute is then not used) or a time Dataset (``response`` float,
        dims ``([record,] point, time)``, plus ``force``).
    kind : {None, "frf", "time"}
        Which model to check against. ``None`` detects it: a Dataset with ``frf`` is an FRF
        Dataset, one with ``response`` a time Dataset.
    require_drive_point : bool, default True
        Require the ``drive_point`` attribute to name one of the points (multi-reference: at
        least one reference label to be a point label). AMI can run without a measured drive
        point (mode vectors then stay unscaled): pass False to skip both checks.
    check_values : bool, default True
        Scan ``frf``/``response``/``force`` for NaN and inf. This reads all data (it computes
        lazily opened variables); pass False to check only structure, coordinates and attributes.

    Returns
    -------
    xarray.Dataset
        ``ds`` itself (not a copy), so ``validate`` can be chained.

    Raises
    ------
    SchemaError
        Listing every problem. Extra variables and attributes are allowed and not checked
        (NaN is fine in them).
    AmiXrValueError
        If ``ds`` is not a Dataset or ``kind`` is unknown.

    Examples
    --------
    >>> import numpy as np, ami_xr
    >>> ds = ami_xr.make_frf_dataset(np.ones((2, 3), complex), [0.0, 1.0, 2.0], drive_point=0)
    >>> ami_xr.validate(ds) is ds
    True
    """
    what, found = find_problems(
        ds, kind, require_drive_point=require_drive_point, check_values=check_values
    )
    if found:
        raise SchemaError(found, what=what)
    return ds
