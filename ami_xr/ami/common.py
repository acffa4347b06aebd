"""Shared helpers of the AMI phases: input checks, the variables each phase makes, provenance."""

from __future__ import annotations

from collections.abc import Hashable
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import IdentificationError
from ami_xr.io.schema import impulse_grid_problem
from ami_xr.provenance import add_history

MODELS = ("auto", *names.AMI_MODELS)  # the ``model`` argument of subtract
MIN_LINES = 8

# Variables each phase adds; a phase run again on its own output (or on a later phase's output)
# first drops what it and the later phases made, so results never mix.
SUBTRACT_VARS = (
    names.SUB_EIGENVALUE,
    names.SUB_RESIDUE,
    names.SUB_BAND_LOW,
    names.SUB_BAND_HIGH,
    names.SUB_NOISE_FLOOR,
    names.SUB_STOP_STATISTIC,
    names.SUB_STOP_REASON,
    names.SUB_N_MODES,
)
ISOLATE_VARS = (
    names.EIGENVALUE,
    names.NATURAL_FREQUENCY,
    names.DAMPING_RATIO,
    names.DETECTED,
    names.POINT_EIGENVALUE,
    names.POINT_SNR,
    names.EIGENVALUE_SPREAD,
    names.ISO_ITERATIONS,
    names.ISO_CONVERGED,
)
GLOBAL_VARS = (
    names.RESIDUE,
    names.MODE_VECTOR,
    names.FRF_SYNTHESIZED,
    names.FRF_RESIDUAL,
    names.RESIDUAL_COEFFICIENT,
    names.MAC,
    names.DRIVE_POINT_SNR,
    names.QUALITY_FLAGS,
)


def check_frf(ds: Any, function: str) -> xr.Dataset:
    """The input checks every phase makes before any work.

    Structure (dims, dtype, a strictly increasing frequency axis that fits ``sample_interval``
    and ``record_samples`` for impulse-response FRFs), unique point labels, and finite values
    (one pass over the data; NaN and inf are named with their points and counts).
    """
    if not isinstance(ds, xr.Dataset):
        raise IdentificationError(f"ds: expected an xarray.Dataset, got {type(ds).__name__}")
    if names.FRF not in ds:
        raise IdentificationError(
            f"ds: {function} needs the variable {names.FRF!r} "
            f"(complex, dims ({names.POINT}, {names.FREQUENCY}))"
        )
    frf = ds[names.FRF]
    if names.REFERENCE in frf.dims:
        refs = np.asarray(ds[names.REFERENCE].values).tolist() if names.REFERENCE in ds else []
        first = refs[0] if refs else 0
        raise IdentificationError(
            f"{names.FRF}: has the {names.REFERENCE!r} dim ({frf.sizes[names.REFERENCE]} "
            f"references {refs}): {function} does not take multi-reference data on its own: "
            f"ami_xr.identify does (one set of poles for all references, mode vectors from "
            f"every drive point); or select one reference first, e.g. "
            f"ds.sel({names.REFERENCE}={first!r}) "
            f"or ami_xr.io.datasets.select_reference(ds, {first!r}) (which also sets "
            f"{names.ATTR_DRIVE_POINT!r} when the reference is a measured point)"
        )
    if set(frf.dims) != {names.POINT, names.FREQUENCY}:
        raise IdentificationError(
            f"{names.FRF}: expected dims ({names.POINT}, {names.FREQUENCY}), got {frf.dims}"
        )
    if not np.issubdtype(frf.dtype, np.complexfloating):
        raise IdentificationError(f"{names.FRF}: expected a complex dtype, got {frf.dtype}")
    f = np.asarray(ds[names.FREQUENCY].values, dtype=float)
    if f.size < MIN_LINES:
        raise IdentificationError(
            f"{names.FREQUENCY}: {f.size} lines; the single-mode fit needs at least {MIN_LINES}"
        )
    if not np.all(np.diff(f) > 0):
        raise IdentificationError(f"{names.FREQUENCY}: must be strictly increasing")
    if f[0] < 0:
        raise IdentificationError(f"{names.FREQUENCY}: must be >= 0 Hz")
    grid = impulse_grid_problem(ds)
    if grid:
        raise IdentificationError(grid)
    _check_unique_points(ds)
    _check_finite(frf, ds)
    return ds


def _shorten(values: list, limit: int = 8) -> str:
    more = f", ... ({len(values)} in all)" if len(values) > limit else ""
    return ", ".join(map(str, values[:limit])) + more


def _check_unique_points(ds: xr.Dataset) -> None:
    """Each point label once: results are selected and written (report, UFF) by label."""
    labels = np.asarray(ds[names.POINT].values)
    keys = labels.astype(str) if labels.dtype.kind in "OUS" else labels
    uniq, first, counts = np.unique(keys, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup = [labels[i].item() if hasattr(labels[i], "item") else labels[i] for i in first]
        dup = [d for d, c in zip(dup, counts, strict=True) if c > 1]
        raise IdentificationError(
            f"coordinate {names.POINT!r}: expected unique point labels, found duplicates "
            f"{_shorten([repr(d) for d in dup])}"
        )


def _check_finite(frf: xr.DataArray, ds: xr.Dataset) -> None:
    """NaN/inf in ``frf`` are named with their points before any work (one pass over the data;
    a NaN would otherwise surface deep in a fit as an SVD that does not converge)."""
    counts = np.asarray((~np.isfinite(frf)).sum(names.FREQUENCY).transpose(names.POINT).values)
    bad = np.flatnonzero(counts)
    if bad.size:
        labels = np.asarray(ds[names.POINT].values)
        where = [
            f"{labels[i].item() if hasattr(labels[i], 'item') else labels[i]!r}: {int(counts[i])}"
            for i in bad
        ]
        raise IdentificationError(
            f"variable {names.FRF!r}: expected finite values, found {int(counts.sum())} NaN or "
            f"inf value(s) at {bad.size} point(s) (point: count) {_shorten(where)}"
        )


def check_values(ds: xr.Dataset) -> None:
    """All-zero or non-finite FRFs are errors naming the point (one reduction over the data)."""
    # skipna=False: the default max skips NaN, so a partly NaN FRF would pass.
    peak = np.asarray(np.abs(ds[names.FRF]).max(names.FREQUENCY, skipna=False).values)
    points = np.asarray(ds[names.POINT].values)
    bad = ~np.isfinite(peak)
    if np.any(bad):
        raise IdentificationError(
            f"{names.FRF}: non-finite values at point(s) {points[bad].tolist()}"
        )
    zero = peak == 0
    if np.any(zero):
        raise IdentificationError(
            f"{names.FRF}: all-zero FRF at point(s) {points[zero].tolist()}; nothing to identify"
        )


def check_fraction(value: Any, argument: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise IdentificationError(
            f"{argument}: expected a number in (0, 1), got {value!r}"
        ) from None
    if not 0.0 < v < 1.0:
        raise IdentificationError(f"{argument}: expected a number in (0, 1), got {value!r}")
    return v


def check_positive_int(value: Any, argument: str, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise IdentificationError(f"{argument}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def check_positive(value: Any, argument: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise IdentificationError(
            f"{argument}: expected a positive number, got {value!r}"
        ) from None
    if not (v > 0 and np.isfinite(v)):
        raise IdentificationError(f"{argument}: expected a positive number, got {value!r}")
    return v


def check_choice(value: Any, argument: str, choices) -> str:
    if value not in choices:
        raise IdentificationError(f"{argument}: expected one of {choices}, got {value!r}")
    return value


def omega_of(ds: xr.Dataset) -> np.ndarray:
    return 2.0 * np.pi * np.asarray(ds[names.FREQUENCY].values, dtype=np.float64)


def drop_results(ds: xr.Dataset, groups) -> xr.Dataset:
    drop = [v for group in groups for v in group if v in ds.variables]
    out = ds.drop_vars(drop)
    for dim in (names.CANDIDATE, names.MODE, names.MODE_2, names.RESIDUAL_TERM):
        if dim in out.coords and not any(dim in out[v].dims for v in out.data_vars):
            out = out.drop_vars(dim)
    return out


def coordinate_attrs(ds: xr.Dataset) -> dict[Hashable, dict]:
    """A copy of the attrs of ``ds``'s non-index coordinates (e.g. ``point_x`` units), taken
    before ``apply_ufunc``: xarray < 2025.6 clears them there, on the variables it was given."""
    return {n: dict(ds[n].attrs) for n in ds.coords if n not in ds.indexes}


def restore_coordinate_attrs(out: xr.Dataset, attrs: dict[Hashable, dict]) -> xr.Dataset:
    """``out`` with the coordinate attrs ``attrs`` (from :func:`coordinate_attrs`) put back."""
    lost = [n for n, a in attrs.items() if n in out.coords and out[n].attrs != a]
    if not lost:
        return out
    # dropped first: assign_coords of old xarray keeps an existing coordinate's attrs
    fixed = {n: xr.Variable(out[n].dims, out[n].values, dict(attrs[n])) for n in lost}
    return out.drop_vars(lost).assign_coords(fixed)


def finish(out: xr.Dataset, function: str, phase: str, parameters: dict) -> xr.Dataset:
    """Record the phase and its provenance (once: writing is the caller's ``to_netcdf``)."""
    out.attrs[names.ATTR_AMI_PHASE] = phase
    return add_history(out, function, parameters)


def drive_index(ds: xr.Dataset) -> int | None:
    """Position of the ``drive_point`` attribute among the points, None when it is not one."""
    drive = ds.attrs.get(names.ATTR_DRIVE_POINT)
    if drive is None:
        return None
    idx = np.flatnonzero(np.asarray(ds[names.POINT].values).astype(str) == str(drive))
    return int(idx[0]) if idx.size else None


def frf_values(ds: xr.Dataset) -> np.ndarray:
    """The FRF as a computed (point, frequency) complex128 array."""
    return np.ascontiguousarray(
        ds[names.FRF].transpose(names.POINT, names.FREQUENCY).values, dtype=np.complex128
    )


def select_modes(ds: xr.Dataset, index) -> xr.Dataset:
    """``ds`` with the modes at positions ``index`` (in that order) on ``mode`` and
    ``mode_2``."""
    index = np.asarray(index, dtype=int)
    sel = {names.MODE: index}
    if names.MODE_2 in ds.dims:
        sel[names.MODE_2] = index
    return ds.isel(sel)


def sort_modes(ds: xr.Dataset) -> xr.Dataset:
    """Modes sorted by natural frequency and labelled 1..n (contiguous); the labels they had
    before are kept in ``mode_label_unsorted`` (attributes such as ``refine_removed_modes``
    name modes by those)."""
    n = ds.sizes.get(names.MODE, 0)
    if n == 0 or names.NATURAL_FREQUENCY not in ds:
        return ds
    fn = np.asarray(ds[names.NATURAL_FREQUENCY].transpose(names.MODE).values, dtype=float)
    order = np.argsort(np.where(np.isfinite(fn), fn, np.inf), kind="stable")
    before = np.asarray(ds[names.MODE].values)
    out = select_modes(ds, order)
    labels = np.arange(1, n + 1)
    out = out.assign_coords({names.MODE: labels})
    if names.MODE_2 in out.dims:
        out = out.assign_coords({names.MODE_2: labels})
    out[names.MODE_LABEL_UNSORTED] = xr.DataArray(
        before[order],
        dims=(names.MODE,),
        attrs={names.ATTR_LONG_NAME: "label of the mode before sorting by natural frequency"},
    )
    return out


def drop_outside_band(ds: xr.Dataset, fmin: float, fmax: float) -> tuple[xr.Dataset, np.ndarray]:
    """``ds`` without the modes whose natural frequency lies outside ``[fmin, fmax]`` Hz, and
    the natural frequencies of the dropped ones."""
    if ds.sizes.get(names.MODE, 0) == 0 or names.NATURAL_FREQUENCY not in ds:
        return ds, np.zeros(0)
    fn = np.asarray(ds[names.NATURAL_FREQUENCY].transpose(names.MODE).values, dtype=float)
    inside = (fn >= fmin) & (fn <= fmax)
    if np.all(inside):
        return ds, np.zeros(0)
    return select_modes(ds, np.flatnonzero(inside)), fn[~inside]


# flags about the AMI iteration that the refinement's converged estimate supersedes
SUPERSEDED_BY_REFINE = (names.FLAG_NOT_CONVERGED,)
_REFINE_TROUBLE = (names.FLAG_REFINE_FALLBACK, names.FLAG_REFINE_NOT_CONVERGED)


def clear_superseded_flags(ds: xr.Dataset, decay: float = 0.0) -> xr.Dataset:
    """After a refinement, the flags that no longer apply are removed.

    * ``refine_fallback`` says the mode was frozen at its AMI eigenvalue. When the final
      polish of the refinement falls back, it freezes every mode at the *refined* values of
      the stage before (measurement.uff: all 8 modes), so a mode whose reported eigenvalue
      (less the exponential-window ``decay`` identify added) differs from ``ami_eigenvalue``
      was refined, not frozen at AMI's value: the flag is dropped.
    * ``not_converged`` (the isolation stopped at its sweep cap) no longer applies to a mode
      the refinement moved to its converged maximum-likelihood estimate (no ``refine_fallback``
      or ``refine_not_converged`` left): the reported eigenvalue is not the isolation's.
    """
    if names.QUALITY_FLAGS not in ds or ds[names.QUALITY_FLAGS].dims != (names.MODE,):
        return ds
    ami = names.AMI_PREFIX + names.EIGENVALUE
    refined = np.zeros(ds.sizes[names.MODE], bool)
    if ami in ds and names.EIGENVALUE in ds:
        lam = np.asarray(ds[names.EIGENVALUE].transpose(names.MODE).values) - decay
        lam0 = np.asarray(ds[ami].transpose(names.MODE).values)
        with np.errstate(invalid="ignore"):
            refined = np.isfinite(lam0) & (np.abs(lam - lam0) > 1e-9 * np.abs(lam0))
    new = []
    for k, text in enumerate(np.asarray(ds[names.QUALITY_FLAGS].values).astype(str)):
        flags = [f for f in text.split(names.FLAG_SEPARATOR) if f]
        if refined[k]:
            flags = [f for f in flags if f != names.FLAG_REFINE_FALLBACK]
        if not any(f in _REFINE_TROUBLE for f in flags):
            flags = [f for f in flags if f not in SUPERSEDED_BY_REFINE]
        new.append(names.FLAG_SEPARATOR.join(flags))
    out = ds.copy(deep=False)
    out[names.QUALITY_FLAGS] = ds[names.QUALITY_FLAGS].copy(data=np.array(new, dtype=str))
    return out
