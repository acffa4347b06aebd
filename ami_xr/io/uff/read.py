"""Universal File Format (UFF) import and export through the ``pyuff`` package.

What is read
------------
* Dataset 58 (ASCII or binary) with function type 4 (FRF) becomes an FRF Dataset, function type 1
  (time response) a time Dataset; coherence records (function type 6) of an FRF file become the
  ``coherence`` variable.
* Dataset 55 (complex mode shapes, analysis type 3) becomes a modal Dataset with ``eigenvalue``,
  ``natural_frequency``, ``damping_ratio`` and ``mode_vector``.
* Datasets 15 and 2411 (node coordinates), when present, give the ``point_x``, ``point_y`` and
  ``point_z`` coordinates of every point on a known node.

Point labels
------------
A UFF degree of freedom is a node number and a direction code (1, 2, 3 = +X, +Y, +Z; 4, 5, 6 =
rotations RX, RY, RZ; negative codes point the other way; 0 = scalar). It becomes the label
``f"{node}{sign}{axis}"``, e.g. ``"1+Z"`` or ``"12-X"``; a scalar DOF (direction 0) becomes the
integer node number. Labels that are neither (``"tip"``) are written with node numbers 1, 2, ...
and the label in ID line 2 (``"ami_xr point=tip"``), which the reader restores.

Single-reference grouping and the drive point
---------------------------------------------
ami_xr's FRF Dataset holds one column of the FRF matrix: responses at many points to a force at one
drive point. A UFF file with one reference DOF and several response DOFs maps directly (points =
response DOFs, ``drive_point`` = the reference DOF). A roving-hammer file has the transpose: one
response DOF, several reference DOFs. By Maxwell-Betti reciprocity (H_rj = H_jr for a linear
system) its FRFs are the same column, so points = reference DOFs and ``drive_point`` = the fixed
response DOF; the Dataset attribute ``uff_layout`` says which case applied. Files where both
vary (multiple references) are refused with a clear error until multi-reference data is supported.

Abscissae
---------
Evenly spaced records store their increment with about 6 significant digits. When ``1 / inc``
is that close to an integer (a sampling rate in Hz or a record length in s), the exact reciprocal
is used, so ``dt = 1/1024 s`` or ``df = 1/60 Hz`` survive a round trip.

Units
-----
The response quantity comes from the ordinate's specific data type (8 displacement, 11 velocity,
12 acceleration) and the force from the denominator (13 excitation force, 9 reaction force). Unit
labels in the file (``"m/s^2"``, ``"g"``, ``"N"``, ...) are used when they are ones ami_xr knows;
otherwise SI units are assumed (m, m/s, m/s^2, N) and the attribute ``uff_units_assumed`` says so.
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.atomic import atomic_path

__all__ = ["read_uff", "write_uff", "point_label", "parse_point_label"]

# --- UFF code tables (from the UFF dataset 58 specification) ---------------------------------
_FUNC_TIME = 1
_FUNC_FRF = 4
_FUNC_COHERENCE = 6
_SPEC_TO_QUANTITY = {8: "displacement", 11: "velocity", 12: "acceleration"}
_QUANTITY_TO_SPEC = {v: k for k, v in _SPEC_TO_QUANTITY.items()}
_SPEC_FORCE = (13, 9)  # excitation force, reaction force
_SPEC_TIME = 17
_SPEC_FREQUENCY = 18
_SI_UNITS = {"displacement": "m", "velocity": "m/s", "acceleration": "m/s^2"}
_AXES = {1: "X", 2: "Y", 3: "Z", 4: "RX", 5: "RY", 6: "RZ"}
_AXIS_CODES = {v: k for k, v in _AXES.items()}
_LABEL_RE = re.compile(r"^\s*(\d+)\s*([+-])\s*(X|Y|Z|RX|RY|RZ)\s*$", re.IGNORECASE)
_ID_TAG = "ami_xr point="
_KNOWN_UNIT_ALIASES = {
    "m/s2": "m/s^2",
    "m/s**2": "m/s^2",
    "mm/s2": "mm/s^2",
    "in/s2": "in/s^2",
    "µm": "um",
    "lbf": "lbf",
    "n": "N",
    "kn": "kN",
}


def _require_pyuff():
    try:
        import pyuff
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            "reading or writing UFF files needs the optional package pyuff: "
            "pip install 'ami_xr[uff]'"
        ) from err
    return pyuff


# --- point labels ----------------------------------------------------------------------------
def point_label(node: int, direction: int) -> str | int:
    """Label of a UFF degree of freedom: ``(1, 3) -> "1+Z"``, ``(7, -1) -> "7-X"``, ``(4, 0) -> 4``.

    Parameters
    ----------
    node : int
        UFF node number.
    direction : int
        UFF direction code: 0 scalar, +-1..3 translations X, Y, Z, +-4..6 rotations RX, RY, RZ.
    """
    node = int(node)
    direction = int(direction)
    if direction == 0:
        return node
    if abs(direction) not in _AXES:
        raise DataFileError(
            f"UFF direction code {direction} of node {node} is not one of 0, +-1..6"
        )
    return f"{node}{'+' if direction > 0 else '-'}{_AXES[abs(direction)]}"


def parse_point_label(label: Any) -> tuple[int, int] | None:
    """Inverse of :func:`point_label`: ``"1+Z" -> (1, 3)``, ``4 -> (4, 0)``; None if not a DOF."""
    if isinstance(label, (int, np.integer)) and not isinstance(label, bool):
        return int(label), 0
    match = _LABEL_RE.match(str(label))
    if match is None:
        return None
    node, sign, axis = match.groups()
    code = _AXIS_CODES[axis.upper()]
    return int(node), code if sign == "+" else -code


def _dof_map(labels: Sequence[Any]) -> dict[Any, tuple[int, int, str]]:
    """Node number, direction code and ID-line tag used to write each point label."""
    parsed = {lab: parse_point_label(lab) for lab in labels}
    used_nodes = {p[0] for p in parsed.values() if p is not None}
    next_node = 1
    out = {}
    for lab in labels:
        p = parsed[lab]
        if p is not None:
            out[lab] = (p[0], p[1], "NONE")
            continue
        while next_node in used_nodes:
            next_node += 1
        used_nodes.add(next_node)
        out[lab] = (next_node, 0, f"{_ID_TAG}{lab}")
    return out


def _label_of(record: dict, which: str) -> Any:
    """Point label of the response (``which="rsp"``) or reference DOF of a dataset-58 record."""
    tag = str(record.get("id2", ""))
    if which == "rsp" and tag.startswith(_ID_TAG):
        return tag[len(_ID_TAG) :]
    if which == "ref":
        tag3 = str(record.get("id3", ""))
        if tag3.startswith(_ID_TAG):
            return tag3[len(_ID_TAG) :]
    return point_label(record[f"{which}_node"], record[f"{which}_dir"])


# --- units -----------------------------------------------------------------------------------
def _unit_label(raw: Any, allowed: Sequence[str]) -> str | None:
    text = str(raw or "").strip()
    if not text or text.upper() == "NONE":
        return None
    text = _KNOWN_UNIT_ALIASES.get(text.lower(), text)
    return text if text in allowed else None


def _quantity_and_units(record: dict, path: Path) -> tuple[str, str, str, bool]:
    spec = int(record.get("ordinate_spec_data_type", 0))
    if spec not in _SPEC_TO_QUANTITY:
        raise DataFileError(
            f"{path}: UFF record for DOF {record.get('rsp_node')}/{record.get('rsp_dir')} has "
            f"ordinate specific data type {spec}; expected 8 (displacement), 11 (velocity) or "
            "12 (acceleration)"
        )
    quantity = _SPEC_TO_QUANTITY[spec]
    resp = _unit_label(record.get("ordinate_axis_units_lab"), names.RESPONSE_UNITS[quantity])
    force = _unit_label(record.get("orddenom_axis_units_lab"), names.FORCE_UNITS)
    assumed = resp is None or force is None
    return quantity, resp or _SI_UNITS[quantity], force or "N", assumed


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
    pyuff = _require_pyuff()
    if not path.is_file():
        raise DataFileError(f"UFF file {str(path)!r} does not exist")
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


def _read_frf(frfs: list[dict], coh: list[dict], coords: dict, path: Path) -> xr.Dataset:
    labels, drive, layout = _single_reference(frfs, path)
    if len(set(labels)) != len(labels):
        raise DataFileError(
            f"{path}: the FRF records repeat a DOF ({labels}); expected one per point"
        )
    quantities = {_quantity_and_units(r, path)[:3] for r in frfs}
    if len(quantities) != 1:
        raise DataFileError(
            f"{path}: the FRFs mix response quantities or units {sorted(quantities)}; expected one"
        )
    quantity, resp_units, force_units = quantities.pop()
    assumed = any(_quantity_and_units(r, path)[3] for r in frfs)
    grids = [_abscissa(r) for r in frfs]
    _check_same_grid(frfs, grids, path, "FRF")
    freq = grids[0]
    data = np.stack([np.asarray(r["data"], dtype=np.complex128) for r in frfs])
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
            names.ATTR_SOURCE_FILE: str(path),
            "uff_layout": layout,
        },
    )
    if assumed:
        ds.attrs["uff_units_assumed"] = "the file gives no known unit labels; SI units assumed"
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


def _read_time(records: list[dict], coords: dict, path: Path) -> xr.Dataset:
    force_recs = [r for r in records if int(r.get("ordinate_spec_data_type", 0)) in _SPEC_FORCE]
    resp_recs = [r for r in records if r not in force_recs]
    if not resp_recs:
        raise DataFileError(f"{path}: the time records hold no response channel (only force)")
    grids = [_abscissa(r) for r in records]
    _check_same_grid(records, grids, path, "time")
    time = grids[0]
    cases = sorted({int(r.get("load_case_id", 0)) for r in records})
    labels = list(dict.fromkeys(_label_of(r, "rsp") for r in resp_recs))
    quantities = {_quantity_and_units(r, path)[:2] for r in resp_recs}
    if len(quantities) != 1:
        raise DataFileError(f"{path}: the responses mix quantities or units {sorted(quantities)}")
    quantity, resp_units = quantities.pop()
    force_units = (
        _unit_label(force_recs[0].get("ordinate_axis_units_lab"), names.FORCE_UNITS)
        if force_recs
        else None
    )
    resp = np.full((len(cases), len(labels), time.size), np.nan)
    for r in resp_recs:
        resp[cases.index(int(r.get("load_case_id", 0))), labels.index(_label_of(r, "rsp"))] = (
            np.asarray(r["data"], dtype=np.float64)
        )
    if np.isnan(resp).any():
        raise DataFileError(f"{path}: not every response DOF has a record for every load case")
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
            names.ATTR_FORCE_UNITS: force_units or "N",
            names.ATTR_SOURCE_FILE: str(path),
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
        ds[names.FORCE] = (
            (names.RECORD, names.TIME),
            force,
            {names.ATTR_UNITS: force_units or "N"},
        )
        drive = drives.pop()
        ds.attrs[names.ATTR_DRIVE_POINT] = str(drive) if isinstance(labels_out[0], str) else drive
    if (
        force_units is None
        or _unit_label(resp_recs[0].get("ordinate_axis_units_lab"), names.RESPONSE_UNITS[quantity])
        is None
    ):
        ds.attrs["uff_units_assumed"] = "the file gives no known unit labels; SI units assumed"
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
        attrs={names.ATTR_SOURCE_FILE: str(path)},
    )
    return _attach_coordinates(
        ds, coords, {lab: n for lab, (n, _) in zip(labels, dofs, strict=True)}
    )


def read_uff(path: str | os.PathLike, *, kind: str | None = None) -> xr.Dataset:
    """Read a UFF file into an ami_xr Dataset.

    Parameters
    ----------
    path : str or path-like
        UFF file (ASCII or binary dataset 58, dataset 55, optional 15/2411 node coordinates).
    kind : {None, "frf", "time", "modes"}
        What to read when the file holds several kinds; by default FRFs if there are any, else
        time histories, else mode shapes.

    Returns
    -------
    xarray.Dataset
        FRF Dataset (``frf`` (point, frequency)), time Dataset (``response``, ``force``) or modal
        Dataset (``eigenvalue``, ``mode_vector``), following the ami_xr data model. See the
        module docstring for the mapping of DOFs, references and units.

    Raises
    ------
    DataFileError
        Missing or unreadable file, no dataset of the requested kind, several references and
        responses at once, records on different grids, unknown quantities.
    """
    path = Path(path)
    if kind not in (None, "frf", "time", "modes"):
        raise AmiXrValueError(f"kind must be None, 'frf', 'time' or 'modes'; got {kind!r}")
    sets = _read_sets(path)
    coords = _node_coordinates(sets)
    s58 = [s for s in sets if s.get("type") == 58]
    frfs = [s for s in s58 if int(s.get("func_type", 0)) == _FUNC_FRF]
    times = [s for s in s58 if int(s.get("func_type", 0)) == _FUNC_TIME]
    cohs = [s for s in s58 if int(s.get("func_type", 0)) == _FUNC_COHERENCE]
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
    if kind == "frf":
        ds = _read_frf(frfs, cohs, coords, path)
    elif kind == "time":
        ds = _read_time(times, coords, path)
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
    measured = drive is not None and drive in ds[names.POINT].values.tolist()
    return validate(ds, require_drive_point=measured)


# --- writing ---------------------------------------------------------------------------------
def _units_lab(text: str) -> str:
    return text if text else "NONE"


def _frf_records(ds: xr.Dataset, binary: bool) -> list[dict]:
    pyuff = _require_pyuff()
    labels = list(ds[names.POINT].values.tolist())
    drive = ds.attrs.get(names.ATTR_DRIVE_POINT)
    dof = _dof_map(labels + ([drive] if drive is not None and drive not in labels else []))
    quantity = ds.attrs.get(names.ATTR_QUANTITY, "displacement")
    freq = np.asarray(ds[names.FREQUENCY].values, dtype=np.float64)
    step = np.diff(freq)
    uniform = freq.size > 1 and np.allclose(step, step[0], rtol=1e-9)
    ref_node, ref_dir, ref_tag = dof[drive] if drive is not None else (0, 0, "NONE")
    records = []
    variables = [(names.FRF, _FUNC_FRF)]
    if names.COHERENCE in ds:
        variables.append((names.COHERENCE, _FUNC_COHERENCE))
    for var, func in variables:
        values = ds[var].transpose(names.POINT, names.FREQUENCY).values
        for i, lab in enumerate(labels):
            node, direction, tag = dof[lab]
            data = np.asarray(values[i], dtype=np.complex128 if func == _FUNC_FRF else np.float64)
            records.append(
                pyuff.prepare_58(
                    binary=int(binary),
                    id1=str(ds.attrs.get("title", "ami_xr"))[:80] or "NONE",
                    id2=tag,
                    id3=ref_tag,
                    id4="NONE",
                    id5="NONE",
                    func_type=func,
                    ver_num=0,
                    load_case_id=0,
                    rsp_ent_name="ami_xr",
                    rsp_node=node,
                    rsp_dir=direction,
                    ref_ent_name="ami_xr",
                    ref_node=ref_node,
                    ref_dir=ref_dir,
                    ord_data_type=6 if func == _FUNC_FRF else 4,
                    num_pts=freq.size,
                    abscissa_spacing=int(uniform),
                    abscissa_min=float(freq[0]),
                    abscissa_inc=float(step[0]) if uniform else 0.0,
                    z_axis_value=0.0,
                    abscissa_spec_data_type=_SPEC_FREQUENCY,
                    abscissa_axis_units_lab="Hz",
                    ordinate_spec_data_type=_QUANTITY_TO_SPEC[quantity] if func == _FUNC_FRF else 0,
                    ordinate_axis_units_lab=_units_lab(ds.attrs.get(names.ATTR_RESPONSE_UNITS, "")),
                    orddenom_spec_data_type=13 if func == _FUNC_FRF else 0,
                    orddenom_axis_units_lab=_units_lab(ds.attrs.get(names.ATTR_FORCE_UNITS, "")),
                    data=data,
                    x=freq,
                )
            )
    return records


def _time_records(ds: xr.Dataset, binary: bool) -> list[dict]:
    pyuff = _require_pyuff()
    labels = list(ds[names.POINT].values.tolist())
    drive = ds.attrs.get(names.ATTR_DRIVE_POINT)
    dof = _dof_map(labels + ([drive] if drive is not None and drive not in labels else []))
    quantity = ds.attrs.get(names.ATTR_QUANTITY, "displacement")
    time = np.asarray(ds[names.TIME].values, dtype=np.float64)
    dt = float(time[1] - time[0]) if time.size > 1 else 1.0
    resp = ds[names.RESPONSE]
    if names.RECORD not in resp.dims:
        resp = resp.expand_dims(names.RECORD)
    resp = resp.transpose(names.RECORD, names.POINT, names.TIME).values
    force = None
    if names.FORCE in ds:
        f = ds[names.FORCE]
        if names.REFERENCE in f.dims:
            raise AmiXrValueError("write_uff: force with a 'reference' dim is not supported yet")
        if names.RECORD not in f.dims:
            f = f.expand_dims(names.RECORD)
        force = f.transpose(names.RECORD, names.TIME).values
    ref_node, ref_dir, ref_tag = dof[drive] if drive is not None else (0, 0, "NONE")

    def record(data, node, direction, tag, case, spec, units):
        return pyuff.prepare_58(
            binary=int(binary),
            id1="ami_xr",
            id2=tag,
            id3=ref_tag,
            id4="NONE",
            id5="NONE",
            func_type=_FUNC_TIME,
            ver_num=0,
            load_case_id=case,
            rsp_ent_name="ami_xr",
            rsp_node=node,
            rsp_dir=direction,
            ref_ent_name="ami_xr",
            ref_node=ref_node,
            ref_dir=ref_dir,
            ord_data_type=4,
            num_pts=time.size,
            abscissa_spacing=1,
            abscissa_min=float(time[0]),
            abscissa_inc=dt,
            z_axis_value=0.0,
            abscissa_spec_data_type=_SPEC_TIME,
            abscissa_axis_units_lab="s",
            ordinate_spec_data_type=spec,
            ordinate_axis_units_lab=_units_lab(units),
            orddenom_spec_data_type=0,
            data=np.asarray(data, dtype=np.float64),
            x=time,
        )

    records = []
    for r in range(resp.shape[0]):
        case = r + 1 if resp.shape[0] > 1 else 0
        for i, lab in enumerate(labels):
            node, direction, tag = dof[lab]
            records.append(
                record(
                    resp[r, i],
                    node,
                    direction,
                    tag,
                    case,
                    _QUANTITY_TO_SPEC[quantity],
                    ds.attrs.get(names.ATTR_RESPONSE_UNITS, ""),
                )
            )
        if force is not None:
            records.append(
                record(
                    force[r],
                    ref_node,
                    ref_dir,
                    ref_tag,
                    case,
                    13,
                    ds.attrs.get(names.ATTR_FORCE_UNITS, ""),
                )
            )
    return records


def _mode_records(ds: xr.Dataset) -> list[dict]:
    """One dataset 55 (complex eigenvalue, first order, displacement) per mode."""
    pyuff = _require_pyuff()
    labels = list(ds[names.POINT].values.tolist())
    dof = _dof_map(labels)
    nodes = sorted({dof[lab][0] for lab in labels})
    vectors = ds[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
    eig = np.asarray(ds[names.EIGENVALUE].values)
    modes = ds[names.MODE].values
    records = []
    rotational = any(abs(dof[lab][1]) > 3 for lab in labels)
    ncomp = 6 if rotational else 3
    for k in range(eig.size):
        comps = np.zeros((ncomp, len(nodes)), dtype=np.complex128)
        for i, lab in enumerate(labels):
            node, direction, _ = dof[lab]
            # A scalar DOF (direction 0) is written as the Z component.
            axis = abs(direction) if direction != 0 else 3
            sign = -1.0 if direction < 0 else 1.0
            comps[axis - 1, nodes.index(node)] = sign * vectors[i, k]
        mode_n = int(modes[k]) if np.issubdtype(np.asarray(modes).dtype, np.integer) else k + 1
        kwargs = {f"r{c + 1}": comps[c] for c in range(ncomp)}
        records.append(
            pyuff.prepare_55(
                id1="ami_xr mode shapes",
                id2="NONE",
                id3="NONE",
                id4="NONE",
                id5="NONE",
                model_type=1,
                analysis_type=3,
                data_ch=3 if rotational else 2,
                spec_data_type=8,
                data_type=5,
                n_data_per_node=ncomp,
                load_case=1,
                mode_n=mode_n,
                eig=complex(eig[k]),
                modal_a=0j,
                modal_b=0j,
                node_nums=np.asarray(nodes),
                **kwargs,
            )
        )
    return records


def write_uff(
    ds: xr.Dataset,
    path: str | os.PathLike,
    *,
    binary: bool = False,
    include: Sequence[str] = ("frf", "time", "modes"),
) -> Path:
    """Write a Dataset as UFF, atomically (see :func:`ami_xr.io.atomic.atomic_path`).

    FRFs (``frf``, and ``coherence`` if present) go to dataset 58 with function type 4 (response =
    each point, reference = the drive point); time Datasets to dataset 58 function type 1 (one
    record per point and per ``record``, load case = record number, plus the force at the drive
    point); identified modes (``eigenvalue`` and ``mode_vector``) to one dataset 55 per mode
    (complex eigenvalue, displacement). Reading the file back with :func:`read_uff` gives the same
    FRFs and mode vectors.

    Parameters
    ----------
    ds : xarray.Dataset
        FRF, time or modal Dataset (an identification result holds FRFs and modes; both are
        written unless ``include`` says otherwise).
    path : str or path-like
        Output file; overwritten atomically.
    binary : bool
        Write dataset 58 in binary (exact float64) rather than ASCII (about 12 significant digits).
    include : sequence of {"frf", "time", "modes"}
        Which parts to write when present.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    pyuff = _require_pyuff()
    path = Path(path)
    bad = set(include) - {"frf", "time", "modes"}
    if bad:
        raise AmiXrValueError(f"include must hold 'frf', 'time' or 'modes'; got {sorted(bad)}")
    records: list[dict] = []
    if "frf" in include and names.FRF in ds:
        records += _frf_records(ds, binary)
    if "time" in include and names.RESPONSE in ds:
        records += _time_records(ds, binary)
    if "modes" in include and names.MODE_VECTOR in ds and names.EIGENVALUE in ds:
        records += _mode_records(ds)
    if not records:
        raise AmiXrValueError(
            f"write_uff: the Dataset has nothing to write for include={list(include)} "
            f"(needs '{names.FRF}', '{names.RESPONSE}' or "
            f"'{names.MODE_VECTOR}'+'{names.EIGENVALUE}')"
        )
    with atomic_path(path) as tmp, warnings.catch_warnings():
        # pyuff warns about optional fields we leave at their defaults.
        warnings.simplefilter("ignore")
        # tmp does not exist yet: pyuff refuses to "overwrite" a file it did not write.
        pyuff.UFF(str(tmp)).write_sets(records, mode="add")
    return path
