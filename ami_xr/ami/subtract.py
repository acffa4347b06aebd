"""Subtraction Phase (the paper's eq. 6) with an automatic, statistical stop."""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr import progress as pg
from ami_xr.ami import chunked as ch
from ami_xr.ami import common as c
from ami_xr.ami.line_noise import colour_shape
from ami_xr.ami.settings import SubtractSettings, parameters, to_attrs
from ami_xr.caller import warn
from ami_xr.core import flags
from ami_xr.core.model import resolve_model
from ami_xr.dsp import band as bd
from ami_xr.dsp.convention import conjugate_error
from ami_xr.errors import AssumptionWarning, CapWarning, NoModesWarning
from ami_xr.kernels import noise as kn
from ami_xr.kernels import subtract as ks

# FRF magnitudes inside which the kernels run on the data as given. Outside, squares (|Y|^2,
# sigma^2, Gram matrices) under- or overflow (an FRF scaled by 1e-300 divided by sigma^2 = 0), so
# the data are first scaled by a power of two: exact in floating point, and the kernels are
# equivariant under it, so the results are those of the data as given, scaled back exactly.
# Inside the range the scale is 1: results on data in any usual unit are bit-identical.
SAFE_MAGNITUDE = (2.0**-250, 2.0**250)


#: Largest |exponent| of a scale: 2^1022 and 2^-1022 are normal floats (2^1024 overflows to inf).
MAX_SCALE_EXPONENT = 1022


def power_of_two_scale(peak: np.ndarray | float) -> np.ndarray | float:
    """Power-of-two factor that brings a peak magnitude into :data:`SAFE_MAGNITUDE` (1 inside it,
    and for a zero or non-finite peak, which the value checks report). The exponent is even, so
    square roots of scaled quantities (mode vectors) scale exactly too.

    The factor is a normal float, at most ``2**MAX_SCALE_EXPONENT``: a subnormal peak (below
    2.2e-308, down to 4.9e-324) needs more than 2^1022 to reach [2^-2, 2), which would overflow
    to inf and turn a small but valid FRF into inf/NaN; it is scaled by 2^1022 instead, which
    still lifts it above 2^-52, far from where squares underflow."""
    peak = np.asarray(peak, dtype=np.float64)
    lo, hi = SAFE_MAGNITUDE
    out_of_range = np.isfinite(peak) & (peak > 0) & ((peak < lo) | (peak > hi))
    exponent = np.frexp(np.where(out_of_range, peak, 1.0))[1]
    exponent = -2 * (exponent // 2)  # even; the scaled peak lies in [2^-2, 2)
    exponent = np.clip(exponent, -MAX_SCALE_EXPONENT, MAX_SCALE_EXPONENT)  # even bounds
    scale = np.where(out_of_range, np.ldexp(1.0, exponent), 1.0)
    return scale if scale.ndim else float(scale)


# Outputs of the Subtraction Phase: SubtractResult field -> (core dims, dtype). The apply_ufunc
# call and the unpacking of its results both follow this table, so no output is matched by
# position.
_OUTPUTS = {
    "lam": ([names.CANDIDATE], np.complex128),
    "res": ([names.CANDIDATE], np.complex128),
    "band_low": ([names.CANDIDATE], np.float64),
    "band_high": ([names.CANDIDATE], np.float64),
    "sigma": ([], np.float64),
    "statistic": ([], np.float64),
    "reason": ([], np.int64),
    "n_modes": ([], np.int64),
}

PIECE_ROWS = 64
"""Most FRFs per kernel call of a per-FRF phase: a pending Ctrl-C (a signal cannot be handled
inside compiled code) is handled between calls, and a progress bar counts the FRFs done."""


def by_pieces(kernel, rows: tuple[np.ndarray, ...], unit: str = "FRFs"):
    """``kernel(*rows)`` for a kernel that treats every row (FRF) on its own, called on pieces of
    at most :data:`PIECE_ROWS` rows (finer, up to ``progress.MAX_CALLS`` pieces, while a bar
    listens; the counts go to it between pieces). The result, a NamedTuple of arrays with one
    row per input row, is joined field by field: the same as one call on all rows."""
    n_rows = rows[0].shape[0]
    step = PIECE_ROWS
    if pg.active():
        step = max(1, min(step, -(-n_rows // pg.MAX_CALLS)))
    if n_rows <= step:  # one call, nothing to count
        return kernel(*rows)
    pg.detail(f"0/{n_rows} {unit}")
    parts = []
    for lo in range(0, n_rows, step):
        parts.append(kernel(*(r[lo : lo + step] for r in rows)))
        pg.detail(f"{min(lo + step, n_rows)}/{n_rows} {unit}")
    return parts[0]._make(np.concatenate(field, axis=0) for field in zip(*parts, strict=True))


def kernel_params(settings: SubtractSettings) -> ks.SubtractParams:
    """The kernel's record of the (checked) settings."""
    return ks.SubtractParams(
        delta=settings.delta,
        max_modes=settings.max_modes,
        pfa=settings.pfa,
        min_points=settings.min_points,
        zeta_max=settings.zeta_max,
        merge_tol=settings.merge_tol,
    )


def _subtract_block(g, *, omega, dt, n_samples, params, line_shape=None) -> tuple[np.ndarray, ...]:
    """The Subtraction Phase on FRFs ``g`` (..., F): the fields of ``_OUTPUTS`` in its order;
    ``line_shape`` (F,): the noise's shape along frequency (None: white)."""
    shape = g.shape[:-1]
    g2 = np.ascontiguousarray(g.reshape(-1, g.shape[-1]), dtype=np.complex128)
    scale = power_of_two_scale(np.max(np.abs(g2), axis=-1)) if g2.size else np.ones(0)
    rescaled = bool(np.any(scale != 1.0))
    if rescaled:
        g2 = g2 * scale[:, None]
    out = by_pieces(
        lambda rows: ks.subtract_batch(rows, omega, dt, n_samples, params, line_shape), (g2,)
    )
    if rescaled:  # residues and noise floors are in FRF units: back to the data as given
        out = out._replace(res=out.res / scale[:, None], sigma=out.sigma / scale)
    two_pi = 2.0 * np.pi
    out = out._replace(band_low=out.band_low / two_pi, band_high=out.band_high / two_pi)
    return tuple(
        getattr(out, name).reshape(shape + getattr(out, name).shape[1:]) for name in _OUTPUTS
    )


def subtract(
    ds: xr.Dataset,
    delta: float = SubtractSettings.delta,
    *,
    max_modes: int = SubtractSettings.max_modes,
    pfa: float = SubtractSettings.pfa,
    min_points: int = SubtractSettings.min_points,
    zeta_max: float = SubtractSettings.zeta_max,
    merge_tol: float = SubtractSettings.merge_tol,
    model: str = SubtractSettings.model,
    fmin: float | None = None,
    fmax: float | None = None,
) -> xr.Dataset:
    """Subtraction Phase: find candidate modes in every FRF, largest peak first (eqs. 6, 10-12).

    For each FRF ``Y = G``: take the largest ``|Y|``; fit one mode by linear least squares
    (eqs. 11-12, or their exact discrete-time analogue) over the contiguous lines with
    ``|Y| >= delta * |Y|_peak`` around it; subtract the fitted mode from ``Y`` (eq. 6); repeat.

    **Automatic stop.** The noise floor ``sigma`` of each FRF is estimated robustly from the
    differences of adjacent lines, ``sigma^2 = median |G_{k+1} - G_k|^2 / (2 ln 2)`` (exact for
    white, complex Gaussian, line-to-line independent noise; differencing removes the smooth modal
    part and the median ignores the few resonant lines). Under noise alone ``|Y|^2 / sigma^2`` is
    Exp(1) on every line, so the largest of ``F`` lines exceeds
    ``t = -ln(1 - (1 - pfa)^(1/F))`` with probability ``pfa``. The phase stops when the largest
    remaining peak has ``|Y|^2 / sigma^2 < t`` (reason ``"below_noise_floor"``).

    **Coloured noise.** When ``ds`` carries a per-line noise model (``frf_line_noise_std``:
    from the coherence, or the one :func:`ami_xr.identify` passes on), its colour along
    frequency ``s(f)`` (:func:`ami_xr.ami.line_noise.colour_shape`: the level over blocks of
    20 % of the frequency, median 1) makes each line's statistic ``|Y|^2 / (sigma s)^2``, with
    ``sigma`` the floor of ``Y / s``: a line is significant against its own noise. Of the
    significant lines the largest ``|Y|`` is still taken first (its tail biases the others'
    fits most); the energy test below weights the lines by ``1 / s^2`` alike.

    A fitted peak is rejected (its band is masked and the next peak is tried) when: fewer than
    ``min_points`` lines are above the ``delta`` level; the fit is not an oscillatory, stable
    mode with damping ratio ``<= zeta_max``; its frequency is outside its band (+- 2 bandwidths)
    or the data range; or subtracting it does not lower the band's energy
    ``sum |Y|^2 / s^2`` by at least ``t sigma^2``. A candidate closer than ``merge_tol`` half-power
    bandwidths (``|lam_a - lam_b| / (|Re lam_a| + |Re lam_b|)``) to an earlier one is merged
    into it (residues added). Other stops: ``"max_modes"``, ``"max_rejected_peaks"``
    (``3 max_modes + 10`` peaks examined).

    Parameters
    ----------
    ds : xarray.Dataset
        FRF Dataset (``frf`` (point, frequency), complex). May be dask-backed (chunked along
        ``point``; the result is identical).
    delta : float in (0, 1)
        Fraction of the peak magnitude that defines the fit band (0.5: quarter-power points).
    max_modes : int
        Most candidates per FRF.
    pfa : float in (0, 1)
        False-alarm probability of the stop rule per FRF.
    min_points : int
        Fewest lines a fit band must have (at least 2: the fit has 4 real unknowns).
    zeta_max : float
        Largest damping ratio accepted as physical.
    merge_tol : float
        Duplicate distance in half-power bandwidths.
    model : {"auto", "discrete", "continuous"}
        Basis: "auto" uses the exact discrete basis when ``frf_source == "impulse_response"``
        (see :func:`ami_xr.core.model.resolve_model`).
    fmin, fmax : float, optional
        Analysis band (Hz). By default the band where the excitation is valid when ``ds``
        carries ``force_autospectrum``/``coherence`` (see :mod:`ami_xr.dsp.band`), else every
        line; a band ``ds`` already records (``analysis_band_fmin``/``_fmax``) is kept. Only the
        lines of the band are analysed; the output holds them and records the band in attrs.

    Returns
    -------
    xarray.Dataset
        The input plus ``subtraction_eigenvalue``, ``subtraction_residue`` (point, candidate;
        NaN-padded), ``subtraction_band_low``/``_high`` (Hz), ``subtraction_noise_floor``,
        ``subtraction_stop_statistic``, ``subtraction_stop_reason``, ``subtraction_n_modes``
        (point).

    Warns
    -----
    NoModesWarning
        When no FRF has any candidate (e.g. pure noise).
    AssumptionWarning
        When the band is chosen from the excitation (says which and why).
    CapWarning
        (a ConvergenceWarning) When a cap (``max_modes``, ``max_rejected_peaks``) ended the phase
        at some FRF; the point's ``subtraction_stop_reason`` and attr ``ami_capped`` (a
        :class:`~ami_xr.core.flags.RunStatus`) record it.
    """
    c.check_frf(ds, "subtract")
    settings = subtract_settings(delta, max_modes, pfa, min_points, zeta_max, merge_tol, model)
    ds = band_of(ds, fmin, fmax, "subtract")
    c.check_values(ds)
    done = subtract_arrays(ds[names.FRF], ds.attrs, settings, colour_shape(ds, ds[names.FRF]))
    out = _assign_outputs(ds, done.variables)
    out.attrs.update(done.attrs)
    return c.finish(out, "ami_xr.subtract", "subtract", parameters(done.settings))


def subtract_settings(
    delta, max_modes, pfa, min_points, zeta_max, merge_tol, model
) -> SubtractSettings:
    """The checked settings of :func:`subtract` (an error naming the first bad one)."""
    return SubtractSettings(
        delta=c.check_fraction(delta, "delta"),
        max_modes=c.check_positive_int(max_modes, "max_modes"),
        pfa=c.check_fraction(pfa, "pfa"),
        min_points=c.check_positive_int(min_points, "min_points", 2),
        zeta_max=c.check_positive(zeta_max, "zeta_max"),
        merge_tol=c.check_positive(merge_tol, "merge_tol"),
        model=c.check_choice(model, "model", c.MODELS),
    )


class Subtracted(NamedTuple):
    """What :func:`subtract_arrays` returns."""

    result: ks.SubtractResult  # the kernel's arrays, point first
    variables: dict  # the output variables (:func:`subtract_variables`)
    attrs: dict  # the attributes the phase records
    settings: SubtractSettings  # with the data model resolved


def subtract_arrays(
    frf: xr.DataArray, attrs: dict, settings: SubtractSettings, noise=(None, None)
) -> Subtracted:
    """The Subtraction Phase on the checked FRFs ``frf`` (point, frequency) of a Dataset with
    ``attrs``: the core of :func:`subtract`, which :func:`ami_xr.identify` calls on its arrays.
    ``noise``: the noise's shape along frequency as
    :func:`~ami_xr.ami.line_noise.colour_shape` gives it (``(None, None)``: white); the
    peaks are then chosen, tested and stopped on the power relative to each line's noise.
    The attributes it records: its settings, the caps, why no mode was found; the caps and a
    zero-modes result are warned about."""
    data_model = resolve_model(attrs, settings.model)
    settings = dataclasses.replace(settings, model=data_model.name)
    omega = 2.0 * np.pi * np.asarray(frf[names.FREQUENCY].values, dtype=np.float64)
    r = _run(frf, omega, data_model, settings, noise)
    new = subtract_variables(r, omega, settings, frf.attrs.get(names.ATTR_UNITS, ""))
    record: dict = {}
    to_attrs(settings, record)
    points = np.asarray(frf[names.POINT].values)
    _warn_caps(new[names.SUB_STOP_REASON].values, points, settings.max_modes, record)
    if int(r.n_modes.sum()) == 0:
        if _has_significant_peak(frf, r.sigma, settings):
            # significant peaks, no fit accepted: the other sign convention? then say so
            flipped = _run(np.conj(frf), omega, data_model, settings)
            found = _conjugate_resonances(frf, flipped, r.sigma, omega, settings)
            if found:
                raise conjugate_error("subtract", int(np.prod(r.n_modes.shape)), found)
        _explain_no_modes(new, record, frf, r.sigma, settings, omega.size)
    return Subtracted(r, new, record, settings)


def subtract_rows(
    g: np.ndarray, omega: np.ndarray, data_model, settings: SubtractSettings, noise=(None, None)
):
    """The kernel on the FRFs ``g`` (P, F) in memory: a :class:`SubtractResult` of arrays with
    one row per FRF (the core of :func:`subtract`, which :func:`ami_xr.identify` calls on its
    arrays); ``noise`` as :func:`subtract_arrays` takes it (a shape per group of points: the
    kernel on each group's rows)."""
    shape, group = noise
    if group is None or np.ndim(shape) < 2:
        out = _subtract_block(g, **_block_kwargs(omega, data_model, settings, shape))
        return ks.SubtractResult(**dict(zip(_OUTPUTS, out, strict=True)))
    parts = {
        int(k): subtract_rows(g[group == k], omega, data_model, settings, (shape[k], None))
        for k in np.unique(group)
    }
    first = next(iter(parts.values()))
    merged = {}
    for name in first._fields:
        field = np.empty((g.shape[0],) + getattr(first, name).shape[1:], getattr(first, name).dtype)
        for k, part in parts.items():
            field[group == k] = getattr(part, name)
        merged[name] = field
    return ks.SubtractResult(**merged)


def _block_kwargs(omega: np.ndarray, data_model, settings: SubtractSettings, shape) -> dict:
    """:func:`_subtract_block`'s keywords."""
    return dict(
        omega=omega,
        dt=data_model.dt,
        n_samples=data_model.n_samples,
        params=kernel_params(settings),
        line_shape=shape,
    )


def _run(
    frf: xr.DataArray,
    omega: np.ndarray,
    data_model,
    settings: SubtractSettings,
    noise=(None, None),
) -> ks.SubtractResult:
    """The kernel on every FRF of ``frf``: a :class:`SubtractResult` of arrays (point first);
    a lazy FRF chunk by chunk of points (one ``apply_ufunc``; one noise shape for all, the
    median of the groups')."""
    if not ch.is_lazy(frf):
        g = frf.transpose(names.POINT, names.FREQUENCY).values
        return subtract_rows(g, omega, data_model, settings, noise)
    shape = noise[0]
    if shape is not None and np.ndim(shape) > 1:
        shape = np.median(shape, axis=0)
    res = xr.apply_ufunc(
        _subtract_block,
        frf,
        kwargs=_block_kwargs(omega, data_model, settings, shape),
        input_core_dims=[[names.FREQUENCY]],
        output_core_dims=[dims for dims, _ in _OUTPUTS.values()],
        dask="parallelized",
        output_dtypes=[dtype for _, dtype in _OUTPUTS.values()],
        dask_gufunc_kwargs={"output_sizes": {names.CANDIDATE: settings.max_modes}},
        keep_attrs=False,
    )
    return ks.SubtractResult(
        **{
            name: np.asarray(o.transpose(names.POINT, ...).values)
            for name, o in zip(_OUTPUTS, res, strict=True)
        }
    )


def subtract_variables(r, omega: np.ndarray, settings: SubtractSettings, frf_units: str) -> dict:
    """The subtraction's output variables (``xarray.Variable`` by name, plus the ``candidate``
    coordinate) from the kernel's result ``r`` (arrays, point first): candidate slots cut to
    the most candidates found, at least one."""
    n_keep = max(int(r.n_modes.max()) if r.n_modes.size else 0, 1)
    pc, p = (names.POINT, names.CANDIDATE), (names.POINT,)
    units = names.ATTR_UNITS
    reason = np.array([ks.STOP_REASONS[int(k)] for k in r.reason], dtype=object).astype(str)
    threshold = float(kn.peak_threshold(omega.size, settings.pfa))
    return {
        names.SUB_EIGENVALUE: xr.Variable(pc, r.lam[:, :n_keep], {units: names.ANGULAR_UNITS}),
        names.SUB_RESIDUE: xr.Variable(
            pc, r.res[:, :n_keep], {units: f"{frf_units} {names.ANGULAR_UNITS}"}
        ),
        names.SUB_BAND_LOW: xr.Variable(pc, r.band_low[:, :n_keep], {units: names.FREQUENCY_UNITS}),
        names.SUB_BAND_HIGH: xr.Variable(
            pc, r.band_high[:, :n_keep], {units: names.FREQUENCY_UNITS}
        ),
        names.SUB_NOISE_FLOOR: xr.Variable(
            p,
            r.sigma,
            {
                units: frf_units,
                names.ATTR_LONG_NAME: "noise standard deviation per line "
                "(median of adjacent differences)",
            },
        ),
        names.SUB_STOP_STATISTIC: xr.Variable(
            p,
            r.statistic,
            {
                names.ATTR_LONG_NAME: "|Y|^2/sigma^2 of the last examined peak",
                names.ATTR_THRESHOLD: threshold,
            },
        ),
        names.SUB_STOP_REASON: xr.Variable(p, reason),
        names.SUB_N_MODES: xr.Variable(p, r.n_modes),
        names.CANDIDATE: xr.Variable((names.CANDIDATE,), np.arange(n_keep)),
    }


def _assign_outputs(ds: xr.Dataset, new: dict) -> xr.Dataset:
    """``ds`` without earlier results, plus the subtraction's output variables ``new``."""
    out = c.drop_results(ds, (c.SUBTRACT_VARS, c.ISOLATE_VARS, c.GLOBAL_VARS))
    new = dict(new)
    coord = new.pop(names.CANDIDATE)
    return out.assign(new).assign_coords({names.CANDIDATE: coord})


def band_of(ds: xr.Dataset, fmin, fmax, function: str) -> xr.Dataset:
    """``ds`` restricted to its analysis band (:func:`ami_xr.dsp.band.analysis_band`); a band
    chosen from the excitation is announced in an :class:`AssumptionWarning`."""
    lines, band = band_and_lines(ds, fmin, fmax, function)
    out = ds.copy(deep=False) if lines is ds else lines
    out.attrs = {**out.attrs, **band}  # a new dict: the caller's Dataset keeps its own
    return out


def band_and_lines(ds: xr.Dataset, fmin, fmax, function: str) -> tuple[xr.Dataset, dict]:
    """:func:`band_of` without its copy: ``ds`` restricted to the lines of its analysis band
    (``ds`` itself, not copied, when that is all of it; its attributes not changed) and the
    attributes that record the band, for the caller's output."""
    recorded = names.ATTR_BAND_FMIN in ds.attrs and fmin is None and fmax is None
    band = bd.analysis_band(ds, fmin, fmax)
    if not recorded and band.rule == bd.RULE_EXCITATION:
        warn(f"{function}: {bd.band_message(band, ds)}", AssumptionWarning)
    return bd.band_lines(ds, band), band.attrs()


def add_capped(attrs, entries) -> None:
    """Set the bits of ``entries`` (a :class:`~ami_xr.core.flags.RunStatus`, or cap names
    "phase:cap") in attr ``ami_capped`` (an int RunStatus)."""
    flags.add_caps(attrs, entries)


def _warn_caps(reasons: np.ndarray, points: np.ndarray, max_modes: int, attrs: dict) -> None:
    """A cap that ended the phase at some FRF (``reasons``, the stop reason per point): a
    warning and attr ``ami_capped`` in ``attrs``."""
    reasons = np.asarray(reasons).astype(str)
    caps = {
        ks.STOP_REASONS[ks.STOP_MAX_MODES]: f"max_modes={max_modes} candidates",
        ks.STOP_REASONS[ks.STOP_MAX_ATTEMPTS]: f"{3 * max_modes + 10} examined peaks "
        "(max_rejected_peaks = 3 max_modes + 10)",
    }
    hit = flags.RunStatus.NONE
    for reason, what in caps.items():
        at = points[reasons == reason]
        if at.size:
            status = flags.RunStatus.of(f"subtract:{reason}")
            hit |= status
            message = (
                f"subtract: stopped at the cap of {what} at point(s) {c.shorten(at.tolist())}, "
                "before the remaining peaks fell below the noise floor; modes may be missing "
                "(raise max_modes, or narrow the band with fmin/fmax); see "
                f"{names.SUB_STOP_REASON}"
            )
            warn(CapWarning(message, status), CapWarning)
    attrs[names.ATTR_AMI_CAPPED] = int(hit)


def _has_significant_peak(frf, sigma, settings: SubtractSettings) -> bool:
    """Some FRF's largest line passes the stop rule's threshold (see :func:`_explain_no_modes`)."""
    t = float(kn.peak_threshold(frf.sizes[names.FREQUENCY], settings.pfa))
    ratio = np.asarray((np.abs(frf).max(names.FREQUENCY) / sigma).values, dtype=np.float64)
    return bool(np.any(ratio**2 >= t))


def _conjugate_resonances(frf, flipped, sigma, omega: np.ndarray, settings) -> int:
    """How many candidates of the conjugated FRFs (``flipped``, the kernel's result on them)
    are resonances of the data, when they are the evidence of the other sign convention; 0
    when they are not (then nothing is advised).

    Conjugating changes no magnitude: data in the other convention have their resonances
    where the conjugated run accepts its candidates. A candidate counts only at a hump of
    ``|G|`` of that FRF -- the largest line within the candidate's half-power half-bandwidth
    (at least 2 lines) either side lies strictly inside that window and at least 3 noise
    floors above both its ends -- and only when its half-power bandwidth spans a line or
    more (a narrower fit is a noise excursion). A band without a resonance (tails of modes
    outside it), where a fit to a tail passes once conjugated, has no such hump. The advice
    needs counted candidates at half or more of the FRFs with a significant peak and, with
    two or more such FRFs, each counted pole seen within ``merge_tol`` half-power
    half-bandwidths at another FRF (a mode shows at more than one point).
    """
    g = np.abs(np.asarray(frf.transpose(..., names.FREQUENCY).values)).reshape(-1, omega.size)
    sig = np.asarray(sigma, dtype=np.float64).reshape(-1)
    lam = np.asarray(flipped.lam).reshape(g.shape[0], -1)
    t = float(kn.peak_threshold(omega.size, settings.pfa))
    with np.errstate(divide="ignore", invalid="ignore"):
        peaked = (g.max(axis=1) / sig) ** 2 >= t
    step = float(np.median(np.diff(omega))) if omega.size > 1 else np.inf
    poles: list[tuple[int, complex]] = []
    for j in np.flatnonzero(peaked):
        for lk in lam[j][np.isfinite(lam[j])]:
            half = abs(lk.real)
            if 2.0 * half < step:
                continue
            at = int(np.argmin(np.abs(omega - lk.imag)))
            reach = max(2, int(np.ceil(half / step)))
            lo, hi = max(at - reach, 0), min(at + reach, omega.size - 1)
            top = lo + int(np.argmax(g[j, lo : hi + 1]))
            if lo < top < hi and g[j, top] - max(g[j, lo], g[j, hi]) >= 3.0 * sig[j]:
                poles.append((int(j), complex(lk)))
    if len(poles) and int(peaked.sum()) >= 2:
        poles = [
            (j, lk)
            for j, lk in poles
            if any(i != j and abs(m - lk) <= settings.merge_tol * abs(lk.real) for i, m in poles)
        ]
    frfs = {j for j, _ in poles}
    return len(poles) if poles and 2 * len(frfs) >= int(peaked.sum()) else 0


def _explain_no_modes(new: dict, attrs: dict, frf, sigma, settings, n_lines) -> None:
    """Say truthfully why no FRF has a candidate, in a warning and in attr ``ami_stop_reason``.

    Two cases look alike in the kernel's stop reason: pure noise (no line above the threshold)
    and clean FRFs whose peaks are significant but whose single-mode fits were all rejected
    (heavily damped or overlapping modes: damping ratio above ``zeta_max``, or a pole outside
    its band). The peak statistic of the data themselves, ``max |G|^2 / sigma^2`` against the
    threshold ``t``, tells them apart; FRFs of the second kind get the point stop reason
    ``"no_accepted_fit"``. ``new``: the output variables (the stop reasons change there);
    ``attrs``: where ``ami_stop_reason`` goes.
    """
    pfa, zeta_max = settings.pfa, settings.zeta_max
    t = float(kn.peak_threshold(n_lines, pfa))
    # (max|G| / sigma)^2, not max|G|^2 / sigma^2: no overflow for any representable FRF
    ratio = np.asarray((np.abs(frf).max(names.FREQUENCY) / sigma).values, dtype=np.float64)
    significant = ratio**2 >= t
    if not np.any(significant):
        attrs[names.ATTR_AMI_STOP_REASON] = names.STOP_NO_SIGNIFICANT_PEAK
        warn(
            "subtract: no FRF has a peak significantly above its noise floor "
            f"(pfa={pfa}); zero modes found",
            NoModesWarning,
        )
        return
    attrs[names.ATTR_AMI_STOP_REASON] = names.STOP_NO_ACCEPTED_FIT
    reason = new[names.SUB_STOP_REASON]
    mask = significant & (np.asarray(reason.values) == ks.STOP_REASONS[ks.STOP_BELOW_FLOOR])
    new[names.SUB_STOP_REASON] = reason.copy(
        data=np.where(mask, names.STOP_NO_ACCEPTED_FIT, np.asarray(reason.values)).astype(str)
    )
    warn(
        f"subtract: zero modes found, although {int(significant.sum())} of {significant.size} "
        f"FRF(s) have a peak significantly above the noise floor (pfa={pfa}): no single-mode "
        f"fit was accepted (damping ratio above zeta_max={zeta_max:g}, or the peak is wider "
        "than its fit band: heavily damped or overlapping modes?). If the modes are this "
        "heavily damped, raise zeta_max (e.g. ami_xr.identify(ds, zeta_max=0.6))",
        NoModesWarning,
    )
