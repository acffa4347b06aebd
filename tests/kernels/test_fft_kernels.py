"""FFT-to-FRF kernels (ami_xr/kernels/fft.py) through their checked wrappers, against numpy,
scipy and the exact discrete modal basis."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.fft

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import fft as kfft
from ami_xr.kernels import windows as kw

from ..reference import PAPER_DT as DT
from ..reference import PAPER_N as N
from ..reference import TWO_MODE_LAM as LAM
from ..reference import TWO_MODE_RES as RES
from ..reference import assert_fft_ratio_close, frf_from_residues, impulse_responses, rel_err


@pytest.mark.parametrize("n", [1, 2, 7, 64, 1001])
def test_rfft_frequencies_match_scipy(n):
    # k / (n dt) against scipy's formula: one or two roundings, so 1e-15 relative (atol=0: the 0 Hz
    # line is exactly 0 in both)
    np.testing.assert_allclose(
        kfft.rfft_frequencies(n, 0.01), scipy.fft.rfftfreq(n, 0.01), rtol=1e-15, atol=0
    )


def test_impulse_to_frf_matches_numpy_reference():
    rng = np.random.default_rng(0)
    y = rng.standard_normal((2, 3, 101))
    w = kw.get_window("hann", 101)
    got = kfft.impulse_to_frf(y, 0.02, window=w)
    # the same pocketfft transform, possibly another SIMD path: a few ulp of the largest bin (norm-
    # wise eps log2(n)); atol=1e-15 covers bins near zero (|y| ~ 1, n = 101)
    np.testing.assert_allclose(got, 0.02 * np.fft.rfft(y * w, axis=-1), rtol=1e-13, atol=1e-15)
    assert got.shape == (2, 3, 51) and got.dtype == np.complex128
    np.testing.assert_allclose(
        kfft.impulse_to_frf(y[0, 0], 0.02), 0.02 * np.fft.rfft(y[0, 0]), rtol=1e-13, atol=1e-15
    )


@pytest.mark.parametrize(("n", "dt"), [(N, DT), (1001, 0.02), (64, 0.5)])
def test_impulse_to_frf_of_modal_response_is_the_exact_discrete_basis(n, dt):
    got = kfft.impulse_to_frf(impulse_responses(LAM, RES, n, dt), dt)
    omega = 2 * np.pi * kfft.rfft_frequencies(n, dt)
    assert got.shape == (2, n // 2 + 1)
    # FFT of n <= 4096 samples (norm-wise error ~eps log2 n ~ 3e-15) vs the closed-form geometric
    # sum, whose 1 - exp(lam dt) loses ~log10(1/|lam dt|) ~ 2 digits: 1e-12 norm-wise
    assert rel_err(got, frf_from_residues(omega, LAM, RES, dt, n)) < 1e-12


def test_exponential_window_shifts_every_eigenvalue_by_beta():
    beta = kw.exponential_decay_rate(N, fs=1.0 / DT, end_value=0.01)
    w = kw.get_window("exponential", N, end_value=0.01)
    got = kfft.impulse_to_frf(impulse_responses(LAM, RES, N, DT), DT, window=w)
    omega = 2 * np.pi * kfft.rfft_frequencies(N, DT)
    # same residues, eigenvalues lam - beta: identification must add beta back to Re(lam)
    # as above (FFT vs closed form, norm-wise); the unshifted poles below are off by ~beta/zeta,
    # i.e. O(1)
    assert rel_err(got, frf_from_residues(omega, LAM - beta, RES, DT, N)) < 1e-12
    assert rel_err(got, frf_from_residues(omega, LAM, RES, DT, N)) > 1e-3


def test_frf_from_force_matches_numpy_reference_and_broadcasts():
    rng = np.random.default_rng(1)
    y = rng.standard_normal((3, 64))
    f = rng.standard_normal(64)
    wy, wf = kw.get_window("exponential", 64, end_value=0.1), kw.get_window("force", 64, width=5)
    got = kfft.frf_from_force(y, f, window=wy, force_window=wf)
    assert_fft_ratio_close(got, y * wy, f * wf)
    per_row = kfft.frf_from_force(y, np.tile(f, (3, 1)), window=wy, force_window=wf)
    # the same FFTs of the same rows, only the force row repeated: equal up to pocketfft's batch-
    # dependent SIMD path (<= a few ulp); F has no zeros near the bins here (random force)
    np.testing.assert_allclose(per_row, got, rtol=1e-15)


def test_discrete_unit_impulse_force_gives_the_impulse_formula():
    f = np.zeros(N)
    f[0] = 1.0 / DT  # unit area
    y = impulse_responses(LAM, RES, N, DT)
    # rfft of dt^-1 delta is exactly 1/dt in every bin, so Y / F differs from dt Y by one rounding
    # of the division: a few ulp per bin; 1e-13 leaves room for pocketfft's paths
    np.testing.assert_allclose(kfft.frf_from_force(y, f), kfft.impulse_to_frf(y, DT), rtol=1e-13)


def test_kernel_inputs_are_not_modified():
    y = impulse_responses(LAM, RES, N, DT)
    y0 = y.copy()
    kfft.impulse_to_frf(y, DT, window=kw.get_window("hann", N))
    # input untouched: a copy, no arithmetic
    np.testing.assert_array_equal(y, y0)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: kfft.impulse_to_frf(np.ones(8), 0.0), "dt"),
        (lambda: kfft.impulse_to_frf(np.ones(8), float("nan")), "dt"),
        (lambda: kfft.impulse_to_frf(np.ones(8) + 0j, 0.1), "y:"),
        (lambda: kfft.impulse_to_frf(np.ones((2, 0)), 0.1), "y:"),
        (lambda: kfft.impulse_to_frf(np.ones(8), 0.1, window=np.ones(7)), "window"),
        (lambda: kfft.frf_from_force(np.ones((2, 8)), np.ones(7)), "f:"),
        (lambda: kfft.frf_from_force(np.ones((2, 8)), np.ones((3, 8))), "f:"),
        (lambda: kfft.frf_from_force(np.ones(8), np.ones((2, 8))), "f:"),
        (lambda: kfft.frf_from_force(np.ones(8), np.zeros(8)), "f:.*zero"),
        (
            lambda: kfft.frf_from_force(np.ones(8), np.ones(8), force_window=np.ones(3)),
            "force_window",
        ),
        (lambda: kfft.rfft_frequencies(0, 0.1), "n:"),
    ],
)
def test_kernel_bad_inputs_name_the_argument(call, match):
    with pytest.raises(AmiXrValueError, match=match):
        call()
