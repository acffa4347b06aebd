"""FRF tables in MATLAB files (``.mat``): v4 to v7 through :func:`scipy.io.loadmat`, v7.3 (HDF5)
through ``h5py`` when it is installed (``pip install "ami_xr[matlab]"``).

The file's variables (or the fields of its one struct) are read into a dict of plain values
(arrays, strings, lists, dicts) by either loader; the FRFs are then found by name
(:data:`FRF_NAMES`, :data:`~.build.FREQUENCY_NAMES`, :data:`POINT_NAMES`) in that dict.
"""

from __future__ import annotations

import os
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

__all__ = [
    "read_frf_mat",
    "load_variables",
    "describe_variables",
    "text_list",
    "FRF_NAMES",
    "POINT_NAMES",
    "V73_NEEDS_H5PY",
]

#: Names (case-insensitive) of the FRF matrix variable.
FRF_NAMES = ("frf", "h")
#: Names (case-insensitive) of the optional point-label variable.
POINT_NAMES = ("points", "labels", "point_labels")
#: Names (case-insensitive) of an optional FRF-unit variable such as ``"m/s^2/N"``.
UNIT_NAMES = ("frf_units", "units")
V73_NEEDS_H5PY = (
    "a MATLAB v7.3 (HDF5) file: reading it needs h5py (pip install 'ami_xr[matlab]'), or save "
    "it again as v7 in MATLAB: save(name, ..., '-v7')"
)
HOW = "say it with a variable {0} in the file, or pass {0}= to ami_xr.open_frf"
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_LOADER_NAMES = ("__header__", "__version__", "__globals__")


def _is_v73(path: Path) -> bool:
    with open(path, "rb") as f:
        head = f.read(520)
    return head.startswith(b"MATLAB 7.3") or _HDF5_SIGNATURE in (head[:8], head[512:520])


def _load_v5(path: Path) -> dict[str, Any]:
    import scipy.io

    try:
        found = scipy.io.loadmat(path, simplify_cells=True)
    except NotImplementedError:  # v7.3 without the usual header
        raise DataFileError(f"{path}: {V73_NEEDS_H5PY}") from None
    except Exception as err:  # scipy raises ValueError, TypeError or MatReadError by case
        raise DataFileError(
            f"{path}: not a MATLAB file scipy.io.loadmat can read ({type(err).__name__}: {err})"
        ) from None
    return {k: v for k, v in found.items() if k not in _LOADER_NAMES}


def _load_v73(path: Path) -> dict[str, Any]:
    try:
        import h5py
    except ImportError:
        raise DataFileError(f"{path}: {V73_NEEDS_H5PY}") from None
    try:
        with h5py.File(path, "r") as f:
            return {k: _h5_value(f, f[k]) for k in f if not k.startswith("#")}
    except OSError as err:
        raise DataFileError(f"{path}: an HDF5 (MATLAB v7.3) file h5py cannot read: {err}") from None


def _h5_value(f: Any, obj: Any) -> Any:
    """A v7.3 variable as :func:`scipy.io.loadmat` (``simplify_cells=True``) gives it: MATLAB
    stores arrays column-major (h5py sees them transposed), complex numbers as (real, imag)
    pairs, text as UTF-16 codes and cells as references."""
    if not hasattr(obj, "dtype"):  # a group: a struct
        return {k: _h5_value(f, obj[k]) for k in obj if not k.startswith("#")}
    kind = obj.attrs.get("MATLAB_class", b"")
    kind = kind.decode() if isinstance(kind, bytes) else str(kind)
    if obj.attrs.get("MATLAB_empty", 0):
        return np.zeros(0)
    data = obj[()]
    if kind == "cell":
        items = [_h5_value(f, f[ref]) for ref in np.asarray(data).T.ravel()]
        return items[0] if len(items) == 1 else items
    data = np.asarray(data)
    if data.dtype.names and {"real", "imag"} <= set(data.dtype.names):
        data = data["real"] + 1j * data["imag"]
    data = data.T
    if kind == "char":
        rows = ["".join(map(chr, row)) for row in np.atleast_2d(data)]
        return rows[0] if len(rows) == 1 else np.array(rows)
    data = np.squeeze(data)
    return data[()] if data.ndim == 0 else data


def load_variables(path: Path) -> tuple[dict[str, Any], bool]:
    """The variables of a ``.mat`` file as plain values (either loader), and whether it is v7.3.

    Raises
    ------
    DataFileError
        Not a MATLAB file, or a v7.3 file without ``h5py``.
    """
    v73 = _is_v73(path)
    return (_load_v73(path) if v73 else _load_v5(path)), v73


def _lookup(scope: dict[str, Any], wanted: tuple[str, ...], test=None) -> str | None:
    """The key of ``scope`` named one of ``wanted`` (case-insensitive) or passing ``test``."""
    hits = [k for k in scope if k.lower() in wanted or (test is not None and test(k))]
    return hits[0] if hits else None


def _describe(scope: dict[str, Any]) -> str:
    parts = []
    for k, v in scope.items():
        shape = getattr(v, "shape", None)
        kind = "struct" if isinstance(v, dict) else type(v).__name__
        parts.append(f"{k} {shape}" if shape is not None else f"{k} ({kind})")
    return ", ".join(parts) or "none"


def describe_variables(scope: dict[str, Any]) -> str:
    """``"name (shape), ..."`` of the variables found, for a message."""
    return _describe(scope)


def text_list(value: Any) -> list:
    """A cell array of text or numbers (or one text) as a list (whole numbers as int)."""
    return _text_list(value)


def _scope(variables: dict[str, Any], path: Path) -> tuple[dict[str, Any], str]:
    """Where the FRFs are: the file's variables, or the fields of its one struct."""
    if _lookup(variables, FREQUENCY_NAMES, is_frequency_name) or _lookup(variables, FRF_NAMES):
        return variables, "the file"
    structs = [k for k, v in variables.items() if isinstance(v, dict)]
    if len(structs) == 1:
        return variables[structs[0]], f"struct {structs[0]!r}"
    return variables, "the file"


def _frequency(value: Any, name: str, path: Path) -> np.ndarray:
    freq = np.squeeze(np.asarray(value))
    if freq.ndim != 1 or freq.size < 2 or not np.issubdtype(freq.dtype, np.number):
        raise DataFileError(
            f"{path}: variable {name!r}: expected a vector of frequencies in Hz, got {_what(freq)}"
        )
    if np.iscomplexobj(freq) or split_unit(name)[1].lower() not in ("", "hz"):
        raise DataFileError(f"{path}: variable {name!r}: expected real frequencies in Hz")
    return freq.astype(np.float64)


def _what(arr: np.ndarray) -> str:
    return f"shape {arr.shape}, dtype {arr.dtype}"


def _frf(value: Any, name: str, n_line: int, path: Path) -> tuple[np.ndarray, str]:
    """(FRFs (point, line), orientation read) from a points x lines or lines x points matrix."""
    frf = np.asarray(value)
    if not np.issubdtype(frf.dtype, np.number) or frf.ndim not in (1, 2):
        raise DataFileError(
            f"{path}: variable {name!r}: expected a complex matrix of FRFs (points x lines or "
            f"lines x points), got {_what(frf)}"
        )
    if not np.iscomplexobj(frf):
        raise DataFileError(
            f"{path}: variable {name!r}: real values; expected complex FRFs (in MATLAB "
            "complex(re, im) or mag .* exp(1i * phase))"
        )
    if frf.ndim == 1:
        frf = frf[None, :]
    rows, cols = frf.shape
    if n_line not in (rows, cols):
        raise DataFileError(
            f"{path}: variable {name!r} has shape {frf.shape}; expected one axis of length "
            f"{n_line}, the number of frequencies"
        )
    if cols == n_line and rows != n_line:
        return frf.astype(np.complex128), "points x lines"
    if rows == cols:
        warn(
            f"{path.name}: variable {name!r} is square ({rows} x {cols}): read as lines x "
            "points (one column per FRF, as MATLAB stores channels)",
            AssumptionWarning,
        )
    return np.ascontiguousarray(frf.T, dtype=np.complex128), "lines x points"


def _text_list(value: Any) -> list:
    if isinstance(value, str):
        return [value]
    items = np.atleast_1d(np.squeeze(np.asarray(value, dtype=object)))
    out = []
    for item in items:
        if isinstance(item, (float, np.floating)) and float(item).is_integer():
            item = int(item)
        out.append(item if isinstance(item, (int, np.integer)) else str(item).strip())
    return out


def _said(scope: dict[str, Any], path: Path) -> dict[str, Any]:
    """What the file says about the test (:data:`METADATA_KEYS`, an FRF unit)."""
    said: dict[str, Any] = {}
    for key in METADATA_KEYS:
        name = _lookup(scope, (key,))
        if name is not None:
            value = _text_list(scope[name])
            if len(value) != 1:
                raise DataFileError(f"{path}: variable {name!r}: expected one value")
            said[key] = value[0]
    unit = _lookup(scope, UNIT_NAMES)
    if unit is not None:
        response, force = frf_units_of(str(scope[unit]), f"variable {unit!r}", path)
        said.setdefault("response_units", response)
        said.setdefault("force_units", force)
    return said


def read_frf_mat(path: str | os.PathLike, **options: Any) -> xr.Dataset:
    """Read FRFs from a MATLAB ``.mat`` file.

    The variables (names case-insensitive; or the fields of the file's one struct):

    * the frequency vector in Hz: ``frequency``, ``freq`` or ``f`` (required);
    * the complex FRF matrix: ``frf`` or ``H``, points x lines or lines x points (the axis
      whose length is the number of frequencies is the frequency axis; a square matrix is read
      as lines x points, with a warning) (required);
    * point labels: ``points``, ``labels`` or ``point_labels`` (a cell array of text or a
      numeric vector);
    * ``drive_point``, ``response_quantity``, ``frf_type``, ``response_units``,
      ``force_units``, or ``frf_units`` (e.g. ``'m/s^2/N'``).

    Parameters
    ----------
    path : str or path-like
        A v4 to v7 file (:func:`scipy.io.loadmat`) or a v7.3 (HDF5) file, read with ``h5py``
        when it is installed (``pip install "ami_xr[matlab]"``).
    drive_point, points, response_quantity, frf_type, response_units, force_units : optional
        As for :func:`~ami_xr.io.frf_tables.read_frf_csv`; a value given wins over the file's.

    Returns
    -------
    xarray.Dataset
        FRF Dataset (``frf`` (point, frequency)), ``frf_source = "measured"``.

    Raises
    ------
    DataFileError
        Not a MATLAB file, a v7.3 file without h5py, no frequency vector or no FRF matrix
        (the message lists the variables found), shapes that do not fit, real FRFs; each
        message names the file and the variable.
    SchemaError
        The FRFs read break the data model (named problems).
    """
    path = Path(path)
    given = ReadOptions.of(options, "read_frf_mat", OPTION_KEYS)
    v73 = _is_v73(path)
    variables = _load_v73(path) if v73 else _load_v5(path)
    scope, where = _scope(variables, path)
    fname = _lookup(scope, FREQUENCY_NAMES, is_frequency_name)
    if fname is None:
        raise DataFileError(
            f"{path}: {where} has no frequency vector; expected a variable named "
            f"{', '.join(FREQUENCY_NAMES)} (in Hz); found: {_describe(scope)}"
        )
    hname = _lookup(scope, FRF_NAMES)
    if hname is None:
        raise DataFileError(
            f"{path}: {where} has no FRF matrix; expected a complex variable named "
            f"{' or '.join(FRF_NAMES)} (points x lines or lines x points); found: "
            f"{_describe(scope)}"
        )
    freq = _frequency(scope[fname], fname, path)
    frf, orientation = _frf(scope[hname], hname, freq.size, path)
    pname = _lookup(scope, POINT_NAMES)
    labels = None
    if pname is not None:
        labels = point_labels(_text_list(scope[pname]))
        if len(labels) != frf.shape[0]:
            raise DataFileError(
                f"{path}: variable {pname!r}: {len(labels)} label(s) for {frf.shape[0]} FRFs"
            )
    record = {
        "format": "MATLAB v7.3" if v73 else "MATLAB",
        "variables": [n for n in (fname, hname, pname) if n is not None],
        "layout": orientation,
    }
    if where != "the file":
        record["struct"] = where.split(" ", 1)[1].strip("'")
    return frf_dataset(path, frf, freq, labels, _said(scope, path), given, HOW, record)
