"""The noise model of ``identify``: fit where the noise is white, report in the quantity given.

Every fit of the pipeline (the subtraction's SDOF fits and peak statistics, the isolation, the
global fit, the refinement's likelihood and the model-order tests) weights the lines of an FRF
alike, which is right when the noise is white in the quantity the FRFs arrive in. Measured noise
is often white in another quantity (receptance computed from accelerometers: the noise grows as
``1 / w^2``; mobility from a vibrometer; a force rolling off), and then the noisiest lines decide
every fit: the same measurement given as receptance, mobility or accelerance lost up to two thirds
of its modes and reported noise spikes as modes (issue 37).

The rule, on the lines analysed:

1. **Noise per point and line.** ``frf_line_noise_std`` where the FRF carries it (``ami_xr.frf``:
   the coherence and the number of averages; each line at least the median of its log over
   blocks of 2 % of the frequency, since each line's estimate is itself random: no line is
   weighted up by a chance low estimate), otherwise the FRF's roughness between adjacent lines
   (:func:`ami_xr.core.frf_noise.block_roughness_std`: the 4th difference, a median over blocks
   of 64 lines).
2. **Working quantity.** Multiplying the FRFs by ``(i w)^k`` changes no line's signal-to-noise
   ratio and no pole; for each quantity the data can be converted to (displacement, velocity,
   acceleration), the loss of unweighted least squares ``mean(s^2) mean(1/s^2)`` (1 for white
   noise; :func:`ami_xr.core.frf_noise.whitening_losses`) is computed from the noise converted
   alike. The pipeline runs in the quantity of the least loss when that is at least
   ``SWITCH_RATIO`` (1.25) times smaller than the loss as given (white noise stays where it is:
   its loss is 1.05-1.15 from the estimate's own scatter).
3. **Line weights.** When the loss in the working quantity still exceeds ``WEIGHT_LOSS`` (100:
   the noise level varies by more than about twenty times across the band), the noise model
   (converted) goes with the data as ``frf_line_noise_std``, and the refinement weights each
   line by it (its likelihood and the model-order statistics); a stored noise model always
   does. Not below: the noise model does
   not see the model error of measured peaks, and weighting the quiet lines up lets it decide
   -- ``measurement.uff`` (loss 10 as accelerance) weighted gives a split 958 Hz mode and two
   more, unweighted its six modes; sdypy-EMA's beam (loss 28-29) weighted an extra 1377 Hz mode,
   unweighted none; the simulated cases of ``benchmark_quantity.py`` give the
   same counts either way once in the working quantity.
4. **Back to the quantity given.** Poles, damping ratios, mode vectors (displacement convention)
   and their standard errors do not depend on the quantity. Residues become ``A / (c lam^k)``
   (``c`` the unit factor, e.g. 9.80665 for g), FRF-shaped outputs ``H / (c (i w)^k)``, residual
   coefficients ``/ c`` (the residual bases of the quantities map onto each other exactly).

FRFs of sampled impulse responses (``frf_source="impulse_response"``) stay as given: their basis
is that of the sampled record, which a conversion would break, and their noise (white in time) is
white in frequency. The decision is recorded in attributes ``noise_model_*`` and, when the
quantity changes, said in an :class:`~ami_xr.errors.AssumptionWarning`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import chunked as ch
from ami_xr.ami.line_noise import even_subset, wants_smoothing
from ami_xr.caller import warn
from ami_xr.core import frf_noise as fn
from ami_xr.dsp.quantity import convert_units
from ami_xr.errors import AssumptionWarning

SWITCH_RATIO = 1.25
WEIGHT_LOSS = 100.0  # below it model error at the peaks outweighs the gain (module docstring)
MAX_POINTS = 64  # points the noise model is estimated on (evenly chosen): O(lines) beyond

ATTR_QUANTITY = "noise_model_quantity"  # the quantity the modes were fitted in
ATTR_SOURCE = "noise_model_source"  # "stored frf_line_noise_std" | "roughness" [: ...]
ATTR_LOSSES = "noise_model_losses"  # loss of unweighted least squares per quantity
ATTR_WEIGHTED = "noise_model_line_weights"  # 1: the refinement weighted the lines
ATTR_RULE = "noise_model_rule"
VAR_SHAPE = "noise_model_shape"  # (frequency) the noise's shape, median 1, quantity given
VAR_LEVEL = "noise_model_level"  # (point) the noise std of one line where the shape is 1


@dataclass(frozen=True)
class Whitening:
    """What :func:`decide` found: the shift ``k`` (working = given times ``(i w)^k``), the unit
    factor ``scale`` of the conversion, the noise model in the working quantity (P, L) when
    the lines are to be weighted (else None), and the record for the attributes."""

    k: int
    target: str
    scale: float
    line_noise: np.ndarray | None
    attrs: dict
    shape: np.ndarray | None = None  # (L,) the noise's shape along frequency, quantity given


def _points(n: int) -> np.ndarray:
    return even_subset(np.arange(n), MAX_POINTS)


def _data(ds: xr.Dataset) -> tuple[np.ndarray, np.ndarray | None, str]:
    """The FRFs (P', L) the noise model is estimated on (at most ``MAX_POINTS`` of them) and
    the stored noise std of the same rows (None without one; a record of the coherence
    smoothed along frequency, :func:`ami_xr.ami.line_noise.wants_smoothing`)."""
    h = ds[names.FRF].transpose(..., names.POINT, names.FREQUENCY)
    rows = _points(int(np.prod(h.shape[:-1])))
    x = ch.rows(h, rows)  # of a lazy FRF only these rows are read
    if names.FRF_LINE_NOISE_STD in ds and ds[names.FRF_LINE_NOISE_STD].dims == h.dims:
        sd = ch.rows(ds[names.FRF_LINE_NOISE_STD].transpose(*h.dims), rows)
        if np.isfinite(sd).mean() > 0.5:
            how = ds[names.FRF_LINE_NOISE_STD].attrs.get(names.ATTR_NOISE_MODEL, "")
            source = "stored frf_line_noise_std" + (f" ({how})" if how else "")
            if wants_smoothing(ds[names.FRF_LINE_NOISE_STD]):  # one random estimate per line
                sd = fn.smoothed_std(sd, ds[names.FREQUENCY].values)
                source = f"{source}; {fn.smoothing_model()}"
            return x, sd, source
    return x, None, "roughness"


def _quantity(power: int) -> str:
    """The response quantity of derivative order ``power`` (0 displacement ... 2 acceleration)."""
    return next(q for q, v in names.QUANTITY_POWER.items() if v == power)


def _noise_free(h: np.ndarray, f: np.ndarray, fourth: np.ndarray | None = None) -> bool:
    """Whether the roughness of ``h`` (P, L) is the FRF's own curvature rather than noise at
    most of its blocks (:func:`ami_xr.core.frf_noise.noise_dominated_share` below 1/2);
    ``fourth``: its order-4 estimate on the lines above 0 Hz, when already made."""
    return fn.noise_dominated_share(h[:, f > 0], fourth=fourth) < 0.5


def decide(ds: xr.Dataset) -> Whitening:
    """The working quantity and the line weights of ``ds`` (the lines analysed); see the
    module docstring."""
    attrs = ds.attrs
    given = attrs.get(names.ATTR_QUANTITY)
    f = np.asarray(ds[names.FREQUENCY].values, dtype=np.float64)
    h, stored, source = _data(ds)
    if given in names.QUANTITY_POWER and attrs.get(names.ATTR_SOURCE) != names.SOURCE_IMPULSE:
        p = names.QUANTITY_POWER[given]
        shifts = [q - p for q in names.QUANTITY_POWER.values()]
    else:
        p, shifts = 0, [0]
    losses, stds = fn.whitening_losses(h, f, shifts, stored)
    best = min(losses, key=losses.get)
    k = best if losses[0] > SWITCH_RATIO * losses[best] else 0
    noise_free = stored is None and _noise_free(h, f, stds[0] if 0 in stds else None)
    if noise_free:
        # the FRF's curvature, not noise: its "level" follows |H| and says nothing of a quantity
        k, source = 0, f"{source}: the curvature of the FRF, not noise; lines weighted alike"
        losses = {0: 1.0}
    target = _quantity(p + k) if k else given
    scale = 1.0
    if k:
        try:
            _, scale = convert_units(str(attrs.get(names.ATTR_RESPONSE_UNITS, "")), p, p + k)
        except ValueError:
            # units that do not say their derivative (e.g. "V"): the FRFs cannot be converted
            # and keep their quantity; the record says why
            k, target = 0, given
            source = f"{source}; response_units not convertible, fitted as given"
    # a stored noise model (from the coherence) always weights the lines, as before issue 37
    weighted = stored is not None or (losses[k] > WEIGHT_LOSS and not noise_free)
    line_noise = None
    if weighted:
        line_noise = np.full((h.shape[0], f.size), np.nan)
        line_noise[:, f > 0] = stds[k] * abs(scale)
    record = {
        ATTR_QUANTITY: str(target or ""),
        ATTR_SOURCE: source,
        ATTR_LOSSES: ", ".join(
            f"{_quantity(p + s)}: {v:.3g}"
            if given in names.QUANTITY_POWER
            else f"as given: {v:.3g}"
            for s, v in sorted(losses.items())
        ),
        ATTR_WEIGHTED: int(weighted),
        ATTR_RULE: (
            f"fit in the quantity whose noise is closest to white (loss mean(s^2) mean(1/s^2) "
            f"of unweighted least squares, smaller by {SWITCH_RATIO:g}x than as given); lines "
            f"weighted by the noise model where the loss there exceeds {WEIGHT_LOSS:g}"
        ),
    }
    shape = None
    if not noise_free:
        w = 2.0 * np.pi * f[f > 0]
        given_std = stds[k] / w[None, :] ** k  # the working estimate, taken back
        with np.errstate(invalid="ignore", divide="ignore"):
            rel = np.nanmedian(given_std / np.nanmedian(given_std, axis=1, keepdims=True), axis=0)
        shape = np.full(f.size, np.nan)
        shape[f > 0] = rel / np.nanmedian(rel)
        ok = np.isfinite(shape) & (shape > 0)
        shape = np.interp(np.arange(f.size), np.flatnonzero(ok), shape[ok]) if ok.any() else None
    return Whitening(int(k), str(target or ""), float(scale), line_noise, record, shape)


def to_working(ds: xr.Dataset, w: Whitening) -> xr.Dataset:
    """``ds`` in the working quantity, with the noise model attached when the lines are to be
    weighted; the 0 Hz line is left out where the conversion divides by ``i w``."""
    from ami_xr.dsp.quantity import convert_quantity

    work = ds
    if w.k:
        if w.k < 0 and float(ds[names.FREQUENCY].values[0]) <= 0.0:
            work = work.isel({names.FREQUENCY: slice(1, None)})
        extra = [v for v in (names.FRF_LINE_NOISE_STD,) if v in work]
        work = convert_quantity(work.drop_vars(extra), w.target)
        work.attrs[names.ATTR_SOURCE] = ds.attrs.get(names.ATTR_SOURCE, names.SOURCE_MEASURED)
    if w.line_noise is not None:
        h = work[names.FRF].transpose(..., names.POINT, names.FREQUENCY)
        sd = w.line_noise[:, -work.sizes[names.FREQUENCY] :]
        subset = sd.shape[0] != int(np.prod(h.shape[:-1]))  # estimated on some points only
        if subset:  # every point gets their median: one row, broadcast at the end
            sd = np.nanmedian(sd, axis=0)[None, :]
        sd = np.where(np.isfinite(sd) & (sd > 0), sd, np.nan).reshape(-1, h.shape[-1])
        if not np.isfinite(sd).any():
            return work.assign_attrs(w.attrs)
        # a line without a level (0 Hz, NaN): the point's median level (the data model asks
        # for finite values; the refinement takes each line's level relative to the others)
        row = np.nanmedian(np.where(np.isfinite(sd).any(axis=1)[:, None], sd, np.nanmedian(sd)), 1)
        sd = np.where(np.isfinite(sd), sd, row[:, None])
        # (a lazy FRF gets a lazy broadcast in its chunks, not a (P, L) array in memory)
        sd = ch.broadcast_rows(sd[0], h) if subset else sd.reshape(h.shape)
        work = work.assign(
            {names.FRF_LINE_NOISE_STD: (h.dims, sd, {names.ATTR_NOISE_MODEL: w.attrs[ATTR_SOURCE]})}
        )
    work.attrs.update(w.attrs)
    return work


_FRF_SHAPED = (names.FRF_SYNTHESIZED,)
_RESIDUES = (
    (names.RESIDUE, names.EIGENVALUE),
    (names.AMI_PREFIX + names.RESIDUE, names.AMI_PREFIX + names.EIGENVALUE),
    (names.SUB_RESIDUE, names.SUB_EIGENVALUE),
)


def _level(x: np.ndarray, factor, divisor) -> np.ndarray:
    """The noise level of each FRF of ``x`` (..., L) (:func:`_with_noise_model`): the
    0.15-quantile of ``|4th difference of x * factor| / divisor``, scaled to a std."""
    q, k4 = fn.BLOCK_QUANTILE, fn.ROUGHNESS_ORDER
    xw = x * factor
    xw = np.where(np.isfinite(xw), xw, 0.0)
    d = (
        np.abs(np.diff(xw, n=k4, axis=-1))
        / np.broadcast_to(divisor, x.shape[-1:])[k4 // 2 : -(k4 // 2)]
    )
    return np.quantile(d, q, axis=-1) / np.sqrt(-np.log(1 - q) * math.comb(2 * k4, k4))


def _with_noise_model(out: xr.Dataset, w: Whitening) -> xr.Dataset:
    """``out`` with the noise model in compact form, in the quantity given: ``noise_model_shape``
    (frequency; median 1) and ``noise_model_level`` (point), the noise std of one line of FRF
    ``j`` at frequency ``f`` being ``level_j * shape(f)``. The level of every point is the
    0.15-quantile of the modulus of its 4th difference over the lines, each divided by the
    shape, on the FRFs in the working quantity (scaled as in
    :func:`ami_xr.core.frf_noise.block_roughness_std`). Nothing for
    noise-free data (no noise to show)."""
    if w.shape is None or names.FRF not in out:
        return out
    return out.assign(noise_model_variables(out[names.FRF], w))


def noise_model_variables(frf: xr.DataArray, w: Whitening) -> dict:
    """The variables :func:`_with_noise_model` adds for the FRFs ``frf`` in the quantity given
    (``w.shape`` set), by name."""
    f = frf[names.FREQUENCY]
    shape = w.shape[-f.size :]
    h = frf.transpose(..., names.FREQUENCY)
    # in the working quantity, where the noise is closest to white (in the quantity given the
    # FRF's own curvature would outweigh the noise where that is far below it)
    fw = np.asarray(f.values, dtype=float)
    conv = np.where(fw > 0, abs(w.scale) * (2.0 * np.pi * fw) ** w.k, np.nan) if w.k else 1.0
    phase = np.exp(0.5j * np.pi * w.k)  # (i w)^k = i^k w^k
    factor = conv * phase if w.k else 1.0
    level = ch.per_row(_level, h, names.FREQUENCY, factor=factor, divisor=shape * conv)
    units = h.attrs.get(names.ATTR_UNITS, "")
    return {
        VAR_SHAPE: (
            (names.FREQUENCY,),
            shape,
            {
                names.ATTR_LONG_NAME: "noise std of one FRF line relative to the point's level",
                names.ATTR_UNITS: "1",
            },
        ),
        VAR_LEVEL: (
            h.dims[:-1],
            level,
            {
                names.ATTR_LONG_NAME: "noise std of one FRF line where noise_model_shape is 1",
                **({names.ATTR_UNITS: units} if units else {}),
            },
        ),
    }


def noise_model_back(result: xr.Dataset, ds: xr.Dataset, w: Whitening) -> dict:
    """For a fit in the quantity given (``w.k == 0``): the variables :func:`from_working` adds
    to ``result`` once the working noise model ``frf_line_noise_std`` is dropped, by name and
    in order: the input's own noise model (``ds``'s ``frf_line_noise_std`` on ``result``'s
    lines), then :func:`noise_model_variables` (none for noise-free data)."""
    new = {}
    if names.FRF_LINE_NOISE_STD in ds:  # the input's own noise model stays in the output
        lines = {names.FREQUENCY: result[names.FREQUENCY].values}
        new[names.FRF_LINE_NOISE_STD] = ds[names.FRF_LINE_NOISE_STD].sel(lines).variable
    if w.shape is not None and names.FRF in result:
        new.update(noise_model_variables(result[names.FRF], w))
    return new


def from_working(result: xr.Dataset, ds: xr.Dataset, w: Whitening) -> xr.Dataset:
    """``result`` of the pipeline on :func:`to_working` ``(ds, w)`` in the quantity of ``ds``."""
    if not w.k:  # the fit ran on the quantity given: the noise model is all that changes
        out = result.drop_vars([names.FRF_LINE_NOISE_STD], errors="ignore")
        out = out.assign(noise_model_back(result, ds, w))
        out.attrs.update(w.attrs)
        return out
    out = result.drop_vars([names.FRF_LINE_NOISE_STD], errors="ignore")
    f = out[names.FREQUENCY]
    if names.FRF_LINE_NOISE_STD in ds:  # the input's own noise model stays in the output
        out = out.assign(
            {
                names.FRF_LINE_NOISE_STD: ds[names.FRF_LINE_NOISE_STD].sel(
                    {names.FREQUENCY: f.values}
                )
            }
        )
    iw = xr.DataArray(2j * np.pi * f.values, dims=[names.FREQUENCY], coords={names.FREQUENCY: f})
    back = 1.0 / (w.scale * iw**w.k)
    frf = ds[names.FRF].sel({names.FREQUENCY: f.values})
    units = ds[names.FRF].attrs.get(names.ATTR_UNITS, "")
    out = out.assign({names.FRF: frf})
    for v in _FRF_SHAPED:
        if v in out:
            out[v] = (out[v] * back).assign_attrs(out[v].attrs)
    if names.FRF_SYNTHESIZED in out and names.FRF_RESIDUAL in out:
        res = (out[names.FRF] - out[names.FRF_SYNTHESIZED]).transpose(*out[names.FRF_RESIDUAL].dims)
        out[names.FRF_RESIDUAL] = out[names.FRF_RESIDUAL].copy(data=res.data)  # lazy stays lazy
    for v, lam_name in _RESIDUES:
        if v in out and lam_name in out:
            lam = out[lam_name]
            out[v] = (out[v] / (w.scale * lam**w.k)).assign_attrs(out[v].attrs)
            if v == names.RESIDUE and names.RESIDUE_STD in out:
                std = out[names.RESIDUE_STD] / (abs(w.scale) * np.abs(lam) ** w.k)
                out[names.RESIDUE_STD] = std.assign_attrs(out[names.RESIDUE_STD].attrs)
    if names.RESIDUAL_COEFFICIENT in out:
        rc = out[names.RESIDUAL_COEFFICIENT]
        out[names.RESIDUAL_COEFFICIENT] = (rc / w.scale).assign_attrs(rc.attrs)
    # noise levels per point: the working level at each line taken back, as an RMS over the lines
    rms = np.sqrt(np.nanmean(np.abs(back.values) ** 2))
    for v in (names.FRF_NOISE_STD, names.SUB_NOISE_FLOOR):
        if v in out:
            out[v] = (out[v] * rms).assign_attrs(out[v].attrs)
    for v in (*_FRF_SHAPED, names.FRF_RESIDUAL, names.FRF_NOISE_STD, names.SUB_NOISE_FLOOR):
        if v in out and units:
            out[v].attrs[names.ATTR_UNITS] = units
    for v, _ in _RESIDUES:
        if v in out and units:
            out[v].attrs[names.ATTR_UNITS] = f"{units} {names.ANGULAR_UNITS}"
    if names.RESIDUE_STD in out and units:
        out[names.RESIDUE_STD].attrs[names.ATTR_UNITS] = f"{units} {names.ANGULAR_UNITS}"
    for key in (names.ATTR_QUANTITY, names.ATTR_FRF_TYPE, names.ATTR_RESPONSE_UNITS):
        if key in ds.attrs:
            out.attrs[key] = ds.attrs[key]
    out = _with_noise_model(out, w)  # on the FRFs as given
    out.attrs.update(w.attrs)
    warn(
        f"identify: the FRFs' noise is closest to white as {w.target} (noise model: "
        f"{w.attrs[ATTR_SOURCE]}; loss of unweighted least squares {w.attrs[ATTR_LOSSES]}): the "
        f"modes were fitted on the FRFs times (i w)^{w.k} and are reported as given "
        f"({ds.attrs.get(names.ATTR_QUANTITY)}); attrs {ATTR_QUANTITY}, {ATTR_LOSSES}",
        AssumptionWarning,
    )
    return out
