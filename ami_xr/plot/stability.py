"""The mode stability chart: which modes hold as the detection threshold and the band vary.

Drawn from the output of :func:`ami_xr.stability` like a stabilization chart, with one row per
identify variant (threshold ``pfa`` and analysis band) in place of one per model order. Same
conventions as :mod:`ami_xr.plot`: a Figure on its own Agg canvas is returned, ``path=`` saves
it atomically, no global matplotlib state is touched, the layout is fixed.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.plot.common import (
    finish,
    label_levels,
    labels_of_modes,
    natural_frequencies,
    new_figure,
    require,
    units_of,
)

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_stability"]

ROW_IN = 0.32  # height of one variant row, inches
MARGINS = (2.3, 0.75, 0.95, 0.8)  # left (variant labels), right (FRF axis), bottom, top


def plot_stability(
    ds: xr.Dataset, *, log: bool = True, path: str | os.PathLike | None = None
) -> Figure:
    """Stability chart of the output of :func:`ami_xr.stability`.

    x: frequency (Hz; log scale with ``log``, as the report's Bode when the band starts above
    0 Hz); y: one row per variant (labelled by threshold and band; the band itself a faint bar).
    A filled circle where a mode was found again, an open one where it was missed although
    inside the variant's band; the modes' natural frequencies as faint vertical lines with their
    labels, and each mode's stability fraction written at the top (1: solid). The FRF
    magnitude summed over points is drawn faint on a second y axis.

    Parameters
    ----------
    ds : xarray.Dataset
        Result of :func:`ami_xr.stability` (``stability_found``, ``stability_in_band``,
        ``stability_fraction``; ``frf`` optional).
    log : bool, default True
        Log frequency axis (linear when the band starts at 0 Hz).
    path : str or path-like, optional
        Save the figure there.
    """
    require(
        ds,
        names.STABILITY_FOUND,
        names.STABILITY_IN_BAND,
        names.STABILITY_FRACTION,
        figure="plot_stability",
    )
    dims = (names.MODE, names.STABILITY_VARIANT)
    found = ds[names.STABILITY_FOUND].transpose(*dims).values.astype(bool)
    in_band = ds[names.STABILITY_IN_BAND].transpose(*dims).values.astype(bool)
    matched = (
        ds[names.STABILITY_FREQUENCY].transpose(*dims).values
        if names.STABILITY_FREQUENCY in ds
        else np.full(found.shape, np.nan)
    )
    fraction = np.atleast_1d(ds[names.STABILITY_FRACTION].values)
    fn, labels = natural_frequencies(ds), labels_of_modes(ds)
    variants = [str(v) for v in ds[names.STABILITY_VARIANT].values.tolist()]
    n_var = len(variants)
    fmin = np.asarray(ds[names.STABILITY_FMIN].values) if names.STABILITY_FMIN in ds else None
    fmax = np.asarray(ds[names.STABILITY_FMAX].values) if names.STABILITY_FMAX in ds else None
    if fmin is not None and fmax is not None and n_var:
        lo, hi = float(fmin.min()), float(fmax.max())
    else:
        f = ds[names.FREQUENCY].values
        lo, hi = float(f[0]), float(f[-1])
    log = bool(log) and lo > 0
    height = MARGINS[2] + MARGINS[3] + max(n_var, 2) * ROW_IN + 0.3
    fig = new_figure(10.0, height, grid=(1, 1), margins=MARGINS, gaps=(0, 0))
    ax = fig.add_subplot()
    if names.FRF in ds:  # faint background: where the peaks are
        twin = ax.twinx()
        frf = ds[names.FRF]
        mag = np.abs(frf).sum(names.POINT) if names.POINT in frf.dims else np.abs(frf)
        freq = ds[names.FREQUENCY].values
        keep = (freq >= lo) & (freq <= hi) & (freq > 0 if log else True)
        twin.semilogy(freq[keep], mag.values[keep], color="0.8", lw=0.6, label="sum |FRF|")
        units = units_of(ds, names.FRF)
        twin.set_ylabel(f"sum over points |FRF| [{units}]" if units else "sum |FRF|", fontsize=7)
        twin.tick_params(labelsize=6, colors="0.5")
        ax.set_zorder(twin.get_zorder() + 1)
        ax.patch.set_visible(False)
    rows = np.arange(n_var)
    if fmin is not None and fmax is not None:
        ax.hlines(rows, fmin, fmax, colors="0.85", lw=5, zorder=0, label="variant's band")
    x = np.where(np.isfinite(matched), matched, fn[:, None])
    yy = np.broadcast_to(rows[None, :], found.shape)
    ax.plot(x[found], yy[found], "o", ms=5, color="tab:blue", ls="none", label="mode found again")
    missed = in_band & ~found
    ax.plot(
        fn[:, None].repeat(n_var, 1)[missed],
        yy[missed],
        "o",
        ms=5,
        mfc="none",
        color="tab:red",
        ls="none",
        label="missed (inside the band)",
    )
    ax.vlines(fn, -0.5, n_var - 0.5, colors="0.6", lw=0.6, alpha=0.6, zorder=0)
    good = np.isfinite(fn) & (fn > 0 if log else True)
    scale = np.log10 if log else np.asarray
    levels = np.zeros(fn.size, int)
    if good.any():  # neighbours' labels staggered upwards
        levels[good] = label_levels(scale(fn[good]), float(scale(lo)), float(scale(hi)), 0.045)
    for f, lab, frac, level in zip(fn, labels, fraction, levels, strict=False):
        if not np.isfinite(f):
            continue
        text = "-" if not np.isfinite(frac) else f"{frac:.2g}"
        ax.annotate(
            f"{lab}: {text}",
            (f, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(0, 2 + 8 * (level % 3)),
            textcoords="offset points",
            ha="center",
            va="bottom",
            fontsize=6,
            color="tab:green" if frac == 1 else "tab:red",
        )
    if log:
        ax.set_xscale("log")
    ax.set_xlim(lo, hi)
    ax.set_ylim(-0.5, n_var - 0.5)
    ax.set_yticks(rows, variants, fontsize=7)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("identify variant (pfa, band)", fontsize=8)
    ax.minorticks_off()
    # fixed height above the labels and fractions (plot_common.set_title: no measuring)
    ax.set_title(
        "Mode stability: mode label: fraction of variants finding it (1 = solid)",
        y=1.0,
        pad=28.0,
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="upper right", bbox_to_anchor=(1.0, -0.17), ncol=3, frameon=False)
    return finish(fig, path)
