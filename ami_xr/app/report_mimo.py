"""The multi-reference parts of the report (issue 22): :func:`ami_xr.app.report.report` on a
result with the ``reference`` dim builds a :class:`MultiReferencePage` and asks it for

- the Dataset the single-reference figures draw (:attr:`MultiReferencePage.view`): one
  reference's FRFs (``reference=R``), or, for all references, what the references share
  (eigenvalues, mode vectors, MAC, flags, ``detected`` in any reference);
- the figures drawn once per reference (Bode, Nyquist, subtraction and the measurement
  figures, stems ``<figure>_reference_<R>``) when all references are reported;
- the multi-reference figures (:mod:`ami_xr.plot.mimo`: participation per reference,
  ``s2/s1`` and drive-point consistency) and the section of the page that tabulates them
  with the MAC within each close or repeated pair (:func:`ami_xr.tables.repeated_pairs`);
  ``participation.csv`` beside the page.
"""

from __future__ import annotations

import csv
import html
import inspect
import io
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.app.report_figures import FIGURES, MEASUREMENT_FIGURES
from ami_xr.errors import AmiXrValueError
from ami_xr.io.atomic import atomic_open
from ami_xr.io.datasets import select_reference
from ami_xr.tables import participation_table, repeated_pairs

#: Multi-reference figures (ami_xr.plot.mimo): stem -> (function, caption).
MIMO_FIGURES: dict[str, tuple[str, str]] = {
    "participation": (
        "plot_participation",
        "Participation of each reference in each mode, |L_r| / max |L_r|: a reference near 0 "
        "sits near the mode's nodal line and sees it weakly.",
    ),
    "reference_checks": (
        "plot_reference_checks",
        "Per mode: s2/s1 of the residue matrix (point x reference; dashed: the repeated-root "
        "threshold) and the drive-point consistency (relative spread of the mode vector's "
        "scale from the drive points: reciprocity). Red: repeated root suspected or separated.",
    ),
}

#: Figures that draw the FRFs of one reference (report stems): drawn once per reference when
#: every reference is reported.
PER_REFERENCE = ("bode", "nyquist", "subtraction", "coherence", "force_spectrum", "hits")


def _label(refs: list, reference: Any) -> Any:
    """The reference label matching ``reference`` (a CLI gives text: compared as text too)."""
    for r in refs:
        if r == reference or str(r) == str(reference):
            return r
    raise AmiXrValueError(f"reference: {reference!r} is not one of the references {refs}")


def shared_view(ds: xr.Dataset) -> xr.Dataset:
    """What every reference of a multi-reference result shares: every variable without the
    ``reference`` dim (eigenvalues, mode vectors, MAC, flags, ``detected`` (point, mode) in
    any reference)."""
    keep = [v for v in ds.data_vars if names.REFERENCE not in ds[v].dims]
    out = ds[keep].drop_vars(names.REFERENCE, errors="ignore")
    out.attrs = dict(ds.attrs)
    return out


@dataclass
class MultiReferencePage:
    """The multi-reference parts of one report; see the module docstring."""

    ds: xr.Dataset
    reference: Any = None
    refs: list = field(init=False)
    view: xr.Dataset = field(init=False)

    def __post_init__(self) -> None:
        self.refs = list(self.ds[names.REFERENCE].values.tolist())
        if self.reference is None:
            self.view = shared_view(self.ds)
        else:
            self.reference = _label(self.refs, self.reference)
            self.view = select_reference(self.ds, self.reference)

    def split(self, wanted: tuple[str, ...], default: bool) -> tuple[tuple, tuple]:
        """``wanted`` as (stems the view draws, stems drawn per reference). All references:
        the FRF figures move to the per-reference list (by default those whose inputs the
        result has); one reference: the view draws them all."""
        if self.reference is not None:
            return wanted, ()
        per = tuple(s for s in wanted if s in PER_REFERENCE)
        if default:
            per += tuple(k for k, v in MEASUREMENT_FIGURES.items() if v[2] in self.ds)
        return tuple(s for s in wanted if s not in PER_REFERENCE), per

    def figures(
        self, outdir: Path, per_reference: tuple[str, ...], frequency_range, draw
    ) -> tuple[list[tuple[str, str, bytes]], list[tuple[str, str]]]:
        """Draw the multi-reference figures and the per-reference ones, written atomically as
        ``<stem>.png``; ``draw(function, ds, kwargs) -> png bytes`` (the report's). Returns
        the figures made (stem, caption, png) and those skipped (stem, reason)."""
        from ami_xr.plot import measurement, modal
        from ami_xr.plot import mimo as plot_mimo

        jobs = [
            (stem, getattr(plot_mimo, f), cap, self.ds) for stem, (f, cap) in MIMO_FIGURES.items()
        ]
        for r in self.refs:
            view = select_reference(self.ds, r)
            tag = re.sub(r"[^A-Za-z0-9_.-]", "_", str(r))
            for stem in per_reference:
                module, spec = (
                    (measurement, MEASUREMENT_FIGURES[stem])
                    if stem in MEASUREMENT_FIGURES
                    else (modal, FIGURES[stem])
                )
                caption = f"Reference {r}: {spec[1]}"
                jobs.append((f"{stem}_reference_{tag}", getattr(module, spec[0]), caption, view))
        made, skipped = [], []
        for stem, func, caption, data in jobs:
            kwargs = {}
            if frequency_range and "frequency_range" in inspect.signature(func).parameters:
                kwargs["frequency_range"] = frequency_range
            try:
                png = draw(func, data, kwargs)
            except AmiXrValueError as err:
                skipped.append((stem, str(err)))
                continue
            with atomic_open(outdir / f"{stem}.png", "wb") as fh:
                fh.write(png)
            made.append((stem, caption, png))
        rows = participation_table(self.ds)
        if rows:
            with atomic_open(outdir / "participation.csv", "w") as fh:
                fh.write(_participation_csv(rows, self.refs))
        return made, skipped

    def html(self) -> str:
        """The page's "References" section: which references, the participation table and the
        MAC within close or repeated pairs."""
        e = html.escape
        points = set(map(str, self.ds[names.POINT].values.tolist()))
        drives = [r for r in self.refs if str(r) in points]
        buf = io.StringIO()
        buf.write("<h2>References</h2>\n<p>")
        buf.write(
            f"{len(self.refs)} references ({e(', '.join(map(str, self.refs)))}) share the poles; "
            f"drive points (a reference on a measured point): "
            f"{e(', '.join(map(str, drives))) or 'none (mode vectors unscaled)'}. "
        )
        if self.reference is None:
            buf.write("The FRF figures are drawn once per reference. ")
        else:
            buf.write(
                f"This report draws the FRFs of reference <b>{e(str(self.reference))}</b>; the "
                "mode vectors and the table below use every reference. "
            )
        added = str(self.ds.attrs.get("multi_reference_union_added", "")).strip()
        if added:
            buf.write(
                f"Poles found by a single reference alone and added to the shared set: "
                f"{e(added)} Hz."
            )
        buf.write("</p>\n")
        rows = participation_table(self.ds)
        if rows:
            buf.write(
                "<table><tr><th>mode</th><th>f [Hz]</th>"
                + "".join(f"<th>|L| ref {e(str(r))}</th>" for r in self.refs)
                + "<th>s2/s1</th><th>drive-point spread</th><th>drive-point SNR</th>"
                "<th>scaled at</th><th>flags</th></tr>\n"
            )
            for row in rows:
                cells = "".join(
                    f"<td>{_num(row['relative'][r], '.2f')} "
                    f"({_num(row['phase_deg'][r], '.0f')}&deg;)</td>"
                    for r in self.refs
                )
                buf.write(
                    f"<tr><td>{e(str(row['mode']))}</td><td>{row['frequency_hz']:.6g}</td>"
                    f"{cells}<td>{_num(row['rank_one_ratio'], '.3g')}</td>"
                    f"<td>{_num(row['drive_point_consistency'], '.3g')}</td>"
                    f"<td>{_num(row['drive_point_snr'], '.3g')}</td>"
                    f"<td class='l'>{e(row['scaling_reference'])}</td>"
                    f"<td class='l flag'>{e(row['flags'])}</td></tr>\n"
                )
            buf.write(
                "</table>\n<p>|L| ref r: participation of reference r relative to the "
                "strongest reference of the mode (its phase in brackets); s2/s1 of the residue "
                "matrix (point x reference; above "
                f"{e(str(self.ds.attrs.get(names.ATTR_RANK_ONE_RATIO_MAX, '?')))} and the "
                "noise: a repeated root); drive-point spread: largest relative deviation of "
                "the mode vector's scale between drive points (reciprocity; n/a with fewer "
                "than two). Also in participation.csv.</p>\n"
            )
        pairs = repeated_pairs(self.ds)
        buf.write("<h3>MAC within close or repeated pairs</h3>\n")
        if not pairs:
            buf.write("<p>No two modes within each other's half-power band.</p>\n")
        else:
            buf.write(
                "<table><tr><th>modes</th><th>f [Hz]</th><th>split [%]</th><th>MAC</th>"
                "<th>flags</th></tr>\n"
            )
            for p in pairs:
                m1, m2 = p["modes"]
                f1, f2 = p["frequency_hz"]
                buf.write(
                    f"<tr><td>{e(str(m1))}, {e(str(m2))}</td><td>{f1:.6g}, {f2:.6g}</td>"
                    f"<td>{p['split_percent']:.3g}</td><td>{_num(p['mac'], '.3f')}</td>"
                    f"<td class='l flag'>{e(' / '.join(x or '-' for x in p['flags']))}</td>"
                    "</tr>\n"
                )
            buf.write(
                "</table>\n<p>A MAC near 0: the references separated two shapes; near 1: one "
                "shape seen twice (suspect).</p>\n"
            )
        return buf.getvalue()


def _num(value: float, fmt: str) -> str:
    return "n/a" if not np.isfinite(value) else format(value, fmt)


def _participation_csv(rows: list[dict[str, Any]], refs: list) -> str:
    out = io.StringIO()
    fields = ["mode", "frequency_hz"]
    fields += [f"relative_{r}" for r in refs] + [f"phase_deg_{r}" for r in refs]
    fields += [
        "rank_one_ratio",
        "drive_point_consistency",
        "drive_point_snr",
        "scaling_reference",
        "flags",
    ]
    writer = csv.DictWriter(out, fieldnames=fields)
    writer.writeheader()
    for row in rows:
        flat = {k: row[k] for k in fields if k in row}
        flat.update({f"relative_{r}": row["relative"][r] for r in refs})
        flat.update({f"phase_deg_{r}": row["phase_deg"][r] for r in refs})
        writer.writerow(flat)
    return out.getvalue()
