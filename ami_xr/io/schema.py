"""Schema validation of ami_xr Datasets: the import path of :mod:`ami_xr.schema`.

The data model and its validator live in :mod:`ami_xr.schema`, a layer below ``dsp``, ``ami``
and ``io`` (so the labeled layers can validate their input without importing ``io``); this
module re-exports its public names (the list is the package's own ``__all__``).
"""

from __future__ import annotations

from ami_xr import schema as _schema
from ami_xr.schema import *  # noqa: F403 (the public names, listed once in ami_xr.schema)

__all__ = list(_schema.__all__)
