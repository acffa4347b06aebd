"""The refinement's projection (:func:`ami_xr.core.varpro.project`) against a plain numpy
least-squares reference, and its rank check."""

from __future__ import annotations

import numpy as np
import pytest

from ami_xr.core import varpro
from ami_xr.kernels.modal_basis import model_columns

LAM = np.array([-0.8 + 40.0j, -1.1 + 47.0j, -2.0 + 90.0j])


def _problem(dt, n, terms=("lower", "upper"), kind=0, n_point=3):
    rng = np.random.default_rng(5)
    omega = np.linspace(0.0, 120.0, 301)
    frf = rng.standard_normal((n_point, omega.size)) + 1j * rng.standard_normal(
        (n_point, omega.size)
    )
    nyquist = np.pi / dt if dt else None
    return varpro.make_problem(frf, omega, dt, n, terms, nyquist=nyquist, residual_kind=kind)


@pytest.mark.parametrize("dt, n", [(None, None), (0.02, None), (np.pi / 120.0, 600)])
@pytest.mark.parametrize("terms", [(), ("lower", "upper")])
def test_projection_equals_least_squares(dt, n, terms):
    prob = _problem(dt, n, terms)
    proj = varpro.project(prob, LAM)
    assert proj.ok
    phi, dphi = model_columns(prob.omega, LAM, dt, n, terms, 0)
    w = prob.line_weight[:, None]
    a = np.concatenate([(phi * w).real, (phi * w).imag])
    v = np.concatenate([(dphi * w).real, (dphi * w).imag])
    coef, *_ = np.linalg.lstsq(a, prob.y.T, rcond=None)
    resid = prob.y - (a @ coef).T
    np.testing.assert_allclose(proj.coef, coef.T, rtol=1e-9, atol=1e-9 * np.abs(coef).max())
    np.testing.assert_allclose(proj.rss, np.sum(resid**2, axis=1), rtol=1e-9)
    np.testing.assert_allclose(proj.v_res, resid @ v, rtol=1e-8, atol=1e-9 * np.abs(v).max())
    np.testing.assert_allclose(proj.q.T @ proj.q, np.eye(a.shape[1]), atol=1e-12)
    np.testing.assert_allclose(proj.q @ proj.r, a, atol=1e-12 * np.abs(a).max())
    vtv = v.T @ v  # columns equal to rounding (the one-pass kernel): a few ulp of the largest
    np.testing.assert_allclose(proj.vtv, vtv, rtol=0, atol=1e-12 * np.abs(vtv).max())


def test_coinciding_or_non_finite_eigenvalues_are_not_ok():
    prob = _problem(None, None)
    twice = np.array([LAM[0], LAM[0], LAM[2]])
    assert not varpro.project(prob, twice).ok
    assert varpro.objective(prob, varpro.project(prob, twice)) == np.inf
    bad = np.array([LAM[0], complex(np.nan, 1.0), LAM[2]])
    assert not varpro.project(prob, bad).ok
