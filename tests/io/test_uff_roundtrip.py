"""UFF round trip (issue 12, item 6): modes survive convert, coherence is dimensionless, units
come from the labels or dataset 164 and an assumption is said on the terminal."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrWarning
from ami_xr.io.uff import read_uff, write_uff
from ami_xr.io.uff.read import ATTR_MODES_SKIPPED, ATTR_UNITS_ASSUMED, ATTR_UNITS_SCALED

pyuff = pytest.importorskip("pyuff")

POINTS = ["1+Z", "2+Z", "3-Y"]
FREQ = np.arange(1, 65) * 0.5


def _result() -> xr.Dataset:
    """FRFs with coherence and three modes, as an identification result holds them."""
    rng = np.random.default_rng(3)
    shape = (len(POINTS), FREQ.size)
    ds = ami_xr.make_frf_dataset(
        rng.normal(size=shape) + 1j * rng.normal(size=shape),
        FREQ,
        points=POINTS,
        drive_point="1+Z",
        response_quantity="acceleration",
        response_units="m/s^2",
    )
    ds[names.COHERENCE] = ((names.POINT, names.FREQUENCY), rng.uniform(0, 1, shape))
    lam = np.array([-0.5 + 30j, -1.2 + 75j, -2.0 + 140j])
    phi = np.array([[1.0, 0.5 - 0.1j, 0.25], [0.75, -1.0, 0.5j], [-0.5, 0.125, -1.0]])
    return ds.assign_coords({names.MODE: [1, 2, 3]}).assign(
        {
            names.EIGENVALUE: (names.MODE, lam),
            names.MODE_VECTOR: ((names.POINT, names.MODE), phi),
        }
    )


def test_convert_of_a_uff_export_keeps_the_mode_shapes(tmp_path):
    from ami_xr.app.cli import main

    result = _result()
    uff = write_uff(result, tmp_path / "result.uff")
    out = tmp_path / "back.nc"
    assert main(["convert", str(uff), "-o", str(out)]) == 0
    back = ami_xr.open_dataset(out)
    assert back[names.MODE].values.tolist() == [1, 2, 3]
    lam = result[names.EIGENVALUE].values
    # dataset 55 is written with %13.5e: 6 significant digits
    np.testing.assert_allclose(back[names.EIGENVALUE].values, lam, rtol=1e-5)
    np.testing.assert_allclose(back[names.NATURAL_FREQUENCY].values, np.abs(lam) / (2 * np.pi))
    np.testing.assert_allclose(back[names.DAMPING_RATIO].values, -lam.real / np.abs(lam))
    got = back[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
    np.testing.assert_allclose(got, result[names.MODE_VECTOR].values, rtol=1e-5, atol=1e-12)
    assert back[names.EIGENVALUE].attrs[names.ATTR_UNITS] == "rad/s"
    np.testing.assert_allclose(back[names.FRF].values, result[names.FRF].values, rtol=1e-10)


def test_modes_missing_a_point_are_left_out_with_a_warning(tmp_path):
    result = _result()
    uff = write_uff(result.isel({names.POINT: [0, 1]}), tmp_path / "modes.uff", include=["modes"])
    frfs = write_uff(result, tmp_path / "frfs.uff", include=["frf"])
    both = tmp_path / "both.uff"
    both.write_bytes(frfs.read_bytes() + uff.read_bytes())
    with pytest.warns(AmiXrWarning, match="not merged"):
        ds = read_uff(both)
    assert names.MODE_VECTOR not in ds and "3-Y" in ds.attrs[ATTR_MODES_SKIPPED]
    assert read_uff(both, kind="modes").sizes[names.MODE] == 3


def test_coherence_records_are_dimensionless(tmp_path):
    path = write_uff(_result(), tmp_path / "c.uff")
    sets = pyuff.UFF(str(path)).read_sets()
    coh = [s for s in sets if s["type"] == 58 and s["func_type"] == 6]
    frf = [s for s in sets if s["type"] == 58 and s["func_type"] == 4]
    assert len(coh) == len(POINTS)
    assert {s["ordinate_axis_units_lab"].strip() for s in coh} == {"1"}
    assert {s["orddenom_axis_units_lab"].strip() for s in coh} == {"NONE"}
    assert {s["ordinate_axis_units_lab"].strip() for s in frf} == {"m/s^2"}


def _write_raw(path, ordinate_label, denom_label, spec=8, units_164=None):
    """Dataset 58 FRFs (displacement over force) with the given unit labels, and optionally a
    dataset 164 (units_code, length factor, force factor) first."""
    sets = []
    if units_164 is not None:
        code, length, force = units_164
        sets.append(
            pyuff.prepare_164(
                units_code=code,
                units_description="test units",
                temp_mode=1,
                length=length,
                force=force,
                temp=1.0,
                temp_offset=273.15,
                return_full_dict=True,
            )
        )
    data = np.array([1.0 + 2.0j, 3.0 - 1.0j, 0.5 + 0.25j, 2.0 + 0j])
    for node in (1, 2):
        sets.append(
            pyuff.prepare_58(
                binary=0,
                id1="raw",
                func_type=4,
                rsp_node=node,
                rsp_dir=3,
                ref_node=1,
                ref_dir=3,
                ord_data_type=6,
                num_pts=data.size,
                abscissa_spacing=1,
                abscissa_min=1.0,
                abscissa_inc=1.0,
                abscissa_spec_data_type=18,
                ordinate_spec_data_type=spec,
                ordinate_axis_units_lab=ordinate_label,
                orddenom_spec_data_type=13,
                orddenom_axis_units_lab=denom_label,
                data=data * node,
                x=np.arange(1.0, 5.0),
            )
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pyuff.UFF(str(path)).write_sets(sets, mode="add")
    return data


def test_dataset_164_units_scale_to_si_without_a_warning(tmp_path):
    path = tmp_path / "mm.uff"
    data = _write_raw(path, "NONE", "NONE", units_164=(5, 1000.0, 1000.0))  # mm, mN
    with warnings.catch_warnings():
        warnings.simplefilter("error", AmiXrWarning)
        ds = read_uff(path)
    assert ds.attrs[names.ATTR_RESPONSE_UNITS] == "m" and ds.attrs[names.ATTR_FORCE_UNITS] == "N"
    # mm per mN = 1 m/N: the FRF keeps its values here, with the factors applied
    np.testing.assert_allclose(ds[names.FRF].values[1], 2 * data * (1 / 1000.0) / (1 / 1000.0))
    assert "dataset 164" in ds.attrs[ATTR_UNITS_SCALED] and ATTR_UNITS_ASSUMED not in ds.attrs

    path = tmp_path / "mm_n.uff"
    _write_raw(path, "NONE", "NONE", units_164=(9, 1000.0, 1.0))  # mm, N
    ds = read_uff(path)
    np.testing.assert_allclose(ds[names.FRF].values[0], data / 1000.0)
    assert ds[names.FRF].attrs[names.ATTR_UNITS] == "m/N"

    path = tmp_path / "si.uff"
    _write_raw(path, "NONE", "NONE", units_164=(1, 1.0, 1.0))
    ds = read_uff(path)  # SI said by dataset 164: nothing assumed, nothing scaled
    assert ATTR_UNITS_ASSUMED not in ds.attrs and ATTR_UNITS_SCALED not in ds.attrs


def test_assumed_units_are_said_on_the_terminal_and_recorded(tmp_path):
    path = tmp_path / "bare.uff"
    data = _write_raw(path, "NONE", "furlong")
    with pytest.warns(AmiXrWarning, match=r"assumed SI.*force in N \(unknown unit label"):
        ds = read_uff(path)
    assert "response in m (no label)" in ds.attrs[ATTR_UNITS_ASSUMED]
    np.testing.assert_array_equal(ds[names.FRF].values[0], data)


def test_a_file_in_g_is_read_in_g(tmp_path):
    path = tmp_path / "g.uff"
    data = _write_raw(path, "G", "n", spec=12)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AmiXrWarning)
        ds = read_uff(path)
    assert ds.attrs[names.ATTR_RESPONSE_UNITS] == "g" and ds.attrs[names.ATTR_FORCE_UNITS] == "N"
    assert ds[names.FRF].attrs[names.ATTR_UNITS] == "g/N"
    np.testing.assert_array_equal(ds[names.FRF].values[0], data)  # not rescaled
