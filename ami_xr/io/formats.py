"""Read and write a measurement file by its suffix: netCDF, UFF or LabVIEW LVM.

The one place that maps a file name to its reader or writer; the command line and
:func:`ami_xr.batch.batch` go through it. Each reader is imported only when its format is used,
so the optional ``pyuff`` is needed for UFF files only.

* ``.nc``: read with :func:`ami_xr.open_dataset`, written with :func:`ami_xr.to_netcdf`;
* ``.uff``, ``.unv``: read with :func:`ami_xr.read_uff`, written with
  :func:`ami_xr.io.uff.write_uff`;
* ``.lvm``: read with :func:`ami_xr.read_lvm` (not written).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ami_xr.errors import AmiXrValueError, DataFileError

__all__ = ["INPUT_SUFFIXES", "OUTPUT_SUFFIXES", "read_any", "write_any"]

NETCDF_SUFFIX = ".nc"
UFF_SUFFIXES = (".uff", ".unv")
LVM_SUFFIX = ".lvm"
#: File suffixes (lower case) :func:`read_any` reads.
INPUT_SUFFIXES = (NETCDF_SUFFIX, *UFF_SUFFIXES, LVM_SUFFIX)
#: File suffixes (lower case) :func:`write_any` writes.
OUTPUT_SUFFIXES = (NETCDF_SUFFIX, *UFF_SUFFIXES)


def read_any(path: str | os.PathLike):
    """Read a measurement file into a Dataset, choosing the reader by the file's suffix.

    Parameters
    ----------
    path : str or path-like
        A ``.nc`` (:func:`ami_xr.open_dataset`), ``.uff``/``.unv`` (:func:`ami_xr.read_uff`)
        or ``.lvm`` (:func:`ami_xr.read_lvm`) file; the suffix is matched case-insensitively.

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    DataFileError
        The suffix is none of :data:`INPUT_SUFFIXES`, or the reader rejects the file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == NETCDF_SUFFIX:
        from ami_xr.io.netcdf import open_dataset

        return open_dataset(path)
    if suffix in UFF_SUFFIXES:
        from ami_xr.io.uff import read_uff

        return read_uff(path)
    if suffix == LVM_SUFFIX:
        from ami_xr.io.lvm import read_lvm

        return read_lvm(path)
    raise DataFileError(f"{path}: unknown file type {suffix!r}; expected one of {INPUT_SUFFIXES}")


def write_any(
    ds,
    path: str | os.PathLike,
    *,
    binary: bool = False,
    function: str | None = None,
    parameters: dict[str, Any] | None = None,
) -> Path:
    """Write a Dataset to ``path`` (atomically), choosing the writer by the file's suffix.

    Parameters
    ----------
    ds : xarray.Dataset
        FRF, time or modal-result Dataset.
    path : str or path-like
        ``.nc`` (netCDF with a provenance record) or ``.uff``/``.unv`` (dataset 58 FRFs or time
        histories, 55 mode shapes).
    binary : bool, default False
        UFF only: write dataset 58 in binary (exact float64) instead of ASCII.
    function, parameters : optional
        netCDF only: the provenance record (see :func:`ami_xr.to_netcdf`).

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    AmiXrValueError
        The suffix is none of :data:`OUTPUT_SUFFIXES`.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in UFF_SUFFIXES:
        from ami_xr.io.uff import write_uff

        return write_uff(ds, path, binary=binary)
    if suffix != NETCDF_SUFFIX:
        raise AmiXrValueError(f"output {str(path)!r}: expected a .nc, .uff or .unv file name")
    from ami_xr.io.netcdf import to_netcdf

    return to_netcdf(ds, path, function=function, parameters=parameters)
