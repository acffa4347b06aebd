"""The model-order step's acceptance rule (ami_xr.core.order): one rule for every proposal, the
likelihood-ratio gain against the error variance of each line (a noise level that follows the
frequency, plus the model error a typical peak shows), decided on the proposal's own band.

The measured-data case it is built for: a roving-accelerometer or drifting test, where each FRF
sees a mode at a slightly different frequency (mass loading, temperature). No single pole fits
every FRF exactly, and a second pole 0.05 % away fits the rest: a phantom split. A real doublet
with distinct shapes 0.4 % apart must still give two modes.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

import ami_xr
from ami_xr import names
from ami_xr.ami.settings import RefineSettings
from ami_xr.core import flags as qf
from ami_xr.core import varpro
from ami_xr.core.model_error import error_variance
from ami_xr.core.regions import (
    band_fit,
    complex_rows,
    fit_modes,
    residual_rows,
    weighted_gain,
)

from ..reference import frf_from_residues
from .test_local_trials import _opts

FN = np.array([176.0, 476.0, 932.0, 1535.0, 2286.0])  # Hz, a free-free beam's first modes
ZETA = 0.002


def _lam(fn, zeta=ZETA):
    wn = 2 * np.pi * np.asarray(fn, float)
    return -zeta * wn + 1j * wn * np.sqrt(1 - zeta**2)


def _beam(shift_rel: float, noise: float, seed: int = 0, n_point: int = 6):
    """Accelerance-like FRFs of five single modes; FRF ``j`` sees every mode shifted by its own
    relative amount (uniform in +-``shift_rel``): one structure, slightly different per test."""
    rng = np.random.default_rng(seed)
    freq = np.arange(50.0, 2600.0, 0.25)
    omega = 2 * np.pi * freq
    phi = rng.standard_normal((n_point, FN.size))
    lam = _lam(FN)
    frf = np.zeros((n_point, freq.size), complex)
    for j in range(n_point):
        lam_j = _lam(FN * (1 + shift_rel * rng.uniform(-1, 1)))
        res = lam_j * phi[j] * phi[0]
        frf[j] = frf_from_residues(omega, lam_j, res[None, :])[0]
    scale = noise * np.abs(frf).max(axis=1, keepdims=True)
    frf += scale * (rng.standard_normal(frf.shape) + 1j * rng.standard_normal(frf.shape))
    return frf, freq, lam


def _dataset(frf, freq):
    return ami_xr.make_frf_dataset(frf, freq, drive_point=0, response_quantity="displacement")


@pytest.mark.parametrize("seed", [0, 1])
def test_a_mode_that_shifts_from_frf_to_frf_is_not_split(seed):
    """Per-FRF shifts up to 0.05 % (a quarter of the half-power bandwidth) and 0.1 % noise:
    one mode each, no two modes within 1 % of a true one."""
    frf, freq, lam = _beam(5e-4, 1e-3, seed)
    out = ami_xr.identify(_dataset(frf, freq))
    fn = np.sort(out[names.NATURAL_FREQUENCY].values)
    for f in FN:
        near = np.abs(fn - f) < 0.01 * f
        assert near.sum() == 1, (f, fn[near])


def test_a_real_doublet_with_distinct_shapes_stays_two_modes():
    """Two modes 0.4 % apart (twice their half-power bandwidth), one strong at the even points,
    the other at the odd points, 0.1 % noise: both found."""
    rng = np.random.default_rng(3)
    freq = np.arange(2700.0, 3000.0, 0.25)
    omega = 2 * np.pi * freq
    fn = np.array([2850.0, 2850.0 * 1.004])
    lam = _lam(fn, 0.001)
    n_point = 8
    even = (np.arange(n_point) % 2 == 0).astype(float)
    phi = np.column_stack([0.2 + even, 1.2 - even]) * rng.uniform(0.8, 1.2, (n_point, 2))
    res = lam[None, :] * phi * phi[0][None, :]
    frf = frf_from_residues(omega, lam, res)
    frf += (
        1e-3
        * np.abs(frf).max()
        * (rng.standard_normal(frf.shape) + 1j * rng.standard_normal(frf.shape))
    )
    out = ami_xr.identify(_dataset(frf, freq))
    found = out[names.NATURAL_FREQUENCY].values
    for f in fn:
        assert np.min(np.abs(found - f)) < 0.25 * (fn[1] - fn[0]), found


def _problem_two_levels():
    """One mode at three points; the noise is ten times higher above 60 Hz than below."""
    rng = np.random.default_rng(0)
    freq = np.linspace(5.0, 100.0, 4000)
    omega = 2 * np.pi * freq
    lam = _lam([30.0], 0.01)
    res = lam[None, :] * rng.standard_normal((3, 1))
    frf = frf_from_residues(omega, lam, res)
    level = np.where(freq > 60.0, 1e-2, 1e-3) * np.abs(frf).max()
    frf = frf + level * (rng.standard_normal(frf.shape) + 1j * rng.standard_normal(frf.shape))
    return varpro.make_problem(frf, omega, None, None), lam, omega, level


def test_error_variance_follows_a_noise_level_that_changes_with_frequency():
    prob, lam, omega, level = _problem_two_levels()
    fit = fit_modes(prob, lam, lam, **_opts(omega))[0]
    width = np.maximum(2 * np.abs(fit.lam.real), 2 * (omega[1] - omega[0]))
    skip = np.zeros(1, bool)
    var_local = error_variance(prob, fit.proj, width, skip, local=True)[0]
    var_flat = error_variance(prob, fit.proj, width, skip)[0]
    truth = 2 * level**2  # E|e|^2 of complex noise with std `level` per component
    low, high = omega < 2 * np.pi * 55, omega > 2 * np.pi * 65
    ratio_low = np.median(var_local[:, low]) / truth[low][0]
    ratio_high = np.median(var_local[:, high]) / truth[high][0]
    assert 0.7 < ratio_high < 1.4  # the loud part: its own level
    # the quiet part: never below the FRF's overall level (the fits weight each FRF alike)
    assert ratio_low > 0.7
    np.testing.assert_allclose(var_local[:, low].min(axis=1), var_flat[:, 0], rtol=1e-12)
    # one level per FRF cannot follow the loud part: it sits between the two
    assert np.median(var_flat[:, high]) < 0.5 * truth[high][0]


def test_weighted_gain_is_the_likelihood_ratio_of_complex_gaussian_lines():
    before = np.array([[3.0 + 4.0j, 1.0]])
    after = np.array([[0.0, 1.0j]])
    var = np.array([[5.0, 2.0]])
    # 2 * (25 / 5 + (1 - 1) / 2)
    assert weighted_gain(before, after, var) == pytest.approx(10.0)


def test_a_noise_bump_is_not_accepted_and_a_missed_mode_is():
    """Against the local error variance: a pole put where the noise is only louder gains less
    than the threshold; a missed mode in the loud part gains more."""
    prob, lam, omega, _ = _problem_two_levels()
    opts = _opts(omega)
    fit = fit_modes(prob, lam, lam, **opts)[0]
    width = np.maximum(2 * np.abs(fit.lam.real), opts["min_width"])
    var = error_variance(prob, fit.proj, width, np.zeros(1, bool), local=True)[0]
    threshold = chi2.isf(RefineSettings.add_pfa / omega.size, 2 + 2 * prob.n_points)
    spurious = _lam([80.0], 0.01)[0]
    trial = (np.append(fit.lam, spurious), np.append(lam, spurious), 1, np.empty(0, int))
    gain = band_fit(prob, fit, trial, opts, opts["min_width"], var)[0]
    if gain is None:  # the pole left its region on the band: judged on all lines instead
        quick = fit_modes(prob, trial[0], trial[1], **dict(opts, max_iter=3))[0]
        r_now = complex_rows(residual_rows(prob, fit.proj))
        gain = weighted_gain(r_now, complex_rows(residual_rows(prob, quick.proj)), var)
    assert gain < threshold
    # now the same data with a mode at 80 Hz the model misses
    rng = np.random.default_rng(1)
    extra = frf_from_residues(
        omega, _lam([80.0], 0.01), _lam([80.0], 0.01)[None, :] * rng.standard_normal((3, 1))
    )
    y = prob.y + np.concatenate([extra.real, extra.imag], axis=1)
    prob2 = varpro.Problem(y, prob.omega, prob.line_weight, None, None)
    fit2 = fit_modes(prob2, lam, lam, **opts)[0]
    var2 = error_variance(prob2, fit2.proj, width, np.zeros(1, bool), local=True)[0]
    start = _lam([80.2], 0.01)[0]
    trial2 = (np.append(fit2.lam, start), np.append(lam, start), 1, np.empty(0, int))
    gain2 = band_fit(prob2, fit2, trial2, opts, opts["min_width"], var2)[0]
    assert gain2 > 10 * threshold


def test_full_fits_are_counted_and_few_on_a_complete_model(paper_benchmark_clean):
    """The refinement records its fits on all lines; on noise-free data with the right modes
    the completion has nothing to try in full."""
    out = ami_xr.identify(paper_benchmark_clean[1])
    n_full = out.attrs[names.ATTR_REFINE_FULL_FITS]
    assert isinstance(n_full, int) and 1 <= n_full <= 4


def test_complete_false_keeps_the_ami_mode_count():
    """``complete=False``: the maximum-likelihood fit of AMI's modes only -- on the mass-loaded
    beam the same five modes, without a single trial fitted; a bad value is refused."""
    frf, freq, _ = _beam(5e-4, 1e-3, 0)
    ds = _dataset(frf, freq)
    out = ami_xr.identify(ds, complete=False)
    fn = np.sort(out[names.NATURAL_FREQUENCY].values)
    assert fn.size == FN.size
    np.testing.assert_allclose(fn, FN, rtol=2e-3)
    assert out.attrs[names.ATTR_REFINE_FULL_FITS] == 1  # the one joint fit
    assert not any(
        "added_by_refine" in str(f) for f in qf.flag_text(out[names.QUALITY_FLAGS].values)
    )
    with pytest.raises(ValueError, match="complete: expected True or False"):
        ami_xr.identify(ds, complete="no")


def _shifted_problem(shift_rel: float, n_point: int = 12, seed: int = 0):
    """The beam at many lines as a varpro problem, and its one-pole-per-mode fit."""
    frf, freq, lam = _beam(shift_rel, 1e-4, seed, n_point)
    omega = 2 * np.pi * freq
    prob = varpro.make_problem(frf, omega, None, None)
    opts = _opts(omega)
    fit = fit_modes(prob, lam, lam, **opts)[0]
    width = np.maximum(2 * np.abs(fit.lam.real), opts["min_width"])
    return prob, fit, width


def test_eigenvalue_scatter_measures_the_frf_to_frf_shift():
    """Shifts uniform in +-0.05 % (standard deviation 0.029 %): every peak's scatter is of that
    order; without shifts it is zero (the noise alone is taken off)."""
    from ami_xr.core.model_error import eigenvalue_scatter

    prob, fit, width = _shifted_problem(5e-4)
    scatter = eigenvalue_scatter(prob, fit.proj, width)
    assert np.all(np.isfinite(scatter))
    assert np.all((scatter > 0.3 * 2.9e-4) & (scatter < 2.0 * 2.9e-4)), scatter
    prob0, fit0, width0 = _shifted_problem(0.0)
    assert np.all(np.nan_to_num(eigenvalue_scatter(prob0, fit0.proj, width0)) < 2e-5)


def test_within_scatter_needs_a_typical_value_from_three_other_peaks():
    from ami_xr.core.model_error import within_scatter

    lam = _lam(FN)
    split = np.append(lam, lam[2] * (1 + 2e-4))  # 0.02 % from the mode at 932 Hz
    wide = np.append(lam, lam[2] * (1 + 4e-3))  # 0.4 %
    scatter = np.full(FN.size, 3e-4)
    assert within_scatter(split, lam, scatter)
    assert not within_scatter(wide, lam, scatter)
    few = scatter.copy()
    few[[0, 1, 3]] = np.nan  # two peaks away from the pole show a scatter: no typical value
    assert not within_scatter(split, lam, few)
    assert not within_scatter(split, lam, np.full(FN.size, np.nan))
