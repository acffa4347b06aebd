"""One subprocess harness for the fault tests and the campaign (issue 42).

``scripts/fault_cases_issue42.py`` (campaign), ``tests/app/test_cluster_faults.py``,
``tests/app/test_cluster_interrupt.py`` and ``tests/app/test_batch_parent_death.py`` start the
``ami-xr`` entry point, dask schedulers and workers as real processes, send signals, and look
at the processes left behind. What they share lives here, once: the command line of the
console script, a free port, the child processes of a process and whether one is alive, the
local dask workers of a command (started, and past their preload), a process stopped by a
signal and timed, a TCP server that is not a dask scheduler, a dask scheduler and worker.

Linux only (``/proc``). Tests load this file by path (``tests/app/proc.py``); every process it starts
or finds is ended by its pid, never by name.
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

#: The console script as installed: ``run()`` holds signals for the safe points.
AMI_XR_RUN = [sys.executable, "-c", "from ami_xr.app.cli import run; run()"]
#: What a message must never contain (a crash, a traceback, an unexpected error).
BUG_CLASS = ("Traceback (most recent call last)", "unexpected", "SystemError", "Segmentation")
#: ``distributed``'s and tornado's own log lines (to be routed to ami_xr's quiet logger).
FOREIGN_LOG = (" - distributed.", " - tornado.", "distributed.nanny", "distributed.worker")
#: (exit code, stderr) of every command :func:`stop` ended, for the campaign's audit.
SEEN: list[tuple[int | None, str]] = []


def env(root: Path | None = None, **extra: str) -> dict[str, str]:
    """This environment with ``root`` (the tree under test) first on ``PYTHONPATH``."""
    out = dict(os.environ)
    if root is not None:
        out["PYTHONPATH"] = os.pathsep.join(filter(None, [str(root), out.get("PYTHONPATH")]))
    out.update(extra)
    return out


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def children(pid: int) -> list[int]:
    """Process ids of the direct children of ``pid`` (of any of its threads)."""
    found: list[int] = []
    try:
        tasks = list(Path(f"/proc/{pid}/task").iterdir())
    except OSError:
        return found
    for task in tasks:
        try:
            found += [int(p) for p in (task / "children").read_text().split()]
        except OSError:
            continue
    return sorted(set(found))


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie does not)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ")
    except OSError:
        return b""


def spawned(pid: int) -> bool:
    """Whether ``pid`` is a multiprocessing child (a local dask worker, a batch worker)."""
    cmd = cmdline(pid)
    return b"spawn_main" in cmd or b"forkserver" in cmd or b"multiprocessing-fork" in cmd


def ignores_sigint(pid: int) -> bool:
    """Whether ``pid`` ignores SIGINT (a local dask worker once its preload has run)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    ignored = [line.split()[1] for line in status.splitlines() if line.startswith("SigIgn")]
    return bool(ignored) and bool(int(ignored[0], 16) & (1 << (signal.SIGINT - 1)))


def kill_left(pids: list[int], within: float) -> list[int]:
    """The processes of ``pids`` still alive after ``within`` s (then killed, by pid)."""
    deadline = time.monotonic() + within
    while time.monotonic() < deadline and any(alive(p) for p in pids):
        time.sleep(0.1)
    left = [p for p in pids if alive(p)]
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
    return left


def start(argv: list[str], cwd: Path | None = None, environ=None, **kw) -> subprocess.Popen:
    """``argv`` in a new session (its own process group), stdout and stderr piped as text."""
    kw.setdefault("stdout", subprocess.PIPE)
    kw.setdefault("stderr", subprocess.PIPE)
    return subprocess.Popen(
        argv, cwd=cwd, text=True, env=environ, start_new_session=True, **kw
    )


def workers_of(
    proc: subprocess.Popen, n: int, bound: float = 60.0, ready: bool = True, forked: bool = False
) -> list[int]:
    """The first ``n`` multiprocessing children of ``proc`` (within ``bound`` s); with
    ``ready`` only once each ignores SIGINT (a local dask worker past its preload); ``forked``:
    any child (a batch's workers are forked, with the command's own command line)."""
    deadline = time.monotonic() + bound
    found: list[int] = []
    while time.monotonic() < deadline and proc.poll() is None:
        found = [p for p in children(proc.pid) if forked or spawned(p)]
        if len(found) >= n and (not ready or all(ignores_sigint(p) for p in found)):
            break
        time.sleep(0.05)
    return found


def stop(proc: subprocess.Popen, signum: int, group: bool = False, bound: float = 30.0):
    """Send ``signum`` to ``proc`` (or its whole group, as a terminal's Ctrl-C does) and wait:
    ``(exit code or None on a hang, stdout, stderr, seconds to the exit)``; a hang is killed."""
    start_ = time.monotonic()
    try:
        if group:
            os.killpg(proc.pid, signum)
        else:
            os.kill(proc.pid, signum)
    except OSError:
        pass
    try:
        out, err = proc.communicate(timeout=bound)
    except subprocess.TimeoutExpired:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except OSError:
            pass
        out, err = proc.communicate()
        SEEN.append((None, err or ""))
        return None, out, err, time.monotonic() - start_
    SEEN.append((proc.returncode, err or ""))
    return proc.returncode, out, err, time.monotonic() - start_


def problems(err: str) -> list[str]:
    """What must not be on stderr: bug-class messages, raw tracebacks, foreign log lines."""
    found = [b for b in BUG_CLASS if b in err]
    found += [f"foreign log line {f!r}" for f in FOREIGN_LOG if f in err]
    return found


class Server(threading.Thread):
    """A TCP server that is not a dask scheduler: answers ``reply`` (e.g. like an HTTP server)
    to every connection, or stays silent (``None``)."""

    def __init__(self, reply: bytes | None) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.reply, self.halt, self.conns = reply, threading.Event(), []

    def run(self) -> None:
        while not self.halt.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            self.conns.append(conn)
            if self.reply is not None:
                conn.sendall(self.reply)

    def close(self) -> None:
        self.halt.set()
        self.join()
        for conn in self.conns:
            conn.close()
        self.sock.close()


def scheduler(port: int, environ=None, bound: float = 30.0) -> subprocess.Popen | None:
    """A dask scheduler on ``127.0.0.1:port`` once it accepts connections (None: it did not)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
         "--port", str(port), "--no-dashboard"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=environ,
    )
    deadline = time.monotonic() + bound
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return proc
        time.sleep(0.2)
    proc.kill()
    proc.wait(10)
    return None


def wait_for_workers(address: str, n: int = 1, bound: float = 60.0, environ=None) -> bool:
    """Whether ``n`` workers joined the scheduler at ``address`` within ``bound`` s (asked by a
    client in a process of its own: no dask thread in this one, which may fork)."""
    code = (
        "import sys; from distributed import Client; "
        f"c = Client({address!r}, timeout={bound}); c.wait_for_workers({n}, timeout={bound}); "
        "c.close()"
    )
    try:
        done = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, env=environ, timeout=bound + 30
        )
    except subprocess.TimeoutExpired:
        return False
    return done.returncode == 0


def connected(proc: subprocess.Popen, port: int, bound: float = 60.0) -> bool:
    """Whether ``proc`` holds a TCP connection to ``port`` on this host within ``bound`` s (a
    client that reached its scheduler)."""
    import psutil  # a dependency of distributed

    deadline = time.monotonic() + bound
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            conns = psutil.Process(proc.pid).net_connections(kind="tcp")
        except (psutil.Error, AttributeError):
            conns = []
        if any(c.raddr and c.raddr.port == port for c in conns):
            return True
        time.sleep(0.1)
    return False


def worker(address: str, environ=None) -> subprocess.Popen:
    """One single-threaded dask worker (no nanny) of the scheduler at ``address``."""
    return subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
         "--no-nanny", "--no-dashboard"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=environ,
    )


def end(*procs: subprocess.Popen) -> None:
    """Kill (by pid) and reap each of ``procs`` still running."""
    for proc in procs:
        if proc is not None and proc.poll() is None:
            proc.kill()
        if proc is not None:
            proc.wait(10)


SLOW_WORKER_SITE = (
    "import os, sys, time\n"
    "if '--multiprocessing-fork' in sys.argv:\n"
    "    time.sleep(float(os.environ.get('AMI_XR_TEST_WORKER_DELAY', '0')))\n"
)


def slow_worker_env(folder: Path, seconds: float, root: Path | None = None) -> dict[str, str]:
    """An environment whose multiprocessing children (the local dask workers) each sleep
    ``seconds`` as they start (a ``sitecustomize`` in ``folder``): a cluster start-up that
    lasts, as on a loaded machine."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "sitecustomize.py").write_text(SLOW_WORKER_SITE)
    out = env(root, AMI_XR_TEST_WORKER_DELAY=str(seconds))
    out["PYTHONPATH"] = os.pathsep.join([str(folder), out.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return out
