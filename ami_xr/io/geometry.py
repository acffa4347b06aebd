"""Measurement geometry (point coordinates ``point_x``/``point_y``/``point_z``): the import path
of :mod:`ami_xr.schema.geometry`, where the data model keeps it."""

from __future__ import annotations

from ami_xr.schema.geometry import (
    coordinate_arrays,
    coordinate_problems,
    has_coordinates,
    point_coordinates,
)

__all__ = ["coordinate_arrays", "coordinate_problems", "point_coordinates", "has_coordinates"]
