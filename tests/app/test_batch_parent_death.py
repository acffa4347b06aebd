"""Issue 42 item 3: ``batch --workers 2`` killed by SIGKILL leaves no worker process behind.

A worker watches its parent (:func:`ami_xr.app.batch._watch_parent`): once the parent is gone
the file in progress stops at its next checkpoint (output rolled back), and the worker exits
after at most :data:`ami_xr.app.batch.PARENT_GRACE_SECONDS` whatever it was doing.
"""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

import ami_xr
from ami_xr.app import batch as batch_module

from ..reference import REPO
from .proc import H

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")


@pytest.mark.slow
def test_workers_end_when_the_batch_is_killed(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    g, _ = ami_xr.simulate.random_system(
        n_points=20, n_modes=20, noise=0.02, seed=1, n_frequencies=2048
    )
    for k in range(6):
        ami_xr.to_netcdf(g, src / f"f{k}.nc")
    proc = H.start(
        [*H.AMI_XR_RUN, "batch", str(src), "-o", str(tmp_path / "out"), "-q", "--workers", "2"],
        environ=H.env(REPO),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    workers = H.workers_of(proc, 2, ready=False, forked=True)
    assert len(workers) >= 2, "the batch did not start its workers"
    time.sleep(1.0)  # files in progress
    proc.kill()
    proc.wait(10)
    grace = batch_module.PARENT_GRACE_SECONDS + batch_module.PARENT_POLL_SECONDS
    left = H.kill_left(workers, grace + 3)
    assert not left, "batch workers outlived their killed parent"
    assert not list((tmp_path / "out").rglob("*.modes.nc.*")), "a partial output"
