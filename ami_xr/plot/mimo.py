"""Figures of a multi-reference result (:mod:`ami_xr.ami.mimo`): what each reference sees.

:func:`plot_participation` draws the participation of every reference in every mode, relative
to the reference that excites the mode best (a reference near 0 sits on the mode's nodal line);
:func:`plot_reference_checks` the two per-mode checks of the residue matrices, ``s2/s1``
(rank one or a repeated root) and the spread of the drive points' scalings (reciprocity).
The numbers behind them come from :func:`ami_xr.tables.participation_table`.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.core import flags
from ami_xr.errors import AmiXrValueError
from ami_xr.plot.common import finish, labels_of_modes, new_figure, require, set_title
from ami_xr.tables import participation_table

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_participation", "plot_reference_checks"]


def plot_participation(ds: xr.Dataset, *, path: str | os.PathLike | None = None) -> Figure:
    """Participation of each reference in each mode, ``|L_r| / max_r |L_r|`` (grouped bars).

    Parameters
    ----------
    ds : xarray.Dataset
        Multi-reference result of :func:`ami_xr.identify` (``participation`` (mode,
        reference)); anything else raises :class:`~ami_xr.errors.AmiXrValueError`, which the
        report turns into a note.
    path : str or path-like, optional
        Save the figure there.
    """
    rows = participation_table(ds)
    refs = list(ds[names.REFERENCE].values.tolist())
    if not rows:
        raise AmiXrValueError("plot_participation: skipped, no modes identified")
    n_k, n_r = len(rows), len(refs)
    fig = new_figure(
        min(1.2 + 0.25 * n_k * max(n_r, 2), 10.9),
        2.6,
        grid=(1, 1),
        margins=(0.7, 1.3, 0.5, 0.3),
        gaps=(0, 0),
    )
    ax = fig.add_subplot()
    width = 0.8 / n_r
    x = np.arange(n_k)
    for i, r in enumerate(refs):
        rel = [row["relative"][r] for row in rows]
        ax.bar(x - 0.4 + (i + 0.5) * width, rel, width, label=f"reference {r}")
    ax.set_xticks(x, [str(row["mode"]) for row in rows], fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("mode", fontsize=8)
    ax.set_ylabel("|L| / max |L|", fontsize=8)
    ax.tick_params(labelsize=8)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    set_title(ax, "Participation per reference", fontsize=9)
    return finish(fig, path)


def plot_reference_checks(ds: xr.Dataset, *, path: str | os.PathLike | None = None) -> Figure:
    """Per mode: ``s2/s1`` of the residue matrix (point x reference) against the
    repeated-root threshold, and the drive-point consistency (largest relative deviation of
    the mode vector's scale between drive points); modes flagged ``repeated_root_suspected``
    or ``repeated_root_separated`` are drawn in red.

    Parameters
    ----------
    ds : xarray.Dataset
        Multi-reference result (``rank_one_ratio``, ``drive_point_consistency``).
    path : str or path-like, optional
        Save the figure there.
    """
    require(ds, names.RANK_ONE_RATIO, names.DRIVE_POINT_CONSISTENCY, figure="plot_reference_checks")
    labels = labels_of_modes(ds)
    if not labels:
        raise AmiXrValueError("plot_reference_checks: skipped, no modes identified")
    ratio = np.asarray(ds[names.RANK_ONE_RATIO].values, dtype=float)
    spread = np.asarray(ds[names.DRIVE_POINT_CONSISTENCY].values, dtype=float)
    marked = np.zeros(ratio.size, bool)
    if names.QUALITY_FLAGS in ds:
        mask = flags.decode(ds[names.QUALITY_FLAGS].values)
        for flag in (names.FLAG_REPEATED_ROOT, names.FLAG_REPEATED_ROOT_SEPARATED):
            marked |= flags.has(mask, flag)
    colors = np.where(marked, "tab:red", "tab:blue")
    x = np.arange(ratio.size)
    fig = new_figure(
        min(2 * (1.6 + 0.35 * ratio.size), 10.9),
        2.6,
        grid=(1, 2),
        margins=(0.7, 0.2, 0.5, 0.3),
        gaps=(0.8, 0),
    )
    threshold = ds.attrs.get(names.ATTR_RANK_ONE_RATIO_MAX)
    for i, (values, title, ylabel) in enumerate(
        (
            (ratio, "Residue matrix s2/s1 (rank one: near 0)", "s2/s1"),
            (spread, "Drive-point consistency (reciprocity)", "relative spread"),
        )
    ):
        ax = fig.add_subplot(1, 2, i + 1)
        # log axis down to the smallest value (noise-free data give ~1e-16), at least 1e-3
        positive = values[np.isfinite(values) & (values > 0)]
        lo = max(1e-17, min(1e-3, 0.3 * positive.min())) if positive.size else 1e-3
        shown = np.where(np.isfinite(values), np.maximum(values, lo), lo)
        ax.bar(x, shown, 0.6, color=colors, bottom=0)
        for k in np.flatnonzero(~np.isfinite(values)):
            ax.text(k, lo, "n/a", ha="center", va="bottom", fontsize=7)
        ax.set_yscale("log")
        ax.set_ylim(lo, 2.0)
        if i == 0 and threshold is not None:
            ax.axhline(float(threshold), color="k", ls="--", lw=0.8)
        ax.set_xticks(x, [str(v) for v in labels], fontsize=8)
        ax.set_xlabel("mode", fontsize=8)
        ax.set_ylabel(ylabel, fontsize=8)
        ax.tick_params(labelsize=8)
        set_title(ax, title, fontsize=9)
    return finish(fig, path)
