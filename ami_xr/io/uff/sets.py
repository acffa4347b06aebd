"""The datasets of a UFF file, read through pyuff one at a time.

pyuff reads a file in one call and, when a dataset fails, says only "Error when reading
data-set(s).". Reading one dataset at a time names the dataset that failed: its place in the file,
its type and the line where it starts.

Lines padded with blanks to 80 columns (SDynPy pads every line, the last data line of a record
included) make pyuff's fixed-width number parsers (dataset 58 in double precision, dataset 55) read
the blank fields as numbers and fail. When a dataset fails and the file has such lines, it is read
again from a copy with the trailing blanks of its ASCII datasets removed (binary 58b data as it
is): blanks carry no value, so nothing read changes.

pyuff decodes text as UTF-8 and puts U+FFFD where it cannot; unit labels written in Latin-1 or
Windows-1252 (``m/s²`` as byte 0xB2, as Windows test-lab software writes them) are decoded
again from the file's bytes (:func:`redecode_text`).
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

from ami_xr.caller import warn
from ami_xr.errors import AssumptionWarning, DataFileError
from ami_xr.io.uff.codes import require_pyuff
from ami_xr.io.uff.completeness import block_tags, check_complete, check_lengths
from ami_xr.io.uff.quiet import quiet

__all__ = ["read_sets", "redecode_text", "strip_padding"]

_PADDED = re.compile(rb"[ \t]+(?=\r\n|\n|\r|\Z)")  # blanks at the end of a line


def _is_binary(block: bytes) -> bool:
    """pyuff's test for a binary dataset (58b): a ``b`` after the dataset number."""
    header = block[:400].splitlines()[1:2]  # the dataset-number line, not the binary data
    return bool(header) and header[0][6:7].lower() == b"b"


def strip_padding(data: bytes) -> bytes:
    """``data`` with the trailing blanks of every line of its ASCII datasets removed."""
    tags = block_tags(data)
    out, pos = [], 0
    for start, end in zip(tags[:-1:2], tags[1::2], strict=True):
        block = data[start:end]
        out += [data[pos:start], block if _is_binary(block) else _PADDED.sub(b"", block)]
        pos = end
    out.append(data[pos:])
    return b"".join(out)


# Text fields of a dataset-58 header: (line of the block, first column, last column, pyuff's key).
# Line 0 is the opening "    -1", line 1 the dataset number.
_TEXT_FIELDS_58 = (
    *((k + 2, 0, 80, f"id{k + 1}") for k in range(5)),
    *(
        (line, start, start + 21, f"{axis}{suffix}")
        for line, axis in ((9, "abscissa_"), (10, "ordinate_"), (11, "orddenom_"), (12, "z_axis_"))
        for start, suffix in ((25, "axis_lab"), (46, "axis_units_lab"))
    ),
)


#: Values per node of dataset 55 by its data characteristic (record 6, field 3): 1 scalar,
#: 2 three translations, 3 three translations and three rotations.
VALUES_PER_NODE = {1: 1, 2: 3, 3: 6}


def repair_values_per_node(data: bytes) -> tuple[bytes, list[str]]:
    """Dataset 55 whose record 6 states a number of values per node its data characteristic
    does not have (SDynPy writes 1 for three translations) with the characteristic's number;
    the repaired data and what was repaired."""
    lines = data.split(b"\n")
    done = []
    for i in range(len(lines) - 7):
        if lines[i].strip() != b"-1" or lines[i + 1].strip() != b"55":
            continue
        fields = lines[i + 7].split()
        if len(fields) < 6 or not all(f.lstrip(b"-").isdigit() for f in fields[:6]):
            continue
        want = VALUES_PER_NODE.get(int(fields[2]))
        if want is None or int(fields[5]) == want:
            continue
        done.append(
            f"dataset 55 at line {i + 1}: record 6 states {int(fields[5])} value(s) per node for "
            f"data characteristic {int(fields[2])}; read with {want}"
        )
        fields[5] = str(want).encode()
        line = lines[i + 7]
        end = b"\r" if line.endswith(b"\r") else b""
        # the same length: offsets into the file stay where they were
        lines[i + 7] = b"".join(f.rjust(10) for f in fields).ljust(len(line) - len(end)) + end
    return b"\n".join(lines), done


def redecode_text(sets: list[dict], data: bytes) -> None:
    """Text fields of dataset-58 headers that pyuff could not decode as UTF-8 (it puts U+FFFD in
    their place), decoded again from the file's bytes as Latin-1: a unit label ``m/s²`` written
    by a Windows program (byte 0xB2) reads as ``m/s²``, not ``m/s`` and U+FFFD. In place."""
    tags = block_tags(data)
    for i, s in enumerate(sets):
        if s.get("type") != 58:
            continue
        fields = [f for f in _TEXT_FIELDS_58 if "\ufffd" in str(s.get(f[3], ""))]
        if not fields or 2 * i + 1 >= len(tags):
            continue
        lines = data[tags[2 * i] : tags[2 * i + 1]][:2000].splitlines()
        for line, start, end, key in fields:
            if line < len(lines):
                s[key] = lines[line][start:end].decode("latin-1").strip()


class _SetFailed(Exception):
    """pyuff could not read dataset ``index`` (0-based) of type ``kind``."""

    def __init__(self, index: int, kind: int, cause: BaseException):
        super().__init__(index, kind, cause)
        self.index, self.kind, self.cause = index, kind, cause


def _read_each(file: Path) -> list[dict]:
    """Every dataset of ``file``, read one by one; :class:`_SetFailed` names the one that fails."""
    pyuff = require_pyuff()
    with quiet():  # pyuff prints while it reads some datasets (2467): not the tool's output
        uff = pyuff.UFF(str(file))
        types = list(uff.get_set_types()) if uff.get_n_sets() else []
        sets = []
        for i, kind in enumerate(types):
            try:
                sets.append(uff.read_sets(i))
            except Exception as err:  # pyuff raises bare Exceptions of many kinds on bad datasets
                raise _SetFailed(i, int(kind), err) from err
    return sets


def _read_copy(data: bytes, path: Path) -> list[dict]:
    """:func:`_read_each` of ``data`` (a repaired copy of ``path``) in a temporary file."""
    with tempfile.TemporaryDirectory(prefix="ami_xr_uff_") as folder:
        copy = Path(folder) / path.name
        copy.write_bytes(data)
        return _read_each(copy)


def _failure(path: Path, data: bytes, failed: _SetFailed, padded: bool) -> DataFileError:
    tags = block_tags(data)
    start = tags[2 * failed.index]
    line = data.count(b"\n", 0, start) + 1
    cause = f"{type(failed.cause).__name__}: {failed.cause}"
    hint = (
        " (read again without the blanks that pad its lines: the values themselves do not parse)"
        if padded
        else ""
    )
    return DataFileError(
        f"{path}: dataset {failed.index + 1} of the file (type {failed.kind}, starting at line "
        f"{line}) cannot be read: pyuff says {cause!r}{hint}; the dataset is damaged or in a "
        "layout pyuff does not read"
    )


def read_sets(path: Path) -> list[dict]:
    """Every dataset of the UFF file ``path`` as pyuff's dicts, after the completeness checks of
    :mod:`ami_xr.io.uff.completeness`.

    Raises
    ------
    DataFileError
        Missing, unreadable, truncated or empty file, or a dataset pyuff cannot read (named by its
        place in the file, type and first line).
    """
    require_pyuff()  # the clear "install the uff extra" error first
    if not path.is_file():
        raise DataFileError(f"UFF file {str(path)!r} does not exist")
    try:
        data = path.read_bytes()
    except OSError as err:
        raise DataFileError(f"{path}: cannot read the file: {err}") from err
    check_complete(data, path)
    fixed, repaired = repair_values_per_node(data)
    for what in repaired:  # an assumption about the file: said on the terminal
        warn(f"{path.name}: {what}", AssumptionWarning)
    try:
        sets = _read_each(path) if not repaired else _read_copy(fixed, path)
    except _SetFailed as failed:
        stripped = strip_padding(fixed)
        if stripped == fixed:
            raise _failure(path, data, failed, padded=False) from failed.cause
        with tempfile.TemporaryDirectory(prefix="ami_xr_uff_") as folder:
            copy = Path(folder) / path.name
            copy.write_bytes(stripped)
            try:
                sets = _read_each(copy)
            except _SetFailed as again:
                raise _failure(path, data, again, padded=True) from again.cause
            except Exception as err:
                raise DataFileError(f"{path}: not a readable UFF file ({err})") from err
    except Exception as err:  # pyuff's own refresh of the file
        raise DataFileError(
            f"{path}: not a readable UFF file ({type(err).__name__}: {err})"
        ) from err
    if not sets:
        raise DataFileError(f"{path}: the UFF file holds no datasets")
    check_lengths(sets, path)
    redecode_text(sets, data)
    return sets
