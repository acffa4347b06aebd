"""Read and write a measurement file by its suffix: netCDF, UFF, LabVIEW LVM, FRF tables.

The readers are registered in :mod:`ami_xr.io.readers` (one signature, one options record);
this module re-exports :func:`read_any` and :func:`open_frf` and holds the writers and the
output rule. The command line and :func:`ami_xr.batch.batch` go through it. Each reader and
writer is imported only when its format is used, so the optional ``pyuff`` is needed for UFF
files only.

* ``.nc``: read with :func:`ami_xr.open_dataset`, written with :func:`ami_xr.to_netcdf`;
* ``.uff``, ``.unv``: read with :func:`ami_xr.read_uff`, written with
  :func:`ami_xr.io.uff.write_uff`;
* ``.lvm``: read with :func:`ami_xr.read_lvm` (not written);
* ``.csv``, ``.txt``, ``.dat`` (FRF tables as text) and ``.mat`` (MATLAB): read with
  :func:`ami_xr.io.frf_tables.read_frf_csv` and :func:`~ami_xr.io.frf_tables.read_frf_mat`
  (not written).

:func:`open_frf` is the Python entry for FRFs in any of these formats.

:func:`check_output` is the output rule every writing command applies before any work: an
output never names one of the inputs (also through a symlink or a hard link), its suffix is
that of the format written, and an existing read-only output, an existing file where a folder
goes or a missing or read-only folder is refused instead of failing after the computation.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.readers import (
    INPUT_SUFFIXES,
    LVM_SUFFIX,
    NETCDF_SUFFIX,
    TABLE_SUFFIXES,
    UFF_SUFFIXES,
    check_input,
    open_frf,
    read_any,
)

__all__ = [
    "INPUT_SUFFIXES",
    "OUTPUT_ANY",
    "OUTPUT_FOLDER",
    "OUTPUT_NETCDF",
    "OUTPUT_SUFFIXES",
    "TABLE_SUFFIXES",
    "LVM_SUFFIX",
    "check_input",
    "check_output",
    "same_file",
    "open_frf",
    "read_any",
    "write_any",
]

#: File suffixes (lower case) :func:`write_any` writes.
OUTPUT_SUFFIXES = (NETCDF_SUFFIX, *UFF_SUFFIXES)
#: ``kind`` of :func:`check_output`: a file of any of :data:`OUTPUT_SUFFIXES` (:func:`write_any`),
#: a netCDF file only (:func:`ami_xr.to_netcdf`), or a folder (created if missing).
OUTPUT_ANY = "file"
OUTPUT_NETCDF = "netcdf"
OUTPUT_FOLDER = "folder"
_WRITE_BITS = stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """``a`` and ``b`` name one file or folder: the same resolved path (symlinks, another
    spelling) or the same inode (hard links, a bind mount); False where one does not exist."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist: not the same file
        return False


def _writable(path: Path) -> bool:
    # Write permission bits as well as access(2): root passes access() for a 0444 file, and
    # replacing it anyway would silently undo a user's "chmod a-w" protection.
    return os.access(path, os.W_OK) and bool(path.stat().st_mode & _WRITE_BITS)


def _nearest_existing(path: Path) -> Path:
    path = Path(os.path.abspath(path))
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def check_output(
    path: str | os.PathLike,
    kind: str = OUTPUT_ANY,
    *,
    inputs: Iterable[str | os.PathLike] = (),
    outputs: Iterable[str | os.PathLike] = (),
    name: str = "output",
    writer: str = "",
) -> Path:
    """Refuse an output path before any work is done; return it as a :class:`~pathlib.Path`.

    Existing writable outputs are replaced (atomically, by the writers); everything that would
    lose data or fail only after the computation is an error here.

    Parameters
    ----------
    path : str or path-like
        The output file or folder.
    kind : {"file", "netcdf", "folder"}
        ``"file"``: a ``.nc``, ``.uff`` or ``.unv`` file (:func:`write_any`); ``"netcdf"``: a
        ``.nc`` file; ``"folder"``: a folder, created with its parents if missing.
    inputs, outputs : iterable of path-like
        Files or folders the command reads, and the other outputs it writes: ``path`` must be
        none of them, also through a symlink or a hard link.
    name : str, default "output"
        How the message names ``path`` (the option, e.g. ``"-o"``).
    writer : str, optional
        What writes ``path`` (e.g. ``"simulate"``), for the message on a wrong suffix.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    DataFileError
        ``path`` is one of ``inputs`` or ``outputs``; its suffix is not one the format has; it
        exists and is read-only; a file output is an existing folder, a folder output an
        existing file; or the folder it goes in is missing (file outputs) or not writable.
    """
    path = Path(path)
    label = f"{name} {str(path)!r}"
    for other in inputs:
        if same_file(path, other):
            same = "" if str(other) == str(path) else f" {str(other)!r}"
            harm = "mix results with the inputs" if kind == OUTPUT_FOLDER else "destroy the input"
            raise DataFileError(
                f"{label} is the input{same}: writing there would {harm}; "
                "choose another output name"
            )
    for other in outputs:
        if same_file(path, other):
            raise DataFileError(
                f"{label} is also the output {str(other)!r}; give each its own name"
            )
    suffix = path.suffix.lower()
    by = f"{writer} writes" if writer else "writes"
    if kind == OUTPUT_NETCDF and suffix != NETCDF_SUFFIX:
        raise DataFileError(f"{label}: {by} netCDF; expected a {NETCDF_SUFFIX} file name")
    if kind == OUTPUT_ANY and suffix not in OUTPUT_SUFFIXES:
        raise DataFileError(f"{label}: expected a .nc, .uff or .unv file name, got {suffix!r}")
    if kind == OUTPUT_FOLDER:
        if path.exists() and not path.is_dir():
            raise DataFileError(f"{label} exists and is not a folder")
        folder = _nearest_existing(path)
    else:
        if path.is_dir():
            raise DataFileError(f"{label} is a folder; expected a file name")
        if path.exists() and not _writable(path):
            mode = stat.S_IMODE(path.stat().st_mode)
            raise DataFileError(
                f"{label} exists and is read-only (mode {mode:04o}); make it writable or "
                "choose another output name"
            )
        folder = Path(os.path.abspath(path)).parent
        if not folder.is_dir():
            raise DataFileError(f"{label}: folder {str(folder)!r} does not exist")
    if not folder.is_dir() or not _writable(folder):
        raise DataFileError(f"{label}: folder {str(folder)!r} is not writable")
    _check_name_length(path, folder, label)
    return path


#: Bytes the atomic writers add to a name for their temporary folder (``.<name>.<12 hex>.tmp``).
TEMP_NAME_EXTRA = len(".") + len(".123456789abc.tmp")


def _check_name_length(path: Path, folder: Path, label: str) -> None:
    """A name the file system takes, but not with the writer's temporary name around it, would
    fail only after the whole computation: refuse it now."""
    try:
        limit = os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):
        limit = 255
    size = len(os.fsencode(path.name))
    if size + TEMP_NAME_EXTRA > limit:
        raise DataFileError(
            f"{label}: the file name is {size} bytes long; at most {limit - TEMP_NAME_EXTRA} "
            f"bytes here (the file system takes {limit}, and the atomic write needs "
            f"{TEMP_NAME_EXTRA} for its temporary name)"
        )


def write_any(
    ds,
    path: str | os.PathLike,
    *,
    binary: bool = False,
    function: str | None = None,
    parameters: dict[str, Any] | None = None,
    geometry: int | str = 2411,
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
    geometry : {2411, 15}
        UFF only: the node dataset of the point coordinates (see
        :func:`ami_xr.io.uff.write_uff`).

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

        return write_uff(ds, path, binary=binary, geometry=geometry)
    if suffix != NETCDF_SUFFIX:
        raise AmiXrValueError(f"output {str(path)!r}: expected a .nc, .uff or .unv file name")
    from ami_xr.io.netcdf import to_netcdf

    return to_netcdf(ds, path, function=function, parameters=parameters)
