"""The modal table of an identification result: rows, aligned text and CSV rows.

Needs no matplotlib: the CLI prints the table, :mod:`ami_xr.app.report` writes it into the
report and :func:`ami_xr.plot.modal.plot_modal_table` draws it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.core import flags as qf
from ami_xr.errors import AmiXrValueError

__all__ = [
    "modal_table",
    "modal_table_csv_rows",
    "format_modal_table",
    "flag_legend",
    "cap_notes",
    "participation_table",
    "repeated_pairs",
    "STD_COLUMNS",
    "INDICATOR_COLUMNS",
    "CAP_DESCRIPTIONS",
    "FOUND_BY_REFINEMENT",
]

#: The "detected in" text of a mode no FRF detected that the refinement added (flag
#: ``added_by_refine``), instead of "none".
FOUND_BY_REFINEMENT = "found by the refinement"

#: What each cap of the attributes ``ami_capped`` / ``ami_capped_superseded`` means, in words
#: (the table of :data:`ami_xr.core.flags.CAPS`, by name).
CAP_DESCRIPTIONS: dict[str, str] = {cap.name: cap.description for cap in qf.CAPS}


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
        ``eigenvalue`` (complex rad/s or nan), ``detected_in`` (point labels joined by spaces;
        :data:`FOUND_BY_REFINEMENT` for a mode no FRF detected that the refinement added, "none"
        for another mode no FRF detected, "-" when unknown) and ``flags`` ("" when none).
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
    flags = (
        [str(f) for f in qf.flag_text(np.atleast_1d(ds[names.QUALITY_FLAGS].values))]
        if names.QUALITY_FLAGS in ds
        else [""] * fn.size
    )
    detected: list[str] = ["-"] * fn.size
    if names.DETECTED in ds and names.POINT in ds[names.DETECTED].dims:
        det = ds[names.DETECTED].transpose(names.POINT, names.MODE).values.astype(bool)
        pts = [str(p) for p in ds[names.POINT].values.tolist()]
        detected = [
            " ".join(p for p, d in zip(pts, det[:, k], strict=True) if d)
            or (FOUND_BY_REFINEMENT if names.FLAG_ADDED_BY_REFINE in _split(flags[k]) else "none")
            for k in range(fn.size)
        ]
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


def _split(text: str) -> list[str]:
    """The flags of one ``quality_flags`` text."""
    return [f for f in (f.strip() for f in text.split(names.FLAG_SEPARATOR)) if f]


def flag_legend(rows: list[dict[str, Any]]) -> list[tuple[str, str, list]]:
    """The quality flags that appear in the modal table, each with what it means.

    Parameters
    ----------
    rows : list of dict
        Rows of :func:`modal_table` (their ``flags`` and ``mode``).

    Returns
    -------
    list of (flag, description, modes)
        One entry per flag present, in bit order (:data:`ami_xr.names.FLAG_MEANINGS`), with the
        one-line description of :data:`ami_xr.core.flags.DESCRIPTIONS` and the labels of the
        modes that carry it; a flag this version does not know (a file from another version)
        comes last, described as such.
    """
    carriers: dict[str, list] = {}
    for r in rows:
        for flag in _split(r["flags"]):
            carriers.setdefault(flag, []).append(r["mode"])
    known = [f for f in names.FLAG_MEANINGS if f in carriers]
    unknown = [f for f in carriers if f not in names.FLAG_MEANINGS]
    out = [(f, qf.describe(f), carriers[f]) for f in known]
    out += [(f, "not a flag this version of ami_xr knows", carriers[f]) for f in unknown]
    return out


def cap_notes(ds: xr.Dataset) -> list[tuple[str, str]]:
    """Sentences on the limits that ended a phase of the identification, for a reader.

    Returns
    -------
    list of (kind, sentence)
        ``("incomplete", ...)`` from the attribute ``ami_capped`` (modes may be missing) and
        ``("superseded", ...)`` from ``ami_capped_superseded`` (the subtraction stopped at a
        limit, but the refinement then completed the model by its statistics, so that limit
        did not decide the mode count; or the isolation stopped at ``max_iter`` but the
        converged refinement re-fitted every mode); empty when neither is set.
    """

    def entries(attr: str) -> list[str]:
        return qf.run_status(ds.attrs, attr).entries

    def words(caps: list[str]) -> str:
        return "; ".join(f"{CAP_DESCRIPTIONS.get(e, e)} [{e}]" for e in caps)

    notes = []
    capped = entries(names.ATTR_AMI_CAPPED)
    if capped:
        text = (
            f"Incomplete: {words(capped)}. Modes may be missing: raise the limit (e.g. "
            "max_modes) or narrow the band (fmin/fmax)."
        )
        notes.append(("incomplete", text))
    superseded = entries(names.ATTR_AMI_CAPPED_SUPERSEDED)
    if "isolate:max_iter" in superseded:
        superseded.remove("isolate:max_iter")
        text = (
            f"Limit superseded: {words(['isolate:max_iter'])}, but the refinement then re-fitted "
            "every mode and converged, so the isolation's estimates are not the result "
            f"({names.ATTR_AMI_CAPPED_SUPERSEDED})."
        )
        notes.append(("superseded", text))
    if superseded:
        text = (
            f"Limit superseded: {words(superseded)}, but the refinement then completed the "
            "model until its statistics showed no further mode, so that limit did not decide "
            f"the number of modes ({names.ATTR_AMI_CAPPED_SUPERSEDED})."
        )
        notes.append(("superseded", text))
    return notes


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
    # multi-reference results (ami_xr.ami.mimo): how far from rank one the residue matrix is,
    # and how far the drive points disagree on the mode vector's scale (reciprocity)
    "rank_one_ratio": (names.RANK_ONE_RATIO, "s2/s1 [-]"),
    "drive_point_consistency": (names.DRIVE_POINT_CONSISTENCY, "drive-point spread [-]"),
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


def _short_points(detected: str, n_points: int, max_points: int) -> str:
    labels = detected.split() if detected not in ("-", "none", FOUND_BY_REFINEMENT) else []
    if not labels or len(labels) <= max_points:
        return detected
    return f"all {n_points}" if len(labels) == n_points else f"{len(labels)} of {n_points}"


def format_modal_table(
    ds: xr.Dataset,
    *,
    extra: dict[str, list[str]] | None = None,
    max_points: int = 6,
    legend: bool = False,
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
    legend : bool
        Follow the table with one line per flag present saying what it means
        (:func:`flag_legend`) and the notes of :func:`cap_notes`.
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
        notes = [text for _, text in cap_notes(ds)] if legend else []
        return "\n".join(["no modes identified", *notes])
    widths = [max(len(h), *(len(row[i]) for row in body)) for i, h in enumerate(header)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip()]
    lines.append("  ".join("-" * w for w in widths))
    lines += [
        "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip() for row in body
    ]
    if legend:
        lines += [f"{flag}: {text}" for flag, text, _ in flag_legend(rows)]
        lines += [text for _, text in cap_notes(ds)]
    return "\n".join(lines)


def _references(ds: xr.Dataset) -> list:
    if names.PARTICIPATION not in ds or names.REFERENCE not in ds[names.PARTICIPATION].dims:
        raise AmiXrValueError(
            f"participation_table: the Dataset has no {names.PARTICIPATION!r} (mode, reference) "
            "(a multi-reference result of ami_xr.identify is needed)"
        )
    return list(ds[names.REFERENCE].values.tolist())


def participation_table(ds: xr.Dataset) -> list[dict[str, Any]]:
    """One row per mode of a multi-reference result: what each reference sees of it.

    Parameters
    ----------
    ds : xarray.Dataset
        Multi-reference result of :func:`ami_xr.identify` (``participation`` (mode,
        reference); ``rank_one_ratio``, ``drive_point_consistency``, ``scaling_reference`` and
        ``drive_point_snr`` are used when present).

    Returns
    -------
    list of dict
        Keys ``mode``, ``frequency_hz``, ``relative`` (dict reference -> ``|L_r| / max_r |L_r|``:
        1 for the reference that excites the mode best, near 0 for one on its nodal line),
        ``phase_deg`` (dict reference -> phase of ``L_r`` relative to the strongest reference,
        degrees), ``rank_one_ratio``, ``drive_point_consistency``, ``drive_point_snr`` (NaN
        when absent), ``scaling_reference`` and ``flags`` ("" when absent).
    """
    refs = _references(ds)
    part = ds[names.PARTICIPATION].transpose(names.MODE, names.REFERENCE).values
    part = np.asarray(part, dtype=np.complex128)
    rows = modal_table(ds)

    def per_mode(var: str) -> np.ndarray:
        if var in ds and ds[var].dims == (names.MODE,):
            return np.asarray(ds[var].values)
        return np.full(part.shape[0], np.nan)

    scaling = per_mode(names.SCALING_REFERENCE)
    out = []
    for k, row in enumerate(rows):
        mag = np.abs(part[k])
        best = int(np.nanargmax(mag)) if np.any(np.isfinite(mag)) else 0
        top = mag[best]
        with np.errstate(invalid="ignore", divide="ignore"):
            rel = mag / top if top > 0 else np.full(mag.size, np.nan)
            phase = np.degrees(np.angle(part[k] / part[k, best])) if top > 0 else rel
        out.append(
            {
                "mode": row["mode"],
                "frequency_hz": row["frequency_hz"],
                "relative": {r: float(v) for r, v in zip(refs, rel, strict=True)},
                "phase_deg": {r: float(v) for r, v in zip(refs, phase, strict=True)},
                "rank_one_ratio": float(per_mode(names.RANK_ONE_RATIO)[k]),
                "drive_point_consistency": float(per_mode(names.DRIVE_POINT_CONSISTENCY)[k]),
                "drive_point_snr": float(per_mode(names.DRIVE_POINT_SNR)[k]),
                "scaling_reference": _text(scaling[k]),
                "flags": row["flags"],
            }
        )
    return out


def repeated_pairs(ds: xr.Dataset) -> list[dict[str, Any]]:
    """Pairs of modes that may be one repeated root: adjacent in frequency and within each
    other's half-power band (``|Im lam_1 - Im lam_2| <= |Re lam_1| + |Re lam_2|``; the two
    modes of a separated repeated root share one eigenvalue), with the MAC of
    their mode vectors (near 0: the references separated two shapes; near 1: one shape seen
    twice, suspect).

    Returns
    -------
    list of dict
        Keys ``modes`` (the two labels), ``frequency_hz`` (the two), ``split_percent``
        (``100 (f2 / f1 - 1)``), ``mac`` (NaN without mode vectors) and ``flags`` (the two).
    """
    rows = modal_table(ds)
    if len(rows) < 2:
        return []
    mac = None
    if names.MAC in ds and ds[names.MAC].ndim == 2:
        mac = np.asarray(ds[names.MAC].values, dtype=float)
    elif names.MODE_VECTOR in ds:
        from ami_xr.core.modal import mac_matrix

        mac = mac_matrix(ds[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values)
    order = np.argsort([r["frequency_hz"] for r in rows])
    out = []
    for i, j in zip(order[:-1], order[1:], strict=True):
        a, b = rows[i], rows[j]
        la, lb = a["eigenvalue"], b["eigenvalue"]
        close = (
            np.isfinite(la)
            and np.isfinite(lb)
            and (abs(la.imag - lb.imag) <= abs(la.real) + abs(lb.real))
        )
        if not close:
            continue
        out.append(
            {
                "modes": (a["mode"], b["mode"]),
                "frequency_hz": (a["frequency_hz"], b["frequency_hz"]),
                "split_percent": 100.0 * (b["frequency_hz"] / a["frequency_hz"] - 1.0),
                "mac": float(mac[i, j]) if mac is not None else float("nan"),
                "flags": (a["flags"], b["flags"]),
            }
        )
    return out
