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


def test_line_noise_std_needs_a_simulated_frf():
    g, truth = ami_xr.simulate.random_system(5, seed=1, n_frequencies=64)
    with pytest.raises(AmiXrValueError, match="frf"):
        line_noise_std(g.assign_attrs({names.ATTR_SOURCE: "estimated"}), truth)


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


# --- clustered systems and the overlap cases (issue 20, item 5) ------------------------------
from ami_xr.simulate import cluster as sc  # noqa: E402
from ami_xr.simulate.catalogue import (  # noqa: E402
    CLUSTER_COMBINATIONS,
    ClusterCase,
    cluster_catalogue,
)


def test_overlap_factor_is_bandwidth_over_spacing():
    lam = np.array([-0.5 + 100j, -1.0 + 102j, -0.1 + 200j])
    # mode 1: 2 * 0.5 / 2; mode 2: 2 * 1 / 2; mode 3: 0.2 / 98
    np.testing.assert_allclose(sc.overlap_factor(lam), [0.5, 1.0, 0.2 / 98], rtol=1e-14)
    assert sc.overlap_factor(np.array([-1.0 + 10j]))[0] == 0.0
    with pytest.raises(AmiXrValueError, match="truth"):
        sc.overlap_factor(np.array([np.nan + 1j]))


def test_layout_places_clusters_at_the_asked_overlap():
    rng = np.random.default_rng(4)
    w, zeta, cl = sc._layout([3, 4], 3, 0.7, (0.02, 0.08), (0.01, 0.03), rng)
    assert w.size == zeta.size == cl.size == 10 and w[-1] == 1.0 and np.all(np.diff(w) > 0)
    assert sorted(np.bincount(cl)[1:]) == [3, 4] and np.sum(cl == 0) == 3
    for c in (1, 2):
        k = np.flatnonzero(cl == c)
        assert np.all(np.diff(k) == 1)  # a cluster is consecutive in frequency
        assert np.all((zeta[k] >= 0.02) & (zeta[k] <= 0.08))
        # undamped spacing: (zeta_i + zeta_j) / overlap, i.e. mean bandwidth / spacing = 0.7
        ratio = w[k[1:]] / w[k[:-1]] - 1
        np.testing.assert_allclose(ratio, (zeta[k[1:]] + zeta[k[:-1]]) / 0.7, rtol=1e-12)
    # blocks are separated: edge modes overlap at most GAP_OVERLAP
    edges = np.flatnonzero(np.diff(cl) != 0) + 1
    for e in edges:
        gap = w[e] / w[e - 1] - 1
        assert gap >= 2 * max(zeta[e], zeta[e - 1]) / sc.GAP_OVERLAP - 1e-12


def test_matrices_have_the_designed_modes_and_non_proportional_damping():
    rng = np.random.default_rng(0)
    w = np.array([1.0, 1.05, 1.1, 1.6, 2.5])
    zeta = np.array([0.05, 0.06, 0.04, 0.02, 0.01])
    M, C, K = sc._matrices(w, zeta, 0.3, rng)
    # undamped: K phi = w^2 M phi
    assert np.allclose(np.sort(np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real)), w)
    assert np.linalg.eigvalsh(C).min() > 0
    # non-proportional: C does not commute with M^-1 K
    a, b = np.linalg.solve(M, C), np.linalg.solve(M, K)
    assert np.linalg.norm(a @ b - b @ a) > 1e-3 * np.linalg.norm(a) * np.linalg.norm(b)
    lam, _ = ami_xr.simulate.state_space_modes(M, C, K)
    # without coupling the eigenvalues would be -zeta w + i w sqrt(1 - zeta^2); with it they
    # move, but stay underdamped and near the design
    assert np.all(np.abs(np.abs(lam) - w) < 0.05 * w)


@pytest.mark.parametrize("source", ["analytic", "impulse_response"])
def test_clustered_system_truth_and_frfs(source):
    frf, truth = ami_xr.simulate.clustered_system(
        6, cluster_sizes=(4,), overlap=1.4, seed=2, source=source, n_frequencies=2048
    )
    assert truth.sizes[names.MODE] == 6 and frf.sizes[names.POINT] == 6
    assert frf.attrs[names.ATTR_SOURCE] == source
    cl = truth[sc.CLUSTER].values
    assert np.sum(cl == 1) == 4 and np.sum(cl == 0) == 2
    ov = truth[sc.OVERLAP].values
    np.testing.assert_array_equal(ov, sc.overlap_factor(truth[names.EIGENVALUE].values))
    assert np.all(ov[cl == 1] > 0.7) and np.all(ov[cl == 0] < 0.5)
    zeta = truth[names.DAMPING_RATIO].values[cl == 1]
    assert np.all((zeta > 0.015) & (zeta < 0.09))  # 2-8 %, moved a little by the coupling
    # complex modes (non-proportional damping): residues far from a common phase
    phi = truth[names.MODE_VECTOR].values[:, cl == 1]
    mpc = np.abs(np.sum(phi**2, axis=0)) / np.sum(np.abs(phi) ** 2, axis=0)
    assert np.min(mpc) < 0.99
    # the FRF is the truth's modal sum (analytic exactly; FFT of impulse responses: to the
    # aliasing of the sampled response, small below half the Nyquist frequency)
    f = frf[names.FREQUENCY].values
    exact = ami_xr.simulate.frf(truth, f)[names.FRF].values
    got = frf[names.FRF].values
    low = (f > 0) & (f < 0.5 * f[-1])
    err = np.abs(got - exact)[:, low].max() / np.abs(exact).max()
    assert err < (1e-12 if source == "analytic" else 2e-2)
    again, truth2 = ami_xr.simulate.clustered_system(
        6, cluster_sizes=(4,), overlap=1.4, seed=2, source=source, n_frequencies=2048
    )
    xr.testing.assert_equal(again[names.FRF], frf[names.FRF])


def test_clustered_system_bad_arguments():
    with pytest.raises(AmiXrValueError, match="cluster_sizes"):
        ami_xr.simulate.clustered_system(5, cluster_sizes=(1,))
    with pytest.raises(AmiXrValueError, match="overlap"):
        ami_xr.simulate.clustered_system(5, overlap=0.0)
    with pytest.raises(AmiXrValueError, match="n_modes"):
        ami_xr.simulate.clustered_system(5, cluster_sizes=(4, 4), n_modes=6)
    with pytest.raises(AmiXrValueError, match="non_proportional"):
        ami_xr.simulate.clustered_system(5, non_proportional=2.0)
    with pytest.raises(AmiXrValueError, match="cluster_damping"):
        ami_xr.simulate.clustered_system(5, cluster_damping=(0.1, 0.05))


def test_line_noise_std_of_fft_impulse_responses_is_measured():
    """sigma_j = alpha max|h_j| dt sqrt(N / 3) for uniform eq. 15 noise: the spread of the noisy
    minus the clean FRF over the lines and a few seeds agrees within a few percent."""
    frf0, truth = ami_xr.simulate.clustered_system(
        5, overlap=0.7, seed=1, source="impulse_response"
    )
    diffs = []
    for seed in (1, 2, 3):
        noisy, _ = ami_xr.simulate.clustered_system(
            5, overlap=0.7, seed=1, source="impulse_response", noise=0.05
        )
        # the noise seed is drawn from the system seed: vary it by hand
        noisy = noisy.copy()
        rng = np.random.default_rng(seed)
        if seed > 1:
            ts = ami_xr.simulate.impulse_response(
                truth,
                (
                    noisy.attrs["record_samples"] * noisy.attrs["sample_interval"],
                    noisy.attrs["record_samples"],
                ),
            )
            ts = ami_xr.simulate.add_noise(ts, 0.05, rng=rng)
            noisy = ami_xr.simulate.frf_from_impulse(ts)
            noisy.attrs.update({"noise_level": 0.05, "noise_kind": "uniform"})
        diffs.append((noisy[names.FRF] - frf0[names.FRF]).values)
    noisy.attrs[names.ATTR_SOURCE] = "impulse_response"
    sigma = line_noise_std(noisy, truth).values
    measured = np.sqrt(np.mean(np.abs(np.concatenate(diffs, axis=1)[:, 1:-1]) ** 2, axis=1))
    np.testing.assert_allclose(measured, sigma, rtol=0.05)


def test_cluster_catalogue_is_deterministic_and_covers_every_combination():
    cases = cluster_catalogue()
    assert (
        len(cases) == 32 and cases == cluster_catalogue(32, 0) and cases != cluster_catalogue(32, 1)
    )
    assert all(isinstance(c, ClusterCase) for c in cases)
    assert {(c.source, c.overlap, c.noise) for c in cases} == set(CLUSTER_COMBINATIONS)
    assert len({c.name for c in cases}) == 32
    assert {c.cluster_sizes for c in cases} >= {(3,), (4,)}
    for c in cases:
        assert 5 <= c.n_points <= c.n_modes and c.n_modes >= sum(c.cluster_sizes) + 2
    frf, truth = cases[29].build()  # impulse response, overlap 1.4, 1 % noise
    assert frf.attrs[names.ATTR_SOURCE] == "impulse_response" and frf.attrs["noise_level"] == 0.01
    assert np.max(truth[sc.OVERLAP].values) > 1.0
