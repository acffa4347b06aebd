"""FRFs from an impact (hammer) test: :func:`impact_frf`. Every record is one hit, checked
(:mod:`ami_xr.dsp.hits`), windowed with a force and an exponential window and averaged by the
estimator random excitation uses too (:mod:`ami_xr.dsp.estimator`)."""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.dsp.blocks import load_block
from ami_xr.dsp.estimator import Setup, finish, point_labels, setup, spectra_to_frf
from ami_xr.dsp.hits import check_hits
from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import impact as _ki
from ami_xr.kernels import windows as _kw


def impact_frf(
    ds: xr.Dataset,
    estimator: str = "H1",
    *,
    force: xr.DataArray | None = None,
    fs: float | None = None,
    force_window: float | None = None,
    exponential_decay: float | None = None,
    exponential_end_value: float | None = None,
    hit_checks: bool = True,
    overload_samples: int = 3,
    double_impact_threshold: float = 0.1,
    min_force: float | None = None,
    weak_force_ratio: float = 0.1,
    nperseg: int | None = None,
    noverlap: int | None = 0,
    nfft: int | None = None,
    detrend: str | bool = "none",
    average: str = "linear",
    n_average: int = 8,
    chunk_samples: int | None = None,
    workers: int = 1,
) -> xr.Dataset:
    """Estimate FRFs (H1, H2 or Hv) and coherence from an impact (hammer) test.

    Every record is one hit. Each hit is checked before use (overload, double impact, weak force;
    see :func:`ami_xr.dsp.hits.check_hits`); rejected hits are listed with their reason and left
    out. The force channel gets a force (transient) window times the exponential window, the
    responses the exponential window. Applying the exponential window to the force as well makes
    the result exact: ``(h * f) e^(-beta t) = (h e^(-beta t)) * (f e^(-beta t))``, so the
    estimated FRF is that of the system with every eigenvalue shifted by ``-beta``; ``beta`` is
    stored as ``exponential_window_decay`` (1/s) and identification adds it back. The accepted
    hits are then averaged as Welch segments (by default one segment per hit).

    Parameters
    ----------
    ds : xarray.Dataset
        Time Dataset: ``response`` ([record,] point, time), ``force`` ``([record,] [reference,]
        time)``, ``time`` coordinate in s (uniform); ``record`` is the hit.
    estimator, force, fs
        As for :func:`~ami_xr.dsp.frf.frf`.
    force_window : float, optional
        Width in s of the force window (1 from the record start to here, then a short
        half-cosine taper). Default: the end of the latest first force pulse of the accepted hits
        plus that pulse's length.
    exponential_decay, exponential_end_value : float, optional
        Exponential window on force and response, by decay rate (1/s) or value at the record
        end; at most one. Default none.
    hit_checks : bool
        Check hits; False uses every hit.
    overload_samples, double_impact_threshold, min_force, weak_force_ratio
        Hit-check thresholds (see :func:`ami_xr.dsp.hits.check_hits`).
    nperseg, noverlap, nfft : int, optional
        Segment length (default the whole hit), overlap (default 0; ``None`` also means 0) and FFT
        length (default ``nperseg``).
    detrend : {"none", "constant", "linear"} or False
        Removed from each segment before windowing (``None`` also means ``"none"``).
    average, n_average, chunk_samples, workers
        As for :func:`~ami_xr.dsp.frf.frf`; averaging runs over hits (segments).

    Returns
    -------
    xarray.Dataset
        The FRF Dataset of :func:`frf` plus ``hit_rejected``, ``hit_reject_reason`` and
        ``hit_peak_force`` (record), attrs ``force_window_width`` (s) and, with an exponential
        window, ``exponential_window_decay`` (1/s).

    Raises
    ------
    AmiXrValueError
        As for :func:`~ami_xr.dsp.frf.frf`; also a bad ``force_window`` or exponential window,
        and every hit rejected (the message lists each hit's reason).
    """
    s = setup(
        ds,
        estimator=estimator,
        force=force,
        fs=fs,
        segments=(nperseg, 0 if noverlap is None else noverlap, nfft, None),
        detrend="none" if detrend is None else detrend,
        average=average,
        n_average=n_average,
        chunk_samples=chunk_samples,
        workers=workers,
    )
    if force_window is not None and not (
        isinstance(force_window, (int, float, np.number)) and force_window > 0
    ):
        raise AmiXrValueError(f"force_window: expected a width in s > 0, got {force_window!r}")
    beta = None
    if exponential_decay is not None or exponential_end_value is not None:
        beta = _kw.exponential_decay_rate(
            s.nperseg, fs=s.fs, decay=exponential_decay, end_value=exponential_end_value
        )
    checks = {
        "overload_samples": overload_samples,
        "double_impact_threshold": double_impact_threshold,
        "min_force": min_force,
        "weak_force_ratio": weak_force_ratio,
    }
    rejected, reasons, peak, pulse = _checked_hits(s, checks, hit_checks)
    use = ~rejected
    extra = _hit_variables(ds, rejected, reasons, peak)
    wf, we, attrs_extra = _windows(ds, s, pulse[use], force_window, beta)
    out = spectra_to_frf(ds, s, (wf * we, we), np.flatnonzero(use), extra, attrs_extra)
    label = "force*exponential" if names.ATTR_EXP_DECAY in attrs_extra else "force"
    params = {"n_records_used": int(use.sum()), **attrs_extra}
    return finish(out, s, "ami_xr.impact_frf", label, params)


def _checked_hits(
    s: Setup, checks: dict[str, Any], hit_checks: bool
) -> tuple[np.ndarray, list[str], np.ndarray, np.ndarray]:
    """Every hit loaded and checked (:func:`~ami_xr.dsp.hits.check_hits` with the thresholds
    ``checks``; without ``hit_checks`` every hit is used): rejected (record) bool, reasons, peak
    force and the first pulse's (start, end) samples per hit. Every hit rejected is an error
    listing each reason."""
    nrec, n_time = s.force.sizes[names.RECORD], s.force.sizes[names.TIME]
    fv = np.stack([load_block(s.force, r, 0, n_time, "force") for r in range(nrec)])
    yv = np.stack([load_block(s.response, r, 0, n_time, "response") for r in range(nrec)])
    if hit_checks:
        rejected, reasons, peak, pulse = check_hits(
            fv, yv, **checks, point_labels=point_labels(s.response)
        )
    else:
        rejected = np.zeros(nrec, bool)
        reasons = [""] * nrec
        peak = np.max(np.abs(fv[:, 0]), axis=1)
        threshold = checks["double_impact_threshold"] * peak
        pulse = _ki.force_pulses(np.ascontiguousarray(fv[:, 0]), threshold, 3)
        pulse = pulse[:, 1:3]
    del fv, yv
    if rejected.all():
        lines = "; ".join(f"hit {r}: {reasons[r]}" for r in range(nrec))
        raise AmiXrValueError(f"ds: every impact hit was rejected ({lines})")
    return rejected, reasons, peak, pulse


def _hit_variables(ds: xr.Dataset, rejected, reasons, peak) -> dict[str, xr.DataArray]:
    """``hit_rejected``, ``hit_reject_reason`` and ``hit_peak_force`` (record)."""
    nrec = rejected.size
    rec = {names.RECORD: ds[names.RECORD].values if names.RECORD in ds.coords else np.arange(nrec)}
    force_units = {names.ATTR_UNITS: ds.attrs.get(names.ATTR_FORCE_UNITS, "")}
    return {
        names.HIT_REJECTED: xr.DataArray(rejected, dims=[names.RECORD], coords=rec),
        names.HIT_REJECT_REASON: xr.DataArray(
            np.array(reasons, dtype=str), dims=[names.RECORD], coords=rec
        ),
        names.HIT_PEAK_FORCE: xr.DataArray(
            peak, dims=[names.RECORD], coords=rec, attrs=force_units
        ),
    }


def _windows(
    ds: xr.Dataset, s: Setup, pulse: np.ndarray, force_window: float | None, beta: float | None
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The force window, the exponential window (ones without ``beta``) and the attributes
    recording them. ``pulse``: (start, end) of the first pulse of each accepted hit."""
    # force window: default covers the first pulse of every accepted hit plus its length
    if force_window is None:
        ends = pulse[:, 1]
        lengths = pulse[:, 1] - pulse[:, 0] + 1
        width = int(min(s.nperseg, max(1, ends.max() + 1 + lengths.max())))
    else:
        width = int(min(s.nperseg, max(1, round(float(force_window) * s.fs))))
    wf = _kw.get_window("force", s.nperseg, width=width)
    attrs_extra: dict[str, Any] = {}
    if beta is not None:
        we = _kw.get_window("exponential", s.nperseg, fs=s.fs, decay=beta)
        # a window already applied to the time data (ami_xr.apply_window) adds up
        attrs_extra[names.ATTR_EXP_DECAY] = float(beta) + float(
            ds.attrs.get(names.ATTR_EXP_DECAY, 0.0) or 0.0
        )
    else:
        we = np.ones(s.nperseg)
    attrs_extra[names.ATTR_FORCE_WINDOW_WIDTH] = width / s.fs
    return wf, we, attrs_extra
