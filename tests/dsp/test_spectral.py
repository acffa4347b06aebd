"""Spectral kernels and the Welch engine against scipy.signal and plain numpy references."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from ami_xr.dsp import spectral as sp
from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import impact as ki
from ami_xr.kernels import spectral as ks

RTOL = 1e-10


def _close(got, want, rtol=RTOL):
    """Relative agreement, scaled by the largest value (bins near zero after detrending)."""
    got, want = np.asarray(got), np.asarray(want)
    assert got.shape == want.shape
    scale = np.max(np.abs(want))
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * scale)


@pytest.fixture(scope="module")
def signals():
    rng = np.random.default_rng(1)
    x = rng.standard_normal(4001)
    b, a = scipy.signal.butter(3, [0.1, 0.3], btype="band")
    y = np.stack([scipy.signal.lfilter(b, a, x), 0.5 * x]) + 0.1 * rng.standard_normal((2, 4001))
    y[1] += np.linspace(0, 3, 4001)  # a trend for the linear detrend to remove
    return x, y


PARAMS = [
    dict(fs=100.0, nperseg=256, noverlap=None, nfft=None, detrend="constant", window="hann"),
    dict(fs=2.0, nperseg=200, noverlap=150, nfft=256, detrend="linear", window="hann"),
    dict(fs=1.0, nperseg=333, noverlap=0, nfft=None, detrend=False, window="boxcar"),
    dict(fs=48.0, nperseg=128, noverlap=64, nfft=None, detrend="constant", window="flattop"),
    dict(fs=10.0, nperseg=100, noverlap=99, nfft=101, detrend="linear", window="hann"),
]


@pytest.mark.parametrize("kw", PARAMS)
def test_csd_welch_coherence_match_scipy(signals, kw):
    x, y = signals
    f, pxy = sp.csd(x, y, **kw)
    f_ref, pxy_ref = scipy.signal.csd(x, y, **kw)
    np.testing.assert_allclose(f, f_ref, rtol=1e-14)
    _close(pxy, pxy_ref)
    _, pyy = sp.welch(y, **kw)
    _close(pyy, scipy.signal.welch(y, **kw)[1])
    _, pxx = sp.welch(x, **kw)
    _close(pxx, scipy.signal.welch(x, **kw)[1])
    _, coh = sp.coherence(x, y, **kw)
    _close(coh, scipy.signal.coherence(x, y, **kw)[1])


def _numpy_reference(x, y, fs, nperseg, noverlap, nfft, detrend, w):
    """Plain numpy Welch: loops over segments, np.polyfit for the linear trend."""
    step = nperseg - noverlap
    starts = range(0, x.size - nperseg + 1, step)
    sxx = syy = 0.0
    sxy = 0.0
    t = np.arange(nperseg)
    for s in starts:
        segs = []
        for v in (x[s : s + nperseg], y[s : s + nperseg]):
            if detrend == "constant":
                v = v - v.mean()
            elif detrend == "linear":
                v = v - np.polyval(np.polyfit(t, v, 1), t)
            segs.append(np.fft.rfft(v * w, nfft))
        sxx = sxx + np.abs(segs[0]) ** 2
        syy = syy + np.abs(segs[1]) ** 2
        sxy = sxy + np.conj(segs[0]) * segs[1]
    scale = np.full(nfft // 2 + 1, 2.0 / (fs * np.sum(w**2) * len(starts)))
    scale[0] /= 2
    if nfft % 2 == 0:
        scale[-1] /= 2
    return sxx * scale, sxy * scale, syy * scale


@pytest.mark.parametrize("detrend", ["constant", "linear", "none"])
def test_engine_matches_numpy_reference(signals, detrend):
    x, y = signals
    nperseg, noverlap, nfft, fs = 300, 120, 512, 7.0
    w = np.hanning(nperseg + 1)[:-1]
    acc = sp.WelchAccumulator(
        1,
        1,
        fs=fs,
        nperseg=nperseg,
        noverlap=noverlap,
        nfft=nfft,
        force_window=w,
        response_window=w,
        detrend=detrend,
    )
    acc.feed(x[None], y[:1])
    gff, gfy, gyy = acc.spectra()
    rxx, rxy, ryy = _numpy_reference(x, y[0], fs, nperseg, noverlap, nfft, detrend, w)
    _close(gff[0, 0].real, rxx)
    _close(gfy[0, 0], rxy)
    _close(gyy[0], ryy)


@pytest.mark.parametrize("block", [1, 7, 255, 256, 257, 1000, 4001])
def test_blocks_carry_overlap_and_equal_one_shot(signals, block):
    x, y = signals
    kw = dict(
        fs=1.0,
        nperseg=256,
        noverlap=100,
        nfft=256,
        force_window=np.hanning(256),
        response_window=np.hanning(256),
        detrend="linear",
    )
    one = sp.WelchAccumulator(1, 2, **kw)
    one.feed(x[None], y)
    many = sp.WelchAccumulator(1, 2, **kw)
    for a in range(0, x.size, block):
        many.feed(x[None, a : a + block], y[:, a : a + block])
    assert many.count == one.count
    for g1, g2 in zip(one.spectra(), many.spectra(), strict=True):
        _close(g2, g1, rtol=1e-13)


def test_records_are_not_joined(signals):
    x, y = signals
    kw = dict(
        fs=1.0,
        nperseg=100,
        noverlap=50,
        nfft=100,
        force_window=np.ones(100),
        response_window=np.ones(100),
    )
    acc = sp.WelchAccumulator(1, 2, **kw)
    acc.feed(x[None, :150], y[:, :150])
    acc.end_record()
    acc.feed(x[None, 150:300], y[:, 150:300])
    assert acc.count == 4  # 2 per record; 5 if a segment straddled the record border


def test_exponential_average_matches_loop(signals):
    x, y = signals
    n_avg, nperseg = 4, 128
    w = np.hanning(nperseg)
    acc = sp.WelchAccumulator(
        1,
        1,
        fs=1.0,
        nperseg=nperseg,
        noverlap=0,
        nfft=nperseg,
        force_window=w,
        response_window=w,
        detrend="none",
        average="exponential",
        n_average=n_avg,
    )
    acc.feed(x[None], y[:1])
    gff, gfy, _ = acc.spectra()
    ref = np.zeros(nperseg // 2 + 1, complex)
    for m, s in enumerate(range(0, x.size - nperseg + 1, nperseg), start=1):
        X = np.fft.rfft(x[s : s + nperseg] * w)
        Y = np.fft.rfft(y[0, s : s + nperseg] * w)
        ref += (np.conj(X) * Y - ref) / min(m, n_avg)
    scale = np.full(ref.size, 2.0 / np.sum(w**2))
    scale[[0, -1]] /= 2
    _close(gfy[0, 0], ref * scale)
    # the first n_avg segments are a plain linear average
    lin = sp.csd(
        x[: n_avg * nperseg],
        y[0, : n_avg * nperseg],
        window=w,
        nperseg=nperseg,
        noverlap=0,
        detrend=False,
    )[1]
    exp = sp.csd(
        x[: n_avg * nperseg],
        y[0, : n_avg * nperseg],
        window=w,
        nperseg=nperseg,
        noverlap=0,
        detrend=False,
        average="exponential",
        n_average=n_avg,
    )[1]
    _close(exp, lin)


def test_frf_from_spectra_siso_and_mimo():
    rng = np.random.default_rng(3)
    nf = 5
    H_true = rng.standard_normal((2, 3, nf)) + 1j * rng.standard_normal((2, 3, nf))
    F = rng.standard_normal((2, 400, nf)) + 1j * rng.standard_normal((2, 400, nf))
    Y = np.einsum("ipk,isk->psk", H_true, F)
    gff, gfy, gyy, _ = ks.accumulate_spectra(F, Y)
    H, coh = ks.frf_from_spectra(gff, gfy, gyy, "H1")
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
    np.testing.assert_allclose(seg, 0.0, atol=1e-12)
    seg = ks.prepare_segments(x, np.array([3]), np.full(10, 2.0), "constant")
    np.testing.assert_allclose(seg[0, 0], 2 * (x[0, 3:13] - x[0, 3:13].mean()))
    with pytest.raises(AmiXrValueError, match="starts"):
        ks.prepare_segments(x, np.array([15]), np.ones(10))
    with pytest.raises(AmiXrValueError, match="detrend"):
        ks.prepare_segments(x, np.array([0]), np.ones(10), "quadratic")


def test_segment_checks():
    with pytest.raises(AmiXrValueError, match="nperseg"):
        sp.check_segments(100, 101, None, None)
    with pytest.raises(AmiXrValueError, match="noverlap"):
        sp.check_segments(100, 50, 50, None)
    with pytest.raises(AmiXrValueError, match="nfft"):
        sp.check_segments(100, 50, 10, 40)
    with pytest.raises(AmiXrValueError, match="window"):
        sp.csd(np.ones(100), np.ones(100), window="kaiserish", nperseg=50)
    with pytest.raises(AmiXrValueError, match="x"):
        sp.csd(np.r_[np.nan, np.ones(99)], np.ones(100), nperseg=50)


def test_hit_check_kernels():
    x = np.array([[0.0, 1.0, 3.0, 3.0, 3.0, 1.0, -2.0], [0.0, 1.0, 2.0, 1.0, -2.0, -2.0, 0.0]])
    np.testing.assert_array_equal(ki.extreme_run(x), [3, 2])
    f = np.zeros((2, 40))
    f[:, 5:8] = [1.0, 3.0, 1.0]
    f[1, 25:27] = 2.0  # second pulse
    p = ki.force_pulses(f, 0.3, 3)
    np.testing.assert_array_equal(p, [[1, 5, 7, -1], [2, 5, 7, 25]])
