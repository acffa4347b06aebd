"""Property-based tests (hypothesis) of the spectra: ``ami_xr.dsp.spectral`` (csd, welch,
coherence), the labeled :func:`ami_xr.frf` and :func:`ami_xr.impulse_to_frf`.

References are ``scipy.signal`` (same parameters, same one-sided density scaling), plain numpy
FFTs, and closed forms: the H1 estimate of a noise-free periodic FIR system, Parseval's identity
and the Cauchy-Schwarz bound of coherence. Records are short so the file runs in seconds.
"""

from __future__ import annotations

import numpy as np
import scipy.signal
from hypothesis import given, settings
from hypothesis import strategies as st

import ami_xr
from ami_xr import names
from ami_xr.dsp import spectral

EPS = np.finfo(np.float64).eps
# Welch spectra here and in scipy: the same segments, windows and scaling, but other FFT calls
# and summation orders. Each line is a mean of |X|^2-like products whose rounding is a few ulp
# of the largest product, so 1e-12 of the spectrum's largest value bounds the difference
# (1e-15 typical) while any scaling, window or segment error is >= 1e-3 of it.
SPEC_RTOL = 1e-12

_SETTINGS = settings(max_examples=25, deadline=None)

DETRENDS = {"constant": "constant", "linear": "linear", "none": False}  # ours -> scipy's


@st.composite
def welch_setups(draw):
    """Record length, fs and Welch parameters in scipy's names (every valid combination)."""
    nperseg = draw(st.integers(4, 64))
    n = draw(st.integers(nperseg, 4 * nperseg + 7))
    return {
        "n": n,
        "fs": draw(st.floats(0.5, 5e4)),
        "nperseg": nperseg,
        "noverlap": draw(st.one_of(st.none(), st.integers(0, nperseg - 1))),
        "nfft": draw(st.one_of(st.none(), st.integers(nperseg, 2 * nperseg))),
        "window": draw(st.sampled_from(["hann", "boxcar", "flattop"])),
        "detrend": draw(st.sampled_from(sorted(DETRENDS))),
    }


def signals(n, n_channel, seed):
    """A force-like ``x`` (n,) and responses ``y`` (n_channel, n) correlated with it."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=n) + rng.uniform(-2, 2)
    y = np.array([scipy.signal.lfilter(rng.normal(size=5), [1.0], x) for _ in range(n_channel)])
    y = y + 0.3 * rng.normal(size=y.shape) + np.linspace(0, rng.uniform(-1, 1), n)  # + trend
    return x, y


def scipy_kwargs(setup):
    kw = {k: setup[k] for k in ("fs", "window", "nperseg", "noverlap", "nfft")}
    kw["detrend"] = DETRENDS[setup["detrend"]]
    return kw


def ours_kwargs(setup):
    return {k: setup[k] for k in ("fs", "window", "nperseg", "noverlap", "nfft", "detrend")}


def assert_close(got, want, scale):
    """``|got - want| <= SPEC_RTOL * scale`` everywhere, worst case in the message."""
    err = np.abs(np.asarray(got) - np.asarray(want))
    assert np.all(err <= SPEC_RTOL * scale), f"worst error {err.max()!r} vs scale {scale!r}"


# --- against scipy.signal -------------------------------------------------------------------------


@_SETTINGS
@given(setup=welch_setups(), n_channel=st.integers(1, 3), seed=st.integers(0, 2**32 - 1))
def test_csd_welch_coherence_match_scipy(setup, n_channel, seed):
    x, y = signals(setup["n"], n_channel, seed)
    ours, ref = ours_kwargs(setup), scipy_kwargs(setup)
    f, pxy = spectral.csd(x, y, **ours)
    f_ref, pxy_ref = scipy.signal.csd(x, y, **ref)
    np.testing.assert_array_equal(f, f_ref)  # both rfftfreq(nfft, 1/fs)
    assert_close(pxy, pxy_ref, np.abs(pxy_ref).max())
    _, pyy = spectral.welch(y, **ours)
    _, pyy_ref = scipy.signal.welch(y, **ref)
    assert_close(pyy, pyy_ref, pyy_ref.max())
    _, pxx = spectral.welch(x, **ours)  # 1-D in, 1-D out
    _, pxx_ref = scipy.signal.welch(x, **ref)
    assert pxx.shape == pxx_ref.shape
    assert_close(pxx, pxx_ref, pxx_ref.max())
    _, coh = spectral.coherence(x, y, **ours)
    with np.errstate(divide="ignore", invalid="ignore"):  # 0/0 where a spectrum vanishes
        _, coh_ref = scipy.signal.coherence(x, y, **ref)
    # a ratio of spectra: relative rounding of each spectrum (SPEC_RTOL of its largest value)
    # divided by the smallest line, where the spectra may be tiny (0 Hz after detrending)
    keep = (pxx_ref > 1e-6 * pxx_ref.max()) & (pyy_ref > 1e-6 * pyy_ref.max(axis=-1, keepdims=True))
    assert_close(coh[keep], coh_ref[keep], 1e6)


@_SETTINGS
@given(setup=welch_setups(), n_point=st.integers(1, 3), seed=st.integers(0, 2**32 - 1))
def test_labeled_frf_spectra_match_scipy(setup, n_point, seed):
    x, y = signals(setup["n"], n_point, seed)
    ds = ami_xr.make_time_dataset(y, fs=setup["fs"], force=x, drive_point=0)
    kw = ours_kwargs(setup)
    kw.pop("fs")
    out = ami_xr.frf(ds, **kw)
    ref = scipy_kwargs(setup)
    f_ref, gff = scipy.signal.welch(x, **ref)
    _, gyy = scipy.signal.welch(y, **ref)
    _, gfy = scipy.signal.csd(x, y, **ref)
    # the frequency coordinate is rfftfreq; fs is recovered from the time axis (1 ulp of fs)
    np.testing.assert_allclose(out[names.FREQUENCY], f_ref, rtol=1e-14)
    assert_close(out["force_autospectrum"], gff, gff.max())
    assert_close(out["response_autospectrum"], gyy, gyy.max())
    assert_close(out["cross_spectrum"], gfy, np.abs(gfy).max())
    keep = gff > 1e-6 * gff.max()  # H1 = Gfy / Gff: relative error over Gff's dynamic range
    assert_close(
        out[names.FRF].values[:, keep],
        gfy[:, keep] / gff[keep],
        1e6 * np.abs(gfy).max() / gff.max(),
    )


# --- closed forms ---------------------------------------------------------------------------------


@_SETTINGS
@given(setup=welch_setups(), n_channel=st.integers(1, 3), seed=st.integers(0, 2**32 - 1))
def test_coherence_lies_in_zero_one(setup, n_channel, seed):
    x, y = signals(setup["n"], n_channel, seed)
    _, coh = spectral.coherence(x, y, **ours_kwargs(setup))
    _, pxx = spectral.welch(x, **ours_kwargs(setup))
    _, pyy = spectral.welch(y, **ours_kwargs(setup))
    # 0/0 is allowed only where a detrended spectrum vanishes (e.g. 0 Hz of one boxcar segment)
    live = (pxx > 1e-20 * pxx.max()) & (pyy > 1e-20 * pyy.max(axis=-1, keepdims=True))
    assert np.all(np.isfinite(coh[live]))
    # |Gxy|^2 <= Gxx Gyy (Cauchy-Schwarz) holds exactly; rounding can lift the ratio by ulps
    assert np.all(coh[live] >= 0.0)
    assert np.all(coh[live] <= 1.0 + 1e-12)


@_SETTINGS
@given(
    nperseg=st.integers(4, 64),
    periods=st.integers(2, 6),
    taps=st.integers(1, 8),
    estimator=st.sampled_from(["H1", "H2"]),
    detrend=st.sampled_from(["none", "constant"]),
    data=st.data(),
)
def test_frf_of_a_periodic_fir_system_is_its_spectrum(
    nperseg, periods, taps, estimator, detrend, data
):
    # x periodic with period nperseg, y = h (*) x its steady state (circular convolution):
    # every segment of nperseg samples (any shift, so any noverlap) obeys Y = H X exactly with
    # the boxcar window, and removing the mean keeps it (mean(y) = H(0) mean(x)).
    noverlap = data.draw(st.integers(0, nperseg - 1))
    seed = data.draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    h = rng.normal(size=min(taps, nperseg))
    period = rng.normal(size=nperseg)
    x = np.tile(period, periods)
    h_full = np.fft.fft(h, nperseg)
    y = np.tile(np.real(np.fft.ifft(np.fft.fft(period) * h_full)), periods)
    ds = ami_xr.make_time_dataset(y[None, :], fs=100.0, force=x, drive_point=0)
    out = ami_xr.frf(
        ds, estimator, window="boxcar", nperseg=nperseg, noverlap=noverlap, detrend=detrend
    )
    want = h_full[: nperseg // 2 + 1]
    got = out[names.FRF].values[0]
    gxx = out["force_autospectrum"].values
    keep = gxx > 1e-8 * gxx.max()  # lines the force excites (not 0 Hz after detrending)
    # a ratio of two spectra each exact to a few ulp of its largest line, over lines whose
    # force is >= 1e-8 of the largest: error <= ~1e-16 / 1e-8 * |H|; 1e-7 bounds it
    tol = 1e-7 * np.abs(want).max()
    assert np.all(np.abs(got[keep] - want[keep]) <= tol)
    coh = out["coherence"].values[0][keep]
    assert np.all(np.abs(coh - 1.0) <= 1e-7)  # noise-free linear system: coherence 1, same tol


@_SETTINGS
@given(setup=welch_setups(), seed=st.integers(0, 2**32 - 1))
def test_welch_obeys_parseval(setup, seed):
    # sum over lines of P * fs / nfft equals the mean over segments of sum (w x)^2 / sum w^2
    # (one-sided density: DC and Nyquist counted once, the others twice)
    setup = dict(setup, detrend="none")
    x, _ = signals(setup["n"], 1, seed)
    _, pxx = spectral.welch(x, **ours_kwargs(setup))
    nperseg = setup["nperseg"]
    noverlap = nperseg // 2 if setup["noverlap"] is None else setup["noverlap"]
    nfft = setup["nfft"] or nperseg
    w = scipy.signal.get_window(setup["window"], nperseg)
    starts = range(0, setup["n"] - nperseg + 1, nperseg - noverlap)
    energy = np.mean([np.sum((w * x[s : s + nperseg]) ** 2) for s in starts]) / np.sum(w**2)
    # sums of <= 130 positive terms: relative rounding ~ 130 eps
    np.testing.assert_allclose(np.sum(pxx) * setup["fs"] / nfft, energy, rtol=1e-12)


@_SETTINGS
@given(
    n=st.integers(2, 300),
    n_point=st.integers(1, 3),
    fs=st.floats(1.0, 1e4),
    window=st.sampled_from([None, "hann", "boxcar"]),
    seed=st.integers(0, 2**32 - 1),
)
def test_impulse_to_frf_is_dt_times_rfft_and_obeys_parseval(n, n_point, fs, window, seed):
    rng = np.random.default_rng(seed)
    h = rng.normal(size=(n_point, n))
    ds = ami_xr.make_time_dataset(h, fs=fs, drive_point=0)
    out = ami_xr.impulse_to_frf(ds, window=window)
    w = np.ones(n) if window is None else scipy.signal.get_window(window, n)
    dt = 1.0 / fs
    want = dt * np.fft.rfft(w * h, axis=-1)
    got = out[names.FRF].values
    # FFT rounding: ~eps log2(n) times dt sum|h|
    assert np.all(np.abs(got - want) <= 64 * EPS * dt * np.abs(h).sum())
    assert out.attrs[names.ATTR_NSAMPLES] == n
    np.testing.assert_allclose(out.attrs[names.ATTR_DT], dt, rtol=1e-14)  # from the time axis
    # Parseval for dt * DFT: sum |H_k|^2 over all n lines = n dt^2 sum (w h)^2
    full = np.concatenate([got, np.conj(got[:, 1 : (n + 1) // 2][:, ::-1])], axis=-1)
    np.testing.assert_allclose(
        np.sum(np.abs(full) ** 2, axis=-1), n * dt**2 * np.sum((w * h) ** 2, axis=-1), rtol=1e-12
    )


# --- streaming ------------------------------------------------------------------------------------


@_SETTINGS
@given(
    setup=welch_setups(),
    chunk=st.integers(1, 200),
    n_point=st.integers(1, 2),
    average=st.sampled_from(["linear", "exponential"]),
    seed=st.integers(0, 2**32 - 1),
)
def test_streaming_in_chunks_equals_in_memory(setup, chunk, n_point, average, seed):
    x, y = signals(setup["n"], n_point, seed)
    ds = ami_xr.make_time_dataset(y, fs=setup["fs"], force=x, drive_point=0)
    kw = ours_kwargs(setup)
    kw.pop("fs")
    whole = ami_xr.frf(ds, average=average, **kw)
    parts = ami_xr.frf(ds, average=average, chunk_samples=chunk, **kw)
    # Tolerance 0: the blocks carry the straddling samples over, so the same segments are
    # windowed, transformed and added in the same order; the sums are bit-identical.
    for name in ("frf", "coherence", "force_autospectrum", "response_autospectrum"):
        np.testing.assert_array_equal(parts[name].values, whole[name].values, err_msg=name)
    assert parts.attrs["n_averages"] == whole.attrs["n_averages"]
