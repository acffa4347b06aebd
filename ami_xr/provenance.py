"""Provenance attributes: which function made a Dataset, with which parameters, when."""

from __future__ import annotations

import json
from datetime import datetime, timezone
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names


def _jsonable(value: Any) -> Any:
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
    """The provenance records of ``ds``, oldest first (empty when it has none)."""
    raw = ds.attrs.get(names.ATTR_HISTORY)
    if not raw:
        return []
    try:
        out = json.loads(raw)
    except (TypeError, ValueError):
        return []
    return out if isinstance(out, list) else []


def add_history(
    ds: xr.Dataset,
    function: str,
    parameters: dict[str, Any] | None = None,
    source_file: str | None = None,
) -> xr.Dataset:
    """Return a shallow copy of ``ds`` with one provenance record appended.

    The record holds the ami_xr version, the function name, its parameters (JSON), a UTC
    timestamp and, where there is one, the source file. The most recent function and source file
    are also stored as plain attributes so ``ncdump -h`` shows them.
    """
    from ami_xr import __version__

    record = {
        "function": function,
        "parameters": _jsonable(parameters or {}),
        "time_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "ami_xr_version": __version__,
    }
    if source_file is not None:
        record["source_file"] = str(source_file)
    out = ds.copy()
    out.attrs = dict(ds.attrs)
    out.attrs[names.ATTR_HISTORY] = json.dumps(history(ds) + [record])
    out.attrs[names.ATTR_VERSION] = __version__
    out.attrs["ami_xr_function"] = function
    if source_file is not None:
        out.attrs[names.ATTR_SOURCE_FILE] = str(source_file)
    return out
