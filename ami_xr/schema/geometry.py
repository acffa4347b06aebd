"""Optional measurement geometry: the point coordinates ``point_x``, ``point_y``, ``point_z``.

Each is a non-dimension float coordinate on ``point`` with a ``units`` attribute (default
``"m"``). :func:`coordinate_arrays` turns what a user passes to ``make_frf_dataset(...,
coordinates=...)`` into those coordinates; :func:`coordinate_problems` is what
:func:`ami_xr.validate` checks about them when they are present.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.schema.messages import Namer

__all__ = ["coordinate_arrays", "coordinate_problems", "point_coordinates", "has_coordinates"]

_AXES = "xyz"


def _numeric(values: Any, argument: str) -> np.ndarray:
    try:
        arr = np.asarray(values)
    except (TypeError, ValueError) as err:  # pragma: no cover - ragged input
        raise AmiXrValueError(f"{argument}: expected numbers, got {values!r}") from err
    if arr.dtype.kind not in "fiu":
        raise AmiXrValueError(
            f"{argument}: expected real numbers (coordinates in the given units), got dtype "
            f"{arr.dtype}"
        )
    arr = arr.astype(np.float64)
    if not np.all(np.isfinite(arr)):
        raise AmiXrValueError(f"{argument}: expected finite values, got NaN or inf")
    return arr


def coordinate_arrays(
    coordinates: Any, n_point: int, units: str = names.COORDINATE_UNITS
) -> dict[str, tuple[str, np.ndarray, dict[str, str]]]:
    """The ``point_x/y/z`` coordinates (name -> (dim, values, attrs)) from ``coordinates``.

    Parameters
    ----------
    coordinates : array_like of shape (n_point, 1, 2 or 3), or dict
        Columns x[, y[, z]]; or a dict with keys among ``"x"``, ``"y"``, ``"z"`` (or
        ``"point_x"`` ...) mapping to ``n_point`` numbers each.
    n_point : int
        Number of points.
    units : str
        Units of the coordinates (default ``"m"``), stored as their ``units`` attribute.

    Raises
    ------
    AmiXrValueError
        Naming ``coordinates`` (and the axis) for a wrong shape, key or non-finite value.
    """
    if not isinstance(units, str) or not units:
        raise AmiXrValueError(f"coordinate_units: expected a non-empty str, got {units!r}")
    columns: dict[str, np.ndarray] = {}
    if isinstance(coordinates, Mapping):
        for key, values in coordinates.items():
            axis = str(key).removeprefix(f"{names.POINT}_")
            if axis not in _AXES:
                raise AmiXrValueError(
                    f"coordinates: unknown key {key!r}; expected 'x', 'y' or 'z' "
                    f"(or {', '.join(names.POINT_COORDS)})"
                )
            arr = _numeric(values, f"coordinates[{key!r}]")
            if arr.shape != (n_point,):
                raise AmiXrValueError(
                    f"coordinates[{key!r}]: expected {n_point} values (one per point), got "
                    f"shape {arr.shape}"
                )
            columns[axis] = arr
        if not columns:
            raise AmiXrValueError("coordinates: expected at least one of 'x', 'y', 'z', got {}")
    else:
        arr = _numeric(coordinates, "coordinates")
        if arr.ndim == 1 and arr.shape[0] == n_point:
            arr = arr[:, None]
        if arr.ndim != 2 or arr.shape[0] != n_point or not 1 <= arr.shape[1] <= 3:
            raise AmiXrValueError(
                f"coordinates: expected shape ({n_point}, 2) or ({n_point}, 3) (columns x, y"
                f"[, z]; ({n_point},) for x only), got {arr.shape}"
            )
        columns = {_AXES[i]: arr[:, i] for i in range(arr.shape[1])}
    return {
        f"{names.POINT}_{axis}": (names.POINT, columns[axis], {names.ATTR_UNITS: units})
        for axis in _AXES
        if axis in columns
    }


def coordinate_problems(ds: xr.Dataset, namer: Namer | None = None) -> list[str]:
    """Problems of the point coordinates present in ``ds`` (none is required).

    Each present ``point_x/y/z`` must lie along ``point`` only, hold real numbers, be finite
    and carry a ``units`` string when it has one.
    """
    namer = namer or Namer()
    problems: list[str] = []
    for name in names.POINT_COORDS:
        if name not in ds.coords:
            continue
        coord = ds.coords[name]
        subject = namer.coord(name)
        if coord.dims != (names.POINT,):
            n = ds.sizes.get(names.POINT)
            problems.append(
                f"{subject}: expected one value per point, dims ({names.POINT!r},)"
                + (f" and {n} values" if n is not None else "")
                + f", got dims {coord.dims} and shape {coord.shape}"
            )
            continue
        if coord.dtype.kind not in "fiu":
            problems.append(f"{subject}: expected real numbers, got dtype {coord.dtype}")
            continue
        values = np.asarray(coord.values, dtype=np.float64)
        bad = ~np.isfinite(values)
        if bad.any():
            problems.append(
                f"{subject}: expected finite values, found {int(bad.sum())} NaN or inf "
                f"(first at point index {int(np.argmax(bad))})"
            )
        units = coord.attrs.get(names.ATTR_UNITS)
        if units is not None and not (isinstance(units, str) and units):
            problems.append(
                f"{namer.var_attr(name, names.ATTR_UNITS)}: expected a units string such as "
                f"{names.COORDINATE_UNITS!r}, got {units!r}"
            )
    return problems


def has_coordinates(ds: xr.Dataset) -> bool:
    """True when ``ds`` has at least one of ``point_x``, ``point_y``, ``point_z``."""
    return any(name in ds.coords for name in names.POINT_COORDS)


def point_coordinates(ds: xr.Dataset, figure: str) -> dict[str, np.ndarray]:
    """The point coordinates present in ``ds`` as float arrays (checked), by name.

    Raises
    ------
    AmiXrValueError
        When ``ds`` has none of them (naming point_x, point_y, point_z) or they are invalid.
    """
    if not has_coordinates(ds):
        raise AmiXrValueError(
            f"{figure}: the Dataset has no point coordinates; give {', '.join(names.POINT_COORDS)}"
            " (e.g. make_frf_dataset(..., coordinates=xyz) or ds.assign_coords(point_x=("
            "'point', x, {'units': 'm'})))"
        )
    problems = coordinate_problems(ds)
    if problems:
        raise AmiXrValueError(f"{figure}: " + "; ".join(problems))
    return {
        name: np.asarray(ds.coords[name].values, dtype=np.float64)
        for name in names.POINT_COORDS
        if name in ds.coords
    }
