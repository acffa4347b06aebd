"""The small checks both data models share: finite values, axes, point labels, references,
the drive point, quantity and units. Each appends what it finds to ``problems``.
"""

from __future__ import annotations

from numbers import Integral

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.coords import RangeAxis, range_axis
from ami_xr.schema.messages import Namer, python_scalar, shorten

__all__ = [
    "KINDS",
    "UNIFORM_RTOL",
    "MULTI_REFERENCE_MESSAGE",
    "MULTI_REFERENCE_DIMS",
    "check_finite",
    "check_axis",
    "check_range_axis",
    "check_points",
    "check_references",
    "drive_points",
    "check_drive_point",
    "check_quantity_units",
    "check_empty",
    "check_noise_std",
]

KINDS = ("frf", "time")

# Time steps may differ from their mean by this fraction of the step (float rounding of t = i*dt).
UNIFORM_RTOL = 1e-6

MULTI_REFERENCE_MESSAGE = (
    f"has a leading {names.REFERENCE!r} dim: multi-reference not supported yet "
    f"(select one reference first, e.g. ds.isel({names.REFERENCE}=0))"
)
# dims of a multi-reference FRF: one row of FRFs (point, frequency) per excitation location
MULTI_REFERENCE_DIMS = (names.REFERENCE, names.POINT, names.FREQUENCY)


# --- small checks, each appends to ``problems`` -------------------------------------------------


def check_finite(da: xr.DataArray, subject: str, problems: list[str]) -> None:
    """Report NaN and inf values of ``da`` (one pass over the data; locations only if bad):
    counted per point when ``da`` has the ``point`` dim, else the first index.

    Only reductions of ``~isfinite(da)`` are computed (counts per point, totals): a lazy
    (dask-backed) ``da`` is reduced chunk by chunk, on the workers of a cluster, and never
    materialised in this process."""
    if da.size == 0 or not (
        np.issubdtype(da.dtype, np.floating) or np.issubdtype(da.dtype, np.complexfloating)
    ):
        return
    bad = ~np.isfinite(da.variable)  # a Variable: lazy for dask data, no coordinates carried
    if names.POINT in da.dims:
        others = [d for d in da.dims if d != names.POINT]
        counts = np.asarray(bad.sum(others).values if others else bad.values, dtype=np.int64)
        n_bad = int(counts.sum())
        if n_bad == 0:
            return
        where = np.flatnonzero(counts)
        # without a point coordinate the points are named by position
        labels = (
            np.asarray(da[names.POINT].values)
            if names.POINT in da.coords
            else np.arange(counts.size)
        )
        listed = [f"{python_scalar(labels[i])!r}: {int(counts[i])}" for i in where]
        more = f", ... ({where.size} in all)" if where.size > 8 else ""
        problems.append(
            f"{subject}: expected finite values, found {n_bad} NaN or inf value(s) at "
            f"{where.size} point(s) (point: count) {', '.join(listed[:8])}{more}"
        )
        return
    n_bad = int(bad.sum().values)
    if n_bad == 0:
        return
    n_nan = int(np.isnan(da.variable).sum().values)
    at = ", ".join(f"{dim}={i}" for dim, i in _first_true(bad).items())
    problems.append(
        f"{subject}: expected finite values, found {n_nan} NaN and {n_bad - n_nan} inf "
        f"(first at index {at})"
    )


def _first_true(mask: xr.Variable) -> dict:
    """The index (dim -> position, in C order) of the first True of ``mask``, found by one
    reduction per dim on ever smaller slices (a lazy mask is never materialised whole)."""
    at: dict = {}
    for dim in mask.dims:
        rest = [d for d in mask.dims if d != dim]
        counts = np.asarray(mask.sum(rest).values if rest else mask.values)
        at[dim] = int(np.flatnonzero(counts)[0])
        mask = mask.isel({dim: at[dim]})
    return at


def check_axis(
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
        check_range_axis(axis, dim, subject, problems, nonnegative=nonnegative)
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


def check_range_axis(
    axis: RangeAxis, dim: str, subject: str, problems: list[str], *, nonnegative: bool
) -> None:
    """``check_axis`` for a coordinate backed by a ``RangeIndex``: values ``start + i * step``
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


def check_points(ds: xr.Dataset, namer: Namer, problems: list[str]) -> np.ndarray | None:
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


def check_references(
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


def check_drive_point(
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


def check_quantity_units(
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


def check_empty(da: xr.DataArray, subject: str, problems: list[str]) -> bool:
    if da.size == 0:
        problems.append(f"{subject}: empty (expected at least one value, got shape {da.shape})")
        return True
    return False


def check_noise_std(
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
        check_finite(std, subject, problems)
        n_neg = int((std < 0).sum())
        if n_neg:
            problems.append(f"{subject}: expected standard deviations >= 0, found {n_neg} < 0")
