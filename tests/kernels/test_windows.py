"""Window kernels against plain numpy references, scipy.signal and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal
import scipy.signal.windows as sw
from hypothesis import given, settings
from hypothesis import strategies as st

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import windows as kw

from ..reference import cosine_window, exponential_window, force_window

FLATTOP = (0.21557895, 0.41663158, 0.277263158, 0.083578947, 0.006947368)
LENGTHS = (1, 2, 3, 4, 7, 8, 9, 64, 255, 1000)


# --- cosine windows ---------------------------------------------------------------------------


@pytest.mark.parametrize("n", LENGTHS)
@pytest.mark.parametrize("sym", [False, True])
@pytest.mark.parametrize("name", ["hann", "flattop", "boxcar"])
def test_cosine_windows_match_scipy_get_window(name, n, sym):
    got = kw.get_window(name, n, sym=sym)
    want = scipy.signal.get_window(name, n, fftbins=not sym)
    assert got.dtype == np.float64 and got.shape == (n,)
    # entries in [0, 1] from a few cosines: a few ulp (2.2e-16 each) of 1 in absolute terms
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


@pytest.mark.parametrize("n", LENGTHS)
@pytest.mark.parametrize("sym", [False, True])
def test_cosine_windows_match_numpy_reference(n, sym):
    # entries in [0, 1] from a few cosines: a few ulp of 1 in absolute terms (near-zero ends)
    np.testing.assert_allclose(
        kw.get_window("hann", n, sym=sym), cosine_window((0.5, 0.5), n, sym), rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(
        kw.get_window("flattop", n, sym=sym), cosine_window(FLATTOP, n, sym), rtol=0, atol=1e-15
    )
    np.testing.assert_array_equal(kw.get_window("boxcar", n, sym=sym), np.ones(n))  # no arithmetic


def test_aliases_give_the_canonical_window():
    # an alias resolves to the same name, hence the same code path: bit-identical
    np.testing.assert_array_equal(kw.get_window("Hanning", 16), kw.get_window("hann", 16))
    np.testing.assert_array_equal(kw.get_window("rectangular", 5), np.ones(5))
    np.testing.assert_array_equal(kw.get_window("flat-top", 16), kw.get_window("flattop", 16))
    assert kw.window_name("transient") == "force"


# --- exponential window -----------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 10, 4096])
def test_exponential_by_decay_matches_numpy_and_scipy(n):
    fs, decay = 4096 / 60.0, 0.35
    got = kw.get_window("exponential", n, fs=fs, decay=decay)
    # one exp of an argument formed with 2-3 roundings: a few ulp relative
    np.testing.assert_allclose(got, exponential_window(n, fs, decay), rtol=1e-14, atol=0)
    scipy_w = sw.exponential(n, center=0, tau=fs / decay, sym=False)
    np.testing.assert_allclose(got, scipy_w, rtol=1e-15, atol=0)  # same formula: <= 4 ulp


def test_exponential_by_end_value():
    n, end = 500, 0.01
    got = kw.get_window("exponential", n, end_value=end)
    assert got[0] == 1.0
    assert got[-1] == pytest.approx(end, rel=1e-14)  # exp(log(end)): a few ulp
    tau = -(n - 1) / np.log(end)  # scipy's documented recipe for a one-sided window
    # the same formula as scipy's: <= 4 ulp
    np.testing.assert_allclose(got, sw.exponential(n, 0, tau, False), rtol=1e-15, atol=0)
    # the same window set by its decay rate
    fs = 100.0
    beta = kw.exponential_decay_rate(n, fs=fs, end_value=end)
    assert beta == pytest.approx(-np.log(end) * fs / (n - 1), rel=1e-15)  # 3 roundings
    # exponent k beta / fs vs k log(end) / (n - 1): relative error ~ eps * exponent (<= 4.6)
    np.testing.assert_allclose(kw.get_window("exponential", n, fs=fs, decay=beta), got, rtol=1e-13)


def test_exponential_decay_rate_shifts_a_mode_exactly():
    fs, n, beta = 50.0, 300, 0.8
    lam = -0.3 + 12.0j
    t = np.arange(n) / fs
    w = kw.get_window(
        "exponential", n, fs=fs, decay=kw.exponential_decay_rate(n, fs=fs, decay=beta)
    )
    # complex exp of arguments up to |lam| t ~ 72: relative error ~ eps * 72 ~ 1.6e-14
    np.testing.assert_allclose(w * np.exp(lam * t), np.exp((lam - beta) * t), rtol=1e-13)


def test_one_sided_windows_ignore_sym():
    # sym is ignored, so both calls run the same code: bit-identical
    a = kw.get_window("exponential", 20, end_value=0.1, sym=True)
    np.testing.assert_array_equal(a, kw.get_window("exponential", 20, end_value=0.1))
    b = kw.get_window("force", 20, width=3, taper=2, sym=True)
    np.testing.assert_array_equal(b, kw.get_window("force", 20, width=3, taper=2))


# --- force window -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("n", "width", "taper"),
    [(32, 5, 4), (32, 1, 0), (16, 10, 10), (8, 8, 3), (100, 7, 1), (1, 1, 2)],
)
def test_force_window_matches_numpy_reference(n, width, taper):
    got = kw.get_window("force", n, width=width, taper=taper)
    np.testing.assert_allclose(got, force_window(n, width, taper), rtol=0, atol=1e-15)  # ulp of 1


@pytest.mark.parametrize(("width", "taper"), [(5, 4), (1, 3), (20, 2), (3, 0)])
def test_force_window_taper_is_the_falling_half_of_scipy_tukey(width, taper):
    n = width + taper + 10
    got = kw.get_window("force", n, width=width, taper=taper)
    m = 2 * (width + taper) + 1
    tukey = sw.tukey(m, (taper + 1) / (width + taper), sym=True)
    # scipy's tukey formula cancels (-2/alpha + 1 + ...), so it is accurate to a few ulp only
    np.testing.assert_allclose(got[: width + taper + 1], tukey[width + taper :], rtol=0, atol=1e-14)
    np.testing.assert_array_equal(got[width + taper :], 0.0)  # zeros are written, not computed


def test_force_window_taper_is_half_a_scipy_hann():
    width, taper = 6, 5
    got = kw.get_window("force", 30, width=width, taper=taper)
    hann = sw.hann(2 * taper + 3, sym=True)
    np.testing.assert_allclose(
        got[width : width + taper],
        hann[taper + 2 : 2 * taper + 2],
        atol=1e-15,  # ulp of 1
    )


def test_force_window_default_taper():
    # rtol=1e-7 (default): the same formula as the oracle, so this mainly checks the default taper
    np.testing.assert_allclose(kw.get_window("force", 200, width=40), force_window(200, 40, 4))
    np.testing.assert_allclose(kw.get_window("force", 20, width=3), force_window(20, 3, 1))


# --- correction factors -----------------------------------------------------------------------


@pytest.mark.parametrize("n", [3, 4, 17, 64, 1001])
def test_periodic_hann_corrections_are_exact(n):
    w = kw.get_window("hann", n)
    # sums of n <= 1001 terms in [0, 1]: relative error <= n eps worst case, ~sqrt(n) eps typical
    assert kw.amplitude_correction(w) == pytest.approx(2.0, rel=1e-14)
    assert kw.energy_correction(w) == pytest.approx(math.sqrt(8 / 3), rel=1e-14)


def test_symmetric_hann_corrections_tend_to_closed_forms():
    w = kw.get_window("hann", 100001, sym=True)
    # the symmetric window's sums differ from the periodic closed forms by O(1/n) = 1e-5
    assert kw.amplitude_correction(w) == pytest.approx(2.0, rel=1e-4)
    assert kw.energy_correction(w) == pytest.approx(math.sqrt(8 / 3), rel=1e-4)


@pytest.mark.parametrize("n", [16, 1000])
def test_periodic_flattop_corrections_closed_form(n):
    w = kw.get_window("flattop", n)
    a = np.array(FLATTOP)
    # sums of n <= 1000 terms of both signs: ~sqrt(n) eps times the cancellation (~5)
    assert kw.amplitude_correction(w) == pytest.approx(1 / a[0], rel=1e-13)
    assert kw.energy_correction(w) == pytest.approx(
        math.sqrt(1 / (a[0] ** 2 + 0.5 * np.sum(a[1:] ** 2))), rel=1e-13
    )


def test_corrections_match_numpy_reference():
    rng = np.random.default_rng(0)
    for w in (np.ones(7), kw.get_window("force", 50, width=9), rng.uniform(0.1, 1.0, 33)):
        # the same sums in (possibly) another order: n <= 50 terms, relative error <= 50 eps
        assert kw.amplitude_correction(w) == pytest.approx(w.size / w.sum(), rel=1e-14)
        assert kw.energy_correction(w) == pytest.approx(np.sqrt(w.size / np.sum(w**2)), rel=1e-14)


def test_exponential_corrections_closed_form():
    n, fs, beta = 400, 20.0, 0.5
    w = kw.get_window("exponential", n, fs=fs, decay=beta)
    q = np.exp(-beta / fs)
    # geometric-series closed form: 1 - q = 0.025 loses ~2 digits to cancellation, plus 400 sums
    assert kw.amplitude_correction(w) == pytest.approx(n * (1 - q) / (1 - q**n), rel=1e-12)
    assert kw.energy_correction(w) == pytest.approx(
        np.sqrt(n * (1 - q**2) / (1 - q ** (2 * n))), rel=1e-12
    )


# --- apply_window -----------------------------------------------------------------------------


def test_apply_window_batched_real_and_complex():
    rng = np.random.default_rng(1)
    w = kw.get_window("hann", 24)
    x = rng.standard_normal((2, 3, 24))
    x0 = x.copy()
    got = kw.apply_window(x, w)
    # one multiplication per element, exactly as numpy does it: bit-identical
    np.testing.assert_array_equal(got, x * w)
    np.testing.assert_array_equal(x, x0)  # input untouched
    assert got is not x and got.shape == x.shape and got.dtype == np.float64
    z = x + 1j * rng.standard_normal(x.shape)
    np.testing.assert_array_equal(kw.apply_window(z, w), z * w)
    np.testing.assert_array_equal(kw.apply_window(np.arange(24), w), np.arange(24) * w)
    np.testing.assert_array_equal(kw.apply_window(x[0, 0], w), x[0, 0] * w)  # 1-D
    assert kw.apply_window(np.empty((0, 24)), w).shape == (0, 24)


def test_apply_window_non_contiguous_input():
    x = np.random.default_rng(2).standard_normal((24, 5)).T  # last axis strided
    w = kw.get_window("flattop", 24)
    np.testing.assert_array_equal(kw.apply_window(x, w), x * w)  # one product each: exact


# --- bad inputs -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"name": "kaiser", "n": 8}, "window"),
        ({"name": 3, "n": 8}, "window"),
        ({"name": "hann", "n": 0}, "n:"),
        ({"name": "hann", "n": 2.5}, "n:"),
        ({"name": "hann", "n": True}, "n:"),
        ({"name": "exponential", "n": 8}, "decay, end_value"),
        ({"name": "exponential", "n": 8, "decay": 1.0, "end_value": 0.1}, "decay, end_value"),
        ({"name": "exponential", "n": 8, "decay": 1.0}, "fs"),
        ({"name": "exponential", "n": 8, "decay": 0.0, "fs": 10.0}, "decay"),
        ({"name": "exponential", "n": 8, "decay": -1.0, "fs": 10.0}, "decay"),
        ({"name": "exponential", "n": 8, "decay": 1.0, "fs": -10.0}, "fs"),
        ({"name": "exponential", "n": 8, "end_value": 1.0}, "end_value"),
        ({"name": "exponential", "n": 8, "end_value": 0.0}, "end_value"),
        ({"name": "exponential", "n": 8, "end_value": "x"}, "end_value"),
        ({"name": "exponential", "n": 1, "end_value": 0.5}, "end_value"),
        ({"name": "force", "n": 8}, "width"),
        ({"name": "force", "n": 8, "width": 9}, "width"),
        ({"name": "force", "n": 8, "width": 0}, "width"),
        ({"name": "force", "n": 8, "width": 2, "taper": -1}, "taper"),
        ({"name": "hann", "n": 8, "decay": 1.0}, "decay"),
        ({"name": "hann", "n": 8, "width": 2}, "width"),
        ({"name": "force", "n": 8, "width": 2, "end_value": 0.5}, "end_value"),
    ],
)
def test_get_window_bad_inputs_name_the_argument(kwargs, match):
    with pytest.raises(AmiXrValueError, match=match):
        kw.get_window(**kwargs)


def test_other_bad_inputs():
    with pytest.raises(AmiXrValueError, match="x:"):
        kw.apply_window(np.ones((2, 5)), np.ones(4))
    with pytest.raises(AmiXrValueError, match="w:"):
        kw.apply_window(np.ones(4), np.ones((2, 2)))
    with pytest.raises(AmiXrValueError, match="w:"):
        kw.apply_window(np.ones(4), np.array([1.0, np.nan, 1.0, 1.0]))
    with pytest.raises(AmiXrValueError, match="x:"):
        kw.apply_window(np.array(["a", "b"]), np.ones(2))
    with pytest.raises(AmiXrValueError, match="w:"):
        kw.amplitude_correction(np.zeros(4))
    with pytest.raises(AmiXrValueError, match="w:"):
        kw.energy_correction(np.zeros(4))
    with pytest.raises(AmiXrValueError, match="w:"):
        kw.amplitude_correction(np.array([]))
    with pytest.raises(AmiXrValueError, match="fs"):
        kw.exponential_decay_rate(10, fs=0.0, decay=1.0)
    with pytest.raises(AmiXrValueError, match="n:"):
        kw.exponential_decay_rate(0, fs=1.0, decay=1.0)


# --- property tests ---------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(["hann", "flattop", "boxcar"]),
    n=st.integers(1, 3000),
    sym=st.booleans(),
)
def test_property_cosine_windows_equal_scipy(name, n, sym):
    got = kw.get_window(name, n, sym=sym)
    # values in [0, 1]: a few ulp of 1 absolute (rtol 1e-7 default is never the binding one)
    np.testing.assert_allclose(got, scipy.signal.get_window(name, n, fftbins=not sym), atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 200),
    width=st.integers(1, 200),
    taper=st.integers(0, 50),
    batch=st.integers(0, 3),
)
def test_property_force_window_and_apply_window(n, width, taper, batch):
    width = min(width, n)
    w = kw.get_window("force", n, width=width, taper=taper)
    np.testing.assert_allclose(w, force_window(n, width, taper), atol=1e-15)  # ulp of 1
    x = np.random.default_rng(n).standard_normal((batch, 2, n))
    np.testing.assert_array_equal(kw.apply_window(x, w), x * w)  # one product each: exact
