"""Identification of 1e3, 1e4 (and 1e5 with --full) FRFs x 4096 lines on a dask LocalCluster.

    python scripts/bench_scale.py                 # 1e3 and 1e4 points, 1 and 2 workers
    python scripts/bench_scale.py --full          # 1e3, 1e4, 1e5 points (about 6.5 GB on disk)
                                                  # x 4096 lines, and 1e3, 1e4 x 1024 lines
                                                  # (the exponent in lines); 2 workers
    python scripts/bench_scale.py --points 1000 2000 --workers 2   # chosen sizes
    python scripts/bench_scale.py --points 1000 --lines 1024 4096 --workers 2  # lines exponent
    python scripts/bench_scale.py --points 1000 --workers 2 --compress off  # every phase on
                                                  # every point (no virtual FRFs)

Each set (:func:`ami_xr.simulate.spread.many_points`: 12 modes, 2 % noise; larger sets repeat
the first 1000 points' FRFs scaled per point by a seeded factor in [0.5, 2], built and written
block by block so that writing never holds more than 1000 FRFs) is written to a netCDF file in
``--dir``, opened lazily (``--chunk`` FRFs per chunk) and identified by :func:`ami_xr.identify`
with a ``dask.distributed`` client on a ``LocalCluster`` (single-threaded workers, ``--memory``
each), ``compress=`` as ``--compress`` says ("auto" by default; "off": every phase on every
point, where the SIMO isolation and the refinement load the FRF into the client). Printed per
run: wall time, CPU seconds of the workers and of the client process (the
scheduler of a LocalCluster runs there; on a shared machine the CPU time is what the wall time
would be without the other processes, times the cores used), peak worker memory (the largest
RSS any worker reported, sampled every 0.2 s) against the limit, client memory growth (RSS
after minus before) and the client's peak growth (largest RSS during the run minus before,
sampled likewise), modes found; at the end the growth exponents of wall time and of total CPU
time against points and against lines (least-squares slopes of log t on log P and on log L)
per worker count. Before the first run one small identification warms the client (imports,
compiled kernels), so that the client figures are those of the run itself.
Written against ami_xr's public API.
"""

from __future__ import annotations

import argparse
import os
import threading
import time
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

import ami_xr
from ami_xr.simulate.spread import many_points

LINES = 4096


def _rss_mb() -> float:
    import psutil

    return psutil.Process(os.getpid()).memory_info().rss / 2**20


def write_set(n_points: int, path: Path, chunk: int, lines: int = LINES) -> None:
    """The simulated set of ``n_points`` FRFs x ``lines`` lines, written block by block (a
    lazy FRF of 1000-FRF blocks: memory of one block, whatever ``n_points``)."""
    if path.exists():
        return
    base, _ = many_points(min(n_points, 1000), lines, 12, noise=0.02, seed=0)
    if n_points > 1000:
        import dask
        import dask.array as da

        first = base["frf"].values

        def block(k: int) -> np.ndarray:
            return first * np.random.default_rng(1 + k).uniform(0.5, 2.0, (first.shape[0], 1))

        reps = -(-n_points // 1000)
        frf = da.concatenate(
            [
                da.from_delayed(dask.delayed(block)(k), shape=first.shape, dtype=first.dtype)
                for k in range(reps)
            ]
        )[:n_points].rechunk({0: chunk})
        attrs = base["frf"].attrs
        base = base.drop_vars("frf").isel(point=np.arange(n_points) % 1000)
        base = base.assign_coords(point=np.arange(n_points))
        base["frf"] = (("point", "frequency"), frf, attrs)
    ami_xr.to_netcdf(base, path)


def run(path: Path, workers: int, memory: str, chunk: int, compress: str | int = "auto") -> Row:
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            memory_limit=memory,
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):
        peak = [0.0]
        stop = threading.Event()

        def sample():
            while not stop.is_set():
                try:
                    info = client.run(lambda: __import__("psutil").Process().memory_info().rss)
                    peak[0] = max(peak[0], max(info.values()) / 2**20)
                except Exception:  # noqa: BLE001 - a missed sample is not a result
                    pass
                stop.wait(0.2)

        ds = ami_xr.open_dataset(path, chunks={"point": chunk})
        before = _rss_mb()
        client_peak = [before]

        def sample_client():
            while not stop.is_set():
                client_peak[0] = max(client_peak[0], _rss_mb())
                stop.wait(0.2)

        threading.Thread(target=sample_client, daemon=True).start()
        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        cpu0, worker0 = time.process_time(), _worker_cpu(client)
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = ami_xr.identify(ds, compress=compress)
        seconds = time.perf_counter() - t0
        stop.set()
        sampler.join()
        worker_cpu = _worker_cpu(client) - worker0
        client_cpu = time.process_time() - cpu0
        growth = _rss_mb() - before
        ds.close()
    return Row(
        seconds,
        worker_cpu,
        client_cpu,
        peak[0],
        growth,
        client_peak[0] - before,
        int(out.sizes.get("mode", 0)),
    )


class Row(NamedTuple):
    """One run's figures (seconds, MB)."""

    wall: float
    worker_cpu: float
    client_cpu: float
    worker_peak: float
    client_growth: float
    client_peak: float
    modes: int


def _worker_cpu(client) -> float:
    """User + system CPU seconds of all worker processes so far."""

    def cpu() -> float:
        t = __import__("psutil").Process().cpu_times()
        return t.user + t.system

    return float(sum(client.run(cpu).values()))


def warm_up(compress: str | int = "auto") -> None:
    """One small identification in this process (imports, compiled kernels, caches)."""
    ds, _ = many_points(300, 512, 12, noise=0.02, seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ami_xr.identify(ds, compress=compress)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="1e3, 1e4, 1e5 points, 2 workers")
    parser.add_argument("--points", type=int, nargs="+", default=None)
    parser.add_argument("--workers", type=int, nargs="+", default=None)
    parser.add_argument("--memory", default="2GB", help="memory limit per worker")
    parser.add_argument("--chunk", type=int, default=1000, help="FRFs per chunk")
    parser.add_argument("--dir", default="bench_scale_data", help="where the sets are written")
    parser.add_argument("--lines", type=int, nargs="+", default=None, help="lines per FRF")
    parser.add_argument(
        "--compress", default="auto", help="identify's compress: auto (default), off or an int"
    )
    args = parser.parse_args(argv)
    compress = int(args.compress) if args.compress.isdigit() else args.compress
    if compress not in ("auto", "off") and not isinstance(compress, int):
        parser.error(f"--compress: expected auto, off or an int, got {args.compress!r}")
    sizes = args.points or ([1000, 10_000, 100_000] if args.full else [1000, 10_000])
    lines = args.lines or [LINES]
    workers = args.workers or ([2] if args.full else [1, 2])
    runs = [(n, m) for n in sizes for m in lines]
    if args.full and not args.lines:  # the exponent in lines, on the two smaller sizes
        runs = sorted(runs + [(n, 1024) for n in sizes if n <= 10_000])
    folder = Path(args.dir)
    folder.mkdir(parents=True, exist_ok=True)
    print(
        f"bench_scale: {sizes} FRFs x {sorted({m for _, m in runs})} lines, 12 modes; workers "
        f"{workers}, {args.memory} each; compress={compress}; cpu_count {os.cpu_count()}; "
        f"load average {os.getloadavg()[0]:.1f}"
    )
    warm_up(compress)
    print(
        f"{'points':>8}{'lines':>7}{'workers':>8}{'wall s':>9}{'worker cpu s':>14}"
        f"{'client cpu s':>14}{'peak worker MB':>16}{'client +MB':>12}{'client peak +MB':>17}"
        f"{'modes':>7}",
        flush=True,
    )
    rows: list[tuple[int, int, int, float, float]] = []
    for n, m in runs:
        path = folder / (f"spread_{n}.nc" if m == LINES else f"spread_{n}_{m}.nc")
        write_set(n, path, args.chunk, m)
        for w in workers:
            r = run(path, w, args.memory, args.chunk, compress)
            rows.append((n, m, w, r.wall, r.worker_cpu + r.client_cpu))
            print(
                f"{n:>8}{m:>7}{w:>8}{r.wall:>9.1f}{r.worker_cpu:>14.1f}{r.client_cpu:>14.1f}"
                f"{r.worker_peak:>16.0f}{r.client_growth:>12.1f}{r.client_peak:>17.0f}"
                f"{r.modes:>7}",
                flush=True,
            )
    print(f"worker memory limit: {args.memory}; load average now {os.getloadavg()[0]:.1f}")
    for w in workers:
        for label, axis, fixed in (("points", 0, 1), ("lines", 1, 0)):
            # slope at the largest value of the other size that has two or more runs
            mine = [r for r in rows if r[2] == w]
            for other in sorted({r[fixed] for r in mine}, reverse=True):
                pts = [r for r in mine if r[fixed] == other]
                if len({r[axis] for r in pts}) > 1:
                    x = np.log([r[axis] for r in pts])
                    slopes = [np.polyfit(x, np.log([r[k] for r in pts]), 1)[0] for k in (3, 4)]
                    print(
                        f"growth exponent against {label} ({'lines' if axis == 0 else 'points'}"
                        f" = {other}), {w} worker(s): wall {slopes[0]:.2f}, cpu {slopes[1]:.2f}"
                    )
                    break
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
