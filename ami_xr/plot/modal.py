"""Figures engineers judge a curve-fit by (matplotlib, an optional extra).

Every function takes an identification result (or an FRF Dataset, for what it needs) and returns
a :class:`matplotlib.figure.Figure`; with ``path=`` it also saves it (PNG, or any format
matplotlib knows by the suffix), atomically through :mod:`ami_xr.io.atomic`. Figures are built
on matplotlib's object API with an Agg canvas attached inside each function: importing this
module imports no matplotlib, selects no backend and changes no global state (safe anywhere).

A figure whose inputs are missing raises :class:`ami_xr.errors.AmiXrValueError` naming them
(:func:`ami_xr.app.report.report` notes "not produced"). Bode plots draw identify's noise model.
"""

from __future__ import annotations

import os
from collections.abc import Hashable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.core import flags
from ami_xr.core.modal import mac_matrix
from ami_xr.errors import AmiXrValueError

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = [
    "plot_bode",
    "plot_nyquist",
    "plot_subtraction",
    "plot_mode_vectors",
    "plot_mac",
    "plot_modal_table",
]

from ami_xr.plot.common import (
    MAX_WIDTH_IN,
    POINT_COORDS,
    draw_noise_model,
    finish,
    in_band,
    labels_of_modes,
    mark_modes,
    natural_frequencies,
    new_figure,
    require,
    select_points,
    set_title,
    units_of,
)
from ami_xr.tables import modal_table

MAX_HEIGHT_IN = 18.0  # tallest figure, inches (x DPI 110 = 1 980 px)
MIN_PANEL_IN = 1.6  # narrowest Nyquist panel: beyond, the figure grows wider than the page


# --- Bode --------------------------------------------------------------------------------------


def plot_bode(
    ds: xr.Dataset,
    *,
    points: Sequence[Hashable] | None = None,
    frequency_range: tuple[float, float] | None = None,
    path: str | os.PathLike | None = None,
) -> Figure:
    """Bode magnitude and phase of the measured FRF, and the synthesised one where present.

    One column per point (at most 12; by default the 12 with the largest peak; at most 3 columns,
    at least 10 inches = 1100 px wide), magnitude on top (log scale, FRF units) and phase
    (degrees) below, each with a legend; the identified natural frequencies are marked with
    dashed red lines labelled by mode number (labels of close modes staggered).

    Parameters
    ----------
    ds : xarray.Dataset
        FRF Dataset or identification result (``frf``; optional ``frf_synthesized``,
        ``natural_frequency``).
    points : sequence of point labels, optional
        Points to show.
    frequency_range : (float, float), optional
        Band to show, in Hz (default the whole band).
    path : str or path-like, optional
        Save the figure there.
    """
    require(ds, names.FRF, figure="plot_bode")
    pts = select_points(ds, points, "plot_bode")
    fn, mode_labels = natural_frequencies(ds), labels_of_modes(ds)
    ds = in_band(ds, frequency_range, "plot_bode")
    freq = ds[names.FREQUENCY].values
    band = (float(freq[0]), float(freq[-1]))
    ncol = min(len(pts), 3)
    nrow_pts = int(np.ceil(len(pts) / ncol))
    fig = new_figure(
        max(10.0, 4.0 * ncol),
        4.2 * nrow_pts,
        grid=(nrow_pts, ncol),
        margins=(0.85, 0.2, 0.5, 0.3),
        gaps=(0.95, 0.8),
    )
    grid = fig.add_gridspec(nrow_pts, ncol)
    synth = ds[names.FRF_SYNTHESIZED] if names.FRF_SYNTHESIZED in ds else None
    units = units_of(ds, names.FRF)
    for i, p in enumerate(pts):
        r, c = divmod(i, ncol)
        pair = grid[r, c].subgridspec(2, 1, height_ratios=[2, 1], hspace=0.06)
        ax_mag = fig.add_subplot(pair[0])
        ax_ph = fig.add_subplot(pair[1], sharex=ax_mag)
        ax_mag.tick_params(labelbottom=False)  # the phase panel below has the same axis
        g = ds[names.FRF].sel({names.POINT: p}).values
        ax_mag.semilogy(freq, np.abs(g), color="0.55", lw=0.8, label="measured")
        ax_ph.plot(freq, np.degrees(np.angle(g)), color="0.55", lw=0.8, label="measured")
        draw_noise_model(ax_mag, ds, p, freq)
        if synth is not None:
            s = synth.sel({names.POINT: p}).values
            ax_mag.semilogy(freq, np.abs(s), color="tab:blue", lw=1.2, label="synthesised")
            ax_ph.plot(freq, np.degrees(np.angle(s)), color="tab:blue", lw=1.2, label="synthesised")
        mark_modes(ax_mag, fn, mode_labels, text=True, band=band)
        mark_modes(ax_ph, fn, mode_labels, text=False, band=band)
        ax_mag.set_xlim(band)
        ax_mag.minorticks_off()  # unlabelled; 8 a decade were a quarter of the drawing time
        drive = " (drive point)" if p == ds.attrs.get(names.ATTR_DRIVE_POINT) else ""
        set_title(ax_mag, f"point {p}{drive}", fontsize=9)
        ax_mag.set_ylabel(f"|FRF| [{units}]" if units else "|FRF|", fontsize=8)
        ax_ph.set_ylabel("phase [deg]", fontsize=8)
        ax_ph.set_xlabel("frequency [Hz]", fontsize=8)
        ax_ph.set_ylim(-190, 190)
        ax_ph.set_yticks([-180, -90, 0, 90, 180])
        ax_mag.legend(fontsize=7, loc="lower right")
        if synth is not None:
            ax_ph.legend(fontsize=6, loc="lower right")
    return finish(fig, path)


# --- Nyquist -----------------------------------------------------------------------------------
def _mode_band(fn: float, zeta: float, df: float, bandwidths: float) -> tuple[float, float]:
    half = max(bandwidths * max(zeta, 1e-4) * fn, 4 * df)
    return fn - half, fn + half


def plot_nyquist(
    ds: xr.Dataset,
    *,
    points: Sequence[Hashable] | None = None,
    bandwidths: float = 3.0,
    path: str | os.PathLike | None = None,
) -> Figure:
    """Nyquist plots (imaginary vs real part) of the FRF near each identified mode.

    One row per point (at most 12) and one column per mode; each panel shows the measured FRF
    (dots) and the synthesised FRF (line, where present) over ``fn +- bandwidths * zeta * fn``
    (at least 4 frequency lines each side), with the line nearest ``fn`` marked.

    Parameters
    ----------
    ds : xarray.Dataset
        Identification result: ``frf`` and ``natural_frequency`` (or ``eigenvalue``);
        ``damping_ratio`` and ``frf_synthesized`` are used when present.
    points : sequence of point labels, optional
        Points to show.
    bandwidths : float
        Half-width of the band around each mode, in half-power bandwidths ``zeta * fn``.
    path : str or path-like, optional
        Save the figure there.
    """
    require(ds, names.FRF, figure="plot_nyquist")
    fn = natural_frequencies(ds)
    if fn.size == 0:
        raise AmiXrValueError(
            f"plot_nyquist: the Dataset has no {names.NATURAL_FREQUENCY!r} or {names.EIGENVALUE!r} "
            "(run ami_xr.identify first)"
        )
    if not bandwidths > 0:
        raise AmiXrValueError(f"plot_nyquist: bandwidths must be > 0, got {bandwidths!r}")
    zeta = (
        np.asarray(ds[names.DAMPING_RATIO].values, dtype=float)
        if names.DAMPING_RATIO in ds
        else np.full(fn.size, 0.01)
    )
    pts = select_points(ds, points, "plot_nyquist")
    freq = ds[names.FREQUENCY].values
    df = float(np.median(np.diff(freq))) if freq.size > 1 else 1.0
    labels = labels_of_modes(ds)
    units = units_of(ds, names.FRF)
    unit_text = f" [{units}]" if units else ""
    # one point: modes wrapped into rows of at most 6; several: a row per point
    ncol = min(fn.size, 6) if len(pts) == 1 else fn.size
    nrow = int(np.ceil(fn.size / ncol)) if len(pts) == 1 else len(pts)
    # at most the page wide (narrowest panel MIN_PANEL_IN) and MAX_HEIGHT_IN tall
    panel = min(2.6, (MAX_HEIGHT_IN - 0.4) / nrow, max(MIN_PANEL_IN, (MAX_WIDTH_IN - 0.6) / ncol))
    fig = new_figure(
        max(panel * ncol + 0.6, 6.0),
        panel * nrow + 0.4,
        grid=(nrow, ncol),
        margins=(0.75, 0.15, 0.45, 0.45),
        gaps=(0.75, 0.8),
    )
    axes = fig.subplots(nrow, ncol, squeeze=False)
    for ax in axes.ravel()[len(pts) * fn.size :]:
        ax.set_visible(False)
    synth = ds[names.FRF_SYNTHESIZED] if names.FRF_SYNTHESIZED in ds else None
    for i, p in enumerate(pts):
        g = ds[names.FRF].sel({names.POINT: p}).values
        s = synth.sel({names.POINT: p}).values if synth is not None else None
        for k in range(fn.size):
            ax = axes.ravel()[i * fn.size + k]
            lo, hi = _mode_band(fn[k], zeta[k], df, bandwidths)
            band = (freq >= lo) & (freq <= hi)
            ax.plot(g[band].real, g[band].imag, ".", color="0.45", ms=3, label="measured")
            if s is not None:
                fit = _fit_on_fine_grid(ds, p, freq, s, band)
                ax.plot(fit.real, fit.imag, "-", color="tab:blue", lw=1.1, label="fit")
            if band.any():
                j = int(np.argmin(np.abs(freq - fn[k])))
                ax.plot(
                    g[j].real, g[j].imag, "o", mfc="none", color="tab:red", ms=6, label="at f_n"
                )
            ax.set_aspect("equal", adjustable="datalim")
            ax.tick_params(labelsize=6)
            ax.locator_params(nbins=4)  # what a 2-inch panel can label legibly
            ax.ticklabel_format(style="sci", scilimits=(-2, 3))
            ax.xaxis.get_offset_text().set_fontsize(6)
            ax.yaxis.get_offset_text().set_fontsize(6)
            title = f"mode {labels[k]}: {fn[k]:.4g} Hz"
            title = title if len(pts) == 1 else f"point {p}, {title}"
            set_title(ax, title, above_offset=True, fontsize=7)
            ax.set_xlabel(f"Re FRF{unit_text}", fontsize=7)
            ax.set_ylabel(f"Im FRF{unit_text}", fontsize=7)
            ax.legend(fontsize=5, loc="best")
    return finish(fig, path)


#: Lines of the fit drawn per measured line in the Nyquist plots.
FIT_OVERSAMPLING = 10


def _fit_on_fine_grid(
    ds: xr.Dataset, point: Hashable, freq: np.ndarray, synth: np.ndarray, band: np.ndarray
) -> np.ndarray:
    """The fitted model over ``band`` on a grid FIT_OVERSAMPLING times finer than the lines.

    The modes (``eigenvalue``, ``residue``, in the basis of the fit) are synthesised on the
    fine grid; what ``frf_synthesized`` holds beyond them (the smooth residual terms) is
    interpolated from the measured lines, so the curve passes through ``frf_synthesized`` at
    every line. Without eigenvalues and residues: ``frf_synthesized`` at the lines.
    """
    idx = np.flatnonzero(band)
    if idx.size < 2 or names.EIGENVALUE not in ds or names.RESIDUE not in ds:
        return synth[band]
    from ami_xr.core.model import CONTINUOUS, resolve_model
    from ami_xr.kernels.modal_basis import mode_contribution

    refined = ds.attrs.get(names.ATTR_REFINE_MODEL)
    if refined == names.MODEL_CONTINUOUS:
        model = CONTINUOUS
    else:
        model = resolve_model(ds.attrs, "exact" if refined == names.MODEL_DISCRETE else "auto")
    lam = np.atleast_1d(np.asarray(ds[names.EIGENVALUE].values, dtype=np.complex128))
    res = np.atleast_1d(
        np.asarray(ds[names.RESIDUE].sel({names.POINT: point}).values, dtype=np.complex128)
    )

    def modes(f: np.ndarray) -> np.ndarray:
        out = np.zeros(f.size, np.complex128)
        for lk, ak in zip(lam, res, strict=True):
            if np.isfinite(lk) and np.isfinite(ak):
                out += mode_contribution(
                    2 * np.pi * f, complex(lk), complex(ak), model.dt, model.n_samples
                )
        return out

    f_line = freq[idx]
    fine = np.linspace(f_line[0], f_line[-1], FIT_OVERSAMPLING * (idx.size - 1) + 1)
    rest = synth[idx] - modes(f_line)
    rest_fine = np.interp(fine, f_line, rest.real) + 1j * np.interp(fine, f_line, rest.imag)
    return modes(fine) + rest_fine


# --- Subtraction residual vs noise floor -------------------------------------------------------
def _subtraction_residual(ds: xr.Dataset, point: Hashable) -> np.ndarray | None:
    """FRF minus every candidate the Subtraction Phase kept, in the basis the phase used."""
    if names.SUB_EIGENVALUE not in ds or names.SUB_RESIDUE not in ds:
        return None
    from ami_xr.core.model import resolve_model
    from ami_xr.kernels.modal_basis import mode_contribution

    model = resolve_model(ds.attrs)  # the basis the phase recorded in ``ami_model``
    sel = {names.POINT: point}
    lam = np.atleast_1d(ds[names.SUB_EIGENVALUE].sel(sel).values)
    res = np.atleast_1d(ds[names.SUB_RESIDUE].sel(sel).values)
    omega = 2 * np.pi * np.asarray(ds[names.FREQUENCY].values, dtype=float)
    out = np.asarray(ds[names.FRF].sel(sel).values, dtype=np.complex128).copy()
    for lk, ak in zip(lam, res, strict=True):
        if np.isfinite(lk) and np.isfinite(ak):
            out -= mode_contribution(omega, complex(lk), complex(ak), model.dt, model.n_samples)
    return out


def plot_subtraction(
    ds: xr.Dataset,
    *,
    points: Sequence[Hashable] | None = None,
    frequency_range: tuple[float, float] | None = None,
    path: str | os.PathLike | None = None,
) -> Figure:
    """What the Subtraction Phase saw: the FRF, its residual, the noise floor and the threshold.

    Per point: |measured FRF| (grey); |residual| after subtracting every candidate the phase
    kept (blue); the estimated noise standard deviation per line (green) and the automatic stop
    threshold ``sigma * sqrt(T)`` on the residual's peak magnitude (red dashed; ``T`` is the
    ``threshold`` attribute of the stop statistic ``|Y|^2 / sigma^2``); the candidates'
    natural frequencies (dashed) and fit bands (shaded). This is the plot the paper's authors
    inspected by eye to decide when to stop subtracting: the phase stops when no residual peak
    rises above the red line.

    Parameters
    ----------
    ds : xarray.Dataset
        Result of ``ami_xr.subtract`` or ``ami_xr.identify`` (``frf``,
        ``subtraction_noise_floor``; candidates, bands and the stop statistic when present).
    points : sequence of point labels, optional
        Points to show.
    frequency_range : (float, float), optional
        Band to show, in Hz (default the whole band).
    path : str or path-like, optional
        Save the figure there.
    """
    require(ds, names.FRF, figure="plot_subtraction")
    if names.SUB_NOISE_FLOOR not in ds:
        raise AmiXrValueError(
            f"plot_subtraction: the Dataset has no {names.SUB_NOISE_FLOOR!r} "
            "(run ami_xr.subtract or ami_xr.identify first)"
        )
    threshold = None
    stop_attrs = ds[names.SUB_STOP_STATISTIC].attrs if names.SUB_STOP_STATISTIC in ds else {}
    if names.ATTR_THRESHOLD in stop_attrs:
        threshold = float(stop_attrs[names.ATTR_THRESHOLD])
    pts = select_points(ds, points, "plot_subtraction")
    ds = in_band(ds, frequency_range, "plot_subtraction")
    freq = ds[names.FREQUENCY].values
    band = (float(freq[0]), float(freq[-1]))
    ncol = min(len(pts), 4)
    nrow = int(np.ceil(len(pts) / ncol))
    fig = new_figure(
        3.4 * ncol, 2.8 * nrow, grid=(nrow, ncol), margins=(0.8, 0.15, 0.5, 0.3), gaps=(0.85, 0.7)
    )
    axes = fig.subplots(nrow, ncol, squeeze=False)
    for ax in axes.ravel()[len(pts) :]:
        ax.set_visible(False)
    for i, p in enumerate(pts):
        ax = axes.ravel()[i]
        sel = {names.POINT: p}
        g = ds[names.FRF].sel(sel).values
        ax.semilogy(freq, np.abs(g), color="0.7", lw=0.8, label="measured")
        residual = _subtraction_residual(ds, p)
        if residual is not None:
            ax.semilogy(freq, np.abs(residual), color="tab:blue", lw=0.7, label="residual")
        ax.minorticks_off()  # unlabelled; 8 a decade were a third of the drawing time
        sigma = float(np.asarray(ds[names.SUB_NOISE_FLOOR].sel(sel).values).ravel()[0])
        ax.axhline(sigma, color="tab:green", lw=1.2, label="noise floor (std)")
        if threshold is not None:
            ax.axhline(
                sigma * np.sqrt(threshold), color="tab:red", lw=1.2, ls="--", label="stop threshold"
            )
        if names.SUB_EIGENVALUE in ds:
            lam = np.atleast_1d(ds[names.SUB_EIGENVALUE].sel(sel).values)
            lam = lam[np.isfinite(lam)]
            mark_modes(ax, np.abs(lam) / (2 * np.pi), [""] * lam.size, text=False, band=band)
        if names.SUB_BAND_LOW in ds and names.SUB_BAND_HIGH in ds:
            lo = np.atleast_1d(ds[names.SUB_BAND_LOW].sel(sel).values)
            hi = np.atleast_1d(ds[names.SUB_BAND_HIGH].sel(sel).values)
            for a, b in zip(lo, hi, strict=True):
                if np.isfinite(a) and np.isfinite(b):
                    ax.axvspan(a, b, color="tab:orange", alpha=0.15, lw=0)
        drive = " (drive point)" if p == ds.attrs.get(names.ATTR_DRIVE_POINT) else ""
        set_title(ax, f"point {p}{drive}", fontsize=9)
        ax.set_xlabel("frequency [Hz]", fontsize=8)
        ax.set_ylabel(f"magnitude [{units_of(ds, names.FRF)}]", fontsize=8)
        ax.set_xlim(band)
        ax.legend(fontsize=6, loc="lower right")
    return finish(fig, path)


# --- mode vectors ------------------------------------------------------------------------------
def _vectors(ds: xr.Dataset, figure: str) -> tuple[xr.DataArray, str]:
    for var in (names.MODE_VECTOR, names.RESIDUE):
        if var in ds:
            return ds[var].transpose(names.POINT, names.MODE), var
    raise AmiXrValueError(
        f"{figure}: the Dataset has no {names.MODE_VECTOR!r} or {names.RESIDUE!r} "
        "(run ami_xr.identify first)"
    )


def _point_coordinate(ds: xr.Dataset, coord: str | None) -> str | None:
    if coord is not None:
        if coord not in ds.coords:
            raise AmiXrValueError(f"plot_mode_vectors: coord {coord!r} is not a coordinate of ds")
        return coord
    return next((c for c in POINT_COORDS if c in ds.coords), None)


def plot_mode_vectors(
    ds: xr.Dataset,
    *,
    coord: str | None = None,
    path: str | os.PathLike | None = None,
) -> Figure:
    """Mode vectors: magnitude and phase per point, and the shape along the structure.

    One row per mode. Columns: magnitude per point (bars), phase per point (degrees), and, when
    the points have a coordinate (``point_x``, ``point_y`` or ``point_z``, or ``coord``), the
    shape along it: the vector rotated so that its largest entry is real, real part plotted
    against the coordinate (imaginary part dotted: near zero for a normal mode). Modes whose
    quality flags are not empty have the flags in their row title.

    Parameters
    ----------
    ds : xarray.Dataset
        Identification result with ``mode_vector`` (or, failing that, ``residue``).
    coord : str, optional
        Point coordinate for the shape plot; by default the first of point_x/point_y/point_z.
    path : str or path-like, optional
        Save the figure there.
    """
    vec, var = _vectors(ds, "plot_mode_vectors")
    xname = _point_coordinate(ds, coord)
    labels = [str(p) for p in vec[names.POINT].values.tolist()]
    nmode = vec.sizes[names.MODE]
    npanel = 3 if xname is not None else 2
    # One block of stacked panels per mode, blocks in a grid: the figure stays at most
    # MAX_HEIGHT_IN tall whatever the number of modes (22 modes were 4 895 px in one column).
    block_h = 1.45 * npanel + 0.3
    rows_max = max(1, int((MAX_HEIGHT_IN - 0.5) // block_h))
    nblock_col = int(np.ceil(max(nmode, 1) / rows_max))
    nblock_row = int(np.ceil(max(nmode, 1) / nblock_col))
    # fixed layout: below each panel its point labels (rotated: as tall as the longest label)
    rotate = len(labels) > 8
    label_h = 0.12 + (0.06 * max(map(len, labels), default=1) if rotate else 0.1)
    fig = new_figure(
        max(7.0, 3.6 * nblock_col),
        nblock_row * block_h + 0.5,
        grid=(nblock_row, nblock_col),
        margins=(0.75, 0.35, 0.15 + label_h, 0.45),
        gaps=(0.8, 0.35 + label_h),
    )
    grid = fig.add_gridspec(nblock_row, nblock_col)
    panel_h = (block_h - 0.35 - label_h) / npanel
    inner_space = (label_h + 0.05) / max(panel_h - label_h, 0.1)
    fn = natural_frequencies(ds)
    flags = _flags(ds)
    pos = np.arange(len(labels))
    units = units_of(ds, var)
    for k in range(nmode):
        r, c = divmod(k, nblock_col)
        block = grid[r, c].subgridspec(npanel, 1, hspace=inner_space)
        ax_m = fig.add_subplot(block[0])
        ax_p = fig.add_subplot(block[1], sharex=ax_m)
        v = vec.isel({names.MODE: k}).values
        ax_m.bar(pos, np.abs(v), color="tab:blue")
        ax_p.bar(pos, np.degrees(np.angle(v)), color="tab:orange")
        ax_p.set_ylim(-190, 190)
        ax_p.set_yticks([-180, -90, 0, 90, 180])
        for ax in (ax_m, ax_p):
            ax.set_xticks(pos, labels, fontsize=6, rotation=90 if rotate else 0)
            ax.tick_params(axis="y", labelsize=6)
        title = f"mode {vec[names.MODE].values[k]}"
        if k < fn.size:
            title += f", {fn[k]:.4g} Hz"
        if k < len(flags) and flags[k]:
            title += f"  [{flags[k]}]"
        set_title(ax_m, title, above_offset=True, fontsize=8 if nblock_col < 4 else 7, loc="left")
        ax_m.set_ylabel(f"|{var}|" + (f" [{units}]" if units else " [-]"), fontsize=7)
        ax_p.set_ylabel("phase [deg]", fontsize=7)
        if xname is not None:
            ax_s = fig.add_subplot(block[2])
            x = np.asarray(ds[xname].values, dtype=float)
            order = np.argsort(x)
            big = v[np.argmax(np.abs(v))] if v.size and np.any(v != 0) else 1.0
            w = v * np.exp(-1j * np.angle(big))
            ax_s.plot(x[order], w.real[order], "o-", color="tab:blue", ms=3, label="real")
            ax_s.plot(x[order], w.imag[order], ":", color="0.5", label="imaginary")
            ax_s.axhline(0, color="0.8", lw=0.6)
            x_units = ds[xname].attrs.get(names.ATTR_UNITS, "")
            ax_s.set_xlabel(f"{xname}" + (f" [{x_units}]" if x_units else ""), fontsize=7)
            ax_s.set_ylabel("shape [-]", fontsize=7)
            ax_s.tick_params(labelsize=6)
            ax_s.legend(fontsize=6, loc="best")
    return finish(fig, path)


# --- MAC ---------------------------------------------------------------------------------------
def plot_mac(ds: xr.Dataset, *, path: str | os.PathLike | None = None) -> Figure:
    """The MAC matrix of the identified mode vectors, values printed in each cell.

    Uses the ``mac`` variable when present, otherwise computes it from ``mode_vector`` (or
    ``residue``). Off-diagonal values near 1 mean two "modes" look alike at the measured points.
    With a single point (one FRF) every entry is 1: the figure is refused
    (:class:`~ami_xr.errors.AmiXrValueError`, which the report turns into a note).

    Parameters
    ----------
    ds : xarray.Dataset
        Identification result.
    path : str or path-like, optional
        Save the figure there.
    """
    if ds.sizes.get(names.POINT, 2) < 2:
        raise AmiXrValueError(
            "plot_mac: skipped, the MAC needs mode vectors at 2 or more points; "
            f"with {ds.sizes[names.POINT]} FRF every entry is 1 and says nothing"
        )
    if names.MAC in ds:
        mac = np.asarray(ds[names.MAC].values, dtype=float)
    else:
        vec, _ = _vectors(ds, "plot_mac")
        mac = mac_matrix(vec.values)
    labels = labels_of_modes(ds) or list(range(1, mac.shape[0] + 1))
    n = mac.shape[0]
    fig = new_figure(
        1.0 + 0.55 * max(n, 3),
        0.8 + 0.5 * max(n, 3),
        grid=(1, 1),
        margins=(0.55, 0.1, 0.5, 0.3),
        gaps=(0, 0),
    )
    ax = fig.add_subplot()
    im = ax.imshow(mac, vmin=0, vmax=1, cmap="viridis")
    for i in range(n):
        for j in range(mac.shape[1]):
            value = mac[i, j]
            ax.text(
                j,
                i,
                "-" if not np.isfinite(value) else f"{value:.2f}",
                ha="center",
                va="center",
                fontsize=7,
                color="w" if value < 0.6 else "k",
            )
    ax.set_xticks(range(mac.shape[1]), labels[: mac.shape[1]], fontsize=8)
    ax.set_yticks(range(n), labels[:n], fontsize=8)
    ax.set_xlabel("mode", fontsize=8)
    ax.set_ylabel("mode", fontsize=8)
    set_title(ax, "MAC", fontsize=9)
    fig.colorbar(im, ax=ax, shrink=0.8)
    return finish(fig, path)


# --- modal table -------------------------------------------------------------------------------
def _flags(ds: xr.Dataset) -> list[str]:
    if names.QUALITY_FLAGS not in ds:
        return []
    return [str(f) for f in flags.flag_text(np.atleast_1d(ds[names.QUALITY_FLAGS].values))]


def plot_modal_table(ds: xr.Dataset, *, path: str | os.PathLike | None = None) -> Figure:
    """The modal table (mode, frequency in Hz and rad/s, damping %, detected-in, flags) as a figure.

    Parameters
    ----------
    ds : xarray.Dataset
        Identification result (``eigenvalue`` or ``natural_frequency``).
    path : str or path-like, optional
        Save the figure there.
    """
    rows = modal_table(ds)
    header = ["mode", "f [Hz]", "w [rad/s]", "zeta [%]", "detected in", "flags"]
    cells = [
        [
            str(r["mode"]),
            f"{r['frequency_hz']:.5g}",
            f"{r['frequency_rad_s']:.5g}",
            f"{r['damping_percent']:.4g}",
            r["detected_in"],
            r["flags"] or "-",
        ]
        for r in rows
    ]
    fig = new_figure(
        9.0, 0.6 + 0.3 * (len(cells) + 1), grid=(1, 1), margins=(0.1, 0.1, 0.1, 0.1), gaps=(0, 0)
    )
    ax = fig.add_subplot()
    ax.axis("off")
    if cells:
        table = ax.table(cellText=cells, colLabels=header, loc="center", cellLoc="center")
        table.auto_set_font_size(False)
        table.set_fontsize(8)
        table.auto_set_column_width(list(range(len(header))))
    else:
        ax.text(0.5, 0.5, "no modes identified", ha="center", va="center")
    return finish(fig, path)
