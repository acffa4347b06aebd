"""Tests of ami_xr.simulate.modal and ami_xr.simulate.random against independent references."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.simulate import (
    add_noise,
    contrast,
    frf,
    impulse_response,
    modal_model,
    mode_peaks,
    random_system,
    residues,
    state_space_modes,
)

from ..reference import frf_from_residues, random_mck, receptance_direct


@pytest.mark.parametrize("n,seed", [(1, 0), (2, 1), (4, 2), (7, 3)])
def test_eq4_equals_direct_solution(n, seed):
    M, C, K = random_mck(n, seed)
    # a pure non-proportional check: C must not commute with M^-1 K
    if n > 1:
        Mi = np.linalg.inv(M)
        # a property of the random system, not a numerical comparison: the commutator is O(1) for
        # general damping, 0 (to rounding) for proportional damping
        assert np.abs(Mi @ C @ Mi @ K - Mi @ K @ Mi @ C).max() > 1e-6
    lam, phi = state_space_modes(M, C, K)
    wn = np.abs(lam)
    omega = np.sort(np.concatenate([np.linspace(0.0, 2 * wn.max(), 101), wn]))
    for P in range(n):
        A = lam * phi * phi[P]  # eq. 5
        model = (
            A[:, :, None] / (1j * omega - lam[None, :, None])
            + np.conj(A)[:, :, None] / (1j * omega - np.conj(lam)[None, :, None])
        ).sum(axis=1)
        direct = receptance_direct(M, C, K, omega, P)
        err = np.abs(model - direct).max() / np.abs(direct).max()
        # eq. 4 from one eigen-decomposition vs a dense solve per line, norm-wise (lines near
        # antiresonances are small): a few ulp times the eigenvector condition number (~1e3 for
        # these random 7-DOF systems)
        assert err < 1e-10


def test_eigen_normalisation_and_ordering():
    M, C, K = random_mck(5, 7)
    lam, phi = state_space_modes(M, C, K)
    assert np.all(lam.imag > 0)
    assert np.all(np.diff(np.abs(lam)) >= 0)
    for k in range(5):
        D = lam[k] ** 2 * M + lam[k] * C + K
        # backward-stable eigenvectors: the residual of the quadratic eigenproblem is ~eps ||D||
        # ||phi|| times the linearisation's condition (~1e3); 1e-10 leaves room
        assert np.linalg.norm(D @ phi[:, k]) < 1e-10 * np.linalg.norm(D, 2) * np.linalg.norm(
            phi[:, k]
        )
        norm = lam[k] * phi[:, k] @ (2 * lam[k] * M + C) @ phi[:, k]
        # the normalisation is applied by one division: the quadratic form is then 1 to a few ulp
        # times its terms (~1e2 cancellation)
        assert abs(norm - 1) < 1e-12
    # eqs. 2-3
    z = -lam.real / np.abs(lam)
    # an identity of complex numbers: a few roundings, and sqrt(1 - z^2) is well-conditioned for z
    # << 1
    np.testing.assert_allclose(lam.imag, np.abs(lam) * np.sqrt(1 - z**2), rtol=1e-12)


def test_proportional_damping_matches_classical_modes():
    M = np.diag([1.0, 2.0, 1.5])
    K = np.array([[300.0, -100, 0], [-100, 250, -150], [0, -150, 150]])
    C = 0.001 * K + 0.2 * M
    lam, phi = state_space_modes(M, C, K)
    w2, v = np.linalg.eigh(
        np.linalg.inv(np.linalg.cholesky(M)) @ K @ np.linalg.inv(np.linalg.cholesky(M)).T
    )
    wn = np.sqrt(w2)
    # the state-space eigenvalues vs a symmetric eigen-decomposition of the undamped system: both
    # backward stable, agreeing to ~cond * eps with cond ~ 1e2
    np.testing.assert_allclose(np.abs(lam), wn, rtol=1e-12)
    # the damping ratio Re(lam) / |lam| ~ 1e-2 loses ~2 digits to the relative size of Re(lam)
    np.testing.assert_allclose(-lam.real / np.abs(lam), 0.0005 * wn + 0.1 / wn, rtol=1e-10)


def test_modal_model_dataset_and_residues():
    M, C, K = random_mck(4, 11)
    T = np.array([[1.0, 0, 0, 0], [0, 0.5, 0.5, 0], [0, 0, 0, 1]])
    truth = modal_model(M, C, K, point_labels=["a", "b", "c"], output=T)
    assert truth[names.EIGENVALUE].dims == (names.MODE,)
    assert truth[names.MODE_VECTOR].dims == (names.POINT, names.MODE)
    assert list(truth[names.POINT].values) == ["a", "b", "c"]
    assert list(truth[names.MODE].values) == [1, 2, 3, 4]
    lam = truth[names.EIGENVALUE].values
    # the same formulas on the same eigenvalues: one or two roundings each
    np.testing.assert_allclose(
        truth[names.NATURAL_FREQUENCY], np.abs(lam) / (2 * np.pi), rtol=1e-15
    )
    np.testing.assert_allclose(truth[names.DAMPING_RATIO], -lam.real / np.abs(lam), rtol=1e-15)
    assert truth[names.NATURAL_FREQUENCY].attrs["units"] == "Hz"
    assert names.RESIDUE not in truth
    withres = residues(truth, "b")
    assert names.RESIDUE not in truth  # input not mutated
    phi = truth[names.MODE_VECTOR].values
    # the same products in possibly another order: two roundings; no residue is near zero
    np.testing.assert_allclose(withres[names.RESIDUE].values, lam * phi * phi[1], rtol=1e-14)
    assert withres.attrs[names.ATTR_DRIVE_POINT] == "b"
    # eq. 8 inverts eq. 5 up to the arbitrary sign of each mode
    A = withres[names.RESIDUE].values
    phi_p = np.sqrt(A[1] / lam)
    sign = np.sign((phi_p / phi[1]).real)
    # sqrt(A_P / lam) inverts lam phi_P^2: a few roundings; no drive-point component near zero
    np.testing.assert_allclose(phi_p * sign, phi[1], rtol=1e-12)
    # a few roundings per entry; atol for components near zero (|phi| ~ 0.1-1)
    np.testing.assert_allclose(A / (lam * phi_p) * sign, phi, rtol=1e-12, atol=1e-15)
    # FRF at measured points with the output matrix: y = T q, f_gen = T[P]^T F
    f_hz = np.linspace(0.1, 3.0, 57)
    g = frf(truth, f_hz, "b")
    omega = 2 * np.pi * f_hz
    direct = np.array([T @ np.linalg.solve(K - w**2 * M + 1j * w * C, T[1]) for w in omega]).T
    np.testing.assert_allclose(
        # eq. 4 with an output matrix vs dense solves: ~cond(eigenvectors) * eps of the largest
        # value (norm-wise via atol)
        g[names.FRF].values,
        direct,
        rtol=1e-10,
        atol=1e-10 * np.abs(direct).max(),
    )
    ami_xr.validate(g)
    assert g.attrs[names.ATTR_SOURCE] == names.SOURCE_ANALYTIC
    assert g[names.FRF].attrs["units"] == "m/N"
    # velocity and acceleration FRFs
    gv = frf(truth, f_hz, "b", response_quantity="velocity")
    ga = frf(truth, f_hz, "b", response_quantity="acceleration")
    # the same synthesis times (i w)^k, k = 1, 2: one complex product per line (exact here; 1e-15
    # allows for the product's rounding on other platforms)
    np.testing.assert_allclose(gv[names.FRF].values, 1j * omega * g[names.FRF].values, rtol=1e-15)
    np.testing.assert_allclose(ga[names.FRF].values, -(omega**2) * g[names.FRF].values, rtol=1e-15)
    assert ga.attrs[names.ATTR_FRF_TYPE] == "accelerance"
    ami_xr.validate(ga)


def test_frf_from_residue_only_model():
    M, C, K = random_mck(3, 5)
    truth = modal_model(M, C, K, drive_point=0)
    slim = truth.drop_vars(names.MODE_VECTOR)
    f = np.linspace(0.0, 5.0, 11)
    want = frf(truth, f)[names.FRF]
    # the stored residues vs residues formed from the mode vectors (lam phi phi_P, a few roundings):
    # the synthesis then agrees to a few ulp of the largest FRF value, norm-wise (lines near an
    # antiresonance are small)
    xr.testing.assert_allclose(
        frf(slim, f)[names.FRF], want, rtol=1e-12, atol=1e-12 * float(np.abs(want).max())
    )
    with pytest.raises(AmiXrValueError, match="drive_point"):
        frf(slim, f, 1)


def test_impulse_response_matches_ode_integration():
    M, C, K = random_mck(3, 4)
    truth = modal_model(M, C, K)
    t = np.linspace(0.0, 3.0, 301)
    P = 2
    h = impulse_response(truth, t, P)
    ami_xr.validate(h)
    assert h.attrs["excitation"] == "unit_impulse"
    assert names.FORCE not in h
    # unit impulse at P: q(0+) = 0, q'(0+) = M^-1 e_P, then free vibration
    n = 3
    Mi = np.linalg.inv(M)

    def rhs(_, x):
        return np.concatenate([x[n:], -Mi @ (K @ x[:n] + C @ x[n:])])

    x0 = np.concatenate([np.zeros(n), Mi[:, P]])
    sol = scipy.integrate.solve_ivp(
        # the reference integrator's own tolerances (not a comparison)
        rhs,
        (0, 3.0),
        x0,
        t_eval=t,
        rtol=1e-11,
        atol=1e-14,
        method="DOP853",
    )
    ref = sol.y[:n]
    # an ODE integration at rtol 1e-11 over ~100 oscillations accumulates global error ~1e-9 of the
    # peak: 1e-8, relative to the peak since h crosses zero
    np.testing.assert_allclose(h[names.RESPONSE].values, ref, atol=1e-8 * np.abs(ref).max())


def test_impulse_response_fft_is_the_discrete_modal_model():
    M, C, K = random_mck(3, 9)
    truth = modal_model(M, C, K, drive_point=0)
    n, duration = 512, 20.0
    h = impulse_response(truth, (duration, n))
    dt = duration / n
    # k * dt vs k * duration / n: one or two roundings (the default rtol 1e-7 is loose; the 0 s
    # sample is exactly 0 in both)
    np.testing.assert_allclose(h[names.TIME].values, np.arange(n) * dt)
    g = dt * np.fft.rfft(h[names.RESPONSE].values, axis=-1)
    omega = 2 * np.pi * np.fft.rfftfreq(n, dt)
    A = truth[names.RESIDUE].values
    lam = truth[names.EIGENVALUE].values
    ref = frf_from_residues(omega, lam, A, dt, n)
    # FFT of 512 samples (norm-wise ~eps log2 n) vs the closed-form sum: relative to the peak, as
    # the FRF has antiresonances
    np.testing.assert_allclose(g, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_impulse_response_time_validation():
    truth = modal_model(*random_mck(2, 0), drive_point=0)
    with pytest.raises(AmiXrValueError, match="time"):
        impulse_response(truth, [0.0, 0.1, 0.3])
    with pytest.raises(AmiXrValueError, match="time"):
        impulse_response(truth, (-1.0, 10))
    with pytest.raises(AmiXrValueError, match="time"):
        impulse_response(truth, (1.0, 2.5))
    with pytest.raises(AmiXrValueError, match="drive_point"):
        impulse_response(truth, (1.0, 16), "nope")


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"M": [[1.0, 2.0], [3.0, 1.0]]}, "M: expected a symmetric"),
        ({"M": -np.eye(2)}, "M: expected a symmetric positive definite"),
        ({"C": np.eye(3)}, "C: expected shape"),
        ({"K": [[np.nan, 0], [0, 1]]}, "K: contains NaN"),
        ({"C": 100 * np.eye(2)}, "C: every mode must be underdamped"),
        ({"output": np.ones((2, 3))}, "output: expected a matrix"),
        ({"point_labels": ["a"]}, "point_labels: expected 2"),
        ({"point_labels": ["a", "a"]}, "point_labels: labels must be unique"),
        ({"drive_point": 5}, "drive_point"),
    ],
)
def test_modal_model_bad_input(kwargs, match):
    args = {"M": np.eye(2), "C": 0.01 * np.eye(2), "K": np.diag([100.0, 400.0])}
    args.update(kwargs)
    M, C, K = args.pop("M"), args.pop("C"), args.pop("K")
    with pytest.raises(AmiXrValueError, match=match):
        modal_model(M, C, K, **args)


def test_frf_bad_input():
    truth = modal_model(np.eye(2), 0.01 * np.eye(2), np.diag([100.0, 400.0]), drive_point=0)
    with pytest.raises(AmiXrValueError, match="frequency_hz"):
        frf(truth, [1.0, 0.5])
    with pytest.raises(AmiXrValueError, match="frequency_hz"):
        frf(truth, [-1.0, 0.5])
    with pytest.raises(AmiXrValueError, match="response_quantity"):
        frf(truth, [1.0], response_quantity="jerk")
    with pytest.raises(AmiXrValueError, match="model"):
        frf({"eigenvalue": 1}, [1.0])


# ---------------------------------------------------------------------------------------------
# noise (eq. 15)
# ---------------------------------------------------------------------------------------------
def _signals():
    t = np.linspace(0, 1, 20000)
    return np.stack([np.sin(40 * t) * np.exp(-t), 1e-6 * np.cos(7 * t), -3.0 * np.exp(-5 * t)])


def test_uniform_noise_is_eq15_per_channel():
    y = _signals()
    alpha = 0.15
    noisy = add_noise(y, alpha, seed=1)
    scale = alpha * np.abs(y).max(axis=-1, keepdims=True)
    r = (noisy - y) / scale
    assert np.all(r >= -1) and np.all(r < 1)
    # statistical: the mean of n = 20000 uniform(-1, 1) draws has std 1 / sqrt(3 n) ~ 0.004; 0.02 is
    # 5 sigma
    np.testing.assert_allclose(r.mean(axis=-1), 0.0, atol=0.02)
    # statistical: the sample variance of 20000 uniform draws has relative std sqrt(0.8 / n) ~ 0.6 %
    np.testing.assert_allclose(r.var(axis=-1), 1 / 3, rtol=0.03)
    assert r.min() < -0.99 and r.max() > 0.99
    # reproducible, and a generator gives the same stream as its seed: the same draws applied with
    # the same operations, bit-identical
    np.testing.assert_array_equal(add_noise(y, alpha, seed=1), noisy)
    np.testing.assert_array_equal(add_noise(y, alpha, rng=np.random.default_rng(1)), noisy)
    assert not np.array_equal(add_noise(y, alpha, seed=2), noisy)
    # alpha = 0 returns the data unchanged (no arithmetic)
    np.testing.assert_array_equal(add_noise(y, 0.0, seed=1), y)


def test_gaussian_noise_std():
    y = _signals()
    noisy = add_noise(y, 0.1, seed=3, kind="gaussian")
    r = (noisy - y) / (0.1 * np.abs(y).max(axis=-1, keepdims=True))
    # statistical: the Gaussian sample std of 20000 draws has relative std 1 / sqrt(2 n) ~ 0.5 %
    np.testing.assert_allclose(r.std(axis=-1), 1.0, rtol=0.03)
    # statistical: the mean's std is 1 / sqrt(n) ~ 0.007; 0.03 is 4 sigma
    np.testing.assert_allclose(r.mean(axis=-1), 0.0, atol=0.03)


def test_noise_on_datasets_and_dataarrays():
    truth = modal_model(*random_mck(3, 2), drive_point=1)
    ts = impulse_response(truth, (10.0, 1024))
    noisy = add_noise(ts, 0.15, seed=0)
    assert noisy.attrs["noise_level"] == 0.15 and noisy.attrs["noise_seed"] == 0
    assert "noise_level" not in ts.attrs  # input untouched
    y = ts[names.RESPONSE].values
    r = (noisy[names.RESPONSE].values - y) / (0.15 * np.abs(y).max(axis=-1, keepdims=True))
    assert np.all(np.abs(r) <= 1)
    # the same noise whatever the container, and whatever the dim order of a DataArray: the same
    # draws and operations, bit-identical
    np.testing.assert_array_equal(noisy[names.RESPONSE].values, add_noise(y, 0.15, seed=0))
    da = ts[names.RESPONSE].transpose(names.TIME, names.POINT)
    nda = add_noise(da, 0.15, seed=0)
    assert nda.dims == da.dims
    np.testing.assert_array_equal(
        nda.transpose(names.POINT, names.TIME).values, noisy[names.RESPONSE].values
    )


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"alpha": -0.1}, "alpha"),
        ({"alpha": float("nan")}, "alpha"),
        ({"kind": "pink"}, "kind"),
        ({"seed": 1, "rng": np.random.default_rng(1)}, "seed, rng"),
        ({"rng": 5}, "rng"),
        ({"dim": "frequency"}, "dim"),
    ],
)
def test_noise_bad_input(kwargs, match):
    da = xr.DataArray(np.ones((2, 10)), dims=["point", "time"])
    args = {"alpha": 0.1}
    args.update(kwargs)
    with pytest.raises(AmiXrValueError, match=match):
        add_noise(da, **args)


# ---------------------------------------------------------------------------------------------
# random systems
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("topology", ["chain", "grid"])
@pytest.mark.parametrize("n_points", [5, 12])
def test_random_system_counts_and_truth(topology, n_points):
    g, truth = random_system(n_points, topology, seed=4, n_frequencies=512)
    ami_xr.validate(g)
    assert g.sizes[names.POINT] == n_points
    assert truth.sizes[names.MODE] == n_points
    assert truth.sizes[names.POINT] == n_points
    assert truth.attrs["topology"] == topology
    assert g.attrs[names.ATTR_DRIVE_POINT] == truth.attrs[names.ATTR_DRIVE_POINT]
    # exact truth: its eq. 4 is the FRF
    ref = frf(truth, g[names.FREQUENCY].values)
    # the noise-free FRF is this very call (same model, grid and drive point): bit-identical
    np.testing.assert_array_equal(g[names.FRF].values, ref[names.FRF].values)
    # non-proportional damping: complex mode vectors (lam*Phi not real)
    lp = truth[names.MODE_VECTOR].values * truth[names.EIGENVALUE].values
    # a property (complex modes), not a rounding comparison: 0 to ~1e-16 for proportional damping
    assert np.max(np.abs(lp.imag) / np.abs(lp).max(axis=0)) > 1e-3
    assert truth[names.NATURAL_FREQUENCY].max() <= 50.0


def test_random_system_more_modes_than_points_and_reproducible():
    g, truth = random_system(6, "chain", n_modes=15, seed=8, n_frequencies=64)
    assert g.sizes[names.POINT] == 6 and truth.sizes[names.MODE] == 15
    assert truth.attrs[names.ATTR_DRIVE_POINT] in list(g[names.POINT].values)
    g2, truth2 = random_system(6, "chain", n_modes=15, seed=8, n_frequencies=64)
    # the same seed, the same computation: bit-identical (reproducibility is the claim)
    np.testing.assert_array_equal(g[names.FRF].values, g2[names.FRF].values)
    np.testing.assert_array_equal(truth[names.EIGENVALUE].values, truth2[names.EIGENVALUE].values)
    g3, _ = random_system(6, "chain", n_modes=15, seed=9, n_frequencies=64)
    assert not np.array_equal(g[names.FRF].values, g3[names.FRF].values)


@pytest.mark.parametrize("topology", ["chain", "grid"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_system_closely_spaced_pair_is_close(topology, seed):
    g, truth = random_system(10, topology, closely_spaced=True, seed=seed, n_frequencies=64)
    pair = np.asarray(truth.attrs["closely_spaced_pair"]) - 1
    assert pair[1] == pair[0] + 1  # adjacent in frequency
    f = truth[names.NATURAL_FREQUENCY].values
    z = truth[names.DAMPING_RATIO].values
    gap = (f[pair[1]] - f[pair[0]]) / f[pair[0]]
    assert 0 < gap < 0.04
    # comparable to the half-power bandwidth 2 zeta (mode coupling), unlike the other modes
    assert gap < 2.5 * 2 * z[pair].max()
    others = np.delete(np.diff(f) / f[:-1], pair[0])
    assert others.min() > 2 * gap


@pytest.mark.parametrize("topology", ["chain", "grid"])
@pytest.mark.parametrize("seed", [0, 3, 5])
def test_random_system_weak_mode_is_weak(topology, seed):
    _, truth = random_system(
        8, topology, weak_mode=True, closely_spaced=seed == 5, seed=seed, n_frequencies=64
    )
    k = truth.attrs["weak_mode"] - 1
    peaks = mode_peaks(truth).values
    assert peaks[k] <= 0.01 * np.median(np.delete(peaks, k))
    P = truth.attrs[names.ATTR_DRIVE_POINT]
    assert contrast(truth, k, P) <= 0.1  # masked by the other modes at the drive point
    # but it makes its own peak at the absorber's (measured) point
    assert contrast(truth, k, truth[names.POINT].values[-1]) > 2


def test_random_system_impulse_source_and_noise():
    g, truth = random_system(5, "chain", source="impulse_response", seed=2)
    ami_xr.validate(g)
    assert g.attrs[names.ATTR_SOURCE] == names.SOURCE_IMPULSE
    dt, n = g.attrs[names.ATTR_DT], g.attrs[names.ATTR_NSAMPLES]
    omega = 2 * np.pi * g[names.FREQUENCY].values
    A, lam = truth[names.RESIDUE].values, truth[names.EIGENVALUE].values
    ref = frf_from_residues(omega, lam, A, dt, n)
    # the simulator's FFT of its sampled impulse responses vs the closed form: ~eps log2(n) of the
    # peak times the eigenvector conditioning
    np.testing.assert_allclose(g[names.FRF].values, ref, rtol=0, atol=1e-10 * np.abs(ref).max())
    gn, _ = random_system(5, "chain", source="impulse_response", seed=2, noise=0.1)
    assert gn.attrs["noise_level"] == 0.1
    assert not np.allclose(gn[names.FRF].values, g[names.FRF].values)
    ga, _ = random_system(5, "grid", seed=2, noise=0.05, n_frequencies=256)
    gc, _ = random_system(5, "grid", seed=2, n_frequencies=256)
    d = ga[names.FRF].values - gc[names.FRF].values
    bound = 0.05 * np.abs(gc[names.FRF].values.real).max(axis=-1)
    assert np.all(np.abs(d.real).max(axis=-1) <= bound)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"n_points": 4}, "n_points"),
        ({"n_points": 51}, "n_points"),
        ({"n_points": 5.0}, "n_points"),
        ({"topology": "ring"}, "topology"),
        ({"n_modes": 3}, "n_modes"),
        ({"n_points": 5, "n_modes": 5, "closely_spaced": True, "weak_mode": True}, "n_modes"),
        ({"source": "measured"}, "source"),
        ({"noise": -1}, "noise"),
        ({"noise_kind": "pink"}, "noise_kind"),
        ({"damping": (0.1, 0.01)}, "damping"),
        ({"pair_gap": 0.5}, "pair_gap"),
        ({"weak_level": 0}, "weak_level"),
        ({"source": "impulse_response", "frequency": [1.0, 2.0]}, "frequency"),
        ({"duration": 10.0}, "duration"),
        ({"max_frequency_hz": -5}, "max_frequency_hz"),
        ({"seed": -1}, "seed"),
    ],
)
def test_random_system_bad_input(kwargs, match):
    with pytest.raises(AmiXrValueError, match=match):
        random_system(**kwargs)


def test_dask_backed_models_stay_lazy_and_agree():
    pytest.importorskip("dask")
    truth = modal_model(*random_mck(4, 1), drive_point=2)
    lazy = truth.chunk({names.POINT: 2})
    f = np.linspace(0.0, 3.0, 40)
    g = frf(lazy, f)
    h = impulse_response(lazy, (5.0, 256))
    assert hasattr(g[names.FRF].data, "dask") and hasattr(h[names.RESPONSE].data, "dask")
    # dask splits the point dim only: every point's synthesis runs the same operations, bit-
    # identical
    np.testing.assert_array_equal(g[names.FRF].values, frf(truth, f)[names.FRF].values)
    np.testing.assert_array_equal(
        h[names.RESPONSE].values, impulse_response(truth, (5.0, 256))[names.RESPONSE].values
    )
