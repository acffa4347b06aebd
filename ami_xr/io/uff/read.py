"""Read UFF files: dataset 58 FRFs and time histories, 55 mode shapes, 15/2411 node coordinates.

See :mod:`ami_xr.io.uff` for the mapping to ami_xr Datasets. The datasets are read one at a time
(:mod:`.sets`); FRF records become a Dataset in :mod:`.frf`, time records in :mod:`.time`, mode
shapes in :mod:`.modes`; units are settled in :mod:`.units`, node coordinates in :mod:`.nodes`.
"""

from __future__ import annotations

import os
from pathlib import Path

import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.uff.codes import FUNC_COHERENCE, FUNC_FRF, FUNC_TIME, describe_sets
from ami_xr.io.uff.frf import read_frf
from ami_xr.io.uff.modes import ATTR_MODES_SKIPPED, MODE_ANALYSIS_TYPES, read_modes, with_modes
from ami_xr.io.uff.nodes import attach_coordinates, node_coordinates
from ami_xr.io.uff.sets import read_sets
from ami_xr.io.uff.time import read_time
from ami_xr.io.uff.units import (
    ATTR_QUANTITY_FROM_LABEL,
    ATTR_UNITS_ASSUMED,
    ATTR_UNITS_SCALED,
    units_system,
)

__all__ = [
    "read_uff",
    "ATTR_UNITS_ASSUMED",
    "ATTR_UNITS_SCALED",
    "ATTR_MODES_SKIPPED",
    "ATTR_QUANTITY_FROM_LABEL",
]


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
            raise DataFileError(
                f"{path}: no FRF (58, function type 4), time response (58, type 1) or mode-shape "
                f"(55) dataset; found datasets {describe_sets(sets)}"
            )
    elif not found[kind]:
        raise DataFileError(
            f"{path}: the file holds no {kind} dataset; found datasets {describe_sets(sets)}"
        )
    system = units_system(sets)
    nodes = node_coordinates(sets, system, path)
    if kind == "frf":
        ds = read_frf(frfs, cohs, nodes, path, system)
        if modes and merge_modes:
            ds = with_modes(ds, modes, path)
    elif kind == "time":
        ds = read_time(times, nodes, path, system)
    else:
        ds, label_nodes = read_modes(modes, path)
        ds = attach_coordinates(ds, nodes, label_nodes)
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
