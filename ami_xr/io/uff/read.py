"""Read UFF files: dataset 58 FRFs and time histories, 55 mode shapes, 15/2411 node coordinates.

See :mod:`ami_xr.io.uff` for the mapping to ami_xr Datasets.
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import errors, names
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.uff.codes import (
    FUNC_COHERENCE,
    FUNC_FRF,
    FUNC_TIME,
    ID_TAG,
    KNOWN_UNIT_ALIASES,
    SI_UNITS,
    SPEC_FORCE,
    SPEC_TO_QUANTITY,
    parse_point_label,
    point_label,
)
from ami_xr.io.uff.modes import (
    ATTR_MODES_SKIPPED,
    MODE_ANALYSIS_TYPES,
    read_modes,
    with_modes,
)
from ami_xr.io.uff.sets import read_sets

__all__ = [
    "read_uff",
    "ATTR_UNITS_ASSUMED",
    "ATTR_UNITS_SCALED",
    "ATTR_MODES_SKIPPED",
    "ATTR_QUANTITY_FROM_LABEL",
]

ATTR_UNITS_ASSUMED = "uff_units_assumed"  # why SI units were assumed (no usable unit labels)
ATTR_UNITS_SCALED = "uff_units_scaled"  # how values were converted to SI by dataset 164
# the response quantity taken from the unit label (ordinate specific data type 0 or 1)
ATTR_QUANTITY_FROM_LABEL = "uff_quantity_from_label"
# the warning class for assumptions (AssumptionWarning where ami_xr.errors has it)
_ASSUMPTION = errors.AssumptionWarning


def _label_of(record: dict, which: str) -> Any:
    """Point label of the response (``which="rsp"``) or reference DOF of a dataset-58 record."""
    tag = str(record.get("id2", ""))
    if which == "rsp" and tag.startswith(ID_TAG):
        return tag[len(ID_TAG) :]
    if which == "ref":
        tag3 = str(record.get("id3", ""))
        if tag3.startswith(ID_TAG):
            return tag3[len(ID_TAG) :]
    return point_label(record[f"{which}_node"], record[f"{which}_dir"])


# --- units -----------------------------------------------------------------------------------
_SUPERSCRIPTS = {"²": "^2", "³": "^3", "**": "^"}
_RESPONSE_UNIT_QUANTITY = {u: q for q, units in names.RESPONSE_UNITS.items() for u in units}
# an FRF unit in one label: "m/s^2/N", "(m/s^2)/N", "(1/N)*(m/s^2)", "(m/s^2)*(1/N)"
_FRF_LABELS = (
    re.compile(r"^\(?1/(?P<f>[^()*/]+)\)?\*\(?(?P<r>[^()*]+?)\)?$"),
    re.compile(r"^\(?(?P<r>[^()*]+?)\)?\*\(?1/(?P<f>[^()*/]+)\)?$"),
    re.compile(r"^\((?P<r>[^()*]+)\)/\(?(?P<f>[^()*/]+?)\)?$"),
    re.compile(r"^(?P<r>[^()*]+)/(?P<f>[^()*/]+)$"),
)


def _unit_label(raw: Any, allowed: Sequence[str]) -> str | None:
    """The known unit a label names (case-insensitive: ``"G"`` is ``"g"``; ``"m/s²"`` is
    ``"m/s^2"``), else None."""
    text = "".join(str(raw or "").split())
    if not text or text.upper() == "NONE":
        return None
    for sign, plain in _SUPERSCRIPTS.items():
        text = text.replace(sign, plain)
    text = KNOWN_UNIT_ALIASES.get(text.lower(), text)
    by_lower = {a.lower(): a for a in allowed}
    return text if text in allowed else by_lower.get(text.lower())


def _ordinate_units(raw: Any) -> tuple[str | None, str | None]:
    """(response unit, force unit) an ordinate label names: ``"m/s^2" -> ("m/s^2", None)``,
    ``"(1/N)*(m/s²)" -> ("m/s^2", "N")``; None for what it does not name."""
    response = _unit_label(raw, tuple(_RESPONSE_UNIT_QUANTITY))
    if response is not None:
        return response, None
    text = "".join(str(raw or "").split())
    for pattern in _FRF_LABELS:
        match = pattern.match(text)
        if match is None:
            continue
        response = _unit_label(match["r"], tuple(_RESPONSE_UNIT_QUANTITY))
        force = _unit_label(match["f"], names.FORCE_UNITS)
        if response is not None and force is not None:
            return response, force
    return None, None


class _System:
    """Dataset 164 of a file: factors that convert its length and force units to SI
    (SI value = file value / factor, as the UFF specification defines them)."""

    def __init__(self, record: dict | None):
        self.given = record is not None
        record = record or {}
        self.length = float(record.get("length", 1.0) or 1.0)
        self.force = float(record.get("force", 1.0) or 1.0)
        self.name = str(record.get("units_description", "") or "").strip() or (
            f"units code {record.get('units_code', '?')}"
        )

    @property
    def is_si(self) -> bool:
        return np.isclose(self.length, 1.0, rtol=1e-6) and np.isclose(self.force, 1.0, rtol=1e-6)

    @property
    def length_is_si(self) -> bool:
        return bool(np.isclose(self.length, 1.0, rtol=1e-6))

    def scaled(self, length: bool) -> str:
        factor = self.length if length else self.force
        what = "length" if length else "force"
        return f"{what} / {factor:.10g} (dataset 164: {self.name})"


def _units_system(sets: list[dict]) -> _System:
    found = [s for s in sets if s.get("type") == 164]
    return _System(found[0] if found else None)


def _part(label: str | None, raw: Any, si: str, is_length: bool, system: _System, part: str):
    """(units, scale to SI, why assumed or "", how scaled or "") of one side of a record whose
    unit label names the known unit ``label`` (None: none)."""
    if label is not None:
        return label, 1.0, "", ""
    raw = str(raw or "").strip()
    if system.given:
        factor = system.length if is_length else system.force
        how = "" if system.is_si else f"{part} {system.scaled(is_length)}"
        return si, 1.0 / factor, "", how
    shown = f"unknown unit label {raw!r}" if raw and raw.upper() != "NONE" else "no label"
    return si, 1.0, f"{part} in {si} ({shown})", ""


def _assumed_si(parts: Sequence[tuple]) -> str:
    """Why SI was assumed for the parts (from :func:`_part`) that found no units, or ""."""
    assumed = [p[2] for p in parts if p[2]]
    if not assumed:
        return ""
    return (
        "the file gives no usable unit label and no units dataset (164); assumed SI: "
        + ", ".join(assumed)
    )


@dataclass(frozen=True)
class _Units:
    """Quantity and units of a dataset-58 record (see :func:`_record_units`)."""

    quantity: str
    response: tuple  # (units, scale to SI, why assumed or "", how scaled or "")
    force: tuple  # the same for the force
    from_label: str = ""  # how the quantity came from the unit label, or ""
    key: tuple = field(init=False)  # what must agree between the records of one Dataset

    def __post_init__(self):
        key = (self.quantity, *self.response[:2], *self.force[:2])
        object.__setattr__(self, "key", key)

    @property
    def assumed(self) -> str:
        return _assumed_si((self.response, self.force))

    @property
    def scaled(self) -> str:
        return "; ".join(p[3] for p in (self.response, self.force) if p[3])


def _dof_text(record: dict) -> str:
    return f"DOF {record.get('rsp_node')}/{record.get('rsp_dir')}"


def _record_quantity(record: dict, path: Path, response: str | None) -> tuple[str, str]:
    """Response quantity of a record and, when the unit label gave it, how."""
    spec = int(record.get("ordinate_spec_data_type", 0))
    if spec in SPEC_TO_QUANTITY:
        return SPEC_TO_QUANTITY[spec], ""
    if spec in (0, 1) and response is not None:
        quantity = _RESPONSE_UNIT_QUANTITY[response]
        how = (
            f"ordinate specific data type {spec} ({'unknown' if spec == 0 else 'general'}): "
            f"{quantity} from the unit label {response!r}"
        )
        return quantity, how
    label = str(record.get("ordinate_axis_units_lab", "") or "").strip()
    raise DataFileError(
        f"{path}: dataset 58 record of {_dof_text(record)} has ordinate specific data type "
        f"{spec} and unit label {label!r}, which name no response quantity; expected data type "
        "8 (displacement), 11 (velocity) or 12 (acceleration), or type 0/1 with a unit label "
        "such as m, m/s, m/s^2 or g (alone or over a force, as m/s^2/N)"
    )


def _record_units(record: dict, path: Path, system: _System | None = None) -> _Units:
    """Quantity and units of a dataset-58 record.

    The quantity comes from the ordinate's specific data type (8, 11, 12), or, for type 0
    (unknown) or 1 (general), from a unit label that names one. A known unit label wins (the
    ordinate label may hold the whole FRF unit, ``"(1/N)*(m/s²)"``); without one, dataset 164
    (when present) gives the units and the values are scaled to SI; without both, SI is assumed
    and the reason is kept."""
    response, label_force = _ordinate_units(record.get("ordinate_axis_units_lab"))
    quantity, from_label = _record_quantity(record, path, response)
    if response is not None and _RESPONSE_UNIT_QUANTITY[response] != quantity:
        response = None  # a unit of another quantity than the data type says: not usable
    force = _unit_label(record.get("orddenom_axis_units_lab"), names.FORCE_UNITS)
    if force is not None and label_force is not None and force != label_force:
        raise DataFileError(
            f"{path}: dataset 58 record of {_dof_text(record)}: the ordinate label "
            f"{record.get('ordinate_axis_units_lab')!r} is per {label_force} but the denominator "
            f"label is {force!r}; expected one force unit"
        )
    system = system or _System(None)
    raw = record.get("ordinate_axis_units_lab")
    return _Units(
        quantity,
        _part(response, raw, SI_UNITS[quantity], True, system, "response"),
        _part(
            force or label_force,
            record.get("orddenom_axis_units_lab"),
            "N",
            False,
            system,
            "force",
        ),
        from_label,
    )


def _tell_assumed(path: Path, why: str) -> None:
    warnings.warn(
        f"{path.name}: {why}; check the FRF units (attribute {ATTR_UNITS_ASSUMED})",
        _ASSUMPTION,
        stacklevel=4,
    )


def _abscissa(record: dict) -> np.ndarray:
    n = len(record["data"])
    if int(record.get("abscissa_spacing", 0)) != 1:
        return np.asarray(record["x"], dtype=np.float64)
    start, inc = float(record["abscissa_min"]), float(record["abscissa_inc"])
    # The header keeps ~6 significant digits (E13.5): dt = 1/1024 s is written 9.76562e-04.
    # When 1/inc is within that precision of an integer (a sampling rate in Hz, a record length
    # in s), use the exact reciprocal so time and frequency axes survive a round trip.
    if inc > 0:
        rate = 1.0 / inc
        nearest = round(rate)
        if nearest >= 1 and abs(rate - nearest) <= 2e-5 * rate:
            inc = 1.0 / nearest
    return start + inc * np.arange(n)


# --- reading ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Nodes:
    """Node coordinates of datasets 15 and 2411 in metres, and how they were converted."""

    xyz: dict[int, tuple[float, float, float]]
    scaled: str = ""  # "point coordinates length / 1000 (dataset 164: ...)", or ""


def _node_coordinates(sets: list[dict], system: _System) -> _Nodes:
    """The coordinates of every node, converted to metres by the length factor of dataset 164
    (the units of the whole file, node coordinates included)."""
    factor = 1.0 if system.length_is_si else system.length
    xyz: dict[int, tuple[float, float, float]] = {}
    for s in sets:
        if s.get("type") in (15, 2411):
            for n, x, y, z in zip(s["node_nums"], s["x"], s["y"], s["z"], strict=False):
                xyz[int(n)] = (float(x) / factor, float(y) / factor, float(z) / factor)
    scaled = f"point coordinates {system.scaled(True)}" if xyz and factor != 1.0 else ""
    return _Nodes(xyz, scaled)


def _attach_coordinates(ds: xr.Dataset, nodes: _Nodes, label_nodes: dict) -> xr.Dataset:
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


def _single_reference(records: list[dict], path: Path) -> tuple[list, Any, str]:
    """Point labels, drive point and layout of a set of FRF-like records (see module docs)."""
    rsp = [_label_of(r, "rsp") for r in records]
    ref = [_label_of(r, "ref") for r in records]
    if len(set(ref)) == 1:
        return rsp, ref[0], "fixed reference: points are the response DOFs"
    if len(set(rsp)) == 1:
        return (
            ref,
            rsp[0],
            (
                "roving hammer: one response DOF, several references; by reciprocity the "
                "points are the reference DOFs and the drive point is the response DOF"
            ),
        )
    raise DataFileError(
        f"{path}: the FRFs have {len(set(rsp))} response and {len(set(ref))} reference DOFs; "
        "ami_xr reads single-reference data (one reference, or one response with a roving "
        "hammer) -- split the file by reference"
    )


def _mixed_labels_to_str(labels: list) -> list:
    # netCDF needs one label type per coordinate.
    if all(isinstance(lab, int) for lab in labels) or all(isinstance(lab, str) for lab in labels):
        return labels
    return [str(lab) for lab in labels]


def _check_same_grid(records: list[dict], grids: list[np.ndarray], path: Path, what: str):
    first = grids[0]
    for r, g in zip(records, grids, strict=True):
        if g.shape != first.shape or not np.allclose(g, first, rtol=1e-9, atol=0):
            raise DataFileError(
                f"{path}: {what} record of DOF {r.get('rsp_node')}/{r.get('rsp_dir')} has a "
                f"different abscissa ({g.size} values from {g[0]:g}) than the first record "
                f"({first.size} values from {first[0]:g}); all records must share one grid"
            )


MULTI_REFERENCE_LAYOUT = (
    "multi-reference: several response and several reference DOFs; points are the response "
    "DOFs, references the reference DOFs (a reference on a point is its drive point)"
)


def _multi_reference(records: list[dict], path: Path) -> tuple[list, list, list] | None:
    """Points, references and, per record, its (reference, point) index pair of FRF records
    with several responses and several references; None for single-reference records.

    Every (reference, response) pair must appear exactly once.
    """
    rsp = [_label_of(r, "rsp") for r in records]
    ref = [_label_of(r, "ref") for r in records]
    if len(set(rsp)) == 1 or len(set(ref)) == 1:
        return None
    both = _mixed_labels_to_str(rsp + ref)  # one label type for points and references
    rsp, ref = both[: len(rsp)], both[len(rsp) :]
    points, refs = list(dict.fromkeys(rsp)), list(dict.fromkeys(ref))
    pairs = list(zip(ref, rsp, strict=True))
    dup = sorted({p for p in pairs if pairs.count(p) > 1}, key=str)
    missing = [(a, b) for a in refs for b in points if (a, b) not in set(pairs)]
    if dup or missing:
        what = f"repeat (reference, response) pairs {dup[:8]}" if dup else ""
        if missing:
            what += (
                (" and " if what else "")
                + f"lack the pairs {missing[:8]}"
                + (f" and {len(missing) - 8} more" if len(missing) > 8 else "")
            )
        raise DataFileError(
            f"{path}: multi-reference FRFs ({len(refs)} references x {len(points)} responses) "
            f"{what}; expected one FRF per (reference, response) pair"
        )
    index = [(refs.index(a), points.index(b)) for a, b in pairs]
    return points, refs, index


def _read_frf(
    frfs: list[dict], coh: list[dict], nodes: _Nodes, path: Path, system: _System
) -> xr.Dataset:
    multi = _multi_reference(frfs, path)
    if multi is None:
        labels, drive, layout = _single_reference(frfs, path)
        if len(set(labels)) != len(labels):
            raise DataFileError(
                f"{path}: the FRF records repeat a DOF ({labels}); expected one per point"
            )
    units = [_record_units(r, path, system) for r in frfs]
    keys = {u.key for u in units}
    if len(keys) != 1:
        raise DataFileError(
            f"{path}: the FRFs mix response quantities or units {sorted(keys)}; expected one"
        )
    quantity, resp_units, resp_scale, force_units, force_scale = keys.pop()
    assumed = next((u.assumed for u in units if u.assumed), "")
    attrs = _unit_attrs(assumed, next((u.scaled for u in units if u.scaled), ""))
    from_label = next((u.from_label for u in units if u.from_label), "")
    if from_label:
        attrs[ATTR_QUANTITY_FROM_LABEL] = from_label
    grids = [_abscissa(r) for r in frfs]
    _check_same_grid(frfs, grids, path, "FRF")
    freq = grids[0]
    data = np.stack([np.asarray(r["data"], dtype=np.complex128) for r in frfs])
    if resp_scale != 1.0 or force_scale != 1.0:
        data = data * (resp_scale / force_scale)
    if assumed:
        _tell_assumed(path, assumed)
    if multi is not None:
        ds, label_nodes = _read_multi_reference(
            frfs, data, multi, freq, (quantity, resp_units, force_units), coh, path
        )
        return _attach_coordinates(ds.assign_attrs(attrs), nodes, label_nodes)
    label_nodes = {}
    for r, lab in zip(frfs, labels, strict=True):
        key = "ref" if layout.startswith("roving") else "rsp"
        label_nodes[lab] = int(r[f"{key}_node"])
    labels_out = _mixed_labels_to_str(labels)
    label_nodes = {out: label_nodes[lab] for out, lab in zip(labels_out, labels, strict=True)}
    if isinstance(labels_out[0], str):
        drive = str(drive)
    ds = xr.Dataset(
        {
            names.FRF: (
                (names.POINT, names.FREQUENCY),
                data,
                {names.ATTR_UNITS: names.frf_units(resp_units, force_units)},
            )
        },
        coords={
            names.POINT: labels_out,
            names.FREQUENCY: (names.FREQUENCY, freq, {names.ATTR_UNITS: names.FREQUENCY_UNITS}),
        },
        attrs={
            names.ATTR_DRIVE_POINT: drive,
            names.ATTR_QUANTITY: quantity,
            names.ATTR_FRF_TYPE: names.QUANTITY_TO_FRF_TYPE[quantity],
            names.ATTR_RESPONSE_UNITS: resp_units,
            names.ATTR_FORCE_UNITS: force_units,
            names.ATTR_SOURCE: names.SOURCE_MEASURED,
            names.ATTR_SOURCE_FILE: path.name,
            "uff_layout": layout,
            **attrs,
        },
    )
    if coh:
        coh_labels, _, _ = _single_reference(coh, path)
        coh_labels = _mixed_labels_to_str(coh_labels)
        if sorted(map(str, coh_labels)) == sorted(map(str, labels_out)):
            by_label = {
                str(lab): np.asarray(r["data"]).real for lab, r in zip(coh_labels, coh, strict=True)
            }
            values = np.stack([by_label[str(lab)] for lab in labels_out])
            if values.shape == data.shape:
                ds[names.COHERENCE] = (
                    (names.POINT, names.FREQUENCY),
                    values,
                    {names.ATTR_UNITS: "1"},
                )
    return _attach_coordinates(ds, nodes, label_nodes)


def _unit_attrs(assumed: str, scaled: str) -> dict:
    """The attributes recording assumed or converted units of an FRF Dataset."""
    attrs = {}
    if assumed:
        attrs[ATTR_UNITS_ASSUMED] = assumed
    if scaled:
        attrs[ATTR_UNITS_SCALED] = f"values converted to SI: {scaled}"
    return attrs


def _read_multi_reference(
    frfs: list[dict],
    data: np.ndarray,
    multi: tuple[list, list, list],
    freq: np.ndarray,
    units: tuple[str, str, str],
    coh: list[dict],
    path: Path,
) -> tuple[xr.Dataset, dict]:
    """FRF Dataset ``frf`` (reference, point, frequency) of multi-reference records, and the
    node of each point label."""
    points, refs, index = multi
    quantity, resp_units, force_units = units
    values = np.empty((len(refs), len(points), freq.size), dtype=np.complex128)
    label_nodes = {}
    for r, (j, i), row in zip(frfs, index, data, strict=True):
        values[j, i] = row
        label_nodes[points[i]] = int(r["rsp_node"])
    ds = xr.Dataset(
        {
            names.FRF: (
                (names.REFERENCE, names.POINT, names.FREQUENCY),
                values,
                {names.ATTR_UNITS: names.frf_units(resp_units, force_units)},
            )
        },
        coords={
            names.REFERENCE: refs,
            names.POINT: points,
            names.FREQUENCY: (names.FREQUENCY, freq, {names.ATTR_UNITS: names.FREQUENCY_UNITS}),
        },
        attrs={
            names.ATTR_QUANTITY: quantity,
            names.ATTR_FRF_TYPE: names.QUANTITY_TO_FRF_TYPE[quantity],
            names.ATTR_RESPONSE_UNITS: resp_units,
            names.ATTR_FORCE_UNITS: force_units,
            names.ATTR_SOURCE: names.SOURCE_MEASURED,
            names.ATTR_SOURCE_FILE: path.name,
            "uff_layout": MULTI_REFERENCE_LAYOUT,
        },
    )
    # coherence records of one reference over the same points: the multiple coherence
    # (point, frequency) as write_uff writes it; other coherence layouts are not read
    if coh and len({_label_of(r, "ref") for r in coh}) == 1:
        coh_labels = _mixed_labels_to_str([_label_of(r, "rsp") for r in coh])
        if sorted(map(str, coh_labels)) == sorted(map(str, points)):
            by_label = {
                str(lab): np.asarray(r["data"]).real for lab, r in zip(coh_labels, coh, strict=True)
            }
            coh_values = np.stack([by_label[str(lab)] for lab in points])
            if coh_values.shape == values.shape[1:]:
                ds[names.COHERENCE] = (
                    (names.POINT, names.FREQUENCY),
                    coh_values,
                    {names.ATTR_UNITS: "1"},
                )
    return ds, label_nodes


def _is_force(record: dict) -> bool:
    """A force record: specific data type 13 or 9, or 0/1 (unknown, general) with a force unit
    label."""
    spec = int(record.get("ordinate_spec_data_type", 0))
    if spec in SPEC_FORCE:
        return True
    label = _unit_label(record.get("ordinate_axis_units_lab"), names.FORCE_UNITS)
    return spec in (0, 1) and label is not None


def _read_time(records: list[dict], nodes: _Nodes, path: Path, system: _System) -> xr.Dataset:
    force_recs = [r for r in records if _is_force(r)]
    resp_recs = [r for r in records if not _is_force(r)]
    if not resp_recs:
        raise DataFileError(f"{path}: the time records hold no response channel (only force)")
    grids = [_abscissa(r) for r in records]
    _check_same_grid(records, grids, path, "time")
    time = grids[0]
    cases = sorted({int(r.get("load_case_id", 0)) for r in records})
    labels = list(dict.fromkeys(_label_of(r, "rsp") for r in resp_recs))
    units = [_record_units(r, path, system) for r in resp_recs]
    quantities = {(u.quantity, *u.response[:2]) for u in units}
    if len(quantities) != 1:
        raise DataFileError(f"{path}: the responses mix quantities or units {sorted(quantities)}")
    quantity, resp_units, _ = quantities.pop()
    resp_part = units[0].response
    force_part = ("N", 1.0, "", "")
    if force_recs:
        raw = force_recs[0].get("ordinate_axis_units_lab")
        label = _unit_label(raw, names.FORCE_UNITS)
        force_part = _part(label, raw, "N", False, system, "force")
    force_units = force_part[0]
    resp = np.full((len(cases), len(labels), time.size), np.nan)
    for r in resp_recs:
        resp[cases.index(int(r.get("load_case_id", 0))), labels.index(_label_of(r, "rsp"))] = (
            np.asarray(r["data"], dtype=np.float64)
        )
    if np.isnan(resp).any():
        raise DataFileError(f"{path}: not every response DOF has a record for every load case")
    if resp_part[1] != 1.0:
        resp = resp * resp_part[1]
    labels_out = _mixed_labels_to_str(labels)
    dims = (names.RECORD, names.POINT, names.TIME)
    ds = xr.Dataset(
        {names.RESPONSE: (dims, resp, {names.ATTR_UNITS: resp_units})},
        coords={
            names.POINT: labels_out,
            names.TIME: (names.TIME, time, {names.ATTR_UNITS: names.TIME_UNITS}),
        },
        attrs={
            names.ATTR_QUANTITY: quantity,
            names.ATTR_RESPONSE_UNITS: resp_units,
            names.ATTR_FORCE_UNITS: force_units,
            names.ATTR_SOURCE_FILE: path.name,
        },
    )
    if force_recs:
        drives = {_label_of(r, "rsp") for r in force_recs}
        if len(drives) != 1:
            raise DataFileError(
                f"{path}: force records at several DOFs {sorted(map(str, drives))}; "
                "expected one drive point"
            )
        force = np.full((len(cases), time.size), np.nan)
        for r in force_recs:
            force[cases.index(int(r.get("load_case_id", 0)))] = np.asarray(
                r["data"], dtype=np.float64
            )
        if np.isnan(force).any():
            raise DataFileError(f"{path}: a load case has no force record")
        if force_part[1] != 1.0:
            force = force * force_part[1]
        ds[names.FORCE] = (
            (names.RECORD, names.TIME),
            force,
            {names.ATTR_UNITS: force_units},
        )
        drive = drives.pop()
        ds.attrs[names.ATTR_DRIVE_POINT] = str(drive) if isinstance(labels_out[0], str) else drive
    assumed = _assumed_si((resp_part, force_part))
    ds.attrs.update(_unit_attrs(assumed, "; ".join(p[3] for p in (resp_part, force_part) if p[3])))
    if assumed:
        _tell_assumed(path, assumed)
    from_label = next((u.from_label for u in units if u.from_label), "")
    if from_label:
        ds.attrs[ATTR_QUANTITY_FROM_LABEL] = from_label
    if len(cases) == 1:
        ds = ds.isel({names.RECORD: 0}, drop=True)
    label_nodes = {lab: parse_point_label(lab)[0] for lab in labels_out if parse_point_label(lab)}
    return _attach_coordinates(ds, nodes, label_nodes)


def read_uff(
    path: str | os.PathLike, *, kind: str | None = None, merge_modes: bool = True
) -> xr.Dataset:
    """Read a UFF file into an ami_xr Dataset.

    Parameters
    ----------
    path : str or path-like
        UFF file (ASCII or binary dataset 58, dataset 55, optional 15/2411 node coordinates).
    kind : {None, "frf", "time", "modes"}
        What to read when the file holds several kinds; by default FRFs if there are any, else
        time histories, else mode shapes.
    merge_modes : bool
        When FRFs are read and the file also holds mode shapes (dataset 55, as
        :func:`write_uff` writes an identification result), add them to the FRF Dataset:
        ``eigenvalue``, ``natural_frequency``, ``damping_ratio`` (dims ``mode``) and
        ``mode_vector`` (``point``, ``mode``). Mode shapes without a value at every FRF point
        are left out with a warning (attribute ``uff_modes_skipped``).

    Returns
    -------
    xarray.Dataset
        FRF Dataset (``frf`` (point, frequency); ``(reference, point, frequency)`` when the
        FRFs have several responses and several references), time Dataset (``response``,
        ``force``) or modal Dataset (``eigenvalue``, ``natural_frequency``,
        ``damping_ratio``, ``mode_vector``; normal modes also ``modal_mass``), following the
        ami_xr data model. See the package docstring (:mod:`ami_xr.io.uff`) for the mapping of
        DOFs, references, mode types and units.

    Raises
    ------
    DataFileError
        Missing or unreadable file, no dataset of the requested kind, several references and
        several responses without exactly one FRF per (reference, response) pair, records on
        different grids, unknown quantities, a dataset pyuff cannot read (named with its line),
        normal modes with a damping ratio outside (-1, 1).
    """
    path = Path(path)
    if kind not in (None, "frf", "time", "modes"):
        raise AmiXrValueError(f"kind must be None, 'frf', 'time' or 'modes'; got {kind!r}")
    sets = read_sets(path)
    s58 = [s for s in sets if s.get("type") == 58]
    frfs = [s for s in s58 if int(s.get("func_type", 0)) == FUNC_FRF]
    times = [s for s in s58 if int(s.get("func_type", 0)) == FUNC_TIME]
    cohs = [s for s in s58 if int(s.get("func_type", 0)) == FUNC_COHERENCE]
    modes = [
        s
        for s in sets
        if s.get("type") == 55 and int(s.get("analysis_type", 0)) in MODE_ANALYSIS_TYPES
    ]
    found = {"frf": frfs, "time": times, "modes": modes}
    if kind is None:
        kind = next((k for k in ("frf", "time", "modes") if found[k]), None)
        if kind is None:
            types = sorted({(s.get("type"), s.get("func_type")) for s in sets}, key=str)
            raise DataFileError(
                f"{path}: no FRF (58, function type 4), time response (58, type 1) or mode-shape "
                f"(55) dataset; found (dataset, function type) {types}"
            )
    elif not found[kind]:
        raise DataFileError(f"{path}: the file holds no {kind} dataset")
    system = _units_system(sets)
    nodes = _node_coordinates(sets, system)
    if kind == "frf":
        ds = _read_frf(frfs, cohs, nodes, path, system)
        if modes and merge_modes:
            ds = with_modes(ds, modes, path)
    elif kind == "time":
        ds = _read_time(times, nodes, path, system)
    else:
        ds, label_nodes = read_modes(modes, path)
        ds = _attach_coordinates(ds, nodes, label_nodes)
    return _validated(ds)


def _validated(ds: xr.Dataset) -> xr.Dataset:
    """Run the data-model check on FRF and time Datasets (modal Datasets have no schema)."""
    if names.FRF not in ds and names.RESPONSE not in ds:
        return ds
    from ami_xr.io.schema import validate

    # A drive point that was not measured is allowed: AMI then leaves mode vectors unscaled.
    drive = ds.attrs.get(names.ATTR_DRIVE_POINT)
    points = ds[names.POINT].values.tolist()
    measured = drive is not None and drive in points
    if names.REFERENCE in ds.dims:  # multi-reference: a reference on a measured point
        measured = any(r in points for r in ds[names.REFERENCE].values.tolist())
    return validate(ds, require_drive_point=measured)
