"""Each mechanism of the model-order step (ami_xr.core.order, core.pairs, core.order_state) on
its own: the per-mode record, the residual screen, the extra-sum-of-squares drop screen, the
drops, the proposals, the acceptance of a fitted trial, the well-posed start, exactness, and
the policy passed down as a parameter (a test runs the step with another policy)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import chi2

from ami_xr.ami.settings import RefineSettings
from ami_xr.core import order, varpro
from ami_xr.core.order_state import Fitted, Modes, State, Trial
from ami_xr.core.policy import POLICY
from ami_xr.core.regions import complex_rows, fit_modes, residual_peaks, residual_rows

from ..reference import frf_from_residues
from .test_local_trials import _opts, _problem

MISSING = 4  # the 52 Hz mode of test_local_trials._problem


def _state(prob, lam, opts, keep=None):
    """A state fitted to the modes ``keep`` of ``lam`` (every mode by default)."""
    lam = lam if keep is None else lam[keep]
    fitted = Fitted(*fit_modes(prob, lam, lam, **opts))
    n_point = prob.n_points
    return State(
        fitted.fit, fitted.free, lam, np.zeros((n_point, lam.size), complex), np.arange(lam.size), 0
    )


def _clean_problem():
    """Three modes at two points, noise-free."""
    fn = np.array([20.0, 35.0, 60.0])
    wn = 2 * np.pi * fn
    lam = -0.01 * wn + 1j * wn * np.sqrt(1 - 1e-4)
    residue = lam[None, :] * np.array([[1.0, 0.5, -0.8], [0.3, -1.0, 0.6]])
    omega = 2 * np.pi * np.linspace(5.0, 80.0, 1500)
    frf = frf_from_residues(omega, lam, residue)
    return varpro.make_problem(frf, omega, None, None), lam, omega


# -- the record of the modes --------------------------------------------------------------


def test_modes_take_keeps_every_field_in_step_and_the_ami_modes_first():
    res0 = np.arange(6.0).reshape(2, 3) + 0j
    m = Modes.start([True, False, True, True], np.arange(4) + 1j, res0, [7, 8, 9])
    m.merged_fn[1] = 5.0
    kept = m.without([1])
    assert kept.n_modes == 3 and kept.n_ami == 2
    np.testing.assert_array_equal(kept.free, [True, True, True])
    np.testing.assert_array_equal(kept.lam0, np.array([0, 2, 3]) + 1j)
    np.testing.assert_array_equal(kept.origin, [7, 9])
    np.testing.assert_array_equal(kept.res0, res0[:, [0, 2]])
    assert np.isnan(kept.merged_fn).all()
    grown = kept.appended(np.array([9 + 9j]))
    assert grown.n_modes == 4 and grown.n_ami == 2  # an added mode has no AMI reference
    assert grown.free[-1] and not grown.at_ami[-1] and not grown.supported[-1]
    kept.free[0] = False  # a copy: the original record is untouched
    assert m.free[0]
    with pytest.raises(ValueError, match="keep"):
        m.take([2, 0])


def test_state_holds_the_record_and_nothing_beside_it():
    """The per-mode fields live in ``state.modes`` only: no second copy on the state to fall
    out of step with the record (an assignment to a field name on the state is refused)."""
    prob, lam, omega = _clean_problem()
    state = _state(prob, lam, _opts(omega))
    state.modes.supported[1] = True  # in place, as the close-pair test marks a pair
    accepted = state.modes.without([0])
    state.accept(state.fit, accepted)
    assert state.modes is accepted and state.changed
    np.testing.assert_array_equal(state.modes.supported, [True, False])
    with pytest.raises(AttributeError):
        _ = state.free
    with pytest.raises(AttributeError):
        state.free = np.ones(3, bool)


def test_residual_candidates_point_at_a_missed_mode_and_not_at_noise():
    prob, lam, omega = _problem(noise=1e-3)
    opts = _opts(omega)
    missing = _state(prob, lam, opts, np.delete(np.arange(lam.size), MISSING))
    peaks, power = residual_peaks(prob, missing.fit.proj, missing.fit.lam, 2)
    assert power.shape == omega.shape
    width = 2 * abs(lam[MISSING].real)
    assert abs(peaks[0].imag - lam[MISSING].imag) < width
    complete = _state(prob, lam, opts)
    fit = complete.fit
    assert residual_peaks(prob, fit.proj, fit.lam, 2, screen_pfa=1e-6)[0] == []


def test_costs_without_each_mode_equal_a_projection_without_it():
    prob, lam, omega = _problem(noise=1e-2)
    fit = _state(prob, lam, _opts(omega)).fit
    costs = order._costs_without_each_mode(prob, fit.proj)
    floor = (varpro.RSS_FLOOR**2) * prob.y_norm2
    for k in (0, MISSING, lam.size - 1):
        proj = varpro.project(prob, np.delete(fit.lam, k))
        direct = 0.5 * prob.n_rows * np.sum(np.log(np.maximum(proj.rss, floor)))
        assert costs[k] == pytest.approx(direct, rel=1e-9)
    assert np.all(costs > fit.cost)  # every real mode explains something


# -- drops -----------------------------------------------------------------------------------


def test_a_pole_that_fits_noise_is_dropped_and_real_modes_stay():
    prob, lam, omega = _problem(noise=1e-3)
    opts = _opts(omega)
    spurious = 2 * np.pi * 70.0 * (-0.01 + 1j)  # between two modes, only noise there
    state = _state(prob, np.append(lam, spurious), opts)
    threshold = chi2.isf(1e-3 / omega.size, 2 + 2 * prob.n_points)
    order._drop_insignificant(prob, state, threshold, opts)
    assert state.fit.lam.size == lam.size and state.changed
    assert state.modes.n_modes == lam.size and state.modes.origin.size == lam.size
    assert np.min(np.abs(state.fit.lam - spurious)) > 2 * np.pi * 5.0
    again = _state(prob, lam, opts)
    order._drop_insignificant(prob, again, threshold, opts)
    assert again.fit.lam.size == lam.size and not again.changed


def test_on_an_exact_fit_a_duplicate_mode_is_removed():
    prob, lam, omega = _clean_problem()
    opts = dict(_opts(omega), max_iter=30)
    dup = lam[1] * (1 + 0.05j)  # a second pole near the 35 Hz mode
    state = _state(prob, np.append(lam, dup), opts)
    order._drop_superfluous(prob, state, opts)
    assert state.fit.lam.size == lam.size
    assert order.is_exact(prob, state.fit)
    none = dataclasses.replace(POLICY, superfluous_tries=0)
    state = _state(prob, np.append(lam, dup), opts)
    order._drop_superfluous(prob, state, opts, none)
    assert state.fit.lam.size == lam.size + 1


# -- proposals and their acceptance ----------------------------------------------------------


def test_proposals_put_a_pole_at_the_missed_peak_within_the_policy_bounds():
    prob, lam, omega = _problem(noise=1e-3)
    opts = _opts(omega)
    state = _state(prob, lam, opts, np.delete(np.arange(lam.size), MISSING))
    trials, _ = order._proposals(prob, state, 0.0, opts["min_width"], POLICY)
    assert all(isinstance(t, Trial) for t in trials)
    first = trials[0]
    assert first.n_add == 1 and first.removed.size == 0
    assert abs(first.start[-1].imag - lam[MISSING].imag) < 2 * abs(lam[MISSING].real)
    assert len(trials) <= POLICY.residual_peaks + 3 * POLICY.max_trials
    few = dataclasses.replace(POLICY, residual_peaks=0, max_trials=0)
    assert order._proposals(prob, state, 0.0, opts["min_width"], few)[0] == []


def _missing_one():
    """The eight-mode problem fitted without its 52 Hz mode, and the trial that adds it."""
    prob, lam, omega = _problem(noise=1e-3)
    opts = _opts(omega)
    state = _state(prob, lam, opts, np.delete(np.arange(lam.size), MISSING))
    fit = state.fit
    none = np.empty(0, int)
    good = Trial(
        np.append(fit.lam, lam[MISSING]), np.append(state.modes.lam0, lam[MISSING]), 1, none
    )
    return prob, lam, omega, opts, state, good


def _judge(prob, state, opts, trials):
    fit = state.fit
    width = np.maximum(2.0 * np.abs(fit.lam.real), opts["min_width"])
    r_now = complex_rows(residual_rows(prob, fit.proj))
    var = order.error_variance(prob, fit.proj, width, np.zeros(fit.lam.size, bool), True, r_now)
    threshold = chi2.isf(1e-3 / prob.omega.size, 2 + 2 * prob.n_points)
    scatter = np.full(fit.lam.size, np.nan)
    stuck = np.zeros(fit.lam.size, int)
    return order.Judge(
        prob, state, fit, trials, threshold, r_now, var[0], scatter, opts, POLICY, stuck
    )


def test_a_fitted_trial_holds_only_when_it_adds_the_missed_mode_and_stays_free():
    prob, lam, omega, opts, state, good = _missing_one()
    fit, none = state.fit, good.removed
    same = Trial(fit.lam.copy(), state.modes.lam0.copy(), 0, none)
    judge = _judge(prob, state, opts, [good, same])
    fitted = Fitted(*fit_modes(prob, good.start, good.ref, **opts))
    ok, moved = order._holds(judge, good, fitted)
    assert ok and not moved.any()
    frozen = fitted._replace(free=np.append(fitted.free[:-1], False))
    assert not order._holds(judge, good, frozen)[0]  # the mode it tries must stay free
    refit = Fitted(*fit_modes(prob, same.start, same.ref, **opts))
    assert not order._holds(judge, same, refit)[0]  # returns where it was: changes nothing
    taken = order._take([(1.0, 1), (2.0, 0)], judge)
    assert taken is not None and taken[0] is good
    no_fits = judge._replace(policy=dataclasses.replace(POLICY, screen_keep=0))
    assert order._take([(2.0, 0)], no_fits) is None


def test_quick_screen_keeps_the_trial_that_explains_the_residual():
    prob, lam, omega = _problem(noise=1e-3)
    opts = _opts(omega)
    none = np.empty(0, int)
    state = _state(prob, lam, opts, np.delete(np.arange(lam.size), MISSING))
    fit = state.fit
    good = Trial(
        np.append(fit.lam, lam[MISSING]), np.append(state.modes.lam0, lam[MISSING]), 1, none
    )
    out = order._quick_screen([0], _judge(prob, state, opts, [good]))
    assert [i for _, i in out] == [0]
    complete = _state(prob, lam, opts)  # nothing missing: a pole in the noise gains too little
    noise = 2 * np.pi * 70.0 * (-0.01 + 1j)
    bad = Trial(np.append(complete.fit.lam, noise), np.append(lam, noise), 1, none)
    assert order._quick_screen([0], _judge(prob, complete, opts, [bad])) == []


def test_a_mode_frozen_far_from_two_failed_trials_spares_the_fits_of_the_others():
    """A present mode that froze in the full fits of two trials far from it is moved out of its
    region by the model, not by the trials: the trials that leave it alone are not fitted."""
    prob, lam, omega, opts, state, good = _missing_one()
    fit, none = state.fit, good.removed
    judge = _judge(prob, state, opts, [good])
    touched, far = order._reach(judge, good)
    assert not touched.any()
    assert far.all()  # every present mode is beyond six bandwidths (6.2 Hz) of 52 Hz
    beside = 2 * np.pi * 43.0 * (-0.01 + 1j)
    near = Trial(np.append(fit.lam, beside), np.append(state.modes.lam0, beside), 1, none)
    assert not order._reach(judge, near)[1][3] and order._reach(judge, near)[1][0]  # 41 vs 12 Hz
    n_fits = prob.n_fits
    judge.stuck[0] = 2
    assert order._take([(1.0, 0)], judge) is None
    assert prob.n_fits == n_fits  # not fitted
    judge.stuck[0] = 1  # one trial's fit is not yet evidence
    assert order._take([(1.0, 0)], judge) is not None
    assert prob.n_fits == n_fits + 1


# -- start and end ---------------------------------------------------------------------------


def test_well_posed_drops_one_of_two_coincident_poles():
    prob, lam, omega = _clean_problem()
    mu = np.append(lam, lam[1])
    keep = order.well_posed(prob, mu)
    assert keep.sum() == lam.size
    assert order.well_posed(prob, lam).all()


def test_exactness_follows_the_policy():
    prob, lam, omega = _clean_problem()
    fit = _state(prob, lam, dict(_opts(omega), max_iter=30)).fit
    assert order.is_exact(prob, fit)
    assert not order.is_exact(prob, fit, dataclasses.replace(POLICY, exact_rss=0.0))
    noisy_prob = _problem(noise=1e-3)[0]
    noisy = _state(noisy_prob, _problem()[1], _opts(_problem()[2])).fit
    assert not order.is_exact(noisy_prob, noisy)


@pytest.mark.parametrize("no_proposals", [False, True])
def test_order_tests_run_with_the_policy_they_are_given(no_proposals):
    """The same missed mode: found with the default policy, not when the policy proposes
    nothing (the step reads its numbers from the parameter, not from a global)."""
    prob, lam, omega = _problem(noise=1e-3)
    opts = _opts(omega)
    state = _state(prob, lam, opts, np.delete(np.arange(lam.size), MISSING))
    policy = dataclasses.replace(POLICY, residual_peaks=0, max_trials=0) if no_proposals else POLICY
    settings = RefineSettings()
    order.order_tests(
        prob, state, settings, opts, prob.n_points, chi2, opts["min_width"], policy=policy
    )
    n = state.fit.lam.size
    assert n == (lam.size - 1 if no_proposals else lam.size)
    if not no_proposals:
        assert np.min(np.abs(state.fit.lam - lam[MISSING])) < 2e-3 * abs(lam[MISSING])
        assert state.modes.n_modes == n and state.modes.origin.size == lam.size - 1


def _pair_case(fn, zeta, residue, max_shift):
    """A state fitted to ``fn``/``zeta`` at two points (0.1 % noise) and the close-pair test
    run on it under a policy whose model-error test never supports a pair (inf * 0 is nan)."""
    from ami_xr.core.pairs import merge_split_pairs

    wn = 2 * np.pi * np.asarray(fn)
    zeta = np.asarray(zeta)
    lam = -zeta * wn + 1j * wn * np.sqrt(1 - zeta**2)
    omega = 2 * np.pi * np.linspace(90.0, 112.0, 1100)
    frf = frf_from_residues(omega, lam, lam[None, :] * np.asarray(residue))
    rng = np.random.default_rng(3)
    frf = frf + 1e-3 * np.abs(frf).max() * (rng.standard_normal(frf.shape) + 0j)
    prob = varpro.make_problem(frf, omega, None, None)
    opts = dict(_opts(omega), max_shift=max_shift)
    state = _state(prob, lam, opts)
    assert state.modes.free.all()
    never = dataclasses.replace(POLICY, pair_excess=np.inf)
    merge_split_pairs(prob, state, 1e-3, 0.0, opts, opts["min_width"], never)
    return state, lam


def test_a_narrow_mode_on_a_broad_poles_band_is_not_merged_into_it():
    """Two lightly damped modes on the band of a heavily damped pole (the hammer FRF's 3962 and
    4017 Hz under a 1.8 %-damped pole at 4048 Hz). Without the broad pole the stronger mode of
    the pair would have to leave its region to take its part: the pair is no split duplicate
    and stays, even under a policy whose model-error test never supports a pair; a split
    duplicate under the same rules is still merged."""
    residue = [[1.0, 0.8, 3.0], [0.5, -0.6, 2.0]]
    state, lam = _pair_case([99.0, 100.0, 100.75], [0.0025, 0.0025, 0.018], residue, 0.5)
    np.testing.assert_allclose(np.sort(state.fit.lam.imag), np.sort(lam.imag), rtol=1e-3)
    assert state.modes.supported.all()
    # one mode split in two close poles: the weaker is merged into the stronger
    state, lam = _pair_case([100.0, 100.05], [0.0025, 0.0025], [[1.0, 0.2], [0.5, 0.1]], 0.5)
    assert state.fit.lam.size == 1 and not state.modes.supported.any()
