"""UFF code tables (dataset 58 and 55 specification), point labels and the pyuff import.

Shared by :mod:`ami_xr.io.uff.read` and :mod:`ami_xr.io.uff.write`; see :mod:`ami_xr.io.uff`
for how a degree of freedom becomes a point label.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

import numpy as np

from ami_xr import names
from ami_xr.errors import DataFileError

__all__ = [
    "DATASET_NAMES",
    "FUNCTION_NAMES",
    "describe_sets",
    "point_label",
    "parse_point_label",
    "dof_map",
    "require_pyuff",
    "FUNC_TIME",
    "FUNC_FRF",
    "FUNC_COHERENCE",
    "SPEC_TO_QUANTITY",
    "QUANTITY_TO_SPEC",
    "SPEC_FORCE",
    "SPEC_TIME",
    "SPEC_FREQUENCY",
    "SI_UNITS",
    "AXES",
    "AXIS_CODES",
    "LABEL_RE",
    "ID_TAG",
    "MODES_ID1",
]

# --- UFF code tables (from the UFF dataset 58 specification) ---------------------------------
FUNC_TIME = 1
FUNC_FRF = 4
FUNC_COHERENCE = 6
SPEC_TO_QUANTITY = {8: "displacement", 11: "velocity", 12: "acceleration"}
QUANTITY_TO_SPEC = {v: k for k, v in SPEC_TO_QUANTITY.items()}
SPEC_FORCE = (13, 9)  # excitation force, reaction force
SPEC_TIME = 17
SPEC_FREQUENCY = 18
SI_UNITS = names.SI_RESPONSE_UNITS  # units assumed when a record gives none
AXES = {1: "X", 2: "Y", 3: "Z", 4: "RX", 5: "RY", 6: "RZ"}
AXIS_CODES = {v: k for k, v in AXES.items()}
LABEL_RE = re.compile(r"^\s*(\d+)\s*([+-])\s*(X|Y|Z|RX|RY|RZ)\s*$", re.IGNORECASE)
ID_TAG = "ami_xr point="
MODES_ID1 = "ami_xr mode shapes"  # ID line 1 of the dataset 55 write_uff writes


#: What the datasets other tools write hold (for messages about what a file holds instead).
DATASET_NAMES = {
    15: "nodes",
    18: "coordinate systems",
    55: "data at nodes",
    58: "function at a DOF",
    82: "trace lines",
    151: "header",
    164: "units",
    1858: "dataset 58 qualifiers",
    2400: "model header",
    2411: "nodes",
    2412: "elements",
    2414: "analysis data (FE results)",
    2420: "coordinate systems",
    2429: "groups",
    2467: "groups",
}
#: Dataset 58 function types (ami_xr reads 1, 4 and 6).
FUNCTION_NAMES = {
    0: "general",
    1: "time response",
    2: "auto spectrum",
    3: "cross spectrum",
    4: "FRF",
    5: "transmissibility",
    6: "coherence",
    7: "auto correlation",
    8: "cross correlation",
    9: "power spectral density",
    10: "energy spectral density",
    11: "probability density",
    12: "spectrum",
    18: "mode indicator function",
    26: "multiple coherence",
}


def describe_sets(sets: Sequence[dict]) -> str:
    """What a file's datasets are, for a message: ``"58 (power spectral density) x4, 2411
    (nodes)"``."""
    counts: dict[str, int] = {}
    for s in sets:
        kind = s.get("type")
        if kind == 58:
            func = int(s.get("func_type", 0) or 0)
            what = FUNCTION_NAMES.get(func, f"function type {func}")
            text = f"58 ({what}, function type {func})"
        else:
            text = f"{kind} ({DATASET_NAMES.get(kind, 'not read')})"
        counts[text] = counts.get(text, 0) + 1
    return ", ".join(f"{k} x{n}" if n > 1 else k for k, n in counts.items()) or "none"


def require_pyuff():
    """The ``pyuff`` module, or an ImportError that says how to install it."""
    try:
        import pyuff
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            "reading or writing UFF files needs the optional package pyuff: "
            "pip install 'ami_xr[uff]'"
        ) from err
    return pyuff


# --- point labels ----------------------------------------------------------------------------
def point_label(node: int, direction: int) -> str | int:
    """Label of a UFF degree of freedom: ``(1, 3) -> "1+Z"``, ``(7, -1) -> "7-X"``, ``(4, 0) -> 4``.

    Parameters
    ----------
    node : int
        UFF node number.
    direction : int
        UFF direction code: 0 scalar, +-1..3 translations X, Y, Z, +-4..6 rotations RX, RY, RZ.
    """
    node = int(node)
    direction = int(direction)
    if direction == 0:
        return node
    if abs(direction) not in AXES:
        raise DataFileError(
            f"UFF direction code {direction} of node {node} is not one of 0, +-1..6"
        )
    return f"{node}{'+' if direction > 0 else '-'}{AXES[abs(direction)]}"


def parse_point_label(label: Any) -> tuple[int, int] | None:
    """Inverse of :func:`point_label`: ``"1+Z" -> (1, 3)``, ``4 -> (4, 0)``; None if not a DOF."""
    if isinstance(label, (int, np.integer)) and not isinstance(label, bool):
        return int(label), 0
    match = LABEL_RE.match(str(label))
    if match is None:
        return None
    node, sign, axis = match.groups()
    code = AXIS_CODES[axis.upper()]
    return int(node), code if sign == "+" else -code


def dof_map(labels: Sequence[Any]) -> dict[Any, tuple[int, int, str]]:
    """Node number, direction code and ID-line tag used to write each point label."""
    parsed = {lab: parse_point_label(lab) for lab in labels}
    used_nodes = {p[0] for p in parsed.values() if p is not None}
    next_node = 1
    out = {}
    for lab in labels:
        p = parsed[lab]
        if p is not None:
            out[lab] = (p[0], p[1], "NONE")
            continue
        while next_node in used_nodes:
            next_node += 1
        used_nodes.add(next_node)
        out[lab] = (next_node, 0, f"{ID_TAG}{lab}")
    return out
