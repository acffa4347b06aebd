"""The refinement's kernels (ami_xr/kernels/modal_basis.py basis and derivative,
ami_xr/kernels/projection.py) against plain numpy references, through their checked wrappers."""

from __future__ import annotations

import numpy as np
import pytest


# ------------------------------------------------------------------------------------------
# kernels against plain numpy references
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("dt,n", [(None, None), (60.0 / 4096, 4096), (0.01, None)])
def test_basis_and_derivative_against_reference(dt, n):
    from ami_xr.kernels.modal_basis import basis_and_derivative, pole_basis

    omega = np.linspace(0.0, 200.0, 301)
    lam = np.array([-0.4 + 65.0j, -2.0 - 30.0j])
    b, db = basis_and_derivative(omega, lam, dt, n)
    h = 1e-6
    for k, lk in enumerate(lam):
        # the same closed form evaluated by two kernels (jointly with the derivative vs alone):
        # rounding differs by a few ulp, amplified near 1 - exp(lam dt) cancellation (~1e2)
        np.testing.assert_allclose(b[k], pole_basis(omega, lk, dt, n), rtol=1e-12)
        fd = (pole_basis(omega, lk + h, dt, n) - pole_basis(omega, lk - h, dt, n)) / (2 * h)
        # central difference with h = 1e-6: truncation ~h^2 |b'''| and rounding ~eps |b| / h ~ 1e-10
        # relative; atol relative to the largest value covers entries near zero
        np.testing.assert_allclose(db[k], fd, rtol=1e-5, atol=1e-9 * np.abs(fd).max())


def test_normal_equations_against_dense():
    from ami_xr.kernels.projection import normal_equations

    rng = np.random.default_rng(0)
    n_point, n_mode = 5, 3
    coef = rng.standard_normal((n_point, 2 * n_mode + 2))
    weight = rng.uniform(0.5, 2.0, n_point)
    a = rng.standard_normal((2 * n_mode, 2 * n_mode))
    s_mat = a @ a.T
    v_res = rng.standard_normal((n_point, 2 * n_mode))
    h, g = normal_equations(coef, weight, s_mat, v_res, n_mode)
    h_ref = np.zeros_like(s_mat)
    g_ref = np.zeros(2 * n_mode)
    for j in range(n_point):
        m = np.zeros_like(s_mat)
        for k in range(n_mode):
            a1, a2 = coef[j, 2 * k], coef[j, 2 * k + 1]
            m[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[a1, -a2], [a2, a1]]
        h_ref += weight[j] * m.T @ s_mat @ m
        g_ref -= weight[j] * m.T @ v_res[j]
    # sums of 5 products of 6x6 matrices with entries O(1) in another order: a few ulp times the
    # terms' magnitude; no entry is near zero for this seed
    np.testing.assert_allclose(h, h_ref, rtol=1e-12)
    np.testing.assert_allclose(g, g_ref, rtol=1e-12)


@pytest.mark.parametrize("n_point", [3, 700])  # serial and parallel paths
def test_projection_kernels_against_numpy(n_point):
    from ami_xr.kernels.projection import gram, matmul_small, project_points

    rng = np.random.default_rng(1)
    a = rng.standard_normal((4098, 6))
    q, _ = np.linalg.qr(a)
    v = rng.standard_normal((4098, 4))
    y = rng.standard_normal((n_point, 4098))
    qty, rss, vtr = project_points(y, q, v)
    r = y - (y @ q) @ q.T
    # dot products of length 4098 (|y|, |q| ~ 1): absolute rounding ~sqrt(n) eps |y| ~ 1e-14, far
    # inside atol; elementwise rtol alone would fail on entries near zero
    np.testing.assert_allclose(qty, y @ q, rtol=1e-10, atol=1e-10)
    # |y|^2 - |Q^T y|^2 vs the residual's own sum of squares: cancellation of ~4098 vs ~6, so ~1e-13
    # relative
    np.testing.assert_allclose(rss, np.sum(r**2, axis=1), rtol=1e-10)
    # V^T y - (V^T Q)(Q^T y) vs V^T r: sums of 4098 terms of O(1) that cancel to O(sqrt n): absolute
    # rounding ~1e-12
    np.testing.assert_allclose(vtr, r @ v, rtol=1e-9, atol=1e-9)
    # sums of 4098 products in another order (BLAS blocks): error ~eps sum|a_i b_i| ~ 1e-12;
    # diagonal O(4098), off-diagonal O(sqrt(4098) = 64), so rtol 1e-12 holds with margin
    np.testing.assert_allclose(gram(a), a.T @ a, rtol=1e-12)
    b = rng.standard_normal((6, 6))
    # sums of 6 products of O(1) entries: a few ulp absolute; atol covers entries near zero
    np.testing.assert_allclose(matmul_small(a, b), a @ b, rtol=1e-12, atol=1e-12)


def test_projection_wrappers_validate():
    from ami_xr.errors import AmiXrValueError
    from ami_xr.kernels.modal_basis import model_columns
    from ami_xr.kernels.projection import matmul_small, normal_equations, project_points

    with pytest.raises(AmiXrValueError, match="coef"):
        normal_equations(np.ones((2, 3)), np.ones(2), np.eye(4), np.ones((2, 4)), 2)
    with pytest.raises(AmiXrValueError, match="q, v"):
        project_points(np.ones((2, 5)), np.ones((4, 2)), np.ones((5, 1)))
    with pytest.raises(AmiXrValueError, match="a, b"):
        matmul_small(np.ones((3, 2)), np.ones((3, 2)))
    with pytest.raises(AmiXrValueError, match="residual_terms"):
        model_columns(np.arange(1.0, 4.0), np.array([-1 + 2j]), None, None, ("middle",))


def test_compute_threads_follow_the_affinity_and_the_batch_share(monkeypatch):
    """The per-point projection uses the cores this process may run on, at most 8, and no
    more than ``AMI_XR_THREADS`` (what ``ami-xr batch`` gives each worker)."""
    import os

    from ami_xr.kernels import projection

    monkeypatch.delenv(projection.THREADS_ENV, raising=False)
    if hasattr(os, "sched_getaffinity"):
        monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2})
        assert projection.compute_threads() == 3
        monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(64)))
        assert projection.compute_threads() == 8
    monkeypatch.setenv(projection.THREADS_ENV, "1")
    assert projection.compute_threads() == 1
    monkeypatch.setenv(projection.THREADS_ENV, "not a number")  # ignored
    assert projection.compute_threads() >= 1


@pytest.mark.parametrize("dt, n", [(None, None), (0.01, None), (0.01, 512)])
@pytest.mark.parametrize("kind", [0, 1, 2])
def test_stacked_columns_equal_model_columns_stacked(dt, n, kind):
    """The refinement's one-pass stacked columns hold the values of ``model_columns``
    real-stacked and line-weighted (the same arithmetic; rounding apart)."""
    from ami_xr.kernels.columns import stacked_columns, stacked_residual_columns
    from ami_xr.kernels.modal_basis import line_variable, model_columns

    rng = np.random.default_rng(3)
    omega = np.linspace(0.0, 300.0, 257)
    lam = np.array([-1.5 + 40j, -0.2 + 41j, -4.0 + 200j])
    weight = rng.uniform(0.5, 2.0, omega.size)
    terms = ("lower", "upper")
    phi, dphi = model_columns(omega, lam, dt, n, terms, kind)

    def stack(z):
        return np.concatenate([z.real * weight[:, None], z.imag * weight[:, None]])

    fixed = stacked_residual_columns(omega, terms, kind, weight)
    a, v = stacked_columns(line_variable(omega, dt or 0.0), lam, dt or 0.0, n or 0, weight, fixed)
    assert a.flags.c_contiguous and v.flags.c_contiguous
    for got, want in ((a, stack(phi)), (v, stack(dphi))):
        # b + conj-pole term cancels where the two are close: the error is relative to the
        # column's size (a few ulp of it), not to each entry
        scale = np.max(np.abs(want), axis=0)
        np.testing.assert_allclose(got / scale, want / scale, rtol=0, atol=1e-14)
    a0, _ = stacked_columns(line_variable(omega, 0.0), lam, 0.0, 0, weight, fixed[:, :0])
    assert a0.shape == (2 * omega.size, 2 * lam.size)


def test_stacked_columns_validate():
    from ami_xr.errors import AmiXrValueError
    from ami_xr.kernels.columns import stacked_columns

    x, lam = np.exp(-0.01j * np.arange(5.0)), np.array([-1 + 2j])
    with pytest.raises(AmiXrValueError, match="x, weight"):
        stacked_columns(x, lam, 0.01, 0, np.ones(4), np.empty((10, 0)))
    with pytest.raises(AmiXrValueError, match="fixed"):
        stacked_columns(x, lam, 0.01, 0, np.ones(5), np.empty((5, 2)))
    with pytest.raises(AmiXrValueError, match="lam"):
        stacked_columns(x, np.ones((1, 1), complex), 0.01, 0, np.ones(5), np.empty((10, 0)))
