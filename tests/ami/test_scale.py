"""Identification of many points (issue 21): compression, the compressed path against the
uncompressed one, and the dask-backed path against the in-memory one."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami import pipeline, scale
from ami_xr.ami.global_fit import receptance_mode_vectors
from ami_xr.ami.settings import GlobalFitSettings, IdentifySettings
from ami_xr.core import compress as cz
from ami_xr.core import flags
from ami_xr.errors import AmiXrValueError, IdentificationError
from ami_xr.simulate import frf, score_modes
from ami_xr.simulate.spread import many_points


@pytest.fixture(scope="module")
def three_hundred():
    """300 points x 512 lines, 6 modes, 2 % noise."""
    return many_points(300, 512, 6, noise=0.02, seed=3)


def _identify(ds, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ami_xr.identify(ds, **kw)


def test_noise_free_low_rank_is_kept_whole():
    # noise-free FRFs of 5 real modes: rank 5 in real form; the basis keeps all their energy
    ds, _ = many_points(60, 256, 5, noise=0.0, seed=1)
    h = ds[names.FRF].values
    v, s = cz.compress_array(h, 12, weighted=False)
    assert v.shape == (5, 256)  # directions of zero energy dropped: the exact rank
    hr = cz.real_form(h)
    assert np.sum(s**2) == pytest.approx(np.sum(hr**2), rel=1e-10)
    # every FRF lies in the span of the virtual FRFs' real form (projection residual ~ 0)
    basis = np.linalg.svd(cz.real_form(v), full_matrices=False)[2]
    resid = hr - (hr @ basis.T) @ basis
    assert np.linalg.norm(resid) < 1e-9 * np.linalg.norm(hr)


def test_virtual_noise_is_unit():
    # pure complex noise of different levels per point: weighted and combined, unit again
    rng = np.random.default_rng(0)
    sigma = rng.uniform(0.1, 10.0, 400)
    h = sigma[:, None] * (rng.standard_normal((400, 1024)) + 1j * rng.standard_normal((400, 1024)))
    h /= np.sqrt(2.0)
    v, _ = cz.compress_array(h, 8, power_iterations=0)
    # Weighted, every point's noise is unit, whatever its level (0.1 .. 10); the kept directions
    # are those where this draw of the noise is largest, by at most the Marchenko-Pastur edge
    # (1 + sqrt(P / 2L))^2 = 1.9 in energy, and with one pass much less than that.
    power = np.mean(np.abs(v) ** 2)
    assert 0.95 < power < 1.5
    unweighted, _ = cz.compress_array(h, 8, power_iterations=0, weighted=False)
    assert np.mean(np.abs(unweighted) ** 2) > 30.0  # the loud points dominate


def test_signal_rank_counts_above_the_noise_edge():
    edge = np.sqrt(0.5) * (np.sqrt(100) + np.sqrt(2 * 50))
    s = np.array([10.0, 3.0, 1.2, 1.0, 0.9, 0.8, 0.7, 0.6]) * edge
    assert cz.signal_rank(s, 100, 50, extra=2) == 5  # 3 above 1.05 edge, plus 2
    assert cz.signal_rank(s[:2], 100, 50, extra=4) == 2  # never more than there are


def test_resolve_settings():
    assert scale.resolve("auto", 192) is None
    assert scale.resolve("auto", 193).rank == scale.DEFAULT_RANK
    assert scale.resolve("off", 10_000) is None
    assert scale.resolve(16, 100).rank == 16
    assert scale.resolve(100, 100) is None
    with pytest.raises(IdentificationError, match="compress"):
        scale.resolve("always", 1000)
    with pytest.raises(IdentificationError, match="compress"):
        scale.resolve(0, 1000)


def test_small_sets_are_not_compressed():
    ds, _ = many_points(20, 256, 5, seed=2)
    out = _identify(ds)
    assert scale.ATTR_COMPRESS_RANK not in out.attrs
    assert names.DETECTED in out  # the per-point outputs of the phases


def test_compressed_matches_uncompressed(three_hundred):
    ds, truth = three_hundred
    comp = _identify(ds)
    full = _identify(ds, compress="off")
    assert comp.attrs[scale.ATTR_COMPRESS_RANK] < 20
    assert comp[names.RESIDUE].dims == (names.POINT, names.MODE)
    assert comp[names.RESIDUE].shape == (300, full.sizes[names.MODE])
    assert list(comp[names.POINT].values) == list(ds[names.POINT].values)
    lam_c, lam_f = comp[names.EIGENVALUE].values, full[names.EIGENVALUE].values
    assert lam_c.size == lam_f.size
    # The compression drops only what lies outside the kept subspace (noise) and weights each
    # point by its noise floor where the refinement profiles each point's variance: two
    # estimators from the same data with slightly different weights, so they differ by less
    # than two standard errors of the uncompressed one (the last mode, near the band edge, has
    # the largest: 2.6 rad/s, a difference of 1.03 of it).
    std = 2.0 * full[names.EIGENVALUE_STD].values
    assert np.all(np.abs(lam_c.real - lam_f.real) < std.real)
    assert np.all(np.abs(lam_c.imag - lam_f.imag) < std.imag)
    fn_std = 2.0 * full[names.NATURAL_FREQUENCY_STD].values
    z_std = 2.0 * full[names.DAMPING_RATIO_STD].values
    assert np.all(
        np.abs(comp[names.NATURAL_FREQUENCY].values - full[names.NATURAL_FREQUENCY]) < fn_std
    )
    assert np.all(np.abs(comp[names.DAMPING_RATIO].values - full[names.DAMPING_RATIO]) < z_std)
    # every true mode found by both
    truth_lam = truth[names.EIGENVALUE].values
    assert score_modes(lam_c, truth_lam).n_found == score_modes(lam_f, truth_lam).n_found == 6
    # residues: the exact per-point solution at nearly the same eigenvalues
    rel = np.abs(comp[names.RESIDUE].values - full[names.RESIDUE].values)
    assert np.max(rel) < 0.01 * np.max(np.abs(full[names.RESIDUE].values))
    # synthesized FRFs reproduce the data to the noise level at every point
    resid = np.sqrt(np.mean(np.abs(comp[names.FRF_RESIDUAL].values) ** 2, axis=1))
    assert np.all(resid < 2.0 * comp[names.FRF_NOISE_STD].values + 1e-30)
    mac = np.diag(comp[names.MAC].values)
    np.testing.assert_allclose(mac, 1.0, rtol=1e-12)


def test_dask_backed_equals_in_memory():
    pytest.importorskip("dask")
    ds, _ = many_points(400, 256, 5, noise=0.02, seed=4)
    mem = _identify(ds, compress=24)
    lazy = _identify(ds.chunk({names.POINT: 70}), compress=24)
    assert hasattr(lazy[names.FRF_SYNTHESIZED].data, "dask")  # never gathered
    for v in (names.EIGENVALUE, names.RESIDUE, names.MODE_VECTOR, names.FRF_SYNTHESIZED):
        x, y = mem[v].values, lazy[v].values
        assert np.max(np.abs(x - y)) <= 1e-10 * np.max(np.abs(x)), v


def _simulated(quantity: str):
    """Noise-free FRFs (300 points x 512 lines, 6 modes) of ``quantity`` over force."""
    _, truth = many_points(300, 512, 6, noise=0.0, seed=3)
    f = np.linspace(0.0, 1.1 * float(truth[names.NATURAL_FREQUENCY].max()), 512)
    return frf(truth, f, drive_point=0, response_quantity=quantity)


def test_compressed_mode_vectors_are_the_uncompressed_ones():
    """Mobility: the compressed path's mode vectors are those of every other path
    (displacement convention, residues over lam), in the same units.

    Noise-free FRFs of an exact modal model: both paths recover its eigenvalues to rounding
    (~1e-15 relative) and fit exact residues at them, so the mode vectors differ by rounding
    only (observed < 3e-12 of each mode's largest entry); 1e-9 leaves margin for other
    platforms and is well inside the 1e-6 of issue 30. With noise the two are different
    estimators (the compressed one weights each point by its noise floor) and agree only
    within their standard errors (test_compressed_matches_uncompressed).
    """
    ds = _simulated("velocity")
    comp = _identify(ds, compress=16)
    full = _identify(ds, compress="off")
    assert scale.ATTR_COMPRESS_RANK in comp.attrs and scale.ATTR_COMPRESS_RANK not in full.attrs
    assert comp.sizes[names.MODE] == full.sizes[names.MODE] == 6
    phi_c, phi_f = comp[names.MODE_VECTOR], full[names.MODE_VECTOR]
    assert phi_c.attrs[names.ATTR_UNITS] == phi_f.attrs[names.ATTR_UNITS] == "sqrt(m/N)"
    assert phi_c.attrs == phi_f.attrs
    a = phi_c.transpose(names.POINT, names.MODE).values
    b = phi_f.transpose(names.POINT, names.MODE).values
    np.testing.assert_array_less(np.max(np.abs(a - b), axis=0), 1e-9 * np.max(np.abs(b), axis=0))


def test_compressed_accelerance_mode_vectors_are_displacement_ones():
    """Accelerance: the compressed path's mode vectors are eq. 8 on its residues over lam^2,
    in sqrt(receptance units), the convention and attributes of global_fit. (Noise-free
    accelerance is not identified to rounding on either path, so the paths' values are not
    compared here.)"""
    out = _identify(_simulated("acceleration"), compress=16)
    assert scale.ATTR_COMPRESS_RANK in out.attrs
    res = out[names.RESIDUE].transpose(names.POINT, names.MODE).values
    lam = out[names.EIGENVALUE].values
    phi, attrs = receptance_mode_vectors(
        res, lam, 0, out.attrs, out[names.FRF].attrs[names.ATTR_UNITS]
    )
    assert out[names.MODE_VECTOR].attrs == attrs
    assert attrs[names.ATTR_UNITS] == "sqrt(m/N)"
    np.testing.assert_allclose(
        out[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values, phi, rtol=1e-12
    )


def test_drive_snr_threshold_is_read_from_the_settings(monkeypatch, three_hundred):
    """The compressed path decides low_drive_point_snr with the threshold of the settings
    record (GlobalFitSettings), not a copy of its default: with the default raised above any
    SNR and no threshold stored by the phases, every mode is flagged."""
    ds, _ = three_hundred
    position = [f.name for f in dataclasses.fields(GlobalFitSettings)].index("drive_snr_min")
    defaults = list(GlobalFitSettings.__init__.__defaults__)
    defaults[position] = 1e30
    monkeypatch.setattr(GlobalFitSettings.__init__, "__defaults__", tuple(defaults))

    def phases(virtual, settings, refined, progress):
        out = pipeline._phases(virtual, settings, refined, progress)
        out.attrs.pop(names.ATTR_AMI_DRIVE_SNR_MIN, None)
        return out

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = scale.identify_compressed(
            ds, IdentifySettings(), True, False, phases, scale.CompressSettings(rank=16)
        )
    snr = out[names.DRIVE_POINT_SNR].values
    # modes a restated default (3) would leave unflagged
    assert np.all(np.isfinite(snr)) and np.any(snr > 3.0)
    mask = flags.decode(out[names.QUALITY_FLAGS].values)
    assert np.all(flags.has(mask, names.FLAG_LOW_DRIVE_SNR))


@pytest.mark.parametrize("lazy", [False, True])
@pytest.mark.parametrize("zero", ["every point", "one point"])
def test_all_zero_frfs_are_refused_as_on_every_point(zero, lazy):
    """An all-zero FRF is the same error on the compressed path as on the uncompressed one
    (issue 34: the compressed path failed with an IndexError when every FRF was zero)."""
    ds, _ = many_points(200, 256, 5, noise=0.02, seed=2)
    h = ds[names.FRF].values.copy()
    h[slice(None) if zero == "every point" else [7]] = 0.0
    ds[names.FRF] = ds[names.FRF].copy(data=h)
    if lazy:
        pytest.importorskip("dask")
        ds = ds.chunk({names.POINT: 70})
    where = r"\[0, 1, 2, .*\(200 in all\)\]" if zero == "every point" else r"\[7\]"
    message = rf"frf: all-zero FRF at point\(s\) {where}; nothing to identify"
    for compress in ("off", "auto", 16):
        with pytest.raises(IdentificationError, match=message):
            _identify(ds, compress=compress)
    assert issubclass(IdentificationError, ValueError)


def test_compress_array_refuses_all_zero_frfs():
    with pytest.raises(AmiXrValueError, match=r"h: every FRF is zero \(shape \(3, 16\)\)"):
        cz.compress_array(np.zeros((3, 16), complex), 2)
    # one zero FRF among others is compressed (its noise scale is 1)
    h = np.zeros((3, 16), complex)
    h[0, 3] = 1.0
    v, s = cz.compress_array(h, 2)
    assert v.shape[0] >= 1 and s[0] > 0
