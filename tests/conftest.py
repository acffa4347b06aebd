"""Shared fixtures: small simulated datasets, numpy- and dask-backed.

Session-scoped fixtures hand every test the same object: tests must not modify them in place
(the ami_xr functions never do; use ``.copy()`` before assigning into one). Naive oracles and
tolerance helpers live in ``tests/reference.py``.
"""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import make_frf_dataset, names

from .reference import REPO, frf_from_residues

# Two modes of a 3-point system: eigenvalues lam = -zeta*wn + i*wd (rad/s) and residues
# A_jk = lam_k Phi_jk Phi_Pk (drive point P = point 1).
FRF_FIXTURE_FN_HZ = np.array([12.0, 31.0])
FRF_FIXTURE_ZETA = np.array([0.02, 0.035])
FRF_FIXTURE_PHI = np.array([[0.6, 0.9], [1.0, -0.4], [0.8, -1.1]])  # rows: points 1, 2, 3
FRF_FIXTURE_POINTS = [1, 2, 3]


# --- the slow tier ------------------------------------------------------------------------------
# Tests marked ``slow`` (long subprocess and CLI runs, local dask clusters, fault probes,
# benchmark-sized cases; each feature keeps a fast test in the default tier) are skipped unless
# asked for: ``python -m pytest -q -m slow --runslow`` runs only them (CI runs both tiers).
RUN_SLOW_OPTION = "--runslow"
RUN_SLOW_ENV = "AMI_XR_SLOW"  # set (non-empty) = --runslow, for runs that cannot add options
SLOW_SKIP_REASON = (
    "slow tier: run with 'python -m pytest -q -m slow --runslow' (or AMI_XR_SLOW=1); "
    "CI (.ci/run) runs it after the default tier"
)


def pytest_addoption(parser):
    parser.addoption(
        RUN_SLOW_OPTION,
        action="store_true",
        default=False,
        help="also run the tests marked slow (with -m slow: only them)",
    )


def run_slow(config) -> bool:
    """Whether this session runs the slow tier (the option, or the environment variable)."""
    return bool(config.getoption(RUN_SLOW_OPTION) or os.environ.get(RUN_SLOW_ENV))


def pytest_collection_modifyitems(config, items):
    if run_slow(config):
        return
    skip = pytest.mark.skip(reason=SLOW_SKIP_REASON)
    for item in items:
        if item.get_closest_marker("slow") is not None:
            item.add_marker(skip)


@pytest.fixture(scope="session", autouse=True)
def _ctrl_c_raises():
    """Ctrl-C raises KeyboardInterrupt in this process and the commands it starts, also when the
    suite was launched in the background (``nohup``, ``cmd &``): a shell ignores SIGINT for such
    jobs, Python then installs no handler, and the interrupt tests would see nothing."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield


def _frf_fixture_modes():
    wn = 2 * np.pi * FRF_FIXTURE_FN_HZ
    lam = -FRF_FIXTURE_ZETA * wn + 1j * wn * np.sqrt(1 - FRF_FIXTURE_ZETA**2)
    phi = FRF_FIXTURE_PHI.astype(complex)
    residue = lam[None, :] * phi * phi[0][None, :]
    return lam, residue


@pytest.fixture
def frf_truth() -> xr.Dataset:
    """Exact modes of ``frf_dataset``: ``eigenvalue`` (mode), ``residue`` (point, mode)."""
    lam, residue = _frf_fixture_modes()
    return xr.Dataset(
        {
            names.EIGENVALUE: ((names.MODE,), lam, {names.ATTR_UNITS: "rad/s"}),
            names.RESIDUE: ((names.POINT, names.MODE), residue),
            names.NATURAL_FREQUENCY: ((names.MODE,), FRF_FIXTURE_FN_HZ, {names.ATTR_UNITS: "Hz"}),
            names.DAMPING_RATIO: ((names.MODE,), FRF_FIXTURE_ZETA),
        },
        coords={names.POINT: FRF_FIXTURE_POINTS, names.MODE: [0, 1]},
    )


@pytest.fixture
def frf_dataset() -> xr.Dataset:
    """Noise-free analytic receptance (eq. 4): 3 points (labels 1, 2, 3; drive point 1),
    200 lines from 0.5 to 50 Hz, two modes at 12 and 31 Hz (see ``frf_truth``)."""
    lam, residue = _frf_fixture_modes()
    frequency = np.linspace(0.5, 50.0, 200)
    omega = 2 * np.pi * frequency
    frf = frf_from_residues(omega, lam, residue)
    return make_frf_dataset(
        frf,
        frequency,
        points=FRF_FIXTURE_POINTS,
        drive_point=1,
        response_quantity="displacement",
        response_units="m",
        force_units="N",
        frf_source=names.SOURCE_ANALYTIC,
    )


@pytest.fixture(scope="session")
def paper_benchmark_clean() -> tuple[xr.Dataset, xr.Dataset, xr.Dataset]:
    """The paper's beam benchmark without noise: (time histories, FRFs, truth)."""
    return ami_xr.simulate.benchmark(noise=0.0)


@pytest.fixture(scope="session")
def paper_benchmark_noisy() -> tuple[xr.Dataset, xr.Dataset, xr.Dataset]:
    """The paper's beam benchmark with its 15 % noise, seed 0: (time histories, FRFs, truth)."""
    return ami_xr.simulate.benchmark(noise=0.15, seed=0)


@pytest.fixture(scope="session")
def sample_benchmark_frf() -> xr.Dataset:
    """sample_data/benchmark_frf.nc, loaded into memory (skips where the checkout lacks it)."""
    path = REPO / "sample_data" / "benchmark_frf.nc"
    if not path.exists():
        pytest.skip("sample_data/ not generated in this checkout")
    return ami_xr.open_dataset(path).load()


@pytest.fixture(scope="session")
def small_random_system() -> tuple[xr.Dataset, xr.Dataset]:
    """A random 5-point chain with 5 modes, 2 % noise, 1024 lines: (FRFs, truth)."""
    return ami_xr.simulate.random_system(
        n_points=5, n_modes=5, noise=0.02, seed=3, n_frequencies=1024
    )


@pytest.fixture
def small_random_system_dask(small_random_system) -> xr.Dataset:
    """The FRFs of ``small_random_system`` as a dask-backed Dataset, one chunk per point."""
    g, _ = small_random_system
    return g.chunk({names.POINT: 1})
