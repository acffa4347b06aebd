"""Input/output layer: schema validation (:mod:`.schema`) and netCDF files (:mod:`.netcdf`)."""

from ami_xr.io.netcdf import open_dataset, to_netcdf
from ami_xr.io.datasets import make_frf_dataset, make_time_dataset
from ami_xr.io.schema import validate

__all__ = ["validate", "make_frf_dataset", "make_time_dataset", "open_dataset", "to_netcdf"]
