"""ami_xr: experimental modal analysis with the Algorithm of Mode Isolation on xarray data.

Importing ami_xr registers the ``ds.ami`` accessor. Nothing is compiled on import: numba kernels
compile on first call and are cached on disk.
"""

from __future__ import annotations

__version__ = "0.1.0"

# Public functions: one import line per module, kept sorted (ruff's isort rules).
from ami_xr import names, simulate  # noqa: E402
from ami_xr.ami import global_fit, identify, isolate, subtract  # noqa: E402
from ami_xr.ami.crb import cramer_rao_bound  # noqa: E402
from ami_xr.ami.refine import refine  # noqa: E402
from ami_xr.batch import batch  # noqa: E402
from ami_xr.errors import (  # noqa: E402
    AmiXrError,
    AmiXrValueError,
    ConvergenceWarning,
    DataFileError,
    IdentificationError,
    NoModesWarning,
    SchemaError,
)
from ami_xr.io import (  # noqa: E402
    make_frf_dataset,
    make_time_dataset,
    open_dataset,
    to_netcdf,
    validate,
)
from ami_xr.io.lvm import read_lvm  # noqa: E402
from ami_xr.io.uff import read_uff, write_uff  # noqa: E402
from ami_xr.plot import (  # noqa: E402
    plot_bode,
    plot_mac,
    plot_modal_table,
    plot_mode_vectors,
    plot_nyquist,
    plot_subtraction,
)
from ami_xr.report import format_modal_table, modal_table, report  # noqa: E402
from ami_xr.dsp import apply_window, impulse_to_frf  # noqa: E402
from ami_xr.dsp import convert_quantity, frf, impact_frf  # noqa: E402

__all__ = [
    "subtract",
    "isolate",
    "global_fit",
    "identify",
    "__version__",
    "names",
    "simulate",
    "AmiXrError",
    "AmiXrValueError",
    "ConvergenceWarning",
    "DataFileError",
    "IdentificationError",
    "NoModesWarning",
    "SchemaError",
    "validate",
    "open_dataset",
    "to_netcdf",
    "make_frf_dataset",
    "make_time_dataset",
    "apply_window",
    "impulse_to_frf",
    "frf",
    "impact_frf",
    "convert_quantity",
    "read_lvm",
    "refine",
    "cramer_rao_bound",
    "batch",
    "read_uff",
    "write_uff",
    "plot_bode",
    "plot_nyquist",
    "plot_subtraction",
    "plot_mode_vectors",
    "plot_mac",
    "plot_modal_table",
    "report",
    "modal_table",
    "format_modal_table",
]

# Last: the accessor module imports the public functions it wraps.
from ami_xr import accessor as _accessor  # noqa: E402,F401  (registers ds.ami)
