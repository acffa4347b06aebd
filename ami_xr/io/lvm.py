"""LabVIEW Measurement (LVM) text files -> time Dataset: :func:`read_lvm`.

An LVM file is a file header (``LabVIEW Measurement`` ... ``***End_of_Header***``) followed by
one or more segments, each a segment header (``Channels``, ``Samples``, ``Y_Unit_Label``, ``X0``,
``Delta_X``, ... ``***End_of_Header***``), a column-title line (``X_Value  <channel names>
Comment``) and rows of samples. ``X_Columns`` says whether rows carry no x value (``No``), one
(``One``) or one per channel (``Multi``). Separator (``Tab``/``Comma``) and decimal separator come
from the file header.

Each segment becomes one record (an impact hit, or a block of a long record): with several
segments the Dataset has a ``record`` dim and a ``record_start`` coordinate (each segment's X0,
s). One channel is the force, the others are responses.
"""

from __future__ import annotations

import io
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError, AssumptionWarning, DataFileError
from ami_xr.provenance import add_history

_END = "***End_of_Header***"
_UNIT_ALIASES = {
    "newtons": "N",
    "newton": "N",
    "n": "N",
    "kn": "kN",
    "lbf": "lbf",
    "lbs": "lbf",
    "m/s^2": "m/s^2",
    "m/s2": "m/s^2",
    "m/s/s": "m/s^2",
    "g": "g",
    "mm/s^2": "mm/s^2",
    "m/s": "m/s",
    "mm/s": "mm/s",
    "in/s": "in/s",
    "m": "m",
    "mm": "mm",
    "um": "um",
    "in": "in",
    "in/s^2": "in/s^2",
}


def _unit(label: str) -> str:
    return _UNIT_ALIASES.get(label.strip().lower(), label.strip())


def _quantity_of(units: str) -> str | None:
    for quantity, allowed in names.RESPONSE_UNITS.items():
        if units in allowed:
            return quantity
    return None


def _parse(path: Path) -> tuple[dict, list[dict]]:
    """(file header, segments); a segment is {header, titles, values (rows, channels), ...}."""
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as err:
        raise DataFileError(f"{path}: cannot read the file: {err}") from err
    lines = text.splitlines()
    if not lines or not lines[0].startswith("LabVIEW Measurement"):
        raise DataFileError(
            f"{path}: not a LabVIEW LVM file (the first line must be 'LabVIEW Measurement')"
        )
    header: dict[str, list[str]] = {}
    i = 1
    while i < len(lines) and not lines[i].startswith(_END):
        fields = lines[i].split("\t")
        if fields[0]:
            header[fields[0].strip()] = fields[1:]
        i += 1
    if i == len(lines):
        raise DataFileError(f"{path}: the file header has no '{_END}' line (truncated?)")
    sep_name = (header.get("Separator", ["Tab"])[0] or "Tab").strip()
    sep = {"Tab": "\t", "Comma": ","}.get(sep_name)
    if sep is None:
        raise DataFileError(f"{path}: unknown Separator {sep_name!r} (expected Tab or Comma)")
    decimal = (header.get("Decimal_Separator", ["."])[0] or ".").strip() or "."
    if sep != "\t":  # the file header used tabs only if the separator is a tab; re-split it
        header = {}
        for line in lines[1:i]:
            fields = line.split(sep)
            if fields[0]:
                header[fields[0].strip()] = fields[1:]
    x_columns = (header.get("X_Columns", ["One"])[0] or "One").strip()
    if x_columns not in ("No", "One", "Multi"):
        raise DataFileError(f"{path}: unknown X_Columns {x_columns!r} (expected No, One or Multi)")
    segments = []
    i += 1
    n = len(lines)
    while i < n:
        while i < n and not lines[i].strip(sep + " "):
            i += 1
        if i >= n:
            break
        seg_header: dict[str, list[str]] = {}
        start = i
        while i < n and not lines[i].startswith(_END):
            fields = lines[i].split(sep)
            if fields[0]:
                seg_header[fields[0].strip()] = fields[1:]
            i += 1
        if i >= n:
            raise DataFileError(f"{path}: segment header from line {start + 1} has no '{_END}'")
        i += 1
        if i >= n or not lines[i].startswith("X_Value"):
            raise DataFileError(f"{path}: line {i + 1}: expected the column titles (X_Value ...)")
        titles = lines[i].split(sep)
        i += 1
        rows_start = i
        while i < n and lines[i].strip(sep + " ") and not lines[i].startswith("Channels"):
            i += 1
        rows = lines[rows_start:i]
        if not rows:
            raise DataFileError(f"{path}: segment at line {start + 1} has no samples")
        try:
            channels = int(seg_header.get("Channels", [""])[0])
        except ValueError:
            raise DataFileError(
                f"{path}: segment at line {start + 1}: missing or bad 'Channels' count"
            ) from None
        width = {"No": 1 + channels, "One": 1 + channels, "Multi": 2 * channels}[x_columns]
        cols = list(range(1, 1 + channels)) if x_columns != "Multi" else list(range(1, width, 2))
        ch_titles = titles[1 : 1 + channels] if x_columns != "Multi" else titles[1::2][:channels]
        # Before the rows are parsed: a file cut inside a row is reported as cut short, not as
        # a row with too few columns.
        _check_sample_counts(seg_header, len(rows), ch_titles, len(segments) + 1, start, path)
        try:  # fast path (C parser); the row loop below finds the bad line on failure
            rows_text = "\n".join(rows)
            if decimal != ".":
                rows_text = rows_text.replace(decimal, ".")
            values = np.loadtxt(
                io.StringIO(rows_text),
                delimiter=sep,
                usecols=cols,
                dtype=np.float64,
                ndmin=2,
                comments=None,
            )
        except ValueError:
            values = None
        if values is None or values.shape != (len(rows), channels):
            data = np.full((len(rows), width), np.nan)
            for k, r in enumerate(rows):
                fields = (r.replace(decimal, ".") if decimal != "." else r).split(sep)
                if len(fields) < width:
                    raise DataFileError(
                        f"{path}: line {rows_start + k + 1}: expected {width} columns, "
                        f"got {len(fields)}"
                    )
                try:
                    data[k] = [float(v) if v.strip() else np.nan for v in fields[:width]]
                except ValueError as err:
                    raise DataFileError(f"{path}: line {rows_start + k + 1}: {err}") from None
            if x_columns == "Multi":
                values = data[:, 1::2]
            else:
                values = data[:, 1 : 1 + channels]
            if np.isnan(values).any():
                bad = int(np.argwhere(np.isnan(values))[0, 0])
                raise DataFileError(f"{path}: line {rows_start + bad + 1}: missing sample value")
        segments.append(
            {
                "header": seg_header,
                "titles": ch_titles,
                "values": values,
                "line": start + 1,
                "channels": channels,
            }
        )
    if not segments:
        raise DataFileError(f"{path}: no data segments after the file header")
    return header, segments


def _check_sample_counts(
    seg_header: dict, found: int, titles: list[str], number: int, start: int, path: Path
) -> None:
    """Compare the rows read with the segment header's ``Samples`` count of each channel.

    A file cut short (a copy or a transfer stopped part-way) otherwise reads as a shorter
    record; a count the header does not give (an optional field for hand-made files) is not
    checked.
    """
    raw = [v.strip() for v in seg_header.get("Samples", [])][: len(titles)]
    for c, text in enumerate(raw):
        if not text:
            continue
        try:
            expected = int(text)
        except ValueError:
            raise DataFileError(
                f"{path}: segment {number} (line {start + 1}): bad Samples count {text!r}"
            ) from None
        if expected != found:
            cause = " (the file is truncated?)" if found < expected else ""
            raise DataFileError(
                f"{path}: segment {number} (line {start + 1}), channel {titles[c].strip()!r}: "
                f"the header says Samples {expected}; expected {expected} samples, "
                f"found {found}{cause}"
            )


def _float_list(seg: dict, key: str, path: Path) -> list[float]:
    raw = [v for v in seg["header"].get(key, []) if v.strip()]
    try:
        out = [float(v) for v in raw[: seg["channels"]]]
    except ValueError:
        raise DataFileError(f"{path}: segment at line {seg['line']}: bad {key} {raw!r}") from None
    if len(out) != seg["channels"]:
        raise DataFileError(
            f"{path}: segment at line {seg['line']}: expected {seg['channels']} {key} values, "
            f"got {len(out)}"
        )
    return out


def _force_channel(
    force_channel: int | str | None, channels: int, units: list[str], titles: list[str], path: Path
) -> int:
    """Index of the force channel: as given (index or title), else the one force unit or title."""
    if force_channel is None:
        cands = [c for c in range(channels) if units[c] in names.FORCE_UNITS]
        if len(cands) != 1:
            cands = [c for c in range(channels) if "force" in titles[c].lower()]
        if len(cands) != 1:
            raise AmiXrValueError(
                f"force_channel: cannot tell the force channel of {path} from units {units} and "
                f"titles {titles}; give force_channel (index or title)"
            )
        return cands[0]
    if isinstance(force_channel, str):
        if force_channel not in titles:
            raise AmiXrValueError(f"force_channel: {force_channel!r} is not one of {titles}")
        return titles.index(force_channel)
    if isinstance(force_channel, (int, np.integer)) and 0 <= force_channel < channels:
        return int(force_channel)
    raise AmiXrValueError(
        f"force_channel: expected a channel index 0..{channels - 1} or a title, "
        f"got {force_channel!r}"
    )


def read_lvm(
    path: str | os.PathLike,
    *,
    force_channel: int | str | None = None,
    points: list | None = None,
    drive_point: Any = None,
    response_quantity: str | None = None,
    response_units: str | None = None,
    force_units: str | None = None,
) -> xr.Dataset:
    """Read a LabVIEW LVM text file into a time Dataset.

    Long because the docstring documents the LVM layouts and every option; the code is 83 lines.

    Parameters
    ----------
    path : str or path-like
        The ``.lvm`` file.
    force_channel : int or str, optional
        Index or column title of the force channel. Default: the channel whose unit label is a
        force unit (Newtons, N, kN, lbf) or whose title contains "force".
    points : list, optional
        Labels of the response channels (default: their column titles).
    drive_point : label, optional
        Label (one of ``points``) of the response measured where the force acts. Default: the
        single response point if there is one; that assumption is recorded as the attribute
        ``drive_point_assumed`` and announced by an :class:`~ami_xr.errors.AssumptionWarning`
        (``ami-xr frf`` prints it as one line). Given, nothing is assumed or reported. With
        several responses and none given, the Dataset has no drive point.
    response_quantity : {"displacement", "velocity", "acceleration"}, optional
        Default: from the response unit label (e.g. m/s^2 -> acceleration).
    response_units, force_units : str, optional
        Override the unit labels of the file.

    Returns
    -------
    xarray.Dataset
        ``response`` ([record,] point, time), ``force`` ([record,] time) and ``time`` (s, from
        0 at each segment start); with several segments a ``record`` dim with coordinate
        ``record_start`` (s). Attrs ``source_file``, units, quantity, drive point (and
        ``drive_point_assumed`` when it was not given).

    Raises
    ------
    DataFileError
        Malformed file (message names the file and line), a segment with fewer (or more) rows
        than its header's ``Samples`` count (a truncated file: the message names the segment,
        the channel and both counts), or segments of different lengths or sampling intervals.
    AmiXrValueError
        Bad arguments (unknown force channel, ...).
    """
    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"{path}: no such file")
    _, segments = _parse(path)
    channels = segments[0]["channels"]
    titles = [t.strip() for t in segments[0]["titles"]]
    shapes = {s["values"].shape for s in segments}
    if len(shapes) != 1 or any(s["channels"] != channels for s in segments):
        raise DataFileError(
            f"{path}: segments differ in samples or channels ({sorted(shapes)}); cannot stack "
            "them as records"
        )
    dts = {dx for s in segments for dx in _float_list(s, "Delta_X", path)}
    if len(dts) != 1 or not next(iter(dts)) > 0:
        raise DataFileError(
            f"{path}: channels or segments have different or bad Delta_X {sorted(dts)}"
        )
    dt = dts.pop()
    units_raw = [u.strip() for u in segments[0]["header"].get("Y_Unit_Label", [])][:channels]
    units = [_unit(u) for u in units_raw] + [""] * (channels - len(units_raw))
    if channels < 2:
        raise DataFileError(
            f"{path}: needs a force and at least one response channel, has {channels}"
        )
    fc = _force_channel(force_channel, channels, units, titles, path)
    resp = [c for c in range(channels) if c != fc]
    ru = response_units or units[resp[0]]
    if len({units[c] for c in resp}) != 1 and response_units is None:
        raise AmiXrValueError(
            f"response_units: the response channels of {path} have different units "
            f"{[units[c] for c in resp]}; give response_units"
        )
    fu = force_units or units[fc]
    quantity = response_quantity or _quantity_of(ru)
    if quantity not in names.QUANTITY_TO_FRF_TYPE:
        raise AmiXrValueError(
            f"response_quantity: cannot tell it from the unit {ru!r}; give one of "
            f"{tuple(names.QUANTITY_TO_FRF_TYPE)}"
        )
    labels = list(points) if points is not None else [titles[c] for c in resp]
    if len(labels) != len(resp) or len(set(labels)) != len(labels):
        raise AmiXrValueError(f"points: expected {len(resp)} unique labels, got {labels!r}")
    assumed = None
    if drive_point is None and len(labels) == 1:
        drive_point, assumed = labels[0], "the single response channel"
        warnings.warn(
            f"{path.name}: drive point assumed to be {drive_point!r} ({assumed}); give "
            "drive_point (ami-xr frf --drive-point) to set it",
            AssumptionWarning,
            stacklevel=2,
        )
    elif drive_point is not None and drive_point not in labels:
        raise AmiXrValueError(f"drive_point: {drive_point!r} is not one of the points {labels!r}")
    values = np.stack([s["values"] for s in segments])  # (record, time, channel)
    nt = values.shape[1]
    t = np.arange(nt) * dt
    response = np.ascontiguousarray(np.moveaxis(values[:, :, resp], 2, 1))
    force = np.ascontiguousarray(values[:, :, fc])
    coords: dict[str, Any] = {
        names.POINT: labels,
        names.TIME: (names.TIME, t, {names.ATTR_UNITS: names.TIME_UNITS}),
    }
    if len(segments) > 1:
        x0 = np.array([_float_list(s, "X0", path)[0] for s in segments])
        rdims: tuple[str, ...] = (names.RECORD, names.POINT, names.TIME)
        fdims: tuple[str, ...] = (names.RECORD, names.TIME)
        coords[names.RECORD] = np.arange(len(segments))
        coords[names.RECORD_START] = (names.RECORD, x0, {names.ATTR_UNITS: names.TIME_UNITS})
    else:
        rdims, fdims = (names.POINT, names.TIME), (names.TIME,)
        response, force = response[0], force[0]
    attrs = {
        names.ATTR_QUANTITY: quantity,
        names.ATTR_RESPONSE_UNITS: ru,
        names.ATTR_FORCE_UNITS: fu,
    }
    if drive_point is not None:
        attrs[names.ATTR_DRIVE_POINT] = drive_point
    if assumed is not None:
        attrs[names.ATTR_DRIVE_POINT_ASSUMED] = assumed
    ds = xr.Dataset(
        {
            names.RESPONSE: (rdims, response, {names.ATTR_UNITS: ru}),
            names.FORCE: (fdims, force, {names.ATTR_UNITS: fu, "channel": titles[fc]}),
        },
        coords=coords,
        attrs=attrs,
    )
    return add_history(
        ds,
        "ami_xr.read_lvm",
        {"force_channel": titles[fc], "n_records": len(segments), "fs": 1.0 / dt},
        source_file=str(path.resolve()),
    )
