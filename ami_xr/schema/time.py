"""The time data model: ``response`` float with dims ``([record,] point, time)`` and ``force``
``([record,] [reference,] time)``,
or impulse responses (attribute ``excitation = "unit_impulse"``).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.schema.geometry import coordinate_problems
from ami_xr.schema.messages import Namer
from ami_xr.schema.parts import (
    MULTI_REFERENCE_MESSAGE,
    check_axis,
    check_drive_point,
    check_empty,
    check_finite,
    check_points,
    check_quantity_units,
)

__all__ = ["signal_problems", "time_problems"]


def signal_problems(
    ds: xr.Dataset,
    var: str,
    allowed: tuple[tuple[str, ...], ...],
    check_values: bool,
    namer: Namer,
) -> list[str]:
    problems: list[str] = []
    da = ds[var]
    subject = namer.var(var)
    takes_reference = any(names.REFERENCE in dims for dims in allowed)
    if da.dims not in allowed and names.REFERENCE in da.dims and not takes_reference:
        problems.append(f"{subject}: {MULTI_REFERENCE_MESSAGE}")
    elif da.dims not in allowed:
        problems.append(f"{subject}: expected dims {' or '.join(map(str, allowed))}, got {da.dims}")
    if not np.issubdtype(da.dtype, np.floating):
        problems.append(f"{subject}: expected real float values (float64), got dtype {da.dtype}")
    empty = check_empty(da, subject, problems)
    if check_values and not empty:
        check_finite(da, subject, problems)
    return problems


def time_problems(ds: xr.Dataset, require_drive_point: bool, check_values: bool, namer: Namer):
    problems: list[str] = []
    p, t, r = names.POINT, names.TIME, names.RECORD
    if names.RESPONSE not in ds.data_vars:
        problems.append(
            f"{namer.var(names.RESPONSE)}: missing (expected float responses with dims "
            f"{(p, t)} or {(r, p, t)})"
        )
    else:
        problems += signal_problems(ds, names.RESPONSE, ((p, t), (r, p, t)), check_values, namer)
    if names.FORCE in ds.data_vars:
        # several force channels (a multi-reference test) on a reference dim
        q = names.REFERENCE
        forces = ((t,), (r, t), (q, t), (r, q, t))
        problems += signal_problems(ds, names.FORCE, forces, check_values, namer)
    elif ds.attrs.get(names.ATTR_EXCITATION) != names.EXCITATION_UNIT_IMPULSE:
        problems.append(
            f"{namer.var(names.FORCE)}: missing (expected float force with dims {(t,)} or "
            f"{(r, t)}, or attribute {names.ATTR_EXCITATION}="
            f"{names.EXCITATION_UNIT_IMPULSE!r} for impulse responses)"
        )
    if names.REFERENCE in ds.coords:  # the force channels' labels
        refs = np.asarray(ds[names.REFERENCE].values).tolist()
        if len(set(map(str, refs))) != len(refs):
            problems.append(
                f"{namer.coord(names.REFERENCE)}: expected unique labels, one per force "
                f"channel, got {refs}"
            )
    check_axis(ds, t, names.TIME_UNITS, namer, problems, uniform=True)
    labels = check_points(ds, namer, problems)
    problems += coordinate_problems(ds, namer)
    check_drive_point(ds, labels, require_drive_point, namer, problems)
    resp_units, force_units = check_quantity_units(ds, namer, problems, need_frf_type=False)
    for var, units in ((names.RESPONSE, resp_units), (names.FORCE, force_units)):
        if var in ds.data_vars and units and names.ATTR_UNITS in ds[var].attrs:
            got = ds[var].attrs[names.ATTR_UNITS]
            if got != units:
                problems.append(
                    f"{namer.var_attr(var, names.ATTR_UNITS)}: expected {units!r} "
                    f"(the Dataset's {'response' if var == names.RESPONSE else 'force'}_units), "
                    f"got {got!r}"
                )
    return problems
