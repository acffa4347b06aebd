"""Spectral and hammer-hit kernels (ami_xr/kernels/spectral.py, impact.py) through their checked
wrappers: FRF estimators from accumulated spectra, segment preparation, pulse detection."""

from __future__ import annotations

import numpy as np
import pytest

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import impact as ki
from ami_xr.kernels import spectral as ks


def test_frf_from_spectra_siso_and_mimo():
    rng = np.random.default_rng(3)
    nf = 5
    H_true = rng.standard_normal((2, 3, nf)) + 1j * rng.standard_normal((2, 3, nf))
    F = rng.standard_normal((2, 400, nf)) + 1j * rng.standard_normal((2, 400, nf))
    Y = np.einsum("ipk,isk->psk", H_true, F)
    gff, gfy, gyy, _ = ks.accumulate_spectra(F, Y)
    H, coh = ks.frf_from_spectra(gff, gfy, gyy, "H1")
    # a 2x2 solve of spectra summed over 400 averages of random data: condition number of Gff
    # ~10, rounding ~1e-14 relative; 1e-9 leaves room for an ill-conditioned draw
    np.testing.assert_allclose(H, H_true, rtol=1e-9)
    np.testing.assert_allclose(coh, 1.0, rtol=1e-9)  # noise-free: multiple coherence 1
    # SISO: H1 = H2 = Hv without noise
    for est in ks.ESTIMATORS:
        h, c = ks.frf_from_spectra(gff[:1, :1], gfy[:1], gyy, est)
        assert h.shape == (1, 3, nf) and c.shape == (3, nf)
    with pytest.raises(AmiXrValueError, match="estimator"):
        ks.frf_from_spectra(gff, gfy, gyy, "H2")
    with pytest.raises(AmiXrValueError, match="estimator"):
        ks.frf_from_spectra(gff, gfy, gyy, "H3")


def test_zero_power_gives_nan_not_error():
    gff = np.zeros((1, 1, 3), complex)
    gfy = np.zeros((1, 2, 3), complex)
    gyy = np.zeros((2, 3))
    for est in ks.ESTIMATORS:
        H, coh = ks.frf_from_spectra(gff, gfy, gyy, est)
        assert np.all(np.isnan(H)) and np.all(np.isnan(coh))


def test_prepare_segments_detrend_and_window():
    x = np.arange(20.0)[None, :] * 2 + 5
    seg = ks.prepare_segments(x, np.array([0, 10]), np.ones(10), "linear")
    # a least-squares line through values up to 45: residual rounding ~ eps * 45 * cond ~ 1e-13
    np.testing.assert_allclose(seg, 0.0, atol=1e-12)
    seg = ks.prepare_segments(x, np.array([3]), np.full(10, 2.0), "constant")
    # a mean of 10 integers and one product: a few ulp; default rtol=1e-7 is loose but no entry
    # is near zero, and a wrong start or window is off by O(1)
    np.testing.assert_allclose(seg[0, 0], 2 * (x[0, 3:13] - x[0, 3:13].mean()))
    with pytest.raises(AmiXrValueError, match="starts"):
        ks.prepare_segments(x, np.array([15]), np.ones(10))
    with pytest.raises(AmiXrValueError, match="detrend"):
        ks.prepare_segments(x, np.array([0]), np.ones(10), "quadratic")


def test_hit_check_kernels():
    x = np.array([[0.0, 1.0, 3.0, 3.0, 3.0, 1.0, -2.0], [0.0, 1.0, 2.0, 1.0, -2.0, -2.0, 0.0]])
    np.testing.assert_array_equal(ki.extreme_run(x), [3, 2])  # integer counts
    f = np.zeros((2, 40))
    f[:, 5:8] = [1.0, 3.0, 1.0]
    f[1, 25:27] = 2.0  # second pulse
    p = ki.force_pulses(f, 0.3, 3)
    np.testing.assert_array_equal(p, [[1, 5, 7, -1], [2, 5, 7, 25]])  # integer indices
