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
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")
pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals and process groups")

ROOT = Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-c", "from ami_xr.app.cli import run; run()"]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


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


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


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


def test_no_scheduler_at_the_address_is_named_in_bounded_time(frf_file):
    address = f"tcp://127.0.0.1:{_free_port()}"
    start = time.monotonic()
    done = _identify(frf_file, "--scheduler", address)
    assert time.monotonic() - start < 20
    _one_error_line(done, address, "no dask scheduler answered")


class _Server(threading.Thread):
    """A TCP server that is not a dask scheduler: answers like an HTTP server, or stays silent."""

    def __init__(self, reply: bytes | None) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.reply, self.stop, self.conns = reply, threading.Event(), []

    def run(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            self.conns.append(conn)
            if self.reply is not None:
                conn.sendall(self.reply)

    def close(self) -> None:
        self.stop.set()
        self.join()
        for conn in self.conns:
            conn.close()
        self.sock.close()


@pytest.mark.parametrize(
    "reply, words",
    [
        (b"HTTP/1.0 400 Bad Request\r\nContent-Length: 0\r\n\r\n", "not a dask scheduler"),
        (None, "no dask scheduler answered"),  # accepts, never speaks
    ],
)
def test_a_server_that_is_no_dask_scheduler(frf_file, reply, words):
    server = _Server(reply)
    server.start()
    try:
        start = time.monotonic()
        done = _identify(frf_file, "--scheduler", f"tcp://127.0.0.1:{server.port}")
        assert time.monotonic() - start < 30
    finally:
        server.close()
    _one_error_line(done, f"127.0.0.1:{server.port}", words)


def _scheduler(port: int) -> subprocess.Popen:
    proc = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
         "--port", str(port), "--no-dashboard"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(),
    )
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return proc
        time.sleep(0.2)
    proc.kill()
    pytest.fail("the dask scheduler did not start")


def _worker(address: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
         "--no-nanny", "--no-dashboard"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(),
    )


def _stop(*procs: subprocess.Popen) -> None:
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
        proc.wait(10)


def test_a_scheduler_without_workers_is_named(frf_file):
    port = _free_port()
    scheduler = _scheduler(port)
    try:
        start = time.monotonic()
        done = _identify(frf_file, "--scheduler", f"tcp://127.0.0.1:{port}")
        assert time.monotonic() - start < 30
    finally:
        _stop(scheduler)
    _one_error_line(done, f"127.0.0.1:{port}", "has no workers")


@pytest.mark.parametrize("victim", ["worker", "scheduler"])
def test_workers_or_scheduler_lost_during_the_run(frf_file, tmp_path, victim):
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = _scheduler(port)
    worker = _worker(address)
    try:
        proc = subprocess.Popen(
            [*CLI, "identify", str(frf_file), "--scheduler", address, "--cluster-timeout", "2",
             "--chunk-points", "2"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=_env(),
        )
        time.sleep(8)  # connected, work under way
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


def _children(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True)
    return [int(p) for p in out.stdout.split()]


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def _start_busy(frf: Path) -> tuple[subprocess.Popen, list[int]]:
    """identify --workers 2 in a new process group, once its two workers run."""
    proc = subprocess.Popen(
        [*CLI, "identify", str(frf), "--workers", "2", "-q", "--chunk-points", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(),
        start_new_session=True,
    )
    deadline = time.monotonic() + 60
    workers: list[int] = []
    while time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.3)
        workers = [p for p in _children(proc.pid) if b"spawn_main" in _cmdline(p)]
        if len(workers) == 2 and all(_ignores_sigint(p) for p in workers):
            break  # their preload has run (a Ctrl-C during their start-up reaches them)
    assert proc.poll() is None and len(workers) == 2, "the local cluster did not start"
    time.sleep(1)  # the work under way
    return proc, workers


def _ignores_sigint(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    ignored = [line.split()[1] for line in status.splitlines() if line.startswith("SigIgn")]
    return bool(ignored) and bool(int(ignored[0], 16) & (1 << (signal.SIGINT - 1)))


def _cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ")
    except OSError:
        return b""


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_to_the_group_ends_the_command_within_2_s(frf_file, signum, code):
    proc, workers = _start_busy(frf_file)
    os.killpg(proc.pid, signum)  # as a terminal's Ctrl-C: workers get it too
    start = time.monotonic()
    try:
        out, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail("identify --workers 2 ran on for 30 s after the signal")
    took = time.monotonic() - start
    if proc.returncode == 0:
        pytest.skip("the run ended before the signal (a fast machine)")
    assert proc.returncode == code, err
    assert err.strip() in ("ami-xr identify: interrupted", "ami-xr: terminated"), err
    assert took < 2.0, f"{took:.2f} s"
    time.sleep(0.5)
    assert not [p for p in workers if _alive(p)]


def test_sigkill_of_the_command_ends_its_workers(frf_file):
    proc, workers = _start_busy(frf_file)
    proc.kill()
    proc.wait(10)
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline and [p for p in workers if _alive(p)]:
        time.sleep(0.2)
    left = [p for p in workers if _alive(p)]
    for pid in left:  # ours: cleaned up by pid
        os.kill(pid, signal.SIGKILL)
    assert not left, "worker processes outlived the killed command"


def test_distributed_logs_only_with_verbose(frf_file):
    quiet = _identify(frf_file, "--workers", "1", "--worker-memory", "100TB", timeout=120)
    assert quiet.returncode == 0, quiet.stderr
    assert "distributed" not in quiet.stderr and " - WARNING - " not in quiet.stderr
    loud = _identify(frf_file, "--workers", "1", "-v", timeout=120)
    assert loud.returncode == 0, loud.stderr
    assert "ami-xr: distributed." in loud.stderr


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
