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
from ami_xr.ami.derive import derived_from, quality_variables
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
from ami_xr.ami.line_noise import colour_shape
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
    natural_frequency,
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
    result, noise_model = given_back(result, ds, scale, given, white)
    # repeated roots and the window's correction decided, sorted, under_resolved flagged (damping
    # std widened), quality indicators: one build
    window = from_attrs(FrfAttributes, ds.attrs)
    result = reported(result, whole, refined, noise_model, window=window, repeated=True)
    if final:  # per-mode selections: the indicators of the modes kept are theirs
        result = drop_beyond_lines(result, whole)
        result = spikes.drop_noise_spikes(result, settings.zeta_max)
    return result


def model_order(settings: IdentifySettings) -> dict:
    """:func:`refine_phase`'s model-order arguments for ``settings``: none (the default step),
    or with ``complete=False`` the maximum-likelihood fit of AMI's modes only (no mode added,
    dropped or merged)."""
    return {} if settings.complete else dict(add_modes=0, drop_modes=False)


def given_back(result: xr.Dataset, ds: xr.Dataset, scale: float, given: xr.Dataset, white):
    """The results of the phases on the working FRFs (``ds`` scaled by the power of two
    ``scale``, in the quantity of the noise model ``white``) back in the quantity of ``given``,
    and the noise model's variables for :func:`reported` (None when :mod:`whitening` took the
    results back itself: a fit in another quantity)."""
    if scale != 1.0:
        result = unscale(result, ds, scale)
    if white.k:
        return whitening.from_working(result, given, white), None
    # fitted as given: the noise model's variables go into the one output build
    noise_model = whitening.noise_model_back(result, given, white)
    result.attrs = {**result.attrs, **white.attrs}  # (a new dict: no alias is changed)
    return result, noise_model


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
    end (the global fit's from :func:`~ami_xr.ami.derive.derived_from`). ``step(phase)`` is told
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
    # peaks chosen and stopped against each line's noise (the model the refinement weights by)
    sub = subtract_arrays(frf, given, sub_settings, colour_shape(work, frf))
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
    (:class:`~ami_xr.ami.derive.ResidueFit`, None: no mode): one Dataset, built once."""
    earlier = {v for g in (c.SUBTRACT_VARS, c.ISOLATE_VARS, c.GLOBAL_VARS) for v in g}
    variables = {k: v for k, v in work.variables.items() if k not in earlier}
    for dim in (names.CANDIDATE, names.MODE, names.MODE_2, names.RESIDUAL_TERM):
        if dim in variables and not any(dim in v.dims for k, v in variables.items() if k != dim):
            del variables[dim]  # a label of earlier results only
    coords = {k for k in work.coords if k in variables} | {names.CANDIDATE, names.MODE}
    for phase in phases:
        variables.update(phase)
    attrs = dict(attrs)
    if fit is not None:
        modes = np.asarray(variables[names.MODE].values)
        more, fitted = derived_from(
            fit, work[names.FRF], attrs, c.omega_of(work), modes, work[names.POINT].values
        )
        variables.update(more)
        variables.update(fitted)
        coords |= set(more)
    for n, a in coord_attrs.items():  # what an apply_ufunc of old xarray cleared
        if n in variables and variables[n].attrs != a:
            variables[n] = variables[n].copy(deep=False)
            variables[n].attrs = dict(a)
    attrs[names.ATTR_AMI_PHASE] = names.PHASE_ISOLATE if fit is None else names.PHASE_GLOBAL_FIT
    return c.built(variables, coords, attrs, like=work)


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
    ``ami_capped_superseded`` (:func:`_capped`) and the isolation's warning is not shown."""
    return _superseded(_converged(out.variables), out.attrs, refined)


def _converged(variables) -> np.ndarray | None:
    """The isolation's ``converged`` per mode among ``variables`` (None when it is not)."""
    v = variables.get(names.ISO_CONVERGED)
    return None if v is None else np.asarray(v.values)


def _superseded(converged: np.ndarray | None, attrs: dict, refined: bool) -> bool:
    """:func:`_isolation_superseded` on the isolation's ``converged`` and the attributes."""
    return bool(
        refined
        and converged is not None
        and not np.all(converged)
        and int(attrs.get(names.ATTR_REFINE_CONVERGED, 0) or 0)
    )


def _repeated_variables(result: xr.Dataset) -> dict:
    """``quality_flags`` with ``repeated_root_suspected`` set where one reference's band-rank
    statistic sees two poles in a mode's band (:mod:`ami_xr.ami.repeated`; issue 22 item 2),
    so that a SIMO Dataset and a one-reference multi-reference Dataset carry the same flags;
    nothing (an empty dict) without quality flags, modes or a suspected mode."""
    if names.QUALITY_FLAGS not in result or not result.sizes.get(names.MODE, 0):
        return {}
    suspected = rp.suspected(*rp.band_rank_statistics(result))
    if not np.any(suspected):
        return {}
    mask = flags.set_where(c.flag_mask(result), names.FLAG_REPEATED_ROOT, suspected)
    return {names.QUALITY_FLAGS: result[names.QUALITY_FLAGS].variable.copy(data=mask)}


def _window_variables(result: xr.Dataset, data: FrfAttributes) -> tuple[dict, dict]:
    """The eigenvalues of ``result`` corrected for the exponential window of the data
    (``lam = lam_measured + beta``), natural frequencies, damping ratios and mode vectors
    following, by name, and the attribute ``exponential_window_corrected`` (beta); nothing
    without a window or modes."""
    beta = float(data.exponential_window_decay)
    if not beta or not result.sizes.get(names.MODE, 0):
        return {}, {}
    lam = result[names.EIGENVALUE].values + beta
    new = {
        names.EIGENVALUE: result[names.EIGENVALUE].variable.copy(data=lam),
        names.NATURAL_FREQUENCY: result[names.NATURAL_FREQUENCY].variable.copy(
            data=natural_frequency(lam)
        ),
        names.DAMPING_RATIO: result[names.DAMPING_RATIO].variable.copy(data=damping_ratio(lam)),
    }
    if names.RESIDUE in result and names.MODE_VECTOR in result:
        # the one displacement convention of global_fit (residues over lam^k), at the new lam
        res = result[names.RESIDUE].transpose(names.POINT, names.MODE).values
        units = (
            str(result[names.FRF].attrs.get(names.ATTR_UNITS, "")) if names.FRF in result else ""
        )
        phi, phi_attrs = receptance_mode_vectors(
            res, lam, c.drive_index(result), result.attrs, units
        )
        mv = result[names.MODE_VECTOR].variable
        mv = mv.copy(data=phi if mv.dims[0] == names.POINT else phi.T)
        mv.attrs = {**mv.attrs, **phi_attrs}
        new[names.MODE_VECTOR] = mv
    return new, {names.ATTR_EXP_CORRECTED: beta}


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
    variables = dict(result.variables)
    variables[names.FRF] = ds[names.FRF].variable
    for factor, scaled in ((scale, _LINEAR_VARS), (np.sqrt(scale), _SQRT_VARS)):
        for v in scaled:
            if v in variables:
                # .data, not .values: a lazy output is scaled back per chunk and stays lazy
                variables[v] = variables[v].copy(data=variables[v].data / factor)
    # the refinement's objective sum_j (n_rows / 2) log rss_j, rss ~ scale^2, n_rows = 2 F
    shift = ds.sizes[names.POINT] * 2 * ds.sizes[names.FREQUENCY] * float(np.log(scale))
    attrs = dict(result.attrs)
    for key in (names.ATTR_REFINE_COST_START, names.ATTR_REFINE_COST):
        if key in attrs:
            attrs[key] = float(attrs[key]) - shift
    return c.built(variables, result.coords, attrs, like=result)


def with_quality(result: xr.Dataset) -> xr.Dataset:
    """Add the modal quality indicators of the final mode vectors (MPC, MPD, complexity; on
    ``mode``) and the mode vectors normalised in phase and magnitude (largest component 1;
    scale-free, like the indicators); nothing when there are no mode vectors."""
    if names.MODE_VECTOR not in result or result.sizes.get(names.MODE, 0) == 0:
        return result
    variables = {**result.variables, **quality_variables(result[names.MODE_VECTOR].variable)}
    return c.built(variables, result.coords, result.attrs, like=result)


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
    _capped(_converged(result.variables), result.attrs, refined, stacklevel=4)
    return result


def reported(
    result: xr.Dataset,
    whole: xr.Dataset,
    refined: bool,
    noise_model: dict | None = None,
    *,
    window: FrfAttributes | None = None,
    repeated: bool = False,
    more: dict | None = None,
) -> xr.Dataset:
    """The one output step: :func:`finish_modes`,
    :func:`~ami_xr.ami.resolution.resolution_checked` and :func:`with_quality` on ``result``
    in one step: the band, the sort order, the flags and widened standard deviations of the
    under-resolved modes and the quality indicators decided on the arrays, and the output built
    once from ``result``'s variables.

    ``noise_model``: the variables of :func:`~ami_xr.ami.whitening.noise_model_back` (they
    replace the working ``frf_line_noise_std``); ``window``: the data's attributes, whose
    exponential window the eigenvalues are corrected for first (``lam_measured + beta``);
    ``repeated``: ``repeated_root_suspected`` decided from one reference's band statistic;
    ``more``: variables added as they are (by name)."""
    variables = dict(result.variables)
    attrs = dict(result.attrs)
    if noise_model is not None:
        variables.pop(names.FRF_LINE_NOISE_STD, None)
        variables.update({k: xr.as_variable(v, name=k) for k, v in noise_model.items()})
    variables.update({k: xr.as_variable(v, name=k) for k, v in (more or {}).items()})
    if repeated:
        variables.update(_repeated_variables(result))
    if window is not None:
        corrected, noted = _window_variables(result, window)
        variables.update(corrected)
        attrs.update(noted)
    n = result.sizes.get(names.MODE, 0)
    sortable = bool(n) and names.NATURAL_FREQUENCY in variables
    fn = np.zeros(0)
    if sortable:
        fn = np.asarray(variables[names.NATURAL_FREQUENCY].transpose(names.MODE).values, float)
    index = np.arange(n)
    band = bd.analysis_band(result)
    if not bd.is_whole(whole, band):  # no mode outside a restricted band (c.drop_outside_band)
        inside = (fn >= band.fmin) & (fn <= band.fmax) if sortable else np.ones(n, bool)
        attrs[names.ATTR_BAND_DROPPED] = ",".join(f"{f:.6g}" for f in fn[~inside])
        index = np.flatnonzero(inside)
    if not index.size or not sortable:  # nothing to sort (c.sort_modes)
        out = c.built(_modes_at(variables, index, n), result.coords, attrs, like=result)
        _capped(_converged(out.variables), out.attrs, refined, stacklevel=4)
        return with_quality(resolution_checked(out, whole))
    order = index[np.argsort(np.where(np.isfinite(fn[index]), fn[index], np.inf), kind="stable")]
    variables = _modes_at(variables, order, n)
    _capped(_converged(variables), attrs, refined, stacklevel=4)
    labels = np.arange(1, order.size + 1)
    for d in (names.MODE, names.MODE_2):
        if d in result.dims:
            variables[d] = xr.IndexVariable((d,), labels)
    variables[names.MODE_LABEL_UNSORTED] = xr.Variable(
        (names.MODE,),
        np.asarray(result[names.MODE].values)[order],
        {names.ATTR_LONG_NAME: "label of the mode before sorting by natural frequency"},
    )
    qf = variables.get(names.QUALITY_FLAGS)
    if names.DAMPING_RATIO in variables and qf is not None:
        mask = flags.decode(qf.values) if qf.dims == (names.MODE,) else np.zeros(labels.size)
        stds = (names.DAMPING_RATIO_STD, names.EIGENVALUE_STD)
        mask, widened = resolution_widened(
            fn[order],
            variables[names.DAMPING_RATIO].transpose(names.MODE).values,
            np.asarray(mask, np.int32),
            {v: variables[v].transpose(names.MODE).values for v in stds if v in variables},
            labels,
            whole,
        )
        variables[names.QUALITY_FLAGS] = qf.copy(data=mask)
        for v, std in widened.items():
            variables[v] = variables[v].copy(data=std)
    if names.MODE_VECTOR in variables:
        variables.update(quality_variables(variables[names.MODE_VECTOR]))
    return c.built(variables, result.coords, attrs, like=result)


def _modes_at(variables: dict, index: np.ndarray, n: int) -> dict:
    """``variables`` (by name) at the modes of positions ``index`` on ``mode`` and ``mode_2``
    (themselves when ``index`` is every one of the ``n`` modes in order)."""
    if index.size == n and np.array_equal(index, np.arange(n)):
        return variables
    out = {}
    for k, v in variables.items():
        at = {d: index for d in (names.MODE, names.MODE_2) if d in v.dims}
        out[k] = v.isel(at) if at else v
    return out


def _in_band(result: xr.Dataset, whole: xr.Dataset) -> xr.Dataset:
    """``result`` without the modes outside a restricted analysis band (listed in attr
    ``analysis_band_dropped_modes``); ``result`` itself when the band is ``whole``'s."""
    band = bd.analysis_band(result)
    if not bd.is_whole(whole, band):
        result, dropped = c.drop_outside_band(result, band.fmin, band.fmax)
        result.attrs[names.ATTR_BAND_DROPPED] = ",".join(f"{f:.6g}" for f in dropped)
    return result


def _capped(converged, attrs: dict, refined: bool, stacklevel: int) -> None:
    """The caps that ended a phase (the isolation's ``converged`` per mode, or None, and the
    attributes ``attrs``), warned about (the refinement's; the isolation warned already) and
    written into ``attrs``."""
    caps = flags.RunStatus.NONE
    if _superseded(converged, attrs, refined):  # the converged refinement re-fitted every mode
        flags.add_caps(attrs, flags.RunStatus.ISOLATE_MAX_ITER, names.ATTR_AMI_CAPPED_SUPERSEDED)
    elif converged is not None and not bool(np.all(converged)):
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
