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
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.build import TIME_OPTION_KEYS, ReadOptions, force_channels, time_dataset
from ami_xr.io.units import force_unit, quantity_of_unit, response_unit

_END = "***End_of_Header***"
HOW = "give {0} (ami-xr frf --drive-point) to set it"


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


def _channel_units(seg: dict, channels: int) -> list[str]:
    """The unit label of each channel, through the one unit parser (``Newtons`` is ``N``)."""
    raw = [u.strip() for u in seg["header"].get("Y_Unit_Label", [])][:channels]
    raw += [""] * (channels - len(raw))
    return [response_unit(u) or force_unit(u) or u for u in raw]


def _stacked(segments: list[dict], path: Path) -> tuple[np.ndarray, float]:
    """The samples of every segment, ``(record, time, channel)``, and the sample interval."""
    channels = segments[0]["channels"]
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
    if channels < 2:
        raise DataFileError(
            f"{path}: needs a force and at least one response channel, has {channels}"
        )
    return np.stack([s["values"] for s in segments]), dts.pop()


def read_lvm(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read a LabVIEW LVM text file into a time Dataset.

    Parameters
    ----------
    path : str or path-like
        The ``.lvm`` file.
    **options
        :class:`~ami_xr.io.build.ReadOptions`:

        * ``force_channel`` (int, str or list): index or column title of the force channel, or
          several (a multi-reference test). Default: the channel whose unit label is a force
          unit (Newtons, N, kN, lbf) or whose title contains "force" or "hammer".
        * ``points`` (list): labels of the response channels (default: their column titles).
        * ``drive_point``: label (one of ``points``) of the response measured where the force
          acts. Default: the single response point if there is one; that assumption is
          recorded as the attribute ``drive_point_assumed`` and announced by an
          :class:`~ami_xr.errors.AssumptionWarning` (``ami-xr frf`` prints it as one line).
          With several responses and none given, the Dataset has no drive point.
        * ``response_quantity``: default from the response unit label (m/s^2 ->
          acceleration); ``response_units``, ``force_units`` override the file's labels;
          ``sensitivity`` converts volt channels (:func:`ami_xr.make_time_dataset`).

    Returns
    -------
    xarray.Dataset
        ``response`` ([record,] point, time), ``force`` (``[record,] [reference,] time``) and
        ``time`` (s, from 0 at each segment start); with several segments a ``record`` dim
        with coordinate ``record_start`` (s). Attrs ``source_file``, units, quantity, drive
        point (and ``drive_point_assumed`` when it was not given).

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
    given = ReadOptions.of(options, "read_lvm", TIME_OPTION_KEYS)
    if not path.is_file():
        raise DataFileError(f"{path}: no such file")
    _, segments = _parse(path)
    values, dt = _stacked(segments, path)  # (record, time, channel)
    titles = [t.strip() for t in segments[0]["titles"]]
    units = _channel_units(segments[0], len(titles))
    fc = force_channels(given.force_channel, titles, units, path)
    resp = [c for c in range(len(titles)) if c not in fc]
    said = {"force_units": force_unit(units[fc[0]])}  # a channel chosen with another unit: N
    if len({units[c] for c in resp}) != 1 and given.response_units is None:
        raise AmiXrValueError(
            f"response_units: the response channels of {path} have different units "
            f"{[units[c] for c in resp]}; give response_units"
        )
    said["response_units"] = units[resp[0]] or None
    if (
        given.response_quantity is None
        and quantity_of_unit(given.response_units or units[resp[0]]) is None
    ):
        raise AmiXrValueError(
            f"response_quantity: cannot tell it from the unit "
            f"{given.response_units or units[resp[0]]!r}; give one of "
            f"{tuple(names.QUANTITY_TO_FRF_TYPE)}"
        )
    response = np.ascontiguousarray(np.moveaxis(values[:, :, resp], 2, 1))
    force = np.ascontiguousarray(np.moveaxis(values[:, :, fc], 2, 1))
    coords: dict[str, Any] = {}
    if len(segments) > 1:
        x0 = np.array([_float_list(s, "X0", path)[0] for s in segments])
        coords[names.RECORD_START] = (names.RECORD, x0, {names.ATTR_UNITS: names.TIME_UNITS})
    else:
        response, force = response[0], force[0]
    forces = [titles[c] for c in fc]
    record = {
        "force_channel": forces if len(forces) > 1 else forces[0],
        "n_records": len(segments),
        "fs": 1.0 / dt,
    }
    channels = {
        "force_names": forces,
        "sensitivity": given.sensitivity,
        "function": "ami_xr.read_lvm",
        "coords": coords,
    }
    labels = [titles[c] for c in resp]
    return time_dataset(path, response, force, 1.0 / dt, labels, said, given, HOW, record, channels)
