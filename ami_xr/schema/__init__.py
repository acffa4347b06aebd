"""The ami_xr data model and its one validator (a layer below ``dsp``, ``ami`` and ``io``).

:func:`validate` checks a Dataset against the data model (see ``ami_xr.names`` and the docs'
"Data model" page) and reports every problem at once in one :class:`~ami_xr.errors.SchemaError`.
:func:`find_problems` returns the same list without raising, phrased in the caller's argument
names if asked (the constructors of :mod:`ami_xr.io.datasets` use it).

Modules: :mod:`~ami_xr.schema.parts` (checks both models share), :mod:`~ami_xr.schema.frf` and
:mod:`~ami_xr.schema.time` (one per model), :mod:`~ami_xr.schema.geometry` (point coordinates)
and :mod:`~ami_xr.schema.messages` (how messages name things). :mod:`ami_xr.io.schema`
re-exports this package for the import paths used before.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError, SchemaError
from ami_xr.schema.frf import IMPULSE_GRID_RTOL, frf_problems, impulse_grid_problem
from ami_xr.schema.messages import Namer, is_positive_number, python_scalar
from ami_xr.schema.parts import KINDS, MULTI_REFERENCE_DIMS, UNIFORM_RTOL, drive_points
from ami_xr.schema.time import time_problems

__all__ = [
    "validate",
    "find_problems",
    "is_positive_number",
    "python_scalar",
    "KINDS",
    "UNIFORM_RTOL",
    "IMPULSE_GRID_RTOL",
    "impulse_grid_problem",
    "drive_points",
    "MULTI_REFERENCE_DIMS",
]


def find_problems(
    ds: Any,
    kind: str | None = None,
    *,
    require_drive_point: bool = True,
    check_values: bool = True,
    arguments: Mapping[str, str] | None = None,
    metadata: bool = True,
) -> tuple[str, list[str]]:
    """What :func:`validate` checks, without raising: a description of ``ds`` and its problems.

    Parameters
    ----------
    ds, kind, require_drive_point, check_values
        As for :func:`validate`.
    arguments : mapping of str to str, optional
        Dataset names (variables, coordinates, attributes, or ``"var.attr"``) to the argument
        names a constructor took them from; messages then say "argument 'points'" rather than
        "coordinate 'point'".
    metadata : bool, default True
        FRF Datasets: also check the attributes that describe the data (units, quantity,
        source, drive point). False checks what an analysis needs (structure, labels, the
        frequency axis and its agreement with an impulse-response grid, finite values): the
        AMI phases validate their input so.

    Returns
    -------
    what : str
        ``"FRF Dataset"``, ``"Time Dataset"`` or ``"Dataset"`` (kind not recognised).
    problems : list of str
        Every problem found, each naming the part and what was expected; empty when ``ds``
        conforms.

    Raises
    ------
    AmiXrValueError
        If ``ds`` is not a Dataset or ``kind`` is unknown.
    """
    namer = Namer(arguments)
    if not isinstance(ds, xr.Dataset):
        hint = " (e.g. da.to_dataset(name='frf'))" if isinstance(ds, xr.DataArray) else ""
        raise AmiXrValueError(f"ds: expected an xarray.Dataset{hint}, got {type(ds).__name__}")
    if kind is not None and kind not in KINDS:
        raise AmiXrValueError(f"kind: expected None or one of {KINDS}, got {kind!r}")
    if kind is None:
        if names.FRF in ds.data_vars:
            kind = "frf"
        elif names.RESPONSE in ds.data_vars:
            kind = "time"
        else:
            return "Dataset", [
                f"{namer.var(names.FRF)} or {namer.var(names.RESPONSE)}: missing (expected "
                f"{names.FRF!r} for an FRF Dataset or {names.RESPONSE!r} for a time Dataset; "
                f"has {sorted(map(str, ds.data_vars))})"
            ]
    if kind == "frf":
        return "FRF Dataset", frf_problems(
            ds, require_drive_point, check_values, namer, metadata=metadata
        )
    return "Time Dataset", time_problems(ds, require_drive_point, check_values, namer)


def validate(
    ds: xr.Dataset,
    kind: str | None = None,
    *,
    require_drive_point: bool = True,
    check_values: bool = True,
) -> xr.Dataset:
    """Check ``ds`` against the ami_xr data model and return it unchanged when it conforms.

    Every problem found is reported at once in one :class:`~ami_xr.errors.SchemaError` whose
    ``problems`` list names, for each, the variable, coordinate or attribute and what was
    expected. Besides structure, units and finite values, the parts must agree: an FRF with
    ``frf_source="impulse_response"`` must have its lines on the rfft grid
    ``k / (record_samples * sample_interval)`` Hz (see :func:`impulse_grid_problem`).

    Parameters
    ----------
    ds : xarray.Dataset
        An FRF Dataset (``frf`` complex, dims ``(point, frequency)``, or
        ``(reference, point, frequency)`` for multi-reference data: one row per excitation
        location, labelled by the ``reference`` coordinate in the point labels' type; a
        reference whose label is a point label is that point's drive point, and the
        ``drive_point`` attribute is then not used) or a time Dataset (``response`` float,
        dims ``([record,] point, time)``, plus ``force``).
    kind : {None, "frf", "time"}
        Which model to check against. ``None`` detects it: a Dataset with ``frf`` is an FRF
        Dataset, one with ``response`` a time Dataset.
    require_drive_point : bool, default True
        Require the ``drive_point`` attribute to name one of the points (multi-reference: at
        least one reference label to be a point label). AMI can run without a measured drive
        point (mode vectors then stay unscaled): pass False to skip both checks.
    check_values : bool, default True
        Scan ``frf``/``response``/``force`` for NaN and inf. This reads all data (it computes
        lazily opened variables); pass False to check only structure, coordinates and attributes.

    Returns
    -------
    xarray.Dataset
        ``ds`` itself (not a copy), so ``validate`` can be chained.

    Raises
    ------
    SchemaError
        Listing every problem. Extra variables and attributes are allowed and not checked
        (NaN is fine in them).
    AmiXrValueError
        If ``ds`` is not a Dataset or ``kind`` is unknown.

    Examples
    --------
    >>> import numpy as np, ami_xr
    >>> ds = ami_xr.make_frf_dataset(np.ones((2, 3), complex), [0.0, 1.0, 2.0], drive_point=0)
    >>> ami_xr.validate(ds) is ds
    True
    """
    what, found = find_problems(
        ds, kind, require_drive_point=require_drive_point, check_values=check_values
    )
    if found:
        raise SchemaError(found, what=what)
    return ds
