"""The ``ds.ami`` accessor: a thin, stateless shell over the public functions.

Each method calls the public function of the same name with the Dataset as first argument and
returns what it returns (a new Dataset; the caller's Dataset is never mutated). ``__init__`` only
stores the Dataset: validation happens inside the functions.
"""

from __future__ import annotations

import functools

import xarray as xr


def _method(func):
    """Make ``func(ds, ...)`` into an accessor method with the same signature and docstring."""

    @functools.wraps(func)
    def method(self, *args, **kwargs):
        return func(self._ds, *args, **kwargs)

    return method


@xr.register_dataset_accessor("ami")
class AmiAccessor:
    """``ds.ami.<name>(...)`` is ``ami_xr.<name>(ds, ...)``."""

    def __init__(self, ds: xr.Dataset):
        self._ds = ds

    # Methods are added as ``name = _method(public_function)``, one line each, imported lazily
    # at the bottom of this module to avoid import cycles.


from ami_xr.io import to_netcdf, validate  # noqa: E402

AmiAccessor.validate = _method(validate)
AmiAccessor.to_netcdf = _method(to_netcdf)

from ami_xr.dsp import apply_window, impulse_to_frf  # noqa: E402

AmiAccessor.apply_window = _method(apply_window)
AmiAccessor.impulse_to_frf = _method(impulse_to_frf)

from ami_xr.ami.refine import refine  # noqa: E402

AmiAccessor.refine = _method(refine)

from ami_xr.io.uff import write_uff  # noqa: E402
from ami_xr.plot import (  # noqa: E402
    plot_bode,
    plot_mac,
    plot_modal_table,
    plot_mode_vectors,
    plot_nyquist,
    plot_subtraction,
)
from ami_xr.report import modal_table, report  # noqa: E402

AmiAccessor.write_uff = _method(write_uff)
AmiAccessor.plot_bode = _method(plot_bode)
AmiAccessor.plot_nyquist = _method(plot_nyquist)
AmiAccessor.plot_subtraction = _method(plot_subtraction)
AmiAccessor.plot_mode_vectors = _method(plot_mode_vectors)
AmiAccessor.plot_mac = _method(plot_mac)
AmiAccessor.plot_modal_table = _method(plot_modal_table)
AmiAccessor.report = _method(report)
AmiAccessor.modal_table = _method(modal_table)

from ami_xr.dsp import convert_quantity, frf  # noqa: E402

AmiAccessor.frf = _method(frf)
AmiAccessor.convert_quantity = _method(convert_quantity)

from ami_xr.ami import global_fit, identify, isolate, subtract  # noqa: E402

AmiAccessor.subtract = _method(subtract)
AmiAccessor.isolate = _method(isolate)
AmiAccessor.global_fit = _method(global_fit)
AmiAccessor.identify = _method(identify)
