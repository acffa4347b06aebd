"""Model-completion trials are screened on their own band (ami_xr.core.regions.band_fit): the
band fit finds a missed mode, its gain is close to the full fit's, and a trial whose band is
most of the data is left to the screen on all lines."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from ami_xr.ami.settings import RefineSettings
from ami_xr.core import varpro
from ami_xr.core.regions import band_fit, fit_modes

from ..reference import frf_from_residues


def _problem(noise=1e-3, seed=0):
    """Eight well separated modes at three points over 4000 lines, white noise."""
    rng = np.random.default_rng(seed)
    fn = np.array([12.0, 21.0, 33.0, 41.0, 52.0, 63.0, 77.0, 88.0])
    wn = 2 * np.pi * fn
    zeta = 0.01
    lam = -zeta * wn + 1j * wn * np.sqrt(1 - zeta**2)
    phi = rng.standard_normal((3, fn.size))
    residue = lam[None, :] * phi * phi[0][None, :]
    omega = 2 * np.pi * np.linspace(5.0, 100.0, 4000)
    frf = frf_from_residues(omega, lam, residue)
    scale = noise * np.abs(frf).max()
    frf = frf + scale * (rng.standard_normal(frf.shape) + 1j * rng.standard_normal(frf.shape))
    return varpro.make_problem(frf, omega, None, None), lam, omega


def _opts(omega):
    return dict(
        decay=0.0,
        max_iter=10,
        tol=RefineSettings.tol,
        max_shift=RefineSettings.max_shift,
        min_width=2.0 * (omega[1] - omega[0]),
        trace=None,
    )


@pytest.mark.parametrize(
    ("noise", "missing", "strong"), [(1e-3, 4, True), (0.1, 2, False), (0.1, 4, False)]
)
def test_a_missed_mode_is_found_on_its_band_with_the_full_fits_gain(noise, missing, strong):
    """The band's likelihood-ratio gain understates the full one (its noise estimate holds more
    of the missed mode) and is close to it near the detection threshold, where it decides."""
    prob, lam, omega = _problem(noise)
    opts = _opts(omega)
    rest = np.delete(lam, missing)
    fit = fit_modes(prob, rest, rest, **opts)[0]
    start = lam[missing] * (1 + 0.002j)  # a residual peak's guess, a little off
    trial = (np.append(fit.lam, start), np.append(rest, start), 1, np.empty(0, int))
    local = band_fit(prob, fit, trial, opts, opts["min_width"])
    gain, refined, n_iter = local
    assert gain is not None  # the band is a fraction of the lines
    assert n_iter > 0
    assert abs(refined[-1] - lam[missing]) < 2e-3 * abs(lam[missing])
    far = np.abs(fit.lam.imag - lam[missing].imag) > 2 * np.pi * 25.0
    np.testing.assert_array_equal(refined[:-1][far], fit.lam[far])  # far modes untouched
    threshold = chi2.isf(1e-3 / omega.size, 2 + 2 * prob.n_points)
    full = fit_modes(prob, refined, trial[1], **opts)[0]
    full_gain = 2.0 * (fit.cost - full.cost)
    assert threshold < gain <= 1.01 * full_gain
    if strong:
        assert gain > 100 * threshold
    else:
        assert gain > 0.5 * full_gain


def test_nothing_to_gain_on_a_band_of_noise():
    prob, lam, omega = _problem()
    opts = _opts(omega)
    fit = fit_modes(prob, lam, lam, **opts)[0]  # complete model
    spurious = 2 * np.pi * 70.0 * (-0.01 + 1j)  # between two modes, only noise there
    trial = (np.append(fit.lam, spurious), np.append(lam, spurious), 1, np.empty(0, int))
    gain = band_fit(prob, fit, trial, opts, opts["min_width"])[0]
    threshold = chi2.isf(1e-3 / omega.size, 2 + 2 * prob.n_points)
    assert gain < threshold


def test_a_trial_spanning_most_of_the_band_is_not_fitted_locally():
    prob, lam, omega = _problem()
    opts = _opts(omega)
    fit = fit_modes(prob, lam, lam, **opts)[0]
    start = fit.lam.copy()
    start[0] *= 1 + 1e-3j  # the first and the last mode restarted: the band is everything
    start[-1] *= 1 - 1e-3j
    trial = (start, lam.copy(), 0, np.empty(0, int))
    assert band_fit(prob, fit, trial, opts, opts["min_width"])[0] is None
    unchanged = (fit.lam.copy(), lam.copy(), 0, np.empty(0, int))
    gain, start, n_iter = band_fit(prob, fit, unchanged, opts, opts["min_width"])
    assert gain is None and n_iter == 0 and start is unchanged[0]
