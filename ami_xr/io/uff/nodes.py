"""UFF node coordinates: datasets 15 and 2411 <-> the ``point_x``, ``point_y``, ``point_z``
coordinates (in metres, dataset 164's length factor applied, Cartesian coordinate systems of
datasets 2420 and 18 applied; other systems refused naming the dataset and the node).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AssumptionWarning, DataFileError
from ami_xr.io.uff.codes import dof_map
from ami_xr.io.uff.units import ATTR_UNITS_SCALED, UnitSystem

__all__ = ["NODE_DATASETS", "Nodes", "attach_coordinates", "node_coordinates", "node_records"]


#: The node datasets read and written: 15 (single precision, about 6 digits) and 2411 (double).
NODE_DATASETS = (15, 2411)
#: Coordinate-system types of datasets 2420 and 18 (only Cartesian systems are applied).
CS_TYPES = {0: "Cartesian", 1: "cylindrical", 2: "spherical"}


@dataclass(frozen=True)
class _System:
    """A coordinate system: global = origin + local @ axes (rows: the local X, Y, Z axes in
    global coordinates), or why it cannot be applied."""

    origin: np.ndarray
    axes: np.ndarray
    refused: str = ""

    @property
    def rotated(self) -> bool:
        return not np.allclose(self.axes, np.eye(3), atol=1e-6)


@dataclass(frozen=True)
class Nodes:
    """Node coordinates of datasets 15 and 2411 in metres (global), how they were converted, and
    the nodes whose displacements are in a rotated coordinate system."""

    xyz: dict[int, tuple[float, float, float]]
    scaled: str = ""  # "point coordinates length / 1000 (dataset 164: ...)", or ""
    local_dofs: dict[int, str] = field(default_factory=dict)  # node -> why its DOFs are local
    path: Path | None = None  # the file, for messages


def _systems(sets: list[dict], factor: float) -> dict[int, _System]:
    """The coordinate systems of datasets 2420 (a transformation matrix: rows 1-3 the local
    axes, row 4 the origin) and 18 (an origin, a point on +X and a point in the XZ plane, in a
    reference system), origins in metres."""
    out: dict[int, _System] = {0: _System(np.zeros(3), np.eye(3))}
    for s in sets:
        if s.get("type") == 2420:
            for label, kind, matrix in zip(
                s["CS_sys_labels"], s["CS_types"], s["CS_matrices"], strict=False
            ):
                m = np.asarray(matrix, dtype=np.float64)
                why = "" if int(kind) == 0 else CS_TYPES.get(int(kind), f"type {kind}")
                out[int(label)] = _System(m[3] / factor, m[:3], why)
    for s in sets:
        if s.get("type") == 18:
            rows = zip(
                s["cs_num"],
                s["cs_type"],
                s["ref_cs_num"],
                s["ref_o"],
                s["x_point"],
                s["xz_point"],
                strict=False,
            )
            for label, kind, ref, o, xp, xzp in rows:
                out[int(label)] = _from_points(int(kind), out.get(int(ref)), o, xp, xzp, factor)
    return out


def _from_points(kind: int, ref: _System | None, o, xp, xzp, factor: float) -> _System:
    """A dataset-18 system from its three points (in its reference system ``ref``)."""
    o, xp, xzp = (np.asarray(v, dtype=np.float64) / factor for v in (o, xp, xzp))
    why = "" if kind == 0 else CS_TYPES.get(kind, f"type {kind}")
    if ref is None or ref.refused:
        why = why or "defined in a reference system the file does not define or apply"
        return _System(np.zeros(3), np.eye(3), why)
    x = xp - o
    v = xzp - o
    z = v - (v @ x) / (x @ x) * x
    if np.linalg.norm(x) == 0 or np.linalg.norm(z) == 0:
        return _System(np.zeros(3), np.eye(3), why or "its three points do not span a plane")
    x, z = x / np.linalg.norm(x), z / np.linalg.norm(z)
    axes = np.array([x, np.cross(z, x), z]) @ ref.axes  # local axes in global
    return _System(ref.origin + o @ ref.axes, axes, why)


def node_coordinates(sets: list[dict], system: UnitSystem, path: Path | None = None) -> Nodes:
    """The coordinates of every node in metres in the global system: dataset 164's length
    factor applied (the units of the whole file, node coordinates included), and a node defined
    in a Cartesian coordinate system of dataset 2420 or 18 moved to global coordinates.

    Raises
    ------
    DataFileError
        A node defined in a coordinate system the file does not define, or in a cylindrical or
        spherical one (named with the dataset and the node).
    """
    factor = 1.0 if system.length_is_si else system.length
    systems = _systems(sets, factor)
    xyz: dict[int, tuple[float, float, float]] = {}
    local: dict[int, str] = {}
    for s in sets:
        if s.get("type") not in NODE_DATASETS:
            continue
        n_nodes = len(s["node_nums"])
        def_cs = np.asarray(s.get("def_cs", np.zeros(n_nodes)), dtype=int)
        disp_cs = np.asarray(s.get("disp_cs", np.zeros(n_nodes)), dtype=int)
        for k, n in enumerate(s["node_nums"]):
            point = np.array([s["x"][k], s["y"][k], s["z"][k]], dtype=np.float64) / factor
            cs = _system_of(systems, int(def_cs[k]), s["type"], int(n), path)
            xyz[int(n)] = tuple(float(v) for v in cs.origin + point @ cs.axes)
            shown = systems.get(int(disp_cs[k]))
            if shown is None or shown.refused or shown.rotated:
                local[int(n)] = (
                    f"dataset {s['type']}: node {int(n)} has its displacements in coordinate "
                    f"system {int(disp_cs[k])}, "
                    + ("which the file does not define" if shown is None else "a rotated one")
                )
    scaled = f"point coordinates {system.scaled(True)}" if xyz and factor != 1.0 else ""
    return Nodes(xyz, scaled, local, path)


def _system_of(systems: dict, label: int, dataset: int, node: int, path: Path | None) -> _System:
    cs = systems.get(label)
    if cs is None or cs.refused:
        why = "which no dataset 2420 or 18 defines" if cs is None else f"({cs.refused})"
        raise DataFileError(
            f"{path}: dataset {dataset}: node {node} is defined in coordinate system {label} "
            f"{why}; ami_xr applies Cartesian systems of datasets 2420 and 18 -- export the "
            "geometry in global (or Cartesian) coordinates"
        )
    return cs


def attach_coordinates(ds: xr.Dataset, nodes: Nodes, label_nodes: dict) -> xr.Dataset:
    """``point_x/y/z`` of the points on known nodes; a point on a node whose displacements are
    in a rotated coordinate system is refused (its DOF direction is not the global one its
    label says).

    Raises
    ------
    DataFileError
        A point's node has its displacements in a rotated or undefined coordinate system.
    """
    for label in ds[names.POINT].values.tolist():
        why = nodes.local_dofs.get(label_nodes.get(label))
        if why is not None:
            raise DataFileError(
                f"{nodes.path}: {why}: the direction of point {label!r} is not the global one its "
                "label names; ami_xr reads DOFs in the global system -- export the data with "
                "global displacement directions"
            )
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


# Length units of point_x/y/z that datasets 15 and 2411 (written in metres) can take, as metres
# per unit.
_METRES_PER_UNIT = {"m": 1.0, "": 1.0, "mm": 1e-3, "cm": 1e-2, "in": 0.0254}


def node_records(ds: xr.Dataset, dataset: int = 2411) -> list[dict]:
    """One dataset 2411 (or 15) with the coordinates of the points' nodes (in metres, global
    system), when they have any.

    Dataset 2411 stores double precision (D25.16), dataset 15 about 6 significant digits
    (E13.5). Coordinates that cannot be written truthfully (unknown length units, two DOFs of
    one node at different places) are left out with a warning rather than written wrong.
    """
    present = [c for c in names.POINT_COORDS if c in ds.coords]
    if not present:
        return []
    labels = list(ds[names.POINT].values.tolist())
    dof = dof_map(labels)
    xyz = np.zeros((len(labels), 3))
    for c in present:
        units = str(ds[c].attrs.get(names.ATTR_UNITS, "m"))
        if units not in _METRES_PER_UNIT:
            warnings.warn(
                f"write_uff: coordinate {c!r} has units {units!r}, not a length dataset "
                f"{dataset} can take ({', '.join(u for u in _METRES_PER_UNIT if u)}); node "
                "coordinates not written",
                AssumptionWarning,
                stacklevel=3,
            )
            return []
        xyz[:, names.POINT_COORDS.index(c)] = (
            np.asarray(ds[c].values, dtype=np.float64) * _METRES_PER_UNIT[units]
        )
    nodes: dict[int, np.ndarray] = {}
    for i, lab in enumerate(labels):
        node = dof[lab][0]
        if node in nodes and not np.allclose(nodes[node], xyz[i], rtol=1e-12, atol=0.0):
            warnings.warn(
                f"write_uff: point {lab!r} shares node {node} with another point at other "
                "coordinates; node coordinates not written",
                AssumptionWarning,
                stacklevel=3,
            )
            return []
        nodes[node] = xyz[i]
    order = sorted(nodes)
    zeros = np.zeros(len(order), dtype=np.int64)
    return [
        {
            "type": dataset,
            "node_nums": np.asarray(order),
            "def_cs": zeros,
            "disp_cs": zeros,
            "color": zeros,
            **{axis: np.array([nodes[n][j] for n in order]) for j, axis in enumerate("xyz")},
        }
    ]
