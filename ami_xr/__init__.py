"""ami_xr: experimental modal analysis with the Algorithm of Mode Isolation on xarray data.

Importing ami_xr registers the ``ds.ami`` accessor and nothing else: each public name below is
imported from its module on first use (PEP 562 module ``__getattr__``), so ``import ami_xr``
loads neither the numerics nor plotting, file formats or dask, and not even xarray: the accessor
is registered when xarray is first imported (:mod:`ami_xr.import_hook`). Nothing is compiled on
import
either: numba kernels compile on first call and are cached on disk.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

# Public functions, classes and constants: name -> the module that defines it.
_PUBLIC: dict[str, str] = {
    # identification (the AMI phases) and its uncertainty
    "subtract": "ami_xr.ami",
    "isolate": "ami_xr.ami",
    "global_fit": "ami_xr.ami",
    "identify": "ami_xr.ami",
    "refine": "ami_xr.ami.refine",
    "cramer_rao_bound": "ami_xr.ami.crb",
    "stability": "ami_xr.ami.stability",
    # errors and warnings
    "AmiXrError": "ami_xr.errors",
    "AmiXrValueError": "ami_xr.errors",
    "ConvergenceWarning": "ami_xr.errors",
    "DataFileError": "ami_xr.errors",
    "IdentificationError": "ami_xr.errors",
    "NoModesWarning": "ami_xr.errors",
    "SchemaError": "ami_xr.errors",
    # data model and files
    "validate": "ami_xr.io",
    "open_dataset": "ami_xr.io",
    "to_netcdf": "ami_xr.io",
    "make_frf_dataset": "ami_xr.io",
    "make_time_dataset": "ami_xr.io",
    "open_frf": "ami_xr.io.formats",
    "combine_runs": "ami_xr.io.combine",
    "split_frf_and_modes": "ami_xr.io.reference_modes",
    "compare_modes": "ami_xr.io.reference_modes",
    "read_lvm": "ami_xr.io.lvm",
    "read_uff": "ami_xr.io.uff",
    "write_uff": "ami_xr.io.uff",
    # signal processing: time histories to FRFs
    "apply_window": "ami_xr.dsp.windows",
    "impulse_to_frf": "ami_xr.dsp.impulse",
    "frf": "ami_xr.dsp.frf",
    "impact_frf": "ami_xr.dsp.frf",
    "convert_quantity": "ami_xr.dsp.quantity",
    "estimate_frf_noise": "ami_xr.dsp.noise_model",
    # campaigns, figures and reports
    "batch": "ami_xr.app.batch",
    "plot_bode": "ami_xr.plot.modal",
    "plot_nyquist": "ami_xr.plot.modal",
    "plot_subtraction": "ami_xr.plot.modal",
    "plot_mode_vectors": "ami_xr.plot.modal",
    "plot_mac": "ami_xr.plot.modal",
    "plot_modal_table": "ami_xr.plot.modal",
    "plot_stability": "ami_xr.plot.stability",
    "plot_mode_shapes": "ami_xr.plot.geometry",
    "animate_mode_shape": "ami_xr.plot.geometry",
    "report": "ami_xr.app.report",
    "modal_table": "ami_xr.tables",
    "format_modal_table": "ami_xr.tables",
    # status as data: quality flags (int bits) in words, the caps of a run
    "flag_text": "ami_xr.core.flags",
    "RunStatus": "ami_xr.core.flags",
}
# Public submodules, also imported on first use.
_SUBMODULES = ("names", "simulate")

__all__ = ["__version__", *_SUBMODULES, *_PUBLIC]


def __getattr__(name: str):
    """Import a public name from its module on first use (PEP 562)."""
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    if name not in _PUBLIC:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_PUBLIC[name]), name)
    globals()[name] = value  # later look-ups find it without calling __getattr__
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


def _register_accessor() -> None:
    importlib.import_module(f"{__name__}.accessor")


# Registers ds.ami as soon as xarray is imported (at once if it already is): ``import ami_xr``
# itself loads no xarray, pandas or numpy. The accessor imports the functions it wraps when a
# method is first called.
from ami_xr.import_hook import call_when_imported  # noqa: E402

call_when_imported("xarray", _register_accessor)
del call_when_imported
