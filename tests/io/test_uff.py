"""UFF import/export (ami_xr.io.uff): dataset 58 FRFs and time histories, 55 mode shapes."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami import identify
from ami_xr.errors import DataFileError
from ami_xr.io.uff import parse_point_label, point_label, read_uff, write_uff

from ..reference import SHARED_DATA

pyuff = pytest.importorskip("pyuff")

MEASUREMENT = SHARED_DATA / "measurement.uff"


def _frf(points, drive, seed=0, n=64):
    rng = np.random.default_rng(seed)
    values = rng.normal(size=(len(points), n)) + 1j * rng.normal(size=(len(points), n))
    return ami_xr.make_frf_dataset(
        values,
        np.arange(n) * 0.5,
        points=points,
        drive_point=drive,
        response_quantity="acceleration",
        response_units="m/s^2",
    )


@pytest.mark.parametrize(
    ("label", "dof"),
    [("1+Z", (1, 3)), ("12-X", (12, -1)), ("3+RY", (3, 5)), (7, (7, 0))],
)
def test_point_labels_round_trip(label, dof):
    assert parse_point_label(label) == dof
    assert point_label(*dof) == label
    assert parse_point_label("tip") is None


@pytest.mark.parametrize("binary", [False, True])
@pytest.mark.parametrize(
    ("points", "drive"),
    [(["1+Z", "2-Y", "3+X"], "1+Z"), (["tip", "m1", "m2"], "tip"), ([1, 2, 3], 2)],
)
def test_frf_58_round_trip(tmp_path, binary, points, drive):
    ds = _frf(points, drive)
    path = write_uff(ds, tmp_path / "frf.uff", binary=binary)
    raw = pyuff.UFF(str(path)).read_sets()
    assert [s["type"] for s in raw] == [58] * len(points)
    assert all(s["func_type"] == 4 and s["ordinate_spec_data_type"] == 12 for s in raw)
    back = read_uff(path)
    assert back[names.POINT].values.tolist() == points
    assert back.attrs[names.ATTR_DRIVE_POINT] == drive
    assert back.attrs[names.ATTR_QUANTITY] == "acceleration"
    assert back.attrs[names.ATTR_RESPONSE_UNITS] == "m/s^2"
    assert back[names.FRF].attrs["units"] == "m/s^2/N"
    # the frequency axis is stored as start and step of an even grid and rebuilt exactly (k * step
    # of exactly representable values)
    np.testing.assert_array_equal(back[names.FREQUENCY].values, ds[names.FREQUENCY].values)
    if binary:
        # binary 58 stores float64: no arithmetic
        np.testing.assert_array_equal(back[names.FRF].values, ds[names.FRF].values)
    else:  # ASCII holds about 12 significant digits
        # ASCII 58 writes %20.11e, 12 significant digits: half a unit in the last is 5e-12 relative
        # per component, for values near zero too (floating format)
        np.testing.assert_allclose(back[names.FRF].values, ds[names.FRF].values, rtol=1e-10)


def test_coherence_travels_with_frfs(tmp_path):
    ds = _frf(["1+Z", "2+Z"], "1+Z")
    ds[names.COHERENCE] = ((names.POINT, names.FREQUENCY), np.full((2, 64), 0.75))
    back = read_uff(write_uff(ds, tmp_path / "c.uff", binary=True))
    # stored as float64 and read back: no arithmetic
    np.testing.assert_array_equal(back[names.COHERENCE].values, ds[names.COHERENCE].values)


def _mode_shapes(points):
    rng = np.random.default_rng(1)
    vec = rng.normal(size=(len(points), 3)) + 1j * rng.normal(size=(len(points), 3))
    lam = np.array([-0.5 + 30j, -0.7 + 48j, -0.4 + 65j])
    return xr.Dataset(
        {
            names.EIGENVALUE: (names.MODE, lam),
            names.MODE_VECTOR: ((names.POINT, names.MODE), vec),
        },
        coords={names.POINT: points, names.MODE: [1, 2, 3]},
    )


@pytest.mark.parametrize("points", [["1+X", "1+Z", "2+Z", "4-Y"], ["tip", "m1", "m2"]])
def test_mode_shapes_55_round_trip(tmp_path, points):
    modes = _mode_shapes(points)
    path = write_uff(modes, tmp_path / "modes.uff")
    raw = pyuff.UFF(str(path)).read_sets()
    assert [s["type"] for s in raw] == [55, 55, 55]
    assert [s["mode_n"] for s in raw] == [1, 2, 3]
    # the test eigenvalues have <= 3 significant digits, which %13.5e holds exactly (the default
    # rtol never binds)
    np.testing.assert_allclose([s["eig"] for s in raw], modes[names.EIGENVALUE].values)
    back = read_uff(path)
    assert names.MODE_VECTOR in back and names.EIGENVALUE in back
    # as above: exact through %13.5e
    np.testing.assert_allclose(back[names.EIGENVALUE].values, modes[names.EIGENVALUE].values)
    if points[0] == "tip":  # free labels come back as node numbers (scalar DOF -> "n+Z")
        assert back.sizes[names.POINT] == 3
        got = back[names.MODE_VECTOR].values
    else:
        assert sorted(back[names.POINT].values.tolist()) == sorted(["1+X", "1+Z", "2+Z", "4+Y"])
        got = back[names.MODE_VECTOR].sel({names.POINT: ["1+X", "1+Z", "2+Z", "4+Y"]}).values
        got = got * np.array([1, 1, 1, -1])[:, None]  # "4-Y" is stored as -(+Y)
    # dataset 55 writes %13.5e, 6 significant digits: half a unit in the last is 5e-6 relative per
    # component (floating format, so none is "near zero")
    np.testing.assert_allclose(got, modes[names.MODE_VECTOR].values, rtol=1e-5)


def test_identification_result_writes_frfs_and_mode_shapes(tmp_path):
    ds = _frf(["1+Z", "2+Z", "3+Z"], "1+Z")
    modes = _mode_shapes(["1+Z", "2+Z", "3+Z"])
    result = ds.merge(modes)
    path = write_uff(result, tmp_path / "result.uff", binary=True)
    types = [s["type"] for s in pyuff.UFF(str(path)).read_sets()]
    assert types.count(58) == 3 and types.count(55) == 3
    # binary float64 round trip: no arithmetic
    xr.testing.assert_equal(read_uff(path)[names.FRF], ds[names.FRF])
    assert read_uff(path, kind="modes").sizes[names.MODE] == 3


def test_time_histories_58_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    resp = rng.normal(size=(2, 3, 128))
    force = rng.normal(size=(2, 128))
    ts = ami_xr.make_time_dataset(
        resp,
        fs=1024.0,
        force=force,
        points=["1+Z", "2+Z", "3+Z"],
        drive_point="1+Z",
        response_quantity="acceleration",
        response_units="m/s^2",
    )
    back = read_uff(write_uff(ts, tmp_path / "t.uff", binary=True))
    # binary float64 round trip: no arithmetic
    np.testing.assert_array_equal(back[names.RESPONSE].values, resp)
    np.testing.assert_array_equal(back[names.FORCE].values, force)
    # the time axis is stored as start and increment and rebuilt as k * dt: a few roundings of k dt;
    # the 0 s sample is exactly 0 in both
    np.testing.assert_allclose(back[names.TIME].values, ts[names.TIME].values, rtol=1e-12)
    assert back.attrs[names.ATTR_DRIVE_POINT] == "1+Z"
    ami_xr.validate(back)


def test_node_coordinates_become_point_coords(tmp_path):
    ds = _frf(["1+Z", "2+Z", "3+Z"], "1+Z")
    path = write_uff(ds, tmp_path / "geo.uff")
    nodes = pyuff.prepare_15(
        node_nums=[1, 2, 3],
        def_cs=[0] * 3,
        disp_cs=[0] * 3,
        color=[1] * 3,
        x=[0.0, 0.5, 1.0],
        y=[0.0] * 3,
        z=[0.0] * 3,
    )
    pyuff.UFF(str(path)).write_sets([nodes], mode="add")
    back = read_uff(path)
    # exactly representable coordinates through %13.5e: exact (the default rtol never binds)
    np.testing.assert_allclose(back["point_x"].values, [0.0, 0.5, 1.0])


def test_errors_name_the_file(tmp_path):
    with pytest.raises(DataFileError, match="does not exist"):
        read_uff(tmp_path / "missing.uff")
    bad = tmp_path / "bad.uff"
    bad.write_text("this is not a universal file\n")
    with pytest.raises(DataFileError, match="bad.uff"):
        read_uff(bad)
    # Several responses AND several references, but not one FRF per (reference, response)
    # pair: refused clearly (a full grid is read as multi-reference, test_multi_reference.py).
    recs = []
    for rsp, ref in [(1, 1), (2, 2)]:
        recs.append(
            pyuff.prepare_58(
                binary=0,
                func_type=4,
                rsp_node=rsp,
                rsp_dir=3,
                ref_node=ref,
                ref_dir=3,
                data=np.ones(4, complex),
                x=np.arange(4.0),
                abscissa_spacing=1,
                abscissa_min=0.0,
                abscissa_inc=1.0,
                ordinate_spec_data_type=12,
                orddenom_spec_data_type=13,
                abscissa_spec_data_type=18,
                id1="x",
                rsp_ent_name="a",
                ref_ent_name="a",
            )
        )
    multi = tmp_path / "multi.uff"
    pyuff.UFF(str(multi)).write_sets(recs, mode="add")
    with pytest.raises(DataFileError, match="reference"):
        read_uff(multi)
    with pytest.raises(DataFileError, match="no modes dataset"):
        read_uff(write_uff(_frf([1, 2], 1), tmp_path / "f.uff"), kind="modes")


def test_failed_write_leaves_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = write_uff(_frf([1, 2], 1), tmp_path / "f.uff")
    old = path.read_bytes()
    real_write_sets = pyuff.UFF.write_sets

    def half_write_then_fail(self, *args, **kwargs):
        real_write_sets(self, *args, **kwargs)
        with open(self._filename, "r+b") as f:  # damaged, as by a crash mid-write
            f.truncate(100)
        raise KeyboardInterrupt

    monkeypatch.setattr(pyuff.UFF, "write_sets", half_write_then_fail)
    with pytest.raises(KeyboardInterrupt):
        write_uff(_frf([1, 2], 1, seed=1), path)
    assert path.read_bytes() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.uff"]


# --- the real measurement ---------------------------------------------------------------------
needs_data = pytest.mark.skipif(not MEASUREMENT.is_file(), reason="shared/data folder absent")


@needs_data
def test_measurement_maps_roving_hammer_by_reciprocity():
    ds = read_uff(MEASUREMENT)
    ami_xr.validate(ds)
    assert ds[names.POINT].values.tolist() == ["1+X", "2+X", "3+X"]
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "1+X"  # the fixed response DOF
    assert ds.attrs["uff_layout"].startswith("roving hammer")
    assert ds.attrs[names.ATTR_FRF_TYPE] == "accelerance"
    assert ds.sizes[names.FREQUENCY] == 1001
    assert float(ds[names.FREQUENCY][-1]) == 1000.0


@needs_data
def test_measurement_converts_and_identifies_without_options(tmp_path):
    from ami_xr.app.cli import main

    nc = tmp_path / "measurement.nc"
    assert main(["convert", str(MEASUREMENT), "-o", str(nc)]) == 0
    ds = ami_xr.open_dataset(nc)
    xr.testing.assert_equal(ds[names.FRF], read_uff(MEASUREMENT)[names.FRF])
    result = identify(ds)
    fn = np.atleast_1d(result[names.NATURAL_FREQUENCY].values)
    assert fn.size >= 1
    assert np.all((fn > 0) & (fn < 1000))
    assert main(["identify", str(nc), "-o", str(tmp_path / "modes.nc"), "-q"]) == 0
