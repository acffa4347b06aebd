"""The paper's measurement noise (eq. 15): :func:`add_noise` on time histories, per channel."""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.provenance import add_history

# Attributes add_noise writes beyond ami_xr.names (simulator-specific).
ATTR_NOISE_LEVEL = "noise_level"  # alpha of eq. 15
ATTR_NOISE_KIND = "noise_kind"  # "uniform" | "gaussian"
ATTR_NOISE_SEED = "noise_seed"

NOISE_KINDS = ("uniform", "gaussian")


def _noise_kernel(y: np.ndarray, r: np.ndarray, alpha: float) -> np.ndarray:
    """y + alpha * max_n |y| * r, the maximum taken along the last (core) axis per channel."""
    return y + alpha * np.abs(y).max(axis=-1, keepdims=True) * r


def add_noise(
    data: Any,
    alpha: float,
    *,
    seed: int | None = None,
    rng: np.random.Generator | None = None,
    kind: str = "uniform",
    dim: str = names.TIME,
):
    """Add the paper's measurement noise (eq. 15) to time histories, per channel.

    ``y_j(t_n) + alpha * max_n |y_j(t_n)| * r_jn`` with ``r_jn`` uniform in [-1, 1) (the paper),
    or, with ``kind="gaussian"``, standard normal (so the noise standard deviation is
    ``alpha * max_n |y_j|``). The maximum is taken along ``dim`` separately for every channel
    (every point, and every record where there is a ``record`` dim).

    Parameters
    ----------
    data : xarray.Dataset, xarray.DataArray or ndarray
        A time Dataset (noise is added to ``response`` only), a DataArray with ``dim``, or an
        array whose LAST axis is time.
    alpha : float
        Noise level as a fraction of each channel's peak amplitude (0.15 in the paper).
    seed : int, optional
        Seed of a fresh ``numpy.random.default_rng``; the same seed gives the same noise.
    rng : numpy.random.Generator, optional
        Generator to draw from instead (mutually exclusive with ``seed``).
    kind : {"uniform", "gaussian"}
    dim : str
        Time dimension of a Dataset or DataArray.

    Returns
    -------
    Same type as ``data``: a new object with noise added.
    """
    if isinstance(alpha, bool) or not np.isscalar(alpha) or not np.isfinite(alpha) or alpha < 0:
        raise AmiXrValueError(f"alpha: expected a finite number >= 0, got {alpha!r}")
    if kind not in NOISE_KINDS:
        raise AmiXrValueError(f"kind: expected one of {NOISE_KINDS}, got {kind!r}")
    if seed is not None and rng is not None:
        raise AmiXrValueError("seed, rng: give at most one of them")
    if rng is None:
        rng = np.random.default_rng(seed)
    elif not isinstance(rng, np.random.Generator):
        raise AmiXrValueError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")

    def draw(shape):
        if kind == "uniform":
            return rng.uniform(-1.0, 1.0, size=shape)
        return rng.standard_normal(size=shape)

    if isinstance(data, xr.Dataset):
        if names.RESPONSE not in data:
            raise AmiXrValueError(f"data: the Dataset has no {names.RESPONSE!r} variable")
        noisy = add_noise(data[names.RESPONSE], alpha, rng=rng, kind=kind, dim=dim)
        out = data.copy()
        out.attrs = dict(data.attrs)
        out[names.RESPONSE] = noisy
        out.attrs[ATTR_NOISE_LEVEL] = float(alpha)
        out.attrs[ATTR_NOISE_KIND] = kind
        if seed is not None:
            out.attrs[ATTR_NOISE_SEED] = int(seed)
        return add_history(
            out, "ami_xr.simulate.add_noise", {"alpha": alpha, "kind": kind, "seed": seed}
        )
    if isinstance(data, xr.DataArray):
        if dim not in data.dims:
            raise AmiXrValueError(f"dim: {dim!r} is not a dimension of data {data.dims}")
        if not np.issubdtype(data.dtype, np.floating):
            raise AmiXrValueError(f"data: expected real floating-point values, got {data.dtype}")
        core_last = data.transpose(..., dim)
        r = xr.DataArray(draw(core_last.shape), dims=core_last.dims)
        out = xr.apply_ufunc(
            _noise_kernel,
            data,
            r,
            kwargs={"alpha": float(alpha)},
            input_core_dims=[[dim], [dim]],
            output_core_dims=[[dim]],
            dask="parallelized",
            output_dtypes=[np.float64],
            keep_attrs=True,
        )
        return out.transpose(*data.dims)
    y = np.asarray(data)
    if y.ndim == 0 or not np.issubdtype(y.dtype, np.floating):
        raise AmiXrValueError(
            "data: expected a Dataset, DataArray or a real floating-point array with time last"
        )
    return _noise_kernel(y, draw(y.shape), float(alpha))
