"""Issue 22: more references never find fewer modes; one reference's band-rank statistic; the
multi-reference Cramér-Rao bound."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.ami import mimo
from ami_xr.core import mimo as cm
from ami_xr.errors import AmiXrValueError
from ami_xr.io.datasets import select_reference
from ami_xr.simulate import modal

from ..reference import damped_chain

POINTS = [1, 2, 3, 4, 5]


def _chain():
    return damped_chain(POINTS)


# a pole the stacked detection missed, added from a reference's proposal:
# tests/ami/test_mimo_onepass.py (each reference is screened, not identified alone)


@pytest.mark.parametrize("seed", [0])
def test_all_references_find_at_least_the_best_single_reference(seed):
    """The symmetric ring at 5 % noise, references 2, 3, 4 (stacked detection alone found
    fewer modes than two references on some seeds)."""
    truth = ami_xr.simulate.symmetric_structure(0.0)
    f = np.linspace(0.05, 50.0, 1000)
    ds = ami_xr.simulate.frf(truth, f, references=[2, 3, 4])
    rng = np.random.default_rng(1000 * seed + 500)
    g = ds[names.FRF]
    re = ami_xr.simulate.add_noise(g.real, 0.05, rng=rng, dim="frequency")
    im = ami_xr.simulate.add_noise(g.imag, 0.05, rng=rng, dim="frequency")
    ds = ds.assign({names.FRF: (re + 1j * im).assign_attrs(g.attrs)})
    found = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for refs in ([2], [3], [4], [2, 3, 4]):
            out = ami_xr.identify(ds.sel(reference=refs))
            found[tuple(refs)] = ami_xr.simulate.score_modes(out, truth).n_found
    assert found[(2, 3, 4)] >= max(found[(2,)], found[(3,)], found[(4,)])
    assert mimo.ATTR_UNION_ADDED in out.attrs


def _band_data(split: float, noise: float, seed: int = 0):
    """Two poles (split relative to |Re lam|) with different shapes, or one pole (split 0)."""
    rng = np.random.default_rng(seed)
    omega = np.linspace(90.0, 110.0, 401)
    lam1 = -1.0 + 100j
    lam2 = lam1 + 1j * split
    a1 = np.array([1.0, 0.5, -0.3, 0.8, 0.2, -0.6]) * 1j
    a2 = np.array([0.2, -0.7, 0.9, 0.1, -0.5, 0.4]) * 1j
    b1 = 1 / (1j * omega - lam1)
    b2 = 1 / (1j * omega - lam2)
    data = np.outer(a1, b1) + (np.outer(a2, b2) if split else 0)
    e = (rng.standard_normal(data.shape) + 1j * rng.standard_normal(data.shape)) / np.sqrt(2)
    data = data + noise * e
    # the one-pole fit: least-squares residues on b1 (what a refinement reporting one mode has)
    res = data @ np.conj(b1) / np.vdot(b1, b1)
    residual = data - np.outer(res, b1)
    use = (np.abs(omega - lam1.imag) <= 2.0)[None, :]
    return residual, np.full(6, noise), b1[None, :], res[:, None], use


def test_band_rank_tells_two_close_poles_from_one():
    from ami_xr.ami.repeated import suspected

    one = cm.band_rank(*_band_data(0.0, 1e-3))
    two = cm.band_rank(*_band_data(0.3, 1e-3))
    assert one[1][0] < 1.5 and not suspected(*one)[0]
    assert two[1][0] > 10 and suspected(*two)[0]
    # split well below the noise: not flagged
    assert not suspected(*cm.band_rank(*_band_data(0.3, 1.0)))[0]


def test_multi_reference_bound_with_one_reference_is_the_simo_bound():
    truth = _chain()
    f = np.linspace(0.0, 120.0, 1200)
    multi = modal.frf(truth, f, references=[4])
    simo = select_reference(multi, 4)
    b_multi = ami_xr.cramer_rao_bound(truth, multi, frf_noise_std=1e-7)
    t_simo = modal.residues(truth, 4)
    b_simo = ami_xr.cramer_rao_bound(t_simo, simo, frf_noise_std=1e-7)
    np.testing.assert_allclose(
        b_multi[names.NATURAL_FREQUENCY_STD].values,
        b_simo[names.NATURAL_FREQUENCY_STD].values,
        rtol=1e-6,
    )
    assert b_multi[names.RESIDUE_STD].dims == (names.REFERENCE, names.POINT, names.MODE)
    # two references: every pole's bound is at most the one-reference bound
    two = ami_xr.cramer_rao_bound(truth, modal.frf(truth, f, references=[1, 4]), frf_noise_std=1e-7)
    assert np.all(
        two[names.NATURAL_FREQUENCY_STD].values
        <= b_multi[names.NATURAL_FREQUENCY_STD].values * (1 + 1e-9)
    )


def test_multi_reference_bound_of_a_repeated_root_and_its_errors():
    truth = ami_xr.simulate.symmetric_structure(0.0)
    ds = ami_xr.simulate.frf(truth, np.linspace(0.05, 50.0, 1000), references=[2, 3])
    b = ami_xr.cramer_rao_bound(truth, ds, frf_noise_std=1e-6)
    rep = b["repeated_pole"].values
    assert rep.sum() == 4  # both pairs
    fn_std = b[names.NATURAL_FREQUENCY_STD].values
    assert np.all(np.isfinite(fn_std)) and np.all(fn_std > 0)
    with pytest.raises(AmiXrValueError, match="mode_vector"):
        ami_xr.cramer_rao_bound(truth.drop_vars(names.MODE_VECTOR), ds, frf_noise_std=1e-6)
