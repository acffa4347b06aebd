"""Issue 42 item 3: ``batch --workers 2`` killed by SIGKILL leaves no worker process behind.

A worker watches its parent (:func:`ami_xr.app.batch._watch_parent`): once the parent is gone
the file in progress stops at its next checkpoint (output rolled back), and the worker exits
after at most :data:`ami_xr.app.batch.PARENT_GRACE_SECONDS` whatever it was doing.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import ami_xr
from ami_xr.app import batch as batch_module

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")

ROOT = Path(__file__).resolve().parents[2]


def _children(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True)
    return [int(p) for p in out.stdout.split()]


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def test_workers_end_when_the_batch_is_killed(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    g, _ = ami_xr.simulate.random_system(
        n_points=20, n_modes=20, noise=0.02, seed=1, n_frequencies=2048
    )
    for k in range(6):
        ami_xr.to_netcdf(g, src / f"f{k}.nc")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen(
        [sys.executable, "-c", "from ami_xr.app.cli import run; run()", "batch", str(src),
         "-o", str(tmp_path / "out"), "-q", "--workers", "2"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    deadline = time.monotonic() + 60
    workers: list[int] = []
    while time.monotonic() < deadline and len(workers) < 2:
        time.sleep(0.2)
        workers = _children(proc.pid)
    assert len(workers) >= 2, "the batch did not start its workers"
    time.sleep(1.0)  # files in progress
    proc.kill()
    proc.wait(10)
    grace = batch_module.PARENT_GRACE_SECONDS + batch_module.PARENT_POLL_SECONDS
    deadline = time.monotonic() + grace + 3
    while time.monotonic() < deadline and [p for p in workers if _alive(p)]:
        time.sleep(0.2)
    left = [p for p in workers if _alive(p)]
    for pid in left:  # ours: cleaned up by pid
        os.kill(pid, signal.SIGKILL)
    assert not left, "batch workers outlived their killed parent"
    assert not list((tmp_path / "out").rglob("*.modes.nc.*")), "a partial output"
