"""Issue 42 item 1: ``identify --workers/--scheduler`` fails in bounded time, with one line.

Each case runs the ``ami-xr`` entry point in a subprocess (as a user would) with a short
``--cluster-timeout``: no scheduler at the address, something that is not a dask scheduler
there, a scheduler without workers, a chunk too big for the workers' memory, workers or the
scheduler lost during the run, SIGINT/SIGTERM during the run (ended within 2 s, no raw
traceback), SIGKILL of the command (its worker processes end with it) and distributed's log
lines kept off stderr.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from ..reference import REPO
from .proc import H

pytest.importorskip("distributed")
pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals and process groups")

CLI = H.AMI_XR_RUN


def _env() -> dict[str, str]:
    return H.env(REPO)


@pytest.fixture(scope="module")
def frf_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("cluster") / "frf.nc"
    subprocess.run(
        [*CLI, "simulate", "random", "--points", "20", "-o", str(path)],
        check=True,
        capture_output=True,
        env=_env(),
        timeout=120,
    )
    return path


def _identify(frf: Path, *options: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*CLI, "identify", str(frf), "-q", "--cluster-timeout", "2", *options],
        capture_output=True,
        text=True,
        env=_env(),
        timeout=timeout,
    )


def _one_error_line(done: subprocess.CompletedProcess, *words: str) -> str:
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 1, done.stderr
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith("ami-xr identify: error: "), lines[0]
    assert "Traceback" not in done.stderr and "unexpected" not in lines[0]
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


@pytest.mark.slow
def test_no_scheduler_at_the_address_is_named_in_bounded_time(frf_file):
    address = f"tcp://127.0.0.1:{H.free_port()}"
    start = time.monotonic()
    done = _identify(frf_file, "--scheduler", address)
    assert time.monotonic() - start < 60  # bounded (a hang never ends); slack for a loaded machine
    _one_error_line(done, address, "no dask scheduler answered")


@pytest.mark.slow
@pytest.mark.parametrize(
    "reply, words",
    [
        (b"HTTP/1.0 400 Bad Request\r\nContent-Length: 0\r\n\r\n", "not a dask scheduler"),
        (None, "no dask scheduler answered"),  # accepts, never speaks
    ],
)
def test_a_server_that_is_no_dask_scheduler(frf_file, reply, words):
    server = H.Server(reply)
    server.start()
    try:
        start = time.monotonic()
        done = _identify(frf_file, "--scheduler", f"tcp://127.0.0.1:{server.port}")
        assert time.monotonic() - start < 90  # bounded; slack for a loaded machine
    finally:
        server.close()
    _one_error_line(done, f"127.0.0.1:{server.port}", words)


def _scheduler(port: int) -> subprocess.Popen:
    proc = H.scheduler(port, _env())
    if proc is None:
        pytest.fail("the dask scheduler did not start")
    return proc


def _worker(address: str) -> subprocess.Popen:
    return H.worker(address, _env())


_stop = H.end


@pytest.mark.slow
def test_a_scheduler_without_workers_is_named(frf_file):
    port = H.free_port()
    scheduler = _scheduler(port)
    try:
        start = time.monotonic()
        done = _identify(frf_file, "--scheduler", f"tcp://127.0.0.1:{port}")
        assert time.monotonic() - start < 90  # bounded; slack for a loaded machine
    finally:
        _stop(scheduler)
    _one_error_line(done, f"127.0.0.1:{port}", "has no workers")


@pytest.mark.slow
@pytest.mark.parametrize("victim", ["worker", "scheduler"])
def test_workers_or_scheduler_lost_during_the_run(frf_file, tmp_path, victim):
    port = H.free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = _scheduler(port)
    worker = _worker(address)
    try:
        assert H.wait_for_workers(address, environ=_env()), "the dask worker did not join"
        proc = H.start(
            [*CLI, "identify", str(frf_file), "--scheduler", address, "--cluster-timeout", "2",
             "--chunk-points", "2"],
            environ=_env(),
        )
        assert H.connected(proc, port), "identify did not reach its scheduler"
        time.sleep(1)  # the work under way
        (worker if victim == "worker" else scheduler).kill()
        try:
            out, err = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            pytest.fail(f"identify ran on for 30 s after its {victim} was killed")
    finally:
        _stop(worker, scheduler)
    done = subprocess.CompletedProcess(proc.args, proc.returncode, out, err)
    if done.returncode == 0:
        pytest.skip("the run ended before the kill (a fast machine)")
    words = "all dask workers were lost" if victim == "worker" else "lost the connection"
    _one_error_line(done, address, words)


def test_a_chunk_too_big_for_the_worker_memory_is_refused_before_the_run(frf_file):
    done = _identify(frf_file, "--workers", "1", "--worker-memory", "100kB", timeout=60)
    _one_error_line(done, "--chunk-points", "--worker-memory")


def _start_busy(frf: Path) -> tuple[subprocess.Popen, list[int]]:
    """identify --workers 2 in a new process group, once its two workers run."""
    proc = H.start(
        [*CLI, "identify", str(frf), "--workers", "2", "-q", "--chunk-points", "2"],
        environ=_env(),
    )
    # once their preload has run (a Ctrl-C to the group during their start-up reaches them)
    workers = H.workers_of(proc, 2)
    assert proc.poll() is None and len(workers) == 2, "the local cluster did not start"
    time.sleep(1)  # the work under way
    return proc, workers


@pytest.mark.slow
@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_to_the_group_ends_the_command_within_2_s(frf_file, signum, code):
    proc, workers = _start_busy(frf_file)
    code_, _, err, took = H.stop(proc, signum, group=True)  # as a terminal's Ctrl-C
    if code_ is None:
        pytest.fail("identify --workers 2 ran on for 30 s after the signal")
    if code_ == 0:
        pytest.skip("the run ended before the signal (a fast machine)")
    assert code_ == code, err
    assert err.strip() in ("ami-xr identify: interrupted", "ami-xr: terminated"), err
    assert took < 10.0, f"{took:.2f} s"  # 2 s idle; a hang runs to the 30 s bound
    assert not H.kill_left(workers, 5.0)  # gone with the command; slack for a loaded machine


@pytest.mark.slow
def test_sigkill_of_the_command_ends_its_workers(frf_file):
    proc, workers = _start_busy(frf_file)
    proc.kill()
    proc.wait(10)
    assert not H.kill_left(workers, 5.0), "worker processes outlived the killed command"


@pytest.mark.slow
def test_distributed_logs_only_with_verbose(frf_file):
    quiet = _identify(frf_file, "--workers", "1", "--worker-memory", "100TB", timeout=120)
    assert quiet.returncode == 0, quiet.stderr
    assert "distributed" not in quiet.stderr and " - WARNING - " not in quiet.stderr
    loud = _identify(frf_file, "--workers", "1", "-v", timeout=120)
    assert loud.returncode == 0, loud.stderr
    assert "ami-xr: distributed." in loud.stderr


@pytest.mark.slow
def test_numpy_warnings_of_the_workers_are_not_shown_raw(frf_file, tmp_path):
    import ami_xr
    from ami_xr import names

    g = ami_xr.open_dataset(frf_file)
    values = g[names.FRF].values.copy()
    values[:, 100] = 1e308  # squares overflow in the noise model, on the workers
    spike = tmp_path / "spike.nc"
    ami_xr.to_netcdf(g.assign({names.FRF: g[names.FRF].copy(data=values)}), spike)
    done = _identify(spike, "--workers", "1", timeout=120)
    assert "RuntimeWarning" not in done.stderr and "overflow encountered" not in done.stderr
    assert done.stderr.strip().splitlines()[-1].startswith("ami-xr identify: ")


@pytest.mark.parametrize("value", ["0", "-1", "nan", "abc", "4000"])
def test_a_bad_cluster_timeout_is_a_usage_error(value, capsys):
    from ami_xr.app.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["identify", "x.nc", "--workers", "1", f"--cluster-timeout={value}"])
    assert stop.value.code == 2
    assert "--cluster-timeout" in capsys.readouterr().err


@pytest.mark.slow
def test_a_worker_killed_over_its_memory_limit_is_reported(tmp_path):
    import ami_xr
    from ami_xr.simulate.spread import many_points

    g, _ = many_points(4000, 1024, 12, noise=0.02, seed=0)
    big = tmp_path / "big.nc"
    ami_xr.to_netcdf(g, big)  # a 64 MiB chunk passes the check (x4 < 300MB); the work does not
    start = time.monotonic()
    done = _identify(big, "--workers", "1", "--worker-memory", "300MB", "--chunk-points", "4000",
                     timeout=180)
    assert time.monotonic() - start < 120
    _one_error_line(done, "a dask worker died", "--worker-memory 300MB")
