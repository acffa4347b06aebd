"""Completeness checks of UFF files, run before pyuff reads them.

pyuff silently drops what it cannot pair or read: a file cut inside a dataset reads as if it had
ended one dataset earlier, a garbled dataset number as an unknown dataset, a short dataset-58
record as a shorter FRF. These checks turn each into a :class:`~ami_xr.errors.DataFileError`
that names the file and says what is missing.
"""

from __future__ import annotations

from pathlib import Path

from ami_xr.errors import DataFileError

__all__ = ["block_tags", "check_complete", "check_lengths"]

_TAG = b"    -1"  # the line that opens and closes every UFF dataset


def block_tags(data: bytes) -> list[int]:
    """Byte offsets of the ``    -1`` delimiter lines, found by pyuff's own rule.

    pyuff pairs these tags (open, close) and silently drops an unpaired last one, so a file cut
    inside a dataset reads as if it had ended one dataset earlier; counting them the same way
    tells a complete file from a truncated one.
    """
    tags = []
    n = len(data)
    blanks = b" " * 74
    ind = data.find(_TAG)
    while ind != -1:
        end = ind + len(_TAG)
        if end == n or data[end] in (10, 13) or (ind + 80 < n and data[end : ind + 80] == blanks):
            tags.append(ind)
        ind = data.find(_TAG, ind + 1)
    return tags


def check_complete(data: bytes, path: Path) -> None:
    """Raise if the file ends inside a dataset (an odd number of delimiter lines), or if a
    dataset has no readable dataset number (pyuff would skip it as an unknown type)."""
    tags = block_tags(data)
    for k, start in enumerate(tags[:-1:2]):
        line = data[start : tags[2 * k + 1]].splitlines()[1:2]
        number = line[0][:6].decode("ascii", errors="replace") if line else ""
        if not number.strip().isdigit():
            raise DataFileError(
                f"{path}: damaged UFF file: dataset {k + 1} (starting at byte {start}) has no "
                f"dataset number on its second line (got {number!r})"
            )
    if len(tags) % 2 == 0:
        return
    start = tags[-1]
    header = data[start:].splitlines()[1:2]
    kind = header[0][:6].decode("ascii", errors="replace").strip() if header else ""
    what = f"dataset type {kind}" if kind else "a dataset"
    raise DataFileError(
        f"{path}: truncated UFF file: {what} starting at byte {start} has no closing '    -1' "
        f"line (the file ends at byte {len(data)}); only the {len(tags) // 2} dataset(s) before "
        "it are complete"
    )


def check_lengths(sets: list[dict], path: Path) -> None:
    """Each dataset-58 record must hold the ``num_pts`` values its header declares."""
    for i, s in enumerate(sets):
        if s.get("type") != 58 or s.get("data") is None or "num_pts" not in s:
            continue
        expected, found = int(s["num_pts"]), len(s["data"])
        if found != expected:
            raise DataFileError(
                f"{path}: dataset 58 #{i + 1} (DOF {s.get('rsp_node')}/{s.get('rsp_dir')}) is "
                f"incomplete: its header declares {expected} values (num_pts), found {found}"
            )
