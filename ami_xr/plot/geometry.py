"""Mode shapes drawn on the measurement geometry (matplotlib; animations also need pillow).

When the points carry coordinates (``point_x``, ``point_y``, ``point_z``; see
:func:`ami_xr.make_frf_dataset`'s ``coordinates``), :func:`plot_mode_shapes` draws each mode's
real, phase-normalised shape (``mode_vector_normalised``: rotated so that its largest component
is real and scaled so that it is 1) on the geometry, and :func:`animate_mode_shape` writes an
animated GIF of ``shape * cos(phase)``.

How the shape is drawn depends on the geometry:

* one coordinate (a line of points, e.g. ``point_x`` only): the deflection
  ``scale * shape`` against that coordinate (the undeformed line at 0);
* two coordinates, one of them the deformation ``direction``: a planar view of the two,
  deformed point ``coordinate + scale * shape`` along ``direction``;
* otherwise (a planar grid deformed out of its plane, or three coordinates): a 3-D view,
  missing coordinates taken as 0, deformed along ``direction`` (default ``"z"``).

SIMO data has one scalar per point (the measured direction), so the shape moves each point along
one ``direction``. Points are joined in their order, or by ``lines`` (pairs of point labels).
"""

from __future__ import annotations

import io
import os
from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from typing import IO, TYPE_CHECKING, Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.io.atomic import atomic_open
from ami_xr.io.geometry import point_coordinates
from ami_xr.plot.common import finish, natural_frequencies, new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_mode_shapes", "animate_mode_shape", "mode_shapes_real", "GIF_DPI"]

#: Pixels per inch of an animation frame (frames are 4 x 3 inches: 400 x 300 px).
GIF_DPI = 100
_GIF_SIZE_IN = (4.0, 3.0)
_GIF_COLORS = 32  # palette size of the GIF: line drawings need few colours
_UNDEFORMED = {"color": "0.6", "alpha": 0.45, "lw": 1.0, "ls": "--", "marker": "o", "ms": 2.5}
_DEFORMED = {"color": "tab:blue", "lw": 1.6, "marker": "o", "ms": 3.5}


@dataclass
class _Geometry:
    """How the points are drawn: ``kind`` line | plane | space, the coordinates on the plot
    axes (``axes``), their values (``xyz``, missing ones zero), the deformation coordinate."""

    kind: str
    axes: tuple[str, ...]
    xyz: dict[str, np.ndarray]
    direction: str | None
    units: str

    def label(self, name: str) -> str:
        return f"{name} [{self.units}]" if self.units else name

    def deformed(self, shape: np.ndarray, scale: float) -> list[np.ndarray]:
        """Data of the deformed points on each plot axis: coordinate + scale * shape along the
        direction (a line geometry: the deflection scale * shape as the second axis)."""
        if self.kind == "line":
            return [self.xyz[self.axes[0]], scale * shape]
        return [self.xyz[a] + (scale * shape if a == self.direction else 0.0) for a in self.axes]

    def undeformed(self) -> list[np.ndarray]:
        if self.kind == "line":
            return [self.xyz[self.axes[0]], np.zeros_like(self.xyz[self.axes[0]])]
        return [self.xyz[a] for a in self.axes]


def _geometry(ds: xr.Dataset, direction: str | None, figure: str) -> _Geometry:
    coords = point_coordinates(ds, figure)
    units = next(
        (
            str(ds.coords[n].attrs[names.ATTR_UNITS])
            for n in coords
            if names.ATTR_UNITS in ds.coords[n].attrs
        ),
        "",
    )
    if direction is not None and direction not in ("x", "y", "z"):
        raise AmiXrValueError(
            f"{figure}: direction must be 'x', 'y' or 'z' (the measured direction), got "
            f"{direction!r}"
        )
    present = tuple(coords)
    n = ds.sizes[names.POINT]
    xyz = {c: coords.get(c, np.zeros(n)) for c in names.POINT_COORDS}
    if len(present) == 1:
        return _Geometry("line", present, xyz, None, units)
    along = f"{names.POINT}_{direction or 'z'}"
    if len(present) == 2 and along in present:
        return _Geometry("plane", present, xyz, along, units)
    return _Geometry("space", names.POINT_COORDS, xyz, along, units)


def mode_shapes_real(ds: xr.Dataset, figure: str = "mode_shapes_real") -> xr.DataArray:
    """Real part of the phase-normalised mode vectors, dims (point, mode), largest entry 1.

    ``mode_vector_normalised`` when ``ds`` has it; else ``mode_vector`` (or ``residue``)
    normalised the same way (:func:`ami_xr.core.modal.phase_normalised`).
    """
    from ami_xr.core.modal import phase_normalised

    if names.MODE_VECTOR_NORMALISED in ds:
        vec = ds[names.MODE_VECTOR_NORMALISED].transpose(names.POINT, names.MODE)
        return xr.DataArray(np.real(vec.values), coords=vec.coords, dims=vec.dims)
    for var in (names.MODE_VECTOR, names.RESIDUE):
        if var in ds:
            vec = ds[var].transpose(names.POINT, names.MODE)
            values = np.real(phase_normalised(vec.values, unit=True))
            return xr.DataArray(values, coords=vec.coords, dims=vec.dims)
    raise AmiXrValueError(
        f"{figure}: the Dataset has no {names.MODE_VECTOR_NORMALISED!r}, {names.MODE_VECTOR!r} or "
        f"{names.RESIDUE!r} (run ami_xr.identify first)"
    )


def _select_modes(shapes: xr.DataArray, modes: Sequence[Hashable] | None, figure: str) -> list:
    labels = list(shapes[names.MODE].values.tolist())
    if modes is None:
        return labels
    modes = [modes] if isinstance(modes, (str, int, np.integer)) else list(modes)
    unknown = [m for m in modes if m not in labels]
    if unknown or not modes:
        raise AmiXrValueError(
            f"{figure}: modes {unknown or modes} are not among the modes {labels}"
        )
    return modes


def _segments(ds: xr.Dataset, lines: Sequence[tuple[Hashable, Hashable]] | None, figure: str):
    """Index pairs of the segments to draw, or None (points joined in their order)."""
    if lines is None:
        return None
    labels = list(ds[names.POINT].values.tolist())
    pairs = []
    for pair in lines:
        try:
            a, b = pair
        except (TypeError, ValueError):
            raise AmiXrValueError(
                f"{figure}: lines must be pairs of point labels, got {pair!r}"
            ) from None
        missing = [p for p in (a, b) if p not in labels]
        if missing:
            raise AmiXrValueError(f"{figure}: lines: points {missing} are not among {labels}")
        pairs.append((labels.index(a), labels.index(b)))
    return pairs


def _default_scale(geo: _Geometry) -> float:
    if geo.kind == "line":
        return 1.0
    extent = max(float(np.ptp(geo.xyz[a])) for a in geo.axes)
    return 0.15 * extent if extent > 0 else 1.0


def _mode_title(ds: xr.Dataset, label: Hashable) -> str:
    labels = list(ds[names.MODE].values.tolist())
    k = labels.index(label)
    fn = natural_frequencies(ds)
    text = f"mode {label}"
    if k < fn.size:
        text += f": {fn[k]:.4g} Hz"
    if names.DAMPING_RATIO in ds:
        zeta = np.atleast_1d(np.asarray(ds[names.DAMPING_RATIO].values, dtype=float))
    elif names.EIGENVALUE in ds:
        lam = np.atleast_1d(np.asarray(ds[names.EIGENVALUE].values, dtype=np.complex128))
        zeta = -lam.real / np.where(np.abs(lam) > 0, np.abs(lam), np.nan)
    else:
        zeta = np.zeros(0)
    if k < zeta.size and np.isfinite(zeta[k]):
        text += f", ζ {100 * zeta[k]:.3g} %"
    return text


def _draw(ax, geo: _Geometry, shape: np.ndarray, scale: float, segments, limits) -> list:
    """Draw undeformed (faint) and deformed points on ``ax``; return the deformed artists
    (the first one the labelled line through every point in order)."""
    under, de = geo.undeformed(), geo.deformed(shape, scale)
    joined = segments is None
    style = "-" if joined else "none"
    ax.plot(*under, **{**_UNDEFORMED, "ls": "--" if joined else "none"}, label="undeformed")
    artists = ax.plot(*de, **{**_DEFORMED, "ls": style}, label=f"deformed (scale {scale:.3g})")
    for i, j in segments or ():
        ax.plot(*[u[[i, j]] for u in under], **{**_UNDEFORMED, "marker": None})
        artists += ax.plot(*[d[[i, j]] for d in de], **{**_DEFORMED, "marker": None})
    if geo.kind == "line":
        ax.set_xlabel(geo.label(geo.axes[0]), fontsize=7)
        ax.set_ylabel("deflection: scale × shape [-]", fontsize=7)
        ax.axhline(0, color="0.85", lw=0.6)
    else:
        for name, setter in zip(geo.axes, ("set_xlabel", "set_ylabel", "set_zlabel"), strict=False):
            getattr(ax, setter)(geo.label(name), fontsize=7)
    if limits is not None:
        for lim, setter in zip(limits, ("set_xlim", "set_ylim", "set_zlim"), strict=False):
            getattr(ax, setter)(*lim)
    if geo.kind == "plane":
        ax.set_aspect("equal", adjustable="box")
    ax.tick_params(labelsize=6)
    return artists


def _move(artists: list, geo: _Geometry, shape: np.ndarray, scale: float, segments) -> None:
    """Set the deformed artists of :func:`_draw` to another shape (an animation frame)."""
    de = geo.deformed(shape, scale)
    parts = [de] + [[d[[i, j]] for d in de] for i, j in segments or ()]
    for artist, data in zip(artists, parts, strict=True):
        if geo.kind == "space":
            artist.set_data_3d(*data)
        else:
            artist.set_data(*data)


def _limits(geo: _Geometry, scale: float) -> list[tuple[float, float]]:
    """Axis limits that hold every frame of an animation (shape * cos, |shape| <= 1)."""
    out = []
    for data, name in zip(
        geo.undeformed(), geo.axes if geo.kind != "line" else (geo.axes[0], None), strict=True
    ):
        moves = geo.kind == "line" and name is None or name == geo.direction
        lo, hi = float(np.min(data)), float(np.max(data))
        if moves:
            lo, hi = lo - abs(scale), hi + abs(scale)
        pad = 0.05 * (hi - lo) if hi > lo else 0.5
        out.append((lo - pad, hi + pad))
    return out


def plot_mode_shapes(
    ds: xr.Dataset,
    modes: Sequence[Hashable] | None = None,
    *,
    direction: str | None = None,
    scale: float | None = None,
    lines: Sequence[tuple[Hashable, Hashable]] | None = None,
    path: str | os.PathLike | None = None,
) -> Figure:
    """Each mode's shape drawn on the measurement geometry, one panel per mode.

    Points at their coordinates (undeformed, faint) and moved by ``scale * shape`` along
    ``direction`` (deformed), ``shape`` the real part of the phase-normalised mode vector
    (largest component 1; see :func:`mode_shapes_real`). The panel title gives the mode label,
    natural frequency and damping ratio. The module docstring says how each geometry is drawn.

    Parameters
    ----------
    ds : xarray.Dataset
        Identification result with point coordinates ``point_x`` (and/or ``point_y``,
        ``point_z``) and ``mode_vector_normalised`` (or ``mode_vector`` / ``residue``).
    modes : sequence of mode labels, optional
        Modes to draw (default all).
    direction : {"x", "y", "z"}, optional
        Direction the measured response points in (default ``"z"``); ignored for a line of
        points (one coordinate), where the deflection is drawn against the coordinate.
    scale : float, optional
        Deformation scale in coordinate units per unit shape; default 15 % of the largest
        extent of the geometry (1 for a line of points).
    lines : sequence of (label, label), optional
        Segments to draw between points; default the points joined in their order.
    path : str or path-like, optional
        Save the figure there (atomically).

    Raises
    ------
    AmiXrValueError
        Without point coordinates (the message names point_x, point_y, point_z), without mode
        vectors, or for an unknown mode, direction or line.
    """
    figure = "plot_mode_shapes"
    geo = _geometry(ds, direction, figure)
    shapes = mode_shapes_real(ds, figure)
    chosen = _select_modes(shapes, modes, figure)
    segments = _segments(ds, lines, figure)
    scale = _default_scale(geo) if scale is None else _check_scale(scale, figure)
    ncol = min(3, len(chosen))
    nrow = int(np.ceil(len(chosen) / ncol))
    fig = new_figure(3.4 * ncol + 0.3, 2.9 * nrow + 0.3)
    projection = "3d" if geo.kind == "space" else None
    for k, label in enumerate(chosen):
        ax = fig.add_subplot(nrow, ncol, k + 1, projection=projection)
        shape = shapes.sel({names.MODE: label}).values
        _draw(ax, geo, shape, scale, segments, None)
        ax.set_title(_mode_title(ds, label), fontsize=8, loc="left")
        ax.legend(fontsize=6, loc="best")
    return finish(fig, path)


def _check_scale(scale: Any, figure: str) -> float:
    try:
        value = float(scale)
    except (TypeError, ValueError):
        raise AmiXrValueError(f"{figure}: scale must be a number, got {scale!r}") from None
    if not np.isfinite(value) or value == 0:
        raise AmiXrValueError(f"{figure}: scale must be finite and non-zero, got {scale!r}")
    return value


def animate_mode_shape(
    ds: xr.Dataset,
    mode: Hashable,
    path_or_buffer: str | os.PathLike | IO[bytes] | None = None,
    frames: int = 16,
    *,
    direction: str | None = None,
    scale: float | None = None,
    lines: Sequence[tuple[Hashable, Hashable]] | None = None,
    fps: float = 12.0,
) -> bytes:
    """An animated GIF of one mode: ``shape * cos(2 pi k / frames)`` for ``k < frames``.

    Drawn as :func:`plot_mode_shapes` draws the mode, with axis limits fixed over the cycle;
    400 x 300 px, a 32-colour palette, looping. The frames are grabbed as
    :class:`matplotlib.animation.PillowWriter` grabs them and saved with pillow.

    Parameters
    ----------
    ds, direction, scale, lines
        As for :func:`plot_mode_shapes`.
    mode : mode label
        The mode to animate.
    path_or_buffer : str, path-like or binary file object, optional
        Where to write the GIF: a path is written atomically; a file object gets the bytes.
    frames : int
        Frames per cycle (2 to 120).
    fps : float
        Frames per second.

    Returns
    -------
    bytes
        The GIF file's content.
    """
    figure = "animate_mode_shape"
    try:
        from PIL import Image
    except ImportError as err:  # pragma: no cover - pillow ships with matplotlib
        raise ImportError("animations need the package pillow (it comes with matplotlib)") from err
    if (
        isinstance(frames, bool)
        or not isinstance(frames, (int, np.integer))
        or not (2 <= frames <= 120)
    ):
        raise AmiXrValueError(f"{figure}: frames must be an integer from 2 to 120, got {frames!r}")
    if not (isinstance(fps, (int, float)) and np.isfinite(fps) and fps > 0):
        raise AmiXrValueError(f"{figure}: fps must be a positive number, got {fps!r}")
    geo = _geometry(ds, direction, figure)
    shapes = mode_shapes_real(ds, figure)
    (label,) = _select_modes(shapes, [mode], figure)
    segments = _segments(ds, lines, figure)
    scale = _default_scale(geo) if scale is None else _check_scale(scale, figure)
    shape = shapes.sel({names.MODE: label}).values
    fig = new_figure(*_GIF_SIZE_IN)
    ax = fig.add_subplot(1, 1, 1, projection="3d" if geo.kind == "space" else None)
    ax.set_title(_mode_title(ds, label), fontsize=8, loc="left")
    artists = _draw(ax, geo, shape, scale, segments, _limits(geo, scale))
    put_text = ax.text2D if geo.kind == "space" else ax.text  # 3-D axes place text by text2D
    stamp = put_text(
        0.99, 0.99, "", transform=ax.transAxes, ha="right", va="top", fontsize=7, color="0.3"
    )
    canvas = fig.canvas
    canvas.draw()  # the layout engine places the axes once; frames reuse that layout
    fig.set_layout_engine("none")
    images = []
    for k in range(int(frames)):
        phase = 2 * np.pi * k / int(frames)
        _move(artists, geo, shape * np.cos(phase), scale, segments)
        stamp.set_text(f"phase {np.degrees(phase):.0f}°")
        canvas.draw()
        rgb = Image.fromarray(np.asarray(canvas.buffer_rgba())).convert("RGB")
        images.append(rgb.quantize(colors=_GIF_COLORS))
    out = io.BytesIO()
    images[0].save(
        out,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=int(round(1000 / fps)),
        loop=0,
    )
    data = out.getvalue()
    if path_or_buffer is not None:
        if hasattr(path_or_buffer, "write"):
            path_or_buffer.write(data)
        else:
            with atomic_open(path_or_buffer, "wb") as fh:
                fh.write(data)
    return data
