"""The single-reference AMI pipeline: subtract -> isolate -> global_fit [-> refine].

:func:`identify_single` runs the phases on an FRF Dataset with dims (point, frequency) and
returns their outputs with the modes as reported (analysis band, exponential-window correction,
sorted, quality indicators). :func:`ami_xr.identify` calls it for one reference, and
:func:`ami_xr.ami.mimo.identify_multi_reference` on the FRFs of every reference stacked.
"""

from __future__ import annotations

import warnings

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import chunked as ch
from ami_xr.ami import common as c
from ami_xr.ami import repeated as rp
from ami_xr.ami import scale as scale_out
from ami_xr.ami import spikes, whitening
from ami_xr.ami.derive import derived
from ami_xr.ami.global_fit import (
    fit_attrs,
    fit_residues,
    isolation_flags,
    receptance_mode_vectors,
)
from ami_xr.ami.isolate import METHODS as ISOLATE_METHODS
from ami_xr.ami.isolate import (
    Candidates,
    isolate_modes,
    isolate_record,
    isolate_settings,
    isolate_variables,
    warn_isolation,
)
from ami_xr.ami.refine import refine as refine_phase
from ami_xr.ami.resolution import resolution_checked, resolution_widened
from ami_xr.ami.settings import (
    FrfAttributes,
    GlobalFitSettings,
    IdentifySettings,
    IsolateSettings,
    SubtractSettings,
    from_attrs,
)
from ami_xr.ami.subtract import (
    add_capped,
    band_and_lines,
    power_of_two_scale,
    subtract_arrays,
    subtract_settings,
)
from ami_xr.caller import warn
from ami_xr.core import flags
from ami_xr.core.modal import (
    damping_ratio,
    mpc,
    mpd,
    natural_frequency,
    phase_normalised,
)
from ami_xr.core.model import resolve_model
from ami_xr.dsp import band as bd
from ami_xr.errors import (
    AssumptionWarning,
    CapWarning,
    ConvergenceWarning,
    IdentificationError,
)
from ami_xr.progress import phases
from ami_xr.provenance import nested_calls

METHODS = (*ISOLATE_METHODS, names.METHOD_PAPER)


def check_settings(settings: IdentifySettings) -> None:
    """The choices of :func:`ami_xr.identify` that no phase checks on its own."""
    c.check_choice(settings.method, "method", METHODS)
    if settings.refine is not None and not isinstance(settings.refine, bool):
        raise IdentificationError(f"refine: expected True, False or None, got {settings.refine!r}")


def refines(settings: IdentifySettings) -> bool:
    """Whether the pipeline ends with the refinement (by default unless ``method="paper"``)."""
    if settings.refine is None:
        return settings.method != names.METHOD_PAPER
    return settings.refine


def identify_single(
    ds: xr.Dataset, settings: IdentifySettings, progress=False, final: bool = True
) -> xr.Dataset:
    """The phases on the FRF Dataset ``ds`` (dims (point, frequency)) with ``settings``; see
    :func:`ami_xr.identify` for what is returned (its provenance record is the caller's).
    ``final=False``: a result the caller goes on with (no mode dropped beyond the lines)."""
    check_settings(settings)
    whole = ds
    # the band first, then the checks on the lines analysed: a NaN line outside the band (frf's
    # Nyquist line of a clean pulse) does not refuse the file
    try:  # the band's record goes into the output's attributes (no copy of ``ds`` for it)
        ds, noted = band_and_lines(ds, settings.fmin, settings.fmax, "identify")
    except Exception:
        c.check_frf(ds, "identify")  # a malformed Dataset: the data model's own message
        raise
    ds = c.check_frf(ds, "identify")
    refined = refines(settings)
    # the noise model: fit in the quantity where the noise is closest to white (ami/whitening)
    white = whitening.decide(ds)
    given = ds
    if white.k or white.line_noise is not None:
        ds = whitening.to_working(ds, white)  # a new Dataset, with the noise model's attrs
    else:  # fitted as given: its attributes, like the band's, go into the output's
        noted = {**noted, **white.attrs}
    # one power of two for all FRFs (the isolation and the global fit combine them)
    peak = np.abs(ds[names.FRF]).max(skipna=False).values
    scale = float(power_of_two_scale(peak))
    work = ds if scale == 1.0 else ds.assign({names.FRF: ds[names.FRF] * scale})
    with nested_calls():  # the phases are identify's, which records itself
        how = scale_out.uses_compression(work, settings)  # many points: poles on virtual FRFs
        if how is None:
            result = _phases(work, settings, refined, progress, noted)
        else:
            work = work.assign_attrs(noted)  # the virtual FRFs' phases take them from work
            result = scale_out.identify_compressed(work, settings, refined, progress, _phases, how)
    if scale != 1.0:
        result = unscale(result, ds, scale)
    noise_model = None
    if white.k:
        result = whitening.from_working(result, given, white)
    else:  # fitted as given: the noise model's variables go into the one output build
        noise_model = whitening.noise_model_back(result, given, white)
        result.attrs = {**result.attrs, **white.attrs}  # (a new dict: no alias is changed)
    result = repeated_flagged(result)
    result = window_corrected(result, from_attrs(FrfAttributes, ds.attrs))
    # sorted, under_resolved flagged (damping std widened), quality indicators: one build
    result = reported(result, whole, refined, noise_model)
    if final:  # per-mode selections: the indicators of the modes kept are theirs
        result = drop_beyond_lines(result, whole)
        result = spikes.drop_noise_spikes(result)
    return result


def model_order(settings: IdentifySettings) -> dict:
    """:func:`refine_phase`'s model-order arguments for ``settings``: none (the default step),
    or with ``complete=False`` the maximum-likelihood fit of AMI's modes only (no mode added,
    dropped or merged)."""
    return {} if settings.complete else dict(add_modes=0, drop_modes=False)


def _phases(
    work: xr.Dataset, settings: IdentifySettings, refined: bool, progress, noted=None
) -> xr.Dataset:
    """subtract -> isolate -> global_fit [-> refine] on ``work`` (with the attributes
    ``noted`` added to its own), with a progress bar."""
    s = settings
    steps = [names.PHASE_SUBTRACT, names.PHASE_ISOLATE, names.PHASE_GLOBAL_FIT]
    steps += [names.PHASE_REFINE] if refined else []
    label = f"identify: {work.sizes.get(names.POINT, 0)} FRFs x {work.sizes[names.FREQUENCY]} lines"
    with (
        phases(progress, label, steps) as step,
        warnings.catch_warnings(record=True) as said,
        c.frf_checked(work),  # identify validated it (or built it from validated FRFs)
    ):
        warnings.simplefilter("always")  # held until the refinement says whether caps mattered
        out = fitted(work, s, step, noted)
        if refined and out.sizes.get(names.MODE, 0) > 0:
            step(names.PHASE_REFINE)
            out = refine_phase(out, **model_order(s))
    dropped = _caps_superseded(out, refined)
    if _isolation_superseded(out, refined):
        dropped |= flags.RunStatus.ISOLATE_MAX_ITER
    for w in said:  # a cap's warning is told apart by its status bits, not by its text
        if not (isinstance(w.message, CapWarning) and w.message.status & dropped):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
    return out


def fitted(work: xr.Dataset, settings: IdentifySettings, step, noted=None) -> xr.Dataset:
    """subtract -> isolate -> global_fit on the arrays of ``work`` (validated by the caller):
    each phase's core on the FRFs and the fit record the one before left, the same calls as
    the public phases make; the labeled outputs of all three in one Dataset, built once at the
    end (the global fit's from :func:`~ami_xr.ami.derive.derived`). ``step(phase)`` is told
    when each phase starts; ``noted``: attributes taken as ``work``'s own."""
    s = settings
    given = {**work.attrs, **(noted or {})}
    paper = s.method == names.METHOD_PAPER
    coord_attrs = c.coordinate_attrs(work)
    step(names.PHASE_SUBTRACT)
    frf = work[names.FRF]
    sub_settings = subtract_settings(
        s.delta,
        s.max_modes,
        s.pfa,
        SubtractSettings.min_points,
        s.zeta_max,
        SubtractSettings.merge_tol,
        names.MODEL_CONTINUOUS if paper else "auto",
    )
    c.check_values(work)
    sub = subtract_arrays(frf, given, sub_settings)
    attrs = {**given, **sub.attrs}
    step(names.PHASE_ISOLATE)
    iso_settings = isolate_settings(
        s.tol,
        s.max_iter,
        names.METHOD_PER_FRF if paper else s.method,
        names.WEIGHTING_MEAN if paper else IsolateSettings.weighting,
    )
    cand = Candidates(
        lam=sub.variables[names.SUB_EIGENVALUE].values,
        res=sub.variables[names.SUB_RESIDUE].values,
        n_modes=sub.result.n_modes,
        sigma=np.asarray(sub.result.sigma, dtype=float),
    )
    omega = c.omega_of(work)
    model = resolve_model(attrs, "auto")
    iso = isolate_modes(frf, cand, omega, model, sub.settings, iso_settings)
    isolate_record(iso, attrs, iso_settings, ch.is_lazy(frf))
    warn_isolation(iso, np.asarray(work[names.POINT].values), iso_settings)
    fit = None
    if iso.n_modes > 0:
        step(names.PHASE_GLOBAL_FIT)
        if not isinstance(s.band, str):
            c.check_positive(s.band, "band")
        fit_settings = GlobalFitSettings(
            s.band if isinstance(s.band, str) else float(s.band), bool(s.residual_terms)
        )
        lam = np.ascontiguousarray(iso.eig, dtype=np.complex128)
        mask = isolation_flags(iso.detected, iso.converged, iso.n_modes)
        fit, band_used = fit_residues(frf, attrs, lam, cand.sigma, mask, fit_settings, s.band)
        fit_attrs(attrs, fit_settings, band_used)
    return _labeled(work, (sub.variables, isolate_variables(iso)), attrs, fit, coord_attrs)


def _labeled(work: xr.Dataset, phases, attrs: dict, fit, coord_attrs) -> xr.Dataset:
    """``work`` (earlier results dropped) with the output variables of the phases (dicts by
    name, the dim coordinates among them), ``attrs``, and the outputs of the global ``fit``
    (:class:`~ami_xr.ami.derive.ResidueFit`, None: no mode)."""
    earlier = [v for g in (c.SUBTRACT_VARS, c.ISOLATE_VARS, c.GLOBAL_VARS) for v in g]
    if any(v in work.variables for v in earlier):
        work = c.drop_results(work, (c.SUBTRACT_VARS, c.ISOLATE_VARS, c.GLOBAL_VARS))
    new = {k: v for phase in phases for k, v in phase.items()}
    coords = {d: new.pop(d) for d in (names.CANDIDATE, names.MODE)}
    out = work.assign_coords(coords).assign(new)
    out.attrs = attrs
    if fit is not None:
        more, fitted = derived(fit, out)
        out = out.assign_coords(more).assign(fitted)
    out = c.restore_coordinate_attrs(out, coord_attrs)
    out.attrs[names.ATTR_AMI_PHASE] = names.PHASE_ISOLATE if fit is None else names.PHASE_GLOBAL_FIT
    return out


def _caps_superseded(out: xr.Dataset, refined: bool) -> flags.RunStatus:
    """Move the subtraction's caps from ``ami_capped`` to ``ami_capped_superseded`` when the
    refinement ran and completed the model by its statistics (it was not stopped by its own
    cap): the residual it leaves shows no further mode, so the candidate cap did not decide the
    mode count. Returns the caps superseded (none: ``RunStatus.NONE``)."""
    caps = flags.run_status(out.attrs)
    hit = caps & flags.SUBTRACT_CAPS
    moot = refined and hit and out.sizes.get(names.MODE, 0) > 0
    if not moot or caps & flags.RunStatus.REFINE_ADD_MODES:
        return flags.RunStatus.NONE
    out.attrs[names.ATTR_AMI_CAPPED] = int(caps & ~flags.SUBTRACT_CAPS)
    flags.add_caps(out.attrs, hit, names.ATTR_AMI_CAPPED_SUPERSEDED)
    return hit


def _isolation_superseded(out: xr.Dataset, refined: bool) -> bool:
    """Whether an isolation that stopped at ``max_iter`` no longer decides the result: the
    refinement ran and converged, re-fitting every mode (it clears ``not_converged`` on each
    mode it moved to its converged estimate). Then ``isolate:max_iter`` goes to
    ``ami_capped_superseded`` (:func:`finish_modes`) and the isolation's warning is not shown."""
    return bool(
        refined
        and names.ISO_CONVERGED in out
        and not np.all(out[names.ISO_CONVERGED].values)
        and int(out.attrs.get(names.ATTR_REFINE_CONVERGED, 0) or 0)
    )


def repeated_flagged(result: xr.Dataset) -> xr.Dataset:
    """``result`` with ``repeated_root_suspected`` set where one reference's band-rank
    statistic sees two poles in a mode's band (:mod:`ami_xr.ami.repeated`; issue 22 item 2),
    so that a SIMO Dataset and a one-reference multi-reference Dataset carry the same flags;
    nothing without quality flags or modes."""
    if names.QUALITY_FLAGS not in result or not result.sizes.get(names.MODE, 0):
        return result
    suspected = rp.suspected(*rp.band_rank_statistics(result))
    if not np.any(suspected):
        return result
    mask = flags.set_where(c.flag_mask(result), names.FLAG_REPEATED_ROOT, suspected)
    result[names.QUALITY_FLAGS] = result[names.QUALITY_FLAGS].copy(data=mask)
    return result


def window_corrected(result: xr.Dataset, data: FrfAttributes) -> xr.Dataset:
    """``result`` with its eigenvalues corrected for the exponential window of the data
    (``lam = lam_measured + beta``), natural frequencies, damping ratios and mode vectors
    following; attr ``exponential_window_corrected`` records beta."""
    beta = float(data.exponential_window_decay)
    if not beta or not result.sizes.get(names.MODE, 0):
        return result
    lam = result[names.EIGENVALUE].values + beta
    result[names.EIGENVALUE] = result[names.EIGENVALUE].copy(data=lam)
    result[names.NATURAL_FREQUENCY] = result[names.NATURAL_FREQUENCY].copy(
        data=natural_frequency(lam)
    )
    result[names.DAMPING_RATIO] = result[names.DAMPING_RATIO].copy(data=damping_ratio(lam))
    if names.RESIDUE in result and names.MODE_VECTOR in result:
        # the one displacement convention of global_fit (residues over lam^k), at the new lam
        res = result[names.RESIDUE].transpose(names.POINT, names.MODE).values
        units = (
            str(result[names.FRF].attrs.get(names.ATTR_UNITS, "")) if names.FRF in result else ""
        )
        phi, phi_attrs = receptance_mode_vectors(
            res, lam, c.drive_index(result), result.attrs, units
        )
        mv = result[names.MODE_VECTOR]
        result[names.MODE_VECTOR] = mv.copy(
            data=phi if mv.dims[0] == names.POINT else phi.T
        ).assign_attrs(phi_attrs)
    result.attrs[names.ATTR_EXP_CORRECTED] = beta
    return result


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


def unscale(result: xr.Dataset, ds: xr.Dataset, scale: float) -> xr.Dataset:
    """Results of the FRF scaled by the power of two ``scale`` back to ``ds`` as given (exact:
    ``scale`` and its square root are powers of two)."""
    result = result.assign({names.FRF: ds[names.FRF]})
    for factor, variables in ((scale, _LINEAR_VARS), (np.sqrt(scale), _SQRT_VARS)):
        for v in variables:
            if v in result:
                # .data, not .values: a lazy output is scaled back per chunk and stays lazy
                result[v] = result[v].copy(data=result[v].data / factor)
    # the refinement's objective sum_j (n_rows / 2) log rss_j, rss ~ scale^2, n_rows = 2 F
    shift = ds.sizes[names.POINT] * 2 * ds.sizes[names.FREQUENCY] * float(np.log(scale))
    for key in (names.ATTR_REFINE_COST_START, names.ATTR_REFINE_COST):
        if key in result.attrs:
            result.attrs[key] = float(result.attrs[key]) - shift
    return result


def with_quality(result: xr.Dataset) -> xr.Dataset:
    """Add the modal quality indicators of the final mode vectors (MPC, MPD, complexity; on
    ``mode``) and the mode vectors normalised in phase and magnitude (largest component 1;
    scale-free, like the indicators); nothing when there are no mode vectors."""
    if names.MODE_VECTOR not in result or result.sizes.get(names.MODE, 0) == 0:
        return result
    return result.assign(quality_variables(result[names.MODE_VECTOR].variable))


def quality_variables(mv: xr.Variable) -> dict:
    """What :func:`with_quality` adds, by name, for the mode vectors ``mv`` (point, mode in
    either order)."""
    phi = mv.transpose(names.POINT, names.MODE).values
    collinearity = mpc(phi)  # complexity is 1 - MPC: one pass over the points for both
    mode = (names.MODE,)
    normalised = xr.Variable(
        (names.POINT, names.MODE),
        phase_normalised(phi, unit=True),
        {
            names.ATTR_UNITS: "1",
            names.ATTR_LONG_NAME: (
                "mode vector rotated in phase and scaled so that its largest component is 1"
            ),
        },
    ).transpose(*mv.dims)
    return {
        names.MPC: xr.Variable(
            mode,
            collinearity,
            {
                names.ATTR_UNITS: "1",
                names.ATTR_LONG_NAME: "modal phase collinearity (1: real mode)",
            },
        ),
        names.MPD: xr.Variable(
            mode,
            mpd(phi),
            {
                names.ATTR_UNITS: "degree",
                names.ATTR_LONG_NAME: "mean phase deviation from the best straight line",
            },
        ),
        names.COMPLEXITY: xr.Variable(
            mode,
            1.0 - collinearity,
            {names.ATTR_UNITS: "1", names.ATTR_LONG_NAME: "mode complexity 1 - MPC (0: real mode)"},
        ),
        names.MODE_VECTOR_NORMALISED: normalised,
    }


def drop_beyond_lines(result: xr.Dataset, whole: xr.Dataset) -> xr.Dataset:
    """The modes as reported: none more than one half-power bandwidth (``2 zeta f_n``) beyond
    the first or the last line of ``whole`` (none of its resonance is in the data: the
    refinement may fit the tail of a mode above the last line; a mode whose peak the edge cuts
    stays). Dropped ones are warned about and listed in ``analysis_band_dropped_modes``; the
    labels stay 1..n. Applied once to the final result (an intermediate result keeps such a
    pole: a later joint fit needs it to model that tail)."""
    if result.sizes.get(names.MODE, 0) == 0 or names.DAMPING_RATIO not in result:
        return result
    lines = np.asarray(whole[names.FREQUENCY].values, dtype=float)
    fn = np.asarray(result[names.NATURAL_FREQUENCY].transpose(names.MODE).values, dtype=float)
    zeta = np.asarray(result[names.DAMPING_RATIO].transpose(names.MODE).values, dtype=float)
    width = 2.0 * np.abs(zeta) * fn
    beyond = (fn - lines[-1] > width) | (lines[0] - fn > width)
    if not beyond.any():
        return result
    out = c.keep_modes(result, ~beyond)
    listed = [x for x in str(result.attrs.get(names.ATTR_BAND_DROPPED, "")).split(",") if x]
    out.attrs[names.ATTR_BAND_DROPPED] = ",".join(listed + [f"{f:.6g}" for f in fn[beyond]])
    warn(
        f"identify: {int(beyond.sum())} mode(s) fitted beyond the measured lines "
        f"{lines[0]:g}-{lines[-1]:g} Hz not reported "
        f"({', '.join(f'{x:.6g}' for x in fn[beyond])} Hz): only the tail of such a mode is in "
        f"the data; attr {names.ATTR_BAND_DROPPED}",
        AssumptionWarning,
    )
    return out


def finish_modes(result: xr.Dataset, whole: xr.Dataset, refined: bool) -> xr.Dataset:
    """The modes as reported: none outside a restricted analysis band, sorted by frequency with
    labels 1..n; caps that ended a phase warned about and listed in attr ``ami_capped``. An
    isolation stopped at ``max_iter`` is listed in ``ami_capped_superseded`` instead when the
    refinement ran and converged (:func:`_isolation_superseded`): it re-fitted every mode."""
    result = c.sort_modes(_in_band(result, whole))
    _capped(result, result.attrs, refined, stacklevel=4)
    return result


def reported(
    result: xr.Dataset, whole: xr.Dataset, refined: bool, noise_model: dict | None = None
) -> xr.Dataset:
    """:func:`finish_modes`, :func:`~ami_xr.ami.resolution.resolution_checked` and
    :func:`with_quality` on ``result`` in one step: the sort order, the flags and widened
    standard deviations of the under-resolved modes and the quality indicators decided on the
    arrays, and the output built once from ``result``'s variables. ``noise_model``: the
    variables of :func:`~ami_xr.ami.whitening.noise_model_back` (they replace the working
    ``frf_line_noise_std``)."""
    result = _in_band(result, whole)
    n = result.sizes.get(names.MODE, 0)
    if not n or names.NATURAL_FREQUENCY not in result:  # nothing to sort (c.sort_modes)
        if noise_model is not None:
            result = result.drop_vars([names.FRF_LINE_NOISE_STD], errors="ignore")
            result = result.assign(noise_model)
        _capped(result, result.attrs, refined, stacklevel=4)
        return with_quality(resolution_checked(result, whole))
    fn = np.asarray(result[names.NATURAL_FREQUENCY].transpose(names.MODE).values, dtype=float)
    order = np.argsort(np.where(np.isfinite(fn), fn, np.inf), kind="stable")
    attrs = dict(result.attrs)
    _capped(result, attrs, refined, stacklevel=4)
    mode_dims = (names.MODE, names.MODE_2)
    if np.array_equal(order, np.arange(n)):  # already sorted: no copy of the (point, mode) data
        variables = {k: v.copy(deep=False) for k, v in result.variables.items()}
    else:
        variables = {
            k: v.isel({d: order for d in mode_dims if d in v.dims})
            for k, v in result.variables.items()
        }
    if noise_model is not None:
        variables.pop(names.FRF_LINE_NOISE_STD, None)
        variables.update({k: xr.as_variable(v, name=k) for k, v in noise_model.items()})
    labels = np.arange(1, n + 1)
    for d in mode_dims:
        if d in result.dims:
            variables[d] = xr.IndexVariable((d,), labels)
    variables[names.MODE_LABEL_UNSORTED] = xr.Variable(
        (names.MODE,),
        np.asarray(result[names.MODE].values)[order],
        {names.ATTR_LONG_NAME: "label of the mode before sorting by natural frequency"},
    )
    if names.DAMPING_RATIO in result and names.QUALITY_FLAGS in result:
        stds = (names.DAMPING_RATIO_STD, names.EIGENVALUE_STD)
        mask, widened = resolution_widened(
            fn[order],
            variables[names.DAMPING_RATIO].transpose(names.MODE).values,
            c.flag_mask(result)[order],
            {v: variables[v].transpose(names.MODE).values for v in stds if v in variables},
            labels,
            whole,
        )
        variables[names.QUALITY_FLAGS] = variables[names.QUALITY_FLAGS].copy(data=mask)
        for v, std in widened.items():
            variables[v] = variables[v].copy(data=std)
    if names.MODE_VECTOR in variables:
        variables.update(quality_variables(variables[names.MODE_VECTOR]))
    coords = {k: variables.pop(k) for k in result.coords}
    return xr.Dataset(variables, coords=coords, attrs=attrs)


def _in_band(result: xr.Dataset, whole: xr.Dataset) -> xr.Dataset:
    """``result`` without the modes outside a restricted analysis band (listed in attr
    ``analysis_band_dropped_modes``); ``result`` itself when the band is ``whole``'s."""
    band = bd.analysis_band(result)
    if not bd.is_whole(whole, band):
        result, dropped = c.drop_outside_band(result, band.fmin, band.fmax)
        result.attrs[names.ATTR_BAND_DROPPED] = ",".join(f"{f:.6g}" for f in dropped)
    return result


def _capped(result: xr.Dataset, attrs: dict, refined: bool, stacklevel: int) -> None:
    """The caps that ended a phase of ``result`` (:func:`finish_modes`), warned about (the
    refinement's; the isolation warned already) and written into ``attrs``."""
    caps = flags.RunStatus.NONE
    if _isolation_superseded(result, refined):  # the converged refinement re-fitted every mode
        flags.add_caps(attrs, flags.RunStatus.ISOLATE_MAX_ITER, names.ATTR_AMI_CAPPED_SUPERSEDED)
    elif names.ISO_CONVERGED in result and not bool(np.all(result[names.ISO_CONVERGED].values)):
        caps |= flags.RunStatus.ISOLATE_MAX_ITER  # isolate warned already
    if refined and names.ATTR_REFINE_CONVERGED in attrs:
        if not int(attrs[names.ATTR_REFINE_CONVERGED]):
            caps |= flags.RunStatus.REFINE_MAX_ITER
            warnings.warn(
                "identify: the refinement stopped at its iteration cap before converging "
                f"({attrs.get(names.ATTR_REFINE_ITERATIONS, '?')} iterations in all; "
                f"attr {names.ATTR_REFINE_CONVERGED}=0; modes still moving carry "
                f"{names.FLAG_REFINE_NOT_CONVERGED})",
                ConvergenceWarning,
                stacklevel=stacklevel,
            )
    add_capped(attrs, caps)
