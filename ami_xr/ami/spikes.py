"""No noise spike as a mode (issue 37 item 3): narrow poles that the noise explains are dropped.

A pole fitted to a noise excursion looks like a mode of almost no damping: its half-power
bandwidth ``2 zeta fn`` is a fraction of a line, so that all its evidence is one or two lines,
where the noise alone reaches ``sigma sqrt(ln(n / p))`` somewhere among ``n`` lines with
probability ``p`` (``|e|^2 / sigma^2`` is exponential for complex Gaussian noise). A real mode
that narrow (a 0.2 %-damped mode on 0.06 Hz lines) stands far above that; a spike does not.

The rule, on the final modes, for each mode whose half-power bandwidth spans fewer than
``NARROW_LINES`` (2) lines:

* its contribution ``A_j / (i w - lam) + conj`` (with that of any other such pole within a
  line of it: two poles of opposite residue at one frequency cancel) at each point, at the
  lines within two lines of its frequency, over the local noise std of that point (the
  robust level of the residual, ``median |r| / sqrt(ln 2)``, over ``NOISE_HALF_WIDTH`` lines
  on either side) is its peak SNR at that point;
* the threshold is ``sqrt(ln(n_lines n_points / PFA))`` (``PFA`` = 0.01: the chance that the
  noise of the whole set puts one line that high);
* the pole is dropped when its SNR stays below the threshold at every point, or (3 points or
  more) exceeds it at one point only: a mode shows at more than one point.

Nor is a pole damped above ``zeta_max`` a mode (the limit the subtraction accepts a peak by):
the refinement's model-order step can fit one to the tail of a mode above the band or to the
end of a sweep (simulated lab tests: 9-57 %-damped poles at the band's top edge), and it is
reported in attr ``overdamped_dropped_modes`` instead.

Dropped modes are warned about (:class:`~ami_xr.errors.AssumptionWarning`), listed in attr
``noise_spike_dropped_modes`` (Hz), and their contribution moves from ``frf_synthesized`` to
``frf_residual``.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import chunked as ch
from ami_xr.ami import common as c
from ami_xr.caller import warn
from ami_xr.errors import AssumptionWarning

NARROW_LINES = 2.0
NOISE_HALF_WIDTH = 32
PFA = 0.01
ATTR_DROPPED = "noise_spike_dropped_modes"
ATTR_RULE = "noise_spike_rule"
ATTR_OVER_DROPPED = "overdamped_dropped_modes"
ATTR_OVER_RULE = "overdamped_rule"
OVER_RULE = (
    "a pole damped above zeta_max = {zeta_max} (the subtraction's physical limit) is not "
    "reported as a mode: the refinement fitted it to the tail of what lies beyond the band or "
    "to the background"
)
RULE = (
    f"a mode whose half-power bandwidth spans fewer than {NARROW_LINES:g} line(s) is dropped "
    f"when its peak contribution over the local residual noise stays below sqrt(ln(lines x "
    f"points / {PFA:g})) at every point, or at all but one of 3 or more points"
)


def _contribution(res: np.ndarray, lam: complex, omega: np.ndarray) -> np.ndarray:
    """``A_j / (i w - lam) + conj(A_j) / (i w - conj(lam))`` (P, L)."""
    s = 1j * omega[None, :]
    return res[:, None] / (s - lam) + np.conj(res)[:, None] / (s - np.conj(lam))


def _median_abs(r: np.ndarray) -> np.ndarray:
    """``median |r|`` along the last axis."""
    return np.median(np.abs(r), axis=-1)


def _contributions(result: xr.Dataset, modes: np.ndarray, like: xr.DataArray) -> xr.DataArray:
    """The summed contribution of ``modes`` (indices) at every point and line, (point,
    frequency): lazy, in ``like``'s chunks of points, when ``like`` is dask-backed."""
    res = result[names.RESIDUE].transpose(names.POINT, names.MODE).isel({names.MODE: modes})
    res = res.drop_vars(names.MODE, errors="ignore")
    if ch.is_lazy(like):
        res = res.chunk({names.POINT: like.chunksizes[names.POINT]})
    lam = np.asarray(result[names.EIGENVALUE].transpose(names.MODE).values)[modes]
    s = 2j * np.pi * np.asarray(result[names.FREQUENCY].values, dtype=float)
    dims = (names.MODE, names.FREQUENCY)
    up = xr.DataArray(1.0 / (s[None, :] - lam[:, None]), dims=dims)
    down = xr.DataArray(1.0 / (s[None, :] - np.conj(lam)[:, None]), dims=dims)
    return xr.dot(res, up, dim=names.MODE) + xr.dot(np.conj(res), down, dim=names.MODE)


def spike_modes(result: xr.Dataset) -> tuple[np.ndarray, np.ndarray]:
    """Which modes of ``result`` the rule (module docstring) drops, and each mode's largest
    peak SNR over the points (NaN where the mode is not narrow)."""
    n_mode = result.sizes.get(names.MODE, 0)
    drop = np.zeros(n_mode, bool)
    snr_max = np.full(n_mode, np.nan)
    need = (names.FRF_RESIDUAL, names.RESIDUE, names.EIGENVALUE, names.DAMPING_RATIO)
    if n_mode == 0 or any(v not in result for v in need):
        return drop, snr_max
    f = np.asarray(result[names.FREQUENCY].values, dtype=float)
    if f.size < 4:
        return drop, snr_max
    df = float(np.median(np.diff(f)))
    omega = 2.0 * np.pi * f
    fn = np.asarray(result[names.NATURAL_FREQUENCY].transpose(names.MODE).values, dtype=float)
    zeta = np.asarray(result[names.DAMPING_RATIO].transpose(names.MODE).values, dtype=float)
    lam = np.asarray(result[names.EIGENVALUE].transpose(names.MODE).values)
    res = result[names.RESIDUE].transpose(names.POINT, names.MODE).values
    # the residual is read a few lines per mode (per chunk of points when it is lazy)
    resid = result[names.FRF_RESIDUAL].transpose(names.POINT, names.FREQUENCY)
    n_point = resid.shape[0]
    threshold = math.sqrt(math.log(f.size * n_point / PFA))
    width = 2.0 * np.abs(zeta) * fn / df
    narrow = np.isfinite(width) & (width < NARROW_LINES)
    for k in np.flatnonzero(narrow):
        at = int(np.argmin(np.abs(f - fn[k])))
        near = slice(max(at - 2, 0), at + 3)
        local = slice(max(at - NOISE_HALF_WIDTH, 0), at + NOISE_HALF_WIDTH + 1)
        near_lines = resid.isel({names.FREQUENCY: local})
        sigma = ch.per_row(_median_abs, near_lines, names.FREQUENCY) / math.sqrt(math.log(2.0))
        # narrow poles within a line of each other act as one (two poles of opposite residue
        # at one frequency cancel: each alone looks strong, together they are noise)
        group = [m for m in range(n_mode) if abs(fn[m] - fn[k]) < df and narrow[m]]
        both = sum(_contribution(res[:, m], lam[m], omega[near]) for m in group)
        peak = np.abs(both).max(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            snr = np.where(sigma > 0, peak / sigma, np.inf)
        snr_max[k] = float(np.nanmax(snr))
        above = int(np.sum(snr >= threshold))
        drop[k] = above == 0 or (n_point >= 3 and above == 1)
    return drop, snr_max


def overdamped_modes(result: xr.Dataset, zeta_max: float) -> np.ndarray:
    """Which modes of ``result`` have a damping ratio above ``zeta_max`` (the physical limit
    the subtraction accepts a peak by): poles the refinement fitted to what lies beyond the
    band (the tail of a mode above it, the end of a sweep) or to the background, not modes."""
    if result.sizes.get(names.MODE, 0) == 0 or names.DAMPING_RATIO not in result:
        return np.zeros(result.sizes.get(names.MODE, 0), bool)
    zeta = np.asarray(result[names.DAMPING_RATIO].transpose(names.MODE).values, dtype=float)
    return np.isfinite(zeta) & (zeta > zeta_max)


def drop_noise_spikes(result: xr.Dataset, zeta_max: float | None = None) -> xr.Dataset:
    """``result`` without the modes :func:`spike_modes` drops, nor (``zeta_max`` given) those
    :func:`overdamped_modes` finds (labels stay 1..n), each said and recorded; the rules are
    recorded in attrs ``noise_spike_rule`` and ``overdamped_rule`` either way."""
    spikes, _ = spike_modes(result)
    result.attrs[ATTR_RULE] = RULE
    over = np.zeros_like(spikes)
    if zeta_max is not None:
        over = overdamped_modes(result, zeta_max) & ~spikes
        result.attrs[ATTR_OVER_RULE] = OVER_RULE.format(zeta_max=zeta_max)
    drop = spikes | over
    if not drop.any():
        return result
    fn = np.asarray(result[names.NATURAL_FREQUENCY].transpose(names.MODE).values, dtype=float)
    zeta = np.asarray(result[names.DAMPING_RATIO].transpose(names.MODE).values, dtype=float)
    if names.FRF_SYNTHESIZED in result and names.FRF_RESIDUAL in result:
        gone = _contributions(result, np.flatnonzero(drop), result[names.FRF_RESIDUAL])
        for v, sign in ((names.FRF_SYNTHESIZED, -1.0), (names.FRF_RESIDUAL, 1.0)):
            da = result[v]
            result[v] = (da + sign * gone).transpose(*da.dims).assign_attrs(da.attrs)
    out = c.keep_modes(result, ~drop)
    for which, attr, what in (
        (spikes, ATTR_DROPPED, "pole(s) narrower than a line that the noise explains"),
        (over, ATTR_OVER_DROPPED, f"pole(s) damped above zeta_max = {zeta_max}"),
    ):
        if not which.any():
            continue
        listed = [x for x in str(result.attrs.get(attr, "")).split(",") if x]
        out.attrs[attr] = ",".join(listed + [f"{x:.6g}" for x in fn[which]])
        said = ", ".join(
            f"{a:.6g} Hz (zeta {b:.2g})" for a, b in zip(fn[which], zeta[which], strict=True)
        )
        warn(
            f"identify: {int(which.sum())} {what} not reported as modes ({said}); attr {attr}",
            AssumptionWarning,
        )
    return out
