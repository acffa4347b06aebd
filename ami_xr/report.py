"""The modal table and the identification report (one self-contained index.html, PNGs and CSV).

``modal_table`` and ``format_modal_table`` need no matplotlib (the CLI prints the table with
them); ``report`` draws the figures of :mod:`ami_xr.plot` and needs the ``plot`` extra.
"""

from __future__ import annotations

import base64
import csv
import html
import importlib
import io
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.atomic import atomic_open
from ami_xr.plot_common import PAGE_WIDTH_PX

__all__ = [
    "modal_table",
    "modal_table_csv_rows",
    "format_modal_table",
    "report",
    "FIGURES",
    "MEASUREMENT_FIGURES",
    "GEOMETRY_FIGURES",
    "STABILITY_FIGURES",
    "STD_COLUMNS",
    "INDICATOR_COLUMNS",
]


#: Report figures: file stem -> (plot function name in ami_xr.plot, caption).
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

#: Figures of the measurement (ami_xr.plot_measurement): stem -> (function, caption, the
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


#: Figures of ami_xr.stability (ami_xr.plot_stability): stem -> (function, caption, the variable
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


#: Figures on the measurement geometry (ami_xr.plot_geometry): stem -> (function, caption).
#: Drawn by default when the points have coordinates (point_x/y/z), with one animated GIF per
#: mode (mode_shape_<mode>.gif); without coordinates the mode_vectors bars remain.
GEOMETRY_FIGURES: dict[str, tuple[str, str]] = {
    "mode_shapes": (
        "plot_mode_shapes",
        "Mode shapes on the measurement geometry: real part of the phase-normalised mode "
        "vector (largest component 1), undeformed points faint.",
    ),
}


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        value = value.decode()
    text = str(value)
    return "" if text in ("nan", "None") else text


def modal_table(ds: xr.Dataset) -> list[dict[str, Any]]:
    """One row per identified mode.

    Parameters
    ----------
    ds : xarray.Dataset
        Identification result with ``eigenvalue`` (rad/s) or ``natural_frequency`` (Hz) and
        ``damping_ratio``; ``detected`` (point, mode) and ``quality_flags`` (mode) are used when
        present.

    Returns
    -------
    list of dict
        Keys ``mode``, ``frequency_hz``, ``frequency_rad_s``, ``damping_percent``,
        ``eigenvalue`` (complex rad/s or nan), ``detected_in`` (point labels joined by spaces, or
        "-" when unknown) and ``flags`` ("" when none).
    """
    if names.EIGENVALUE in ds:
        lam = np.atleast_1d(np.asarray(ds[names.EIGENVALUE].values, dtype=np.complex128))
        wn = np.abs(lam)
        fn = wn / (2 * np.pi)
        zeta = np.where(wn > 0, -lam.real / np.where(wn > 0, wn, 1), np.nan)
    elif names.NATURAL_FREQUENCY in ds:
        fn = np.atleast_1d(np.asarray(ds[names.NATURAL_FREQUENCY].values, dtype=float))
        wn = 2 * np.pi * fn
        lam = np.full(fn.size, np.nan + 0j)
        zeta = np.full(fn.size, np.nan)
    else:
        raise AmiXrValueError(
            f"modal_table: the Dataset has no {names.EIGENVALUE!r} or {names.NATURAL_FREQUENCY!r} "
            "(run ami_xr.identify first)"
        )
    if names.DAMPING_RATIO in ds:
        zeta = np.atleast_1d(np.asarray(ds[names.DAMPING_RATIO].values, dtype=float))
    modes = (
        list(ds[names.MODE].values.tolist())
        if names.MODE in ds.coords
        else list(range(1, fn.size + 1))
    )
    detected: list[str] = ["-"] * fn.size
    if names.DETECTED in ds and names.POINT in ds[names.DETECTED].dims:
        det = ds[names.DETECTED].transpose(names.POINT, names.MODE).values.astype(bool)
        pts = [str(p) for p in ds[names.POINT].values.tolist()]
        detected = [
            " ".join(p for p, d in zip(pts, det[:, k], strict=True) if d) or "none"
            for k in range(fn.size)
        ]
    flags = (
        [_text(f) for f in np.atleast_1d(ds[names.QUALITY_FLAGS].values)]
        if names.QUALITY_FLAGS in ds
        else [""] * fn.size
    )
    stds = _std_columns(ds, fn.size)
    return [
        {
            "mode": modes[k],
            "frequency_hz": float(fn[k]),
            "frequency_rad_s": float(wn[k]),
            "damping_percent": float(100 * zeta[k]),
            "eigenvalue": complex(lam[k]),
            **{key: float(values[k]) for key, values in stds.items()},
            "detected_in": detected[k],
            "flags": flags[k],
        }
        for k in range(fn.size)
    ]


#: Standard deviations the table shows when the Dataset has them: row key -> (variable, part,
#: header text). ``part`` picks the real or imaginary part of a complex std.
STD_COLUMNS: dict[str, tuple[str, str, str]] = {
    "frequency_hz_std": (names.NATURAL_FREQUENCY_STD, "real", "std f [Hz]"),
    "damping_percent_std": (names.DAMPING_RATIO_STD, "percent", "std zeta [%]"),
    "eigenvalue_real_std_rad_s": (names.EIGENVALUE_STD, "real", "std Re(lambda) [rad/s]"),
    "eigenvalue_imag_std_rad_s": (names.EIGENVALUE_STD, "imag", "std Im(lambda) [rad/s]"),
}


#: Modal quality indicators the table shows when the Dataset has them: row key -> (variable,
#: header text).
INDICATOR_COLUMNS: dict[str, tuple[str, str]] = {
    "mpc": (names.MPC, "MPC [-]"),
    "mpd_deg": (names.MPD, "MPD [deg]"),
    "complexity": (names.COMPLEXITY, "complexity [-]"),
    "stability_fraction": (names.STABILITY_FRACTION, "stability [-]"),
}


def _std_columns(ds: xr.Dataset, n_mode: int) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for key, (var, _) in INDICATOR_COLUMNS.items():
        if var in ds and ds[var].size == n_mode:
            out[key] = np.atleast_1d(np.asarray(ds[var].values, dtype=float))
    for key, (var, part, _) in STD_COLUMNS.items():
        if var not in ds:
            continue
        values = np.atleast_1d(np.asarray(ds[var].values))
        if values.size != n_mode:
            continue
        if part == "imag":
            out[key] = np.imag(values).astype(float)
        elif part == "percent":
            out[key] = 100 * np.real(values).astype(float)
        else:
            out[key] = np.real(values).astype(float)
    return out


def modal_table_csv_rows(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows of ``modal_table.csv``: one column per real quantity, numbers as plain floats.

    The complex eigenvalue becomes ``eigenvalue_real_rad_s`` and ``eigenvalue_imag_rad_s``
    (a spreadsheet cannot read Python's ``(-0.44+30.6j)``); the damping is given as a ratio as
    well as in percent; std columns follow their quantity; flags stay text.
    """
    out = []
    for r in rows:
        lam = r["eigenvalue"]
        row: dict[str, Any] = {
            "mode": r["mode"],
            "frequency_hz": r["frequency_hz"],
            "frequency_rad_s": r["frequency_rad_s"],
            "damping_ratio": r["damping_percent"] / 100,
            "damping_percent": r["damping_percent"],
            "eigenvalue_real_rad_s": lam.real,
            "eigenvalue_imag_rad_s": lam.imag,
        }
        row.update({key: r[key] for key in STD_COLUMNS if key in r})
        row.update({key: r[key] for key in INDICATOR_COLUMNS if key in r})
        row["detected_in"] = r["detected_in"]
        row["flags"] = r["flags"]
        out.append(row)
    return out


def _source_name(ds: xr.Dataset) -> str:
    """The source file's name without its folder (no machine path goes into a report)."""
    source = ds.attrs.get(names.ATTR_SOURCE_FILE)
    if source is None:
        return "dataset"
    return Path(str(source).replace("\\", "/")).name or "dataset"


def _short_points(detected: str, n_points: int, max_points: int) -> str:
    labels = detected.split() if detected not in ("-", "none") else []
    if not labels or len(labels) <= max_points:
        return detected
    return f"all {n_points}" if len(labels) == n_points else f"{len(labels)} of {n_points}"


def format_modal_table(
    ds: xr.Dataset,
    *,
    extra: dict[str, list[str]] | None = None,
    max_points: int = 6,
) -> str:
    """The modal table as aligned text, for terminals and logs.

    Parameters
    ----------
    ds : xarray.Dataset
        Identification result (see :func:`modal_table`).
    extra : dict of column name -> list of str, optional
        Additional columns (one string per mode), e.g. reference values to compare with.
    max_points : int
        The "detected in" column lists point labels up to this many, then says "all N" or
        "k of N" (:func:`modal_table` and the report always list them all).
    """
    rows = modal_table(ds)
    header = ["mode", "f [Hz]", "w [rad/s]", "zeta [%]"]
    body = [
        [
            str(r["mode"]),
            f"{r['frequency_hz']:.5f}",
            f"{r['frequency_rad_s']:.4f}",
            f"{r['damping_percent']:.3f}",
        ]
        for r in rows
    ]
    for name, values in (extra or {}).items():
        header.append(name)
        for row, v in zip(body, list(values) + [""] * len(body), strict=False):
            row.append(v)
    header += ["detected in", "flags"]
    n_points = ds.sizes.get(names.POINT, 0)
    for row, r in zip(body, rows, strict=True):
        row += [_short_points(r["detected_in"], n_points, max_points), r["flags"] or "-"]
    if not body:
        return "no modes identified"
    widths = [max(len(h), *(len(row[i]) for row in body)) for i, h in enumerate(header)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip()]
    lines.append("  ".join("-" * w for w in widths))
    lines += [
        "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip() for row in body
    ]
    return "\n".join(lines)


def _attrs_summary(ds: xr.Dataset) -> list[tuple[str, str]]:
    keys = (
        names.ATTR_SOURCE_FILE,
        names.ATTR_DRIVE_POINT,
        names.ATTR_QUANTITY,
        names.ATTR_FRF_TYPE,
        names.ATTR_SOURCE,
        names.ATTR_VERSION,
        names.ATTR_FUNCTION,
    )
    out = [
        (k, _source_name(ds) if k == names.ATTR_SOURCE_FILE else str(ds.attrs[k]))
        for k in keys
        if k in ds.attrs
    ]
    if names.POINT in ds.sizes:
        out.append(("points", str(ds.sizes[names.POINT])))
    if names.FREQUENCY in ds.coords and ds.sizes.get(names.FREQUENCY, 0):
        f = ds[names.FREQUENCY].values
        out.append(("frequency lines", f"{f.size} from {f[0]:.6g} to {f[-1]:.6g} Hz"))
    return out


def report(
    ds: xr.Dataset,
    outdir: str | os.PathLike,
    *,
    title: str | None = None,
    figures: tuple[str, ...] | None = None,
    frequency_range: tuple[float, float] | None = None,
) -> Path:
    """Write the identification report: index.html, one PNG per figure and the table as CSV.

    ``index.html`` is self-contained: its figures (and the CSV behind its download link) are
    embedded as base64 data URIs, so the page alone can be mailed or archived; the PNG and
    CSV files beside it are the same content for other tools.

    The page opens with what an engineer checks first when the FRFs were estimated by
    :func:`ami_xr.frf` or :func:`ami_xr.impact_frf`: the estimator and number of averages, the
    impact hits (rejected ones with their reason) and the coherence, force-spectrum and hits
    figures (:data:`MEASUREMENT_FIGURES`, drawn when their inputs are present). Then the modal
    table (with the std columns when the Dataset has them) and the figures of :data:`FIGURES`.
    Figures whose inputs are missing from ``ds`` (e.g. no subtraction outputs, no mode vectors)
    are skipped and listed in the page as "not produced" with the reason. Every file is written
    atomically; an existing report in ``outdir`` is overwritten file by file.

    Parameters
    ----------
    ds : xarray.Dataset
        Identification result of :func:`ami_xr.identify` (an FRF Dataset alone gives the Bode
        plot and notes for the rest).
    outdir : str or path-like
        Folder to write (created if missing).
    title : str, optional
        Page title; by default "ami_xr report: " and the source file's name (never its folder).
    figures : tuple of str, optional
        Keys of :data:`FIGURES`, :data:`MEASUREMENT_FIGURES`, :data:`STABILITY_FIGURES` and
        :data:`GEOMETRY_FIGURES` to draw (default: all of FIGURES, the measurement figures
        whose inputs are present, ``stability`` after :func:`ami_xr.stability`, and
        ``mode_shapes`` with one animated GIF per mode when the points have coordinates).
    frequency_range : (float, float), optional
        Band in Hz for the figures with a frequency axis (Bode, subtraction, coherence, force
        spectrum); default the whole band.

    Returns
    -------
    pathlib.Path
        Path of ``index.html``.
    """
    from ami_xr import plot, plot_geometry, plot_measurement
    from ami_xr.io.geometry import has_coordinates
    from ami_xr.plot_common import gc_paused, png_bytes

    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise DataFileError(f"report: output {str(outdir)!r} exists and is not a folder")
    if names.REFERENCE in ds.dims:
        # the figures draw one FRF per point; multi-reference pages are not built yet (issue 13)
        refs = ds[names.REFERENCE].values.tolist()
        raise AmiXrValueError(
            f"ds: report draws one reference at a time, and this result has the "
            f"{names.REFERENCE!r} dim ({refs}); select one first, e.g. "
            f"ds.sel({names.REFERENCE}={refs[0]!r}) (the modal table of all references prints "
            "with ami_xr.format_modal_table)"
        )
    known = {**MEASUREMENT_FIGURES, **FIGURES, **STABILITY_FIGURES, **GEOMETRY_FIGURES}
    if figures is None:
        wanted = tuple(k for k, v in MEASUREMENT_FIGURES.items() if v[2] in ds) + tuple(FIGURES)
        wanted += tuple(k for k, v in STABILITY_FIGURES.items() if v[2] in ds)
        wanted += tuple(GEOMETRY_FIGURES) if has_coordinates(ds) else ()
    else:
        wanted = tuple(figures)
    unknown = [f for f in wanted if f not in known]
    if unknown:
        raise AmiXrValueError(f"report: unknown figures {unknown}; choose from {list(known)}")
    frequency_range = _check_range(frequency_range, ds)
    outdir.mkdir(parents=True, exist_ok=True)
    made: list[tuple[str, str, bytes]] = []
    skipped: list[tuple[str, str]] = []
    for stem in sorted(wanted, key=list(known).index):
        func_name, caption = known[stem][:2]
        module = plot_measurement if stem in MEASUREMENT_FIGURES else plot
        module = plot_geometry if stem in GEOMETRY_FIGURES else module
        if stem in STABILITY_FIGURES:  # ami_xr.plot_stability is the function: import the module
            module = importlib.import_module(f"ami_xr.{func_name}")
        kwargs = {"frequency_range": frequency_range} if stem in _BANDED and frequency_range else {}
        try:
            with gc_paused():  # a third of the drawing time otherwise (plot_common.gc_paused)
                fig = getattr(module, func_name)(ds, **kwargs)
        except AmiXrValueError as err:
            skipped.append((stem, str(err)))
            continue
        png = png_bytes(fig)  # at the size the page shows it (plot_common.PAGE_WIDTH_PX)
        with atomic_open(outdir / f"{stem}.png", "wb") as fh:
            fh.write(png)
        made.append((stem, caption, png))
        if stem in GEOMETRY_FIGURES:
            made += _mode_animations(ds, outdir, skipped)
    try:
        rows = modal_table(ds)
    except AmiXrValueError as err:
        rows = []
        skipped.append(("modal table", str(err)))
    if rows:
        with atomic_open(outdir / "modal_table.csv", "w") as fh:
            fh.write(_csv_text(rows))
    summary = plot_measurement.measurement_summary(ds)
    page = _html(ds, rows, summary, made, skipped, title or f"ami_xr report: {_source_name(ds)}")
    index = outdir / "index.html"
    with atomic_open(index, "wb") as fh:
        fh.write(page.encode("utf-8"))
    return index


#: Figures with a frequency axis: they take ``frequency_range``.
_BANDED = frozenset({"bode", "subtraction", "coherence", "force_spectrum"})


def _check_range(frequency_range, ds: xr.Dataset) -> tuple[float, float] | None:
    if frequency_range is None:
        return None
    try:
        f0, f1 = (float(f) for f in frequency_range)
    except (TypeError, ValueError):
        raise AmiXrValueError(
            f"report: frequency_range must be two numbers (f0, f1) in Hz, got {frequency_range!r}"
        ) from None
    if not (np.isfinite(f0) and np.isfinite(f1) and f0 < f1):
        raise AmiXrValueError(
            f"report: frequency_range must satisfy f0 < f1 (finite, Hz), got {(f0, f1)!r}"
        )
    if names.FREQUENCY in ds.coords:  # a band outside the data: say so, draw nothing
        f = np.asarray(ds[names.FREQUENCY].values, dtype=float)
        if np.count_nonzero((f >= f0) & (f <= f1)) < 2:
            raise AmiXrValueError(
                f"report: frequency_range {(f0, f1)!r} Hz holds fewer than 2 frequency lines "
                f"(the data span {f.min():.6g} to {f.max():.6g} Hz)"
            )
    return f0, f1


# the page is as wide as the widest figure is drawn (plot_common.PAGE_WIDTH_PX): images at 1:1
_CSS = (
    f"body{{font-family:sans-serif;margin:2em;max-width:{PAGE_WIDTH_PX}px}}"
    "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;"
    "text-align:right}th{background:#eee}td.l{text-align:left}"
    "img{max-width:100%;border:1px solid #ddd}.flag{color:#b00}"
)


def _measurement_html(summary: dict[str, Any]) -> str:
    e = html.escape
    if not summary:
        return ""
    buf = io.StringIO()
    buf.write("<h2>Measurement</h2>\n<p>")
    if names.ATTR_ESTIMATOR in summary:
        buf.write(f"FRF estimator: <b>{e(str(summary[names.ATTR_ESTIMATOR]))}</b>. ")
    if names.ATTR_N_AVERAGES in summary:
        buf.write(f"Number of averages: <b>{e(str(summary[names.ATTR_N_AVERAGES]))}</b>. ")
    hits = summary.get("hits", [])
    if hits:
        n_bad = sum(h["rejected"] for h in hits)
        buf.write(f"Impact hits: {len(hits)}, of which {n_bad} rejected.")
    buf.write("</p>\n")
    if hits:
        units = e(str(summary.get("force_units") or ""))
        buf.write(
            f"<table><tr><th>hit</th><th>peak force [{units}]</th><th>averaged</th>"
            "<th>reason rejected</th></tr>\n"
        )
        for h in hits:
            used = "no" if h["rejected"] else "yes"
            cls = " class='l flag'" if h["rejected"] else " class='l'"
            buf.write(
                f"<tr><td>{e(str(h['record']))}</td><td>{h['peak_force']:.6g}</td>"
                f"<td{cls}>{used}</td><td{cls}>{e(h['reason'])}</td></tr>\n"
            )
        buf.write("</table>\n")
    return buf.getvalue()


def _table_html(rows: list[dict[str, Any]]) -> str:
    e = html.escape
    if not rows:
        return "<p>No modes identified.</p>\n"
    stds = [k for k in STD_COLUMNS if k in rows[0]]
    quality = [k for k in INDICATOR_COLUMNS if k in rows[0]]
    buf = io.StringIO()
    buf.write(
        "<table><tr><th>mode</th><th>f [Hz]</th><th>&omega; [rad/s]</th>"
        "<th>&zeta; [%]</th><th>eigenvalue [rad/s]</th>"
    )
    buf.write("".join(f"<th>{e(STD_COLUMNS[k][2])}</th>" for k in stds))
    buf.write("".join(f"<th>{e(INDICATOR_COLUMNS[k][1])}</th>" for k in quality))
    buf.write("<th>detected in</th><th>flags</th></tr>\n")
    for r in rows:
        lam = r["eigenvalue"]
        lam_text = "" if not np.isfinite(lam) else f"{lam.real:.6g}{lam.imag:+.6g}i"
        buf.write(
            f"<tr><td>{e(str(r['mode']))}</td><td>{r['frequency_hz']:.6g}</td>"
            f"<td>{r['frequency_rad_s']:.6g}</td><td>{r['damping_percent']:.4g}</td>"
            f"<td>{e(lam_text)}</td>"
        )
        buf.write("".join(f"<td>{r[k]:.3g}</td>" for k in stds + quality))
        buf.write(
            f"<td class='l'>{e(r['detected_in'])}</td>"
            f"<td class='l flag'>{e(r['flags'])}</td></tr>\n"
        )
    buf.write("</table>\n")
    if stds:
        buf.write(
            "<p>Standard deviations (columns "
            + ", ".join(e(STD_COLUMNS[k][2]) for k in stds)
            + ") from the Cram&eacute;r-Rao bound of the fit.</p>\n"
        )
    buf.write(
        f"<p><a href='{_csv_data_uri(rows)}' download='modal_table.csv'>modal_table.csv</a> "
        "(one number per column; also written next to this page)</p>\n"
    )
    return buf.getvalue()


def _csv_text(rows: list[dict[str, Any]]) -> str:
    csv_rows = modal_table_csv_rows(rows)
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=list(csv_rows[0]))
    writer.writeheader()
    writer.writerows(csv_rows)
    return out.getvalue()


def _csv_data_uri(rows: list[dict[str, Any]]) -> str:
    return "data:text/csv;base64," + base64.b64encode(_csv_text(rows).encode()).decode("ascii")


def _html(ds, rows, summary, made, skipped, title) -> str:
    e = html.escape
    buf = io.StringIO()
    buf.write(
        "<!DOCTYPE html>\n<html><head><meta charset='utf-8'>"
        f"<title>{e(title)}</title><style>{_CSS}</style></head><body>\n"
    )
    buf.write(f"<h1>{e(title)}</h1>\n<table>\n")
    for k, v in _attrs_summary(ds):
        buf.write(f"<tr><th>{e(k)}</th><td class='l'>{e(v)}</td></tr>\n")
    buf.write("</table>\n")
    buf.write(_measurement_html(summary))
    for stem, caption, png in made:
        if stem in MEASUREMENT_FIGURES:
            buf.write(_figure_html(stem, caption, png))
    buf.write("<h2>Modal table</h2>\n")
    buf.write(_table_html(rows))
    for stem, caption, png in made:
        if stem not in MEASUREMENT_FIGURES:
            buf.write(_figure_html(stem, caption, png))
    if skipped:
        buf.write("<h2>Not produced</h2>\n<ul>\n")
        for stem, why in skipped:
            buf.write(f"<li><b>{e(stem)}</b>: {e(why)}</li>\n")
        buf.write("</ul>\n")
    buf.write("</body></html>\n")
    return buf.getvalue()


def _figure_html(stem: str, caption: str, png: bytes) -> str:
    e = html.escape
    kind = "gif" if png[:6] == b"GIF89a" else "png"  # mode shape animations are GIFs
    return (
        f"<h2>{e(stem.replace('_', ' '))}</h2>\n<p>{e(caption)}</p>\n"
        f"<img src='data:image/{kind};base64,{base64.b64encode(png).decode('ascii')}' "
        f"alt='{e(stem)}.{kind}'>\n"
    )


def _mode_animations(
    ds: xr.Dataset, outdir: Path, skipped: list[tuple[str, str]]
) -> list[tuple[str, str, bytes]]:
    """One animated GIF per mode (mode_shape_<mode>.gif, written atomically) for the page."""
    from ami_xr.plot_geometry import animate_mode_shape

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
