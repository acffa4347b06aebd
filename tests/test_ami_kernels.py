"""AMI kernels against plain numpy references and closed-form single/two-mode data."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ami_xr.kernels import ami as k
from ami_xr.kernels.basis import mode_contribution, pole_basis

N = 4096
DT = 60.0 / N
OMEGA = 2 * np.pi * np.fft.rfftfreq(N, DT)
MODELS = [(None, None), (DT, N)]


def _band(lo, hi):
    return (OMEGA > lo) & (OMEGA < hi)


def test_rows_are_eqs_11_12():
    """Real/imaginary rows of (*) are the paper's eqs. 11-12 in its four unknowns."""
    lam, a = -0.4 + 65.0j, 1e-3 + 2e-3j
    sel = _band(62, 68)
    g = mode_contribution(OMEGA[sel], lam, a)
    ws = 65.0
    rows, rhs = k.single_mode_rows(g, OMEGA[sel], ws)
    x = np.array(
        [
            abs(lam) ** 2 / ws**2,
            -2 * lam.real / ws,
            -2 * (lam.real * a.real + lam.imag * a.imag) / ws**2,
            2 * a.real / ws,
        ]
    )
    np.testing.assert_allclose(rows @ x, rhs, atol=1e-12 * np.abs(rhs).max())
    # eq. 11 (real part) and eq. 12 (imaginary part) written out with numpy
    w = OMEGA[sel]
    eq11 = (
        g.real * (abs(lam) ** 2 - w**2)
        + 2 * w * g.imag * lam.real
        + 2 * (lam.real * a.real + lam.imag * a.imag)
    )
    eq12 = g.imag * (abs(lam) ** 2 - w**2) - 2 * w * g.real * lam.real - 2 * w * a.real
    np.testing.assert_allclose(eq11, 0, atol=1e-12 * np.abs(g).max() * 65**2)
    np.testing.assert_allclose(eq12, 0, atol=1e-12 * np.abs(g).max() * 65**2)
    # rows as numpy builds them: G v^2 = -c0 G - c1 G v + e0 + e1 v, v = i w / ws
    v = 1j * w / ws
    cols = np.stack([-g, -g * v, np.ones_like(g), v], axis=1)
    ref = np.empty((2 * w.size, 4))
    ref[0::2], ref[1::2] = cols.real, cols.imag
    np.testing.assert_allclose(rows, ref, rtol=1e-14, atol=0)


@pytest.mark.parametrize("dt,n", MODELS)
def test_single_mode_exact(dt, n):
    lam, a = -0.4 + 65.0j, 1e-3 + 2e-3j
    sel = _band(62, 68)
    g = mode_contribution(OMEGA, lam, a, dt, n)[sel]
    est, res, code = k.fit_single_mode(g, OMEGA[sel], dt, n)
    assert code == k.FIT_OK
    assert abs(est - lam) / abs(lam) < 1e-12
    assert abs(res - a) / abs(a) < 1e-10


@pytest.mark.parametrize("dt,n", MODELS)
def test_single_mode_matches_lstsq(dt, n):
    """The normal-equation solve equals numpy's lstsq on the same rows (noisy data)."""
    rng = np.random.default_rng(1)
    lam, a = -0.6 + 40.0j, 2e-3 - 1e-3j
    sel = _band(38, 42)
    g = mode_contribution(OMEGA, lam, a, dt, n)[sel]
    scale = 0.02 * np.abs(g).max()
    g = g + scale * (rng.standard_normal(g.size) + 1j * rng.standard_normal(g.size))
    ws = float(np.mean(OMEGA[sel]))
    rows, rhs = k.single_mode_rows(g, OMEGA[sel], ws, dt)
    sol = np.linalg.lstsq(rows, rhs, rcond=None)[0]
    c0, c1 = sol[0], sol[1]
    v1 = complex(-c1 / 2, math.sqrt(4 * c0 - c1**2) / 2)
    lam_ref = ws * v1 if dt is None else np.log(1 / (1 - dt * ws * v1)) / dt
    est, _, code = k.fit_single_mode(g, OMEGA[sel], dt, n)
    assert code == k.FIT_OK
    assert abs(est - lam_ref) / abs(lam_ref) < 1e-10


@pytest.mark.parametrize("dt,n", MODELS)
def test_simo_single_mode_exact(dt, n):
    lam = -0.5 + 48.0j
    res = np.array([1e-3 + 2e-3j, -3e-3 + 1e-3j, 5e-4 - 1e-4j])
    sel = _band(46, 50)
    g = np.stack([mode_contribution(OMEGA, lam, r, dt, n)[sel] for r in res])
    est, r_est, code = k.fit_single_mode_simo(g, OMEGA[sel], dt, n)
    assert code == k.FIT_OK
    assert abs(est - lam) / abs(lam) < 1e-12
    np.testing.assert_allclose(r_est, res, rtol=1e-9)


@pytest.mark.parametrize("dt,n", MODELS)
def test_two_mode_fit_exact(dt, n):
    l1, l2 = -0.39 + 65.0j, -0.59 + 65.9j
    r = np.array([[1e-3 + 2e-3j, -2e-3 + 1e-3j], [3e-3 - 2e-3j, 1e-3 + 1e-3j]])
    g = np.stack(
        [
            mode_contribution(OMEGA, l1, ri[0], dt, n) + mode_contribution(OMEGA, l2, ri[1], dt, n)
            for ri in r
        ]
    )
    idx = np.flatnonzero(_band(63.5, 67.5))
    x = k._line_variable(OMEGA, dt or 0.0)
    lam = np.zeros(2, complex)
    res = np.zeros((2, 2), complex)
    code = k._fit_two_modes(
        g, x, idx[0], idx[-1] + 1, 65.4, dt or 0.0, n or 0, 0.5, 0.1, 1e9, np.ones(2), lam, res
    )
    assert code == k.FIT_OK
    order = np.argsort(lam.imag)
    np.testing.assert_allclose(lam[order], [l1, l2], rtol=1e-10)
    np.testing.assert_allclose(res[:, order], r, rtol=1e-7)


@pytest.mark.parametrize("dt,n", MODELS)
def test_synthesize_matches_basis(dt, n):
    lam = np.array([-0.4 + 30j, -0.7 + 48j, np.nan + 0j])
    res = np.array([[1e-3 + 1e-3j, 2e-3 - 1e-3j, 1.0], [-1e-3j, 5e-4 + 0j, np.nan]])
    out = k.synthesize(OMEGA, lam, res, dt, n)
    ref = np.stack(
        [
            sum(mode_contribution(OMEGA, lam[m], res[j, m], dt, n) for m in range(2))
            for j in range(2)
        ]
    )
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-18)


@pytest.mark.parametrize("dt,n", MODELS)
def test_residue_normal_equations_numpy(dt, n):
    lam = np.array([-0.4 + 30j, -0.7 + 48j])
    rng = np.random.default_rng(0)
    g = rng.standard_normal((3, OMEGA.size)) + 1j * rng.standard_normal((3, OMEGA.size))
    use = _band(20, 60)
    nmat, rhs = k.residue_normal_equations(g, OMEGA, lam, use, dt, n)
    cols = []
    for lk in lam:
        b = pole_basis(OMEGA[use], lk, dt, n)
        bc = pole_basis(OMEGA[use], np.conj(lk), dt, n)
        cols += [b + bc, 1j * (b - bc)]
    cmat = np.stack(cols, axis=1)
    real = np.vstack([cmat.real, cmat.imag])
    np.testing.assert_allclose(nmat, real.T @ real, rtol=1e-10)
    data = np.hstack([g[:, use].real, g[:, use].imag]).T
    np.testing.assert_allclose(rhs, real.T @ data, rtol=1e-10, atol=1e-10 * np.abs(rhs).max())


@pytest.mark.parametrize("dt,n", MODELS)
def test_residues_fixed_exact(dt, n):
    lam = np.array([-0.4 + 30j, -0.7 + 48j, -0.3 + 65j])
    res = np.array([[1e-3 + 1e-3j, 2e-3 - 1e-3j, 1e-4j], [-1e-3j, 5e-4 + 0j, 3e-3 + 1e-3j]])
    g = k.synthesize(OMEGA, lam, res, dt, n)
    out = k.residues_fixed(g, OMEGA, lam, None, dt, n)
    np.testing.assert_allclose(out, res, rtol=1e-9)
    # with residual terms (receptance): exact data of modes + R_L/(iw)^2 + R_U
    w = OMEGA[1:]
    extra = np.array([[1e-2 + 0j, 2e-6 + 1e-7j], [-3e-2 + 0j, 1e-6 + 0j]])
    g2 = g[:, 1:] + extra[:, :1] / (1j * w) ** 2 + extra[:, 1:]
    out2 = k.residues_fixed(g2, w, lam, None, dt, n, residual_kind=0)
    np.testing.assert_allclose(out2[:, :3], res, rtol=1e-7)
    np.testing.assert_allclose(out2[:, 3:], extra, rtol=1e-6)


def test_noise_floor_and_threshold():
    rng = np.random.default_rng(3)
    sigma = 0.7
    shape = (4, 20000)
    noise = sigma / np.sqrt(2) * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))
    np.testing.assert_allclose(k.noise_floor(noise), sigma, rtol=0.03)
    t = k.peak_threshold(2049, 1e-3)
    assert abs((1 - math.exp(-t)) ** 2049 - (1 - 1e-3)) < 1e-12
    ts = k._sum_threshold(4, 2049, 1e-3)
    assert abs(k._gamma_tail(4, ts) - (1 - (1 - 1e-3) ** (1 / 2049))) < 1e-9
    # gamma tail against the closed form for k = 2
    assert abs(k._gamma_tail(2, 3.0) - math.exp(-3.0) * 4.0) < 1e-15


def test_wrappers_validate():
    with pytest.raises(ValueError, match="omega"):
        k.synthesize(np.array([2.0, 1.0]), np.array([1j]), np.array([[1.0]]))
    with pytest.raises(ValueError, match="data"):
        k.fit_single_mode(np.ones(3, complex), np.arange(4.0))
