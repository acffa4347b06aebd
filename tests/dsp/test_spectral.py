"""The Welch engine (ami_xr/dsp/spectral.py) against scipy.signal and plain numpy references."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from ami_xr.dsp import spectral as sp
from ami_xr.errors import AmiXrValueError

from ..reference import assert_close_to_scale, welch_spectra

# Sums over ~30 segments of 256-512-point FFTs: rounding ~eps * log2(n) * n_seg ~ 1e-13 of the
# largest bin; scipy sums in another order. 1e-10 of the largest bin leaves room, and a wrong
# scaling, window or detrend is off by far more than that.
RTOL = 1e-10


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
    dict(fs=10.0, nperseg=100, noverlap=90, nfft=101, detrend="linear", window="hann"),
    # a one-sample step (~3900 segments): the slow tier
    pytest.param(
        dict(fs=10.0, nperseg=100, noverlap=99, nfft=101, detrend="linear", window="hann"),
        marks=pytest.mark.slow,
    ),
]


@pytest.mark.parametrize("kw", PARAMS)
def test_csd_welch_coherence_match_scipy(signals, kw):
    x, y = signals
    f, pxy = sp.csd(x, y, **kw)
    f_ref, pxy_ref = scipy.signal.csd(x, y, **kw)
    np.testing.assert_allclose(f, f_ref, rtol=1e-14)  # k * fs / nfft: one or two roundings
    assert_close_to_scale(pxy, pxy_ref, RTOL)
    _, pyy = sp.welch(y, **kw)
    assert_close_to_scale(pyy, scipy.signal.welch(y, **kw)[1], RTOL)
    _, pxx = sp.welch(x, **kw)
    assert_close_to_scale(pxx, scipy.signal.welch(x, **kw)[1], RTOL)
    _, coh = sp.coherence(x, y, **kw)
    assert_close_to_scale(coh, scipy.signal.coherence(x, y, **kw)[1], RTOL)


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
    rxx, rxy, ryy = welch_spectra(x, y[0], fs, nperseg, noverlap, nfft, detrend, w)
    assert_close_to_scale(gff[0, 0].real, rxx, RTOL)
    assert_close_to_scale(gfy[0, 0], rxy, RTOL)
    assert_close_to_scale(gyy[0], ryy, RTOL)


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
        # the same segments, FFTs and sums in the same order: only the block-boundary bookkeeping
        # differs, so the result agrees to the rounding of the running sums (~1e-14 here)
        assert_close_to_scale(g2, g1, 1e-13)


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
    assert_close_to_scale(gfy[0, 0], ref * scale, RTOL)
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
    assert_close_to_scale(exp, lin, RTOL)


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
