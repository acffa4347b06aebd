"""Figures (matplotlib, the ``plot`` extra), one module per topic.

:mod:`~ami_xr.plot.modal` draws an identification result (Bode, Nyquist, subtraction, mode
vectors, MAC, modal table), :mod:`~ami_xr.plot.measurement` the measurement behind it,
:mod:`~ami_xr.plot.stability` the stability chart and :mod:`~ami_xr.plot.geometry` mode shapes
on the measured points; :mod:`~ami_xr.plot.common` holds what they share. Importing any of them
imports no matplotlib: each function does, on its first call. The public functions are also
``ami_xr.plot_bode``, ``ami_xr.plot_mac``, ... .
"""
