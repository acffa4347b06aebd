"""``frf_line_noise_std`` of ami_xr.frf / ami_xr.impact_frf against Monte Carlo.

Each test simulates one force and many noisy copies of the same response (one "point" per
realisation, independent output noise), so one call estimates hundreds of FRFs at once: given the
force, their spread is the random error the coherence formula predicts (the force is common, so
the spread is the error conditional on it, the quantity the formula estimates).

Tolerances: at one line the empirical variance of R realisations has a relative standard
deviation ``1/sqrt(R - 1)`` (|error|^2 is exponential) and the mean predicted variance
``1/sqrt(R (n_d - q))`` (chi-square with 2 (n_d - q) degrees of freedom); the ratio averaged over
L lines scatters by about their root sum of squares over sqrt(L / c), c ~ 2 for the correlation
of neighbouring lines of a windowed DFT. Each test uses 4 to 5 such standard deviations.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names

from ..reference import sampled_response

FS = 256.0
R = 300  # realisations (points)
M = np.eye(2)
K = 1.5e4 * np.array([[2.0, -1.0], [-1.0, 1.0]])  # modes near 12 and 31.5 Hz


def _residues():
    """Eigenvalues and residues (force at point 0) of a well-damped 2-DOF system (zeta 6-8 %):
    its 256-sample Welch segments leak little, so the coherence loss is the output noise."""
    model = ami_xr.simulate.modal_model(M, 6.0 * M + 6e-4 * K, K, drive_point=0)
    model = ami_xr.simulate.residues(model, 0)
    return model[names.EIGENVALUE].values, model[names.RESIDUE].values


def _time_ds(force, response):
    return ami_xr.make_time_dataset(
        response,
        fs=FS,
        force=force,
        points=list(range(response.shape[-2])),
        drive_point=0,
        response_quantity="displacement",
        response_units="m",
        force_units="N",
    )


def _ratio(est: xr.Dataset, clean: xr.Dataset | None = None):
    """Empirical over predicted variance per line (frequency,), and the mask of lines used."""
    h = est[names.FRF].values  # (..., point, frequency)
    dev = h - h.mean(axis=-2, keepdims=True)
    emp = (np.abs(dev) ** 2).sum(axis=-2) / (h.shape[-2] - 1)
    pred = (est[names.FRF_LINE_NOISE_STD].values ** 2).mean(axis=-2)
    use = np.isfinite(pred) & (pred > 0) & (est[names.FREQUENCY].values > 1.0)
    if clean is not None:  # lines where leakage (coherence loss without noise) is negligible
        loss_clean = 1 - clean[names.COHERENCE].values[..., 0, :]
        loss_noisy = 1 - est[names.COHERENCE].values.mean(axis=-2)
        use &= np.all(np.atleast_2d(loss_clean < 0.02 * loss_noisy), axis=0)
    return emp / pred, use


@pytest.mark.parametrize("noverlap", [0, 128])
def test_random_h1_noise_std_matches_monte_carlo(noverlap):
    lam, res = _residues()
    rng = np.random.default_rng(1)
    n = 256 * 9
    f = rng.standard_normal(n)
    y = sampled_response(f, lam, res, 1 / FS)[0]
    sigma = 0.5 * y.std()
    ys = y + sigma * rng.standard_normal((R, n))
    kw = {"nperseg": 256, "noverlap": noverlap}
    est = ami_xr.frf(_time_ds(f, ys), **kw)
    clean = ami_xr.frf(_time_ds(f, y[None]), **kw)
    std = est[names.FRF_LINE_NOISE_STD]
    assert std.dims == est[names.FRF].dims and std.dtype == np.float64
    assert std.attrs[names.ATTR_UNITS] == est[names.FRF].attrs[names.ATTR_UNITS]
    model = std.attrs[names.ATTR_NOISE_MODEL]
    assert (
        model.startswith("coherence") and f"of {est.attrs[names.ATTR_N_AVERAGES]} segments" in model
    )
    ratio, use = _ratio(est, clean)
    assert use.sum() > 30
    n_d = est.attrs[names.ATTR_N_AVERAGES]
    sd_line = np.sqrt(1 / (R - 1) + 1 / (R * (n_d - 1)))
    tol = 5 * sd_line / np.sqrt(use.sum() / 2)  # ~3 %
    assert np.mean(ratio[use]) == pytest.approx(1.0, abs=tol)
    # every line within 5 sd of its own scatter (plus the force's share with overlap)
    assert np.all(np.abs(ratio[use] - 1) < 5 * sd_line + (0.15 if noverlap else 0.0))


def _hits(amplitudes, n, rng):
    """Half-sine force pulses of 5 samples, one per record (hit)."""
    pulse = np.sin(np.pi * np.arange(1, 6) / 6)
    f = np.zeros((len(amplitudes), n))
    f[:, 3:8] = np.asarray(amplitudes)[:, None] * pulse
    return f


def test_impact_noise_std_matches_monte_carlo_with_three_hits():
    lam, res = _residues()
    rng = np.random.default_rng(2)
    n = 1024
    f = _hits([1.0, 0.8, 1.2], n, rng)
    y = np.stack([sampled_response(fh, lam, res, 1 / FS)[0] for fh in f])  # (hit, time)
    sigma = 0.05 * np.abs(y).max()
    ys = y[:, None, :] + sigma * rng.standard_normal((3, R, n))
    est = ami_xr.impact_frf(_time_ds(f, ys), hit_checks=False)
    model = est[names.FRF_LINE_NOISE_STD].attrs[names.ATTR_NOISE_MODEL]
    assert "n_d=3 " in model and "q=1" in model
    ratio, use = _ratio(est)
    assert use.sum() > 300
    sd_line = np.sqrt(1 / (R - 1) + 1 / (R * 2))
    # no window: neighbouring lines are independent
    assert np.mean(ratio[use]) == pytest.approx(1.0, abs=5 * sd_line / np.sqrt(use.sum()))
    # Bendat & Piersol's plug-in formula with n_d (not n_d - 1) would predict 2/3 of the variance
    assert abs(np.mean(ratio[use]) - 1.5) > 0.4


def test_multi_reference_noise_std_matches_monte_carlo():
    lam, res = _residues()
    rng = np.random.default_rng(3)
    n = 256 * 12
    f = rng.standard_normal((2, n))
    # force at point 0 and at point 1 (reciprocity: the residue of point 1 driven at 0)
    y = sampled_response(f[0], lam, res, 1 / FS)[0] + sampled_response(f[1], lam, res, 1 / FS)[1]
    ys = y + 0.5 * y.std() * rng.standard_normal((R, n))
    force = xr.DataArray(f, dims=[names.REFERENCE, names.TIME], coords={names.REFERENCE: [0, 1]})
    ds = _time_ds(f[0], ys)
    kw = {"nperseg": 256, "noverlap": 0}
    est = ami_xr.frf(ds, force=force, **kw)
    clean = ami_xr.frf(_time_ds(f[0], y[None]), force=force, **kw)
    std = est[names.FRF_LINE_NOISE_STD]
    assert std.dims == (names.REFERENCE, names.POINT, names.FREQUENCY)
    assert "q=2" in std.attrs[names.ATTR_NOISE_MODEL]
    ratio, use = _ratio(est, clean)
    assert use[0].sum() > 30
    sd_line = np.sqrt(1 / (R - 1) + 1 / (R * (12 - 2)))
    tol = 5 * sd_line / np.sqrt(use[0].sum() / 2)
    for r in range(2):
        assert np.mean(ratio[r][use[r]]) == pytest.approx(1.0, abs=tol)


def test_one_hit_falls_back_to_roughness():
    lam, res = _residues()
    rng = np.random.default_rng(4)
    n = 1024
    f = _hits([1.0], n, rng)
    y = sampled_response(f[0], lam, res, 1 / FS)
    sigma = 1e-3 * np.abs(y).max()
    est = ami_xr.impact_frf(_time_ds(f, (y + sigma * rng.standard_normal(y.shape))[None]))
    std = est[names.FRF_LINE_NOISE_STD]
    model = std.attrs[names.ATTR_NOISE_MODEL]
    assert model.startswith("roughness") and "1 average(s)" in model
    # the FRF's noise: sigma * sqrt(n) / |F| per line (dt * DFT, force spectrum ~ flat)
    fdt = np.abs(np.fft.rfft(f[0])) / FS
    want = sigma * np.sqrt(n) / FS / fdt
    got = std.isel(point=0).values
    mid = slice(40, 400)  # away from the band edges
    assert np.median(got[mid] / want[mid]) == pytest.approx(1.0, rel=0.15)


def test_noise_std_round_trips_netcdf_and_validates(tmp_path):
    lam, res = _residues()
    rng = np.random.default_rng(5)
    f = rng.standard_normal(2048)
    y = sampled_response(f, lam, res, 1 / FS)
    est = ami_xr.frf(_time_ds(f, y + 1e-3 * rng.standard_normal(y.shape)))
    ami_xr.validate(est)
    path = tmp_path / "h.nc"
    ami_xr.to_netcdf(est, path)
    back = ami_xr.open_dataset(path)
    xr.testing.assert_allclose(back[names.FRF_LINE_NOISE_STD], est[names.FRF_LINE_NOISE_STD])
    assert (
        back[names.FRF_LINE_NOISE_STD].attrs[names.ATTR_NOISE_MODEL]
        == (est[names.FRF_LINE_NOISE_STD].attrs[names.ATTR_NOISE_MODEL])
    )
