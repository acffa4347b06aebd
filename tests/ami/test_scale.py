"""Identification of many points (issue 21): compression, the compressed path against the
uncompressed one, and the dask-backed path against the in-memory one."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami import scale
from ami_xr.core import compress as cz
from ami_xr.errors import IdentificationError
from ami_xr.simulate import score_modes
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
