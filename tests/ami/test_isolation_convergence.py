"""SIMO isolation stops by a reachable rule: the benchmark converges, a weak mode beside a strong
one does not make the model-order check cycle (issue 10 item 5, issue 11 item 2)."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.errors import ConvergenceWarning

from ..reference import SHARED_DATA, frf_from_residues

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"


def test_benchmark_isolation_converges(paper_benchmark_noisy):
    g = paper_benchmark_noisy[1]
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConvergenceWarning)
        iso = ami_xr.isolate(ami_xr.subtract(g))
    assert bool(iso[names.ISO_CONVERGED].values.all())
    assert iso.sizes[names.MODE] == 4


def test_weak_mode_beside_strong_does_not_cycle():
    """bench_peers system 3 (38 points, 8 modes, 3 % noise): the mode at 1628 Hz beside the one
    at 1714 used to be added, merged away and added again until the restart budget ran out
    (1153 sweeps, the last mode never isolated)."""
    sys.path.insert(0, str(SCRIPTS))
    try:
        import bench_peers as bp
    finally:
        sys.path.remove(str(SCRIPTS))
    frf, lam_true = bp.systems()[3].build()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        iso = ami_xr.isolate(ami_xr.subtract(frf))
    it = int(iso[names.ISO_ITERATIONS].values[0])
    assert bool(iso[names.ISO_CONVERGED].values.all())
    assert it < 600
    lam = iso[names.EIGENVALUE].values
    s = ami_xr.simulate.score_modes(lam, lam_true)
    assert s.n_found == lam_true.size and s.n_spurious == 0
    assert np.all(np.isfinite(lam))


MEASUREMENT = SHARED_DATA / "measurement.uff"
MEASURED_FN_HZ = np.array([51.5, 142.2, 278.7, 460.4, 687.2, 958.5])


def _isolated_hz(frf):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        iso = ami_xr.isolate(ami_xr.subtract(frf))
    return iso[names.EIGENVALUE].values.imag / (2 * np.pi)


@pytest.mark.skipif(not MEASUREMENT.exists(), reason="shared measured data absent")
def test_measured_lightly_damped_modes_kept():
    """measurement.uff (3 measured accelerance FRFs, 1 Hz lines): its lightly damped modes span
    1-3 lines, too few to fit, in every sweep; the isolation keeps them at their subtraction
    estimates (the immediate pruning of modes that could not be fitted kept only 460 and 959
    Hz)."""
    fn = _isolated_hz(ami_xr.read_uff(MEASUREMENT))
    for f in MEASURED_FN_HZ:
        assert np.min(np.abs(fn - f)) < 0.5, (f, fn)


def test_simulated_lightly_damped_modes_kept():
    """Self-contained case of the same failure: 4 modes with zeta 5e-4 on 1 Hz lines (half-power
    bands 0.05-0.5 Hz), 2 % multiplicative model error and a little noise. Every true mode is
    isolated (the refinement merges the duplicates); the regressed rule kept 2 of the 4."""
    fn = np.array([50.3, 140.6, 280.4, 459.7])
    wn = 2 * np.pi * fn
    zeta = 5e-4
    lam = -zeta * wn + 1j * wn * np.sqrt(1 - zeta**2)
    phi = np.array([[0.6, 0.9, 0.7, 1.0], [1.0, -0.4, 0.5, -0.8], [0.8, -1.1, -0.6, 0.4]])
    residue = lam[None, :] * phi * phi[0][None, :]
    f = np.arange(10.0, 600.0, 1.0)
    frf = frf_from_residues(2 * np.pi * f, lam, residue)
    rng = np.random.default_rng(0)
    frf = frf * (1 + 0.02 * rng.standard_normal(frf.shape))
    noise = rng.standard_normal(frf.shape) + 1j * rng.standard_normal(frf.shape)
    frf = frf + 1e-4 * np.abs(frf).max() * noise
    ds = ami_xr.make_frf_dataset(
        frf,
        f,
        points=[1, 2, 3],
        drive_point=1,
        response_quantity="displacement",
        response_units="m",
        force_units="N",
        frf_source=names.SOURCE_ANALYTIC,
    )
    got = _isolated_hz(ds)
    for f0 in fn:
        assert np.min(np.abs(got - f0)) < 0.2, (f0, got)
