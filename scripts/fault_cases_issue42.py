"""Issue 42 fault cases of ``scripts/fault_campaign.py``: the dask path, workers and threads.

``cluster``  (case ``i`` picks one of :data:`CLUSTER_KINDS`) ``identify --scheduler`` at an
             address with no scheduler, a silent server, an HTTP server; SIGINT/SIGTERM sent to
             the process group of ``identify --workers 2`` at a random moment once its workers
             run (one during their start-up reaches them: a known limit, docs/cli.md); SIGKILL of
             ``identify --workers 2`` and of ``batch --workers 2`` (no worker process may
             survive its parent); a file whose values overflow in the workers (no raw numpy
             warning); SIGINT to ``identify --workers 2`` alone while its workers start
             (``sigint-start-up``); the worker or the scheduler of ``identify --scheduler``
             killed at a random moment of the run (``lost-worker``, ``lost-scheduler``).
             Each must end in bounded time with exit 0 (finished first), 1 (one line
             naming the address), 130 or 143, no bug-class message, no process left.
``threads``  8 threads opening and identifying netCDF files in one process (a crash of
             netCDF/HDF5 is a SIGSEGV: "anything else").

Each case returns ``(category, case, outcome, detail)`` with the campaign's outcome strings.
Written against the console entry point and the public API; processes are started, signalled
and looked at through ``scripts/proc_harness.py`` (shared with the tests), which records each
command's exit code and stderr in ``SEEN`` for the campaign's audit.
"""

from __future__ import annotations

import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CLEAN, CORRECT, OTHER = "clean error", "correct result", "anything else"
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
    "sigint-start-up",
    "lost-worker",
    "lost-scheduler",
)
Outcome = tuple[str, str, str, str]


def _harness():
    """``scripts/proc_harness.py`` (the subprocess harness the tests share), from beside this
    file however this file was loaded."""
    import importlib.util

    module = sys.modules.get("proc_harness")
    if module is None:
        path = Path(__file__).resolve().with_name("proc_harness.py")
        spec = importlib.util.spec_from_file_location("proc_harness", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules["proc_harness"] = module
        spec.loader.exec_module(module)
    return module


H = _harness()
AMI_XR_RUN, BUG_CLASS = H.AMI_XR_RUN, H.BUG_CLASS


def _one_line(code: int | None, err: str, *words: str) -> tuple[str, str]:
    lines = err.strip().splitlines()
    bugs = H.problems(err)
    ok = code == 1 and len(lines) == 1 and not bugs and all(w in err for w in words)
    return (CLEAN if ok else OTHER), f"exit {code}: {err.strip()[-300:]}"


def _scheduler_case(kind: str, frf: Path, cwd: Path) -> tuple[str, str]:
    server = None
    if kind == "no-scheduler":
        port = H.free_port()
    else:
        server = H.Server(None if kind == "silent-server" else b"HTTP/1.0 400 Bad Request\r\n\r\n")
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
    H.SEEN.append((done.returncode, done.stderr))
    return _one_line(done.returncode, done.stderr, address)


def _signal_case(kind: str, frf: Path, cwd: Path, rng: random.Random) -> tuple[str, str]:
    """SIGINT/SIGTERM to the group of ``identify --workers 2`` once its workers run (or to the
    command alone while they start), or SIGKILL of the command."""
    argv = [*AMI_XR_RUN, "identify", str(frf), "-q", "--workers", "2", "--chunk-points", "1"]
    proc = H.start(argv, cwd=cwd)
    start_up = kind == "sigint-start-up"
    workers = H.workers_of(proc, 1 if start_up else 2, ready=not start_up)
    time.sleep(rng.uniform(0.0, 0.5 if start_up else 4.0))
    sig = {"sigkill-workers": signal.SIGKILL, "sigterm-workers": signal.SIGTERM}.get(
        kind, signal.SIGINT
    )
    code, _, err, took = H.stop(proc, sig, group=not start_up and sig != signal.SIGKILL)
    workers = sorted(set(workers + [p for p in H.children(proc.pid) if H.spawned(p)]))
    if code is None:
        return OTHER, "hang (no exit within 30 s of the signal)"
    left = H.kill_left(workers, 5.0)
    if left:
        return OTHER, f"worker process(es) {left} outlived the command"
    if sig == signal.SIGKILL:
        return CLEAN, f"SIGKILL; workers gone (exit {code})"
    expected = 130 if sig == signal.SIGINT else 143
    bugs = H.problems(err)
    if code == 0 and not bugs:
        return CORRECT, "finished before the signal"
    ok = code == expected and not bugs and took <= HONOUR_S
    return (CLEAN if ok else OTHER), f"exit {code} after {took:.2f} s: {err[-300:]}"


def _lost_case(kind: str, frf: Path, cwd: Path, rng: random.Random) -> tuple[str, str]:
    """``identify --scheduler`` on a scheduler with one worker; the worker or the scheduler
    killed at a random moment of the run: exit 0 (finished first) or one line naming the
    address, within the cluster timeout and a margin."""
    port = H.free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = H.scheduler(port)
    if scheduler is None:
        return OTHER, "harness: the dask scheduler did not start"
    worker = H.worker(address)
    if not H.wait_for_workers(address):
        H.end(worker, scheduler)
        return OTHER, "harness: the dask worker did not join"
    try:
        proc = H.start(
            [*AMI_XR_RUN, "identify", str(frf), "-q", "--scheduler", address,
             "--cluster-timeout", "2", "--chunk-points", "2"],
            cwd=cwd,
        )
        if not H.connected(proc, port):
            H.end(proc)
            return OTHER, "identify did not reach its scheduler within 60 s"
        time.sleep(rng.uniform(0.0, 3.0))
        (worker if kind == "lost-worker" else scheduler).kill()
        try:
            _, err = proc.communicate(timeout=40)
        except subprocess.TimeoutExpired:
            H.end(proc)
            return OTHER, f"hang (no exit within 40 s of the {kind})"
    finally:
        H.end(worker, scheduler)
    code = proc.returncode
    H.SEEN.append((code, err))
    if code == 0 and not H.problems(err):
        return CORRECT, "finished before the kill"
    words = "all dask workers were lost" if kind == "lost-worker" else "lost the connection"
    return _one_line(code, err, address, words)


def _batch_kill_case(frf: Path, cwd: Path, rng: random.Random) -> tuple[str, str]:
    folder = cwd / "in"
    folder.mkdir()
    for k in range(4):
        shutil.copy(frf, folder / f"f{k}.nc")
    proc = H.start(
        [*AMI_XR_RUN, "batch", "in", "-o", "out", "-q", "--workers", "2"],
        cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    workers = H.workers_of(proc, 2, ready=False, forked=True)
    time.sleep(rng.uniform(0.0, 2.0))
    proc.kill()
    proc.wait(10)
    left = H.kill_left(workers, 5.0)
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
    H.SEEN.append((done.returncode, done.stderr))
    raw = "RuntimeWarning" in done.stderr or "overflow encountered" in done.stderr
    bugs = H.problems(done.stderr)
    ok = done.returncode in (0, 1) and not raw and not bugs
    return (CLEAN if ok else OTHER), f"exit {done.returncode}: {done.stderr[-300:]}"


def cluster_case(i: int, seed: int, work: Path, frf: Path) -> Outcome:
    """One ``cluster`` case (kind ``CLUSTER_KINDS[i % len(CLUSTER_KINDS)]``) on the FRF file ``frf``."""
    kind = CLUSTER_KINDS[i % len(CLUSTER_KINDS)]
    rng = random.Random(seed)
    case_dir = Path(tempfile.mkdtemp(dir=work, prefix="cluster"))
    try:
        if kind in ("no-scheduler", "silent-server", "http-server"):
            outcome, detail = _scheduler_case(kind, frf, case_dir)
        elif kind.startswith("sig") and kind != "sigkill-batch":
            outcome, detail = _signal_case(kind, frf, case_dir, rng)
        elif kind.startswith("lost"):
            outcome, detail = _lost_case(kind, frf, case_dir, rng)
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
        H.SEEN.append((done.returncode, ""))  # library use in threads: only a crash counts
        code = done.returncode
        ok = code == 0
        detail = f"exit {code}" + ("" if ok else f": {done.stdout[-200:]}{done.stderr[-300:]}")
        return "threads", f"8 threads x {2 + i % 3}", CORRECT if ok else OTHER, detail
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)
