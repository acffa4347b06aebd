"""Schema validation of ami_xr Datasets: the import path of :mod:`ami_xr.schema`.

The data model and its validator live in :mod:`ami_xr.schema`, a layer below ``dsp``, ``ami``
and ``io`` (so the labeled layers can validate their input without importing ``io``); this
module re-exports its public names.
"""

from __future__ import annotations

from ami_xr.schema import (
    IMPULSE_GRID_RTOL,
    KINDS,
    MULTI_REFERENCE_DIMS,
    UNIFORM_RTOL,
    drive_points,
    find_problems,
    impulse_grid_problem,
    is_positive_number,
    python_scalar,
    validate,
)

__all__ = [
    "validate",
    "find_problems",
    "is_positive_number",
    "python_scalar",
    "KINDS",
    "UNIFORM_RTOL",
    "IMPULSE_GRID_RTOL",
    "impulse_grid_problem",
    "drive_points",
    "MULTI_REFERENCE_DIMS",
]
