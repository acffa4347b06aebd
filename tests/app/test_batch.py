"""Batch processing of a folder tree (ami_xr.batch and `ami-xr batch`)."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.app.batch import SUMMARY_NAME, batch, find_inputs
from ami_xr.app.cli import EXIT_BATCH_FAILURES, EXIT_OK, main
from ami_xr.errors import AmiXrValueError, DataFileError

from ..reference import REPO, SUBPROCESS_ENV


def _small_frf(seed: int):
    g, _ = ami_xr.simulate.random_system(
        n_points=5, n_modes=5, noise=0.01, seed=seed, n_frequencies=512
    )
    return g


@pytest.fixture
def campaign(tmp_path) -> Path:
    """day1/a.nc, day1/b.uff, day2/c.nc (good FRFs) and day2/broken.nc (not netCDF)."""
    root = tmp_path / "campaign"
    (root / "day1").mkdir(parents=True)
    (root / "day2").mkdir()
    ami_xr.to_netcdf(_small_frf(1), root / "day1" / "a.nc")
    ami_xr.write_uff(_small_frf(2), root / "day1" / "b.uff", binary=True)
    ami_xr.to_netcdf(_small_frf(3), root / "day2" / "c.nc")
    (root / "day2" / "broken.nc").write_text("not a netCDF file")
    (root / "notes.txt").write_text("ignored")
    return root


def _by_file(summary):
    return {row["file"]: row for row in summary.rows}


def test_bad_file_is_skipped_and_the_rest_go_on(campaign, tmp_path):
    out = tmp_path / "out"
    summary = batch(campaign, out, progress=False)
    rows = _by_file(summary)
    assert set(rows) == {"day1/a.nc", "day1/b.uff", "day2/c.nc", "day2/broken.nc"}
    assert rows["day2/broken.nc"]["status"] == "failed"
    assert "broken.nc" in rows["day2/broken.nc"]["message"]
    for good in ("day1/a.nc", "day1/b.uff", "day2/c.nc"):
        assert rows[good]["status"] == "ok"
        assert rows[good]["modes"] >= 1
    assert summary.n_failed == 1 and not summary.ok
    # outputs mirror the input tree, and are complete identification results
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*.modes.nc")) == [
        "day1/a.modes.nc",
        "day1/b.modes.nc",
        "day2/c.modes.nc",
    ]
    result = ami_xr.open_dataset(out / "day1" / "a.modes.nc")
    assert names.EIGENVALUE in result and result.attrs["batch_input"] == "day1/a.nc"
    assert not list(out.rglob(".*.tmp"))
    # summary CSV
    with open(out / SUMMARY_NAME, newline="") as fh:
        table = list(csv.DictReader(fh))
    assert [r["file"] for r in table] == [r["file"] for r in summary.rows]
    assert {"file", "status", "modes", "frequencies_hz"} <= set(table[0])
    freqs = rows["day1/a.nc"]["frequencies_hz"].split()
    assert len(freqs) == rows["day1/a.nc"]["modes"]
    text = summary.format()
    assert "1 failed" in text and "day1/a.nc" in text


def test_rerun_skips_up_to_date_outputs_and_redoes_changed_ones(campaign, tmp_path):
    out = tmp_path / "out"
    batch(campaign, out, progress=False)
    mtimes = {p: p.stat().st_mtime_ns for p in out.rglob("*.modes.nc")}
    rows = _by_file(batch(campaign, out, progress=False))
    assert {rows[f]["status"] for f in ("day1/a.nc", "day1/b.uff", "day2/c.nc")} == {"up to date"}
    assert rows["day1/a.nc"]["modes"] >= 1  # read back from the output
    assert rows["day2/broken.nc"]["status"] == "failed"  # failures are retried, not cached
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.modes.nc")} == mtimes
    # touching an input without changing it keeps it up to date (content hash decides)
    os.utime(campaign / "day1" / "a.nc")
    assert _by_file(batch(campaign, out, progress=False))["day1/a.nc"]["status"] == "up to date"
    # new content -> redone
    ami_xr.to_netcdf(_small_frf(7), campaign / "day2" / "c.nc")
    rows = _by_file(batch(campaign, out, progress=False))
    assert rows["day2/c.nc"]["status"] == "ok"
    assert rows["day1/a.nc"]["status"] == "up to date"
    # new parameters -> everything redone
    rows = _by_file(batch(campaign, out, progress=False, frf_options={"estimator": "H2"}))
    assert rows["day1/a.nc"]["status"] == "ok"
    # force -> redone
    rows = _by_file(
        batch(campaign, out, progress=False, frf_options={"estimator": "H2"}, force=True)
    )
    assert rows["day1/b.uff"]["status"] == "ok"


def test_resume_after_a_crash(campaign, tmp_path):
    out = tmp_path / "out"
    batch(campaign, out, progress=False)
    # A crash left one output missing and a temporary file behind.
    (out / "day2" / "c.modes.nc").unlink()
    stale = out / "day2" / ".c.modes.nc.0123456789ab.tmp"
    stale.write_bytes(b"partial")
    rows = _by_file(batch(campaign, out, progress=False))
    assert rows["day2/c.nc"]["status"] == "ok"
    assert rows["day1/a.nc"]["status"] == "up to date"
    assert not stale.exists()


def test_parallel_workers_give_the_same_results(campaign, tmp_path):
    serial = batch(campaign, tmp_path / "s", progress=False)
    parallel = batch(campaign, tmp_path / "p", workers=2, progress=False)
    assert [(r["file"], r["status"], r["modes"], r["frequencies_hz"]) for r in serial.rows] == [
        (r["file"], r["status"], r["modes"], r["frequencies_hz"]) for r in parallel.rows
    ]


def test_cli_exit_code_and_summary(campaign, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["batch", str(campaign), "-o", str(out), "-q"]) == EXIT_BATCH_FAILURES
    text = capsys.readouterr().out
    assert "failed" in text and "batch_summary.csv" in text
    (campaign / "day2" / "broken.nc").unlink()
    assert main(["batch", str(campaign), "-o", str(out), "-q"]) == EXIT_OK
    assert "0 failed" in capsys.readouterr().out


def test_output_inside_input_is_not_rescanned(campaign):
    batch(campaign, campaign / "results", progress=False)
    inputs = find_inputs(campaign, exclude=[campaign / "results"])
    found = {p.relative_to(campaign).as_posix() for p in inputs}
    assert not any(f.startswith("results") for f in found)
    rows = _by_file(batch(campaign, campaign / "results", progress=False))
    assert not any(f.startswith("results") for f in rows)


def test_bad_arguments(campaign, tmp_path):
    with pytest.raises(DataFileError, match="input_dir"):
        batch(tmp_path / "nope", tmp_path / "out")
    with pytest.raises(AmiXrValueError, match="workers"):
        batch(campaign, tmp_path / "out", workers=0)
    with pytest.raises(AmiXrValueError, match="identify_options"):
        batch(campaign, tmp_path / "out", identify_options="paper")


@pytest.mark.slow  # batch interrupts in the default tier: tests/app/test_batch_faults.py
@pytest.mark.parametrize("workers", ["1", "2"])
def test_ctrl_c_leaves_no_partial_files_and_resumes(tmp_path, workers):
    root = tmp_path / "many"
    root.mkdir()
    for seed in range(6):
        ami_xr.to_netcdf(_small_frf(seed), root / f"f{seed}.nc")
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "ami_xr.app.cli",
            "batch",
            str(root),
            "-o",
            str(out),
            "-q",
            "--workers",
            workers,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=SUBPROCESS_ENV,
    )
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None:
            if list(out.rglob("*.modes.nc")):
                break
            time.sleep(0.05)
        interrupted = proc.poll() is None
        if interrupted:
            proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    if interrupted and proc.returncode == 130:
        assert "interrupted" in err or "stopping" in err  # issue 25: stops within ~1 s
    assert proc.returncode in (130, EXIT_OK), err
    assert not list(out.rglob(".*.tmp"))
    assert (out / SUMMARY_NAME).is_file()
    done = {p.name for p in out.rglob("*.modes.nc")}
    for path in out.rglob("*.modes.nc"):
        ami_xr.open_dataset(path)  # complete and readable
    rows = _by_file(batch(root, out, progress=False))
    assert all(
        rows[f"f{s}.nc"]["status"] == "up to date" for s in range(6) if f"f{s}.modes.nc" in done
    )
    assert all(row["status"] in ("ok", "up to date") for row in rows.values())
    assert np.all([Path(out / row["output"]).is_file() for row in rows.values()])


@pytest.mark.slow
def test_batch_campaign_script(tmp_path):
    script = REPO / "scripts" / "batch_campaign.py"
    cmd = [sys.executable, str(script), "--example", "2", "-o", str(tmp_path / "c")]
    first = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=SUBPROCESS_ENV)
    assert first.returncode == 0, first.stderr
    assert "2 processed" in first.stdout and "max |f error|" in first.stdout
    second = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=SUBPROCESS_ENV)
    assert second.returncode == 0, second.stderr
    assert "2 up to date" in second.stdout


def test_a_batch_worker_takes_its_share_of_the_threads(monkeypatch):
    import os
    import signal

    from ami_xr import interrupt
    from ami_xr.app import batch
    from ami_xr.kernels import projection

    monkeypatch.delenv(projection.THREADS_ENV, raising=False)
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        batch._worker_init(None, None, threads=1)
        assert os.environ[projection.THREADS_ENV] == "1"
        assert projection.compute_threads() == 1
    finally:
        for s, h in handlers.items():
            signal.signal(s, h)
        interrupt.use_event(None)


def test_ctrl_c_while_planning_still_writes_the_summary(campaign, tmp_path, monkeypatch):
    # A Ctrl-C before any file starts (while the inputs are planned) leaves an empty summary;
    # an error at that stage leaves none (nothing was attempted).
    import ami_xr.app.batch as batch_module

    def stopped(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(batch_module, "_plan", stopped)
    out = tmp_path / "stopped"
    with pytest.raises(KeyboardInterrupt):
        batch(campaign, out, progress=False)
    with open(out / SUMMARY_NAME, newline="") as fh:
        assert list(csv.DictReader(fh)) == []

    def broken(*args, **kwargs):
        raise RuntimeError("planning failed")

    monkeypatch.setattr(batch_module, "_plan", broken)
    out = tmp_path / "broken"
    with pytest.raises(RuntimeError, match="planning failed"):
        batch(campaign, out, progress=False)
    assert not (out / SUMMARY_NAME).exists()


@pytest.mark.parametrize("workers, told", [(2, True), (1, False)])
def test_more_workers_than_cores_is_said(campaign, tmp_path, capsys, monkeypatch, workers, told):
    import ami_xr.kernels.projection as projection

    monkeypatch.setattr(projection, "usable_cores", lambda: 1)
    (campaign / "day2" / "broken.nc").unlink()
    out = tmp_path / "out"
    assert main(["batch", str(campaign), "-o", str(out), "-q", "--workers", str(workers)]) == 0
    err = capsys.readouterr().err
    assert ("--workers 2 exceeds the 1 core(s)" in err) is told, err
    assert (out / SUMMARY_NAME).is_file()


def test_usable_cores_is_a_positive_count():
    from ami_xr.kernels.projection import usable_cores

    assert isinstance(usable_cores(), int) and usable_cores() >= 1
