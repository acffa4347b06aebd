"""Read and write a measurement file by its suffix: netCDF, UFF, LabVIEW LVM, FRF tables.

The one place that maps a file name to its reader or writer; the command line and
:func:`ami_xr.batch.batch` go through it. Each reader is imported only when its format is used,
so the optional ``pyuff`` is needed for UFF files only.

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

from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError

__all__ = [
    "INPUT_SUFFIXES",
    "OUTPUT_ANY",
    "OUTPUT_FOLDER",
    "OUTPUT_NETCDF",
    "OUTPUT_SUFFIXES",
    "TABLE_SUFFIXES",
    "check_output",
    "open_frf",
    "read_any",
    "write_any",
]

NETCDF_SUFFIX = ".nc"
UFF_SUFFIXES = (".uff", ".unv")
LVM_SUFFIX = ".lvm"
TEXT_SUFFIXES = (".csv", ".txt", ".dat")
MATLAB_SUFFIX = ".mat"
#: Suffixes (lower case) of measurement files: what ``batch`` looks for in a folder tree.
INPUT_SUFFIXES = (NETCDF_SUFFIX, *UFF_SUFFIXES, LVM_SUFFIX)
#: Suffixes (lower case) of FRF tables (text and MATLAB), which :func:`read_any` reads too;
#: ``batch`` leaves them out (a folder of measurements holds other .txt and .csv files).
TABLE_SUFFIXES = (*TEXT_SUFFIXES, MATLAB_SUFFIX)
_READ_SUFFIXES = (*INPUT_SUFFIXES, *TABLE_SUFFIXES)
#: File suffixes (lower case) :func:`write_any` writes.
OUTPUT_SUFFIXES = (NETCDF_SUFFIX, *UFF_SUFFIXES)
#: ``kind`` of :func:`check_output`: a file of any of :data:`OUTPUT_SUFFIXES` (:func:`write_any`),
#: a netCDF file only (:func:`ami_xr.to_netcdf`), or a folder (created if missing).
OUTPUT_ANY = "file"
OUTPUT_NETCDF = "netcdf"
OUTPUT_FOLDER = "folder"
_WRITE_BITS = stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH


def _same_file(a: Path, b: Path) -> bool:
    """``a`` and ``b`` name one file: the same resolved path (symlinks) or inode (hard links)."""
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
        if _same_file(path, Path(other)):
            same = "" if str(other) == str(path) else f" {str(other)!r}"
            harm = "mix results with the inputs" if kind == OUTPUT_FOLDER else "destroy the input"
            raise DataFileError(
                f"{label} is the input{same}: writing there would {harm}; "
                "choose another output name"
            )
    for other in outputs:
        if _same_file(path, Path(other)):
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


def _kind_of(mode: int) -> str:
    for test, what in (
        (stat.S_ISFIFO, "a named pipe (FIFO)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISDIR, "a folder"),
    ):
        if test(mode):
            return what
    return "not a regular file"


def check_input(path: str | os.PathLike, *, name: str = "input", folder: bool = False) -> Path:
    """Refuse, before anything opens it, an input that is not a regular file (or a folder, with
    ``folder=True``): a named pipe would block the reader forever, a device (``/dev/zero``,
    also through a symlink) never ends. Names what the path is.

    Raises
    ------
    DataFileError
        The path is empty, missing, or of the wrong kind.
    """
    text = os.fspath(path)
    if text == "":
        raise DataFileError(f"{name}: the path is empty")
    p = Path(text)
    try:
        mode = os.stat(p).st_mode  # follows symlinks: a link to /dev/zero is a device
    except FileNotFoundError:
        link = " (a symlink whose target is missing)" if os.path.islink(p) else ""
        raise DataFileError(f"{name}: {text!r}: no such file{link}") from None
    except OSError as err:
        raise DataFileError(f"{name}: {text!r}: {err.strerror or err}") from None
    wanted = stat.S_ISDIR(mode) if folder else stat.S_ISREG(mode)
    if not wanted:
        expected = "a folder" if folder else "a regular file"
        raise DataFileError(f"{name}: {text!r} is {_kind_of(mode)}, expected {expected}")
    return p


def read_any(
    path: str | os.PathLike,
    *,
    force_channel: int | str | None = None,
    points: list | None = None,
    drive_point: Any = None,
    want: str | None = None,
):
    """Read a measurement file into a Dataset, choosing the reader by the file's suffix.

    Parameters
    ----------
    path : str or path-like
        A ``.nc`` (:func:`ami_xr.open_dataset`), ``.uff``/``.unv`` (:func:`ami_xr.read_uff`),
        ``.lvm`` (:func:`ami_xr.read_lvm`), ``.csv``/``.txt``/``.dat``
        (:func:`~ami_xr.io.frf_tables.read_frf_csv`) or ``.mat``
        (:func:`~ami_xr.io.frf_tables.read_frf_mat`) file; the suffix is matched
        case-insensitively.
    force_channel, points : optional
        Passed to :func:`ami_xr.read_lvm`; the other formats name their channels themselves,
        so giving one for them raises.
    drive_point : label, optional
        Passed to :func:`ami_xr.read_lvm` and the table readers; for the other formats it must
        be one of the Dataset's points and replaces its ``drive_point`` attribute.
    want : {"frf", "time"}, optional
        What the caller needs: a modes file (identify's output) is then refused with a
        message naming the commands that take it (:func:`ami_xr.io.kinds.refuse_other_kind`).
        None (default) takes any kind. A ``.mat`` file is read as time histories
        (:func:`ami_xr.io.time_mat.read_time_mat`, which also takes ``force_channel`` and
        ``points``) with ``want="time"`` or when it has a sampling rate and no frequency
        vector, else as an FRF table.

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    DataFileError
        The path is not a regular file (:func:`check_input`), the suffix is none of
        :data:`INPUT_SUFFIXES` and :data:`TABLE_SUFFIXES`, or the reader rejects the file; a
        :class:`~ami_xr.io.kinds.ModesFileError` for a modes file where ``want`` asks for
        another kind.
    """
    path = check_input(path, name=str(path) or "input")
    suffix = path.suffix.lower()
    if suffix == LVM_SUFFIX:
        from ami_xr.io.lvm import read_lvm

        return read_lvm(path, force_channel=force_channel, points=points, drive_point=drive_point)
    if suffix not in _READ_SUFFIXES:
        raise DataFileError(
            f"{path}: unknown file type {suffix!r}; expected one of {_READ_SUFFIXES}"
        )
    if suffix == MATLAB_SUFFIX and want != "frf":
        from ami_xr.io.time_mat import holds_time_histories, read_time_mat

        if want == "time" or holds_time_histories(path):  # else an FRF table
            return read_time_mat(
                path, force_channel=force_channel, points=points, drive_point=drive_point
            )
    for name, given in (("force_channel", force_channel), ("points", points)):
        if given is not None:
            raise AmiXrValueError(
                f"{name}: only for LabVIEW {LVM_SUFFIX} input; {path.name} names its channels"
            )
    if suffix in TABLE_SUFFIXES:  # FRFs only: no other kind to refuse
        return _read_table(path, drive_point=drive_point)
    if suffix == NETCDF_SUFFIX:
        from ami_xr.io.netcdf import open_dataset

        ds = open_dataset(path)
    else:
        from ami_xr.io.uff import read_uff

        ds = read_uff(path)
    if want is not None:
        from ami_xr.io.kinds import refuse_other_kind

        refuse_other_kind(ds, path, want)
    if drive_point is not None:
        labels = list(ds[names.POINT].values) if names.POINT in ds.coords else []
        as_text = [label for label in labels if str(label) == str(drive_point)]
        drive_point = as_text[0] if drive_point not in labels and as_text else drive_point
        if drive_point not in labels:
            raise AmiXrValueError(
                f"drive_point: {drive_point!r} is not one of the points {labels!r} of {path.name}"
            )
        ds.attrs[names.ATTR_DRIVE_POINT] = drive_point
        ds.attrs.pop(names.ATTR_DRIVE_POINT_ASSUMED, None)
    return ds


def _read_table(path: Path, **options: Any):
    """An FRF table (:data:`TABLE_SUFFIXES`) with its reader's ``options``."""
    if path.suffix.lower() == MATLAB_SUFFIX:
        from ami_xr.io.frf_tables import read_frf_mat

        return read_frf_mat(path, **options)
    from ami_xr.io.frf_tables import read_frf_csv

    return read_frf_csv(path, **options)


def open_frf(
    path: str | os.PathLike,
    *,
    drive_point: Any = None,
    points: list | None = None,
    response_quantity: str | None = None,
    frf_type: str | None = None,
    response_units: str | None = None,
    force_units: str | None = None,
):
    """Read FRFs from a file of any format ami_xr reads, chosen by the suffix.

    Parameters
    ----------
    path : str or path-like
        ``.nc``, ``.uff``/``.unv``, or an FRF table: ``.csv``/``.txt``/``.dat`` (a frequency
        column and real/imaginary or magnitude/phase columns per point) or ``.mat`` (MATLAB
        variables ``freq`` and ``H``); the accepted layouts are described in
        :mod:`ami_xr.io.frf_tables`.
    drive_point : label, optional
        The point where the force acts: replaces the file's (it must be one of the points).
    points : list, optional
        Tables only: point labels in the file's order, replacing its own.
    response_quantity, frf_type, response_units, force_units : str, optional
        Tables only (netCDF and UFF files state them): as for :func:`ami_xr.make_frf_dataset`;
        default what the file says, else receptance in m/N is assumed, with an
        :class:`~ami_xr.errors.AssumptionWarning` and the attribute
        ``response_quantity_assumed``.

    Returns
    -------
    xarray.Dataset
        FRF Dataset following the data model (built with :func:`ami_xr.make_frf_dataset` for
        tables).

    Raises
    ------
    DataFileError
        The file is missing, of an unknown type, holds time histories or modes instead of FRFs,
        or its reader rejects it (the message names the file and the column or variable).
    AmiXrValueError
        A table-only option given for a netCDF or UFF file.
    """
    path = check_input(path, name=str(path) or "input")
    table = {
        "points": points,
        "response_quantity": response_quantity,
        "frf_type": frf_type,
        "response_units": response_units,
        "force_units": force_units,
    }
    if path.suffix.lower() in TABLE_SUFFIXES:
        return _read_table(path, drive_point=drive_point, **table)
    for name, given in table.items():
        if given is not None:
            raise AmiXrValueError(
                f"{name}: only for FRF tables ({', '.join(TABLE_SUFFIXES)}); {path.name} states "
                "its points and units"
            )
    if path.suffix.lower() == LVM_SUFFIX:
        raise DataFileError(
            f"{path}: a LabVIEW file holds time histories; estimate FRFs with ami_xr.frf "
            f"(ami-xr frf {path.name} -o frf.nc) first"
        )
    ds = read_any(path, drive_point=drive_point, want="frf")
    if names.FRF not in ds:
        raise DataFileError(
            f"{path}: holds no FRFs (variable {names.FRF!r}); for time histories estimate them "
            "with ami_xr.frf first"
        )
    return ds


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
