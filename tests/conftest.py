"""Shared fixtures. Append new fixtures at the bottom; keep each small and documented."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from ami_xr import make_frf_dataset, names
from ami_xr.kernels.modal_basis import mode_contribution

# Two modes of a 3-point system: eigenvalues lam = -zeta*wn + i*wd (rad/s) and residues
# A_jk = lam_k Phi_jk Phi_Pk (drive point P = point 1).
FRF_FIXTURE_FN_HZ = np.array([12.0, 31.0])
FRF_FIXTURE_ZETA = np.array([0.02, 0.035])
FRF_FIXTURE_PHI = np.array([[0.6, 0.9], [1.0, -0.4], [0.8, -1.1]])  # rows: points 1, 2, 3
FRF_FIXTURE_POINTS = [1, 2, 3]


def _frf_fixture_modes():
    wn = 2 * np.pi * FRF_FIXTURE_FN_HZ
    lam = -FRF_FIXTURE_ZETA * wn + 1j * wn * np.sqrt(1 - FRF_FIXTURE_ZETA**2)
    phi = FRF_FIXTURE_PHI.astype(complex)
    residue = lam[None, :] * phi * phi[0][None, :]
    return lam, residue


@pytest.fixture
def frf_truth() -> xr.Dataset:
    """Exact modes of ``frf_dataset``: ``eigenvalue`` (mode), ``residue`` (point, mode)."""
    lam, residue = _frf_fixture_modes()
    return xr.Dataset(
        {
            names.EIGENVALUE: ((names.MODE,), lam, {names.ATTR_UNITS: "rad/s"}),
            names.RESIDUE: ((names.POINT, names.MODE), residue),
            names.NATURAL_FREQUENCY: ((names.MODE,), FRF_FIXTURE_FN_HZ, {names.ATTR_UNITS: "Hz"}),
            names.DAMPING_RATIO: ((names.MODE,), FRF_FIXTURE_ZETA),
        },
        coords={names.POINT: FRF_FIXTURE_POINTS, names.MODE: [0, 1]},
    )


@pytest.fixture
def frf_dataset() -> xr.Dataset:
    """Noise-free analytic receptance (eq. 4): 3 points (labels 1, 2, 3; drive point 1),
    200 lines from 0.5 to 50 Hz, two modes at 12 and 31 Hz (see ``frf_truth``)."""
    lam, residue = _frf_fixture_modes()
    frequency = np.linspace(0.5, 50.0, 200)
    omega = 2 * np.pi * frequency
    frf = np.zeros((3, frequency.size), dtype=complex)
    for j in range(3):
        for k in range(lam.size):
            frf[j] += mode_contribution(omega, lam[k], residue[j, k])
    return make_frf_dataset(
        frf,
        frequency,
        points=FRF_FIXTURE_POINTS,
        drive_point=1,
        response_quantity="displacement",
        response_units="m",
        force_units="N",
        frf_source=names.SOURCE_ANALYTIC,
    )
