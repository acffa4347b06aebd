"""Labeled signal processing on time Datasets: windows, impulse responses to FRFs, FRF estimation
from force and response histories (random and impact excitation), quantity conversion."""

from ami_xr.dsp.frf import frf, frf_from_options, impact_frf
from ami_xr.dsp.hits import check_hits
from ami_xr.dsp.impulse import impulse_to_frf
from ami_xr.dsp.quantity import convert_quantity
from ami_xr.dsp.windows import apply_window

__all__ = [
    "apply_window",
    "check_hits",
    "convert_quantity",
    "frf",
    "frf_from_options",
    "impact_frf",
    "impulse_to_frf",
]
