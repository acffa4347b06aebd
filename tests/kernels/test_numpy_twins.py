"""Issue 38 item 4: the helpers only Python calls are plain numpy (nothing to compile on a first
run); each gives what the jitted per-line arithmetic of the AMI kernels gives."""

from __future__ import annotations

import numpy as np
import pytest

from ami_xr.kernels import modal_basis as kb
from ami_xr.kernels import residues as kr

from ..reference import PAPER_DT as DT
from ..reference import PAPER_N as N

OMEGA = 2 * np.pi * np.linspace(0.0, 30.0, 601)
MODELS = [(0.0, 0), (DT, N), (DT, 0)]


def _modes(seed=0, n_p=4, n_k=5):
    rng = np.random.default_rng(seed)
    # damped frequencies on lines, between lines, on a tie, below and above the grid
    im = np.array([2 * np.pi * 5.0, 2 * np.pi * 7.025, 0.5 * (OMEGA[10] + OMEGA[11]), -3.0, 400.0])
    lam = -rng.uniform(0.1, 2.0, n_k) + 1j * im[:n_k]
    res = rng.standard_normal((n_p, n_k)) + 1j * rng.standard_normal((n_p, n_k))
    return lam, res


@pytest.mark.parametrize("dt, n", MODELS)
def test_contribution_peaks_equal_the_kernel_per_mode(dt, n):
    lam, res = _modes()
    res[1, 2] = np.nan
    lam_p = np.broadcast_to(lam, res.shape).copy()
    lam_p[3, 0] = np.nan + 1j
    x = kb.line_variable(OMEGA, dt)
    for shared in (lam[None, :], lam_p):
        got = kb.contribution_peaks(OMEGA, dt or None, n or None, shared, res)
        want = np.full(res.shape, np.nan)
        for j in range(res.shape[0]):
            for k in range(res.shape[1]):
                lj = shared[0 if shared.shape[0] == 1 else j, k]
                if not (np.isnan(lj.real) or np.isnan(res[j, k].real)):
                    want[j, k] = kb.contribution_peak(OMEGA, x, lj, res[j, k], dt, n)
        # the same arithmetic element by element; numpy's and numba's exp may differ in the last
        # bit, which 1 - p q near the pole amplifies by |p q| / |1 - p q| ~ 1 / (|Re lam| dt)
        # (<~ 1e3 here)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
        assert np.array_equal(np.isnan(got), np.isnan(want))


@pytest.mark.parametrize("dt", [0.0, DT])
def test_line_variable(dt):
    want = np.array([np.exp(-1j * w * dt) if dt > 0 else 1j * w for w in OMEGA])
    np.testing.assert_allclose(kb.line_variable(OMEGA, dt), want, rtol=1e-15, atol=1e-15)


@pytest.mark.parametrize("dt, n", MODELS)
@pytest.mark.parametrize("kind", [-1, 0, 1, 2])
def test_residue_normal_equations_equal_the_per_line_sums(dt, n, kind):
    """Normal matrix and right sides of eq. 9 against sums over lines written out, with
    columns from :func:`~ami_xr.kernels.modal_basis.add_mode`'s arithmetic (``mode_basis``)."""
    lam, res = _modes()
    lam = lam[:3]
    rng = np.random.default_rng(1)
    data = rng.standard_normal((3, OMEGA.size)) + 1j * rng.standard_normal((3, OMEGA.size))
    use = rng.uniform(size=OMEGA.size) < 0.7
    nmat, rhs = kr.residue_normal_equations(data, OMEGA, lam, use, dt or None, n or None, kind)
    x = kb.line_variable(OMEGA, dt)
    cols = []
    for lk in lam:
        br, bi, bcr, bci = (np.empty(OMEGA.size) for _ in range(4))
        kb.mode_basis(x, lk, dt, n, br, bi, bcr, bci, 0, OMEGA.size)
        b, bc = br + 1j * bi, bcr + 1j * bci
        cols += [b + bc, 1j * (b - bc)]
    if kind >= 0:
        s = 1j * OMEGA
        with np.errstate(divide="ignore", invalid="ignore"):
            lo = [1 / s**2, 1 / s, np.ones_like(s)][kind]
        lo = np.where(OMEGA == 0, 0, lo) if kind < 2 else lo
        up = [np.ones_like(s), s, s**2][kind]
        cols += [lo, 1j * lo, up, 1j * up]
    c = np.array(cols)[:, use]
    want_n = np.array([[np.sum((np.conj(a) * b).real) for b in c] for a in c])
    want_r = np.array([[np.sum((np.conj(a) * g[use]).real) for g in data] for a in c])
    # sums of a few hundred products in another order: rounding relative to the sum of |terms|
    scale_n = np.abs(c) @ np.abs(c).T
    scale_r = np.abs(c) @ np.abs(data[:, use]).T
    assert np.all(np.abs(nmat - want_n) <= 1e-13 * scale_n)
    assert np.all(np.abs(rhs - want_r) <= 1e-13 * scale_r)
    np.testing.assert_array_equal(nmat, nmat.T)


def test_residues_of_a_row_do_not_depend_on_the_rows_given_with_it():
    """Chunked (dask) and whole inputs give bit-identical residues (the labeled layer's
    dask-equals-memory tests rely on it)."""
    lam, _ = _modes()
    rng = np.random.default_rng(2)
    data = rng.standard_normal((5, OMEGA.size)) + 1j * rng.standard_normal((5, OMEGA.size))
    whole = kr.residues_fixed(data, OMEGA, lam[:3], residual_kind=1)
    alone = np.vstack([kr.residues_fixed(row, OMEGA, lam[:3], residual_kind=1) for row in data])
    np.testing.assert_array_equal(whole, alone)


# --- the small solves: numpy for Python callers, scalars inside the single-mode fit -------------
def _gauss_loops(a, b):
    """Gaussian elimination with partial pivoting written element by element (the scalar loops
    the numpy version vectorises)."""
    n, m = a.shape[0], b.shape[1]
    a, x = [list(map(float, r)) for r in a], [list(map(float, r)) for r in b]
    for col in range(n):
        piv, big = col, abs(a[col][col])
        for r in range(col + 1, n):
            if abs(a[r][col]) > big:
                big, piv = abs(a[r][col]), r
        if big == 0.0 or not np.isfinite(big):
            return None
        a[col], a[piv], x[col], x[piv] = a[piv], a[col], x[piv], x[col]
        for r in range(col + 1, n):
            f = a[r][col] / a[col][col]
            if f != 0.0:
                for c in range(col, n):
                    a[r][c] -= f * a[col][c]
                for c in range(m):
                    x[r][c] -= f * x[col][c]
    for col in range(n - 1, -1, -1):
        for c in range(m):
            s = x[col][c]
            for k in range(col + 1, n):
                s -= a[col][k] * x[k][c]
            x[col][c] = s / a[col][col]
    return np.array(x)


def _systems(seed, count):
    rng = np.random.default_rng(seed)
    for t in range(count):
        n, m = (2, 1) if t % 2 else (int(rng.integers(1, 9)), int(rng.integers(1, 4)))
        a = rng.normal(size=(3 * n, n)) * np.exp(rng.uniform(-8, 8, n))  # badly scaled
        nmat = a.T @ a
        if t % 5 == 0:
            nmat = nmat[::-1, ::-1].copy() - 2.0 * np.diag(np.diag(nmat))  # pivoting, negative
        if t % 7 == 0:
            nmat[0, :] = nmat[:, 0] = 0.0  # singular
        yield nmat, rng.normal(size=(n, m))


def test_gauss_solve_is_the_scalar_elimination():
    """Each element sees the scalar loops' operations in their order: the same result (to one
    rounding of the last operation: numpy and Python evaluate identical IEEE expressions)."""
    from ami_xr.kernels import linalg

    for nmat, rhs in _systems(1, 120):
        want = _gauss_loops(nmat, rhs)
        got, ok = linalg.gauss_solve(nmat, rhs)
        assert ok == (want is not None)
        if ok:
            np.testing.assert_allclose(got, want, rtol=1e-15, atol=0)


def test_solve2_is_solve_normal_of_a_2x2_system():
    """The scalar 2 x 2 solve inlined into ``fit_single`` against the general one (same
    scaling, pivoting and refinement), singular and badly scaled systems included."""
    import numba

    from ami_xr.kernels import linalg

    solve2 = numba.njit(lambda a, b: linalg.solve2(a[0, 0], a[0, 1], a[1, 0], a[1, 1], b[0], b[1]))
    seen = {True: 0, False: 0}
    for nmat, rhs in _systems(2, 200):
        if nmat.shape != (2, 2):
            continue
        want, ok = linalg.solve_normal(nmat, rhs)
        x0, x1, ok2 = solve2(nmat, rhs[:, 0])
        assert ok2 == ok
        seen[ok] += 1
        if ok:
            np.testing.assert_allclose([x0, x1], want[:, 0], rtol=1e-15, atol=0)
    assert seen[True] > 50 and seen[False] > 5
