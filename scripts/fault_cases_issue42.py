"""Issue 42 fault cases of ``scripts/fault_campaign.py``: the dask path, workers and threads.

``cluster``  (case ``i`` picks one of :data:`CLUSTER_KINDS`) ``identify --scheduler`` at an
             address with no scheduler, a silent server, an HTTP server; SIGINT/SIGTERM sent to
             the process group of ``identify --workers 2`` at a random moment once its workers
             run (one during their start-up reaches them: a known limit, docs/cli.md); SIGKILL of
             ``identify --workers 2`` and of ``batch --workers 2`` (no worker process may
             survive its parent); a file whose values overflow in the workers (no raw numpy
             warning). Each must end in bounded time with exit 0 (finished first), 1 (one line
             naming the address), 130 or 143, no bug-class message, no process left.
``threads``  8 threads opening and identifying netCDF files in one process (a crash of
             netCDF/HDF5 is a SIGSEGV: "anything else").

Each case returns ``(category, case, outcome, detail)`` with the campaign's outcome strings.
Written against the console entry point and the public API.
"""

from __future__ import annotations

import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

CLEAN, CORRECT, OTHER = "clean error", "correct result", "anything else"
AMI_XR_RUN = [sys.executable, "-c", "from ami_xr.app.cli import run; run()"]
BUG_CLASS = ("Traceback (most recent call last)", "unexpected", "SystemError", "Segmentation")
HONOUR_S = 2.0
CLUSTER_KINDS = (
    "no-scheduler",
    "silent-server",
    "http-server",
    "sigint-workers",
    "sigterm-workers",
    "sigkill-workers",
    "sigkill-batch",
    "overflow-workers",
)
Outcome = tuple[str, str, str, str]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _children(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True)
    return [int(p) for p in out.stdout.split()]


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def _kill_left(pids: list[int], within: float) -> list[int]:
    """The processes of ``pids`` still alive after ``within`` s (then killed, by pid)."""
    deadline = time.monotonic() + within
    while time.monotonic() < deadline and any(_alive(p) for p in pids):
        time.sleep(0.2)
    left = [p for p in pids if _alive(p)]
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
    return left


def _one_line(code: int | None, err: str, *words: str) -> tuple[str, str]:
    lines = err.strip().splitlines()
    bugs = [b for b in BUG_CLASS if b in err]
    ok = code == 1 and len(lines) == 1 and not bugs and all(w in err for w in words)
    return (CLEAN if ok else OTHER), f"exit {code}: {err.strip()[-300:]}"


class _Server(threading.Thread):
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


def _scheduler_case(kind: str, frf: Path, cwd: Path) -> tuple[str, str]:
    server = None
    if kind == "no-scheduler":
        port = _free_port()
    else:
        server = _Server(None if kind == "silent-server" else b"HTTP/1.0 400 Bad Request\r\n\r\n")
        server.start()
        port = server.port
    address = f"tcp://127.0.0.1:{port}"
    try:
        done = subprocess.run(
            [*AMI_XR_RUN, "identify", str(frf), "--scheduler", address, "--cluster-timeout", "2"],
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=60,
        )
    except subprocess.TimeoutExpired:
        return OTHER, "hang (no exit within 60 s)"
    finally:
        if server is not None:
            server.close()
    return _one_line(done.returncode, done.stderr, address)


def _workers_of(proc: subprocess.Popen, n: int, bound: float = 60.0) -> list[int]:
    """The ``n`` local worker processes of ``proc`` once each ignores SIGINT (their preload
    has run: a Ctrl-C that comes while they still start reaches them, see docs/cli.md)."""
    deadline = time.monotonic() + bound
    found: list[int] = []
    while time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.2)
        found = [p for p in _children(proc.pid) if _spawned(p)]
        if len(found) >= n and all(_ignores_sigint(p) for p in found):
            break
    return found


def _ignores_sigint(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    ignored = [line.split()[1] for line in status.splitlines() if line.startswith("SigIgn")]
    return bool(ignored) and bool(int(ignored[0], 16) & (1 << (signal.SIGINT - 1)))


def _spawned(pid: int) -> bool:
    try:
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False
    return b"spawn_main" in cmd or b"forkserver" in cmd or not cmd.strip(b"\0")


def _signal_case(kind: str, frf: Path, cwd: Path, rng: random.Random) -> tuple[str, str]:
    argv = [*AMI_XR_RUN, "identify", str(frf), "-q", "--workers", "2", "--chunk-points", "1"]
    proc = subprocess.Popen(
        argv, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,
    )
    workers = _workers_of(proc, 2)
    time.sleep(rng.uniform(0.0, 4.0))  # the work under way
    sig = {"sigint-workers": signal.SIGINT, "sigterm-workers": signal.SIGTERM}.get(kind)
    start = time.monotonic()
    try:
        if sig is None:
            proc.kill()
        else:
            os.killpg(proc.pid, sig)
    except OSError:
        pass
    try:
        _, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        return OTHER, "hang (no exit within 30 s of the signal)"
    took = time.monotonic() - start
    left = _kill_left(workers, 5.0)
    if left:
        return OTHER, f"worker process(es) {left} outlived the command"
    if sig is None:
        return CLEAN, f"SIGKILL; workers gone (exit {proc.returncode})"
    expected = 130 if sig == signal.SIGINT else 143
    bugs = [b for b in BUG_CLASS if b in err]
    if proc.returncode == 0 and not bugs:
        return CORRECT, "finished before the signal"
    ok = proc.returncode == expected and not bugs and took <= HONOUR_S
    return (CLEAN if ok else OTHER), f"exit {proc.returncode} after {took:.2f} s: {err[-300:]}"


def _batch_kill_case(frf: Path, cwd: Path, rng: random.Random) -> tuple[str, str]:
    folder = cwd / "in"
    folder.mkdir()
    for k in range(4):
        shutil.copy(frf, folder / f"f{k}.nc")
    proc = subprocess.Popen(
        [*AMI_XR_RUN, "batch", "in", "-o", "out", "-q", "--workers", "2"],
        cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 60
    workers: list[int] = []
    while time.monotonic() < deadline and len(workers) < 2 and proc.poll() is None:
        time.sleep(0.1)
        workers = _children(proc.pid)
    time.sleep(rng.uniform(0.0, 2.0))
    proc.kill()
    proc.wait(10)
    left = _kill_left(workers, 5.0)
    partial = [p.name for p in (cwd / "out").rglob("*") if p.is_file() and ".tmp" in str(p)]
    if left:
        return OTHER, f"batch worker(s) {left} outlived the killed batch"
    return CLEAN, f"workers gone; temporary files left for the next run: {len(partial)}"


def _overflow_case(frf: Path, cwd: Path) -> tuple[str, str]:
    import ami_xr
    from ami_xr import names

    g = ami_xr.open_dataset(frf)
    values = g[names.FRF].values.copy()
    values[:, values.shape[1] // 3] = 1e308
    spike = cwd / "spike.nc"
    ami_xr.to_netcdf(g.assign({names.FRF: g[names.FRF].copy(data=values)}), spike)
    try:
        done = subprocess.run(
            [*AMI_XR_RUN, "identify", str(spike), "-q", "--workers", "1"],
            cwd=cwd, capture_output=True, text=True, timeout=120,
        )
    except subprocess.TimeoutExpired:
        return OTHER, "hang (no exit within 120 s)"
    raw = "RuntimeWarning" in done.stderr or "overflow encountered" in done.stderr
    bugs = [b for b in BUG_CLASS if b in done.stderr]
    ok = done.returncode in (0, 1) and not raw and not bugs
    return (CLEAN if ok else OTHER), f"exit {done.returncode}: {done.stderr[-300:]}"


def cluster_case(i: int, seed: int, work: Path, frf: Path) -> Outcome:
    """One ``cluster`` case (kind ``CLUSTER_KINDS[i % 8]``) on the FRF file ``frf``."""
    kind = CLUSTER_KINDS[i % len(CLUSTER_KINDS)]
    rng = random.Random(seed)
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="cluster"))
    try:
        if kind in ("no-scheduler", "silent-server", "http-server"):
            outcome, detail = _scheduler_case(kind, frf, case_dir)
        elif kind in ("sigint-workers", "sigterm-workers", "sigkill-workers"):
            outcome, detail = _signal_case(kind, frf, case_dir, rng)
        elif kind == "sigkill-batch":
            outcome, detail = _batch_kill_case(frf, case_dir, rng)
        else:
            outcome, detail = _overflow_case(frf, case_dir)
        return "cluster", f"identify/batch: {kind}", outcome, detail
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


THREADS_CHILD = r"""
import sys, threading, warnings
import ami_xr
paths, repeats = sys.argv[1:-1], int(sys.argv[-1])
errors = []
def work(k):
    try:
        for r in range(repeats):
            ds = ami_xr.open_dataset(paths[(k + r) % len(paths)])
            lazy = ami_xr.open_dataset(paths[(k + r + 1) % len(paths)], chunks={"point": 1})
            lazy.load(); lazy.close()
            with warnings.catch_warnings():
                warnings.simplefilter("always")
                ami_xr.identify(ds, progress=True, refine=False)
    except Exception as err:
        errors.append(f"{type(err).__name__}: {err}")
threads = [threading.Thread(target=work, args=(k,)) for k in range(8)]
[t.start() for t in threads]
[t.join() for t in threads]
print(errors)
sys.exit(1 if errors else 0)
"""


def threads_case(i: int, work: Path, frf: Path) -> Outcome:
    """8 threads opening (eagerly and lazily) and identifying copies of ``frf``."""
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="threads"))
    try:
        paths = []
        for k in range(4):
            paths.append(str(shutil.copy(frf, case_dir / f"f{k}.nc")))
        try:
            done = subprocess.run(
                [sys.executable, "-c", THREADS_CHILD, *paths, str(2 + i % 3)],
                capture_output=True, text=True, timeout=600,
            )
        except subprocess.TimeoutExpired:
            return "threads", "8 threads", OTHER, "hang (no exit within 600 s)"
        code = done.returncode
        ok = code == 0
        detail = f"exit {code}" + ("" if ok else f": {done.stdout[-200:]}{done.stderr[-300:]}")
        return "threads", f"8 threads x {2 + i % 3}", CORRECT if ok else OTHER, detail
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)
