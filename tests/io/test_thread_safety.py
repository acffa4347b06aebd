"""Issue 42 item 5: netCDF files opened and identified from 8 threads without a crash.

netCDF-C/HDF5 are not thread-safe; :data:`ami_xr.io.lazy_source.NETCDF_LOCK` serialises every
netCDF call of ami_xr. The runs happen in a child process (a crash there is a SIGSEGV/SIGBUS
exit code, not a dead test session). The default tier repeats each thread's open 10 times; the
slow tier (``--runslow``, tests/conftest.py) the open and the identify 50 times each (the
issue's bar).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import ami_xr

ROOT = Path(__file__).resolve().parents[2]

CHILD = r"""
import sys, threading, warnings
import ami_xr
from ami_xr import names

paths, repeats, mode = sys.argv[1:-2], int(sys.argv[-2]), sys.argv[-1]
errors = []

def work(k):
    try:
        for r in range(repeats):
            path = paths[(k + r) % len(paths)]
            if mode == "open":
                ds = ami_xr.open_dataset(path)                       # eager
                lazy = ami_xr.open_dataset(path, chunks={"point": 1})  # lazy, read block-wise
                assert abs(lazy[names.FRF].sum().values - ds[names.FRF].sum().values) < 1e-9
                lazy.close()
            else:
                ds = ami_xr.open_dataset(path)
                with warnings.catch_warnings():
                    warnings.simplefilter("always")  # warnings raised in every thread
                    out = ami_xr.identify(ds, progress=True)
                assert out.sizes.get(names.MODE, 0) >= 1
    except Exception as err:
        errors.append(f"{type(err).__name__}: {err}")

threads = [threading.Thread(target=work, args=(k,)) for k in range(8)]
for t in threads:
    t.start()
for t in threads:
    t.join()
print("errors:", errors)
sys.exit(1 if errors else 0)
"""


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> list[str]:
    folder = tmp_path_factory.mktemp("threads")
    paths = []
    for seed in range(4):
        g, _ = ami_xr.simulate.random_system(
            n_points=5, n_modes=5, noise=0.01, seed=seed, n_frequencies=256
        )
        path = folder / f"frf{seed}.nc"
        ami_xr.to_netcdf(g, path)
        paths.append(str(path))
    return paths


def _run(files: list[str], repeats: int, mode: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run(
        [sys.executable, "-c", CHILD, *files, str(repeats), mode],
        capture_output=True,
        text=True,
        env=env,
        timeout=1800,
    )


@pytest.mark.parametrize("repeats", [10, pytest.param(50, marks=pytest.mark.slow)])
def test_opens_from_8_threads_do_not_crash(files, repeats):
    done = _run(files, repeats, "open")
    assert done.returncode == 0, f"exit {done.returncode}: {done.stdout[-900:]}{done.stderr[-900:]}"


@pytest.mark.slow  # identify in 8 threads: the slow tier only (the opens above stay fast)
@pytest.mark.parametrize("repeats", [50])
def test_identify_from_8_threads_on_files_opened_there(files, repeats):
    done = _run(files, repeats, "identify")
    assert done.returncode == 0, f"exit {done.returncode}: {done.stdout[-900:]}{done.stderr[-900:]}"


def test_the_lock_is_held_around_opens(monkeypatch, files):
    # the open of one thread waits while another holds the lock
    import threading

    from ami_xr.io.lazy_source import NETCDF_LOCK

    opened = threading.Event()

    def other():
        ami_xr.open_dataset(files[0])
        opened.set()

    with NETCDF_LOCK:
        thread = threading.Thread(target=other)
        thread.start()
        assert not opened.wait(1.0)
    thread.join(30)
    assert opened.is_set()
