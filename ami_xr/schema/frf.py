"""The FRF data model: ``frf`` complex with dims ``(point, frequency)`` (or ``(reference, point,
frequency)``), its axis, labels, metadata and, for FRFs of impulse responses, their grid.
"""

from __future__ import annotations

from numbers import Integral, Real

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.coords import range_axis
from ami_xr.schema.geometry import coordinate_problems
from ami_xr.schema.messages import Namer, is_positive_number, python_scalar
from ami_xr.schema.parts import (
    MULTI_REFERENCE_DIMS,
    check_axis,
    check_drive_point,
    check_empty,
    check_finite,
    check_noise_std,
    check_points,
    check_quantity_units,
    check_references,
)

__all__ = [
    "IMPULSE_GRID_RTOL",
    "impulse_grid_problem",
    "frf_problems",
    "frf_metadata_problems",
    "impulse_problems",
]

# How far a frequency may sit from the rfft grid k / (N dt), as a fraction of its own value
# (and of one line spacing at k = 0). k / (N dt) computed in float64 -- by rfftfreq, by
# arange(k) / (N dt) or by k * (1 / (N dt)) -- differs from the exact value by a few ulp
# (~1e-15 relative), and dt read back from a text file written with 7 or more significant
# digits by less than 1e-6; an axis that disagrees with dt or N (a wrong dt, a padded FFT, Hz
# multiplied by 2 pi) is off by a whole fraction of a line at most lines, far above this.
IMPULSE_GRID_RTOL = 1e-6


def impulse_grid_problem(ds: xr.Dataset, namer: Namer | None = None) -> str | None:
    """Why the frequency axis of an impulse-response FRF Dataset is not its rfft grid, or None.

    An FRF with ``frf_source == "impulse_response"`` is ``dt * rfft`` of ``record_samples``
    samples, so its lines are ``k / (record_samples * sample_interval)`` Hz with
    ``0 <= k <= record_samples // 2`` (a band of them is fine). The discrete modal model uses
    ``sample_interval`` and the axis together: when they disagree its modes are wrong.

    Parameters
    ----------
    ds : xarray.Dataset
        FRF Dataset; only checked when ``frf_source`` is ``"impulse_response"`` and the
        frequency axis, ``sample_interval`` and ``record_samples`` are usable (their own
        problems are reported by :func:`validate`).
    namer : optional
        How the message names the frequency coordinate (default "coordinate 'frequency'").

    Returns
    -------
    str or None
        One message naming ``frequency`` and the expected spacing, or None when the axis fits.
    """
    namer = namer or Namer()
    attrs = ds.attrs
    dt, n = attrs.get(names.ATTR_DT), attrs.get(names.ATTR_NSAMPLES)
    if attrs.get(names.ATTR_SOURCE) != names.SOURCE_IMPULSE or names.FREQUENCY not in ds.coords:
        return None
    if not (is_positive_number(dt) and is_positive_number(n) and isinstance(n, Integral)):
        return None
    coord = ds.coords[names.FREQUENCY]
    if coord.ndim != 1 or coord.size == 0 or coord.dtype.kind not in "fiu":
        return None
    axis = range_axis(ds, names.FREQUENCY)
    if axis is not None:  # uniform by construction: its first, second and last lines suffice
        idx = np.unique(np.array([0, 1, axis.size - 1]).clip(0, axis.size - 1))
        freq = axis.start + idx * axis.step
    else:
        idx = np.arange(coord.size)
        freq = np.asarray(coord.values, dtype=np.float64)
    if not np.all(np.isfinite(freq)):
        return None
    df = 1.0 / (float(n) * float(dt))
    lines = freq / df
    k = np.rint(lines)
    off = (np.abs(lines - k) > IMPULSE_GRID_RTOL * np.maximum(np.abs(lines), 1.0)) | (k < 0)
    off |= k > int(n) // 2
    if not off.any():
        return None
    first = int(np.argmax(off))
    units = coord.attrs.get(names.ATTR_UNITS)
    return (
        f"{namer.coord(names.FREQUENCY)}: expected the rfft grid of an impulse response, "
        f"k / (record_samples * sample_interval) = k * {df!r} Hz with 0 <= k <= "
        f"{int(n) // 2} (frf_source {names.SOURCE_IMPULSE!r}, sample_interval {float(dt)!r} s, "
        f"record_samples {int(n)}), but {int(off.sum())} of {off.size} checked lines are off "
        f"it (first: index {int(idx[first])} = {float(freq[first])!r} {units}, {lines[first]:.6g} "
        "line spacings); are the frequencies in Hz (not rad/s), and are sample_interval and "
        "record_samples those of the record?"
    )


def frf_problems(
    ds: xr.Dataset,
    require_drive_point: bool,
    check_values: bool,
    namer: Namer,
    metadata: bool = True,
) -> list[str]:
    problems: list[str] = []
    want_dims = (names.POINT, names.FREQUENCY)
    multi = False
    if names.FRF not in ds.data_vars:
        problems.append(
            f"{namer.var(names.FRF)}: missing (expected complex FRF with dims {want_dims})"
        )
        frf = None
    else:
        frf = ds[names.FRF]
        subject = namer.var(names.FRF)
        multi = names.REFERENCE in frf.dims
        if multi:
            if frf.dims != MULTI_REFERENCE_DIMS:
                problems.append(
                    f"{subject}: expected dims {MULTI_REFERENCE_DIMS} (multi-reference) or "
                    f"{want_dims}, got {frf.dims}"
                )
        elif names.COMPLEX in frf.dims:
            problems.append(
                f"{subject}: has the on-disk dim {names.COMPLEX!r} (real, imag); "
                "open the file with ami_xr.open_dataset to decode it"
            )
        elif frf.dims != want_dims:
            problems.append(f"{subject}: expected dims {want_dims}, got {frf.dims}")
        if not np.issubdtype(frf.dtype, np.complexfloating):
            problems.append(
                f"{subject}: expected complex values (complex128), got dtype {frf.dtype}"
            )
        empty = check_empty(frf, subject, problems)
        if check_values and not empty:
            check_finite(frf, subject, problems)
        if names.FRF_LINE_NOISE_STD in ds.data_vars:
            check_noise_std(ds[names.FRF_LINE_NOISE_STD], frf, check_values, namer, problems)
    check_axis(
        ds,
        names.FREQUENCY,
        names.FREQUENCY_UNITS,
        namer,
        problems,
        nonnegative=True,
        metadata=metadata,
    )
    labels = check_points(ds, namer, problems)
    problems += coordinate_problems(ds, namer)
    if metadata:
        frf_metadata_problems(ds, frf, labels, multi, require_drive_point, namer, problems)
    source = ds.attrs.get(names.ATTR_SOURCE)
    if source == names.SOURCE_IMPULSE:
        impulse_problems(ds, source, namer, problems)
    if names.ATTR_EXP_DECAY in ds.attrs:
        decay = ds.attrs[names.ATTR_EXP_DECAY]
        if not (is_positive_number(decay) or (isinstance(decay, Real) and decay == 0)):
            problems.append(
                f"{namer.attr(names.ATTR_EXP_DECAY)}: expected a finite decay rate >= 0 in 1/s, "
                f"got {python_scalar(decay)!r}"
            )
    return problems


def frf_metadata_problems(ds, frf, labels, multi, require_drive_point, namer, problems):
    """The drive point(s), quantity, units and source attributes of an FRF Dataset."""
    if multi:
        check_references(ds, labels, require_drive_point, namer, problems)
    else:
        check_drive_point(ds, labels, require_drive_point, namer, problems)
    resp_units, force_units = check_quantity_units(ds, namer, problems, need_frf_type=True)
    if frf is not None and resp_units and force_units:
        want = names.frf_units(resp_units, force_units)
        got = frf.attrs.get(names.ATTR_UNITS)
        if got != want:
            problems.append(
                f"{namer.var_attr(names.FRF, names.ATTR_UNITS)}: expected {want!r} "
                f"(response_units/force_units), got {got!r}"
            )
    source = ds.attrs.get(names.ATTR_SOURCE)
    if source not in names.SOURCES:
        got = "missing" if source is None else f"got {source!r}"
        problems.append(f"{namer.attr(names.ATTR_SOURCE)}: expected one of {names.SOURCES}, {got}")


def impulse_problems(ds: xr.Dataset, source: str, namer: Namer, problems: list[str]) -> None:
    """An impulse-response FRF's sample interval and record length, and its rfft grid."""
    dt = ds.attrs.get(names.ATTR_DT)
    if not is_positive_number(dt):
        got = "missing" if dt is None else f"got {python_scalar(dt)!r}"
        problems.append(
            f"{namer.attr(names.ATTR_DT)}: expected a positive sample interval in s "
            f"because frf_source is {source!r}, {got}"
        )
    n = ds.attrs.get(names.ATTR_NSAMPLES)
    if not (is_positive_number(n) and isinstance(n, Integral)):
        got = "missing" if n is None else f"got {python_scalar(n)!r}"
        problems.append(
            f"{namer.attr(names.ATTR_NSAMPLES)}: expected a positive integer record length "
            f"because frf_source is {source!r}, {got}"
        )
    elif is_positive_number(dt):
        grid = impulse_grid_problem(ds, namer)
        if grid:
            problems.append(grid)
