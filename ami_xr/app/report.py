"""The identification report (one self-contained index.html, PNGs and CSV).

``report`` draws the figures of :mod:`ami_xr.plot` and needs the ``plot`` extra; the modal table
it shows comes from :mod:`ami_xr.tables` (re-exported here), which needs no matplotlib.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import os
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.app.report_figures import (
    FIGURES,
    GEOMETRY_FIGURES,
    MEASUREMENT_FIGURES,
    STABILITY_FIGURES,
    draw_figures,
    draw_png,
    wanted_figures,
)
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.atomic import atomic_open
from ami_xr.plot.common import PAGE_WIDTH_PX
from ami_xr.tables import (
    INDICATOR_COLUMNS,
    STD_COLUMNS,
    cap_notes,
    flag_legend,
    format_modal_table,
    modal_table,
    modal_table_csv_rows,
)

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


def _source_name(ds: xr.Dataset) -> str:
    """The source file's name without its folder (no machine path goes into a report)."""
    source = ds.attrs.get(names.ATTR_SOURCE_FILE)
    if source is None:
        return "dataset"
    return Path(str(source).replace("\\", "/")).name or "dataset"


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
    reference: Any = None,
) -> Path:
    """Write the identification report: index.html, one PNG per figure and the table as CSV.

    ``index.html`` is self-contained: its figures (and the CSV behind its download link) are
    embedded as base64 data URIs, so the page alone can be mailed or archived; the PNG and
    CSV files beside it are the same content for other tools.

    The page opens with what an engineer checks first when the FRFs were estimated by
    :func:`ami_xr.frf` or :func:`ami_xr.impact_frf`: the estimator and number of averages, the
    impact hits (rejected ones with their reason) and the coherence, force-spectrum and hits
    figures (:data:`MEASUREMENT_FIGURES`, drawn when their inputs are present). Then the modal
    table (with the std columns when the Dataset has them), a legend of the quality flags that
    appear in it (:func:`ami_xr.tables.flag_legend`: one plain-language line each), the limits
    that ended a phase (:func:`ami_xr.tables.cap_notes`: ``ami_capped``, and
    ``ami_capped_superseded`` when the refinement made a cap moot) and the figures
    of :data:`FIGURES`.
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
    reference : label, optional
        Multi-reference results only: report this reference's FRFs (the mode vectors and the
        "References" section use every reference). Default: every reference, the FRF figures
        drawn once per reference (:mod:`ami_xr.app.report_mimo`); both add the participation
        per reference, the drive-point consistency and the MAC within close pairs.

    Returns
    -------
    pathlib.Path
        Path of ``index.html``.
    """
    from ami_xr.plot import measurement as plot_measurement

    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise DataFileError(f"report: output {str(outdir)!r} exists and is not a folder")
    multi = None  # multi-reference: the figures below draw a view (ami_xr.app.report_mimo)
    if names.REFERENCE in ds.dims:
        from ami_xr.app.report_mimo import MultiReferencePage

        multi = MultiReferencePage(ds, reference)
        ds = multi.view
    elif reference is not None:
        raise AmiXrValueError(
            f"reference: {reference!r} given, but ds has no {names.REFERENCE!r} dim "
            "(a single-reference result)"
        )
    wanted = wanted_figures(ds, figures)
    frequency_range = _check_range(frequency_range, ds)
    per_reference: tuple[str, ...] = ()
    if multi is not None:
        wanted, per_reference = multi.split(wanted, figures is None)
    outdir.mkdir(parents=True, exist_ok=True)
    made, skipped = draw_figures(ds, outdir, wanted, frequency_range)
    if multi is not None:
        extra_made, extra_skipped = multi.figures(outdir, per_reference, frequency_range, draw_png)
        made, skipped = made + extra_made, skipped + extra_skipped
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
    if multi is not None:  # the References section, just before the modal table
        page = page.replace("<h2>Modal table</h2>", multi.html() + "<h2>Modal table</h2>", 1)
    index = outdir / "index.html"
    with atomic_open(index, "wb") as fh:
        fh.write(page.encode("utf-8"))
    return index


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


# the page is as wide as the widest figure is drawn (plot.common.PAGE_WIDTH_PX): images at 1:1
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


def _legend_html(rows: list[dict[str, Any]]) -> str:
    """The flags present in the table, each with its one-line meaning and the modes carrying it."""
    if not rows:
        return ""
    e = html.escape
    legend = flag_legend(rows)
    if not legend:
        return "<p>No mode carries a quality flag.</p>\n"
    buf = io.StringIO()
    buf.write("<h3>Flags</h3>\n<table><tr><th>flag</th><th>modes</th><th>what it means</th></tr>\n")
    for flag, text, modes in legend:
        buf.write(
            f"<tr><td class='l flag'>{e(flag)}</td>"
            f"<td class='l'>{e(', '.join(str(m) for m in modes))}</td>"
            f"<td class='l'>{e(text)}</td></tr>\n"
        )
    buf.write("</table>\n")
    return buf.getvalue()


def _caps_html(ds: xr.Dataset) -> str:
    """The limits that ended a phase, in words (nothing when none was reached)."""
    notes = cap_notes(ds)
    if not notes:
        return ""
    e = html.escape
    items = "".join(
        f"<li{' class=flag' if kind == 'incomplete' else ''}>{e(text)}</li>\n"
        for kind, text in notes
    )
    return f"<h3>Limits reached</h3>\n<ul>\n{items}</ul>\n"


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
    buf.write(_legend_html(rows))
    buf.write(_caps_html(ds))
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
