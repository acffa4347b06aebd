"""Kernel layer: plain ndarrays in, ndarrays out; numpy, numba and math only.

Kernels take batch dims first and the core dim (frequency or time) last. Private ``_name`` kernels
are jitted and assume clean input; the public wrapper of the same name checks shapes and dtypes and
raises before any jitted code runs.
"""
