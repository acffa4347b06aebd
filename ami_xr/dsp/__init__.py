"""Labeled signal processing on time Datasets: windows and FFT-to-FRF conversion."""

from ami_xr.dsp.impulse import impulse_to_frf
from ami_xr.dsp.windows import apply_window

__all__ = ["apply_window", "impulse_to_frf"]
