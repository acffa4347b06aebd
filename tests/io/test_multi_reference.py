"""Multi-reference FRF Datasets (issue 13 item 1): dims (reference, point, frequency).

Construction and validation, SIMO Datasets unchanged, netCDF and UFF round trips, the MIMO H1
output of ``frf``, and the AMI phases refusing multi-reference data until they support it.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import (
    AmiXrValueError,
    AssumptionWarning,
    DataFileError,
    IdentificationError,
    SchemaError,
)
from ami_xr.io.datasets import make_frf_dataset, select_reference
from ami_xr.io.schema import drive_points
from ami_xr.io.uff.read import ATTR_UNITS_ASSUMED
from ami_xr.simulate import modal

from ..reference import EPS

pyuff = pytest.importorskip("pyuff")

POINTS = ["a", "b", "c"]


def _model():
    """A damped 3-DOF chain (points a, b, c) with modes near 13, 36 and 52 Hz."""
    m = np.diag([1.0, 1.5, 0.8])
    k = np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]]) * 4e4
    c = 2e-4 * k + 0.8 * m
    return modal.modal_model(m, c, k, point_labels=POINTS)


def _mimo(references=("a", "c"), n=64):
    return modal.frf(_model(), np.linspace(0.0, 80.0, n), references=list(references))


# --- make_frf_dataset and validate -------------------------------------------------------------


def test_make_frf_dataset_accepts_a_3d_array():
    values = np.arange(24).reshape(2, 3, 4) * (1 + 1j)
    ds = make_frf_dataset(values, [0.0, 1.0, 2.0, 3.0], points=[1, 2, 3], references=[1, 7])
    assert ds[names.FRF].dims == (names.REFERENCE, names.POINT, names.FREQUENCY)
    assert ds[names.REFERENCE].values.tolist() == [1, 7]
    assert names.ATTR_DRIVE_POINT not in ds.attrs
    np.testing.assert_array_equal(ds[names.FRF].values, values)
    assert ami_xr.validate(ds) is ds
    assert drive_points(ds) == [1]  # reference 1 is point 1; reference 7 is not measured


def test_make_frf_dataset_errors_name_the_argument():
    f = [0.0, 1.0, 2.0]
    with pytest.raises(SchemaError, match=r"argument 'drive_point': not used with a 'reference'"):
        make_frf_dataset(np.ones((2, 2, 3), complex), f, references=[0, 1], drive_point=0)
    with pytest.raises(SchemaError, match=r"argument 'references': expected int labels like"):
        make_frf_dataset(np.ones((2, 2, 3), complex), f, references=["x", "y"])
    with pytest.raises(SchemaError, match=r"argument 'references': expected unique labels"):
        make_frf_dataset(np.ones((2, 2, 3), complex), f, references=[0, 0])
    with pytest.raises(AmiXrValueError, match=r"references: expected 2 labels"):
        make_frf_dataset(np.ones((2, 2, 3), complex), f, references=[0, 1, 2])
    with pytest.raises(AmiXrValueError, match=r"references: given, but frf has shape \(2, 3\)"):
        make_frf_dataset(np.ones((2, 3), complex), f, references=[0])
    with pytest.raises(AmiXrValueError, match=r"frf: expected shape .*n_reference"):
        make_frf_dataset(np.ones((1, 2, 2, 3), complex), f)


def test_validate_multi_reference_problems_name_the_dim_or_attribute():
    ds = _mimo()
    assert ami_xr.validate(ds) is ds
    assert drive_points(ds) == ["a", "c"]
    swapped = ds.transpose(names.POINT, names.REFERENCE, names.FREQUENCY)
    with pytest.raises(SchemaError, match=r"variable 'frf': expected dims \('reference', 'point'"):
        ami_xr.validate(swapped)
    with pytest.raises(SchemaError, match=r"attribute 'drive_point': not used with a 'reference'"):
        ami_xr.validate(ds.assign_attrs(drive_point="a"))
    off = ds.assign_coords({names.REFERENCE: ["x", "y"]})
    with pytest.raises(SchemaError, match=r"coordinate 'reference': no reference \['x', 'y'\]"):
        ami_xr.validate(off)
    assert ami_xr.validate(off, require_drive_point=False) is off
    with pytest.raises(SchemaError, match=r"coordinate 'reference': expected str labels"):
        ami_xr.validate(ds.assign_coords({names.REFERENCE: [0, 2]}))


def test_simo_datasets_are_unchanged():
    values = np.ones((2, 3), complex)
    ds = make_frf_dataset(values, [0.0, 1.0, 2.0], points=[4, 5], drive_point=4)
    assert ds[names.FRF].dims == (names.POINT, names.FREQUENCY)
    assert names.REFERENCE not in ds.dims and ds.attrs[names.ATTR_DRIVE_POINT] == 4
    assert ami_xr.validate(ds) is ds
    assert drive_points(ds) == [4]
    simo = modal.frf(_model(), np.linspace(0.0, 80.0, 16), drive_point="b")
    assert names.REFERENCE not in simo.dims and simo.attrs[names.ATTR_DRIVE_POINT] == "b"


def test_select_reference_gives_the_simo_dataset_with_its_drive_point():
    ds = _mimo()
    one = select_reference(ds, "c")
    assert names.REFERENCE not in one.coords
    assert one.attrs[names.ATTR_DRIVE_POINT] == "c"
    assert ami_xr.validate(one) is one
    simo = modal.frf(_model(), ds[names.FREQUENCY].values, drive_point="c")
    np.testing.assert_array_equal(one[names.FRF].values, simo[names.FRF].values)
    with pytest.raises(AmiXrValueError, match="reference: 'z' is not one of"):
        select_reference(ds, "z")


def test_simulator_frf_is_reciprocal_and_matches_simo():
    ds = _mimo(("a", "b", "c"))
    h = ds[names.FRF].values
    scale = np.abs(h).max()
    # G_ij = G_ji: both are sums of lam Phi_i Phi_j terms, the same products in another order
    np.testing.assert_allclose(h, h.transpose(1, 0, 2), rtol=0, atol=1e-13 * scale)
    with pytest.raises(AmiXrValueError, match="references: expected unique labels among"):
        modal.frf(_model(), [1.0, 2.0], references=["a", "q"])
    with pytest.raises(AmiXrValueError, match="drive_point: not used with references"):
        modal.frf(_model(), [1.0, 2.0], drive_point="a", references=["a"])


# --- files ---------------------------------------------------------------------------------------


def test_netcdf_round_trip_is_bit_exact(tmp_path):
    ds = _mimo()
    path = ami_xr.to_netcdf(ds, tmp_path / "mimo.nc")
    back = ami_xr.open_dataset(path).load()
    assert back[names.FRF].dims == (names.REFERENCE, names.POINT, names.FREQUENCY)
    assert back[names.REFERENCE].values.tolist() == ["a", "c"]
    got = back[names.FRF].values
    assert got.dtype == np.complex128
    np.testing.assert_array_equal(got.view(np.uint64), ds[names.FRF].values.view(np.uint64))
    assert ami_xr.validate(back) is back


def _ref_dofs(path):
    sets = pyuff.UFF(str(path)).read_sets()
    sets = sets if isinstance(sets, list) else [sets]
    return [
        (int(s["ref_node"]), int(s["ref_dir"]), int(s["rsp_node"]), int(s["rsp_dir"]))
        for s in sets
        if s.get("type") == 58 and int(s["func_type"]) == 4
    ]


def test_uff_round_trip_keeps_the_reference_of_every_frf(tmp_path):
    labels = ["1+Z", "2+Z", "3+Y"]
    ds = _mimo(("a", "c")).assign_coords({names.POINT: labels, names.REFERENCE: ["1+Z", "3+Y"]})
    path = ami_xr.write_uff(ds, tmp_path / "mimo.uff", binary=True)
    dofs = _ref_dofs(path)
    assert sorted(dofs) == sorted(
        (rn, rd, pn, pd) for rn, rd in [(1, 3), (3, 2)] for pn, pd in [(1, 3), (2, 3), (3, 2)]
    )
    back = ami_xr.read_uff(path)
    assert back[names.FRF].dims == (names.REFERENCE, names.POINT, names.FREQUENCY)
    assert back[names.REFERENCE].values.tolist() == ["1+Z", "3+Y"]
    assert back[names.POINT].values.tolist() == labels
    assert names.ATTR_DRIVE_POINT not in back.attrs
    assert back.attrs["uff_layout"].startswith("multi-reference")
    np.testing.assert_array_equal(back[names.FRF].values, ds[names.FRF].values)  # binary: exact
    # a reference that is not a measured point keeps its own DOF too
    far = ds.assign_coords({names.REFERENCE: ["1+Z", "9-X"]})
    back = ami_xr.read_uff(ami_xr.write_uff(far, tmp_path / "far.uff", binary=True))
    assert back[names.REFERENCE].values.tolist() == ["1+Z", "9-X"]
    assert (9, -1, 2, 3) in _ref_dofs(tmp_path / "far.uff")


def test_uff_multi_reference_with_coherence_and_str_labels(tmp_path):
    ds = _mimo(("a", "c"))
    ds[names.COHERENCE] = (
        (names.POINT, names.FREQUENCY),
        np.full((3, ds.sizes[names.FREQUENCY]), 0.75),
        {names.ATTR_UNITS: "1"},
    )
    back = ami_xr.read_uff(ami_xr.write_uff(ds, tmp_path / "coh.uff"))
    assert back[names.REFERENCE].values.tolist() == ["a", "c"]
    assert back[names.POINT].values.tolist() == POINTS
    np.testing.assert_array_equal(back[names.COHERENCE].values, 0.75)
    # ASCII dataset 58 keeps about 12 significant digits
    np.testing.assert_allclose(
        back[names.FRF].values, ds[names.FRF].values, rtol=1e-10, atol=1e-12 * 3e-4
    )


def _record(rsp, ref, data):
    return pyuff.prepare_58(
        binary=0,
        func_type=4,
        rsp_node=rsp,
        rsp_dir=3,
        ref_node=ref,
        ref_dir=3,
        data=data,
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


def test_uff_read_several_references_and_responses(tmp_path):
    pairs = [(rsp, ref) for ref in (1, 5) for rsp in (1, 2, 3)]
    recs = [_record(rsp, ref, np.full(4, rsp + 10j * ref)) for rsp, ref in pairs]
    path = tmp_path / "grid.uff"
    pyuff.UFF(str(path)).write_sets(recs, mode="add")
    with pytest.warns(AssumptionWarning, match="grid.uff: the file gives no usable unit") as rec:
        ds = ami_xr.read_uff(path)
    assert rec[0].filename == __file__  # the warning points at the caller
    assert ds.attrs[ATTR_UNITS_ASSUMED]
    assert ds[names.REFERENCE].values.tolist() == ["1+Z", "5+Z"]
    assert ds[names.POINT].values.tolist() == ["1+Z", "2+Z", "3+Z"]
    np.testing.assert_array_equal(ds[names.FRF].sel(reference="5+Z", point="2+Z").values, 2 + 50j)
    assert drive_points(ds) == ["1+Z"]
    # one pair missing: refused, naming it
    holey = tmp_path / "holey.uff"
    pyuff.UFF(str(holey)).write_sets(recs[:-1], mode="add")
    with pytest.raises(DataFileError, match=r"lack the pairs \[\('5\+Z', '3\+Z'\)\]"):
        ami_xr.read_uff(holey)


def test_uff_roving_hammer_stays_simo(tmp_path):
    # one response, several references: by reciprocity a SIMO Dataset (unchanged behaviour)
    recs = [_record(2, ref, np.full(4, ref + 1j)) for ref in (1, 2, 3)]
    path = tmp_path / "roving.uff"
    pyuff.UFF(str(path)).write_sets(recs, mode="add")
    with pytest.warns(AssumptionWarning, match="no usable unit"):
        ds = ami_xr.read_uff(path)
    assert names.REFERENCE not in ds.dims
    assert ds.attrs[names.ATTR_DRIVE_POINT] == "2+Z"
    assert ds.attrs["uff_layout"].startswith("roving hammer")


# --- MIMO H1 from time data --------------------------------------------------------------------


def test_frf_with_two_force_channels_validates_and_equals_the_simulator():
    """Noise-free 2-input data: each record's responses are the exact circular responses
    Y_r = H F_r of the simulator's H on the rfft grid, so H1 over the two records is H up to
    rounding: the two-input analogue of ``assert_fft_ratio_close``'s bound."""
    fs, n = 256.0, 511  # odd: no Nyquist line (irfft would drop its imaginary part)
    freq = np.fft.rfftfreq(n, 1 / fs)
    h = modal.frf(_model(), freq, references=["a", "c"])[names.FRF].values  # (ref, point, f)
    rng = np.random.default_rng(5)
    force = rng.standard_normal((2, 2, n))  # (record, reference, time)
    big_f = np.fft.rfft(force, axis=-1)
    resp = np.fft.irfft(np.einsum("jpk,rjk->rpk", h, big_f), n, axis=-1)  # (record, point, time)
    ds = xr.Dataset(
        {
            names.RESPONSE: ((names.RECORD, names.POINT, names.TIME), resp),
            names.FORCE: ((names.RECORD, names.REFERENCE, names.TIME), force),
        },
        coords={
            names.RECORD: [0, 1],
            names.POINT: POINTS,
            names.REFERENCE: ["a", "c"],
            names.TIME: np.arange(n) / fs,
        },
        attrs={
            names.ATTR_RESPONSE_UNITS: "m",
            names.ATTR_FORCE_UNITS: "N",
            names.ATTR_QUANTITY: "displacement",
            names.ATTR_DRIVE_POINT: "a",
        },
    )
    est = ami_xr.frf(ds, nperseg=n, window="boxcar", detrend=False)
    assert ami_xr.validate(est) is est
    assert names.ATTR_DRIVE_POINT not in est.attrs
    assert drive_points(est) == ["a", "c"]
    got = est[names.FRF].transpose(names.REFERENCE, names.POINT, names.FREQUENCY).values
    np.testing.assert_array_equal(est[names.FREQUENCY].values, freq)
    # H = Y F^-1 per line (two records, two references). FFT rounding: each bin of Y and F off
    # by at most unit * ||signal|| (as in assert_fft_ratio_close), so H is off by
    # (||dY|| + ||H|| ||dF||) ||F^-1||; the 2x2 normal-equation solve adds eps * cond(F)^2 * ||H||.
    unit = 10 * EPS * np.log2(n) * np.sqrt(n)
    d_y = unit * np.sqrt((np.linalg.norm(resp, axis=-1) ** 2).sum(axis=0))  # (point,)
    d_f = unit * np.linalg.norm(force)
    fmat = big_f.transpose(2, 1, 0)  # (f, reference, record)
    sv = np.linalg.svd(fmat, compute_uv=False)
    inv_norm, cond = 1 / sv[:, -1], sv[:, 0] / sv[:, -1]
    h_norm = np.linalg.norm(h, axis=0)  # (point, f): norm over references
    tol = (d_y[:, None] + h_norm * d_f) * inv_norm + 10 * EPS * cond**2 * h_norm
    err = np.linalg.norm(got - h, axis=0)
    assert np.all(err <= tol), f"max error / bound = {np.max(err / tol):.3g}"


# --- the AMI phases on their own refuse multi-reference data (identify takes it) ----------------


@pytest.mark.parametrize("phase", ["subtract", "isolate", "global_fit"])
def test_ami_phases_refuse_multi_reference_with_a_clear_message(phase):
    ds = _mimo()
    with pytest.raises(IdentificationError) as info:
        getattr(ami_xr, phase)(ds)
    msg = str(info.value)
    assert "'reference' dim" in msg
    assert "does not take multi-reference data on its own: ami_xr.identify does" in msg
    assert "ds.sel(reference='a')" in msg
    assert isinstance(info.value, ValueError)
