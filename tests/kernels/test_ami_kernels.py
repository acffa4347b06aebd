"""AMI kernels (one test section per topic module of ami_xr/kernels) against plain numpy
references and closed-form single/two-mode data, through their checked public wrappers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import isolate as ki
from ami_xr.kernels import linalg as kl
from ami_xr.kernels import modal_basis as kb
from ami_xr.kernels import noise as kn
from ami_xr.kernels import residues as kr
from ami_xr.kernels import single_mode as k
from ami_xr.kernels import subtract as ks
from ami_xr.kernels import two_mode as k2
from ami_xr.kernels.modal_basis import mode_contribution, pole_basis

from ..reference import PAPER_DT as DT
from ..reference import PAPER_N as N
from ..reference import PAPER_OMEGA as OMEGA
from ..reference import frf_from_residues, single_mode_lstsq

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
    # the exact unknowns satisfy every row; rounding of 4-term dot products of O(|rhs|) values: a
    # few ulp of the largest right-hand side (norm-wise: the residual is 0)
    np.testing.assert_allclose(rows @ x, rhs, rtol=0, atol=1e-12 * np.abs(rhs).max())
    # eq. 11 (real part) and eq. 12 (imaginary part) written out with numpy
    w = OMEGA[sel]
    eq11 = (
        g.real * (abs(lam) ** 2 - w**2)
        + 2 * w * g.imag * lam.real
        + 2 * (lam.real * a.real + lam.imag * a.imag)
    )
    eq12 = g.imag * (abs(lam) ** 2 - w**2) - 2 * w * g.real * lam.real - 2 * w * a.real
    # exact data satisfies eqs. 11-12 identically: the residual is rounding of terms of size |g| w^2
    # (w ~ 65), so the bound is relative to that scale, not to 0
    np.testing.assert_allclose(eq11, 0, atol=1e-12 * np.abs(g).max() * 65**2)
    np.testing.assert_allclose(eq12, 0, atol=1e-12 * np.abs(g).max() * 65**2)
    # rows as numpy builds them: G v^2 = -c0 G - c1 G v + e0 + e1 v, v = i w / ws
    v = 1j * w / ws
    cols = np.stack([-g, -g * v, np.ones_like(g), v], axis=1)
    ref = np.empty((2 * w.size, 4))
    ref[0::2], ref[1::2] = cols.real, cols.imag
    # the same products in another order: <= 2-3 roundings each, no entry is near zero (|g| and w/ws
    # ~ 1)
    np.testing.assert_allclose(rows, ref, rtol=1e-14, atol=0)


@pytest.mark.parametrize("dt,n", MODELS)
def test_single_mode_exact(dt, n):
    lam, a = -0.4 + 65.0j, 1e-3 + 2e-3j
    sel = _band(62, 68)
    g = mode_contribution(OMEGA, lam, a, dt, n)[sel]
    est, res, code = k.fit_single_mode(g, OMEGA[sel], dt, n)
    assert code == k.FIT_OK
    # exact data: the linear least squares is consistent, so only rounding remains (measured 2e-16);
    # 1e-12 leaves room for other CPUs and BLAS
    assert abs(est - lam) / abs(lam) < 1e-12
    # the residue follows from the eigenvalue through the basis near resonance, which amplifies its
    # error by up to |lam| / |Re lam| ~ 1.6e2 (measured 1.5e-14)
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
    lam_ref = single_mode_lstsq(rows, rhs, ws, dt)
    est, _, code = k.fit_single_mode(g, OMEGA[sel], dt, n)
    assert code == k.FIT_OK
    # normal equations vs QR-based lstsq on the same noisy rows: they differ by up to cond(rows)^2
    # eps
    assert abs(est - lam_ref) / abs(lam_ref) < 1e-10


@pytest.mark.parametrize("dt,n", MODELS)
def test_simo_single_mode_exact(dt, n):
    lam = -0.5 + 48.0j
    res = np.array([1e-3 + 2e-3j, -3e-3 + 1e-3j, 5e-4 - 1e-4j])
    sel = _band(46, 50)
    g = np.stack([mode_contribution(OMEGA, lam, r, dt, n)[sel] for r in res])
    est, r_est, code = k.fit_single_mode(g, OMEGA[sel], dt, n)
    assert code == k.FIT_OK
    # exact data: the linear least squares is consistent, so only rounding remains (measured 2e-16);
    # 1e-12 leaves room for other CPUs and BLAS
    assert abs(est - lam) / abs(lam) < 1e-12
    # SIMO residues from the fitted eigenvalue's basis: its rounding error times the resonance
    # sensitivity (~1e2); no residue near zero
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
    sel = slice(idx[0], idx[-1] + 1)
    lam, res, code = k2.fit_two_modes(
        g[:, sel], OMEGA[sel], dt, n, scale=65.4, zeta_max=0.5, w_lo=0.1, w_hi=1e9
    )
    assert code == k.FIT_OK
    order = np.argsort(lam.imag)
    # two overlapping modes (1.4 % apart) from exact data: the 2-mode polynomial is ill-conditioned;
    # rounding alone moves the poles by up to ~2e-10 (measured: the data perturbed by 2e-16
    # relative gives 1.3e-10 with numba's np.roots and BLAS, 1.7e-10 with the loops and
    # poly_roots of today's fit_two; 2.3e-10 unperturbed, discrete model)
    np.testing.assert_allclose(lam[order], [l1, l2], rtol=5e-10)
    # residues of close modes are ~|lam| / |l1 - l2| ~ 1e2 more sensitive than the poles: measured
    # 2.8e-9
    np.testing.assert_allclose(res[:, order], r, rtol=1e-7)


@pytest.mark.parametrize("dt,n", MODELS)
def test_synthesize_matches_basis(dt, n):
    lam = np.array([-0.4 + 30j, -0.7 + 48j, np.nan + 0j])
    res = np.array([[1e-3 + 1e-3j, 2e-3 - 1e-3j, 1.0], [-1e-3j, 5e-4 + 0j, np.nan]])
    out = kb.synthesize(OMEGA, lam, res, dt, n)
    ref = frf_from_residues(OMEGA, lam[:2], res[:, :2], dt, n)  # the NaN mode is skipped
    # the same basis sums in another order: a few ulp of each term; atol (1e-15 of the |g| ~ 1e-3
    # scale) covers sums that cancel
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-18)


@pytest.mark.parametrize("dt,n", MODELS)
def test_residue_normal_equations_numpy(dt, n):
    lam = np.array([-0.4 + 30j, -0.7 + 48j])
    rng = np.random.default_rng(0)
    g = rng.standard_normal((3, OMEGA.size)) + 1j * rng.standard_normal((3, OMEGA.size))
    use = _band(20, 60)
    nmat, rhs = kr.residue_normal_equations(g, OMEGA, lam, use, dt, n)
    cols = []
    for lk in lam:
        b = pole_basis(OMEGA[use], lk, dt, n)
        bc = pole_basis(OMEGA[use], np.conj(lk), dt, n)
        cols += [b + bc, 1j * (b - bc)]
    cmat = np.stack(cols, axis=1)
    real = np.vstack([cmat.real, cmat.imag])
    want = real.T @ real
    # sums of ~600 products of basis values in another order: rounding ~sqrt(n) eps of the largest
    # terms; cross terms between the two modes are small, so the bound is relative to the largest
    np.testing.assert_allclose(nmat, want, rtol=1e-10, atol=1e-10 * np.abs(want).max())
    data = np.hstack([g[:, use].real, g[:, use].imag]).T
    # sums of ~600 products of random data with the basis: rounding ~sqrt(n) eps of the largest;
    # atol for entries that cancel
    np.testing.assert_allclose(rhs, real.T @ data, rtol=1e-10, atol=1e-10 * np.abs(rhs).max())


@pytest.mark.parametrize("dt,n", MODELS)
def test_residues_fixed_exact(dt, n):
    lam = np.array([-0.4 + 30j, -0.7 + 48j, -0.3 + 65j])
    res = np.array([[1e-3 + 1e-3j, 2e-3 - 1e-3j, 1e-4j], [-1e-3j, 5e-4 + 0j, 3e-3 + 1e-3j]])
    g = kb.synthesize(OMEGA, lam, res, dt, n)
    out = kr.residues_fixed(g, OMEGA, lam, None, dt, n)
    # exact data, least squares with the exact eigenvalues: rounding only (measured 5e-15), the
    # smallest |res| is 1e-4 so none is near zero; 1e-9 leaves room for the ill-conditioned basis of
    # other grids
    np.testing.assert_allclose(out, res, rtol=1e-9)
    # with residual terms (receptance): exact data of modes + R_L/(iw)^2 + R_U
    w = OMEGA[1:]
    extra = np.array([[1e-2 + 0j, 2e-6 + 1e-7j], [-3e-2 + 0j, 1e-6 + 0j]])
    g2 = g[:, 1:] + extra[:, :1] / (1j * w) ** 2 + extra[:, 1:]
    out2 = kr.residues_fixed(g2, w, lam, None, dt, n, residual_kind=0)
    # with residual terms the columns 1/w^2 and 1 are nearly collinear with the modes' low/high
    # tails: measured 5e-14, kept loose for that conditioning
    np.testing.assert_allclose(out2[:, :3], res, rtol=1e-7)
    # the residual-term coefficients carry the collinearity relative to the smallest coefficient
    # (|2e-6|): measured 1.5e-11
    np.testing.assert_allclose(out2[:, 3:], extra, rtol=1e-6)


def test_noise_floor_and_threshold():
    rng = np.random.default_rng(3)
    sigma = 0.7
    shape = (4, 20000)
    noise = sigma / np.sqrt(2) * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))
    # statistical: a scale estimated from 20000 samples per row scatters by ~1/sqrt(20000) ~ 0.7 %
    # (measured up to 0.4 % for this seed); 3 % is a wrong constant's margin
    np.testing.assert_allclose(kn.noise_floor(noise), sigma, rtol=0.03)
    t = kn.peak_threshold(2049, 1e-3)
    # t is the root of this equation: the 2049-th power amplifies the rounding of 1 - exp(-t) ~ 1 by
    # 2049: ~5e-13
    assert abs((1 - math.exp(-t)) ** 2049 - (1 - 1e-3)) < 1e-12
    ts = kn.sum_threshold(4, 2049, 1e-3)
    # ts is found by a root finder with tolerance ~1e-12 on a tail of size 5e-7: absolute 1e-9 (a
    # wrong k is off by orders of magnitude)
    assert abs(kn.gamma_tail(4, ts) - (1 - (1 - 1e-3) ** (1 / 2049))) < 1e-9
    # gamma tail against the closed form for k = 2
    # closed form exp(-x)(1 + x) = 0.199: a few ulp absolute
    assert abs(kn.gamma_tail(2, 3.0) - math.exp(-3.0) * 4.0) < 1e-15


def test_wrappers_validate():
    with pytest.raises(ValueError, match="omega"):
        kb.synthesize(np.array([2.0, 1.0]), np.array([1j]), np.array([[1.0]]))
    with pytest.raises(ValueError, match="data"):
        k.fit_single_mode(np.ones(3, complex), np.arange(4.0))


# --- linalg ------------------------------------------------------------------------------------
def test_solve_normal_equations_against_numpy():
    rng = np.random.default_rng(4)
    a = rng.standard_normal((30, 6))
    nmat = a.T @ a
    rhs = rng.standard_normal((6, 3))
    x, ok = kl.solve_normal_equations(nmat, rhs)
    assert ok
    want = np.linalg.solve(nmat, rhs)
    # Cholesky vs LU of a 6x6 SPD matrix with cond ~10: both backward stable, so they agree to
    # ~cond * eps of the largest entry; atol covers entries near zero
    np.testing.assert_allclose(x, want, rtol=1e-10, atol=1e-10 * np.abs(want).max())
    x1, ok1 = kl.solve_normal_equations(nmat, rhs[:, 0])
    assert ok1 and x1.shape == (6, 1)
    _, ok_singular = kl.solve_normal_equations(np.zeros((2, 2)), np.ones(2))
    assert not ok_singular
    with pytest.raises(AmiXrValueError, match="nmat"):
        kl.solve_normal_equations(np.ones((2, 3)), np.ones(2))
    with pytest.raises(AmiXrValueError, match="rhs"):
        kl.solve_normal_equations(np.eye(2), np.ones(3))


# --- noise ---------------------------------------------------------------------------------------
def test_noise_wrappers_validate():
    with pytest.raises(AmiXrValueError, match="pfa"):
        kn.peak_threshold(100, 1.5)
    with pytest.raises(AmiXrValueError, match="n_lines"):
        kn.sum_threshold(2, 0, 1e-3)
    with pytest.raises(AmiXrValueError, match="k"):
        kn.gamma_tail(0, 1.0)
    with pytest.raises(AmiXrValueError, match="data"):
        kn.noise_floor(np.ones(1, complex))


# --- modal_basis ---------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", [0, 1, 2])
def test_synthesize_residual_terms_numpy(kind):
    w = OMEGA[:50]
    coef = np.array([[1.0 + 2.0j, 3.0 - 1.0j], [0.5j, 2.0 + 0j]])
    s = 1j * w
    with np.errstate(divide="ignore", invalid="ignore"):
        lower = (1 / s**2, 1 / s, np.ones_like(s))[kind]
    lower = np.where((w == 0) & (kind < 2), 0, lower)
    upper = (np.ones_like(s), s, s**2)[kind]
    ref = coef[:, :1] * lower + coef[:, 1:] * upper
    if kind == 0:
        ref[:, w == 0] = 0  # receptance: the whole line at 0 Hz is left out (documented)
    out = kb.synthesize_residual_terms(w, coef, kind)
    # one or two complex products/divisions per entry; no cancellation (|upper| >> |lower| for w <=
    # 5 rad/s), so a few ulp relative
    np.testing.assert_allclose(out, ref, rtol=1e-13, atol=0)
    with pytest.raises(AmiXrValueError, match="residual_kind"):
        kb.synthesize_residual_terms(w, coef, 3)
    with pytest.raises(AmiXrValueError, match="coef"):
        kb.synthesize_residual_terms(w, coef[:, :1], kind)


@pytest.mark.parametrize("dt,n", MODELS)
def test_contribution_peaks_numpy(dt, n):
    lam = np.array([[-0.4 + 30j, -0.7 + 48j, np.nan + 0j]])
    res = np.array([[1e-3 + 1e-3j, 2e-3 - 1e-3j, 1.0], [-1e-3j, np.nan, 1.0]])
    out = kb.contribution_peaks(OMEGA, dt, n, lam, res)
    for j in range(2):
        for m in range(3):
            if np.isnan(lam[0, m]) or np.isnan(res[j, m]):
                assert np.isnan(out[j, m])
                continue
            c = int(np.argmin(np.abs(OMEGA - lam[0, m].imag)))
            near = slice(max(c - 1, 0), c + 2)
            ref = np.abs(mode_contribution(OMEGA[near], lam[0, m], res[j, m], dt, n)).max()
            # the kernel evaluates the same closed form at the same three lines: a few ulp, times
            # the resonance cancellation (~1e2)
            assert out[j, m] == pytest.approx(ref, rel=1e-12)
    with pytest.raises(AmiXrValueError, match="lam"):
        kb.contribution_peaks(OMEGA, dt, n, lam[:, :2], res)
    with pytest.raises(AmiXrValueError, match="dt"):
        kb.synthesize(OMEGA, lam, res, -1.0)


# --- subtract, isolate, isolate_simo ------------------------------------------------------------
TRUE_LAM = np.array([-0.3 + 2 * np.pi * 5.0j, -0.5 + 2 * np.pi * 8.0j])
TRUE_RES = np.array([[1e-2 - 2e-2j, 2e-2 + 1e-2j], [-1e-2 + 1e-2j, 3e-2 - 1e-2j]])
W2 = 2 * np.pi * np.linspace(0.5, 12.0, 1200)


def _two_mode_frfs(noise=1e-4, seed=0):
    rng = np.random.default_rng(seed)
    g = kb.synthesize(W2, TRUE_LAM, TRUE_RES)
    return g + noise * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape))


def _isolate_params(**kw):
    base = dict(
        delta=0.5,
        tol=1e-4,
        max_iter=100,
        pfa=1e-3,
        min_points=3,
        zeta_max=0.25,
        merge_tol=0.5,
        max_modes=6,
        reweight=True,
        se_fraction=ki.STOP_FRACTION,
        paper_sweeps=False,
    )
    base.update(kw)
    return ki.IsolateParams(**base)


def _assert_same_eigenvalues(lam, ref, rtol):
    lam = np.sort_complex(lam[np.isfinite(lam)])
    assert lam.size == ref.size
    # rtol from the caller (a relative error in |lam|, which is far from zero)
    np.testing.assert_allclose(lam, np.sort_complex(ref), rtol=rtol)


def test_subtract_isolate_recover_two_modes():
    g = _two_mode_frfs()
    params = ks.SubtractParams(0.5, 6, 1e-3, 3, 0.25, 0.5)
    lam, res, blo, bhi, sigma, stat, reason, n = ks.subtract_batch(g, W2, None, None, params)
    assert lam.shape == (2, 6) and np.all(n >= 2)
    assert all(ks.STOP_REASONS[r] in ks.STOP_REASONS for r in reason)
    # statistical: the noise floor is estimated from a few hundred lines after subtraction, biased
    # by the modes' remains: 20 %
    np.testing.assert_allclose(sigma, 1e-4 * np.sqrt(2), rtol=0.2)
    for j in range(2):  # every true mode among the candidates (spurious ones are isolate's job)
        for true in TRUE_LAM:
            # subtract's candidates are one-mode fits without isolation: biased by the other mode's
            # tail (~1e-4 relative here); 1e-3 is still well inside the half-power bandwidth
            assert np.nanmin(np.abs(lam[j, : n[j]] - true)) < 1e-3 * abs(true)
    lam_i, res_i, n_i, it, conv = ki.isolate_batch(
        g, W2, None, None, lam, res, n, sigma, _isolate_params(reweight=False)
    )
    assert conv.all() and list(n_i) == [2, 2]
    for j in range(2):
        # 1e-4 noise on peaks of ~1e-1: isolated estimates scatter by ~1e-5 relative; 1e-4 is ~1 %
        # of the half-power bandwidth
        _assert_same_eigenvalues(lam_i[j], TRUE_LAM, 1e-4)
    start = np.full(6, np.nan + 0j)
    start[:2] = lam[0, :2]
    lam_s, res_s, n_s, it_s, conv_s = ki.isolate_simo(
        g, W2, None, None, start, 2, sigma, _isolate_params()
    )
    assert conv_s and n_s == 2
    _assert_same_eigenvalues(lam_s, TRUE_LAM, 1e-4)
    order = np.argsort(lam_s[:2].imag)
    # residues from a narrow band around each peak (no residual terms): the other mode's tail biases
    # them by up to ~1 %
    np.testing.assert_allclose(res_s[:, :2][:, order], TRUE_RES, rtol=1e-2)
    est = ki.point_estimates(
        g,
        W2,
        None,
        None,
        lam_s[:2][order],
        res_s[:, :2][:, order],
        delta=0.5,
        min_points=3,
        zeta_max=0.25,
    )
    # per-point estimates with the same noise: as for the isolated eigenvalues above
    np.testing.assert_allclose(est, np.broadcast_to(TRUE_LAM, est.shape), rtol=1e-4)


def test_isolate_wrappers_validate():
    g = _two_mode_frfs()
    sigma = np.full(2, 1e-4)
    lam0 = np.full((2, 6), np.nan + 0j)
    params = _isolate_params()
    with pytest.raises(AmiXrValueError, match="params"):
        ki.isolate_batch(g, W2, None, None, lam0, lam0, np.zeros(2, int), sigma, (0.5,) * 10)
    with pytest.raises(AmiXrValueError, match="n0"):
        ki.isolate_batch(g, W2, None, None, lam0, lam0, np.full(2, 7), sigma, params)
    with pytest.raises(AmiXrValueError, match="sigma"):
        ki.isolate_simo(g, W2, None, None, lam0[0], 0, sigma[:1], params)
    with pytest.raises(AmiXrValueError, match="data"):
        ki.isolate_simo(g[:, :-1], W2, None, None, lam0[0], 0, sigma, params)
    with pytest.raises(AmiXrValueError, match="params"):
        ks.subtract_batch(g, W2, None, None, params)
    with pytest.raises(AmiXrValueError, match="res"):
        ki.point_estimates(
            g, W2, None, None, TRUE_LAM, TRUE_RES[:1], delta=0.5, min_points=3, zeta_max=0.25
        )


def test_sweep_order_is_numpy_argsort():
    """The sweeps' insertion sort orders as a stable ``np.argsort`` (NaN last; for distinct
    values every sort agrees)."""
    from ami_xr.kernels import sorting

    rng = np.random.default_rng(7)
    for n in (0, 1, 2, 5, 14, 15, 16, 40):
        a = rng.standard_normal(n + 3)
        a[rng.random(n + 3) < 0.2] = np.nan
        got = sorting.argsort_first(a, np.int64(n))
        assert got.dtype == np.int64
        np.testing.assert_array_equal(got, np.argsort(a[:n], kind="stable"))
