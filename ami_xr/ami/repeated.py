"""One reference that cannot separate a repeated pair says so (issue 22 item 2).

One reference sees a repeated pair through one column of the FRF matrix: two poles closer than
their bandwidth whose shapes differ leave a shape that varies across the band, which one pole
cannot fit. :func:`band_rank_statistics` measures it for every identified mode: within
``BAND_HALF_WIDTH`` half-power half-bandwidths ``|Re lam|`` of the mode, the data less every
other term of the fitted model (``frf_residual`` plus the mode's own positive-pole term), each
FRF divided by its noise standard deviation, is a (point x line) matrix that is rank one for one
mode (:func:`ami_xr.core.mimo.band_rank`). Its second singular value above
``EXCESS_MIN (sqrt(P) + sqrt(n))`` (beyond what noise gives) and above ``RATIO_MIN`` of the
first (a model error proportional to the response stays below) sets ``repeated_root_suspected``.

An exactly repeated root (split 0) is one pole with one residue vector in every column of the
FRF matrix: no statistic of one column can tell it from one mode; two references resolve it
(:mod:`ami_xr.ami.mimo`).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.core import mimo as cm
from ami_xr.core.model import resolve_model
from ami_xr.kernels.modal_basis import pole_basis

BAND_HALF_WIDTH = 2.0  # lines within 2 |Re lam| of Im lam: the half-power band, both sides
EXCESS_MIN = 1.5  # s2 over the largest singular value of noise alone, sqrt(P) + sqrt(n)
RATIO_MIN = 0.02  # s2 / s1: a model error proportional to the response stays below


def band_rank_statistics(result: xr.Dataset) -> tuple[np.ndarray, np.ndarray]:
    """``(ratio, excess)`` per mode of :func:`ami_xr.core.mimo.band_rank` on ``result`` (the
    output of the pipeline, dims (point, frequency) or (reference, point, frequency): each
    reference on its own, the largest excess kept); NaN where the residual, the residues or
    the noise levels are missing. The noise levels are ``frf_noise_std`` (the refinement's),
    else the subtraction's ``subtraction_noise_floor`` (the same adjacent-line estimate,
    present without the refinement)."""
    n_k = result.sizes.get(names.MODE, 0)
    nan = np.full(n_k, np.nan)
    noise_var = names.FRF_NOISE_STD if names.FRF_NOISE_STD in result else names.SUB_NOISE_FLOOR
    need = (names.FRF_RESIDUAL, names.RESIDUE, names.EIGENVALUE, noise_var)
    if n_k == 0 or any(v not in result for v in need):
        return nan, nan.copy()
    model = resolve_model(result.attrs, "auto")
    omega = 2 * np.pi * np.asarray(result[names.FREQUENCY].values, dtype=float)
    lam = np.asarray(result[names.EIGENVALUE].transpose(names.MODE).values, np.complex128)
    # the data are the windowed FRFs: their poles are the measured ones, before the correction
    lam = lam - float(result.attrs.get(names.ATTR_EXP_CORRECTED, 0.0) or 0.0)
    basis = np.array([pole_basis(omega, lk, model.dt, model.n_samples) for lk in lam])
    use = np.abs(omega[None, :] - lam.imag[:, None]) <= BAND_HALF_WIDTH * np.abs(lam.real)[:, None]
    refs = [None]
    if names.REFERENCE in result[names.FRF_RESIDUAL].dims:
        refs = list(result[names.REFERENCE].values)
    ratio, excess = nan.copy(), nan.copy()
    for r in refs:
        pick = {} if r is None else {names.REFERENCE: r}

        def block(name, *dims, pick=pick):
            da = result[name]
            da = da.sel(pick) if pick and names.REFERENCE in da.dims else da
            return da.transpose(*dims).values

        rr, ee = cm.band_rank(
            block(names.FRF_RESIDUAL, names.POINT, names.FREQUENCY),
            block(noise_var, names.POINT),
            basis,
            block(names.RESIDUE, names.POINT, names.MODE),
            use,
        )
        better = np.isfinite(ee) & ~(ee <= excess)
        ratio = np.where(better, rr, ratio)
        excess = np.where(better, ee, excess)
    return ratio, excess


def suspected(ratio: np.ndarray, excess: np.ndarray) -> np.ndarray:
    """Where the band-rank statistics say two poles (see the module docstring)."""
    with np.errstate(invalid="ignore"):
        return (excess > EXCESS_MIN) & (ratio > RATIO_MIN)
