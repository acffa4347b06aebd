"""identify on multi-reference FRFs (dims reference, point, frequency): ami_xr.ami.mimo."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami import mimo
from ami_xr.core import flags as qf
from ami_xr.core import mimo as cm
from ami_xr.core.modal import mac_matrix
from ami_xr.errors import AssumptionWarning
from ami_xr.io.datasets import select_reference
from ami_xr.simulate import modal
from ami_xr.tables import format_modal_table

from ..reference import damped_chain

POINTS = [1, 2, 3, 4, 5]
REFS = [1, 4]


def _chain():
    return damped_chain(POINTS)


def _noisy(ds: xr.Dataset, level: float, seed: int) -> xr.Dataset:
    """Complex Gaussian noise of standard deviation ``level`` x each FRF's peak."""
    rng = np.random.default_rng(seed)
    g = ds[names.FRF].values
    peak = np.abs(g).max(axis=-1, keepdims=True)
    e = (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)) / np.sqrt(2)
    return ds.assign({names.FRF: ds[names.FRF].copy(data=g + level * peak * e)})


def _identify(ds, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AssumptionWarning)
        return ami_xr.identify(ds, **kw)


@pytest.fixture(scope="module")
def chain():
    truth = _chain()
    ds = modal.frf(truth, np.linspace(0.0, 120.0, 1200), references=REFS)
    return truth, ds, _identify(ds)


def _phi(ds):
    return ds[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values


def test_noise_free_exact_poles_mode_vectors_and_participation(chain):
    truth, ds, out = chain
    lam, lam_true = out[names.EIGENVALUE].values, truth[names.EIGENVALUE].values
    assert lam.shape == lam_true.shape
    np.testing.assert_allclose(lam, lam_true, rtol=1e-6)
    phi, phi_true = _phi(out), _phi(truth)
    mac = np.diag(mac_matrix(np.concatenate([phi, phi_true], axis=1))[:5, 5:])
    assert np.all(mac > 0.999)
    # eq. 8 fixes the scale up to the square root's sign: phi = +-truth, exactly
    sign = np.sign((phi / phi_true).real[0])
    np.testing.assert_allclose(phi, phi_true * sign, rtol=1e-6, atol=1e-9 * np.abs(phi).max())
    # participation factors: L_r = phi at the reference's point (reciprocity)
    part = out[names.PARTICIPATION]
    assert part.dims == (names.MODE, names.REFERENCE)
    at_refs = phi[[POINTS.index(r) for r in REFS], :].T
    np.testing.assert_allclose(part.values, at_refs, rtol=1e-6, atol=1e-9 * np.abs(phi).max())
    assert np.all(out[names.DRIVE_POINT_CONSISTENCY].values < 1e-8)
    assert np.all(out[names.RANK_ONE_RATIO].values < 1e-8)
    assert not any(
        names.FLAG_REPEATED_ROOT in f for f in qf.flag_text(out[names.QUALITY_FLAGS].values)
    )


def test_outputs_are_on_reference_and_point(chain):
    _, ds, out = chain
    assert out[names.RESIDUE].dims == (names.REFERENCE, names.POINT, names.MODE)
    assert out[names.FRF_SYNTHESIZED].dims == (names.REFERENCE, names.POINT, names.FREQUENCY)
    assert out[names.MODE_VECTOR].dims == (names.POINT, names.MODE)
    assert out[names.DETECTED].dims == (names.POINT, names.MODE)
    assert out[names.MAC].dims == (names.MODE, names.MODE_2)
    assert out[names.REFERENCE].values.tolist() == REFS
    assert out[names.POINT].values.tolist() == POINTS
    xr.testing.assert_identical(out[names.FRF], ds[names.FRF])
    assert names.ATTR_DRIVE_POINT not in out.attrs
    assert out.attrs[names.ATTR_RANK_ONE_RATIO_MAX] == mimo.RANK_ONE_RATIO_MAX
    assert "stacked" in out.attrs[names.ATTR_MULTI_REFERENCE]
    assert set(out[names.SCALING_REFERENCE].values.astype(str)) <= {"1", "4"}
    # residues are the truth's lam phi_j phi_r (reference r on point r)
    truth = _chain()
    lam = truth[names.EIGENVALUE].values
    phi = _phi(truth)
    want = lam[None, None, :] * phi[None, :, :] * phi[[0, 3], :][:, None, :]
    np.testing.assert_allclose(out[names.RESIDUE].values, want, rtol=1e-6, atol=1e-12)
    text = format_modal_table(out)
    assert len(text.splitlines()) == 2 + 5 and "1 2 3 4 5" in text


def test_analysis_band_is_kept(chain):
    truth, ds, _ = chain
    # residual terms for the modes outside the band (without them the fit is biased, here as
    # in SIMO, and the bias can make a residue matrix look rank two)
    out = _identify(ds, fmin=15.0, fmax=60.0, residual_terms=True)
    f = out[names.FREQUENCY].values
    assert f[0] >= 15.0 and f[-1] <= 60.0
    assert out[names.FRF].dims == (names.REFERENCE, names.POINT, names.FREQUENCY)
    xr.testing.assert_identical(
        out[names.FRF], ds[names.FRF].sel({names.FREQUENCY: slice(15.0, 60.0)})
    )
    np.testing.assert_allclose(
        out[names.EIGENVALUE].values, truth[names.EIGENVALUE].values[1:], rtol=1e-4
    )
    # no quality flag; a mode the refinement's completion found instead of AMI says so
    flags = [f for f in qf.flag_text(out[names.QUALITY_FLAGS].values) if f != "added_by_refine"]
    assert not any(flags)


def test_written_and_read_back(chain, tmp_path):
    _, _, out = chain
    path = tmp_path / "mimo.nc"
    ami_xr.to_netcdf(out, path)
    back = ami_xr.open_dataset(path)
    for v in (names.RESIDUE, names.PARTICIPATION, names.MODE_VECTOR, names.RANK_ONE_RATIO):
        np.testing.assert_array_equal(back[v].values, out[v].values)
    assert back[names.RESIDUE].dims == (names.REFERENCE, names.POINT, names.MODE)


def test_one_percent_noise_finds_every_mode_with_consistent_scaling():
    truth = _chain()
    ds = _noisy(modal.frf(truth, np.linspace(0.0, 120.0, 1200), references=REFS), 0.01, 1)
    out = _identify(ds)
    fn, fn_true = out[names.NATURAL_FREQUENCY].values, truth[names.NATURAL_FREQUENCY].values
    assert fn.shape == fn_true.shape
    np.testing.assert_allclose(fn, fn_true, rtol=2e-3)
    phi, phi_true = _phi(out), _phi(truth)
    mac = np.diag(mac_matrix(np.concatenate([phi, phi_true], axis=1))[:5, 5:])
    assert np.all(mac > 0.98)
    assert np.all(out[names.DRIVE_POINT_CONSISTENCY].values < 0.15)
    # the residues' noise, not a second mode: no flag although s2/s1 of the weak modes is
    # a few percent
    assert not any(
        names.FLAG_REPEATED_ROOT in f for f in qf.flag_text(out[names.QUALITY_FLAGS].values)
    )
    # L_r = phi at the reference's point: exactly where the scale came from, within the
    # drive-point spread elsewhere
    part = out[names.PARTICIPATION].values
    at_refs = phi[[POINTS.index(r) for r in REFS], :].T
    used = [REFS.index(int(r)) for r in out[names.SCALING_REFERENCE].values]
    k = np.arange(phi.shape[1])
    np.testing.assert_allclose(part[k, used], at_refs[k, used], rtol=1e-9)
    assert np.all(np.abs(part - at_refs) <= 0.2 * np.abs(phi).max(axis=0)[:, None])


def _ring(split: float = 0.0) -> xr.Dataset:
    """Four equal masses on a ring (cyclic symmetry): modes at 15.9, 42.1 (a pair) and 57.4 Hz,
    built from mass-normalised real shapes (the pair: cos and sin waves), proportional
    damping; the pair's second frequency raised by ``split`` (a fraction)."""
    wn = 2 * np.pi * np.array([15.9155, 42.1084, 42.1084 * (1 + split), 57.3841])
    zeta = np.array([0.0075, 0.01, 0.01, 0.012])
    lam = -zeta * wn + 1j * wn * np.sqrt(1 - zeta**2)
    v = np.array([[1, 1, 1, 1], [1, 0, -1, 0], [0, 1, 0, -1], [1, -1, 1, -1]], float).T
    v /= np.linalg.norm(v, axis=0)
    # receptance residue v_j v_P / (2 i wd) = lam phi_j phi_P
    phi = v / np.sqrt(2j * lam.imag * lam)[None, :]
    return xr.Dataset(
        {
            names.EIGENVALUE: ((names.MODE,), lam),
            names.MODE_VECTOR: ((names.POINT, names.MODE), phi),
        },
        coords={names.POINT: [1, 2, 3, 4], names.MODE: [1, 2, 3, 4]},
        attrs={names.ATTR_FORCE_UNITS: "N"},
    )


def _pair_products(ds):
    """``Phi Phi^T`` of all modes (P, P): invariant under any rotation of a repeated pair."""
    phi = _phi(ds)
    return phi @ phi.T


def test_repeated_pair_is_separated_by_two_drive_points():
    truth = _ring()
    ds = modal.frf(truth, np.linspace(0.0, 80.0, 1000), references=[1, 2])
    with pytest.warns(AssumptionWarning, match="separated into two modes"):
        out = ami_xr.identify(ds)
    np.testing.assert_allclose(
        out[names.EIGENVALUE].values, truth[names.EIGENVALUE].values, rtol=1e-9
    )
    flags = qf.flag_text(out[names.QUALITY_FLAGS].values)
    assert [names.FLAG_REPEATED_ROOT_SEPARATED in f for f in flags] == [0, 1, 1, 0]
    assert not any(names.FLAG_REPEATED_ROOT in f.split(",") for f in flags)
    want = _pair_products(truth)
    np.testing.assert_allclose(_pair_products(out), want, atol=1e-9 * np.abs(want).max())
    np.testing.assert_allclose(out[names.MPC].values, 1.0)  # real shapes stay real
    assert out[names.MAC].values[1, 2] < 1e-9
    assert np.all(out[names.DRIVE_POINT_CONSISTENCY].values < 1e-9)
    assert out[names.RANK_ONE_RATIO].values[1] == pytest.approx(1.0, rel=1e-6)
    # the residues of the pair add up to the one pole's residue matrix
    res = out[names.RESIDUE].values
    lam = truth[names.EIGENVALUE].values
    phi = _phi(truth)
    pair = sum(lam[k] * np.outer(phi[[0, 1], k], phi[:, k]) for k in (1, 2))
    np.testing.assert_allclose(res[:, :, 1] + res[:, :, 2], pair, atol=1e-12)


def test_repeated_pair_separated_at_one_percent_noise():
    truth = _ring()
    ds = _noisy(modal.frf(truth, np.linspace(0.0, 80.0, 1000), references=[1, 2]), 0.01, 1)
    out = _identify(ds)
    flags = qf.flag_text(out[names.QUALITY_FLAGS].values)
    assert [names.FLAG_REPEATED_ROOT_SEPARATED in f for f in flags] == [0, 1, 1, 0]
    np.testing.assert_allclose(
        out[names.NATURAL_FREQUENCY].values, [15.9155, 42.1084, 42.1084, 57.3841], rtol=1e-3
    )
    want = _pair_products(truth)
    assert np.abs(_pair_products(out) - want).max() < 0.05 * np.abs(want).max()


def test_repeated_pair_with_one_drive_point_is_flagged_not_split():
    ds = modal.frf(_ring(), np.linspace(0.0, 80.0, 1000), references=[1, 2])
    ds = ds.assign_coords({names.REFERENCE: [1, 99]})  # the second force not on a point
    with pytest.warns(AssumptionWarning, match=names.FLAG_REPEATED_ROOT):
        out = ami_xr.identify(ds)
    fn = out[names.NATURAL_FREQUENCY].values
    assert fn.size == 3
    flags = qf.flag_text(out[names.QUALITY_FLAGS].values)
    assert [names.FLAG_REPEATED_ROOT in f.split(",") for f in flags] == [0, 1, 0]
    assert out[names.RANK_ONE_RATIO].values[1] == pytest.approx(1.0, rel=1e-6)


def test_references_on_a_nodal_line_of_the_pair_see_one_mode():
    """Forces at 1 and 3 excite only the cosine wave of the pair (the sine has nodes there):
    the residue matrix is rank one, nothing to flag or separate."""
    ds = modal.frf(_ring(), np.linspace(0.0, 80.0, 1000), references=[1, 3])
    out = _identify(ds)
    assert out.sizes[names.MODE] == 3
    assert np.all(out[names.RANK_ONE_RATIO].values < 1e-9)


def test_one_reference_cannot_tell_the_rank():
    """With one reference the pair looks like one mode (its FRFs are exactly those of one
    mode): the rank test has no information, rank_one_ratio is NaN and nothing is flagged."""
    ds = modal.frf(_ring(), np.linspace(0.0, 80.0, 1000), references=[1])
    out = _identify(ds)
    assert out.sizes[names.MODE] == 3
    assert np.all(np.isnan(out[names.RANK_ONE_RATIO].values))
    assert out[names.DRIVE_POINT_CONSISTENCY].values == pytest.approx(np.zeros(3))


def test_one_reference_gives_the_simo_poles_and_residues(chain):
    _, ds, _ = chain
    one = ds.isel({names.REFERENCE: [1]})
    multi = _identify(one)
    simo = _identify(select_reference(ds, 4))
    np.testing.assert_array_equal(multi[names.EIGENVALUE].values, simo[names.EIGENVALUE].values)
    np.testing.assert_array_equal(
        multi[names.RESIDUE].isel({names.REFERENCE: 0}).values, simo[names.RESIDUE].values
    )
    # the scaling is eq. 8 at the same drive point: the SIMO mode vectors
    np.testing.assert_allclose(_phi(multi), _phi(simo), rtol=1e-9, atol=1e-15)


def test_simo_dataset_does_not_take_the_multi_reference_path(monkeypatch, frf_dataset):
    before = _identify(frf_dataset)

    def refuse(*args, **kwargs):
        raise AssertionError("the multi-reference path was taken for a SIMO Dataset")

    monkeypatch.setattr(mimo, "identify_multi_reference", refuse)
    after = _identify(frf_dataset)
    xr.testing.assert_identical(before.drop_attrs(), after.drop_attrs())


def test_no_drive_point_leaves_mode_vectors_unscaled(chain):
    _, ds, _ = chain
    away = ds.assign_coords({names.REFERENCE: [98, 99]})
    with pytest.warns(AssumptionWarning, match="no reference"):
        out = ami_xr.identify(away)
    phi = _phi(out)
    np.testing.assert_allclose(np.abs(phi).max(axis=0), 1.0)
    assert np.all(np.isnan(out[names.DRIVE_POINT_CONSISTENCY].values))
    assert out[names.MODE_VECTOR].attrs[names.ATTR_SCALING].startswith("unit largest")


def test_phases_alone_point_at_identify(chain):
    _, ds, _ = chain
    with pytest.raises(ami_xr.errors.IdentificationError, match="ami_xr.identify does"):
        ami_xr.subtract(ds)


def test_sqrt_2x2_is_a_symmetric_square_root():
    m = np.array([[2.0 + 1j, 0.3], [0.3, 1.0 - 0.5j]])
    r = cm.sqrt_2x2(m)
    np.testing.assert_allclose(r @ r, m, atol=1e-14)
    np.testing.assert_allclose(r, r.T)
    assert cm.sqrt_2x2(np.zeros((2, 2))) is None


def test_rank_one_helpers_against_a_constructed_matrix():
    rng = np.random.default_rng(0)
    phi = rng.standard_normal((1, 6)) + 1j * rng.standard_normal((1, 6))
    lam = np.array([-1.0 + 50j])
    a = (lam[:, None, None] * phi[:, :, None] * phi[:, [0, 2], None].transpose(0, 2, 1)).reshape(
        1, 6, 2
    )
    u, s1, w, ratio = cm.rank_one(a)
    assert ratio[0] < 1e-14
    scales = cm.drive_point_scales(u, s1, w, lam, [(0, 0), (2, 1)])
    assert cm.aligned_spread(scales, np.array([0]))[0] < 1e-12
    got = u * scales[:, :1]
    assert np.allclose(got, phi) or np.allclose(got, -phi)
    part = cm.participation(s1, w, lam, scales[:, 0])
    np.testing.assert_allclose(part, got[:, [0, 2]], rtol=1e-12)


def test_report_refuses_an_unknown_reference_before_writing(chain, tmp_path):
    # multi-reference reports are built (tests/app/test_report_mimo.py); a wrong label is not
    pytest.importorskip("matplotlib")
    _, _, out = chain
    with pytest.raises(ValueError, match=r"reference: 'nope' is not one of the references"):
        ami_xr.report(out, tmp_path / "rep", reference="nope")
    assert not (tmp_path / "rep").exists()


def test_complete_false_adds_no_mode_on_any_run(chain):
    """``complete=False`` reaches every refinement of the multi-reference path (the stacked
    run, each reference's and the union refit): no mode is added by the refinement."""
    _, ds, _ = chain
    out = _identify(ds, fmin=15.0, fmax=60.0, residual_terms=True, complete=False)
    flags = qf.flag_text(out[names.QUALITY_FLAGS].values)
    assert not any("added_by_refine" in f for f in flags)
