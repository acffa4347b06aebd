"""How each identified mode holds as the detection threshold and the analysis band vary.

The AMI counterpart of a stabilization chart. A PolyMAX user trusts a pole that stays put as the
model order grows; AMI has no model order to sweep, but its mode count is decided by two
choices: the false-alarm probability ``pfa`` of the subtraction's stop test (the detection
threshold) and the analysis band. :func:`stability` re-runs :func:`ami_xr.identify` for every
combination of a few thresholds and a few bands (the reference band, and the same band trimmed
at both ends) and asks, for each mode of the reference identification, in which of those
variants it is found again.

* **Match.** A variant's mode matches a reference mode ``k`` when ``|lam - lam_k| <
  |Re lam_k|`` (half the half-power bandwidth ``2 |Re lam_k|``); pairs are taken nearest first,
  each mode at most once (:func:`ami_xr.core.matching.match_nearest`).
* **Fraction.** ``stability_fraction`` is the share of the variants whose band contains the
  mode in which it is found. A mode found in every such variant (fraction 1) is *solid*; a
  mode that appears only with the loosest threshold, or only in one band, is not.
* **Spread.** ``stability_frequency_spread`` is the standard deviation of the matched natural
  frequencies (Hz; NaN when the mode is matched in fewer than two variants).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import common as c
from ami_xr.ami.identify import identify
from ami_xr.ami.settings import SubtractSettings, from_attrs
from ami_xr.core.matching import match_nearest
from ami_xr.errors import AmiXrValueError
from ami_xr.progress import Progress

__all__ = ["DEFAULT_BAND_TRIM", "DEFAULT_PFA", "MATCH_TOLERANCE", "stability", "variant_label"]

#: Detection thresholds of the variants (the subtraction's false-alarm probability).
DEFAULT_PFA = (1e-2, 1e-3, 1e-4, 1e-5)
#: Band variants: the reference band, and the band with 10 % of its width cut at each end.
DEFAULT_BAND_TRIM = (0.0, 0.1)
#: Match radius in units of |Re lam| (half the half-power bandwidth).
MATCH_TOLERANCE = 1.0


def variant_label(pfa: float, trim: float) -> str:
    """``"pfa=1e-3, full band"`` or ``"pfa=1e-3, band 10%-trimmed"``."""
    mantissa, exponent = f"{pfa:.0e}".split("e")
    p = f"{mantissa}e{int(exponent)}"
    band = "full band" if trim == 0 else f"band {100 * trim:g}%-trimmed"
    return f"pfa={p}, {band}"


def _check(pfa: Any, band_trim: Any) -> tuple[tuple, tuple]:
    def floats(x: Any, name: str, ok, allowed: str) -> tuple[float, ...]:
        try:
            values = tuple(float(v) for v in np.atleast_1d(np.asarray(x, dtype=float)))
        except (TypeError, ValueError):
            values = ()
        if not values or not all(ok(v) for v in values) or len(set(values)) != len(values):
            raise AmiXrValueError(f"{name}: expected distinct numbers {allowed}, got {x!r}")
        return values

    pfas = floats(pfa, "pfa", lambda v: 0 < v < 1, "in (0, 1)")
    trims = floats(band_trim, "band_trim", lambda v: 0 <= v < 0.5, "in [0, 0.5)")
    return pfas, trims


def _reference_band(result: xr.Dataset, ds: xr.Dataset) -> tuple[float, float]:
    f = ds[names.FREQUENCY].values
    lo = float(result.attrs.get(names.ATTR_BAND_FMIN, f[0]))
    hi = float(result.attrs.get(names.ATTR_BAND_FMAX, f[-1]))
    return lo, hi


def stability(
    ds: xr.Dataset,
    result: xr.Dataset | None = None,
    *,
    pfa: Sequence[float] = DEFAULT_PFA,
    band_trim: Sequence[float] = DEFAULT_BAND_TRIM,
    progress: bool = False,
    **identify_kwargs: Any,
) -> xr.Dataset:
    """Re-identify under other thresholds and bands; say how each mode of ``result`` holds.

    Parameters
    ----------
    ds : xarray.Dataset
        The FRF Dataset ``result`` was identified from.
    result : xarray.Dataset, optional
        The reference identification (default ``ami_xr.identify(ds, **identify_kwargs)``).
    pfa : sequence of float
        False-alarm probabilities of the subtraction's stop test, one set of variants each
        (default 1e-2, 1e-3, 1e-4, 1e-5: from loose to strict).
    band_trim : sequence of float
        Fractions of the reference analysis band's width cut at each end, one set of variants
        each (default 0 and 0.1: the band itself and the band 10 % narrower at both ends).
        Each variant passes its band to identify as ``fmin``/``fmax``.
    progress : bool
        A bar of the variants done on stderr.
    **identify_kwargs
        Other options of :func:`ami_xr.identify`, the same for every variant.

    Returns
    -------
    xarray.Dataset
        ``result`` with, on the new dim ``stability_variant`` (``len(pfa) * len(band_trim)``
        variants, labelled e.g. ``"pfa=1e-3, band 10%-trimmed"``; coords ``stability_pfa``,
        ``stability_band_fmin``, ``stability_band_fmax`` in Hz): ``stability_found`` and
        ``stability_in_band`` (mode, stability_variant) bool, ``stability_frequency`` (mode,
        stability_variant) Hz of the matched mode (NaN if none), ``stability_fraction`` (mode)
        in [0, 1] over the variants whose band holds the mode, ``stability_frequency_spread``
        (mode) Hz; attrs ``stability_rule`` and ``stability_match_tolerance``.
    """
    c.check_frf(ds, "stability")
    pfas, trims = _check(pfa, band_trim)
    if result is not None and (
        not isinstance(result, xr.Dataset) or names.EIGENVALUE not in result
    ):
        raise AmiXrValueError(
            f"result: expected an identification result with {names.EIGENVALUE!r} "
            "(from ami_xr.identify), or None"
        )
    own_reference = result is None
    if own_reference:
        result = identify(ds, **identify_kwargs)
    lo, hi = _reference_band(result, ds)
    n_mode = result.sizes.get(names.MODE, 0)
    lam_ref = np.atleast_1d(result[names.EIGENVALUE].values).astype(np.complex128)
    lam_ref = np.where(lam_ref.imag < 0, lam_ref.conj(), lam_ref)
    f_ref = np.abs(lam_ref) / (2 * np.pi)
    usable = np.isfinite(lam_ref) & (lam_ref.real < 0)
    variants = [(p, t) for t in trims for p in pfas]
    n_var = len(variants)
    found = np.zeros((n_mode, n_var), bool)
    in_band = np.zeros((n_mode, n_var), bool)
    freq = np.full((n_mode, n_var), np.nan)
    fmins, fmaxs = np.empty(n_var), np.empty(n_var)
    ref_pfa = from_attrs(SubtractSettings, result.attrs).pfa if own_reference else None
    with Progress(
        "stability: identify variants", total=n_var, unit="variant", enabled=progress
    ) as bar:
        for v, (p, t) in enumerate(variants):
            width = hi - lo
            f0, f1 = lo + t * width, hi - t * width
            fmins[v], fmaxs[v] = f0, f1
            in_band[:, v] = usable & (f_ref >= f0) & (f_ref <= f1)
            if own_reference and t == 0 and p == ref_pfa:
                out = result  # the reference itself: same threshold, same band
            else:
                kwargs = {**identify_kwargs, "fmin": f0, "fmax": f1}
                with warnings.catch_warnings():  # the variants' warnings are not the user's
                    warnings.simplefilter("ignore")
                    out = identify(ds, pfa=p, **kwargs)
            bar.update()
            if out.sizes.get(names.MODE, 0) == 0 or not usable.any():
                continue
            lam_v = np.atleast_1d(out[names.EIGENVALUE].values)
            lam_v = np.where(lam_v.imag < 0, lam_v.conj(), lam_v)  # upper half plane
            ref_index, index = match_nearest(lam_v, lam_ref[usable], MATCH_TOLERANCE)
            rows = np.flatnonzero(usable)[ref_index]
            hit = in_band[rows, v]
            rows, ids = rows[hit], index[hit]
            found[rows, v] = True
            freq[rows, v] = np.abs(lam_v[ids]) / (2 * np.pi)
    n_in = in_band.sum(axis=1)
    n_found = found.sum(axis=1)
    fraction = np.where(n_in > 0, n_found / np.maximum(n_in, 1), np.nan)
    spread = np.full(n_mode, np.nan)
    several = n_found >= 2
    spread[several] = [np.std(freq[k, found[k]]) for k in np.flatnonzero(several)]
    return _assemble(result, variants, fmins, fmaxs, found, in_band, freq, fraction, spread)


def _assemble(result, variants, fmins, fmaxs, found, in_band, freq, fraction, spread):
    dims2 = (names.MODE, names.STABILITY_VARIANT)
    hz = {names.ATTR_UNITS: "Hz"}
    labels = [variant_label(p, t) for p, t in variants]
    out = result.assign_coords(
        {
            names.STABILITY_VARIANT: (names.STABILITY_VARIANT, labels),
            names.STABILITY_PFA: (
                names.STABILITY_VARIANT,
                np.array([p for p, _ in variants]),
                {names.ATTR_UNITS: "1", names.ATTR_LONG_NAME: "false-alarm probability"},
            ),
            names.STABILITY_FMIN: (names.STABILITY_VARIANT, fmins, hz),
            names.STABILITY_FMAX: (names.STABILITY_VARIANT, fmaxs, hz),
        }
    )
    out = out.assign(
        {
            names.STABILITY_FOUND: (
                dims2,
                found,
                {names.ATTR_LONG_NAME: "mode found again in the variant"},
            ),
            names.STABILITY_IN_BAND: (
                dims2,
                in_band,
                {names.ATTR_LONG_NAME: "mode inside the variant's analysis band"},
            ),
            names.STABILITY_FREQUENCY: (
                dims2,
                freq,
                {**hz, names.ATTR_LONG_NAME: "natural frequency of the matched mode"},
            ),
            names.STABILITY_FRACTION: (
                (names.MODE,),
                fraction,
                {
                    names.ATTR_UNITS: "1",
                    names.ATTR_LONG_NAME: "share of the in-band variants that find the mode "
                    "(1: solid)",
                },
            ),
            names.STABILITY_FREQUENCY_SPREAD: (
                (names.MODE,),
                spread,
                {**hz, names.ATTR_LONG_NAME: "std of the matched natural frequencies"},
            ),
        }
    )
    out.attrs[names.ATTR_STABILITY_RULE] = (
        f"identify re-run for pfa in {sorted({p for p, _ in variants}, reverse=True)} and the "
        "analysis band trimmed at each end by "
        f"{sorted({100 * t for _, t in variants})} % of its width; a variant's mode matches a "
        f"mode when |lam - lam_mode| < {MATCH_TOLERANCE:g} |Re lam_mode| (nearest first, one to "
        "one); stability_fraction = found / variants whose band holds the mode; 1 = solid"
    )
    out.attrs[names.ATTR_STABILITY_TOLERANCE] = MATCH_TOLERANCE
    return out
