"""The region codes of :func:`ami_xr.core.regions._mode_codes` (the check the refinement's
Levenberg-Marquardt runs on every step) against a plain per-mode reference."""

from __future__ import annotations

import numpy as np
import pytest

from ami_xr.core.matching import match_by_distance
from ami_xr.core.regions import _mode_codes, fit_modes


def _reference(lam, lam0, max_shift, min_width):
    """The codes mode by mode, as the rule states them."""
    code = np.zeros(lam.size, dtype=int)
    for k in range(lam.size):
        if not np.isfinite(lam[k]) or lam[k].real >= 0 or lam[k].imag <= 0:
            code[k] = 2
    if not np.isfinite(lam).all():
        return code
    ref = lam0[match_by_distance(lam, lam0, np.maximum(2.0 * np.abs(lam0.real), min_width))]
    for k in range(lam.size):
        w = max(2.0 * abs(ref[k].real), min_width)
        far = abs(lam[k] - ref[k]) > max_shift * w
        collapsed = -lam[k].real < -ref[k].real / (1.0 + max_shift)
        if code[k] == 0 and (far or collapsed):
            code[k] = 1
        others = [abs(lam[j] - lam[k]) for j in range(lam.size) if j != k]
        if others and min(others) < 1e-6 * abs(lam[k]):
            code[k] = 2
    return code


@pytest.mark.parametrize("seed", range(20))
def test_codes_match_the_per_mode_rule(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 9))
    wn = np.sort(20.0 + 100.0 * rng.random(n))
    lam0 = -wn * (0.002 + 0.05 * rng.random(n)) + 1j * wn
    # moves from nothing to several bandwidths, some damping collapsed, some coincident pairs
    lam = lam0 + np.abs(lam0.real) * 3.0 * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    lam = np.where(rng.random(n) < 0.2, lam.imag * 1j - 1e-4, lam)
    if n > 1 and rng.random() < 0.5:
        k = int(rng.integers(0, n - 1))
        lam[k + 1] = lam[k] * (1.0 + 1e-9)
    if rng.random() < 0.2:
        lam[0] = complex(abs(lam[0].real), lam[0].imag)  # unstable
    expected = _reference(lam, lam0, 2.0, 0.01)
    np.testing.assert_array_equal(_mode_codes(lam, lam0, 2.0, 0.01), expected)


def test_coincident_modes_are_impossible_and_a_lone_mode_is_not():
    lam0 = np.array([-0.5 + 100.0j, -0.6 + 130.0j, -0.4 + 160.0j])
    lam = lam0.copy()
    lam[1] = lam[0] * (1.0 + 1e-8)  # merged into mode 0
    np.testing.assert_array_equal(_mode_codes(lam, lam0, 2.0, 0.01), [2, 2, 0])
    np.testing.assert_array_equal(_mode_codes(lam0[:1], lam0[:1], 2.0, 0.01), [0])


def test_a_mode_that_is_not_finite_makes_only_its_own_code_impossible():
    lam0 = np.array([-0.5 + 100.0j, -0.6 + 130.0j])
    lam = np.array([complex(np.nan, np.nan), -0.6 + 130.0j])
    np.testing.assert_array_equal(_mode_codes(lam, lam0, 2.0, 0.01), [2, 0])


def test_a_fit_gives_up_when_a_mode_it_needs_freezes():
    """``give_up``: the fit stops as soon as one of those modes leaves its region (a band fit
    of a trial is useless then); a fit in which they stay free is the same as without it."""
    from .test_local_trials import _opts, _problem

    prob, lam, omega = _problem(0.1)
    opts = _opts(omega)
    need = np.zeros(lam.size + 1, bool)
    need[-1] = True
    # an extra pole beside the 52 Hz mode leaves its region (it runs into the mode)
    start = np.append(lam, 2 * np.pi * (-0.3 + 52.3j))
    full = fit_modes(prob, start, start, **opts)
    short = fit_modes(prob, start, start, give_up=need, **opts)
    assert not full[1][-1] and not short[1][-1]
    assert short[2] < full[2]
    # on an extra pole that stays free nothing changes
    start = np.append(lam, 2 * np.pi * (-0.01 + 12.15j))
    full = fit_modes(prob, start, start, **opts)
    same = fit_modes(prob, start, start, give_up=need, **opts)
    assert full[1].all() and same[1].all() and same[2] == full[2]
    np.testing.assert_array_equal(same[0].lam, full[0].lam)
