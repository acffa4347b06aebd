"""Provenance: which function made a Dataset, with which parameters, from which file, when.

The one writer of provenance attributes. Every public function that makes or writes a Dataset
appends one record with :func:`add_history`; :func:`history` reads them back. The records are a
JSON list in the Dataset attribute ``ami_xr_history`` (:data:`ami_xr.names.ATTR_HISTORY`), oldest
first, each ``{"function", "parameters", "time_utc", "ami_xr_version"[, "source_file"]}``; the
latest function, the ami_xr version and the source file are also plain attributes
(:data:`ami_xr.names.ATTR_FUNCTION`, :data:`~ami_xr.names.ATTR_VERSION`,
:data:`~ami_xr.names.ATTR_SOURCE_FILE`) so ``ncdump -h`` shows them.

Files also get the CF global attribute ``history``, one line per record (:func:`cf_history`),
written by :func:`ami_xr.io.netcdf.to_netcdf` (see :mod:`ami_xr.io.cf`).

No machine path is recorded: ``source_file`` (record and attribute) holds the file name only,
and a string parameter that is an absolute path is stored as its file name, so a file can be
handed to a colleague without telling where it lay on the author's machine.
"""

from __future__ import annotations

import json
import os
from datetime import datetime, timezone
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.names import ATTR_FUNCTION  # kept importable from here, defined in names

__all__ = ["add_history", "history", "cf_history", "file_name", "ATTR_FUNCTION"]


def file_name(path: str | os.PathLike) -> str:
    """The last component of ``path`` (``"/home/me/run1.lvm"`` -> ``"run1.lvm"``)."""
    return os.path.basename(os.fspath(path).rstrip("/\\")) or os.fspath(path)


def _jsonable(value: Any) -> Any:
    """``value`` as JSON-serialisable data (complex as [real, imag], unknown types as repr,
    absolute paths as their file name)."""
    if isinstance(value, os.PathLike) or (isinstance(value, str) and os.path.isabs(value)):
        return file_name(value)
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, complex):
        return [value.real, value.imag]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in value]
    return repr(value)


def history(ds: xr.Dataset) -> list[dict]:
    """The provenance records of ``ds``, oldest first.

    Empty when ``ds`` has none or its ``ami_xr_history`` attribute is not a JSON list.
    """
    raw = ds.attrs.get(names.ATTR_HISTORY)
    if not raw:
        return []
    try:
        out = json.loads(raw)
    except (TypeError, ValueError):
        return []
    return out if isinstance(out, list) else []


def cf_history(ds: xr.Dataset) -> list[str]:
    """The records of ``ds`` as CF ``history`` lines: ``"<UTC time>Z <function> (ami_xr <v>)"``."""
    lines = []
    for record in history(ds):
        if not isinstance(record, dict):
            continue
        stamp = str(record.get("time_utc", "")).replace("+00:00", "Z")
        version = record.get(names.ATTR_VERSION, "?")
        lines.append(f"{stamp} {record.get('function', '?')} (ami_xr {version})")
    return lines


def add_history(
    ds: xr.Dataset,
    function: str,
    parameters: dict[str, Any] | None = None,
    source_file: str | None = None,
) -> xr.Dataset:
    """Return a shallow copy of ``ds`` with one provenance record appended.

    Parameters
    ----------
    ds : xarray.Dataset
        Not modified.
    function : str
        Public name of the function that made the Dataset (``"ami_xr.identify"``).
    parameters : dict, optional
        Its parameters; stored as JSON (arrays as lists, complex numbers as ``[real, imag]``,
        anything else as its ``repr``).
    source_file : str or path-like, optional
        File the data came from; only its name is stored.

    Returns
    -------
    xarray.Dataset
        ``ds`` with the record appended to ``ami_xr_history``, and the plain attributes
        :data:`ATTR_FUNCTION`, ``ami_xr_version`` and (when given) ``source_file`` (the file
        name, without its folder) set.
    """
    from ami_xr import __version__

    record = {
        "function": function,
        "parameters": _jsonable(parameters or {}),
        "time_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        names.ATTR_VERSION: __version__,
    }
    if source_file is not None:
        record[names.ATTR_SOURCE_FILE] = file_name(source_file)
    out = ds.copy()
    out.attrs = dict(ds.attrs)
    out.attrs[names.ATTR_HISTORY] = json.dumps(history(ds) + [record])
    out.attrs[names.ATTR_VERSION] = __version__
    out.attrs[ATTR_FUNCTION] = function
    if source_file is not None:
        out.attrs[names.ATTR_SOURCE_FILE] = file_name(source_file)
    return out
