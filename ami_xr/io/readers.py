"""One reader interface: a registry of readers by file suffix, one signature, one options record.

Every format is a :class:`Reader`: its suffixes, the kinds of data it gives (``"frf"``,
``"time"``, ``"modes"``), the options of :class:`~ami_xr.io.build.ReadOptions` it takes and a
read function ``read(path, options, want) -> xarray.Dataset``. :func:`read_any` and
:func:`open_frf` (the command line, :func:`ami_xr.batch.batch`) find the reader by the suffix
(:func:`reader_for`) and refuse an option the format does not take, naming the formats that
do. The readers build their Datasets through :func:`~ami_xr.io.build.frf_dataset` and
:func:`~ami_xr.io.build.time_dataset` (tables, MATLAB, LabVIEW) or
:func:`ami_xr.make_frf_dataset` and :func:`ami_xr.make_time_dataset` (UFF); netCDF files are
Datasets already. Each reader module is imported only when its format is used, so the optional
``pyuff`` is needed for UFF files only.

* ``.nc``: FRFs, time histories or modes, :func:`ami_xr.open_dataset`;
* ``.uff``, ``.unv``: FRFs, time histories or modes, :func:`ami_xr.read_uff`;
* ``.lvm``: time histories, :func:`ami_xr.read_lvm`;
* ``.csv``, ``.txt``, ``.dat``: FRFs (:func:`~ami_xr.io.frf_tables.read_frf_csv`) or time
  histories (:func:`~ami_xr.io.time_table.read_time_csv`);
* ``.mat``: FRFs (:func:`~ami_xr.io.frf_tables.read_frf_mat`) or time histories
  (:func:`~ami_xr.io.time_mat.read_time_mat`).
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.build import OPTION_KEYS, TIME_OPTION_KEYS, ReadOptions, matching_label

__all__ = [
    "INPUT_SUFFIXES",
    "LVM_SUFFIX",
    "NETCDF_SUFFIX",
    "TABLE_SUFFIXES",
    "UFF_SUFFIXES",
    "Reader",
    "check_input",
    "open_frf",
    "read_any",
    "reader_for",
    "register",
]

NETCDF_SUFFIX = ".nc"
UFF_SUFFIXES = (".uff", ".unv")
LVM_SUFFIX = ".lvm"
TEXT_SUFFIXES = (".csv", ".txt", ".dat")
MATLAB_SUFFIX = ".mat"
#: Suffixes (lower case) of measurement files: what ``batch`` looks for in a folder tree.
INPUT_SUFFIXES = (NETCDF_SUFFIX, *UFF_SUFFIXES, LVM_SUFFIX)
#: Suffixes (lower case) of tables (text and MATLAB), which :func:`read_any` reads too;
#: ``batch`` leaves them out (a folder of measurements holds other .txt and .csv files).
TABLE_SUFFIXES = (*TEXT_SUFFIXES, MATLAB_SUFFIX)

#: ``read(path, options, want)``: the one signature of every registered reader.
Read = Callable[[Path, ReadOptions, "str | None"], xr.Dataset]


@dataclass(frozen=True)
class Reader:
    """One file format.

    Attributes
    ----------
    name : str
        How messages name the format (``"LabVIEW .lvm input"``).
    suffixes : tuple of str
        Lower-case file suffixes.
    kinds : tuple of str
        What its files hold: ``"frf"``, ``"time"``, ``"modes"``.
    accepts : tuple of str
        The :class:`~ami_xr.io.build.ReadOptions` fields it takes.
    read : callable
        ``read(path, options, want) -> xarray.Dataset``; ``want`` is ``"frf"``, ``"time"`` or
        None (any kind).
    """

    name: str
    suffixes: tuple[str, ...]
    kinds: tuple[str, ...]
    accepts: tuple[str, ...]
    read: Read


_REGISTRY: dict[str, Reader] = {}


def register(reader: Reader) -> Reader:
    """Add ``reader`` for each of its suffixes (replacing a reader registered before)."""
    for suffix in reader.suffixes:
        _REGISTRY[suffix.lower()] = reader
    return reader


def readers() -> list[Reader]:
    """The registered readers, each once, in registration order."""
    return list(dict.fromkeys(_REGISTRY.values()))


def reader_for(path: str | os.PathLike) -> Reader:
    """The reader of ``path`` by its suffix (case-insensitive).

    Raises
    ------
    DataFileError
        No reader for the suffix.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in _REGISTRY:
        raise DataFileError(
            f"{path}: unknown file type {suffix!r}; expected one of {tuple(_REGISTRY)}"
        )
    return _REGISTRY[suffix]


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


def _options(reader: Reader, given: dict[str, Any], path: Path) -> ReadOptions:
    """The options of a call; one the format does not take names the formats that do."""
    for key, value in given.items():
        if value is None or key in reader.accepts:
            continue
        takers = [r.name for r in readers() if key in r.accepts]
        where = f"only for {', '.join(takers)}" if takers else "not an option"
        raise AmiXrValueError(f"{key}: {where}; {path.name} names its channels, points and units")
    return ReadOptions.of(given, f"the {reader.name} reader", reader.accepts)


def read_any(path: str | os.PathLike, *, want: str | None = None, **options: Any) -> xr.Dataset:
    """Read a measurement file into a Dataset, choosing the reader by the file's suffix.

    Parameters
    ----------
    path : str or path-like
        A file of a registered format (module docstring); the suffix is matched
        case-insensitively.
    want : {"frf", "time"}, optional
        What the caller needs: a modes file (identify's output) is then refused with a
        message naming the commands that take it (:func:`ami_xr.io.kinds.refuse_other_kind`);
        a table or MATLAB file is read as that kind. None (default) takes any kind (a table or
        MATLAB file holding time histories is told by its time column or sampling rate).
    **options
        :class:`~ami_xr.io.build.ReadOptions` (``points``, ``drive_point``,
        ``response_quantity``, ``frf_type``, ``response_units``, ``force_units``,
        ``force_channel``, ``fs``, ``sensitivity``): each format takes the ones it needs.

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    DataFileError
        The path is not a regular file (:func:`check_input`), no reader takes its suffix, or
        the reader rejects the file; a :class:`~ami_xr.io.kinds.ModesFileError` for a modes
        file where ``want`` asks for another kind.
    AmiXrValueError
        An option the format does not take (the message names the formats that take it).
    """
    path = check_input(path, name=str(path) or "input")
    reader = reader_for(path)
    return reader.read(path, _options(reader, options, path), want)


def open_frf(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read FRFs from a file of any format ami_xr reads, chosen by the suffix.

    Parameters
    ----------
    path : str or path-like
        ``.nc``, ``.uff``/``.unv``, or an FRF table: ``.csv``/``.txt``/``.dat`` (a frequency
        column and real/imaginary or magnitude/phase columns per point) or ``.mat`` (MATLAB
        variables ``freq`` and ``H``); the accepted layouts are described in
        :mod:`ami_xr.io.frf_tables`.
    **options
        ``drive_point`` (every format: the point where the force acts, one of the points);
        tables only (netCDF and UFF files state them): ``points``, ``response_quantity``,
        ``frf_type``, ``response_units``, ``force_units``, as for
        :func:`ami_xr.make_frf_dataset`; default what the file says, else receptance in m/N is
        assumed, with an :class:`~ami_xr.errors.AssumptionWarning` and the attribute
        ``response_quantity_assumed``.

    Returns
    -------
    xarray.Dataset
        FRF Dataset following the data model.

    Raises
    ------
    DataFileError
        The file is missing, of an unknown type, holds time histories or modes instead of FRFs,
        or its reader rejects it (the message names the file and the column or variable).
    AmiXrValueError
        An option the format does not take.
    """
    path = check_input(path, name=str(path) or "input")
    reader = reader_for(path)
    if "frf" not in reader.kinds:
        raise DataFileError(
            f"{path}: a {reader.name} file holds time histories; estimate FRFs with ami_xr.frf "
            f"(ami-xr frf {path.name} -o frf.nc) first"
        )
    ds = read_any(path, want="frf", **options)
    if names.FRF not in ds:
        raise DataFileError(
            f"{path}: holds no FRFs (variable {names.FRF!r}); for time histories estimate them "
            "with ami_xr.frf first"
        )
    return ds


# --- the registered formats --------------------------------------------------------------------
def _stored(ds: xr.Dataset, path: Path, options: ReadOptions, want: str | None) -> xr.Dataset:
    """A Dataset stored whole (netCDF, UFF): the kind checked, a drive point given set."""
    if want is not None:
        from ami_xr.io.kinds import refuse_other_kind

        refuse_other_kind(ds, path, want)
    if options.drive_point is not None:
        labels = list(ds[names.POINT].values.tolist()) if names.POINT in ds.coords else []
        ds.attrs[names.ATTR_DRIVE_POINT] = matching_label(
            options.drive_point, labels, "given", path
        )
        ds.attrs.pop(names.ATTR_DRIVE_POINT_ASSUMED, None)
    return ds


def _read_netcdf(path: Path, options: ReadOptions, want: str | None) -> xr.Dataset:
    from ami_xr.io.netcdf import open_dataset

    return _stored(open_dataset(path), path, options, want)


def _read_uff(path: Path, options: ReadOptions, want: str | None) -> xr.Dataset:
    from ami_xr.io.uff import read_uff

    return _stored(read_uff(path), path, options, want)


def _read_lvm(path: Path, options: ReadOptions, want: str | None) -> xr.Dataset:
    from ami_xr.io.lvm import read_lvm

    return read_lvm(path, **options.given())


def _table(path: Path, options: ReadOptions, want: str | None) -> xr.Dataset:
    """A table, text or MATLAB: time histories when ``want`` says so or the file has a time
    column or a sampling rate (and no frequency), else FRFs."""
    if path.suffix.lower() == MATLAB_SUFFIX:
        from ami_xr.io.frf_tables import read_frf_mat as read_frf
        from ami_xr.io.time_mat import holds_time_histories
        from ami_xr.io.time_mat import read_time_mat as read_time
    else:
        from ami_xr.io.frf_tables import read_frf_csv as read_frf
        from ami_xr.io.time_table import holds_time_histories
        from ami_xr.io.time_table import read_time_csv as read_time

    if want == "time" or (want is None and holds_time_histories(path)):
        return read_time(path, **options.given())
    return read_frf(path, **options.given())


register(
    Reader("netCDF", (NETCDF_SUFFIX,), ("frf", "time", "modes"), ("drive_point",), _read_netcdf)
)
register(Reader("UFF", UFF_SUFFIXES, ("frf", "time", "modes"), ("drive_point",), _read_uff))
_TIME = tuple(k for k in TIME_OPTION_KEYS if k != "frf_type")
register(Reader("LabVIEW .lvm input", (LVM_SUFFIX,), ("time",), _TIME, _read_lvm))
_TABLES = tuple(dict.fromkeys((*OPTION_KEYS, *TIME_OPTION_KEYS)))
register(Reader("text tables (.csv, .txt, .dat)", TEXT_SUFFIXES, ("frf", "time"), _TABLES, _table))
register(Reader("MATLAB files (.mat)", (MATLAB_SUFFIX,), ("frf", "time"), _TABLES, _table))
