"""UFF dataset 58 time records (function type 1) -> a time Dataset built by
:func:`ami_xr.make_time_dataset`: responses per DOF, the force record(s), one record per load
case (rules: :mod:`ami_xr.io.uff`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import DataFileError
from ami_xr.io.uff.codes import parse_point_label
from ami_xr.io.uff.nodes import Nodes, attach_coordinates
from ami_xr.io.uff.records import abscissa, check_same_grid, label_of, mixed_labels_to_str
from ami_xr.io.uff.units import (
    ATTR_QUANTITY_FROM_LABEL,
    UnitSystem,
    assumed_si,
    is_force,
    record_units,
    tell_assumed,
    unit_attrs,
    unit_part,
)
from ami_xr.io.units import force_unit

__all__ = ["read_time"]


def _by_case(
    records: list[dict], cases: list[int], rows: list, row_of, n_time: int, what: str, path: Path
) -> np.ndarray:
    """``(case, row, time)`` samples of ``records``; a missing (case, row) is refused."""
    out = np.full((len(cases), len(rows), n_time), np.nan)
    for r in records:
        out[cases.index(int(r.get("load_case_id", 0))), row_of(r)] = np.asarray(
            r["data"], dtype=np.float64
        )
    if np.isnan(out).any():
        raise DataFileError(f"{path}: not every {what} has a record for every load case")
    return out


def read_time(records: list[dict], nodes: Nodes, path: Path, system: UnitSystem) -> xr.Dataset:
    """The time Dataset of a file's time records: ``response`` ([record,] point, time) and
    ``force`` ([record,] time) (one record per load case)."""
    from ami_xr.io.datasets import make_time_dataset

    force_recs = [r for r in records if is_force(r)]
    resp_recs = [r for r in records if not is_force(r)]
    if not resp_recs:
        raise DataFileError(f"{path}: the time records hold no response channel (only force)")
    if not force_recs:
        dofs = sorted({str(label_of(r, "rsp")) for r in resp_recs})
        raise DataFileError(
            f"{path}: the time records (dataset 58, function type 1) hold responses at "
            f"{len(dofs)} DOF(s) {dofs[:6]}{' ...' if len(dofs) > 6 else ''} and no force record "
            "(ordinate specific data type 13 or 9, or a force unit label such as N); ami_xr "
            "estimates FRFs from a force and responses"
        )
    grids = [abscissa(r) for r in records]
    check_same_grid(records, grids, path, "time")
    time = grids[0]
    cases = sorted({int(r.get("load_case_id", 0)) for r in records})
    labels = list(dict.fromkeys(label_of(r, "rsp") for r in resp_recs))
    units = [record_units(r, path, system) for r in resp_recs]
    quantities = {(u.quantity, *u.response[:2]) for u in units}
    if len(quantities) != 1:
        raise DataFileError(f"{path}: the responses mix quantities or units {sorted(quantities)}")
    quantity, resp_units, _ = quantities.pop()
    resp_part = units[0].response
    row = {lab: k for k, lab in enumerate(labels)}
    resp = (
        _by_case(
            resp_recs,
            cases,
            labels,
            lambda r: row[label_of(r, "rsp")],
            time.size,
            "response DOF",
            path,
        )
        * resp_part[1]
    )
    labels_out = mixed_labels_to_str(labels)
    raw = force_recs[0].get("ordinate_axis_units_lab")
    force_part = unit_part(force_unit(raw), raw, "N", False, system, "force")
    drives = {label_of(r, "rsp") for r in force_recs}
    if len(drives) != 1:
        raise DataFileError(
            f"{path}: force records at several DOFs {sorted(map(str, drives))}; "
            "expected one drive point"
        )
    force = _by_case(force_recs, cases, [0], lambda r: 0, time.size, "force", path)
    force = force[:, 0] * force_part[1]
    drive = drives.pop()
    drive = str(drive) if isinstance(labels_out[0], str) else drive
    one = len(cases) == 1
    attrs = {names.ATTR_SOURCE_FILE: path.name}
    assumed = assumed_si((resp_part, force_part))
    attrs.update(unit_attrs(assumed, "; ".join(p[3] for p in (resp_part, force_part) if p[3])))
    if assumed:
        tell_assumed(path, assumed)
    from_label = next((u.from_label for u in units if u.from_label), "")
    if from_label:
        attrs[ATTR_QUANTITY_FROM_LABEL] = from_label
    ds = make_time_dataset(
        resp[0] if one else resp,
        time,
        force=force[0] if one else force,
        points=labels_out,
        response_quantity=quantity,
        response_units=resp_units,
        force_units=force_part[0],
        **attrs,
    )
    ds.attrs[names.ATTR_DRIVE_POINT] = drive  # after the check: an unmeasured DOF is allowed
    label_nodes = {lab: parse_point_label(lab)[0] for lab in labels_out if parse_point_label(lab)}
    return attach_coordinates(ds, nodes, label_nodes)
