"""All AMI phases in a row: subtract -> isolate -> global_fit [-> refine].

:func:`identify` gathers its settings into one :class:`~ami_xr.ami.settings.IdentifySettings`
record and hands it to the single-reference pipeline (:mod:`ami_xr.ami.pipeline`) or, for FRFs
with a ``reference`` dim, to the multi-reference one (:mod:`ami_xr.ami.mimo`).
"""

from __future__ import annotations

import dataclasses

import xarray as xr

from ami_xr.ami import common as c
from ami_xr.ami import mimo
from ami_xr.ami.pipeline import METHODS, identify_single, refines
from ami_xr.ami.settings import (
    GlobalFitSettings,
    IdentifySettings,
    IsolateSettings,
    SubtractSettings,
)
from ami_xr.core.threads import single_blas_thread
from ami_xr.errors import IdentificationError
from ami_xr.provenance import public_call

__all__ = ["identify", "METHODS"]


@public_call
def identify(
    ds: xr.Dataset,
    *,
    method: str = IsolateSettings.method,
    refine: bool | None = None,
    delta: float = SubtractSettings.delta,
    tol: float = IsolateSettings.tol,
    max_iter: int = IsolateSettings.max_iter,
    band: float | str = GlobalFitSettings.band,
    residual_terms: bool = GlobalFitSettings.residual_terms,
    pfa: float = SubtractSettings.pfa,
    max_modes: int = SubtractSettings.max_modes,
    zeta_max: float = SubtractSettings.zeta_max,
    fmin: float | None = None,
    fmax: float | None = None,
    compress: str | int = "auto",
    complete: bool = True,
    noise_std=None,
    progress=False,
) -> xr.Dataset:
    """Identify modes: :func:`subtract`, :func:`isolate`, :func:`global_fit` and, by default,
    the maximum-likelihood refinement :func:`ami_xr.ami.refine.refine`.

    Parameters
    ----------
    ds : xarray.Dataset
        FRF Dataset.
    method : {"simo", "per_frf", "paper"}
        "paper" reproduces the paper's AMI exactly: per-FRF isolation, plain mean, eq. 9 over
        bands, continuous eq. 4 basis, no refinement. "per_frf" and "simo" use the exact
        discrete basis for impulse-response FRFs, SNR weighting, and refine by default.
    refine : bool, optional
        Run the joint refinement (default: when available and ``method != "paper"``).
    delta, pfa, max_modes, zeta_max :
        See :func:`ami_xr.subtract`. Raise ``zeta_max`` for heavily damped structures (the
        zero-modes warning says when the peaks were significant but no fit was accepted).
    tol, max_iter :
        See :func:`ami_xr.isolate`.
    band, residual_terms :
        See :func:`ami_xr.global_fit`.
    fmin, fmax : float, optional
        Analysis band in Hz (each overrides its limit). By default, for an FRF estimated by
        :func:`ami_xr.frf`/:func:`ami_xr.impact_frf` (``force_autospectrum``, ``coherence``),
        the band where the excitation is valid (:mod:`ami_xr.dsp.band`: force within 20 dB of
        its maximum -- 40 dB below that band where the coherence holds --, coherence good for
        a 29 % random error of |H1| on most lines), announced in an
        ``AssumptionWarning``; otherwise every line. Only the band is analysed (the output
        holds its lines), no mode outside it is reported (dropped ones: attr
        ``analysis_band_dropped_modes``), and attrs ``analysis_band_*`` record it.
    compress : "auto", "off" or int, default "auto"
        Many points: the eigenvalues from a few virtual FRFs, then every point's residues
        (:mod:`ami_xr.ami.scale`, :mod:`ami_xr.core.compress`): "auto" to 48 virtual FRFs
        above 192 points, an int ``r`` to ``r``, "off" never.
    complete : bool, default True
        The refinement's model-order step (:mod:`ami_xr.core.order`: add, drop or merge modes
        when the likelihood gain beats noise and a measured peak's model error). False: the
        maximum-likelihood fit of AMI's modes as they are.
    noise_std : xarray.DataArray or array_like, optional
        Your noise std per line, broadcastable to ``frf`` (:mod:`ami_xr.ami.whitening`).
    progress : bool or callable, default False
        True draws a bar of the phases on stderr (tqdm when installed, a plain line otherwise)
        with the counts inside the running phase; a callable is called as ``progress(phase,
        done, total)`` when each phase starts and ``progress("done", total, total)`` at the
        end, one with a ``detail(text)`` method also gets the counts (:mod:`ami_xr.progress`).
        Never changes the results.

    Returns
    -------
    xarray.Dataset
        The outputs of all phases. When the input has ``exponential_window_decay`` (beta, 1/s),
        the identified eigenvalues are corrected ``lam = lam_measured + beta`` (the window
        multiplies the impulse response by ``exp(-beta t)``); natural frequency, damping ratio
        and mode vectors follow, and attr ``exponential_window_corrected`` records beta.
        Quality indicators of the final mode vectors, on ``mode``: ``mpc`` (modal phase
        collinearity, 1 for a real mode), ``mpd`` (mean phase deviation, degrees), and
        ``complexity`` (1 - MPC), see :func:`ami_xr.core.modal.mpc`; and
        ``mode_vector_normalised``, the mode vectors rotated and scaled so that each one's
        largest component is 1 (real and positive; dimensionless, for display and comparison
        of shapes); ``mode_vector`` itself keeps the phase and scaling of eq. 8.

    Notes
    -----
    FRFs of any representable magnitude are identified: when the largest ``|frf|`` lies outside
    ``2^-250 .. 2^250`` (e.g. an FRF scaled by 1e-300, whose squares underflow), the phases run
    on the FRF scaled by a power of two and the results are scaled back, exactly, so they equal
    those of the FRF in ordinary units times the scale. Within that range nothing is scaled.
    """
    if not isinstance(complete, bool):
        raise IdentificationError(f"complete: expected True or False, got {complete!r}")
    settings = IdentifySettings(
        method=method,
        refine=refine,
        delta=delta,
        tol=tol,
        max_iter=max_iter,
        band=band,
        residual_terms=residual_terms,
        pfa=pfa,
        max_modes=max_modes,
        zeta_max=zeta_max,
        fmin=fmin,
        fmax=fmax,
        compress=compress,
        complete=complete,
    )
    if noise_std is not None:
        ds = with_noise_std(ds, noise_std)
    # small products only: one BLAS thread, which does not collapse when the cores are busy
    with single_blas_thread():
        if mimo.is_multi_reference(ds):  # dims (reference, point, frequency)
            result = mimo.identify_multi_reference(ds, settings, progress)
        else:
            result = identify_single(ds, settings, progress)
    params = dict(
        dataclasses.asdict(settings),
        refine=refines(settings),
        residual_terms=bool(residual_terms),
    )
    return c.finish(result, "ami_xr.identify", "identify", params)


def with_noise_std(ds: xr.Dataset, noise_std) -> xr.Dataset:
    """``ds`` with the user's noise model ``noise_std`` as ``frf_line_noise_std`` (the dims of
    ``frf``); an :class:`IdentificationError` naming ``noise_std`` when it does not broadcast to
    ``frf`` or holds values that are not finite and >= 0, or is 0 everywhere."""
    import numpy as np

    from ami_xr import names

    if not isinstance(ds, xr.Dataset) or names.FRF not in ds:
        return ds  # identify's own checks name what is wrong with ds
    h = ds[names.FRF]
    try:
        if isinstance(noise_std, xr.DataArray):
            sd = noise_std.broadcast_like(h).transpose(*h.dims).values
        else:
            sd = np.broadcast_to(np.asarray(noise_std, dtype=np.float64), h.shape)
        sd = np.asarray(sd, dtype=np.float64)
    except (ValueError, TypeError) as exc:
        raise IdentificationError(
            f"noise_std: expected a noise std per line broadcastable to frf {dict(h.sizes)}, "
            f"got {getattr(noise_std, 'shape', type(noise_std).__name__)} ({exc})"
        ) from None
    if sd.shape != h.shape or not np.all(np.isfinite(sd)) or np.any(sd < 0) or not sd.any():
        raise IdentificationError(
            f"noise_std: expected finite values >= 0, not all 0, of the shape of frf "
            f"{dict(h.sizes)}; got shape {sd.shape}"
        )
    attrs = {names.ATTR_NOISE_MODEL: "given by the user (identify noise_std=)"}
    if names.ATTR_UNITS in h.attrs:
        attrs[names.ATTR_UNITS] = h.attrs[names.ATTR_UNITS]
    return ds.assign({names.FRF_LINE_NOISE_STD: (h.dims, sd, attrs)})
