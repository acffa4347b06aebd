"""The analysis band: the lines where the excitation is valid, or the band the user gives.

An FRF estimated from force and response histories (:func:`ami_xr.frf`,
:func:`ami_xr.impact_frf`) carries the force autospectrum ``force_autospectrum`` and the
coherence ``coherence``. Where the force has fallen far below its level in the band (a hammer
tip excites nothing above its first spectral notch) the FRF is noise divided by almost nothing:
peaks there are not modes. :func:`analysis_band` picks the band by default as follows.

* **Smoothing window.** Both rules look at each line through a window of constant relative
  width: the lines within ``+-RELATIVE_WINDOW / 2`` (1/32) of the line's frequency, at least
  ``2 MIN_HALF_WIDTH + 1`` (5) lines, cut off at the ends of the data (no padding). A window
  that depends on the line's own frequency, not on how many lines the Dataset holds, is what
  makes the rule independent of where the data were cut; it also follows the width of
  resonances and antiresonances, which grows with frequency at a given damping. On the hammer
  test of ``shared/data`` (1 Hz lines) it spans 5 lines at 50 Hz, 103 at 1650 Hz and 305 at
  4.9 kHz. The 0 Hz line is never part of a window.
* **Force rule.** The force's reference level is the MAXIMUM over the lines above 0 Hz of the
  force autospectrum smoothed by a running median over the window above. A line passes when
  its smoothed force lies within ``FORCE_DROP_DB`` (20 dB) of that level -- or, when the FRF
  has a coherence, within ``FORCE_FLOOR_DB`` (40 dB): the coherence then says where the
  response is clean, and a clean peak where the force is low (a sweep's lowest modes, 28 dB
  below the force's peak in a shaker test, issue 37) is a mode; below 40 dB the excitation is
  no longer the source (a sweep's harmonics past its end, a hammer tip's notch) whatever the
  coherence. Several references: every one must pass. Removing lines from either end of the
  data can only lower the maximum, so every line that passes on the whole record passes on any
  cut of it (issue 20).
* **Coherence rule.** Coherence dips at every antiresonance (little response, the same noise),
  so a single line of low coherence must not cut the band. A line passes when at least
  ``coherence_fraction`` (half) of the lines of its window have coherence ``>= coherence_min``
  (several points: the second highest over points, :func:`clean_coherence`, since the force
  shows where some points respond cleanly). What a coherence means depends on the averages:
  the random error of ``|H1|`` is ``sqrt((1 - coh) / (coh n))``; a line passes where it is at
  most ``1 / sqrt(12)`` (29 %), i.e. ``coherence_min = 1 / (1 + n / 12)``: 0.8 at the hammer
  test's 3 averages (the level was set there: below 6 kHz its coherence is above 0.99 except at
  antiresonances, where it falls to 0.55-0.9 for up to 100 lines while the force is within
  3 dB of its low-frequency level, so 0.9 would end the band at 1.6 kHz; above the force's band
  it is 0.5-0.85 on most lines, which 0.8 rejects), 0.44 at 15 averages (a displacement sensor's
  FRF from 15 averages is good to 26 % where its coherence is 0.5; a fixed 0.8 cut a shaker
  test's band at 18 Hz below a clean 21 Hz mode). ``n_averages`` from the FRF's attribute
  (``ami_xr.frf`` writes it), 3 without one.
* **The band** runs from the first to the last line that passes both rules inside the run of
  lines where the force lies within ``FORCE_DROP_DB`` (the run holding most passing lines;
  without a force: all lines), then, with a coherence, on down through the lines below it that
  pass with the force down to ``FORCE_FLOOR_DB``, as long as they pass without a gap (a shaker
  cannot push at low frequency; never upwards: a force rolling off at the top is a hammer
  tip's or a sweep's end, past which the response is harmonics and noise). A line whose force
  fails with passing lines within its window on both sides passes (a gap of the smoothing: a
  repeated sweep fills every other line, and the median of a window flips with its parity).
  Lines that fail inside the band stay: a stretch of low coherence between two modes (an
  antiresonance, a building's quiet range between its modes) is no reason to drop the modes
  on either side -- the longest run of passing lines, the rule before issue 37, dropped a
  wheel's 667 and 1625 Hz modes and four of a building's five. A clean peak where the force is
  weak at the low end joins the band when the coherence holds from the band's edge to it (the
  hammer test's coherence is 0.9-0.98 at 9-14 kHz with the force 29-40 dB down: left out, and
  taking its 4.9-6.8 kHz in cost 16 of 23 visible peaks below 4.9 kHz and twice the time).
  On the hammer test the band is 12-4867 Hz: below 12 Hz the coherence is 0.02-0.8, at
  4867 Hz the smoothed force is 20 dB below its maximum.

A Dataset without ``force_autospectrum`` and ``coherence`` (a bare FRF, simulated data) is
analysed over the whole band. ``fmin``/``fmax`` override either limit. When ``[a, b]`` lies
inside the band chosen on the whole data, ``ds.sel(frequency=slice(a, b))`` passes every line
(up to the windows cut off at the new ends), so its band is the whole cut: the same lines as
``fmin=a, fmax=b``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError

FORCE_DROP_DB = 20.0
FORCE_FLOOR_DB = 40.0  # with a coherence: the force may fall this far where the response is clean
COHERENCE_MIN = 0.8  # at DEFAULT_AVERAGES; coherence_min(n) for n averages
DEFAULT_AVERAGES = 3.0
MAX_RELATIVE_ERROR = 12.0**-0.5  # of |H1| on a line, from the coherence and the averages
COHERENCE_FRACTION = 0.5
RELATIVE_WINDOW = 1.0 / 16.0  # window width over frequency (+-1/32 around each line)
MIN_HALF_WIDTH = 2  # lines on each side at least

ATTR_FORCE_FLOOR_DB = "analysis_band_force_floor_db"  # the force rule where there is a coherence
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
            ATTR_FORCE_FLOOR_DB: FORCE_FLOOR_DB,
            names.ATTR_BAND_COHERENCE_MIN: COHERENCE_MIN,
            names.ATTR_BAND_COHERENCE_FRACTION: COHERENCE_FRACTION,
        }


def _windows(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) of each line's window (module docstring); ``f`` increasing."""
    half = 0.5 * RELATIVE_WINDOW * f
    i = np.arange(f.size)
    lo = np.minimum(np.searchsorted(f, f - half, side="left"), i - MIN_HALF_WIDTH)
    hi = np.maximum(np.searchsorted(f, f + half, side="right"), i + MIN_HALF_WIDTH + 1)
    return np.clip(lo, 0, None), np.minimum(hi, f.size)


def _running_median(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Median of ``x[lo[i]:hi[i]]`` for every ``i``, windows of one length at a time."""
    out = np.empty(x.size)
    length = hi - lo
    for n in np.unique(length):
        at = np.flatnonzero(length == n)
        out[at] = np.median(x[lo[at, None] + np.arange(n)], axis=1)
    return out


def _running_mean(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    c = np.concatenate([[0.0], np.cumsum(x, dtype=float)])
    return (c[hi] - c[lo]) / (hi - lo)


def coherence_min(n_averages: float | None = None) -> float:
    """The coherence a line needs: the random error of ``|H1|`` from ``n`` averages,
    ``sqrt((1 - coh) / (coh n))``, at most ``1 / sqrt(12)`` (29 %): ``1 / (1 + n / 12)``, 0.8
    at the hammer test's 3 averages (where the level was set), 0.44 at 15. Without a number of
    averages: ``DEFAULT_AVERAGES`` (3)."""
    n = float(n_averages) if n_averages and n_averages > 0 else DEFAULT_AVERAGES
    return 1.0 / (1.0 + n * MAX_RELATIVE_ERROR**2)


def valid_lines(
    frequency: np.ndarray,
    force_autospectrum: np.ndarray | None,
    coherence: np.ndarray | None,
    n_averages: float | None = None,
) -> tuple[np.ndarray, str]:
    """Boolean mask of the lines passing the force and coherence rules (module docstring), and a
    description of the rules applied. ``force_autospectrum`` is ``(..., frequency)``,
    ``coherence`` ``(point, frequency)``; either may be None (rule not applied). Lines at 0 Hz
    never pass and are no part of any window."""
    f = np.asarray(frequency, dtype=float)
    n = f.size
    pos = np.flatnonzero(f > 0)
    lo, hi = _windows(f[pos])
    ok = np.zeros(n, bool)
    ok_pos = np.ones(pos.size, bool)
    rules = []
    if force_autospectrum is not None:
        ok_pos &= force_lines(f, force_autospectrum, coherence is not None)[pos]
        weak = (
            f" ({FORCE_FLOOR_DB:g} dB on the lines below that band joined to it without a gap "
            "in the coherence)"
            if coherence is not None
            else ""
        )
        rules.append(
            f"force autospectrum (running median over +-{RELATIVE_WINDOW / 2:.3g} of each "
            f"line's frequency) within {FORCE_DROP_DB:g} dB of its maximum{weak}"
        )
    if coherence is not None:
        coh = np.asarray(coherence, dtype=float).reshape(-1, n)[:, pos]
        level = coherence_min(n_averages)
        frac = _running_mean(clean_coherence(coh) >= level, lo, hi)
        ok_pos &= frac >= COHERENCE_FRACTION
        rules.append(
            f"coherence >= {level:.3g} ({n_averages or DEFAULT_AVERAGES:g} averages) on at least "
            f"{COHERENCE_FRACTION:.0%} of the lines within +-{RELATIVE_WINDOW / 2:.3g} of each "
            "line's frequency"
        )
    ok[pos] = ok_pos
    return ok, " and ".join(rules)


def clean_coherence(coherence: np.ndarray) -> np.ndarray:
    """The coherence (points, lines) the rule judges each line by: the second highest over
    the points (the highest of two, the one of one; NaN as 0).

    Whether the force excites the structure at a frequency shows at the points that respond
    there above their sensor's noise; elsewhere the coherence is low for a reason of the
    point's own (a node of the mode, a sensor whose noise is white in another quantity: a
    velocity sensor's receptance falls towards its noise above the modes). The median over
    points asked that most points be clean, and cut a clean, well-excited mode out of the band
    where only a few points see it (mobility from 15 averages, 6 points: a 32 Hz mode left
    out at 25 Hz, ``scripts/benchmark_lab_band.py --quantity velocity``). Two points must agree,
    so that one channel's crosstalk with the force does not extend the band."""
    c = np.sort(np.nan_to_num(np.asarray(coherence, dtype=float), nan=0.0), axis=0)
    return c[-2] if c.shape[0] >= 3 else c[-1]


def force_lines(frequency: np.ndarray, force_autospectrum, with_coherence: bool) -> np.ndarray:
    """Lines (bool, every line of ``frequency``) whose smoothed force lies within
    ``FORCE_DROP_DB`` of its maximum (``FORCE_FLOOR_DB`` ``with_coherence``); 0 Hz never."""
    f = np.asarray(frequency, dtype=float)
    n = f.size
    pos = np.flatnonzero(f > 0)
    ok = np.zeros(n, bool)
    if not pos.size:
        return ok
    lo, hi = _windows(f[pos])
    drop = FORCE_FLOOR_DB if with_coherence else FORCE_DROP_DB
    ok_pos = np.ones(pos.size, bool)
    for row in np.asarray(force_autospectrum, dtype=float).reshape(-1, n)[:, pos]:
        smooth = _running_median(row, lo, hi)
        level = np.max(smooth)
        with np.errstate(divide="ignore", invalid="ignore"):
            ok_pos &= (level > 0) & (smooth >= level * 10 ** (-drop / 10))
    # a failing line with passing lines within its window on both sides is a gap of the
    # smoothing, not a roll-off (a repeated sweep's spectrum fills every other line: the median
    # of a window flips with its parity), so it passes; a roll-off fails on one side
    c = np.concatenate([[0], np.cumsum(ok_pos)])
    i = np.arange(pos.size)
    ok_pos |= (c[i] - c[lo] > 0) & (c[hi] - c[i + 1] > 0)
    ok[pos] = ok_pos
    return ok


def band_span(ok: np.ndarray, within: np.ndarray | None = None) -> tuple[int, int] | None:
    """First and last index of ``ok`` inside the run of ``within`` (default: all lines)
    holding most ``ok`` lines (the lowest on a tie); None when no line is ``ok``."""
    ok = np.asarray(ok, dtype=bool)
    within = np.ones(ok.size, bool) if within is None else np.asarray(within, dtype=bool)
    edges = np.diff(np.concatenate([[0], within.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    counts = [int(ok[a:b].sum()) for a, b in zip(starts, ends, strict=True)]
    if not counts or max(counts) == 0:
        return None
    k = int(np.argmax(counts))
    idx = np.flatnonzero(ok[starts[k] : ends[k]]) + starts[k]
    return int(idx[0]), int(idx[-1])


def _extended(run: tuple[int, int], ok: np.ndarray) -> tuple[int, int]:
    """``run`` grown downwards through the contiguous lines that pass ``ok`` (the force within
    ``FORCE_FLOOR_DB`` and a clean coherence): a shaker's force falls at low frequency while
    the response stays clean. Never upwards: a force rolling off at the top is a hammer tip's
    or a sweep's end, where the response is harmonics and noise."""
    lo, hi = run
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    return lo, hi


def longest_run(ok: np.ndarray) -> tuple[int, int] | None:
    """First and last index of the longest run of True in ``ok`` (the lowest on a tie)."""
    edges = np.diff(np.concatenate([[0], np.asarray(ok, dtype=np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    if starts.size == 0:
        return None
    k = int(np.argmax(ends - starts))
    return int(starts[k]), int(ends[k]) - 1


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
    n_avg = ds.attrs.get(names.ATTR_N_AVERAGES)
    try:
        n_avg = float(n_avg) if n_avg is not None else None
    except (TypeError, ValueError):
        n_avg = None
    ok, rule = valid_lines(f, gff, coh, n_avg)
    run = band_span(ok, None if gff is None else force_lines(f, gff, False))
    if run is not None and gff is not None and coh is not None:
        run = _extended(run, ok)
    if run is None:
        return Band(
            float(f[0]),
            float(f[-1]),
            RULE_WHOLE,
            "",
            f"no line passes the excitation rule ({rule}); whole band used",
        )
    lo, hi = run
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


def band_lines(ds: xr.Dataset, band: Band) -> xr.Dataset:
    """``ds`` restricted to the lines of ``band`` (every variable on ``frequency``); ``ds``
    itself (not copied) when the band is the whole of it. The band is not recorded: see
    :func:`apply_band`."""
    if is_whole(ds, band):
        return ds
    f = ds[names.FREQUENCY]
    return ds.isel({names.FREQUENCY: ((f >= band.fmin) & (f <= band.fmax)).values})


def apply_band(ds: xr.Dataset, band: Band) -> xr.Dataset:
    """``ds`` restricted to the lines of ``band`` (every variable on ``frequency``), with the
    band recorded in its attributes (a Dataset over the whole band is not copied)."""
    lines = band_lines(ds, band)
    ds = ds.copy(deep=False) if lines is ds else lines
    # a new dict: isel shares the attrs dict with its source, and updating it in place wrote
    # this band into the caller's Dataset (a later identify of it then kept the band)
    ds.attrs = {**ds.attrs, **band.attrs()}
    return ds


def band_message(band: Band, ds: xr.Dataset) -> str:
    f = np.asarray(ds[names.FREQUENCY].values, dtype=float)
    return (
        f"analysis band {band.fmin:g}-{band.fmax:g} Hz of {f[0]:g}-{f[-1]:g} Hz ({band.reason}); "
        "no mode is reported outside it; set fmin/fmax (ami-xr identify --fmin/--fmax) to change it"
    )
