"""Faults during `ami-xr batch`: double Ctrl-C, SIGTERM, SIGKILL leftovers, bad file names.

The signal tests run a child batch whose identification is replaced by a quick function that
returns a ~64 MB Dataset, so the time goes into writing outputs and the signals land in the
writes (where an interrupt raised under xarray's file lock used to hang the process). Unloaded,
the child starts its first write ~0.8 s after "ready" and writes each file in ~0.3 s; the
delays below fall in and around those writes. A hang fails the test after ``HANG_SECONDS``.
"""

from __future__ import annotations

import csv
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import ami_xr
from ami_xr.app.batch import SUMMARY_NAME, batch

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals and file names")

REPO = Path(__file__).resolve().parents[2]
ENV = {
    **os.environ,
    "PYTHONPATH": os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]),
}
HANG_SECONDS = 30
N_FILES = 4

# The child runs the console-script entry point (ami_xr.app.cli.run: its SIGTERM handling from the
# start) and says "ready" from inside main(), once the CLI's own signal handling is in place -
# a signal before that would test the interpreter's start-up, not ami-xr.
CHILD = """
import sys
import numpy as np, xarray as xr
import ami_xr.ami
import ami_xr.app.batch  # imported before "ready": the signals land in the batch
import ami_xr.app.cli as cli


def quick_identify(ds, **options):
    # Stands in for the identification: the batch's time goes into writing ~64 MB per file.
    n = 2**20
    return xr.Dataset({f"v{i}": ("a", np.arange(n, dtype=float) + i) for i in range(8)})


ami_xr.ami.identify = quick_identify
check_paths = cli.check_paths
cli.check_paths = lambda args: (print("ready", flush=True), check_paths(args))
sys.argv = ["ami-xr", "batch", sys.argv[1], "-o", sys.argv[2], "-q", "--workers", "1"]
cli.run()
"""


def _small_frf(seed: int):
    g, _ = ami_xr.simulate.random_system(
        n_points=5, n_modes=5, noise=0.01, seed=seed, n_frequencies=512
    )
    return g


@pytest.fixture
def inputs(tmp_path) -> Path:
    root = tmp_path / "in"
    root.mkdir()
    for seed in range(N_FILES):
        ami_xr.to_netcdf(_small_frf(seed), root / f"f{seed}.nc")
    return root


def _run_and_signal(tmp_path: Path, root: Path, out: Path, signals: list[tuple[float, int]]):
    """Start the child batch; send each ``(delay, signal)`` in turn; return (rc, stderr)."""
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    proc = subprocess.Popen(
        [sys.executable, str(script), str(root), str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
    )
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 120)
        assert ready and proc.stdout.readline().strip() == "ready", proc.stderr.read()
        for delay, sig in signals:
            time.sleep(delay)
            if proc.poll() is None:
                proc.send_signal(sig)
        try:
            _, err = proc.communicate(timeout=HANG_SECONDS)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the batch did not stop within {HANG_SECONDS} s of {signals}: it hangs")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, err


def _assert_outputs_complete(out: Path) -> set[str]:
    done = set()
    for path in out.rglob("*.modes.nc"):
        assert set(ami_xr.open_dataset(path).data_vars) == {f"v{i}" for i in range(8)}
        done.add(path.name)
    return done


# the first timing in the default tier, the others in the slow one
@pytest.mark.parametrize(
    "delay", (0.9, *(pytest.param(d, marks=pytest.mark.slow) for d in (1.6, 2.1)))
)
@pytest.mark.parametrize("gap", (0.02, pytest.param(0.15, marks=pytest.mark.slow)))
def test_double_ctrl_c_stops_at_once_without_partial_outputs(tmp_path, inputs, delay, gap):
    out = tmp_path / "out"
    rc, err = _run_and_signal(tmp_path, inputs, out, [(delay, signal.SIGINT), (gap, signal.SIGINT)])
    # 0: done before the first signal; -SIGINT: the second came after the batch had stopped
    # and reported the interrupt (Python's default handler is back then).
    assert rc in (130, 0) or (rc == -signal.SIGINT and "interrupted" in err), err
    assert "Traceback" not in err
    _assert_outputs_complete(out)
    assert list(out.rglob(".*.tmp")) == []
    # a loaded machine may deliver the first Ctrl-C before the batch made its folder: nothing
    # to summarise then; from the folder on the summary is always written
    assert (out / SUMMARY_NAME).is_file() or not out.exists()


@pytest.mark.parametrize("delay", (1.0, pytest.param(1.8, marks=pytest.mark.slow)))
def test_sigterm_stops_the_batch_with_cleanup(tmp_path, inputs, delay):
    out = tmp_path / "out"
    rc, err = _run_and_signal(tmp_path, inputs, out, [(delay, signal.SIGTERM)])
    assert rc in (143, 0), err
    _assert_outputs_complete(out)
    assert list(out.rglob(".*.tmp")) == []
    assert (out / SUMMARY_NAME).is_file() or not out.exists()  # (as for the double Ctrl-C)


def test_sigkill_leftovers_are_removed_by_the_next_batch(tmp_path, inputs):
    # Kill the batch the moment a temporary output folder appears (inside a write), rather than
    # at fixed delays that depend on the machine's speed.
    out = tmp_path / "out"
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    proc = subprocess.Popen(
        [sys.executable, str(script), str(inputs), str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
    )
    try:
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline:
            if out.is_dir() and list(out.rglob(".*.tmp")):
                proc.send_signal(signal.SIGKILL)
                break
            time.sleep(0.002)
        proc.wait(timeout=HANG_SECONDS)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGKILL, "the batch ended before a write was caught"
    leftovers = list(out.rglob(".*.tmp"))
    assert leftovers and all(p.is_dir() for p in leftovers), "no kill landed inside a write"
    summary = batch(inputs, out, progress=False)
    assert list(out.rglob(".*.tmp")) == []
    assert all(row["status"] in ("ok", "up to date") for row in summary.rows)


def _non_utf8_campaign(tmp_path: Path) -> Path:
    root = tmp_path / "names"
    root.mkdir()
    ami_xr.to_netcdf(_small_frf(1), root / "good.nc")
    ami_xr.to_netcdf(_small_frf(2), root / "tmp.nc")
    os.rename(root / "tmp.nc", os.path.join(os.fsencode(root), b"bad\xff.nc"))
    return root


def test_non_utf8_file_name_gets_a_summary_and_the_good_files_are_reported(tmp_path):
    root = _non_utf8_campaign(tmp_path)
    out = tmp_path / "out"
    summary = batch(root, out, progress=False)
    rows = {os.fsencode(r["file"]): r for r in summary.rows}
    assert rows[b"good.nc"]["status"] == "ok"
    assert rows[b"bad\xff.nc"]["status"] == "failed"
    assert "not valid UTF-8" in rows[b"bad\xff.nc"]["message"]
    assert "bad\\xff.nc" in summary.format()
    summary.format().encode("utf-8")  # printable on any UTF-8 stream
    with open(out / SUMMARY_NAME, encoding="utf-8", newline="") as fh:
        written = {r["file"]: r for r in csv.DictReader(fh)}
    assert written["good.nc"]["status"] == "ok"
    assert written["bad\\xff.nc"]["status"] == "failed"
    assert (out / "good.modes.nc").is_file()


def test_cli_batch_with_a_non_utf8_file_name_prints_the_table(tmp_path):
    root = _non_utf8_campaign(tmp_path)
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "ami_xr.app.cli", "batch", str(root), "-o", str(out), "-q"],
        capture_output=True,
        text=True,
        timeout=600,
        env={**ENV, "PYTHONIOENCODING": "utf-8"},
    )
    assert proc.returncode == 3, proc.stderr  # some files failed
    assert "Traceback" not in proc.stderr
    assert "good.nc" in proc.stdout and "bad\\xff.nc" in proc.stdout
    assert (out / SUMMARY_NAME).is_file()
    assert np.isin(["good.modes.nc"], os.listdir(out)).all()
