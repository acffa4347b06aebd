"""Lines where an estimated FRF is NaN are named, explained and recorded (issue 33, item 4):
a clean two-sample pulse has no force power at the Nyquist line, where H1 = Gfy/Gff is 0/0."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.dsp.frf import ATTR_UNDEFINED_LINES, ATTR_UNDEFINED_REASON
from ami_xr.errors import AssumptionWarning

FS = 1024.0
N = 1024


def _pulse_test() -> xr.Dataset:
    """One hit of a two-sample pulse (spectrum exactly 0 at Nyquist) on a 100 Hz mode."""
    t = np.arange(N) / FS
    force = np.zeros(N)
    force[10:12] = 1.0
    h = np.exp(-5 * t) * np.sin(2 * np.pi * 100 * t)
    response = np.convolve(force, h)[:N]
    return ami_xr.make_time_dataset(
        response[None, None],
        fs=FS,
        force=force[None],
        points=["1+Z"],
        drive_point="1+Z",
        response_quantity="acceleration",
        response_units="m/s^2",
    )


def _undefined_warnings(caught) -> list[str]:
    return [
        str(w.message)
        for w in caught
        if issubclass(w.category, AssumptionWarning) and "FRF is NaN" in str(w.message)
    ]


def test_impact_frf_names_the_nyquist_line_and_why():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = ami_xr.impact_frf(_pulse_test())
    assert np.isnan(out[names.FRF].values[..., -1]).all()
    (message,) = _undefined_warnings(caught)
    assert "1 of 513 lines" in message
    assert "512 Hz" in message and "force autospectrum Gff is exactly 0" in message
    np.testing.assert_array_equal(out.attrs[ATTR_UNDEFINED_LINES], [512.0])
    assert "512 Hz" in out.attrs[ATTR_UNDEFINED_REASON]


def test_frf_names_every_nan_line():
    # boxcar, constant detrend: 0 Hz has no force power either
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = ami_xr.frf(_pulse_test(), window="boxcar", nperseg=N)
    nan_lines = out[names.FREQUENCY].values[~np.isfinite(out[names.FRF].values).any(axis=0)]
    np.testing.assert_array_equal(out.attrs[ATTR_UNDEFINED_LINES], nan_lines)
    np.testing.assert_array_equal(nan_lines, [0.0, 512.0])
    (message,) = _undefined_warnings(caught)
    assert "2 of 513 lines" in message and "0, 512 Hz" in message


def test_no_word_and_no_attribute_where_every_line_is_defined():
    rng = np.random.default_rng(0)
    ts = ami_xr.make_time_dataset(
        rng.normal(size=(1, 1, 4096)),
        fs=FS,
        force=rng.normal(size=(1, 4096)),
        points=["1+Z"],
        drive_point="1+Z",
        response_quantity="acceleration",
        response_units="m/s^2",
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = ami_xr.frf(ts, nperseg=512)
    assert not _undefined_warnings(caught)
    assert ATTR_UNDEFINED_LINES not in out.attrs and ATTR_UNDEFINED_REASON not in out.attrs


def test_the_record_survives_netcdf(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = ami_xr.impact_frf(_pulse_test())
    back = ami_xr.open_dataset(ami_xr.to_netcdf(out, tmp_path / "frf.nc"))
    np.testing.assert_array_equal(back.attrs[ATTR_UNDEFINED_LINES], [512.0])
    assert back.attrs[ATTR_UNDEFINED_REASON] == out.attrs[ATTR_UNDEFINED_REASON]


def test_identify_with_a_band_that_leaves_out_the_nan_line():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = ami_xr.impact_frf(_pulse_test())
        result = ami_xr.identify(ds, fmax=400.0)
    np.testing.assert_allclose(result[names.NATURAL_FREQUENCY].values, [100.0], rtol=1e-3)


def test_identify_over_the_nan_line_still_refuses_naming_it():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = ami_xr.impact_frf(_pulse_test())
    with pytest.raises(ValueError, match="finite"):
        ami_xr.identify(ds, fmin=0.0, fmax=FS / 2)
