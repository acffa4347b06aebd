"""Input/output layer: every file ami_xr reads or writes, and the data-model check.

* :mod:`.schema` -- :func:`validate` (every problem at once), :func:`~.schema.find_problems`
* :mod:`.datasets` -- :func:`make_frf_dataset`, :func:`make_time_dataset` from plain arrays
* :mod:`.netcdf` -- :func:`open_dataset`, :func:`to_netcdf` (lossless complex and attributes)
* :mod:`.atomic` -- the one atomic writer every file goes through
* :mod:`.uff` -- Universal File Format (needs ``pyuff``); :mod:`.lvm` -- LabVIEW measurement files
"""

from ami_xr.io.datasets import make_frf_dataset, make_time_dataset
from ami_xr.io.netcdf import open_dataset, to_netcdf
from ami_xr.io.schema import validate

__all__ = ["validate", "make_frf_dataset", "make_time_dataset", "open_dataset", "to_netcdf"]
