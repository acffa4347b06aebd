"""Shared helpers of the AMI phases: input checks, the variables each phase makes, provenance."""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Hashable, Iterator
from functools import partial
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.core import checks, flags
from ami_xr.errors import IdentificationError, SchemaError
from ami_xr.io.schema import find_problems
from ami_xr.provenance import record_history

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


# The FRF array identify validated, while its phases run on it (see frf_checked)
_CHECKED: contextvars.ContextVar[Any] = contextvars.ContextVar("ami_xr_checked_frf", default=None)


@contextlib.contextmanager
def frf_checked(ds: xr.Dataset) -> Iterator[None]:
    """Within this block, :func:`check_frf` does not validate again a Dataset whose FRF is this
    very array (the same object, not an equal one): :func:`ami_xr.identify` validates its input
    once and its phases receive that FRF unchanged, so the one validation covers them. Any
    other Dataset (another array, a transposed or edited FRF) is validated as always."""
    token = _CHECKED.set(ds[names.FRF].data)
    try:
        yield
    finally:
        _CHECKED.reset(token)


def check_frf(ds: Any, function: str) -> xr.Dataset:
    """The input checks every phase makes before any work.

    The FRF Dataset's structure is checked by the data model's one validator,
    :func:`ami_xr.io.schema.find_problems` (dims, dtype, unique point labels, a strictly
    increasing frequency axis on the rfft grid of an impulse-response FRF, finite values named
    with their points and counts; every problem at once in a
    :class:`~ami_xr.errors.SchemaError`), without the descriptive attributes (units, quantity)
    an analysis does not need. Multi-reference data and too few lines for a fit are the
    phases' own errors.
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
    if frf.data is _CHECKED.get() and frf.dims == (names.POINT, names.FREQUENCY):
        return ds  # identify's own input, validated once (frf_checked)
    if set(frf.dims) == {names.POINT, names.FREQUENCY} and not _in_order(ds):
        ds = ds.transpose(names.POINT, names.FREQUENCY, ...)  # either order: phases transpose
    ds = whole_lines(ds)
    what, problems = find_problems(ds, "frf", require_drive_point=False, metadata=False)
    if problems:
        raise SchemaError(problems, what=f"{function}: the {what}")
    check_drive_point(ds)
    n_lines = ds.sizes[names.FREQUENCY]
    if n_lines < MIN_LINES:
        raise IdentificationError(
            f"{names.FREQUENCY}: {n_lines} lines; the single-mode fit needs at least {MIN_LINES}"
        )
    return ds


def _in_order(ds: xr.Dataset) -> bool:
    """Whether every variable of ``ds`` has ``point`` and ``frequency`` first, in that order
    (what ``ds.transpose(point, frequency, ...)`` makes; then there is nothing to copy)."""
    first = (names.POINT, names.FREQUENCY)
    for var in ds.variables.values():
        lead = tuple(d for d in first if d in var.dims)
        if var.dims[: len(lead)] != lead:
            return False
    return True


def whole_lines(ds: xr.Dataset) -> xr.Dataset:
    """``ds`` with lazy (dask) variables in one chunk along ``frequency``: the per-FRF kernels
    take whole lines (xarray refuses a core dim in several chunks), so a file opened in small
    frequency chunks is rechunked here, not by the user. Chunks along ``point`` are kept."""
    split = [
        name
        for name, var in ds.variables.items()
        if names.FREQUENCY in var.dims
        and var.chunks is not None
        and len(var.chunks[var.dims.index(names.FREQUENCY)]) > 1
    ]
    if not split:
        return ds
    whole = {name: ds[name].variable.chunk({names.FREQUENCY: -1}) for name in split}
    data = {n: v for n, v in whole.items() if n in ds.data_vars}
    coords = {n: v for n, v in whole.items() if n not in ds.data_vars}
    return ds.assign(data).assign_coords(coords)


def check_drive_point(ds: xr.Dataset) -> None:
    """A ``drive_point`` attribute that names no point is an error naming it (it would leave
    the mode vectors unscaled without a word); no attribute: unscaled mode vectors, as asked."""
    drive = ds.attrs.get(names.ATTR_DRIVE_POINT)
    if drive is None or names.POINT not in ds.coords or drive_index(ds) is not None:
        return
    raise IdentificationError(
        f"{names.ATTR_DRIVE_POINT}: {drive!r} is not among the point labels "
        f"{shorten(np.asarray(ds[names.POINT].values))}; set the attribute to the label of "
        "the point where the force acts (mode vectors are scaled there), or remove it to get "
        "unscaled mode vectors"
    )


def check_values(ds: xr.Dataset) -> None:
    """An all-zero FRF is an error naming the point (nothing to identify; the values are
    known finite from :func:`check_frf`)."""
    peak = np.asarray(np.abs(ds[names.FRF]).max(names.FREQUENCY).values)
    check_peaks(peak, np.asarray(ds[names.POINT].values))


def check_peaks(peak: np.ndarray, points: np.ndarray) -> None:
    """The check of :func:`check_values` on the largest magnitude ``peak`` (P,) of each FRF,
    for a caller that has it from its own pass over the data."""
    zero = np.asarray(peak) == 0
    if np.any(zero):
        raise IdentificationError(
            f"{names.FRF}: all-zero FRF at point(s) {shorten(points[zero])}; nothing to identify"
        )


# The scalar checks of :mod:`ami_xr.core.checks`, raising IdentificationError as the phases do.
check_choice = partial(checks.check_choice, error=IdentificationError)
check_fraction = partial(checks.check_fraction, error=IdentificationError)
check_positive = partial(checks.check_positive, error=IdentificationError)
check_positive_int = partial(checks.check_positive_int, error=IdentificationError)
shorten = checks.shorten


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
    """Record the phase and its provenance in the attributes of ``out`` (the Dataset the phase
    made; once: writing is the caller's ``to_netcdf``)."""
    out.attrs[names.ATTR_AMI_PHASE] = phase
    record_history(out.attrs, function, parameters)
    return out


def drive_index(ds: xr.Dataset) -> int | None:
    """Position of the ``drive_point`` attribute among the points, None when it is not one."""
    if ds.attrs.get(names.ATTR_DRIVE_POINT) is None:
        return None
    return drive_position(ds[names.POINT].values, ds.attrs)


def drive_position(points, attrs) -> int | None:
    """Position of the ``drive_point`` of ``attrs`` among the labels ``points``, None when it is
    not one (:func:`drive_index` on arrays)."""
    drive = attrs.get(names.ATTR_DRIVE_POINT)
    if drive is None:
        return None
    idx = np.flatnonzero(np.asarray(points).astype(str) == str(drive))
    return int(idx[0]) if idx.size else None


def _direct_constructor():
    """xarray's private constructor of a Dataset from checked parts, None where it is gone."""
    return getattr(xr.Dataset, "_construct_direct", None)


def built(
    variables: dict[Hashable, Any], coords, attrs: dict, like: xr.Dataset | None = None
) -> xr.Dataset:
    """One Dataset of ``variables`` (Variables or ``(dims, data[, attrs])`` tuples, by name;
    those named in ``coords`` and the dimension coordinates are its coordinates) with the
    attributes ``attrs``: how the phases build each output once, from their arrays.

    ``xarray.Dataset(...)`` would build a second Dataset inside (its ``Coordinates``) and check
    again what the phases made consistent; this is xarray's own constructor for the results of
    its operations (private: should a later xarray change it, the public constructor builds
    the same Dataset). A dimension coordinate that is the very Variable of ``like`` keeps
    ``like``'s index (a new one is built otherwise)."""
    from xarray.indexes import PandasIndex

    out: dict[Hashable, xr.Variable] = {}
    indexes = {}
    sizes: dict[Hashable, int] = {}
    for name, v in variables.items():
        v = v if isinstance(v, xr.Variable) else xr.Variable(*v)
        if v.dims == (name,):  # a dimension coordinate: indexed
            same = like is not None and name in like.xindexes and like.variables[name] is v
            if same:
                indexes[name] = like.xindexes[name]
            else:
                indexes[name] = PandasIndex.from_variables({name: v}, options={})
                v = indexes[name].create_variables({name: v})[name]
        for d, n in zip(v.dims, v.shape, strict=True):
            if sizes.setdefault(d, n) != n:
                raise ValueError(f"{name}: {d} has {n} elements, another variable {sizes[d]}")
        out[name] = v
    names_ = {n for n in coords if n in out} | set(indexes)
    direct = _direct_constructor()
    if direct is not None:
        try:
            return direct(out, names_, sizes, dict(attrs), indexes)
        except TypeError:  # xarray's private constructor changed: the public one below
            pass
    data_vars = {k: v for k, v in out.items() if k not in names_}
    return xr.Dataset(data_vars, coords={k: out[k] for k in names_}, attrs=dict(attrs))


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


def keep_modes(ds: xr.Dataset, keep: np.ndarray) -> xr.Dataset:
    """``ds`` with the modes where ``keep`` (bool, on ``mode``) is True, labelled 1..n on
    ``mode`` (and ``mode_2``)."""
    index = np.flatnonzero(keep)
    variables = {}
    for k, v in ds.variables.items():
        at = {d: index for d in (names.MODE, names.MODE_2) if d in v.dims}
        variables[k] = v.isel(at) if at else v
    for d in (names.MODE, names.MODE_2):
        if d in ds.dims:  # labelled 1..n
            variables[d] = xr.Variable((d,), np.arange(1, index.size + 1))
    return built(variables, ds.coords, ds.attrs, like=ds)


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
    labels = np.arange(1, n + 1)
    mode_dims = [d for d in (names.MODE, names.MODE_2) if d in ds.dims]
    unsorted = xr.Variable(
        (names.MODE,),
        before[order],
        {names.ATTR_LONG_NAME: "label of the mode before sorting by natural frequency"},
    )
    out = ds.isel(dict.fromkeys(mode_dims, order)).assign_coords(dict.fromkeys(mode_dims, labels))
    return out.assign({names.MODE_LABEL_UNSORTED: unsorted})


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


def flag_mask(ds: xr.Dataset) -> np.ndarray:
    """The int32 flag mask (:mod:`ami_xr.core.flags`) of each mode of ``ds``: decoded from its
    ``quality_flags``, zeros when it has none."""
    n_mode = ds.sizes.get(names.MODE, 0)
    if names.QUALITY_FLAGS in ds and ds[names.QUALITY_FLAGS].dims == (names.MODE,):
        return flags.decode(ds[names.QUALITY_FLAGS].values)
    return np.zeros(n_mode, np.int32)
