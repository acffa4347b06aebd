"""The noise of an FRF per line: ``frf_line_noise_std`` beside ``frf``.

``ami_xr.frf`` and ``ami_xr.impact_frf`` store it from the coherence and the number of averages
(:func:`ami_xr.core.frf_noise.coherence_noise_std`). A bare FRF (read from a UFF file, simulated,
made by ``impulse_to_frf``) has no coherence: :func:`estimate_frf_noise` estimates it from the
data, from the roughness between adjacent lines (:func:`ami_xr.core.frf_noise.roughness_noise_std`).
:func:`noise_std_of` is what the identification phases call: the stored variable where there is
one, the estimate otherwise.

``frf_line_noise_std`` has the dims of ``frf`` (``[reference,] point, frequency``), float, in the
FRF's
units: ``sqrt(E|H_est - H|^2)`` at each line (each of the real and imaginary parts carries half
the variance); its ``noise_model`` attribute says how it was obtained.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.core import frf_noise as _fn
from ami_xr.core.checks import check_choice
from ami_xr.errors import AmiXrValueError

METHODS = ("roughness",)
LONG_NAME = "standard deviation of the FRF estimate per line"
_UNIFORM_RTOL = 1e-6  # line spacing may differ from its mean by this fraction


def _check_frf(ds: xr.Dataset) -> xr.DataArray:
    if not isinstance(ds, xr.Dataset) or names.FRF not in ds.data_vars:
        raise AmiXrValueError(f"ds: expected an FRF Dataset with a {names.FRF!r} variable")
    h = ds[names.FRF]
    if names.FREQUENCY not in h.dims:
        raise AmiXrValueError(f"ds: {names.FRF!r} has no {names.FREQUENCY!r} dim, got {h.dims}")
    freq = np.asarray(ds[names.FREQUENCY].values, dtype=np.float64)
    if freq.size > 2:
        step = np.diff(freq)
        if not np.all(np.abs(step - step.mean()) <= _UNIFORM_RTOL * abs(step.mean())):
            raise AmiXrValueError(
                f"ds: the {names.FREQUENCY!r} lines are not uniformly spaced; the roughness "
                "estimate differences adjacent lines"
            )
    return h


def estimate_frf_noise(
    ds: xr.Dataset,
    method: str = "roughness",
    *,
    order: int = _fn.ROUGHNESS_ORDER,
    window: int = _fn.ROUGHNESS_WINDOW,
) -> xr.Dataset:
    """Estimate the noise of each FRF line from the data; ``ds`` with ``frf_line_noise_std`` added.

    ``method="roughness"``: the difference of order ``order`` along frequency annihilates the
    modal part where it is smooth on the scale of ``order`` lines and multiplies white noise by
    ``sqrt(binomial(2 order, order))``; a running median of its modulus over ``window`` lines,
    scaled to a standard deviation (median of a complex Gaussian's modulus ``sigma sqrt(ln 2)``),
    follows noise that varies by orders of magnitude across the band and ignores the few lines
    at a sharp resonance. ``order=4``: a resonance peak ``d`` lines away leaves ``~24/d^5`` of
    its height, so only ~10 lines around a peak with a peak-to-noise ratio of 1e4 and a
    half-power bandwidth of 2 lines count as outliers; the median of 65 lines tolerates 32.
    ``window=65``: the per-line scatter of the estimate is ~14 % (median of 65 correlated
    differences), and noise that changes by 100x across 1000 lines changes by 35 % over a window.

    An existing ``frf_line_noise_std`` (from the coherence of ``ami_xr.frf``) is replaced.

    Parameters
    ----------
    ds : xarray.Dataset
        FRF Dataset (``frf`` with dims ``[reference,] point, frequency``; uniform lines).
    method : {"roughness"}
    order : int
        Even difference order >= 2.
    window : int
        Odd number of lines of the running median.

    Returns
    -------
    xarray.Dataset
        A copy of ``ds`` with ``frf_line_noise_std`` (dims of ``frf``, float, units of ``frf``;
        attrs
        ``noise_model``, ``long_name``, ``units``).

    Raises
    ------
    AmiXrValueError
        No ``frf``, non-uniform lines, unknown ``method``, bad ``order`` or ``window``, fewer
        than ``order + 1`` lines.
    """
    check_choice(method, "method", METHODS)
    h = _check_frf(ds)
    _fn.check_roughness(order, window, h.sizes[names.FREQUENCY])
    std = xr.apply_ufunc(
        _fn.roughness_noise_std,
        h,
        kwargs={"order": order, "window": window},
        input_core_dims=[[names.FREQUENCY]],
        output_core_dims=[[names.FREQUENCY]],
        dask="parallelized",
        # the differences need every line at once; the float64 output is given as a real meta
        # (output_dtypes would cast dask's complex meta of the input, with a ComplexWarning)
        dask_gufunc_kwargs={"allow_rechunk": True, "meta": np.empty((0,) * h.ndim)},
        keep_attrs=False,
    ).transpose(*h.dims)
    attrs = {
        names.ATTR_LONG_NAME: LONG_NAME,
        names.ATTR_NOISE_MODEL: _fn.roughness_model(order, window),
    }
    if names.ATTR_UNITS in h.attrs:
        attrs[names.ATTR_UNITS] = h.attrs[names.ATTR_UNITS]
    # the Variable only: apply_ufunc's coordinates have lost their attributes (units)
    return ds.assign({names.FRF_LINE_NOISE_STD: xr.Variable(h.dims, std.data, attrs)})


def noise_std_of(ds: xr.Dataset) -> xr.DataArray:
    """The noise std per FRF line the identification phases use: ``ds.frf_line_noise_std`` where it
    is stored per line (from ``ami_xr.frf``'s coherence or an earlier estimate), else
    :func:`estimate_frf_noise`'s roughness estimate. Dims of ``frf``."""
    h = _check_frf(ds)
    if names.FRF_LINE_NOISE_STD in ds and ds[names.FRF_LINE_NOISE_STD].dims == h.dims:
        return ds[names.FRF_LINE_NOISE_STD]
    return estimate_frf_noise(ds)[names.FRF_LINE_NOISE_STD]
