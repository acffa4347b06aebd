"""ami_xr.stability: how each mode holds as the detection threshold and the band vary."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami.stability import variant_label
from ami_xr.errors import AmiXrValueError
from ami_xr.simulate import random_system

PFA = (1e-2, 1e-5)
TRIM = (0.0, 0.2)
FAKE_HZ = 11.65  # between the system's first two modes (5.58 and 17.73 Hz): no mode there


@pytest.fixture(scope="module")
def system():
    ds, truth = random_system(5, weak_mode=True, noise=0.03, seed=0, n_frequencies=1024)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = ami_xr.identify(ds)
    return ds, truth, ref


@pytest.fixture(scope="module")
def with_fake(system):
    """The reference with its second mode moved to an empty frequency (a spurious mode)."""
    ds, _, ref = system
    lam = ref[names.EIGENVALUE].values.copy()
    zeta = -lam[1].real / abs(lam[1])
    w = 2 * np.pi * FAKE_HZ
    lam[1] = -zeta * w + 1j * w * np.sqrt(1 - zeta**2)
    fake = ref.assign({names.EIGENVALUE: ref[names.EIGENVALUE].copy(data=lam)})
    fake[names.NATURAL_FREQUENCY] = fake[names.NATURAL_FREQUENCY].copy(data=np.abs(lam) / 2 / np.pi)
    return ds, ami_xr.stability(ds, fake, pfa=PFA, band_trim=TRIM)


def test_strong_modes_are_solid_a_spurious_one_is_not(with_fake):
    _, out = with_fake
    frac = out[names.STABILITY_FRACTION].values
    assert frac[1] == 0.0  # the spurious mode: found in no variant
    np.testing.assert_array_equal(frac[[0, 2, 3]], 1.0)  # the true modes: in every variant
    assert not out[names.STABILITY_FOUND].values[1].any()
    assert np.isnan(out[names.STABILITY_FREQUENCY_SPREAD].values[1])


def test_only_variants_whose_band_holds_the_mode_count(with_fake):
    _, out = with_fake
    fmin = out[names.STABILITY_FMIN].values
    assert fmin[0] < 5.0 < fmin[-1]  # the trimmed band starts above mode 1 (5.58 Hz)
    in_band = out[names.STABILITY_IN_BAND].sel({names.MODE: 1}).values
    np.testing.assert_array_equal(in_band, [True, True, False, False])
    assert out[names.STABILITY_FRACTION].sel({names.MODE: 1}).item() == 1.0


def test_variables_dims_coords_and_attrs(with_fake):
    _, out = with_fake
    n_mode = out.sizes[names.MODE]
    for var in (names.STABILITY_FOUND, names.STABILITY_IN_BAND, names.STABILITY_FREQUENCY):
        assert out[var].dims == (names.MODE, names.STABILITY_VARIANT)
        assert out[var].shape == (n_mode, len(PFA) * len(TRIM))
    assert out[names.STABILITY_FOUND].dtype == bool
    assert out[names.STABILITY_FRACTION].dims == (names.MODE,)
    assert out[names.STABILITY_FRACTION].attrs[names.ATTR_UNITS] == "1"
    assert out[names.STABILITY_FREQUENCY_SPREAD].attrs[names.ATTR_UNITS] == "Hz"
    assert out[names.STABILITY_FMIN].attrs[names.ATTR_UNITS] == "Hz"
    labels = out[names.STABILITY_VARIANT].values.tolist()
    assert labels == [
        "pfa=1e-2, full band",
        "pfa=1e-5, full band",
        "pfa=1e-2, band 20%-trimmed",
        "pfa=1e-5, band 20%-trimmed",
    ]
    np.testing.assert_array_equal(out[names.STABILITY_PFA].values, [1e-2, 1e-5, 1e-2, 1e-5])
    assert "stability_fraction" in out.attrs[names.ATTR_STABILITY_RULE]
    assert out.attrs[names.ATTR_STABILITY_TOLERANCE] == 1.0
    # the matched frequencies of the true modes are close to their reference frequencies
    f = out[names.STABILITY_FREQUENCY].values[[0, 2, 3]]
    fn = out[names.NATURAL_FREQUENCY].values[[0, 2, 3]]
    assert np.nanmax(np.abs(f - fn[:, None]) / fn[:, None]) < 0.01


def test_reference_outputs_unchanged(system):
    ds, _, ref = system
    out = ami_xr.stability(ds, ref, pfa=(1e-3,), band_trim=(0.0,))
    for var in ref.variables:
        xr.testing.assert_identical(out[var], ref[var])
    assert all(out.attrs[k] is v or out.attrs[k] == v for k, v in ref.attrs.items())
    # the reference's own threshold and band: every mode found again; one match, no spread
    np.testing.assert_array_equal(out[names.STABILITY_FRACTION].values, 1.0)
    assert np.isnan(out[names.STABILITY_FREQUENCY_SPREAD].values).all()


def test_netcdf_round_trip(with_fake, tmp_path):
    _, out = with_fake
    path = tmp_path / "stab.nc"
    ami_xr.to_netcdf(out, path)
    back = ami_xr.open_dataset(path)
    for var in (
        names.STABILITY_FOUND,
        names.STABILITY_IN_BAND,
        names.STABILITY_FREQUENCY,
        names.STABILITY_FRACTION,
        names.STABILITY_FREQUENCY_SPREAD,
    ):
        xr.testing.assert_identical(back[var].load(), out[var])
    assert back[names.STABILITY_FOUND].dtype == bool


def test_computes_the_reference_and_shows_progress(capsys):
    ds, _ = random_system(5, noise=0.01, seed=1, n_frequencies=512)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = ami_xr.stability(ds, pfa=(1e-3,), band_trim=(0.0,), progress=True)
    assert out.sizes[names.STABILITY_VARIANT] == 1
    np.testing.assert_array_equal(out[names.STABILITY_FRACTION].values, 1.0)
    assert "stability" in capsys.readouterr().err
    assert "stability_fraction" in ds.ami.stability(pfa=(1e-3,), band_trim=(0.0,))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"pfa": ()}, "pfa"),
        ({"pfa": (2.0,)}, "pfa"),
        ({"pfa": (1e-3, 1e-3)}, "pfa"),
        ({"band_trim": (0.6,)}, "band_trim"),
        ({"band_trim": "x"}, "band_trim"),
    ],
)
def test_bad_arguments_raise_before_any_work(system, kwargs, match):
    ds, _, ref = system
    with pytest.raises(AmiXrValueError, match=match):
        ami_xr.stability(ds, ref, **kwargs)


def test_bad_result(system):
    ds, _, _ = system
    with pytest.raises(AmiXrValueError, match="result"):
        ami_xr.stability(ds, ds)


def test_variant_label():
    assert variant_label(1e-3, 0.0) == "pfa=1e-3, full band"
    assert variant_label(5e-2, 0.1) == "pfa=5e-2, band 10%-trimmed"
