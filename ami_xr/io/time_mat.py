"""Time histories in MATLAB files (``.mat``): channels with a sampling rate, for ``ami-xr frf``.

The file's variables, or the fields of its one struct (names case-insensitive), in one of two
layouts:

* **force and response**: ``force`` (a vector: one force channel) and ``response`` (a vector
  or a matrix, channels x samples or samples x channels), optionally ``points`` (a label per
  response channel);
* **channels**: a matrix ``data`` (or ``channels``, ``signals``, ``y``) of all channels with
  ``channel_names`` (or ``names``, ``titles``, ``labels``: a cell array of text) and optionally
  ``channel_units`` (``units``: a cell array, e.g. ``{'N', 'm/s^2', 'm/s^2'}``); the force
  channel is the one named by ``force_channel`` (index or name), else the one channel with a
  force unit (N, kN, lbf), else the one whose name contains "force"; the others are the
  responses, labelled by their names.

And the sampling: ``fs`` (or ``sample_rate``, ``sampling_rate``, ``samplerate``; Hz), ``dt``
(``sample_interval``; s), or a time vector ``t``/``time`` (s, uniform). The samples axis of a
matrix is the one whose length is the time vector's, else the longer one. What the numbers do
not say comes from variables ``drive_point``, ``response_quantity``, ``response_units``,
``force_units``, or from the keyword arguments (which win). A file that fits neither layout is
refused with a :class:`~ami_xr.errors.DataFileError` naming the file, what it holds and what
is expected.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.frf_tables.build import FREQUENCY_NAMES, is_frequency_name
from ami_xr.io.frf_tables.matlab import describe_variables, load_variables, text_list
from ami_xr.provenance import add_history

__all__ = ["RATE_NAMES", "holds_time_histories", "read_time_mat"]

RATE_NAMES = ("fs", "sample_rate", "sampling_rate", "samplerate")
INTERVAL_NAMES = ("dt", "sample_interval")
TIME_NAMES = ("t", "time")
MATRIX_NAMES = ("data", "channels", "signals", "y")
CHANNEL_NAMES = ("channel_names", "names", "titles", "labels")
CHANNEL_UNITS = ("channel_units", "units")
EXPECTED = (
    "expected time histories as 'force' and 'response' variables, or a matrix 'data' with "
    "'channel_names' (and 'channel_units'), and a sampling rate 'fs' (Hz), 'dt' (s) or a time "
    "vector 't' (s)"
)


def _find(scope: dict[str, Any], wanted: tuple[str, ...]) -> str | None:
    hits = [k for k in scope if k.lower() in wanted]
    return hits[0] if hits else None


def _load(path: Path) -> tuple[dict[str, Any], str]:
    variables, _ = load_variables(path)
    if any(_find(variables, w) for w in (RATE_NAMES, INTERVAL_NAMES, TIME_NAMES)):
        return variables, "the file"
    structs = [k for k, v in variables.items() if isinstance(v, dict)]
    if len(structs) == 1:
        return variables[structs[0]], f"struct {structs[0]!r}"
    return variables, "the file"


def holds_time_histories(path: str | os.PathLike) -> bool:
    """True when the ``.mat`` file (or its one struct) has a sampling rate, a sample interval
    or a time vector and no frequency vector: time histories, not an FRF table."""
    scope, _ = _load(Path(path))
    timed = any(_find(scope, w) for w in (RATE_NAMES, INTERVAL_NAMES, TIME_NAMES))
    return timed and not any(is_frequency_name(k) or k.lower() in FREQUENCY_NAMES for k in scope)


def _number(value: Any, name: str, path: Path) -> float:
    x = np.squeeze(np.asarray(value, dtype=float)) if not isinstance(value, str) else np.nan
    if np.ndim(x) != 0 or not np.isfinite(x) or x <= 0:
        raise DataFileError(f"{path}: variable {name!r}: expected one number > 0, got {value!r}")
    return float(x)


def _sampling(scope: dict[str, Any], where: str, path: Path) -> tuple[float, int | None]:
    """Sampling rate (Hz) and, from a time vector, the number of samples."""
    if (name := _find(scope, RATE_NAMES)) is not None:
        return _number(scope[name], name, path), None
    if (name := _find(scope, INTERVAL_NAMES)) is not None:
        return 1.0 / _number(scope[name], name, path), None
    if (name := _find(scope, TIME_NAMES)) is not None:
        t = np.squeeze(np.asarray(scope[name], dtype=float))
        steps = np.diff(t) if t.ndim == 1 and t.size > 1 else np.array([np.nan])
        if not (np.all(steps > 0) and np.allclose(steps, steps[0], rtol=1e-6, atol=0)):
            raise DataFileError(f"{path}: variable {name!r}: expected uniform times in s")
        return 1.0 / float((t[-1] - t[0]) / (t.size - 1)), int(t.size)
    raise DataFileError(
        f"{path}: {where} has no sampling rate; {EXPECTED}; found: {describe_variables(scope)}"
    )


def _channels(value: Any, name: str, n_time: int | None, path: Path) -> np.ndarray:
    """(channel, sample) float array of a vector or matrix variable."""
    x = np.asarray(value)
    if not np.issubdtype(x.dtype, np.number) or np.iscomplexobj(x) or x.ndim not in (1, 2):
        raise DataFileError(
            f"{path}: variable {name!r}: expected real samples (a vector or a matrix), got "
            f"{x.dtype} of shape {x.shape}"
        )
    x = np.atleast_2d(x.astype(np.float64))
    if n_time is not None and x.shape[0] == n_time and x.shape[1] != n_time:
        return np.ascontiguousarray(x.T)
    if n_time is None and x.shape[0] > x.shape[1]:
        return np.ascontiguousarray(x.T)
    return x


def _force_index(force_channel: Any, titles: list, units: list[str], path: Path) -> int:
    if force_channel is not None:
        if isinstance(force_channel, (int, np.integer)) and 0 <= force_channel < len(titles):
            return int(force_channel)
        if str(force_channel) in map(str, titles):
            return [str(t) for t in titles].index(str(force_channel))
        raise AmiXrValueError(
            f"force_channel: expected an index 0..{len(titles) - 1} or one of {titles}, got "
            f"{force_channel!r} ({path.name})"
        )
    rules = (
        lambda c: units[c] in names.FORCE_UNITS,
        lambda c: "force" in str(titles[c]).lower(),
    )
    for test in rules:
        hits = [c for c in range(len(titles)) if test(c)]
        if len(hits) == 1:
            return hits[0]
    raise AmiXrValueError(
        f"force_channel: cannot tell the force channel of {path.name} from the channel names "
        f"{titles} and units {units}; give force_channel (ami-xr frf --force-channel)"
    )


def read_time_mat(
    path: str | os.PathLike,
    *,
    force_channel: int | str | None = None,
    points: list | None = None,
    drive_point: Any = None,
    response_quantity: str | None = None,
    response_units: str | None = None,
    force_units: str | None = None,
) -> xr.Dataset:
    """Read force and response time histories from a MATLAB file (layouts: module docstring).

    Parameters
    ----------
    path : str or path-like
        A v4 to v7 file, or v7.3 with ``h5py`` installed.
    force_channel : int or str, optional
        Layout "channels": the force channel's index or name.
    points : list, optional
        Labels of the response channels, in file order.
    drive_point, response_quantity, response_units, force_units : optional
        As for :func:`ami_xr.make_time_dataset`; given, they win over the file's variables.

    Returns
    -------
    xarray.Dataset
        A time Dataset (``response`` (point, time), ``force`` (time)) with ``source_file``.

    Raises
    ------
    DataFileError
        Not a MATLAB file; no sampling rate or no channels (the message lists the variables
        found and what is expected); several force channels; shapes that do not fit.
    AmiXrValueError
        A force channel that cannot be told or bad labels.
    """
    from ami_xr.io.datasets import make_time_dataset

    path = Path(path)
    scope, where = _load(path)
    fs, n_time = _sampling(scope, where, path)
    keys = ("drive_point", "response_quantity", "response_units", "force_units")
    said = {k: text_list(scope[n])[0] for k in keys if (n := _find(scope, (k,))) is not None}
    fname, rname, mname = (_find(scope, w) for w in (("force",), ("response",), MATRIX_NAMES))
    if fname is not None and rname is not None:
        force = _channels(scope[fname], fname, n_time, path)
        response = _channels(scope[rname], rname, n_time, path)
        if force.shape[0] != 1:
            raise DataFileError(
                f"{path}: variable {fname!r} holds {force.shape[0]} force channels; ami-xr frf "
                "reads one force channel from a .mat file (build a multi-reference time Dataset "
                "in Python: ami_xr.frf takes force with a 'reference' dim)"
            )
        pname = _find(scope, ("points", "point_labels"))
        labels = text_list(scope[pname]) if pname is not None else None
        channel = fname
    elif mname is not None:
        data = _channels(scope[mname], mname, n_time, path)
        nname, uname = _find(scope, CHANNEL_NAMES), _find(scope, CHANNEL_UNITS)
        titles = text_list(scope[nname]) if nname else list(range(data.shape[0]))
        units = [str(u) for u in text_list(scope[uname])] if uname else [""] * data.shape[0]
        if len(titles) != data.shape[0] or len(units) != data.shape[0]:
            raise DataFileError(
                f"{path}: {data.shape[0]} channels in {mname!r} but {len(titles)} names and "
                f"{len(units)} units"
            )
        fc = _force_index(force_channel, titles, units, path)
        rest = [c for c in range(data.shape[0]) if c != fc]
        force, response, labels = data[fc : fc + 1], data[rest], [titles[c] for c in rest]
        said.setdefault("force_units", units[fc] or None)
        if len({units[c] for c in rest}) == 1 and units[rest[0]]:
            said.setdefault("response_units", units[rest[0]])
        channel = str(titles[fc])
    else:
        found = describe_variables(scope)
        raise DataFileError(f"{path}: {where} has no channels; {EXPECTED}; found: {found}")
    if force.shape[1] != response.shape[1]:
        raise DataFileError(
            f"{path}: the force has {force.shape[1]} samples, the responses {response.shape[1]}"
        )
    given = {
        "drive_point": drive_point,
        "response_quantity": response_quantity,
        "response_units": response_units,
        "force_units": force_units,
    }
    kw = {k: v for k, v in said.items() if v is not None}
    kw.update({k: v for k, v in given.items() if v is not None})  # the arguments win
    labels = list(points) if points is not None else labels
    ds = make_time_dataset(response, fs=fs, force=force[0], points=labels, **kw)
    ds[names.FORCE].attrs["channel"] = channel
    ds.attrs[names.ATTR_SOURCE_FILE] = path.name
    record = {"fs": fs, "force_channel": channel}
    return add_history(ds, "ami_xr.io.time_mat.read_time_mat", record, source_file=path.name)
