"""FRF tables as text: ``.csv``, ``.txt`` and ``.dat`` (the layouts: :mod:`ami_xr.io.frf_tables`).

The file is read in four steps, each with its own errors: the lines (comments, the ``# key:
value`` lines, the separator), the header (which column is what), the cells (numbers, every one
named by line and column when it is not), and the Dataset (:func:`.build.frf_dataset`).
"""

from __future__ import annotations

import csv
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr.caller import warn
from ami_xr.errors import AssumptionWarning, DataFileError
from ami_xr.io.build import (
    FREQUENCY_NAMES,
    METADATA_KEYS,
    OPTION_KEYS,
    ReadOptions,
    frf_dataset,
    frf_units_of,
    is_frequency_name,
    point_labels,
    split_unit,
)

__all__ = ["read_frf_csv", "read_lines", "cell_values", "is_number", "ATTR_COLUMNS_ASSUMED"]

#: Attribute recording the layout assumed for a table without a header line.
ATTR_COLUMNS_ASSUMED = "table_columns_assumed"
# column-name parts (case-insensitive) -> what the column holds
PARTS = {
    "re": "real",
    "real": "real",
    "im": "imag",
    "imag": "imag",
    "imaginary": "imag",
    "mag": "mag",
    "magnitude": "mag",
    "abs": "mag",
    "amp": "mag",
    "amplitude": "mag",
    "phase": "phase",
    "ph": "phase",
    "angle": "phase",
}
_PART_NAMES = "|".join(sorted(PARTS, key=len, reverse=True))
_COLUMN = re.compile(rf"^(?P<label>.+?)[\s_.:-]+(?P<part>{_PART_NAMES})$", re.IGNORECASE)
_METADATA = re.compile(r"^#\s*(?P<key>[A-Za-z_ ]+?)\s*[:=]\s*(?P<value>.*?)\s*$")
_PAIRS = ({"real", "imag"}, {"mag", "phase"})
_WORDS = {"real": "real", "imag": "imaginary", "mag": "magnitude", "phase": "phase"}
_PHASE_UNITS = {"": 1.0, "deg": 1.0, "degree": 1.0, "degrees": 1.0, "°": 1.0, "rad": 180 / np.pi}
HOW = "say it with a line '# {0}: ...' above the header, or pass {0}= to ami_xr.open_frf"


@dataclass
class _Lines:
    """The rows of a text table: (line number, fields), with what its comment lines said."""

    rows: list[tuple[int, list[str]]] = field(default_factory=list)
    said: dict[str, str] = field(default_factory=dict)
    separator: str | None = None


def _text(path: Path) -> str:
    data = path.read_bytes()
    if b"\x00" in data[:4096]:
        raise DataFileError(f"{path}: a binary file; expected a text table (CSV, TXT or DAT)")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:  # a spreadsheet's export in a Windows code page
        return data.decode("latin-1")


def _separator(line: str) -> str | None:
    for sep in ("\t", ",", ";"):
        if sep in line:
            return sep
    return None  # runs of spaces


def _split(line: str, sep: str | None) -> list[str]:
    """The fields of a line: quoted as a spreadsheet quotes them (``"a, b"``), or split at runs
    of spaces (``sep`` None)."""
    raw = line.split() if sep is None else next(csv.reader([line], delimiter=sep))
    fields = [f.strip() for f in raw]
    while sep is not None and fields and fields[-1] == "":  # a trailing separator
        fields.pop()
    return fields


def read_lines(
    path: Path, keys: tuple[str, ...] = METADATA_KEYS, max_rows: int | None = None
) -> _Lines:
    """The rows of a text table (the first ``max_rows``, or all) and what its ``# key: value``
    lines above them say (``keys``)."""
    out = _Lines()
    for number, raw in enumerate(_text(path).splitlines(), start=1):
        if max_rows is not None and len(out.rows) >= max_rows:
            break
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            match = _METADATA.match(line)
            key = match["key"].strip().lower().replace(" ", "_") if match else ""
            if key in keys and not out.rows:
                out.said[key] = match["value"].strip().strip('"').strip("'")
            continue
        if not out.rows:
            out.separator = _separator(line)
        out.rows.append((number, _split(line, out.separator)))
    if not out.rows:
        raise DataFileError(f"{path}: no header and no data rows; expected a table")
    return out


def is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


@dataclass
class _Columns:
    """Which column is what: the frequency, and per point its two columns and their kind."""

    frequency: int = 0
    points: dict[str, dict[str, int]] = field(default_factory=dict)  # label -> part -> column
    phase_scale: dict[str, float] = field(default_factory=dict)  # label -> to degrees
    units: set[str] = field(default_factory=set)
    layout: str = ""


def _frequency_column(header: list[str], path: Path) -> int:
    found = [i for i, name in enumerate(header) if is_frequency_name(name)]
    if len(found) != 1:
        how = "no" if not found else f"{len(found)} ({[header[i] for i in found]})"
        raise DataFileError(
            f"{path}: {how} frequency column; expected one column named "
            f"{' or '.join(FREQUENCY_NAMES)} (in Hz; '[Hz]' or '_hz' may follow); "
            f"the columns are {header}"
        )
    unit = split_unit(header[found[0]])[1]
    if unit.lower() not in ("", "hz"):
        raise DataFileError(
            f"{path}: column {header[found[0]]!r}: frequencies in {unit!r}; expected Hz"
        )
    return found[0]


def _columns(header: list[str], path: Path) -> _Columns:
    """Map a header to the frequency column and each point's pair of columns."""
    cols = _Columns(frequency=_frequency_column(header, path), layout="header")
    for i, name in enumerate(header):
        if i == cols.frequency:
            continue
        base, unit = split_unit(name)
        match = _COLUMN.match(base)
        if match is None:
            raise DataFileError(
                f"{path}: column {name!r} (column {i + 1}): not understood; expected "
                "<point>_re and <point>_im, or <point>_mag and <point>_phase (degrees), e.g. "
                "'p1_re', '1 mag', 'tip phase [deg]'"
            )
        label, part = match["label"].strip(), PARTS[match["part"].lower()]
        parts = cols.points.setdefault(label, {})
        if part in parts:
            raise DataFileError(
                f"{path}: columns {header[parts[part]]!r} and {name!r} both hold the {part} "
                f"part of point {label!r}"
            )
        parts[part] = i
        if part == "phase":
            scale = _PHASE_UNITS.get(unit.lower())
            if scale is None:
                raise DataFileError(
                    f"{path}: column {name!r}: phase unit {unit!r}; expected deg or rad"
                )
            cols.phase_scale[label] = scale
        elif unit:
            cols.units.add(unit)
    for label, parts in cols.points.items():
        if set(parts) not in _PAIRS:
            have = ", ".join(repr(header[c]) for c in parts.values())
            need = {"real": "imag", "imag": "real", "mag": "phase", "phase": "mag"}
            missing = sorted({need[p] for p in parts} - set(parts))
            what = (
                f"no column for the {' and '.join(_WORDS[m] for m in missing)} part"
                if missing
                else "both real/imaginary and magnitude/phase columns"
            )
            raise DataFileError(
                f"{path}: point {label!r}: {what} (found {have}); expected '{label}_re' with "
                f"'{label}_im', or '{label}_mag' with '{label}_phase'"
            )
    if not cols.points:
        raise DataFileError(f"{path}: only a frequency column; expected FRF columns after it")
    return cols


def _headerless(width: int, path: Path) -> _Columns:
    if width < 3 or width % 2 == 0:
        raise DataFileError(
            f"{path}: no header line and {width} column(s); without a header the columns must "
            "be the frequency (Hz) and pairs of real and imaginary parts (an odd number, at "
            "least 3); add a header such as 'freq,p1_re,p1_im' for other layouts"
        )
    points = {str(k): {"real": 1 + 2 * k, "imag": 2 + 2 * k} for k in range((width - 1) // 2)}
    return _Columns(frequency=0, points=points, layout="headerless")


def _cell_error(path: Path, number: int, column: str, cell: str) -> DataFileError:
    if cell == "":
        what = "an empty cell"
    elif is_number(cell):
        what = f"{cell!r} is not a finite number"
    else:
        what = f"{cell!r} is not a number"
        if "," in cell:
            what += " (a decimal comma? expected a decimal point)"
    return DataFileError(f"{path}: line {number}, column {column!r}: {what}")


def cell_values(rows: list[tuple[int, list[str]]], header: list[str], path: Path) -> np.ndarray:
    """The cells as floats, shape (n_row, n_column); a bad row or cell is named."""
    width = len(header)
    for number, fields in rows:
        if len(fields) != width:
            raise DataFileError(
                f"{path}: line {number}: {len(fields)} field(s), expected {width} (the columns "
                f"{header})"
            )
    if not rows:
        raise DataFileError(f"{path}: a header and no data rows")
    try:
        values = np.array([fields for _, fields in rows], dtype=np.float64)
    except ValueError:
        values = None
    if values is not None and np.isfinite(values).all():
        return values
    for number, fields in rows:  # find the first bad cell
        for name, cell in zip(header, fields, strict=True):
            if not (is_number(cell) and np.isfinite(float(cell))):
                raise _cell_error(path, number, name, cell)
    raise DataFileError(f"{path}: cells that are not numbers")  # not reached


def _frequency(freq: np.ndarray, rows: list, name: str, path: Path) -> np.ndarray:
    step = np.diff(freq)
    if step.size and not (step > 0).all():
        k = int(np.argmax(step <= 0)) + 1
        raise DataFileError(
            f"{path}: line {rows[k][0]}, column {name!r}: frequency {freq[k]:g} after "
            f"{freq[k - 1]:g}; expected strictly increasing frequencies"
        )
    if freq[0] < 0:
        raise DataFileError(f"{path}: column {name!r}: negative frequency {freq[0]:g} Hz")
    return freq


def read_frf_csv(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read an FRF table from a text file (``.csv``, ``.txt``, ``.dat``).

    The accepted layouts are described in :mod:`ami_xr.io.frf_tables`; in short: a header line
    with a frequency column (Hz) and, per point, ``<point>_re``/``<point>_im`` or
    ``<point>_mag``/``<point>_phase`` (degrees) columns, or no header and the columns
    frequency, real, imaginary, real, imaginary, ...

    Parameters
    ----------
    path : str or path-like
        The file; comma, tab, semicolon or space separated (decided from the header line).
    drive_point : label, optional
        The point where the force acts; default the file's (``# drive_point: ...``), else the
        single point of a one-FRF table (assumed, with an
        :class:`~ami_xr.errors.AssumptionWarning` and attribute ``drive_point_assumed``).
    points : list, optional
        Point labels in column order, replacing the header's.
    response_quantity, frf_type, response_units, force_units : str, optional
        As for :func:`ami_xr.make_frf_dataset`; default what the file says (``# key: value``
        lines, units in the column names such as ``p1_re [m/s^2/N]``); with nothing said,
        receptance in m/N is assumed, with a warning and attribute
        ``response_quantity_assumed``.

    Returns
    -------
    xarray.Dataset
        FRF Dataset (``frf`` (point, frequency)), ``frf_source = "measured"``.

    Raises
    ------
    DataFileError
        A frequency or FRF column missing or not understood, a row with the wrong number of
        fields, a cell that is not a finite number (named by line and column), frequencies that
        do not increase; each message names the file.
    SchemaError
        The FRFs read break the data model (named problems).
    """
    path = Path(path)
    given = ReadOptions.of(options, "read_frf_csv", OPTION_KEYS)
    lines = read_lines(path)
    first = lines.rows[0][1]
    has_header = not all(is_number(f) for f in first)
    if has_header:
        header, rows = first, lines.rows[1:]
        cols = _columns(header, path)
    else:
        rows = lines.rows
        cols = _headerless(len(first), path)
        header = [f"column {i + 1}" for i in range(len(first))]
    values = cell_values(rows, header, path)
    freq = _frequency(values[:, cols.frequency], rows, header[cols.frequency], path)
    frf = np.empty((len(cols.points), freq.size), dtype=np.complex128)
    for k, (label, parts) in enumerate(cols.points.items()):
        if "real" in parts:
            frf[k] = values[:, parts["real"]] + 1j * values[:, parts["imag"]]
        else:
            phase = np.deg2rad(values[:, parts["phase"]] * cols.phase_scale.get(label, 1.0))
            frf[k] = values[:, parts["mag"]] * np.exp(1j * phase)
    said: dict[str, Any] = dict(lines.said)
    if len(cols.units) > 1:
        raise DataFileError(f"{path}: the FRF columns mix units {sorted(cols.units)}")
    if cols.units:
        unit = cols.units.pop()
        response, force = frf_units_of(unit, "FRF columns", path)
        said.setdefault("response_units", response)
        said.setdefault("force_units", force)
    extra = {}
    if not has_header:
        extra[ATTR_COLUMNS_ASSUMED] = _assumed_columns(path, len(cols.points))
    record = {"format": "text table", "layout": cols.layout, "columns": header}
    labels = point_labels(list(cols.points)) if has_header else None
    return frf_dataset(path, frf, freq, labels, said, given, HOW, record, extra)


def _assumed_columns(path: Path, n: int) -> str:
    """Warn that a table without a header was read as frequency and (real, imaginary) pairs."""
    what = (
        f"no header line: column 1 read as the frequency in Hz and columns 2 to {2 * n + 1} as "
        f"the real and imaginary parts of points 0 to {n - 1}"
    )
    warn(
        f"{path.name}: {what}; add a header (e.g. 'freq,p1_re,p1_im') to name the points",
        AssumptionWarning,
    )
    return what
