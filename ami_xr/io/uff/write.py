"""Write UFF files: FRFs and time histories as dataset 58, identified modes as dataset 55.

See :mod:`ami_xr.io.uff` for the mapping from ami_xr Datasets.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.io.atomic import atomic_path
from ami_xr.io.uff.codes import (
    FUNC_COHERENCE,
    FUNC_FRF,
    FUNC_TIME,
    QUANTITY_TO_SPEC,
    SPEC_FREQUENCY,
    SPEC_TIME,
    dof_map,
    require_pyuff,
)

__all__ = ["write_uff"]


def _units_lab(text: str) -> str:
    return text if text else "NONE"


def _frf_records(ds: xr.Dataset, binary: bool) -> list[dict]:
    pyuff = require_pyuff()
    labels = list(ds[names.POINT].values.tolist())
    drive = ds.attrs.get(names.ATTR_DRIVE_POINT)
    dof = dof_map(labels + ([drive] if drive is not None and drive not in labels else []))
    quantity = ds.attrs.get(names.ATTR_QUANTITY, "displacement")
    freq = np.asarray(ds[names.FREQUENCY].values, dtype=np.float64)
    step = np.diff(freq)
    uniform = freq.size > 1 and np.allclose(step, step[0], rtol=1e-9)
    ref_node, ref_dir, ref_tag = dof[drive] if drive is not None else (0, 0, "NONE")
    records = []
    variables = [(names.FRF, FUNC_FRF)]
    if names.COHERENCE in ds:
        variables.append((names.COHERENCE, FUNC_COHERENCE))
    for var, func in variables:
        values = ds[var].transpose(names.POINT, names.FREQUENCY).values
        for i, lab in enumerate(labels):
            node, direction, tag = dof[lab]
            data = np.asarray(values[i], dtype=np.complex128 if func == FUNC_FRF else np.float64)
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
                    ord_data_type=6 if func == FUNC_FRF else 4,
                    num_pts=freq.size,
                    abscissa_spacing=int(uniform),
                    abscissa_min=float(freq[0]),
                    abscissa_inc=float(step[0]) if uniform else 0.0,
                    z_axis_value=0.0,
                    abscissa_spec_data_type=SPEC_FREQUENCY,
                    abscissa_axis_units_lab="Hz",
                    ordinate_spec_data_type=QUANTITY_TO_SPEC[quantity] if func == FUNC_FRF else 0,
                    ordinate_axis_units_lab=_units_lab(ds.attrs.get(names.ATTR_RESPONSE_UNITS, "")),
                    orddenom_spec_data_type=13 if func == FUNC_FRF else 0,
                    orddenom_axis_units_lab=_units_lab(ds.attrs.get(names.ATTR_FORCE_UNITS, "")),
                    data=data,
                    x=freq,
                )
            )
    return records


def _time_records(ds: xr.Dataset, binary: bool) -> list[dict]:
    pyuff = require_pyuff()
    labels = list(ds[names.POINT].values.tolist())
    drive = ds.attrs.get(names.ATTR_DRIVE_POINT)
    dof = dof_map(labels + ([drive] if drive is not None and drive not in labels else []))
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
            func_type=FUNC_TIME,
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
            abscissa_spec_data_type=SPEC_TIME,
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
                    QUANTITY_TO_SPEC[quantity],
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
    require_pyuff()  # the clear "install the uff extra" error before any work
    labels = list(ds[names.POINT].values.tolist())
    dof = dof_map(labels)
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
        # The record dict that pyuff.prepare_55 builds, written out: prepare_55 of pyuff 2.5.3
        # (what pip installs on Python 3.10) rejects complex mode shapes.
        records.append(
            {
                "type": 55,
                "id1": "ami_xr mode shapes",
                "id2": "NONE",
                "id3": "NONE",
                "id4": "NONE",
                "id5": "NONE",
                "model_type": 1,
                "analysis_type": 3,
                "data_ch": 3 if rotational else 2,
                "spec_data_type": 8,
                "data_type": 5,
                "n_data_per_node": ncomp,
                "load_case": 1,
                "mode_n": mode_n,
                "eig": complex(eig[k]),
                "modal_a": 0j,
                "modal_b": 0j,
                "node_nums": np.asarray(nodes),
                **kwargs,
            }
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
    pyuff = require_pyuff()
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
