"""Faults of issue 25 on the command line: special files, streams, environment, full disk,
batch with workers under SIGTERM to the process group (each in a subprocess)."""

from __future__ import annotations

import csv
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX files and signals")

REPO = Path(__file__).resolve().parents[2]
SAMPLE = REPO / "sample_data" / "benchmark_frf.nc"
ENV = {**os.environ, "PYTHONPATH": str(REPO)}
CLI = [sys.executable, "-c", "from ami_xr.app.cli import run; run()"]


def ami(*args, timeout=600, env=None, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*CLI, *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env or ENV,
        **kw,
    )


# --- special files (items 5 and 10) --------------------------------------------------------------
def test_fifo_input_is_refused_up_front(tmp_path):
    fifo = tmp_path / "f.nc"
    os.mkfifo(fifo)
    for command in (
        ["identify", fifo],
        ["convert", fifo, "-o", tmp_path / "x.uff"],
        ["report", fifo, "-o", tmp_path / "rep"],
        ["frf", fifo, "-o", tmp_path / "g.nc"],
    ):
        done = ami(*command, timeout=60)  # blocking on the pipe would time out
        assert done.returncode == 1, done.stderr
        assert "named pipe (FIFO)" in done.stderr and "unexpected" not in done.stderr


def test_symlink_to_a_device_and_empty_path_are_named(tmp_path):
    link = tmp_path / "z.nc"
    link.symlink_to("/dev/zero")
    done = ami("identify", link, timeout=60)
    assert done.returncode == 1 and "character device" in done.stderr, done.stderr
    done = ami("identify", "", timeout=60)
    assert done.returncode == 1 and "path is empty" in done.stderr, done.stderr


@pytest.mark.slow
def test_batch_never_blocks_on_a_fifo(tmp_path):
    src, out = tmp_path / "in", tmp_path / "out"
    src.mkdir()
    shutil.copy(SAMPLE, src / "a.nc")
    os.mkfifo(src / "x.nc")
    done = ami("batch", src, "-o", out, "-q", timeout=600)
    assert done.returncode == 3, done.stderr  # one file failed: the FIFO
    rows = {r["file"]: r for r in csv.DictReader(open(out / "batch_summary.csv"))}
    assert rows["a.nc"]["status"] == "ok"
    assert rows["x.nc"]["status"] == "failed" and "named pipe" in rows["x.nc"]["message"]


def test_output_name_too_long_for_the_temporary_name_fails_before_the_work(tmp_path):
    name = "m" * 240 + ".nc"  # legal, but not with '.<name>.<12 hex>.tmp' around it
    started = time.monotonic()
    done = ami("identify", SAMPLE, "-o", tmp_path / name, timeout=120)
    assert done.returncode == 1 and "-o" in done.stderr and "bytes" in done.stderr, done.stderr
    assert "Subtraction" not in done.stdout and done.stdout == ""
    assert time.monotonic() - started < 120


# --- streams and environment (item 6) ------------------------------------------------------------
@pytest.mark.slow
def test_closed_stderr_and_broken_stdout_do_not_fail_a_good_run(tmp_path):
    out = tmp_path / "m.nc"
    done = subprocess.run(
        [*CLI, "identify", str(SAMPLE), "-q", "-o", str(out)],
        stdout=subprocess.PIPE,
        stderr=None,
        env=ENV,
        timeout=600,
        text=True,
        preexec_fn=lambda: os.close(2),  # 2>&-
    )
    assert done.returncode == 0 and out.exists()
    out.unlink()
    pipe = subprocess.Popen(
        f"{sys.executable} -c 'from ami_xr.app.cli import run; run()' identify {SAMPLE} "
        f"-q -o {out} | head -c 1 >/dev/null; echo ${{PIPESTATUS[0]}}",
        shell=True,
        executable="/bin/bash",
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=ENV,
        text=True,
    )
    status, err = pipe.communicate(timeout=600)
    assert status.strip() == "0", err
    assert "BrokenPipe" not in err and out.exists()


def test_read_only_home_gets_a_quiet_matplotlib_config_dir(tmp_path):
    code = (
        "import os; from ami_xr.app import cli; cli._matplotlib_config_dir(); "
        "d = os.environ.get('MPLCONFIGDIR'); print(d and os.path.isdir(d))"
    )
    env = {**ENV, "HOME": "/dev/null/nohome", "XDG_CONFIG_HOME": ""}
    env.pop("MPLCONFIGDIR", None)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert done.stdout.strip() == "True", done.stderr


# --- batch with workers, SIGTERM to the process group (item 4) -----------------------------------
@pytest.mark.slow
def test_batch_sigterm_to_the_group_leaves_a_summary_matching_the_outputs(tmp_path):
    src, out = tmp_path / "in", tmp_path / "out"
    src.mkdir()
    for k in range(4):
        shutil.copy(SAMPLE, src / f"f{k}.nc")
    proc = subprocess.Popen(
        [*CLI, "batch", str(src), "-o", str(out), "-q", "--workers", "2"],
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and proc.poll() is None:
        if list(out.glob("*.modes.nc")):
            break
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGTERM)
    sent = time.monotonic()
    try:
        _, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail("batch did not stop within 120 s of SIGTERM")
    assert proc.returncode in (143, 0), err  # 0 only when it had finished already
    assert "unexpected" not in err and "Traceback" not in err
    rows = list(csv.DictReader(open(out / "batch_summary.csv")))
    listed = {r["output"] for r in rows if r["status"] in ("ok", "capped")}
    on_disk = {p.name for p in out.glob("*.modes.nc")}
    assert listed == on_disk and on_disk
    assert not list(out.glob(".*.tmp"))
    assert time.monotonic() - sent < 120


# --- full disk (item 7) --------------------------------------------------------------------------
FULL_DISK = """
import resource, sys
resource.setrlimit(resource.RLIMIT_FSIZE, (40_000, 40_000))  # files past 40 kB: EFBIG
from ami_xr.app.cli import run
run()
"""


@pytest.mark.parametrize("suffix", [".nc", ".uff"])
def test_a_full_disk_is_named_and_leaves_nothing(tmp_path, suffix):
    out = tmp_path / f"b{suffix}"
    out.write_text("old\n")
    done = subprocess.run(
        [sys.executable, "-c", FULL_DISK, "convert", str(SAMPLE), "-o", str(out)],
        capture_output=True,
        text=True,
        env=ENV,
        timeout=300,
    )
    assert done.returncode == 1, done.stderr
    assert "no space left on the device writing" in done.stderr, done.stderr
    assert "unexpected" not in done.stderr
    assert out.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]
