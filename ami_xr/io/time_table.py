"""Time histories as text tables (``.csv``, ``.txt``, ``.dat``): channels with a sampling rate, for
``ami-xr frf``.

The layout (a small header convention; separators, quoting and comments as for the FRF tables
of :mod:`ami_xr.io.frf_tables`)::

    # fs: 2048
    # force_channel: hammer
    # sensitivity: hammer=0.00225
    # drive_point: a1
    time [s], hammer [V], a1 [m/s^2], a2 [g]
    0.0, 0.01, 0.002, 0.0001
    ...

* **the channels**: one column each, the name first and the unit in brackets after it (any
  spelling of :mod:`ami_xr.io.units`: ``[m/s²]``, ``[G]``, ``[Newtons]``, or ``[V]`` for a
  channel recorded in volts);
* **the sampling**: a time column named ``t`` or ``time`` (s; uniform), or a line ``# fs:
  <Hz>`` (also ``sample_rate``, ``sampling_rate``) above the header, or the option ``fs``;
* **the force channel(s)**: ``# force_channel: <name>`` (several separated by commas: a
  multi-reference test), or the option ``force_channel`` (``ami-xr frf --force-channel``),
  else the one channel with a force unit, else the one whose name contains "force" or "hammer";
* **volts**: ``# sensitivity: <channel>=<V per unit>, ...`` (or the option ``sensitivity``, a
  dict): the channel is divided by it; the unit after the conversion is the force's ``N`` (or
  ``# force_units:``), and for responses ``# response_units:`` (volts say nothing of it). A
  channel in volts without a sensitivity is refused, naming it;
* ``# drive_point:``, ``# response_quantity:``, ``# response_units:``, ``# force_units:`` say
  what the numbers do not (the options of the same names win).

A table is read as time histories (and not as FRFs) when it has a time column or an ``fs`` line
and no frequency column, or when ``ami-xr frf`` asks for time histories.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.build import (
    METADATA_KEYS,
    TIME_OPTION_KEYS,
    ReadOptions,
    force_channels,
    is_frequency_name,
    point_labels,
    split_unit,
    time_dataset,
)
from ami_xr.io.frf_tables.text import cell_values, is_number, read_lines
from ami_xr.io.units import force_unit, response_unit

__all__ = ["holds_time_histories", "read_time_csv"]

TIME_NAMES = ("t", "time")
RATE_KEYS = ("fs", "sample_rate", "sampling_rate")
VOLTS = ("v", "volt", "volts")
_KEYS = (*METADATA_KEYS, *RATE_KEYS, "force_channel", "sensitivity")
HOW = "say it with a line '# {0}: ...' above the header, or pass {0}= (ami-xr frf --drive-point)"
EXPECTED = (
    "expected a header of channel names with units in brackets ('time [s], force [N], a1 "
    "[m/s^2]') and a time column or a '# fs: <Hz>' line"
)


def _is_time_name(name: str) -> bool:
    return split_unit(name)[0].lower() in TIME_NAMES


def holds_time_histories(path: str | os.PathLike) -> bool:
    """True when a text table has a time column or a sampling-rate line and no frequency
    column: time histories, not FRFs."""
    lines = read_lines(Path(path), _KEYS, max_rows=1)  # the header is enough to tell
    header = lines.rows[0][1]
    if any(is_frequency_name(name) for name in header):
        return False
    return any(k in lines.said for k in RATE_KEYS) or any(_is_time_name(n) for n in header)


def _sensitivity(text: str | None, path: Path) -> dict[str, float]:
    """``{channel: V per unit}`` of a ``# sensitivity: a=0.01, b=0.1`` line."""
    out: dict[str, float] = {}
    for item in filter(None, (p.strip() for p in (text or "").split(","))):
        name, _, value = item.rpartition("=")
        if not name.strip() or not is_number(value):
            raise DataFileError(
                f"{path}: '# sensitivity: {text}': expected <channel>=<volts per unit>, ..."
            )
        out[name.strip()] = float(value)
    return out


def _rate(said: dict[str, str], given: ReadOptions, time: np.ndarray | None, path: Path) -> float:
    """The sampling rate: the option, the ``# fs`` line or the time column (uniform)."""
    key = next((k for k in RATE_KEYS if k in said), None)
    if given.fs is not None:
        return float(given.fs)
    if key is not None:
        if not is_number(said[key]) or not float(said[key]) > 0:
            raise DataFileError(f"{path}: '# {key}: {said[key]}': expected a rate > 0 in Hz")
        return float(said[key])
    if time is None:
        raise DataFileError(f"{path}: no time column and no sampling rate; {EXPECTED}")
    steps = np.diff(time)
    if time.size < 2 or not (np.all(steps > 0) and np.allclose(steps, steps[0], rtol=1e-6)):
        raise DataFileError(f"{path}: the time column: expected uniform increasing times in s")
    return float((time.size - 1) / (time[-1] - time[0]))


def _volts_checked(
    names_: list[str], units: list[str], sensitivity: dict, said: dict, path: Path, forces: list
) -> None:
    """A channel in volts needs a sensitivity, and a response in volts its units after it."""
    for c, (name, unit) in enumerate(zip(names_, units, strict=True)):
        if unit.lower() not in VOLTS:
            continue
        if name not in sensitivity:
            raise DataFileError(
                f"{path}: channel {name!r} is in volts; give its sensitivity in V per unit "
                f"('# sensitivity: {name}=<V/unit>' above the header, or sensitivity=)"
            )
        if c not in forces and "response_units" not in said:
            raise DataFileError(
                f"{path}: response channel {name!r} is in volts; say the units after the "
                "sensitivity ('# response_units: m/s^2', or response_units=)"
            )


def read_time_csv(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read force and response time histories from a text table (layout: module docstring).

    Parameters
    ----------
    path : str or path-like
        The ``.csv``, ``.txt`` or ``.dat`` file.
    **options
        :class:`~ami_xr.io.build.ReadOptions`: ``force_channel`` (name or index, or several),
        ``fs`` (Hz, for a table without a time column or ``# fs`` line), ``sensitivity``
        (``{channel: V per unit}``), ``points`` (labels of the response channels),
        ``drive_point``, ``response_quantity``, ``response_units``, ``force_units``; given,
        they win over the file's lines.

    Returns
    -------
    xarray.Dataset
        A time Dataset: ``response`` (point, time), ``force`` ([reference,] time), with
        ``source_file``.

    Raises
    ------
    DataFileError
        No header, no sampling rate, cells that are not numbers (named by line and column),
        a channel in volts without a sensitivity, units that disagree.
    AmiXrValueError
        A force channel that cannot be told, or bad options.
    """
    path = Path(path)
    given = ReadOptions.of(options, "read_time_csv", TIME_OPTION_KEYS)
    lines = read_lines(path, _KEYS)
    header = lines.rows[0][1]
    if all(is_number(f) for f in header):
        raise DataFileError(f"{path}: no header line; {EXPECTED}")
    values = cell_values(lines.rows[1:], header, path)
    timed = [c for c, name in enumerate(header) if _is_time_name(name)]
    time = values[:, timed[0]] if timed else None
    fs = _rate(lines.said, given, time, path)
    channels = [c for c in range(len(header)) if c not in timed[:1]]
    titles = [split_unit(header[c])[0] for c in channels]
    units = [split_unit(header[c])[1] for c in channels]
    wanted = (
        given.force_channel if given.force_channel is not None else lines.said.get("force_channel")
    )
    fc = force_channels(wanted, titles, units, path)
    rest = [c for c in range(len(titles)) if c not in fc]
    if not rest:
        raise DataFileError(f"{path}: only force channels {titles}; expected responses too")
    said: dict[str, Any] = {k: lines.said[k] for k in METADATA_KEYS if k in lines.said}
    sensitivity = given.sensitivity or _sensitivity(lines.said.get("sensitivity"), path)
    _volts_checked(titles, units, sensitivity, {**said, **given.given()}, path, fc)
    said.setdefault("force_units", force_unit(units[fc[0]]))
    found = {response_unit(units[c]) for c in rest if units[c].lower() not in VOLTS}
    if len(found) > 1 and given.response_units is None:
        raise AmiXrValueError(
            f"response_units: the response channels of {path.name} have different units "
            f"{[units[c] for c in rest]}; give response_units"
        )
    if found and "response_units" not in said:
        said["response_units"] = found.pop() or units[rest[0]]
    samples = values[:, channels].T
    forces = [titles[c] for c in fc]
    record = {"format": "text table", "fs": fs, "force_channel": forces, "columns": header}
    meta = {
        "force_names": forces,
        "sensitivity": sensitivity or None,
        "function": "ami_xr.read_any",
    }
    labels = point_labels([titles[c] for c in rest])
    return time_dataset(
        path, samples[rest], samples[fc], fs, labels, said, given, HOW, record, meta
    )
