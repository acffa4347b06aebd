"""Dataset-58 records: their point labels, abscissae, and how a set of them maps to points and
references (single reference, roving hammer, multi-reference; rules: :mod:`ami_xr.io.uff`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ami_xr.errors import DataFileError
from ami_xr.io.uff.codes import ID_TAG, point_label

__all__ = [
    "ID_LINES",
    "MULTI_REFERENCE_LAYOUT",
    "id_lines",
    "abscissa",
    "check_same_grid",
    "label_of",
    "mixed_labels_to_str",
    "multi_reference",
    "single_reference",
]


def label_of(record: dict, which: str) -> Any:
    """Point label of the response (``which="rsp"``) or reference DOF of a dataset-58 record."""
    tag = str(record.get("id2", ""))
    if which == "rsp" and tag.startswith(ID_TAG):
        return tag[len(ID_TAG) :]
    if which == "ref":
        tag3 = str(record.get("id3", ""))
        if tag3.startswith(ID_TAG):
            return tag3[len(ID_TAG) :]
    return point_label(record[f"{which}_node"], record[f"{which}_dir"])


def abscissa(record: dict) -> np.ndarray:
    n = len(record["data"])
    if int(record.get("abscissa_spacing", 0)) != 1:
        return np.asarray(record["x"], dtype=np.float64)
    start, inc = float(record["abscissa_min"]), float(record["abscissa_inc"])
    # The header keeps ~6 significant digits (E13.5): dt = 1/1024 s is written 9.76562e-04.
    # When 1/inc is within that precision of an integer (a sampling rate in Hz, a record length
    # in s), use the exact reciprocal so time and frequency axes survive a round trip.
    if inc > 0:
        rate = 1.0 / inc
        nearest = round(rate)
        if nearest >= 1 and abs(rate - nearest) <= 2e-5 * rate:
            inc = 1.0 / nearest
    return start + inc * np.arange(n)


def single_reference(records: list[dict], path: Path) -> tuple[list, Any, str]:
    """Point labels, drive point and layout of a set of FRF-like records (see module docs)."""
    rsp = [label_of(r, "rsp") for r in records]
    ref = [label_of(r, "ref") for r in records]
    if len(set(ref)) == 1:
        return rsp, ref[0], "fixed reference: points are the response DOFs"
    if len(set(rsp)) == 1:
        return (
            ref,
            rsp[0],
            (
                "roving hammer: one response DOF, several references; by reciprocity the "
                "points are the reference DOFs and the drive point is the response DOF"
            ),
        )
    raise DataFileError(
        f"{path}: the FRFs have {len(set(rsp))} response and {len(set(ref))} reference DOFs; "
        "ami_xr reads single-reference data (one reference, or one response with a roving "
        "hammer) -- split the file by reference"
    )


def mixed_labels_to_str(labels: list) -> list:
    # netCDF needs one label type per coordinate.
    if all(isinstance(lab, int) for lab in labels) or all(isinstance(lab, str) for lab in labels):
        return labels
    return [str(lab) for lab in labels]


def check_same_grid(records: list[dict], grids: list[np.ndarray], path: Path, what: str):
    first = grids[0]
    for r, g in zip(records, grids, strict=True):
        if g.shape != first.shape or not np.allclose(g, first, rtol=1e-9, atol=0):
            raise DataFileError(
                f"{path}: {what} record of DOF {r.get('rsp_node')}/{r.get('rsp_dir')} has a "
                f"different abscissa ({g.size} values from {g[0]:g}) than the first record "
                f"({first.size} values from {first[0]:g}); all records must share one grid"
            )


MULTI_REFERENCE_LAYOUT = (
    "multi-reference: several response and several reference DOFs; points are the response "
    "DOFs, references the reference DOFs (a reference on a point is its drive point)"
)


def multi_reference(records: list[dict], path: Path) -> tuple[list, list, list] | None:
    """Points, references and, per record, its (reference, point) index pair of FRF records
    with several responses and several references; None for single-reference records.

    Every (reference, response) pair must appear exactly once.
    """
    rsp = [label_of(r, "rsp") for r in records]
    ref = [label_of(r, "ref") for r in records]
    if len(set(rsp)) == 1 or len(set(ref)) == 1:
        return None
    both = mixed_labels_to_str(rsp + ref)  # one label type for points and references
    rsp, ref = both[: len(rsp)], both[len(rsp) :]
    points, refs = list(dict.fromkeys(rsp)), list(dict.fromkeys(ref))
    pairs = list(zip(ref, rsp, strict=True))
    dup = sorted({p for p in pairs if pairs.count(p) > 1}, key=str)
    missing = [(a, b) for a in refs for b in points if (a, b) not in set(pairs)]
    if dup or missing:
        what = f"repeat (reference, response) pairs {dup[:8]}" if dup else ""
        if missing:
            what += (
                (" and " if what else "")
                + f"lack the pairs {missing[:8]}"
                + (f" and {len(missing) - 8} more" if len(missing) > 8 else "")
            )
        raise DataFileError(
            f"{path}: multi-reference FRFs ({len(refs)} references x {len(points)} responses) "
            f"{what}; expected one FRF per (reference, response) pair"
        )
    index = [(refs.index(a), points.index(b)) for a, b in pairs]
    return points, refs, index


#: The ID lines of a dataset-58 record, kept per point on a round trip (coordinates
#: ``uff_id1`` ... ``uff_id5``; ID line 1 shared by every record: attribute ``title``).
ID_LINES = ("id1", "id2", "id3", "id4", "id5")
_EMPTY = ("", "NONE", "ami_xr")  # what ami_xr's writer puts where a record says nothing


def id_lines(records: list[dict]) -> tuple[dict[str, list[str]], str | None]:
    """The informative ID lines of records that are one per point: ``({"uff_id2": [...], ...},
    title)``. A line that every record leaves empty (``NONE``) or holds ami_xr's own label tag
    is left out; ID line 1 common to every record is the ``title``."""
    lines: dict[str, list[str]] = {}
    title = None
    for key in ID_LINES:
        texts = [str(r.get(key, "") or "").strip() for r in records]
        texts = ["NONE" if t.startswith(ID_TAG) else t for t in texts]
        if all(t in _EMPTY for t in texts):
            continue
        if key == "id1" and len(set(texts)) == 1:
            title = texts[0]
            continue
        lines[f"uff_{key}"] = [t or "NONE" for t in texts]
    return lines, title
