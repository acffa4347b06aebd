"""All AMI phases in a row: subtract -> isolate -> global_fit [-> refine]."""

from __future__ import annotations

import warnings

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import common as c
from ami_xr.ami.global_fit import global_fit
from ami_xr.ami.isolate import METHODS as ISOLATE_METHODS
from ami_xr.ami.isolate import isolate
from ami_xr.ami.settings import GlobalFitSettings, IsolateSettings, SubtractSettings
from ami_xr.ami.subtract import add_capped, band_of, power_of_two_scale, subtract
from ami_xr.core.modal import (
    complexity,
    damping_ratio,
    mode_vectors,
    mpc,
    mpd,
    natural_frequency,
    phase_normalised,
)
from ami_xr.dsp import band as bd
from ami_xr.errors import ConvergenceWarning, IdentificationError
from ami_xr.progress import phases

METHODS = (*ISOLATE_METHODS, names.METHOD_PAPER)


def _is_multi_reference(ds) -> bool:
    return isinstance(ds, xr.Dataset) and names.FRF in ds and names.REFERENCE in ds[names.FRF].dims


def _refine_function():
    try:
        from ami_xr.ami.refine import refine as fn
    except ImportError:
        return None
    return fn


# Outputs in FRF units (scale with the FRF) and those that scale with its square root (mode
# vectors: Phi_j Phi_P = A_jP / lam). Everything else (eigenvalues, frequencies, damping ratios,
# SNRs, MAC, counts, flags) is scale-free.
_LINEAR_VARS = (
    names.SUB_RESIDUE,
    names.SUB_NOISE_FLOOR,
    names.RESIDUE,
    names.RESIDUE_STD,
    names.FRF_SYNTHESIZED,
    names.FRF_RESIDUAL,
    names.FRF_NOISE_STD,
    names.RESIDUAL_COEFFICIENT,
    names.AMI_PREFIX + names.RESIDUE,
)
_SQRT_VARS = (names.MODE_VECTOR, names.MODE_VECTOR_STD, names.AMI_PREFIX + names.MODE_VECTOR)


def _unscale(result: xr.Dataset, ds: xr.Dataset, scale: float) -> xr.Dataset:
    """Results of the FRF scaled by the power of two ``scale`` back to ``ds`` as given (exact:
    ``scale`` and its square root are powers of two)."""
    result = result.assign({names.FRF: ds[names.FRF]})
    for factor, variables in ((scale, _LINEAR_VARS), (np.sqrt(scale), _SQRT_VARS)):
        for v in variables:
            if v in result:
                result[v] = result[v].copy(data=result[v].values / factor)
    # the refinement's objective sum_j (n_rows / 2) log rss_j, rss ~ scale^2, n_rows = 2 F
    shift = ds.sizes[names.POINT] * 2 * ds.sizes[names.FREQUENCY] * float(np.log(scale))
    for key in (names.ATTR_REFINE_COST_START, names.ATTR_REFINE_COST):
        if key in result.attrs:
            result.attrs[key] = float(result.attrs[key]) - shift
    return result


def _with_quality(result: xr.Dataset) -> xr.Dataset:
    """Add the modal quality indicators of the final mode vectors (MPC, MPD, complexity; on
    ``mode``) and the mode vectors normalised in phase and magnitude (largest component 1;
    scale-free, like the indicators); nothing when there are no mode vectors."""
    if names.MODE_VECTOR not in result or result.sizes.get(names.MODE, 0) == 0:
        return result
    mv = result[names.MODE_VECTOR]
    phi = mv.transpose(names.POINT, names.MODE).values
    mode = [names.MODE]
    normalised = xr.DataArray(
        phase_normalised(phi, unit=True), dims=(names.POINT, names.MODE)
    ).transpose(*mv.dims)
    normalised.attrs[names.ATTR_UNITS] = "1"
    normalised.attrs[names.ATTR_LONG_NAME] = (
        "mode vector rotated in phase and scaled so that its largest component is 1"
    )
    return result.assign(
        {
            names.MPC: (
                mode,
                mpc(phi),
                {
                    names.ATTR_UNITS: "1",
                    names.ATTR_LONG_NAME: "modal phase collinearity (1: real mode)",
                },
            ),
            names.MPD: (
                mode,
                mpd(phi),
                {
                    names.ATTR_UNITS: "degree",
                    names.ATTR_LONG_NAME: "mean phase deviation from the best straight line",
                },
            ),
            names.COMPLEXITY: (
                mode,
                complexity(phi),
                {
                    names.ATTR_UNITS: "1",
                    names.ATTR_LONG_NAME: "mode complexity 1 - MPC (0: real mode)",
                },
            ),
            names.MODE_VECTOR_NORMALISED: normalised,
        }
    )


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
        its low-frequency level, coherence >= 0.8 on most lines), announced in an
        ``AssumptionWarning``; otherwise every line. Only the band is analysed (the output
        holds its lines), no mode outside it is reported (dropped ones: attr
        ``analysis_band_dropped_modes``), and attrs ``analysis_band_*`` record it.
    progress : bool or callable, default False
        True draws a bar of the phases (subtract, isolate, global_fit, refine) on stderr,
        labelled with the numbers of FRFs and lines, its elapsed time moving during a long phase
        (tqdm when installed, a plain line otherwise), and the counts inside the running phase:
        FRFs done by the subtraction and the per-FRF isolation, the refinement's stage, modes
        and iterations. A callable is called as ``progress(phase, done, total)`` when each phase
        starts (``done`` phases finished) and ``progress("done", total, total)`` at the end; one
        with a ``detail(text)`` method also gets those counts (see :mod:`ami_xr.progress`).
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
    if _is_multi_reference(ds):  # dims (reference, point, frequency): ami_xr.ami.mimo
        from ami_xr.ami.mimo import identify_multi_reference

        return identify_multi_reference(
            ds,
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
            progress=progress,
        )
    c.check_frf(ds, "identify")
    c.check_choice(method, "method", METHODS)
    if refine is not None and not isinstance(refine, bool):
        raise IdentificationError(f"refine: expected True, False or None, got {refine!r}")
    whole = ds
    ds = band_of(ds, fmin, fmax, "identify")
    paper = method == names.METHOD_PAPER
    fn = None
    if refine or (refine is None and not paper):
        fn = _refine_function()
        if fn is None and refine:
            raise IdentificationError("refine: ami_xr.ami.refine is not available")
    model = names.MODEL_CONTINUOUS if paper else "auto"
    # one power of two for all FRFs (the isolation and the global fit combine them)
    peak = np.abs(ds[names.FRF]).max(skipna=False).values
    scale = float(power_of_two_scale(peak))
    work = ds if scale == 1.0 else ds.assign({names.FRF: ds[names.FRF] * scale})
    steps = [names.PHASE_SUBTRACT, names.PHASE_ISOLATE, names.PHASE_GLOBAL_FIT]
    steps += [names.PHASE_REFINE] if fn is not None else []
    label = f"identify: {ds.sizes.get(names.POINT, 0)} FRFs x {ds.sizes[names.FREQUENCY]} lines"
    with phases(progress, label, steps) as step:
        step(names.PHASE_SUBTRACT)
        out = subtract(work, delta, pfa=pfa, max_modes=max_modes, model=model, zeta_max=zeta_max)
        step(names.PHASE_ISOLATE)
        out = isolate(
            out,
            tol,
            max_iter,
            method=names.METHOD_PER_FRF if paper else method,
            weighting=names.WEIGHTING_MEAN if paper else IsolateSettings.weighting,
        )
        if out.sizes.get(names.MODE, 0) == 0:
            result = out
        else:
            step(names.PHASE_GLOBAL_FIT)
            out = global_fit(out, band=band, residual_terms=residual_terms)
            if fn is not None:
                step(names.PHASE_REFINE)
                out = fn(out)
            result = out
    if scale != 1.0:
        result = _unscale(result, ds, scale)
    beta = float(ds.attrs.get(names.ATTR_EXP_DECAY, 0.0) or 0.0)
    if beta and result.sizes.get(names.MODE, 0):
        lam = result[names.EIGENVALUE].values + beta
        result[names.EIGENVALUE] = result[names.EIGENVALUE].copy(data=lam)
        result[names.NATURAL_FREQUENCY] = result[names.NATURAL_FREQUENCY].copy(
            data=natural_frequency(lam)
        )
        result[names.DAMPING_RATIO] = result[names.DAMPING_RATIO].copy(data=damping_ratio(lam))
        if names.RESIDUE in result:
            res = result[names.RESIDUE].transpose(names.POINT, names.MODE).values
            phi = mode_vectors(res, lam, c.drive_index(result))
            result[names.MODE_VECTOR] = result[names.MODE_VECTOR].copy(
                data=phi if result[names.MODE_VECTOR].dims[0] == names.POINT else phi.T
            )
        result.attrs[names.ATTR_EXP_CORRECTED] = beta
    result = _finish_modes(result, whole, refined=fn is not None)
    result = _with_quality(result)
    params = dict(
        method=method,
        refine=fn is not None,
        delta=delta,
        tol=tol,
        max_iter=max_iter,
        band=band,
        residual_terms=bool(residual_terms),
        pfa=pfa,
        max_modes=max_modes,
        zeta_max=zeta_max,
        fmin=fmin,
        fmax=fmax,
    )
    return c.finish(result, "ami_xr.identify", "identify", params)


def _finish_modes(result: xr.Dataset, whole: xr.Dataset, refined: bool) -> xr.Dataset:
    """The modes as reported: none outside a restricted analysis band, superseded flags
    cleared, sorted by frequency with labels 1..n; caps that ended a phase warned about and
    listed in attr ``ami_capped``."""
    band = bd.analysis_band(result)
    if not bd.is_whole(whole, band):
        result, dropped = c.drop_outside_band(result, band.fmin, band.fmax)
        result.attrs[names.ATTR_BAND_DROPPED] = ",".join(f"{f:.6g}" for f in dropped)
    if refined:
        beta = float(result.attrs.get(names.ATTR_EXP_CORRECTED, 0.0) or 0.0)
        result = c.clear_superseded_flags(result, beta)
    result = c.sort_modes(result)
    caps = []
    if names.ISO_CONVERGED in result and not bool(np.all(result[names.ISO_CONVERGED].values)):
        caps.append("isolate:max_iter")  # isolate warned already
    if refined and names.ATTR_REFINE_CONVERGED in result.attrs:
        if not int(result.attrs[names.ATTR_REFINE_CONVERGED]):
            caps.append("refine:max_iter")
            warnings.warn(
                "identify: the refinement stopped at its iteration cap before converging "
                f"({result.attrs.get(names.ATTR_REFINE_ITERATIONS, '?')} iterations in all; "
                f"attr {names.ATTR_REFINE_CONVERGED}=0; modes still moving carry "
                f"{names.FLAG_REFINE_NOT_CONVERGED})",
                ConvergenceWarning,
                stacklevel=3,
            )
    add_capped(result.attrs, caps)
    return result
