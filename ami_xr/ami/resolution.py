"""Frequency resolution of the identified modes (issue 37 item 4): flag, widen, advise.

A mode whose half-power bandwidth ``2 zeta f_n`` spans fewer than :data:`RESOLUTION_LINES`
lines of the FRF it was identified from is ``under_resolved``: its damping is decided by a
handful of lines and, for a Welch estimate, by the window's own smearing, which the noise
statistics of the fit do not see. :func:`resolution_checked` (called once by the
single-reference pipeline, after the modes are final) sets the flag, widens the damping
ratio's standard deviation by that resolution bias (combined in quadrature with the
statistical one), and says in one warning which modes are under-resolved and which segment
length (or line spacing) would resolve them all (the narrowest half-power bandwidth, usually
the lightest-damped mode's).

The bias of a flagged mode, as a damping ratio, is

    b = (1 + B_w) df / (2 f_n)

with ``df`` the line spacing and ``B_w`` the equivalent noise bandwidth of the Welch window in
lines, ``B_w = nfft sum(w^2) / (sum w)^2`` (1.5 for a Hann window with ``nfft = nperseg``),
when the FRF's provenance records an :func:`ami_xr.frf` estimate with a named window
(``B_w = 0`` otherwise: a measured FRF, an impact FRF, or a window given as an array). The
term ``df / (2 f_n)`` is the damping ratio whose half-power bandwidth is one line; the window's
term bounds how far its smearing widens a peak narrower than its own bandwidth. Biases add
(they are systematic, not independent noise); the reported standard deviations become

    damping_ratio_std = sqrt(std^2 + b^2)
    Re(eigenvalue_std) = sqrt(std_re^2 + (b omega_n / (1 - zeta^2))^2)

(``d zeta / d Re(lam) = -(1 - zeta^2) / omega_n``).

The advice puts :data:`RESOLUTION_LINES` lines in the half-power bandwidth of the narrowest
flagged mode at the damping left when the window's smearing is taken out in quadrature,
``sqrt(zeta^2 - (B_w df / (2 f_n))^2)``, but at least ``zeta /`` :data:`MAX_REFINEMENT`
(:func:`target_spacing`), as an ``nperseg`` for a Welch estimate (:func:`advice`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.ami import common as c
from ami_xr.caller import warn
from ami_xr.core import flags
from ami_xr.errors import AmiXrValueError, AssumptionWarning
from ami_xr.kernels import windows
from ami_xr.provenance import history

#: A mode is ``under_resolved`` when its half-power bandwidth ``2 zeta f_n`` spans fewer lines.
RESOLUTION_LINES = 3.0
#: The provenance record of a Welch FRF estimate (its parameters hold window, nperseg, nfft, fs).
WELCH_FUNCTION = "ami_xr.frf"
#: The advice takes the damping as low as the window's smearing leaves it, but never below
#: ``zeta`` over this factor: when the window is wider than the peak measured, the data say
#: only that the true damping is lower; a rerun with the advice sharpens the estimate (and
#: advises again if the mode is still under-resolved).
MAX_REFINEMENT = 2.0
#: Segments per record below which the advice says the record is short for its ``nperseg``
#: (:data:`ami_xr.dsp.frf.SUGGESTED_SEGMENTS`, the count frf's own advice keeps).
SEGMENTS = 8


class _Attrs(NamedTuple):
    """What :func:`ami_xr.provenance.history` reads of a Dataset (no Dataset built for it)."""

    attrs: dict


@dataclass(frozen=True)
class WelchWindow:
    """The Welch estimate an FRF came from: its window (name), segment and FFT lengths, and
    sampling rate (Hz), as :func:`ami_xr.frf` records them in the provenance, and the length of
    a record as the segments averaged tell it."""

    window: str
    nperseg: int
    nfft: int
    fs: float
    #: samples per record, from the segments averaged (None when not recorded)
    record_samples: int | None = None

    def enbw_lines(self) -> float:
        """The window's equivalent noise bandwidth in lines of ``fs / nfft``:
        ``nfft sum(w^2) / (sum w)^2``."""
        w = windows.get_window(self.window, self.nperseg)
        return float(self.nfft * np.sum(w * w) / np.sum(w) ** 2)


def welch_window(attrs: dict) -> WelchWindow | None:
    """The last :data:`WELCH_FUNCTION` record in the provenance of an FRF Dataset with
    attributes ``attrs`` (also as a step of a command's record, as ``ami-xr frf`` writes it);
    None when there is none or its window is not a named window (an array)."""
    found = None
    for record in history(_Attrs(dict(attrs))):  # history reads the attrs only
        if not isinstance(record, dict):
            continue
        steps = record.get("steps")
        for r in [*(steps if isinstance(steps, list) else []), record]:
            if isinstance(r, dict) and r.get("function") == WELCH_FUNCTION:
                found = r.get("parameters")
    if not isinstance(found, dict):
        return None
    try:
        name = windows.window_name(str(found["window"]))
        nperseg, fs = int(found["nperseg"]), float(found["fs"])
        nfft = int(found.get("nfft") or nperseg)
        windows.get_window(name, nperseg)
    except (KeyError, TypeError, ValueError, AmiXrValueError):
        return None
    return WelchWindow(name, nperseg, nfft, fs, _record_samples(found, nperseg, attrs))


def _record_samples(parameters: dict, nperseg: int, attrs: dict) -> int | None:
    """Samples per record of a Welch estimate: ``nperseg + (n - 1) (nperseg - noverlap)`` for
    ``n`` segments per record (attr ``n_averages`` over ``n_records_used``); None when the
    Dataset does not say."""
    try:
        noverlap = int(parameters.get("noverlap", nperseg // 2))
        per_record = int(attrs[names.ATTR_N_AVERAGES]) / int(parameters.get("n_records_used", 1))
    except (KeyError, TypeError, ValueError, ZeroDivisionError):
        return None
    if per_record < 1 or not 0 <= noverlap < nperseg:
        return None
    return int(nperseg + (per_record - 1) * (nperseg - noverlap))


def line_spacing(frequency: np.ndarray) -> float:
    """The line spacing (Hz) of the frequency lines: the median step (NaN with one line)."""
    f = np.asarray(frequency, dtype=float)
    return float(np.median(np.diff(f))) if f.size > 1 else math.nan


def resolution_bias(fn: np.ndarray, df: float, welch: WelchWindow | None) -> np.ndarray:
    """The damping-ratio bias bound ``(1 + B_w) df / (2 f_n)`` of modes at ``fn`` (Hz) from
    lines ``df`` apart (``B_w``: :meth:`WelchWindow.enbw_lines`, 0 without a Welch window)."""
    b_w = 0.0 if welch is None else welch.enbw_lines()
    with np.errstate(divide="ignore", invalid="ignore"):
        return (1.0 + b_w) * df / (2.0 * np.abs(np.asarray(fn, dtype=float)))


def target_spacing(fn: np.ndarray, zeta: np.ndarray, smear: np.ndarray) -> np.ndarray:
    """The line spacing (Hz) that puts :data:`RESOLUTION_LINES` lines in the half-power
    bandwidth of modes at ``fn`` (Hz) with measured damping ``zeta``, taken at the damping left
    when the window's smearing ``smear`` (``B_w df / (2 f_n)``, as a damping ratio) is taken
    out in quadrature, ``sqrt(zeta^2 - smear^2)`` (the widths of a peak and of the window it is
    seen through add about so), but at least ``zeta /`` :data:`MAX_REFINEMENT`."""
    zeta = np.abs(np.asarray(zeta, dtype=float))
    left = np.sqrt(np.maximum(zeta**2 - np.asarray(smear, dtype=float) ** 2, 0.0))
    low = np.maximum(left, zeta / MAX_REFINEMENT)
    return 2.0 * low * np.abs(np.asarray(fn, dtype=float)) / RESOLUTION_LINES


def advice(target: float, df: float, welch: WelchWindow | None) -> str:
    """How to get lines ``target`` Hz apart (now ``df``): with a Welch window the ``nperseg``
    (next power of two, at least twice the one used, the FFT padding kept), otherwise the line
    spacing and the segment duration it takes."""
    if welch is None:
        return (
            f"lines {target:.3g} Hz apart or finer (now {df:.3g} Hz: segments of at least "
            f"{1.0 / target:.3g} s)"
        )
    wanted = welch.fs / target * welch.nperseg / welch.nfft
    nperseg = max(1 << max(int(math.ceil(math.log2(wanted))), 0), 2 * welch.nperseg)
    text = (
        f"nperseg={nperseg} or more (now {welch.nperseg}: lines {df:.3g} Hz apart; ami-xr frf "
        f"--nperseg), so that {RESOLUTION_LINES:g} lines or more span its half-power bandwidth"
    )
    n = welch.record_samples
    if n is not None and nperseg * SEGMENTS > n:
        text += (
            f"; a record of {n} samples holds fewer than {SEGMENTS} such segments (fewer "
            "averages, a noisier FRF): record longer, or keep this FRF and the widened std"
        )
    return text


def resolution_checked(result: xr.Dataset, whole: xr.Dataset) -> xr.Dataset:
    """``result`` with ``under_resolved`` set on every mode whose half-power bandwidth
    ``2 zeta f_n`` spans fewer than :data:`RESOLUTION_LINES` lines of ``whole`` (the FRF
    Dataset identified from; cleared elsewhere), their ``damping_ratio_std`` and the real part
    of ``eigenvalue_std`` widened by the resolution bias (module docstring; where those
    variables exist), and one :class:`~ami_xr.errors.AssumptionWarning` naming them and what
    would resolve them all (:func:`target_spacing`, :func:`advice`). Unchanged without modes
    or quality flags.

    Parameters
    ----------
    result : xarray.Dataset
        The identified modes (``natural_frequency``, ``damping_ratio``, ``quality_flags`` on
        ``mode``).
    whole : xarray.Dataset
        The FRF Dataset as given: its ``frequency`` lines and its provenance (the Welch window
        of :func:`ami_xr.frf`).

    Returns
    -------
    xarray.Dataset
        A new Dataset (``result`` is not modified).
    """
    need = (names.NATURAL_FREQUENCY, names.DAMPING_RATIO, names.QUALITY_FLAGS)
    if not result.sizes.get(names.MODE, 0) or any(v not in result for v in need):
        return result
    stds = {
        v: result[v].transpose(names.MODE).values
        for v in (names.DAMPING_RATIO_STD, names.EIGENVALUE_STD)
        if v in result
    }
    mask, stds = resolution_widened(
        result[names.NATURAL_FREQUENCY].transpose(names.MODE).values,
        result[names.DAMPING_RATIO].transpose(names.MODE).values,
        c.flag_mask(result),
        stds,
        result[names.MODE].values,
        whole,
    )
    result = result.copy()
    result[names.QUALITY_FLAGS] = result[names.QUALITY_FLAGS].copy(data=mask)
    for v, std in stds.items():
        result[v] = result[v].copy(data=std)
    return result


def resolution_widened(fn, zeta, mask, stds: dict, labels, whole: xr.Dataset):
    """:func:`resolution_checked` on the arrays of the modes (natural frequencies ``fn``,
    damping ratios ``zeta``, flag ``mask``, labels; on ``mode``) and the standard deviations
    ``stds`` (``damping_ratio_std``, ``eigenvalue_std`` by name, those present): the flags and
    the standard deviations, widened where a mode is under-resolved (the same warning)."""
    df = line_spacing(whole[names.FREQUENCY].values)
    fn = np.asarray(fn, dtype=float)
    zeta = np.asarray(zeta, dtype=float)
    with np.errstate(invalid="ignore"):
        under = 2.0 * np.abs(zeta) * fn < RESOLUTION_LINES * df
    mask = flags.set_where(mask, names.FLAG_UNDER_RESOLVED, under)
    if not under.any():
        return mask, {}
    welch = welch_window(whole.attrs)
    bias = np.where(under, resolution_bias(fn, df, welch), 0.0)
    out = {}
    if names.DAMPING_RATIO_STD in stds:
        z_std = np.asarray(stds[names.DAMPING_RATIO_STD], dtype=float)
        out[names.DAMPING_RATIO_STD] = np.hypot(z_std, bias)
    if names.EIGENVALUE_STD in stds:
        e_std = np.asarray(stds[names.EIGENVALUE_STD], dtype=np.complex128)
        re_bias = bias * 2.0 * np.pi * fn / np.maximum(1.0 - zeta**2, 1e-12)
        out[names.EIGENVALUE_STD] = np.hypot(e_std.real, re_bias) + 1j * e_std.imag
    # the narrowest half-power bandwidth needs the finest lines: resolving it resolves all
    smear = 0.0 if welch is None else welch.enbw_lines() * df / (2.0 * fn)
    target = np.where(under, target_spacing(fn, zeta, smear), np.nan)
    k = int(np.nanargmin(target))
    listed = ", ".join(
        f"{labels[i]} ({fn[i]:.4g} Hz, zeta {zeta[i]:.2%})" for i in np.flatnonzero(under)
    )
    warn(
        f"identify: mode(s) {listed} have a half-power bandwidth 2 zeta f_n of fewer than "
        f"{RESOLUTION_LINES:g} lines ({df:.3g} Hz apart): flagged {names.FLAG_UNDER_RESOLVED}, "
        "their damping_ratio_std widened by the bias of the line spacing"
        f"{'' if welch is None else ' and the ' + welch.window + ' window'}; to resolve them "
        f"(mode {labels[k]} has the narrowest) estimate the FRF with "
        f"{advice(float(target[k]), df, welch)}",
        AssumptionWarning,
    )
    return mask, out
