"""Several references in one pass (issue 41): the single-reference pipeline runs once, on the
stacked FRFs, and each reference is only screened against the stacked model (what it sees that
the stacked model misses is proposed and tested on its own FRFs)."""

from __future__ import annotations

import warnings

import numpy as np

import ami_xr
from ami_xr import names
from ami_xr.ami import mimo, mimo_refit, mimo_screen
from ami_xr.ami import pipeline as pl
from ami_xr.ami.settings import IdentifySettings
from ami_xr.ami.subtract import band_of
from ami_xr.simulate import modal

from ..reference import damped_chain

POINTS = [1, 2, 3, 4, 5]


def _noisy_chain(refs, level=0.01, seed=0):
    truth = damped_chain(POINTS)
    ds = modal.frf(truth, np.linspace(0.0, 120.0, 1200), references=refs)
    g = ds[names.FRF]
    rng = np.random.default_rng(seed)
    re = ami_xr.simulate.add_noise(g.real, level, rng=rng, dim=names.FREQUENCY)
    im = ami_xr.simulate.add_noise(g.imag, level, rng=rng, dim=names.FREQUENCY)
    return truth, ds.assign({names.FRF: (re + 1j * im).assign_attrs(g.attrs)})


def test_three_references_run_the_pipeline_once(monkeypatch):
    """The phases (subtract, isolate, global fit, refinement with its order tests) run once for
    three references, not once stacked and once per reference."""
    truth, ds = _noisy_chain([1, 3, 4])
    runs = []
    phases = pl._phases

    def counting(work, *args, **kwargs):
        runs.append(work.sizes[names.POINT])
        return phases(work, *args, **kwargs)

    monkeypatch.setattr(pl, "_phases", counting)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = ami_xr.identify(ds)
    assert runs == [3 * len(POINTS)]
    assert ami_xr.simulate.score_modes(out, truth).n_found == truth.sizes[names.MODE]


def _stacked_without(ds, drop: int):
    """The stacked FRFs and the stacked pipeline's result with mode ``drop`` left out."""
    from ami_xr.ami import common as c

    refs, points = mimo._check(ds)
    stacked = mimo._stacked(ds, refs, points)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        full = mimo.identify_single(stacked, IdentifySettings(), final=False)
    keep = [k for k in range(full.sizes[names.MODE]) if k != drop]
    return refs, stacked, full, c.select_modes(full, keep)


def test_a_mode_the_stacked_model_misses_is_proposed_by_a_reference():
    truth, ds = _noisy_chain([1, 4])
    refs, stacked, full, missing = _stacked_without(ds, 2)
    lam = mimo_refit._measured_poles(stacked, missing)
    band = band_of(stacked, None, None, "identify")
    got = mimo_screen.proposals(band, lam, len(refs))
    true = truth[names.EIGENVALUE].values[2]
    assert len(got) == 1
    assert abs(got[0].lam - true) < abs(true.real)  # within half the half-power bandwidth
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        settings = IdentifySettings()
        out, added = mimo_refit.with_reference_proposals(stacked, missing, len(refs), settings)
    assert added.size == 1
    # every mode within half its half-power bandwidth (1 % noise), none more
    assert out.sizes[names.MODE] == truth.sizes[names.MODE]
    assert ami_xr.simulate.score_modes(out, truth).n_found == truth.sizes[names.MODE]
    # nothing missed: no proposal, the stacked result returned as it is
    lam = mimo_refit._measured_poles(stacked, full)
    assert mimo_screen.proposals(band, lam, len(refs)) == []


def test_a_pole_the_noisier_reference_alone_reports_at_the_band_edge_is_refused():
    """Two references with opposite noise shapes, one ten times noisier (the case of
    scripts/benchmark_noise_groups.py): where reference b's noise is 300 times a's, at the
    band's lower edge, its own pipeline reported a pole (about 2.3 Hz) that joined the union
    unchecked; screened with its own noise shape against the stacked model, it is not
    proposed, and the three modes alone are reported."""
    import runpy

    import xarray as xr

    from ..reference import REPO

    case = runpy.run_path(str(REPO / "scripts" / "benchmark_noise_groups.py"), run_name="case")
    res, sd, group = case["_system"]()
    n_point, freq, lam = case["N_POINT"], case["FREQ"], case["LAM"]
    shape = (2, n_point, freq.size)
    dims = (names.REFERENCE, names.POINT, names.FREQUENCY)
    for seed in (1, 2):  # both reported the edge pole before
        flat = case["_dataset"](res, sd, group, seed, False)
        ds = xr.Dataset(
            {
                names.FRF: (dims, flat[names.FRF].values.reshape(shape)),
                names.FRF_LINE_NOISE_STD: (dims, sd.reshape(shape)),
            },
            coords={
                names.REFERENCE: [101, 102],
                names.POINT: list(range(1, n_point + 1)),
                names.FREQUENCY: freq,
            },
            attrs={names.ATTR_SOURCE: names.SOURCE_ANALYTIC},
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = ami_xr.identify(ds)
        fn = np.sort(out[names.NATURAL_FREQUENCY].values)
        np.testing.assert_allclose(fn, np.sort(np.abs(lam)) / (2 * np.pi), rtol=1e-3)
        assert out.attrs[mimo.ATTR_UNION_ADDED] == ""
