"""Issue 24 item 4: ill-conditioned multi-input spectra are reported before any NaN is written."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError, AssumptionWarning


def _two_input(forces: np.ndarray) -> xr.Dataset:
    rng = np.random.default_rng(3)
    y = np.array([[2.0, 0.5], [-1.0, 3.0]]) @ forces + 0.01 * rng.standard_normal(forces.shape)
    return xr.Dataset(
        {
            names.RESPONSE: ((names.POINT, names.TIME), y),
            names.FORCE: ((names.REFERENCE, names.TIME), forces),
        },
        coords={
            names.POINT: ["a", "b"],
            names.REFERENCE: ["a", "b"],
            names.TIME: np.arange(forces.shape[1]) / 100.0,
        },
        attrs={
            names.ATTR_RESPONSE_UNITS: "m",
            names.ATTR_FORCE_UNITS: "N",
            names.ATTR_QUANTITY: "displacement",
        },
    )


def test_fully_correlated_inputs_are_an_error_not_an_all_nan_frf():
    f = np.random.default_rng(1).standard_normal(2**13)
    ds = _two_input(np.stack([f, f]))  # both actuators driven by the same signal
    with pytest.raises(AmiXrValueError, match="force channels \\['a', 'b'\\] are fully correlated"):
        ami_xr.frf(ds, nperseg=256)


def test_inputs_correlated_at_some_lines_warn_naming_them():
    rng = np.random.default_rng(1)
    n = 2**13
    f1 = rng.standard_normal(n)
    # the second input is the first plus sines on the lines below 20 Hz (periodic in a segment
    # of 256 samples, so no leakage with a boxcar window): above 20 Hz the two are identical
    t = np.arange(n) / 100.0
    f2 = f1 + sum(np.cos(2 * np.pi * k * 100.0 / 256 * t + rng.uniform(0, 6.3)) for k in range(52))
    ds = _two_input(np.stack([f1, f2]))
    with pytest.warns(AssumptionWarning, match="singular .* at \\d+ of 129 lines") as caught:
        est = ami_xr.frf(ds, nperseg=256, window="boxcar")
    assert caught[0].filename == __file__  # the caller's line
    h = est[names.FRF]
    f = est[names.FREQUENCY].values
    assert np.all(np.isnan(h.values[..., f > 30.0]))
    assert np.all(np.isfinite(h.values[..., (f > 1.0) & (f < 19.0)]))
