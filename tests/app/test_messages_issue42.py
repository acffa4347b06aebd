"""Issue 42 item 4: messages that say what is true.

* an FRF of magnitude below 2.2e-308 (subnormal) is scaled without overflow (the power-of-two
  scale was inf: the FRF became NaN and was refused as "not finite"), with no raw ldexp warning;
* a ``drive_point`` attribute that names no point is an error naming it (mode vectors were left
  unscaled without a word);
* a corrupt ``ami_xr_cf_added`` attribute is an error naming it (it was ignored and a later error
  blamed a missing coordinate).
"""

from __future__ import annotations

import warnings

import netCDF4
import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami.subtract import power_of_two_scale
from ami_xr.errors import DataFileError, IdentificationError


@pytest.mark.parametrize("peak", [1e-310, 2.0**-1074, 1e-300, 1e300, 1.7e308])
def test_power_of_two_scale_is_finite_and_a_normal_float(peak):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "overflow encountered in ldexp"
        scale = power_of_two_scale(peak)
    assert np.isfinite(scale) and scale >= np.finfo(float).tiny
    assert np.frexp(scale)[0] == 0.5  # a power of two: exact
    assert np.isfinite(peak * scale) and peak * scale > 2.0**-60


def test_power_of_two_scale_arrays_and_the_usual_range():
    scale = power_of_two_scale(np.array([1e-320, 1.0, 0.0, np.inf, 1e-3]))
    assert np.all(np.isfinite(scale))
    assert list(scale[1:]) == [1.0, 1.0, 1.0, 1.0]


@pytest.fixture(scope="module")
def small():
    g, _ = ami_xr.simulate.random_system(n_points=5, noise=0.01, seed=0, n_frequencies=256)
    return g


def test_a_subnormal_frf_is_identified_not_called_non_finite(small):
    peak = float(np.abs(small[names.FRF]).max())
    tiny = small.assign({names.FRF: small[names.FRF] / peak * 1e-310})
    reference = ami_xr.identify(small, refine=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        out = ami_xr.identify(tiny, refine=False)
    np.testing.assert_allclose(
        np.sort(out[names.NATURAL_FREQUENCY].values),
        np.sort(reference[names.NATURAL_FREQUENCY].values),
        rtol=1e-6,
    )


def test_a_drive_point_that_names_no_point_is_an_error_naming_it(small):
    bad = small.assign_attrs({names.ATTR_DRIVE_POINT: 99})
    with pytest.raises(IdentificationError, match=r"drive_point: 99 is not among the point"):
        ami_xr.identify(bad)
    unscaled = small.copy()
    unscaled.attrs.pop(names.ATTR_DRIVE_POINT, None)  # no attribute: unscaled, as asked
    out = ami_xr.identify(unscaled, refine=False)
    assert out.sizes[names.MODE] >= 1


@pytest.mark.parametrize(
    "marker, words",
    [
        ("{not json", "not valid JSON"),
        ("[1, 2]", "got a JSON list"),
        ('{"variables": [], "attrs": {}}', "'global' (missing)"),
        ('{"variables": {}, "attrs": {}, "global": {}}', "'variables' (dict)"),
    ],
)
def test_a_corrupt_cf_marker_is_an_error_naming_it(small, tmp_path, marker, words):
    path = tmp_path / "frf.nc"
    ami_xr.to_netcdf(small, path)
    with netCDF4.Dataset(path, "a") as nc:
        nc.setncattr("ami_xr_cf_added", marker)
    with pytest.raises(DataFileError, match="ami_xr_cf_added") as caught:
        ami_xr.open_dataset(path)
    assert words in str(caught.value) and str(path) in str(caught.value)
