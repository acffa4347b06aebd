"""The screen before a close-pair split trial (issue 41, cost): a split whose likelihood ratio,
fitted on the lines around the pole with only its neighbours free, stays below the trial's
threshold is not refitted on every pole (an exactly repeated root: its second pole fits noise);
a real close pair passes it and is split as before. The refits of one identification share its
working data (decided once)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.stats import chi2

from ami_xr import names
from ami_xr.ami import mimo, mimo_refit, mimo_screen
from ami_xr.ami.settings import RefineSettings
from ami_xr.core import varpro

from .test_mimo_refit import SETTINGS, _start, _truth

F = np.linspace(2, 24, 551)


def _merged(fn_pair, seed=0):
    """The stacked FRFs of two references and a refit with one pole for the pair ``fn_pair``."""
    truth = _truth([8.0, *fn_pair], [0.01, 0.012, 0.012])
    lam = truth[names.EIGENVALUE].values
    _, stacked, merged = _start(truth, F, [2, 5], 0.001, seed, [lam[0], lam[1:].mean()])
    return stacked, merged


def _gain(stacked, merged):
    work = mimo_refit.working_data(stacked, SETTINGS).work
    terms = str(merged.attrs.get(names.ATTR_REFINE_RESIDUAL_TERMS, "")).split(",")
    prob = mimo_screen.stacked_problem(work, tuple(t for t in terms if t))
    lam = mimo_refit._measured_poles(stacked, merged)
    k = int(np.argmin(np.abs(lam.imag - 2 * np.pi * 15.0)))
    gain = mimo_screen.split_gain(prob, lam, k, mimo_refit.SPLIT_START, 10)
    limit = chi2.isf(RefineSettings.add_pfa, 2 + 2 * stacked.sizes[names.POINT])
    return gain, limit


@pytest.mark.parametrize("seed", [0, 1])
def test_the_screen_passes_a_close_pair_and_refuses_a_repeated_root(seed):
    """A pair 0.33 % apart seen through one pole gains far above the threshold; an exactly
    repeated root's second pole gains what noise gives (below it)."""
    gain, limit = _gain(*_merged([15.0, 15.05], seed))
    assert gain > 3 * limit
    gain, limit = _gain(*_merged([15.0, 15.0], seed))
    assert np.isfinite(gain) and gain < limit


def _split_counting_trials(monkeypatch, stacked, merged):
    """``with_close_pairs_split`` with its trial refits counted: (calls, result, split)."""
    calls = []
    trial = mimo_refit._split_trial
    monkeypatch.setattr(
        mimo_refit, "_split_trial", lambda *a, **k: calls.append(a) or trial(*a, **k)
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out, split = mimo_refit.with_close_pairs_split(
            stacked, merged, 2, SETTINGS, mimo.RANK_ONE_RATIO_MAX, mimo.NOISE_FACTOR
        )
    return calls, out, split


def test_an_exactly_repeated_root_costs_no_refit(monkeypatch):
    """The split of an exactly repeated root is screened out: no trial refit runs, the result
    is the one given."""
    stacked, merged = _merged([15.0, 15.0])
    calls, out, split = _split_counting_trials(monkeypatch, stacked, merged)
    assert mimo_refit.not_rank_one(merged, 2, mimo.RANK_ONE_RATIO_MAX, mimo.NOISE_FACTOR)[1] > 0
    assert not calls and split.size == 0 and out is merged


def test_a_close_pair_still_runs_its_trial(monkeypatch):
    """The screen lets the real pair through: its trial runs and the split is kept."""
    stacked, merged = _merged([15.0, 15.05])
    calls, _, split = _split_counting_trials(monkeypatch, stacked, merged)
    assert len(calls) == 1 and split.size == 1 and abs(split[0] - 15.025) < 0.01


def test_a_window_too_short_for_its_poles_says_nothing():
    """Fewer lines around the pole than its model needs: NaN (the trial decides)."""
    omega = 2 * np.pi * np.linspace(14.9, 15.1, 9)
    lam = np.array([-0.5 + 2j * np.pi * 15.0])
    frf = 1.0 / (1j * omega[None, :] - lam[0]) * np.ones((3, 1))
    prob = varpro.make_problem(frf, omega, None, None)
    assert np.isnan(mimo_screen.split_gain(prob, lam, 0, 0.25, 10))


def test_the_refits_shared_working_data_change_nothing():
    """A refit given the identification's working data is the refit that decides them
    itself."""
    stacked, merged = _merged([15.0, 15.05])
    lam = mimo_refit._measured_poles(stacked, merged)
    none = np.zeros((stacked.sizes[names.POINT], 0), bool)
    work = mimo_refit.working_data(stacked, SETTINGS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = mimo_refit.refit(stacked, merged, lam, none, SETTINGS)
        b = mimo_refit.refit(stacked, merged, lam, none, SETTINGS, working=work)
    np.testing.assert_array_equal(a[names.EIGENVALUE].values, b[names.EIGENVALUE].values)
    np.testing.assert_array_equal(a[names.RESIDUE].values, b[names.RESIDUE].values)


def test_the_shared_working_data_are_decided_once(monkeypatch):
    """A :class:`mimo_refit.SharedWorking` decides nothing until asked, then once."""
    stacked, merged = _merged([15.0, 15.05])
    calls = []
    decide = mimo_refit.working_data
    monkeypatch.setattr(mimo_refit, "working_data", lambda *a: calls.append(1) or decide(*a))
    shared = mimo_refit.SharedWorking(stacked, SETTINGS)
    assert not calls
    lam = mimo_refit._measured_poles(stacked, merged)
    none = np.zeros((stacked.sizes[names.POINT], 0), bool)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = mimo_refit.refit(stacked, merged, lam, none, SETTINGS, working=shared)
        b = mimo_refit.refit(stacked, merged, lam, none, SETTINGS, working=shared)
    assert len(calls) == 1
    np.testing.assert_array_equal(a[names.EIGENVALUE].values, b[names.EIGENVALUE].values)


def _problem(stacked, merged):
    work = mimo_refit.working_data(stacked, SETTINGS).work
    terms = str(merged.attrs.get(names.ATTR_REFINE_RESIDUAL_TERMS, "")).split(",")
    prob = mimo_screen.stacked_problem(work, tuple(t for t in terms if t))
    lam = mimo_refit._measured_poles(stacked, merged)
    return prob, lam, int(np.argmin(np.abs(lam.imag - 2 * np.pi * 15.0)))


def test_the_first_order_gain_is_that_of_two_poles_a_hair_apart():
    """:func:`mimo_screen.first_order_gain` from the projection's own columns equals the gain
    of the pole replaced by two poles ``lam -+ eps`` (free residues: the pole's term and its
    derivative to first order), computed by a projection of its own."""
    stacked, merged = _merged([15.0, 15.05])
    prob, lam, k = _problem(stacked, merged)
    proj = varpro.project(prob, lam)
    got = mimo_screen.first_order_gain(prob, proj, k)
    eps = 1e-3 * abs(lam[k].real)
    two = np.append(lam, lam[k] + eps)
    two[k] = lam[k] - eps
    ref = 2.0 * (varpro.objective(prob, proj) - varpro.objective(prob, varpro.project(prob, two)))
    assert got > 100 and abs(got - ref) < 1e-3 * ref


@pytest.mark.parametrize("seed", [0, 1])
def test_a_split_within_the_noise_to_first_order_is_refused_without_a_fit(monkeypatch, seed):
    """An exactly repeated root: the split's first-order term gains what noise gives (below
    the chi-square level of 2 per FRF at ``FIRST_ORDER_PFA``) and no pole is fitted; a close
    pair's first-order gain is most of its fitted split's, and the fit runs."""
    fits = []
    lm = varpro.levenberg_marquardt
    monkeypatch.setattr(
        varpro, "levenberg_marquardt", lambda *a, **k: fits.append(1) or lm(*a, **k)
    )
    stacked, merged = _merged([15.0, 15.0], seed)
    prob, lam, k = _problem(stacked, merged)
    sub, keep = mimo_screen._window(prob, lam, k)
    first = mimo_screen.first_order_gain(sub, varpro.project(sub, lam[keep]), int(keep[:k].sum()))
    level = chi2.isf(mimo_screen.FIRST_ORDER_PFA, 2 * prob.n_points)
    assert 0 < first < level
    fits.clear()  # the fits that made the start
    assert mimo_screen.split_gain(prob, lam, k, mimo_refit.SPLIT_START, 10) == first
    assert not fits
    stacked, merged = _merged([15.0, 15.05], seed)
    prob, lam, k = _problem(stacked, merged)
    sub, keep = mimo_screen._window(prob, lam, k)
    first = mimo_screen.first_order_gain(sub, varpro.project(sub, lam[keep]), int(keep[:k].sum()))
    fits.clear()
    gain = mimo_screen.split_gain(prob, lam, k, mimo_refit.SPLIT_START, 10)
    assert fits and first > level and 0.8 * gain < first <= 1.05 * gain
