"""The paper's benchmark (cantilever beam with three absorbers) against the paper's tables."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError
from ami_xr.simulate import beam_absorbers, benchmark, benchmark_model, state_space_modes
from ami_xr.simulate.beam import (
    AREA,
    LENGTH,
    PAPER_EIGENVALUES,
    PAPER_MODE_VECTORS,
    RHO,
    clamped_free_modes,
    clamped_free_roots,
)

from ..reference import REPO, SUBPROCESS_ENV, frf_from_residues

# np.trapezoid is numpy >= 2.0; np.trapz (removed in numpy 2.x later) is the same rule on 1.24.
trapezoid = getattr(np, "trapezoid", None) or np.trapz

# Tables 1-2 "Analytical" row exactly as printed: (real, decimals), (imag, decimals).
PRINTED = [
    ("-0.45827", "30.551"),
    ("-0.71973", "48.025"),
    ("-0.39311", "65"),
    ("-0.59137", "65.896"),
]


def _as_printed(value: float, printed: str) -> str:
    decimals = len(printed.split(".")[1]) if "." in printed else 0
    return f"{value:.{decimals}f}" if decimals else f"{value:.0f}"


def test_fundamental_beam_frequency():
    b1 = clamped_free_roots(1)[0]
    w1 = b1**2 * np.sqrt(
        ami_xr.simulate.beam.E * ami_xr.simulate.beam.I_AREA / (RHO * AREA * LENGTH**4)
    )
    assert f"{w1:.4f}" == "65.3594"


def test_clamped_free_roots_and_modes():
    b = clamped_free_roots(30)
    # roots of cos b cosh b = -1 found to full precision: the residual is a few ulp of cos b ~ 1
    # (the 1 / cosh term is tiny)
    np.testing.assert_allclose(np.cos(b) + 1 / np.cosh(b), 0.0, atol=1e-14)
    # the textbook value printed to 10 decimals: half a unit in the last digit is 5e-11
    assert b[0] == pytest.approx(1.8751040687, abs=1e-9)
    # the asymptote (j - 1/2) pi differs from the root by ~2 exp(-b) <= 1e-8 from j = 6
    np.testing.assert_allclose(b[5:], (np.arange(6, 31) - 0.5) * np.pi, atol=1e-6)
    # orthogonality and the analytic mass/stiffness integrals used in beam_absorbers
    xi = np.linspace(0, 1, 20001)
    psi = clamped_free_modes(b[:8], xi)
    R = (np.sinh(b[:8]) + np.sin(b[:8])) / (np.cosh(b[:8]) + np.cos(b[:8]))
    gram = trapezoid(psi[:, :, None] * psi[:, None, :], xi, axis=0)
    # the trapezoid rule on 20001 points: error ~h^2 / 12 max|f''| ~ (5e-5)^2 / 12 * b^4 * 4 ~ 1e-6
    # for b ~ 24 (mode 8)
    np.testing.assert_allclose(gram, np.diag(R**2), atol=2e-6)
    # eq. 14 literally, where it is numerically safe, and the clamped end
    direct = (
        np.sin(b[:4] * xi[:, None])
        - np.sinh(b[:4] * xi[:, None])
        - R[:4] * (np.cos(b[:4] * xi[:, None]) - np.cosh(b[:4] * xi[:, None]))
    )
    # eq. 14 literally cancels sinh against cosh (~e^b / 2 ~ 1e4 for b ~ 11): ~1e4 eps absolute; the
    # stable form is exact
    np.testing.assert_allclose(psi[:, :4], direct, atol=1e-10)
    # the clamped end: exactly 0 in exact arithmetic, a few ulp of the O(1) terms in floating point
    np.testing.assert_allclose(psi[0], 0.0, atol=1e-14)
    # stable for many terms: |Psi_j(1)| = 2 R_j (R_j -> 1), no cancellation blow-up
    tip = clamped_free_modes(b, [1.0])[0]
    # the stable form of eq. 14 at xi = 1 against the closed form 2 R_j: a few ulp times the
    # rounding of R_j's hyperbolic terms (1e-9 bounds exp(-b) cancellation in R)
    np.testing.assert_allclose(np.abs(tip[:8]), 2 * R, rtol=1e-9)
    # R_j -> 1 as exp(-b_j) <= 1e-11 for j > 8, so |Psi_j(1)| = 2 to ~1e-11
    np.testing.assert_allclose(np.abs(tip[8:]), 2.0, rtol=1e-9)


def test_tables_1_2_every_printed_digit_with_J1():
    truth = benchmark_model()
    lam = truth[names.EIGENVALUE].values[:4]
    for value, (re, im) in zip(lam, PRINTED, strict=True):
        assert _as_printed(value.real, re) == re
        assert _as_printed(value.imag, im) == _as_printed(float(im), im)
    # the text's rounded natural frequencies and damping ratios
    # the text's rounded values: half a unit in the last printed digit (0.05) plus the text's own
    # rounding of 30.55 to 30.6
    np.testing.assert_allclose(np.abs(lam), [30.6, 48.03, 65.0, 65.90], atol=0.06)
    # the text's damping ratios printed to 3 decimals: half a unit is 5e-4
    np.testing.assert_allclose(-lam.real / np.abs(lam), [0.015, 0.015, 0.006, 0.009], atol=6e-4)


def test_J2_no_longer_matches_the_tables():
    M, C, K, _, _ = beam_absorbers(2)
    lam, _ = state_space_modes(M, C, K)
    assert f"{lam[2].real:.5f}" != "-0.39311"


def test_ritz_series_converges_for_many_terms():
    lams = [state_space_modes(*beam_absorbers(J)[:3])[0][:4] for J in (10, 25, 40)]
    # Ritz convergence, not rounding: the truncation error between J = 25 and 40 terms (measured
    # 3.5e-10)
    np.testing.assert_allclose(lams[1], lams[2], rtol=1e-8)
    # truncation at J = 10 terms (measured 7e-9); both bounds fail if the series stops converging
    np.testing.assert_allclose(lams[0], lams[2], rtol=1e-6)


def _sign_fixed(ours, paper):
    """Ours times the sign (+-1) that best matches the paper's column."""
    s = np.sign(np.real(np.vdot(ours, paper)))
    return s * ours


@pytest.mark.parametrize("mode", [0, 1, 2, 3])
def test_tables_3_6_suspended_masses(mode):
    truth = benchmark_model()
    ours = truth[names.MODE_VECTOR].sel({names.POINT: ["m1", "m2", "m3"]}).values[:, mode]
    paper = PAPER_MODE_VECTORS[1:, mode]
    ours = _sign_fixed(ours, paper)
    # the paper prints 5 significant digits: half a unit in the last is <= 1e-4 relative
    np.testing.assert_allclose(ours, paper, rtol=1e-4)


@pytest.mark.parametrize("mode", [0, 1, 2, 3])
def test_tables_q1_row_is_mass_normalised_ritz_coordinate(mode):
    M, C, K, output, _ = beam_absorbers(1, basis="mass")
    lam, phi = state_space_modes(M, C, K)
    ours = _sign_fixed(phi[:, mode], PAPER_MODE_VECTORS[:, mode])
    # the paper prints 5 significant digits: half a unit in the last is <= 1e-4 relative
    np.testing.assert_allclose(ours, PAPER_MODE_VECTORS[:, mode], rtol=1e-4)
    # ... and NOT the tip displacement: tip = 0.41345 * q1 in that basis
    truth = benchmark_model()
    tip = _sign_fixed(
        truth[names.MODE_VECTOR].sel({names.POINT: "tip"}).values[mode : mode + 1],
        PAPER_MODE_VECTORS[:1, mode],
    )
    # the paper's 5 significant digits, as above
    np.testing.assert_allclose(tip / PAPER_MODE_VECTORS[0, mode], output[0, 0], rtol=1e-4)
    # 0.41345 printed to 5 decimals: half a unit is 5e-6, and the tip factor is read off a ratio of
    # printed values
    assert output[0, 0] == pytest.approx(0.41345, abs=2e-5)


def test_bases_give_the_same_measured_model():
    a = benchmark_model()
    M, C, K, output, labels = beam_absorbers(1, basis="mass")
    b = ami_xr.simulate.modal_model(M, C, K, output=output, point_labels=labels, drive_point="tip")
    # two Ritz bases of the same model: eigen-decompositions of similar matrices agree to ~cond *
    # eps (measured 2e-16)
    np.testing.assert_allclose(a[names.EIGENVALUE], b[names.EIGENVALUE], rtol=1e-12)
    # residues go through the eigenvectors, whose conditioning (close modes 3 and 4) amplifies
    # rounding; measured 6e-15 of the largest, atol for the smallest (~5e-8)
    np.testing.assert_allclose(a[names.RESIDUE], b[names.RESIDUE], rtol=1e-9, atol=1e-15)


def test_paper_eigenvalue_constants():
    assert PAPER_EIGENVALUES[2] == -0.39311 + 65j


def test_benchmark_datasets(paper_benchmark_noisy, paper_benchmark_clean):
    ts, g, truth = paper_benchmark_noisy  # benchmark(): 15 % noise, seed 0
    ami_xr.validate(ts)
    ami_xr.validate(g)
    assert list(ts[names.POINT].values) == ["tip", "m1", "m2", "m3"]
    assert ts.attrs[names.ATTR_DRIVE_POINT] == "tip" == g.attrs[names.ATTR_DRIVE_POINT]
    assert ts.sizes[names.TIME] == 4096 and g.sizes[names.FREQUENCY] == 2049
    dt = 60.0 / 4096
    assert g.attrs[names.ATTR_DT] == dt and g.attrs[names.ATTR_NSAMPLES] == 4096
    assert g.attrs[names.ATTR_SOURCE] == names.SOURCE_IMPULSE
    # differences of k / 60: a few ulp of 34 Hz (~1e-14 absolute), inside the default rtol 1e-7; a
    # wrong record length is off by O(1)
    np.testing.assert_allclose(np.diff(g[names.FREQUENCY].values), 1 / 60.0)
    # the paper: frequency step 0.1047 rad/s, Nyquist 214 rad/s
    assert f"{2 * np.pi / 60:.4f}" == "0.1047"
    assert f"{np.pi / dt:.0f}" == "214"
    want = dt * np.fft.rfft(ts[names.RESPONSE].values)
    # the same real FFT of the same samples (another implementation or batch may round differently):
    # norm-wise error ~eps log2(n) = 3e-15 of the largest line (measured 2e-16); rtol=0, since the
    # default rtol would make this an elementwise 1e-7 check
    np.testing.assert_allclose(g[names.FRF].values, want, rtol=0, atol=1e-13 * np.abs(want).max())
    assert truth.sizes[names.MODE] == 4 and truth.attrs[names.ATTR_DRIVE_POINT] == "tip"
    # the noise is eq. 15 with alpha = 0.15 per channel
    clean, gclean, _ = paper_benchmark_clean
    y = clean[names.RESPONSE].values
    r = (ts[names.RESPONSE].values - y) / (0.15 * np.abs(y).max(axis=-1, keepdims=True))
    assert np.all(np.abs(r) <= 1) and r.max() > 0.99
    # reproducible; another seed differs
    # reproducible: the same seed, the same computation, bit-identical
    np.testing.assert_array_equal(benchmark()[0][names.RESPONSE].values, ts[names.RESPONSE].values)
    assert not np.array_equal(
        benchmark(seed=1)[0][names.RESPONSE].values, ts[names.RESPONSE].values
    )
    # noise-free FRF = the exact discrete-time modal model of the truth
    omega = 2 * np.pi * gclean[names.FREQUENCY].values
    A, lam = truth[names.RESIDUE].values, truth[names.EIGENVALUE].values
    ref = frf_from_residues(omega, lam, A, dt, 4096)
    np.testing.assert_allclose(
        # FFT of 4096 samples vs the closed-form sum, relative to the peak (the FRFs have
        # antiresonances): ~eps log2(n) times the geometric sum's cancellation (~1e2)
        gclean[names.FRF].values,
        ref,
        rtol=0,
        atol=1e-12 * np.abs(ref).max(),
    )


def test_benchmark_bad_input():
    with pytest.raises(AmiXrValueError, match="J"):
        beam_absorbers(0)
    with pytest.raises(AmiXrValueError, match="basis"):
        beam_absorbers(1, basis="unit")
    with pytest.raises(AmiXrValueError, match="alpha"):
        benchmark(noise=-1)
    with pytest.raises(AmiXrValueError, match="time"):
        benchmark(n_samples=1)
    with pytest.raises(AmiXrValueError, match="kind"):
        benchmark(noise=0.0, kind="pink")


SAMPLE_FILES = (
    "benchmark_impulse.nc",
    "benchmark_frf.nc",
    "benchmark_impulse_clean.nc",
    "benchmark_frf_clean.nc",
    "benchmark_truth.nc",
)


def _sample_data_script():
    """scripts/make_sample_data.py as a module (loaded from its path: no sys.path edits)."""
    spec = importlib.util.spec_from_file_location(
        "make_sample_data", REPO / "scripts" / "make_sample_data.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_sample_data_regenerate_to_rounding(tmp_path, sample_benchmark_frf):
    committed = REPO / "sample_data"
    if not all((committed / f).exists() for f in SAMPLE_FILES):
        pytest.skip("sample_data/ not generated in this checkout")
    # the script's --check: regenerate, compare norm-wise to RTOL (justified in the script)
    run = subprocess.run(
        [sys.executable, str(REPO / "scripts" / "make_sample_data.py"), "--check"],
        capture_output=True,
        text=True,
        env=SUBPROCESS_ENV,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "agree with this code" in run.stdout
    for name in SAMPLE_FILES:
        assert (committed / name).stat().st_size < 2_000_000
    ami_xr.validate(sample_benchmark_frf)
    assert sample_benchmark_frf.attrs["noise_level"] == 0.15


def test_sample_data_check_catches_a_change(tmp_path):
    script = _sample_data_script()
    assert set(script.FILES) == set(SAMPLE_FILES)
    fresh, changed = tmp_path / "fresh", tmp_path / "changed"
    script.write_sample_data(fresh)
    script.write_sample_data(changed)
    assert script.compare(fresh, changed) == []
    # a relative change of 1e-8 in one FRF line is far above rounding and must be reported
    g = ami_xr.open_dataset(changed / "benchmark_frf.nc")
    frf = g[names.FRF].values.copy()
    frf[1, 100] *= 1 + 1e-8 * np.max(np.abs(frf)) / np.abs(frf[1, 100])
    ami_xr.to_netcdf(
        g.assign({names.FRF: g[names.FRF].copy(data=frf)}), changed / "benchmark_frf.nc"
    )
    problems = script.compare(fresh, changed)
    assert len(problems) == 1 and "benchmark_frf.nc: frf" in problems[0]
    (changed / "benchmark_truth.nc").unlink()
    assert any("benchmark_truth.nc: missing" in p for p in script.compare(fresh, changed))


@pytest.mark.parametrize("J", [1, 4])
def test_benchmark_frf_is_direct_solution_at_measured_points(J):
    M, C, K, output, labels = beam_absorbers(J)
    truth = benchmark_model(J)
    assert truth.sizes[names.MODE] == J + 3
    f = np.linspace(0.0, 34.0, 400)
    g = ami_xr.simulate.frf(truth, f)
    # tip force acts on the Ritz coordinates through Psi_j(L); measured y = output @ q
    direct = np.array(
        [output @ np.linalg.solve(K - w**2 * M + 1j * w * C, output[0]) for w in 2 * np.pi * f]
    ).T
    np.testing.assert_allclose(
        # eq. 4 from one eigen-decomposition vs dense solves: ~cond(eigenvectors) * eps of the
        # largest value (close modes 3-4: cond ~1e3-1e5)
        g[names.FRF].values,
        direct,
        rtol=1e-10,
        atol=1e-10 * np.abs(direct).max(),
    )
    assert list(g[names.POINT].values) == list(labels)
