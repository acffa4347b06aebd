"""Property-based tests (hypothesis) of the kernel layer's checked wrappers.

Random stable, underdamped modes inside the band, random residues, random grids of the
continuous model and of the exact discrete (impulse-response) model; every property is checked
against an independent numpy expression written here, not against another kernel.

Tolerances are relative to the size of the compared quantity; each says in a comment why it is
right. The examples are small so the file runs in a few seconds, also with ``NUMBA_DISABLE_JIT=1``
(every kernel as plain Python).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.fft
import scipy.signal
from hypothesis import given, settings
from hypothesis import strategies as st

from ami_xr.errors import AmiXrValueError
from ami_xr.kernels import fft as kfft
from ami_xr.kernels import linalg, modal_basis, noise, projection, residues, single_mode
from ami_xr.kernels import windows as kwin

from ..reference import impulse_responses

EPS = np.finfo(np.float64).eps
# Rounding error of one evaluation of a sum of a few modal terms, relative to its largest
# term: each term costs O(10) flops with errors of a few ulp; 1e3 ulp leaves a wide margin.
SUM_RTOL = 1e3 * EPS

_SETTINGS = settings(max_examples=30, deadline=None)


def assert_within(got, want, tol):
    """``|got - want| <= tol`` elementwise (``tol`` broadcast), with the worst case shown."""
    err = np.abs(np.asarray(got) - np.asarray(want))
    bad = err > tol
    assert not np.any(bad), f"{int(bad.sum())} values off; worst error {err.max()!r}"


# --- strategies ---------------------------------------------------------------------------------


@st.composite
def modes(draw, max_modes: int = 3):
    """``lam`` (K,) stable and underdamped, natural frequencies >= 30 % apart in 20..400 rad/s,
    and residues (P, K) with |A| in [0.1, 10] (P = 1..3)."""
    n_mode = draw(st.integers(1, max_modes))
    n_point = draw(st.integers(1, 3))
    w0 = draw(st.floats(20.0, 60.0))
    gaps = draw(st.lists(st.floats(1.3, 2.0), min_size=n_mode, max_size=n_mode))
    wn = w0 * np.cumprod(gaps)
    zeta = np.array(draw(st.lists(st.floats(1e-3, 0.1), min_size=n_mode, max_size=n_mode)))
    lam = -zeta * wn + 1j * wn * np.sqrt(1.0 - zeta**2)
    mag = draw(st.lists(st.floats(0.1, 10.0), min_size=n_point * n_mode, max_size=n_point * n_mode))
    phase = draw(
        st.lists(st.floats(-np.pi, np.pi), min_size=n_point * n_mode, max_size=n_point * n_mode)
    )
    res = (np.array(mag) * np.exp(1j * np.array(phase))).reshape(n_point, n_mode)
    return lam, res


@st.composite
def models(draw, lam):
    """``(dt, n_samples)``: None, None (continuous) or a discrete model whose Nyquist frequency
    lies 1.5-4x above the highest mode and whose record holds 16..256 samples."""
    if draw(st.booleans()):
        return None, None
    wmax = float(np.max(np.abs(lam)))
    dt = np.pi / (wmax * draw(st.floats(1.5, 4.0)))
    return dt, draw(st.one_of(st.none(), st.integers(16, 256)))


def band(lam, dt, n_lines):
    """``n_lines`` angular frequencies spanning the modes (below Nyquist in the discrete model)."""
    wn = np.abs(lam)
    lo, hi = 0.5 * wn.min(), 1.5 * wn.max()
    if dt:
        hi = min(hi, 0.99 * np.pi / dt)
    return np.linspace(lo, hi, n_lines)


def contribution_ref(omega, lam, res, dt=None, n_samples=None):
    """One mode, written straight from the module docstring of ``modal_basis`` (the closed
    form that ``tests.reference.frf_from_residues``, built on ``mode_contribution``, relies on)."""
    if not dt:
        return res / (1j * omega - lam) + np.conj(res) / (1j * omega - np.conj(lam))
    out = 0j
    for a, p in ((res, lam), (np.conj(res), np.conj(lam))):
        scale = dt * (1.0 - np.exp(p * n_samples * dt)) if n_samples else dt
        out = out + a * scale / (1.0 - np.exp((p - 1j * omega) * dt))
    return out


def scale_of(lam, res, omega, dt, n_samples):
    """Largest |single-mode contribution| on the grid: the yardstick of rounding errors."""
    return max(
        np.max(np.abs(contribution_ref(omega, lam[k], res[j, k], dt, n_samples)))
        for j in range(res.shape[0])
        for k in range(lam.size)
    )


# --- modal basis and synthesis ----------------------------------------------------------------


@_SETTINGS
@given(data=st.data(), n_lines=st.integers(2, 60))
def test_synthesis_is_the_sum_of_the_reference_contributions(data, n_lines):
    lam, res = data.draw(modes())
    dt, n = data.draw(models(lam))
    omega = band(lam, dt, n_lines)
    got = modal_basis.synthesize(omega, lam, res, dt, n)
    want = sum(contribution_ref(omega, lam[k], res[:, k : k + 1], dt, n) for k in range(lam.size))
    # sum of K <= 3 terms, each evaluated to a few ulp of its own size
    np.testing.assert_allclose(got, want, rtol=0, atol=SUM_RTOL * scale_of(lam, res, omega, dt, n))
    per_mode = sum(
        modal_basis.mode_contribution(omega, lam[k], res[:, k : k + 1], dt, n)
        for k in range(lam.size)
    )
    # the wrappers mode_contribution/pole_basis evaluate the same b(lam, w) in another order
    np.testing.assert_allclose(
        got, per_mode, rtol=0, atol=SUM_RTOL * scale_of(lam, res, omega, dt, n)
    )


@_SETTINGS
@given(
    data=st.data(),
    a=st.floats(-3.0, 3.0),
    b=st.floats(-3.0, 3.0),
    n_lines=st.integers(2, 40),
)
def test_synthesis_is_real_linear_in_the_residues(data, a, b, n_lines):
    lam, r1 = data.draw(modes())
    _, r2 = data.draw(modes())
    r2 = np.resize(r2, r1.shape)  # same (P, K), other values
    dt, n = data.draw(models(lam))
    omega = band(lam, dt, n_lines)
    lhs = modal_basis.synthesize(omega, lam, a * r1 + b * r2, dt, n)
    rhs = a * modal_basis.synthesize(omega, lam, r1, dt, n) + b * modal_basis.synthesize(
        omega, lam, r2, dt, n
    )
    size = (abs(a) + abs(b) + 1.0) * max(
        scale_of(lam, r1, omega, dt, n), scale_of(lam, r2, omega, dt, n)
    )
    # both sides are sums of the same terms with rounding of a few ulp of each term
    np.testing.assert_allclose(lhs, rhs, rtol=0, atol=SUM_RTOL * size)


@_SETTINGS
@given(data=st.data(), n_samples=st.integers(16, 300))
def test_discrete_synthesis_is_dt_times_the_dft_of_the_sampled_impulse_response(data, n_samples):
    # the docstring's claim: on the DFT grid, with n_samples, the discrete model is exact
    lam, res = data.draw(modes())
    dt, _ = data.draw(models(lam).filter(lambda m: m[0] is not None))
    h = impulse_responses(lam, res, n_samples, dt)  # (P, N): sum_k 2 Re(A_k exp(lam_k t))
    frf = kfft.impulse_to_frf(h, dt)
    omega = 2 * np.pi * kfft.rfft_frequencies(n_samples, dt)
    np.testing.assert_allclose(omega, 2 * np.pi * scipy.fft.rfftfreq(n_samples, dt), rtol=1e-15)
    model = modal_basis.synthesize(omega, lam, res, dt, n_samples)
    # FFT rounding is ~eps log2(N) times the l1 norm of the record: dt sum|h| bounds every line
    size = dt * np.abs(h).sum(axis=-1, keepdims=True) + np.abs(model).max()
    assert_within(frf, model, 1e3 * EPS * size)


@_SETTINGS
@given(
    coef=st.lists(st.complex_numbers(max_magnitude=1e3, allow_nan=False), min_size=2, max_size=6),
    kind=st.sampled_from([0, 1, 2]),
    start=st.sampled_from([0.0, 0.5, 3.0]),
    n_lines=st.integers(2, 30),
)
def test_residual_terms_match_their_closed_forms(coef, kind, start, n_lines):
    coef = np.resize(np.array(coef), (len(coef) // 2, 2))
    omega = np.linspace(start, start + 50.0, n_lines)
    s = 1j * omega
    with np.errstate(divide="ignore", invalid="ignore"):
        lower = (1 / s**2, 1 / s, np.ones_like(s))[kind]
    upper = (np.ones_like(s), s, s**2)[kind]
    if kind in (0, 1):
        lower = np.where(omega == 0, 0, lower)  # singular at 0 Hz: left out
    want = coef[:, :1] * lower + coef[:, 1:] * upper
    if kind == 0:
        want[:, omega == 0] = 0  # receptance: the whole 0 Hz line is left at 0 (docstring)
    got = modal_basis.synthesize_residual_terms(omega, coef, kind)
    # two products and a sum: a few ulp of the larger term
    size = np.abs(coef[:, :1] * lower) + np.abs(coef[:, 1:] * upper)
    assert_within(got, want, 16 * EPS * size)


# --- single-mode least squares (eqs. 10-12) ----------------------------------------------------


def _single_mode_case(data, n_lines):
    lam, res = data.draw(modes(max_modes=1))
    dt, n = data.draw(models(lam))
    wn, zeta = abs(lam[0]), -lam[0].real / abs(lam[0])
    half = (3 * zeta + data.draw(st.floats(0.02, 0.3))) * wn  # band around the resonance
    omega = np.linspace(wn - half, wn + half, n_lines)
    if dt:
        omega = omega[omega < 0.99 * np.pi / dt]
    return lam[0], res[:, 0], dt, n, omega


# Noise-free data of one mode satisfy eq. (*) of single_mode exactly, so the least-squares
# solution is the truth up to rounding amplified by the condition number of the 4x4 normal
# equations (squared by forming them; < 1e5 for these bands of >= 6 lines around the peak):
# 1e-13 observed, 1e-8 leaves room and is still far below any real estimation error.
FIT_RTOL = 1e-8


@_SETTINGS
@given(data=st.data(), n_lines=st.integers(6, 40), c=st.floats(1e-3, 1e3))
def test_fit_single_mode_recovers_a_noise_free_mode_and_scales(data, n_lines, c):
    lam, res, dt, n, omega = _single_mode_case(data, n_lines)
    frf = contribution_ref(omega, lam, res[0], dt, n)
    lam_fit, res_fit, code = single_mode.fit_single_mode(frf, omega, dt, n)
    assert code == single_mode.FIT_OK
    assert abs(lam_fit - lam) <= FIT_RTOL * abs(lam)
    assert abs(res_fit - res[0]) <= FIT_RTOL * abs(res[0])
    # scaling the data by a real c scales the residue, leaves the eigenvalue (same tolerance)
    sign = data.draw(st.sampled_from([1.0, -1.0]))
    lam_c, res_c, code = single_mode.fit_single_mode(sign * c * frf, omega, dt, n)
    assert code == single_mode.FIT_OK
    assert abs(lam_c - lam_fit) <= FIT_RTOL * abs(lam)
    assert abs(res_c - sign * c * res_fit) <= FIT_RTOL * c * abs(res_fit)


@_SETTINGS
@given(data=st.data(), n_lines=st.integers(6, 40))
def test_fit_single_mode_on_many_frfs_recovers_one_eigenvalue_and_every_residue(data, n_lines):
    lam, res, dt, n, omega = _single_mode_case(data, n_lines)
    frf = np.array([contribution_ref(omega, lam, a, dt, n) for a in res])
    lam_fit, res_fit, code = single_mode.fit_single_mode(frf, omega, dt, n)
    assert code == single_mode.FIT_OK
    # as for the per-FRF fit: exact model, rounding times the condition number
    assert abs(lam_fit - lam) <= FIT_RTOL * abs(lam)
    np.testing.assert_allclose(res_fit, res, rtol=FIT_RTOL)


# --- residues with fixed eigenvalues (eq. 9) --------------------------------------------------


@_SETTINGS
@given(
    data=st.data(),
    n_lines=st.integers(40, 120),
    c=st.one_of(st.floats(1e-3, 1e3), st.floats(-1e3, -1e-3)),  # no subnormal scale factors
)
def test_residues_fixed_recovers_known_residues_and_scales(data, n_lines, c):
    lam, res = data.draw(modes())
    dt, n = data.draw(models(lam))
    omega = band(lam, dt, n_lines)
    kind = data.draw(st.sampled_from([-1, 0, 1, 2]))
    frf = sum(contribution_ref(omega, lam[k], res[:, k : k + 1], dt, n) for k in range(lam.size))
    coef = None
    if kind >= 0:
        # residual terms of roughly the size of the modes at the band edges
        coef = np.array([[1e4, 1e-4], [1e2, 1e-2], [1e0, 1e-6]][kind]) * (0.3 - 0.2j)
        coef = np.broadcast_to(coef, (res.shape[0], 2))
        frf = frf + modal_basis.synthesize_residual_terms(omega, coef, kind)
    got = residues.residues_fixed(frf, omega, lam, dt=dt, n_samples=n, residual_kind=kind)
    # Exact model: rounding times the condition number of the (2K + 4)-column normal equations,
    # which the >= 30 % mode spacing and >= 40 lines keep below ~1e6 (Jacobi-scaled);
    # 1e-13 observed. 1e-6 relative to the largest residue is still far below any physical error.
    tol = 1e-6 * np.abs(res).max()
    np.testing.assert_allclose(got[:, : lam.size], res, rtol=0, atol=tol)
    if kind >= 0:
        np.testing.assert_allclose(got[:, lam.size :], coef, rtol=1e-6)
    # eq. 9 is real-linear in the data: real c scales every residue (same conditioning)
    scaled = residues.residues_fixed(c * frf, omega, lam, dt=dt, n_samples=n, residual_kind=kind)
    np.testing.assert_allclose(scaled, c * got, rtol=0, atol=1e-6 * abs(c) * np.abs(got).max())


# --- noise floors and thresholds --------------------------------------------------------------


@_SETTINGS
@given(
    n_lines=st.integers(2, 200),
    n_frf=st.integers(1, 3),
    seed=st.integers(0, 2**32 - 1),
    c=st.floats(1e-6, 1e6),
    offset=st.complex_numbers(max_magnitude=10.0),
)
def test_noise_floor_is_the_median_difference_estimate(n_lines, n_frf, seed, c, offset):
    rng = np.random.default_rng(seed)
    y = rng.normal(size=(n_frf, n_lines)) + 1j * rng.normal(size=(n_frf, n_lines))
    want = np.sqrt(np.median(np.abs(np.diff(y, axis=-1)) ** 2, axis=-1) / (2 * np.log(2)))
    got = noise.noise_floor(y)
    # a median of squared differences and one sqrt: a few ulp
    np.testing.assert_allclose(got, want, rtol=1e-14)
    # equivariant under scaling, invariant under a constant offset (differences cancel it);
    # the offset adds rounding of |offset| ulp per difference, ~1e-15 * 10 / O(1) noise
    np.testing.assert_allclose(noise.noise_floor(c * y), c * got, rtol=1e-14)
    np.testing.assert_allclose(noise.noise_floor(y + offset), got, rtol=1e-13)


@_SETTINGS
@given(n_lines=st.integers(1, 10**6), pfa=st.floats(1e-9, 0.5))
def test_peak_threshold_has_the_stated_false_alarm_probability(n_lines, pfa):
    t = noise.peak_threshold(n_lines, pfa)
    # P(max of n Exp(1) > t) = 1 - (1 - exp(-t))^n, evaluated in log space to keep digits
    p = -np.expm1(n_lines * np.log1p(-np.exp(-t)))
    # log/expm1 round trip of the closed form: relative error of a few ulp times n exp(-t) ~ 1
    assert abs(p - pfa) <= 1e-10 * pfa
    assert noise.peak_threshold(n_lines, pfa / 2) > t  # rarer false alarms need a higher bar


# --- small dense linear algebra ---------------------------------------------------------------


@_SETTINGS
@given(n=st.integers(1, 12), m=st.integers(1, 4), seed=st.integers(0, 2**32 - 1))
def test_solve_normal_equations_matches_numpy(n, m, seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(3 * n, n)) * np.exp(rng.uniform(-3, 3, n))  # badly scaled columns
    nmat = a.T @ a
    rhs = rng.normal(size=(n, m))
    x, ok = linalg.solve_normal_equations(nmat, rhs)
    assert ok
    want = np.linalg.solve(nmat, rhs)
    # both are backward stable: forward errors are bounded by cond * eps; Jacobi scaling removes
    # the column scales, leaving cond(random 3n x n)^2 < ~1e4
    np.testing.assert_allclose(x, want, rtol=0, atol=1e-8 * np.abs(want).max())
    np.testing.assert_allclose(
        nmat @ x, rhs, rtol=0, atol=1e-9 * np.abs(nmat).max() * np.abs(x).max()
    )


def _backward_error(coef, z):
    """``|p(z)| / sum_k |coef_k| |z|^(n-k)``: the relative change of the coefficients that makes
    ``z`` an exact root (rounding level for a backward-stable root finder)."""
    powers = z ** np.arange(coef.size - 1, -1, -1)
    return abs(np.dot(coef, powers)) / np.dot(np.abs(coef), np.abs(powers))


@_SETTINGS
@given(
    degree=st.integers(1, 6),
    scale=st.floats(-3, 3),
    seed=st.integers(0, 2**32 - 1),
    pairs=st.booleans(),
)
def test_poly_roots_are_the_roots_of_np_roots(degree, scale, seed, pairs):
    rng = np.random.default_rng(seed)
    if pairs:  # two modes: conjugate pairs of close poles, the two-mode fit's quartic
        w = 1.0 + rng.uniform(0.0, 0.1, 2)
        sig = -rng.uniform(1e-3, 3e-2, 2)
        want = np.concatenate([sig + 1j * w, sig - 1j * w]) * 10.0**scale
        coef = np.poly(want).real.astype(np.complex128)
    else:
        coef = (rng.normal(size=degree + 1) + 1j * rng.normal(size=degree + 1)) * 10.0**scale
        want = np.roots(coef)
    got = linalg.polynomial_roots(coef)
    assert got.shape == want.shape
    for z in got:
        assert _backward_error(coef, z) < 1e-14
    # same roots: each matched to the nearest of np.roots within its conditioning
    # (separation from the other roots; every root here is simple)
    for z in want:
        d = np.abs(got - z)
        sep = np.sort(np.abs(want - z))[1] if want.size > 1 else abs(z) + 1.0
        assert d.min() <= 1e-10 * max(abs(z), 1.0) * max(1.0, 1.0 / sep)
    # ordered by decreasing imaginary part, then decreasing real part
    assert all(
        (a.imag > b.imag) or (a.imag == b.imag and a.real >= b.real)
        for a, b in zip(got[:-1], got[1:])
    )


def test_poly_roots_of_multiple_and_zero_roots():
    # a double root: any backward-stable method finds it only to sqrt(eps)
    got = linalg.polynomial_roots(np.array([1.0, -2.0, 1.0]))
    np.testing.assert_allclose(got, [1.0, 1.0], atol=1e-7)
    # trailing zero coefficients are exact zero roots, as np.roots gives them
    got = linalg.polynomial_roots(np.array([1.0, 3.0, 0.0, 0.0]))
    assert np.count_nonzero(got == 0) == 2
    np.testing.assert_allclose(got[got != 0], [-3.0], rtol=1e-15)
    np.testing.assert_array_equal(linalg.polynomial_roots(np.array([2.0, 0.0])), [0.0])


@pytest.mark.parametrize("coef", [[0.0, 1.0, 2.0], [1.0], [[1.0, 2.0]], [1.0, np.nan, 2.0]])
def test_poly_roots_bad_coefficients_are_named(coef):
    with pytest.raises(AmiXrValueError, match="coef"):
        linalg.polynomial_roots(np.array(coef))


@_SETTINGS
@given(n=st.integers(1, 30), m=st.integers(1, 6), k=st.integers(1, 6), seed=st.integers(0, 99))
def test_gram_and_matmul_small_match_numpy(n, m, k, seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, m))
    b = rng.normal(size=(m, k))
    # sums of <= 30 products in another order than BLAS: n eps times the sum of |terms|
    np.testing.assert_allclose(
        projection.gram(a), a.T @ a, rtol=0, atol=n * EPS * (np.abs(a).T @ np.abs(a)).max()
    )
    np.testing.assert_allclose(
        projection.matmul_small(a, b), a @ b, rtol=0, atol=m * EPS * (np.abs(a) @ np.abs(b)).max()
    )
    g = projection.gram(a)
    assert np.array_equal(g, g.T)  # filled symmetric by construction


# --- windows and FFT ------------------------------------------------------------------------------


@_SETTINGS
@given(
    name=st.sampled_from(["boxcar", "hann", "flattop"]),
    n=st.integers(1, 300),
    sym=st.booleans(),
)
def test_cosine_windows_match_scipy(name, n, sym):
    got = kwin.get_window(name, n, sym=sym)
    want = scipy.signal.get_window(name, n, fftbins=not sym)
    # a cosine sum of <= 5 terms with O(1) coefficients: a few ulp
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)


@_SETTINGS
@given(
    n=st.integers(1, 200), p=st.integers(1, 3), dt=st.floats(1e-5, 10.0), seed=st.integers(0, 99)
)
def test_impulse_to_frf_is_dt_times_rfft_of_the_windowed_record(n, p, dt, seed):
    rng = np.random.default_rng(seed)
    y = rng.normal(size=(p, n))
    w = kwin.get_window("hann", n)
    got = kfft.impulse_to_frf(y, dt, window=w)
    want = dt * np.fft.rfft(w * y, axis=-1)
    # two FFT implementations: ~eps log2(n) times the l1 norm of the record
    np.testing.assert_allclose(got, want, rtol=0, atol=64 * EPS * dt * np.abs(y).sum())
    # Parseval on the windowed record (full spectrum from the one-sided half)
    full = np.fft.fft(w * y, axis=-1)
    np.testing.assert_allclose(
        np.sum(np.abs(full) ** 2, axis=-1) / n, np.sum((w * y) ** 2, axis=-1), rtol=1e-12
    )


# --- argument errors --------------------------------------------------------------------------

OMEGA = np.linspace(1.0, 10.0, 8)
LAM = np.array([-0.1 + 5j])


def _bad_omega(omega):
    return [
        lambda: modal_basis.synthesize(omega, LAM, np.ones((1, 1), complex)),
        lambda: modal_basis.synthesize_residual_terms(omega, np.ones((1, 2)), 0),
        lambda: single_mode.fit_single_mode(np.ones(omega.shape[-1], complex), omega),
        lambda: residues.residues_fixed(np.ones((1, omega.shape[-1])), omega, LAM),
    ]


def _corrupt_omega(bad, where):
    omega = OMEGA.copy()
    if isinstance(bad, float):
        omega[where] = bad  # non-finite
    elif bad == "repeat":
        omega[max(where, 1)] = omega[max(where, 1) - 1]  # not strictly increasing
    elif bad == "reverse":
        omega = omega[::-1].copy()
    elif bad == "2d":
        omega = omega.reshape(2, 4)
    else:
        omega = omega[:1]
    return omega


@_SETTINGS
@given(
    which=st.integers(0, 3),
    where=st.integers(0, 7),
    bad=st.sampled_from([np.nan, np.inf, -np.inf, "repeat", "reverse", "2d", "short"]),
)
def test_bad_omega_is_named(which, where, bad):
    with pytest.raises(AmiXrValueError, match=r"^omega: "):
        _bad_omega(_corrupt_omega(bad, where))[which]()


# -inf first / +inf last is still "strictly increasing": checked_omega tests isfinite too
@pytest.mark.parametrize("which", range(4))
@pytest.mark.parametrize(("bad", "where"), [(-np.inf, 0), (np.inf, 7)])
def test_infinite_end_of_omega_is_named(which, bad, where):
    with pytest.raises(AmiXrValueError, match=r"^omega: "), np.errstate(all="ignore"):
        _bad_omega(_corrupt_omega(bad, where))[which]()


@_SETTINGS
@given(dt=st.sampled_from([np.nan, np.inf, -1.0, -1e-9]), n_samples=st.sampled_from([None, 16]))
def test_bad_dt_is_named(dt, n_samples):
    with pytest.raises(AmiXrValueError, match=r"^dt"):
        modal_basis.synthesize(OMEGA, LAM, np.ones((1, 1)), dt, n_samples)
    with pytest.raises(AmiXrValueError, match=r"^dt"):
        kfft.impulse_to_frf(np.ones(8), dt)
    with pytest.raises(AmiXrValueError, match=r"^dt"):
        kfft.rfft_frequencies(8, dt)


@_SETTINGS
@given(p=st.integers(1, 3), k=st.integers(1, 3), dp=st.integers(1, 2), dk=st.integers(1, 2))
def test_mismatched_shapes_are_named(p, k, dp, dk):
    res = np.ones((p, k), complex)
    with pytest.raises(AmiXrValueError, match=r"^lam: "):
        modal_basis.synthesize(OMEGA, np.ones((p + dp, k + dk), complex), res)
    with pytest.raises(AmiXrValueError, match=r"^data: "):
        residues.residues_fixed(np.ones((p, OMEGA.size + dk)), OMEGA, LAM)
    with pytest.raises(AmiXrValueError, match=r"^use: "):
        residues.residues_fixed(np.ones((p, OMEGA.size)), OMEGA, LAM, use=np.ones(dk, bool))
    with pytest.raises(AmiXrValueError, match=r"^data: "):
        single_mode.fit_single_mode(np.ones(OMEGA.size + dk, complex), OMEGA)
    with pytest.raises(AmiXrValueError, match=r"^data: "):
        single_mode.fit_single_mode(np.ones((p, OMEGA.size - dk), complex), OMEGA)
    with pytest.raises(AmiXrValueError, match=r"^coef: "):
        modal_basis.synthesize_residual_terms(OMEGA, np.ones((p, 2 + dk)), 0)
    with pytest.raises(AmiXrValueError, match=r"^nmat: "):
        linalg.solve_normal_equations(np.ones((k, k + dk)), np.ones(k))
    with pytest.raises(AmiXrValueError, match=r"^rhs: "):
        linalg.solve_normal_equations(np.eye(k), np.ones(k + dk))
    with pytest.raises(AmiXrValueError, match=r"^a, b: "):
        projection.matmul_small(np.ones((p, k)), np.ones((k + dk, 2)))
    with pytest.raises(AmiXrValueError, match=r"^a: "):
        projection.gram(np.ones(k))
    with pytest.raises(AmiXrValueError, match=r"^data: "):
        noise.noise_floor(np.ones((p, 1)))
    with pytest.raises(AmiXrValueError, match=r"^x: "):
        kwin.apply_window(np.ones((p, k)), np.ones(k + dk))


@_SETTINGS
@given(
    where=st.integers(0, 7),
    value=st.sampled_from([np.nan, np.inf, -np.inf]),
)
def test_non_finite_windows_and_bad_dtypes_are_named(where, value):
    w = np.ones(8)
    w[where] = value
    with pytest.raises(AmiXrValueError, match=r"^w: contains NaN or inf"):
        kwin.apply_window(np.ones(8), w)
    with pytest.raises(AmiXrValueError, match=r"^window: contains NaN or inf"):
        kfft.impulse_to_frf(np.ones(8), 0.1, window=w)
    with pytest.raises(AmiXrValueError, match=r"^y: expected real samples"):
        kfft.impulse_to_frf(np.ones(8, complex), 0.1)
    with pytest.raises(AmiXrValueError, match=r"^x: expected numeric samples"):
        kwin.apply_window(np.array(["a"] * 8), np.ones(8))
    with pytest.raises(AmiXrValueError, match=r"^pfa: "):
        noise.peak_threshold(10, value)
    with pytest.raises(AmiXrValueError, match=r"^zeta_max: "):
        single_mode.fit_single_mode(np.ones(8, complex), OMEGA, zeta_max=-abs(value))
