"""What the CSV and MATLAB readers share: point labels, FRF units, what the file says about the
test (drive point, quantity, units), the assumptions and the Dataset.

Both readers end in :func:`frf_dataset`, which builds the Dataset with
:func:`ami_xr.make_frf_dataset` (so the data-model check is the one every FRF Dataset passes)
and states what it had to assume as the other readers do: an
:class:`~ami_xr.errors.AssumptionWarning` that names the file and how to say it instead, and an
attribute that records it (``drive_point_assumed``, ``response_quantity_assumed``).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.caller import warn
from ami_xr.dsp.quantity import ATTR_QUANTITY_ASSUMED, resolve_quantity
from ami_xr.errors import AmiXrValueError, AssumptionWarning, DataFileError, SchemaError
from ami_xr.io.datasets import make_frf_dataset
from ami_xr.provenance import add_history

__all__ = [
    "FREQUENCY_NAMES",
    "METADATA_KEYS",
    "frf_dataset",
    "frf_units_of",
    "point_labels",
    "split_unit",
]

#: Names of the frequency column or variable (case-insensitive; a unit in brackets, ``[Hz]``,
#: or a trailing ``_hz`` may follow).
FREQUENCY_NAMES = ("frequency", "freq", "f")
#: What a file may say about the test: ``# key: value`` lines above a CSV header, variables (or
#: struct fields) of a MATLAB file. The readers' keyword arguments of the same names win.
METADATA_KEYS = ("drive_point", "response_quantity", "frf_type", "response_units", "force_units")
FUNCTION = "ami_xr.open_frf"  # the provenance record of a table read

_UNIT = re.compile(r"^(?P<base>.*?)\s*[\[(]\s*(?P<unit>[^\])]*?)\s*[\])]\s*$")
_HZ = re.compile(r"^(?P<base>.*?)[\s_]+hz$", re.IGNORECASE)
_INTEGER = re.compile(r"^[+-]?\d+$")


def split_unit(name: str) -> tuple[str, str]:
    """``(base, unit)`` of a column or variable name: ``"freq [Hz]"`` -> ``("freq", "Hz")``,
    ``"frequency_hz"`` -> ``("frequency", "Hz")``, ``"p1_re"`` -> ``("p1_re", "")``."""
    text = name.strip()
    match = _UNIT.match(text)
    if match:
        return match["base"].strip(), match["unit"].strip()
    match = _HZ.match(text)
    if match and match["base"]:
        return match["base"].strip(), "Hz"
    return text, ""


def is_frequency_name(name: str) -> bool:
    """A frequency column or variable name (:data:`FREQUENCY_NAMES`, any unit)."""
    return split_unit(name)[0].lower() in FREQUENCY_NAMES


def point_labels(texts: Sequence[str]) -> list:
    """Point labels from a file's texts: integers when every one is a whole number, else the
    stripped texts."""
    stripped = [str(t).strip() for t in texts]
    if stripped and all(_INTEGER.match(t) for t in stripped):
        return [int(t) for t in stripped]
    return stripped


def frf_units_of(unit: str, where: str, path: Path) -> tuple[str, str]:
    """``(response_units, force_units)`` of an FRF unit such as ``"m/s^2/N"`` or ``"g/N"``.

    Raises
    ------
    DataFileError
        ``unit`` is not ``<response units>/<force units>`` with units ami_xr knows.
    """
    response, _, force = unit.strip().rpartition("/")
    known = [u for units in names.RESPONSE_UNITS.values() for u in units]
    if response not in known or force not in names.FORCE_UNITS:
        raise DataFileError(
            f"{path}: {where}: FRF unit {unit!r} not understood; expected <response>/<force> "
            f"with a response unit of {known} and a force unit of {list(names.FORCE_UNITS)} "
            "(e.g. 'm/s^2/N')"
        )
    return response, force


def _matching_label(value: Any, labels: list, where: str, path: Path) -> Any:
    """The point label ``value`` names (compared as text: ``"3"`` names point 3)."""
    if value in labels:
        return value
    hits = [label for label in labels if str(label) == str(value).strip()]
    if not hits:
        raise DataFileError(
            f"{path}: drive_point ({where}): {value!r} is not one of the points {labels}"
        )
    return hits[0]


def _assume(path: Path, what: str, how: str) -> str:
    """Warn (at the user's line) that ``what`` was assumed; return the record's text."""
    warn(f"{path.name}: {what}; {how}", AssumptionWarning)
    return what


def frf_dataset(
    path: Path,
    frf: np.ndarray,
    frequency: np.ndarray,
    labels: list | None,
    said: dict[str, Any],
    given: dict[str, Any],
    how: str,
    record: dict[str, Any],
    extra_attrs: dict[str, Any] | None = None,
) -> xr.Dataset:
    """The FRF Dataset of a table file, validated by :func:`ami_xr.make_frf_dataset`.

    Parameters
    ----------
    path : pathlib.Path
        The file, named in every message.
    frf : ndarray of complex, shape (n_point, n_frequency)
    frequency : ndarray of float, shape (n_frequency,)
        In Hz.
    labels : list or None
        Point labels read from the file; None for ``0 .. n_point - 1``.
    said : dict
        What the file says (keys of :data:`METADATA_KEYS`).
    given : dict
        The reader's keyword arguments (keys of :data:`METADATA_KEYS` and ``points``); a value
        given wins over the file's.
    how : str
        How a user says in this format what was assumed (for the warnings).
    record : dict
        Parameters of the provenance record (format, layout, columns or variables read).
    extra_attrs : dict, optional
        Further attributes, e.g. an assumption about the layout.

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    DataFileError
        Labels that do not fit, a drive point that is not a point, bad units.
    SchemaError
        What the data-model check finds, each problem named, with the file.
    """
    n_point = frf.shape[0]
    if given.get("points") is not None:
        labels = list(given["points"])
        if len(labels) != n_point:
            raise AmiXrValueError(
                f"points: expected {n_point} labels (the FRFs of {path.name}), got {len(labels)}"
            )
    if labels is not None and len(set(map(str, labels))) != len(labels):
        raise DataFileError(f"{path}: the point labels {labels} repeat; expected unique labels")
    options = {k: v for k, v in said.items() if v is not None}
    options.update({k: given[k] for k in METADATA_KEYS if given.get(k) is not None})
    attrs: dict[str, Any] = dict(extra_attrs or {})
    shown = labels if labels is not None else list(range(n_point))
    drive = options.get("drive_point")
    if drive is not None:
        where = "given" if given.get("drive_point") is not None else "from the file"
        drive = _matching_label(drive, shown, where, path)
    elif n_point == 1:
        drive = shown[0]
        attrs[names.ATTR_DRIVE_POINT_ASSUMED] = _assume(
            path, f"drive point assumed to be {drive!r} (the single FRF)", how.format("drive_point")
        )
    try:
        quantity, units, assumed = resolve_quantity(
            options.get("response_quantity"), options.get("frf_type"), options.get("response_units")
        )
    except AmiXrValueError as err:
        raise DataFileError(f"{path}: {err}") from None
    force_units = options.get("force_units", "N")
    if assumed is not None:
        attrs[ATTR_QUANTITY_ASSUMED] = _assume(
            path,
            f"no response quantity, FRF type or units given: receptance in {units}/{force_units} "
            "assumed",
            how.format("response_quantity"),
        )
    try:
        ds = make_frf_dataset(
            frf,
            frequency,
            points=labels,
            drive_point=drive,
            response_quantity=quantity,
            response_units=units,
            force_units=force_units,
            **attrs,
        )
    except SchemaError as err:
        raise SchemaError(err.problems, what=f"{path}: the FRFs read") from None
    except AmiXrValueError as err:
        raise DataFileError(f"{path}: {err}") from None
    return add_history(ds, FUNCTION, record, source_file=path)
