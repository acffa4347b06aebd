"""netCDF files: lossless encode/decode of what netCDF cannot store, atomic writes, lazy opening.

On-disk conventions (readable without ami_xr, see the README's "netCDF files" section):

* A complex variable ``z`` with dims ``(d1, ..., dn)`` is stored as a float variable ``z`` with
  dims ``(d1, ..., dn, "complex")``; index 0 of the trailing dim holds the real part, index 1 the
  imaginary part (complex128 -> float64, complex64 -> float32), bit for bit. The variable carries
  the attribute ``ami_xr_complex = "real,imag along last dim complex"``. Plain xarray recovers
  it with ``raw.z.isel(complex=0) + 1j * raw.z.isel(complex=1)`` (exact except for the sign of
  zero and NaN imaginary parts; use the view in the README for bit-exact values).
* Boolean variables are stored by xarray as int8 with the attribute ``dtype = "bool"`` (plain
  xarray decodes them back).
* Attributes netCDF cannot hold natively (bool, complex, None, dict, empty or one-element
  lists, integers beyond int64) are stored in a plain form, and the attribute
  ``ami_xr_encoded_attrs`` of the same variable (or of the Dataset) holds a JSON object
  ``{attribute name: tag}`` saying how to decode each: ``"bool"`` (int8 0/1), ``"bool[]"``
  (int8 array), ``"complex"`` (float array ``[real, imag]``), ``"complex[]"`` (float array
  ``[re0, im0, re1, im1, ...]``), ``"json"`` (a JSON string), ``"[1]"`` (a one-element
  array stored as a scalar).
* Float variables are written without ``_FillValue`` so every bit pattern (NaN payloads, -0.0)
  comes back unchanged.
* CF metadata (:mod:`ami_xr.io.cf`): ``Conventions = "CF-1.11"``, ``title``, ``source``, a CF
  ``history`` line per step, ``long_name`` on every variable, ``units`` (UDUNITS) on every
  numeric one (mode vectors in ``sqrt(X)``: ``units_of_square = X`` instead), string or
  unsorted dim coordinates as label variables ``<dim>_label``, and the int32 bit field
  ``quality_flags`` with the CF ``flag_masks``/``flag_meanings`` (a file of an earlier version,
  flags as comma text, reads as the same bits). The IOOS compliance
  checker (``cf:1.11``) finds no issue in these files (``tests/io/test_cf_compliance.py``).
* No machine path: ``source_file`` and the history records hold file names only. In memory,
  :func:`open_dataset` sets ``source_file`` to the absolute path read.
"""

from __future__ import annotations

import contextlib
import functools
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.coords import uniform_coords
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.atomic import atomic_path, interrupts_deferred
from ami_xr.io.cf import ATTR_CF_ADDED, annotate, flags_as_bits, on_disk_name, strip
from ami_xr.io.lazy_source import NETCDF_LOCK, locked_call, source_guard
from ami_xr.io.netcdf_codec import (
    ATTR_COMPLEX,
    ATTR_COMPLEX_VALUE,
    ATTR_ENCODED_ATTRS,
    ATTR_TAGS,
    check_cf_marker,
    decode_attrs,
    encode_attrs,
    from_pairs,
    to_pairs,
)
from ami_xr.provenance import add_history, running_command

__all__ = [
    "open_dataset",
    "to_netcdf",
    "encode",
    "decode",
    "LAZY_THRESHOLD_BYTES",
    "ATTR_COMPLEX",
    "ATTR_COMPLEX_VALUE",
    "ATTR_ENCODED_ATTRS",
    "ATTR_TAGS",
]

ENGINE = "netcdf4"
FORMAT = "NETCDF4"  # needed for int64 and variable-length strings

# Files larger than this open lazily (dask-backed) when neither ``chunks`` nor ``lazy`` is given.
LAZY_THRESHOLD_BYTES = 256 * 2**20


def _is_dask(data: Any) -> bool:
    try:
        import dask
    except ImportError:  # pragma: no cover - dask is an optional dependency
        return False
    return dask.is_dask_collection(data)


def _encode_complex_variable(name: str, var: xr.Variable) -> xr.Variable:
    if names.COMPLEX in var.dims:
        raise AmiXrValueError(
            f"variable {name!r}: already has a dim {names.COMPLEX!r}, reserved for the on-disk "
            "complex encoding"
        )
    data = var.data
    real = np.empty(0, var.dtype).real.dtype
    if _is_dask(data):
        # map_blocks with an explicit meta: lazy, one block in -> one block out (no rechunk)
        pairs = data.map_blocks(
            to_pairs,
            new_axis=data.ndim,
            chunks=data.chunks + ((2,),),
            meta=np.empty((0,) * (data.ndim + 1), real),
        )
    else:
        pairs = to_pairs(data)
    out = xr.Variable(var.dims + (names.COMPLEX,), pairs)
    out.attrs = {**var.attrs, ATTR_COMPLEX: ATTR_COMPLEX_VALUE}
    return out


def _decode_complex_variable(name: str, var: xr.Variable) -> xr.Variable:
    if (
        not var.dims
        or var.dims[-1] != names.COMPLEX
        or var.shape[-1] != 2
        or not np.issubdtype(var.dtype, np.floating)
    ):
        raise DataFileError(
            f"variable {name!r} is flagged {ATTR_COMPLEX!r} but is not float with a last dim "
            f"{names.COMPLEX!r} of length 2 (dims {var.dims}, dtype {var.dtype})"
        )
    data = var.data
    ctype = np.result_type(var.dtype, np.complex64)
    if _is_dask(data):
        data = data.rechunk({data.ndim - 1: 2})  # (real, imag) of a value in one block
        values = data.map_blocks(
            from_pairs, drop_axis=data.ndim - 1, meta=np.empty((0,) * (data.ndim - 1), ctype)
        )
    else:
        values = from_pairs(data)
    out = xr.Variable(var.dims[:-1], values)
    out.attrs = {k: v for k, v in var.attrs.items() if k != ATTR_COMPLEX}
    return out


# --- whole Datasets -------------------------------------------------------------------------------


def _rebuild(ds: xr.Dataset, variables: dict[str, xr.Variable], attrs: dict) -> xr.Dataset:
    coord_names = set(ds.coords)
    return xr.Dataset(
        {k: v for k, v in variables.items() if k not in coord_names},
        coords={k: v for k, v in variables.items() if k in coord_names},
        attrs=attrs,
    )


def encode(ds: xr.Dataset) -> xr.Dataset:
    """The Dataset as it is written to disk: complex variables as (real, imag) pairs, attributes
    netCDF cannot hold tagged, stale encodings dropped. Lazy (dask) data stays lazy.

    Raises :class:`~ami_xr.errors.AmiXrValueError` (naming the variable or attribute) for what
    cannot be stored: complex dimension coordinates, 2-D attributes, unsupported types.
    """
    if names.COMPLEX in ds.dims:
        raise AmiXrValueError(
            f"ds: has a dim {names.COMPLEX!r}, reserved for the on-disk complex encoding; "
            "rename it before writing (or, if this came from an ami_xr file opened with plain "
            "xarray, open it with ami_xr.open_dataset)"
        )
    variables: dict[str, xr.Variable] = {}
    for name, var in ds.variables.items():
        owner = f"variable {name!r}"
        var = var.copy(deep=False)
        var.encoding = {}
        var.attrs = encode_attrs(var.attrs, owner)
        if np.issubdtype(var.dtype, np.complexfloating):
            if name in ds.dims:
                raise AmiXrValueError(
                    f"coordinate {name!r}: a complex dimension coordinate cannot be written to "
                    "netCDF; make it a non-index coordinate or drop it"
                )
            var = _encode_complex_variable(str(name), var.to_base_variable())
        if np.issubdtype(var.dtype, np.floating):
            var.encoding = {"_FillValue": None}  # keep every bit pattern; NaN is stored as is
        variables[name] = var
    return _rebuild(ds, variables, encode_attrs(ds.attrs, "the Dataset"))


def decode(ds: xr.Dataset) -> xr.Dataset:
    """Inverse of :func:`encode`: complex variables back from (real, imag), attributes untagged.

    Works lazily on dask-backed Datasets (nothing is read).
    """
    variables: dict[str, xr.Variable] = {}
    for name, var in ds.variables.items():
        if ATTR_COMPLEX in var.attrs:
            var = _decode_complex_variable(str(name), var.to_base_variable())
        else:
            var = var.copy(deep=False)
        var.attrs = decode_attrs(var.attrs, f"variable {name!r}")
        variables[name] = var
    return _rebuild(ds, variables, decode_attrs(ds.attrs, "the Dataset"))


# --- files ----------------------------------------------------------------------------------------


def _check_dask(argument: str) -> None:
    try:
        import dask.array  # noqa: F401
    except ImportError as err:  # pragma: no cover - dask is installed in the test environment
        raise AmiXrValueError(
            f"{argument}: lazy opening needs dask (pip install 'ami_xr[dask]')"
        ) from err


# A lazily opened uniform time axis is replaced by a RangeIndex when the stored values match
# start + i * step to this many ulp of the largest |t| (rounding of i * dt or i / fs).
_TIME_AXIS_ULPS = 16
_TIME_AXIS_PROBES = 4096  # strided sample of stored time values checked against the grid
# attributes under which xarray would transform the stored values; the fast path then steps aside
_TRANSFORMING_ATTRS = ("scale_factor", "add_offset", "calendar")


def _uniform_time_axis(path: Path) -> xr.Coordinates | None:
    """An O(1)-memory ``time`` coordinate for ``path``, or None to let xarray read it.

    Reads only ``time[0]``, ``time[1]``, ``time[-1]`` and a strided sample of at most
    ``_TIME_AXIS_PROBES`` values with netCDF4 (never the whole variable). Returns None unless
    ``time`` is a 1-D float64 dimension coordinate of >= 2 finite, increasing values, without
    CF scaling, calendar or "since" units, whose probed values all equal the grid
    ``t0 + i * (t[-1] - t0) / (n - 1)`` to ``_TIME_AXIS_ULPS`` ulp of ``max(|t0|, |t[-1]|)``.
    """
    import netCDF4

    with netCDF4.Dataset(path, "r") as nc:
        # an epoch-less time axis is "elapsed_time" on disk (ami_xr.io.cf); strip renames it
        marker = nc.getncattr(ATTR_CF_ADDED) if ATTR_CF_ADDED in nc.ncattrs() else None
        dim = on_disk_name(marker, names.TIME)
        var = nc.variables.get(dim)
        if var is None or var.dimensions != (dim,) or var.dtype != np.float64:
            return None
        n = int(var.shape[0])
        attrs = {k: var.getncattr(k) for k in var.ncattrs()}
        units = attrs.get(names.ATTR_UNITS)
        if (
            n < 2
            or any(k in attrs for k in _TRANSFORMING_ATTRS)
            or (isinstance(units, str) and " since " in units)
        ):
            return None
        var.set_auto_maskandscale(False)  # raw stored values; fill values are checked below
        stride = max(1, -(-(n - 1) // (_TIME_AXIS_PROBES - 1)))  # ceil
        strided = np.asarray(var[0:n:stride], np.float64).tolist()
        read = dict(zip(range(0, n, stride), strided, strict=True))
        read[1], read[n - 1] = (float(v) for v in np.asarray(var[[1, n - 1]], np.float64))
        positions = np.array(sorted(read))
        probes = np.array([read[i] for i in positions])
        fills = [attrs[k] for k in ("_FillValue", "missing_value") if k in attrs]
    if not np.all(np.isfinite(probes)) or any(np.any(probes == f) for f in fills):
        return None
    t0, last = float(probes[0]), float(probes[-1])
    if not last > t0:
        return None
    kept = {k: v for k, v in attrs.items() if k not in ("_FillValue", "missing_value")}
    coords = uniform_coords(t0, last, n, dim, decode_attrs(kept, f"variable {dim!r}"))
    grid = coords[dim].variable[positions].values  # computes only the probed positions
    tol = _TIME_AXIS_ULPS * np.finfo(np.float64).eps * max(abs(t0), abs(last))
    if np.max(np.abs(grid - probes)) > tol:
        return None
    return coords


def _disk_chunks(path: Path, chunks):
    """``chunks`` with a ``time`` key under the dim's on-disk name (``elapsed_time`` for an
    epoch-less time axis, see :mod:`ami_xr.io.cf`)."""
    if not isinstance(chunks, dict) or names.TIME not in chunks:
        return chunks
    import netCDF4

    with netCDF4.Dataset(path, "r") as nc:
        marker = nc.getncattr(ATTR_CF_ADDED) if ATTR_CF_ADDED in nc.ncattrs() else None
    disk = on_disk_name(marker, names.TIME)
    return {(disk if k == names.TIME else k): v for k, v in chunks.items()}


def _check_utf8_name(path: Path) -> None:
    """Raise :class:`DataFileError` for a path that is not valid UTF-8 (netCDF-C takes UTF-8
    names only; ``os.listdir`` hands such names over with surrogate escapes)."""
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        shown = os.fsencode(path).decode("utf-8", "backslashreplace")
        raise DataFileError(
            f"{shown}: the path is not valid UTF-8, which netCDF cannot open; rename the file"
        ) from None


def open_dataset(
    path: str | os.PathLike,
    chunks: dict[str, int] | int | str | None = None,
    lazy: bool | None = None,
) -> xr.Dataset:
    """Open an ami_xr netCDF file, decoding complex variables and tagged attributes.

    Parameters
    ----------
    path : str or path-like
        The netCDF file.
    chunks : dict, int or "auto", optional
        dask chunk sizes, e.g. ``{"time": 2**20}``; implies ``lazy=True``.
    lazy : bool, optional
        Whether to return dask-backed variables instead of reading the file into memory.
        The rule when ``lazy`` is None: lazy if ``chunks`` is given or the file is larger than
        ``LAZY_THRESHOLD_BYTES`` (256 MiB; chunks then default to ``"auto"``), eager otherwise.
        An eager open reads everything and closes the file. A lazy open keeps the file open and
        reads on compute; decoding complex variables stays lazy too. ``ds.close()`` (or a
        ``with`` block) releases the file. The file must stay as it was until the data are read:
        each block read checks its size, modification time and inode against the open
        (:mod:`ami_xr.io.lazy_source`), and a changed, truncated, replaced or removed file is a
        :class:`~ami_xr.errors.DataFileError` naming it, never a result from stale data.

        Time axis of a lazy open: a 1-D float64 ``time`` dimension coordinate is not read into
        a pandas index (8 bytes per sample, 8 GB for 1e9 samples). Only ``time[0]``,
        ``time[1]``, ``time[-1]`` and a strided sample of at most 4096 values are read; when
        they all lie on the uniform grid ``t0 + i * dt`` with ``dt = (time[-1] - t0) / (n - 1)``
        (to 16 ulp of the largest ``|time|``, i.e. float rounding), ``time`` becomes an
        O(1)-memory coordinate backed by ``xarray.indexes.RangeIndex`` whose values are
        ``t0 + i * dt`` (equal to the stored ones to rounding) and whose attributes are the
        stored ones. Otherwise (non-uniform, non-finite, CF-scaled or datetime ``time``) it is
        read as usual. Eager opens always read the stored values. A ``RangeIndex`` selects by
        position (``isel``) and by nearest label (``sel(time=t, method="nearest")``), not by
        label slices; ``ds.drop_indexes("time").set_xindex("time")`` turns it into an ordinary
        pandas index (computing every value).

    Returns
    -------
    xarray.Dataset
        With attribute ``source_file`` set to the absolute path read (in memory only:
        :func:`to_netcdf` records the file name, never the folder).

    Raises
    ------
    DataFileError
        If the file is missing, not a netCDF file, truncated or not decodable; the message names
        the file. For a lazy open also later, when the data are computed, if the file changed
        or vanished since the open.
    AmiXrValueError
        If ``lazy=False`` is combined with ``chunks``.
    """
    path = Path(path)
    if lazy is False and chunks is not None:
        raise AmiXrValueError(f"chunks: given {chunks!r} but lazy=False; chunks imply a lazy open")
    if not path.exists():
        raise DataFileError(f"{path}: no such file")
    if not path.is_file():
        raise DataFileError(f"{path}: not a file")
    _check_utf8_name(path)
    if lazy is None:
        lazy = chunks is not None or path.stat().st_size > LAZY_THRESHOLD_BYTES
    if lazy:
        _check_dask("lazy")
        chunks = "auto" if chunks is None else chunks
    try:
        # Ctrl-C waits until the file is read or opened: raised under xarray's file lock it
        # could leave the lock held and the next close of the file wait forever.
        # NETCDF_LOCK: netCDF-C/HDF5 are not thread-safe (opens from several threads crashed)
        with interrupts_deferred(), NETCDF_LOCK:
            time_axis = _uniform_time_axis(path) if lazy else None
            # each block read checks that the file is still the one opened (lazy_source)
            guard = {"getitem": source_guard(str(path.resolve()))} if lazy else None
            raw = xr.open_dataset(
                path,
                engine=ENGINE,
                chunks=_disk_chunks(path, chunks) if lazy else None,
                decode_timedelta=False,
                drop_variables=list(time_axis) if time_axis is not None else None,
                from_array_kwargs=guard,
            )
            if not lazy:
                with raw:
                    raw = raw.load()
        ds = decode(raw)
        if time_axis is not None:
            ds = ds.assign_coords(time_axis)
        check_cf_marker(ds.attrs.get(ATTR_CF_ADDED))
        ds = strip(ds)  # the CF metadata to_netcdf added is an on-disk encoding
        ds = flags_as_bits(ds)  # a file of an earlier version: the flags as text
    except DataFileError as err:  # decode() names what is wrong: add the file, nothing else
        raise DataFileError(f"{path}: {err}") from err
    except (
        OSError,
        RuntimeError,
        ValueError,
        KeyError,
        IndexError,
        TypeError,
        AttributeError,
    ) as err:
        raise DataFileError(
            f"{path}: cannot read it as a netCDF file (truncated, corrupt or not netCDF?): "
            f"{type(err).__name__}: {err}"
        ) from err
    ds.attrs[names.ATTR_SOURCE_FILE] = str(path.resolve())
    if lazy:
        # decode/strip built a new Dataset: close() releases the file (under the lock)
        ds.set_close(functools.partial(locked_call, raw.close))
    return ds


def to_netcdf(
    ds: xr.Dataset,
    path: str | os.PathLike,
    *,
    function: str | None = None,
    parameters: dict[str, Any] | None = None,
) -> Path:
    """Write ``ds`` to a netCDF file atomically, with provenance.

    The Dataset is encoded (see the module docstring: complex as real/imag pairs, special
    attributes tagged), a provenance record is appended to ``ami_xr_history`` (the writing
    ``function`` and its ``parameters``, UTC time, ami_xr version and the Dataset's
    ``source_file`` if it has one), and the file is written with
    :func:`ami_xr.io.atomic.atomic_path`: to a temporary file in a private hidden folder
    ``.<name>.<random>.tmp`` next to ``path``, which it then replaces with ``os.replace``.

    Guarantees: on any error the temporary folder and file are removed and an existing ``path``
    is left untouched; ``path`` may be the file ``ds`` was lazily opened from (the old file stays
    readable until the new one is complete, then is swapped in one rename; POSIX only).
    Leftover temporary folders of earlier, killed writes of ``path`` are removed first.

    Interrupts (main thread): SIGINT and SIGTERM are held while xarray writes (an exception
    raised under its file lock could leave the lock held and the process hanging) and handed
    to their handlers once the file is closed, or, for a dask-backed Dataset, as soon as the
    chunk being written is done; the write is then rolled back (``KeyboardInterrupt``, or
    ``SystemExit(143)`` for a default SIGTERM) and ``path`` stays as it was. A handler that
    does not raise (a batch's first Ctrl-C) lets the write complete.

    Parameters
    ----------
    ds : xarray.Dataset
        Any Dataset (not validated: modal results are written too).
    path : str or path-like
        Target file; its folder must exist.
    function : str, optional
        Name of the function that produced the data, for the provenance record (default: the
        command running, see :func:`ami_xr.provenance.command`, else ``"ami_xr.to_netcdf"``).
    parameters : dict, optional
        Its parameters (JSON-serialised in the record).

    Returns
    -------
    pathlib.Path
        The absolute path written.

    Raises
    ------
    AmiXrValueError
        Something in ``ds`` netCDF cannot store (raised before any file is touched).
    DataFileError
        The folder is missing or the file cannot be written.
    """
    if not isinstance(ds, xr.Dataset):
        raise AmiXrValueError(f"ds: expected an xarray.Dataset, got {type(ds).__name__}")
    path = Path(path).absolute()
    _check_utf8_name(path)
    recorded = annotate(
        add_history(
            ds,
            # inside a command (ami-xr ...) the write is the command's record
            function or running_command() or "ami_xr.to_netcdf",
            parameters,
            source_file=ds.attrs.get(names.ATTR_SOURCE_FILE),
        )
    )
    encoded = encode(recorded)  # raises on unstorable content before any file exists
    # Ctrl-C/SIGTERM are held for the whole write, lazy chunks included, and delivered once the
    # file is closed (the write is then rolled back). Delivering them between dask chunks was
    # tried: with xarray 2025.4 / netCDF4 1.6.5 it deadlocked the workers on xarray's file lock.
    # An eager write holds NETCDF_LOCK (HDF5 is not thread-safe); a lazy one cannot: its chunks
    # are read, under the lock, by dask threads while this thread writes.
    lazy = any(_is_dask(v.data) for v in encoded.variables.values())
    with atomic_path(path) as tmp, interrupts_deferred():
        with _drained_on_error(encoded), contextlib.nullcontext() if lazy else NETCDF_LOCK:
            try:
                encoded.to_netcdf(tmp, mode="w", format=FORMAT, engine=ENGINE)
            except Exception:
                _WRITE_FAILED[0] = True
                raise
    return path


# Whether a netCDF write failed inside the library in this process. After one (a full disk,
# a file-size limit) the HDF5 library of netCDF4 1.6.5 crashed in its exit handler (SIGSEGV
# after the error message had been printed and the output rolled back): the command line then
# leaves without the library's exit handlers (ami_xr.app.cli.run).
_WRITE_FAILED = [False]


def write_failed() -> bool:
    """True when a netCDF write of this process failed inside the library."""
    return _WRITE_FAILED[0]


def _draining_threaded_get(dsk, keys, **kwargs):
    """dask's threaded scheduler on a private pool that is drained before an error propagates.

    The stock scheduler re-raises the first failing task at once while other worker threads may
    still be writing chunks; xarray then closes the netCDF file under them (and the atomic writer
    removes it), which can crash the process inside HDF5 (a segfault, seen with netCDF4 1.6.5).

    One worker thread: netCDF reads and writes are serialised by xarray's HDF5 lock anyway, and
    with two workers a lazy netCDF-to-netCDF copy interrupted by Ctrl-C deadlocked on xarray's
    combined file locks (xarray 2025.4 / netCDF4 1.6.5, 1 in ~6 tries); with one it did not in
    12. The cost: a lazy computation written here runs on one thread.
    """
    import dask.threaded

    kwargs.pop("num_workers", None)
    pool = ThreadPoolExecutor(max_workers=1)
    try:
        return dask.threaded.get(dsk, keys, pool=pool, **kwargs)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)  # no task touches the file after this


@contextlib.contextmanager
def _drained_on_error(ds: xr.Dataset):
    """Write ``ds`` with :func:`_draining_threaded_get` when dask's threaded scheduler is in effect.

    A distributed client, the synchronous or the process scheduler are left alone.
    """
    lazy = [v.data for v in ds.variables.values() if _is_dask(v.data)]
    if not lazy:
        yield
        return
    import dask
    import dask.base
    import dask.threaded

    if dask.base.get_scheduler(collections=lazy) is not dask.threaded.get:
        yield
        return
    with dask.config.set(scheduler=_draining_threaded_get):
        yield
