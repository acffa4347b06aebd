"""The benchmark catalogue (issue 10, item 7) and the scoring of identified modes."""

from __future__ import annotations

from itertools import product

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.simulate.catalogue import (
    NOISE_LEVELS,
    CatalogueCase,
    identifiable,
    line_noise_std,
    peak_snr,
    score_modes,
)

TRUE = np.array([-0.5 + 20j, -1.0 + 50j, -2.0 + 90j])


def test_catalogue_is_deterministic_and_covers_every_combination():
    cases = ami_xr.simulate.catalogue()
    assert len(cases) >= 32
    assert cases == ami_xr.simulate.catalogue(32, seed=0)
    assert cases != ami_xr.simulate.catalogue(32, seed=1)
    assert all(isinstance(c, CatalogueCase) for c in cases)
    combos = {(c.topology, c.closely_spaced, c.weak_mode, c.noise) for c in cases}
    wanted = set(product(("chain", "grid"), (False, True), (False, True), (0.0, 0.01, 0.05, 0.15)))
    assert combos == wanted and set(NOISE_LEVELS) == {0.0, 0.01, 0.05, 0.15}
    assert len({c.name for c in cases}) == len(cases)
    for c in cases:
        assert 5 <= c.n_points <= c.n_modes <= 12
    # more cases repeat the combinations with new systems
    more = ami_xr.simulate.catalogue(40)
    assert more[:32] == cases and (more[32].topology, more[32].noise) == ("chain", 0.0)


@pytest.mark.parametrize("bad", [{"n_cases": 0}, {"n_cases": 2.5}, {"seed": -1}])
def test_catalogue_bad_input(bad):
    with pytest.raises(AmiXrValueError, match=next(iter(bad))):
        ami_xr.simulate.catalogue(**bad)


def test_case_builds_its_random_system():
    case = next(c for c in ami_xr.simulate.catalogue() if c.closely_spaced and c.weak_mode)
    g, truth = case.build(n_frequencies=64)
    assert g.sizes[names.POINT] == case.n_points and truth.sizes[names.MODE] == case.n_modes
    assert "closely_spaced_pair" in truth.attrs and "weak_mode" in truth.attrs
    assert g.attrs.get("noise_level", 0.0) == case.noise


def test_line_noise_std_matches_the_added_noise_and_identifiable():
    g, truth = ami_xr.simulate.random_system(6, noise=0.05, seed=3, n_frequencies=4096)
    clean, _ = ami_xr.simulate.random_system(6, seed=3, n_frequencies=4096)
    sigma = line_noise_std(g, truth)
    e = (g[names.FRF] - clean[names.FRF]).values
    measured = np.sqrt(np.mean(np.abs(e) ** 2, axis=1))
    np.testing.assert_allclose(sigma.values, measured, rtol=0.05)  # 4096 draws per point
    snr = peak_snr(truth, sigma)
    ok = identifiable(truth, sigma)
    np.testing.assert_array_equal(ok, (snr >= 10 ** (6 / 20)).any(names.POINT).values)
    assert identifiable(truth, sigma, snr_db=-200.0).all()
    assert not identifiable(truth, sigma, snr_db=200.0).any()
    # no noise: every mode is identifiable
    assert (line_noise_std(clean, truth) == 0).all() and identifiable(truth, 0 * sigma).all()


def test_line_noise_std_needs_an_analytic_frf():
    g, truth = ami_xr.simulate.random_system(5, seed=1, n_frequencies=64)
    with pytest.raises(AmiXrValueError, match="frf"):
        line_noise_std(g.assign_attrs({names.ATTR_SOURCE: names.SOURCE_IMPULSE}), truth)


def test_score_exact_match():
    s = score_modes(TRUE[::-1], TRUE)
    assert (s.n_true, s.n_found, s.n_spurious) == (3, 3, 0)
    np.testing.assert_array_equal(s.true_index, [0, 1, 2])
    np.testing.assert_array_equal(s.identified_index, [2, 1, 0])
    assert np.all(s.frequency_error == 0) and np.all(s.damping_error == 0)
    assert np.all(np.isnan(s.frequency_over_crb))


def test_score_spurious_and_missed_modes():
    # a fourth mode far from all: spurious; and the conjugate of a true one still matches
    s = score_modes([TRUE[0], np.conj(TRUE[1]), TRUE[2], -1 + 70j], TRUE)
    assert (s.n_found, s.n_spurious) == (3, 1) and list(s.spurious) == [3]
    # mode 2 missing: one just outside the tolerance (|Re lam| = 1) does not count
    s = score_modes([TRUE[0], TRUE[1] + 1.01, TRUE[2]], TRUE)
    assert list(s.found) == [True, False, True] and list(s.spurious) == [1]
    s = score_modes([TRUE[0], TRUE[1] + 0.99j, TRUE[2]], TRUE)
    assert s.found.all()
    s = score_modes([TRUE[0], TRUE[1] + 1.01, TRUE[2]], TRUE, tolerance=1.1)
    assert s.found.all()
    # NaN eigenvalues and no identified modes at all
    s = score_modes([np.nan + 0j, TRUE[0]], TRUE)
    assert s.n_found == 1 and list(s.spurious) == [0]
    s = score_modes(np.array([], complex), TRUE)
    assert (s.n_found, s.n_spurious, s.true_index.size) == (0, 0, 0)


def test_score_is_one_to_one_nearest_first():
    # two identified modes near true mode 2; the nearer is the match, the other is spurious
    ident = [TRUE[1] + 0.6j, TRUE[1] - 0.2, TRUE[0], TRUE[2]]
    s = score_modes(ident, TRUE)
    assert s.n_found == 3 and list(s.spurious) == [0]
    assert s.identified_index[s.true_index == 1].item() == 1
    # a close true pair and two identified modes: each goes to its own true mode
    pair = np.array([-1.0 + 50j, -1.0 + 51.5j])
    s = score_modes([pair[1] - 0.1j, pair[0] + 0.9j], pair)
    assert s.found.all() and s.n_spurious == 0
    np.testing.assert_array_equal(s.identified_index, [1, 0])


def test_score_errors_relative_and_over_the_bound():
    truth = xr.Dataset({names.EIGENVALUE: ((names.MODE,), TRUE)}, coords={names.MODE: [1, 2, 3]})
    lam = TRUE.copy()
    fn, zeta = np.abs(lam) / (2 * np.pi), -lam.real / np.abs(lam)
    new_fn, new_zeta = fn * (1 + 1e-3), zeta * (1 - 2e-2)
    wn = 2 * np.pi * new_fn
    ident = xr.Dataset(
        {names.EIGENVALUE: ((names.MODE,), -new_zeta * wn + 1j * wn * np.sqrt(1 - new_zeta**2))}
    )
    crb = xr.Dataset(
        {
            names.NATURAL_FREQUENCY_STD: ((names.MODE,), fn * 1e-3 / 2),
            names.DAMPING_RATIO_STD: ((names.MODE,), zeta * 2e-2 / 4),
        }
    )
    s = score_modes(ident, truth, crb=crb)
    np.testing.assert_allclose(s.frequency_error, 1e-3, rtol=1e-9)
    np.testing.assert_allclose(s.damping_error, 2e-2, rtol=1e-9)
    np.testing.assert_allclose(s.frequency_over_crb, 2.0, rtol=1e-9)
    np.testing.assert_allclose(s.damping_over_crb, 4.0, rtol=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"identified": np.zeros((2, 2))}, "identified"),
        ({"identified": xr.Dataset()}, "identified"),
        ({"truth": [1 + 2j]}, "truth"),
        ({"tolerance": 0}, "tolerance"),
        ({"crb": xr.Dataset()}, "crb"),
    ],
)
def test_score_bad_input(kwargs, match):
    args = {"identified": TRUE, "truth": TRUE, **kwargs}
    with pytest.raises(AmiXrValueError, match=match):
        score_modes(args.pop("identified"), args.pop("truth"), **args)
