"""The report's figures, shared by the report (:mod:`ami_xr.app.report`) and its
multi-reference parts (:mod:`ami_xr.app.report_mimo`): the tables of figures (stem -> plotting
function, caption and, for those drawn only when their input is present, the variable they
need), the figures drawn by default, and the drawing of each into a PNG written atomically."""

from __future__ import annotations

import re
from pathlib import Path

import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.io.atomic import atomic_open

#: Report figures: file stem -> (function name in ami_xr.plot.modal, caption).
FIGURES: dict[str, tuple[str, str]] = {
    "modal_table": ("plot_modal_table", "Identified modes with their quality flags."),
    "bode": (
        "plot_bode",
        "Measured (grey) and synthesised (blue) FRFs; dashed lines mark the "
        "identified natural frequencies.",
    ),
    "nyquist": (
        "plot_nyquist",
        "Nyquist plots of each FRF near each mode (measured dots, "
        "synthesised line, circle at the natural frequency).",
    ),
    "subtraction": (
        "plot_subtraction",
        "Subtraction phase: FRF, residual, estimated noise floor and the automatic stop threshold.",
    ),
    "mode_vectors": (
        "plot_mode_vectors",
        "Mode vectors: magnitude and phase per point (and "
        "shape along the structure where point coordinates "
        "are given).",
    ),
    "mac": ("plot_mac", "Modal Assurance Criterion between the identified mode vectors."),
}


#: Figures of the measurement (ami_xr.plot.measurement): stem -> (function, caption, the
#: variable they need). By default drawn only when that variable is present.
MEASUREMENT_FIGURES: dict[str, tuple[str, str, str]] = {
    "coherence": (
        "plot_coherence",
        "Coherence of each FRF: where it drops well below 1 the FRF is not to be trusted.",
        names.COHERENCE,
    ),
    "force_spectrum": (
        "plot_force_spectrum",
        "Force autospectrum relative to its peak: the band the excitation reached.",
        names.FORCE_AUTOSPECTRUM,
    ),
    "hits": (
        "plot_hits",
        "Peak force of each impact hit; rejected hits (red) with their reason.",
        names.HIT_PEAK_FORCE,
    ),
}


#: Figures of ami_xr.stability (ami_xr.plot.stability): stem -> (function, caption, the variable
#: they need). By default drawn only when that variable is present.
STABILITY_FIGURES: dict[str, tuple[str, str, str]] = {
    "stability": (
        "plot_stability",
        "Mode stability: identify re-run over detection thresholds (pfa) and analysis bands, one "
        "row per variant; filled: the mode found again, open: missed inside the band. Above "
        "each mode its label and the fraction of variants finding it (1: solid).",
        names.STABILITY_FOUND,
    ),
}


#: Figures on the measurement geometry (ami_xr.plot.geometry): stem -> (function, caption).
#: Drawn by default when the points have coordinates (point_x/y/z), with one animated GIF per
#: mode (mode_shape_<mode>.gif); without coordinates the mode_vectors bars remain.
GEOMETRY_FIGURES: dict[str, tuple[str, str]] = {
    "mode_shapes": (
        "plot_mode_shapes",
        "Mode shapes on the measurement geometry: real part of the phase-normalised mode "
        "vector (largest component 1), undeformed points faint.",
    ),
}


#: Figures with a frequency axis: they take ``frequency_range``.
BANDED = frozenset({"bode", "subtraction", "coherence", "force_spectrum"})


def known_figures() -> dict[str, tuple]:
    """Every figure a report can draw, in the order of the page."""
    return {**MEASUREMENT_FIGURES, **FIGURES, **STABILITY_FIGURES, **GEOMETRY_FIGURES}


def wanted_figures(ds: xr.Dataset, figures: tuple[str, ...] | None) -> tuple[str, ...]:
    """``figures``, checked, or by default all of :data:`FIGURES`, the measurement and
    stability figures whose inputs ``ds`` has, and the geometry figures when its points have
    coordinates."""
    from ami_xr.io.geometry import has_coordinates

    known = known_figures()
    if figures is None:
        wanted = tuple(k for k, v in MEASUREMENT_FIGURES.items() if v[2] in ds) + tuple(FIGURES)
        wanted += tuple(k for k, v in STABILITY_FIGURES.items() if v[2] in ds)
        wanted += tuple(GEOMETRY_FIGURES) if has_coordinates(ds) else ()
    else:
        wanted = tuple(figures)
    unknown = [f for f in wanted if f not in known]
    if unknown:
        raise AmiXrValueError(f"report: unknown figures {unknown}; choose from {list(known)}")
    return wanted


def draw_figures(
    ds: xr.Dataset,
    outdir: Path,
    wanted: tuple[str, ...],
    frequency_range: tuple[float, float] | None,
) -> tuple[list[tuple[str, str, bytes]], list[tuple[str, str]]]:
    """Draw the ``wanted`` figures of ``ds`` in page order, each written atomically as
    ``<stem>.png`` (the geometry figures with one animated GIF per mode). Returns the figures
    made (stem, caption, image bytes) and those skipped for missing inputs (stem, reason)."""
    from ami_xr.plot import geometry as plot_geometry
    from ami_xr.plot import measurement as plot_measurement
    from ami_xr.plot import modal as plot
    from ami_xr.plot import stability as plot_stability
    from ami_xr.plot.common import gc_paused, png_bytes

    known = known_figures()
    made: list[tuple[str, str, bytes]] = []
    skipped: list[tuple[str, str]] = []
    for stem in sorted(wanted, key=list(known).index):
        func_name, caption = known[stem][:2]
        module = plot_measurement if stem in MEASUREMENT_FIGURES else plot
        module = plot_geometry if stem in GEOMETRY_FIGURES else module
        module = plot_stability if stem in STABILITY_FIGURES else module
        kwargs = {"frequency_range": frequency_range} if stem in BANDED and frequency_range else {}
        try:
            with gc_paused():  # a third of the drawing time otherwise (plot.common.gc_paused)
                fig = getattr(module, func_name)(ds, **kwargs)
        except AmiXrValueError as err:
            skipped.append((stem, str(err)))
            continue
        png = png_bytes(fig)  # at the size the page shows it (plot.common.PAGE_WIDTH_PX)
        with atomic_open(outdir / f"{stem}.png", "wb") as fh:
            fh.write(png)
        made.append((stem, caption, png))
        if stem in GEOMETRY_FIGURES:
            made += _mode_animations(ds, outdir, skipped)
    return made, skipped


def draw_png(func, data: xr.Dataset, kwargs: dict) -> bytes:
    """The PNG of ``func(data, **kwargs)`` as the report draws every figure."""
    from ami_xr.plot.common import gc_paused, png_bytes

    with gc_paused():
        fig = func(data, **kwargs)
    return png_bytes(fig)


def _mode_animations(
    ds: xr.Dataset, outdir: Path, skipped: list[tuple[str, str]]
) -> list[tuple[str, str, bytes]]:
    """One animated GIF per mode (mode_shape_<mode>.gif, written atomically) for the page."""
    from ami_xr.plot.geometry import animate_mode_shape

    out: list[tuple[str, str, bytes]] = []
    for label in ds[names.MODE].values.tolist():
        stem = "mode_shape_" + re.sub(r"[^A-Za-z0-9_.-]", "_", str(label))
        try:
            gif = animate_mode_shape(ds, label, outdir / f"{stem}.gif")
        except ImportError as err:  # pragma: no cover - pillow ships with matplotlib
            skipped.append(("mode shape animations", str(err)))
            break
        caption = f"Mode {label} animated: shape x cos(phase) over one cycle on the geometry."
        out.append((stem, caption, gif))
    return out
