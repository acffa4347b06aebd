"""What every reader shares: the options it takes, what a file says about the test, the force
channels, the assumptions and the Dataset.

Every reader of :mod:`ami_xr.io.readers` takes one set of keyword options (:class:`ReadOptions`:
the six metadata keywords ``points``, ``drive_point``, ``response_quantity``, ``frf_type``,
``response_units``, ``force_units``, and the time readers' ``force_channel``, ``fs``,
``sensitivity``) and ends in :func:`frf_dataset` or :func:`time_dataset`, which build the
Dataset with :func:`ami_xr.make_frf_dataset` or :func:`ami_xr.make_time_dataset` (so the
data-model check is the one every Dataset passes) and state what they had to assume: an
:class:`~ami_xr.errors.AssumptionWarning` that names the file and how to say it instead, and an
attribute that records it (``drive_point_assumed``, ``response_quantity_assumed``). Units in a
file go through the one unit parser, :mod:`ami_xr.io.units`.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.caller import warn
from ami_xr.dsp.quantity import ATTR_QUANTITY_ASSUMED, resolve_quantity
from ami_xr.errors import AmiXrValueError, AssumptionWarning, DataFileError, SchemaError
from ami_xr.io.units import force_unit, frf_unit, response_unit
from ami_xr.provenance import add_history

__all__ = [
    "FREQUENCY_NAMES",
    "METADATA_KEYS",
    "ReadOptions",
    "force_channels",
    "frf_dataset",
    "frf_units_of",
    "point_labels",
    "split_unit",
    "time_dataset",
]

#: Names of the frequency column or variable (case-insensitive; a unit in brackets, ``[Hz]``,
#: or a trailing ``_hz`` may follow).
FREQUENCY_NAMES = ("frequency", "freq", "f")
#: What a file may say about the test: ``# key: value`` lines above a CSV header, variables (or
#: struct fields) of a MATLAB file. The readers' keyword arguments of the same names win.
METADATA_KEYS = ("drive_point", "response_quantity", "frf_type", "response_units", "force_units")
FUNCTION = "ami_xr.open_frf"  # the provenance record of a table read

# a unit after the name: in brackets (which may hold parentheses: "[(1/N)*(m/s^2)]") or in
# parentheses (the name itself holding none: "frequency (Hz)")
_UNITS = (
    re.compile(r"^(?P<base>.*?)\s*\[\s*(?P<unit>.*?)\s*\]\s*$"),
    re.compile(r"^(?P<base>[^(]*?)\s*\(\s*(?P<unit>.*?)\s*\)\s*$"),
)
_HZ = re.compile(r"^(?P<base>.*?)[\s_]+hz$", re.IGNORECASE)
_INTEGER = re.compile(r"^[+-]?\d+$")


@dataclass(frozen=True)
class ReadOptions:
    """The keyword options of every reader (each reader takes the ones its format needs).

    Attributes
    ----------
    points : list, optional
        Point labels in the file's order (FRFs or response channels), replacing its own.
    drive_point : label, optional
        The point where the force acts; replaces what the file says.
    response_quantity, frf_type, response_units, force_units : str, optional
        As for :func:`ami_xr.make_frf_dataset`; a value given wins over the file's.
    force_channel : int, str or list, optional
        Time histories: the force channel(s), by index (0 = first) or name; several (a list,
        or names separated by commas) make a multi-reference time Dataset.
    fs : float, optional
        Time tables without a time column: the sampling rate in Hz.
    sensitivity : dict, optional
        Time histories recorded in volts: ``{channel: V per unit}``; the channel's samples are
        divided by it (see :func:`ami_xr.make_time_dataset`).
    """

    points: list | None = None
    drive_point: Any = None
    response_quantity: str | None = None
    frf_type: str | None = None
    response_units: str | None = None
    force_units: str | None = None
    force_channel: Any = None
    fs: float | None = None
    sensitivity: dict | None = None

    @classmethod
    def of(cls, options: dict[str, Any], reader: str, accepts: Sequence[str]) -> ReadOptions:
        """The options of a reader call; a keyword the reader does not take is refused.

        Raises
        ------
        AmiXrValueError
            A keyword that is no option, or one ``reader`` does not take (given, not None).
        """
        known = {f.name for f in dataclasses.fields(cls)}
        for key, value in options.items():
            if key not in known:
                raise AmiXrValueError(
                    f"{key}: not an option of {reader}; expected one of {sorted(accepts)}"
                )
            if value is not None and key not in accepts:
                raise AmiXrValueError(
                    f"{key}: not taken by {reader} (it takes {', '.join(accepts)})"
                )
        return cls(**options)

    def given(self) -> dict[str, Any]:
        """The options given (not None), by name."""
        return {k: v for k, v in dataclasses.asdict(self).items() if v is not None}


#: Words in a channel name that make it the force channel when no unit tells (the second rule of
#: :func:`force_channels`).
FORCE_WORDS = ("force", "hammer")
#: The six metadata keywords: what a file says about the test, and what a caller may say instead.
OPTION_KEYS = ("points", *METADATA_KEYS)
#: The options of the time readers (LabVIEW, MATLAB and text time histories).
TIME_OPTION_KEYS = (*OPTION_KEYS, "force_channel", "fs", "sensitivity")


def split_unit(name: str) -> tuple[str, str]:
    """``(base, unit)`` of a column or variable name: ``"freq [Hz]"`` -> ``("freq", "Hz")``,
    ``"frequency_hz"`` -> ``("frequency", "Hz")``, ``"p1_re"`` -> ``("p1_re", "")``."""
    text = name.strip()
    for form in _UNITS:
        match = form.match(text)
        if match:
            return match["base"].strip(), match["unit"].strip()
    match = _HZ.match(text)
    if match and match["base"]:
        return match["base"].strip(), "Hz"
    return text, ""


def is_frequency_name(name: str) -> bool:
    """A frequency column or variable name (:data:`FREQUENCY_NAMES`, any unit)."""
    return split_unit(name)[0].lower() in FREQUENCY_NAMES


def point_labels(texts: Sequence[str]) -> list:
    """Point labels from a file's texts: integers when every one is a whole number, else the
    stripped texts."""
    stripped = [str(t).strip() for t in texts]
    if stripped and all(_INTEGER.match(t) for t in stripped):
        return [int(t) for t in stripped]
    return stripped


def frf_units_of(unit: str, where: str, path: Path) -> tuple[str, str]:
    """``(response_units, force_units)`` of an FRF unit such as ``"m/s^2/N"``, ``"m/s²/N"`` or
    ``"(1/N)*(g)"`` (the spellings of :mod:`ami_xr.io.units`).

    Raises
    ------
    DataFileError
        ``unit`` is not ``<response units>/<force units>`` with units ami_xr knows.
    """
    found = frf_unit(unit)
    if found is None:
        known = [u for units in names.RESPONSE_UNITS.values() for u in units]
        raise DataFileError(
            f"{path}: {where}: FRF unit {unit!r} not understood; expected <response>/<force> "
            f"with a response unit of {known} and a force unit of {list(names.FORCE_UNITS)} "
            "(e.g. 'm/s^2/N')"
        )
    return found


def force_channels(
    force_channel: Any, titles: Sequence[Any], units: Sequence[str], path: Path
) -> list[int]:
    """Indices of the force channel(s) among ``titles``: as given (an index or a name, a list of
    them, or names separated by commas), else the one channel with a force unit, else the one
    whose name contains "force" or "hammer" (:data:`FORCE_WORDS`).

    Raises
    ------
    AmiXrValueError
        A channel given that is none of ``titles``, or none given and the rules find no single
        force channel (the message names the titles and units).
    """
    n = len(titles)
    shown = [str(t) for t in titles]
    if force_channel is None:
        rules = (
            lambda c: force_unit(units[c]) is not None,
            lambda c: any(word in shown[c].lower() for word in FORCE_WORDS),
        )
        for test in rules:
            hits = [c for c in range(n) if test(c)]
            if len(hits) == 1:
                return hits
        raise AmiXrValueError(
            f"force_channel: cannot tell the force channel of {path.name} from the channel names "
            f"{shown} and units {list(units)}; give force_channel (index or name; ami-xr frf "
            "--force-channel)"
        )
    wanted = force_channel
    if isinstance(wanted, str) and "," in wanted and wanted not in shown:
        wanted = [w.strip() for w in wanted.split(",")]
    out = []
    for one in wanted if isinstance(wanted, (list, tuple)) else [wanted]:
        if isinstance(one, (int, np.integer)) and not isinstance(one, bool) and 0 <= one < n:
            out.append(int(one))
        elif str(one).strip() in shown:
            out.append(shown.index(str(one).strip()))
        else:
            raise AmiXrValueError(
                f"force_channel: expected a channel index 0..{n - 1} or one of {shown}, got "
                f"{one!r} ({path.name})"
            )
    if len(set(out)) != len(out):
        raise AmiXrValueError(f"force_channel: a channel given twice in {force_channel!r}")
    return out


def matching_label(value: Any, labels: list, where: str, path: Path | str) -> Any:
    """The point label ``value`` names (compared as text: ``"3"`` names point 3).

    Raises
    ------
    AmiXrValueError
        ``value`` names none of ``labels``: a :class:`DataFileError` when the file said it
        (``where`` other than ``"given"``).
    """
    if value in labels:
        return value
    hits = [label for label in labels if str(label) == str(value).strip()]
    if hits:
        return hits[0]
    if where == "given":  # the caller's argument: name it, as every argument error does
        name = getattr(path, "name", path)
        raise AmiXrValueError(
            f"drive_point: {value!r} is not one of the points {labels!r} of {name}"
        )
    raise DataFileError(
        f"{path}: drive_point ({where}): {value!r} is not one of the points {labels}"
    )


def _assume(path: Path, what: str, how: str) -> str:
    """Warn (at the user's line) that ``what`` was assumed; return the record's text."""
    warn(f"{path.name}: {what}; {how}", AssumptionWarning)
    return what


@dataclass
class _Settled:
    """What the file said and the options gave, settled: labels, drive point, quantity, units
    and the attributes that record an assumption."""

    labels: list | None
    drive: Any
    quantity: str
    units: str
    force_units: str
    attrs: dict[str, Any]


def _normal_units(options: dict[str, Any]) -> None:
    """Unit texts through the one unit parser (``"m/s²"`` is ``"m/s^2"``); what it does not
    know is left for the data-model check to name."""
    for key, parse in (("response_units", response_unit), ("force_units", force_unit)):
        if isinstance(options.get(key), str):
            options[key] = parse(options[key]) or options[key]


def _settle(
    path: Path,
    n_point: int,
    labels: list | None,
    said: dict[str, Any],
    options: ReadOptions,
    how: str,
    single: tuple[str, str],
) -> _Settled:
    """Labels, drive point, quantity and units from the file (``said``) and ``options`` (which
    win); ``single`` is what a one-point file's drive point assumption records and says."""
    if options.points is not None:
        labels = list(options.points)
        if len(labels) != n_point:
            raise AmiXrValueError(
                f"points: expected {n_point} labels (the {single[1]}s of {path.name}), got "
                f"{len(labels)}"
            )
    if labels is not None and len(set(map(str, labels))) != len(labels):
        raise DataFileError(f"{path}: the point labels {labels} repeat; expected unique labels")
    given = options.given()
    merged = {k: v for k, v in said.items() if v is not None}
    merged.update({k: given[k] for k in METADATA_KEYS if k in given})
    _normal_units(merged)
    attrs: dict[str, Any] = {}
    shown = labels if labels is not None else list(range(n_point))
    drive = merged.get("drive_point")
    if drive is not None:
        where = "given" if options.drive_point is not None else "from the file"
        drive = matching_label(drive, shown, where, path)
    elif n_point == 1:
        drive = shown[0]
        what = f"drive point assumed to be {drive!r} (the single {single[1]})"
        _assume(path, what, how.format("drive_point"))
        attrs[names.ATTR_DRIVE_POINT_ASSUMED] = single[0] or what
    try:
        quantity, units, assumed = resolve_quantity(
            merged.get("response_quantity"), merged.get("frf_type"), merged.get("response_units")
        )
    except AmiXrValueError as err:
        raise DataFileError(f"{path}: {err}") from None
    force_units = merged.get("force_units", "N")
    if assumed is not None:
        attrs[ATTR_QUANTITY_ASSUMED] = _assume(
            path,
            f"no response quantity, FRF type or units given: receptance in {units}/{force_units} "
            "assumed",
            how.format("response_quantity"),
        )
    return _Settled(labels, drive, quantity, units, force_units, attrs)


def _built(path: Path, build: Any, record: dict[str, Any], function: str) -> xr.Dataset:
    """``build()`` (a constructor call) with its errors naming ``path``, and its record."""
    try:
        ds = build()
    except SchemaError as err:
        raise SchemaError(err.problems, what=f"{path}: the data read") from None
    except AmiXrValueError as err:
        raise DataFileError(f"{path}: {err}") from None
    return add_history(ds, function, record, source_file=path)


def frf_dataset(
    path: Path,
    frf: np.ndarray,
    frequency: np.ndarray,
    labels: list | None,
    said: dict[str, Any],
    options: ReadOptions,
    how: str,
    record: dict[str, Any],
    extra_attrs: dict[str, Any] | None = None,
) -> xr.Dataset:
    """The FRF Dataset of a table file, validated by :func:`ami_xr.make_frf_dataset`.

    Parameters
    ----------
    path : pathlib.Path
        The file, named in every message.
    frf : ndarray of complex, shape (n_point, n_frequency)
    frequency : ndarray of float, shape (n_frequency,)
        In Hz.
    labels : list or None
        Point labels read from the file; None for ``0 .. n_point - 1``.
    said : dict
        What the file says (keys of :data:`METADATA_KEYS`).
    options : ReadOptions
        The reader's options; a value given wins over the file's.
    how : str
        How a user says in this format what was assumed (for the warnings).
    record : dict
        Parameters of the provenance record (format, layout, columns or variables read).
    extra_attrs : dict, optional
        Further attributes, e.g. an assumption about the layout.

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    DataFileError
        Labels that do not fit, a drive point that is not a point, bad units.
    SchemaError
        What the data-model check finds, each problem named, with the file.
    """
    from ami_xr.io.datasets import make_frf_dataset

    got = _settle(path, frf.shape[0], labels, said, options, how, ("", "FRF"))

    def build() -> xr.Dataset:
        return make_frf_dataset(
            frf,
            frequency,
            points=got.labels,
            drive_point=got.drive,
            response_quantity=got.quantity,
            response_units=got.units,
            force_units=got.force_units,
            **{**(extra_attrs or {}), **got.attrs},
        )

    return _built(path, build, record, FUNCTION)


def _sensitivity_keys(
    sensitivity: dict | None, forces: list, labels: list | None, path: Path
) -> dict | None:
    """``{channel name: V per unit}`` as :func:`ami_xr.make_time_dataset` names channels: the
    one force is ``"force"``, several are references, responses are point labels."""
    if not sensitivity:
        return None
    out = {}
    points = list(labels or [])
    for name, volts in sensitivity.items():
        hits = [p for p in points if str(p) == str(name)]
        if len(forces) == 1 and str(name) == str(forces[0]):
            out["force"] = volts
        elif str(name) in map(str, forces):
            out[str(name)] = volts
        elif hits:
            out[hits[0]] = volts
        else:
            raise AmiXrValueError(
                f"sensitivity: {name!r} is no channel of {path.name}; expected one of "
                f"{[*map(str, forces), *map(str, points)]}"
            )
    return out


def time_dataset(
    path: Path,
    response: np.ndarray,
    force: np.ndarray,
    fs: float,
    labels: list | None,
    said: dict[str, Any],
    options: ReadOptions,
    how: str,
    record: dict[str, Any],
    channels: dict[str, Any],
) -> xr.Dataset:
    """The time Dataset of a file of channels, validated by :func:`ami_xr.make_time_dataset`.

    Parameters
    ----------
    path : pathlib.Path
        The file, named in every message.
    response : ndarray of float, shape ([n_record,] n_point, n_time)
    force : ndarray of float, shape ([n_record,] n_force, n_time)
        One force channel, or several (a multi-reference time Dataset).
    fs : float
        Sampling rate in Hz.
    labels : list or None
        Labels of the response channels; None for ``0 .. n_point - 1``.
    said, options, how, record
        As for :func:`frf_dataset`; ``options.sensitivity`` scales volt channels.
    channels : dict
        ``force_names`` (the force channels' names), optionally ``sensitivity`` (as
        :func:`ami_xr.make_time_dataset` takes it), ``function`` (the record's name) and
        ``coords`` (further coordinates, e.g. ``record_start``).

    Returns
    -------
    xarray.Dataset
        ``response``, ``force`` (``reference`` dim with several force channels), with the
        file's name in ``source_file``.
    """
    from ami_xr.io.datasets import make_time_dataset

    got = _settle(
        path,
        response.shape[-2],
        labels,
        said,
        options,
        how,
        ("the single response channel", "response channel"),
    )
    forces = list(channels["force_names"])
    one = len(forces) == 1
    sensitivity = _sensitivity_keys(channels.get("sensitivity"), forces, got.labels, path)

    def build() -> xr.Dataset:
        return make_time_dataset(
            response,
            fs=fs,
            force=force[..., 0, :] if one else force,
            references=None if one else forces,
            points=got.labels,
            drive_point=got.drive,
            response_quantity=got.quantity,
            response_units=got.units,
            force_units=got.force_units,
            sensitivity=sensitivity,
            **{names.ATTR_SOURCE_FILE: path.name, **got.attrs},
        )

    function = channels.get("function", "ami_xr.read_any")
    ds = _built(path, build, record, function)
    if one:
        ds[names.FORCE].attrs["channel"] = str(forces[0])
    return ds.assign_coords(channels.get("coords", {}))
