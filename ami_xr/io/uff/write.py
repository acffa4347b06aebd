"""Write UFF files: FRFs and time histories as dataset 58, identified modes as dataset 55,
point coordinates as dataset 2411 (or 15).

See :mod:`ami_xr.io.uff` for the mapping from ami_xr Datasets.
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError, SchemaError
from ami_xr.io.atomic import atomic_path, interrupts_deferred
from ami_xr.io.uff.codes import (
    FUNC_COHERENCE,
    FUNC_FRF,
    FUNC_TIME,
    MODES_ID1,
    QUANTITY_TO_SPEC,
    SPEC_FREQUENCY,
    SPEC_TIME,
    dof_map,
    require_pyuff,
)
from ami_xr.io.uff.nodes import NODE_DATASETS, node_records
from ami_xr.io.uff.quiet import quiet

__all__ = ["MODAL_A_LINE", "check_writable", "modal_a_b", "write_uff"]


def _nonfinite(values: np.ndarray, dims: Sequence[str]) -> str | None:
    """How many NaN or inf ``values`` holds, and where the first is; None when none."""
    bad = ~np.isfinite(values)
    if not bad.any():
        return None
    first = np.unravel_index(int(np.argmax(bad)), bad.shape)
    where = ", ".join(f"{dim}={int(i)}" for dim, i in zip(dims, first, strict=True))
    return f"{int(bad.sum())} NaN or inf value(s) (first at index {where})"


def _axis_problems(ds: xr.Dataset, dim: str, units: str) -> list[str]:
    """The abscissa of dataset 58: present, finite, strictly increasing."""
    if dim not in ds.coords or ds.coords[dim].ndim != 1:
        return [f"coordinate {dim!r}: missing (expected 1-D values in {units} along dim {dim!r})"]
    coord = ds.coords[dim]
    if coord.dtype.kind not in "fiu":
        return [f"coordinate {dim!r}: expected real numbers in {units}, got dtype {coord.dtype}"]
    values = np.asarray(coord.values, dtype=np.float64)
    if values.size < 2:
        # pyuff cannot write a one-value record (it fails with a bare Exception).
        return [f"coordinate {dim!r}: expected at least 2 values, got {values.size}"]
    bad = _nonfinite(values, (dim,))
    if bad:
        return [f"coordinate {dim!r}: expected finite values, found {bad}"]
    steps = np.diff(values)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        return [
            f"coordinate {dim!r}: expected strictly increasing values, not increasing at "
            f"{int((steps <= 0).sum())} place(s) (first: index {i} = {float(values[i])!r} then "
            f"{float(values[i + 1])!r})"
        ]
    return []


def _signal_problems(ds: xr.Dataset, var: str, dims: set[str], dtype_kind: str) -> list[str]:
    """Dims, dtype and finiteness of one variable written as dataset-58 records."""
    da = ds[var]
    what = {"c": "complex", "f": "real float"}[dtype_kind]
    if not dims <= set(da.dims):
        return [f"variable {var!r}: expected dims including {sorted(dims)}, got {da.dims}"]
    if da.dtype.kind != dtype_kind:
        return [f"variable {var!r}: expected {what} values, got dtype {da.dtype}"]
    bad = _nonfinite(np.asarray(da.values), da.dims)
    return [f"variable {var!r}: expected finite values, found {bad}"] if bad else []


def _point_problems(ds: xr.Dataset) -> list[str]:
    """Unique point labels: each becomes one UFF degree of freedom."""
    labels = [str(v) for v in ds[names.POINT].values.tolist()]
    dup = sorted({lab for lab in labels if labels.count(lab) > 1})
    return [f"coordinate {names.POINT!r}: expected unique labels, duplicates {dup}"] if dup else []


def check_writable(ds: xr.Dataset, include: Sequence[str]) -> None:
    """Check what :func:`write_uff` will write, before any record is made.

    A UFF file with NaN values, a real-valued FRF record, a decreasing abscissa or two records on
    one degree of freedom reads back wrong (or not at all) in any program, so it is never
    written. Every problem is reported at once.

    Raises
    ------
    SchemaError
        Naming each variable or coordinate and what was expected.
    """
    problems: list[str] = []
    if "frf" in include and names.FRF in ds:
        problems += _signal_problems(ds, names.FRF, {names.POINT, names.FREQUENCY}, "c")
        if names.COHERENCE in ds:
            problems += _signal_problems(ds, names.COHERENCE, {names.POINT, names.FREQUENCY}, "f")
        problems += _axis_problems(ds, names.FREQUENCY, names.FREQUENCY_UNITS)
    if "time" in include and names.RESPONSE in ds:
        problems += _signal_problems(ds, names.RESPONSE, {names.POINT, names.TIME}, "f")
        if names.FORCE in ds:
            problems += _signal_problems(ds, names.FORCE, {names.TIME}, "f")
        problems += _axis_problems(ds, names.TIME, names.TIME_UNITS)
    if names.POINT in ds.coords:
        problems += _point_problems(ds)
    if "frf" in include and names.FRF in ds and names.REFERENCE in ds[names.FRF].dims:
        refs = [str(v) for v in ds[names.REFERENCE].values.tolist()]
        dup = sorted({r for r in refs if refs.count(r) > 1})
        if dup:
            problems.append(
                f"coordinate {names.REFERENCE!r}: expected unique labels, duplicates {dup}"
            )
    if problems:
        raise SchemaError(problems, what="Dataset to write as UFF")


# coherence records: dimensionless ordinate (UDUNITS "1"), no denominator
COHERENCE_UNITS = "1"


def _units_lab(text: str) -> str:
    return text if text else "NONE"


def _id_lines(ds: xr.Dataset, labels: list) -> dict[str, list[str]]:
    """ID lines 1-5 of each point's records: the ``uff_id1`` ... ``uff_id5`` coordinates
    :func:`read_uff` keeps, else the ``title`` (line 1) and ``NONE`` (UFF lines hold 80
    characters)."""
    title = str(ds.attrs.get("title", "ami_xr"))[:80] or "NONE"
    out = {}
    for key in ("id1", "id2", "id3", "id4", "id5"):
        coord = f"uff_{key}"
        if coord in ds.coords and ds[coord].dims == (names.POINT,):
            out[key] = [str(t)[:80] or "NONE" for t in ds[coord].values.tolist()]
        else:
            out[key] = [title if key == "id1" else "NONE"] * len(labels)
    return out


def _frf_records(ds: xr.Dataset, binary: bool) -> list[dict]:
    pyuff = require_pyuff()
    labels = list(ds[names.POINT].values.tolist())
    multi = names.REFERENCE in ds[names.FRF].dims
    # multi-reference: every reference's own node/direction; SIMO: the drive point's
    drive = None if multi else ds.attrs.get(names.ATTR_DRIVE_POINT)
    refs = list(ds[names.REFERENCE].values.tolist()) if multi else [drive]
    dof = dof_map(labels + [r for r in dict.fromkeys(refs) if r is not None and r not in labels])
    quantity = ds.attrs.get(names.ATTR_QUANTITY, "displacement")
    freq = np.asarray(ds[names.FREQUENCY].values, dtype=np.float64)
    step = np.diff(freq)
    uniform = freq.size > 1 and np.allclose(step, step[0], rtol=1e-9)
    response_units = _units_lab(ds.attrs.get(names.ATTR_RESPONSE_UNITS, ""))
    force_units = _units_lab(ds.attrs.get(names.ATTR_FORCE_UNITS, ""))
    lines = _id_lines(ds, labels)
    # a roving-hammer file read by read_uff is written back as it was: the drive point is the
    # response DOF, each point a reference DOF (the same FRFs by reciprocity)
    roving = not multi and str(ds.attrs.get("uff_layout", "")).startswith("roving hammer")
    records = []
    variables = [(names.FRF, FUNC_FRF)]
    if names.COHERENCE in ds:
        variables.append((names.COHERENCE, FUNC_COHERENCE))
    for var, func in variables:
        if names.REFERENCE in ds[var].dims:
            values = ds[var].transpose(names.REFERENCE, names.POINT, names.FREQUENCY).values
            rows = list(zip(refs, values, strict=True))
        else:  # SIMO, or the multiple coherence (point, frequency) of multi-reference FRFs
            rows = [(drive, ds[var].transpose(names.POINT, names.FREQUENCY).values)]
        for ref, ref_values in rows:
            ref_node, ref_dir, ref_tag = dof[ref] if ref is not None else (0, 0, "NONE")
            for i, lab in enumerate(labels):
                node, direction, tag = dof[lab]
                rsp = (ref_node, ref_dir, ref_tag) if roving else (node, direction, tag)
                ref = (node, direction, tag) if roving else (ref_node, ref_dir, ref_tag)
                dtype = np.complex128 if func == FUNC_FRF else np.float64
                records.append(
                    pyuff.prepare_58(
                        binary=int(binary),
                        id1=lines["id1"][i],
                        id2=rsp[2] if rsp[2] != "NONE" else lines["id2"][i],
                        id3=ref[2] if ref[2] != "NONE" else lines["id3"][i],
                        id4=lines["id4"][i],
                        id5=lines["id5"][i],
                        func_type=func,
                        ver_num=0,
                        load_case_id=0,
                        rsp_ent_name="ami_xr",
                        rsp_node=rsp[0],
                        rsp_dir=rsp[1],
                        ref_ent_name="ami_xr",
                        ref_node=ref[0],
                        ref_dir=ref[1],
                        ord_data_type=6 if func == FUNC_FRF else 4,
                        num_pts=freq.size,
                        abscissa_spacing=int(uniform),
                        abscissa_min=float(freq[0]),
                        abscissa_inc=float(step[0]) if uniform else 0.0,
                        z_axis_value=0.0,
                        abscissa_spec_data_type=SPEC_FREQUENCY,
                        abscissa_axis_units_lab="Hz",
                        ordinate_spec_data_type=(
                            QUANTITY_TO_SPEC[quantity] if func == FUNC_FRF else 0
                        ),
                        ordinate_axis_units_lab=(
                            response_units if func == FUNC_FRF else COHERENCE_UNITS
                        ),
                        orddenom_spec_data_type=13 if func == FUNC_FRF else 0,
                        orddenom_axis_units_lab=force_units if func == FUNC_FRF else "NONE",
                        data=np.asarray(ref_values[i], dtype=dtype),
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


#: ID line 4 of dataset 55: how the modal A and B written make FRFs from the mode vectors.
MODAL_A_LINE = "modal A = 1/lam, B = -1: H_jk = sum Phi_j Phi_k/(A (iw - lam)) + conj"


def modal_a_b(eigenvalue: complex) -> tuple[complex, complex]:
    """Modal A and B of dataset 55 (complex modes, analysis type 3) for ami_xr's mode vectors.

    The first-order (state-space) form that dataset 55 follows writes the residues as
    ``A_jk = psi_j psi_k / a`` with modal A ``a = psi^T A psi`` and modal B
    ``b = psi^T B psi = -lam a``. ami_xr's mode vectors satisfy ``A_jk = lam Phi_j Phi_k``
    (eq. 8), so with ``psi = Phi``: ``a = 1 / lam`` and ``b = -1``. A mode without a finite,
    non-zero eigenvalue gets ``a = b = 0`` (no scaling stated).
    """
    lam = complex(eigenvalue)
    if not (np.isfinite(lam.real) and np.isfinite(lam.imag)) or lam == 0:
        return 0j, 0j
    return 1.0 / lam, -1.0 + 0j


def _convention_lines(ds: xr.Dataset) -> tuple[str, str]:
    """ID lines 2 and 3 of dataset 55: the mode-vector convention and units (80 columns)."""
    attrs = ds[names.MODE_VECTOR].attrs
    units = attrs.get(names.ATTR_UNITS, "")
    if str(attrs.get("convention", "")).startswith("displacement"):
        line2 = "displacement mode vectors, eq. 8: A_jP = lam Phi_j Phi_P (receptance A)"
    else:  # a file from before the convention: scaled on the FRF as measured
        line2 = f"mode vectors of the {ds.attrs.get(names.ATTR_FRF_TYPE, 'FRF')} (eq. 8)"
    return line2[:80], (f"units {units}" if units else "NONE")[:80]


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
    id2, id3 = _convention_lines(ds)
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
                "id1": MODES_ID1,
                "id2": id2,
                "id3": id3,
                "id4": MODAL_A_LINE,
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
                "modal_a": modal_a_b(eig[k])[0],
                "modal_b": modal_a_b(eig[k])[1],
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
    geometry: int | str = 2411,
) -> Path:
    """Write a Dataset as UFF, atomically (see :func:`ami_xr.io.atomic.atomic_path`).

    FRFs (``frf``, and ``coherence`` if present) go to dataset 58 with function type 4 (response =
    each point, reference = the drive point; multi-reference FRFs, dims ``(reference, point,
    frequency)``: one record per (reference, point) with that reference's node and direction,
    and a ``coherence`` without ``reference`` dim with reference node 0); time Datasets to
    dataset 58 function type 1 (one record per point and per ``record``, load case = record
    number, plus the force at the drive point); identified modes (``eigenvalue`` and
    ``mode_vector``) to one dataset 55 per mode (complex eigenvalue, displacement; modal A
    ``1/lam`` and modal B ``-1``, so that ``Phi_j Phi_k / A`` is the receptance residue and
    another tool rebuilds the FRFs from the shapes: :func:`modal_a_b`, ID line 4 says so); point
    coordinates (``point_x/y/z``, if any) to one dataset 2411 (double precision; dataset 15 with
    ``geometry=15``) in metres, first. Reading the file back with :func:`read_uff` gives the
    same FRFs, mode vectors and coordinates (with dataset 15 to the 6 digits it holds).

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
    geometry : {2411, 15}
        The node dataset of the point coordinates: 2411 (default; double precision, what
        current tools write) or 15 (older tools; about 6 significant digits).

    Returns
    -------
    pathlib.Path
        The written file.

    Raises
    ------
    SchemaError
        The Dataset would make an invalid UFF file (see :func:`check_writable`): NaN or inf in
        ``frf``/``coherence``/``response``/``force``, a real-valued ``frf``, a frequency or time
        axis that is not strictly increasing, duplicate point labels. Nothing is written.
    AmiXrValueError
        Unknown ``include`` entries, or nothing to write.
    """
    pyuff = require_pyuff()
    path = Path(path)
    bad = set(include) - {"frf", "time", "modes"}
    if bad:
        raise AmiXrValueError(f"include must hold 'frf', 'time' or 'modes'; got {sorted(bad)}")
    if str(geometry) not in map(str, NODE_DATASETS):
        raise AmiXrValueError(f"geometry: expected 2411 or 15 (the node dataset), got {geometry!r}")
    check_writable(ds, include)
    records: list[dict] = []
    if "frf" in include and names.FRF in ds:
        records += node_records(ds, int(geometry))
        records += _frf_records(ds, binary)
    if "time" in include and names.RESPONSE in ds:
        records += _time_records(ds, binary)
    if "modes" in include and names.MODE_VECTOR in ds and names.EIGENVALUE in ds:
        if not any(r.get("type") in NODE_DATASETS for r in records):
            records = node_records(ds, int(geometry)) + records
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
        # pyuff's bare ``except:`` turns a KeyboardInterrupt raised inside it into "Error
        # writing data-set": signals are held while pyuff runs and handed over between blocks
        # of records (an interrupt then removes the temporary file, the target is untouched).
        with interrupts_deferred() as held:
            # tmp does not exist yet: pyuff refuses to "overwrite" a file it did not write;
            # "add" creates it and appends the later blocks.
            with quiet():  # pyuff's print() output is not the tool's output
                uff = pyuff.UFF(str(tmp))
            for lo in range(0, len(records), RECORDS_PER_BLOCK):
                for record in records[lo : lo + RECORDS_PER_BLOCK]:
                    offset = tmp.stat().st_size if tmp.exists() else 0
                    with quiet():
                        uff.write_sets([record], mode="add")
                    if record.get("type") == 58:
                        _restate_abscissa(tmp, offset, record)
                held.deliver()
    return path


# --- the abscissa of dataset 58 --------------------------------------------------------------
#: Width of the real fields of record 7 of dataset 58 (Fortran 3I10,3E13.5; pyuff reads the
#: fields by these columns).
_FIELD = 13
#: Columns of record 7 (of the dataset's 9th line) that hold the abscissa minimum and increment.
_MIN_COLS, _INC_COLS = slice(30, 43), slice(43, 56)


def _short_exponent(text: str) -> str:
    """``1.25E-01`` -> ``1.25E-1``: a Fortran and Python real either way, two columns shorter."""
    return re.sub(r"E([+-])0*(\d)", r"E\1\2", text)


def real_field(value: float, width: int = _FIELD) -> str:
    """``value`` as the most precise text that fits ``width`` columns with a leading blank.

    pyuff writes the abscissa minimum and increment of dataset 58 as ``%13.5e``: six significant
    digits, so a step of 0.10666666666666667 Hz comes back as 0.106667 Hz and the 321st line
    drifts by 7e-5 Hz in every reader that rebuilds the axis from the header (pyuff, SDynPy).
    UFF reads the field as a Fortran real of 13 columns: any real text (fixed point, an
    exponent with one digit) is valid there, which leaves room for 10 or 11 significant digits
    (``.10666666667``): the last of 321 lines is then off by about 1e-9 Hz. Full double
    precision (17 digits) does not fit; a wider field would shift the columns pyuff and Fortran
    readers cut the record by. The text pyuff would write is kept where it is already exact.
    """
    text = f"{value:{width}.5e}"
    if float(text) == value:
        return text
    best: tuple[float, int, str] | None = None
    for digits in range(17, -1, -1):
        for candidate in (
            f"{value:.{digits}f}",
            _short_exponent(f"{value:.{digits}E}"),
            f"{value:.{digits}g}",
            re.sub(r"^(-?)0\.", r"\1.", f"{value:.{digits}f}"),  # .1066666667: one more digit
        ):
            if len(candidate) > width - 1:
                continue
            key = (abs(float(candidate) - value), len(candidate), candidate)
            if best is None or key < best:
                best = key
    return best[2].rjust(width) if best is not None else text


def _restate_abscissa(path: Path, offset: int, record: dict) -> None:
    """Rewrite, in place and at the same width, the abscissa minimum and increment of the
    dataset-58 record pyuff has just written at byte ``offset`` of ``path`` (see
    :func:`real_field`). Uneven abscissas (written point by point) are left as they are."""
    if int(record.get("abscissa_spacing", 0)) != 1:
        return
    x = np.asarray(record["x"], dtype=np.float64)
    if x.size < 2:
        return
    with open(path, "r+b") as fh:
        fh.seek(offset)
        head = fh.read(16384)  # 8 header lines of 80 characters, UTF-8: well within
        lines = head.split(b"\n", 9)
        if len(lines) < 10:
            return
        line = lines[8]
        if len(line.rstrip(b"\r")) != 3 * 10 + 3 * _FIELD:
            return  # not the record-7 layout pyuff writes: leave the file as written
        start = offset + sum(len(part) + 1 for part in lines[:8])
        fields = (real_field(float(x[0])) + real_field(float(x[1] - x[0]))).encode("ascii")
        fh.seek(start + _MIN_COLS.start)
        fh.write(fields)


#: Records pyuff writes between two looks at a held Ctrl-C or SIGTERM: one (a record of 2049
#: lines takes pyuff ~0.1 s, ~0.4 s on a loaded machine; 32 held a SIGTERM for up to 10 s).
RECORDS_PER_BLOCK = 1
