"""global_fit widens a band that holds too few lines (modes damped below the line spacing), says
so and records it, instead of failing; it still fails where no band can serve."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.errors import AssumptionWarning, IdentificationError

LAM = np.array([-0.02 + 2j * np.pi * 10.3, -0.03 + 2j * np.pi * 20.6])  # bandwidths << 1 Hz lines
PHI = np.array([[1.0, 0.5], [0.4, -1.0], [0.2, 0.3]])


def _dataset(freq):
    w = 2 * np.pi * freq
    res = PHI * PHI[0] * LAM  # drive point 0, eq. 8 scaling
    h = sum(
        res[:, k, None] / (1j * w - LAM[k]) + np.conj(res[:, k, None]) / (1j * w - np.conj(LAM[k]))
        for k in range(LAM.size)
    )
    ds = ami_xr.make_frf_dataset(h, freq, points=["a", "b", "c"], drive_point="a")
    return ds.assign_coords({names.MODE: [1, 2]}).assign({names.EIGENVALUE: (names.MODE, LAM)})


def test_too_narrow_band_is_widened_with_a_warning_and_an_attribute():
    ds = _dataset(np.arange(0.0, 30.0, 1.0))
    with pytest.warns(AssumptionWarning, match=r"global_fit: only \d+ lines .* widened to band="):
        out = ami_xr.global_fit(ds, band=1.0)
    used = out.attrs[names.ATTR_AMI_BAND_USED]
    assert used > 1.0 and np.log2(used) == int(np.log2(used))  # a doubling of the band given
    assert out.attrs[names.ATTR_AMI_BAND] == 1.0  # the setting as given stays recorded
    # the residues of the exact model are recovered from the lines of the widened band
    np.testing.assert_allclose(
        out[names.RESIDUE].transpose(names.POINT, names.MODE).values,
        PHI * PHI[0] * LAM,
        rtol=1e-8,
    )


def test_a_band_with_enough_lines_is_used_as_given():
    ds = _dataset(np.arange(0.0, 30.0, 0.005))
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)
        out = ami_xr.global_fit(ds, band=1.0)
    assert names.ATTR_AMI_BAND_USED not in out.attrs


def test_no_band_can_serve_still_fails_with_the_reason():
    # 8 lines (the least an FRF Dataset may have) but 8 modes in them: 16 real equations < 17
    lam = -0.02 + 2j * np.pi * (10.3 + np.arange(8))
    ds = _dataset(np.arange(10.0, 18.0, 1.0)).drop_vars([names.EIGENVALUE, names.MODE])
    ds = ds.assign_coords({names.MODE: np.arange(1, 9)}).assign(
        {names.EIGENVALUE: (names.MODE, lam)}
    )
    with pytest.raises(IdentificationError, match="band: 8 lines selected, the residue fit needs"):
        ami_xr.global_fit(ds, band=1.0)
