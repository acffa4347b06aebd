"""UFF node coordinates: datasets 15 and 2411 -> the ``point_x``, ``point_y``, ``point_z``
coordinates (in metres, dataset 164's length factor applied).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.io.uff.units import ATTR_UNITS_SCALED, UnitSystem

__all__ = ["Nodes", "attach_coordinates", "node_coordinates"]


@dataclass(frozen=True)
class Nodes:
    """Node coordinates of datasets 15 and 2411 in metres, and how they were converted."""

    xyz: dict[int, tuple[float, float, float]]
    scaled: str = ""  # "point coordinates length / 1000 (dataset 164: ...)", or ""


def node_coordinates(sets: list[dict], system: UnitSystem) -> Nodes:
    """The coordinates of every node, converted to metres by the length factor of dataset 164
    (the units of the whole file, node coordinates included)."""
    factor = 1.0 if system.length_is_si else system.length
    xyz: dict[int, tuple[float, float, float]] = {}
    for s in sets:
        if s.get("type") in (15, 2411):
            for n, x, y, z in zip(s["node_nums"], s["x"], s["y"], s["z"], strict=False):
                xyz[int(n)] = (float(x) / factor, float(y) / factor, float(z) / factor)
    scaled = f"point coordinates {system.scaled(True)}" if xyz and factor != 1.0 else ""
    return Nodes(xyz, scaled)


def attach_coordinates(ds: xr.Dataset, nodes: Nodes, label_nodes: dict) -> xr.Dataset:
    if not nodes.xyz:
        return ds
    labels = ds[names.POINT].values
    if not all(label_nodes.get(lab) in nodes.xyz for lab in labels):
        return ds
    xyz = np.array([nodes.xyz[label_nodes[lab]] for lab in labels])
    attrs = {names.ATTR_UNITS: names.COORDINATE_UNITS}
    if nodes.scaled:
        attrs[ATTR_UNITS_SCALED] = nodes.scaled
    ds = ds.assign_coords(
        {coord: (names.POINT, xyz[:, i], dict(attrs)) for i, coord in enumerate(names.POINT_COORDS)}
    )
    if not nodes.scaled:
        return ds
    before = ds.attrs.get(ATTR_UNITS_SCALED)
    how = f"{before}; {nodes.scaled}" if before else f"values converted to SI: {nodes.scaled}"
    return ds.assign_attrs({ATTR_UNITS_SCALED: how})
