"""O(1)-memory uniform axes: build and recognise coordinates backed by xarray's ``RangeIndex``.

A lazily opened record of 1e9 samples would otherwise carry a 1e9-value pandas index (8 GB)
for its ``time`` coordinate. A ``RangeIndex`` stores only start, step and size and computes the
values it is asked for, so code on the streaming path reads the sampling from here instead of
materialising ``coord.values``.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import Any, NamedTuple

import xarray as xr
from xarray.indexes import RangeIndex  # xarray >= 2025.4

__all__ = ["RangeAxis", "range_axis", "uniform_coords"]


class RangeAxis(NamedTuple):
    """A uniform axis: value ``i`` is ``start + i * step`` for ``i`` in ``range(size)``."""

    start: float
    step: float
    size: int


def range_axis(obj: Any, dim: Hashable) -> RangeAxis | None:
    """(start, step, size) of ``obj``'s coordinate ``dim`` when a ``RangeIndex`` backs it.

    ``obj`` is a Dataset or DataArray (also the coordinate itself). None when ``dim`` has no
    index or another index (a pandas index holds its values in memory anyway). Reads no values.
    """
    index = getattr(obj, "xindexes", {}).get(dim)
    if not isinstance(index, RangeIndex) or index.dim != dim:
        return None
    return RangeAxis(float(index.start), float(index.step), int(index.size))


def uniform_coords(start: float, last: float, size: int, dim: str, attrs: dict) -> xr.Coordinates:
    """A ``RangeIndex``-backed coordinate ``dim`` of ``size`` values from ``start`` to ``last``.

    Built with ``RangeIndex.linspace`` (not ``arange``): the size is exactly ``size`` whatever
    the float rounding of ``(last - start) / step``. Value ``i`` is ``start + i * step`` with
    ``step = (last - start) / (size - 1)`` to rounding.
    """
    index = RangeIndex.linspace(start, last, size, endpoint=True, dim=dim)
    coords = xr.Coordinates.from_xindex(index)
    coords[dim].attrs.update(attrs)
    return coords
