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

History lists only the calls the user made. A public function that calls other public functions
(``identify`` runs ``subtract``, ``isolate``, ``global_fit`` and ``refine``) makes those calls
inside :func:`nested_calls`, or is decorated with :func:`public_call` as are the functions it
calls: a record is added only by the outermost public call (a context variable counts the
depth, so threads and asyncio tasks each have their own).

A command (``ami-xr frf``, ``ami-xr identify``, one file of a batch) is one call of the user's
too: it runs inside :func:`command`, and its output's record, named after the command, holds
the public calls it made (the read, the FRF estimate, identify, the write) as its ``steps``
(each ``{"function", "parameters"[, "source_file"]}``) instead of as records of their own.

No machine path is recorded: ``source_file`` (record and attribute) holds the file name only,
and a string parameter that is an absolute path is stored as its file name, so a file can be
handed to a colleague without telling where it lay on the author's machine.
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import json
import os
from collections.abc import Callable, Iterator
from datetime import datetime, timezone
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.names import ATTR_FUNCTION  # kept importable from here, defined in names

__all__ = [
    "add_history",
    "record_history",
    "command",
    "history",
    "cf_history",
    "file_name",
    "nested_calls",
    "public_call",
    "recording",
    "running_command",
    "ATTR_FUNCTION",
]

# How many public calls enclose the code running now: 0 outside any, 1 in the body of the
# outermost one, more inside calls it makes. add_history records only at depth 0 or 1.
_DEPTH: contextvars.ContextVar[int] = contextvars.ContextVar("ami_xr_call_depth", default=0)


# The command running now (see command()); records added inside are its steps.
_COMMAND: contextvars.ContextVar[str | None] = contextvars.ContextVar(
    "ami_xr_command", default=None
)
_STEP_OF = "step_of"  # the marker of a record that is a step of a command, until gathered


@contextlib.contextmanager
def command(name: str) -> Iterator[None]:
    """Records added inside are steps of the command ``name``: the record
    ``add_history(ds, name, ...)`` adds (the write of the command's output) gathers the step
    records made before it into its ``"steps"``, so the history lists the command, not what it
    called.

    Examples
    --------
    >>> with command("ami-xr frf"):  # doctest: +SKIP
    ...     ts = read_lvm(path)                      # a step
    ...     g = impact_frf(ts)                       # a step
    ...     to_netcdf(g, out, function="ami-xr frf") # the record, with both steps
    """
    token = _COMMAND.set(name)
    try:
        yield
    finally:
        _COMMAND.reset(token)


def running_command() -> str | None:
    """The name of the :func:`command` running now, ``None`` outside one."""
    return _COMMAND.get()


def recording() -> bool:
    """True when :func:`add_history` called here would append a record (no enclosing call is
    itself recorded)."""
    return _DEPTH.get() <= 1


@contextlib.contextmanager
def nested_calls() -> Iterator[None]:
    """Public functions called inside add no provenance record (their caller records itself).

    Examples
    --------
    >>> with nested_calls():  # doctest: +SKIP
    ...     out = subtract(ds, delta)  # no "ami_xr.subtract" record
    """
    token = _DEPTH.set(max(_DEPTH.get(), 1) + 1)
    try:
        yield
    finally:
        _DEPTH.reset(token)


def public_call(func: Callable) -> Callable:
    """Decorator of a public function that records itself with :func:`add_history`: called from
    inside another such function (or inside :func:`nested_calls`) it adds no record."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        token = _DEPTH.set(_DEPTH.get() + 1)
        try:
            return func(*args, **kwargs)
        finally:
            _DEPTH.reset(token)

    return wrapper


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
    return _records(ds.attrs.get(names.ATTR_HISTORY))


def _records(raw) -> list:
    """The records of an ``ami_xr_history`` attribute (empty when it is not a JSON list)."""
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
        name, without its folder) set. Inside a call that records itself (see
        :func:`nested_calls`) a copy of ``ds`` with its attributes unchanged.
    """
    out = ds.copy()
    out.attrs = dict(ds.attrs)
    record_history(out.attrs, function, parameters, source_file)
    return out


def record_history(
    attrs: dict,
    function: str,
    parameters: dict[str, Any] | None = None,
    source_file: str | None = None,
) -> None:
    """Append one provenance record to the attributes ``attrs`` of a Dataset a function made
    (its own: they are modified), as :func:`add_history` does on a copy; nothing inside a call
    that records itself (:func:`nested_calls`)."""
    from ami_xr import __version__

    if not recording():
        return
    record = {
        "function": function,
        "parameters": _jsonable(parameters or {}),
        "time_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        names.ATTR_VERSION: __version__,
    }
    if source_file is not None:
        record[names.ATTR_SOURCE_FILE] = file_name(source_file)
    records = _records(attrs.get(names.ATTR_HISTORY))
    running = _COMMAND.get()
    if running is not None and function == running:  # the command's own record: gather
        first = len(records)
        while (
            first
            and isinstance(records[first - 1], dict)
            and (records[first - 1].get(_STEP_OF) == running)
        ):
            first -= 1
        keep = ("function", "parameters", names.ATTR_SOURCE_FILE)
        record["steps"] = [{k: r[k] for k in keep if k in r} for r in records[first:]]
        records = records[:first]
    elif running is not None:
        record[_STEP_OF] = running
    attrs[names.ATTR_HISTORY] = json.dumps(records + [record])
    attrs[names.ATTR_VERSION] = __version__
    attrs[ATTR_FUNCTION] = function
    if source_file is not None:
        attrs[names.ATTR_SOURCE_FILE] = file_name(source_file)
