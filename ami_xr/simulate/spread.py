"""FRF sets with many measured points (issue 21 benchmarks): one small system seen through a
random output matrix.

:func:`many_points` takes a random lumped-mass chain of ``n_modes`` degrees of freedom
(:func:`ami_xr.simulate.random_system`) and measures ``y = T q`` at ``n_points`` points, with
``T`` Gaussian (seeded) except its first row, which measures degree of freedom 0 alone: point 0 is
the drive point. The modes are those of the chain (exact), the mode vectors ``T Phi``; the FRFs
are analytic (eq. 4) on ``n_lines`` lines from 0 Hz to 1.1 times the highest natural frequency,
with the paper's noise (eq. 15, level ``noise``) on the real and imaginary parts of each FRF.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.simulate.modal import frf
from ami_xr.simulate.noise import add_noise
from ami_xr.simulate.random import random_system

__all__ = ["many_points"]


def many_points(
    n_points: int,
    n_lines: int = 2048,
    n_modes: int = 12,
    *,
    noise: float = 0.02,
    seed: int = 0,
    max_frequency_hz: float = 1000.0,
) -> tuple[xr.Dataset, xr.Dataset]:
    """``(frf Dataset, truth)`` of ``n_modes`` modes measured at ``n_points`` points (module
    docstring). ``truth`` has ``eigenvalue``, ``natural_frequency``, ``damping_ratio`` (mode) and
    ``mode_vector`` (point, mode)."""
    for value, name, low in ((n_points, "n_points", 1), (n_lines, "n_lines", 8)):
        if not isinstance(value, (int, np.integer)) or value < low:
            raise AmiXrValueError(f"{name}: expected an integer >= {low}, got {value!r}")
    _, chain = random_system(
        n_modes, "chain", n_frequencies=2, seed=seed, max_frequency_hz=max_frequency_hz
    )
    phi = chain[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
    out = np.random.default_rng(seed).standard_normal((n_points, phi.shape[0]))
    out[0] = 0.0
    out[0, 0] = 1.0
    truth = xr.Dataset(
        {v: chain[v] for v in (names.EIGENVALUE, names.NATURAL_FREQUENCY, names.DAMPING_RATIO)},
        attrs={k: v for k, v in chain.attrs.items() if k != names.ATTR_DRIVE_POINT},
    )
    truth[names.MODE_VECTOR] = xr.DataArray(
        out @ phi,
        dims=(names.POINT, names.MODE),
        coords={names.POINT: np.arange(n_points), names.MODE: chain[names.MODE].values},
        attrs=dict(chain[names.MODE_VECTOR].attrs),
    )
    f = np.linspace(0.0, 1.1 * float(chain[names.NATURAL_FREQUENCY].max()), n_lines)
    ds = frf(truth, f, drive_point=0)
    if noise:
        re = add_noise(ds[names.FRF].real, noise, seed=seed, dim=names.FREQUENCY)
        im = add_noise(ds[names.FRF].imag, noise, seed=seed + 1, dim=names.FREQUENCY)
        ds[names.FRF] = (re + 1j * im).assign_attrs(ds[names.FRF].attrs)
    return ds, truth
