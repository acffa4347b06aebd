"""Point coordinates point_x/y/z: the constructor, validate, the netCDF round trip and the
AMI phases keeping them (issue 12 item 5)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError, SchemaError

N_POINT = 5
X = np.linspace(0.0, 2.0, N_POINT)  # a beam-like line of points, m


def _frf(coordinates=None, **kwargs):
    return ami_xr.make_frf_dataset(
        np.ones((N_POINT, 4), complex), [0.0, 1.0, 2.0, 3.0], coordinates=coordinates, **kwargs
    )


@pytest.fixture(scope="module")
def beam_frf() -> xr.Dataset:
    """The 5-point random chain of the simulator, its points on a line 2 m long."""
    g, _ = ami_xr.simulate.random_system(
        n_points=N_POINT, n_modes=5, noise=0.02, seed=3, n_frequencies=1024
    )
    return g.assign_coords({names.POINT_X: (names.POINT, X, {names.ATTR_UNITS: "m"})})


@pytest.mark.parametrize(
    ("coordinates", "want"),
    [
        (np.c_[X, 2 * X], (names.POINT_X, names.POINT_Y)),
        (np.c_[X, 2 * X, 3 * X], names.POINT_COORDS),
        ({"x": X, "z": 3 * X}, (names.POINT_X, names.POINT_Z)),
        ({"point_y": 2 * X}, (names.POINT_Y,)),
        (X, (names.POINT_X,)),
    ],
)
def test_make_frf_dataset_writes_coordinates(coordinates, want):
    ds = _frf(coordinates)
    assert tuple(c for c in names.POINT_COORDS if c in ds.coords) == want
    factor = {names.POINT_X: 1, names.POINT_Y: 2, names.POINT_Z: 3}
    for name in want:
        assert ds[name].dims == (names.POINT,)
        assert ds[name].dtype == np.float64
        assert ds[name].attrs[names.ATTR_UNITS] == "m"
        np.testing.assert_array_equal(ds[name].values, factor[name] * X)
        assert name not in ds.indexes  # non-dimension coordinates
    assert ami_xr.validate(ds, require_drive_point=False) is ds


def test_coordinate_units_are_stored():
    ds = _frf(np.c_[X, X], coordinate_units="mm")
    assert ds[names.POINT_X].attrs[names.ATTR_UNITS] == "mm"


def test_no_coordinates_by_default():
    assert not any(c in _frf().coords for c in names.POINT_COORDS)


@pytest.mark.parametrize(
    ("coordinates", "match"),
    [
        (np.zeros((N_POINT - 1, 3)), r"coordinates: expected shape \(5, 2\)"),
        (np.zeros((N_POINT, 4)), r"coordinates: expected shape"),
        ({"x": X[:3]}, r"coordinates\['x'\]: expected 5 values"),
        ({"w": X}, r"coordinates: unknown key 'w'"),
        ({}, r"coordinates: expected at least one"),
        (np.c_[X, [0, np.nan, 0, 0, 0]], r"coordinates: expected finite values"),
        ({"y": ["a"] * N_POINT}, r"coordinates\['y'\]: expected real numbers"),
    ],
)
def test_make_frf_dataset_rejects_bad_coordinates(coordinates, match):
    with pytest.raises(AmiXrValueError, match=match):
        _frf(coordinates)


def test_bad_coordinate_units_rejected():
    with pytest.raises(AmiXrValueError, match="coordinate_units"):
        _frf(X, coordinate_units="")


def test_validate_names_a_non_finite_coordinate():
    ds = _frf(np.c_[X, X]).assign_coords(
        {names.POINT_Y: (names.POINT, [0.0, np.inf, 0, 0, 0], {names.ATTR_UNITS: "m"})}
    )
    with pytest.raises(SchemaError, match=r"coordinate 'point_y': expected finite values"):
        ami_xr.validate(ds, require_drive_point=False)


def test_validate_names_a_non_numeric_coordinate():
    ds = _frf().assign_coords({names.POINT_Z: (names.POINT, ["a", "b", "c", "d", "e"])})
    with pytest.raises(SchemaError, match=r"coordinate 'point_z': expected real numbers"):
        ami_xr.validate(ds, require_drive_point=False)


def test_validate_names_a_coordinate_of_the_wrong_length():
    ds = _frf().assign_coords({names.POINT_X: (names.FREQUENCY, [0.0, 1, 2, 3])})
    with pytest.raises(SchemaError, match=r"coordinate 'point_x': expected one value per point"):
        ami_xr.validate(ds, require_drive_point=False)


def test_validate_names_bad_coordinate_units():
    ds = _frf(X)
    ds[names.POINT_X].attrs[names.ATTR_UNITS] = 3
    with pytest.raises(SchemaError, match=r"attribute 'units' of variable 'point_x'"):
        ami_xr.validate(ds, require_drive_point=False)


def test_validate_checks_coordinates_of_time_datasets_too():
    ds = ami_xr.make_time_dataset(np.zeros((2, 8)), fs=100.0).assign_coords(
        {names.POINT_X: (names.POINT, [0.0, np.nan])}
    )
    with pytest.raises(SchemaError, match="point_x"):
        ami_xr.validate(ds, require_drive_point=False)


def test_netcdf_round_trip_keeps_coordinates(tmp_path):
    ds = _frf(np.c_[X, 2 * X, 3 * X], coordinate_units="mm")
    ami_xr.to_netcdf(ds, tmp_path / "geo.nc")
    with ami_xr.open_dataset(tmp_path / "geo.nc") as back:
        for name in names.POINT_COORDS:
            xr.testing.assert_identical(back[name].load(), ds[name])
            assert back[name].attrs[names.ATTR_UNITS] == "mm"
            assert name not in back.indexes


def _assert_coords_kept(out: xr.Dataset, ds: xr.Dataset) -> None:
    xr.testing.assert_identical(out[names.POINT_X], ds[names.POINT_X])


def test_coordinates_survive_the_phases(beam_frf):
    sub = ami_xr.subtract(beam_frf)
    _assert_coords_kept(sub, beam_frf)
    iso = ami_xr.isolate(sub)
    _assert_coords_kept(iso, beam_frf)
    fit = ami_xr.global_fit(iso)
    _assert_coords_kept(fit, beam_frf)
    _assert_coords_kept(ami_xr.refine(fit), beam_frf)
    # the inputs keep theirs too (xarray < 2025.6 cleared them inside apply_ufunc)
    for phase_input in (beam_frf, iso, fit):
        assert phase_input[names.POINT_X].attrs == {names.ATTR_UNITS: "m"}


def test_coordinates_survive_identify_and_netcdf(tmp_path, beam_frf):
    result = ami_xr.identify(beam_frf)
    _assert_coords_kept(result, beam_frf)
    ami_xr.to_netcdf(result, tmp_path / "modes.nc")
    with ami_xr.open_dataset(tmp_path / "modes.nc") as back:
        _assert_coords_kept(back.load(), beam_frf)
