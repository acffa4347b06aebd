"""UFF dataset 58 FRF records (function type 4) and their coherence (type 6) -> an FRF Dataset,
built by :func:`ami_xr.make_frf_dataset` (single reference, roving hammer or multi-reference;
rules: :mod:`ami_xr.io.uff`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import DataFileError
from ami_xr.io.uff.nodes import Nodes, attach_coordinates
from ami_xr.io.uff.records import (
    MULTI_REFERENCE_LAYOUT,
    abscissa,
    check_same_grid,
    id_lines,
    label_of,
    mixed_labels_to_str,
    multi_reference,
    single_reference,
)
from ami_xr.io.uff.units import (
    ATTR_QUANTITY_FROM_LABEL,
    UnitSystem,
    record_units,
    tell_assumed,
    unit_attrs,
)

__all__ = ["read_frf"]


def _units(frfs: list[dict], path: Path, system: UnitSystem) -> tuple[tuple, float, dict]:
    """``((quantity, response units, force units), scale to SI, attributes)`` shared by every
    record; records that disagree are refused."""
    units = [record_units(r, path, system) for r in frfs]
    keys = {u.key for u in units}
    if len(keys) != 1:
        raise DataFileError(
            f"{path}: the FRFs mix response quantities or units {sorted(keys)}; expected one"
        )
    quantity, resp_units, resp_scale, force_units, force_scale = keys.pop()
    assumed = next((u.assumed for u in units if u.assumed), "")
    attrs = unit_attrs(assumed, next((u.scaled for u in units if u.scaled), ""))
    from_label = next((u.from_label for u in units if u.from_label), "")
    if from_label:
        attrs[ATTR_QUANTITY_FROM_LABEL] = from_label
    if assumed:
        tell_assumed(path, assumed)
    return (quantity, resp_units, force_units), resp_scale / force_scale, attrs


def _layout(frfs: list[dict], path: Path) -> tuple[list, list | None, Any, list, str, dict]:
    """``(points, references or None, drive point, (reference, point) index per record, layout,
    node of each point label)``."""
    multi = multi_reference(frfs, path)
    if multi is not None:
        points, refs, index = multi
        nodes = {points[i]: int(r["rsp_node"]) for r, (_, i) in zip(frfs, index, strict=True)}
        return points, refs, None, index, MULTI_REFERENCE_LAYOUT, nodes
    labels, drive, layout = single_reference(frfs, path)
    if len(set(labels)) != len(labels):
        raise DataFileError(
            f"{path}: the FRF records repeat a DOF ({labels}); expected one per point"
        )
    key = "ref" if layout.startswith("roving") else "rsp"
    points = mixed_labels_to_str(labels)
    nodes = {out: int(r[f"{key}_node"]) for out, r in zip(points, frfs, strict=True)}
    drive = str(drive) if isinstance(points[0], str) else drive
    index = [(0, i) for i in range(len(points))]
    return points, None, drive, index, layout, nodes


def _coherence(coh: list[dict], points: list, n_frequency: int) -> np.ndarray | None:
    """The coherence (point, frequency) of records of one reference (or one response: a roving
    hammer) over the FRFs' points (with several references the multiple coherence, as
    :func:`~ami_xr.io.uff.write_uff` writes it), else None."""
    rsp, ref = ([label_of(r, key) for r in coh] for key in ("rsp", "ref"))
    if not coh or (len(set(ref)) != 1 and len(set(rsp)) != 1):
        return None
    labels = mixed_labels_to_str(rsp if len(set(ref)) == 1 else ref)  # roving hammer: refs
    if sorted(map(str, labels)) != sorted(map(str, points)):
        return None
    by_label = {str(lab): np.asarray(r["data"]).real for lab, r in zip(labels, coh, strict=True)}
    values = np.stack([by_label[str(lab)] for lab in points])
    return values if values.shape == (len(points), n_frequency) else None


def read_frf(
    frfs: list[dict], coh: list[dict], nodes: Nodes, path: Path, system: UnitSystem
) -> xr.Dataset:
    """The FRF Dataset of a file's FRF records (``frf`` (point, frequency), or (reference,
    point, frequency) for multi-reference records) with its coherence and coordinates."""
    from ami_xr.io.datasets import make_frf_dataset

    points, refs, drive, index, layout, label_nodes = _layout(frfs, path)
    (quantity, resp_units, force_units), scale, attrs = _units(frfs, path, system)
    grids = [abscissa(r) for r in frfs]
    check_same_grid(frfs, grids, path, "FRF")
    freq = grids[0]
    shape = (len(refs or [0]), len(points), freq.size)
    values = np.empty(shape, dtype=np.complex128)
    for r, (j, i) in zip(frfs, index, strict=True):
        values[j, i] = np.asarray(r["data"], dtype=np.complex128)
    if scale != 1.0:
        values = values * scale
    ds = make_frf_dataset(
        values if refs is not None else values[0],
        freq,
        points=points,
        references=refs,
        response_quantity=quantity,
        response_units=resp_units,
        force_units=force_units,
        **{names.ATTR_SOURCE_FILE: path.name, "uff_layout": layout, **attrs},
    )
    if drive is not None:  # set after the check: a drive point that was not measured is allowed
        ds.attrs = {names.ATTR_DRIVE_POINT: drive, **ds.attrs}
    if refs is None:  # one record per point: its ID lines kept for a round trip
        lines, title = id_lines(frfs)
        ds = ds.assign_coords({k: (names.POINT, v) for k, v in lines.items()})
        if title is not None:
            ds.attrs.setdefault("title", title)
    coherence = _coherence(coh, points, freq.size)
    if coherence is not None:
        units = {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}
        ds[names.COHERENCE] = ((names.POINT, names.FREQUENCY), coherence, units)
    return attach_coordinates(ds, nodes, label_nodes)
