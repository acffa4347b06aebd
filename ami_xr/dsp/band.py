"""The analysis band: the lines where the excitation is valid, or the band the user gives.

An FRF estimated from force and response histories (:func:`ami_xr.frf`,
:func:`ami_xr.impact_frf`) carries the force autospectrum ``force_autospectrum`` and the
coherence ``coherence``. Where the force has fallen far below its low-frequency level (a hammer
tip excites nothing above its first spectral notch) the FRF is noise divided by almost nothing:
peaks there are not modes. :func:`analysis_band` picks the band by default as follows.

* **Force rule.** The low-frequency level of the force is the median of ``force_autospectrum``
  over the lowest ``low_fraction`` (10 %) of the lines above 0 Hz. A line passes when the force,
  smoothed by a running median over ``window`` lines, lies within ``force_drop_db`` (20 dB) of
  that level (several references: every one must pass).
* **Coherence rule.** Coherence dips at every antiresonance (little response, the same noise),
  so a single line of low coherence must not cut the band. A line passes when at least
  ``coherence_fraction`` (half) of the ``window`` lines around it have coherence
  ``>= coherence_min`` (0.8; several points: the median over points). The level is set on the
  hammer test of ``shared/data``: below 6 kHz its coherence is above 0.99 except at
  antiresonances, where it falls to 0.55-0.9 for up to 100 lines (1.61-1.72 kHz) while the
  force is within 3 dB of its low-frequency level, so 0.9 would end the band at 1.6 kHz; above
  the force's band it is 0.5-0.85 on most lines, which 0.8 rejects. The random error of
  ``|H1|`` from ``n`` averages is ``sqrt((1 - coh) / (2 coh n))``: 16 % at 0.8 for ``n = 1``.
* The band is the contiguous run of lines that pass both rules, from the lowest line above
  0 Hz that passes up to the last line before the first one that fails.

``window`` is ``max(5, n_lines // 256)`` lines, made odd (101 lines of 1 Hz for a 25.6 kHz
hammer test). A Dataset without ``force_autospectrum`` and ``coherence`` (a bare FRF, simulated
data) is analysed over the whole band. ``fmin``/``fmax`` override either limit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError

FORCE_DROP_DB = 20.0
COHERENCE_MIN = 0.8
COHERENCE_FRACTION = 0.5
LOW_FRACTION = 0.1

RULE_EXCITATION = "excitation"  # picked from force autospectrum and coherence
RULE_WHOLE = "whole"  # no excitation information: every line
RULE_USER = "user"  # both limits given


@dataclass(frozen=True)
class Band:
    """An analysis band [fmin, fmax] in Hz, the rule that chose it and why (one sentence)."""

    fmin: float
    fmax: float
    rule: str
    user_given: str  # "", "fmin", "fmax" or "fmin,fmax"
    reason: str

    def attrs(self) -> dict:
        return {
            names.ATTR_BAND_FMIN: float(self.fmin),
            names.ATTR_BAND_FMAX: float(self.fmax),
            names.ATTR_BAND_RULE: self.rule,
            names.ATTR_BAND_USER_GIVEN: self.user_given,
            names.ATTR_BAND_REASON: self.reason,
            names.ATTR_BAND_FORCE_DROP_DB: FORCE_DROP_DB,
            names.ATTR_BAND_COHERENCE_MIN: COHERENCE_MIN,
            names.ATTR_BAND_COHERENCE_FRACTION: COHERENCE_FRACTION,
        }


def _window(n: int) -> int:
    w = max(5, n // 256)
    return w + 1 - w % 2


def _running_median(x: np.ndarray, w: int) -> np.ndarray:
    pad = np.pad(x, w // 2, mode="edge")
    return np.median(np.lib.stride_tricks.sliding_window_view(pad, w), axis=-1)


def _running_mean(x: np.ndarray, w: int) -> np.ndarray:
    pad = np.pad(x.astype(float), w // 2, mode="edge")
    c = np.concatenate([[0.0], np.cumsum(pad)])
    return (c[w:] - c[:-w]) / w


def valid_lines(
    frequency: np.ndarray,
    force_autospectrum: np.ndarray | None,
    coherence: np.ndarray | None,
) -> tuple[np.ndarray, str]:
    """Boolean mask of the lines passing the force and coherence rules (module docstring), and a
    description of the rules applied. ``force_autospectrum`` is ``(..., frequency)``,
    ``coherence`` ``(point, frequency)``; either may be None (rule not applied)."""
    f = np.asarray(frequency, dtype=float)
    n = f.size
    w = _window(n)
    ok = f > 0
    rules = []
    if force_autospectrum is not None:
        g = np.asarray(force_autospectrum, dtype=float).reshape(-1, n)
        above = np.flatnonzero(f > 0)
        low = above[: max(1, int(round(LOW_FRACTION * above.size)))]
        for row in g:
            level = np.median(row[low])
            smooth = _running_median(row, w)
            with np.errstate(divide="ignore", invalid="ignore"):
                ok &= (level > 0) & (smooth >= level * 10 ** (-FORCE_DROP_DB / 10))
        rules.append(
            f"force autospectrum (running median of {w} lines) within {FORCE_DROP_DB:g} dB of "
            f"its low-frequency level (median of the lowest {LOW_FRACTION:.0%} of lines above "
            "0 Hz)"
        )
    if coherence is not None:
        coh = np.asarray(coherence, dtype=float).reshape(-1, n)
        med = np.nanmedian(coh, axis=0) if coh.shape[0] > 1 else coh[0]
        frac = _running_mean(np.nan_to_num(med) >= COHERENCE_MIN, w)
        ok &= frac >= COHERENCE_FRACTION
        rules.append(
            f"coherence >= {COHERENCE_MIN:g} on at least {COHERENCE_FRACTION:.0%} of the {w} "
            "lines around each line"
        )
    return ok, " and ".join(rules)


def _excitation_band(ds: xr.Dataset) -> Band | None:
    f = np.asarray(ds[names.FREQUENCY].values, dtype=float)
    gff = coh = None
    if names.FORCE_AUTOSPECTRUM in ds and names.FREQUENCY in ds[names.FORCE_AUTOSPECTRUM].dims:
        gff = ds[names.FORCE_AUTOSPECTRUM].transpose(..., names.FREQUENCY).values
    if names.COHERENCE in ds and names.FREQUENCY in ds[names.COHERENCE].dims:
        coh = ds[names.COHERENCE].transpose(..., names.FREQUENCY).values
        if not np.any(np.isfinite(coh)):
            coh = None
    if gff is None and coh is None:
        return None
    ok, rule = valid_lines(f, gff, coh)
    lines = np.flatnonzero(ok)
    if lines.size == 0:
        return Band(
            float(f[0]),
            float(f[-1]),
            RULE_WHOLE,
            "",
            f"no line passes the excitation rule ({rule}); whole band used",
        )
    lo = int(lines[0])
    fail = np.flatnonzero(~ok[lo:])
    hi = lo + int(fail[0]) - 1 if fail.size else f.size - 1
    why = f"excitation valid: {rule}"
    return Band(float(f[lo]), float(f[hi]), RULE_EXCITATION, "", why)


def analysis_band(ds: xr.Dataset, fmin: float | None = None, fmax: float | None = None) -> Band:
    """The band identification analyses (see the module docstring); ``fmin``/``fmax`` (Hz)
    override the chosen limits. A Dataset that already records a band (the output of a phase
    run with one) keeps it unless limits are given."""
    f = np.asarray(ds[names.FREQUENCY].values, dtype=float)
    for value, arg in ((fmin, "fmin"), (fmax, "fmax")):
        if value is not None and not (
            isinstance(value, (int, float, np.number)) and np.isfinite(value) and value >= 0
        ):
            raise AmiXrValueError(f"{arg}: expected a number >= 0 Hz or None, got {value!r}")
    if fmin is not None and fmax is not None and fmin >= fmax:
        raise AmiXrValueError(f"fmin, fmax: expected fmin < fmax, got {fmin!r} >= {fmax!r}")
    if fmin is None and fmax is None and names.ATTR_BAND_FMIN in ds.attrs:
        a = ds.attrs
        return Band(
            float(a[names.ATTR_BAND_FMIN]),
            float(a[names.ATTR_BAND_FMAX]),
            str(a.get(names.ATTR_BAND_RULE, RULE_USER)),
            str(a.get(names.ATTR_BAND_USER_GIVEN, "")),
            str(a.get(names.ATTR_BAND_REASON, "")),
        )
    auto = _excitation_band(ds) if fmin is None or fmax is None else None
    if auto is None:
        auto = Band(
            float(f[0]),
            float(f[-1]),
            RULE_WHOLE,
            "",
            "no excitation information (force_autospectrum, coherence): whole band",
        )
    given = [a for a, v in (("fmin", fmin), ("fmax", fmax)) if v is not None]
    if not given:
        band = auto
    else:
        lo = float(fmin) if fmin is not None else auto.fmin
        hi = float(fmax) if fmax is not None else auto.fmax
        rule = RULE_USER if len(given) == 2 else auto.rule
        reason = "given by the user" if len(given) == 2 else f"{given[0]} given; else {auto.reason}"
        band = Band(lo, hi, rule, ",".join(given), reason)
    inside = (f >= band.fmin) & (f <= band.fmax)
    if np.count_nonzero(inside) < 8:
        raise AmiXrValueError(
            f"fmin, fmax: the band {band.fmin:g}-{band.fmax:g} Hz holds "
            f"{np.count_nonzero(inside)} lines of the FRF ({f[0]:g}-{f[-1]:g} Hz); "
            "at least 8 needed"
        )
    return band


def is_whole(ds: xr.Dataset, band: Band) -> bool:
    f = np.asarray(ds[names.FREQUENCY].values, dtype=float)
    return band.fmin <= f[0] and band.fmax >= f[-1]


def apply_band(ds: xr.Dataset, band: Band) -> xr.Dataset:
    """``ds`` restricted to the lines of ``band`` (every variable on ``frequency``), with the
    band recorded in its attributes (a Dataset over the whole band is not copied)."""
    if not is_whole(ds, band):
        f = ds[names.FREQUENCY]
        ds = ds.isel({names.FREQUENCY: ((f >= band.fmin) & (f <= band.fmax)).values})
    else:
        ds = ds.copy(deep=False)
    ds.attrs.update(band.attrs())
    return ds


def band_message(band: Band, ds: xr.Dataset) -> str:
    f = np.asarray(ds[names.FREQUENCY].values, dtype=float)
    return (
        f"analysis band {band.fmin:g}-{band.fmax:g} Hz of {f[0]:g}-{f[-1]:g} Hz ({band.reason}); "
        "no mode is reported outside it; set fmin/fmax (ami-xr identify --fmin/--fmax) to change it"
    )
