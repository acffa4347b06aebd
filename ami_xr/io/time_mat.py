"""Time histories in MATLAB files (``.mat``): channels with a sampling rate, for ``ami-xr frf``.

The file's variables, or the fields of its one struct (names case-insensitive), in one of two
layouts:

* **force and response**: ``force`` (a vector: one force channel, or a matrix of several: a
  multi-reference test) and ``response`` (a vector or a matrix, channels x samples or
  samples x channels), optionally ``points`` (a label per response channel);
* **channels**: a matrix ``data`` (or ``channels``, ``signals``, ``y``) of all channels with
  ``channel_names`` (or ``names``, ``titles``, ``labels``: a cell array of text) and optionally
  ``channel_units`` (``units``: a cell array, e.g. ``{'N', 'm/s^2', 'm/s^2'}``); the force
  channel is the one named by ``force_channel`` (index or name), else the one channel with a
  force unit (N, kN, lbf), else the one whose name contains "force" or "hammer" (several given: a
  multi-reference test); the others are the
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

from ami_xr.errors import DataFileError
from ami_xr.io.build import (
    FREQUENCY_NAMES,
    TIME_OPTION_KEYS,
    ReadOptions,
    force_channels,
    is_frequency_name,
    time_dataset,
)
from ami_xr.io.frf_tables.matlab import describe_variables, load_variables, text_list

__all__ = ["RATE_NAMES", "holds_time_histories", "read_time_mat"]

RATE_NAMES = ("fs", "sample_rate", "sampling_rate", "samplerate")
INTERVAL_NAMES = ("dt", "sample_interval")
TIME_NAMES = ("t", "time")
MATRIX_NAMES = ("data", "channels", "signals", "y")
CHANNEL_NAMES = ("channel_names", "names", "titles", "labels")
CHANNEL_UNITS = ("channel_units", "units")
HOW = "say it with a variable {0} in the file, or pass {0}= (ami-xr frf --drive-point)"
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


def read_time_mat(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read force and response time histories from a MATLAB file (layouts: module docstring).

    Parameters
    ----------
    path : str or path-like
        A v4 to v7 file, or v7.3 with ``h5py`` installed.
    **options
        :class:`~ami_xr.io.build.ReadOptions`: ``force_channel`` (layout "channels": the force
        channel's index or name, or several), ``points`` (labels of the response channels, in
        file order), ``sensitivity`` (volt channels), and ``drive_point``,
        ``response_quantity``, ``response_units``, ``force_units`` as for
        :func:`ami_xr.make_time_dataset`; given, they win over the file's variables.

    Returns
    -------
    xarray.Dataset
        A time Dataset (``response`` (point, time), ``force`` ([reference,] time)) with
        ``source_file``.

    Raises
    ------
    DataFileError
        Not a MATLAB file; no sampling rate or no channels (the message lists the variables
        found and what is expected); shapes that do not fit.
    AmiXrValueError
        A force channel that cannot be told or bad labels.
    """
    path = Path(path)
    given = ReadOptions.of(options, "read_time_mat", TIME_OPTION_KEYS)
    scope, where = _load(path)
    fs, n_time = _sampling(scope, where, path)
    keys = ("drive_point", "response_quantity", "response_units", "force_units")
    said = {k: text_list(scope[n])[0] for k in keys if (n := _find(scope, (k,))) is not None}
    fname, rname, mname = (_find(scope, w) for w in (("force",), ("response",), MATRIX_NAMES))
    if fname is not None and rname is not None:
        force = _channels(scope[fname], fname, n_time, path)
        response = _channels(scope[rname], rname, n_time, path)
        pname = _find(scope, ("points", "point_labels"))
        labels = text_list(scope[pname]) if pname is not None else None
        forces = [fname] if force.shape[0] == 1 else [f"{fname}{k}" for k in range(len(force))]
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
        fc = force_channels(given.force_channel, titles, units, path)
        rest = [c for c in range(data.shape[0]) if c not in fc]
        force, response, labels = data[fc], data[rest], [titles[c] for c in rest]
        said.setdefault("force_units", units[fc[0]] or None)
        if len({units[c] for c in rest}) == 1 and units[rest[0]]:
            said.setdefault("response_units", units[rest[0]])
        forces = [str(titles[c]) for c in fc]
    else:
        found = describe_variables(scope)
        raise DataFileError(f"{path}: {where} has no channels; {EXPECTED}; found: {found}")
    if force.shape[1] != response.shape[1]:
        raise DataFileError(
            f"{path}: the force has {force.shape[1]} samples, the responses {response.shape[1]}"
        )
    record = {"fs": fs, "force_channel": forces if len(forces) > 1 else forces[0]}
    channels = {
        "force_names": forces,
        "sensitivity": given.sensitivity,
        "function": "ami_xr.io.time_mat.read_time_mat",
    }
    return time_dataset(path, response, force, fs, labels, said, given, HOW, record, channels)
