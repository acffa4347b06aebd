"""Helpers shared by the figure modules (:mod:`ami_xr.plot`, :mod:`ami_xr.plot.measurement`):
a Figure on its own Agg canvas, atomic saving, input checks, point and band selection, mode
marks. No matplotlib is imported until a figure is made.
"""

from __future__ import annotations

import gc
import os
from collections.abc import Hashable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.io.atomic import atomic_open

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

#: Dots per inch of every saved figure (the report's PNGs): pixel size = inches x DPI.
DPI = 110
#: Widest image the report's page shows at its own size (CSS pixels); figures are drawn no
#: wider, so no pixel is drawn that the browser then scales away.
PAGE_WIDTH_PX = 1200
#: Widest figure, inches (PAGE_WIDTH_PX at DPI).
MAX_WIDTH_IN = PAGE_WIDTH_PX / DPI
#: PNG options of every saved figure: zlib level 1 encodes several times faster than the
#: default 6 for files a few per cent larger.
PNG_OPTIONS = {"pil_kwargs": {"compress_level": 1}, "metadata": {"Software": None}}

POINT_COORDS = tuple(f"{names.POINT}_{axis}" for axis in "xyz")

_MAX_POINTS = 12  # beyond this, figures show the points with the strongest response


def new_figure(
    width: float,
    height: float,
    *,
    grid: tuple[int, int] | None = None,
    margins: tuple[float, float, float, float] = (0.8, 0.25, 0.55, 0.4),
    gaps: tuple[float, float] = (0.8, 0.7),
) -> Figure:
    """A Figure on its own Agg canvas, at most MAX_WIDTH_IN wide.

    With ``grid`` (rows, columns of equal axes) the layout is fixed: ``margins`` (left, right,
    bottom, top) and ``gaps`` (between columns, between rows) in inches. The figure is then
    drawn once when saved; a layout engine (constrained layout, used without ``grid``) measures
    every text and draws twice, which made up half the drawing time of the report.
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            "plots need the optional package matplotlib: pip install 'ami_xr[plot]'"
        ) from err
    width = min(width, MAX_WIDTH_IN)
    if grid is None:
        fig = Figure(figsize=(width, height), layout="constrained")
    else:
        fig = Figure(figsize=(width, height))
        fixed_layout(fig, *grid, margins=margins, gaps=gaps)
    FigureCanvasAgg(fig)  # Agg for this figure only; the global backend is left alone
    return fig


def fixed_layout(
    fig: Figure,
    nrow: int,
    ncol: int,
    *,
    margins: tuple[float, float, float, float],
    gaps: tuple[float, float],
) -> None:
    """Set the subplot parameters of ``fig`` from margins and gaps in inches (see new_figure)."""
    width, height = fig.get_size_inches()
    left, right, bottom, top = margins
    wgap, hgap = gaps
    ax_w = max((width - left - right - wgap * (ncol - 1)) / ncol, 0.1)
    ax_h = max((height - bottom - top - hgap * (nrow - 1)) / nrow, 0.1)
    fig.subplots_adjust(
        left=left / width,
        right=1 - right / width,
        bottom=bottom / height,
        top=1 - top / height,
        wspace=wgap / ax_w,
        hspace=hgap / ax_h,
    )


def set_title(ax, text: str, *, above_offset: bool = False, **kwargs) -> None:
    """Title at a fixed height: matplotlib's automatic placement measures the axes' texts at
    every draw (a quarter of the report's drawing time). ``above_offset``: high enough to clear
    the y-axis offset text ("1e-3") drawn above the top left corner of a linear axis."""
    ax.set_title(text, y=1.0, pad=14.0 if above_offset else 6.0, **kwargs)


@contextmanager
def gc_paused() -> Iterator[None]:
    """Python's cyclic garbage collector off for the block (as it was before, afterwards).

    Building and drawing a figure allocates tens of thousands of small matplotlib objects; every
    700 of them start a collection, and every so often a full one walks every object of the
    process (xarray, scipy, numba: some 260 000) - a third of the drawing time of the report.
    The figure's own garbage is collected later, as usual.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def png_bytes(fig: Figure) -> bytes:
    """The figure as PNG at DPI (PNG_OPTIONS)."""
    import io

    buf = io.BytesIO()
    with gc_paused():
        fig.savefig(buf, format="png", dpi=DPI, **PNG_OPTIONS)
    return buf.getvalue()


def finish(fig: Figure, path: str | os.PathLike | None) -> Figure:
    if path is not None:
        # Saved atomically; matplotlib cannot see the suffix of a file object, so pass it on.
        suffix = os.path.splitext(os.fspath(path))[1][1:].lower()
        options = PNG_OPTIONS if suffix in ("", "png") else {}
        with atomic_open(path, "wb") as fh, gc_paused():
            fig.savefig(fh, format=suffix or None, dpi=DPI, **options)
    return fig


def require(ds: xr.Dataset, *variables: str, figure: str) -> None:
    missing = [v for v in variables if v not in ds.variables]
    if missing:
        raise AmiXrValueError(
            f"{figure}: the Dataset has no {', '.join(repr(m) for m in missing)} "
            f"(it has {sorted(map(str, ds.data_vars))})"
        )


def select_points(ds: xr.Dataset, points: Sequence[Hashable] | None, figure: str) -> list:
    labels = list(ds[names.POINT].values.tolist())
    if points is not None:
        points = list(points)
        unknown = [p for p in points if p not in labels]
        if unknown:
            raise AmiXrValueError(f"{figure}: points {unknown} are not among the points {labels}")
        return points
    if len(labels) <= _MAX_POINTS or names.FRF not in ds:
        return labels[:_MAX_POINTS]
    # Many points: show the strongest FRFs, in their original order.
    peak = np.abs(ds[names.FRF]).max(names.FREQUENCY).values
    keep = set(np.argsort(peak)[::-1][:_MAX_POINTS].tolist())
    return [lab for i, lab in enumerate(labels) if i in keep]


def natural_frequencies(ds: xr.Dataset) -> np.ndarray:
    if names.NATURAL_FREQUENCY in ds:
        return np.atleast_1d(np.asarray(ds[names.NATURAL_FREQUENCY].values, dtype=float))
    if names.EIGENVALUE in ds:
        return np.abs(np.atleast_1d(ds[names.EIGENVALUE].values)) / (2 * np.pi)
    return np.zeros(0)


def labels_of_modes(ds: xr.Dataset) -> list:
    if names.MODE in ds.coords:
        return list(ds[names.MODE].values.tolist())
    return list(range(1, natural_frequencies(ds).size + 1))


def label_levels(fn: np.ndarray, lo: float, hi: float, min_gap: float = 0.035) -> list[int]:
    """Stagger level (0, 1, 2, ...) of each mode label so that labels closer than ``min_gap``
    (fraction of the axis width) to one on the same level move down a level."""
    span = hi - lo if hi > lo else 1.0
    last: list[float] = []  # last x (axis fraction) used on each level
    levels = [0] * fn.size
    for k in np.argsort(fn):
        x = (fn[k] - lo) / span
        level = next((i for i, x0 in enumerate(last) if x - x0 >= min_gap), len(last))
        if level == len(last):
            last.append(x)
        last[level] = x
        levels[k] = level
    return levels


def mark_modes(
    ax, fn: np.ndarray, labels: Sequence, text: bool, band: tuple[float, float] | None = None
) -> None:
    """Dashed lines at the natural frequencies inside ``band``; with ``text`` their mode labels,
    staggered downwards from the top of the axes where neighbours would collide."""
    fn = np.asarray(fn, dtype=float)
    keep = np.isfinite(fn)
    if band is not None:
        keep &= (fn >= band[0]) & (fn <= band[1])
    fn_in = fn[keep]
    labels_in = [lab for lab, k in zip(labels, keep, strict=False) if k]
    lo, hi = band if band is not None else (fn_in.min(initial=0.0), fn_in.max(initial=1.0))
    levels = label_levels(fn_in, lo, hi) if text else [0] * fn_in.size
    if fn_in.size:  # one collection for all the lines, not one artist per mode
        ax.vlines(
            fn_in,
            0,
            1,
            transform=ax.get_xaxis_transform(),
            colors="tab:red",
            lw=0.8,
            linestyles="--",
            alpha=0.7,
        )
    for i, (f, lab) in enumerate(zip(fn_in, labels_in, strict=False)):
        if text:
            ax.annotate(
                str(lab),
                (f, 0.98 - 0.08 * (levels[i] % 4)),
                xycoords=("data", "axes fraction"),
                ha="center",
                va="top",
                fontsize=7,
                color="tab:red",
                bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.8},
            )


def in_band(ds: xr.Dataset, frequency_range: tuple[float, float] | None, figure: str):
    """``ds`` cut to ``frequency_range`` (Hz), checked to keep at least two lines."""
    if frequency_range is None:
        return ds
    f0, f1 = (float(f) for f in frequency_range)
    if not f0 < f1:
        raise AmiXrValueError(f"{figure}: frequency_range must have f0 < f1, got {(f0, f1)!r}")
    out = ds.sel({names.FREQUENCY: slice(f0, f1)})
    if out.sizes[names.FREQUENCY] < 2:
        f = ds[names.FREQUENCY].values
        raise AmiXrValueError(
            f"{figure}: frequency_range {(f0, f1)!r} holds fewer than 2 lines "
            f"(the data span {f[0]:.6g} to {f[-1]:.6g} Hz)"
        )
    return out


def units_of(ds: xr.Dataset, var: str) -> str:
    return str(ds[var].attrs.get(names.ATTR_UNITS, "")) if var in ds else ""


def draw_noise_model(ax, ds, point, freq) -> None:
    """Draw identify's noise model at ``point`` on a magnitude axis: the noise std of one line,
    ``noise_model_level * noise_model_shape`` (issue 37); nothing without one."""
    if "noise_model_level" not in ds or "noise_model_shape" not in ds:
        return
    level = ds["noise_model_level"]
    if level.dims != (names.POINT,):
        return
    std = float(level.sel({names.POINT: point}).values) * ds["noise_model_shape"].values
    ax.semilogy(freq, std, color="tab:red", lw=0.8, ls=":", label="noise (model)")
