"""Read UFF files: dataset 58 FRFs and time histories, 55 mode shapes, 15/2411 node coordinates.

See :mod:`ami_xr.io.uff` for the mapping to ami_xr Datasets.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
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
    dof_map,
    parse_point_label,
    point_label,
    require_pyuff,
)
from ami_xr.io.uff.completeness import check_complete, check_lengths

__all__ = ["read_uff", "ATTR_UNITS_ASSUMED", "ATTR_UNITS_SCALED", "ATTR_MODES_SKIPPED"]

ATTR_UNITS_ASSUMED = "uff_units_assumed"  # why SI units were assumed (no usable unit labels)
ATTR_UNITS_SCALED = "uff_units_scaled"  # how values were converted to SI by dataset 164
ATTR_MODES_SKIPPED = "uff_modes_skipped"  # why dataset-55 modes were not merged with the FRFs
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
def _unit_label(raw: Any, allowed: Sequence[str]) -> str | None:
    """The known unit a label names (case-insensitive: ``"G"`` is ``"g"``), else None."""
    text = str(raw or "").strip()
    if not text or text.upper() == "NONE":
        return None
    text = KNOWN_UNIT_ALIASES.get(text.lower(), text)
    by_lower = {a.lower(): a for a in allowed}
    return text if text in allowed else by_lower.get(text.lower())


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

    def scaled(self, length: bool) -> str:
        factor = self.length if length else self.force
        what = "length" if length else "force"
        return f"{what} / {factor:.10g} (dataset 164: {self.name})"


def _units_system(sets: list[dict]) -> _System:
    found = [s for s in sets if s.get("type") == 164]
    return _System(found[0] if found else None)


def _part(raw: Any, allowed, si: str, is_length: bool, system: _System, part: str):
    """(units, scale to SI, why assumed or "", how scaled or "") of one side of a record."""
    raw = str(raw or "").strip()
    label = _unit_label(raw, allowed)
    if label is not None:
        return label, 1.0, "", ""
    if system.given:
        factor = system.length if is_length else system.force
        how = "" if system.is_si else f"{part} {system.scaled(is_length)}"
        return si, 1.0 / factor, "", how
    shown = f"unknown unit label {raw!r}" if raw and raw.upper() != "NONE" else "no label"
    return si, 1.0, f"{part} in {si} ({shown})", ""


def _quantity_and_units(record: dict, path: Path, system: _System | None = None):
    """(quantity, response units, force units, why assumed or "", scale to SI of the response
    and of the force, how they were scaled or "") of a dataset-58 record.

    A known unit label wins; without one, dataset 164 (when present) gives the units and the
    values are scaled to SI; without both, SI is assumed and the reason is returned."""
    spec = int(record.get("ordinate_spec_data_type", 0))
    if spec not in SPEC_TO_QUANTITY:
        raise DataFileError(
            f"{path}: UFF record for DOF {record.get('rsp_node')}/{record.get('rsp_dir')} has "
            f"ordinate specific data type {spec}; expected 8 (displacement), 11 (velocity) or "
            "12 (acceleration)"
        )
    quantity = SPEC_TO_QUANTITY[spec]
    system = system or _System(None)
    resp = _part(
        record.get("ordinate_axis_units_lab"),
        names.RESPONSE_UNITS[quantity],
        SI_UNITS[quantity],
        True,
        system,
        "response",
    )
    force = _part(
        record.get("orddenom_axis_units_lab"), names.FORCE_UNITS, "N", False, system, "force"
    )
    out = {"response": resp[:2], "force": force[:2]}
    assumed = [p[2] for p in (resp, force) if p[2]]
    scaled = [p[3] for p in (resp, force) if p[3]]
    why = ""
    if assumed:
        why = (
            "the file gives no usable unit label and no units dataset (164); assumed SI: "
            + ", ".join(assumed)
        )
    return (
        quantity,
        out["response"][0],
        out["force"][0],
        why,
        out["response"][1],
        out["force"][1],
        "; ".join(scaled),
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
def _read_sets(path: Path) -> list[dict]:
    pyuff = require_pyuff()
    if not path.is_file():
        raise DataFileError(f"UFF file {str(path)!r} does not exist")
    try:
        data = path.read_bytes()
    except OSError as err:
        raise DataFileError(f"{path}: cannot read the file: {err}") from err
    check_complete(data, path)
    del data
    try:
        uff = pyuff.UFF(str(path))
        sets = uff.read_sets()
    except Exception as err:  # pyuff raises bare Exceptions of many kinds on bad files
        raise DataFileError(
            f"{path}: not a readable UFF file ({type(err).__name__}: {err})"
        ) from err
    if isinstance(sets, dict):
        sets = [sets]
    if not sets:
        raise DataFileError(f"{path}: the UFF file holds no datasets")
    check_lengths(list(sets), path)
    return list(sets)


def _node_coordinates(sets: list[dict]) -> dict[int, tuple[float, float, float]]:
    coords: dict[int, tuple[float, float, float]] = {}
    for s in sets:
        if s.get("type") in (15, 2411):
            for n, x, y, z in zip(s["node_nums"], s["x"], s["y"], s["z"], strict=False):
                coords[int(n)] = (float(x), float(y), float(z))
    return coords


def _attach_coordinates(ds: xr.Dataset, coords: dict, label_nodes: dict) -> xr.Dataset:
    if not coords:
        return ds
    labels = ds[names.POINT].values
    if not all(label_nodes.get(lab) in coords for lab in labels):
        return ds
    xyz = np.array([coords[label_nodes[lab]] for lab in labels])
    return ds.assign_coords(
        {
            f"{names.POINT}_{axis}": (names.POINT, xyz[:, i], {names.ATTR_UNITS: "m"})
            for i, axis in enumerate("xyz")
        }
    )


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
    frfs: list[dict], coh: list[dict], coords: dict, path: Path, system: _System
) -> xr.Dataset:
    multi = _multi_reference(frfs, path)
    if multi is None:
        labels, drive, layout = _single_reference(frfs, path)
        if len(set(labels)) != len(labels):
            raise DataFileError(
                f"{path}: the FRF records repeat a DOF ({labels}); expected one per point"
            )
    units = [_quantity_and_units(r, path, system) for r in frfs]
    quantities = {u[:3] + u[4:6] for u in units}
    if len(quantities) != 1:
        raise DataFileError(
            f"{path}: the FRFs mix response quantities or units {sorted(quantities)}; expected one"
        )
    quantity, resp_units, force_units, resp_scale, force_scale = quantities.pop()
    assumed = next((u[3] for u in units if u[3]), "")
    scaled = next((u[6] for u in units if u[6]), "")
    grids = [_abscissa(r) for r in frfs]
    _check_same_grid(frfs, grids, path, "FRF")
    freq = grids[0]
    data = np.stack([np.asarray(r["data"], dtype=np.complex128) for r in frfs])
    if resp_scale != 1.0 or force_scale != 1.0:
        data = data * (resp_scale / force_scale)
    if multi is not None:
        if assumed:
            _tell_assumed(path, assumed)
        return _read_multi_reference(
            frfs, data, multi, freq, (quantity, resp_units, force_units), coh, coords, path
        ).assign_attrs(_unit_attrs(assumed, scaled))
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
        },
    )
    if assumed:
        ds.attrs[ATTR_UNITS_ASSUMED] = assumed
        _tell_assumed(path, assumed)
    if scaled:
        ds.attrs[ATTR_UNITS_SCALED] = f"values converted to SI: {scaled}"
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
    return _attach_coordinates(ds, coords, label_nodes)


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
    coords: dict,
    path: Path,
) -> xr.Dataset:
    """FRF Dataset ``frf`` (reference, point, frequency) of multi-reference records."""
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
    return _attach_coordinates(ds, coords, label_nodes)


def _read_time(records: list[dict], coords: dict, path: Path, system: _System) -> xr.Dataset:
    force_recs = [r for r in records if int(r.get("ordinate_spec_data_type", 0)) in SPEC_FORCE]
    resp_recs = [r for r in records if r not in force_recs]
    if not resp_recs:
        raise DataFileError(f"{path}: the time records hold no response channel (only force)")
    grids = [_abscissa(r) for r in records]
    _check_same_grid(records, grids, path, "time")
    time = grids[0]
    cases = sorted({int(r.get("load_case_id", 0)) for r in records})
    labels = list(dict.fromkeys(_label_of(r, "rsp") for r in resp_recs))
    quantities = {_quantity_and_units(r, path, system)[:2] for r in resp_recs}
    if len(quantities) != 1:
        raise DataFileError(f"{path}: the responses mix quantities or units {sorted(quantities)}")
    quantity, resp_units = quantities.pop()
    resp_part = _part(
        resp_recs[0].get("ordinate_axis_units_lab"),
        names.RESPONSE_UNITS[quantity],
        SI_UNITS[quantity],
        True,
        system,
        "response",
    )
    force_part = (
        _part(
            force_recs[0].get("ordinate_axis_units_lab"),
            names.FORCE_UNITS,
            "N",
            False,
            system,
            "force",
        )
        if force_recs
        else ("N", 1.0, "", "")
    )
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
    assumed = [p[2] for p in (resp_part, force_part) if p[2]]
    if assumed:
        why = (
            "the file gives no usable unit label and no units dataset (164); assumed SI: "
            + ", ".join(assumed)
        )
        ds.attrs[ATTR_UNITS_ASSUMED] = why
        _tell_assumed(path, why)
    scaled = [p[3] for p in (resp_part, force_part) if p[3]]
    if scaled:
        ds.attrs[ATTR_UNITS_SCALED] = "values converted to SI: " + "; ".join(scaled)
    if len(cases) == 1:
        ds = ds.isel({names.RECORD: 0}, drop=True)
    label_nodes = {lab: parse_point_label(lab)[0] for lab in labels_out if parse_point_label(lab)}
    return _attach_coordinates(ds, coords, label_nodes)


def _read_modes(modes: list[dict], coords: dict, path: Path) -> xr.Dataset:
    # Collect every (node, direction) that carries data, in node order.
    comp_keys = ("r1", "r2", "r3", "r4", "r5", "r6")
    dofs: list[tuple[int, int]] = []
    for m in modes:
        for c, key in enumerate(comp_keys, start=1):
            values = m.get(key)
            if values is None:
                continue
            for node, v in zip(m["node_nums"], np.asarray(values), strict=True):
                if v != 0 and (int(node), c) not in dofs:
                    dofs.append((int(node), c))
    dofs.sort()
    labels = [point_label(n, d) for n, d in dofs]
    vectors = np.zeros((len(dofs), len(modes)), dtype=np.complex128)
    eig = np.zeros(len(modes), dtype=np.complex128)
    for k, m in enumerate(modes):
        eig[k] = complex(m.get("eig", np.nan))
        nodes = [int(n) for n in m["node_nums"]]
        for i, (node, c) in enumerate(dofs):
            values = m.get(comp_keys[c - 1])
            if values is not None and node in nodes:
                vectors[i, k] = np.asarray(values)[nodes.index(node)]
    wn = np.abs(eig)
    ds = xr.Dataset(
        {
            names.EIGENVALUE: (names.MODE, eig, {names.ATTR_UNITS: "rad/s"}),
            names.NATURAL_FREQUENCY: (names.MODE, wn / (2 * np.pi), {names.ATTR_UNITS: "Hz"}),
            names.DAMPING_RATIO: (names.MODE, -eig.real / wn, {names.ATTR_UNITS: "1"}),
            names.MODE_VECTOR: ((names.POINT, names.MODE), vectors),
        },
        coords={
            names.POINT: labels,
            names.MODE: [int(m.get("mode_n", k + 1)) for k, m in enumerate(modes)],
        },
        attrs={names.ATTR_SOURCE_FILE: path.name},
    )
    return _attach_coordinates(
        ds, coords, {lab: n for lab, (n, _) in zip(labels, dofs, strict=True)}
    )


def _modal_variables(modes: list[dict], vectors: np.ndarray) -> dict:
    eig = np.array([complex(m.get("eig", np.nan)) for m in modes], dtype=np.complex128)
    wn = np.abs(eig)
    with np.errstate(invalid="ignore", divide="ignore"):
        zeta = -eig.real / wn
    return {
        names.EIGENVALUE: (names.MODE, eig, {names.ATTR_UNITS: names.ANGULAR_UNITS}),
        names.NATURAL_FREQUENCY: (
            names.MODE,
            wn / (2 * np.pi),
            {names.ATTR_UNITS: names.FREQUENCY_UNITS},
        ),
        names.DAMPING_RATIO: (names.MODE, zeta, {names.ATTR_UNITS: names.DIMENSIONLESS_UNITS}),
        names.MODE_VECTOR: ((names.POINT, names.MODE), vectors),
    }


def _with_modes(ds: xr.Dataset, modes: list[dict], path: Path) -> xr.Dataset:
    """The FRF Dataset with the dataset-55 modes at its points (the mapping of
    :func:`ami_xr.io.uff.write_uff`: component ``|direction|`` of the point's node, sign flipped
    for a negative direction, Z for a scalar DOF). Modes that miss a point are not merged: a
    warning and the attribute ``uff_modes_skipped`` say so."""
    labels = ds[names.POINT].values.tolist()
    dof = dof_map(labels)
    vectors = np.zeros((len(labels), len(modes)), dtype=np.complex128)
    missing = []
    for k, m in enumerate(modes):
        nodes = [int(n) for n in m["node_nums"]]
        for i, lab in enumerate(labels):
            node, direction, _ = dof[lab]
            axis = abs(direction) if direction != 0 else 3
            values = m.get(f"r{axis}")
            if values is None or node not in nodes:
                missing.append(lab)
                continue
            sign = -1.0 if direction < 0 else 1.0
            vectors[i, k] = sign * np.asarray(values)[nodes.index(node)]
    if missing:
        why = (
            f"{len(modes)} mode shape(s) (dataset 55) not merged with the FRFs: no value at "
            f"point(s) {sorted(set(map(str, missing)))}; read them with read_uff(path, "
            "kind='modes')"
        )
        warnings.warn(f"{path.name}: {why}", _ASSUMPTION, stacklevel=3)
        return ds.assign_attrs({ATTR_MODES_SKIPPED: why})
    mode_labels = [int(m.get("mode_n", k + 1)) for k, m in enumerate(modes)]
    if len(set(mode_labels)) != len(mode_labels):
        mode_labels = list(range(1, len(modes) + 1))
    return ds.assign_coords({names.MODE: mode_labels}).assign(_modal_variables(modes, vectors))


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
        ``force``) or modal Dataset (``eigenvalue``, ``mode_vector``), following the ami_xr
        data model. See the module docstring for the mapping of DOFs, references and units.

    Raises
    ------
    DataFileError
        Missing or unreadable file, no dataset of the requested kind, several references and
        several responses without exactly one FRF per (reference, response) pair, records on
        different grids, unknown quantities.
    """
    path = Path(path)
    if kind not in (None, "frf", "time", "modes"):
        raise AmiXrValueError(f"kind must be None, 'frf', 'time' or 'modes'; got {kind!r}")
    sets = _read_sets(path)
    coords = _node_coordinates(sets)
    s58 = [s for s in sets if s.get("type") == 58]
    frfs = [s for s in s58 if int(s.get("func_type", 0)) == FUNC_FRF]
    times = [s for s in s58 if int(s.get("func_type", 0)) == FUNC_TIME]
    cohs = [s for s in s58 if int(s.get("func_type", 0)) == FUNC_COHERENCE]
    modes = [s for s in sets if s.get("type") == 55 and int(s.get("analysis_type", 0)) in (2, 3)]
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
    if kind == "frf":
        ds = _read_frf(frfs, cohs, coords, path, system)
        if modes and merge_modes:
            ds = _with_modes(ds, modes, path)
    elif kind == "time":
        ds = _read_time(times, coords, path, system)
    else:
        ds = _read_modes(modes, coords, path)
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
