"""Point coordinates in UFF: written as dataset 15 (metres) and read back onto ``point``."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError, AssumptionWarning
from ami_xr.io.uff import read_uff, write_uff

pyuff = pytest.importorskip("pyuff")

POINTS = ["1+Z", "2+Z", "3+Z", "4-Y"]
XYZ = np.array([[0.0, 0.0, 0.0], [0.25, 0.0, 0.0], [0.5, 0.125, 0.0], [0.75, -0.3, 0.05]])
FREQ = np.arange(1, 33) * 0.5


def _frf(coordinates=XYZ, units="m"):
    rng = np.random.default_rng(5)
    shape = (len(POINTS), FREQ.size)
    return ami_xr.make_frf_dataset(
        rng.normal(size=shape) + 1j * rng.normal(size=shape),
        FREQ,
        points=POINTS,
        drive_point="1+Z",
        coordinates=coordinates,
        coordinate_units=units,
    )


def _node_sets(path, dataset=2411):
    return [s for s in pyuff.UFF(str(path)).read_sets() if s["type"] == dataset]


def test_coordinates_round_trip_through_dataset_2411_exactly(tmp_path):
    path = write_uff(_frf(), tmp_path / "g.uff")  # 2411 by default: double precision
    (nodes,) = _node_sets(path)
    assert _node_sets(path, 15) == []
    with pytest.raises(AmiXrValueError, match="geometry: expected 2411 or 15"):
        write_uff(_frf(), tmp_path / "x.uff", geometry=16)
    back = read_uff(path)
    for j, c in enumerate(names.POINT_COORDS):
        np.testing.assert_allclose(back[c].values, XYZ[:, j], rtol=1e-15, atol=0)


def test_coordinates_round_trip_through_dataset_15(tmp_path):
    from ami_xr.io.formats import write_any

    path = write_any(_frf(), tmp_path / "g.uff", geometry=15)
    (nodes,) = _node_sets(path, 15)
    assert _node_sets(path) == []
    assert list(map(int, nodes["node_nums"])) == [1, 2, 3, 4]
    back = read_uff(path)
    for j, c in enumerate(names.POINT_COORDS):
        # dataset 15 holds E13.5: 6 significant digits
        np.testing.assert_allclose(back[c].values, XYZ[:, j], rtol=1e-5, atol=1e-12)
        assert back[c].attrs[names.ATTR_UNITS] == "m"


def test_millimetres_are_written_as_metres(tmp_path):
    path = write_uff(_frf(XYZ * 1000, units="mm"), tmp_path / "mm.uff")
    np.testing.assert_allclose(read_uff(path)[names.POINT_X].values, XYZ[:, 0], rtol=1e-5)


def test_modes_only_file_gets_the_coordinates_too(tmp_path):
    ds = _frf().assign_coords({names.MODE: [1]})
    ds[names.EIGENVALUE] = (names.MODE, np.array([-0.5 + 30j]))
    ds[names.MODE_VECTOR] = ((names.POINT, names.MODE), np.ones((len(POINTS), 1), complex))
    path = write_uff(ds, tmp_path / "m.uff", include=("modes",))
    assert len(_node_sets(path)) == 1


def test_no_coordinates_no_node_dataset(tmp_path):
    path = write_uff(_frf(coordinates=None), tmp_path / "n.uff")
    assert _node_sets(path) == []
    assert names.POINT_X not in read_uff(path).coords


def test_unknown_length_units_are_not_written_and_the_user_is_told(tmp_path):
    with pytest.warns(AssumptionWarning, match="units 'furlong'.*not written"):
        path = write_uff(_frf(units="furlong"), tmp_path / "f.uff")
    assert _node_sets(path) == []


def test_two_dofs_of_one_node_at_different_places_are_not_written(tmp_path):
    ds = _frf().assign_coords({names.POINT: ["1+Z", "1+X", "3+Z", "4-Y"]})
    with pytest.warns(AssumptionWarning, match="shares node 1"):
        path = write_uff(ds, tmp_path / "c.uff")
    assert _node_sets(path) == []
    # the same node at the same place is fine
    same = ds.assign_coords(
        {c: ds[c].copy(data=np.r_[0.0, 0.0, ds[c].values[2:]]) for c in names.POINT_COORDS}
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssumptionWarning)
        path = write_uff(same, tmp_path / "s.uff")
    assert list(map(int, _node_sets(path)[0]["node_nums"])) == [1, 3, 4]
