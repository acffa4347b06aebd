"""The refinement's line weights from the stored per-line noise model (issues 20, 41).

``frf_line_noise_std`` (point, frequency) of a measured FRF (its coherence and averages, or the
noise model :mod:`ami_xr.ami.whitening` passes on) is a level per point times a shape along
frequency. The level of each FRF is profiled out by the refinement's likelihood; the shape
weights the lines. FRFs that share a force share a shape; FRFs of several references do not:
a ``noise_group`` coordinate on ``point`` gives each group (reference) its own shape
(:mod:`ami_xr.core.grouped`).
"""

from __future__ import annotations

import warnings

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import chunked as ch
from ami_xr.core import frf_noise as fn

P, F = names.POINT, names.FREQUENCY

# Coordinate on ``point``: the FRFs of one group share a line shape of the noise model, each
# group its own (the multi-reference path stacks one group per reference)
NOISE_GROUP = "noise_group"
# the shape is a median over points: at most this many (evenly chosen) are read, so that a
# lazy set of 10^5 points is not loaded whole for it (its median moves by ~1/sqrt(rows))
MAX_ROWS = 256
# colour_shape: the noise's level over blocks of this share of the frequency (a quarter octave
# is about 19 %): wide against a mode's half-power band (a few per cent at most)
COLOUR_WIDTH = 0.2


def wants_smoothing(std: xr.DataArray) -> bool:
    """Whether a stored ``frf_line_noise_std`` is smoothed along frequency before it weights the
    lines (:func:`ami_xr.core.frf_noise.smoothed_std`): a record of the coherence formula (one
    random estimate per line), not one already smoothed (the whitening passes its smoothed
    model on, recorded as ``stored ...``), nor one given by the user or from the roughness."""
    return str(std.attrs.get(names.ATTR_NOISE_MODEL, "")).startswith("coherence")


def line_noise_shape(ds: xr.Dataset, frf: xr.DataArray):
    """Relative noise level of each line of ``frf`` from the stored per-line noise model
    (``frf_line_noise_std`` of a measured FRF, from its coherence and averages): the median
    over points (at most ``MAX_ROWS`` of them, evenly chosen) of each point's noise relative to
    its median, scaled to median 1 (a record of
    the coherence smoothed along frequency first: :func:`wants_smoothing`); with a
    ``noise_group`` coordinate on ``point`` (two groups or more), one such shape per group.
    Returns ``(shape (L,) or shapes (G, L), group of each point (P,) or None)``; ``(None,
    None)`` when the FRF has no per-line noise model (the lines are then weighted alike)."""
    if names.FRF_LINE_NOISE_STD not in ds:
        return None, None
    std = ds[names.FRF_LINE_NOISE_STD].transpose(P, F).sel({F: frf[F].values})
    index = None
    if NOISE_GROUP in frf.coords and frf[NOISE_GROUP].dims == (P,):
        _, index = np.unique(np.asarray(frf[NOISE_GROUP].values), return_inverse=True)
        index = index.ravel()
    groups = [np.arange(std.sizes[P])] if index is None else _members(index)
    read = np.concatenate([even_subset(g, max(MAX_ROWS // len(groups), 8)) for g in groups])
    sd = np.asarray(ch.rows(std, np.sort(read)), dtype=np.float64)  # of a lazy std these only
    if wants_smoothing(ds[names.FRF_LINE_NOISE_STD]):
        sd = fn.smoothed_std(sd, frf[F].values)
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = sd / np.nanmedian(sd, axis=1, keepdims=True)
    if index is None or index.max() < 1:
        return _shape(rel), None
    of_read = index[np.sort(read)]
    shapes = [_shape(rel[of_read == g]) for g in range(index.max() + 1)]
    if any(x is None for x in shapes):  # a group without a noise model: one shape for all
        return _shape(rel), None
    return np.array(shapes), index


def colour_shape(ds: xr.Dataset, frf: xr.DataArray, width: float = COLOUR_WIDTH):
    """The noise's colour along frequency, for the subtraction's peak statistics: the shape of
    :func:`line_noise_shape` (per group where it gives one per group) reduced to its level over
    blocks of ``width`` of the frequency (:func:`ami_xr.core.frf_noise.local_level`, median 1).
    Returns ``(shape, group)`` as :func:`line_noise_shape` does, ``(None, None)`` without a
    per-line noise model.

    Why a level, not the shape itself: the coherence's noise estimate follows the FRF at its
    peaks (leakage lowers the coherence there, and its formula scales with ``|H|^2``), so the
    power relative to it has no peak at a resonance; the phase looks for peaks against the
    noise's colour (a force rolling off, sensor noise in another quantity), which changes over
    tens of per cent of the frequency, not over a mode's bandwidth."""
    shape, group = line_noise_shape(ds, frf)
    if shape is None:
        return None, None
    f = np.asarray(frf[F].values, dtype=np.float64)
    level = fn.local_level(np.atleast_2d(shape), f, width)
    level = level / np.median(level, axis=-1, keepdims=True)
    return (level[0] if np.ndim(shape) == 1 else level), group


def _members(index: np.ndarray) -> list[np.ndarray]:
    """The points of each group ``0 .. max(index)``."""
    return [np.flatnonzero(index == g) for g in range(int(index.max()) + 1)]


def even_subset(points: np.ndarray, n: int) -> np.ndarray:
    """At most ``n`` of ``points``, evenly chosen (all of them when there are no more)."""
    if points.size <= n:
        return points
    return points[np.unique(np.linspace(0, points.size - 1, n).round().astype(int))]


def _shape(rel: np.ndarray) -> np.ndarray | None:
    """The median over points of their relative noise (P, L), median 1; None without two lines
    of known level."""
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN lines
        shape = np.nanmedian(rel, axis=0)
    ok = np.isfinite(shape) & (shape > 0)
    if ok.sum() < 2:
        return None
    shape = np.where(ok, shape, np.median(shape[ok]))  # lines without a level: a typical one
    shape = np.clip(shape / np.median(shape), 1e-3, 1e3)  # no line ignored, none dominant
    return shape
