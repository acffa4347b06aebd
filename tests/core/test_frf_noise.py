"""The roughness estimate of the FRF noise per line (ami_xr.core.frf_noise, estimate_frf_noise),
the effective number of averages, and frf_line_noise_std in validate, netCDF and UFF."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.core.frf_noise import effective_averages, roughness_noise_std
from ami_xr.errors import AmiXrValueError, SchemaError


def _noise(shape, std, rng):
    """Complex white noise with E|e|^2 = std^2 (std broadcast along the last axis)."""
    return std * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)


def _system(noise=0.0, seed=0):
    """A simulated 6-point chain, 4096 lines to 50 Hz (noise-free FRF and its truth)."""
    frf, truth = ami_xr.simulate.random_system(6, noise=0.0, seed=seed)
    return frf


def test_recovers_white_noise_where_the_frf_is_smooth():
    frf = _system()
    h = frf[names.FRF]
    rng = np.random.default_rng(0)
    sigma = 1e-3 * float(np.abs(h).max())
    noisy = frf.assign({names.FRF: h.copy(data=h.values + _noise(h.shape, sigma, rng))})
    est = ami_xr.estimate_frf_noise(noisy)
    std = est[names.FRF_LINE_NOISE_STD]
    assert std.dims == h.dims and std.attrs[names.ATTR_UNITS] == h.attrs[names.ATTR_UNITS]
    assert std.attrs[names.ATTR_NOISE_MODEL].startswith("roughness")
    ratio = std.values / sigma
    # the median over lines: ~1 % scatter; per line ~14 % (median of 65 correlated differences)
    assert np.median(ratio) == pytest.approx(1.0, rel=0.05)
    assert np.mean(np.abs(ratio - 1) < 0.3) > 0.9
    # the accessor is the same function
    xr.testing.assert_identical(noisy.ami.estimate_frf_noise(), est)


def test_follows_noise_that_changes_100x_across_the_band():
    frf = _system(seed=1)
    h = frf[names.FRF]
    rng = np.random.default_rng(1)
    x = np.linspace(0.0, 1.0, h.sizes[names.FREQUENCY])
    sigma = 1e-3 * float(np.abs(h).max()) * 10.0 ** (-2 * x)  # 100x down across the band
    noisy = frf.assign({names.FRF: h.copy(data=h.values + _noise(h.shape, sigma, rng))})
    std = ami_xr.estimate_frf_noise(noisy)[names.FRF_LINE_NOISE_STD].values
    ratio = std / sigma
    for part in np.array_split(np.arange(x.size), 8):  # each eighth of the band
        assert np.median(ratio[:, part]) == pytest.approx(1.0, rel=0.1)
    # a single level per FRF is off by 10x at the ends
    assert np.median(np.abs(np.log10(ratio))) < 0.1


def test_not_fooled_by_a_sharp_resonance():
    f = np.linspace(0.0, 100.0, 2001)  # 0.05 Hz lines
    fn, zeta = 50.0, 5e-4  # half-power bandwidth 0.05 Hz: one line
    w, wn = 2 * np.pi * f, 2 * np.pi * fn
    h = 1.0 / (wn**2 - w**2 + 2j * zeta * wn * w)
    sigma = 1e-4 * np.abs(h).max()  # peak-to-noise ratio 1e4
    rng = np.random.default_rng(2)
    noisy = h + _noise(h.shape, sigma, rng)
    std = roughness_noise_std(noisy[None])[0]
    near = np.abs(f - fn) < 2.0  # 40 lines either side of the peak
    # a plain std of the 4th difference would be 100x too large at the peak
    plain = np.abs(np.diff(noisy, 4)).max() / np.sqrt(70) / sigma
    assert plain > 100
    assert np.all(std[near] / sigma < 2.0) and np.median(std[near] / sigma) < 1.3
    assert np.median(std / sigma) == pytest.approx(1.0, rel=0.1)


def test_effective_averages():
    hann = np.hanning(258)[1:-1]
    assert effective_averages(np.ones(64), 64, 10) == pytest.approx(10.0)
    # 50 % Hann overlap: Welch's 1 / (1 + 2 rho^2), rho = 1/6 for the periodic Hann window
    assert effective_averages(hann, 128, 1000) == pytest.approx(1000 / (1 + 2 / 36), rel=2e-3)
    # exponential averaging with time constant N: 2N - 1 independent averages in the limit
    assert effective_averages(np.ones(64), 64, 10000, "exponential", 8) == pytest.approx(15.0)
    assert effective_averages(np.ones(64), 64, 5, "exponential", 8) == pytest.approx(5.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"method": "residual"}, "method"),
        ({"order": 3}, "order"),
        ({"order": 1}, "order"),
        ({"window": 64}, "window"),
        ({"window": 0}, "window"),
    ],
)
def test_bad_arguments_raise(kwargs, match):
    frf = _system()
    with pytest.raises(AmiXrValueError, match=match):
        ami_xr.estimate_frf_noise(frf, **kwargs)


def test_too_few_or_uneven_lines_raise():
    frf = _system()
    with pytest.raises(AmiXrValueError, match="frf: expected more than order=4"):
        ami_xr.estimate_frf_noise(frf.isel({names.FREQUENCY: slice(1, 5)}))
    uneven = frf.isel({names.FREQUENCY: [1, 2, 3, 5, 8, 9, 10, 11, 12]})
    with pytest.raises(AmiXrValueError, match="uniformly spaced"):
        ami_xr.estimate_frf_noise(uneven)


def test_multi_reference_frf():
    model = ami_xr.simulate.random_system(5, seed=3)[1]
    frf = ami_xr.simulate.frf(model, np.linspace(1.0, 50.0, 1024), references=[0, 1])
    est = ami_xr.estimate_frf_noise(frf)
    assert est[names.FRF_LINE_NOISE_STD].dims == (names.REFERENCE, names.POINT, names.FREQUENCY)
    ami_xr.validate(est)


def test_validate_netcdf_and_uff_with_noise_std(tmp_path):
    frf = _system()
    est = ami_xr.estimate_frf_noise(frf)
    ami_xr.validate(est)
    path = tmp_path / "h.nc"
    ami_xr.to_netcdf(est, path)
    back = ami_xr.open_dataset(path)
    xr.testing.assert_allclose(back[names.FRF_LINE_NOISE_STD], est[names.FRF_LINE_NOISE_STD])
    assert (
        back[names.FRF_LINE_NOISE_STD].attrs[names.ATTR_NOISE_MODEL]
        == (est[names.FRF_LINE_NOISE_STD].attrs[names.ATTR_NOISE_MODEL])
    )
    uff = tmp_path / "h.uff"
    ami_xr.write_uff(est, uff)  # the noise std is not an FRF: not written
    read = ami_xr.read_uff(uff)
    assert names.FRF_LINE_NOISE_STD not in read
    bad = est.copy()
    bad[names.FRF_LINE_NOISE_STD] = -bad[names.FRF_LINE_NOISE_STD]
    with pytest.raises(SchemaError, match="frf_line_noise_std.*>= 0"):
        ami_xr.validate(bad)
    bad[names.FRF_LINE_NOISE_STD] = bad[names.FRF_LINE_NOISE_STD].isel({names.POINT: 0})
    with pytest.raises(SchemaError, match="frf_line_noise_std.*dims"):
        ami_xr.validate(bad)
    # refine's one level per FRF (dims point) has its own name: both can sit in one Dataset
    both = est.assign({names.FRF_NOISE_STD: est[names.FRF_LINE_NOISE_STD].max(names.FREQUENCY)})
    ami_xr.validate(both)
    assert names.FRF_LINE_NOISE_STD != names.FRF_NOISE_STD
    nan = est.copy()
    nan[names.FRF_LINE_NOISE_STD][0, 0] = np.nan
    with pytest.raises(SchemaError, match="frf_line_noise_std.*NaN"):
        ami_xr.validate(nan)


def test_noise_std_of_prefers_the_stored_per_line_noise():
    from ami_xr.dsp.noise_model import noise_std_of

    frf = _system()
    est = ami_xr.estimate_frf_noise(frf)
    stored = est.assign({names.FRF_LINE_NOISE_STD: 2.0 * est[names.FRF_LINE_NOISE_STD]})
    xr.testing.assert_identical(noise_std_of(stored), stored[names.FRF_LINE_NOISE_STD])
    xr.testing.assert_identical(noise_std_of(frf), est[names.FRF_LINE_NOISE_STD])
    # one level per FRF (dims point) is not a per-line noise: estimated instead
    per_frf = est[names.FRF_LINE_NOISE_STD].max(names.FREQUENCY)
    level = est.assign({names.FRF_LINE_NOISE_STD: per_frf})
    xr.testing.assert_identical(noise_std_of(level), est[names.FRF_LINE_NOISE_STD])


def test_dask_backed_frf_gives_the_same_estimate():
    pytest.importorskip("dask")
    frf, _ = ami_xr.simulate.random_system(6, seed=0, noise=0.01)
    want = ami_xr.estimate_frf_noise(frf)[names.FRF_LINE_NOISE_STD]
    for chunks in ({names.POINT: 2}, {names.FREQUENCY: 1000}):
        got = ami_xr.estimate_frf_noise(frf.chunk(chunks))[names.FRF_LINE_NOISE_STD]
        assert got.chunks is not None
        xr.testing.assert_allclose(got.compute(), want)


def _scattered(level: np.ndarray, n_d: int, rng) -> np.ndarray:
    """A per-line std estimate of ``level`` as the coherence formula gives it: each line's
    variance a chi-square of 2 n_d degrees of freedom over 2 n_d (n_d averages)."""
    return level * np.sqrt(rng.chisquare(2 * n_d, level.shape) / (2 * n_d))


def test_smoothed_std_keeps_a_slow_trend_and_lifts_the_low_scatter():
    from ami_xr.core.frf_noise import smoothed_std

    rng = np.random.default_rng(3)
    f = np.linspace(0.0, 2000.0, 8001)
    level = 1e-3 * (1.0 + f / 200.0) ** -1.5  # a force spectrum rolling off 30-fold
    raw = _scattered(np.broadcast_to(level, (4, f.size)), 5, rng)
    smooth = smoothed_std(raw, f)
    above = f > 200.0  # blocks of 40 lines and more
    low_raw = np.log(raw[:, above] / level[above])
    low_smooth = np.log(smooth[:, above] / level[above])
    # the raw estimate falls to less than half the true noise on some lines (weighting them up
    # more than 4-fold); floored at the local level, no line falls more than ~20 % below it
    assert low_raw.min() < np.log(0.5)
    assert low_smooth.min() > np.log(0.8)
    # lines above the level keep their own estimate, none is lowered
    assert np.all(smooth >= raw)
    kept = raw[:, above] > 1.3 * level[above]
    np.testing.assert_array_equal(smooth[:, above][kept], raw[:, above][kept])
    # a constant stays that constant
    np.testing.assert_allclose(smoothed_std(np.full((2, f.size), 0.7), f), 0.7, rtol=1e-12)


def test_smoothed_std_fills_missing_lines_lifts_dips_and_keeps_bumps():
    from ami_xr.core.frf_noise import smoothed_std, smoothing_edges

    f = np.linspace(0.0, 100.0, 1001)
    sd = np.full(f.size, 2.0)
    sd[0] = np.nan  # 0 Hz: no estimate
    sd[400:403] = 1e-6  # three lines of (wrongly) tiny noise would dominate the weights
    sd[600:603] = 9.0  # three of a raised noise (leakage at a peak) are kept
    out = smoothed_std(sd, f)
    assert out.shape == sd.shape and np.all(np.isfinite(out))
    np.testing.assert_allclose(np.delete(out, [600, 601, 602]), 2.0, rtol=1e-12)
    np.testing.assert_array_equal(out[600:603], 9.0)
    assert np.all(np.isnan(smoothed_std(np.full((1, 50), np.nan), f[:50])))
    edges = smoothing_edges(f)
    widths = np.diff(edges)
    assert edges[0] == 0 and edges[-1] == f.size and widths.min() >= 8
    assert widths[-2] >= 0.02 * 90.0 / 0.1  # 2 % of f near the top: ~18 lines (the last one
    # is what is left, at least 8)
