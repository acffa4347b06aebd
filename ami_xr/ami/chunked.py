"""Statistics of point-by-frequency arrays that never hold more than one chunk of points at once.

``identify`` takes FRF sets larger than memory as dask arrays chunked along ``point`` (a lazily
opened file, :func:`ami_xr.open_dataset` with ``chunks``). Every statistic of the FRFs, the
residuals or the synthesized FRFs then has to reduce chunk by chunk, on whatever dask scheduler
is active (the workers of a ``dask.distributed`` client included), so that only per-point or
smaller results reach the caller: taking ``.values`` of such an array builds one task that
holds all of it (10^5 points x 4096 lines: 6.1 GiB for a worker of 2 GB, issue 42).

Three shapes of work, each the same function on a numpy array (one call on the whole array, as
before) and a dask one (one call per chunk of points):

* :func:`rows`: a few chosen rows (points) as a numpy array, reading only their chunks;
* :func:`per_row`: a function of each row's frequency line, one value per row;
* :func:`map_reduce`: partial results per chunk of rows combined pairwise in a tree
  (``split_every`` at a time), for statistics that pool the points;
* :func:`fit_per_row`: a small vector per row (a fit's coefficients), gathered;
* :func:`made_from_rows`: rows the size of the FRF made per chunk from small per-row values
  (synthesized FRFs from residues): lazy, in the FRF's chunks, when the FRF is lazy.

On a numpy array the work goes in blocks of :data:`ROWS` rows with an interrupt checkpoint
between blocks (a Ctrl-C of the command line lands within a block's time).

dask is imported only where an array is dask-backed (it is an optional dependency).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import interrupt, names

ATTR_LAZY_LOADED = "ami_lazy_loaded"
"""Attribute of a result: the phases (comma-separated) that loaded a lazy FRF into memory
(:func:`loaded`)."""

LOAD_WARN_BYTES = 2**28
"""A lazy FRF larger than this (256 MiB) loaded into memory is told in a warning."""

ROWS = 256
"""Rows per call on a numpy array: a pending Ctrl-C is raised between calls
(:func:`ami_xr.interrupt.checkpoint`), at most a fraction of a second apart."""

__all__ = [
    "ATTR_LAZY_LOADED",
    "broadcast_rows",
    "fit_per_row",
    "is_lazy",
    "loaded",
    "note_loaded",
    "made_from_rows",
    "map_reduce",
    "per_row",
    "rows",
]


def is_lazy(x: Any) -> bool:
    """Whether ``x`` (an array or a DataArray) is dask-backed."""
    return hasattr(getattr(x, "data", x), "dask")


def _one_chunk_last(data):
    """A dask array with its last axis in one chunk (rows are then whole)."""
    if data.ndim > 1 and len(data.chunks[-1]) > 1:
        data = data.rechunk({data.ndim - 1: -1})
    return data


def rows(da: xr.DataArray, index: np.ndarray) -> np.ndarray:
    """Rows ``index`` of ``da`` flattened to (rows, last dim) as a numpy array; of a dask-backed
    ``da`` only the chunks that hold them are read."""
    data = da.data
    index = np.asarray(index, dtype=np.intp)
    if not is_lazy(da):
        return np.asarray(data).reshape(-1, data.shape[-1])[index]
    data = _one_chunk_last(data)
    if data.ndim > 2:
        data = data.reshape(-1, data.shape[-1])
    return np.asarray(data[index].compute())


def per_row(
    func: Callable[..., np.ndarray], da: xr.DataArray, dim: str, **kwargs: Any
) -> np.ndarray:
    """``func(block, **kwargs)`` over the rows of ``da`` along ``dim`` (the core dim, last in
    ``block``; one value per row, dtype float) as a numpy array of ``da``'s other dims: one call
    on a numpy ``da``, one per chunk of a dask one (only the per-row values are gathered)."""
    if is_lazy(da) and len(da.chunksizes.get(dim, ())) > 1:
        da = da.chunk({dim: -1})
    if not is_lazy(da):
        x = np.asarray(da.transpose(..., dim).values)
        flat = x.reshape(-1, x.shape[-1])
        parts = []
        for lo in range(0, flat.shape[0], ROWS):
            interrupt.checkpoint()
            parts.append(np.asarray(func(flat[lo : lo + ROWS], **kwargs), dtype=np.float64))
        out = np.concatenate(parts) if parts else np.zeros(0)
        return out.reshape(x.shape[:-1])
    out = xr.apply_ufunc(
        func,
        da,
        kwargs=kwargs,
        input_core_dims=[[dim]],
        output_core_dims=[[]],
        dask="parallelized",
        output_dtypes=[np.float64],
        keep_attrs=False,
    )
    return np.asarray(out.values)


def _blocks(data, starts: Sequence[int], stops: Sequence[int]) -> list:
    """``data`` cut at the row bounds: a dask array's blocks (delayed), a numpy array's slices."""
    if data is None:
        return [None] * len(starts)
    if is_lazy(data):
        import dask.array as da

        data = _one_chunk_last(data)
        chunks = (tuple(b - a for a, b in zip(starts, stops, strict=True)),) + data.chunks[1:]
        if data.chunks != chunks:
            data = data.rechunk(chunks)
        return list(da.Array.to_delayed(data).reshape(len(starts), -1)[:, 0])
    return [data[a:b] for a, b in zip(starts, stops, strict=True)]


def map_reduce(
    func: Callable[..., Any],
    combine: Callable[[list], Any],
    arrays: Sequence[Any],
    shared: Any = None,
    split_every: int = 8,
) -> Any:
    """``combine`` of ``func(*blocks, shared)`` over the chunks of rows of ``arrays`` (numpy or
    dask arrays, or None, with the same number of rows).

    On numpy arrays ``func`` sees blocks of :data:`ROWS` rows, combined once. Otherwise the row
    chunks of the first dask array decide the blocks (the others are cut alike), ``shared`` goes
    to the scheduler once, and the partial results are combined ``split_every`` at a time in a tree;
    only the final combination reaches the caller.
    """
    lazy = [a for a in arrays if a is not None and is_lazy(a)]
    if not lazy:
        n_rows = next((len(a) for a in arrays if a is not None), 0)
        parts = []
        for lo in range(0, max(n_rows, 1), ROWS):
            interrupt.checkpoint()
            parts.append(func(*(None if a is None else a[lo : lo + ROWS] for a in arrays), shared))
        return parts[0] if len(parts) == 1 else combine(parts)
    import dask

    sizes = lazy[0].chunks[0]
    stops = list(np.cumsum(sizes))
    starts = [0, *stops[:-1]]
    blocks = [_blocks(a, starts, stops) for a in arrays]
    held = dask.delayed(shared, pure=True) if shared is not None else None
    task = dask.delayed(func, pure=True)
    parts = [task(*(b[i] for b in blocks), held) for i in range(len(starts))]
    join = dask.delayed(combine, pure=True)
    while len(parts) > 1:
        parts = [join(parts[i : i + split_every]) for i in range(0, len(parts), split_every)]
    (total,) = dask.compute(parts[0])
    return total


def broadcast_rows(row: np.ndarray, like: xr.DataArray):
    """``row`` (L,) repeated to the shape of ``like`` (..., L): a dask array in ``like``'s
    chunks when ``like`` is dask-backed (nothing of size ``like`` is held), else a numpy
    array."""
    if is_lazy(like):
        import dask.array as da

        return da.broadcast_to(da.from_array(row, chunks=-1), like.shape, chunks=like.data.chunks)
    return np.array(np.broadcast_to(row, like.shape))


def fit_per_row(
    func: Callable[..., np.ndarray],
    da: xr.DataArray,
    dim: str,
    out_dim: str,
    size: int,
    dtype: Any = np.complex128,
    **kwargs: Any,
) -> xr.DataArray:
    """``func(block, **kwargs)`` (..., ``dim``) -> (..., ``size``) over the rows of ``da``, as a
    numpy-backed DataArray with ``out_dim`` in place of ``dim``: one call on a numpy ``da``, one
    task per chunk of rows of a dask one (only the small per-row results are gathered)."""
    if is_lazy(da) and len(da.chunksizes.get(dim, ())) > 1:
        da = da.chunk({dim: -1})
    out = xr.apply_ufunc(
        func,
        da,
        kwargs=kwargs,
        input_core_dims=[[dim]],
        output_core_dims=[[out_dim]],
        exclude_dims={dim},
        dask="parallelized",
        output_dtypes=[dtype],
        dask_gufunc_kwargs={"output_sizes": {out_dim: size}},
        keep_attrs=False,
    )
    return out.compute()


def made_from_rows(
    func: Callable[..., np.ndarray],
    small: Sequence[xr.DataArray],
    in_dims: Sequence[str],
    like: xr.DataArray,
    out_dim: str,
    dtype: Any = np.complex128,
    **kwargs: Any,
) -> xr.DataArray:
    """``func(*blocks, **kwargs)`` -> (..., ``like.sizes[out_dim]``) over the rows of the small
    per-row arrays ``small`` (core dims ``in_dims``), with dims ``like``'s: lazy, one task per
    chunk of ``like``'s rows, when ``like`` is dask-backed (nothing of ``like``'s size is made
    before it is asked for, and then only a chunk at a time), else computed at once. The
    result carries ``out_dim`` as ``out_dim + "_out"`` (no coordinate); rename it back."""
    tmp = out_dim + "_out"
    if is_lazy(like):
        chunks = {d: like.chunksizes[d] for d in like.dims if d != out_dim}
        small = [s.chunk({d: chunks[d] for d in s.dims if d in chunks}) for s in small]
    out = xr.apply_ufunc(
        func,
        *small,
        kwargs=kwargs,
        input_core_dims=[[d] for d in in_dims],
        output_core_dims=[[tmp]],
        dask="parallelized",
        output_dtypes=[dtype],
        dask_gufunc_kwargs={"output_sizes": {tmp: like.sizes[out_dim]}},
        keep_attrs=False,
    )
    return out.transpose(*[tmp if d == out_dim else d for d in like.dims])


def loaded(da: xr.DataArray, phase: str) -> xr.DataArray:
    """``da`` in memory, for a phase that fits every FRF at once (the SIMO isolation, the
    refinement: their kernels hold all points); a dask-backed ``da`` larger than
    :data:`LOAD_WARN_BYTES` is told in an ``AssumptionWarning`` first. The caller records it
    with :func:`note_loaded`."""
    if not is_lazy(da):
        return da
    if da.nbytes > LOAD_WARN_BYTES:
        from ami_xr.caller import warn
        from ami_xr.errors import AssumptionWarning

        warn(
            f"{phase}: fits all {da.sizes.get(names.POINT, 1)} FRFs at once: the lazily opened FRF "
            f"({da.nbytes / 2**20:.0f} MiB) is loaded into memory; identify's compress='auto' "
            f"(or an int) keeps it on the dask workers (attr {ATTR_LAZY_LOADED})",
            AssumptionWarning,
        )
    return da.compute()


def note_loaded(attrs: dict, phase: str) -> None:
    """Add ``phase`` to attr :data:`ATTR_LAZY_LOADED` of ``attrs`` (once)."""
    listed = [p for p in str(attrs.get(ATTR_LAZY_LOADED, "")).split(",") if p]
    attrs[ATTR_LAZY_LOADED] = ",".join(listed + ([phase] if phase not in listed else []))
