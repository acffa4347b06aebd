"""Issue 42: the isolation engine returns between its restarts when asked (a caller handles
interrupts there) and goes on where it stopped: the results are those of one call.

The data: five modes on six FRFs, isolation started from one (SIMO) or two (per FRF) of them,
so the model-order check adds modes and the engine restarts several times.
"""

from __future__ import annotations

import numpy as np
import pytest

from ami_xr.kernels import isolate as ki
from ami_xr.kernels import modal_basis as kb

from .test_ami_kernels import _isolate_params

OMEGA = 2 * np.pi * np.linspace(0.5, 30.0, 1500)
LAM = np.array([-0.3, -0.5, -0.6, -0.9, -1.2]) + 2j * np.pi * np.array([4.0, 9.0, 14.5, 20.0, 26.0])


def _frfs(n_p=6, noise=1e-4, seed=1):
    rng = np.random.default_rng(seed)
    res = (rng.standard_normal((n_p, LAM.size)) + 1j * rng.standard_normal((n_p, LAM.size))) * 1e-2
    g = kb.synthesize(OMEGA, LAM, res)
    return g + noise * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape))


def _params(**kw):
    return _isolate_params(**{"max_modes": 8, **kw})


def _same(a, b):
    # the same arithmetic in the same order, only split over calls: identical values
    for name in ki.IsolateResult._fields:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@pytest.fixture
def every_restart(monkeypatch):
    """The engine returns before every restart after the first of a call."""
    monkeypatch.setattr(ki, "BETWEEN_WORK", 1)


def test_simo_isolation_returns_between_restarts_with_the_same_result(every_restart):
    g = _frfs()
    sigma = np.full(g.shape[0], 1e-4)
    start = np.full(8, np.nan + 0j)
    start[0] = LAM[2] * (1 + 1e-3)
    one = ki.isolate_simo(g, OMEGA, None, None, start, 1, sigma, _params())
    calls = []
    split = ki.isolate_simo(
        g, OMEGA, None, None, start, 1, sigma, _params(), between=lambda: calls.append(1)
    )
    _same(one, split)
    assert one.n_modes == 5, one.lam  # the order check added four: four restarts or more
    assert len(calls) >= 4


def test_per_frf_isolation_resumes_across_groups_with_the_same_result(every_restart):
    g = _frfs(n_p=4)
    sigma = np.full(g.shape[0], 1e-4)
    lam0 = np.full((4, 8), np.nan + 0j)
    lam0[:, :2] = LAM[[1, 3]]
    res0 = np.zeros((4, 8), complex)
    n0 = np.full(4, 2)
    params = _params(paper_sweeps=True, se_fraction=0.0, reweight=False)
    one = ki.isolate_batch(g, OMEGA, None, None, lam0, res0, n0, sigma, params)
    calls = []
    split = ki.isolate_batch(
        g, OMEGA, None, None, lam0, res0, n0, sigma, params, between=lambda: calls.append(1)
    )
    _same(one, split)
    assert np.all(one.n_modes >= 5), one.n_modes  # the order check added three or more
    assert len(calls) >= 4 * 3  # at least three restarts after the first in each FRF


def test_an_exception_from_between_stops_the_isolation(every_restart):
    g = _frfs()
    start = np.full(8, np.nan + 0j)
    start[0] = LAM[2]

    def stop():
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        ki.isolate_simo(g, OMEGA, None, None, start, 1, np.full(6, 1e-4), _params(), between=stop)


def test_two_mode_fits_of_the_order_check_run_in_python_between_calls(monkeypatch):
    """A close pair started as one mode: the order check asks for two-mode fits (the kernel
    returns, :func:`split_fit` runs, the kernel goes on); splitting the work over more calls
    changes nothing."""
    rng = np.random.default_rng(0)
    lam = np.array([-0.1 + 2j * np.pi * 9.0, -0.1 + 2j * np.pi * 9.05])
    res = (rng.standard_normal((5, 2)) + 1j * rng.standard_normal((5, 2))) * 1e-2
    g = kb.synthesize(OMEGA, lam, res)
    g = g + 1e-4 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape))
    sigma = np.full(5, 1e-4)
    lam0 = np.full((5, 8), np.nan + 0j)
    lam0[:, 0] = lam[0]
    res0 = np.zeros((5, 8), complex)
    n0 = np.ones(5, int)
    asked = []
    real = ki.split_fit
    monkeypatch.setattr(ki, "split_fit", lambda *a: asked.append(1) or real(*a))
    params = _params(reweight=False)
    one = ki.isolate_batch(g, OMEGA, None, None, lam0, res0, n0, sigma, params)
    assert asked  # a split was tried
    # FRF 0: the pair, split (1e-4 noise on peaks of ~1e-1: well inside a bandwidth, 0.2 rad/s)
    found = one.lam[0, :2]
    np.testing.assert_allclose(found[np.argsort(found.imag)], lam, atol=0.02)
    monkeypatch.setattr(ki, "BETWEEN_WORK", 1)
    split = ki.isolate_batch(
        g, OMEGA, None, None, lam0, res0, n0, sigma, params, between=lambda: None
    )
    _same(one, split)
