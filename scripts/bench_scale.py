"""Identification of 1e3, 1e4 (and 1e5 with --full) FRFs x 4096 lines on a dask LocalCluster.

    python scripts/bench_scale.py                 # 1e3 and 1e4 points, 1 and 2 workers
    python scripts/bench_scale.py --full          # also 1e5 points (about 6.5 GB on disk)
    python scripts/bench_scale.py --points 1000 2000 --workers 2   # chosen sizes

Each set (:func:`ami_xr.simulate.spread.many_points`: 12 modes, 2 % noise; larger sets repeat
the first 1000 points' FRFs with fresh noise-free copies scaled per point, so writing stays
cheap) is written to a netCDF file chunked along ``point`` (``--chunk`` FRFs per chunk) in
``--dir``, opened lazily and identified by :func:`ami_xr.identify` with a
``dask.distributed`` client on a ``LocalCluster`` (single-threaded workers, ``--memory`` each).
Printed per run: wall time, peak worker memory (the largest RSS any worker reported, sampled
every 0.2 s), client memory growth (RSS after minus before), modes found; at the end the growth
exponent of time against points (least-squares slope of log t on log P) per worker count.
Written against ami_xr's public API.
"""

from __future__ import annotations

import argparse
import os
import threading
import time
import warnings
from pathlib import Path

import numpy as np

import ami_xr
from ami_xr.simulate.spread import many_points

LINES = 4096


def _rss_mb() -> float:
    import psutil

    return psutil.Process(os.getpid()).memory_info().rss / 2**20


def write_set(n_points: int, path: Path, chunk: int) -> None:
    """The simulated set of ``n_points`` FRFs x 4096 lines, written chunked along point."""
    if path.exists():
        return
    base, _ = many_points(min(n_points, 1000), LINES, 12, noise=0.02, seed=0)
    if n_points > 1000:
        reps = -(-n_points // 1000)
        rng = np.random.default_rng(1)
        frf = np.concatenate(
            [base["frf"].values * rng.uniform(0.5, 2.0, (1000, 1)) for _ in range(reps)]
        )[:n_points]
        base = base.isel(point=np.arange(n_points) % 1000).assign_coords(point=np.arange(n_points))
        base["frf"] = base["frf"].copy(data=frf)
    ami_xr.to_netcdf(base, path)


def run(path: Path, workers: int, memory: str, chunk: int) -> tuple[float, float, float, int]:
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
        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = ami_xr.identify(ds)
        seconds = time.perf_counter() - t0
        stop.set()
        sampler.join()
        growth = _rss_mb() - before
    return seconds, peak[0], growth, int(out.sizes.get("mode", 0))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="also 1e5 points")
    parser.add_argument("--points", type=int, nargs="+", default=None)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--memory", default="2GB", help="memory limit per worker")
    parser.add_argument("--chunk", type=int, default=1000, help="FRFs per chunk")
    parser.add_argument("--dir", default="bench_scale_data", help="where the sets are written")
    args = parser.parse_args(argv)
    sizes = args.points or ([1000, 10_000, 100_000] if args.full else [1000, 10_000])
    folder = Path(args.dir)
    folder.mkdir(parents=True, exist_ok=True)
    print(
        f"bench_scale: {sizes} FRFs x {LINES} lines, 12 modes; workers {args.workers}, "
        f"{args.memory} each; cpu_count {os.cpu_count()}"
    )
    print(
        f"{'points':>8}{'workers':>8}{'wall s':>9}{'peak worker MB':>16}"
        f"{'client +MB':>12}{'modes':>7}",
        flush=True,
    )
    times: dict[int, list[tuple[int, float]]] = {w: [] for w in args.workers}
    for n in sizes:
        path = folder / f"spread_{n}.nc"
        write_set(n, path, args.chunk)
        for w in args.workers:
            seconds, peak, growth, modes = run(path, w, args.memory, args.chunk)
            times[w].append((n, seconds))
            print(f"{n:>8}{w:>8}{seconds:>9.2f}{peak:>16.0f}{growth:>12.1f}{modes:>7}", flush=True)
    for w, rows in times.items():
        if len(rows) > 1:
            p, t = np.log([r[0] for r in rows]), np.log([r[1] for r in rows])
            print(
                f"growth exponent of time against points, {w} worker(s): "
                f"{np.polyfit(p, t, 1)[0]:.2f}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
