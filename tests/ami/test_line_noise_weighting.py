"""The refinement weights each line by the per-line noise model (issue 20 item 2)."""

from __future__ import annotations

import warnings

import numpy as np
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami.line_noise import line_noise_shape as _line_noise_shape
from ami_xr.simulate import clustered_system


def _with_line_noise(frf: xr.Dataset, level: np.ndarray, seed: int) -> xr.Dataset:
    """``frf`` plus complex noise of std ``level`` (per line, every point alike), with the
    noise model stored as ``frf_line_noise_std``."""
    rng = np.random.default_rng(seed)
    h = frf[names.FRF].values
    scale = np.abs(h).max(axis=1, keepdims=True)
    std = scale * level[None, :]
    noise = std / np.sqrt(2.0) * (rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape))
    out = frf.copy()
    out[names.FRF] = frf[names.FRF].copy(data=h + noise)
    out[names.FRF_LINE_NOISE_STD] = (frf[names.FRF].dims, std)
    return out


def test_line_noise_shape_is_relative_and_robust():
    f = np.arange(6.0)
    sd = np.array([[1.0, 1, 2, 2, np.nan, 1], [10.0, 10, 20, 20, 10, 10]])
    ds = xr.Dataset(
        {names.FRF_LINE_NOISE_STD: ((names.POINT, names.FREQUENCY), sd)},
        coords={names.FREQUENCY: f},
    )
    frf = xr.DataArray(
        np.zeros((2, 6)), dims=(names.POINT, names.FREQUENCY), coords={names.FREQUENCY: f}
    )
    shape, group = _line_noise_shape(ds, frf)
    # per-point levels divided out (1 and 10), median over points, median scaled to 1
    np.testing.assert_allclose(shape, [1, 1, 2, 2, 1, 1], rtol=1e-12)
    assert group is None
    assert _line_noise_shape(xr.Dataset(coords={names.FREQUENCY: f}), frf) == (None, None)


def test_line_noise_shape_per_group():
    f = np.arange(6.0)
    sd = np.array([[1.0, 1, 2, 2, 4, 4], [10.0, 10, 20, 20, 40, 40], [3.0, 3, 3, 1, 1, 1]])
    ds = xr.Dataset(
        {names.FRF_LINE_NOISE_STD: ((names.POINT, names.FREQUENCY), sd)},
        coords={names.FREQUENCY: f},
    )
    frf = xr.DataArray(
        np.zeros((3, 6)),
        dims=(names.POINT, names.FREQUENCY),
        coords={names.FREQUENCY: f, "noise_group": (names.POINT, ["b", "b", "a"])},
    )
    shapes, group = _line_noise_shape(ds, frf)
    # one shape per group (labels sorted: "a" is group 0), each of median 1
    np.testing.assert_array_equal(group, [1, 1, 0])
    np.testing.assert_allclose(shapes[1], [0.5, 0.5, 1, 1, 2, 2], rtol=1e-12)
    np.testing.assert_allclose(shapes[0], [1.5, 1.5, 1.5, 0.5, 0.5, 0.5], rtol=1e-12)


def test_noisy_lines_are_discounted():
    frf, truth = clustered_system(n_points=5, cluster_sizes=(3,), overlap=0.5, seed=3)
    n = frf.sizes[names.FREQUENCY]
    level = np.full(n, 1e-4)
    level[n // 2 :] = 3e-2  # the upper half of the band is 300 times noisier
    noisy = _with_line_noise(frf, level, seed=0)
    flat = noisy.assign({names.FRF_LINE_NOISE_STD: noisy[names.FRF_LINE_NOISE_STD] * 0 + 1.0})
    bare = noisy.drop_vars(names.FRF_LINE_NOISE_STD)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        weighted = ami_xr.identify(noisy)
        same = ami_xr.identify(flat)
        plain = ami_xr.identify(bare)
    # a stored flat noise model is the unweighted likelihood
    lam = truth[names.EIGENVALUE].values
    quiet = lam[lam.imag < 2 * np.pi * frf[names.FREQUENCY].values[n // 2]]

    def error(modes):
        est = modes[names.EIGENVALUE].values
        return max(np.min(np.abs(est - t)) / abs(t.real) for t in quiet)

    # the modes in the quiet half: weighting by the noise model is far more accurate there
    assert error(weighted) < 0.3 * error(same)
    # a bare FRF (no stored model) is weighted by its own roughness estimate (issue 37): the
    # 300-fold step is found and the quiet modes come out as well as with the true model
    assert plain.attrs["noise_model_line_weights"] == 1
    assert plain.attrs["noise_model_source"] == "roughness"
    assert "stored" in same.attrs["noise_model_source"]  # flat: the same as unweighted
    assert error(plain) < 0.3 * error(same)


def test_the_users_noise_model_is_used_and_checked():
    import pytest

    from ami_xr.errors import IdentificationError

    frf, truth = clustered_system(n_points=5, cluster_sizes=(3,), overlap=0.5, seed=3)
    n = frf.sizes[names.FREQUENCY]
    level = np.full(n, 1e-4)
    level[n // 2 :] = 3e-2
    noisy = _with_line_noise(frf, level, seed=0)
    stored = noisy[names.FRF_LINE_NOISE_STD]
    bare = noisy.drop_vars(names.FRF_LINE_NOISE_STD)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        given = ami_xr.identify(bare, noise_std=stored)
        as_stored = ami_xr.identify(noisy)
    np.testing.assert_allclose(
        given[names.EIGENVALUE].values, as_stored[names.EIGENVALUE].values, rtol=1e-9
    )
    assert "given by the user" in given.attrs["noise_model_source"]
    assert given.attrs["noise_model_line_weights"] == 1
    for bad, why in ((np.ones(3), "broadcastable"), (-stored, ">= 0"), (stored * 0, "not all 0")):
        with pytest.raises(IdentificationError, match=f"noise_std: .*{why}"):
            ami_xr.identify(bare, noise_std=bad)
    assert issubclass(IdentificationError, ValueError)
