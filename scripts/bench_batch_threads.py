"""Threads in a batch (issue 38 item 5): ``ami-xr batch --workers 2`` against ``--workers 1``.

Writes ``--files`` simulated FRF sets of measured size (``--points`` x ``--lines``, 1 % noise)
to a temporary folder, runs :func:`ami_xr.batch` on them once with one worker and once with two
(``force=True``: every file identified in both runs), and prints per run the wall time, the CPU
time of the parent and its worker processes, the threads one worker process ran over the batch
(distinct thread ids: short-lived ones count) and how many of them computed at once (sampled from
``/proc`` while the batch runs; Linux only, else "-"; one worker runs in the parent process, so
the one-worker row has none). The target: two workers on a two-core machine not slower than
one, and no worker running more compute threads than the core it is given (identification
holds BLAS to one thread, no kernel is parallel).

Usage::

    python scripts/bench_batch_threads.py              # 8 files of 12 x 8192 lines
    python scripts/bench_batch_threads.py --quick      # 4 files of 6 x 2048 lines
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import threading
import time
import warnings
from pathlib import Path

import ami_xr

sys.path.insert(0, str(Path(__file__).resolve().parent))
import proc_harness  # noqa: E402  (the /proc walk shared with the fault campaign)


def _thread_cpu(pid: int) -> dict[int, float]:
    """CPU seconds of each thread of process ``pid`` (Linux /proc; empty elsewhere)."""
    tick = os.sysconf("SC_CLK_TCK")
    out = {}
    try:
        tasks = list(Path(f"/proc/{pid}/task").iterdir())
    except OSError:
        return out
    for task in tasks:
        try:
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        out[int(task.name)] = (int(fields[11]) + int(fields[12])) / tick  # utime + stime
    return out


class _ThreadSampler:
    """The threads of this process's children while the batch runs: the most distinct threads
    one worker ran, and the most of them that computed at once (at least half of one
    sampling interval of 0.1 s on the CPU in that interval; short-lived pool threads count)."""

    INTERVAL = 0.1

    def __init__(self) -> None:
        self.seen: dict[int, set[int]] = {}
        self.busy = 0
        self._last: dict[tuple[int, int], float] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(self.INTERVAL):
            for child in proc_harness.children(os.getpid()):
                now = _thread_cpu(child)
                self.seen.setdefault(child, set()).update(now)
                gained = sum(
                    cpu - self._last.get((child, tid), 0.0) >= 0.5 * self.INTERVAL
                    for tid, cpu in now.items()
                )
                self.busy = max(self.busy, int(gained))
                self._last.update({(child, tid): cpu for tid, cpu in now.items()})

    @property
    def peak(self) -> tuple[int, int]:
        """(most distinct threads of one worker, most threads of one worker computing at once)."""
        if not self.seen:
            return 0, 0
        return max(len(t) for t in self.seen.values()), self.busy

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


def _cpu_seconds() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def make_files(folder: Path, n_files: int, n_points: int, n_lines: int) -> None:
    """``n_files`` simulated FRF sets as netCDF (lumped chains, one mode per point, 1 % noise)."""
    for i in range(n_files):
        frf, _ = ami_xr.simulate.random_system(
            n_points=n_points, n_modes=n_points, noise=0.01, seed=100 + i, n_frequencies=n_lines
        )
        ami_xr.to_netcdf(frf, folder / f"set{i:02d}.nc")


def run(folder: Path, out: Path, workers: int) -> dict:
    """One batch over ``folder``: wall and CPU seconds, peak worker threads, files failed."""
    cpu, wall = _cpu_seconds(), time.perf_counter()
    with _ThreadSampler() as sampler, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rows = ami_xr.batch(folder, out, workers=workers, force=True, progress=False).rows
    return {
        "wall": time.perf_counter() - wall,
        "cpu": _cpu_seconds() - cpu,
        "threads": sampler.peak,
        "failed": sum(r["status"] == "failed" for r in rows),
        "files": len(rows),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, default=8)
    parser.add_argument("--points", type=int, default=12)
    parser.add_argument("--lines", type=int, default=8192)
    parser.add_argument("--quick", action="store_true", help="4 files of 6 x 2048 lines")
    args = parser.parse_args(argv)
    if args.quick:
        args.files, args.points, args.lines = 4, 6, 2048
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(
        f"batch of {args.files} files of {args.points} points x {args.lines} lines, "
        f"{cores} core(s), load {os.getloadavg()[0]:.1f}"
    )
    with tempfile.TemporaryDirectory(prefix="ami_xr_batch_threads_") as tmp:
        folder, out = Path(tmp) / "in", Path(tmp) / "out"
        folder.mkdir()
        make_files(folder, args.files, args.points, args.lines)
        run(folder, out, 1)  # warm the kernel cache: neither timed run pays the first compile
        results = {w: run(folder, out, w) for w in (1, 2)}
    print(
        f"{'workers':>8} {'wall s':>8} {'CPU s':>8} {'threads seen':>15} "
        f"{'at once':>10} {'failed':>7}"
    )
    for w, r in results.items():
        every, busy = r["threads"] if r["threads"][0] else ("-", "-")
        print(
            f"{w:>8} {r['wall']:8.1f} {r['cpu']:8.1f} {every!s:>15} {busy!s:>10} {r['failed']:>7}"
        )
    ratio = results[2]["wall"] / results[1]["wall"]
    verdict = "met" if ratio <= 1.0 else "NOT met"
    print(f"wall time, 2 workers / 1 worker: {ratio:.2f} (target <= 1 on >= 2 cores): {verdict}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
