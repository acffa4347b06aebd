"""Real signals during netCDF writes (SIGINT, SIGTERM, SIGKILL) in subprocesses.

Each case starts a child that writes a ~100 MB Dataset over an existing small file and signals
it at one of a fixed set of moments after the write began. A hang fails the test (the child
must exit within ``HANG_SECONDS``; the write alone takes well under a second) instead of
hanging the suite. After SIGINT/SIGTERM the target is the old file (or, when the signal came
after the write, the complete new one) and no temporary folder is left; after SIGKILL the
leftover is removed by the next write of the same target.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr.io.atomic import atomic_path, remove_stale

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")

REPO = Path(__file__).resolve().parents[2]

ENV = {
    **os.environ,
    "PYTHONPATH": os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]),
}
# Seconds a signalled child may take to exit: the write it must finish or roll back takes
# < 1 s here; a hang (the interrupt raised under xarray's file lock) never ends.
HANG_SECONDS = 30
# Moments after the child announced the write (s): before, during and around its end.
# two moments in the default tier, the other three in the slow one
DELAYS = (0.05, 0.25, *(pytest.param(d, marks=pytest.mark.slow) for d in (0.0, 0.12, 0.4)))
MEGABYTES = 100

CHILD = """
import sys
import numpy as np, xarray as xr
import ami_xr

mode, target, megabytes = sys.argv[1], sys.argv[2], int(sys.argv[3])
if mode == "hold":  # announce from inside the write, once the temporary file exists, and stay
    import time
    write = xr.Dataset.to_netcdf

    def held(self, *args, **kwargs):
        out = write(self, *args, **kwargs)
        print("writing", flush=True)
        time.sleep(120)
        return out

    xr.Dataset.to_netcdf = held
if mode == "lazy":
    ds = ami_xr.open_dataset(sys.argv[4], chunks={"a": 2**17})
else:
    n = megabytes * 2**20 // 8 // 20  # 20 variables: many lock round trips in one write
    ds = xr.Dataset({f"v{i}": ("a", np.arange(n, dtype=float) + i) for i in range(20)})
if mode != "hold":
    print("writing", flush=True)
try:
    ami_xr.to_netcdf(ds, target)
    print("done", flush=True)
except KeyboardInterrupt:
    sys.exit(130)
"""


def _old_file(path: Path) -> bytes:
    ami_xr.to_netcdf(xr.Dataset({"old": ("x", np.arange(3.0))}), path)
    return path.read_bytes()


def _temporaries(folder: Path) -> list[Path]:
    return sorted(folder.rglob(".*.tmp"))


def _signal_child(tmp_path: Path, args: list[str], sig: int, delay: float):
    """Run the writer child, send ``sig`` ``delay`` s after it starts writing; (rc, stdout)."""
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    proc = subprocess.Popen(
        [sys.executable, str(script), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
    )
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 120)
        assert ready and proc.stdout.readline().strip() == "writing", proc.stderr.read()
        time.sleep(delay)
        proc.send_signal(sig)
        try:
            out, err = proc.communicate(timeout=HANG_SECONDS)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the write did not end within {HANG_SECONDS} s of {sig!r}: it hangs")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, out, err


def _assert_old_or_complete(target: Path, old: bytes, finished: bool) -> None:
    # A signal after the rename but before the child printed "done" leaves the complete new
    # file: both outcomes are allowed, a partial file never.
    if finished or target.read_bytes() != old:
        assert set(ami_xr.open_dataset(target).data_vars) >= {"v0", "v19"}


@pytest.mark.parametrize("delay", DELAYS)
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_during_write_never_hangs_and_keeps_the_old_file(tmp_path, sig, delay):
    target = tmp_path / "big.nc"
    old = _old_file(target)
    rc, out, err = _signal_child(tmp_path, ["eager", str(target), str(MEGABYTES)], sig, delay)
    finished = "done" in out
    if not finished:  # interrupted: exit status of Ctrl-C; of SIGTERM (-15 before the write)
        assert rc in ((130,) if sig == signal.SIGINT else (128 + signal.SIGTERM, -sig)), err
    _assert_old_or_complete(target, old, finished)
    assert _temporaries(tmp_path) == []


@pytest.mark.parametrize("delay", (0.1, pytest.param(0.3, marks=pytest.mark.slow)))
def test_ctrl_c_stops_a_lazy_write_between_chunks(tmp_path, delay):
    source = tmp_path / "source.nc"
    n = MEGABYTES * 2**20 // 8 // 20
    ami_xr.to_netcdf(
        xr.Dataset({f"v{i}": ("a", np.arange(n, dtype=float) + i) for i in range(20)}), source
    )
    target = tmp_path / "copy.nc"
    old = _old_file(target)
    args = ["lazy", str(target), "0", str(source)]
    rc, out, err = _signal_child(tmp_path, args, signal.SIGINT, delay)
    finished = "done" in out
    if not finished:
        assert rc == 130, err
    _assert_old_or_complete(target, old, finished)
    assert _temporaries(tmp_path) == []


def test_sigkill_leftover_is_removed_by_the_next_write_of_the_target(tmp_path):
    target = tmp_path / "big.nc"
    old = _old_file(target)
    # The child holds inside the write (its temporary file written, not yet renamed): the kill
    # lands there whatever the disk's speed (timed delays missed it on a fast CI disk).
    rc, _, err = _signal_child(tmp_path, ["hold", str(target), "1"], signal.SIGKILL, 0.0)
    assert rc == -signal.SIGKILL, err
    assert target.read_bytes() == old
    leftovers = _temporaries(tmp_path)
    assert leftovers and all(p.is_dir() for p in leftovers), "no temporary folder left by the kill"
    ami_xr.to_netcdf(xr.Dataset({"new": ("x", np.arange(2.0))}), target)
    assert _temporaries(tmp_path) == []
    assert list(ami_xr.open_dataset(target).data_vars) == ["new"]


def test_a_live_writers_temporary_folder_is_not_removed(tmp_path):
    target = tmp_path / "shared.nc"
    with atomic_path(target) as tmp:  # another writer of the same target, still writing
        tmp.write_bytes(b"in progress")
        ami_xr.to_netcdf(xr.Dataset({"a": ("x", np.arange(2.0))}), target)
        assert remove_stale(tmp_path) == []
        assert tmp.read_bytes() == b"in progress"
    assert target.read_bytes() == b"in progress"  # the slower writer's rename wins
    assert _temporaries(tmp_path) == []


def test_remove_stale_removes_a_killed_writers_folder_with_its_file(tmp_path):
    leftover = tmp_path / "sub" / ".r.modes.nc.0123456789ab.tmp"
    leftover.mkdir(parents=True)
    (leftover / "r.modes.nc").write_bytes(b"\0" * 4096)
    assert remove_stale(tmp_path) == [leftover]
    assert not leftover.exists()


def test_ctrl_c_inside_pyuff_is_not_swallowed_and_rolls_back(tmp_path, monkeypatch):
    """pyuff's bare ``except:`` in ``refresh`` turned a KeyboardInterrupt into "Error refreshing
    UFF file" (issue 25 item 3): signals are held while pyuff runs and raised between blocks,
    so the interrupt is a KeyboardInterrupt and the old target stays."""
    pyuff = pytest.importorskip("pyuff")
    ds = ami_xr.open_dataset(REPO / "sample_data" / "benchmark_frf.nc").load()
    target = tmp_path / "b.uff"
    target.write_text("old\n")
    calls = []

    class SignalOnSecondUse:  # pyuff's numpy, inside refresh's try/bare except
        def __getattr__(self, name):
            if name == "asarray":
                calls.append(1)
                if len(calls) == 2:
                    os.kill(os.getpid(), signal.SIGINT)
            return getattr(np, name)

    monkeypatch.setitem(pyuff.UFF.refresh.__globals__, "np", SignalOnSecondUse())
    with pytest.raises(KeyboardInterrupt):
        ami_xr.write_uff(ds, target)
    assert target.read_text() == "old\n"
    assert not list(tmp_path.glob(".*.tmp"))
