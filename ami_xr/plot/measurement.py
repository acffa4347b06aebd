"""Figures of the measurement behind an estimated FRF: coherence, force spectrum, impact hits.

An engineer checks these before any modal parameter: where the coherence drops the FRF is not
to be trusted; the force autospectrum shows the band the hammer tip excited (a drop of 10-20 dB
marks its end); the hits show which impacts were averaged and why others were left out. The
inputs are what :func:`ami_xr.frf` and :func:`ami_xr.impact_frf` write (``coherence``,
``force_autospectrum``, ``hit_peak_force``, ``hit_rejected``, ``hit_reject_reason``); they
survive :func:`ami_xr.identify`. Same conventions as :mod:`ami_xr.plot`: a Figure is returned,
``path=`` saves it atomically, no global matplotlib state is touched.
"""

from __future__ import annotations

import os
from collections.abc import Hashable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.plot.common import (
    finish,
    new_figure,
    require,
    select_points,
    set_title,
    units_of,
)

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_coherence", "plot_force_spectrum", "plot_hits", "measurement_summary"]

#: Fixed margins (left, right, bottom, top; inches) of these one-panel figures.
MARGINS = (0.8, 0.2, 0.55, 0.35)


def _band(ds: xr.Dataset, frequency_range: tuple[float, float] | None) -> xr.Dataset:
    if frequency_range is None:
        return ds
    f0, f1 = frequency_range
    return ds.sel({names.FREQUENCY: slice(f0, f1)})


def plot_coherence(
    ds: xr.Dataset,
    *,
    points: Sequence[Hashable] | None = None,
    frequency_range: tuple[float, float] | None = None,
    path: str | os.PathLike | None = None,
) -> Figure:
    """Coherence of each FRF against frequency (0 to 1), one line per point, with a legend.

    Parameters
    ----------
    ds : xarray.Dataset
        Dataset with ``coherence`` (point, frequency).
    points : sequence of point labels, optional
        Points to show (at most 12 by default).
    frequency_range : (float, float), optional
        Band to show, in Hz.
    path : str or path-like, optional
        Save the figure there.
    """
    require(ds, names.COHERENCE, figure="plot_coherence")
    ds = _band(ds, frequency_range)
    pts = select_points(ds, points, "plot_coherence")
    freq = ds[names.FREQUENCY].values
    fig = new_figure(10.0, 3.2, grid=(1, 1), margins=MARGINS, gaps=(0, 0))
    ax = fig.add_subplot()
    coh = ds[names.COHERENCE]
    for p in pts:
        ax.plot(freq, coh.sel({names.POINT: p}).values, lw=0.8, label=f"point {p}")
    ax.set_ylim(-0.02, 1.05)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("coherence [-]")
    set_title(ax, "Coherence (values well below 1: noise, leakage or nonlinearity)", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    return finish(fig, path)


def plot_force_spectrum(
    ds: xr.Dataset,
    *,
    frequency_range: tuple[float, float] | None = None,
    path: str | os.PathLike | None = None,
) -> Figure:
    """Force autospectrum in dB relative to its largest value, with the -10 and -20 dB lines.

    Parameters
    ----------
    ds : xarray.Dataset
        Dataset with ``force_autospectrum`` ([reference,] frequency).
    frequency_range : (float, float), optional
        Band to show, in Hz.
    path : str or path-like, optional
        Save the figure there.
    """
    require(ds, names.FORCE_AUTOSPECTRUM, figure="plot_force_spectrum")
    ds = _band(ds, frequency_range)
    gff = ds[names.FORCE_AUTOSPECTRUM]
    other = [d for d in gff.dims if d != names.FREQUENCY]
    gff = gff.transpose(*other, names.FREQUENCY)
    values = np.asarray(gff.values, dtype=float).reshape(-1, gff.sizes[names.FREQUENCY])
    freq = ds[names.FREQUENCY].values
    units = units_of(ds, names.FORCE_AUTOSPECTRUM) or "force^2/Hz"
    fig = new_figure(10.0, 3.2, grid=(1, 1), margins=MARGINS, gaps=(0, 0))
    ax = fig.add_subplot()
    ref_labels = gff[other[0]].values.tolist() if other else [None]
    top = np.nanmax(values) if values.size and np.nanmax(values) > 0 else 1.0
    for row, ref in zip(values, ref_labels, strict=True):
        with np.errstate(divide="ignore"):
            db = 10 * np.log10(np.where(row > 0, row, np.nan) / top)
        ax.plot(freq, db, lw=0.9, label="force" if ref is None else f"force {ref}")
    ax.axhline(-10, color="tab:orange", ls="--", lw=0.8, label="-10 dB")
    ax.axhline(-20, color="tab:red", ls="--", lw=0.8, label="-20 dB")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"G_ff [dB re max {top:.3g} {units}]")
    set_title(ax, "Force autospectrum (the excited band ends where it falls 10-20 dB)", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    return finish(fig, path)


def _hit_reasons(ds: xr.Dataset) -> list[str]:
    if names.HIT_REJECT_REASON not in ds:
        return [""] * ds.sizes.get(names.RECORD, 0)
    out = []
    for value in np.atleast_1d(ds[names.HIT_REJECT_REASON].values):
        text = value.decode() if isinstance(value, bytes) else str(value)
        out.append("" if text in ("nan", "None") else text)
    return out


def measurement_summary(ds: xr.Dataset) -> dict[str, object]:
    """Estimator, number of averages and the hits of an estimated FRF (empty when unknown).

    Returns
    -------
    dict
        Keys present only when known: ``estimator``, ``n_averages``, ``hits`` (a list of
        dicts ``record``, ``peak_force``, ``rejected``, ``reason``) and ``force_units``.
    """
    out: dict[str, object] = {}
    for key in (names.ATTR_ESTIMATOR, names.ATTR_N_AVERAGES):
        if key in ds.attrs:
            out[key] = ds.attrs[key]
    if names.HIT_PEAK_FORCE in ds:
        peak = np.atleast_1d(np.asarray(ds[names.HIT_PEAK_FORCE].values, dtype=float))
        rejected = (
            np.atleast_1d(np.asarray(ds[names.HIT_REJECTED].values, dtype=bool))
            if names.HIT_REJECTED in ds
            else np.zeros(peak.size, bool)
        )
        records = (
            ds[names.RECORD].values.tolist()
            if names.RECORD in ds.coords
            else list(range(peak.size))
        )
        reasons = _hit_reasons(ds)
        out["hits"] = [
            {
                "record": records[i],
                "peak_force": float(peak[i]),
                "rejected": bool(rejected[i]),
                "reason": reasons[i] if i < len(reasons) else "",
            }
            for i in range(peak.size)
        ]
        out["force_units"] = units_of(ds, names.HIT_PEAK_FORCE)
    return out


def plot_hits(ds: xr.Dataset, *, path: str | os.PathLike | None = None) -> Figure:
    """Peak force of each impact hit; rejected hits in red, hatched, with their reason.

    Parameters
    ----------
    ds : xarray.Dataset
        Dataset with ``hit_peak_force`` (record); ``hit_rejected`` and ``hit_reject_reason``
        are used when present.
    path : str or path-like, optional
        Save the figure there.
    """
    require(ds, names.HIT_PEAK_FORCE, figure="plot_hits")
    hits = measurement_summary(ds)["hits"]
    units = units_of(ds, names.HIT_PEAK_FORCE) or "force units"
    n = len(hits)
    fig = new_figure(
        10.0,
        2.6 + 0.25 * sum(h["rejected"] for h in hits),
        grid=(1, 1),
        margins=MARGINS,
        gaps=(0, 0),
    )
    ax = fig.add_subplot()
    pos = np.arange(n)
    peak = [h["peak_force"] for h in hits]
    kept = [not h["rejected"] for h in hits]
    kept_mask = np.asarray(kept, dtype=bool)
    if kept_mask.any():
        ax.bar(pos[kept_mask], np.asarray(peak)[kept_mask], color="tab:blue", label="averaged")
    if not all(kept):
        bad = ~np.asarray(kept)
        ax.bar(pos[bad], np.asarray(peak)[bad], color="tab:red", hatch="//", label="rejected")
        for i in np.flatnonzero(bad):
            reason = hits[i]["reason"].split(":")[0] or "rejected"
            ax.annotate(
                reason, (pos[i], peak[i]), ha="center", va="bottom", fontsize=7, color="tab:red"
            )
    ax.set_xticks(pos, [f"hit {h['record']}" for h in hits], fontsize=8)
    ax.set_ylabel(f"peak force [{units}]")
    set_title(ax, f"Impact hits: {sum(kept)} of {n} averaged", fontsize=9)
    ax.margins(y=0.15)
    ax.legend(fontsize=7, loc="upper right")
    return finish(fig, path)
