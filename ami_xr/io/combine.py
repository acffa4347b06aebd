"""One FRF set from the runs of a roving test: :func:`combine_runs`.

A test measured in runs arrives as one FRF Dataset (or file) per run:

* **roving response** (a shaker at one point, the accelerometers moved from run to run): every
  run shares the excitation (the ``drive_point`` attribute, or the ``reference`` labels of
  multi-reference runs) and measures other points; the set holds every run's points;
* **roving hammer** (one accelerometer, the hammer moved): every run shares its one response
  point and has its own excitation point. By Maxwell-Betti reciprocity (``H_rp = H_pr``) these
  FRFs are one column of the FRF matrix too: the set's points are the hammer positions and its
  drive point is the response point (as :func:`ami_xr.read_uff` reads a roving-hammer file).

What belongs to a point (``frf``, ``coherence``, ``response_autospectrum``,
``cross_spectrum``, ``frf_line_noise_std``, geometry coordinates) is concatenated along
``point``. What belongs to a run (``force_autospectrum``: each run had its own force) gets a
``run`` dimension; per-hit variables (``record``) are concatenated along ``record`` with the
``record_run`` coordinate. The coordinate ``point_run`` says which run each point came from.
Attributes every run agrees on are kept; those that differ go to the JSON attribute
``run_attributes`` (``{attribute: {run: value}}``); each run's provenance goes to
``run_history``. The frequency lines, response quantity, units and exponential window must be
the same in every run, and the drive point (reference) must agree: else a
:class:`RunMismatchError` (a ``ValueError``) names the run and what differs.
"""

from __future__ import annotations

import json
import os
from collections.abc import Hashable, Sequence
from typing import Any

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.caller import warn
from ami_xr.errors import AmiXrValueError, AssumptionWarning
from ami_xr.io.messages import python_scalar
from ami_xr.provenance import add_history, file_name, history, public_call

__all__ = [
    "LAYOUT_HAMMER",
    "LAYOUT_RESPONSE",
    "RUN",
    "RunMismatchError",
    "combine_runs",
]

#: Dimension of what each run measured once (its force autospectrum).
RUN = "run"
#: Coordinate on ``point``: the run each point came from.
POINT_RUN = "point_run"
#: Coordinate on ``record``: the run each hit (record) came from.
RECORD_RUN = "record_run"
#: Attribute: ``{attribute: {run: value}}`` (JSON) of the attributes that differ between runs.
ATTR_RUN_ATTRIBUTES = "run_attributes"
#: Variable (run,): each run's provenance (its ``ami_xr_history``, JSON text).
RUN_HISTORY = "run_history"
#: Attribute: which layout was combined (one sentence).
ATTR_LAYOUT = "combine_layout"
#: Attribute: runs that did not state their drive point and took the set's (comma-separated).
ATTR_DRIVE_ASSUMED = "combine_drive_point_assumed"
#: Attributes of :func:`ami_xr.frf` naming the lines without an estimate (the union is kept).
ATTR_UNDEFINED_LINES = "frf_undefined_frequencies"
ATTR_UNDEFINED_REASON = "frf_undefined_reason"
LAYOUT_RESPONSE = "roving_response"
LAYOUT_HAMMER = "roving_hammer"
LAYOUTS = ("auto", LAYOUT_RESPONSE, LAYOUT_HAMMER)
_LAYOUT_TEXT = {
    LAYOUT_RESPONSE: "roving response: the runs share the excitation; points are every run's "
    "response points",
    LAYOUT_HAMMER: "roving hammer: the runs share one response point; by reciprocity the points "
    "are the runs' excitation points and the drive point is the response point",
}
#: Attributes that must be equal in every run (the FRFs are otherwise not one set).
MUST_AGREE = (
    names.ATTR_QUANTITY,
    names.ATTR_FRF_TYPE,
    names.ATTR_RESPONSE_UNITS,
    names.ATTR_FORCE_UNITS,
    names.ATTR_EXP_DECAY,
    names.ATTR_EXP_CORRECTED,
    names.ATTR_DT,
    names.ATTR_NSAMPLES,
)
#: Attributes not merged: provenance is rebuilt, the drive point decided here.
_NOT_MERGED = (
    names.ATTR_HISTORY,
    names.ATTR_VERSION,
    names.ATTR_FUNCTION,
    names.ATTR_DRIVE_POINT,
    names.ATTR_DRIVE_POINT_ASSUMED,
    "history",
)


class RunMismatchError(AmiXrValueError):
    """The runs given to :func:`combine_runs` are not parts of one FRF set; the message names the
    run and what differs."""


def _open(part: Any, i: int) -> tuple[xr.Dataset, str | None]:
    if isinstance(part, xr.Dataset):
        return part, None
    if isinstance(part, (str, os.PathLike)):
        from ami_xr.io.formats import open_frf

        return open_frf(part), file_name(part)
    raise AmiXrValueError(
        f"parts[{i}]: expected an FRF Dataset or a file path, got {type(part).__name__}"
    )


def _labels(parts: list[xr.Dataset], files: list[str | None], run_labels) -> list[str]:
    if run_labels is not None:
        labels = [str(x) for x in run_labels]
        if len(labels) != len(parts):
            raise AmiXrValueError(
                f"run_labels: expected {len(parts)} labels (one per part), got {len(labels)}"
            )
    else:
        labels = [
            f or str(ds.attrs.get(names.ATTR_SOURCE_FILE) or f"run{i}")
            for i, (ds, f) in enumerate(zip(parts, files, strict=True))
        ]
        if len(set(labels)) != len(labels):  # same source file names: number them
            labels = [f"run{i}" for i in range(len(parts))]
    if len(set(labels)) != len(labels):
        raise AmiXrValueError(f"run_labels: expected unique labels, got {labels}")
    return labels


def _plain(value: Any) -> Any:
    """An attribute value as JSON data (numpy scalars and arrays as Python ones; an absolute
    path, e.g. the ``source_file`` :func:`ami_xr.open_dataset` keeps in memory, as its file
    name: no machine path goes into a file)."""
    if isinstance(value, str) and os.path.isabs(value):
        return file_name(value)
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()] if value.dtype.kind != "c" else repr(value)
    if isinstance(value, complex):
        return [value.real, value.imag]
    return value if isinstance(value, (str, int, float, bool, list, dict)) or value is None else (
        repr(value)
    )


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))
    except (TypeError, ValueError):
        return a == b


def _label_equal(a: Any, b: Any) -> bool:
    return a == b or str(a) == str(b)


def _check_one(ds: xr.Dataset, run: str, first: xr.Dataset, first_run: str) -> None:
    """The run's frequency lines, FRF layout and the attributes of :data:`MUST_AGREE` equal the
    first run's."""
    if names.FRF not in ds or names.POINT not in ds[names.FRF].dims:
        raise RunMismatchError(
            f"run {run!r}: expected an FRF Dataset (variable 'frf' with a 'point' dim)"
        )
    f, f0 = ds[names.FREQUENCY].values, first[names.FREQUENCY].values
    if f.shape != f0.shape or not np.allclose(f, f0, rtol=1e-9, atol=0.0):
        raise RunMismatchError(
            f"run {run!r}: frequency lines ({f.size} from {f[0]:g} to {f[-1]:g} Hz) differ from "
            f"run {first_run!r}'s ({f0.size} from {f0[0]:g} to {f0[-1]:g} Hz); expected the same "
            "lines in every run"
        )
    ref, ref0 = (d[names.FRF].sizes.get(names.REFERENCE) for d in (ds, first))
    if (ref is None) != (ref0 is None) or (
        ref is not None
        and not _same(ds[names.REFERENCE].values, first[names.REFERENCE].values)
    ):
        raise RunMismatchError(
            f"run {run!r}: references {_refs(ds)} differ from run {first_run!r}'s "
            f"{_refs(first)}; expected the same excitation in every run"
        )
    for attr in MUST_AGREE:
        a, b = ds.attrs.get(attr), first.attrs.get(attr)
        if not _same(a, b):
            raise RunMismatchError(
                f"run {run!r}: attribute {attr!r} is {a!r}, run {first_run!r} has {b!r}; "
                "expected the same in every run"
            )
    unit, unit0 = (d[names.FRF].attrs.get(names.ATTR_UNITS) for d in (ds, first))
    if unit != unit0:
        raise RunMismatchError(
            f"run {run!r}: frf units {unit!r}, run {first_run!r} has {unit0!r}; expected the "
            "same in every run"
        )


def _refs(ds: xr.Dataset) -> Any:
    return list(ds[names.REFERENCE].values) if names.REFERENCE in ds[names.FRF].dims else None


def _layout(parts: list[xr.Dataset], layout: str) -> str:
    if layout not in LAYOUTS:
        raise AmiXrValueError(f"layout: expected one of {LAYOUTS}, got {layout!r}")
    if layout != "auto":
        return layout
    points = [list(ds[names.POINT].values) for ds in parts]
    drives = [ds.attrs.get(names.ATTR_DRIVE_POINT) for ds in parts]
    one_point = all(len(p) == 1 for p in points) and len({str(p[0]) for p in points}) == 1
    distinct = len({str(d) for d in drives}) == len(parts) and None not in drives
    if len(parts) > 1 and one_point and distinct and _refs(parts[0]) is None:
        return LAYOUT_HAMMER
    return LAYOUT_RESPONSE


def _excitation(
    parts: list[xr.Dataset], runs: list[str], drive_point: Any
) -> tuple[Any, list[str]]:
    """The drive point the runs share (roving response) and the runs that did not state it."""
    if _refs(parts[0]) is not None:  # multi-reference: the reference labels were checked
        return None, []
    stated = [
        (r, ds.attrs[names.ATTR_DRIVE_POINT])
        for r, ds in zip(runs, parts, strict=True)
        if ds.attrs.get(names.ATTR_DRIVE_POINT) is not None
    ]
    origin = "the drive_point argument"
    if drive_point is None and stated:
        origin, drive_point = f"run {stated[0][0]!r}", python_scalar(stated[0][1])
    for run, d in stated:
        d = python_scalar(d)
        if not _label_equal(d, drive_point):
            raise RunMismatchError(
                f"run {run!r}: drive point {d!r}, but {origin} has {drive_point!r}; a roving-"
                "response test keeps the excitation at one point (for a roving hammer give "
                "layout='roving_hammer')"
            )
    missing = [
        r for r, ds in zip(runs, parts, strict=True) if ds.attrs.get(names.ATTR_DRIVE_POINT) is None
    ]
    return drive_point, missing if drive_point is not None else []


def _hammer(parts: list[xr.Dataset], runs: list[str], drive_point: Any) -> tuple[list, Any]:
    """Roving hammer: each run relabelled to its excitation point; the shared response point."""
    response = None
    out = []
    for run, ds in zip(runs, parts, strict=True):
        pts = [python_scalar(p) for p in ds[names.POINT].values]
        if len(pts) != 1 or _refs(ds) is not None:
            raise RunMismatchError(
                f"run {run!r}: {len(pts)} response point(s) {pts}; a roving-hammer run has one "
                "response point and one excitation (drive_point)"
            )
        if response is None:
            response = pts[0] if drive_point is None else drive_point
        if not _label_equal(pts[0], response):
            raise RunMismatchError(
                f"run {run!r}: response point {pts[0]!r}, but the set's is {response!r}; a "
                "roving-hammer test keeps the response at one point"
            )
        hit = ds.attrs.get(names.ATTR_DRIVE_POINT)
        if hit is None:
            raise RunMismatchError(
                f"run {run!r}: no drive_point attribute; a roving-hammer run must say where the "
                "hammer hit"
            )
        # the run's geometry is the sensor's place, not the hammer's: not carried over
        where = [c for c in ds.coords if c != names.POINT and names.POINT in ds[c].dims]
        out.append(ds.drop_vars(where).assign_coords({names.POINT: [hit]}))
    return out, response


def _merge_attrs(parts: list[xr.Dataset], runs: list[str]) -> tuple[dict, dict]:
    keys: list[str] = []
    for ds in parts:
        keys += [k for k in ds.attrs if k not in keys and k not in _NOT_MERGED]
    common, differ = {}, {}
    for k in keys:
        values = [ds.attrs.get(k) for ds in parts]
        if all(k in ds.attrs for ds in parts) and all(_same(v, values[0]) for v in values):
            common[k] = values[0]
        else:
            differ[k] = {r: _plain(v) for r, v in zip(runs, values, strict=True)}
    lines = [(r, ds.attrs.get(ATTR_UNDEFINED_LINES)) for r, ds in zip(runs, parts, strict=True)]
    lines = [(r, np.atleast_1d(v)) for r, v in lines if v is not None and np.size(v)]
    if lines:  # a line without an estimate in any run has none in the set
        common[ATTR_UNDEFINED_LINES] = np.unique(np.concatenate([v for _, v in lines]))
        common[ATTR_UNDEFINED_REASON] = "; ".join(
            f"run {r}: {parts[runs.index(r)].attrs.get(ATTR_UNDEFINED_REASON, '')}"
            for r, _ in lines
        )
        for k in (ATTR_UNDEFINED_LINES, ATTR_UNDEFINED_REASON):
            differ.pop(k, None)
    return common, differ


def _per_point(parts: list[xr.Dataset], runs: list[str], name: str) -> xr.DataArray | None:
    arrays = [ds[name] for ds in parts if name in ds.variables]
    if len(arrays) != len(parts):
        return None
    return xr.concat(arrays, dim=names.POINT, join="override", combine_attrs="override")


def _per_run(parts: list[xr.Dataset], runs: list[str], name: str) -> xr.DataArray | None:
    arrays = [ds[name] for ds in parts if name in ds.data_vars]
    if len(arrays) != len(parts) or len({a.dims for a in arrays}) != 1:
        return None
    stacked = [a.expand_dims({RUN: [r]}) for a, r in zip(arrays, runs, strict=True)]
    dim = names.RECORD if names.RECORD in arrays[0].dims else RUN
    if dim == names.RECORD:  # hits: one list, each record with its run
        stacked = [
            a.drop_vars(names.RECORD, errors="ignore").assign_coords(
                {RECORD_RUN: (names.RECORD, [r] * a.sizes[names.RECORD])}
            )
            for a, r in zip(arrays, runs, strict=True)
        ]
    return xr.concat(stacked, dim=dim, join="override", combine_attrs="override")


@public_call
def combine_runs(
    parts: Sequence[xr.Dataset | str | os.PathLike],
    *,
    drive_point: Hashable | None = None,
    layout: str = "auto",
    run_labels: Sequence[Hashable] | None = None,
) -> xr.Dataset:
    """One FRF set from the runs of a roving test (see the module docstring).

    Parameters
    ----------
    parts : sequence of xarray.Dataset or path-like
        The runs' FRF Datasets (or files :func:`ami_xr.open_frf` reads), in the order their
        points are to appear. At least one.
    drive_point : label, optional
        Roving response: where the shaker acts, for runs that do not state it (a run without
        the drive point among its points has no ``drive_point`` attribute when it was made by
        :func:`ami_xr.frf`); runs that state one must agree. Default: the drive point the runs
        state (runs without one take it, with an :class:`~ami_xr.errors.AssumptionWarning`
        and the attribute ``combine_drive_point_assumed``). Roving hammer: the response point
        (default: the runs' one point).
    layout : {"auto", "roving_response", "roving_hammer"}
        ``"auto"``: a roving hammer when every run has the same single response point and the
        runs' drive points all differ, else a roving response.
    run_labels : sequence, optional
        A label per run (default: the file name of a path, else the Dataset's ``source_file``,
        else ``run0``, ``run1``, ...).

    Returns
    -------
    xarray.Dataset
        An FRF Dataset (validated; the drive point may be an unmeasured point), with
        ``point_run`` (point), a ``run`` dim for per-run variables (``force_autospectrum``
        (run, [reference,] frequency), ``run_history`` (run)), ``record_run`` (record) for
        hit variables, the attributes ``combine_layout`` and ``run_attributes``.

    Raises
    ------
    RunMismatchError
        Naming the run: another frequency grid, quantity, units, exponential window or
        references; a drive point (roving response) or response point (roving hammer) that
        disagrees; a point measured in two runs.
    AmiXrValueError
        ``parts`` empty or not Datasets/paths; bad ``layout`` or ``run_labels``.
    """
    if isinstance(parts, (str, os.PathLike, xr.Dataset)) or not len(parts):
        raise AmiXrValueError("parts: expected a non-empty sequence of FRF Datasets or files")
    opened = [_open(p, i) for i, p in enumerate(parts)]
    datasets = [ds for ds, _ in opened]
    runs = _labels(datasets, [f for _, f in opened], run_labels)
    for run, ds in zip(runs, datasets, strict=True):
        _check_one(ds, run, datasets[0], runs[0])
    kind = _layout(datasets, layout)
    if drive_point is not None:
        drive_point = python_scalar(drive_point)
    assumed: list[str] = []
    if kind == LAYOUT_HAMMER:
        datasets, drive = _hammer(datasets, runs, drive_point)
    else:
        drive, assumed = _excitation(datasets, runs, drive_point)
    seen: dict[str, str] = {}
    for run, ds in zip(runs, datasets, strict=True):
        for p in map(python_scalar, ds[names.POINT].values):
            if str(p) in seen:
                raise RunMismatchError(
                    f"run {run!r}: point {p!r} was measured in run {seen[str(p)]!r} too; expected "
                    "each point in one run (select one of them with ds.drop_sel(point=...))"
                )
            seen[str(p)] = run
    f0 = datasets[0][names.FREQUENCY]
    datasets = [ds.assign_coords({names.FREQUENCY: f0}) for ds in datasets]
    data_vars, dropped = {}, []
    for name in dict.fromkeys(n for ds in datasets for n in ds.data_vars):
        with_point = names.POINT in datasets[0][name].dims if name in datasets[0] else False
        da = (_per_point if with_point else _per_run)(datasets, runs, name)
        if da is None:
            dropped.append(name)
        else:
            data_vars[name] = da
    out = xr.Dataset(data_vars)
    for coord in dict.fromkeys(c for ds in datasets for c in ds.coords):
        if coord not in out.coords and all(coord in ds.coords for ds in datasets):
            if names.POINT in datasets[0][coord].dims and coord != names.POINT:
                out = out.assign_coords({coord: _per_point(datasets, runs, coord)})
    point_runs = [r for r, ds in zip(runs, datasets, strict=True) for _ in ds[names.POINT].values]
    out = out.assign_coords({POINT_RUN: (names.POINT, point_runs), RUN: runs})
    out[RUN_HISTORY] = (RUN, [json.dumps(history(ds)) for ds in datasets])
    common, differ = _merge_attrs(datasets, runs)
    out.attrs = common
    if differ:
        out.attrs[ATTR_RUN_ATTRIBUTES] = json.dumps(differ)
    out.attrs[ATTR_LAYOUT] = _LAYOUT_TEXT[kind]
    if drive is not None:
        out.attrs[names.ATTR_DRIVE_POINT] = drive
    if assumed and len(assumed) < len(runs) and drive_point is None:
        out.attrs[ATTR_DRIVE_ASSUMED] = ",".join(assumed)
        warn(
            f"combine_runs: run(s) {', '.join(assumed)} state no drive point; taken as "
            f"{drive!r}, the other runs' (pass drive_point= to say so)",
            AssumptionWarning,
        )
    if dropped:
        warn(
            f"combine_runs: variable(s) {', '.join(dropped)} not in every run (or with other "
            "dims): left out of the set",
            AssumptionWarning,
        )
    from ami_xr.schema import validate

    points = list(out[names.POINT].values)
    # NaN lines a run's estimate recorded (frf_undefined_frequencies) are allowed, as in the runs
    validate(
        out,
        require_drive_point=drive is not None and drive in points,
        check_values=ATTR_UNDEFINED_LINES not in out.attrs,
    )
    params = {"runs": runs, "layout": kind, "drive_point": drive}
    return add_history(out, "ami_xr.combine_runs", params)
