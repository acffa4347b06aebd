"""The encodings of :mod:`ami_xr.io.netcdf` for what netCDF cannot store natively.

* complex values as (real, imag) pairs along a trailing dim, bit exact (:func:`to_pairs`,
  :func:`from_pairs`);
* attributes netCDF cannot hold, tagged in ``ami_xr_encoded_attrs`` (:func:`encode_attrs`,
  :func:`decode_attrs`; the tags are listed in the module docstring of :mod:`ami_xr.io.netcdf`);
* the check of the ``ami_xr_cf_added`` marker that :mod:`ami_xr.io.cf` writes
  (:func:`check_cf_marker`).

Every decoding error is a :class:`~ami_xr.errors.DataFileError` naming the attribute and what was
expected.
"""

from __future__ import annotations

import json
from numbers import Integral
from typing import Any

import numpy as np

from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io.cf import ATTR_CF_ADDED

__all__ = [
    "ATTR_COMPLEX",
    "ATTR_COMPLEX_VALUE",
    "ATTR_ENCODED_ATTRS",
    "ATTR_TAGS",
    "check_cf_marker",
    "decode_attrs",
    "encode_attrs",
    "from_pairs",
    "to_pairs",
]

ATTR_COMPLEX = "ami_xr_complex"
ATTR_COMPLEX_VALUE = f"real,imag along last dim {names.COMPLEX}"
ATTR_ENCODED_ATTRS = "ami_xr_encoded_attrs"
_RESERVED_ATTRS = (ATTR_COMPLEX, ATTR_ENCODED_ATTRS)

_INT64 = np.iinfo(np.int64)


# --- complex <-> (real, imag) pairs, bit exact ---------------------------------------------------


def to_pairs(z: np.ndarray) -> np.ndarray:
    """complex (...,) -> float (..., 2) by reinterpreting memory (no arithmetic, bit exact)."""
    z = np.asarray(z)
    if not z.flags.c_contiguous:
        z = z.copy(order="C")
    return z.reshape(-1).view(z.real.dtype).reshape(z.shape + (2,))


def from_pairs(x: np.ndarray) -> np.ndarray:
    """float (..., 2) -> complex (...,) by reinterpreting memory (no arithmetic, bit exact).

    ``re + 1j * im`` is not exact: it turns -0.0 real parts into +0.0 and a NaN imaginary part
    into a NaN real part.
    """
    x = np.asarray(x)
    if not x.flags.c_contiguous:
        x = x.copy(order="C")
    ctype = np.result_type(x.dtype, np.complex64)
    return x.reshape(-1).view(ctype).reshape(x.shape[:-1])


# --- attributes -----------------------------------------------------------------------------------


def _encode_attr(key: str, value: Any, owner: str) -> tuple[Any, str | None]:
    """(value netCDF can store, tag or None) for one attribute."""

    def fail(why: str) -> AmiXrValueError:
        return AmiXrValueError(
            f"attribute {key!r} of {owner}: {why}; netCDF attributes can hold str, numbers, bool, "
            "complex, 1-D lists/arrays of those, dict and None (JSON-serialisable)"
        )

    if isinstance(value, (bool, np.bool_)):
        return np.int8(value), "bool"
    if isinstance(value, (complex, np.complexfloating)):
        return to_pairs(np.asarray(value)), "complex"
    if isinstance(value, str):
        if "\x00" in value:
            raise fail("a NUL character cannot be stored in a netCDF string")
        return value, None
    if isinstance(value, Integral):
        if _INT64.min <= int(value) <= _INT64.max:
            return value, None
        return json.dumps(int(value)), "json"
    if isinstance(value, (float, np.floating)):
        return value, None
    if value is None or isinstance(value, dict):
        try:
            return json.dumps(value), "json"
        except (TypeError, ValueError) as err:
            raise fail(f"a {type(value).__name__} that is not JSON-serialisable ({err})") from err
    if isinstance(value, (list, tuple, np.ndarray)):
        arr = np.asarray(value) if not isinstance(value, np.ndarray) else value
        if arr.ndim != 1:
            raise fail(f"a {arr.ndim}-D array cannot be an attribute (store it as a variable)")
        if arr.size == 0 or arr.dtype == object:
            try:
                return json.dumps(_json_list(value)), "json"
            except (TypeError, ValueError) as err:
                raise fail(f"a list of mixed or unsupported types ({err})") from err
        if arr.dtype.kind == "b":
            return arr.astype(np.int8), "bool[]"
        if arr.dtype.kind == "c":
            return to_pairs(arr).reshape(-1), "complex[]"
        if arr.dtype.kind == "U" and any("\x00" in s for s in arr):
            raise fail("a NUL character cannot be stored in a netCDF string")
        if arr.dtype.kind not in "iufU":
            raise fail(f"arrays of dtype {arr.dtype} are not supported")
        if arr.dtype.kind == "u" and arr.dtype.itemsize == 8 and arr.max() > _INT64.max:
            raise fail("uint64 values beyond int64")
        if arr.size == 1:  # netCDF reads a one-element attribute back as a scalar
            return (arr[0].item() if arr.dtype.kind == "U" else arr[0]), "[1]"
        return value, None
    raise fail(f"type {type(value).__name__} is not supported")


def _json_list(value: Any) -> Any:
    return [v.item() if isinstance(v, np.generic) else v for v in value]


def _decode_attr(value: Any, tag: str) -> Any:
    if tag == "bool":
        return bool(value)
    if tag == "bool[]":
        return np.atleast_1d(np.asarray(value)).astype(bool)
    if tag == "complex":
        return from_pairs(np.asarray(value)).item()
    if tag == "complex[]":
        return from_pairs(np.asarray(value).reshape(-1, 2))
    if tag == "json":
        return json.loads(value)
    if tag == "[1]":
        return np.atleast_1d(np.asarray(value))
    raise DataFileError(f"unknown attribute encoding tag {tag!r}")


def encode_attrs(attrs: dict, owner: str) -> dict:
    out: dict[str, Any] = {}
    tags: dict[str, str] = {}
    for key, value in attrs.items():
        if not isinstance(key, str):
            raise AmiXrValueError(
                f"attribute {key!r} of {owner}: netCDF attribute names must be str"
            )
        if key in _RESERVED_ATTRS:
            raise AmiXrValueError(
                f"attribute {key!r} of {owner}: the name is reserved for ami_xr's netCDF encoding "
                "(was this file opened with plain xarray? use ami_xr.open_dataset)"
            )
        out[key], tag = _encode_attr(key, value, owner)
        if tag is not None:
            tags[key] = tag
    if tags:
        out[ATTR_ENCODED_ATTRS] = json.dumps(tags)
    return out


#: The tags :func:`_encode_attr` writes into ``ami_xr_encoded_attrs``.
ATTR_TAGS = ("bool", "bool[]", "complex", "complex[]", "json", "[1]")


def _encoded_tags(raw: Any, attrs: dict, owner: str) -> dict[str, str]:
    """The tags of ``ami_xr_encoded_attrs`` (its value ``raw``) of ``owner``, checked: a JSON
    object naming attributes that ``attrs`` has, each with a known tag."""
    where = f"attribute {ATTR_ENCODED_ATTRS!r} of {owner}"
    expected = (
        "expected a JSON object mapping attribute names to encoding tags "
        f"({', '.join(ATTR_TAGS)}), as ami_xr.to_netcdf writes it"
    )
    hint = " (a file written or edited by another tool? remove the attribute or rewrite the file)"
    try:
        tags = json.loads(raw)
    except (TypeError, ValueError) as err:  # JSONDecodeError is a ValueError
        raise DataFileError(
            f"{where}: {expected}, got {_short(raw)}, which is not valid JSON ({err}){hint}"
        ) from None
    if not isinstance(tags, dict):
        raise DataFileError(f"{where}: {expected}, got a JSON {type(tags).__name__}{hint}")
    for key, tag in tags.items():
        if key not in attrs:
            raise DataFileError(
                f"{where}: names attribute {key!r}, which {owner} does not have "
                f"(it has {_short(sorted(map(str, attrs)), 200)}){hint}"
            )
        if tag not in ATTR_TAGS:
            raise DataFileError(
                f"{where}: unknown encoding tag {_short(tag)} for attribute {key!r} "
                f"(expected one of {', '.join(ATTR_TAGS)}){hint}"
            )
    return tags


def _short(value: Any, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def decode_attrs(attrs: dict, owner: str = "the Dataset") -> dict:
    attrs = dict(attrs)
    raw = attrs.pop(ATTR_ENCODED_ATTRS, None)
    if raw is None:
        return attrs
    for key, tag in _encoded_tags(raw, attrs, owner).items():
        try:
            attrs[key] = _decode_attr(attrs[key], tag)
        except (TypeError, ValueError) as err:
            raise DataFileError(
                f"attribute {key!r} of {owner}: tagged {tag!r} in {ATTR_ENCODED_ATTRS!r} but its "
                f"value {_short(attrs[key])} cannot be decoded as that ({err}); expected what "
                "ami_xr.to_netcdf writes for that tag (a file written or edited by another tool?)"
            ) from None
    return attrs


#: Keys of the ``ami_xr_cf_added`` JSON object (:func:`ami_xr.io.cf.annotate`) and their types.
_CF_MARKER_KEYS = {"variables": list, "attrs": dict, "global": dict}
_CF_MARKER_OPTIONAL = {"renamed": dict, "labels": dict, "units_of_square": dict}


def check_cf_marker(raw: Any) -> None:
    """Raise :class:`DataFileError` naming the attribute when ``ami_xr_cf_added`` (what
    :func:`ami_xr.io.cf.annotate` added, undone on reading) is present but not the JSON object
    it writes: ignored, it left the CF encoding in place (``elapsed_time`` for ``time``, label
    variables for ``point``) and a later error blamed a missing coordinate."""
    if raw is None:
        return
    where = f"attribute {ATTR_CF_ADDED!r} of the Dataset"
    expected = (
        "expected the JSON object ami_xr.to_netcdf writes (keys "
        f"{', '.join(_CF_MARKER_KEYS)}, optionally {', '.join(_CF_MARKER_OPTIONAL)})"
    )
    hint = " (a file written or edited by another tool? remove the attribute or rewrite the file)"
    try:
        added = json.loads(raw)
    except (TypeError, ValueError):
        raise DataFileError(
            f"{where}: {expected}, got {_short(raw)}, not valid JSON{hint}"
        ) from None
    if not isinstance(added, dict):
        raise DataFileError(f"{where}: {expected}, got a JSON {type(added).__name__}{hint}")
    wrong = [
        f"{key!r} ({'missing' if key not in added else type(added[key]).__name__})"
        for key, kind in _CF_MARKER_KEYS.items()
        if not isinstance(added.get(key), kind)
    ] + [
        f"{key!r} ({type(added[key]).__name__})"
        for key, kind in _CF_MARKER_OPTIONAL.items()
        if key in added and not isinstance(added[key], kind)
    ]
    if wrong:
        raise DataFileError(f"{where}: {expected}; wrong: {', '.join(wrong)}{hint}")


