"""The file behind a lazy open must not change before its data are read.

A lazily opened netCDF file (:func:`ami_xr.open_dataset` with ``chunks``) is read when the
computation runs. If the file was truncated, rewritten or removed in between, netCDF/HDF5 may
hand back stale or zero-filled blocks from its caches, and a computation would return a wrong
result with no error. :func:`source_guard` records the file's identity at the open (size,
modification time, inode and device); every block read by dask first checks it
(:func:`guarded_getter`, dask's ``getitem`` of :func:`dask.array.from_array`), and a
difference, a vanished file or a read that fails is a :class:`~ami_xr.errors.DataFileError`
naming the file, raised before the block is used.

netCDF-C and the HDF5 library under it are not thread-safe, and xarray's own locks leave
parts of an open (attributes, variable metadata) unguarded: files opened from several threads
crashed the process (SIGSEGV) in about a third of the runs. :data:`NETCDF_LOCK` is the one
process-wide lock ami_xr holds around every netCDF/HDF5 call it makes: the opens and eager reads
of :func:`ami_xr.open_dataset`, each block read of a lazy open (:func:`guarded_getter`), the
close of a lazy open, eager writes and the batch's look at an output's attributes.
"""

from __future__ import annotations

import functools
import os
import threading
from collections.abc import Callable
from typing import Any

from ami_xr.errors import DataFileError

__all__ = ["NETCDF_LOCK", "guarded_getter", "locked_call", "source_guard", "stamp"]

#: Held around every netCDF-C/HDF5 call of ami_xr (re-entrant: an open inside a locked block,
#: e.g. a reader that opens a second file, does not wait on itself).
NETCDF_LOCK = threading.RLock()

Stamp = tuple[int, int, int, int]


def stamp(path: str) -> Stamp:
    """What identifies the file's content cheaply: size, mtime (ns), inode and device."""
    st = os.stat(path)
    return st.st_size, st.st_mtime_ns, st.st_ino, st.st_dev


def check_source(path: str, opened: Stamp) -> None:
    """Raise :class:`DataFileError` when ``path`` is gone or differs from ``opened``."""
    prefix = f"{path}: opened lazily, but the file"
    advice = "its data can no longer be read as they were; open it again"
    try:
        now = stamp(path)
    except OSError as err:
        raise DataFileError(
            f"{prefix} was removed or renamed before the computation read it "
            f"({type(err).__name__}); {advice}"
        ) from None
    if now == opened:
        return
    what = []
    if now[0] != opened[0]:
        what.append(f"size {opened[0]} -> {now[0]} bytes")
    if now[1] != opened[1]:
        what.append("modification time")
    if now[2:] != opened[2:]:
        what.append("replaced by another file")
    raise DataFileError(
        f"{prefix} changed on disk before the computation read it ({', '.join(what)}); {advice}"
    )


def guarded_getter(a: Any, b: Any, asarray: bool = True, lock: Any = None, *, source=None):
    """dask's block getter, after :func:`check_source`; a failing read names the file too."""
    from dask.array.core import getter

    path, opened = source
    check_source(path, opened)
    try:
        with NETCDF_LOCK:
            return getter(a, b, asarray=asarray, lock=lock)
    except (OSError, RuntimeError) as err:  # netCDF-C/HDF5 read errors
        check_source(path, opened)  # changed while reading: say so
        raise DataFileError(
            f"{path}: opened lazily, but reading a block of it failed (truncated or corrupt?): "
            f"{type(err).__name__}: {err}"
        ) from err


def source_guard(path: str) -> Callable[..., Any]:
    """The ``getitem`` for :func:`dask.array.from_array` that guards ``path`` as it is now."""
    return functools.partial(guarded_getter, source=(path, stamp(path)))


def locked_call(function: Callable[[], Any]) -> Any:
    """``function()`` under :data:`NETCDF_LOCK` (e.g. the close of a lazily opened file)."""
    with NETCDF_LOCK:
        return function()
