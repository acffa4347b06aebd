"""The shared-pole refit of the multi-reference path (issue 41): the noise model of the first
pass, a pole above the band for the modes beyond it, and close pairs split by their residue
matrix."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami import mimo, mimo_refit
from ami_xr.ami.settings import IdentifySettings

POINTS = list(range(1, 9))


def _truth(fn, zeta, seed=3):
    """A modal model on 8 points: modes at ``fn`` (Hz) with damping ratios ``zeta`` and real
    mode vectors drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    wn = 2 * np.pi * np.asarray(fn, float)
    z = np.asarray(zeta, float)
    lam = -z * wn + 1j * wn * np.sqrt(1 - z**2)
    phi = rng.standard_normal((len(POINTS), lam.size)) * 0.05
    return xr.Dataset(
        {
            names.EIGENVALUE: ((names.MODE,), lam),
            names.MODE_VECTOR: ((names.POINT, names.MODE), phi + 0j),
        },
        coords={names.POINT: POINTS, names.MODE: np.arange(1, lam.size + 1)},
    )


def _noisy(truth, f, refs, level, seed):
    ds = ami_xr.simulate.frf(truth, f, references=refs)
    g = ds[names.FRF]
    rng = np.random.default_rng(seed)
    re = ami_xr.simulate.add_noise(g.real, level, rng=rng, dim=names.FREQUENCY)
    im = ami_xr.simulate.add_noise(g.imag, level, rng=rng, dim=names.FREQUENCY)
    return ds.assign({names.FRF: (re + 1j * im).assign_attrs(g.attrs)})


def _identify(ds):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ami_xr.identify(ds)


def _true_noise(ds, level):
    g = ds[names.FRF]
    return level * np.sqrt(
        (np.abs(g.real).max(names.FREQUENCY) ** 2 + np.abs(g.imag).max(names.FREQUENCY) ** 2) / 3
    )


SETTINGS = IdentifySettings(complete=False)  # no model completion: the trials alone add poles


def _start(truth, f, refs, level, seed, poles):
    """The stacked FRFs and a result refitted (:func:`mimo_refit.refit`) from ``poles``."""
    ds = _noisy(truth, f, refs, level, seed)
    labels, points = mimo._check(ds)
    stacked = mimo._stacked(ds, labels, points)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        first = ami_xr.ami.pipeline.identify_single(stacked, SETTINGS, final=False)
        none = np.zeros((stacked.sizes[names.POINT], 0), bool)
        return ds, stacked, mimo_refit.refit(stacked, first, np.asarray(poles), none, SETTINGS)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_close_pair_fitted_as_one_pole_is_split_by_its_residue_matrix(seed):
    """Two modes 0.33 % apart (a quarter of their half-power bandwidth), two references: one
    pole at their mean leaves a residue matrix of rank two; the split trial finds both."""
    truth = _truth([8.0, 15.0, 15.05], [0.01, 0.012, 0.012])
    lam = truth[names.EIGENVALUE].values
    f = np.linspace(2, 24, 551)
    _, stacked, merged = _start(truth, f, [2, 5], 0.001, seed, [lam[0], lam[1:].mean()])
    evidence = mimo_refit.not_rank_one(merged, 2, mimo.RANK_ONE_RATIO_MAX, mimo.NOISE_FACTOR)
    assert evidence[0] == 0 and evidence[1] > 1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out, split = mimo_refit.with_close_pairs_split(
            stacked, merged, 2, SETTINGS, mimo.RANK_ONE_RATIO_MAX, mimo.NOISE_FACTOR
        )
    assert split.size == 1 and abs(split[0] - 15.025) < 0.01
    got = np.sort(out[names.NATURAL_FREQUENCY].values)
    # each member within a few bound-sized errors (0.1 % noise: fn std ~1e-3 Hz here)
    np.testing.assert_allclose(got, [8.0, 15.0, 15.05], atol=5e-3)


def test_an_exactly_repeated_root_is_not_split():
    """One pole with a rank-two residue matrix explains an exactly repeated root: the second
    pole gains nothing and the pole stays one (the drive points separate it later)."""
    truth = _truth([8.0, 15.0, 15.0], [0.01, 0.012, 0.012])
    lam = truth[names.EIGENVALUE].values
    f = np.linspace(2, 24, 551)
    _, stacked, merged = _start(truth, f, [2, 5], 0.001, 0, [lam[0], lam[1]])
    evidence = mimo_refit.not_rank_one(merged, 2, mimo.RANK_ONE_RATIO_MAX, mimo.NOISE_FACTOR)
    assert evidence[1] > 1  # rank two indeed
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out, split = mimo_refit.with_close_pairs_split(
            stacked, merged, 2, SETTINGS, mimo.RANK_ONE_RATIO_MAX, mimo.NOISE_FACTOR
        )
    assert split.size == 0 and out.sizes[names.MODE] == 2


def test_a_pole_above_the_band_takes_the_tail_of_the_modes_beyond_it():
    """Analytic FRFs on 2-20 Hz of modes at 8, 15 and 18.5 Hz and one at 21.5 Hz (3.5
    bandwidths above the last line), no residual terms (exact data): fitted with the band's
    poles only, the tail shows as misfit (noise estimate above the true one, the 18.5 Hz mode
    biased); a pole above the lines removes it and is not reported."""
    truth = _truth([8.0, 15.0, 18.5, 21.5], [0.01, 0.01, 0.01, 0.01])
    lam = truth[names.EIGENVALUE].values
    f = np.linspace(2, 20, 451)
    ds, stacked, inband = _start(truth, f, [2, 5], 0.001, 0, lam[:3])
    true_noise = _true_noise(ami_xr.simulate.frf(truth, f, references=[2, 5]), 0.001)
    true_noise = true_noise.transpose(names.REFERENCE, names.POINT).values.ravel()
    before = inband[names.FRF_NOISE_STD].transpose(names.POINT).values / true_noise
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out, added = mimo_refit.with_tail_poles(stacked, inband, SETTINGS)
    after = out[names.FRF_NOISE_STD].transpose(names.POINT).values / true_noise
    assert added.size >= 1 and np.all((added > 20.0) & (added < 26.0))
    assert np.median(before) > 1.2 and np.median(after) < 1.1
    fn = np.sort(out[names.NATURAL_FREQUENCY].values)
    err_before = abs(np.sort(inband[names.NATURAL_FREQUENCY].values)[2] - 18.5)
    assert abs(fn[2] - 18.5) < err_before
    # the tail pole is not a mode of the result as reported
    from ami_xr.ami import pipeline as pl

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reported = pl.drop_beyond_lines(out, stacked)
    assert reported[names.NATURAL_FREQUENCY].values.max() < 20.0


def test_the_refit_runs_in_the_first_pass_noise_model():
    """Receptance FRFs whose noise is white in acceleration (accelerometers): the first pass
    fits in acceleration (:mod:`ami_xr.ami.whitening`), and the refit from its own poles
    lands on the same optimum, in the quantity given, with the noise model recorded."""
    truth = _truth([6.0, 11.0, 17.0, 23.0], [0.01, 0.01, 0.01, 0.01])
    f = np.linspace(1, 30, 581)
    ds = ami_xr.simulate.frf(truth, f, references=[2, 5])
    g = ds[names.FRF].transpose(names.REFERENCE, names.POINT, names.FREQUENCY)
    w2 = (2 * np.pi * f) ** 2
    acc = g.values * -w2
    rng = np.random.default_rng(0)
    sd = 0.002 * np.abs(acc).max(axis=-1, keepdims=True)
    e = sd * (rng.standard_normal(acc.shape) + 1j * rng.standard_normal(acc.shape))
    ds = ds.assign({names.FRF: g.copy(data=g.values + e / -w2)})
    first, lam, again = _first_and_refit(ds)
    assert first.attrs["noise_model_quantity"] == "acceleration"
    assert again.attrs["noise_model_quantity"] == "acceleration"
    assert again.attrs[names.ATTR_QUANTITY] == "displacement"
    std = np.abs(first[names.EIGENVALUE_STD].values)
    moved = np.abs(np.sort_complex(again[names.EIGENVALUE].values) - np.sort_complex(lam))
    assert np.all(moved < 0.05 * std)
    # residues come back in the quantity given (receptance): those of the first pass
    a0 = first[names.RESIDUE].transpose(names.POINT, names.MODE).values
    a1 = again[names.RESIDUE].transpose(names.POINT, names.MODE).values
    np.testing.assert_allclose(a1, a0, rtol=1e-3, atol=1e-3 * np.abs(a0).max())


def test_residual_terms_on_exact_frfs_only_when_a_pole_lies_beyond_the_lines():
    """``frf_source="analytic"`` means no residual term ("auto"); a pole fitted beyond the lines
    shows modes outside the band, and the refit then fits the terms; other sources and an
    explicit choice are left as set."""
    truth = _truth([8.0, 15.0], [0.01, 0.01])
    f = np.linspace(2, 20, 91)
    ds = ami_xr.simulate.frf(truth, f, references=[2, 5])
    lam = truth[names.EIGENVALUE].values
    beyond = np.append(lam, -0.2 + 2j * np.pi * 23.0)
    rule = mimo_refit._residual_terms
    assert rule(ds, lam, SETTINGS) is False
    assert rule(ds, beyond, SETTINGS) is True
    measured = ds.assign_attrs({names.ATTR_SOURCE: names.SOURCE_MEASURED})
    assert rule(measured, beyond, SETTINGS) is False  # as set (measured: "auto" fits them)
    assert rule(ds, lam, IdentifySettings(residual_terms=True)) is True


def test_no_tail_pole_is_tried_when_no_pole_is_near_the_last_line(monkeypatch):
    """The band's last pole 12 half-power bandwidths below the last line: what lies above
    reaches the band as a smooth tail, and no refit is spent on a tail pole (issue 41 item 3)."""
    truth = _truth([8.0, 15.0, 17.5, 26.0], [0.01, 0.01, 0.01, 0.01])
    lam = truth[names.EIGENVALUE].values
    f = np.linspace(2, 22, 501)  # 17.5 Hz: (22 - 17.5) / 0.35 = 12.9 bandwidths below
    _, stacked, inband = _start(truth, f, [2, 5], 0.001, 0, lam[:3])
    assert not mimo_refit.near_the_edge(lam[:3], 22.0)
    assert mimo_refit.near_the_edge(lam[:3], 19.0)  # 4.3 bandwidths: tried
    calls = []
    monkeypatch.setattr(mimo_refit, "_trial", lambda *a, **k: calls.append(a))
    out, added = mimo_refit.with_tail_poles(stacked, inband, SETTINGS)
    assert not calls and added.size == 0 and out is inband


def test_the_refit_reports_through_the_one_output_step():
    """The refit's result goes through identify's output step (:func:`pipeline.reported`):
    from the first pass's own poles it carries the first pass's ``under_resolved`` flags and
    widened damping-ratio standard deviations (a mode 2.4 lines wide at 6 Hz), sorted, with the
    quality indicators (before issue 39 its own tail left the resolution check out)."""
    from ami_xr.core import flags as fl

    truth = _truth([6.0, 11.0, 17.0, 23.0], [0.01, 0.01, 0.01, 0.01])
    f = np.linspace(1, 30, 581)
    ds = _noisy(truth, f, [2, 5], 0.002, 0)
    first, lam, again = _first_and_refit(ds)
    under = [
        fl.has(fl.decode(x[names.QUALITY_FLAGS].values), names.FLAG_UNDER_RESOLVED)
        for x in (first, again)
    ]
    assert under[0].any()  # the case holds an under-resolved mode
    np.testing.assert_array_equal(under[1], under[0])
    np.testing.assert_allclose(
        again[names.DAMPING_RATIO_STD].values, first[names.DAMPING_RATIO_STD].values, rtol=0.2
    )
    assert np.all(np.diff(again[names.NATURAL_FREQUENCY].values) >= 0)
    assert names.MPC in again and names.MODE_LABEL_UNSORTED in again


def _frozen_above(rank):
    """A stand-in for ``mimo_refit._frozen``: the refinement's flags, and every pole above 20 Hz
    from the ``rank``-th up (0: all of them) as if frozen at its start."""
    real = mimo_refit._frozen

    def frozen(out):
        got = real(out).copy()
        fn = out[names.NATURAL_FREQUENCY].values
        above = np.flatnonzero(fn > 20.0)
        got[above[np.argsort(fn[above])][rank:]] = True
        return got

    return frozen


def test_a_further_tail_pole_frozen_at_its_start_is_kept_only_when_asked(monkeypatch):
    """Two modes above the lines (21.5 and 23 Hz): the first tail pole places itself; a second
    one the refinement holds at its start (here: made to) is refused by default and kept with
    ``keep_frozen`` (the trial after a kept split), the likelihood supporting it. A first tail
    pole held at its start is refused either way."""
    truth = _truth([8.0, 15.0, 18.5, 21.5, 23.0], [0.01] * 5)
    lam = truth[names.EIGENVALUE].values
    f = np.linspace(2, 20, 451)
    _, stacked, inband = _start(truth, f, [2, 5], 0.001, 0, lam[:3])
    monkeypatch.setattr(mimo_refit, "_frozen", _frozen_above(1))
    got = {}
    for keep in (False, True):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            got[keep] = mimo_refit.with_tail_poles(stacked, inband, SETTINGS, keep_frozen=keep)
    assert got[False][1].size == 1 and got[True][1].size == 2
    assert np.all(got[True][1] > 20.0)
    fn = np.sort(got[True][0][names.NATURAL_FREQUENCY].values)
    assert np.sum(fn > 20.0) == 2 and np.sum(fn <= 20.0) == 3
    monkeypatch.setattr(mimo_refit, "_frozen", _frozen_above(0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out, added = mimo_refit.with_tail_poles(stacked, inband, SETTINGS, keep_frozen=True)
    assert added.size == 0 and out is inband


def _first_and_refit(ds):
    """The stacked first pass of ``ds`` (not final), its poles, and their refit."""
    labels, points = mimo._check(ds)
    stacked = mimo._stacked(ds, labels, points)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        first = ami_xr.ami.pipeline.identify_single(stacked, SETTINGS, final=False)
        lam = first[names.EIGENVALUE].values
        none = np.zeros((stacked.sizes[names.POINT], 0), bool)
        again = mimo_refit.refit(stacked, first, lam, none, SETTINGS)
    return first, lam, again
